/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/validate_impl.h - the median test with a thread count, for the PIV engine. Not
 * installed. */
#ifndef RPIV_VALIDATE_IMPL_H
#define RPIV_VALIDATE_IMPL_H

#include "rpiv/validate.h"

/* rpiv_validate_median on nthreads threads (<= 0: OpenMP's default); the same result for any
 * count. */
RPIV_NODISCARD rpiv_status validate_median_nt(rpiv_field *f, double threshold, double eps,
                                              size_t *nrejected, int nthreads);

#endif /* RPIV_VALIDATE_IMPL_H */
