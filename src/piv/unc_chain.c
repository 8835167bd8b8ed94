/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/unc_chain.c - the predictor's random error carried into each vector of a deforming
 * pass (docs/uncertainty.md, "The predictor's noise"). A vector of a deforming pass is
 * p(c) + r: the predictor at the window's centre plus the residual peak, and the residual
 * measures the window mean of the truth minus the predictor. The predictor's own error e_p
 * therefore enters as e_p(c) - <e_p>_W, which the spline of the previous field, its filter
 * and the window fix as a linear map G of the previous level's errors:
 *   e_i = n_i + sum_k G_ik e'_k,   G_ik = eta_k(c_i) - <eta_k>_{W_i},
 * eta_k the predictor of a unit impulse at node k (separable: eta_k(x, y) = eta_kx(x)
 * eta_ky(y)). Every level's window noise n comes from the same pixels, so two windows (of any
 * level) sharing pixels share noise: cov(n_a, n_b) = s_a s_b |W_a & W_b| / sqrt(|W_a| |W_b|),
 * s the windows' correlation-statistics sigmas. The error of a vector is expanded back through
 * the levels into the window noises and its variance summed with these covariances. */
#include "deform_impl.h"
#include "piv_impl.h"
#include "uncertainty_impl.h"

#include "rpiv/deform.h"

#include "base/hash.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

/* Levels kept: an older level's error reaches the newest only through the product of the
 * maps of the levels between, each |G| < 1 and of zero sum: beyond 8 it is negligible. */
#define UNC_LEVELS 8
/* Nodes of the previous level taken either side of a window's span (the cubic spline's
 * impulse response decays by 2 - sqrt(3) = 0.27 a node: 3 nodes, 2 %). */
#define UNC_RADIUS 3
/* Terms of the expansion with a smaller coefficient are dropped. */
#define UNC_TINY 1e-4

typedef struct unc_level {
    int nx, ny;
    double x0, y0, dx, dy;        /* the field's node positions           */
    int wx0, wy0, sx, sy, ww, wh; /* window 0's first pixel, steps, sizes  */
    double shift;                 /* pixel x samples the predictor at x+shift */
    float *s[2];                  /* correlation-statistics sigma, u and v */
    /* the map from the level before: per axis, eta_k at window i's centre and its mean over
     * window i ([k * n + i]); NULL when the level before does not reach this one */
    double *hx, *ax, *hy, *ay;
    int pnx, pny; /* the grid of the level before */
    /* the predictor's error carried in (unc_chain_pred_error): the map without the denoiser,
     * and the error's estimate at the level before's nodes, u and v */
    double *hx0, *ax0, *hy0, *ay0;
    float *pe[2];
    /* the first level of a pass without deformation (unc_chain_keep_first): its field as the
     * next pass's predictor took it (fv), and its error against the final field (fe,
     * unc_chain_first_error; fe_ok once set) */
    float *fv[2], *fe[2];
    int fe_ok;
    /* a denoised predictor (the refinement's repeats): the map above is the spline's and the
     * window's alone (G0), and the predictor's errors reach it through the filter [fa/2, 1 -
     * fa, fa/2] and the denoiser as the linear map A it was on this predictor (dw: its weights
     * on the level before's grid, piv_pred_denoise_weights; dorder its refine_denoise_order):
     * G = G0 N A F, N the grid's Nyquist notch (piv_pred_notch; m 0: none) */
    float *dw;
    int dorder;
    piv_notch notch;
    double fa;
} unc_level;

struct unc_chain {
    int n;
    unc_level lv[UNC_LEVELS];
    uint64_t hash; /* of the field the newest level returned */
};

/* Free the shrinkage data of a level (only the newest level's is used). */
static void shrink_free(unc_level *l)
{
    free(l->hx0);
    free(l->ax0);
    free(l->hy0);
    free(l->ay0);
    free(l->pe[0]);
    free(l->pe[1]);
    l->hx0 = l->ax0 = l->hy0 = l->ay0 = NULL;
    l->pe[0] = l->pe[1] = NULL;
}

static void level_free(unc_level *l)
{
    shrink_free(l);
    free(l->fv[0]);
    free(l->fv[1]);
    free(l->fe[0]);
    free(l->fe[1]);
    free(l->dw);
    free(l->s[0]);
    free(l->s[1]);
    free(l->hx);
    free(l->ax);
    free(l->hy);
    free(l->ay);
    memset(l, 0, sizeof *l);
}

void unc_chain_free(unc_chain *c)
{
    if (!c)
        return;
    for (int k = 0; k < c->n; k++)
        level_free(&c->lv[k]);
    free(c);
}

/* One axis of the map: the previous grid has pn nodes at p0 + k pd; this level's n windows
 * start at pixel w0 + i st and are ww wide; the predictor is the spline of the previous field
 * filtered by [a/2, 1 - a, a/2] (the engine's pred_filter: edge nodes unfiltered), sampled at
 * pixel + shift. Fills h and m ([k * n + i]). */
static rpiv_status axis_map(int pn, double p0, double pd, int n, int w0, int st, int ww,
                            double shift, double filter, int img, double *h, double *m)
{
    rpiv_status s = RPIV_OK;
    for (int k = 0; k < pn && !s; k++) {
        rpiv_field *f = NULL;
        rpiv_deform_pred *p = NULL;
        if ((s = rpiv_field_new(pn, 1, p0, 0, pd, 1, &f)))
            break;
        memset(f->u, 0, (size_t)pn * sizeof *f->u);
        memset(f->v, 0, (size_t)pn * sizeof *f->v);
        f->u[k] = 1;
        if (filter > 0 && pn > 2) {
            const float c0 = (float)(1 - filter), c1 = (float)(0.5 * filter);
            if (k >= 1 && k <= pn - 2)
                f->u[k] = c0;
            if (k - 1 >= 1)
                f->u[k - 1] = c1;
            if (k + 1 <= pn - 2)
                f->u[k + 1] = c1;
        }
        if (!(s = rpiv_deform_pred_new(f, img, 1, shift, &p))) {
            for (int i = 0; i < n; i++) {
                double u, v, sum = 0;
                const int x0 = w0 + i * st;
                rpiv_deform_pred_eval(p, x0 + 0.5 * (ww - 1) + shift, 0, &u, &v);
                h[(size_t)k * (size_t)n + (size_t)i] = u;
                for (int x = x0; x < x0 + ww; x++) {
                    rpiv_deform_pred_eval(p, x + shift, 0, &u, &v);
                    sum += u;
                }
                m[(size_t)k * (size_t)n + (size_t)i] = sum / ww;
            }
        }
        rpiv_deform_pred_free(p);
        rpiv_field_free(f);
    }
    return s;
}

rpiv_status unc_chain_push(unc_chain **chain, int linked, const unc_geom *g, double filter,
                           const rpiv_field *f, const float *su, const float *sv,
                           const float *weights)
{
    if (!*chain && !(*chain = calloc(1, sizeof **chain)))
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the uncertainty");
    unc_chain *c = *chain;
    if (!linked || !c->n) {
        for (int k = 0; k < c->n; k++)
            level_free(&c->lv[k]);
        c->n = 0;
        linked = 0;
    }
    if (c->n == UNC_LEVELS) { /* drop the oldest level */
        level_free(&c->lv[0]);
        memmove(&c->lv[0], &c->lv[1], (UNC_LEVELS - 1) * sizeof c->lv[0]);
        memset(&c->lv[UNC_LEVELS - 1], 0, sizeof c->lv[0]);
        c->n--;
        free(c->lv[0].hx);
        free(c->lv[0].ax);
        free(c->lv[0].hy);
        free(c->lv[0].ay);
        free(c->lv[0].dw);
        c->lv[0].hx = c->lv[0].ax = c->lv[0].hy = c->lv[0].ay = NULL;
        c->lv[0].dw = NULL;
    }
    if (c->n) /* the shrinkage term is the newest level's only */
        shrink_free(&c->lv[c->n - 1]);
    unc_level *l = &c->lv[c->n];
    memset(l, 0, sizeof *l);
    *l = (unc_level){.nx = f->nx,
                     .ny = f->ny,
                     .x0 = f->x0,
                     .y0 = f->y0,
                     .dx = f->dx,
                     .dy = f->dy,
                     .wx0 = g->wx0,
                     .wy0 = g->wy0,
                     .sx = g->sx,
                     .sy = g->sy,
                     .ww = g->ww,
                     .wh = g->wh,
                     .shift = g->shift};
    const size_t n = (size_t)f->nx * (size_t)f->ny;
    l->s[0] = malloc(n * sizeof *l->s[0]);
    l->s[1] = malloc(n * sizeof *l->s[1]);
    if (!l->s[0] || !l->s[1]) {
        level_free(l);
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the uncertainty");
    }
    /* vectors without their own statistics (replaced): the RMS of the valid ones */
    const float *src[2] = {su, sv};
    for (int q = 0; q < 2; q++) {
        double ss = 0;
        size_t m = 0;
        for (size_t k = 0; k < n; k++)
            if (f->flag[k] == RPIV_FLAG_VALID) {
                ss += (double)src[q][k] * (double)src[q][k];
                m++;
            }
        const float fill = m ? (float)sqrt(ss / (double)m) : (float)UNC_SIGMA_MAX;
        for (size_t k = 0; k < n; k++)
            l->s[q][k] = f->flag[k] == RPIV_FLAG_VALID      ? src[q][k]
                         : f->flag[k] == RPIV_FLAG_REPLACED ? fill
                                                            : 0;
    }
    if (linked) {
        const unc_level *p = &c->lv[c->n - 1];
        l->pnx = p->nx;
        l->pny = p->ny;
        const size_t mx = (size_t)p->nx * (size_t)f->nx, my = (size_t)p->ny * (size_t)f->ny;
        l->hx = malloc(mx * sizeof *l->hx);
        l->ax = malloc(mx * sizeof *l->ax);
        l->hy = malloc(my * sizeof *l->hy);
        l->ay = malloc(my * sizeof *l->ay);
        rpiv_status st = RPIV_OK;
        const int adaptive = g->denoise && weights;
        const size_t ng = (size_t)PIV_DENOISE_STAGES * 2 * (size_t)p->nx * (size_t)p->ny;
        if (adaptive && (l->dw = malloc(ng * sizeof *l->dw)))
            memcpy(l->dw, weights, ng * sizeof *l->dw);
        l->fa = adaptive ? filter : 0;
        l->dorder = adaptive ? g->denoise : 0;
        if (adaptive)
            l->notch = g->notch;
        if (!l->hx || !l->ax || !l->hy || !l->ay || (adaptive && !l->dw))
            st = rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the uncertainty");
        if (!st)
            st = axis_map(p->nx, p->x0, p->dx, f->nx, g->wx0, g->sx, g->ww, g->shift,
                          adaptive ? 0 : filter, g->img_w, l->hx, l->ax);
        if (!st)
            st = axis_map(p->ny, p->y0, p->dy, f->ny, g->wy0, g->sy, g->wh, g->shift,
                          adaptive ? 0 : filter, g->img_h, l->hy, l->ay);
        if (st) {
            level_free(l);
            return st;
        }
    }
    c->n++;
    return RPIV_OK;
}

rpiv_status unc_chain_pred_error(unc_chain *c, const unc_geom *g, const rpiv_field *err)
{
    if (!c || c->n < 2 || !c->lv[c->n - 1].hx)
        return RPIV_OK;
    unc_level *l = &c->lv[c->n - 1];
    const unc_level *p = &c->lv[c->n - 2];
    if (err->nx != p->nx || err->ny != p->ny)
        return RPIV_OK;
    const size_t mx = (size_t)p->nx * (size_t)l->nx, my = (size_t)p->ny * (size_t)l->ny;
    const size_t n = (size_t)p->nx * (size_t)p->ny;
    shrink_free(l);
    l->hx0 = malloc(mx * sizeof *l->hx0);
    l->ax0 = malloc(mx * sizeof *l->ax0);
    l->hy0 = malloc(my * sizeof *l->hy0);
    l->ay0 = malloc(my * sizeof *l->ay0);
    l->pe[0] = malloc(n * sizeof *l->pe[0]);
    l->pe[1] = malloc(n * sizeof *l->pe[1]);
    rpiv_status st = RPIV_OK;
    if (!l->hx0 || !l->ax0 || !l->hy0 || !l->ay0 || !l->pe[0] || !l->pe[1])
        st = rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the uncertainty");
    if (!st)
        st = axis_map(p->nx, p->x0, p->dx, l->nx, g->wx0, g->sx, g->ww, g->shift, 0, g->img_w,
                      l->hx0, l->ax0);
    if (!st)
        st = axis_map(p->ny, p->y0, p->dy, l->ny, g->wy0, g->sy, g->wh, g->shift, 0, g->img_h,
                      l->hy0, l->ay0);
    if (st) {
        shrink_free(l);
        return st;
    }
    memcpy(l->pe[0], err->u, n * sizeof *l->pe[0]);
    memcpy(l->pe[1], err->v, n * sizeof *l->pe[1]);
    return RPIV_OK;
}

rpiv_status unc_chain_keep_first(unc_chain *c, const rpiv_field *f)
{
    if (!c || c->n != 1 || c->lv[0].shift != 0 || f->nx != c->lv[0].nx || f->ny != c->lv[0].ny)
        return RPIV_OK;
    unc_level *l = &c->lv[0];
    const size_t n = (size_t)f->nx * (size_t)f->ny;
    for (int q = 0; q < 2; q++) {
        free(l->fv[q]);
        free(l->fe[q]);
        l->fv[q] = malloc(n * sizeof *l->fv[q]);
        l->fe[q] = malloc(n * sizeof *l->fe[q]);
    }
    l->fe_ok = 0;
    if (!l->fv[0] || !l->fv[1] || !l->fe[0] || !l->fe[1])
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the uncertainty");
    memcpy(l->fv[0], f->u, n * sizeof *l->fv[0]);
    memcpy(l->fv[1], f->v, n * sizeof *l->fv[1]);
    return RPIV_OK;
}

rpiv_status unc_chain_first_error(unc_chain *c, const rpiv_field *f, int img_w, int img_h)
{
    if (!c || !c->n)
        return RPIV_OK;
    unc_level *l = &c->lv[0];
    l->fe_ok = 0;
    if (c->n < 2 || !l->fv[0])
        return RPIV_OK;
    rpiv_deform_pred *p = NULL;
    rpiv_status st = rpiv_deform_pred_new(f, img_w, img_h, 0, &p);
    if (st)
        return st;
    for (int j = 0; j < l->ny; j++)
        for (int i = 0; i < l->nx; i++) {
            const size_t k = (size_t)j * (size_t)l->nx + (size_t)i;
            double u, v;
            rpiv_deform_pred_eval(p, l->x0 + i * l->dx, l->y0 + j * l->dy, &u, &v);
            l->fe[0][k] = (float)((double)l->fv[0][k] - u);
            l->fe[1][k] = (float)((double)l->fv[1][k] - v);
        }
    rpiv_deform_pred_free(p);
    l->fe_ok = 1;
    return RPIV_OK;
}

void unc_chain_set_hash(unc_chain *c, const rpiv_field *f)
{
    if (c)
        c->hash = piv_field_hash(f);
}

int unc_chain_links(const unc_chain *c, const rpiv_field *predictor)
{
    return c && c->n && predictor && c->lv[c->n - 1].nx == predictor->nx &&
           c->lv[c->n - 1].ny == predictor->ny && c->hash == piv_field_hash(predictor);
}

/* The first level's measured error carried into a vector (expand_var): eh = sum_k cf_k fe_k
 * (u, v), c2 = sum_k cf_k^2 (u, v), var0 the variance of the first level's own terms. */
typedef struct first_err {
    double eh[2], c2[2], var0[2];
    int ok;
} first_err;

/* One term of a vector's expansion: a window of some level, its coefficient. */
typedef struct term {
    int x0, y0, x1, y1; /* the window's pixels [x0, x1) x [y0, y1) */
    double q[2];        /* coefficient * sigma / sqrt(area), u and v */
} term;

static int gcd(int a, int b)
{
    a = a < 0 ? -a : a;
    b = b < 0 ? -b : b;
    while (b) {
        int r = a % b;
        a = b;
        b = r;
    }
    return a;
}

/* Cells beyond which the variance is summed over pairs of terms instead. */
#define UNC_MAX_CELLS 262144

/* var[0], var[1] = sum over pixels of (sum of the q of the windows holding it)^2. Returns 0,
 * or -1 when out of memory. */
static int terms_var(const term *t, size_t nt, double var[2])
{
    int X0 = t[0].x0, Y0 = t[0].y0, X1 = t[0].x1, Y1 = t[0].y1, gx = 0, gy = 0;
    for (size_t a = 1; a < nt; a++) {
        X0 = t[a].x0 < X0 ? t[a].x0 : X0;
        Y0 = t[a].y0 < Y0 ? t[a].y0 : Y0;
        X1 = t[a].x1 > X1 ? t[a].x1 : X1;
        Y1 = t[a].y1 > Y1 ? t[a].y1 : Y1;
    }
    for (size_t a = 0; a < nt; a++) {
        gx = gcd(gcd(gx, t[a].x0 - X0), t[a].x1 - X0);
        gy = gcd(gcd(gy, t[a].y0 - Y0), t[a].y1 - Y0);
    }
    const size_t cx = (size_t)((X1 - X0) / gx), cy = (size_t)((Y1 - Y0) / gy);
    if (cx * cy <= UNC_MAX_CELLS) {
        double *cell = calloc(2 * cx * cy, sizeof *cell);
        if (!cell)
            return -1;
        for (size_t a = 0; a < nt; a++)
            for (int y = (t[a].y0 - Y0) / gy; y < (t[a].y1 - Y0) / gy; y++)
                for (int x = (t[a].x0 - X0) / gx; x < (t[a].x1 - X0) / gx; x++) {
                    double *c = cell + 2 * ((size_t)y * cx + (size_t)x);
                    c[0] += t[a].q[0];
                    c[1] += t[a].q[1];
                }
        for (size_t k = 0; k < cx * cy; k++) {
            var[0] += cell[2 * k] * cell[2 * k];
            var[1] += cell[2 * k + 1] * cell[2 * k + 1];
        }
        var[0] *= (double)gx * gy;
        var[1] *= (double)gx * gy;
        free(cell);
        return 0;
    }
    for (size_t a = 0; a < nt; a++)
        for (size_t b = a; b < nt; b++) {
            const int x0 = t[a].x0 > t[b].x0 ? t[a].x0 : t[b].x0;
            const int x1 = t[a].x1 < t[b].x1 ? t[a].x1 : t[b].x1;
            const int y0 = t[a].y0 > t[b].y0 ? t[a].y0 : t[b].y0;
            const int y1 = t[a].y1 < t[b].y1 ? t[a].y1 : t[b].y1;
            if (x1 <= x0 || y1 <= y0)
                continue;
            const double ov = (double)(x1 - x0) * (y1 - y0) * (a == b ? 1 : 2);
            var[0] += ov * t[a].q[0] * t[b].q[0];
            var[1] += ov * t[a].q[1] * t[b].q[1];
        }
    return 0;
}

/* The node range of the level before (pn nodes at p0 + k pd) that the windows i0..i1 of this
 * level reach. */
static void reach(int i0, int i1, int w0, int st, int ww, double shift, double p0, double pd,
                  int pn, int *k0, int *k1)
{
    const double half = 0.5 * ww / pd + UNC_RADIUS;
    const double c0 = (w0 + i0 * st + 0.5 * (ww - 1) + shift - p0) / pd;
    const double c1 = (w0 + i1 * st + 0.5 * (ww - 1) + shift - p0) / pd;
    *k0 = (int)floor(c0 - half);
    *k1 = (int)ceil(c1 + half);
    *k0 = *k0 < 0 ? 0 : *k0;
    *k1 = *k1 > pn - 1 ? pn - 1 : *k1;
}

/* Add w times level l's map (h*, a*: per axis, eta_k at the window centres and its window
 * mean, [k * n + i]) applied to the coefficients cf of l's nodes bx0.. (bw) x by0.. (bh) to
 * out, the coefficients of the level before's nodes kx0.. (kw) x ky0.. (kh):
 * out[ky][kx] += w sum (hy[ky][iy] hx[kx][ix] - ay ax) cf[iy][ix]. 0, or -1 out of memory. */
static int back_map(const unc_level *l, const double *hx, const double *ax, const double *hy,
                    const double *ay, double w, const double *cf, int bx0, int bw, int by0, int bh,
                    int kx0, int kw, int ky0, int kh, double *out)
{
    double *th = malloc((size_t)bh * (size_t)kw * sizeof *th);
    double *ta = malloc((size_t)bh * (size_t)kw * sizeof *ta);
    if (!th || !ta) {
        free(th);
        free(ta);
        return -1;
    }
    for (int j = 0; j < bh; j++)
        for (int k = 0; k < kw; k++) {
            double sh = 0, sa = 0;
            const size_t row = (size_t)(kx0 + k) * (size_t)l->nx;
            for (int i = 0; i < bw; i++) {
                const double a = cf[(size_t)j * (size_t)bw + (size_t)i];
                sh += a * hx[row + (size_t)(bx0 + i)];
                sa += a * ax[row + (size_t)(bx0 + i)];
            }
            th[(size_t)j * (size_t)kw + (size_t)k] = w * sh;
            ta[(size_t)j * (size_t)kw + (size_t)k] = w * sa;
        }
    for (int m = 0; m < kh; m++) {
        const size_t row = (size_t)(ky0 + m) * (size_t)l->ny;
        for (int j = 0; j < bh; j++) {
            const double y = hy[row + (size_t)(by0 + j)], a = ay[row + (size_t)(by0 + j)];
            for (int k = 0; k < kw; k++)
                out[(size_t)m * (size_t)kw + (size_t)k] +=
                    y * th[(size_t)j * (size_t)kw + (size_t)k] -
                    a * ta[(size_t)j * (size_t)kw + (size_t)k];
        }
    }
    free(th);
    free(ta);
    return 0;
}

/* Nodes the filter and the denoiser carry a coefficient across, per axis: the
 * filter 1, the denoiser's stages 2 (second difference at an end), 4 (the fourth difference
 * at dilation 2), 8 (the second at dilation 4, at an end). */
#define UNC_DENOISE_REACH 15

/* The coefficients of the level before's nodes kx0.. (kw) x ky0.. (kh), u and v, of the
 * errors sum_k cf_k e_k of level l's nodes bx0.. (bw) x by0.. (bh): out[q] = G^T cf[q]
 * (new arrays; out[1] == out[0] while cf[1] == cf[0] and the map is the same for u and v).
 * G = G0 A F for a denoised predictor (unc_level.dw), the map itself otherwise. 0, or -1 out
 * of memory. */
static int level_back(const unc_level *l, double *const cf[2], int bx0, int bw, int by0, int bh,
                      int kx0, int kw, int ky0, int kh, double *out[2])
{
    const size_t nk = (size_t)kh * (size_t)kw;
    out[0] = out[1] = NULL;
    if (!l->dw) {
        out[0] = calloc(nk, sizeof *out[0]);
        out[1] = cf[1] == cf[0] ? out[0] : calloc(nk, sizeof *out[1]);
        if (!out[0] || !out[1] ||
            back_map(l, l->hx, l->ax, l->hy, l->ay, 1, cf[0], bx0, bw, by0, bh, kx0, kw, ky0, kh,
                     out[0]) ||
            (out[1] != out[0] && back_map(l, l->hx, l->ax, l->hy, l->ay, 1, cf[1], bx0, bw, by0, bh,
                                          kx0, kw, ky0, kh, out[1])))
            return -1;
        return 0;
    }
    /* G0^T cf on the block widened by the denoiser's and the notch's reach, then N^T, A^T and
     * F^T there, cut back */
    const int rx = UNC_DENOISE_REACH + l->notch.m[0] * (1 << l->notch.levels[0]),
              ry = UNC_DENOISE_REACH + l->notch.m[1] * (1 << l->notch.levels[1]);
    const int ex0 = kx0 - rx < 0 ? 0 : kx0 - rx;
    const int ey0 = ky0 - ry < 0 ? 0 : ky0 - ry;
    const int ex1 = kx0 + kw - 1 + rx > l->pnx - 1 ? l->pnx - 1 : kx0 + kw - 1 + rx;
    const int ey1 = ky0 + kh - 1 + ry > l->pny - 1 ? l->pny - 1 : ky0 + kh - 1 + ry;
    const int ew = ex1 - ex0 + 1, eh = ey1 - ey0 + 1;
    const size_t ne = (size_t)ew * (size_t)eh;
    double *e = calloc(3 * ne, sizeof *e);
    out[0] = malloc(nk * sizeof *out[0]);
    out[1] = malloc(nk * sizeof *out[1]);
    if (!e || !out[0] || !out[1]) {
        free(e);
        return -1;
    }
    double *b = e + ne, *tmp = e + 2 * ne;
    for (int q = 0; q < 2; q++) {
        if (q == 0 || cf[1] != cf[0]) {
            memset(b, 0, ne * sizeof *b);
            if (back_map(l, l->hx, l->ax, l->hy, l->ay, 1, cf[q], bx0, bw, by0, bh, ex0, ew, ey0,
                         eh, b)) {
                free(e);
                return -1;
            }
        }
        memcpy(e, b, ne * sizeof *e);
        piv_pred_notch_t(e, &l->notch, l->pnx, l->pny, ex0, ew, ey0, eh, tmp);
        if (piv_pred_denoise_map_t(l->dw, l->dorder, l->pnx, l->pny, q, e, ex0, ew, ey0, eh, tmp)) {
            free(e);
            return -1;
        }
        if (l->fa > 0)
            piv_pred_filter_t(e, l->fa, l->pnx, l->pny, ex0, ew, ey0, eh, tmp);
        for (int m = 0; m < kh; m++)
            memcpy(out[q] + (size_t)m * (size_t)kw,
                   e + (size_t)(ky0 - ey0 + m) * (size_t)ew + (size_t)(kx0 - ex0),
                   (size_t)kw * sizeof *e);
    }
    free(e);
    return 0;
}

static void cf_free(double *cf[2])
{
    if (cf[1] != cf[0])
        free(cf[1]);
    free(cf[0]);
    cf[0] = cf[1] = NULL;
}

/* The variance, u and v, of sum_k cf[q]_k e_k, e the errors of the nodes bx0..bx1 x by0..by1
 * of level L (cf: their coefficients, u and v, cf[1] == cf[0] when the same; taken over and
 * freed): each level's window noises and, through the maps, those of the levels before.
 * Returns 0, or -1 when out of memory. */
static int expand_var(const unc_chain *c, int L, int bx0, int bx1, int by0, int by1, double *cf[2],
                      double var[2], first_err *fst)
{
    double *nx_cf[2] = {NULL, NULL};
    term *t = NULL;
    size_t nt = 0, cap = 0, nt0 = 0;
    int bad = !cf[0] || !cf[1], at0 = 0;
    var[0] = var[1] = 0;
    for (int lev = L; lev >= 0 && !bad; lev--) {
        const unc_level *l = &c->lv[lev];
        const int bw = bx1 - bx0 + 1, bh = by1 - by0 + 1;
        nt0 = nt;
        at0 = lev == 0;
        /* this level's terms */
        for (int j = 0; j < bh; j++)
            for (int i = 0; i < bw; i++) {
                const size_t at = (size_t)j * (size_t)bw + (size_t)i;
                const double a0 = fabs(cf[0][at]) < UNC_TINY ? 0 : cf[0][at];
                const double a1 = fabs(cf[1][at]) < UNC_TINY ? 0 : cf[1][at];
                if (a0 == 0 && a1 == 0)
                    continue;
                if (nt == cap) {
                    cap = cap ? 2 * cap : 64;
                    term *nt_ = realloc(t, cap * sizeof *t);
                    if (!nt_) {
                        bad = 1;
                        break;
                    }
                    t = nt_;
                }
                const int gx = bx0 + i, gy = by0 + j;
                const size_t k = (size_t)gy * (size_t)l->nx + (size_t)gx;
                const double r = sqrt((double)l->ww * l->wh);
                term *e = &t[nt++];
                e->x0 = l->wx0 + gx * l->sx;
                e->y0 = l->wy0 + gy * l->sy;
                e->x1 = e->x0 + l->ww;
                e->y1 = e->y0 + l->wh;
                e->q[0] = a0 / r * (double)l->s[0][k];
                e->q[1] = a1 / r * (double)l->s[1][k];
            }
        if (bad || !l->hx || lev == 0)
            break;
        /* back to the level before */
        int kx0, kx1, ky0, ky1;
        reach(bx0, bx1, l->wx0, l->sx, l->ww, l->shift, c->lv[lev - 1].x0, c->lv[lev - 1].dx,
              l->pnx, &kx0, &kx1);
        reach(by0, by1, l->wy0, l->sy, l->wh, l->shift, c->lv[lev - 1].y0, c->lv[lev - 1].dy,
              l->pny, &ky0, &ky1);
        if (level_back(l, cf, bx0, bw, by0, bh, kx0, kx1 - kx0 + 1, ky0, ky1 - ky0 + 1, nx_cf)) {
            bad = 1;
            break;
        }
        cf_free(cf);
        cf[0] = nx_cf[0];
        cf[1] = nx_cf[1];
        nx_cf[0] = nx_cf[1] = NULL;
        bx0 = kx0;
        bx1 = kx1;
        by0 = ky0;
        by1 = ky1;
    }
    /* the variance of the sum of the terms: window noises covary by their shared pixels,
     * var = sum_a sum_b q_a q_b |W_a & W_b| = sum over pixels of (sum of q_a over the windows
     * holding the pixel)^2, summed on cells of g pixels (g: the common divisor of the edges) */
    if (!bad && nt)
        bad = terms_var(t, nt, var);
    if (fst && !bad && at0 && L > 0 && c->lv[0].fe_ok) {
        /* the first level's error as the final field measured it, through the coefficients
         * cf of its nodes; the variance its window noises were counted with (its terms) */
        const unc_level *l = &c->lv[0];
        const int bw = bx1 - bx0 + 1, bh = by1 - by0 + 1;
        for (int j = 0; j < bh; j++)
            for (int i = 0; i < bw; i++) {
                const size_t at = (size_t)j * (size_t)bw + (size_t)i;
                const size_t k = (size_t)(by0 + j) * (size_t)l->nx + (size_t)(bx0 + i);
                for (int q = 0; q < 2; q++) {
                    fst->eh[q] += cf[q][at] * (double)l->fe[q][k];
                    fst->c2[q] += cf[q][at] * cf[q][at];
                }
            }
        if (nt > nt0)
            bad = terms_var(t + nt0, nt - nt0, fst->var0);
        fst->ok = !bad;
    }
    cf_free(cf);
    cf_free(nx_cf);
    free(t);
    return bad ? -1 : 0;
}

/* The variance of vector (ix, iy) of the newest level, u and v. Returns 0, or -1 when out of
 * memory. */
static int vector_var(const unc_chain *c, int ix, int iy, double var[2], first_err *fst)
{
    double *cf[2];
    cf[0] = cf[1] = malloc(sizeof *cf[0]);
    if (cf[0])
        cf[0][0] = 1;
    return expand_var(c, c->n - 1, ix, ix, iy, iy, cf, var, fst);
}

/* The denoiser's shrinkage of the true field, for vector (ix, iy) of the newest level (docs/
 * uncertainty.md, "The vortex"): the predictor's nodes hold t + n (truth, noise) and the
 * denoiser removed r = (t - D t) + (I - A) n from them (A the linear map the denoiser was on
 * this predictor, its weights held: L, its linear part, where it drops every detail), so the
 * vector carries -G0 (t - D t) besides the noise the chain counts (G0: the spline and the
 * window without the denoiser; G = G0 A the chain's map). Estimated by eh = -G0 r, whose
 * noise -G0 (I - A) n = -(G0 - G) n
 * has the variance vn the chain gives for those coefficients: add[q] = max(0, eh^2 - vn), u
 * and v. Returns 0, or -1 when out of memory. */
static int shrink_var(const unc_chain *c, int ix, int iy, double add[2])
{
    const unc_level *l = &c->lv[c->n - 1], *p = &c->lv[c->n - 2];
    int kx0, kx1, ky0, ky1;
    reach(ix, ix, l->wx0, l->sx, l->ww, l->shift, p->x0, p->dx, l->pnx, &kx0, &kx1);
    reach(iy, iy, l->wy0, l->sy, l->wh, l->shift, p->y0, p->dy, l->pny, &ky0, &ky1);
    const int kw = kx1 - kx0 + 1, kh = ky1 - ky0 + 1;
    const size_t nk = (size_t)kh * (size_t)kw;
    double one = 1, *const unit[2] = {&one, &one};
    double *g0 = calloc(nk, sizeof *g0), *d[2] = {NULL, NULL};
    if (!g0 ||
        back_map(l, l->hx0, l->ax0, l->hy0, l->ay0, 1, &one, ix, 1, iy, 1, kx0, kw, ky0, kh, g0) ||
        level_back(l, unit, ix, 1, iy, 1, kx0, kw, ky0, kh, d)) {
        free(g0);
        free(d[0]);
        if (d[1] != d[0])
            free(d[1]);
        return -1;
    }
    double eh[2] = {0, 0}, vn[2];
    for (int m = 0; m < kh; m++)
        for (int k = 0; k < kw; k++) {
            const size_t at = (size_t)m * (size_t)kw + (size_t)k;
            const size_t node = (size_t)(ky0 + m) * (size_t)p->nx + (size_t)(kx0 + k);
            eh[0] += g0[at] * (double)l->pe[0][node];
            eh[1] += g0[at] * (double)l->pe[1][node];
        }
    for (size_t at = 0; at < nk; at++) {
        d[0][at] = g0[at] - d[0][at];
        if (d[1] != d[0])
            d[1][at] = g0[at] - d[1][at];
    }
    free(g0);
    if (expand_var(c, c->n - 2, kx0, kx1, ky0, ky1, d, vn, NULL))
        return -1;
    for (int q = 0; q < 2; q++)
        add[q] = fmax(0, eh[q] * eh[q] - vn[q]);
    return 0;
}

rpiv_status unc_chain_total(const unc_chain *c, const rpiv_field *f, float *su, float *sv,
                            int nthreads)
{
    const unc_level *l = &c->lv[c->n - 1];
    const size_t n = (size_t)l->nx * (size_t)l->ny;
    int bad = 0;
#pragma omp parallel for schedule(dynamic, 8) num_threads(nthreads) reduction(| : bad)
    for (size_t k = 0; k < n; k++) {
        if (f->flag[k] != RPIV_FLAG_VALID)
            continue;
        double var[2];
        const int ix = (int)(k % (size_t)l->nx), iy = (int)(k / (size_t)l->nx);
        double add[2] = {0, 0};
        first_err fst = {{0, 0}, {0, 0}, {0, 0}, 0};
        if (vector_var(c, ix, iy, var, &fst) || (l->pe[0] && shrink_var(c, ix, iy, add))) {
            bad = 1;
            continue;
        }
        var[0] += add[0];
        var[1] += add[1];
        if (fst.ok)
            for (int q = 0; q < 2; q++) {
                /* the first level's error, measured, in place of its window noise: the excess
                 * of eh^2 over the variance its terms were counted with and over the noise of
                 * the estimate (the final field's error at the first level's nodes, taken as
                 * this vector's, through the same coefficients) */
                const double vn = var[q] * fst.c2[q];
                var[q] += fmax(0, fst.eh[q] * fst.eh[q] - vn - fst.var0[q]);
            }
        su[k] = (float)fmin(sqrt(var[0] > 0 ? var[0] : 0), UNC_SIGMA_MAX);
        sv[k] = (float)fmin(sqrt(var[1] > 0 ? var[1] : 0), UNC_SIGMA_MAX);
    }
    return bad ? rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the uncertainty") : RPIV_OK;
}

/* |second difference| of g along a line of n nodes at the edge node k0 (inward stride st),
 * less what the predictor continued beyond the edge with curved (where its 4 end nodes are
 * valid, as deform_pred_new_ext; threshold t). */
static double edge_curv(const rpiv_field *f, const float *g, int n, size_t k0, ptrdiff_t st,
                        int curved, double t)
{
    const double c =
        (double)g[k0] - 2 * (double)g[(ptrdiff_t)k0 + st] + (double)g[(ptrdiff_t)k0 + 2 * st];
    curved = curved && deform_edge_valid(f->flag, k0, st, n);
    return fabs(c - (curved ? deform_edge_curv(g + k0, n, st, t) : 0));
}

void unc_edge_bias(const rpiv_field *f, int ww, int wh, int curved, float *su, float *sv)
{
    const int nx = f->nx, ny = f->ny;
    const float *g[2] = {f->u, f->v};
    float *s[2] = {su, sv};
    double thr[2] = {0, 0}; /* the engine's threshold, from this field as the proxy */
    if (curved)
        piv_curv_threshold(f, thr);
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            const size_t k = (size_t)j * (size_t)nx + (size_t)i;
            const int ex = nx >= 3 && (i == 0 || i == nx - 1);
            const int ey = ny >= 3 && (j == 0 || j == ny - 1);
            if ((!ex && !ey) || f->flag[k] != RPIV_FLAG_VALID)
                continue;
            for (int c = 0; c < 2; c++) {
                double b = 0;
                if (ex)
                    b += (double)ww * ww / 24 / (f->dx * f->dx) *
                         edge_curv(f, g[c], nx, k, i == 0 ? 1 : -1, curved, thr[c]);
                if (ey)
                    b += (double)wh * wh / 24 / (f->dy * f->dy) *
                         edge_curv(f, g[c], ny, k, j == 0 ? (ptrdiff_t)nx : -(ptrdiff_t)nx, curved,
                                   thr[c]);
                const double t = sqrt((double)s[c][k] * (double)s[c][k] + b * b);
                s[c][k] = (float)(t < UNC_SIGMA_MAX ? t : UNC_SIGMA_MAX);
            }
        }
}
