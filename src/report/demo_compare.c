/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Step 5 of the demo: R-PIV against the P-PIV reference at z*_inf, z*_max, z*_sup along y* at
 * every x* (paper figs 24, 25), against the CCM's integral prediction at y* = 0.5 along x*
 * (fig 26) as pairs are added (fig 27), and the CCM inversion (the bias-corrected U*(z*))
 * against the analytic duct. Comparisons use Eq. "E1" through field.h/flow.h; predictions and
 * the inversion are the ccm module's. */
#include "demo_impl.h"

#include "rpiv/ccm.h"
#include "rpiv/flow.h"
#include "rpiv/report.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NZ_SHEET 2000 /* samples of I0(z*) for the metrics of a column */
#define NZ_CURVE 129  /* samples of the P-PIV profile U*(z*) given to the model */

/* P-PIV U* at column i, y* (linear between rows), height z. */
static double vol_at_y(const demo_ctx *c, int i, double ystar, double z)
{
    double t = (ystar - c->ys[0]) / (c->ys[1] - c->ys[0]);
    if (!(t >= 0 && t <= c->ny - 1))
        return (double)NAN;
    int j0 = (int)floor(t);
    if (j0 >= c->ny - 1)
        j0 = c->ny - 2;
    double a = t - j0;
    return (1 - a) * demo_vol_eval(c, i, j0, z) + a * demo_vol_eval(c, i, j0 + 1, z);
}

/* Sheet metrics at x* from I0 sampled on the channel height. */
static int sheet_metrics(const demo_ctx *c, double xstar, rpiv_sheet_metrics *m)
{
    double z[NZ_SHEET], v[NZ_SHEET];
    for (int k = 0; k < NZ_SHEET; k++) {
        z[k] = (k + 0.5) / NZ_SHEET;
        v[k] = rpiv_sheet_eval(c->sheet, xstar, z[k]);
    }
    if (rpiv_sheet_metrics_of(z, v, NZ_SHEET, m) != RPIV_OK || !(m->imax > 0)) {
        rpiv_errclear();
        return 0;
    }
    return 1;
}

static void mean_of(const double *v, const unsigned char *use, int n, double *mean, int *count)
{
    double s = 0;
    int k = 0;
    for (int i = 0; i < n; i++)
        if (use[i] && isfinite(v[i])) {
            s += v[i];
            k++;
        }
    *mean = k ? s / k : (double)NAN;
    if (count)
        *count = k;
}

/* E1 along y* at column i between the P-PIV reference at height z and R-PIV. */
static double e1_column(const demo_ctx *c, int i, double z, double *aref, double *acmp, double *al)
{
    size_t n = 0;
    for (int j = 0; j < c->ny; j++) {
        size_t q = (size_t)j * (size_t)c->nx + (size_t)i;
        if (!c->fluid[q])
            continue;
        al[n] = c->ys[j];
        aref[n] = demo_vol_eval(c, i, j, z);
        acmp[n] = (double)c->rfield->u[q] / c->bulk_px;
        n++;
    }
    if (n < 2)
        return (double)NAN;
    rpiv_profile ref = {n, al, aref}, cmp = {n, al, acmp};
    rpiv_compare r;
    if (rpiv_profile_compare(&ref, &cmp, &r) != RPIV_OK) {
        rpiv_errclear();
        return (double)NAN;
    }
    return r.e1;
}

/* E1 along x* over the compared columns between ref[i] and cmp[i]. */
static double e1_along_x(const demo_ctx *c, const double *ref, const double *cmp)
{
    double *al = malloc((size_t)c->nx * 3 * sizeof *al);
    if (!al)
        return (double)NAN;
    double *r = al + c->nx, *m = r + c->nx;
    size_t n = 0;
    for (int i = 0; i < c->nx; i++)
        if (c->col_ok[i] && isfinite(ref[i]) && isfinite(cmp[i])) {
            al[n] = c->xs[i];
            r[n] = ref[i];
            m[n] = cmp[i];
            n++;
        }
    double e1 = (double)NAN;
    if (n >= 2) {
        rpiv_profile pr = {n, al, r}, pc = {n, al, m};
        rpiv_compare res;
        if (rpiv_profile_compare(&pr, &pc, &res) == RPIV_OK)
            e1 = res.e1;
        else
            rpiv_errclear();
    }
    free(al);
    return e1;
}

static rpiv_status alloc_columns(demo_ctx *c)
{
    size_t nx = (size_t)c->nx;
    c->col_ok = calloc(nx, 1);
    double **arr[] = {&c->czinf, &c->czmax,  &c->czsup,  &c->e1inf, &c->e1max,
                      &c->e1sup, &c->ur_mid, &c->up_mid, &c->umodel};
    for (size_t k = 0; k < sizeof arr / sizeof arr[0]; k++)
        if (!(*arr[k] = malloc(nx * sizeof(double))))
            return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    c->usnap_mid = malloc(c->nsnap * nx * sizeof *c->usnap_mid);
    if (!c->col_ok || !c->usnap_mid)
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    return RPIV_OK;
}

/* Figs 24-25: metrics and E1 per column. */
static rpiv_status columns(demo_ctx *c)
{
    rpiv_demo_result *r = c->res;
    size_t ny = (size_t)c->ny;
    double *buf = malloc(3 * ny * sizeof *buf);
    if (!buf)
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    /* a column is compared when the sheet is lit across its final window */
    const rpiv_piv_params *pp = &c->e.piv;
    double half = 0.5 * pp->win_w[pp->npass - 1] * c->spp;
    double zop = c->e.camera.zop_star;
    unsigned char *core = calloc((size_t)c->nx, 3);
    if (!core) {
        free(buf);
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    }
    unsigned char *wall = core + c->nx, *above = wall + c->nx;
    for (int i = 0; i < c->nx; i++) {
        rpiv_sheet_metrics m, ml, mr;
        c->czinf[i] = c->czmax[i] = c->czsup[i] = (double)NAN;
        c->e1inf[i] = c->e1max[i] = c->e1sup[i] = (double)NAN;
        c->col_ok[i] = sheet_metrics(c, c->xs[i], &m) && sheet_metrics(c, c->xs[i] - half, &ml) &&
                       sheet_metrics(c, c->xs[i] + half, &mr);
        c->ur_mid[i] = demo_field_at_y(c, c->rfield, i, 0.5);
        c->up_mid[i] = (double)NAN;
        if (!c->col_ok[i])
            continue;
        c->czinf[i] = m.zinf;
        c->czmax[i] = m.zmax;
        c->czsup[i] = m.zsup;
        c->e1inf[i] = e1_column(c, i, m.zinf, buf, buf + ny, buf + 2 * ny);
        c->e1max[i] = e1_column(c, i, m.zmax, buf, buf + ny, buf + 2 * ny);
        c->e1sup[i] = e1_column(c, i, m.zsup, buf, buf + ny, buf + 2 * ny);
        c->up_mid[i] = vol_at_y(c, i, 0.5, m.zmax);
        core[i] = m.zmax >= c->p.core_z && m.zmax <= zop;
        wall[i] = m.zmax < c->p.wall_z;
        above[i] = m.zmax > zop;
    }
    free(buf);
    int n = 0;
    for (int i = 0; i < c->nx; i++)
        n += c->col_ok[i];
    /* the P-PIV planes at y* = 0.5 against the duct, along z (cf. the paper's fig 19) */
    double *ze = malloc(3 * c->nz * sizeof *ze), s = 0;
    int ns = 0;
    if (!ze)
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    for (int i = 0; i < c->nx; i++) {
        if (!c->col_ok[i])
            continue;
        double *zr = ze + c->nz, *zc = zr + c->nz;
        for (size_t k = 0; k < c->nz; k++) {
            ze[k] = c->zk[k + 1];
            zr[k] = rpiv_duct_u(0.5, ze[k]);
            zc[k] = vol_at_y(c, i, 0.5, ze[k]);
        }
        rpiv_profile pr = {c->nz, ze, zr}, pc = {c->nz, ze, zc};
        rpiv_compare cz;
        if (isfinite(zc[0]) && rpiv_profile_compare(&pr, &pc, &cz) == RPIV_OK && isfinite(cz.e1)) {
            s += cz.e1;
            ns++;
        }
        rpiv_errclear();
    }
    free(ze);
    r->ppiv_e1_z = ns ? s / ns : (double)NAN;
    r->ncols = n;
    mean_of(c->e1inf, c->col_ok, c->nx, &r->e1_zinf, NULL);
    mean_of(c->e1max, c->col_ok, c->nx, &r->e1_zmax, NULL);
    mean_of(c->e1sup, c->col_ok, c->nx, &r->e1_zsup, NULL);
    mean_of(c->e1max, core, c->nx, &r->e1_zmax_core, &r->ncols_core);
    mean_of(c->e1max, wall, c->nx, &r->e1_zmax_wall, &r->ncols_wall);
    mean_of(c->e1max, above, c->nx, &r->e1_zmax_above, &r->ncols_above);
    free(core);
    /* the fig 24 column: the compared one nearest profile_x */
    c->icol24 = -1;
    for (int i = 0; i < c->nx; i++)
        if (c->col_ok[i] && (c->icol24 < 0 || fabs(c->xs[i] - c->p.profile_x) <
                                                  fabs(c->xs[c->icol24] - c->p.profile_x)))
            c->icol24 = i;
    r->profile_x = c->icol24 >= 0 ? c->xs[c->icol24] : (double)NAN;
    if (!n)
        return rpiv_fail(RPIV_ENUMERIC,
                         "demo: the sheet is dark over every column of the band "
                         "(x* %.3f ... %.3f): nothing to compare",
                         r->x0_star, r->x1_star);
    demo_note(c,
              "  %d columns compared; E1 along y* of R-PIV vs P-PIV at z*_inf %.2f %%, "
              "z*_max %.2f %%, z*_sup %.2f %%",
              n, 100 * r->e1_zinf, 100 * r->e1_zmax, 100 * r->e1_zsup);
    return RPIV_OK;
}

/* Fig 26: the CCM's integral prediction at y* = 0.5 for every compared column, with the sheet
 * there, the object plane, and the P-PIV profile U*(z*) at (x*, 0.5) as the velocity. */
static rpiv_status model(demo_ctx *c)
{
    rpiv_status st;
    rpiv_ccm_params cp = rpiv_ccm_params_default();
    rpiv_ccm_work *w;
    if ((st = rpiv_ccm_work_new(&cp, &w)))
        return st;
    double z[NZ_CURVE], u[NZ_CURVE];
    for (int i = 0; i < c->nx; i++) {
        c->umodel[i] = (double)NAN;
        if (!c->col_ok[i])
            continue;
        for (int k = 0; k < NZ_CURVE; k++) {
            z[k] = (double)k / (NZ_CURVE - 1);
            u[k] = vol_at_y(c, i, 0.5, z[k]);
        }
        if (!isfinite(u[NZ_CURVE / 2]))
            continue;
        for (int k = 0; k < NZ_CURVE; k++)
            if (!isfinite(u[k]))
                u[k] = 0;
        rpiv_ccm_curve *cu;
        if ((st = rpiv_ccm_curve_new(z, u, NZ_CURVE, &cu)))
            break;
        rpiv_ccm_sheet_at at = {c->sheet, c->xs[i]};
        rpiv_ccm_model m = rpiv_config_ccm_model(&c->e, c->e.synth.dt_s);
        m.illum = (rpiv_ccm_func){rpiv_ccm_sheet_fn, &at};
        m.u = (rpiv_ccm_func){rpiv_ccm_curve_fn, cu};
        m.breaks[0] = c->czmax[i];
        m.nbreaks = 1;
        rpiv_ccm_peak pk;
        st = rpiv_ccm_predict(&m, w, &pk);
        rpiv_ccm_curve_free(cu);
        if (st) {
            char msg[400];
            snprintf(msg, sizeof msg, "%s", rpiv_errmsg());
            st = rpiv_fail(st, "demo: CCM prediction at x* = %.4f: %s", c->xs[i], msg);
            break;
        }
        c->umodel[i] = pk.dx / m.scale_px;
    }
    rpiv_ccm_work_free(w);
    return st;
}

/* Fig 27 and the final comparisons at y* = 0.5. */
static void convergence(demo_ctx *c)
{
    rpiv_demo_result *r = c->res;
    size_t nx = (size_t)c->nx;
    for (size_t k = 0; k < c->nsnap; k++) {
        double *us = c->usnap_mid + k * nx;
        for (int i = 0; i < c->nx; i++)
            us[i] = c->snapf[k] ? demo_field_at_y(c, c->snapf[k], i, 0.5) : (double)NAN;
        r->conv_n[k] = c->snap[k];
        r->conv_e1[k] = e1_along_x(c, c->umodel, us);
    }
    r->nconv = c->nsnap;
    r->e1_model = e1_along_x(c, c->umodel, c->ur_mid);
    r->e1_model_ppiv = e1_along_x(c, c->up_mid, c->ur_mid);
    demo_note(c,
              "  y* = 0.5: E1 along x* of R-PIV vs the CCM %.2f %% (after %d pairs: %.2f %%), "
              "vs P-PIV at z*_max %.2f %%",
              100 * r->e1_model, r->conv_n[0], 100 * r->conv_e1[0], 100 * r->e1_model_ppiv);
}

/* The bias correction: U*(z*) from the R-PIV row at y* = 0.5 by the CCM inversion. */
static rpiv_status invert(demo_ctx *c)
{
    rpiv_demo_result *r = c->res;
    r->e1_assoc = r->e1_corr = (double)NAN;
    size_t n = 0;
    double *xs = malloc(2 * (size_t)c->nx * sizeof *xs);
    if (!xs)
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    double *um = xs + c->nx;
    for (int i = 0; i < c->nx; i++)
        if (c->col_ok[i] && isfinite(c->ur_mid[i])) {
            xs[n] = c->xs[i];
            um[n] = c->ur_mid[i];
            n++;
        }
    rpiv_ccm_model base = rpiv_config_ccm_model(&c->e, c->e.synth.dt_s);
    if (!(base.window_pairs > 0)) /* the noise of the R-PIV ensemble's planes */
        base.window_pairs = c->p.rpiv_pairs;
    rpiv_ccm_invert_params ip = rpiv_ccm_invert_params_default();
    ip.symmetric = 1; /* the duct is symmetric about z* = 0.5, as the paper extends it */
    ip.measured = 1;  /* the row is what the engine measured: fit the engine's estimate */
    rpiv_ccm_params cp = rpiv_ccm_params_default();
    cp.subpixel = c->e.piv.subpixel;
    rpiv_ccm_invert_result *inv = NULL;
    rpiv_status st = n >= 4
                         ? rpiv_ccm_invert(&base, c->sheet, xs, um, NULL, n, &ip, &cp, NULL, &inv)
                         : rpiv_fail(RPIV_ENUMERIC, "only %zu measurements", n);
    free(xs);
    if (st == RPIV_ENUMERIC || st == RPIV_EINVAL) {
        demo_note(c, "  no bias correction: %s", rpiv_errmsg());
        rpiv_errclear();
        return RPIV_OK;
    }
    if (st)
        return st;
    double y = 0.5;
    rpiv_ccm_func truth = {rpiv_ccm_duct_fn, &y};
    char path[RPIV_PATH_MAX];
    if ((st = rpiv_ccm_invert_e1(inv, truth, 1, &r->e1_assoc, &r->e1_corr)) ||
        (st = demo_path(c, "data/ccm_invert.txt", path, sizeof path)) ||
        (st = rpiv_ccm_invert_save(inv, "R-PIV at y* = 0.5 along x* (rpiv demo)", path)))
        goto out_free;
    c->ninv = inv->nout;
    c->ninvm = inv->nmeas;
    c->inv_z = malloc(3 * inv->nout * sizeof(double));
    c->inv_zm = malloc(2 * inv->nmeas * sizeof(double));
    if (!c->inv_z || !c->inv_zm) {
        st = rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
        goto out_free;
    }
    c->inv_u = c->inv_z + inv->nout;
    c->inv_sd = c->inv_u + inv->nout;
    c->inv_um = c->inv_zm + inv->nmeas;
    memcpy(c->inv_z, inv->z, inv->nout * sizeof(double));
    memcpy(c->inv_u, inv->u, inv->nout * sizeof(double));
    memcpy(c->inv_sd, inv->u_std, inv->nout * sizeof(double));
    memcpy(c->inv_zm, inv->zmax, inv->nmeas * sizeof(double));
    memcpy(c->inv_um, inv->umeas, inv->nmeas * sizeof(double));
    demo_note(c,
              "  bias correction (CCM inversion): E1 vs the analytic duct %.2f %%, the "
              "paper's association (U at z*_max) %.2f %%",
              100 * r->e1_corr, 100 * r->e1_assoc);
out_free:
    rpiv_ccm_invert_free(inv);
    return st;
}

static int cmp_dbl(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The R-PIV ensemble's sigma_u against its error at the compared vectors (U*): raw (against
 * the analytic U at z*_max) and after the sheet-bias correction. */
static void unc_coverage(demo_ctx *c, const rpiv_quantity *qb, const rpiv_quantity *qz)
{
    rpiv_demo_result *r = c->res;
    const rpiv_quantity *qs = rpiv_field_quantity(c->bfield, "sigma_u");
    r->unc_n = 0;
    r->unc_cov_raw = r->unc_cov_corr = r->unc_med_sigma = (double)NAN;
    r->unc_rms_raw = r->unc_rms_corr = (double)NAN;
    size_t nv = (size_t)c->nx * (size_t)c->ny, n = 0, in_raw = 0, in_corr = 0;
    double *sig = qs ? malloc(nv * sizeof *sig) : NULL, se_raw = 0, se_corr = 0;
    if (!sig)
        return;
    for (int i = 0; i < c->nx; i++)
        for (int j = 0; c->col_ok[i] && j < c->ny; j++) {
            size_t k = (size_t)j * (size_t)c->nx + (size_t)i;
            if (!c->fluid[k] || c->bfield->flag[k] != RPIV_FLAG_VALID)
                continue;
            double t = rpiv_duct_u(c->ys[j], (double)qz->data[k]);
            double s = (double)qs->data[k] / c->bulk_px;
            double er = (double)c->bfield->u[k] / c->bulk_px - t;
            double ec = er - (double)qb->data[k] / c->bulk_px;
            in_raw += fabs(er) <= s;
            in_corr += fabs(ec) <= s;
            se_raw += er * er;
            se_corr += ec * ec;
            sig[n++] = s;
        }
    if (n) {
        qsort(sig, n, sizeof *sig, cmp_dbl);
        r->unc_n = n;
        r->unc_cov_raw = (double)in_raw / (double)n;
        r->unc_cov_corr = (double)in_corr / (double)n;
        r->unc_med_sigma = n % 2 ? sig[n / 2] : 0.5 * (sig[n / 2 - 1] + sig[n / 2]);
        r->unc_rms_raw = sqrt(se_raw / (double)n);
        r->unc_rms_corr = sqrt(se_corr / (double)n);
        demo_note(c,
                  "  uncertainty: %zu vectors, |error| <= sigma_u for %.1f %% raw, %.1f %% "
                  "after the bias correction; median sigma %.4f U*",
                  n, 100 * r->unc_cov_raw, 100 * r->unc_cov_corr, r->unc_med_sigma);
    }
    free(sig);
}

/* The per-vector sheet bias of the R-PIV field (rpiv_ccm_bias_field: the duct's variation
 * across the depth, referred to z*_max, the CCM's continuous peak) and the corrected field
 * against the analytic U at z*_max(x*), over the compared vectors: the whole field and
 * RPIV_DEMO_BIAS_BANDS equal bands of x* (where the sheet is thin or thick). */
static rpiv_status sheet_bias(demo_ctx *c)
{
    rpiv_demo_result *r = c->res;
    r->bias_e1_raw = r->bias_e1_corr = (double)NAN;
    r->nbias_bands = 0;
    if (!c->rfield)
        return RPIV_OK;
    rpiv_status st = rpiv_field_copy(c->rfield, &c->bfield);
    if (st)
        return st;
    rpiv_ccm_model base = rpiv_config_ccm_model(&c->e, c->e.synth.dt_s);
    if (!(base.window_pairs > 0)) /* the noise of the R-PIV ensemble's planes */
        base.window_pairs = c->p.rpiv_pairs;
    rpiv_ccm_geometry g = {c->x0s, c->y0s, c->spp};
    rpiv_ccm_bias_params bp = rpiv_ccm_bias_params_default();
    bp.rel_thickness = bp.dz = 0; /* the report does not use the bias's uncertainty */
    bp.measured = c->e.bias.measured;
    rpiv_ccm_params cp = rpiv_ccm_params_default();
    cp.subpixel = c->e.piv.subpixel;
    st = rpiv_ccm_bias_field(c->bfield, &base, c->sheet, &g, &bp, &cp, NULL);
    if (st == RPIV_ENUMERIC || st == RPIV_EINVAL) {
        demo_note(c, "  no sheet bias: %s", rpiv_errmsg());
        rpiv_errclear();
        rpiv_field_free(c->bfield);
        c->bfield = NULL;
        return RPIV_OK;
    }
    if (st)
        return st;
    const rpiv_quantity *qb = rpiv_field_quantity(c->bfield, "bias_u");
    const rpiv_quantity *qz = rpiv_field_quantity(c->bfield, "z_ref");
    if (!qb || !qz)
        return rpiv_fail(RPIV_ENUMERIC, "demo: the sheet bias wrote no bias_u or z_ref");
    /* bands of x* over the compared columns */
    int i0 = -1, i1 = -1;
    for (int i = 0; i < c->nx; i++)
        if (c->col_ok[i]) {
            i0 = i0 < 0 ? i : i0;
            i1 = i;
        }
    if (i0 < 0)
        return RPIV_OK;
    enum { NB = RPIV_DEMO_BIAS_BANDS };
    double xa = c->xs[i0], xb = c->xs[i1] + 1e-9;
    double s[NB + 1][6] = {{0}}; /* n, sum truth, sum raw err^2, sum corr err^2, err, bias */
    double se[NB] = {0};
    int ne[NB] = {0};
    for (int i = i0; i <= i1; i++) {
        if (!c->col_ok[i])
            continue;
        int b = (int)((c->xs[i] - xa) / (xb - xa) * NB);
        b = b < 0 ? 0 : b >= NB ? NB - 1 : b;
        if (c->czsup[i] > c->czinf[i]) {
            se[b] += c->czsup[i] - c->czinf[i];
            ne[b]++;
        }
        for (int j = 0; j < c->ny; j++) {
            size_t k = (size_t)j * (size_t)c->nx + (size_t)i;
            if (!c->fluid[k] || c->bfield->flag[k] == RPIV_FLAG_MASKED)
                continue;
            double u = (double)c->bfield->u[k] / c->bulk_px;
            double bias = (double)qb->data[k] / c->bulk_px;
            double t = rpiv_duct_u(c->ys[j], (double)qz->data[k]);
            for (int q = 0; q < 2; q++) {
                double *a = s[q ? NB : b];
                a[0] += 1;
                a[1] += t;
                a[2] += (u - t) * (u - t);
                a[3] += (u - bias - t) * (u - bias - t);
                a[4] += u - t;
                a[5] += bias;
            }
        }
    }
    for (int b = 0; b <= NB; b++) {
        double *a = s[b];
        double raw = a[0] > 0 && a[1] > 0 ? sqrt(a[2] / a[0]) / (a[1] / a[0]) : (double)NAN;
        double cor = a[0] > 0 && a[1] > 0 ? sqrt(a[3] / a[0]) / (a[1] / a[0]) : (double)NAN;
        if (b == NB) {
            r->bias_e1_raw = raw;
            r->bias_e1_corr = cor;
            continue;
        }
        r->bias_x0[b] = xa + (xb - xa) * b / NB;
        r->bias_x1[b] = xa + (xb - xa) * (b + 1) / NB;
        r->bias_raw[b] = raw;
        r->bias_corr[b] = cor;
        r->bias_err[b] = a[0] > 0 ? a[4] / a[0] : (double)NAN;
        r->bias_mean[b] = a[0] > 0 ? a[5] / a[0] : (double)NAN;
        r->bias_e[b] = ne[b] ? se[b] / ne[b] : (double)NAN;
    }
    r->nbias_bands = NB;
    unc_coverage(c, qb, qz);
    demo_note(c,
              "  sheet bias per vector: E1 vs the analytic U at z*_max, raw %.2f %%, corrected "
              "%.2f %%",
              100 * r->bias_e1_raw, 100 * r->bias_e1_corr);
    return RPIV_OK;
}

/* The comparison tables in DIR/data (rpiv_report_write_file: atomic). */
static rpiv_status w_compare(const void *obj, FILE *fp)
{
    const demo_ctx *c = obj;
    fprintf(fp, "# rpiv demo: R-PIV against P-PIV and the CCM along x*\n"
                "# E1_* along y*, R-PIV vs P-PIV at the sheet's z*_inf, z*_max, z*_sup; U* at "
                "y* = 0.5\n"
                "# columns: x* compared z*_inf z*_max z*_sup E1_inf E1_max E1_sup U_RPIV "
                "U_PPIV(z*_max) U_model\n");
    for (int i = 0; i < c->nx; i++)
        fprintf(fp, "%.6f %d %.6f %.6f %.6f %.6g %.6g %.6g %.6f %.6f %.6f\n", c->xs[i],
                c->col_ok[i], c->czinf[i], c->czmax[i], c->czsup[i], c->e1inf[i], c->e1max[i],
                c->e1sup[i], c->ur_mid[i], c->up_mid[i], c->umodel[i]);
    return RPIV_OK;
}

static rpiv_status w_convergence(const void *obj, FILE *fp)
{
    const demo_ctx *c = obj;
    fprintf(fp, "# rpiv demo: E1 along x* at y* = 0.5, R-PIV after N pairs vs the CCM\n"
                "# columns: N E1\n");
    for (size_t k = 0; k < c->nsnap; k++)
        fprintf(fp, "%d %.6g\n", c->res->conv_n[k], c->res->conv_e1[k]);
    return RPIV_OK;
}

static rpiv_status save_tables(demo_ctx *c)
{
    char path[RPIV_PATH_MAX];
    rpiv_status st;
    if ((st = demo_path(c, "data/compare_x.txt", path, sizeof path)) ||
        (st = rpiv_report_write_file(path, w_compare, c)) ||
        (st = demo_path(c, "data/convergence.txt", path, sizeof path)) ||
        (st = rpiv_report_write_file(path, w_convergence, c)))
        return st;
    return RPIV_OK;
}

rpiv_status demo_compare(demo_ctx *c)
{
    rpiv_status st;
    demo_note(c, "step 5/6: comparisons: R-PIV vs P-PIV (figs 24-25), vs the CCM (figs 26-27), "
                 "bias correction");
    if ((st = alloc_columns(c)) || (st = columns(c)) || (st = model(c)))
        return st;
    convergence(c);
    if ((st = demo_tick(c, 1)) || (st = invert(c)) || (st = sheet_bias(c)) ||
        (st = demo_tick(c, 1)))
        return st;
    return save_tables(c);
}
