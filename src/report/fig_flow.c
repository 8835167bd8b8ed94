/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The square-duct profile table and figure of `rpiv duct`, the figures of `rpiv compare`
 * (both profiles, or the map of the difference of two fields), and a count over a field. */
#include "fig_impl.h"

#include "rpiv/flow.h"
#include "rpiv/report.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

rpiv_status rpiv_report_duct(FILE *fp, const double *al, size_t n, int along_y, double fixed,
                             const char *png)
{
    double *u = malloc((n ? n : 1) * sizeof *u);
    if (!u)
        return rpiv_fail(RPIV_ENOMEM, "duct: out of memory");
    for (size_t k = 0; k < n; k++)
        u[k] = along_y ? rpiv_duct_u(al[k], fixed) : rpiv_duct_u(fixed, al[k]);
    fprintf(fp,
            "# rpiv duct: square-duct laminar profile U* = U/U_bulk (Eq. \"White\"), %s* = %.10g\n",
            along_y ? "z" : "y", fixed);
    fprintf(fp, "# %s* U*\n", along_y ? "y" : "z");
    for (size_t k = 0; k < n; k++)
        fprintf(fp, "%.10g %.10g\n", al[k], u[k]);
    rpiv_status st = RPIV_OK;
    if (fflush(fp) != 0)
        st = rpiv_fail(RPIV_EIO, "duct: cannot write the table: %s", strerror(errno));
    if (!st && png) {
        char title[96], label[96];
        snprintf(title, sizeof title, "Square duct, %s* = %.4g", along_y ? "z" : "y", fixed);
        snprintf(label, sizeof label, "U*(%s* = %.4g)", along_y ? "z" : "y", fixed);
        rpiv_plot_series s = {al, u, n, label, n > 1 ? RPIV_PLOT_LINE : RPIV_PLOT_POINTS};
        st = rpiv_plot_lines(png, title, along_y ? "y*" : "z*", "U* = U / U#dbulk#u", &s, 1, NULL);
    }
    free(u);
    return st;
}

rpiv_status rpiv_report_compare_profiles(const char *png, const rpiv_profile *ref,
                                         const rpiv_profile *cmp, const char *ref_name,
                                         const char *cmp_name, const rpiv_compare *r)
{
    char title[64];
    snprintf(title, sizeof title, "E#d1#u = %.4g", r->e1);
    rpiv_plot_series s[2] = {{ref->alpha, ref->value, ref->n, ref_name, RPIV_PLOT_LINE},
                             {cmp->alpha, cmp->value, cmp->n, cmp_name, RPIV_PLOT_POINTS}};
    return rpiv_plot_lines(png, title, "#ga", "value", s, 2, NULL);
}

static double component(const rpiv_field *f, size_t k, rpiv_component c)
{
    return c == RPIV_COMPONENT_U   ? (double)f->u[k]
           : c == RPIV_COMPONENT_V ? (double)f->v[k]
                                   : hypot((double)f->u[k], (double)f->v[k]);
}

rpiv_status rpiv_report_compare_fields(const char *png, const rpiv_field *ref,
                                       const rpiv_field *cmp, rpiv_component c, const char *cname,
                                       const rpiv_compare *r)
{
    size_t np = (size_t)ref->nx * (size_t)ref->ny;
    double *d = malloc(np * sizeof *d);
    if (!d)
        return rpiv_fail(RPIV_ENOMEM, "compare: out of memory");
    for (size_t k = 0; k < np; k++) {
        int masked = ref->flag[k] == RPIV_FLAG_MASKED || cmp->flag[k] == RPIV_FLAG_MASKED;
        d[k] = masked ? (double)NAN : component(ref, k, c) - component(cmp, k, c);
    }
    double ext[4] = {ref->x0 - 0.5 * ref->dx, ref->x0 + (ref->nx - 0.5) * ref->dx,
                     ref->y0 - 0.5 * ref->dy, ref->y0 + (ref->ny - 0.5) * ref->dy};
    char title[96], zl[32];
    snprintf(title, sizeof title, "REF - CMP (%s), E#d1#u = %.4g", cname, r->e1);
    snprintf(zl, sizeof zl, "#gD%s (px)", cname);
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.cmap = RPIV_PLOT_CMAP_DIVERGING;
    double m = r->max_abs > 0 ? r->max_abs : 1;
    o.zmin = -m;
    o.zmax = m;
    o.zlabel = zl;
    rpiv_status st = rpiv_plot_map(png, title, d, ref->nx, ref->ny, ext, &o);
    free(d);
    return st;
}
