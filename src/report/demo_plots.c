/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Step 6 of the demo, its figures: the PNG plots of every step (plot.h), which the report
 * (demo_report.c) shows. */
#include "demo_impl.h"
#include "fig_impl.h"

#include "rpiv/flow.h"
#include "rpiv/plot.h"
#include "rpiv/report.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- plots ---------------------------------------------------------------------------------- */

/* A plot written into DIR: counted in the result and as a unit of work. */
static rpiv_status done(demo_ctx *c, const char *name)
{
    demo_add_plot(c, name);
    return demo_tick(c, 1);
}

/* A line plot of the series that have finite points; nothing if none has. */
static rpiv_status lines(demo_ctx *c, const char *name, const char *title, const char *xl,
                         const char *yl, rpiv_plot_series *s, size_t ns, const rpiv_plot_opts *o)
{
    size_t m = fig_keep_finite(s, ns);
    if (!m) {
        demo_note(c, "  %s: no data, not plotted", name);
        return RPIV_OK;
    }
    /* room above the data for the legend (drawn in the top right corner) */
    rpiv_plot_opts oo = o ? *o : rpiv_plot_opts_default();
    if (!(oo.ymin < oo.ymax)) {
        double lo = (double)INFINITY, hi = -(double)INFINITY;
        for (size_t k = 0; k < m; k++)
            for (size_t i = 0; i < s[k].n; i++)
                if (isfinite(s[k].x[i]) && isfinite(s[k].y[i])) {
                    lo = fmin(lo, s[k].y[i]);
                    hi = fmax(hi, s[k].y[i]);
                }
        double span = hi > lo ? hi - lo : fmax(1e-3, fabs(hi));
        oo.ymin = lo - 0.04 * span;
        oo.ymax = hi + (0.1 + 0.08 * (double)m) * span;
    }
    char path[RPIV_PATH_MAX];
    rpiv_status st;
    if ((st = demo_path(c, name, path, sizeof path)) ||
        (st = rpiv_plot_lines(path, title, xl, yl, s, m, &oo)))
        return st;
    return done(c, name);
}

/* Traced profiles I0*(z*) as rpiv raytrace draws them: I0* runs from 0 to 1 (each profile
 * divided by its maximum), the axis to 1.05 so that the peaks stay off the frame; the legend
 * sits in the top right corner, above the profiles' tails. Nothing if no series has finite
 * points. */
static rpiv_status profiles(demo_ctx *c, const char *name, const char *title, rpiv_plot_series *s,
                            size_t ns)
{
    size_t m = fig_keep_finite(s, ns);
    if (!m) {
        demo_note(c, "  %s: no data, not plotted", name);
        return RPIV_OK;
    }
    char path[RPIV_PATH_MAX];
    rpiv_status st;
    if ((st = demo_path(c, name, path, sizeof path)) ||
        (st = rpiv_report_sheet_profiles(path, title, "I0*", s, m, 1.05)))
        return st;
    return done(c, name);
}

static rpiv_status plot_sheet(demo_ctx *c)
{
    const rpiv_optics_result *t = c->trace;
    size_t nz = t->nz, nx = t->nx;
    rpiv_status st;
    double *buf = malloc((12 * nz + 16) * sizeof *buf);
    if (!buf)
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    /* traced profiles at a few stations (figs 7b, 11) */
    static const double xsel[] = {2.0, 4.455, 6.5, 8.0};
    rpiv_plot_series s[8];
    char lab[8][48];
    size_t ns = 0;
    for (size_t q = 0; q < 4; q++) {
        size_t k = 0;
        for (size_t i = 1; i < nx; i++)
            if (fabs(t->xstar[i] - xsel[q]) < fabs(t->xstar[k] - xsel[q]))
                k = i;
        double *p = buf + ns * nz;
        if (!(rpiv_optics_profile_norm(t, k, p) > 0))
            continue;
        snprintf(lab[ns], sizeof lab[ns], "x* = %.3g", t->xstar[k]);
        s[ns] = (rpiv_plot_series){p, t->zstar, nz, lab[ns], RPIV_PLOT_LINE};
        ns++;
    }
    if ((st = profiles(c, "sheet_profiles.png", "Traced sheet I0*(z*) (paper figs 7b, 11)", s, ns)))
        goto out;
    /* fig 11: beta1 sweep at x* = 4.455 */
    ns = 0;
    for (size_t q = 0; q < c->nsweep && q < 8; q++) {
        snprintf(lab[q], sizeof lab[q], "#gb#d1#u = %.2g deg", c->sweep_beta[q]);
        s[ns++] = (rpiv_plot_series){c->sweep_prof + q * nz, t->zstar, nz, lab[q], RPIV_PLOT_LINE};
    }
    if ((st = profiles(c, "sheet_beta1.png", "Traced I0*(z*) at x* = 4.455 vs #gb#d1#u (fig 11)", s,
                       ns)))
        goto out;
    /* fig 8: z*_inf, z*_max, z*_sup along x*, traced and as synthesised, and z*_OP */
    double xr[2] = {c->res->x0_star, c->res->x1_star}, zr[2];
    zr[0] = zr[1] = c->e.camera.zop_star;
    rpiv_plot_series m[7] = {
        {t->xstar, c->mzinf, nx, "z*#dinf#u traced", RPIV_PLOT_POINTS},
        {t->xstar, c->mzmax, nx, "z*#dmax#u traced", RPIV_PLOT_POINTS},
        {t->xstar, c->mzsup, nx, "z*#dsup#u traced", RPIV_PLOT_POINTS},
        {c->xs, c->czinf, (size_t)c->nx, "z*#dinf#u synthesis", RPIV_PLOT_LINE},
        {c->xs, c->czmax, (size_t)c->nx, "z*#dmax#u synthesis", RPIV_PLOT_LINE},
        {c->xs, c->czsup, (size_t)c->nx, "z*#dsup#u synthesis", RPIV_PLOT_LINE},
        {xr, zr, 2, "z*#dOP#u", RPIV_PLOT_LINE}};
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.ymin = 0;
    o.ymax = 1.45; /* the channel, and room for the legend above it */
    if ((st = lines(c, "sheet_metrics.png", "Sheet edges and peak along x* (figs 8, 21)", "x*",
                    "z*", m, 7, &o)))
        goto out;
    /* self-similarity: traced profiles of the band in z+ = (z* - z*_max)/e*, and the fit */
    if (c->fit) {
        /* up to five stations of the band with metrics, evenly spread */
        size_t cand[64], nc = 0;
        for (size_t k = 0; k < nx && nc < 64; k++)
            if (isfinite(c->me[k]) && t->xstar[k] >= c->res->x0_star &&
                t->xstar[k] <= c->res->x1_star)
                cand[nc++] = k;
        size_t npick = nc < 5 ? nc : 5;
        ns = 0;
        for (size_t q = 0; q < npick; q++) {
            size_t k = cand[npick > 1 ? q * (nc - 1) / (npick - 1) : 0];
            double *p = buf + ns * 2 * nz, *v = p + nz;
            if (!(rpiv_optics_profile_norm(t, k, v) > 0))
                continue;
            for (size_t j = 0; j < nz; j++)
                p[j] = (t->zstar[j] - c->mzmax[k]) / c->me[k];
            snprintf(lab[ns], sizeof lab[ns], "traced x* = %.3g", t->xstar[k]);
            s[ns] = (rpiv_plot_series){p, v, nz, lab[ns], RPIV_PLOT_LINE};
            ns++;
        }
        s[ns++] = (rpiv_plot_series){c->fit->zplus, c->fit->shape, c->fit->n, "self-similar fit",
                                     RPIV_PLOT_POINTS};
        rpiv_plot_opts o2 = rpiv_plot_opts_default();
        o2.xmin = -2.5;
        o2.xmax = 2.5;
        if ((st = lines(c, "sheet_selfsim.png",
                        "Self-similar sheet: I0* vs z+ = (z* - z*#dmax#u)/e*", "z+", "I0*", s, ns,
                        &o2)))
            goto out;
    }
out:
    free(buf);
    return st;
}

static rpiv_status plot_duct(demo_ctx *c)
{
    enum { N = 201 };
    double a[N], uz[N], uy[N];
    for (int k = 0; k < N; k++) {
        a[k] = (double)k / (N - 1);
        uz[k] = rpiv_duct_u(0.5, a[k]);
        uy[k] = rpiv_duct_u(a[k], 0.5);
    }
    rpiv_plot_series s[2] = {{a, uz, N, "U*(y* = 0.5, z*)", RPIV_PLOT_LINE},
                             {a, uy, N, "U*(y*, z* = 0.5)", RPIV_PLOT_LINE}};
    char title[96];
    snprintf(title, sizeof title, "Square duct, laminar (Eq. White), Re = %g",
             c->e.channel.reynolds);
    return lines(c, "duct_profiles.png", title, "z* or y*", "U* = U / U#db#u", s, 2, NULL);
}

/* A map of U*(y*, z*) over the fluid rows of column i and NZS heights. (Only fluid rows:
 * rpiv_plot_map stretches its colour scale when cells are blank.) */
static rpiv_status section(demo_ctx *c, const char *name, const char *title, int analytic, int i)
{
    enum { NZS = 64 };
    int j0 = 0, j1 = c->ny - 1;
    while (j0 < c->ny && !c->fluid[(size_t)j0 * (size_t)c->nx + (size_t)i])
        j0++;
    while (j1 > j0 && !c->fluid[(size_t)j1 * (size_t)c->nx + (size_t)i])
        j1--;
    int ny = j1 - j0 + 1;
    if (j0 >= c->ny || ny < 2) {
        demo_note(c, "  %s: no fluid rows, not plotted", name);
        return RPIV_OK;
    }
    double *z = malloc((size_t)ny * NZS * sizeof *z);
    if (!z)
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    for (int k = 0; k < NZS; k++) {
        double zs = (k + 0.5) / NZS;
        for (int j = j0; j <= j1; j++) {
            double v = analytic ? rpiv_duct_u(c->ys[j], zs) : demo_vol_eval(c, i, j, zs);
            z[(size_t)k * (size_t)ny + (size_t)(j - j0)] = isfinite(v) ? v : 0;
        }
    }
    double hy = 0.5 * (c->ys[1] - c->ys[0]);
    double ext[4] = {c->ys[j0] - hy, c->ys[j1] + hy, 0, 1};
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.xlabel = "y*";
    o.ylabel = "z*";
    o.y_axis = RPIV_PLOT_UP;
    o.zlabel = "U*";
    o.zmin = 0;
    o.zmax = 2.2;
    char path[RPIV_PATH_MAX];
    rpiv_status st = demo_path(c, name, path, sizeof path);
    if (!st)
        st = rpiv_plot_map(path, title, z, ny, NZS, ext, &o);
    free(z);
    if (st)
        return st;
    return done(c, name);
}

/* A plot size for the band's aspect ratio, with room for the axes and a colour bar. */
static void band_size(const demo_ctx *c, rpiv_plot_opts *o)
{
    double w = 500.0 * c->w / c->h + 300;
    o->width_px = w < 700 ? 700 : w > 1600 ? 1600 : (int)w;
    o->height_px = 560;
}

/* The field figure of rpiv plot (rpiv_plot_field): a colour map of the displacement, arrows
 * scaled to the 95 % quantile of the speeds with a reference arrow, the flags in a key; sized
 * for the band's aspect ratio (a plot box 700 px wide, plus the margins, bar and key). */
static rpiv_status quiver(demo_ctx *c, const char *name, const char *title, const rpiv_field *f)
{
    rpiv_plot_field_params p = rpiv_plot_field_params_default();
    double aspect = (double)c->h / c->w, hgt = 933.0 * aspect + 60;
    p.width_px = 1000;
    p.height_px = hgt < 450 ? 450 : hgt > 1100 ? 1100 : (int)hgt;
    char path[RPIV_PATH_MAX];
    rpiv_status st;
    if ((st = demo_path(c, name, path, sizeof path)) ||
        (st = rpiv_plot_field(f, path, title, &p, NULL)))
        return st;
    return done(c, name);
}

/* data / bulk_px (U*) over the compared rows (a contiguous band of rows, no blank cell), in x*,
 * y*, colours over [zmin, zmax]. */
static rpiv_status grid_map(demo_ctx *c, const char *name, const char *title, const float *data,
                            const char *zlabel, double zmin, double zmax)
{
    int j0 = c->ny, j1 = -1;
    for (int j = 0; j < c->ny; j++)
        for (int i = 0; i < c->nx; i++)
            if (c->fluid[(size_t)j * (size_t)c->nx + (size_t)i]) {
                j0 = j < j0 ? j : j0;
                j1 = j > j1 ? j : j1;
            }
    if (j1 - j0 < 1) {
        demo_note(c, "  %s: no compared rows, not plotted", name);
        return RPIV_OK;
    }
    int ny = j1 - j0 + 1, nx = c->nx;
    double *z = malloc((size_t)nx * (size_t)ny * sizeof *z);
    if (!z)
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    for (int j = j0; j <= j1; j++)
        for (int i = 0; i < nx; i++)
            z[(size_t)(j - j0) * (size_t)nx + (size_t)i] =
                (double)data[(size_t)j * (size_t)nx + (size_t)i] / c->bulk_px;
    double hx = 0.5 * c->gdx * c->spp, hy = 0.5 * c->gdy * c->spp;
    double ext[4] = {c->xs[0] - hx, c->xs[nx - 1] + hx, c->ys[j0] - hy, c->ys[j1] + hy};
    rpiv_plot_opts o = rpiv_plot_opts_default();
    band_size(c, &o);
    o.xlabel = "x*";
    o.ylabel = "y*";
    o.zlabel = zlabel;
    o.zmin = zmin;
    o.zmax = zmax;
    char path[RPIV_PATH_MAX];
    rpiv_status st = demo_path(c, name, path, sizeof path);
    if (!st)
        st = rpiv_plot_map(path, title, z, nx, ny, ext, &o);
    free(z);
    if (st)
        return st;
    return done(c, name);
}

static rpiv_status field_map(demo_ctx *c, const char *name, const char *title, const rpiv_field *f)
{
    return grid_map(c, name, title, f->u, "U*", 0, 2.2);
}

/* The per-vector sheet bias (bias_u of rpiv_ccm_bias_field) in U*, symmetric colours. */
static rpiv_status bias_map(demo_ctx *c)
{
    const rpiv_quantity *q = c->bfield ? rpiv_field_quantity(c->bfield, "bias_u") : NULL;
    if (!q)
        return RPIV_OK;
    double m = 0;
    for (size_t k = 0; k < (size_t)c->nx * (size_t)c->ny; k++)
        if (c->fluid[k])
            m = fmax(m, fabs((double)q->data[k]) / c->bulk_px);
    m = m > 0 ? m : 1e-3;
    return grid_map(c, "bias_map.png",
                    "Sheet bias per vector (CCM, duct variation, against z*_max): bias U*", q->data,
                    "bias U*", -m, m);
}

/* The R-PIV ensemble's random uncertainty sigma_u per vector, U*. */
static rpiv_status unc_map(demo_ctx *c)
{
    const rpiv_quantity *q = c->rfield ? rpiv_field_quantity(c->rfield, "sigma_u") : NULL;
    if (!q)
        return RPIV_OK;
    double m = 0;
    for (size_t k = 0; k < (size_t)c->nx * (size_t)c->ny; k++)
        if (c->fluid[k] && c->rfield->flag[k] == RPIV_FLAG_VALID)
            m = fmax(m, (double)q->data[k] / c->bulk_px);
    m = m > 0 ? m : 1e-3;
    return grid_map(c, "uncertainty_map.png",
                    "Random uncertainty per vector of the R-PIV ensemble: sigma_u U*", q->data,
                    "sigma_u U*", 0, m);
}

static rpiv_status plot_image(demo_ctx *c)
{
    if (!c->sample)
        return RPIV_OK;
    int w = c->sample->w < 640 ? c->sample->w : 640, h = c->sample->h;
    double *z = malloc((size_t)w * (size_t)h * sizeof *z);
    if (!z)
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            z[(size_t)y * (size_t)w + (size_t)x] =
                (double)c->sample->px[(size_t)y * (size_t)c->sample->w + (size_t)x];
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.cmap = RPIV_PLOT_CMAP_GRAY;
    o.zlabel = "counts";
    o.width_px = 1000;
    o.height_px = 900;
    char path[RPIV_PATH_MAX], title[128];
    snprintf(title, sizeof title, "R-PIV frame A of pair 1 (left %d px of the %d x %d band)", w,
             c->sample->w, h);
    rpiv_status st = demo_path(c, "rpiv_image.png", path, sizeof path);
    if (!st)
        st = rpiv_plot_map(path, title, z, w, h, NULL, &o);
    free(z);
    if (st)
        return st;
    return done(c, "rpiv_image.png");
}

static rpiv_status plot_compare(demo_ctx *c)
{
    rpiv_status st;
    size_t nx = (size_t)c->nx, ny = (size_t)c->ny;
    char title[128];
    /* P-PIV error per plane */
    {
        double *z = c->zk + 1;
        rpiv_plot_series s = {z, c->plane_e1, c->nz, "E1 (U vs analytic)", RPIV_PLOT_BOTH};
        for (size_t k = 0; k < c->nz; k++)
            c->plane_e1[k] *= 100;
        st = lines(c, "ppiv_e1.png", "P-PIV planes vs the analytic duct", "z*#dB#u = z*#dOP#u",
                   "E1 (%)", &s, 1, NULL);
        for (size_t k = 0; k < c->nz; k++)
            c->plane_e1[k] /= 100;
        if (st)
            return st;
    }
    /* fig 24 */
    if (c->icol24 >= 0) {
        int i = c->icol24;
        double *b = malloc(6 * ny * sizeof *b);
        if (!b)
            return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
        double *y = b, *ur = b + ny, *pi = b + 2 * ny, *pm = b + 3 * ny, *ps = b + 4 * ny,
               *ua = b + 5 * ny;
        size_t n = 0;
        for (int j = 0; j < c->ny; j++) {
            size_t q = (size_t)j * nx + (size_t)i;
            if (!c->fluid[q])
                continue;
            y[n] = c->ys[j];
            ur[n] = (double)c->rfield->u[q] / c->bulk_px;
            pi[n] = demo_vol_eval(c, i, j, c->czinf[i]);
            pm[n] = demo_vol_eval(c, i, j, c->czmax[i]);
            ps[n] = demo_vol_eval(c, i, j, c->czsup[i]);
            ua[n] = rpiv_duct_u(c->ys[j], c->czmax[i]);
            n++;
        }
        char l1[48], l2[48], l3[48];
        snprintf(l1, sizeof l1, "P-PIV z* = %.3f (z*#dinf#u)", c->czinf[i]);
        snprintf(l2, sizeof l2, "P-PIV z* = %.3f (z*#dmax#u)", c->czmax[i]);
        snprintf(l3, sizeof l3, "P-PIV z* = %.3f (z*#dsup#u)", c->czsup[i]);
        rpiv_plot_series s[5] = {{y, pi, n, l1, RPIV_PLOT_BOTH},
                                 {y, pm, n, l2, RPIV_PLOT_BOTH},
                                 {y, ps, n, l3, RPIV_PLOT_BOTH},
                                 {y, ua, n, "analytic at z*#dmax#u", RPIV_PLOT_LINE},
                                 {y, ur, n, "R-PIV", RPIV_PLOT_POINTS}};
        snprintf(title, sizeof title, "Profiles across the channel at x* = %.3f (fig 24)",
                 c->xs[i]);
        st = lines(c, "fig24_profiles.png", title, "y*", "U*", s, 5, NULL);
        free(b);
        if (st)
            return st;
    }
    /* fig 25 */
    {
        double *b = malloc(3 * nx * sizeof *b);
        if (!b)
            return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
        for (size_t i = 0; i < nx; i++) {
            b[i] = 100 * c->e1inf[i];
            b[nx + i] = 100 * c->e1max[i];
            b[2 * nx + i] = 100 * c->e1sup[i];
        }
        rpiv_plot_series s[3] = {{c->xs, b, nx, "ref P-PIV(z*#dinf#u)", RPIV_PLOT_BOTH},
                                 {c->xs, b + 2 * nx, nx, "ref P-PIV(z*#dsup#u)", RPIV_PLOT_BOTH},
                                 {c->xs, b + nx, nx, "ref P-PIV(z*#dmax#u)", RPIV_PLOT_BOTH}};
        st = lines(c, "fig25_e1.png", "E1 along y* of R-PIV vs P-PIV, at each x* (fig 25)", "x*",
                   "E1 (%)", s, 3, NULL);
        free(b);
        if (st)
            return st;
    }
    /* fig 26 */
    {
        double *ua = malloc(nx * sizeof *ua);
        if (!ua)
            return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
        for (size_t i = 0; i < nx; i++)
            ua[i] = c->col_ok[i] ? rpiv_duct_u(0.5, c->czmax[i]) : (double)NAN;
        rpiv_plot_series s[4] = {{c->xs, ua, nx, "analytic at z*#dmax#u", RPIV_PLOT_LINE},
                                 {c->xs, c->up_mid, nx, "P-PIV at z*#dmax#u", RPIV_PLOT_LINE},
                                 {c->xs, c->umodel, nx, "CCM (Eq. statform)", RPIV_PLOT_LINE},
                                 {c->xs, c->ur_mid, nx, "R-PIV", RPIV_PLOT_POINTS}};
        st = lines(c, "fig26_model.png", "U* at y* = 0.5 along x*: R-PIV and the model (fig 26)",
                   "x*", "U*", s, 4, NULL);
        free(ua);
        if (st)
            return st;
    }
    /* fig 27 */
    {
        double ln[RPIV_DEMO_MAX_SNAP], e[RPIV_DEMO_MAX_SNAP];
        for (size_t k = 0; k < c->nsnap; k++) {
            ln[k] = log10((double)c->snap[k]);
            e[k] = 100 * c->res->conv_e1[k];
        }
        rpiv_plot_series s = {ln, e, c->nsnap, "R-PIV vs CCM at y* = 0.5", RPIV_PLOT_BOTH};
        if ((st = lines(c, "fig27_convergence.png", "E1 along x* vs the number of pairs (fig 27)",
                        "log#d10#u N#dim#u", "E1 (%)", &s, 1, NULL)))
            return st;
    }
    /* the bias correction */
    if (c->ninv) {
        size_t n = c->ninv;
        double *b = malloc(4 * n * sizeof *b);
        if (!b)
            return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
        double *ut = b, *lo = b + n, *hi = b + 2 * n, *zt = b + 3 * n;
        for (size_t k = 0; k < n; k++) {
            zt[k] = c->inv_z[k];
            ut[k] = rpiv_duct_u(0.5, zt[k]);
            lo[k] = c->inv_u[k] - c->inv_sd[k];
            hi[k] = c->inv_u[k] + c->inv_sd[k];
        }
        rpiv_plot_series s[5] = {
            {ut, zt, n, "analytic (truth)", RPIV_PLOT_LINE},
            {c->inv_u, zt, n, "CCM inversion", RPIV_PLOT_LINE},
            {lo, zt, n, "- 1 sd", RPIV_PLOT_LINE},
            {hi, zt, n, "+ 1 sd", RPIV_PLOT_LINE},
            {c->inv_um, c->inv_zm, c->ninvm, "R-PIV at z*#dmax#u (association)", RPIV_PLOT_POINTS}};
        rpiv_plot_opts o = rpiv_plot_opts_default();
        o.xmin = 0;
        o.xmax = 3.4;
        o.ymin = 0;
        o.ymax = 1;
        st = lines(c, "ccm_invert.png", "Bias-corrected U*(z*) at y* = 0.5 (CCM inversion)", "U*",
                   "z*", s, 5, &o);
        free(b);
        if (st)
            return st;
    }
    return RPIV_OK;
}

rpiv_status demo_plots(demo_ctx *c)
{
    rpiv_status st;
    if ((st = plot_sheet(c)) || (st = plot_duct(c)))
        return st;
    int imid = c->nx / 2;
    char title[96];
    snprintf(title, sizeof title, "P-PIV plane z*#dB#u = %.4f (sum of correlation)", c->zmid);
    if ((st = c->ppiv_mid ? quiver(c, "ppiv_plane.png", title, c->ppiv_mid) : RPIV_OK) ||
        (st = section(c, "ppiv_section.png", "P-PIV volume: U*(y*, z*) (fig 23)", 0, imid)) ||
        (st = section(c, "duct_section.png", "Analytic U*(y*, z*)", 1, imid)) ||
        (st = plot_image(c)) ||
        (st = quiver(c, "rpiv_field.png", "R-PIV vectors (sum of correlation)", c->rfield)) ||
        (st = field_map(c, "rpiv_map.png", "R-PIV: U* over the compared vectors", c->rfield)) ||
        (st = bias_map(c)) || (st = unc_map(c)) || (st = plot_compare(c)))
        return st;
    return RPIV_OK;
}
