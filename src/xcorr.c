/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/xcorr.c - FFT cross-correlation of windows: plans once, new-array execute per thread. */
#include "rpiv/xcorr.h"

#include <assert.h>
#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

struct rpiv_xcorr {
    int w, h;
    size_t n, nc;   /* real and complex element counts */
    fftwf_plan fwd; /* r2c, w x h */
    fftwf_plan inv; /* c2r, w x h */
};

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
    x->nc = (size_t)(w / 2 + 1) * (size_t)h;
    float *r = fftwf_malloc(x->n * sizeof *r);
    fftwf_complex *c = fftwf_malloc(x->nc * sizeof *c);
    if (r && c) {
        /* FFTW's row-major n0 x n1 is h rows of w */
        x->fwd = fftwf_plan_dft_r2c_2d(h, w, r, c, FFTW_ESTIMATE);
        x->inv = fftwf_plan_dft_c2r_2d(h, w, c, r, FFTW_ESTIMATE);
    }
    fftwf_free(r);
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
    if (!ws)
        return rpiv_fail(RPIV_ENOMEM, "xcorr: out of memory for a workspace");
    ws->a = fftwf_malloc(x->n * sizeof(float));
    ws->b = fftwf_malloc(x->n * sizeof(float));
    ws->plane = fftwf_malloc(x->n * sizeof(float));
    ws->fa = fftwf_malloc(x->nc * sizeof(fftwf_complex));
    ws->fb = fftwf_malloc(x->nc * sizeof(fftwf_complex));
    if (!ws->a || !ws->b || !ws->plane || !ws->fa || !ws->fb) {
        rpiv_xcorr_work_free(ws);
        return rpiv_fail(RPIV_ENOMEM, "xcorr: out of memory for a %dx%d workspace", x->w, x->h);
    }
    memset(ws->a, 0, x->n * sizeof(float));
    memset(ws->b, 0, x->n * sizeof(float));
    *out = ws;
    return RPIV_OK;
}

void rpiv_xcorr_work_free(rpiv_xcorr_work *ws)
{
    if (!ws)
        return;
    fftwf_free(ws->a);
    fftwf_free(ws->b);
    fftwf_free(ws->plane);
    fftwf_free(ws->fa);
    fftwf_free(ws->fb);
    free(ws);
}

/* Partial sums in LANES independent accumulators, combined in a fixed order at the end: the
 * compiler can keep them in vector registers (a single running sum cannot be vectorised
 * without reassociation), and the result does not depend on anything but the data. Float
 * lanes are enough: a lane sums at most 64 x 64 / 16 = 256 grey levels of 16 bits, and the
 * mean and energy only need ~1e-6 relative precision. */
#define LANES 16

/* Sum of v[0..n-1], n a multiple of LANES or not. */
static double lane_sum(const float *v, size_t n)
{
    float acc[LANES] = {0};
    size_t i = 0;
    for (; i + LANES <= n; i += LANES)
        for (int l = 0; l < LANES; l++)
            acc[l] += v[i + (size_t)l];
    double s = 0;
    for (; i < n; i++)
        s += (double)v[i];
    for (int l = 0; l < LANES; l++)
        s += (double)acc[l];
    return s;
}

/* Subtract m from v[0..n-1]; return the sum of squares of the result. */
static double lane_center(float *v, size_t n, float m)
{
    float acc[LANES] = {0};
    size_t i = 0;
    for (; i + LANES <= n; i += LANES)
        for (int l = 0; l < LANES; l++) {
            float x = v[i + (size_t)l] - m;
            v[i + (size_t)l] = x;
            acc[l] += x * x;
        }
    double e = 0;
    for (; i < n; i++) {
        v[i] -= m;
        e += (double)v[i] * (double)v[i];
    }
    for (int l = 0; l < LANES; l++)
        e += (double)acc[l];
    return e;
}

/* Remove the mean of v[0..n-1] in place; return the sum of squares of the result. */
static double demean(float *v, size_t n)
{
    return lane_center(v, n, (float)(lane_sum(v, n) / (double)n));
}

/* Copy a w x h window from a frame of stride `stride` into dst, summing it on the way, then
 * remove its mean; the energy is returned. */
static double load_demean(float *dst, const float *src, size_t stride, int w, int h)
{
    float acc[LANES] = {0};
    double s = 0;
    for (int j = 0; j < h; j++) {
        const float *a = src + (size_t)j * stride;
        float *d = dst + (size_t)j * (size_t)w;
        int i = 0;
        for (; i + LANES <= w; i += LANES)
            for (int l = 0; l < LANES; l++) {
                float x = a[i + l];
                d[i + l] = x;
                acc[l] += x;
            }
        for (; i < w; i++) {
            d[i] = a[i];
            s += (double)a[i];
        }
    }
    for (int l = 0; l < LANES; l++)
        s += (double)acc[l];
    size_t n = (size_t)w * (size_t)h;
    return lane_center(dst, n, (float)(s / (double)n));
}

/* Transforms, spectrum product, inverse transform, for mean-removed windows. */
static void correlate(const rpiv_xcorr *x, rpiv_xcorr_work *ws, int mode, double e1, double e2)
{
    fftwf_execute_dft_r2c(x->fwd, ws->a, ws->fa);
    fftwf_execute_dft_r2c(x->fwd, ws->b, ws->fb);
    /* R = IDFT(conj(A) B) / n; FFTW's c2r is unnormalised, so fold 1/n (and the energy
     * normalisation) into the spectrum. The DC bin is zeroed: exact mean removal. */
    double sc = 1.0 / (double)x->n;
    if (mode == RPIV_XCORR_NORMALISE)
        sc = (e1 > 0 && e2 > 0) ? sc / sqrt(e1 * e2) : 0;
    const float s = (float)sc;
    const float *fa = ws->fa;
    float *fb = ws->fb;
    for (size_t k = 0; k < 2 * x->nc; k += 2) {
        float ar = fa[k], ai = fa[k + 1], br = fb[k], bi = fb[k + 1];
        fb[k] = (ar * br + ai * bi) * s;
        fb[k + 1] = (ar * bi - ai * br) * s;
    }
    fb[0] = fb[1] = 0;
    fftwf_execute_dft_c2r(x->inv, ws->fb, ws->plane);
}

void rpiv_xcorr_run(const rpiv_xcorr *x, rpiv_xcorr_work *ws, int mode, double *ea, double *eb)
{
    double e1 = demean(ws->a, x->n), e2 = demean(ws->b, x->n);
    correlate(x, ws, mode, e1, e2);
    if (ea)
        *ea = e1;
    if (eb)
        *eb = e2;
}

void rpiv_xcorr_run_from(const rpiv_xcorr *x, rpiv_xcorr_work *ws, const float *a, size_t stride_a,
                         const float *b, size_t stride_b, int mode, double *ea, double *eb)
{
    double e1 = load_demean(ws->a, a, stride_a, x->w, x->h);
    double e2 = load_demean(ws->b, b, stride_b, x->w, x->h);
    correlate(x, ws, mode, e1, e2);
    if (ea)
        *ea = e1;
    if (eb)
        *eb = e2;
}
