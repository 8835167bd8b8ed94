/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Beyond the paper: undo the R-PIV bias. The sheet sits at a different height at every x*, so
 * a row of R-PIV velocities along x* constrains the whole profile U(z*). U is a cubic B-spline
 * (zero at the walls), fitted by regularised non-linear least squares on Eq. "statform". */
#include "ccm_impl.h"

#include "base/atomic.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_blas.h>
#include <gsl/gsl_bspline.h>
#include <gsl/gsl_errno.h>
#include <gsl/gsl_multifit_nlinear.h>

#define ORDER      4  /* cubic */
#define MAX_ROUNDS 10 /* fits with updated offsets (measured = 1) */
/* the offsets have converged when none moves by more than 1e-4 px (3e-5 U* at the default
 * scale, 1e-3 of an ensemble's scatter; above the window's own fixed point, 1e-5 px) */
#define OFFSET_TOL 1e-4
#define LOOSE_TOL  1e-6 /* the fits' tolerances while the offsets move */

rpiv_ccm_invert_params rpiv_ccm_invert_params_default(void)
{
    return (rpiv_ccm_invert_params){.ncoef = 16,
                                    .lambda = 1e-4,
                                    .symmetric = 0,
                                    .sigma = 0,
                                    .max_iter = 100,
                                    .xtol = 1e-10,
                                    .gtol = 1e-10,
                                    .ftol = 1e-12,
                                    .nout = 129,
                                    .measured = 0};
}

rpiv_status rpiv_ccm_invert_params_check(const rpiv_ccm_invert_params *p)
{
    if (p->ncoef < 5 || p->ncoef > 200)
        return rpiv_fail(RPIV_EINVAL, "ccm invert: %zu coefficients outside 5..200", p->ncoef);
    if (!(p->lambda >= 0 && p->lambda < 1e12))
        return rpiv_fail(RPIV_EINVAL, "ccm invert: lambda %g outside 0..1e12", p->lambda);
    if (!(p->sigma >= 0 && p->sigma < 1e6))
        return rpiv_fail(RPIV_EINVAL, "ccm invert: sigma %g outside 0..1e6", p->sigma);
    if (p->max_iter < 1 || p->max_iter > 100000)
        return rpiv_fail(RPIV_EINVAL, "ccm invert: %zu iterations outside 1..1e5", p->max_iter);
    if (!(p->xtol > 0 && p->gtol > 0 && p->ftol > 0 && p->xtol < 1 && p->gtol < 1 && p->ftol < 1))
        return rpiv_fail(RPIV_EINVAL, "ccm invert: tolerances must be in (0, 1)");
    if (p->nout < 2 || p->nout > 1000000)
        return rpiv_fail(RPIV_EINVAL, "ccm invert: %zu output samples outside 2..1e6", p->nout);
    if (p->measured != 0 && p->measured != 1)
        return rpiv_fail(RPIV_EINVAL, "ccm invert: measured %d is neither 0 nor 1", p->measured);
    return RPIV_OK;
}

void rpiv_ccm_invert_free(rpiv_ccm_invert_result *r)
{
    if (!r)
        return;
    free(r->z);
    free(r->u);
    free(r->u_std);
    free(r->xstar);
    free(r->zmax);
    free(r->umeas);
    free(r->ufit);
    free(r->coef);
    free(r);
}

/* One measurement: its fixed quadrature rule and the B-spline basis at the rule's nodes. */
typedef struct meas {
    rpiv_ccm_corr *corr; /* amp, c fixed; dx = scale U(z_n) updated */
    size_t *i0;          /* first non-zero basis function at node n */
    double *b;           /* ORDER values per node */
    double delta;        /* last peak, px */
    double off;          /* what the engine measures less the continuous peak, px (measured) */
    double off_new;      /* the same at the last fitted profile */
} meas;

typedef struct inv {
    size_t nm, ncoef, np;
    meas *m;
    const double *umeas;
    double *wt; /* sqrt of the weight of each measurement */
    double scale, slam;
    int *map;       /* coefficient k -> unknown, -1 = fixed 0 */
    double *coef;   /* full coefficient vector */
    double *cached; /* unknowns of the last forward pass */
    int have_cache;
    rpiv_ccm_params p;
    rpiv_status *sts;
    char (*msg)[256];
    rpiv_status fail;
    char failmsg[256];
    const rpiv_progress *progress;
    size_t max_iter;
    int stop;
    int win_w, win_h, win_deform; /* the engine's window (measured = 1) */
    double win_pairs;
} inv;

static void expand(inv *v, const gsl_vector *x)
{
    for (size_t k = 0; k < v->ncoef; k++)
        v->coef[k] = v->map[k] < 0 ? 0 : gsl_vector_get(x, (size_t)v->map[k]);
}

static double node_u(const inv *v, const meas *m, size_t n)
{
    const double *b = m->b + ORDER * n;
    size_t i = m->i0[n];
    double s = 0;
    for (int q = 0; q < ORDER; q++)
        s += b[q] * v->coef[i + (size_t)q];
    return s;
}

/* The peaks of all measurements at the unknowns x (cached). */
static int forward(inv *v, const gsl_vector *x)
{
    if (v->stop)
        return GSL_EFAILED;
    if (v->have_cache && !memcmp(v->cached, x->data, v->np * sizeof *v->cached) && x->stride == 1)
        return GSL_SUCCESS;
    expand(v, x);
    int bad = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(| : bad)
    for (long j = 0; j < (long)v->nm; j++) {
        meas *m = &v->m[j];
        for (size_t n = 0; n < m->corr->n; n++)
            m->corr->g[n].dx = v->scale * node_u(v, m, n);
        rpiv_ccm_peak pk;
        v->sts[j] = rpiv_ccm_corr_peak(m->corr, &v->p, &pk);
        if (v->sts[j]) {
            snprintf(v->msg[j], sizeof v->msg[j], "%s", rpiv_errmsg());
            bad = 1;
        } else {
            m->delta = pk.dx;
        }
    }
    if (bad) {
        for (size_t j = 0; j < v->nm; j++)
            if (v->sts[j]) {
                v->fail = v->sts[j];
                snprintf(v->failmsg, sizeof v->failmsg, "measurement %zu: %s", j, v->msg[j]);
                break;
            }
        v->have_cache = 0;
        return GSL_EFAILED;
    }
    for (size_t i = 0; i < v->np; i++)
        v->cached[i] = gsl_vector_get(x, i);
    v->have_cache = 1;
    return GSL_SUCCESS;
}

static int res_f(const gsl_vector *x, void *u, gsl_vector *f)
{
    inv *v = u;
    int gs = forward(v, x);
    if (gs)
        return gs;
    for (size_t j = 0; j < v->nm; j++)
        gsl_vector_set(f, j, v->wt[j] * ((v->m[j].delta + v->m[j].off) / v->scale - v->umeas[j]));
    for (size_t k = 0; k + 2 < v->ncoef; k++)
        gsl_vector_set(f, v->nm + k, v->slam * (v->coef[k] - 2 * v->coef[k + 1] + v->coef[k + 2]));
    return GSL_SUCCESS;
}

/* d^2 R_n / d delta^2 of one term on its row (DY = 0) at delta; dR'/dDX_n is its negative. */
static double term_d2(const rpiv_ccm_gauss *g, double d)
{
    double fx, fxd, fxdd, fy, fyd, fydd;
    ccm_axis(d - g->dx, g->c, g->box, &fx, &fxd, &fxdd);
    ccm_axis(0, g->c, g->box, &fy, &fyd, &fydd);
    return g->amp * fxdd * fy;
}

/* dU_j/dc_k by implicit differentiation of R'(delta; c) = 0 at the continuous peak. */
static int res_df(const gsl_vector *x, void *u, gsl_matrix *J)
{
    inv *v = u;
    int gs = forward(v, x);
    if (gs)
        return gs;
    gsl_matrix_set_zero(J);
    for (size_t j = 0; j < v->nm; j++) {
        const meas *m = &v->m[j];
        double d = m->delta, r2 = 0;
        for (size_t n = 0; n < m->corr->n; n++)
            r2 += term_d2(&m->corr->g[n], d);
        if (!(r2 < 0)) {
            v->fail = RPIV_ENUMERIC;
            snprintf(v->failmsg, sizeof v->failmsg,
                     "measurement %zu: the correlation peak is not a maximum", j);
            return GSL_EFAILED;
        }
        for (size_t n = 0; n < m->corr->n; n++) {
            double dn = v->wt[j] * term_d2(&m->corr->g[n], d) / r2;
            const double *b = m->b + ORDER * n;
            for (int q = 0; q < ORDER; q++) {
                int col = v->map[m->i0[n] + (size_t)q];
                if (col >= 0)
                    *gsl_matrix_ptr(J, j, (size_t)col) += dn * b[q];
            }
        }
    }
    static const double d2[3] = {1, -2, 1};
    for (size_t k = 0; k + 2 < v->ncoef; k++)
        for (int q = 0; q < 3; q++) {
            int col = v->map[k + (size_t)q];
            if (col >= 0)
                *gsl_matrix_ptr(J, v->nm + k, (size_t)col) += v->slam * d2[q];
        }
    return GSL_SUCCESS;
}

static void on_iter(const size_t iter, void *u, const gsl_multifit_nlinear_workspace *w)
{
    (void)w;
    inv *v = u;
    if (rpiv_progress_report(v->progress, iter, v->max_iter))
        v->stop = 1;
}

/* What the engine measures less the continuous peak, for every measurement at the unknowns x
 * (rpiv_ccm_corr_peak_window on the measurement's rule): the offsets of the forward model with
 * measured = 1; *change: the largest move of an offset, px. */
static int offsets(inv *v, const gsl_vector *x, double *change)
{
    int gs = forward(v, x);
    if (gs)
        return gs;
#pragma omp parallel for schedule(dynamic, 1)
    for (long j = 0; j < (long)v->nm; j++) {
        meas *m = &v->m[j];
        rpiv_ccm_peak pk;
        v->sts[j] = ccm_corr_peak_window_sig(m->corr, NULL, 0, &v->p, v->win_w, v->win_h,
                                             v->win_deform, v->win_pairs, &pk, NULL);
        if (v->sts[j])
            snprintf(v->msg[j], sizeof v->msg[j], "%s", rpiv_errmsg());
        else if (!isfinite(pk.dx_sub)) {
            v->sts[j] = RPIV_ENUMERIC;
            snprintf(v->msg[j], sizeof v->msg[j], "no sub-pixel estimate of the peak");
        } else
            m->off_new = pk.dx_sub - pk.dx;
    }
    double ch = 0;
    for (size_t j = 0; j < v->nm; j++) {
        if (v->sts[j]) {
            v->fail = v->sts[j];
            snprintf(v->failmsg, sizeof v->failmsg, "measurement %zu: %s", j, v->msg[j]);
            return GSL_EFAILED;
        }
        ch = fmax(ch, fabs(v->m[j].off_new - v->m[j].off));
        v->m[j].off = v->m[j].off_new;
    }
    *change = ch;
    return GSL_SUCCESS;
}

/* Piecewise-linear first guess through the "velocity at z*_max" association, mirrored. */
static double assoc_guess(const double *z, const double *u, size_t n, double zz)
{
    double za = 0, ua = 0;
    for (size_t i = 0; i <= n; i++) {
        double zb = i < n ? z[i] : 1, ub = i < n ? u[i] : 0;
        if (zz <= zb) {
            double f = zb > za ? (zz - za) / (zb - za) : 0;
            return ua + f * (ub - ua);
        }
        za = zb;
        ua = ub;
    }
    return 0;
}

static int cmp_pair(const void *a, const void *b)
{
    double x = ((const double *)a)[0], y = ((const double *)b)[0];
    return (x > y) - (x < y);
}

static void meas_free(meas *m)
{
    rpiv_ccm_corr_free(m->corr);
    free(m->i0);
    free(m->b);
}

/* Build measurement j: the fixed rule at x_j, pruned of negligible terms, and its basis. */
static rpiv_status meas_init(meas *m, const rpiv_ccm_model *base, const rpiv_sheet *sheet,
                             double xstar, rpiv_ccm_work *w, gsl_bspline_workspace *bw,
                             gsl_vector *bk)
{
    rpiv_ccm_model mm = *base;
    rpiv_ccm_sheet_at at = {sheet, xstar};
    mm.illum = (rpiv_ccm_func){rpiv_ccm_sheet_fn, &at};
    mm.v = (rpiv_ccm_func){NULL, NULL};
    rpiv_status st = rpiv_ccm_corr_new(0, &m->corr);
    if (st)
        return st;
    if ((st = rpiv_ccm_stat_corr_fixed(&mm, w, m->corr)))
        return st;
    rpiv_ccm_corr *c = m->corr;
    double amax = 0;
    for (size_t n = 0; n < c->n; n++)
        amax = fmax(amax, c->g[n].amp);
    size_t k = 0;
    for (size_t n = 0; n < c->n; n++) {
        if (c->g[n].amp < 1e-15 * amax)
            continue; /* below the rounding of the sum: no effect on the peak */
        c->g[k] = c->g[n];
        c->g[k].dy = 0;
        w->zn[k] = w->zn[n];
        k++;
    }
    c->n = k;
    m->i0 = malloc(k * sizeof *m->i0);
    m->b = malloc(ORDER * k * sizeof *m->b);
    if (!m->i0 || !m->b)
        return rpiv_fail(RPIV_ENOMEM, "ccm invert: out of memory");
    for (size_t n = 0; n < k; n++) {
        size_t is, ie;
        gsl_bspline_eval_nonzero(w->zn[n], bk, &is, &ie, bw);
        m->i0[n] = is;
        for (int q = 0; q < ORDER; q++)
            m->b[ORDER * n + (size_t)q] = gsl_vector_get(bk, (size_t)q);
    }
    return RPIV_OK;
}

static rpiv_status alloc_result(size_t nout, size_t nm, size_t ncoef, rpiv_ccm_invert_result **out)
{
    rpiv_ccm_invert_result *r = calloc(1, sizeof *r);
    if (!r)
        return rpiv_fail(RPIV_ENOMEM, "ccm invert: out of memory");
    r->nout = nout;
    r->nmeas = nm;
    r->ncoef = ncoef;
    r->z = malloc(nout * sizeof *r->z);
    r->u = malloc(nout * sizeof *r->u);
    r->u_std = malloc(nout * sizeof *r->u_std);
    r->xstar = malloc(nm * sizeof *r->xstar);
    r->zmax = malloc(nm * sizeof *r->zmax);
    r->umeas = malloc(nm * sizeof *r->umeas);
    r->ufit = malloc(nm * sizeof *r->ufit);
    r->coef = malloc(ncoef * sizeof *r->coef);
    if (!r->z || !r->u || !r->u_std || !r->xstar || !r->zmax || !r->umeas || !r->ufit || !r->coef) {
        rpiv_ccm_invert_free(r);
        return rpiv_fail(RPIV_ENOMEM, "ccm invert: out of memory");
    }
    *out = r;
    return RPIV_OK;
}

rpiv_status rpiv_ccm_invert(const rpiv_ccm_model *base, const rpiv_sheet *sheet,
                            const double *xstar, const double *umeas, const double *usigma,
                            size_t n, const rpiv_ccm_invert_params *ip, const rpiv_ccm_params *p,
                            const rpiv_progress *progress, rpiv_ccm_invert_result **out)
{
    *out = NULL;
    rpiv_status st;
    if ((st = rpiv_ccm_model_check(base)) || (st = rpiv_ccm_params_check(p)) ||
        (st = rpiv_ccm_invert_params_check(ip)))
        return st;
    if (n < 3)
        return rpiv_fail(RPIV_EINVAL, "ccm invert: need at least 3 measurements, got %zu", n);
    if (!(fabs(base->scale_px) > 0))
        return rpiv_fail(RPIV_EINVAL, "ccm invert: the displacement scale is zero");
    for (size_t j = 0; j < n; j++)
        if (!isfinite(xstar[j]) || !isfinite(umeas[j]) ||
            (usigma && !(usigma[j] > 0 && isfinite(usigma[j]))))
            return rpiv_fail(RPIV_EINVAL,
                             "ccm invert: measurement %zu is not finite or its sigma not > 0", j);

    inv v;
    memset(&v, 0, sizeof v);
    v.nm = n;
    v.ncoef = ip->ncoef;
    v.umeas = umeas;
    v.scale = base->scale_px;
    v.slam = sqrt(ip->lambda);
    v.p = *p;
    v.progress = progress;
    v.max_iter = ip->max_iter;
    v.win_w = base->window_w;
    v.win_h = base->window_h;
    v.win_deform = base->window_deform;
    v.win_pairs = base->window_pairs;
    rpiv_ccm_invert_result *res = NULL;
    rpiv_ccm_work *w = NULL;
    gsl_bspline_workspace *bw = gsl_bspline_alloc(ORDER, ip->ncoef - ORDER + 2);
    gsl_vector *bk = gsl_vector_alloc(ORDER), *bfull = gsl_vector_alloc(ip->ncoef);
    gsl_vector *x0 = NULL, *tmpv = NULL;
    gsl_matrix *cov = NULL;
    gsl_multifit_nlinear_workspace *nw = NULL;
    double *pairs = NULL;
    v.m = calloc(n, sizeof *v.m);
    v.map = malloc(ip->ncoef * sizeof *v.map);
    v.coef = calloc(ip->ncoef, sizeof *v.coef);
    v.sts = calloc(n, sizeof *v.sts);
    v.wt = malloc(n * sizeof *v.wt);
    v.msg = calloc(n, sizeof *v.msg);
    pairs = malloc(4 * n * sizeof *pairs);
    if (!bw || !bk || !bfull || !v.m || !v.map || !v.coef || !v.sts || !v.wt || !v.msg || !pairs) {
        st = rpiv_fail(RPIV_ENOMEM, "ccm invert: out of memory");
        goto out_free;
    }
    gsl_bspline_knots_uniform(0, 1, bw);
    /* weights sbar / sigma_j with sbar = 1 / sqrt(mean 1/sigma_j^2): their squares average to
     * 1, so lambda keeps its meaning whatever the sigmas */
    double sbar = 0;
    for (size_t j = 0; j < n; j++)
        sbar += usigma ? 1 / (usigma[j] * usigma[j] * (double)n) : 0;
    sbar = usigma ? 1 / sqrt(sbar) : 0;
    for (size_t j = 0; j < n; j++)
        v.wt[j] = usigma ? sbar / usigma[j] : 1;
    /* unknowns: the interior coefficients (the end ones are U at the walls, 0) */
    size_t nc = ip->ncoef, np = 0;
    for (size_t k = 0; k < nc; k++) {
        size_t mk = nc - 1 - k;
        if (k == 0 || k == nc - 1)
            v.map[k] = -1;
        else if (ip->symmetric && mk < k)
            v.map[k] = v.map[mk];
        else
            v.map[k] = (int)np++;
    }
    v.np = np;
    v.cached = malloc(np * sizeof *v.cached);
    if (!v.cached) {
        st = rpiv_fail(RPIV_ENOMEM, "ccm invert: out of memory");
        goto out_free;
    }
    if ((st = alloc_result(ip->nout, n, nc, &res)) || (st = rpiv_ccm_work_new(p, &w)))
        goto out_free;
    /* the measurements' rules and the association of the paper */
    for (size_t j = 0; j < n; j++) {
        if ((st = meas_init(&v.m[j], base, sheet, xstar[j], w, bw, bk)))
            goto out_free;
        if ((st = rpiv_ccm_sheet_zmax(sheet, xstar[j], p, &res->zmax[j])))
            goto out_free;
        res->xstar[j] = xstar[j];
        res->umeas[j] = umeas[j];
        if (rpiv_progress_report(progress, 0, ip->max_iter)) {
            st = rpiv_fail(RPIV_EINTR, "ccm invert: interrupted");
            goto out_free;
        }
    }
    /* first guess: the association, mirrored where the data do not reach */
    size_t na = 0;
    double zdmax = 0;
    for (size_t j = 0; j < n; j++)
        zdmax = fmax(zdmax, res->zmax[j]);
    for (size_t j = 0; j < n; j++) {
        pairs[2 * na] = res->zmax[j];
        pairs[2 * na++ + 1] = umeas[j];
        if (res->zmax[j] < 0.5 && 1 - res->zmax[j] > zdmax) {
            pairs[2 * na] = 1 - res->zmax[j];
            pairs[2 * na++ + 1] = umeas[j];
        }
    }
    qsort(pairs, na, 2 * sizeof *pairs, cmp_pair);
    x0 = gsl_vector_alloc(np);
    tmpv = gsl_vector_alloc(np);
    cov = gsl_matrix_alloc(np, np);
    if (!x0 || !tmpv || !cov) {
        st = rpiv_fail(RPIV_ENOMEM, "ccm invert: out of memory");
        goto out_free;
    }
    {
        double *zz = malloc(na * sizeof *zz), *uu = malloc(na * sizeof *uu);
        if (!zz || !uu) {
            free(zz);
            free(uu);
            st = rpiv_fail(RPIV_ENOMEM, "ccm invert: out of memory");
            goto out_free;
        }
        for (size_t i = 0; i < na; i++) {
            zz[i] = pairs[2 * i];
            uu[i] = pairs[2 * i + 1];
        }
        for (size_t k = 0; k < nc; k++)
            if (v.map[k] >= 0)
                gsl_vector_set(x0, (size_t)v.map[k],
                               assoc_guess(zz, uu, na, gsl_bspline_greville_abscissa(k, bw)));
        free(zz);
        free(uu);
    }
    /* the regularised fit */
    size_t nres = n + nc - 2;
    gsl_multifit_nlinear_parameters fp = gsl_multifit_nlinear_default_parameters();
    nw = gsl_multifit_nlinear_alloc(gsl_multifit_nlinear_trust, &fp, nres, np);
    if (!nw) {
        st = rpiv_fail(RPIV_ENOMEM, "ccm invert: out of memory");
        goto out_free;
    }
    gsl_multifit_nlinear_fdf fdf;
    memset(&fdf, 0, sizeof fdf);
    fdf.f = res_f;
    fdf.df = res_df;
    fdf.n = nres;
    fdf.p = np;
    fdf.params = &v;
    /* measured = 1: the offsets at the first guess, then fit, offsets at the fit, again. While
     * the offsets still move by more than 10 OFFSET_TOL the fit stops at LOOSE_TOL (its
     * solution only starts the next round); the fit the offsets settle on is a tight one */
    double change = 0;
    int gs = ip->measured ? offsets(&v, x0, &change) : GSL_SUCCESS, tight = 0;
    for (size_t round = 1; !gs; round++) {
        int info = 0;
        tight = !ip->measured || change < 10 * OFFSET_TOL;
        gs = gsl_multifit_nlinear_init(x0, &fdf, nw);
        if (!gs)
            gs = gsl_multifit_nlinear_driver(
                ip->max_iter, tight ? ip->xtol : fmax(ip->xtol, LOOSE_TOL),
                tight ? ip->gtol : fmax(ip->gtol, LOOSE_TOL),
                tight ? ip->ftol : fmax(ip->ftol, LOOSE_TOL), on_iter, &v, &info, nw);
        res->rounds = round;
        res->iterations += gsl_multifit_nlinear_niter(nw);
        if (gs == GSL_ENOPROG)
            gs = GSL_SUCCESS;
        if (gs || !ip->measured || (tight && change < OFFSET_TOL))
            break;
        gsl_vector_memcpy(x0, gsl_multifit_nlinear_position(nw));
        gs = offsets(&v, x0, &change);
        if (gs || (tight && change < OFFSET_TOL))
            break;
        if (round == MAX_ROUNDS) {
            v.fail = RPIV_ENUMERIC;
            snprintf(v.failmsg, sizeof v.failmsg,
                     "the engine's offsets still move by %.3g px after %d fits", change,
                     MAX_ROUNDS);
            break;
        }
    }
    if (v.stop) {
        st = rpiv_fail(RPIV_EINTR, "ccm invert: interrupted");
        goto out_free;
    }
    if (v.fail) {
        st = rpiv_fail(v.fail, "ccm invert: %s", v.failmsg);
        goto out_free;
    }
    if (gs) {
        st = ccm_gsl_fail(gs, "the least-squares fit of the profile");
        goto out_free;
    }
    const gsl_vector *xs = gsl_multifit_nlinear_position(nw);
    if (forward(&v, xs)) {
        st = rpiv_fail(v.fail ? v.fail : RPIV_ENUMERIC, "ccm invert: %s", v.failmsg);
        goto out_free;
    }
    /* covariance: sigma^2 (J^T J)^-1 with J including the penalty rows (Bayesian band) */
    gsl_matrix *J = gsl_multifit_nlinear_jac(nw);
    if ((gs = res_df(xs, &v, J)) || (gs = gsl_multifit_nlinear_covar(J, 0.0, cov))) {
        st = v.fail ? rpiv_fail(v.fail, "ccm invert: %s", v.failmsg)
                    : ccm_gsl_fail(gs, "the covariance of the fit");
        goto out_free;
    }
    double chi2 = 0, edf = 0;
    for (size_t j = 0; j < n; j++) {
        res->ufit[j] = (v.m[j].delta + v.m[j].off) / v.scale;
        res->offset_max = fmax(res->offset_max, fabs(v.m[j].off / v.scale));
        double d = v.wt[j] * (res->ufit[j] - umeas[j]);
        chi2 += d * d;
        /* effective degrees of freedom: trace of J_d C J_d^T */
        gsl_vector_const_view row = gsl_matrix_const_row(J, j);
        gsl_blas_dgemv(CblasNoTrans, 1.0, cov, &row.vector, 0.0, tmpv);
        double q;
        gsl_blas_ddot(&row.vector, tmpv, &q);
        edf += q;
    }
    double sigma = ip->sigma > 0 ? ip->sigma : sbar;
    if (!(sigma > 0))
        sigma = (double)n > edf + 0.5 ? sqrt(chi2 / ((double)n - edf)) : sqrt(chi2);
    res->sigma = sigma;
    res->chi2 = chi2;
    memcpy(res->coef, v.coef, nc * sizeof *v.coef);
    for (size_t i = 0; i < ip->nout; i++) {
        double z = (double)i / (double)(ip->nout - 1);
        gsl_bspline_eval(z, bfull, bw);
        double s = 0;
        for (size_t k = 0; k < nc; k++)
            s += gsl_vector_get(bfull, k) * v.coef[k];
        gsl_vector_set_zero(x0);
        for (size_t k = 0; k < nc; k++)
            if (v.map[k] >= 0)
                *gsl_vector_ptr(x0, (size_t)v.map[k]) += gsl_vector_get(bfull, k);
        double var;
        gsl_blas_dgemv(CblasNoTrans, 1.0, cov, x0, 0.0, tmpv);
        gsl_blas_ddot(x0, tmpv, &var);
        res->z[i] = z;
        res->u[i] = s;
        res->u_std[i] = sigma * sqrt(var > 0 ? var : 0);
    }
    *out = res;
    res = NULL;
out_free:
    if (v.m)
        for (size_t j = 0; j < n; j++)
            meas_free(&v.m[j]);
    free(v.m);
    free(v.map);
    free(v.coef);
    free(v.cached);
    free(v.sts);
    free(v.wt);
    free(v.msg);
    free(pairs);
    if (nw)
        gsl_multifit_nlinear_free(nw);
    gsl_matrix_free(cov);
    gsl_vector_free(x0);
    gsl_vector_free(tmpv);
    gsl_vector_free(bk);
    gsl_vector_free(bfull);
    if (bw)
        gsl_bspline_free(bw);
    rpiv_ccm_work_free(w);
    rpiv_ccm_invert_free(res);
    return st;
}

rpiv_status rpiv_ccm_invert_save(const rpiv_ccm_invert_result *r, const char *hdr, const char *path)
{
    atomic_file af; /* unique temporary name, fsync, rename, fsync of the folder */
    rpiv_status st = atomic_begin(&af, path, 1);
    if (st)
        return st;
    FILE *fp = af.fp;
    fprintf(fp, "# rpiv-ccm-invert 1\n");
    ccm_file_header(fp, hdr);
    fprintf(fp, "# sigma = %.6g\n# chi2 = %.6g\n# iterations = %zu\n", r->sigma, r->chi2,
            r->iterations);
    if (r->rounds > 1 || r->offset_max > 0)
        fprintf(fp,
                "# forward model: the engine's estimate on its window, %zu fits, largest "
                "offset from the continuous peak %.6g U*\n",
                r->rounds, r->offset_max);
    fprintf(fp, "# measurements: #m x* z*_max U*_meas U*_fit\n");
    for (size_t j = 0; j < r->nmeas; j++)
        fprintf(fp, "#m %.8g %.8g %.10g %.10g\n", r->xstar[j], r->zmax[j], r->umeas[j], r->ufit[j]);
    fprintf(fp, "# columns: z* U* std_U*\n");
    for (size_t i = 0; i < r->nout; i++)
        fprintf(fp, "%.8g %.10g %.6e\n", r->z[i], r->u[i], r->u_std[i]);
    return atomic_commit(&af);
}

static int cmp_triple(const void *a, const void *b)
{
    double x = ((const double *)a)[0], y = ((const double *)b)[0];
    return (x > y) - (x < y);
}

rpiv_status rpiv_ccm_invert_e1(const rpiv_ccm_invert_result *r, rpiv_ccm_func ref, int mirror,
                               double *e1_assoc, double *e1_corr)
{
    size_t n = r->nmeas, k = 0;
    rpiv_status st = RPIV_OK;
    double *t = malloc(3 * 2 * n * sizeof *t); /* (z, U_assoc, U_corr) */
    double *z = malloc(2 * n * sizeof *z), *a = malloc(2 * n * sizeof *a),
           *c = malloc(2 * n * sizeof *c), *f = malloc(2 * n * sizeof *f);
    gsl_bspline_workspace *bw = gsl_bspline_alloc(ORDER, r->ncoef - ORDER + 2);
    gsl_vector *b = gsl_vector_alloc(r->ncoef);
    if (!t || !z || !a || !c || !f || !bw || !b) {
        st = rpiv_fail(RPIV_ENOMEM, "ccm invert: out of memory");
        goto out_free;
    }
    gsl_bspline_knots_uniform(0, 1, bw);
    for (size_t j = 0; j < n; j++) {
        double zz[2] = {r->zmax[j], 1 - r->zmax[j]};
        for (int q = 0; q < (mirror && r->zmax[j] < 0.5 - 1e-9 ? 2 : 1); q++) {
            if (!(zz[q] >= 0 && zz[q] <= 1))
                continue;
            gsl_bspline_eval(zz[q], b, bw);
            double u = 0;
            for (size_t i = 0; i < r->ncoef; i++)
                u += gsl_vector_get(b, i) * r->coef[i];
            t[3 * k] = zz[q];
            t[3 * k + 1] = r->umeas[j];
            t[3 * k + 2] = u;
            k++;
        }
    }
    qsort(t, k, 3 * sizeof *t, cmp_triple);
    for (size_t i = 0; i < k; i++) {
        z[i] = t[3 * i];
        a[i] = t[3 * i + 1];
        c[i] = t[3 * i + 2];
        f[i] = ref.fn(ref.user, z[i]);
    }
    if ((st = rpiv_e1(z, f, a, k, e1_assoc)))
        goto out_free;
    st = rpiv_e1(z, f, c, k, e1_corr);
out_free:
    free(t);
    free(z);
    free(a);
    free(c);
    free(f);
    gsl_vector_free(b);
    if (bw)
        gsl_bspline_free(bw);
    return st;
}
