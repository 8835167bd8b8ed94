/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Eq. "statform": the correlation averaged over the particle-presence law, by adaptive
 * quadrature, and as a cached quadrature rule whose nodes are Gaussian terms. */
#include "ccm_impl.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_spline.h>

#define MAX_PTS (RPIV_CCM_MAX_BREAKS + 12)
/* Gauss-Legendre points of the first pass, which only locates the integer peak */
#define COARSE_POINTS 5

rpiv_status rpiv_ccm_work_new(const rpiv_ccm_params *p, rpiv_ccm_work **out)
{
    *out = NULL;
    rpiv_status st = rpiv_ccm_params_check(p);
    if (st)
        return st;
    rpiv_ccm_work *w = calloc(1, sizeof *w);
    if (!w)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
    w->p = *p;
    w->iw = gsl_integration_workspace_alloc(p->limit);
    w->gl = gsl_integration_glfixed_table_alloc(p->gl_points);
    w->gl1 = gsl_integration_glfixed_table_alloc(COARSE_POINTS);
    w->scan_z = malloc(p->scan * sizeof *w->scan_z);
    w->scan_v = malloc(p->scan * sizeof *w->scan_v);
    w->ia = malloc(p->limit * sizeof *w->ia);
    w->ib = malloc(p->limit * sizeof *w->ib);
    if (!w->iw || !w->gl || !w->gl1 || !w->scan_z || !w->scan_v || !w->ia || !w->ib) {
        rpiv_ccm_work_free(w);
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for the quadrature workspace");
    }
    st = rpiv_ccm_corr_new(1024, &w->corr);
    if (st) {
        rpiv_ccm_work_free(w);
        return st;
    }
    *out = w;
    return RPIV_OK;
}

void rpiv_ccm_work_free(rpiv_ccm_work *w)
{
    if (!w)
        return;
    if (w->iw)
        gsl_integration_workspace_free(w->iw);
    if (w->gl)
        gsl_integration_glfixed_table_free(w->gl);
    if (w->gl1)
        gsl_integration_glfixed_table_free(w->gl1);
    free(w->scan_z);
    free(w->scan_v);
    free(w->ia);
    free(w->ib);
    free(w->zn);
    rpiv_ccm_corr_free(w->corr);
    free(w);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Add the sampled maximum of f and the samples where it falls below a quarter of it. */
static size_t add_features(rpiv_ccm_work *w, rpiv_ccm_fn fn, const void *user, double *pts,
                           size_t n, size_t cap)
{
    size_t ns = w->p.scan, k = 0;
    double best = -HUGE_VAL;
    for (size_t i = 0; i < ns; i++) {
        w->scan_v[i] = fn(user, w->scan_z[i]);
        if (w->scan_v[i] > best) {
            best = w->scan_v[i];
            k = i;
        }
    }
    if (!(best > 0))
        return n;
    double q = 0.25 * best;
    size_t lo = k, hi = k;
    while (lo > 0 && w->scan_v[lo] >= q)
        lo--;
    while (hi < ns - 1 && w->scan_v[hi] >= q)
        hi++;
    if (lo == 0 && hi == ns - 1)
        return n; /* no narrow feature (e.g. a constant) */
    const size_t idx[3] = {lo, k, hi};
    for (int j = 0; j < 3 && n < cap; j++)
        pts[n++] = w->scan_z[idx[j]];
    return n;
}

size_t ccm_breakpoints(const rpiv_ccm_model *m, rpiv_ccm_work *w, double *pts, size_t cap)
{
    size_t n = 0, ns = w->p.scan;
    pts[n++] = m->zlo;
    pts[n++] = m->zhi;
    pts[n++] = m->camera.zop_star;
    for (size_t i = 0; i < m->nbreaks && n < cap; i++)
        pts[n++] = m->breaks[i];
    for (size_t i = 0; i < ns; i++)
        w->scan_z[i] = m->zlo + (m->zhi - m->zlo) * (double)i / (double)(ns - 1);
    n = add_features(w, m->illum.fn, m->illum.user, pts, n, cap);
    if (m->presence.fn)
        n = add_features(w, m->presence.fn, m->presence.user, pts, n, cap);
    qsort(pts, n, sizeof *pts, cmp_double);
    size_t k = 0;
    double tiny = 1e-12 * (m->zhi - m->zlo);
    for (size_t i = 0; i < n; i++) {
        if (pts[i] < m->zlo || pts[i] > m->zhi)
            continue;
        if (k && pts[i] - pts[k - 1] <= tiny)
            continue;
        pts[k++] = pts[i];
    }
    /* make the ends exact */
    pts[0] = m->zlo;
    pts[k - 1] = m->zhi;
    return k;
}

/* The integrand of Eq. "statform" and its probes. */
typedef struct integ {
    ccm_frame f;
    int nshift; /* 0: amplitude alone; else sum over the shifts */
    int exact;  /* boxed terms: 1 exact; 0 the Gaussian of the same variance (the rule's
                 * adaptive pass only chooses subintervals; the rule's terms are exact) */
    double sx[5], sy[5];
} integ;

static double integrand(double z, void *u)
{
    const integ *q = u;
    if (!q->nshift) /* the amplitude alone: no velocity needed */
        return ccm_amp_term(&q->f, z).amp * ccm_presence(q->f.m, z) * q->f.pnorm;
    rpiv_ccm_gauss g = ccm_simp_term(&q->f, z);
    double a = g.amp * ccm_presence(q->f.m, z) * q->f.pnorm;
    if (!(a > 0))
        return a;
    double s = 0;
    for (int k = 0; k < q->nshift; k++) {
        rpiv_ccm_gauss unit = g;
        unit.amp = 1;
        if (!q->exact && g.box > 0) {
            double cc = g.c / (1 + g.c * g.box * g.box / 3);
            unit = (rpiv_ccm_gauss){cc / g.c, cc, g.dx, g.dy, 0};
        }
        s += ccm_term_eval(&unit, q->sx[k] - g.dx, q->sy[k] - g.dy);
    }
    return a * s;
}

static double presence_fn(double z, void *u)
{
    return ccm_presence(u, z);
}

static rpiv_status qagp(rpiv_ccm_work *w, gsl_function *F, const double *pts, size_t npts,
                        double *res, const char *what)
{
    double tmp[MAX_PTS], err;
    memcpy(tmp, pts, npts * sizeof *pts);
    int gs = gsl_integration_qagp(F, tmp, npts, 0, w->p.epsrel, w->p.limit, w->iw, res, &err);
    if (gs && gs != GSL_EROUND)
        return ccm_gsl_fail(gs, what);
    if (!isfinite(*res))
        return rpiv_fail(RPIV_ENUMERIC, "ccm: %s is not finite", what);
    return RPIV_OK;
}

/* Prepare the frame (normalisation of P) and the breakpoints. */
static rpiv_status setup(const rpiv_ccm_model *m, rpiv_ccm_work *w, integ *q, double *pts,
                         size_t *npts)
{
    rpiv_status st = rpiv_ccm_model_check(m);
    if (st)
        return st;
    memset(q, 0, sizeof *q);
    ccm_frame_init(&q->f, m);
    *npts = ccm_breakpoints(m, w, pts, MAX_PTS);
    if (!m->presence.fn) {
        q->f.pnorm = 1 / (m->zhi - m->zlo);
        return RPIV_OK;
    }
    double tot;
    gsl_function F = {presence_fn, (void *)m};
    if ((st = qagp(w, &F, pts, *npts, &tot, "the integral of the presence law P")))
        return st;
    if (!(tot > 0))
        return rpiv_fail(RPIV_EINVAL, "ccm: the presence law P integrates to %g over [%g, %g]", tot,
                         m->zlo, m->zhi);
    q->f.pnorm = 1 / tot;
    return RPIV_OK;
}

rpiv_status rpiv_ccm_stat_eval(const rpiv_ccm_model *m, rpiv_ccm_work *w, double dx, double dy,
                               double *value)
{
    integ q;
    double pts[MAX_PTS];
    size_t npts;
    rpiv_status st = setup(m, w, &q, pts, &npts);
    if (st)
        return st;
    q.nshift = 1;
    q.exact = 1;
    q.sx[0] = dx;
    q.sy[0] = dy;
    gsl_function F = {integrand, &q};
    return qagp(w, &F, pts, npts, value, "the integral of Eq. statform");
}

/* Adaptive pass on the probe; keep its final subintervals, sorted. */
static rpiv_status partition(rpiv_ccm_work *w, integ *q, const double *pts, size_t npts)
{
    double res;
    gsl_function F = {integrand, q};
    rpiv_status st = qagp(w, &F, pts, npts, &res, "the adaptive quadrature of Eq. statform");
    if (st)
        return st;
    if (!(res > 0))
        return rpiv_fail(RPIV_ENUMERIC,
                         "ccm: no illuminated particle between z* = %g and %g (the integral "
                         "of P I0^2 ... is %g)",
                         q->f.m->zlo, q->f.m->zhi, res);
    size_t n = w->iw->size;
    for (size_t i = 0; i < n; i++)
        w->ia[i] = w->iw->alist[i];
    qsort(w->ia, n, sizeof *w->ia, cmp_double);
    /* the upper ends are the next lower ends and zhi */
    for (size_t i = 0; i + 1 < n; i++)
        w->ib[i] = w->ia[i + 1];
    w->ib[n - 1] = q->f.m->zhi;
    w->nint = n;
    return RPIV_OK;
}

/* Gauss-Legendre nodes on the partition, each interval split to max_width: one term each. */
static rpiv_status fill_rule(rpiv_ccm_work *w, const integ *q, int coarse, rpiv_ccm_corr *out)
{
    out->n = 0;
    rpiv_status st;
    const gsl_integration_glfixed_table *gl = coarse ? w->gl1 : w->gl;
    size_t npt = coarse ? COARSE_POINTS : w->p.gl_points;
    for (size_t i = 0; i < w->nint; i++) {
        double a = w->ia[i], b = w->ib[i];
        size_t nsub = coarse ? 1 : (size_t)ceil((b - a) / w->p.max_width - 1e-9);
        if (nsub < 1)
            nsub = 1;
        for (size_t s = 0; s < nsub; s++) {
            double sa = a + (b - a) * (double)s / (double)nsub;
            double sb = s + 1 == nsub ? b : a + (b - a) * (double)(s + 1) / (double)nsub;
            for (size_t k = 0; k < npt; k++) {
                double zk, wk;
                gsl_integration_glfixed_point(sa, sb, k, &zk, &wk, gl);
                rpiv_ccm_gauss g = ccm_simp_term(&q->f, zk);
                g.amp *= wk * ccm_presence(q->f.m, zk) * q->f.pnorm;
                if (!(g.amp > 0))
                    continue;
                if (out->n == w->zcap) {
                    size_t cap = w->zcap ? 2 * w->zcap : 1024;
                    double *nz = realloc(w->zn, cap * sizeof *nz);
                    if (!nz)
                        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
                    w->zn = nz;
                    w->zcap = cap;
                }
                w->zn[out->n] = zk;
                if ((st = rpiv_ccm_corr_add(out, g)))
                    return st;
            }
        }
    }
    /* drop the terms below the rounding of the sum (the far tails of a sheet): they cannot
     * move the peak and would cost an exponential at every evaluation */
    double amax = 0;
    for (size_t k = 0; k < out->n; k++)
        amax = fmax(amax, out->g[k].amp);
    size_t k = 0;
    for (size_t i = 0; i < out->n; i++)
        if (out->g[i].amp >= 1e-17 * amax) {
            out->g[k] = out->g[i];
            w->zn[k++] = w->zn[i];
        }
    out->n = k;
    return RPIV_OK;
}

rpiv_status rpiv_ccm_stat_corr_fixed(const rpiv_ccm_model *m, rpiv_ccm_work *w, rpiv_ccm_corr *out)
{
    integ q;
    double pts[MAX_PTS];
    size_t npts;
    rpiv_status st = setup(m, w, &q, pts, &npts);
    if (st)
        return st;
    if ((st = partition(w, &q, pts, npts)))
        return st;
    return fill_rule(w, &q, 0, out);
}

rpiv_status rpiv_ccm_stat_corr(const rpiv_ccm_model *m, rpiv_ccm_work *w, rpiv_ccm_corr *out)
{
    integ q;
    double pts[MAX_PTS];
    size_t npts;
    rpiv_status st = setup(m, w, &q, pts, &npts);
    if (st)
        return st;
    /* first pass: the amplitude alone and a coarse rule, to find the sampled peak */
    if ((st = partition(w, &q, pts, npts)) || (st = fill_rule(w, &q, 1, out)))
        return st;
    int mx, my;
    if ((st = ccm_sampled_max(out, &w->p, &mx, &my)))
        return st;
    /* second pass: the integrand itself around the sampled peak */
    static const int ox[5] = {0, -1, 1, 0, 0}, oy[5] = {0, 0, 0, -1, 1};
    q.nshift = 5;
    for (int k = 0; k < 5; k++) {
        q.sx[k] = mx + ox[k];
        q.sy[k] = my + oy[k];
    }
    if ((st = partition(w, &q, pts, npts)))
        return st;
    q.nshift = 0;
    return fill_rule(w, &q, 0, out);
}

rpiv_status rpiv_ccm_predict(const rpiv_ccm_model *m, rpiv_ccm_work *w, rpiv_ccm_peak *out)
{
    return ccm_predict_sig(m, w, out, NULL);
}

rpiv_status ccm_predict_sig(const rpiv_ccm_model *m, rpiv_ccm_work *w, rpiv_ccm_peak *out,
                            ccm_wsig *sig)
{
    rpiv_status st = rpiv_ccm_stat_corr(m, w, w->corr);
    if (st)
        return st;
    return ccm_corr_peak_window_sig(w->corr, NULL, 0, &w->p, m->window_w, m->window_h,
                                    m->window_deform, m->window_pairs, out, sig);
}

/* ---- the tabulated velocity profile ----------------------------------------------------- */

static double utab_u(const void *user, double z)
{
    const ccm_utab *t = user;
    if (!(z >= t->zlo && z <= t->zhi))
        return t->u0.fn(t->u0.user, z);
    return gsl_spline_eval(t->su, z, NULL);
}

static double utab_v(const void *user, double z)
{
    const ccm_utab *t = user;
    if (!(z >= t->zlo && z <= t->zhi))
        return t->v0.fn(t->v0.user, z);
    return gsl_spline_eval(t->sv, z, NULL);
}

static rpiv_status spline_of(rpiv_ccm_func f, double zlo, double zhi, size_t n, void **out)
{
    double *x = malloc(n * sizeof *x), *y = malloc(n * sizeof *y);
    gsl_spline *s = gsl_spline_alloc(gsl_interp_akima, n);
    rpiv_status st = RPIV_OK;
    if (!x || !y || !s) {
        st = rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for the velocity table");
        goto out_free;
    }
    for (size_t i = 0; i < n; i++) {
        x[i] = zlo + (zhi - zlo) * (double)i / (double)(n - 1);
        y[i] = f.fn(f.user, x[i]);
        if (!isfinite(y[i])) {
            st = rpiv_fail(RPIV_EINVAL, "ccm: the velocity profile is not finite at z* = %g", x[i]);
            goto out_free;
        }
    }
    x[n - 1] = zhi;
    int gs = gsl_spline_init(s, x, y, n);
    if (gs) {
        st = ccm_gsl_fail(gs, "the velocity table");
        goto out_free;
    }
    *out = s;
    s = NULL;
out_free:
    if (s)
        gsl_spline_free(s);
    free(x);
    free(y);
    return st;
}

rpiv_status ccm_utab_init(ccm_utab *t, const rpiv_ccm_model *m, const rpiv_ccm_params *p,
                          rpiv_ccm_model *tm)
{
    memset(t, 0, sizeof *t);
    *tm = *m;
    if (!p->utab)
        return RPIV_OK;
    t->u0 = m->u;
    t->v0 = m->v;
    t->zlo = m->zlo;
    t->zhi = m->zhi;
    rpiv_status st = spline_of(m->u, m->zlo, m->zhi, p->utab, &t->su);
    if (!st && m->v.fn)
        st = spline_of(m->v, m->zlo, m->zhi, p->utab, &t->sv);
    if (st) {
        ccm_utab_free(t);
        return st;
    }
    tm->u = (rpiv_ccm_func){utab_u, t};
    if (m->v.fn)
        tm->v = (rpiv_ccm_func){utab_v, t};
    return RPIV_OK;
}

void ccm_utab_free(ccm_utab *t)
{
    if (t->su)
        gsl_spline_free(t->su);
    if (t->sv)
        gsl_spline_free(t->sv);
    t->su = t->sv = NULL;
}
