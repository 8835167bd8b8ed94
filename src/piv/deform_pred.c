/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/deform_pred.c - the field predictor: the cubic spline through a vector field (ghost
 * nodes linearly continued), evaluated at pixels, with per-row and per-column taps. */
#include "rpiv/deform.h"

#include "deform_impl.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

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

double deform_edge_curv(const float *g, int n, ptrdiff_t stride, double t)
{
    if (n < 4)
        return 0;
    const double c0 = (double)g[0] - 2.0 * (double)g[stride] + (double)g[2 * stride],
                 c1 = (double)g[stride] - 2.0 * (double)g[2 * stride] + (double)g[3 * stride];
    if (!(c0 * c1 > 0)) /* a change of sign, or none: no curvature to continue */
        return 0;
    const double c = fabs(c0) < fabs(c1) ? c0 : c1;
    return fabs(c) > t ? c - t * t / c : 0;
}

/* Fill the G ghosts on both sides of a line whose n real samples start at g (stride):
 * point-symmetric, plus at an end with curve_lo / curve_hi k^2 times its limited second
 * difference, threshold t (up to 2 RPIV_DEFORM_GHOST steps, then held: the prefilter reads
 * that far with a weight below 1e-5 of the edge's). */
static void ghosts(float *g, int n, size_t stride, int curve_lo, int curve_hi, double t)
{
    const int G = PAD;
    float *rev = g + (size_t)(n - 1) * stride;
    const double clo = curve_lo ? deform_edge_curv(g, n, (ptrdiff_t)stride, t) : 0,
                 chi = curve_hi ? deform_edge_curv(rev, n, -(ptrdiff_t)stride, t) : 0;
    for (int k = 1; k <= G; k++) {
        const int kk = k < 2 * RPIV_DEFORM_GHOST ? k : 2 * RPIV_DEFORM_GHOST;
        double lo = 2.0 * (double)g[0] - ext(g, n, stride, k) + (double)(kk * kk) * clo;
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
        hi += (double)(kk * kk) * chi;
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
    return deform_pred_new_ext(f, w, h, shift, NULL, NULL, out);
}

int deform_edge_valid(const unsigned char *flag, size_t k0, ptrdiff_t st, int n)
{
    if (!flag || n < 4)
        return 0;
    for (int q = 0; q < 4; q++)
        if (flag[(ptrdiff_t)k0 + q * st] != RPIV_FLAG_VALID)
            return 0;
    return 1;
}

rpiv_status deform_pred_new_ext(const rpiv_field *f, int w, int h, double shift,
                                const unsigned char *flag, const double thr[2],
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
        const double t = thr ? thr[c] : 0;
        for (int j = 0; j < f->ny; j++) {
            float *row = g + (size_t)(j + G) * snx + G;
            memcpy(row, src + (size_t)j * (size_t)f->nx, (size_t)f->nx * sizeof *row);
            const size_t r = (size_t)j * (size_t)f->nx;
            ghosts(row, f->nx, 1, deform_edge_valid(flag, r, 1, f->nx),
                   deform_edge_valid(flag, r + (size_t)f->nx - 1, -1, f->nx), t);
        }
        for (int i = 0; i < p->nx; i++) {
            /* the ghost columns (the grid's corners beyond it) continued linearly */
            const int ic = i - G, real = ic >= 0 && ic < f->nx;
            const ptrdiff_t st = (ptrdiff_t)f->nx;
            ghosts(g + (size_t)G * snx + (size_t)i, f->ny, snx,
                   real && deform_edge_valid(flag, (size_t)ic, st, f->ny),
                   real && deform_edge_valid(flag, (size_t)(f->ny - 1) * (size_t)f->nx + (size_t)ic,
                                             -st, f->ny),
                   t);
        }
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

void deform_pred_grid_row(const rpiv_deform_pred *p, int y, float *tu, float *tv)
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
    deform_pred_grid_row(p, y, tu, tv);
    for (int x = x0; x < x1; x++) {
        const float *wx = p->wx + 4 * (size_t)x, *a = tu + p->ix[x], *b = tv + p->ix[x];
        u[x - x0] = wx[0] * a[0] + wx[1] * a[1] + wx[2] * a[2] + wx[3] * a[3];
        v[x - x0] = wx[0] * b[0] + wx[1] * b[1] + wx[2] * b[2] + wx[3] * b[3];
    }
}
