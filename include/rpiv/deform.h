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

/* The offset of the deformed frames' sampling grid that cancels the interpolation bias; see
 * rpiv_deform_run. */
#define RPIV_DEFORM_SHIFT 0.25

/* Build the interpolant of f for images of w x h pixels; its rows (rpiv_deform_pred_row, and
 * so rpiv_deform_run) are evaluated at the points (x + shift, y + shift) of the pixels (x, y).
 * f is copied; flags are ignored (the caller replaces invalid vectors first). */
RPIV_NODISCARD rpiv_status rpiv_deform_pred_new(const rpiv_field *f, int w, int h, double shift,
                                                rpiv_deform_pred **out);
void rpiv_deform_pred_free(rpiv_deform_pred *p); /* NULL is a no-op */

/* The predictor at any point (x, y), px (no shift applied). */
void rpiv_deform_pred_eval(const rpiv_deform_pred *p, double x, double y, double *u, double *v);

/* The predictor at the points (x + shift, y + shift) for the pixels x0..x1-1
 * (0 <= x0 < x1 <= w) of row y (0 <= y < h), into u[0..x1-x0-1], v[...]. scratch holds
 * rpiv_deform_pred_scratch(p) floats. Thread-safe. */
size_t rpiv_deform_pred_scratch(const rpiv_deform_pred *p);
void rpiv_deform_pred_row(const rpiv_deform_pred *p, int y, int x0, int x1, float *u, float *v,
                          float *scratch);

/* Symmetric deformation, over the rectangle rect = {x0, y0, x1, y1} (x0 <= x < x1,
 * y0 <= y < y1, inside the image), of a pair given by the B-spline coefficients of its
 * frames. With c the predictor's shift and q = x + (c, c):
 *     out_a(x) = A(q - p(q)/2),   out_b(x) = B(q + p(q)/2),
 * so a particle displaced by p between the frames sits at the same place in both outputs,
 * and pixel x of the outputs stands for the point q of the frames.
 *
 * Why c = RPIV_DEFORM_SHIFT = 1/4: interpolating at a fraction t of a pixel moves the image
 * by t + e(t), where the phase error e of any symmetric interpolator is odd and 1-periodic,
 * e(t) ~ E sin(2 pi t). Frame A is sampled at the fraction c - p/2, frame B at c + p/2, so
 * the two frames end up displaced by p + e(c + p/2) + e(p/2 - c) relative to each other:
 * with c = 0 that is p + 2 e(p/2), a bias that reaches 0.017 px for 2.5 px particles and
 * cubic B-splines; with c = 1/4 the two arguments differ by half a pixel and the first
 * harmonic cancels (measured: below 0.003 px). docs/piv.md gives the figures.
 *
 * out_a and out_b are w x h images; only the rectangle is written. Where either sample falls
 * outside [1, w - 2] x [1, h - 2] of its frame (beyond it the interpolant reads taps the
 * prefilter's mirror boundary made up), both outputs take their fill value (fill_a, fill_b: the
 * callers pass the frames' mean grey level, so after the windows' mean removal those pixels add
 * nothing): a particle there has no partner in the other frame and would only add noise.
 * nthreads as in prefilter. */
RPIV_NODISCARD rpiv_status rpiv_deform_run(const float *coef_a, const float *coef_b, int w, int h,
                                           const rpiv_deform_pred *p, const int rect[4],
                                           float fill_a, float fill_b, float *out_a, float *out_b,
                                           int nthreads);

#endif /* RPIV_DEFORM_H */
