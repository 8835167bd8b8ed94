/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/peak_impl.h - the wide-neighbourhood sub-pixel estimator (peak_fit.c), used by
 * peak.c for RPIV_SUBPIXEL_SPLINE. */
#ifndef RPIV_SRC_PEAK_IMPL_H
#define RPIV_SRC_PEAK_IMPL_H

#include "rpiv/peak.h"

/* Half-width of the widest neighbourhood the spline estimator reads: (2 R + 1)^2 samples. */
#define PEAK_SPLINE_R 3

/* The continuous maximum of the tensor-product not-a-knot cubic spline through the logarithm
 * of the 7 x 7 samples of the w x h circular plane around its integer maximum (bi, bj), or of
 * the 5 x 5 ones when one of the 7 x 7 is not positive (or the plane is smaller than 7),
 * found by Newton's method from (x0, y0) (offsets in px from (bi, bj), e.g. the 3-point
 * Gaussian's). 1 and the offsets in *fx, *fy (within 1 px of (bi, bj)) on success; 0 when a
 * sample of the 5 x 5 is not positive or not finite, the plane is smaller than 5, the spline
 * has no maximum within 1 px, or Newton's method does not converge in 40 steps (the caller
 * then keeps its 3-point fit). */
int peak_fit_spline(const float *plane, int w, int h, int bi, int bj, double x0, double y0,
                    double *fx, double *fy);

/* The first-order sensitivity of the spline estimator's maximum to the plane's samples: by
 * the implicit function theorem on the spline's zero gradient g at the maximum x*,
 * d x* = -H^-1 d g, and g is linear in the logarithms of the samples (docs/uncertainty.md,
 * "Ensemble fields"). jx[j n + i], jy[j n + i]: d x* / d c and d y* / d c of sample (i, j) of
 * the n x n neighbourhood (n = 7 or 5, as peak_fit_spline chose it) centred on (bi, bj);
 * hxx, hxy, hyy: the spline's Hessian at the maximum (of ln c). */
typedef struct peak_sens {
    int n;
    double hxx, hxy, hyy;
    double jx[(2 * PEAK_SPLINE_R + 1) * (2 * PEAK_SPLINE_R + 1)];
    double jy[(2 * PEAK_SPLINE_R + 1) * (2 * PEAK_SPLINE_R + 1)];
} peak_sens;

/* The sensitivity at (fx, fy), offsets from (bi, bj) that peak_fit_spline returned for the
 * same plane: 1 and *out; 0 when the spline has no maximum there (its fallback was used). */
int peak_spline_sens(const float *plane, int w, int h, int bi, int bj, double fx, double fy,
                     peak_sens *out);

/* The sub-pixel offsets *fx, *fy (px, from the integer maximum) of the peak at (bi, bj) of the
 * w x h circular plane by `method` (auto: the 3-point Gaussian; spline: its estimator with the
 * Gaussian as start and fallback): 1 on success; 0 and offsets 0 when the fit is impossible. */
int peak_fit_at(const float *plane, int w, int h, int bi, int bj, rpiv_subpixel method, double *fx,
                double *fy);

#endif /* RPIV_SRC_PEAK_IMPL_H */
