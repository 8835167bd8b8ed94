/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image/prep_impl.h - what the preprocessing files share (preprocess.c, prep_local.c,
 * prep_clahe.c). Not installed. */
#ifndef RPIV_PREP_IMPL_H
#define RPIV_PREP_IMPL_H

#include "rpiv/preprocess.h"

#include <string.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

/* What takes CLAHE's output rows while they are in cache: each thread, having written the rows
 * y0..y1-1 of its share ya..yb-1 (in order, whole tile rows), calls rows(ctx, ya, yb, y0, y1). */
typedef struct prep_sink {
    void (*rows)(void *ctx, int ya, int yb, int y0, int y1);
    void *ctx;
} prep_sink;

/* The operations, each on im in place with nt threads (nt >= 1). */
/* clahe: the bins span the low_pct-th to the high_pct-th percentile of im (values outside
 * saturate to the end bins); 0 and 100: im's min and max. sink: NULL, or what takes the
 * output rows (not called if the image is left as it is). */
RPIV_NODISCARD rpiv_status prep_clahe(rpiv_image *im, int tile, double clip, int bins,
                                      double low_pct, double high_pct, int nt,
                                      const prep_sink *sink);
RPIV_NODISCARD rpiv_status prep_highpass(rpiv_image *im, int size, rpiv_prep_background how,
                                         int nt);
/* clahe, then highpass of the sliding minimum (RPIV_PREP_BG_MIN) of window size: the same bits
 * as the two in turn, the cells' minima of the background taken from CLAHE's output rows as
 * they are written (one read of the frame less). */
RPIV_NODISCARD rpiv_status prep_clahe_highpass(rpiv_image *im, int tile, double clip, int bins,
                                               double low_pct, double high_pct, int size, int nt);
RPIV_NODISCARD rpiv_status prep_normalize(rpiv_image *im, int size, int nt);

/* The least and greatest values of row r (w >= 1; a NaN counts only as r[0]): with SSE,
 * min/max instructions on four accumulators of four lanes that do not wait on each other. */
static inline void prep_row_range(const float *r, size_t w, float *lo, float *hi)
{
    float a = r[0], b = r[0];
    size_t x = 0;
#if defined(__SSE2__)
    /* _mm_min_ps(v, m) is v < m ? v : m, the scalar form: a NaN v never replaces m */
    __m128 m0 = _mm_set1_ps(r[0]), m1 = m0, m2 = m0, m3 = m0, M0 = m0, M1 = m0, M2 = m0, M3 = m0;
    for (; x + 16 <= w; x += 16) {
        __m128 v0 = _mm_loadu_ps(r + x), v1 = _mm_loadu_ps(r + x + 4), v2 = _mm_loadu_ps(r + x + 8),
               v3 = _mm_loadu_ps(r + x + 12);
        m0 = _mm_min_ps(v0, m0);
        m1 = _mm_min_ps(v1, m1);
        m2 = _mm_min_ps(v2, m2);
        m3 = _mm_min_ps(v3, m3);
        M0 = _mm_max_ps(v0, M0);
        M1 = _mm_max_ps(v1, M1);
        M2 = _mm_max_ps(v2, M2);
        M3 = _mm_max_ps(v3, M3);
    }
    m0 = _mm_min_ps(_mm_min_ps(m0, m1), _mm_min_ps(m2, m3));
    M0 = _mm_max_ps(_mm_max_ps(M0, M1), _mm_max_ps(M2, M3));
    float lm[4], lM[4];
    _mm_storeu_ps(lm, m0);
    _mm_storeu_ps(lM, M0);
    for (int k = 0; k < 4; k++) {
        a = lm[k] < a ? lm[k] : a;
        b = lM[k] > b ? lM[k] : b;
    }
#endif
    for (; x < w; x++) {
        a = r[x] < a ? r[x] : a;
        b = r[x] > b ? r[x] : b;
    }
    *lo = a;
    *hi = b;
}

/* The smallest and largest value of im (the same as rpiv_image_stats_of's, without its serial
 * sum in double: threads over rows, exact whatever their number). */
static inline void prep_range(const rpiv_image *im, float *lo, float *hi, int nt)
{
    const size_t w = (size_t)im->w, h = (size_t)im->h;
    const float *px = im->px;
    float mn = px[0], mx = px[0];
#pragma omp parallel for schedule(static) num_threads(nt) reduction(min : mn) reduction(max : mx)
    for (size_t y = 0; y < h; y++) {
        float a, b;
        prep_row_range(px + y * w, w, &a, &b);
        mn = a < mn ? a : mn;
        mx = b > mx ? b : mx;
    }
    *lo = mn;
    *hi = mx;
}

/* CLAHE's clipping of one histogram (nbins counts) at limit, as MATLAB's adapthisteq and
 * Zuiderveld 1994: the excess over the limit is redistributed so that no bin ends above the
 * limit: first the whole share excess / nbins to every bin that it does not lift above the
 * limit (the others filled to the limit), then one count at a time on the bins still below
 * it, every step-th bin (step = nbins / what remains, at least 1) from a start that moves on
 * by one bin each round. The total count is kept. The limit must be at least the total over
 * nbins (rounded up), so that the bins can hold it. */
void prep_clahe_clip(size_t *hist, size_t nbins, size_t limit);

#endif /* RPIV_PREP_IMPL_H */
