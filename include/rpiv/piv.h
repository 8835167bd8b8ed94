/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/piv.h - multi-pass deforming FFT cross-correlation PIV, per pair and ensemble. */
#ifndef RPIV_PIV_H
#define RPIV_PIV_H

#include "rpiv/error.h"
#include "rpiv/field.h"
#include "rpiv/image.h"
#include "rpiv/peak.h"

#define RPIV_PIV_MAX_PASSES 8

typedef enum rpiv_background {
    RPIV_BACKGROUND_NONE = 0,
    RPIV_BACKGROUND_MIN = 1,  /* subtract the series' per-pixel minimum */
    RPIV_BACKGROUND_MEAN = 2  /* subtract the series' per-pixel mean    */
} rpiv_background;

typedef struct rpiv_piv_params {
    int npass;                          /* number of passes, 1..8 (3)                  */
    int win_w[RPIV_PIV_MAX_PASSES];     /* window width per pass, px (64, 32, 32)      */
    int win_h[RPIV_PIV_MAX_PASSES];     /* window height per pass, px (64, 32, 32)     */
    double overlap;                     /* window overlap fraction, 0..0.95 (0.5)      */
    int step_px;                        /* grid step, px; 0 = from overlap (0)         */
    int ensemble;                       /* 1: sum of correlation over all pairs (0)    */
    rpiv_subpixel subpixel;             /* (gauss)                                     */
    double median_thr;                  /* normalised median threshold; 0 = off (2)    */
    double median_eps;                  /* median test epsilon, px (0.1)               */
    rpiv_background background;         /* (none)                                      */
    int roi[4];                         /* x0, y0, x1, y1 px; all 0 = whole image      */
    char mask[512];                     /* mask image, 0 = masked ("" = none)          */
    int threads;                        /* OpenMP threads; 0 = all cores (0)           */
    double scale_mm_per_px;             /* physical scale, 0 = unset (0)               */
    double dt_s;                        /* pulse separation, s; 0 = unset (0)          */
    int deform;                         /* 1: deform images between passes (1)         */
    double max_mem_mb;                  /* refuse runs needing more memory, MB (4096)  */
} rpiv_piv_params;

rpiv_piv_params rpiv_piv_params_default(void);
RPIV_NODISCARD rpiv_status rpiv_piv_params_check(const rpiv_piv_params *p);

/* (The engine API follows; see the PIV engine issue.) */

#endif /* RPIV_PIV_H */
