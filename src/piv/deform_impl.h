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

/* deform_row with vector blocks of at most vl pixels: 0 (none, every pixel alone), 4, or 8
 * (where the CPU has AVX2, else 4). deform_row is vl = 8; all give the same bits. */
void deform_row_blocks(int vl, const float *coef_a, const float *coef_b, int w, int h,
                       const rpiv_deform_pred *p, int x0, int x1, int y, float fill_a, float fill_b,
                       float *ra, float *rb, float *scratch);

/* The per-pixel code the blocks replaced (same arguments), kept as the reference of the
 * tests and the benchmark: its tap weights are computed in another order (vweights), so its
 * results differ from deform_row's in the last bits. The prefilter's and the predictor rows'
 * references give the same bits as rpiv_deform_prefilter and rpiv_deform_pred_row. */
void deform_row_ref(const float *coef_a, const float *coef_b, int w, int h,
                    const rpiv_deform_pred *p, int x0, int x1, int y, float fill_a, float fill_b,
                    float *ra, float *rb, float *scratch);
void deform_prefilter_ref(float *img, int w, int h, int nthreads);

/* rpiv_deform_prefilter of both frames of a pair, the same bits; with one or two threads, a
 * frame per thread in two sweeps over its memory instead of three. */
void deform_prefilter_pair(float *a, float *b, int w, int h, int nthreads);
void deform_pred_row_ref(const rpiv_deform_pred *p, int y, int x0, int x1, float *u, float *v,
                         float *scratch);

#endif /* RPIV_SRC_DEFORM_IMPL_H */
