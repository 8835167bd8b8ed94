/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The correlation as a sum of Gaussians and its peak; the model's inputs; Eq. "CCM_gen" and
 * Eq. "CCM_simp". */
#include "ccm_impl.h"
#include "rpiv/peak.h"

#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_math.h>
#include <gsl/gsl_min.h>
#include <gsl/gsl_multimin.h>
#include <gsl/gsl_roots.h>

/* ---- parameters ----------------------------------------------------------------------- */

rpiv_ccm_params rpiv_ccm_params_default(void)
{
    return (rpiv_ccm_params){.epsrel = 1e-9,
                             .limit = 1000,
                             .gl_points = 20,
                             .max_width = 1.0 / 64,
                             .scan = 4001,
                             .xtol_px = 1e-7,
                             .max_iter = 500,
                             .max_range_px = 4096,
                             .subpixel = RPIV_SUBPIXEL_GAUSS,
                             .utab = 4097};
}

rpiv_status rpiv_ccm_params_check(const rpiv_ccm_params *p)
{
    if (!(p->epsrel >= 1e-14 && p->epsrel <= 0.1))
        return rpiv_fail(RPIV_EINVAL, "ccm.epsrel: %g outside 1e-14..0.1", p->epsrel);
    if (p->limit < 10 || p->limit > 1000000)
        return rpiv_fail(RPIV_EINVAL, "ccm.limit: %zu outside 10..1e6", p->limit);
    if (p->gl_points < 2 || p->gl_points > 100)
        return rpiv_fail(RPIV_EINVAL, "ccm.gl_points: %zu outside 2..100", p->gl_points);
    if (!(p->max_width > 1e-6 && p->max_width <= 10))
        return rpiv_fail(RPIV_EINVAL, "ccm.max_width: %g outside (1e-6, 10]", p->max_width);
    if (p->scan < 3 || p->scan > 10000000)
        return rpiv_fail(RPIV_EINVAL, "ccm.scan: %zu outside 3..1e7", p->scan);
    if (!(p->xtol_px > 0 && p->xtol_px < 1))
        return rpiv_fail(RPIV_EINVAL, "ccm.xtol_px: %g outside (0, 1)", p->xtol_px);
    if (p->max_iter < 1 || p->max_iter > 1000000)
        return rpiv_fail(RPIV_EINVAL, "ccm.max_iter: %d outside 1..1e6", p->max_iter);
    if (p->max_range_px < 3 || p->max_range_px > 1000000)
        return rpiv_fail(RPIV_EINVAL, "ccm.max_range_px: %d outside 3..1e6", p->max_range_px);
    if ((p->utab > 0 && p->utab < 5) || p->utab > 10000000)
        return rpiv_fail(RPIV_EINVAL, "ccm.utab: %zu nodes: 0 or 5..1e7", p->utab);
    if (p->subpixel < RPIV_SUBPIXEL_GAUSS || p->subpixel > RPIV_SUBPIXEL_CENTROID)
        return rpiv_fail(RPIV_EINVAL, "ccm.subpixel: unknown estimator %d", (int)p->subpixel);
    return RPIV_OK;
}

rpiv_status ccm_gsl_fail(int gsl_status, const char *what)
{
    return rpiv_fail(RPIV_ENUMERIC, "ccm: %s failed: %s", what, gsl_strerror(gsl_status));
}

rpiv_status ccm_file_begin(const char *path, char *tmp, FILE **fp)
{
    *fp = NULL;
    if (snprintf(tmp, RPIV_PATH_MAX + 16, "%s.tmp", path) >= RPIV_PATH_MAX + 16)
        return rpiv_fail(RPIV_EINVAL, "%s: path too long", path);
    *fp = fopen(tmp, "w");
    if (!*fp)
        return rpiv_fail(RPIV_EIO, "%s: cannot create: %s", path, strerror(errno));
    return RPIV_OK;
}

rpiv_status ccm_file_end(FILE *fp, const char *tmp, const char *path)
{
    int bad = ferror(fp);
    bad |= fclose(fp) != 0;
    if (bad || rename(tmp, path) != 0) {
        remove(tmp);
        return rpiv_fail(RPIV_EIO, "%s: cannot write", path);
    }
    return RPIV_OK;
}

void ccm_file_header(FILE *fp, const char *hdr)
{
    const char *s = hdr;
    while (s && *s) {
        size_t len = strcspn(s, "\n");
        fprintf(fp, "# %.*s\n", (int)len, s);
        s += len;
        if (*s == '\n')
            s++;
    }
}

unsigned long ccm_seed(unsigned long seed, unsigned long index)
{
    unsigned long long z = (unsigned long long)seed * 0x9E3779B97F4A7C15ULL + index + 1;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    z ^= z >> 31;
    return (unsigned long)(z & 0xFFFFFFFFUL);
}

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
    /* the sampled plane around the maximum, handed to the PIV engine's estimator
     * (peak.h) as the 4 x 4 float plane in circular order that it reads after an FFT:
     * shifts -2..1, the fits use -1..1, normalised by the centre */
    float plane[16] = {0};
    double r0 = rpiv_ccm_corr_eval(c, mx, my);
    for (int j = -1; j <= 1; j++)
        for (int i = -1; i <= 1; i++) {
            if (i && j && p->subpixel != RPIV_SUBPIXEL_CENTROID)
                continue; /* the 3-point fits read the row and the column only */
            double v = i || j ? rpiv_ccm_corr_eval(c, mx + i, my + j) / r0 : 1.0;
            plane[((j + 4) % 4) * 4 + (i + 4) % 4] = (float)v;
        }
    rpiv_peak fit;
    rpiv_peak_find(plane, 4, 4, 1, p->subpixel, &fit);
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

/* ---- the model's inputs --------------------------------------------------------------- */

rpiv_ccm_model rpiv_ccm_model_default(void)
{
    static const double one = 1.0;
    rpiv_camera cam = rpiv_camera_default();
    rpiv_channel ch = rpiv_channel_default();
    rpiv_ccm_model m;
    memset(&m, 0, sizeof m);
    m.camera = cam;
    m.h_m = ch.h_m;
    m.dp_m = rpiv_particles_default().dp_m;
    m.scale_px = rpiv_ccm_scale_px(&cam, &ch, 1e-3);
    m.illum = (rpiv_ccm_func){rpiv_ccm_const_fn, &one};
    m.u = (rpiv_ccm_func){rpiv_ccm_duct_fn, NULL};
    m.zlo = 0;
    m.zhi = 1;
    return m;
}

rpiv_status rpiv_ccm_model_check(const rpiv_ccm_model *m)
{
    rpiv_status st = rpiv_camera_check(&m->camera);
    if (st)
        return st;
    if (!(m->h_m > 0 && m->h_m < 10))
        return rpiv_fail(RPIV_EINVAL, "ccm: channel height %g m outside (0, 10)", m->h_m);
    if (!(m->dp_m > 0 && m->dp_m < 1e-2))
        return rpiv_fail(RPIV_EINVAL, "ccm: particle diameter %g m outside (0, 1e-2)", m->dp_m);
    if (!isfinite(m->scale_px) || fabs(m->scale_px) > 1e6)
        return rpiv_fail(RPIV_EINVAL, "ccm: displacement scale %g px outside -1e6..1e6",
                         m->scale_px);
    if (!m->illum.fn || !m->u.fn)
        return rpiv_fail(RPIV_EINVAL, "ccm: the illumination and the velocity profile are "
                                      "required");
    if (!(m->zlo < m->zhi) || !isfinite(m->zlo) || !isfinite(m->zhi))
        return rpiv_fail(RPIV_EINVAL, "ccm: particle heights [%g, %g] are not an interval", m->zlo,
                         m->zhi);
    if (m->nbreaks > RPIV_CCM_MAX_BREAKS)
        return rpiv_fail(RPIV_EINVAL, "ccm: %zu breakpoints, at most %d", m->nbreaks,
                         RPIV_CCM_MAX_BREAKS);
    return RPIV_OK;
}

double rpiv_ccm_scale_px(const rpiv_camera *cam, const rpiv_channel *ch, double dt_s)
{
    return rpiv_channel_bulk_ms(ch) * dt_s * cam->magnification / rpiv_camera_pixel_m(cam);
}

double rpiv_ccm_duct_fn(const void *user, double zstar)
{
    double y = user ? *(const double *)user : 0.5;
    return rpiv_duct_u(y, zstar);
}

double rpiv_ccm_const_fn(const void *user, double zstar)
{
    (void)zstar;
    return *(const double *)user;
}

double rpiv_ccm_sheet_fn(const void *user, double zstar)
{
    const rpiv_ccm_sheet_at *s = user;
    return rpiv_sheet_eval(s->sheet, s->xstar, zstar);
}

static double sheet_neg(double z, void *u)
{
    return -rpiv_ccm_sheet_fn(u, z);
}

/* Scan [a, b] with n + 1 samples; return the index of the largest and its value. */
static size_t scan_max(const rpiv_ccm_sheet_at *at, double a, double b, size_t n, double *best)
{
    size_t k = 0;
    *best = -1;
    for (size_t i = 0; i <= n; i++) {
        double v = rpiv_ccm_sheet_fn(at, a + (b - a) * (double)i / (double)n);
        if (v > *best) {
            *best = v;
            k = i;
        }
    }
    return k;
}

rpiv_status rpiv_ccm_sheet_zmax(const rpiv_sheet *s, double xstar, const rpiv_ccm_params *p,
                                double *zmax)
{
    rpiv_ccm_sheet_at at = {s, xstar};
    /* a coarse scan (1/16 of p->scan), then the fine one around its maximum; the full fine
     * scan if the coarse one sees no light */
    size_t nf = p->scan - 1, nc = nf / 16 >= 16 ? nf / 16 : nf;
    double best, h = 1.0 / (double)nf;
    size_t kc = scan_max(&at, 0, 1, nc, &best);
    double lo = 0, hi = 1;
    size_t n = nf;
    if (best > 0 && nc < nf) {
        lo = fmax(0, (double)(kc - (kc > 0)) / (double)nc);
        hi = fmin(1, (double)(kc + 1) / (double)nc);
        n = (size_t)lround((hi - lo) / h);
    }
    size_t k = scan_max(&at, lo, hi, n, &best);
    if (!(best > 0) && n < nf) {
        lo = 0;
        hi = 1;
        n = nf;
        k = scan_max(&at, lo, hi, n, &best);
    }
    if (!(best > 0))
        return rpiv_fail(RPIV_ENUMERIC, "ccm: the sheet is zero at x* = %g", xstar);
    double step = (hi - lo) / (double)n, z = lo + step * (double)k;
    *zmax = z;
    if ((k == 0 && lo == 0) || (k == n && hi == 1))
        return RPIV_OK;
    double a = z - step, b = z + step;
    double fa = -rpiv_ccm_sheet_fn(&at, a), fb = -rpiv_ccm_sheet_fn(&at, b);
    if (!(-best < fa && -best < fb))
        return RPIV_OK; /* a plateau at the sampled maximum */
    gsl_min_fminimizer *m = gsl_min_fminimizer_alloc(gsl_min_fminimizer_brent);
    if (!m)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
    gsl_function F = {sheet_neg, &at};
    int gs = gsl_min_fminimizer_set_with_values(m, &F, z, -best, a, fa, b, fb);
    for (int it = 0; gs == GSL_SUCCESS && it < p->max_iter; it++) {
        gs = gsl_min_fminimizer_iterate(m);
        double l = gsl_min_fminimizer_x_lower(m), u = gsl_min_fminimizer_x_upper(m);
        if (!gs && u - l < 1e-12 + 4 * GSL_SQRT_DBL_EPSILON * fabs(l))
            break;
    }
    if (!gs)
        *zmax = gsl_min_fminimizer_x_minimum(m);
    gsl_min_fminimizer_free(m);
    return gs ? ccm_gsl_fail(gs, "sheet maximum search") : RPIV_OK;
}

typedef struct zmax_ctx {
    const rpiv_sheet *s;
    const rpiv_ccm_params *p;
    double target;
    int failed;
} zmax_ctx;

static double zmax_minus(double x, void *u)
{
    zmax_ctx *c = u;
    double z;
    if (rpiv_ccm_sheet_zmax(c->s, x, c->p, &z)) {
        c->failed = 1;
        return (double)GSL_NAN;
    }
    return z - c->target;
}

rpiv_status rpiv_ccm_sheet_x_of_zmax(const rpiv_sheet *s, double target, double xlo, double xhi,
                                     const rpiv_ccm_params *p, double *xstar)
{
    zmax_ctx c = {s, p, target, 0};
    double flo = zmax_minus(xlo, &c);
    int dark_lo = c.failed;
    c.failed = 0;
    double fhi = zmax_minus(xhi, &c);
    int dark_hi = c.failed;
    c.failed = 0;
    if (dark_lo != dark_hi) {
        /* The sheet is dark (zero thickness) at one end, as a fitted e*(x*) = e0 + e1 x* is
         * below some x*: the range starts where it is lit, found by bisection. */
        double dark = dark_lo ? xlo : xhi, lit = dark_lo ? xhi : xlo;
        for (int it = 0; it < 200 && fabs(lit - dark) > 1e-12 * fmax(1.0, fabs(lit)); it++) {
            double mid = 0.5 * (dark + lit);
            (void)zmax_minus(mid, &c);
            if (c.failed)
                dark = mid;
            else
                lit = mid;
            c.failed = 0;
        }
        if (dark_lo)
            xlo = lit;
        else
            xhi = lit;
        flo = zmax_minus(xlo, &c);
        fhi = zmax_minus(xhi, &c);
    }
    if (c.failed || (dark_lo && dark_hi))
        return rpiv_fail(RPIV_ENUMERIC, "ccm: the sheet is zero at the ends of x* in [%g, %g]", xlo,
                         xhi);
    if (flo == 0 || fhi == 0) {
        *xstar = flo == 0 ? xlo : xhi;
        return RPIV_OK;
    }
    if ((flo > 0) == (fhi > 0))
        return rpiv_fail(RPIV_EINVAL,
                         "ccm: the sheet's maximum does not reach z* = %g for x* in [%g, %g] "
                         "(z*_max goes from %g to %g)",
                         target, xlo, xhi, flo + target, fhi + target);
    gsl_root_fsolver *r = gsl_root_fsolver_alloc(gsl_root_fsolver_brent);
    if (!r)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
    gsl_function F = {zmax_minus, &c};
    int gs = gsl_root_fsolver_set(r, &F, xlo, xhi);
    for (int it = 0; gs == GSL_SUCCESS; it++) {
        gs = gsl_root_fsolver_iterate(r);
        if (gs || c.failed)
            break;
        double a = gsl_root_fsolver_x_lower(r), b = gsl_root_fsolver_x_upper(r);
        if (gsl_root_test_interval(a, b, 1e-12, 1e-11) == GSL_SUCCESS)
            break;
        if (it >= p->max_iter)
            gs = GSL_EMAXITER;
    }
    *xstar = gsl_root_fsolver_root(r);
    gsl_root_fsolver_free(r);
    if (c.failed)
        return rpiv_fail(RPIV_ENUMERIC, "ccm: the sheet vanishes inside x* in [%g, %g]", xlo, xhi);
    return gs ? ccm_gsl_fail(gs, "search of the section of a given z*_max") : RPIV_OK;
}

/* ---- tabulated curves ----------------------------------------------------------------- */

static rpiv_status curve_alloc(size_t n, int with_w, rpiv_ccm_curve **out)
{
    rpiv_ccm_curve *c = calloc(1, sizeof *c);
    if (!c)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
    c->x = malloc(n * sizeof *c->x);
    c->y = malloc(n * sizeof *c->y);
    c->w = with_w ? malloc(n * sizeof *c->w) : NULL;
    if (!c->x || !c->y || (with_w && !c->w)) {
        rpiv_ccm_curve_free(c);
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for a curve of %zu points", n);
    }
    c->n = n;
    *out = c;
    return RPIV_OK;
}

rpiv_status rpiv_ccm_curve_new(const double *x, const double *y, size_t n, rpiv_ccm_curve **out)
{
    *out = NULL;
    if (n < 2)
        return rpiv_fail(RPIV_EINVAL, "ccm: a curve needs at least 2 points, got %zu", n);
    for (size_t i = 0; i < n; i++) {
        if (!isfinite(x[i]) || !isfinite(y[i]))
            return rpiv_fail(RPIV_EINVAL, "ccm: curve point %zu is not finite", i);
        if (i && !(x[i] > x[i - 1]))
            return rpiv_fail(RPIV_EINVAL, "ccm: curve abscissae not increasing at point %zu", i);
    }
    rpiv_ccm_curve *c = NULL;
    rpiv_status st = curve_alloc(n, 0, &c);
    if (st)
        return st;
    memcpy(c->x, x, n * sizeof *x);
    memcpy(c->y, y, n * sizeof *y);
    *out = c;
    return RPIV_OK;
}

rpiv_status rpiv_ccm_curve_load(const char *path, rpiv_ccm_curve **out)
{
    *out = NULL;
    FILE *fp = fopen(path, "r");
    if (!fp)
        return rpiv_fail(RPIV_EIO, "%s: cannot open: %s", path, strerror(errno));
    rpiv_status st = RPIV_OK;
    size_t n = 0, cap = 0;
    double *x = NULL, *y = NULL, *w = NULL;
    int ncol = 0, lineno = 0;
    char buf[1024];
    while (fgets(buf, sizeof buf, fp)) {
        lineno++;
        char *s = buf + strspn(buf, " \t");
        if (*s == '#' || *s == '\n' || *s == '\r' || *s == '\0')
            continue;
        double v[3];
        int k = sscanf(s, "%lf %lf %lf", &v[0], &v[1], &v[2]);
        if (k < 2 || !isfinite(v[0]) || !isfinite(v[1]) || (k == 3 && !isfinite(v[2]))) {
            st = rpiv_fail(RPIV_EFORMAT, "%s:%d: expected two or three numbers 'x y [w]'", path,
                           lineno);
            goto out_free;
        }
        if (!ncol)
            ncol = k;
        if (k != ncol) {
            st = rpiv_fail(RPIV_EFORMAT, "%s:%d: %d columns, the first row had %d", path, lineno, k,
                           ncol);
            goto out_free;
        }
        if (n && !(v[0] > x[n - 1])) {
            st = rpiv_fail(RPIV_EFORMAT, "%s:%d: first column not increasing", path, lineno);
            goto out_free;
        }
        if (n == cap) {
            cap = cap ? 2 * cap : 64;
            double *nx = realloc(x, cap * sizeof *nx);
            if (nx)
                x = nx;
            double *ny = nx ? realloc(y, cap * sizeof *ny) : NULL;
            if (ny)
                y = ny;
            double *nw = ny ? realloc(w, cap * sizeof *nw) : NULL;
            if (nw)
                w = nw;
            if (!nw) {
                st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
                goto out_free;
            }
        }
        x[n] = v[0];
        y[n] = v[1];
        w[n] = k == 3 ? v[2] : 0;
        n++;
    }
    if (ferror(fp)) {
        st = rpiv_fail(RPIV_EIO, "%s: read error", path);
        goto out_free;
    }
    if (n < 2) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: fewer than 2 data rows", path);
        goto out_free;
    }
    rpiv_ccm_curve *c = NULL;
    st = curve_alloc(n, ncol == 3, &c);
    if (st)
        goto out_free;
    memcpy(c->x, x, n * sizeof *x);
    memcpy(c->y, y, n * sizeof *y);
    if (c->w)
        memcpy(c->w, w, n * sizeof *w);
    *out = c;
out_free:
    free(x);
    free(y);
    free(w);
    fclose(fp);
    return st;
}

void rpiv_ccm_curve_free(rpiv_ccm_curve *c)
{
    if (!c)
        return;
    free(c->x);
    free(c->y);
    free(c->w);
    free(c);
}

double rpiv_ccm_curve_eval(const rpiv_ccm_curve *c, double x)
{
    if (!(x >= c->x[0] && x <= c->x[c->n - 1]))
        return 0;
    size_t lo = 0, hi = c->n - 1;
    while (hi - lo > 1) {
        size_t mid = (lo + hi) / 2;
        if (c->x[mid] <= x)
            lo = mid;
        else
            hi = mid;
    }
    double f = (x - c->x[lo]) / (c->x[hi] - c->x[lo]);
    return c->y[lo] + f * (c->y[hi] - c->y[lo]);
}

double rpiv_ccm_curve_fn(const void *user, double x)
{
    return rpiv_ccm_curve_eval(user, x);
}

rpiv_status rpiv_ccm_profile_of_field(const rpiv_field *f, const rpiv_ccm_geometry *g,
                                      double scale_px, double ystar, rpiv_ccm_curve **out)
{
    *out = NULL;
    if (!(g->star_per_px > 0) || !(fabs(scale_px) > 0) || !(f->dx > 0) || !(f->dy != 0) ||
        f->nx < 1 || f->ny < 1)
        return rpiv_fail(RPIV_EINVAL, "ccm: field or geometry with a zero step or scale");
    /* grid row j has y* = y0_star + (y0 + j dy + 0.5) star_per_px */
    double yp = (ystar - g->y0_star) / g->star_per_px - 0.5;
    double jj = (yp - f->y0) / f->dy;
    long j = lround(jj);
    if (jj < -1 || jj > f->ny) /* more than one step outside */
        return rpiv_fail(RPIV_EINVAL, "ccm: y* = %g is outside the vector field (y* %g to %g)",
                         ystar, g->y0_star + (f->y0 + 0.5) * g->star_per_px,
                         g->y0_star + (f->y0 + (f->ny - 1) * f->dy + 0.5) * g->star_per_px);
    j = j < 0 ? 0 : (j >= f->ny ? f->ny - 1 : j);
    double *x = malloc((size_t)f->nx * sizeof *x), *u = malloc((size_t)f->nx * sizeof *u);
    rpiv_status st = RPIV_OK;
    if (!x || !u) {
        st = rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
        goto out_free;
    }
    size_t n = 0;
    for (int i = 0; i < f->nx; i++) {
        size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
        if (f->flag[k] != RPIV_FLAG_VALID || !isfinite(f->u[k]))
            continue;
        x[n] = g->x0_star + (f->x0 + i * f->dx + 0.5) * g->star_per_px;
        u[n++] = (double)f->u[k] / scale_px;
    }
    if (n < 3) {
        st = rpiv_fail(RPIV_ENUMERIC, "ccm: %zu valid vectors in the field's row at y* = %g", n,
                       ystar);
        goto out_free;
    }
    st = rpiv_ccm_curve_new(x, u, n, out);
out_free:
    free(x);
    free(u);
    return st;
}

/* ---- Eq. "CCM_gen" and Eq. "CCM_simp" ------------------------------------------------- */

/* Peak and variance (px^2) of the image of Eq. "int" of a particle at z with intensity i. */
static void image_of(const ccm_frame *f, double z, double i, double dp, double *peak, double *var)
{
    const rpiv_camera *cam = &f->m->camera;
    double zd = rpiv_imaging_defocus_m(cam, f->m->h_m, z);
    double de = rpiv_imaging_de_m(cam, dp, zd);
    double s = rpiv_imaging_sigma_m(cam, de) / f->pixel_m;
    *peak = rpiv_imaging_peak(cam, i * dp * dp, de, zd);
    *var = s * s;
}

void ccm_frame_init(ccm_frame *f, const rpiv_ccm_model *m)
{
    f->m = m;
    f->pixel_m = rpiv_camera_pixel_m(&m->camera);
    double pk, var;
    /* the reference particle: in focus (z = z*_OP), I0 = 1, d_p of the model */
    image_of(f, m->camera.zop_star, 1.0, m->dp_m, &pk, &var);
    f->ref = pk * pk * M_PI * var;
    f->pnorm = 1;
}

/* The correlation of two Gaussian images P1 exp(-r^2/(2 s1^2)) and P2 exp(-|r-D|^2/(2 s2^2)):
 * P1 P2 2 pi s1^2 s2^2 / (s1^2 + s2^2) exp(-|D - d|^2 / (2 (s1^2 + s2^2))). */
rpiv_ccm_gauss ccm_term(const ccm_frame *f, double z1, double z2, double i1, double i2, double dp1,
                        double dp2, double ddx, double ddy)
{
    double p1, v1, p2, v2;
    image_of(f, z1, i1, dp1, &p1, &v1);
    image_of(f, z2, i2, dp2, &p2, &v2);
    double vs = v1 + v2;
    return (rpiv_ccm_gauss){
        .amp = p1 * p2 * 2 * M_PI * v1 * v2 / vs / f->ref, .c = 1 / (2 * vs), .dx = ddx, .dy = ddy};
}

rpiv_ccm_gauss ccm_amp_term(const ccm_frame *f, double z)
{
    const rpiv_ccm_model *m = f->m;
    double i0 = m->illum.fn(m->illum.user, z);
    double p, v;
    image_of(f, z, i0 > 0 ? i0 : 0, m->dp_m, &p, &v);
    return (rpiv_ccm_gauss){.amp = p * p * M_PI * v / f->ref, .c = 1 / (4 * v), .dx = 0, .dy = 0};
}

rpiv_ccm_gauss ccm_simp_term(const ccm_frame *f, double z)
{
    const rpiv_ccm_model *m = f->m;
    rpiv_ccm_gauss g = ccm_amp_term(f, z);
    g.dx = m->u.fn(m->u.user, z) * m->scale_px;
    g.dy = m->v.fn ? m->v.fn(m->v.user, z) * m->scale_px : 0;
    return g;
}

double ccm_presence(const rpiv_ccm_model *m, double z)
{
    return m->presence.fn ? m->presence.fn(m->presence.user, z) : 1.0;
}

rpiv_status rpiv_ccm_gen(const rpiv_ccm_model *m, const rpiv_ccm_particle *pt, size_t n,
                         rpiv_ccm_corr *out)
{
    rpiv_status st = rpiv_camera_check(&m->camera);
    if (st)
        return st;
    if (!(m->h_m > 0) || !(m->dp_m > 0))
        return rpiv_fail(RPIV_EINVAL, "ccm: channel height and particle diameter must be > 0");
    ccm_frame f;
    ccm_frame_init(&f, m);
    for (size_t i = 0; i < n; i++) {
        const rpiv_ccm_particle *q = &pt[i];
        if (!(q->i1 >= 0 && q->i2 >= 0) || !(q->dp_m > 0) || !isfinite(q->z1) || !isfinite(q->z2) ||
            !isfinite(q->dx) || !isfinite(q->dy))
            return rpiv_fail(RPIV_EINVAL,
                             "ccm: particle %zu: intensities must be >= 0, the diameter > 0 "
                             "and positions finite",
                             i);
        st = rpiv_ccm_corr_add(
            out, ccm_term(&f, q->z1, q->z2, q->i1, q->i2, q->dp_m, q->dp_m, q->dx, q->dy));
        if (st)
            return st;
    }
    return RPIV_OK;
}

rpiv_status rpiv_ccm_simp(const rpiv_ccm_model *m, const double *z, size_t n, double weight,
                          rpiv_ccm_corr *out)
{
    rpiv_status st = rpiv_ccm_model_check(m);
    if (st)
        return st;
    ccm_frame f;
    ccm_frame_init(&f, m);
    for (size_t i = 0; i < n; i++) {
        rpiv_ccm_gauss g = ccm_simp_term(&f, z[i]);
        g.amp *= weight;
        if ((st = rpiv_ccm_corr_add(out, g)))
            return st;
    }
    return RPIV_OK;
}
