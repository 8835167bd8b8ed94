/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/xcorr.c - FFT cross-correlation of windows: two window pairs per complex transform,
 * plans once, new-array execute per thread. */
#include "rpiv/xcorr.h"

#include "simd.h"

#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

struct rpiv_xcorr {
    int w, h;
    size_t n;       /* pixels per window */
    fftwf_plan fwd; /* c2c forward, h x w, in place */
    fftwf_plan inv; /* c2c backward, h x w, in place */
};

/* The private buffers behind rpiv_xcorr_work's opaque pointers: complex, n each. */
typedef struct xc_bufs {
    fftwf_complex *z0, *z1; /* packed windows a + i b, then their spectra */
    fftwf_complex *t;       /* the two cross-spectra packed, then the two planes */
} xc_bufs;

rpiv_status rpiv_xcorr_new(int w, int h, rpiv_xcorr **out)
{
    *out = NULL;
    if (w < 4 || h < 4 || w > 4096 || h > 4096)
        return rpiv_fail(RPIV_EINVAL, "xcorr: window %dx%d outside 4..4096 px", w, h);
    rpiv_xcorr *x = calloc(1, sizeof *x);
    if (!x)
        return rpiv_fail(RPIV_ENOMEM, "xcorr: out of memory");
    x->w = w;
    x->h = h;
    x->n = (size_t)w * (size_t)h;
    fftwf_complex *c = fftwf_malloc(x->n * sizeof *c);
    if (c) {
        /* FFTW's row-major n0 x n1 is h rows of w */
        x->fwd = fftwf_plan_dft_2d(h, w, c, c, FFTW_FORWARD, FFTW_ESTIMATE);
        x->inv = fftwf_plan_dft_2d(h, w, c, c, FFTW_BACKWARD, FFTW_ESTIMATE);
    }
    fftwf_free(c);
    if (!x->fwd || !x->inv) {
        rpiv_xcorr_free(x);
        return rpiv_fail(RPIV_ENOMEM, "xcorr: cannot make FFTW plans for %dx%d windows", w, h);
    }
    *out = x;
    return RPIV_OK;
}

void rpiv_xcorr_free(rpiv_xcorr *x)
{
    if (!x)
        return;
    if (x->fwd)
        fftwf_destroy_plan(x->fwd);
    if (x->inv)
        fftwf_destroy_plan(x->inv);
    free(x);
}

void rpiv_xcorr_size(const rpiv_xcorr *x, int *w, int *h)
{
    *w = x->w;
    *h = x->h;
}

rpiv_status rpiv_xcorr_work_new(const rpiv_xcorr *x, rpiv_xcorr_work **out)
{
    *out = NULL;
    rpiv_xcorr_work *ws = calloc(1, sizeof *ws);
    xc_bufs *bf = calloc(1, sizeof *bf);
    if (!ws || !bf) {
        free(ws);
        free(bf);
        return rpiv_fail(RPIV_ENOMEM, "xcorr: out of memory for a workspace");
    }
    ws->priv = bf;
    ws->a = fftwf_malloc(x->n * sizeof(float));
    ws->b = fftwf_malloc(x->n * sizeof(float));
    ws->plane = fftwf_malloc(x->n * sizeof(float));
    ws->plane2 = fftwf_malloc(x->n * sizeof(float));
    ws->a2 = fftwf_malloc(x->n * sizeof(float));
    ws->b2 = fftwf_malloc(x->n * sizeof(float));
    /* one spare complex after each spectrum: see cross_pack */
    bf->z0 = fftwf_malloc((x->n + 1) * sizeof(fftwf_complex));
    bf->z1 = fftwf_malloc((x->n + 1) * sizeof(fftwf_complex));
    bf->t = fftwf_malloc(x->n * sizeof(fftwf_complex));
    if (bf->z0 && bf->z1) {
        memset(bf->z0 + x->n, 0, sizeof(fftwf_complex));
        memset(bf->z1 + x->n, 0, sizeof(fftwf_complex));
    }
    if (!ws->a || !ws->b || !ws->a2 || !ws->b2 || !ws->plane || !ws->plane2 || !bf->z0 || !bf->z1 ||
        !bf->t) {
        rpiv_xcorr_work_free(ws);
        return rpiv_fail(RPIV_ENOMEM, "xcorr: out of memory for a %dx%d workspace", x->w, x->h);
    }
    memset(ws->a, 0, x->n * sizeof(float));
    memset(ws->b, 0, x->n * sizeof(float));
    memset(ws->a2, 0, x->n * sizeof(float));
    memset(ws->b2, 0, x->n * sizeof(float));
    *out = ws;
    return RPIV_OK;
}

void rpiv_xcorr_work_free(rpiv_xcorr_work *ws)
{
    if (!ws)
        return;
    xc_bufs *bf = ws->priv;
    if (bf) {
        fftwf_free(bf->z0);
        fftwf_free(bf->z1);
        fftwf_free(bf->t);
        free(bf);
    }
    fftwf_free(ws->a);
    fftwf_free(ws->b);
    fftwf_free(ws->plane);
    fftwf_free(ws->plane2);
    fftwf_free(ws->a2);
    fftwf_free(ws->b2);
    free(ws);
}

/* The glue around the transforms (packing, cross-spectra, unpacking) is written with GCC/Clang
 * vector extensions, 8 floats (4 complex) at a time, in kernels cloned for AVX2 (simd.h). */
typedef float v8f __attribute__((vector_size(32)));
#define SHUF   __builtin_shufflevector
#define KERNEL RPIV_KERNEL

/* Unaligned access to 8 floats through a vector type that may alias them. */
typedef float v8fu __attribute__((vector_size(32), aligned(4), may_alias));
#define load8(p)     (*(const v8fu *)(p))
#define store8(p, v) (*(v8fu *)(p) = (v))

/* Pack a w x h window pair into z as a + i b (rows of a stride_a floats apart, of b
 * stride_b), remove each window's mean; the energies sum a'^2, sum b'^2 go to e[0], e[1].
 * Sums run in vector lanes combined in a fixed order (even lanes a, odd lanes b): the result
 * depends on nothing but the data. Float lanes are enough: a lane sums at most 64 x 64 / 4
 * grey levels of 16 bits, and the mean and energy only need ~1e-6 relative precision. */
KERNEL static void load_pack(float *restrict z, const float *a, size_t stride_a, const float *b,
                             size_t stride_b, int w, int h, double e[2])
{
    const size_t n2 = 2 * (size_t)w * (size_t)h;
    v8f sa = {0}, sb = {0};
    double s[2] = {0, 0};
    for (int j = 0; j < h; j++) {
        const float *ra = a + (size_t)j * stride_a, *rb = b + (size_t)j * stride_b;
        float *d = z + 2 * (size_t)j * (size_t)w;
        int i = 0;
        for (; i + 8 <= w; i += 8) {
            v8f va = load8(ra + i), vb = load8(rb + i);
            sa += va;
            sb += vb;
            store8(d + 2 * i, SHUF(va, vb, 0, 8, 1, 9, 2, 10, 3, 11));
            store8(d + 2 * i + 8, SHUF(va, vb, 4, 12, 5, 13, 6, 14, 7, 15));
        }
        for (; i < w; i++) {
            d[2 * i] = ra[i];
            d[2 * i + 1] = rb[i];
            s[0] += (double)ra[i];
            s[1] += (double)rb[i];
        }
    }
    for (int l = 0; l < 8; l++) {
        s[0] += (double)sa[l];
        s[1] += (double)sb[l];
    }
    const double n = (double)(n2 / 2);
    const float ma = (float)(s[0] / n), mb = (float)(s[1] / n);
    const v8f m = {ma, mb, ma, mb, ma, mb, ma, mb};
    /* four accumulators: one would make the loop wait on the latency of each addition */
    v8f sq = {0}, sq1 = {0}, sq2 = {0}, sq3 = {0};
    size_t k = 0;
    for (; k + 32 <= n2; k += 32) {
        v8f v0 = load8(z + k) - m, v1 = load8(z + k + 8) - m;
        v8f v2 = load8(z + k + 16) - m, v3 = load8(z + k + 24) - m;
        store8(z + k, v0);
        store8(z + k + 8, v1);
        store8(z + k + 16, v2);
        store8(z + k + 24, v3);
        sq += v0 * v0;
        sq1 += v1 * v1;
        sq2 += v2 * v2;
        sq3 += v3 * v3;
    }
    for (; k + 8 <= n2; k += 8) {
        v8f v = load8(z + k) - m;
        store8(z + k, v);
        sq += v * v;
    }
    sq = (sq + sq1) + (sq2 + sq3);
    e[0] = e[1] = 0;
    for (; k < n2; k++) {
        z[k] -= k & 1 ? mb : ma;
        e[k & 1] += (double)z[k] * (double)z[k];
    }
    for (int l = 0; l < 8; l++)
        e[l & 1] += (double)sq[l];
}

/* Spectra f0 and f1 of packed pairs a + i b -> t = c0 S0 + i c1 S1, where S = conj(A) B is
 * the cross-spectrum of a pair. With P = F(k) and R = F(-k), A(k) = (P + conj R) / 2 and
 * B(k) = (P - conj R) / 2i, so that
 *     Re S = (Re R Im P + Im R Re P) / 2,   Im S = (|R|^2 - |P|^2) / 4.
 * S is Hermitian (its inverse transform is real), so the inverse transform of t carries the
 * correlation of pair 0 in its real part and that of pair 1 in its imaginary part. The DC
 * term is zeroed: exact mean removal. A lone pair passes f1 = f0 with c1 = 0. The spectra
 * hold one spare complex after their end (read, never used, by the row reversal). */
KERNEL static void cross_pack(const float *f0, const float *f1, float *restrict t, int w, int h,
                              float c0, float c1)
{
    const size_t sw = 2 * (size_t)w; /* floats per spectrum row */
    const float a0 = 0.5f * c0, b0 = 0.25f * c0, a1 = 0.5f * c1, b1 = 0.25f * c1;
    const v8f ca = {a0, b0, a0, b0, a0, b0, a0, b0}, cb = {-b1, a1, -b1, a1, -b1, a1, -b1, a1};
    for (int ky = 0; ky < h; ky++) {
        const size_t kr = (size_t)(ky ? h - ky : 0);
        const float *p0 = f0 + (size_t)ky * sw, *q0 = f0 + kr * sw;
        const float *p1 = f1 + (size_t)ky * sw, *q1 = f1 + kr * sw;
        float *tr = t + (size_t)ky * sw;
        int kx = 0;
        if (w % 4 == 0)
            for (; kx < w; kx += 4) {
                /* R at kx..kx+3 is the partner row at w-kx..w-kx-3 (index w is index 0) */
                const size_t o = 2 * (size_t)(w - kx - 3);
                v8f r0 = load8(q0 + o), r1 = load8(q1 + o);
                r0 = SHUF(r0, r0, 6, 7, 4, 5, 2, 3, 0, 1);
                r1 = SHUF(r1, r1, 6, 7, 4, 5, 2, 3, 0, 1);
                if (!kx) {
                    r0[0] = q0[0];
                    r0[1] = q0[1];
                    r1[0] = q1[0];
                    r1[1] = q1[1];
                }
                v8f x0 = load8(p0 + 2 * kx), x1 = load8(p1 + 2 * kx);
                v8f y0 = r0 * r0 - x0 * x0, y1 = r1 * r1 - x1 * x1;
                x0 = r0 * SHUF(x0, x0, 1, 0, 3, 2, 5, 4, 7, 6);
                x1 = r1 * SHUF(x1, x1, 1, 0, 3, 2, 5, 4, 7, 6);
                /* m0 = (Re S0, Im S0) x 2 and x 4, m1 = (Im S1, Re S1) likewise */
                v8f m0 = SHUF(x0, y0, 0, 8, 2, 10, 4, 12, 6, 14) +
                         SHUF(x0, y0, 1, 9, 3, 11, 5, 13, 7, 15);
                v8f m1 = SHUF(y1, x1, 0, 8, 2, 10, 4, 12, 6, 14) +
                         SHUF(y1, x1, 1, 9, 3, 11, 5, 13, 7, 15);
                store8(tr + 2 * kx, ca * m0 + cb * m1);
            }
        for (; kx < w; kx++) { /* widths that are not a multiple of 4 */
            const size_t i = 2 * (size_t)kx, r = 2 * (size_t)(kx ? w - kx : 0);
            float pr = p0[i], pi = p0[i + 1], rr = q0[r], ri = q0[r + 1];
            float sr0 = rr * pi + ri * pr, si0 = (rr * rr - pr * pr) + (ri * ri - pi * pi);
            pr = p1[i];
            pi = p1[i + 1];
            rr = q1[r];
            ri = q1[r + 1];
            float sr1 = rr * pi + ri * pr, si1 = (rr * rr - pr * pr) + (ri * ri - pi * pi);
            tr[i] = a0 * sr0 - b1 * si1;
            tr[i + 1] = b0 * si0 + a1 * sr1;
        }
    }
    t[0] = t[1] = 0;
}

/* The packed planes t (n complex) -> plane0 = Re t * s0 and plane1 = Im t * s1 (plane1 may
 * be NULL). */
KERNEL static void unpack(const float *t, size_t n, float s0, float s1, float *restrict plane0,
                          float *restrict plane1)
{
    size_t i = 0;
    for (; i + 8 <= n; i += 8) {
        v8f u = load8(t + 2 * i), v = load8(t + 2 * i + 8);
        store8(plane0 + i, s0 * SHUF(u, v, 0, 2, 4, 6, 8, 10, 12, 14));
        if (plane1)
            store8(plane1 + i, s1 * SHUF(u, v, 1, 3, 5, 7, 9, 11, 13, 15));
    }
    for (; i < n; i++) {
        plane0[i] = t[2 * i] * s0;
        if (plane1)
            plane1[i] = t[2 * i + 1] * s1;
    }
}

/* The spectrum scale of a pair: 1 / (n sqrt(ea eb)), so that both packed planes come out as
 * correlation coefficients (neither pair's rounding swamps a weaker partner's plane); 0 for
 * a window without contrast. *back gets the factor that restores the mode's plane. */
static float pair_scale(const rpiv_xcorr *x, const double e[2], int mode, float *back)
{
    double g = sqrt(e[0] * e[1]);
    if (!(e[0] > 0 && e[1] > 0) || !(g > 0)) {
        *back = 0;
        return 0;
    }
    *back = mode == RPIV_XCORR_NORMALISE ? 1.0f : (float)g;
    return (float)(1.0 / ((double)x->n * g));
}

void rpiv_xcorr_run_pairs(const rpiv_xcorr *x, rpiv_xcorr_work *ws, const rpiv_xcorr_src *src,
                          int count, int mode, double *e)
{
    xc_bufs *bf = ws->priv;
    const int two = count > 1;
    float back[2] = {0, 0}, c[2] = {0, 0};
    fftwf_complex *z[2] = {bf->z0, bf->z1};
    for (int k = 0; k < (two ? 2 : 1); k++) {
        load_pack((float *)z[k], src[k].a, src[k].stride_a, src[k].b, src[k].stride_b, x->w, x->h,
                  e + 2 * k);
        fftwf_execute_dft(x->fwd, z[k], z[k]);
        c[k] = pair_scale(x, e + 2 * k, mode, &back[k]);
    }
    cross_pack((const float *)bf->z0, (const float *)(two ? bf->z1 : bf->z0), (float *)bf->t, x->w,
               x->h, c[0], c[1]);
    fftwf_execute_dft(x->inv, bf->t, bf->t);
    unpack((const float *)bf->t, x->n, back[0], back[1], ws->plane, two ? ws->plane2 : NULL);
}

void rpiv_xcorr_run_from(const rpiv_xcorr *x, rpiv_xcorr_work *ws, const float *a, size_t stride_a,
                         const float *b, size_t stride_b, int mode, double *ea, double *eb)
{
    const rpiv_xcorr_src src = {a, b, stride_a, stride_b};
    double e[4];
    rpiv_xcorr_run_pairs(x, ws, &src, 1, mode, e);
    if (ea)
        *ea = e[0];
    if (eb)
        *eb = e[1];
}

void rpiv_xcorr_run(const rpiv_xcorr *x, rpiv_xcorr_work *ws, int mode, double *ea, double *eb)
{
    rpiv_xcorr_run_from(x, ws, ws->a, (size_t)x->w, ws->b, (size_t)x->w, mode, ea, eb);
}
