/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/deform_prefilter.c - the cubic B-spline prefilter: a frame's samples into the
 * coefficients of its interpolating spline (mirror boundaries), in place. */
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
/* Columns per task in the column pass: a fixed split, so results do not depend on threads. */
#define COLBLOCK 64

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
