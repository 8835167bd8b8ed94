/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/validate_impl.h - the median test with a thread count, for the PIV engine. Not
 * installed. */
#ifndef RPIV_VALIDATE_IMPL_H
#define RPIV_VALIDATE_IMPL_H

#include "rpiv/piv.h"
#include "rpiv/validate.h"

/* rpiv_validate_median on nthreads threads (<= 0: OpenMP's default); the same result for any
 * count. lines = 1: a vector failing the 3 x 3 test is kept if it agrees with its neighbours
 * along a row, a column or a diagonal (1 and 2 steps either way), as the extrema of a
 * resolved shear layer do and outliers do not. */
RPIV_NODISCARD rpiv_status validate_median_nt(rpiv_field *f, double threshold, double eps,
                                              int lines, size_t *nrejected, int nthreads);

/* rpiv_validate_replace; lines = 1: a vector is replaced by the medians of the grid line
 * (row, column or diagonal, 1 and 2 steps either way, at least 2 usable) along which the
 * field varies least, where there is one, else by the 3 x 3 block's. */
RPIV_NODISCARD rpiv_status validate_replace_lines(rpiv_field *f, int fill_masked, int lines,
                                                  size_t *nfilled);

/* The tests of p beyond the median (peak ratio, limits, std; validate_more.c), each if on. */
RPIV_NODISCARD rpiv_status validate_more(rpiv_field *f, const rpiv_piv_params *p);

#endif /* RPIV_VALIDATE_IMPL_H */
