/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/deform.h - image interpolation and symmetric image deformation by a predictor.
 *
 * Images are interpolated with cubic B-splines (Unser, IEEE Signal Proc. Mag. 16(6), 1999):
 * a recursive prefilter turns the grey levels into spline coefficients (in place), after
 * which the interpolant passes exactly through every pixel value and is C2 between them.
 * Among the interpolators of support 4 it has the smallest error for the band-limited
 * particle images of PIV (it reproduces cubics and attenuates high frequencies least), which
 * is what the sub-pixel accuracy of a deforming PIV needs; see docs/piv.md. The coefficients
 * are extended beyond the image by mirror symmetry (whole-sample, c[-k] = c[k]).
 *
 * The predictor is a displacement field known on a grid of window centres (an rpiv_field),
 * interpolated to every pixel with the same cubic B-spline on the grid. Beyond the outermost
 * grid points the field is extended point-symmetrically (g(-k) = 2 g(0) - g(k)), which keeps
 * a linear field linear, for up to RPIV_DEFORM_GHOST grid steps, then held constant. */
#ifndef RPIV_DEFORM_H
#define RPIV_DEFORM_H

#include "rpiv/error.h"
#include "rpiv/field.h"

#include <stddef.h>

#define RPIV_DEFORM_GHOST 4

/* Replace the w x h image img by its cubic B-spline coefficients, in place. Rows, then
 * columns, are split among nthreads threads (<= 0: OpenMP's default); the result does not
 * depend on nthreads. */
void rpiv_deform_prefilter(float *img, int w, int h, int nthreads);

/* The interpolated image at (x, y) (pixel centres at integers) from coefficients coef.
 * Positions outside [-0.5, w - 0.5] x [-0.5, h - 0.5] give `fill`. */
float rpiv_deform_sample(const float *coef, int w, int h, double x, double y, float fill);

/* A predictor: the cubic B-spline interpolant of a field's (u, v), ready to be evaluated at
 * the pixels of a w x h image. */
typedef struct rpiv_deform_pred rpiv_deform_pred;

/* Build the interpolant of f for images of w x h pixels. f is copied; flags are ignored (the
 * caller replaces invalid vectors first). */
RPIV_NODISCARD rpiv_status rpiv_deform_pred_new(const rpiv_field *f, int w, int h,
                                                rpiv_deform_pred **out);
void rpiv_deform_pred_free(rpiv_deform_pred *p); /* NULL is a no-op */

/* The predictor at any point (x, y), px. */
void rpiv_deform_pred_eval(const rpiv_deform_pred *p, double x, double y, double *u,
                           double *v);

/* The predictor at the pixels x0..x1-1 (0 <= x0 < x1 <= w) of row y (0 <= y < h), into
 * u[0..x1-x0-1], v[...]. scratch holds rpiv_deform_pred_scratch(p) floats. Thread-safe. */
size_t rpiv_deform_pred_scratch(const rpiv_deform_pred *p);
void rpiv_deform_pred_row(const rpiv_deform_pred *p, int y, int x0, int x1, float *u, float *v,
                          float *scratch);

/* Symmetric deformation over the rectangle rect = {x0, y0, x1, y1} (x0 <= x < x1, y0 <= y <
 * y1, inside the image) of a pair given by the B-spline coefficients of its frames:
 *     out_a(x) = A(x - p(x)/2),   out_b(x) = B(x + p(x)/2),
 * so that a particle displaced by p between the frames sits at the same place in both
 * outputs. out_a and out_b are w x h images; only the rectangle is written. Samples that fall
 * outside the frames take fill_a / fill_b (the callers pass the frame's mean grey level, so
 * that after the windows' mean removal they add no edge). nthreads as in prefilter. */
RPIV_NODISCARD rpiv_status rpiv_deform_run(const float *coef_a, const float *coef_b, int w,
                                           int h, const rpiv_deform_pred *p, const int rect[4],
                                           float fill_a, float fill_b, float *out_a,
                                           float *out_b, int nthreads);

#endif /* RPIV_DEFORM_H */
