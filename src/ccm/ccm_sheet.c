/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The sheet seen by the model: the height z*_max(x*) of its maximum at a section and the
 * section where that height is a given z* (the R-PIV scenario and the inverse problem). */
#include "ccm_impl.h"

#include <math.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_math.h>
#include <gsl/gsl_min.h>
#include <gsl/gsl_roots.h>

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
