/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image/prep_local.c - the local filters of preprocessing: the background (sliding
 * minimum, or a Gaussian-like blur) removed by the high-pass, and the local min/max
 * normalisation. Every 2-D window is separable: a 1-D pass along each row, then along each
 * column, ends padded with the end value.
 *
 * Why not GSL's moving-window statistics (gsl_movstat) and Gaussian filter: measured on a
 * 2560 x 2160 pair they cost 12 to 24 times a whole default PIV run of the pair (general
 * accumulators behind function pointers, one double vector per line, columns gathered one
 * by one), where the target is 15 %. The filters here are the classic O(1)-per-sample forms:
 * van Herk / Gil-Werman for the sliding min and max (two running extrema per block of K),
 * running sums in double for the box mean; the column passes work on strips of columns, row
 * after row, so that they run along memory. Each output sample is computed by one thread from the
 * same inputs in the same order: the result does not depend on the thread count. */
#include "prep_impl.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

typedef enum { OP_MIN, OP_MAX, OP_MEAN } line_op;

/* columns per strip in the column passes, which keep a few windows of rows of the strip (K + 1
 * rows for the means, 4 K for min and max): each row's part is a run of 1 KiB along memory */
enum { STRIP = 256 };

static inline float pick(line_op op, float a, float b)
{
    return op == OP_MIN ? (a < b ? a : b) : (a > b ? a : b);
}

static inline size_t clampi(long i, size_t n)
{
    return i < 0 ? 0 : ((size_t)i >= n ? n - 1 : (size_t)i);
}

/* In place, a[i] = the least (OP_MIN) or greatest of a[i .. i+K-1], for i + K <= n, by
 * doubling: the extremum over 2P samples is that of two overlapping windows of P, so
 * log2(K) + 1 passes along memory, each vectorised; tmp: n floats. Extrema are exact: the
 * result is that of any other order. */
static void doubling(float *a, size_t n, size_t K, line_op op, float *tmp)
{
    float *src = a, *dst = tmp;
    size_t P = 1;
    for (; 2 * P <= K; P *= 2) {
        const float *restrict s = src;
        float *restrict d = dst;
        const size_t m = n - P;
        if (op == OP_MIN)
            for (size_t i = 0; i < m; i++)
                d[i] = s[i + P] < s[i] ? s[i + P] : s[i];
        else
            for (size_t i = 0; i < m; i++)
                d[i] = s[i + P] > s[i] ? s[i + P] : s[i];
        float *t = src;
        src = dst;
        dst = t;
    }
    /* the window K from two windows of P (P <= K < 2P), into a */
    const size_t m = n - K + 1, off = K - P;
    if (src == a) { /* an even number of passes: the last level is in a, read it from a copy */
        memcpy(tmp, a, n * sizeof *a);
        src = tmp;
    }
    const float *restrict s = src;
    float *restrict d = a;
    if (op == OP_MIN)
        for (size_t i = 0; i < m; i++)
            d[i] = s[i + off] < s[i] ? s[i + off] : s[i];
    else
        for (size_t i = 0; i < m; i++)
            d[i] = s[i + off] > s[i] ? s[i + off] : s[i];
}

/* The padded row p[0..n+K-2] = x[clamp(i - r)]. */
static void pad_row(const float *x, float *p, size_t n, size_t K)
{
    const size_t r = K / 2;
    for (size_t i = 0; i < r; i++)
        p[i] = x[clampi((long)i - (long)r, n)];
    memcpy(p + r, x, n * sizeof *x);
    for (size_t i = n + r; i < n + 2 * r; i++)
        p[i] = x[clampi((long)i - (long)r, n)];
}

enum { LANES = 4 }; /* rows whose running means advance together */
#if defined(__has_builtin)
#if __has_builtin(__builtin_convertvector)
#define LANES_V 1
#endif
#endif
#ifndef LANES_V
#define LANES_V 0
#endif

/* The mean over K (odd) of LANES rows x[k * stride ...] (n samples each) into the same rows,
 * ends padded with the end values: per row the running sum in double of the original
 * row-by-row pass (the same operations in the same order, so the same bits), the rows
 * interleaved so that the sums advance in vector registers. scratch: 3 LANES (n + K) floats'
 * worth. */
static void row_means(float *x, size_t stride, size_t n, size_t K, float *scratch)
{
    const size_t N = n + K - 1;
    float *q = scratch;                 /* N x LANES, interleaved */
    float *row = scratch + N * LANES;   /* one padded row */
    float *o = scratch + N * LANES + N; /* n x LANES results */
    for (size_t k = 0; k < LANES; k++) {
        pad_row(x + k * stride, row, n, K);
        for (size_t i = 0; i < N; i++)
            q[i * LANES + k] = row[i];
    }
#if defined(__GNUC__) && LANES_V
    /* the four lanes as two vectors of two doubles (GCC's and clang's vector extension):
     * the same IEEE operations lane by lane, two at a time */
    typedef double v2d __attribute__((vector_size(16)));
    typedef float v2f __attribute__((vector_size(8)));
    v2d s0 = {0, 0}, s1 = {0, 0};
    const v2d kk = {(double)K, (double)K};
    for (size_t i = 0; i < K; i++) {
        v2f a, b;
        memcpy(&a, q + i * LANES, sizeof a);
        memcpy(&b, q + i * LANES + 2, sizeof b);
        s0 += __builtin_convertvector(a, v2d);
        s1 += __builtin_convertvector(b, v2d);
    }
    for (size_t j = 0; j < n; j++) {
        if (j > 0) {
            v2f i0, i1, o0, o1;
            memcpy(&i0, q + (j + K - 1) * LANES, sizeof i0);
            memcpy(&i1, q + (j + K - 1) * LANES + 2, sizeof i1);
            memcpy(&o0, q + (j - 1) * LANES, sizeof o0);
            memcpy(&o1, q + (j - 1) * LANES + 2, sizeof o1);
            s0 += __builtin_convertvector(i0, v2d) - __builtin_convertvector(o0, v2d);
            s1 += __builtin_convertvector(i1, v2d) - __builtin_convertvector(o1, v2d);
        }
        v2f r0 = __builtin_convertvector(s0 / kk, v2f), r1 = __builtin_convertvector(s1 / kk, v2f);
        memcpy(o + j * LANES, &r0, sizeof r0);
        memcpy(o + j * LANES + 2, &r1, sizeof r1);
    }
#else
    double s[LANES] = {0};
    for (size_t i = 0; i < K; i++)
        for (size_t k = 0; k < LANES; k++)
            s[k] += (double)q[i * LANES + k];
    for (size_t k = 0; k < LANES; k++)
        o[k] = (float)(s[k] / (double)K);
    for (size_t j = 1; j < n; j++) {
        const float *in = q + (j + K - 1) * LANES, *out = q + (j - 1) * LANES;
        for (size_t k = 0; k < LANES; k++) {
            s[k] += (double)in[k] - (double)out[k];
            o[j * LANES + k] = (float)(s[k] / (double)K);
        }
    }
#endif
    for (size_t k = 0; k < LANES; k++)
        for (size_t j = 0; j < n; j++)
            x[k * stride + j] = o[j * LANES + k];
}

/* One row: x = op over the window of K (odd) samples of src centred on each sample (src may
 * be x), ends padded with the end values; scratch: 3 (n + K) floats. The mean of a single row
 * (the rows left over by row_means), in double as row_means. */
static void row_pass(const float *src, float *x, size_t n, size_t K, line_op op, float *scratch)
{
    const size_t N = n + K - 1;
    float *p = scratch, *tmp = scratch + N + 1;
    pad_row(src, p, n, K);
    if (op == OP_MEAN) {
        double s = 0;
        for (size_t i = 0; i < K; i++)
            s += (double)p[i];
        x[0] = (float)(s / (double)K);
        for (size_t j = 1; j < n; j++) {
            s += (double)p[j + K - 1] - (double)p[j - 1];
            x[j] = (float)(s / (double)K);
        }
        return;
    }
    doubling(p, N, K, op, tmp);
    memcpy(x, p, n * sizeof *x);
}

/* The columns c0..c1-1 of the w x h array a, in place: op over K rows centred on each row.
 * scratch: 4 K STRIP floats for min and max, (K + 1) STRIP floats and STRIP doubles for the
 * mean. */
static void col_pass(float *a, size_t w, size_t h, size_t c0, size_t c1, size_t K, line_op op,
                     float *scratch)
{
    const size_t r = K / 2, N = h + 2 * r, m = c1 - c0;
    if (op == OP_MEAN) {
        /* row by row down the strip, each output row written in place at once: the input rows
         * that leave the window later (row j - r - 1 at step j) are kept in a ring of K + 1
         * rows, slot = padded index i (row clamp(i - r)) mod K + 1 */
        double *s = (double *)scratch;
        float *ring = (float *)(s + STRIP);
        memset(s, 0, m * sizeof *s);
        for (size_t i = 0; i < K; i++) {
            const float *row = a + clampi((long)i - (long)r, h) * w + c0;
            memcpy(ring + (i % (K + 1)) * m, row, m * sizeof *row);
            for (size_t c = 0; c < m; c++)
                s[c] += (double)row[c];
        }
        for (size_t j = 0; j < h; j++) {
            if (j > 0) {
                const float *in = a + clampi((long)(j + r), h) * w + c0; /* not written yet */
                const float *outr = ring + ((j - 1) % (K + 1)) * m;
                memcpy(ring + ((j + K - 1) % (K + 1)) * m, in, m * sizeof *in);
                for (size_t c = 0; c < m; c++)
                    s[c] += (double)in[c] - (double)outr[c];
            }
            float *o = a + j * w + c0;
            for (size_t c = 0; c < m; c++)
                o[c] = (float)(s[c] / (double)K);
        }
        return;
    }
    /* van Herk / Gil-Werman by blocks of K padded rows (padded row i: row clamp(i - r)), row
     * after row down the strip: block b's prefix (g) and suffix (h) extrema, then the output
     * rows j of block b - 1, pick(h[j], g[j + K - 1]) with j + K - 1 in block b - 1 or b,
     * written in place: every padded row that reads row j (j + r, and the clamped ends) is in
     * a block up to b, already read. The operations of the whole-height form, in its order. */
    float *gb[2] = {scratch, scratch + K * m}, *hb[2] = {scratch + 2 * K * m, scratch + 3 * K * m};
    const size_t nb = (N + K - 1) / K;
    for (size_t blk = 0; blk <= nb; blk++) {
        if (blk < nb) {
            float *g = gb[blk & 1], *hh = hb[blk & 1];
            const size_t i0 = blk * K, n = N - i0 < K ? N - i0 : K;
            for (size_t k = 0; k < n; k++) {
                const float *p = a + clampi((long)(i0 + k) - (long)r, h) * w + c0;
                float *gk = g + k * m;
                memcpy(hh + k * m, p, m * sizeof *p);
                if (k == 0)
                    memcpy(gk, p, m * sizeof *gk);
                else
                    for (size_t c = 0; c < m; c++)
                        gk[c] = pick(op, gk[c - m], p[c]);
            }
            for (size_t k = n - 1; k-- > 0;) { /* the block's last row is its own suffix */
                float *hk = hh + k * m;
                for (size_t c = 0; c < m; c++)
                    hk[c] = pick(op, hk[c + m], hk[c]);
            }
        }
        if (blk > 0) {
            const size_t pb = blk - 1;
            for (size_t j = pb * K; j < pb * K + K && j < h; j++) {
                const size_t q = j + K - 1;
                const float *hj = hb[pb & 1] + (j - pb * K) * m,
                            *gq = gb[(q / K) & 1] + (q % K) * m;
                float *o = a + j * w + c0;
                for (size_t c = 0; c < m; c++)
                    o[c] = pick(op, hj[c], gq[c]);
            }
        }
    }
}

/* The odd window of about `size` samples, at most the largest odd number <= 2n - 1. */
static size_t window(int size, size_t n)
{
    size_t K = (size_t)size | 1u, kmax = (2 * n - 1) | 1u;
    return K < kmax ? K : kmax;
}

/* The separable 2-D operations opa on the w x h array a and opb on b (or NULL), rows then
 * columns, in one parallel region: in place, or, if src is not NULL (min and max only), the
 * rows' pass reading src. Each of a and b gets the bits of its operation alone. */
static rpiv_status separable2(const float *src, float *a, line_op opa, float *b, line_op opb, int w,
                              int h, int size, int nt)
{
    const size_t W = (size_t)w, H = (size_t)h;
    const size_t Kx = window(size, W), Ky = window(size, H);
    const size_t per_row = 3 * LANES * (W + Kx) + 2 * (W + Kx),
                 per_col = opa == OP_MEAN ? (Ky + 1) * STRIP + 2 * STRIP : 4 * Ky * STRIP;
    const size_t per = per_row > per_col ? per_row : per_col;
    float *scr = malloc((size_t)nt * per * sizeof *scr);
    if (!scr)
        return rpiv_fail(RPIV_ENOMEM, "preprocess: out of memory for the %dx%d filter", size, size);
    const size_t strip = STRIP, nstrips = (W + strip - 1) / strip;
    /* the means by groups of LANES rows, the rows left over one by one */
    const size_t ngroups = opa == OP_MEAN ? H / LANES : 0, rest0 = ngroups * LANES;
#pragma omp parallel num_threads(nt)
    {
        float *mine = scr + (size_t)omp_get_thread_num() * per;
#pragma omp for schedule(static)
        for (size_t g = 0; g < ngroups; g++) {
            row_means(a + g * LANES * W, W, W, Kx, mine);
            if (b)
                row_means(b + g * LANES * W, W, W, Kx, mine);
        }
#pragma omp for schedule(static)
        for (size_t j = rest0; j < H; j++) {
            row_pass(src ? src + j * W : a + j * W, a + j * W, W, Kx, opa, mine);
            if (b)
                row_pass(src ? src + j * W : b + j * W, b + j * W, W, Kx, opb, mine);
        }
#pragma omp for schedule(static)
        for (size_t s = 0; s < nstrips; s++) {
            size_t c0 = s * strip, c1 = c0 + strip < W ? c0 + strip : W;
            col_pass(a, W, H, c0, c1, Ky, opa, mine);
            if (b)
                col_pass(b, W, H, c0, c1, Ky, opb, mine);
        }
    }
    free(scr);
    return RPIV_OK;
}

static rpiv_status separable(float *a, int w, int h, int size, line_op op, int nt)
{
    return separable2(NULL, a, op, NULL, op, w, h, size, nt);
}

static float *copy_of(const rpiv_image *im)
{
    size_t n = (size_t)im->w * (size_t)im->h;
    float *c = malloc(n * sizeof *c);
    if (c)
        memcpy(c, im->px, n * sizeof *c);
    return c;
}

/* Pixel p between the centres of cells i0 <= i1 (of c px, n cells), weight f of i1. */
static void lerp_at(int p, int c, int n, int *i0, int *i1, float *f)
{
    double t = ((double)p + 0.5) / c - 0.5;
    int a = t <= 0 ? 0 : (int)t;
    a = a > n - 1 ? n - 1 : a;
    *i0 = a;
    *i1 = a + 1 < n ? a + 1 : a;
    *f = t <= 0 || *i1 == a ? 0.0f : (float)(t - a);
}

/* The background of the sliding minimum on a coarse grid: the minima of cells of c x c px
 * (c = half the window), each cell then taking the least of its 3 x 3 neighbourhood (a window
 * of about 1.5 times the size, so a cell with no background pixel borrows its neighbours'),
 * interpolated bilinearly between cell centres and subtracted (clipped at 0). Two passes over
 * the frame instead of four separable sliding-window passes: the cells' minima by bands of c
 * rows (or taken from CLAHE's output rows as it writes them, hp_rows); then in one parallel
 * region the 3 x 3 minima and their interpolation along x by grid rows, the subtraction by
 * image rows. */
typedef struct hp_grid {
    int w, h, c, gx, gy, nspan;
    float *px, *cell, *g, *rowmin, *fxs, *along;
    int *ix, *span;
    unsigned char *done; /* the bands whose cells' minima are in */
} hp_grid;

static void hp_free(hp_grid *q)
{
    free(q->cell);
    free(q->rowmin);
    free(q->ix);
    free(q->span);
    free(q->fxs);
    free(q->along);
    free(q->done);
}

static rpiv_status hp_new(hp_grid *q, rpiv_image *im, int size, int nt)
{
    const int w = im->w, h = im->h, c = size / 2 > 1 ? size / 2 : 1;
    const int gx = (w + c - 1) / c, gy = (h + c - 1) / c;
    *q = (hp_grid){.w = w, .h = h, .c = c, .gx = gx, .gy = gy, .px = im->px};
    q->cell = malloc(2 * (size_t)gx * (size_t)gy * sizeof *q->cell);
    q->rowmin = malloc((size_t)nt * (size_t)w * sizeof *q->rowmin);
    q->ix = malloc(2 * (size_t)w * sizeof *q->ix);
    q->span = malloc(((size_t)w + 1) * sizeof *q->span);
    q->fxs = malloc((size_t)w * sizeof *q->fxs);
    /* each grid row interpolated along x once (it does not depend on the image row): then
     * every image row is a blend of two of these, vectorised */
    q->along = malloc((size_t)gy * (size_t)w * sizeof *q->along);
    q->done = calloc((size_t)gy, 1);
    if (!q->cell || !q->rowmin || !q->ix || !q->span || !q->fxs || !q->along || !q->done) {
        hp_free(q);
        return rpiv_fail(RPIV_ENOMEM, "preprocess: out of memory for the background grid");
    }
    q->g = q->cell + (size_t)gx * (size_t)gy;
    /* cell centres at (i + 0.5) c - 0.5; clamped outside the first and last centres. The
     * column weights are the same for every row: once; the spans of columns between the same
     * two cell centres */
    int nspan = 0;
    for (int x = 0; x < w; x++) {
        lerp_at(x, c, gx, &q->ix[2 * x], &q->ix[2 * x + 1], &q->fxs[x]);
        if (x == 0 || q->ix[2 * x] != q->ix[2 * x - 2] || q->ix[2 * x + 1] != q->ix[2 * x - 1])
            q->span[nspan++] = x;
    }
    q->span[nspan] = w;
    q->nspan = nspan;
    return RPIV_OK;
}

/* The cells' minima of band j (rows j c .. j c + c - 1): the least of each column of its rows,
 * in row order (along memory, in vector registers), then of each cell's c columns. */
static void hp_band(hp_grid *q, int j)
{
    const int w = q->w, c = q->c, y0 = j * c, y1 = y0 + c < q->h ? y0 + c : q->h;
    float *restrict o = q->rowmin + (size_t)omp_get_thread_num() * (size_t)w;
    memcpy(o, q->px + (size_t)y0 * (size_t)w, (size_t)w * sizeof *o);
    for (int y = y0 + 1; y < y1; y++) {
        const float *restrict r = q->px + (size_t)y * (size_t)w;
        for (int x = 0; x < w; x++)
            o[x] = r[x] < o[x] ? r[x] : o[x];
    }
    float *row = q->cell + (size_t)j * (size_t)q->gx;
    for (int i = 0; i < q->gx; i++) {
        int x0 = i * c, x1 = x0 + c < w ? x0 + c : w;
        float m = o[x0];
        for (int x = x0 + 1; x < x1; x++)
            m = o[x] < m ? o[x] : m;
        row[i] = m;
    }
    q->done[j] = 1;
}

/* A prep_sink's rows: the bands that end among the rows y0..y1-1 just written, if the thread's
 * share ya..yb-1 holds the whole band (a band across two shares is left to hp_finish). */
static void hp_rows(void *ctx, int ya, int yb, int y0, int y1)
{
    hp_grid *q = ctx;
    for (int j = y0 / q->c; j * q->c < y1; j++) {
        int end = j * q->c + q->c < q->h ? j * q->c + q->c : q->h;
        if (j * q->c >= ya && end <= yb && end > y0 && end <= y1)
            hp_band(q, j);
    }
}

/* The bands not done yet, the 3 x 3 minima, the background subtracted. */
static void hp_finish(hp_grid *q, int nt)
{
    const int w = q->w, h = q->h, c = q->c, gx = q->gx, gy = q->gy;
    const float *cell = q->cell;
#pragma omp parallel num_threads(nt)
    {
#pragma omp for schedule(static)
        for (int j = 0; j < gy; j++)
            if (!q->done[j])
                hp_band(q, j);
#pragma omp for schedule(static)
        for (int j = 0; j < gy; j++) {
            float *gj = q->g + (size_t)j * (size_t)gx;
            for (int i = 0; i < gx; i++) {
                float m = cell[(size_t)j * (size_t)gx + (size_t)i];
                for (int dj = -1; dj <= 1; dj++)
                    for (int di = -1; di <= 1; di++) {
                        int jj = j + dj, ii = i + di;
                        if (jj >= 0 && jj < gy && ii >= 0 && ii < gx) {
                            float v = cell[(size_t)jj * (size_t)gx + (size_t)ii];
                            m = v < m ? v : m;
                        }
                    }
                gj[i] = m;
            }
            float *t = q->along + (size_t)j * (size_t)w;
            for (int k = 0; k < q->nspan; k++) {
                const int x0 = q->span[k], x1 = q->span[k + 1], i0 = q->ix[2 * x0],
                          i1 = q->ix[2 * x0 + 1];
                const float a0 = gj[i0], da = gj[i1] - gj[i0];
                for (int x = x0; x < x1; x++)
                    t[x] = a0 + q->fxs[x] * da;
            }
        }
#pragma omp for schedule(static)
        for (int y = 0; y < h; y++) {
            int j0, j1;
            float fy;
            lerp_at(y, c, gy, &j0, &j1, &fy);
            const float *restrict top = q->along + (size_t)j0 * (size_t)w;
            const float *restrict bot = q->along + (size_t)j1 * (size_t)w;
            float *restrict r = q->px + (size_t)y * (size_t)w;
            for (int x = 0; x < w; x++) {
                float d = r[x] - (top[x] + fy * (bot[x] - top[x]));
                r[x] = d > 0 ? d : 0;
            }
        }
    }
}

static rpiv_status highpass_coarse_min(rpiv_image *im, int size, int nt)
{
    hp_grid q;
    rpiv_status st = hp_new(&q, im, size, nt);
    if (st)
        return st;
    hp_finish(&q, nt);
    hp_free(&q);
    return RPIV_OK;
}

rpiv_status prep_clahe_highpass(rpiv_image *im, int tile, double clip, int bins, double low_pct,
                                double high_pct, int size, int nt)
{
    hp_grid q;
    rpiv_status st = hp_new(&q, im, size, nt);
    if (st)
        return st;
    const prep_sink sink = {hp_rows, &q};
    st = prep_clahe(im, tile, clip, bins, low_pct, high_pct, nt, &sink);
    if (!st)
        hp_finish(&q, nt);
    hp_free(&q);
    return st;
}

rpiv_status prep_highpass(rpiv_image *im, int size, rpiv_prep_background how, int nt)
{
    if (how == RPIV_PREP_BG_MIN)
        return highpass_coarse_min(im, size, nt);
    size_t n = (size_t)im->w * (size_t)im->h;
    float *bg = copy_of(im);
    if (!bg)
        return rpiv_fail(RPIV_ENOMEM, "preprocess: out of memory for the background");
    /* a Gaussian of standard deviation size / 4 as three box means of width b: each adds
     * (b^2 - 1) / 12 to the variance, so b = sqrt(1 + 4 sigma^2), made odd */
    double sigma = (double)size / 4.0;
    int b = (int)lround(sqrt(1.0 + 4.0 * sigma * sigma));
    b |= 1;
    rpiv_status st = RPIV_OK;
    for (int k = 0; k < 3 && !st; k++)
        st = separable(bg, im->w, im->h, b, OP_MEAN, nt);
    if (!st) {
        float *px = im->px;
#pragma omp parallel for schedule(static) num_threads(nt)
        for (size_t i = 0; i < n; i++) {
            float d = px[i] - bg[i];
            px[i] = d > 0 ? d : 0;
        }
    }
    free(bg);
    return st;
}

rpiv_status prep_normalize(rpiv_image *im, int size, int nt)
{
    float lo, hi;
    prep_range(im, &lo, &hi, nt);
    if (!(hi > lo))
        return RPIV_OK; /* one grey level: nothing to normalise */
    size_t n = (size_t)im->w * (size_t)im->h;
    float *mn = malloc(n * sizeof *mn), *mx = malloc(n * sizeof *mx);
    rpiv_status st = RPIV_OK;
    if (!mn || !mx)
        st = rpiv_fail(RPIV_ENOMEM, "preprocess: out of memory for the normalisation");
    /* the local min and max together (their rows' pass reads the image), then their means */
    if (!st && !(st = separable2(im->px, mn, OP_MIN, mx, OP_MAX, im->w, im->h, size, nt)))
        st = separable2(NULL, mn, OP_MEAN, mx, OP_MEAN, im->w, im->h, size, nt);
    if (!st) {
        /* a floor on the local range: flat regions (no particle in the window) stay dark
         * instead of amplifying their noise to full scale */
        const float floor_range = 1e-2f * (hi - lo);
        float *px = im->px;
#pragma omp parallel for schedule(static) num_threads(nt)
        for (size_t i = 0; i < n; i++) {
            float r = mx[i] - mn[i];
            float v = (px[i] - mn[i]) / (r > floor_range ? r : floor_range);
            px[i] = v < 0 ? 0 : (v > 1 ? 1 : v);
        }
    }
    free(mn);
    free(mx);
    return st;
}
