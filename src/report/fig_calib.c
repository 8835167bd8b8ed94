/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The figures and tables of the calibration from target images (calib.h): the sheet's
 * profiles, self-similar shape and edges along the plates, and the depth-of-focus curve.
 * Written for `rpiv calib sheet|dof --png` (docs/calib.md). */
#include "fig_impl.h"

#include "rpiv/report.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

rpiv_status rpiv_report_calib_sheet(const rpiv_calib_sheet_result *r, const char *dir)
{
    char path[RPIV_PATH_MAX];
    size_t n = r->nplates, ns = n < 12 ? n : 12;
    rpiv_plot_series *ser = calloc(ns + 1, sizeof *ser);
    char(*lab)[40] = calloc(ns + 1, sizeof *lab);
    double *zp = NULL, *lines = NULL;
    rpiv_status st = RPIV_OK;
    if (!ser || !lab) {
        st = rpiv_fail(RPIV_ENOMEM, "calib sheet: out of memory (plot)");
        goto out;
    }
    /* the profiles as the paper draws them: I0* across, z* up */
    for (size_t s = 0; s < ns; s++) {
        const rpiv_calib_sheet_plate *pl = &r->plate[rpiv_report_pick(s, ns, n)];
        snprintf(lab[s], sizeof lab[s], "x* = %.2f", pl->x_max);
        ser[s] = (rpiv_plot_series){pl->inten, pl->z, pl->n, lab[s], RPIV_PLOT_LINE};
    }
    if ((st = fig_path(path, dir, "calib_sheet_profiles.png")) ||
        (st = rpiv_report_sheet_profiles(path, "sheet profiles along the plates", "I#d0#u*", ser,
                                         ns, 1.05)))
        goto out;
    /* the mean shape and the plates in z+ */
    size_t nmax = 0;
    for (size_t i = 0; i < n; i++)
        nmax = r->plate[i].n > nmax ? r->plate[i].n : nmax;
    zp = malloc(ns * nmax * sizeof *zp);
    if (!zp) {
        st = rpiv_fail(RPIV_ENOMEM, "calib sheet: out of memory (plot)");
        goto out;
    }
    for (size_t s = 0; s < ns; s++) {
        const rpiv_calib_sheet_plate *pl = &r->plate[rpiv_report_pick(s, ns, n)];
        for (size_t k = 0; k < pl->n; k++) {
            double x = pl->x[k];
            zp[s * nmax + k] = rpiv_sheet_zplus(pl->z[k], r->zm0 + r->zm1 * x, r->e0 + r->e1 * x);
        }
        ser[s].y = zp + s * nmax;
        ser[s].style = RPIV_PLOT_POINTS;
    }
    ser[ns] = (rpiv_plot_series){r->shape, r->zplus, r->nshape, "mean", RPIV_PLOT_LINE};
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.xmin = 0;
    o.xmax = 1.05;
    if ((st = fig_path(path, dir, "calib_sheet_shape.png")) ||
        (st = rpiv_plot_lines(path, "self-similar shape", "I#d0#u*", "z#u+#d = (z* - z*#dmax#u)/e*",
                              ser, ns + 1, &o)))
        goto out;
    /* edges and peak along x*, with the fitted lines */
    lines = malloc((6 * n + 8) * sizeof *lines);
    if (!lines) {
        st = rpiv_fail(RPIV_ENOMEM, "calib sheet: out of memory (plot)");
        goto out;
    }
    double *xi = lines, *zi = lines + n, *xm = lines + 2 * n, *zm = lines + 3 * n,
           *xs = lines + 4 * n, *zs = lines + 5 * n, *lx = lines + 6 * n, *fi = lx + 2,
           *fm = lx + 4, *fs = lx + 6;
    lx[0] = HUGE_VAL;
    lx[1] = -HUGE_VAL;
    for (size_t i = 0; i < n; i++) {
        const rpiv_calib_sheet_plate *pl = &r->plate[i];
        xi[i] = pl->x_inf;
        zi[i] = pl->raw.zinf;
        xm[i] = pl->x_max;
        zm[i] = pl->raw.zmax;
        xs[i] = pl->x_sup;
        zs[i] = pl->raw.zsup;
        lx[0] = fmin(lx[0], fmin(pl->x_inf, pl->x_sup));
        lx[1] = fmax(lx[1], fmax(pl->x_inf, pl->x_sup));
    }
    for (int k = 0; k < 2; k++) {
        fi[k] = r->inf0 + r->inf1 * lx[k];
        fm[k] = r->zm0 + r->zm1 * lx[k];
        fs[k] = r->sup0 + r->sup1 * lx[k];
    }
    rpiv_plot_series e[6] = {
        {xs, zs, n, "z*#dsup#u", RPIV_PLOT_POINTS}, {xm, zm, n, "z*#dmax#u", RPIV_PLOT_POINTS},
        {xi, zi, n, "z*#dinf#u", RPIV_PLOT_POINTS}, {lx, fs, 2, "fitted lines", RPIV_PLOT_LINE},
        {lx, fm, 2, NULL, RPIV_PLOT_LINE},          {lx, fi, 2, NULL, RPIV_PLOT_LINE}};
    rpiv_plot_opts oe = rpiv_plot_opts_default();
    oe.ymin = 0;
    oe.ymax = 1.25; /* room for the legend */
    if (!(st = fig_path(path, dir, "calib_sheet_edges.png")))
        st = rpiv_plot_lines(path, "sheet edges where each plate meets them", "x*", "z*", e,
                             n > 1 ? 6 : 3, &oe);
out:
    free(ser);
    free(lab);
    free(zp);
    free(lines);
    return st;
}

rpiv_status rpiv_report_calib_dof(const rpiv_calib_focus *c, const rpiv_calib_focus *m,
                                  double shift, const char *dir)
{
    char path[RPIV_PATH_MAX], title[128];
    double *zm = NULL;
    rpiv_plot_series ser[3] = {{c->z, c->g, c->n, "measured", RPIV_PLOT_POINTS},
                               {c->z, c->gfit, c->n, "local fit", RPIV_PLOT_LINE},
                               {NULL, NULL, 0, "model", RPIV_PLOT_LINE}};
    size_t ns = 2;
    if (m && m->n) {
        zm = malloc(m->n * sizeof *zm);
        if (!zm)
            return rpiv_fail(RPIV_ENOMEM, "calib dof: out of memory (plot)");
        for (size_t i = 0; i < m->n; i++)
            zm[i] = m->z[i] + shift;
        ser[2].x = zm;
        ser[2].y = m->g;
        ser[2].n = m->n;
        ns = 3;
    }
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.xmin = 0;
    o.xmax = 1;
    snprintf(title, sizeof title, "focus: DOF* = %.3f, z*#dOP#u = %.3f", c->dof, c->zop);
    rpiv_status st = fig_path(path, dir, "calib_dof.png");
    if (!st)
        st = rpiv_plot_lines(path, title, "z*", "(1/I* - 1) normalised", ser, ns, &o);
    free(zm);
    return st;
}

/* ---- tables ------------------------------------------------------------------------------ */

static rpiv_status w_plates(const void *r, FILE *fp)
{
    return rpiv_calib_sheet_write_plates(r, fp);
}
static rpiv_status w_profiles(const void *r, FILE *fp)
{
    return rpiv_calib_sheet_write_profiles(r, fp);
}
static rpiv_status w_focus(const void *c, FILE *fp)
{
    return rpiv_calib_focus_write(c, fp);
}
static rpiv_status w_dots(const void *r, FILE *fp)
{
    return rpiv_calib_dof_write_dots(r, fp);
}

rpiv_status rpiv_report_calib_sheet_tables(const rpiv_calib_sheet_result *r, const char *dir)
{
    char path[RPIV_PATH_MAX];
    rpiv_status st;
    if ((st = fig_path(path, dir, "calib_sheet_plates.txt")) ||
        (st = rpiv_report_write_file(path, w_plates, r)) ||
        (st = fig_path(path, dir, "calib_sheet_profiles.txt")) ||
        (st = rpiv_report_write_file(path, w_profiles, r)))
        return st;
    return RPIV_OK;
}

rpiv_status rpiv_report_calib_dof_tables(const rpiv_calib_dof_result *r,
                                         const rpiv_calib_focus *model, const char *dir)
{
    char path[RPIV_PATH_MAX];
    rpiv_status st;
    if ((st = fig_path(path, dir, "calib_dof_curve.txt")) ||
        (st = rpiv_report_write_file(path, w_focus, &r->curve)) ||
        (st = fig_path(path, dir, "calib_dof_dots.txt")) ||
        (st = rpiv_report_write_file(path, w_dots, r)))
        return st;
    if (model && ((st = fig_path(path, dir, "calib_dof_model.txt")) ||
                  (st = rpiv_report_write_file(path, w_focus, model))))
        return st;
    return RPIV_OK;
}
