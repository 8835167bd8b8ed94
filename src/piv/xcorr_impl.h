/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/xcorr_impl.h - the correlation's insides, for the tests. */
#ifndef RPIV_SRC_XCORR_IMPL_H
#define RPIV_SRC_XCORR_IMPL_H

#include "rpiv/xcorr.h"

/* rpiv_xcorr_run_pairs with the glue's vector width forced: vl = 4 (SSE2 / NEON code), 8 (the
 * AVX2 code where the CPU has it, else 4) or 0 (the best the CPU has, as the library runs).
 * Both widths give the same bits (tests/test_xcorr.c checks it). */
void xcorr_run_pairs_vl(const rpiv_xcorr *x, rpiv_xcorr_work *ws, const rpiv_xcorr_src *src,
                        int count, int mode, double *e, int vl);

#endif /* RPIV_SRC_XCORR_IMPL_H */
