/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/deform_impl.h - one row of a symmetric deformation, for callers that deform strips of
 * rows into their own buffers (the PIV passes). */
#ifndef RPIV_SRC_DEFORM_IMPL_H
#define RPIV_SRC_DEFORM_IMPL_H

#include "rpiv/deform.h"

#include <stddef.h>

/* Floats of scratch deform_row needs for the columns x0..x1-1. */
size_t deform_row_scratch(const rpiv_deform_pred *p, int x0, int x1);

/* Row y of rpiv_deform_run, columns x0..x1-1: ra[x], rb[x] for x0 <= x < x1 (ra and rb point
 * at the start of the output rows). Single-threaded; thread-safe with distinct scratch. */
void deform_row(const float *coef_a, const float *coef_b, int w, int h, const rpiv_deform_pred *p,
                int x0, int x1, int y, float fill_a, float fill_b, float *ra, float *rb,
                float *scratch);

#endif /* RPIV_SRC_DEFORM_IMPL_H */
