/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/deform.c - cubic B-spline prefilter and sampling; field predictor; symmetric deformation. */
#include "rpiv/deform.h"

#include "deform_impl.h"

#include <math.h>
#include <omp.h>
#if defined(__x86_64__) || defined(__SSE2__)
#include <immintrin.h>
#endif
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* The pole of the cubic B-spline prefilter, z = sqrt(3) - 2, and the filter's gain. */
#define POLE (-0.267949192431122706472553658494127633)
#define GAIN 6.0
/* Causal initialisation horizon: |z|^HORIZON < 1e-9. */
#define HORIZON 16
/* Ghost nodes around a predictor's grid: the prefilter's mirror boundary sits this far out,
 * where its effect on the evaluated range (RPIV_DEFORM_GHOST steps) is below 1e-6. */
#define PAD 16
/* Columns per task in the column pass: a fixed split, so results do not depend on threads. */
#define COLBLOCK 64

static int nthr(int n)
{
    return n > 0 ? n : omp_get_max_threads();
}

/* Causal initial value c+(0) for the mirror-extended signal s[0], s[stride], ... (n >= 2). */
static double causal_init(const float *s, int n, size_t stride)
{
    const double z = POLE;
    if (n > HORIZON) {
        double zk = 1, sum = 0;
        for (int k = 0; k < HORIZON; k++) {
            sum += zk * (double)s[(size_t)k * stride];
            zk *= z;
        }
        return sum;
    }
    /* exact for the mirror extension of period 2n-2 (Unser's initial causal coefficient) */
    double zn1 = pow(z, n - 1), zk = z, zr = zn1 * zn1 / z;
    double sum = (double)s[0] + zn1 * (double)s[(size_t)(n - 1) * stride];
    for (int k = 1; k < n - 1; k++) {
        sum += (zk + zr) * (double)s[(size_t)k * stride];
        zk *= z;
        zr /= z;
    }
    return sum / (1.0 - zn1 * zn1);
}

/* Prefilter lines in place: rows y0..y0+nl-1 (nl <= 4) of a w-wide image, their recursions
 * interleaved so that the nl independent dependency chains overlap in the pipeline (one
 * line's recursion is latency-bound). Each line gets exactly the arithmetic of a lone line. */
static void prefilter_lines4(float *img, int w, int y0, int nl)
{
    const float z = (float)POLE, g = (float)GAIN;
    float *c[4];
    if (w < 2)
        return;
    for (int l = 0; l < nl; l++) {
        c[l] = img + (size_t)(y0 + l) * (size_t)w;
        for (int k = 0; k < w; k++)
            c[l][k] *= g;
        c[l][0] = (float)causal_init(c[l], w, 1);
    }
    if (nl == 4) {
        float *c0 = c[0], *c1 = c[1], *c2 = c[2], *c3 = c[3];
        for (int k = 1; k < w; k++) {
            c0[k] += z * c0[k - 1];
            c1[k] += z * c1[k - 1];
            c2[k] += z * c2[k - 1];
            c3[k] += z * c3[k - 1];
        }
    } else {
        for (int l = 0; l < nl; l++)
            for (int k = 1; k < w; k++)
                c[l][k] += z * c[l][k - 1];
    }
    for (int l = 0; l < nl; l++)
        c[l][w - 1] = (float)((POLE / (POLE * POLE - 1.0)) *
                              ((double)c[l][w - 1] + POLE * (double)c[l][w - 2]));
    if (nl == 4) {
        float *c0 = c[0], *c1 = c[1], *c2 = c[2], *c3 = c[3];
        for (int k = w - 2; k >= 0; k--) {
            c0[k] = z * (c0[k + 1] - c0[k]);
            c1[k] = z * (c1[k + 1] - c1[k]);
            c2[k] = z * (c2[k + 1] - c2[k]);
            c3[k] = z * (c3[k + 1] - c3[k]);
        }
    } else {
        for (int l = 0; l < nl; l++)
            for (int k = w - 2; k >= 0; k--)
                c[l][k] = z * (c[l][k + 1] - c[l][k]);
    }
}

/* Prefilter lines in place: rows y0..y0+nl-1 (nl <= LINES) of a w-wide image, their
 * recursions interleaved so that the nl independent dependency chains overlap in the pipeline
 * (one line's recursion is latency-bound). Each line gets exactly the arithmetic of a lone
 * line. */
#define LINES 8
static void prefilter_lines(float *img, int w, int y0, int nl)
{
    const float z = (float)POLE, g = (float)GAIN;
    float *c[LINES];
    if (w < 2)
        return;
    /* the gain: on the samples causal_init reads first, on the others within the recursion
     * (the same product, rounded the same, added the same) */
    const int k0 = w > HORIZON ? HORIZON : w;
    for (int l = 0; l < nl; l++) {
        c[l] = img + (size_t)(y0 + l) * (size_t)w;
        for (int k = 0; k < k0; k++)
            c[l][k] *= g;
        c[l][0] = (float)causal_init(c[l], w, 1);
        for (int k = 1; k < k0; k++)
            c[l][k] += z * c[l][k - 1];
    }
    if (nl == LINES) {
        float *c0 = c[0], *c1 = c[1], *c2 = c[2], *c3 = c[3], *c4 = c[4], *c5 = c[5], *c6 = c[6],
              *c7 = c[7];
        for (int k = k0; k < w; k++) {
            c0[k] = g * c0[k] + z * c0[k - 1];
            c1[k] = g * c1[k] + z * c1[k - 1];
            c2[k] = g * c2[k] + z * c2[k - 1];
            c3[k] = g * c3[k] + z * c3[k - 1];
            c4[k] = g * c4[k] + z * c4[k - 1];
            c5[k] = g * c5[k] + z * c5[k - 1];
            c6[k] = g * c6[k] + z * c6[k - 1];
            c7[k] = g * c7[k] + z * c7[k - 1];
        }
    } else {
        for (int l = 0; l < nl; l++)
            for (int k = k0; k < w; k++)
                c[l][k] = g * c[l][k] + z * c[l][k - 1];
    }
    for (int l = 0; l < nl; l++)
        c[l][w - 1] = (float)((POLE / (POLE * POLE - 1.0)) *
                              ((double)c[l][w - 1] + POLE * (double)c[l][w - 2]));
    if (nl == LINES) {
        float *c0 = c[0], *c1 = c[1], *c2 = c[2], *c3 = c[3], *c4 = c[4], *c5 = c[5], *c6 = c[6],
              *c7 = c[7];
        for (int k = w - 2; k >= 0; k--) {
            c0[k] = z * (c0[k + 1] - c0[k]);
            c1[k] = z * (c1[k + 1] - c1[k]);
            c2[k] = z * (c2[k + 1] - c2[k]);
            c3[k] = z * (c3[k + 1] - c3[k]);
            c4[k] = z * (c4[k + 1] - c4[k]);
            c5[k] = z * (c5[k + 1] - c5[k]);
            c6[k] = z * (c6[k + 1] - c6[k]);
            c7[k] = z * (c7[k + 1] - c7[k]);
        }
    } else {
        for (int l = 0; l < nl; l++)
            for (int k = w - 2; k >= 0; k--)
                c[l][k] = z * (c[l][k + 1] - c[l][k]);
    }
}

#if defined(__SSE2__)
/* Rows per group of the transposed row pass. */
#define TROWS 16

/* Prefilter rows y0..y0+TROWS-1 of a w-wide image (w >= 2) in place, 4 columns at a time
 * through 4 x 4 transposes: lane l of a column vector is row 4 q + l, so each step of the
 * recursion advances 4 rows with one vector operation, 4 such chains in flight. The first
 * samples (up to the causal horizon), the last one and the columns left over by the 4 x 4
 * tiles are done per row as in prefilter_lines; every value gets exactly its arithmetic. */
static void prefilter_rows_t(float *img, int w, int y0)
{
    const float z = (float)POLE, g = (float)GAIN;
    const __m128 vz = _mm_set1_ps(z), vg = _mm_set1_ps(g);
    float *c[TROWS];
    __m128 prev[TROWS / 4];
    const int k0 = w > HORIZON ? HORIZON : w;
    for (int l = 0; l < TROWS; l++) {
        c[l] = img + (size_t)(y0 + l) * (size_t)w;
        for (int k = 0; k < k0; k++)
            c[l][k] *= g;
        c[l][0] = (float)causal_init(c[l], w, 1);
        for (int k = 1; k < k0; k++)
            c[l][k] += z * c[l][k - 1];
    }
    for (int q = 0; q < TROWS / 4; q++)
        prev[q] = _mm_setr_ps(c[4 * q][k0 - 1], c[4 * q + 1][k0 - 1], c[4 * q + 2][k0 - 1],
                              c[4 * q + 3][k0 - 1]);
    int k = k0;
    for (; k + 4 <= w; k += 4)
        for (int q = 0; q < TROWS / 4; q++) {
            float *const *r = c + 4 * q;
            __m128 t0 = _mm_loadu_ps(r[0] + k), t1 = _mm_loadu_ps(r[1] + k);
            __m128 t2 = _mm_loadu_ps(r[2] + k), t3 = _mm_loadu_ps(r[3] + k);
            _MM_TRANSPOSE4_PS(t0, t1, t2, t3);
            t0 = _mm_add_ps(_mm_mul_ps(vg, t0), _mm_mul_ps(vz, prev[q]));
            t1 = _mm_add_ps(_mm_mul_ps(vg, t1), _mm_mul_ps(vz, t0));
            t2 = _mm_add_ps(_mm_mul_ps(vg, t2), _mm_mul_ps(vz, t1));
            t3 = _mm_add_ps(_mm_mul_ps(vg, t3), _mm_mul_ps(vz, t2));
            prev[q] = t3;
            _MM_TRANSPOSE4_PS(t0, t1, t2, t3);
            _mm_storeu_ps(r[0] + k, t0);
            _mm_storeu_ps(r[1] + k, t1);
            _mm_storeu_ps(r[2] + k, t2);
            _mm_storeu_ps(r[3] + k, t3);
        }
    for (int l = 0; l < TROWS; l++)
        for (int kk = k; kk < w; kk++)
            c[l][kk] = g * c[l][kk] + z * c[l][kk - 1];
    for (int l = 0; l < TROWS; l++)
        c[l][w - 1] = (float)((POLE / (POLE * POLE - 1.0)) *
                              ((double)c[l][w - 1] + POLE * (double)c[l][w - 2]));
    __m128 *next = prev;
    for (int q = 0; q < TROWS / 4; q++)
        next[q] = _mm_setr_ps(c[4 * q][w - 1], c[4 * q + 1][w - 1], c[4 * q + 2][w - 1],
                              c[4 * q + 3][w - 1]);
    k = w - 2; /* the next column to do, downwards */
    for (; k >= 3; k -= 4)
        for (int q = 0; q < TROWS / 4; q++) {
            float *const *r = c + 4 * q;
            const int s = k - 3;
            __m128 t0 = _mm_loadu_ps(r[0] + s), t1 = _mm_loadu_ps(r[1] + s);
            __m128 t2 = _mm_loadu_ps(r[2] + s), t3 = _mm_loadu_ps(r[3] + s);
            _MM_TRANSPOSE4_PS(t0, t1, t2, t3);
            t3 = _mm_mul_ps(vz, _mm_sub_ps(next[q], t3));
            t2 = _mm_mul_ps(vz, _mm_sub_ps(t3, t2));
            t1 = _mm_mul_ps(vz, _mm_sub_ps(t2, t1));
            t0 = _mm_mul_ps(vz, _mm_sub_ps(t1, t0));
            next[q] = t0;
            _MM_TRANSPOSE4_PS(t0, t1, t2, t3);
            _mm_storeu_ps(r[0] + s, t0);
            _mm_storeu_ps(r[1] + s, t1);
            _mm_storeu_ps(r[2] + s, t2);
            _mm_storeu_ps(r[3] + s, t3);
        }
    for (int l = 0; l < TROWS; l++)
        for (int kk = k; kk >= 0; kk--)
            c[l][kk] = z * (c[l][kk + 1] - c[l][kk]);
}
#else
#define TROWS 0
#endif

/* Prefilter columns i0..i1-1 of a w x h image in place, all columns of the block together. */
static void prefilter_cols(float *img, int w, int h, int i0, int i1)
{
    const float z = (float)POLE, g = (float)GAIN;
    const size_t sw = (size_t)w;
    int nb = i1 - i0;
    float first[COLBLOCK], cn[COLBLOCK];
    for (int i = 0; i < nb; i++)
        first[i] = (float)(GAIN * causal_init(img + i0 + i, h, sw));
    for (int i = 0; i < nb; i++)
        img[(size_t)i0 + (size_t)i] = first[i];
    for (int k = 1; k < h; k++) {
        float *row = img + (size_t)k * sw + i0;
        const float *prev = row - sw;
        for (int i = 0; i < nb; i++)
            row[i] = g * row[i] + z * prev[i];
    }
    float *last = img + (size_t)(h - 1) * sw + i0, *before = last - sw;
    for (int i = 0; i < nb; i++)
        cn[i] =
            (float)((POLE / (POLE * POLE - 1.0)) * ((double)last[i] + POLE * (double)before[i]));
    for (int i = 0; i < nb; i++)
        last[i] = cn[i];
    for (int k = h - 2; k >= 0; k--) {
        float *row = img + (size_t)k * sw + i0;
        const float *next = row + sw;
        for (int i = 0; i < nb; i++)
            row[i] = z * (next[i] - row[i]);
    }
}

void deform_prefilter_ref(float *img, int w, int h, int nthreads)
{
    int nt = nthr(nthreads);
#pragma omp parallel num_threads(nt)
    {
#pragma omp for schedule(static)
        for (int g = 0; g < (h + 3) / 4; g++)
            prefilter_lines4(img, w, 4 * g, 4 * g + 4 <= h ? 4 : h - 4 * g);
        if (h >= 2) {
#pragma omp for schedule(static)
            for (int b = 0; b < (w + COLBLOCK - 1) / COLBLOCK; b++) {
                int i0 = b * COLBLOCK, i1 = i0 + COLBLOCK < w ? i0 + COLBLOCK : w;
                prefilter_cols(img, w, h, i0, i1);
            }
        }
    }
}

/* The column pass over the columns i0..i1-1 of a w-wide image, in pieces that sweep whole
 * rows of the slab (contiguous memory, which the hardware prefetches; the blocks of
 * prefilter_cols jump a row's length at every step). Each column gets exactly the arithmetic
 * of prefilter_cols: the causal sums of causal_init, in the same order, run over the columns
 * side by side. */

/* The causal start: row 0 = GAIN sum_k z^k row k over the horizon (the rows already
 * filtered along x). acc holds i1 - i0 doubles. */
static void slab_causal_start(float *img, int w, int i0, int i1, double *acc)
{
    const size_t sw = (size_t)w;
    const int nb = i1 - i0;
    double zk = 1;
    for (int i = 0; i < nb; i++)
        acc[i] = 0;
    for (int k = 0; k < HORIZON; k++) {
        const float *row = img + (size_t)k * sw + i0;
        for (int i = 0; i < nb; i++)
            acc[i] += zk * (double)row[i];
        zk *= POLE;
    }
    float *row = img + i0;
    for (int i = 0; i < nb; i++)
        row[i] = (float)(GAIN * acc[i]);
}

/* Rows k0..k1-1 (k0 >= 1) advanced by the causal recursion. */
static void slab_causal_rows(float *img, int w, int i0, int i1, int k0, int k1)
{
    const float z = (float)POLE, g = (float)GAIN;
    const size_t sw = (size_t)w;
    for (int k = k0; k < k1; k++) {
        float *cur = img + (size_t)k * sw + i0;
        const float *prev = cur - sw;
        for (int i = 0; i < i1 - i0; i++)
            cur[i] = g * cur[i] + z * prev[i];
    }
}

/* The anticausal recursion of the h rows, from the last one up. */
static void slab_anticausal(float *img, int w, int h, int i0, int i1)
{
    const float z = (float)POLE;
    const size_t sw = (size_t)w;
    const int nb = i1 - i0;
    float *last = img + (size_t)(h - 1) * sw + i0, *before = last - sw;
    for (int i = 0; i < nb; i++)
        last[i] =
            (float)((POLE / (POLE * POLE - 1.0)) * ((double)last[i] + POLE * (double)before[i]));
    for (int k = h - 2; k >= 0; k--) {
        float *cur = img + (size_t)k * sw + i0;
        const float *next = cur + sw;
        for (int i = 0; i < nb; i++)
            cur[i] = z * (next[i] - cur[i]);
    }
}

/* The column pass of the columns i0..i1-1 of a w x h image (h > HORIZON) in place. */
static void prefilter_slab(float *img, int w, int h, int i0, int i1, double *acc)
{
    slab_causal_start(img, w, i0, i1, acc);
    slab_causal_rows(img, w, i0, i1, 1, h);
    slab_anticausal(img, w, h, i0, i1);
}

void rpiv_deform_prefilter(float *img, int w, int h, int nthreads)
{
    int nt = nthr(nthreads);
    /* the column pass in slabs of whole rows: one per thread, in multiples of 16 columns (the
     * split does not change any column's arithmetic) */
    int slab = ((w + nt - 1) / nt + 15) / 16 * 16, nslab = (w + slab - 1) / slab;
    double *acc = h > HORIZON ? malloc((size_t)nslab * (size_t)slab * sizeof *acc) : NULL;
#pragma omp parallel num_threads(nt)
    {
        /* groups of TROWS rows through transposed tiles, then the rest LINES at a time */
        const int nt16 = TROWS && w >= 2 ? h / (TROWS ? TROWS : 1) : 0, done = nt16 * TROWS;
#if TROWS
#pragma omp for schedule(static)
        for (int gi = 0; gi < nt16; gi++)
            prefilter_rows_t(img, w, TROWS * gi);
#endif
#pragma omp for schedule(static)
        for (int gi = 0; gi < (h - done + LINES - 1) / LINES; gi++) {
            const int y0 = done + LINES * gi;
            prefilter_lines(img, w, y0, y0 + LINES <= h ? LINES : h - y0);
        }
        if (acc) {
#pragma omp for schedule(static)
            for (int b = 0; b < nslab; b++) {
                int i0 = b * slab, i1 = i0 + slab < w ? i0 + slab : w;
                prefilter_slab(img, w, h, i0, i1, acc + (size_t)b * (size_t)slab);
            }
        } else if (h >= 2) { /* short columns (exact initialisation), or no memory */
#pragma omp for schedule(static)
            for (int b = 0; b < (w + COLBLOCK - 1) / COLBLOCK; b++) {
                int i0 = b * COLBLOCK, i1 = i0 + COLBLOCK < w ? i0 + COLBLOCK : w;
                prefilter_cols(img, w, h, i0, i1);
            }
        }
    }
    free(acc);
}

#if TROWS
/* Prefilter a whole frame (w >= 2, h > HORIZON) on one thread in two sweeps over its memory
 * instead of three: down the frame, each group of rows is filtered along the rows and then,
 * still in cache, advanced by the causal column recursion; then the anticausal column
 * recursion up the frame. acc holds w doubles. Every value gets the arithmetic of
 * rpiv_deform_prefilter (the row pass of prefilter_rows_t / prefilter_lines, the column
 * pass of prefilter_slab over all columns). */
static void prefilter_fused(float *img, int w, int h, double *acc)
{
    const int n16 = h / TROWS;
    int done = 0, next = 0; /* rows filtered along x; next row of the column recursion */
    for (int gi = 0; done < h; gi++) {
        if (gi < n16) {
            prefilter_rows_t(img, w, TROWS * gi);
            done += TROWS;
        } else {
            const int nl = done + LINES <= h ? LINES : h - done;
            prefilter_lines(img, w, done, nl);
            done += nl;
        }
        if (!next && done >= HORIZON) {
            slab_causal_start(img, w, 0, w, acc);
            next = 1;
        }
        if (next) {
            slab_causal_rows(img, w, 0, w, next, done);
            next = done;
        }
    }
    slab_anticausal(img, w, h, 0, w);
}
#endif

void deform_prefilter_pair(float *a, float *b, int w, int h, int nthreads)
{
    const int nt = nthr(nthreads);
    double *acc = NULL;
#if TROWS
    /* up to two threads: a frame each, fused; more: each frame split between all of them */
    if (nt <= 2 && w >= 2 && h > HORIZON)
        acc = malloc(2 * (size_t)w * sizeof *acc);
    if (acc) {
#pragma omp parallel for schedule(static) num_threads(nt)
        for (int k = 0; k < 2; k++)
            prefilter_fused(k ? b : a, w, h, acc + (size_t)k * (size_t)w);
        free(acc);
        return;
    }
#endif
    rpiv_deform_prefilter(a, w, h, nt);
    rpiv_deform_prefilter(b, w, h, nt);
}

/* Cubic B-spline weights for taps -1, 0, 1, 2 at fraction t in [0, 1). */
static inline void bweights(float t, float wt[4])
{
    float t2 = t * t, t3 = t2 * t, s = 1.0f - t;
    wt[0] = s * s * s * (1.0f / 6.0f);
    wt[1] = (2.0f / 3.0f) - t2 + 0.5f * t3;
    wt[3] = t3 * (1.0f / 6.0f);
    wt[2] = 1.0f - wt[0] - wt[1] - wt[3];
}

/* Mirror (whole-sample symmetric) index into 0..n-1, for |i| within one period. */
static inline int mirror(int i, int n)
{
    if (n == 1)
        return 0;
    int p = 2 * n - 2;
    i %= p;
    if (i < 0)
        i += p;
    return i < n ? i : p - i;
}

/* Four floats in a vector register (GCC/Clang vector extension; SSE2 on x86-64, NEON on
 * arm64): the 4 taps of a cubic B-spline along x. */
typedef float v4f __attribute__((vector_size(16)));

static inline v4f load4(const float *p)
{
    v4f v;
    memcpy(&v, p, sizeof v);
    return v;
}

/* The weights of taps -1, 0, 1, 2 as one vector: w(t) = ((C3 t + C2) t + C1) t + C0. */
static inline v4f vweights(float t)
{
    const v4f c0 = {1.0f / 6, 2.0f / 3, 1.0f / 6, 0}, c1 = {-0.5f, 0, 0.5f, 0},
              c2 = {0.5f, -1, 0.5f, 0}, c3 = {-1.0f / 6, 0.5f, -0.5f, 1.0f / 6};
    return ((c3 * t + c2) * t + c1) * t + c0;
}

/* floor of a float of modest magnitude, without a libm call (SSE2 has no round). */
static inline int ifloor(float v)
{
    int i = (int)v;
    return (float)i > v ? i - 1 : i;
}

/* A sample point xi + ox (xi integer, ox a small offset): integer tap base and fraction. */
typedef struct spos {
    int ix, iy;
    float tx, ty;
} spos;

static inline spos locate(int xi, int yi, float ox, float oy)
{
    int fx = ifloor(ox), fy = ifloor(oy);
    return (spos){xi + fx, yi + fy, ox - (float)fx, oy - (float)fy};
}

/* 1 if the point lies in [-0.5, w - 0.5] x [-0.5, h - 0.5]. */
static inline int inside(const spos *p, int w, int h)
{
    return !(p->ix < -1 || (p->ix == -1 && p->tx < 0.5f) || p->ix > w - 1 ||
             (p->ix == w - 1 && p->tx > 0.5f) || p->iy < -1 || (p->iy == -1 && p->ty < 0.5f) ||
             p->iy > h - 1 || (p->iy == h - 1 && p->ty > 0.5f));
}

/* The interpolant at a located point inside the image with the tap weights wx, wy: 4 x 4 taps,
 * mirrored at the edges; summed over the rows, then over the columns. */
static inline float sample_w(const float *c, int w, int h, const spos *p, v4f wx, v4f wy)
{
    const size_t sw = (size_t)w;
    v4f acc;
    if (p->ix >= 1 && p->ix + 2 < w && p->iy >= 1 && p->iy + 2 < h) {
        const float *r = c + (size_t)(p->iy - 1) * sw + (size_t)(p->ix - 1);
        acc = wy[0] * load4(r) + wy[1] * load4(r + sw) + wy[2] * load4(r + 2 * sw) +
              wy[3] * load4(r + 3 * sw);
    } else {
        int cx[4];
        for (int k = 0; k < 4; k++)
            cx[k] = mirror(p->ix - 1 + k, w);
        acc = (v4f){0, 0, 0, 0};
        for (int m = 0; m < 4; m++) {
            const float *r = c + (size_t)mirror(p->iy - 1 + m, h) * sw;
            v4f row = {r[cx[0]], r[cx[1]], r[cx[2]], r[cx[3]]};
            acc += wy[m] * row;
        }
    }
    acc *= wx;
    return (acc[0] + acc[1]) + (acc[2] + acc[3]);
}

/* bweights as a vector. */
static inline v4f bweights4(float t)
{
    float wt[4];
    bweights(t, wt);
    return (v4f){wt[0], wt[1], wt[2], wt[3]};
}

/* The interpolant at a located point inside the image (the weights of bweights, which the
 * vector blocks compute lane by lane). */
static inline float sample_at(const float *c, int w, int h, const spos *p)
{
    return sample_w(c, w, h, p, bweights4(p->tx), bweights4(p->ty));
}

/* The same with the weights of vweights: the per-pixel code the blocks replaced. */
static inline float sample_at_ref(const float *c, int w, int h, const spos *p)
{
    return sample_w(c, w, h, p, vweights(p->tx), vweights(p->ty));
}

float rpiv_deform_sample(const float *coef, int w, int h, double x, double y, float fill)
{
    if (!(x >= -0.5 && x <= w - 0.5 && y >= -0.5 && y <= h - 0.5))
        return fill;
    double fx = floor(x), fy = floor(y);
    spos p = locate((int)fx, (int)fy, (float)(x - fx), (float)(y - fy));
    return sample_at(coef, w, h, &p);
}

/* ---- predictor ----------------------------------------------------------------------------- */

struct rpiv_deform_pred {
    int nx, ny; /* padded grid size (field + 2 * PAD) */
    double x0, y0, dx, dy;
    float *cu, *cv; /* spline coefficients, ny x nx */
    int w, h;       /* image size */
    double shift;   /* rows and columns evaluated at pixel + shift */
    float maxabs;   /* largest |coefficient|: the interpolant's bound (convex weights) */
    int *ix, *iy;   /* first tap per pixel column / row */
    float *wx, *wy; /* 4 weights per pixel column / row */
    float *wxs;     /* the column weights by tap: wxs[k * w + x] = wx[4 * x + k] */
    int *runend;    /* first column after x whose first tap differs from ix[x] */
};

void rpiv_deform_pred_free(rpiv_deform_pred *p)
{
    if (!p)
        return;
    free(p->cu);
    free(p->cv);
    free(p->ix);
    free(p->iy);
    free(p->wx);
    free(p->wy);
    free(p->wxs);
    free(p->runend);
    free(p);
}

/* Value k >= 0 along a line of n samples, linearly continued beyond its end. */
static double ext(const float *g, int n, size_t stride, int k)
{
    if (k <= n - 1)
        return (double)g[(size_t)k * stride];
    if (n == 1)
        return (double)g[0];
    double e = (double)g[(size_t)(n - 1) * stride], d = e - (double)g[(size_t)(n - 2) * stride];
    return e + (k - (n - 1)) * d;
}

/* Fill the G ghosts on both sides of a line whose n real samples start at g (stride). */
static void ghosts(float *g, int n, size_t stride)
{
    const int G = PAD;
    float *rev = g + (size_t)(n - 1) * stride;
    for (int k = 1; k <= G; k++) {
        double lo = 2.0 * (double)g[0] - ext(g, n, stride, k);
        /* the far end: the same rule on the reversed line */
        double hi;
        if (k <= n - 1)
            hi = 2.0 * (double)rev[0] - (double)rev[-(ptrdiff_t)((size_t)k * stride)];
        else if (n == 1)
            hi = (double)rev[0];
        else {
            double e = (double)g[0], d = e - (double)g[stride];
            hi = 2.0 * (double)rev[0] - (e + (k - (n - 1)) * d);
        }
        g[-(ptrdiff_t)((size_t)k * stride)] = (float)lo;
        rev[(size_t)k * stride] = (float)hi;
    }
}

/* Real grid coordinate t (0 = first node of n) clamped to RPIV_DEFORM_GHOST steps beyond the
 * grid; first tap *i0 in padded coordinates and the four weights. */
static void tap(double t, int n, int *i0, float wt[4])
{
    const double lo = -RPIV_DEFORM_GHOST, hi = n - 1 + RPIV_DEFORM_GHOST;
    t = t < lo ? lo : (t > hi ? hi : t);
    double ft = floor(t);
    int i = (int)ft;
    bweights((float)(t - ft), wt);
    *i0 = i - 1 + PAD;
}

rpiv_status rpiv_deform_pred_new(const rpiv_field *f, int w, int h, double shift,
                                 rpiv_deform_pred **out)
{
    const int G = PAD;
    *out = NULL;
    if (w < 1 || h < 1)
        return rpiv_fail(RPIV_EINVAL, "deform: image size %dx%d", w, h);
    rpiv_deform_pred *p = calloc(1, sizeof *p);
    if (!p)
        return rpiv_fail(RPIV_ENOMEM, "deform: out of memory for the predictor");
    p->nx = f->nx + 2 * G;
    p->ny = f->ny + 2 * G;
    p->x0 = f->x0;
    p->y0 = f->y0;
    p->dx = f->dx;
    p->dy = f->dy;
    p->w = w;
    p->h = h;
    p->shift = shift;
    size_t n = (size_t)p->nx * (size_t)p->ny, snx = (size_t)p->nx;
    p->cu = malloc(n * sizeof *p->cu);
    p->cv = malloc(n * sizeof *p->cv);
    p->ix = malloc((size_t)w * sizeof *p->ix);
    p->iy = malloc((size_t)h * sizeof *p->iy);
    p->wx = malloc((size_t)w * 4 * sizeof *p->wx);
    p->wy = malloc((size_t)h * 4 * sizeof *p->wy);
    p->wxs = malloc((size_t)w * 4 * sizeof *p->wxs);
    p->runend = malloc((size_t)w * sizeof *p->runend);
    if (!p->cu || !p->cv || !p->ix || !p->iy || !p->wx || !p->wy || !p->wxs || !p->runend) {
        rpiv_deform_pred_free(p);
        return rpiv_fail(RPIV_ENOMEM, "deform: out of memory for the predictor");
    }
    for (int c = 0; c < 2; c++) {
        float *g = c ? p->cv : p->cu;
        const float *src = c ? f->v : f->u;
        for (int j = 0; j < f->ny; j++) {
            float *row = g + (size_t)(j + G) * snx + G;
            memcpy(row, src + (size_t)j * (size_t)f->nx, (size_t)f->nx * sizeof *row);
            ghosts(row, f->nx, 1);
        }
        for (int i = 0; i < p->nx; i++)
            ghosts(g + (size_t)G * snx + (size_t)i, f->ny, snx);
        rpiv_deform_prefilter(g, p->nx, p->ny, 1);
        for (size_t k = 0; k < n; k++) {
            float a = fabsf(g[k]);
            p->maxabs = a > p->maxabs ? a : p->maxabs;
        }
    }
    for (int x = 0; x < w; x++)
        tap((x + shift - f->x0) / f->dx, f->nx, &p->ix[x], p->wx + 4 * (size_t)x);
    for (int y = 0; y < h; y++)
        tap((y + shift - f->y0) / f->dy, f->ny, &p->iy[y], p->wy + 4 * (size_t)y);
    for (int x = 0; x < w; x++)
        for (int k = 0; k < 4; k++)
            p->wxs[(size_t)k * (size_t)w + (size_t)x] = p->wx[4 * (size_t)x + (size_t)k];
    for (int x = w - 1; x >= 0; x--)
        p->runend[x] = x + 1 < w && p->ix[x + 1] == p->ix[x] ? p->runend[x + 1] : x + 1;
    *out = p;
    return RPIV_OK;
}

void rpiv_deform_pred_eval(const rpiv_deform_pred *p, double x, double y, double *u, double *v)
{
    int i0, j0;
    float wx[4], wy[4];
    tap((x - p->x0) / p->dx, p->nx - 2 * PAD, &i0, wx);
    tap((y - p->y0) / p->dy, p->ny - 2 * PAD, &j0, wy);
    double su = 0, sv = 0;
    for (int m = 0; m < 4; m++) {
        size_t r = (size_t)(j0 + m) * (size_t)p->nx + (size_t)i0;
        double ru = 0, rv = 0;
        for (int k = 0; k < 4; k++) {
            ru += (double)wx[k] * (double)p->cu[r + (size_t)k];
            rv += (double)wx[k] * (double)p->cv[r + (size_t)k];
        }
        su += (double)wy[m] * ru;
        sv += (double)wy[m] * rv;
    }
    *u = su;
    *v = sv;
}

size_t rpiv_deform_pred_scratch(const rpiv_deform_pred *p)
{
    return 2 * (size_t)p->nx;
}

/* The grid rows of the predictor combined for image row y: tu[k], tv[k] for the nx columns. */
static void pred_grid_row(const rpiv_deform_pred *p, int y, float *tu, float *tv)
{
    const size_t snx = (size_t)p->nx;
    const float *wy = p->wy + 4 * (size_t)y;
    const float *ru = p->cu + (size_t)p->iy[y] * snx, *rv = p->cv + (size_t)p->iy[y] * snx;
    for (size_t k = 0; k < snx; k++) {
        tu[k] =
            wy[0] * ru[k] + wy[1] * ru[k + snx] + wy[2] * ru[k + 2 * snx] + wy[3] * ru[k + 3 * snx];
        tv[k] =
            wy[0] * rv[k] + wy[1] * rv[k + snx] + wy[2] * rv[k + 2 * snx] + wy[3] * rv[k + 3 * snx];
    }
}

void deform_pred_row_ref(const rpiv_deform_pred *p, int y, int x0, int x1, float *u, float *v,
                         float *scratch)
{
    float *tu = scratch, *tv = scratch + (size_t)p->nx;
    pred_grid_row(p, y, tu, tv);
    for (int x = x0; x < x1; x++) {
        const float *wx = p->wx + 4 * (size_t)x, *a = tu + p->ix[x], *b = tv + p->ix[x];
        u[x - x0] = wx[0] * a[0] + wx[1] * a[1] + wx[2] * a[2] + wx[3] * a[3];
        v[x - x0] = wx[0] * b[0] + wx[1] * b[1] + wx[2] * b[2] + wx[3] * b[3];
    }
}

#define ALWAYS_INLINE static inline __attribute__((always_inline))

size_t deform_row_scratch(const rpiv_deform_pred *p, int x0, int x1)
{
    return 2 * (size_t)(x1 - x0) + rpiv_deform_pred_scratch(p);
}

/* The 4 x 4 taps at a located point whose taps all lie inside the image. */
static inline float sample_inner(const float *c, size_t sw, const spos *p)
{
    v4f wx = vweights(p->tx), wy = vweights(p->ty);
    const float *r = c + (size_t)(p->iy - 1) * sw + (size_t)(p->ix - 1);
    v4f acc = wy[0] * load4(r) + wy[1] * load4(r + sw) + wy[2] * load4(r + 2 * sw) +
              wy[3] * load4(r + 3 * sw);
    acc *= wx;
    return (acc[0] + acc[1]) + (acc[2] + acc[3]);
}

void deform_row_ref(const float *coef_a, const float *coef_b, int w, int h,
                    const rpiv_deform_pred *p, int x0, int x1, int y, float fill_a, float fill_b,
                    float *ra, float *rb, float *scratch)
{
    const size_t nw = (size_t)(x1 - x0);
    const float c = (float)p->shift;
    float *pu = scratch, *pv = pu + nw, *tmp = pv + nw;
    deform_pred_row_ref(p, y, x0, x1, pu, pv, tmp);
    /* The columns whose samples in both frames have all their taps inside the image take
     * the short path (no bounds test, no mirroring). The predictor is a convex combination
     * of its spline coefficients, so |p| <= maxabs (with a margin for rounding). */
    float m = 0.5f * p->maxabs * 1.001f + c + 1.0f;
    int xa = x1, xb = x1; /* the short path covers [xa, xb) */
    if (m < 1e6f && (float)y - m >= 1.0f && (float)y + m <= (float)(h - 3)) {
        float lo = 1.0f + m, hi = (float)(w - 3) - m;
        xa = lo > (float)x0 ? (int)ceilf(lo) : x0;
        xb = hi < (float)(x1 - 1) ? (int)floorf(hi) + 1 : x1;
        if (xa > xb)
            xa = xb = x1;
    }
    const size_t sw = (size_t)w;
    for (int x = x0; x < x1; x++) {
        float hx = 0.5f * pu[x - x0], hy = 0.5f * pv[x - x0];
        spos pa = locate(x, y, c - hx, c - hy), pb = locate(x, y, c + hx, c + hy);
        if (x >= xa && x < xb) {
            ra[x] = sample_inner(coef_a, sw, &pa);
            rb[x] = sample_inner(coef_b, sw, &pb);
        } else if (inside(&pa, w, h) && inside(&pb, w, h)) {
            ra[x] = sample_at_ref(coef_a, w, h, &pa);
            rb[x] = sample_at_ref(coef_b, w, h, &pb);
        } else { /* a particle here has no partner in the other frame */
            ra[x] = fill_a;
            rb[x] = fill_b;
        }
    }
}

/* Per pixel, for the columns [xs, xe) of row y: the samples of the frames not done yet
 * (done_a, done_b: that frame's block was computed; its points are then inside), or the
 * fill values where either point falls outside its frame. */
static void pixels(const float *coef_a, const float *coef_b, int w, int h, float c, const float *pu,
                   const float *pv, int xs, int xe, int y, float fill_a, float fill_b, float *ra,
                   float *rb, int done_a, int done_b)
{
    for (int x = xs; x < xe; x++) {
        float hx = 0.5f * pu[x - xs], hy = 0.5f * pv[x - xs];
        spos pa = locate(x, y, c - hx, c - hy), pb = locate(x, y, c + hx, c + hy);
        if ((done_a || inside(&pa, w, h)) && (done_b || inside(&pb, w, h))) {
            if (!done_a)
                ra[x] = sample_at(coef_a, w, h, &pa);
            if (!done_b)
                rb[x] = sample_at(coef_b, w, h, &pb);
        } else { /* a particle here has no partner in the other frame */
            ra[x] = fill_a;
            rb[x] = fill_b;
        }
    }
}

/* ---- vector blocks -------------------------------------------------------------------------
 * The samples of VL consecutive pixels of a row computed together, one pixel per lane of a
 * GCC/Clang vector: VL = 4 (SSE2, NEON) everywhere, VL = 8 (AVX2) where the CPU has it. Every
 * lane performs exactly the float operations, in the same order, that sample_at performs for
 * its pixel, so the blocks give the same bits as the per-pixel code, whatever the block
 * width and however a row is cut (no contraction into FMAs: ISO C mode, and no FMA in the
 * targets). */
#if defined(__GNUC__) && !defined(__clang__)
/* The helpers taking and returning vectors are always inlined: no call crosses an ABI. */
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

typedef int32_t v4i __attribute__((vector_size(16)));

#define DB_VL     4
#define DB_VF     v4f
#define DB_VI     v4i
#define DB_(name) name##_4
#define DB_TARGET
#if defined(__SSE2__)
#define DB_ALLZERO(e)                                                                              \
    (_mm_movemask_epi8(_mm_cmpeq_epi32((__m128i)(e), _mm_setzero_si128())) == 0xFFFF)
#else
static inline int allzero4(v4i e)
{
    return !(e[0] | e[1] | e[2] | e[3]);
}
#define DB_ALLZERO(e) allzero4(e)
#endif
#define DB_GATHER(c, idx) ((v4f){(c)[(idx)[0]], (c)[(idx)[1]], (c)[(idx)[2]], (c)[(idx)[3]]})
#include "deform_block.h"

#if defined(__x86_64__) && defined(__GNUC__)
#define DEFORM_AVX2 1
typedef float v8f __attribute__((vector_size(32)));
typedef int32_t v8i __attribute__((vector_size(32)));
#define DB_VL             8
#define DB_VF             v8f
#define DB_VI             v8i
#define DB_(name)         name##_8
#define DB_TARGET         __attribute__((target("avx2")))
#define DB_ALLZERO(e)     _mm256_testz_si256((__m256i)(e), (__m256i)(e))
#define DB_GATHER(c, idx) ((v8f)_mm256_i32gather_ps((c), (__m256i)(idx), 4))
#define DB_FLOOR(o)       ((v8f)_mm256_floor_ps((__m256)(o)))
#include "deform_block.h"
#endif

void rpiv_deform_pred_row(const rpiv_deform_pred *p, int y, int x0, int x1, float *u, float *v,
                          float *scratch)
{
    float *tu = scratch, *tv = scratch + (size_t)p->nx;
    pred_grid_row(p, y, tu, tv);
#ifdef DEFORM_AVX2
    if (__builtin_cpu_supports("avx2"))
        pred_runs_8(p, tu, tv, x0, x1, u, v);
    else
#endif
        pred_runs_4(p, tu, tv, x0, x1, u, v);
}

void deform_row_blocks(int vl, const float *coef_a, const float *coef_b, int w, int h,
                       const rpiv_deform_pred *p, int x0, int x1, int y, float fill_a, float fill_b,
                       float *ra, float *rb, float *scratch)
{
    const size_t nw = (size_t)(x1 - x0);
    const float c = (float)p->shift;
    float *pu = scratch, *pv = pu + nw, *tmp = pv + nw;
    rpiv_deform_pred_row(p, y, x0, x1, pu, pv, tmp);
    int x = x0;
    /* |p| <= maxabs (the predictor is a convex combination of its coefficients): a bounded
     * predictor keeps the integer conversions of the blocks in range. */
    if (vl > 0 && 0.5f * p->maxabs * 1.001f + c + 1.0f < 1e6f) {
#ifdef DEFORM_AVX2
        if (vl >= 8 && __builtin_cpu_supports("avx2"))
            x = blocks_8(coef_a, coef_b, w, h, c, pu, pv, x0, x1, y, fill_a, fill_b, ra, rb);
        else
#endif
            x = blocks_4(coef_a, coef_b, w, h, c, pu, pv, x0, x1, y, fill_a, fill_b, ra, rb);
    }
    pixels(coef_a, coef_b, w, h, c, pu + (x - x0), pv + (x - x0), x, x1, y, fill_a, fill_b, ra, rb,
           0, 0);
}

void deform_row(const float *coef_a, const float *coef_b, int w, int h, const rpiv_deform_pred *p,
                int x0, int x1, int y, float fill_a, float fill_b, float *ra, float *rb,
                float *scratch)
{
    deform_row_blocks(8, coef_a, coef_b, w, h, p, x0, x1, y, fill_a, fill_b, ra, rb, scratch);
}

rpiv_status rpiv_deform_run(const float *coef_a, const float *coef_b, int w, int h,
                            const rpiv_deform_pred *p, const int rect[4], float fill_a,
                            float fill_b, float *out_a, float *out_b, int nthreads)
{
    int x0 = rect[0], y0 = rect[1], x1 = rect[2], y1 = rect[3];
    if (x0 < 0 || y0 < 0 || x1 > w || y1 > h || x0 >= x1 || y0 >= y1 || p->w != w || p->h != h)
        return rpiv_fail(RPIV_EINVAL, "deform: rectangle %d,%d,%d,%d outside the %dx%d image", x0,
                         y0, x1, y1, w, h);
    int nt = nthr(nthreads);
    size_t per = deform_row_scratch(p, x0, x1);
    float *scr = malloc((size_t)nt * per * sizeof *scr);
    if (!scr)
        return rpiv_fail(RPIV_ENOMEM, "deform: out of memory");
#pragma omp parallel num_threads(nt)
    {
        float *mine = scr + (size_t)omp_get_thread_num() * per;
#pragma omp for schedule(static)
        for (int y = y0; y < y1; y++)
            deform_row(coef_a, coef_b, w, h, p, x0, x1, y, fill_a, fill_b,
                       out_a + (size_t)y * (size_t)w, out_b + (size_t)y * (size_t)w, mine);
    }
    free(scr);
    return RPIV_OK;
}
