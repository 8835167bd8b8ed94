/* SPDX-License-Identifier: GPL-3.0-or-later */
/* What the ray tracer's results are used for: beta1 sweeps (paper figs 11-12), the one-ray
 * sensitivity to the index ratio (fig. 10) and the self-similar sheet fit (sheet.h). */
#include "rpiv/optics.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_fit.h>
#include <gsl/gsl_interp.h>

/* ---- sweeps -------------------------------------------------------------------------------- */

static void fill_row(const rpiv_optics_result *r, rpiv_optics_sweep_row *row, double *prof)
{
    rpiv_sheet_metrics m;
    row->beta1_deg = r->laser.beta1_deg;
    row->it_ig = r->stats.transmitted;
    row->elevation_deg = r->axis.transmitted ? r->axis.elevation * 180 / M_PI : (double)NAN;
    row->ipeak = rpiv_optics_profile_norm(r, 0, prof);
    if (rpiv_sheet_metrics_of(r->zstar, r->inten, r->nz, &m) == RPIV_OK) {
        row->zmax = m.zmax;
        row->zinf = m.zinf;
        row->zsup = m.zsup;
        row->e = m.e;
    } else {
        row->zmax = row->zinf = row->zsup = row->e = (double)NAN;
        rpiv_errclear();
    }
}

rpiv_status rpiv_optics_sweep_beta1(const rpiv_laser *l, const rpiv_prism *p, double h_m,
                                    double xstar, const double *beta1, size_t n,
                                    const rpiv_optics_opts *o, const rpiv_progress *prog,
                                    rpiv_optics_sweep_row *rows, double *profiles)
{
    rpiv_status st;
    if (n < 1)
        return rpiv_fail(RPIV_EINVAL, "raytrace: empty beta1 sweep");
    if ((st = rpiv_optics_opts_check(o)))
        return st;
    size_t nz = rpiv_optics_nbins(o);
    double *prof = malloc(nz * sizeof *prof);
    if (!prof)
        return rpiv_fail(RPIV_ENOMEM, "raytrace: out of memory");
    double ref = (double)NAN;
    int have_ref = 0;
    size_t total = n + 1; /* one more trace for the reference unless 2 deg is in the list */
    for (size_t i = 0; i < n; i++)
        if (fabs(beta1[i] - 2.0) < 1e-12)
            total = n;
    for (size_t i = 0; i <= n; i++) {
        rpiv_laser li = *l;
        if (i == n) { /* the reference, if the sweep did not pass through 2 deg */
            if (have_ref)
                break;
            li.beta1_deg = 2.0;
        } else {
            li.beta1_deg = beta1[i];
        }
        rpiv_optics_result *r;
        if ((st = rpiv_optics_trace(&li, p, h_m, &xstar, 1, o, NULL, &r)))
            goto out_free;
        rpiv_optics_sweep_row row;
        fill_row(r, &row, prof);
        rpiv_optics_result_free(r);
        if (fabs(li.beta1_deg - 2.0) < 1e-12) {
            ref = row.ipeak;
            have_ref = 1;
        }
        if (i < n) {
            rows[i] = row;
            if (profiles)
                memcpy(profiles + i * nz, prof, nz * sizeof *prof);
        }
        if (rpiv_progress_report(prog, i + 1, total)) {
            st = rpiv_fail(RPIV_EINTR, "raytrace: sweep interrupted at beta1 = %g deg",
                           li.beta1_deg);
            goto out_free;
        }
    }
    for (size_t i = 0; i < n; i++)
        rows[i].ipeak_star = ref > 0 ? rows[i].ipeak / ref : (double)NAN;
    st = RPIV_OK;
out_free:
    free(prof);
    return st;
}

/* ---- one-ray sensitivity ------------------------------------------------------------------- */

rpiv_status rpiv_optics_sensitivity(const rpiv_laser *l, const rpiv_prism *p, double deta0,
                                    double deta1, size_t n, rpiv_optics_sens_row *rows,
                                    double *cutoff)
{
    rpiv_optics_axis ax;
    rpiv_status st;
    if (n < 2 || !isfinite(deta0) || !isfinite(deta1) || !(deta1 > deta0))
        return rpiv_fail(RPIV_EINVAL,
                         "raytrace: sensitivity needs deta0 < deta1 and at least 2 rows");
    if ((st = rpiv_optics_axis_of(l, p, &ax)))
        return st;
    double eta0 = p->n_pmma / p->n_water, tt0, T0;
    if (!rpiv_optics_refract(eta0, 1.0, ax.theta_i, l->polar, &tt0, &T0) || !(T0 > 0))
        return rpiv_fail(RPIV_ENUMERIC,
                         "raytrace: the axis ray is totally reflected at the floor (incidence "
                         "%.4f deg, critical %.4f deg): no reference for the sensitivity",
                         ax.theta_i * 180 / M_PI, ax.theta_c * 180 / M_PI);
    if (deta0 <= -eta0)
        return rpiv_fail(RPIV_EINVAL, "raytrace: deta %g makes the index ratio negative", deta0);
    for (size_t i = 0; i < n; i++) {
        rpiv_optics_sens_row *q = rows + i;
        q->deta = deta0 + (deta1 - deta0) * (double)i / (double)(n - 1);
        q->transmitted =
            rpiv_optics_refract(eta0 + q->deta, 1.0, ax.theta_i, l->polar, &q->theta_t, &q->T);
        q->dtheta_rel = q->transmitted ? q->theta_t / tt0 - 1 : (double)NAN;
        q->dT_rel = q->T / T0 - 1;
    }
    if (cutoff)
        *cutoff = 1.0 / sin(ax.theta_i) - eta0;
    return RPIV_OK;
}

/* ---- self-similar fit ---------------------------------------------------------------------- */

void rpiv_optics_selfsim_free(rpiv_optics_selfsim *f)
{
    if (!f)
        return;
    free(f->zplus);
    free(f->shape);
    free(f);
}

static double rms_resid(const double *x, const double *y, size_t n, double c0, double c1)
{
    double s = 0;
    for (size_t i = 0; i < n; i++) {
        double d = y[i] - (c0 + c1 * x[i]);
        s += d * d;
    }
    return sqrt(s / (double)n);
}

rpiv_status rpiv_optics_selfsim_fit(const double *xstar, size_t nx, const double *zstar, size_t nz,
                                    const double *inten, double dzplus, rpiv_optics_selfsim **out)
{
    rpiv_status st = RPIV_OK;
    *out = NULL;
    if (nx < 2 || nz < 3)
        return rpiv_fail(RPIV_EINVAL, "selfsim fit: need 2 stations and 3 heights (have %zu, %zu)",
                         nx, nz);
    if (!(dzplus >= 1e-4 && dzplus <= 0.5))
        return rpiv_fail(RPIV_EINVAL, "selfsim fit: z+ step %g outside 1e-4..0.5", dzplus);
    for (size_t j = 1; j < nz; j++)
        if (!(zstar[j] > zstar[j - 1]))
            return rpiv_fail(RPIV_EINVAL, "selfsim fit: heights not increasing at row %zu", j);
    rpiv_optics_selfsim *f = calloc(1, sizeof *f);
    double *xs = malloc(nx * sizeof *xs), *es = malloc(nx * sizeof *es),
           *zm = malloc(nx * sizeof *zm), *im = malloc(nx * sizeof *im);
    size_t *idx = malloc(nx * sizeof *idx);
    double *res = NULL, *norm = malloc(nz * sizeof *norm);
    gsl_interp *li = gsl_interp_alloc(gsl_interp_linear, nz); /* a station's I(z*), linear */
    gsl_interp_accel *hint = gsl_interp_accel_alloc();
    if (!f || !xs || !es || !zm || !im || !idx || !norm || !li || !hint) {
        st = rpiv_fail(RPIV_ENOMEM, "selfsim fit: out of memory");
        goto out_free;
    }
    size_t nu = 0;
    double zpmin = (double)INFINITY, zpmax = -(double)INFINITY;
    for (size_t k = 0; k < nx; k++) {
        rpiv_sheet_metrics m;
        if (rpiv_sheet_metrics_of(zstar, inten + k * nz, nz, &m) != RPIV_OK || !(m.e > 0)) {
            rpiv_errclear();
            continue;
        }
        xs[nu] = xstar[k];
        es[nu] = m.e;
        zm[nu] = m.zmax;
        im[nu] = m.imax;
        idx[nu] = k;
        zpmin = fmin(zpmin, rpiv_sheet_zplus(zstar[0], m.zmax, m.e));
        zpmax = fmax(zpmax, rpiv_sheet_zplus(zstar[nz - 1], m.zmax, m.e));
        nu++;
    }
    if (nu < 2) {
        st = rpiv_fail(RPIV_ENUMERIC,
                       "selfsim fit: only %zu of %zu stations have a sheet that falls to a "
                       "quarter of its peak on both sides inside the channel",
                       nu, nx);
        goto out_free;
    }
    double cov00, cov01, cov11, ss;
    gsl_fit_linear(xs, 1, es, 1, nu, &f->e0, &f->e1, &cov00, &cov01, &cov11, &ss);
    gsl_fit_linear(xs, 1, zm, 1, nu, &f->zm0, &f->zm1, &cov00, &cov01, &cov11, &ss);
    if (!isfinite(f->e0 + f->e1 + f->zm0 + f->zm1)) {
        st = rpiv_fail(RPIV_ENUMERIC, "selfsim fit: the stations' x* are all equal");
        goto out_free;
    }
    f->rms_e = rms_resid(xs, es, nu, f->e0, f->e1);
    f->rms_zm = rms_resid(xs, zm, nu, f->zm0, f->zm1);
    f->nused = nu;

    /* each station resampled on z+ (NaN where it does not cover z+; all cover z+ = 0) */
    long g0 = (long)floor(zpmin / dzplus), g1 = (long)ceil(zpmax / dzplus);
    size_t ng = (size_t)(g1 - g0 + 1);
    f->n = ng;
    f->zplus = malloc(ng * sizeof *f->zplus);
    f->shape = calloc(ng, sizeof *f->shape);
    res = malloc(nu * ng * sizeof *res);
    if (!f->zplus || !f->shape || !res) {
        st = rpiv_fail(RPIV_ENOMEM, "selfsim fit: out of memory (%zu rows)", ng);
        goto out_free;
    }
    for (size_t g = 0; g < ng; g++)
        f->zplus[g] = (double)(g0 + (long)g) * dzplus;
    for (size_t q = 0; q < nu; q++) {
        const double *p = inten + idx[q] * nz;
        for (size_t j = 0; j < nz; j++)
            norm[j] = p[j] / im[q];
        int gs = gsl_interp_init(li, zstar, norm, nz);
        if (gs) {
            st = rpiv_fail(RPIV_ENUMERIC, "selfsim fit: station %zu: %s", idx[q], gsl_strerror(gs));
            goto out_free;
        }
        gsl_interp_accel_reset(hint);
        for (size_t g = 0; g < ng; g++) {
            double z = zm[q] + f->zplus[g] * es[q], v;
            res[q * ng + g] = z >= zstar[0] && z <= zstar[nz - 1] &&
                                      gsl_interp_eval_e(li, zstar, norm, z, hint, &v) == GSL_SUCCESS
                                  ? v
                                  : (double)NAN;
        }
    }
    /* the mean over the stations covering each z+, renormalised to a maximum of 1 */
    double mx = 0;
    for (size_t g = 0; g < ng; g++) {
        double acc = 0, cnt = 0;
        for (size_t q = 0; q < nu; q++)
            if (!isnan(res[q * ng + g])) {
                acc += res[q * ng + g];
                cnt += 1;
            }
        f->shape[g] = cnt > 0 ? acc / cnt : 0;
        mx = fmax(mx, f->shape[g]);
    }
    for (size_t g = 0; g < ng; g++)
        f->shape[g] = fmin(1.0, fmax(0.0, f->shape[g] / mx));
    /* how self-similar: the stations' departure from the mean shape where they cover it */
    double ss2 = 0, ns2 = 0;
    for (size_t q = 0; q < nu; q++)
        for (size_t g = 0; g < ng; g++)
            if (!isnan(res[q * ng + g])) {
                double d = res[q * ng + g] - f->shape[g];
                ss2 += d * d;
                ns2 += 1;
            }
    f->rms_shape = sqrt(ss2 / ns2);
    *out = f;
    f = NULL;
out_free:
    rpiv_optics_selfsim_free(f);
    free(xs);
    free(es);
    free(zm);
    free(im);
    free(idx);
    free(res);
    free(norm);
    if (li)
        gsl_interp_free(li);
    if (hint)
        gsl_interp_accel_free(hint);
    return st;
}

rpiv_status rpiv_optics_selfsim_save(const rpiv_optics_selfsim *f, const char *path)
{
    return rpiv_sheet_save_profile(path, f->e0, f->e1, f->zm0, f->zm1, f->zplus, f->shape, f->n);
}
