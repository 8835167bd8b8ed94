/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/deform_impl.h - what the deformation's files share (deform_prefilter.c,
 * deform_pred.c, deform.c), and one row of a symmetric deformation, for callers that deform
 * strips of rows into their own buffers (the PIV passes). */
#ifndef RPIV_SRC_DEFORM_IMPL_H
#define RPIV_SRC_DEFORM_IMPL_H

#include "rpiv/deform.h"

#include <omp.h>
#include <stddef.h>

/* Ghost nodes around a predictor's grid: the prefilter's mirror boundary sits this far out,
 * where its effect on the evaluated range (RPIV_DEFORM_GHOST steps) is below 1e-6. */
#define PAD 16

/* Does rpiv_deform_run take a frame's sample at coordinate t (its n pixels' centres at
 * 0..n-1)? Where every tap of the cubic B-spline with a non-zero weight is one of its pixels,
 * 1 <= t <= n - 2, none made up by the prefilter's mirror boundary (deform.c's `inside` on a
 * located point, unc_bias.c's edge model). */
static inline int deform_takes(double t, int n)
{
    return t >= 1.0 && t <= (double)n - 2.0;
}

/* rpiv_deform_pred_new; with flag (f's nx x ny node flags, or those of the field it was
 * prepared from), the ghost nodes also continue the field's curvature at each end of each grid
 * line whose 4 end nodes are RPIV_FLAG_VALID (measured), k^2 times deform_edge_curv with the
 * threshold thr[0] for u, thr[1] for v (docs/piv.md, "Deformation"); NULL: linearly. */
RPIV_NODISCARD rpiv_status deform_pred_new_ext(const rpiv_field *f, int w, int h, double shift,
                                               const unsigned char *flag, const double thr[2],
                                               rpiv_deform_pred **out);

/* The limited second difference at the end g[0] of a line of n nodes (stride, inward): the
 * smaller in magnitude of the first two second differences when they have the same sign, else
 * 0 (minmod: noise, whose second differences alternate, is not continued), then shrunk by the
 * non-negative garrote with threshold t (c - t^2 / c above t, else 0: a curvature the field's
 * noise could make is not continued; t = 0: kept); 0 for n < 4. */
double deform_edge_curv(const float *g, int n, ptrdiff_t stride, double t);

/* Are the 4 end nodes of a line of n nodes, from flag[k0] inward by st, all RPIV_FLAG_VALID
 * (0 for n < 4): where deform_pred_new_ext continues the curvature. */
int deform_edge_valid(const unsigned char *flag, size_t k0, ptrdiff_t st, int n);

/* The thread count: n, or OpenMP's default for n <= 0. */
static inline int nthr(int n)
{
    return n > 0 ? n : omp_get_max_threads();
}

/* Cubic B-spline weights for taps -1, 0, 1, 2 at fraction t in [0, 1). */
static inline void bweights(float t, float wt[4])
{
    float t2 = t * t, t3 = t2 * t, s = 1.0f - t;
    wt[0] = s * s * s * (1.0f / 6.0f);
    wt[1] = (2.0f / 3.0f) - t2 + 0.5f * t3;
    wt[3] = t3 * (1.0f / 6.0f);
    wt[2] = 1.0f - wt[0] - wt[1] - wt[3];
}

struct rpiv_deform_pred {
    int nx, ny; /* padded grid size (field + 2 * PAD) */
    double x0, y0, dx, dy;
    float *cu, *cv; /* spline coefficients, ny x nx */
    int w, h;       /* image size */
    double shift;   /* rows and columns evaluated at pixel + shift */
    float maxabs;   /* largest |coefficient|: the interpolant's bound (convex weights) */
    int *ix, *iy;   /* first tap per pixel column / row */
    float *wx, *wy; /* 4 weights per pixel column / row */
    float *wxs;     /* the column weights by tap: wxs[k * w + x] = wx[4 * x + k] */
    int *runend;    /* first column after x whose first tap differs from ix[x] */
};

/* The grid rows of the predictor combined for image row y: tu[k], tv[k] for the nx columns. */
void deform_pred_grid_row(const rpiv_deform_pred *p, int y, float *tu, float *tv);

/* Floats of scratch deform_row needs for the columns x0..x1-1. */
size_t deform_row_scratch(const rpiv_deform_pred *p, int x0, int x1);

/* Row y of rpiv_deform_run, columns x0..x1-1: ra[x], rb[x] for x0 <= x < x1 (ra and rb point
 * at the start of the output rows). Single-threaded; thread-safe with distinct scratch. */
void deform_row(const float *coef_a, const float *coef_b, int w, int h, const rpiv_deform_pred *p,
                int x0, int x1, int y, float fill_a, float fill_b, float *ra, float *rb,
                float *scratch);

/* deform_row with vector blocks of at most vl pixels: 0 (none, every pixel alone), 4, or 8
 * (where the CPU has AVX2, else 4). deform_row is vl = 8; all give the same bits. */
void deform_row_blocks(int vl, const float *coef_a, const float *coef_b, int w, int h,
                       const rpiv_deform_pred *p, int x0, int x1, int y, float fill_a, float fill_b,
                       float *ra, float *rb, float *scratch);

/* The per-pixel code the blocks replaced (same arguments), kept as the reference of the
 * tests and the benchmark: its tap weights are computed in another order (vweights), so its
 * results differ from deform_row's in the last bits. The prefilter's and the predictor rows'
 * references give the same bits as rpiv_deform_prefilter and rpiv_deform_pred_row. */
void deform_row_ref(const float *coef_a, const float *coef_b, int w, int h,
                    const rpiv_deform_pred *p, int x0, int x1, int y, float fill_a, float fill_b,
                    float *ra, float *rb, float *scratch);
void deform_prefilter_ref(float *img, int w, int h, int nthreads);

/* rpiv_deform_prefilter of both frames of a pair, the same bits; with one or two threads, a
 * frame per thread in two sweeps over its memory instead of three. */
void deform_prefilter_pair(float *a, float *b, int w, int h, int nthreads);
void deform_pred_row_ref(const rpiv_deform_pred *p, int y, int x0, int x1, float *u, float *v,
                         float *scratch);

#endif /* RPIV_SRC_DEFORM_IMPL_H */
