/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/deform.c - sampling the spline of a frame and the symmetric deformation of a pair by
 * a predictor, row by row, in vector blocks. The prefilter is deform_prefilter.c, the
 * predictor deform_pred.c. */
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

/* 1 if the deformation takes the frame's sample at the point: where every tap of the cubic
 * B-spline with a non-zero weight is one of the frame's pixels, [1, w - 2] x [1, h - 2]
 * (deform_takes). Nearer the frame's edge the interpolant reads taps the prefilter's mirror
 * boundary made up, a particle cut by the frame is continued by its mirror image, and the
 * two frames, sampled d/2 either side, are so in different ways: the edge windows of a
 * uniform flow had errors of 0.01-0.02 px on noise-free images (docs/piv.md). */
static inline int inside(const spos *p, int w, int h)
{
    return deform_takes((double)p->ix + (double)p->tx, w) &&
           deform_takes((double)p->iy + (double)p->ty, h);
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
    deform_pred_grid_row(p, y, tu, tv);
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

/* ---- the predictor filter adapted to the noise (deform_impl.h) ---------------------------- */
