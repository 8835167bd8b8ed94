/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv_impl.h - the PIV plan's insides, shared by piv.c (per pair) and ensemble.c. */
#ifndef RPIV_SRC_PIV_IMPL_H
#define RPIV_SRC_PIV_IMPL_H

#include "rpiv/deform.h"
#include "rpiv/piv.h"
#include "rpiv/xcorr.h"

#include <stddef.h>

typedef struct piv_pass {
    int ww, wh;              /* window size, px                                    */
    int sx, sy;              /* grid step, px                                      */
    int nx, ny;              /* grid size                                          */
    int ox, oy;              /* first pixel of window (0, 0)                       */
    int rect[4];             /* pixels covered by the windows: x0, y0, x1, y1      */
    size_t nwin;
    rpiv_xcorr *xc;
    rpiv_xcorr_work **ws;    /* one per thread                                     */
    unsigned char *masked;   /* nwin flags (1 = masked window), NULL without mask   */
} piv_pass;

enum { PIV_EMPTY = 0, PIV_RAW = 1, PIV_COEF = 2 };

struct rpiv_piv {
    rpiv_piv_params p;
    int w, h, nthreads, npass;
    int roi[4];
    piv_pass pass[RPIV_PIV_MAX_PASSES];
    unsigned char *mask;     /* w*h, 1 = masked pixel; NULL = no mask                */
    float *bga, *bgb;        /* backgrounds, NULL = none                             */
    float *ia, *ib;          /* loaded frames, then their B-spline coefficients      */
    float *da, *db;          /* deformed frames (NULL if no pass deforms)            */
    float fill_a, fill_b;    /* mean grey level of the loaded frames                 */
    int state;               /* PIV_EMPTY, PIV_RAW or PIV_COEF                       */
    size_t bytes;            /* memory held                                          */
};

/* What a pass correlates: frames (stride w) and, in window-offset mode, the integer offsets
 * of every window (A at -off_a, B at +off_b... see piv.c). */
typedef struct piv_source {
    const float *fa, *fb;
    const rpiv_deform_pred *pred; /* NULL: no predictor                               */
    int offsets;                  /* 1: integer window offsets from pred (deform off)  */
    double shift;                 /* pixel x of the frames stands for x + shift        */
} piv_source;

/* The sampling shift of pass k: RPIV_DEFORM_SHIFT for a deforming pass (k > 0, deformation
 * on), 0 otherwise. Vectors of the pass sit at their window's centre plus this shift. */
double piv_shift(const rpiv_piv *pv, int k);

/* Build the interpolant of a predictor field (copied; rejected and masked vectors filled
 * with neighbour medians first), rows evaluated at pixel + shift. */
RPIV_NODISCARD rpiv_status piv_pred_new(const rpiv_piv *pv, const rpiv_field *predictor,
                                        double shift, rpiv_deform_pred **out);

/* The source of pass k without touching the frames (predictor, shift, offsets mode). */
void piv_source_of(const rpiv_piv *pv, int k, const rpiv_deform_pred *pred, piv_source *src);

/* Prepare the loaded pair for pass k with predictor pred (may be NULL): prefilter and deform
 * when the pass deforms. */
RPIV_NODISCARD rpiv_status piv_prepare(rpiv_piv *pv, int k, const rpiv_deform_pred *pred,
                                       piv_source *src);

/* Correlate window `win` of pass ps from src with the workspace ws (raw plane, energies);
 * *pu, *pv get the displacement the window pair was shifted by (the predictor at the centre,
 * or the integer offset). */
void piv_window(const rpiv_piv *pv, const piv_pass *ps, const piv_source *src,
                rpiv_xcorr_work *ws, size_t win, double *ea, double *eb, double *pu,
                double *pv_);

/* Just the displacement window `win` is shifted by (as piv_window gives it). */
void piv_window_shift(const piv_pass *ps, const piv_source *src, size_t win, double *pu,
                      double *pv_);

/* The vector of window `win` from its (raw or summed) plane and energies: into f at win. */
void piv_vector(const rpiv_piv *pv, const piv_pass *ps, const float *plane, double ea,
                double eb, double pu, double pv_, rpiv_field *f, size_t win);

/* Validate (median test if enabled) and replace rejected vectors. */
RPIV_NODISCARD rpiv_status piv_validate(const rpiv_piv *pv, rpiv_field *f);

#endif /* RPIV_SRC_PIV_IMPL_H */
