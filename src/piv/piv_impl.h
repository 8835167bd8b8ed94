/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/piv_impl.h - the PIV plan's insides, shared by piv.c (per pair) and ensemble.c. */
#ifndef RPIV_SRC_PIV_IMPL_H
#define RPIV_SRC_PIV_IMPL_H

#include "rpiv/deform.h"
#include "rpiv/piv.h"
#include "rpiv/xcorr.h"

#include <stddef.h>
#include <stdint.h>

typedef struct piv_pass {
    int ww, wh;  /* window size, px                                    */
    int sx, sy;  /* grid step, px                                      */
    int nx, ny;  /* grid size                                          */
    int ox, oy;  /* first pixel of window (0, 0)                       */
    int rect[4]; /* pixels covered by the windows: x0, y0, x1, y1      */
    size_t nwin;
    rpiv_xcorr *xc;
    rpiv_xcorr_work **ws;  /* one per thread                                     */
    unsigned char *masked; /* nwin flags (1 = masked window), NULL without mask   */
} piv_pass;

enum { PIV_EMPTY = 0, PIV_RAW = 1, PIV_COEF = 2 };

struct rpiv_piv {
    rpiv_piv_params p;
    int w, h, nthreads, npass;
    int roi[4];
    piv_pass pass[RPIV_PIV_MAX_PASSES];
    unsigned char *mask;   /* w*h, 1 = masked pixel; NULL = no mask                */
    float *bga, *bgb;      /* backgrounds, NULL = none                             */
    float *ia, *ib;        /* loaded frames, then their B-spline coefficients      */
    float *prep;           /* a frame being preprocessed; NULL without preprocessing */
    int deforms;           /* passes after the first deform the frames             */
    float fill_a, fill_b;  /* mean grey level of the loaded frames                 */
    int state;             /* PIV_EMPTY, PIV_RAW or PIV_COEF                       */
    size_t bytes;          /* memory held                                          */
    rpiv_progress cancel;  /* asked between passes and rows of windows (fn NULL: never) */
    struct unc_chain *unc; /* the passes' uncertainty (uncertainty_impl.h), or NULL */
    int unc_no_total;      /* 1: the final pass's step leaves its field's sigma out (a
                              refinement iterate that is not the one returned, refine.c) */
    uint64_t final_hash;   /* piv_field_hash of the field the final pass last returned for the
                              loaded pair (final_known 1): a predictor equal to it makes a step a
                              refinement repeat, notched (refine_notch) */
    int final_known;
};

/* What a pass correlates: frames (stride w) whose first row is image row row0, and the
 * predictor that shifts the windows (by deformation, or by integer offsets). */
typedef struct piv_source {
    const float *fa, *fb;
    int row0;                     /* image row of fa[0], fb[0]                         */
    const rpiv_deform_pred *pred; /* NULL: no predictor                               */
    int offsets;                  /* 1: integer window offsets from pred (deform off)  */
    int deform;                   /* 1: the frames are deformed by pred, strip by strip */
    double shift;                 /* pixel x of the frames stands for x + shift        */
} piv_source;

/* Called from the worker threads with each correlated window (distinct windows at once):
 * the raw plane and its column maxima (rpiv_peak_find_cm), the energies, the shift of the
 * window pair, and the window pair as correlated (deformed; valid during the call). */
typedef void (*piv_win_fn)(void *ctx, const float *plane, const float *colmax, size_t win,
                           double ea, double eb, double pu, double pv_, const rpiv_xcorr_src *xs);

/* Correlate every unmasked window of pass k on the loaded pair with predictor pred (may be
 * NULL), calling fn for each. A deforming pass works strip by strip: the rows under one row
 * of windows are deformed into a thread's buffer of a window's height (the overlap with the
 * previous strip moved up, only the new rows computed), then that row of windows is
 * correlated; no deformed frame is ever held whole, and threads never wait for each other. */
RPIV_NODISCARD rpiv_status piv_pass_run(rpiv_piv *pv, int k, const rpiv_deform_pred *pred,
                                        piv_win_fn fn, void *ctx);
/* piv_pass_run that stops (RPIV_EINTR) when the plan's cancel hook asks (a pair's passes). */
RPIV_NODISCARD rpiv_status piv_pass_run_cut(rpiv_piv *pv, int k, const rpiv_deform_pred *pred,
                                            piv_win_fn fn, void *ctx);

/* Has the plan's cancel hook (rpiv_piv_set_cancel) asked to stop? Calling thread only. */
int piv_cancelled(const rpiv_piv *pv);
/* A pass's check inside a parallel region (cut = 1: the hook is asked by thread 0 of the
 * team, which is the calling thread, and sets *stop; every thread reads *stop): 1 = stop. */
int piv_pass_stopped(const rpiv_piv *pv, int cut, int *stop);

/* The sampling shift of pass k: RPIV_DEFORM_SHIFT for a deforming pass (k > 0, deformation
 * on), 0 otherwise. Vectors of the pass sit at their window's centre plus this shift. */
double piv_shift(const rpiv_piv *pv, int k);

/* The notch of a predictor's grid modes a window does not see (piv_pred_notch_orders). */
typedef struct piv_notch {
    int m[2];      /* the order along x and y, 0: none                             */
    int levels[2]; /* dilations 1, 2, .. 2^(levels - 1) along x and y             */
} piv_notch;
/* Build the interpolant of pass `pass`'s predictor field (copied; masked vectors filled with
 * neighbour medians first, rejected ones taken with the values their replacement gave them,
 * then low-pass filtered with weight `filter`, 0 = none, then denoised where it serves a repeat,
 * then notched by `notch`, NULL or m 0 = none: piv_pred_notch_orders), rows evaluated at pixel +
 * piv_shift(pv, pass); beyond the grid continued as piv_edge_curved says for an ensemble's pass
 * or a single pair's. */
RPIV_NODISCARD rpiv_status piv_pred_new(const rpiv_piv *pv, const rpiv_field *predictor, int pass,
                                        double filter, const piv_notch *notch, int ensemble,
                                        rpiv_deform_pred **out);
/* 1 when the predictor continues its curvature beyond the grid (params edge_curvature). */
int piv_edge_curved(const rpiv_piv *pv, int ensemble);
/* The predictor's low-pass filter [a/2, 1 - a, a/2] along x, then along y, edge nodes kept
 * (src/piv/piv.c; refine_filter). */
RPIV_NODISCARD rpiv_status piv_pred_filter(rpiv_field *f, double a);
/* c := F^T c, F that filter on an nx x ny grid, c the nodes bx0.. (bw) x by0.. (bh), row after
 * row (taken as 0 outside; what F^T would carry out of the block is dropped). tmp: bw bh
 * doubles. */
void piv_pred_filter_t(double *c, double a, int nx, int ny, int bx0, int bw, int by0, int bh,
                       double *tmp);
/* Does a predictor on this field's grid serve a pass that repeats the window size before it
 * (the grid is that of pass j, and pass j + 1, or the last pass itself, repeats)? Such
 * predictors are denoised with refine_denoise (src/piv/refine_filter.c). */
int piv_pred_repeats(const rpiv_piv *pv, const rpiv_field *predictor);
/* Is this predictor denoised (refine_denoise on, piv_pred_repeats)? 0 if not, else the
 * refine_denoise_order it is denoised with. */
int piv_pred_denoised(const rpiv_piv *pv, const rpiv_field *predictor);
/* Shrink the detail of a grid field above its smoothing, along x then y, at dilations 1, 2
 * and 4 grid steps (fourth differences at 1 and 2, the second at 4; with refine_denoise_order
 * 2 the second at 1), with thresholds from the field's own noise level (pv: the window of the pass
 * the field's grid belongs to; src/piv/refine_filter.c). */
RPIV_NODISCARD rpiv_status piv_pred_denoise(const rpiv_piv *pv, rpiv_field *f);
/* The grid's Nyquist notch (refine_notch; docs/piv.md, "The grid's Nyquist mode"): a wave of
 * 2 grid steps is not seen by a window of 2 steps or more (its mean over the window is nil), so
 * a repeat never corrects it and keeps what an earlier pass's noise put there; with a window of
 * 4 steps or more (75 % overlap) the same holds for the wave of 4 steps. Each line of a denoised
 * predictor loses them by U - (-d2 / 4)^m U, on the line itself and, for the wave of 4 steps,
 * on its two interleaved sub-lines of every other node (response 1 - q^m, q = (1 - cos d w) / 2
 * at dilation d: 0 at 2 d grid steps a wavelength; m >= 2; cubics pass, each (sub-)line
 * continued by the cubic through its 4 end samples). */
#define PIV_NOTCH_MAX       RPIV_PIV_NOTCH_MAX
#define PIV_NOTCH_DILATIONS 4 /* the largest dilation: waves of 8 grid steps (87.5 % overlap) */
/* A field's identity: a hash of its grid size, u, v and flags (HASH0 for NULL). */
uint64_t piv_field_hash(const rpiv_field *f);
/* RMS difference of u, v of two fields on the same grid, over the vectors not masked in a
 * (valid = 0: a pair's refinement) or valid in both (valid = 1: an ensemble's repeats,
 * rpiv_ensemble_change); *count (may be NULL) the vectors counted, 0 returned with none. */
double piv_field_change(const rpiv_field *a, const rpiv_field *b, int valid, size_t *count);
/* The notch for the predictor of a single pair's pass `pass` (denoise: piv_pred_denoised's
 * result), where the predictor is denoised and the step is a refinement repeat, the final pass
 * run on the field it last returned for this pair (pv->final_hash; so the listed passes, and
 * ensembles, which run those only, are as before): along each axis the order refine_notch and
 * the dilations d = 1, 2, 4 with the pass's window spanning 2 d grid steps or more; else none. */
void piv_pred_notch_orders(const rpiv_piv *pv, int pass, int denoise, const rpiv_field *predictor,
                           piv_notch *n);
/* An ensemble's predictor of the final size (a pass whose predictor is on its own grid): with
 * ensemble_denoise, denoised as piv_pred_denoised says and not notched; without, not denoised
 * (an ensemble's detail is mostly the flow's, and the denoiser's threshold, taken from that
 * detail, shrinks it) but notched as a pair's repeats are (piv_pred_notch_orders) (docs/piv.md,
 * "Ensembles: the final pass repeated"). */
int piv_pred_denoised_ensemble(const rpiv_piv *pv, const rpiv_field *predictor);
void piv_pred_notch_ensemble(const rpiv_piv *pv, int pass, const rpiv_field *predictor,
                             piv_notch *n);
/* The notch n on f's u and v (NULL or orders 0: nothing). */
RPIV_NODISCARD rpiv_status piv_pred_notch(rpiv_field *f, const piv_notch *n);
/* c := N^T c for the notch N of piv_pred_notch on an nx x ny grid: c holds the nodes bx0.. (bw) x
 * by0.. (bh), row after row, and is taken as 0 outside them (what N^T would carry out of the
 * block is dropped). tmp: bw bh doubles. */
void piv_pred_notch_t(double *c, const piv_notch *n, int nx, int ny, int bx0, int bw, int by0,
                      int bh, double *tmp);
/* The threshold of a curvature continued beyond f's grid (edge_curvature; deform_edge_curv),
 * u and v: the universal threshold of f's second differences, 4 sigma sqrt(2 ln n), sigma the
 * denoiser's noise level of their detail at dilation 1 (the smallest over the four grid
 * directions of the median absolute detail / 0.6745; src/piv/refine_filter.c). Infinite
 * (nothing continued) where that estimate fails: fewer than 8 details in every direction, or
 * no memory for it. */
void piv_curv_threshold(const rpiv_field *f, double thr[2]);
/* The denoiser's stages a component: its levels, each along x then along y. */
#define PIV_DENOISE_STAGES 6
/* piv_pred_denoise on f, which it changes likewise, and *gain (new, PIV_DENOISE_STAGES x 2 x
 * nx x ny floats: [((comp * levels + level) * 2 + axis) * nx ny + node]): the factor each stage
 * applied to each node's detail (the garrote's output over its detail: 0 where the detail was
 * dropped, 1 - t^2 / d^2 where it was kept, 1 where the stage did not run). With these weights
 * held the denoiser is the linear map A = S_last ... S_first, S = I + diag(g - 1) D (D the
 * stage's detail operator), and A f is the denoised f (docs/uncertainty.md, "The denoiser's
 * weights"). */
RPIV_NODISCARD rpiv_status piv_pred_denoise_weights(const rpiv_piv *pv, rpiv_field *f,
                                                    float **gain);
/* c := A^T c for component comp (0 u, 1 v) with the weights of piv_pred_denoise_weights on an
 * nx x ny grid (fine: the refine_denoise_order they were made with): c holds the nodes bx0.. (bw) x
 * by0.. (bh), row after row, and is taken as 0 outside them (what A^T would carry out of the block
 * is dropped). tmp: bw bh doubles. Returns 0, or -1 when out of memory (c then partly mapped). */
RPIV_NODISCARD int piv_pred_denoise_map_t(const float *gain, int fine, int nx, int ny, int comp,
                                          double *c, int bx0, int bw, int by0, int bh, double *tmp);

/* The source of pass k without touching the frames (predictor, shift, offsets mode). */
void piv_source_of(const rpiv_piv *pv, int k, const rpiv_deform_pred *pred, piv_source *src);

/* Check the loaded pair can serve pass k with predictor pred and describe the source;
 * prefilters the frames (once per pair) when the pass deforms. */
RPIV_NODISCARD rpiv_status piv_prepare(rpiv_piv *pv, int k, const rpiv_deform_pred *pred,
                                       piv_source *src);

/* Correlate the unmasked windows among (i, j) and (i + 1, j) of pass ps from src (grid column
 * i, row j), the two packed in one set of transforms (rpiv_xcorr_run_pairs), and hand each to
 * fn with its raw plane, energies and the displacement its window pair was shifted by (the
 * predictor at the centre, or the integer offset). Windows are always paired this way, so a
 * plane does not depend on how the work is split. */
void piv_windows(const rpiv_piv *pv, const piv_pass *ps, const piv_source *src, rpiv_xcorr_work *ws,
                 size_t i, size_t j, piv_win_fn fn, void *ctx);

/* Just the displacement window `win` is shifted by (as piv_windows gives it). */
void piv_window_shift(const piv_pass *ps, const piv_source *src, size_t win, double *pu,
                      double *pv_);

/* The vector of window `win` from its (raw or summed) plane, its column maxima (NULL: not
 * known) and energies: into f at win. ensemble: 1 for a sum of correlation (the estimator
 * of rpiv_subpixel_resolve). near > 0: the peak is the highest local maximum within near px
 * of the window pair's shift (rpiv_peak_find_near); 0: the plane's highest. peak: NULL or
 * where the peak found is copied. */
void piv_vector(const rpiv_piv *pv, const piv_pass *ps, const float *plane, const float *colmax,
                double ea, double eb, double pu, double pv_, rpiv_field *f, size_t win,
                int ensemble, int near, rpiv_peak *peak);

/* The peak search radius of pass `pass` run with a predictor (piv.search_radius; -1: an
 * eighth of the smaller side of the window of the pass before, which made the predictor, or
 * of the first pass's own; at least 2 px); 0 without a predictor or when off. */
int piv_search_radius(const rpiv_piv *pv, int pass, int has_predictor);
/* The same from the parameters alone (the memory estimate's). */
int piv_params_search_radius(const rpiv_piv_params *p, int pass, int has_predictor);

/* Validate (median test if enabled) and replace rejected vectors. */
RPIV_NODISCARD rpiv_status piv_validate(const rpiv_piv *pv, rpiv_field *f);

/* Is pass `pass` a repeat of the window size before it (deforming): a refinement pass? */
int piv_repeats(const rpiv_piv *pv, int pass);

/* rpiv_piv_step; defer = 1 on a refinement pass: no validation (rpiv_piv_passes validates the
 * field it ends with), a window without a peak keeps the predictor's vector, flagged
 * replaced. */
RPIV_NODISCARD rpiv_status piv_step(rpiv_piv *pv, int pass, const rpiv_field *predictor, int defer,
                                    rpiv_field **out);

/* The uncertainty of the vectors of pass `pass` (f, validated; cs its windows' own sigmas, u
 * then v; shift: piv_shift's): the level joins the chain of the passes before it when its
 * predictor is the field the last one returned (`refines`: a repeat, its predictor
 * low-passed; `notch`: the notch piv_step gave it); the final pass gets sigma_u, sigma_v
 * (unc_step.c). cs: the windows' own sigmas u, v, then their 3-point curvatures x, y (unc_cs), nwin
 * floats each. */
RPIV_NODISCARD rpiv_status piv_step_uncertainty(rpiv_piv *pv, int pass, double shift,
                                                const rpiv_field *predictor, const piv_notch *notch,
                                                int refines, rpiv_field *f, const float *cs);

/* Correlation-based correction (piv_cbc.c; piv.cbc): the planes of a pass's windows kept
 * around the predicted shift, then each window's peak chosen on its plane combined with its
 * four neighbours' (mode 1: their product, 2: their sum, each normalised by its maximum). */
/* Only windows whose own peak ratio is below this are reconsidered: a clear peak keeps its
 * choice (on docs/piv.md's 54 weak-peak pairs no window at or above 2 ever moved). */
#define PIV_CBC_RATIO 2.0f

typedef struct piv_cbc {
    int mode;
    int reach;  /* the combination's search: |shift| <= reach px                 */
    int r, s;   /* the planes kept: shifts |d| <= r, s = 2 r + 1                 */
    int nx, ny; /* the pass's grid                                               */
    size_t nwin;
    float *crop;          /* nwin s x s planes, shift (dx, dy) at (dy + r) s + dx + r      */
    float *ratio;         /* the window's own peak ratio                                   */
    float *top, *val;     /* the whole plane's highest value; the peak the window chose    */
    float *cmax;          /* the kept plane's highest value                                */
    float *scale;         /* sqrt(ea eb): corr = value / scale                             */
    double *pu;           /* the window pair's shift, u then v per window                  */
    int *ixy;             /* the window's own integer peak, x then y                       */
    unsigned char *has;   /* 1: a measured window (its plane kept)                         */
    unsigned char *moved; /* 1: its peak moved by the correction                           */
} piv_cbc;

/* A correction for pass ps whose search radius is near (0: no predictor, a quarter of the
 * window). *out NULL (and RPIV_OK) when the windows are too small for a choice. */
RPIV_NODISCARD rpiv_status piv_cbc_new(const piv_pass *ps, int near, int mode, piv_cbc **out);
void piv_cbc_free(piv_cbc *cb);
/* The bytes piv_cbc_new holds per window of ww x wh with search radius near (0: none). */
double piv_cbc_bytes(int ww, int wh, int near);
/* Keep window win's plane (w x h, circular; colmax its column maxima or NULL), its peak pk,
 * energies and shift. Thread-safe for distinct windows. */
void piv_cbc_store(piv_cbc *cb, const float *plane, const float *colmax, int w, int h, size_t win,
                   const rpiv_peak *pk, double ea, double eb, double pu, double pv_);
/* Choose every valid window's peak on the combined planes; where it is another local maximum
 * of the window's own plane, its vector (fitted by method on the own plane), peak ratio
 * (against the higher of the plane's top and the peak replaced) and corr change in f. The
 * count of moved vectors (cb->moved marks them). offsets: 1 when the pass's windows are
 * shifted by integer offsets (planes aligned by them), 0 when deformed or unshifted. */
size_t piv_cbc_apply(piv_cbc *cb, int offsets, rpiv_subpixel method, rpiv_field *f, int nthreads);

#endif /* RPIV_SRC_PIV_IMPL_H */
