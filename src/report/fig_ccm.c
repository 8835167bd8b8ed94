/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The figures of the cross-correlation model (ccm.h): the paper's figures 19-22 (profiles and
 * pointwise error of a scenario), the Monte-Carlo convergence and the bias correction, as
 * `rpiv ccm` writes them (docs/ccm.md); and the reading of measured R-PIV velocities. */
#include "fig_impl.h"

#include "rpiv/report.h"
#include "rpiv/synth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

rpiv_status rpiv_report_ccm_tables(const char *dir, const char *name, rpiv_ccm_table *const *t,
                                   const double *e, size_t nt)
{
    rpiv_status st = RPIV_OK;
    size_t nmax = 0;
    for (size_t k = 0; k < nt; k++)
        nmax = t[k]->n > nmax ? t[k]->n : nmax;
    double *buf = malloc(4 * nt * nmax * sizeof *buf);
    char(*lab)[64] = calloc(nt + 1, sizeof *lab);
    rpiv_plot_series *ser = calloc(2 * nt + 1, sizeof *ser);
    if (!buf || !lab || !ser) {
        st = rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
        goto out_free;
    }
    for (size_t k = 0; k < nt; k++) {
        double *z = buf + 4 * k * nmax, *um = z + nmax, *ur = um + nmax, *er = ur + nmax;
        for (size_t i = 0; i < t[k]->n; i++) {
            z[i] = t[k]->row[i].zstar;
            um[i] = t[k]->row[i].umodel;
            ur[i] = t[k]->row[i].uref;
            er[i] = 100 * t[k]->row[i].err;
        }
        if (e)
            snprintf(lab[k], sizeof lab[k], "model, e* = %g", e[k]);
        else
            snprintf(lab[k], sizeof lab[k], "model, velocity at z*_max");
        ser[k + 1] = (rpiv_plot_series){z, um, t[k]->n, lab[k], RPIV_PLOT_BOTH};
        if (!k)
            ser[0] = (rpiv_plot_series){z, ur, t[k]->n, "reference (White)", RPIV_PLOT_LINE};
        ser[nt + 1 + k] = (rpiv_plot_series){z, er, t[k]->n, lab[k], RPIV_PLOT_BOTH};
    }
    char path[RPIV_PATH_MAX + 64], title[128];
    snprintf(path, sizeof path, "%s/ccm_%s_profile.png", dir, name);
    snprintf(title, sizeof title, "%s: U*(z*)", name);
    if ((st = rpiv_plot_lines(path, title, "z*", "U*", ser, nt + 1, NULL)))
        goto out_free;
    snprintf(path, sizeof path, "%s/ccm_%s_error.png", dir, name);
    snprintf(title, sizeof title, "%s: pointwise relative error", name);
    st = rpiv_plot_lines(path, title, "z*", "(U*#dmodel#u - U*#dref#u) / U*#dref#u (%)",
                         ser + nt + 1, nt, NULL);
out_free:
    free(buf);
    free(lab);
    free(ser);
    return st;
}

rpiv_status rpiv_report_ccm_convergence(const char *dir, const rpiv_ccm_mc_result *res,
                                        double scale_px, double dx_integral)
{
    size_t K = res->nnim;
    double *v = malloc(5 * K * sizeof *v);
    if (!v)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
    double *lx = v, *mn = v + K, *lo = v + 2 * K, *hi = v + 3 * K, *in = v + 4 * K;
    for (size_t i = 0; i < K; i++) {
        lx[i] = log10((double)res->nim[i]);
        mn[i] = res->mean[i] / scale_px;
        lo[i] = mn[i] - res->std[i] / scale_px;
        hi[i] = mn[i] + res->std[i] / scale_px;
        in[i] = dx_integral / scale_px;
    }
    rpiv_plot_series ser[4] = {{lx, mn, K, "mean of the repetitions", RPIV_PLOT_BOTH},
                               {lx, lo, K, "mean - std", RPIV_PLOT_LINE},
                               {lx, hi, K, "mean + std", RPIV_PLOT_LINE},
                               {lx, in, K, "integral (Eq. statform)", RPIV_PLOT_LINE}};
    char png[RPIV_PATH_MAX + 64];
    snprintf(png, sizeof png, "%s/ccm_convergence.png", dir);
    rpiv_status st = rpiv_plot_lines(png, "Monte-Carlo sum of correlation", "log#d10#u N#dim#u",
                                     "U*", ser, 4, NULL);
    free(v);
    return st;
}

rpiv_status rpiv_report_ccm_invert(const char *dir, const rpiv_ccm_invert_result *res,
                                   const rpiv_ccm_func *ref)
{
    size_t n = res->nout, m = res->nmeas;
    double *v = malloc((4 * n + 2 * m) * sizeof *v);
    if (!v)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
    double *lo = v, *hi = v + n, *rf = v + 2 * n, *zr = v + 3 * n, *zm = v + 4 * n, *um = zm + m;
    for (size_t i = 0; i < n; i++) {
        lo[i] = res->u[i] - 2 * res->u_std[i];
        hi[i] = res->u[i] + 2 * res->u_std[i];
        zr[i] = res->z[i];
        rf[i] = ref ? ref->fn(ref->user, res->z[i]) : 0;
    }
    for (size_t j = 0; j < m; j++) {
        zm[j] = res->zmax[j];
        um[j] = res->umeas[j];
    }
    rpiv_plot_series ser[5] = {
        {zm, um, m, "measured, at z*#dmax#u (association)", RPIV_PLOT_POINTS},
        {zr, res->u, n, "corrected (inverse CCM)", RPIV_PLOT_LINE},
        {zr, lo, n, "corrected - 2 sigma", RPIV_PLOT_LINE},
        {zr, hi, n, "corrected + 2 sigma", RPIV_PLOT_LINE},
        {zr, rf, n, "reference", RPIV_PLOT_LINE}};
    char path[RPIV_PATH_MAX + 64];
    snprintf(path, sizeof path, "%s/ccm_invert.png", dir);
    rpiv_status st =
        rpiv_plot_lines(path, "R-PIV bias correction", "z*", "U*", ser, ref ? 5 : 4, NULL);
    free(v);
    return st;
}
