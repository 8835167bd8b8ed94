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
    size_t n, nc;  /* real and complex element counts */
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

/* Remove the mean of v[0..n-1] in place; return sum of squares of the result. Sums in double
 * (16-bit grey levels squared over a 64 x 64 window exceed float's 24 bits). */
static double demean(float *v, size_t n)
{
    double s = 0;
    for (size_t i = 0; i < n; i++)
        s += (double)v[i];
    float m = (float)(s / (double)n);
    double e = 0;
    for (size_t i = 0; i < n; i++) {
        v[i] -= m;
        e += (double)v[i] * (double)v[i];
    }
    return e;
}

void rpiv_xcorr_run(const rpiv_xcorr *x, rpiv_xcorr_work *ws, int mode, double *ea, double *eb)
{
    double e1 = demean(ws->a, x->n), e2 = demean(ws->b, x->n);
    fftwf_execute_dft_r2c(x->fwd, ws->a, ws->fa);
    fftwf_execute_dft_r2c(x->fwd, ws->b, ws->fb);
    /* R = IDFT(conj(A) B) / n; FFTW's c2r is unnormalised, so fold 1/n (and the energy
     * normalisation) into the spectrum. The DC bin is zeroed: exact mean removal. */
    double sc = 1.0 / (double)x->n;
    if (mode == RPIV_XCORR_NORMALISE)
        sc = (e1 > 0 && e2 > 0) ? sc / sqrt(e1 * e2) : 0;
    float s = (float)sc;
    float *fa = ws->fa, *fb = ws->fb;
    for (size_t k = 0; k < x->nc; k++) {
        float ar = fa[2 * k], ai = fa[2 * k + 1], br = fb[2 * k], bi = fb[2 * k + 1];
        fb[2 * k] = (ar * br + ai * bi) * s;
        fb[2 * k + 1] = (ar * bi - ai * br) * s;
    }
    fb[0] = fb[1] = 0;
    fftwf_execute_dft_c2r(x->inv, ws->fb, ws->plane);
    if (ea)
        *ea = e1;
    if (eb)
        *eb = e2;
}
