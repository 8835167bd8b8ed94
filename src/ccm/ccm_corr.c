/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The correlation as a sum of Gaussians (rpiv_ccm_corr) and its peak: the integer-sampled
 * maximum, the PIV sub-pixel estimator on it, and the continuous maximum (Brent on a line,
 * Nelder-Mead on the plane, a Newton polish). */
#include "ccm_impl.h"
#include "rpiv/peak.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_math.h>
#include <gsl/gsl_min.h>
#include <gsl/gsl_multimin.h>

/* ---- the sum of Gaussians ------------------------------------------------------------- */

rpiv_status rpiv_ccm_corr_new(size_t cap, rpiv_ccm_corr **out)
{
    *out = NULL;
    rpiv_ccm_corr *c = calloc(1, sizeof *c);
    if (!c)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
    if (cap) {
        c->g = malloc(cap * sizeof *c->g);
        if (!c->g) {
            free(c);
            return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for %zu terms", cap);
        }
        c->cap = cap;
    }
    *out = c;
    return RPIV_OK;
}

void rpiv_ccm_corr_free(rpiv_ccm_corr *c)
{
    if (!c)
        return;
    free(c->g);
    free(c);
}

rpiv_status rpiv_ccm_corr_add(rpiv_ccm_corr *c, rpiv_ccm_gauss g)
{
    if (c->n == c->cap) {
        size_t cap = c->cap ? 2 * c->cap : 64;
        rpiv_ccm_gauss *ng = realloc(c->g, cap * sizeof *ng);
        if (!ng)
            return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for %zu terms", cap);
        c->g = ng;
        c->cap = cap;
    }
    c->g[c->n++] = g;
    return RPIV_OK;
}

double rpiv_ccm_corr_eval(const rpiv_ccm_corr *c, double dx, double dy)
{
    double s = 0;
    for (size_t k = 0; k < c->n; k++) {
        const rpiv_ccm_gauss *g = &c->g[k];
        double ex = dx - g->dx, ey = dy - g->dy;
        s += g->amp * exp(-g->c * (ex * ex + ey * ey));
    }
    return s;
}

/* R and its first and second derivatives at (x, y). */
static void corr_d2(const rpiv_ccm_corr *c, double x, double y, double *r, double g[2], double h[3])
{
    double s = 0, gx = 0, gy = 0, hxx = 0, hyy = 0, hxy = 0;
    for (size_t k = 0; k < c->n; k++) {
        const rpiv_ccm_gauss *t = &c->g[k];
        double ex = x - t->dx, ey = y - t->dy, cc = t->c;
        double e = t->amp * exp(-cc * (ex * ex + ey * ey));
        s += e;
        gx -= 2 * cc * ex * e;
        gy -= 2 * cc * ey * e;
        hxx += (4 * cc * cc * ex * ex - 2 * cc) * e;
        hyy += (4 * cc * cc * ey * ey - 2 * cc) * e;
        hxy += 4 * cc * cc * ex * ey * e;
    }
    *r = s;
    g[0] = gx;
    g[1] = gy;
    h[0] = hxx;
    h[1] = hxy;
    h[2] = hyy;
}

typedef struct span {
    int mode;           /* 0 general, 1 all DY equal, 2 all DX equal, 3 all equal */
    double dx0, dy0;    /* the common DX / DY */
    int x0, x1, y0, y1; /* integer box */
} span;

static rpiv_status corr_span(const rpiv_ccm_corr *c, const rpiv_ccm_params *p, span *s)
{
    double xmin = HUGE_VAL, xmax = -HUGE_VAL, ymin = HUGE_VAL, ymax = -HUGE_VAL;
    size_t nact = 0;
    for (size_t k = 0; k < c->n; k++) {
        const rpiv_ccm_gauss *g = &c->g[k];
        if (!(g->amp > 0))
            continue;
        if (!isfinite(g->amp) || !isfinite(g->dx) || !isfinite(g->dy) || !(g->c > 0) ||
            !isfinite(g->c))
            return rpiv_fail(RPIV_ENUMERIC, "ccm: correlation term %zu is not finite", k);
        nact++;
        xmin = fmin(xmin, g->dx);
        xmax = fmax(xmax, g->dx);
        ymin = fmin(ymin, g->dy);
        ymax = fmax(ymax, g->dy);
    }
    if (!nact)
        return rpiv_fail(RPIV_ENUMERIC,
                         "ccm: the correlation is zero everywhere (no illuminated particle)");
    if (xmax - xmin > p->max_range_px || ymax - ymin > p->max_range_px)
        return rpiv_fail(RPIV_ELIMIT,
                         "ccm: displacements span %.4g x %.4g px, more than max_range_px = %d",
                         xmax - xmin, ymax - ymin, p->max_range_px);
    s->mode = (ymin == ymax ? 1 : 0) | (xmin == xmax ? 2 : 0);
    s->dx0 = xmin;
    s->dy0 = ymin;
    s->x0 = (int)floor(xmin) - 1;
    s->x1 = (int)ceil(xmax) + 1;
    s->y0 = (int)floor(ymin) - 1;
    s->y1 = (int)ceil(ymax) + 1;
    return RPIV_OK;
}

/* The integer-sampled maximum. When all DY are equal every term decreases with |y - DY|, so
 * the best row is the integer nearest DY and only that row is sampled (likewise for DX). */
static void sampled_argmax(const rpiv_ccm_corr *c, const span *s, int *mx, int *my)
{
    double best = -1;
    if (s->mode & 1) {
        int y = (int)lround(s->dy0);
        *my = y;
        *mx = s->x0;
        for (int x = s->x0; x <= s->x1; x++) {
            double r = rpiv_ccm_corr_eval(c, x, y);
            if (r > best) {
                best = r;
                *mx = x;
            }
        }
        return;
    }
    if (s->mode & 2) {
        int x = (int)lround(s->dx0);
        *mx = x;
        *my = s->y0;
        for (int y = s->y0; y <= s->y1; y++) {
            double r = rpiv_ccm_corr_eval(c, x, y);
            if (r > best) {
                best = r;
                *my = y;
            }
        }
        return;
    }
    *mx = s->x0;
    *my = s->y0;
    for (int y = s->y0; y <= s->y1; y++)
        for (int x = s->x0; x <= s->x1; x++) {
            double r = rpiv_ccm_corr_eval(c, x, y);
            if (r > best) {
                best = r;
                *mx = x;
                *my = y;
            }
        }
}

rpiv_status ccm_sampled_max(const rpiv_ccm_corr *c, const rpiv_ccm_params *p, int *mx, int *my)
{
    span s;
    rpiv_status st = corr_span(c, p, &s);
    if (st)
        return st;
    sampled_argmax(c, &s, mx, my);
    return RPIV_OK;
}

typedef struct pkline {
    const rpiv_ccm_corr *c;
    int axis; /* 0: along x at y = at; 1: along y at x = at */
    double at;
} pkline;

static double line_r(const pkline *l, double t)
{
    return l->axis ? rpiv_ccm_corr_eval(l->c, l->at, t) : rpiv_ccm_corr_eval(l->c, t, l->at);
}

static double line_neg(double t, void *u)
{
    return -line_r(u, t);
}

/* Brent's method on -R along the line, bracketed by the integer samples around m, then a
 * Newton polish on the analytic derivative (Brent alone stops near sqrt(eps) |t|, since R is
 * flat at its maximum). */
static rpiv_status line_max(const pkline *l, int m, int lo, int hi, double guess,
                            const rpiv_ccm_params *p, double *tmax)
{
    double fm = line_r(l, m), fa = line_r(l, m - 1), fb = line_r(l, m + 1);
    /* walk to a local maximum of the samples on this line */
    for (int step = 0; step < hi - lo + 2; step++) {
        if (fb > fm && m + 1 <= hi + 1) {
            m++;
            fa = fm;
            fm = fb;
            fb = line_r(l, m + 1);
        } else if (fa > fm && m - 1 >= lo - 1) {
            m--;
            fb = fm;
            fm = fa;
            fa = line_r(l, m - 1);
        } else {
            break;
        }
    }
    double t0 = m, f0 = fm;
    if (guess > m - 1 && guess < m + 1) {
        double fg = line_r(l, guess);
        if (fg > f0) {
            t0 = guess;
            f0 = fg;
        }
    }
    if (!(f0 > fa) || !(f0 > fb)) {
        double tm = fa == fm ? m - 0.5 : m + 0.5, fmid = line_r(l, tm);
        if (fmid > fa && fmid > fb) {
            t0 = tm;
            f0 = fmid;
        } else {
            return rpiv_fail(RPIV_ENUMERIC, "ccm: flat correlation around shift %d", m);
        }
    }
    gsl_min_fminimizer *s = gsl_min_fminimizer_alloc(gsl_min_fminimizer_brent);
    if (!s)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
    gsl_function F = {line_neg, (void *)l};
    int gs = gsl_min_fminimizer_set_with_values(s, &F, t0, -f0, m - 1.0, -fa, m + 1.0, -fb);
    int it = 0;
    while (gs == GSL_SUCCESS && it++ < p->max_iter) {
        gs = gsl_min_fminimizer_iterate(s);
        if (gs)
            break;
        double a = gsl_min_fminimizer_x_lower(s), b = gsl_min_fminimizer_x_upper(s);
        double x = gsl_min_fminimizer_x_minimum(s);
        if (b - a < p->xtol_px + 4 * GSL_SQRT_DBL_EPSILON * fabs(x)) {
            gs = GSL_SUCCESS;
            break;
        }
        gs = GSL_SUCCESS;
        if (it == p->max_iter)
            gs = GSL_EMAXITER;
    }
    double t = gsl_min_fminimizer_x_minimum(s);
    gsl_min_fminimizer_free(s);
    if (gs)
        return ccm_gsl_fail(gs, "Brent's peak search");
    for (int k = 0; k < 8; k++) {
        double r, g[2], h[3];
        if (l->axis)
            corr_d2(l->c, l->at, t, &r, g, h);
        else
            corr_d2(l->c, t, l->at, &r, g, h);
        double d1 = l->axis ? g[1] : g[0], d2 = l->axis ? h[2] : h[0];
        if (!(d2 < 0))
            break;
        double dt = -d1 / d2;
        if (!(fabs(dt) < 1e-3))
            break;
        t += dt;
        if (fabs(dt) < 4 * DBL_EPSILON * (1 + fabs(t)))
            break;
    }
    *tmax = t;
    return RPIV_OK;
}

static double simplex_neg(const gsl_vector *v, void *u)
{
    return -rpiv_ccm_corr_eval(u, gsl_vector_get(v, 0), gsl_vector_get(v, 1));
}

/* General 2-D case: Nelder-Mead on -R from the sub-pixel estimate, then Newton polish. */
static rpiv_status plane_max(const rpiv_ccm_corr *c, double x0, double y0, const rpiv_ccm_params *p,
                             double *xm, double *ym)
{
    rpiv_status st = RPIV_OK;
    gsl_multimin_fminimizer *s =
        gsl_multimin_fminimizer_alloc(gsl_multimin_fminimizer_nmsimplex2, 2);
    gsl_vector *x = gsl_vector_alloc(2), *step = gsl_vector_alloc(2);
    if (!s || !x || !step) {
        st = rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
        goto out_free;
    }
    gsl_vector_set(x, 0, x0);
    gsl_vector_set(x, 1, y0);
    gsl_vector_set_all(step, 0.25);
    gsl_multimin_function F = {simplex_neg, 2, (void *)c};
    int gs = gsl_multimin_fminimizer_set(s, &F, x, step);
    int it = 0;
    while (gs == GSL_SUCCESS) {
        gs = gsl_multimin_fminimizer_iterate(s);
        if (gs)
            break;
        if (gsl_multimin_test_size(gsl_multimin_fminimizer_size(s), p->xtol_px) == GSL_SUCCESS)
            break;
        if (++it >= p->max_iter)
            gs = GSL_EMAXITER;
    }
    if (gs) {
        st = ccm_gsl_fail(gs, "simplex peak search");
        goto out_free;
    }
    double px = gsl_vector_get(s->x, 0), py = gsl_vector_get(s->x, 1);
    for (int k = 0; k < 8; k++) {
        double r, g[2], h[3];
        corr_d2(c, px, py, &r, g, h);
        double det = h[0] * h[2] - h[1] * h[1];
        if (!(h[0] < 0 && det > 0))
            break;
        double sx = -(h[2] * g[0] - h[1] * g[1]) / det, sy = -(h[0] * g[1] - h[1] * g[0]) / det;
        if (!(fabs(sx) < 1e-3 && fabs(sy) < 1e-3))
            break;
        px += sx;
        py += sy;
        if (fabs(sx) + fabs(sy) < 4 * DBL_EPSILON * (1 + fabs(px) + fabs(py)))
            break;
    }
    *xm = px;
    *ym = py;
out_free:
    gsl_vector_free(step);
    gsl_vector_free(x);
    gsl_multimin_fminimizer_free(s);
    return st;
}

rpiv_status rpiv_ccm_corr_peak(const rpiv_ccm_corr *c, const rpiv_ccm_params *p, rpiv_ccm_peak *out)
{
    span s;
    rpiv_status st = corr_span(c, p, &s);
    if (st)
        return st;
    int mx, my;
    sampled_argmax(c, &s, &mx, &my);
    out->mx = mx;
    out->my = my;
    /* the sampled plane around the maximum, handed to the PIV engine's estimator for a sum
     * of correlation (peak.h, rpiv_subpixel_resolve) as the 8 x 8 float plane in circular
     * order that it reads after an FFT: shifts -4..3, the search over -1..1, normalised by
     * the centre; the samples the estimator reads (the 3-point fits: the row and the column
     * through the centre; the centroid: 3 x 3; the spline: 7 x 7) */
    enum { PW = 8 };
    float plane[PW * PW] = {0};
    rpiv_subpixel method = rpiv_subpixel_resolve(p->subpixel, 1);
    int rad = method == RPIV_SUBPIXEL_SPLINE ? 3 : 1;
    double r0 = rpiv_ccm_corr_eval(c, mx, my);
    for (int j = -rad; j <= rad; j++)
        for (int i = -rad; i <= rad; i++) {
            if (i && j && method != RPIV_SUBPIXEL_CENTROID && method != RPIV_SUBPIXEL_SPLINE)
                continue;
            double v = i || j ? rpiv_ccm_corr_eval(c, mx + i, my + j) / r0 : 1.0;
            plane[((j + PW) % PW) * PW + (i + PW) % PW] = (float)v;
        }
    rpiv_peak fit;
    rpiv_peak_find(plane, PW, PW, 1, method, &fit);
    out->dx_sub = mx + fit.dx;
    out->dy_sub = my + fit.dy;
    /* the continuous maximum */
    if (s.mode == 3) {
        out->dx = s.dx0;
        out->dy = s.dy0;
    } else if (s.mode & 1) {
        pkline l = {c, 0, s.dy0};
        out->dy = s.dy0;
        st = line_max(&l, mx, s.x0, s.x1, out->dx_sub, p, &out->dx);
    } else if (s.mode & 2) {
        pkline l = {c, 1, s.dx0};
        out->dx = s.dx0;
        st = line_max(&l, my, s.y0, s.y1, out->dy_sub, p, &out->dy);
    } else {
        double x0 = isfinite(out->dx_sub) ? out->dx_sub : mx;
        double y0 = isfinite(out->dy_sub) ? out->dy_sub : my;
        st = plane_max(c, x0, y0, p, &out->dx, &out->dy);
    }
    if (st)
        return st;
    out->value = rpiv_ccm_corr_eval(c, out->dx, out->dy);
    return RPIV_OK;
}
