/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/uncertainty_impl.h - random uncertainty of each vector by correlation statistics
 * (Wieneke 2015; docs/uncertainty.md). */
#ifndef RPIV_SRC_UNCERTAINTY_IMPL_H
#define RPIV_SRC_UNCERTAINTY_IMPL_H

#include "rpiv/field.h"

#include <stddef.h>

/* The largest sigma reported, px: where the statistics cannot be propagated through the
 * peak fit (the noise of the correlation difference as large as the neighbours of the peak),
 * the displacement is not known to better than a pixel. */
#define UNC_SIGMA_MAX 1.0

/* The standard uncertainty (1 sigma, px) of the displacement measured on a window pair: a
 * (rows sa floats apart) and b (sb), w x h, the pair as it was correlated (deformed), the
 * correlation peak at the integer shift (ix, iy). scratch holds w * h floats. Writes *su, *sv
 * in 0..UNC_SIGMA_MAX. */
void unc_cs(const float *a, size_t sa, const float *b, size_t sb, int w, int h, int ix, int iy,
            float *scratch, double *su, double *sv);

/* Add (or find) the quantities sigma_u and sigma_v of f, zeroed; their data to *su, *sv. */
RPIV_NODISCARD rpiv_status unc_add(rpiv_field *f, float **su, float **sv);

/* After validation: a replaced vector takes the RMS sigma of its valid 8-neighbours (the
 * replacement interpolates them), or the largest sigma of the field's valid vectors when it
 * has none; a masked vector has 0. No-op if f has no sigma_u. */
void unc_replaced(rpiv_field *f);

#endif /* RPIV_SRC_UNCERTAINTY_IMPL_H */
