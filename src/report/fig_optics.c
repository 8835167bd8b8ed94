/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The figures of the traced laser sheet (optics.h), as `rpiv raytrace --png` writes them
 * (docs/optics.md): a profile, the edges along x* (paper fig 8), the map over (x*, z*), the
 * beta1 sweep (figs 11-12) and the one-ray sensitivity (fig 10); and the metrics of every
 * traced station, which the demo shares. */
#include "fig_impl.h"

#include "rpiv/report.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

rpiv_status rpiv_report_optics_profile(const rpiv_optics_result *r, const char *dir)
{
    char path[RPIV_PATH_MAX], title[128];
    rpiv_status st;
    double *in = malloc(r->nz * sizeof *in);
    if (!in)
        return rpiv_fail(RPIV_ENOMEM, "raytrace: out of memory (plot)");
    rpiv_optics_profile_norm(r, 0, in);
    snprintf(title, sizeof title, "sheet at x* = %g, #gb#d1#u = %g deg (%s), %s-polarised",
             r->xstar[0], r->laser.beta1_deg, rpiv_beta1_side_name(r->laser.beta1_side),
             rpiv_polar_name(r->laser.polar));
    rpiv_plot_series ser = {in, r->zstar, r->nz, NULL, RPIV_PLOT_LINE};
    if (!(st = fig_path(path, dir, "raytrace_profile.png")))
        st = rpiv_report_sheet_profiles(path, title, "I#d0#u* = I / I#dmax#u", &ser, 1, 0);
    free(in);
    return st;
}

rpiv_status rpiv_report_optics_metrics_plot(const rpiv_optics_result *v,
                                            const rpiv_optics_selfsim *f, const char *dir)
{
    char path[RPIV_PATH_MAX];
    rpiv_status st;
    size_t n = v->nx;
    double *a = malloc(5 * n * sizeof *a);
    if (!a)
        return rpiv_fail(RPIV_ENOMEM, "raytrace: out of memory (plot)");
    double *zi = a, *zm = a + n, *zs = a + 2 * n, *fit = a + 3 * n, *e = a + 4 * n;
    rpiv_optics_metrics_all(v, zi, zm, zs, e);
    for (size_t k = 0; k < n; k++)
        fit[k] = f ? f->zm0 + f->zm1 * v->xstar[k] : (double)NAN;
    rpiv_plot_series ser[5] = {{v->xstar, zs, n, "z*#dsup#u", RPIV_PLOT_BOTH},
                               {v->xstar, zm, n, "z*#dmax#u", RPIV_PLOT_BOTH},
                               {v->xstar, zi, n, "z*#dinf#u", RPIV_PLOT_BOTH},
                               {v->xstar, e, n, "e*", RPIV_PLOT_POINTS},
                               {v->xstar, fit, n, "z*#dmax#u fit", RPIV_PLOT_LINE}};
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.ymin = 0;
    o.ymax = 1;
    st = fig_path(path, dir, "raytrace_metrics.png");
    if (!st) {
        size_t nu = fig_keep_finite(ser, 5);
        st = nu ? rpiv_plot_lines(path, "sheet edges and thickness along x*", "x*", "z*, e*", ser,
                                  nu, &o)
                : RPIV_OK;
    }
    free(a);
    return st;
}

rpiv_status rpiv_report_optics_map(const rpiv_laser *laser, const rpiv_prism *prism, double h_m,
                                   double x_last, const rpiv_optics_opts *opts, const char *dir)
{
    enum { NXM = 200 };
    double xs[NXM], x0 = -0.5, x1 = x_last > 1 ? x_last : 9;
    char path[RPIV_PATH_MAX];
    rpiv_optics_result *r = NULL;
    rpiv_status st;
    for (int k = 0; k < NXM; k++)
        xs[k] = x0 + (x1 - x0) * (k + 0.5) / NXM;
    if ((st = rpiv_optics_trace(laser, prism, h_m, xs, NXM, opts, NULL, &r)))
        return st;
    size_t nz = r->nz;
    double *z = malloc(NXM * nz * sizeof *z), *col = malloc(nz * sizeof *col);
    if (!z || !col) {
        st = rpiv_fail(RPIV_ENOMEM, "raytrace: out of memory (map)");
        goto out;
    }
    for (int k = 0; k < NXM; k++) {
        rpiv_optics_profile_norm(r, (size_t)k, col);
        for (size_t q = 0; q < nz; q++)
            z[q * NXM + (size_t)k] = col[q];
    }
    double ext[4] = {x0, x1, 0, 1};
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.y_axis = RPIV_PLOT_UP;
    o.aspect = RPIV_PLOT_FREE;
    o.xlabel = "x*";
    o.ylabel = "z*";
    o.zlabel = "I / I#dmax#u(x*)";
    o.zmin = 0;
    o.zmax = 1;
    if (!(st = fig_path(path, dir, "raytrace_map.png")))
        st = rpiv_plot_map(path, "the refracted sheet, normalised at each x*", z, NXM, (int)nz, ext,
                           &o);
out:
    free(z);
    free(col);
    rpiv_optics_result_free(r);
    return st;
}

rpiv_status rpiv_report_optics_sweep(const rpiv_optics_sweep_row *rows, size_t n,
                                     const double *prof, size_t nz, double x, const char *dir)
{
    char path[RPIV_PATH_MAX], title[96];
    size_t ns = n < 12 ? n : 12;
    rpiv_status st;
    double *z = malloc(nz * sizeof *z), *a = malloc(4 * n * sizeof *a);
    rpiv_plot_series *ser = malloc(ns * sizeof *ser);
    char(*lab)[32] = malloc(ns * sizeof *lab);
    if (!z || !a || !ser || !lab) {
        st = rpiv_fail(RPIV_ENOMEM, "raytrace: out of memory (plot)");
        goto out;
    }
    for (size_t q = 0; q < nz; q++)
        z[q] = ((double)q + 0.5) / (double)nz;
    /* at most 12 profiles, evenly picked (fig. 11) */
    for (size_t s = 0; s < ns; s++) {
        size_t i = rpiv_report_pick(s, ns, n);
        snprintf(lab[s], sizeof lab[s], "%g deg", rows[i].beta1_deg);
        ser[s] = (rpiv_plot_series){prof + i * nz, z, nz, lab[s], RPIV_PLOT_LINE};
    }
    snprintf(title, sizeof title, "profiles at x* = %g against #gb#d1#u", x);
    if ((st = fig_path(path, dir, "raytrace_sweep_profiles.png")) ||
        (st = rpiv_report_sheet_profiles(path, title, "I#d0#u*", ser, ns, 0)))
        goto out;
    /* fig. 12 (and e*) */
    double *b = a, *e = a + n, *it = a + 2 * n, *ip = a + 3 * n;
    for (size_t i = 0; i < n; i++) {
        b[i] = rows[i].beta1_deg;
        e[i] = rows[i].e;
        it[i] = rows[i].it_ig;
        ip[i] = rows[i].ipeak_star;
    }
    rpiv_plot_series s3[3] = {{b, it, n, "I#dt#u/I#dg#u", RPIV_PLOT_BOTH},
                              {b, ip, n, "I*#dpeak#u", RPIV_PLOT_BOTH},
                              {b, e, n, "e*", RPIV_PLOT_BOTH}};
    size_t nu = fig_keep_finite(s3, 3);
    snprintf(title, sizeof title, "transmission, peak and thickness at x* = %g", x);
    if (!(st = fig_path(path, dir, "raytrace_sweep.png")) && nu)
        st = rpiv_plot_lines(path, title, "#gb#d1#u (deg)", "", s3, nu, NULL);
out:
    free(z);
    free(a);
    free(ser);
    free(lab);
    return st;
}

rpiv_status rpiv_report_optics_sensitivity(const rpiv_optics_sens_row *rows, size_t n, double beta1,
                                           const char *dir)
{
    char path[RPIV_PATH_MAX], title[96];
    double de[128], th[128], tt[128];
    if (n > 128)
        n = 128;
    for (size_t i = 0; i < n; i++) {
        de[i] = rows[i].deta;
        th[i] = rows[i].transmitted ? rows[i].dtheta_rel : (double)NAN;
        tt[i] = rows[i].dT_rel;
    }
    rpiv_plot_series ser[2] = {{de, th, n, "#gd#gh#dt#u/#gh#dt0#u", RPIV_PLOT_BOTH},
                               {de, tt, n, "#gdT/T#d0#u", RPIV_PLOT_BOTH}};
    snprintf(title, sizeof title, "one ray at #gb#d1#u = %g deg", beta1);
    rpiv_status st = fig_path(path, dir, "raytrace_sensitivity.png");
    return st ? st
              : rpiv_plot_lines(path, title, "#gd#gy  (#gy = n#dPMMA#u / n#dwater#u)",
                                "relative change", ser, 2, NULL);
}
