/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/uncertainty_impl.h - random uncertainty of each vector by correlation statistics
 * (Wieneke 2015; docs/uncertainty.md). */
#ifndef RPIV_SRC_UNCERTAINTY_IMPL_H
#define RPIV_SRC_UNCERTAINTY_IMPL_H

#include "piv_impl.h"

#include "rpiv/field.h"
#include "rpiv/peak.h"
#include "rpiv/piv.h"

#include <stddef.h>
#include <stdint.h>

/* The largest sigma reported, px: where the statistics cannot be propagated through the
 * peak fit (the noise of the correlation difference as large as the neighbours of the peak),
 * the displacement is not known to better than a pixel. */
#define UNC_SIGMA_MAX 1.0

/* The standard uncertainty (1 sigma, px) of the displacement measured on a window pair: a
 * (rows sa floats apart) and b (sb), w x h, the pair as it was correlated (deformed), the
 * correlation peak at the integer shift (ix, iy). scratch holds 2 w h floats. Writes *su, *sv
 * in 0..UNC_SIGMA_MAX, and the 3-point curvature of the logarithm of the correlation at the
 * peak, x then y, to curv (0 where a value is not positive; unc_systematic's width). */
void unc_cs(const float *a, size_t sa, const float *b, size_t sb, int w, int h, int ix, int iy,
            float *scratch, double *su, double *sv, double curv[2]);

/* The sums unc_cs propagates, for one pair: per direction (x, then y) the correlation at the
 * peak's integer shift C0, at +1 and -1 px, and the variance of C+ - C- (sums[8]); scratch
 * as unc_cs's. An
 * ensemble adds them over its pairs (independent pairs: their variances add). */
void unc_cs_sums(const float *a, size_t sa, const float *b, size_t sb, int w, int h, int ix, int iy,
                 float *scratch, double sums[8]);

/* The 3-point curvature of ln c at (bi, bj) of the circular w x h plane, x and y (ln c- -
 * 2 ln c0 + ln c+); 0 where one of the five samples is not positive. */
int unc_curv_at(const float *plane, int w, int h, int bi, int bj, double *hx, double *hy);

/* The peak fit's sigma (px, 0..UNC_SIGMA_MAX) from C0, C+, C- and var(C+ - C-). */
double unc_cs_sigma(double c0, double cp, double cm, double var);

/* The data of quantity `name` of f, or NULL. */
float *unc_quantity(rpiv_field *f, const char *name);

/* Add (or find) the quantities sigma_u and sigma_v of f, zeroed; their data to *su, *sv. */
RPIV_NODISCARD rpiv_status unc_add(rpiv_field *f, float **su, float **sv);

/* After validation: a replaced vector takes the RMS sigma of its valid 8-neighbours (the
 * replacement interpolates them), or the largest sigma of the field's valid vectors when it
 * has none; a masked vector has 0. No-op if f has no sigma_u. */
void unc_replaced(rpiv_field *f);

/* ---- the predictor's noise carried through the passes (unc_chain.c) ---- */

/* The levels (passes run on one pair) whose errors reach the newest vectors. */
typedef struct unc_chain unc_chain;

/* A pass's windows: window (i, j) covers pixels [wx0 + i sx, + ww) x [wy0 + j sy, + wh); a
 * deforming pass samples its predictor at pixel + shift; the image is img_w x img_h. denoise:
 * 0, or its predictor went through the refinement's denoiser (refine_filter.c) with this
 * refine_denoise_order, whose effect on the predictor's errors is the linear map it was on
 * that predictor, its weights held (unc_pred_weights). */
typedef struct unc_geom {
    int wx0, wy0, sx, sy, ww, wh, img_w, img_h;
    double shift;
    int denoise;     /* 0, or the predictor's refine_denoise_order (piv_pred_denoised)      */
    piv_notch notch; /* the predictor's notch (piv_pred_notch_orders) */
} unc_geom;

/* The weights of the refinement's denoiser on the predictor built from field predictor
 * (prepared as piv_pred_new prepares it, low-passed with weight filter, then denoised):
 * piv_pred_denoise_weights's *gain (new), on predictor's grid; kept = 0: every kept detail's
 * weight set to 0 (the denoiser's linear part L, every detail taken as dropped). */
RPIV_NODISCARD rpiv_status unc_pred_weights(const rpiv_piv *pv, const rpiv_field *predictor,
                                            double filter, int kept, float **gain);

void unc_chain_free(unc_chain *c); /* NULL is a no-op */

/* Add the level of a pass that returned field f with windows g and correlation-statistics
 * sigmas su, sv (valid vectors'; the others take their RMS). linked = 1: the pass deformed
 * by the predictor built from the newest level's field, low-passed with weight `filter`; 0:
 * the chain restarts at this level (no predictor, window offsets, or a predictor from
 * elsewhere, taken as exact). weights: with g->denoise, the denoiser's weights on that
 * predictor (unc_pred_weights; NULL: the predictor taken as not denoised). Creates *chain if
 * NULL. */
RPIV_NODISCARD rpiv_status unc_chain_push(unc_chain **chain, int linked, const unc_geom *g,
                                          double filter, const rpiv_field *f, const float *su,
                                          const float *sv, const float *weights);

/* The newest level's predictor had the error err at the level before's nodes (estimated by
 * unc_pred_error): its part the chain does not count as noise enters the vectors' variance
 * (unc_chain_total; docs/uncertainty.md, "The predictor's systematic error"). g: the newest
 * level's windows. No-op unless the newest level is linked and err is on its predictor's grid. */
RPIV_NODISCARD rpiv_status unc_chain_pred_error(unc_chain *c, const unc_geom *g,
                                                const rpiv_field *err);

/* The error of the predictor of a final field f, at the nodes of the field `predictor` it was
 * built from (f on the same grid), as the final pass measured it: the predictor's nodes as
 * piv_pred_new prepares them (the replaced vectors as they are, the masked ones filled),
 * through the refinement's denoiser if `denoise` and the notch `notch` (NULL or m 0: none),
 * minus f (prepared alike). *out: a new field. */
RPIV_NODISCARD rpiv_status unc_pred_error(const rpiv_piv *pv, const rpiv_field *predictor,
                                          int denoise, const piv_notch *notch, const rpiv_field *f,
                                          rpiv_field **out);

/* The chain's first level is a pass without deformation (no predictor, or window offsets):
 * keep its field f as the next pass took it for its predictor (prepared as piv_pred_new
 * prepares it). No-op unless the chain holds that level alone. Correlation statistics assume
 * the window's particles moved alike; without deformation a window spans the flow's whole
 * displacement variation across it, whose error they do not see (docs/uncertainty.md,
 * "Session 9"). */
RPIV_NODISCARD rpiv_status unc_chain_keep_first(unc_chain *c, const rpiv_field *f);

/* The kept first level's error at its nodes, measured against the final field f (prepared;
 * images img_w x img_h): its field minus f's spline at its nodes; unc_chain_total carries it
 * into the vectors in place of the first level's window noise where it is larger. No-op
 * without a kept first level or with the chain at one level. */
RPIV_NODISCARD rpiv_status unc_chain_first_error(unc_chain *c, const rpiv_field *f, int img_w,
                                                 int img_h);

/* Remember f as the field the newest level returned (unc_chain_links compares with it). */
void unc_chain_set_hash(unc_chain *c, const rpiv_field *f);

/* Is predictor the field the newest level of c returned? */
int unc_chain_links(const unc_chain *c, const rpiv_field *predictor);

/* The total random uncertainty of the valid vectors of f (the newest level's field): its own
 * window noise and the predictors' noise carried through the levels, into su, sv. */
RPIV_NODISCARD rpiv_status unc_chain_total(const unc_chain *c, const rpiv_field *f, float *su,
                                           float *sv, int nthreads);

/* The bias of the vectors on the grid's edge rows and columns, added to their sigma (in
 * quadrature): a top-hat window of ww x wh px measures the window mean, u + ww^2/24 u_xx +
 * wh^2/24 u_yy + ..., which the deformation compensates inside the grid, but not across its
 * edge, where the predictor is continued linearly; u_xx, u_yy from the field's second
 * differences inward. f: the final field (grid steps dx, dy px). curved: the predictor
 * continued its limited curvature (deform_edge_curv): what the limiter left out instead. */
void unc_edge_bias(const rpiv_field *f, int ww, int wh, int curved, float *su, float *sv);

/* ---- the systematic error of the engine's chain on a model particle (unc_bias.c) ---- */

/* The model: pixel-integrated Gaussian particle images of standard deviation sx, sy px;
 * deform: the pass resamples both frames with the predictor, sampling shift c; method: the
 * sub-pixel estimator (resolved). */
typedef struct unc_model {
    double sx, sy, c;
    int deform;
    rpiv_subpixel method;
    int ww, wh; /* the window, px (the share of pixel pairs at a shift k: 1 - |k| / w); 0: none */
} unc_model;

/* Set m->sx, m->sy so that the estimator's curvature of ln c at the model's peak (displacement
 * (dx, dy), predictor (px, py)) equals the measured hx, hy (< 0). 0 if it cannot. */
int unc_model_fit(unc_model *m, double hx, double hy, double dx, double dy, double px, double py);

/* The systematic error (estimate - truth, px) of the engine's chain on the model at
 * displacement (dx, dy) and predictor (px, py): 1 and *bx, *by, or 0 (no fit). */
int unc_model_bias(const unc_model *m, double dx, double dy, double px, double py, double *bx,
                   double *by);

/* The systematic term of a final field f's valid vectors (docs/uncertainty.md, "The
 * systematic floor"), added to su, sv in quadrature: the engine's chain on the model particle
 * whose 3-point curvature is the median of the windows' hx, hy (valid vectors with both < 0),
 * at each vector's displacement and predictor pu, pv (NULL: the vector itself, a converged
 * deforming pass); ww x wh the windows; deform and c as in unc_model, the model's estimator
 * the 3-point Gaussian. frame (NULL: not known): the frame's width and height, px, and the
 * windows' grid, {w, h, ox, oy, sx, sy} (node (i, j)'s window starts at (ox + i sx,
 * oy + j sy)): the windows near the image's edge get the edge's share of the bias too. */
void unc_systematic(const rpiv_field *f, int ww, int wh, const float *hx, const float *hy,
                    const double *pu, const double *pv, int deform, double c, const int *frame,
                    float *su, float *sv, int nthreads);

#endif /* RPIV_SRC_UNCERTAINTY_IMPL_H */
