/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/xcorr.c - FFT cross-correlation of windows: two window pairs per complex transform,
 * plans once, new-array execute per thread. */
#include "rpiv/xcorr.h"

#include "xcorr_impl.h"

#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

struct rpiv_xcorr {
    int w, h;
    size_t n;       /* pixels per window */
    fftwf_plan fwd; /* c2c forward, h x w, in place */
    fftwf_plan inv; /* c2c backward, h x w, in place */
    int width;      /* vector width of the glue, 4 or 8 floats (glue_width) */
};

/* The private buffers behind rpiv_xcorr_work's opaque pointers: complex, n each. */
typedef struct xc_bufs {
    fftwf_complex *z0, *z1; /* packed windows a + i b, then their spectra */
    fftwf_complex *t;       /* the two cross-spectra packed, then the two planes */
} xc_bufs;

static int glue_width(int vl);

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
    x->width = glue_width(0);
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
    ws->colmax = fftwf_malloc(2 * (size_t)x->w * sizeof(float));
    ws->colmax2 = ws->colmax ? ws->colmax + x->w : NULL;
    /* one spare complex after each spectrum: see cross_pack */
    bf->z0 = fftwf_malloc((x->n + 1) * sizeof(fftwf_complex));
    bf->z1 = fftwf_malloc((x->n + 1) * sizeof(fftwf_complex));
    bf->t = fftwf_malloc((x->n + 1) * sizeof(fftwf_complex)); /* spare: cross_pack */
    if (bf->z0 && bf->z1) {
        memset(bf->z0 + x->n, 0, sizeof(fftwf_complex));
        memset(bf->z1 + x->n, 0, sizeof(fftwf_complex));
    }
    if (!ws->a || !ws->b || !ws->a2 || !ws->b2 || !ws->plane || !ws->plane2 || !ws->colmax ||
        !bf->z0 || !bf->z1 || !bf->t) {
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
    fftwf_free(ws->colmax);
    free(ws);
}

/* The glue around the transforms is written with GCC/Clang vector extensions in
 * xcorr_pack.h, included twice: 8 floats (4 complex) at a time for CPUs with AVX2, chosen at
 * run time, and 4 at a time (SSE2, NEON) otherwise; both give the same bits (the header
 * says why).
 *
 * The cross-spectra (cross_pack): from the spectra f0 and f1 of packed pairs a + i b,
 * t = c0 S0 + i c1 S1, where S = conj(A) B is the cross-spectrum of a pair. With P = F(k)
 * and R = F(-k),
 *     A(k) = (P + conj R) / 2,   B(k) = (P - conj R) / 2i,   so that
 *     Re S = (Re R Im P + Im R Re P) / 2,   Im S = (|R|^2 - |P|^2) / 4.
 * S is Hermitian (its inverse transform is real), so the inverse transform of t carries the
 * correlation of pair 0 in its real part and that of pair 1 in its imaginary part. The DC
 * term is zeroed: exact mean removal. A lone pair passes f1 = f0 with c1 = 0. The spectra
 * hold one spare complex after their end (read, never used, by the row reversal); so does t
 * (written, never used, by the halved loop). */
#define SHUF __builtin_shufflevector

typedef float v4f __attribute__((vector_size(16)));
typedef float v4fu __attribute__((vector_size(16), aligned(4), may_alias));
#define XG_VL     4
#define XG_VF     v4f
#define XG_VU     v4fu
#define XG_(name) name##_4
#define XG_TARGET
#define XG_REV(r)    SHUF(r, r, 2, 3, 0, 1)
#define XG_SWAP(x)   SHUF(x, x, 1, 0, 3, 2)
#define XG_PE(a, b)  SHUF(a, b, 0, 4, 2, 6)
#define XG_PO(a, b)  SHUF(a, b, 1, 5, 3, 7)
#define XG_ZLO(a, b) SHUF(a, b, 0, 4, 1, 5)
#define XG_ZHI(a, b) SHUF(a, b, 2, 6, 3, 7)
#define XG_EV(a, b)  SHUF(a, b, 0, 2, 4, 6)
#define XG_OD(a, b)  SHUF(a, b, 1, 3, 5, 7)
#include "xcorr_pack.h"

#if defined(__x86_64__) && defined(__GNUC__) && !defined(RPIV_NO_CLONES)
#define XCORR_AVX2 1
typedef float v8f __attribute__((vector_size(32)));
typedef float v8fu __attribute__((vector_size(32), aligned(4), may_alias));
#define XG_VL        8
#define XG_VF        v8f
#define XG_VU        v8fu
#define XG_(name)    name##_8
#define XG_TARGET    __attribute__((target("avx2")))
#define XG_REV(r)    SHUF(r, r, 6, 7, 4, 5, 2, 3, 0, 1)
#define XG_SWAP(x)   SHUF(x, x, 1, 0, 3, 2, 5, 4, 7, 6)
#define XG_PE(a, b)  SHUF(a, b, 0, 8, 2, 10, 4, 12, 6, 14)
#define XG_PO(a, b)  SHUF(a, b, 1, 9, 3, 11, 5, 13, 7, 15)
#define XG_ZLO(a, b) SHUF(a, b, 0, 8, 1, 9, 2, 10, 3, 11)
#define XG_ZHI(a, b) SHUF(a, b, 4, 12, 5, 13, 6, 14, 7, 15)
#define XG_EV(a, b)  SHUF(a, b, 0, 2, 4, 6, 8, 10, 12, 14)
#define XG_OD(a, b)  SHUF(a, b, 1, 3, 5, 7, 9, 11, 13, 15)
#include "xcorr_pack.h"
#endif

/* The glue's width: 8 where the CPU has AVX2 (and it is built), else 4; a request (vl = 4 or
 * 8, from the tests) is honoured as far as the CPU allows. */
static int glue_width(int vl)
{
#ifdef XCORR_AVX2
    if (vl != 4 && __builtin_cpu_supports("avx2"))
        return 8;
#endif
    (void)vl;
    return 4;
}

#ifdef XCORR_AVX2
#define GLUE(vl, name, ...) ((vl) == 8 ? name##_8(__VA_ARGS__) : name##_4(__VA_ARGS__))
#else
#define GLUE(vl, name, ...) ((void)(vl), name##_4(__VA_ARGS__))
#endif

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

void xcorr_run_pairs_vl(const rpiv_xcorr *x, rpiv_xcorr_work *ws, const rpiv_xcorr_src *src,
                        int count, int mode, double *e, int vl)
{
    xc_bufs *bf = ws->priv;
    const int two = count > 1, width = vl ? glue_width(vl) : x->width;
    float back[2] = {0, 0}, c[2] = {0, 0};
    fftwf_complex *z[2] = {bf->z0, bf->z1};
    for (int k = 0; k < (two ? 2 : 1); k++) {
        GLUE(width, load_pack, (float *)z[k], src[k].a, src[k].stride_a, src[k].b, src[k].stride_b,
             x->w, x->h, e + 2 * k);
        fftwf_execute_dft(x->fwd, z[k], z[k]);
        c[k] = pair_scale(x, e + 2 * k, mode, &back[k]);
    }
    GLUE(width, cross_pack, (const float *)bf->z0, (const float *)(two ? bf->z1 : bf->z0),
         (float *)bf->t, x->w, x->h, c[0], c[1]);
    fftwf_execute_dft(x->inv, bf->t, bf->t);
    GLUE(width, unpack, (const float *)bf->t, x->w, x->h, back[0], back[1], ws->plane,
         two ? ws->plane2 : NULL, ws->colmax, ws->colmax2);
}

void rpiv_xcorr_run_pairs(const rpiv_xcorr *x, rpiv_xcorr_work *ws, const rpiv_xcorr_src *src,
                          int count, int mode, double *e)
{
    xcorr_run_pairs_vl(x, ws, src, count, mode, e, 0);
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
