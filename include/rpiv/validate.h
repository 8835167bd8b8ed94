/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/validate.h - outlier detection (normalised median test) and replacement.
 *
 * Normalised median test (Westerweel & Scarano, Exp. Fluids 39:1096, 2005), per component:
 * for a vector U0 with neighbours U1..Un (its 3 x 3 neighbourhood, valid ones only), Um the
 * median of the neighbours, ri = |Ui - Um| and rm the median of the ri,
 *     r0* = |U0 - Um| / (rm + eps);
 * the vector is rejected when r0* > threshold for u or for v (the paper's recommendation:
 * eps = 0.1 px, threshold 2). The median of an even count is the mean of the middle two.
 * Every vector is tested against the field as it came in (the order of the sweep does not
 * matter). */
#ifndef RPIV_VALIDATE_H
#define RPIV_VALIDATE_H

#include "rpiv/error.h"
#include "rpiv/field.h"

#include <stddef.h>

/* Test the vectors of f flagged RPIV_FLAG_VALID; those rejected get RPIV_FLAG_REPLACED
 * (their values are left for rpiv_validate_replace). Vectors with fewer than two valid
 * neighbours are kept. *nrejected (may be NULL) gets the count. RPIV_EINVAL for threshold
 * <= 0 or eps < 0. */
RPIV_NODISCARD rpiv_status rpiv_validate_median(rpiv_field *f, double threshold, double eps,
                                                size_t *nrejected);

/* Replace every vector flagged RPIV_FLAG_REPLACED (and, if fill_masked, every
 * RPIV_FLAG_MASKED one, keeping its flag) by the component-wise median of its valid 3 x 3
 * neighbours; vectors without any take, in a following sweep, the median of the neighbours
 * filled in the sweep before, and so on outwards. If the field has no valid vector at all,
 * they become 0. *nfilled (may be NULL) gets the number of vectors written. */
RPIV_NODISCARD rpiv_status rpiv_validate_replace(rpiv_field *f, int fill_masked, size_t *nfilled);

/* ---- more tests, inpainting, smoothing (src/piv/validate_more.c, docs/postprocess.md) ----
 * The tests flag RPIV_FLAG_VALID vectors RPIV_FLAG_REPLACED (values left for a replacement)
 * and count them in *nrejected (may be NULL). */

/* Peak ratio (highest / second correlation peak) below min_ratio; a ratio of 0 (unknown)
 * is kept. RPIV_EINVAL for min_ratio < 0. */
RPIV_NODISCARD rpiv_status rpiv_validate_peak_ratio(rpiv_field *f, double min_ratio,
                                                    size_t *nrejected);
/* Global limits, px: u outside [umin, umax] or v outside [vmin, vmax]; a component whose
 * min >= max is not tested. */
RPIV_NODISCARD rpiv_status rpiv_validate_limits(rpiv_field *f, double umin, double umax,
                                                double vmin, double vmax, size_t *nrejected);
/* Global mean +- k std: u or v farther than k standard deviations (of the valid vectors)
 * from their mean. RPIV_EINVAL for k <= 0. */
RPIV_NODISCARD rpiv_status rpiv_validate_std(rpiv_field *f, double k, size_t *nrejected);

/* Replace every RPIV_FLAG_REPLACED vector (and, if fill_masked, every masked one, keeping
 * its flag) by inpainting: the discrete Laplace equation (4-neighbour mean) is solved over
 * them with the valid vectors as boundary values and zero normal gradient at the grid's
 * edge and at masked vectors not filled (successive over-relaxation, started from the
 * median replacement, to a change below 1e-5 px). Gaps of many vectors are filled smoothly;
 * in a gap enclosed by valid vectors a linear field is reproduced exactly (not at the edge,
 * where the zero normal gradient holds). *nfilled as rpiv_validate_replace. */
RPIV_NODISCARD rpiv_status rpiv_validate_inpaint(rpiv_field *f, int fill_masked, size_t *nfilled);

/* Smooth u and v by penalised least squares (Garcia, Comput. Stat. Data Anal. 54:1167,
 * 2010): minimise |W^(1/2) (y_hat - y)|^2 + s |D y_hat|^2 with D the discrete Laplacian
 * (reflective edges), solved with the DCT-II; weight 0 for masked vectors (which keep their
 * values), 1 for the others; with weights 0 the solution is iterated (at most 200 times).
 * s in grid steps^4; 0 leaves f unchanged. RPIV_EINVAL for s < 0. */
RPIV_NODISCARD rpiv_status rpiv_validate_smooth(rpiv_field *f, double s);

#endif /* RPIV_VALIDATE_H */
