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

#endif /* RPIV_VALIDATE_H */
