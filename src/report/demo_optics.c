/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Step 1 of the demo: trace the refracted sheet of the experiment (optics.h), its profiles and
 * metrics along x* (paper figs 7, 8), a beta1 sweep at x* = 4.455 (fig 11), and the
 * self-similar sheet fitted on the stations of the image band, which the R-PIV synthesis then
 * uses (or the configuration's [sheet] if the trace cannot give one). */
#include "demo_impl.h"

#include "rpiv/report.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define X_FIG11 4.455 /* paper fig 11 */
#define X_FIG7  6.5   /* paper fig 7b: e* = 0.42 */

static const double sweep_beta[] = {1.0, 1.3, 1.6, 2.0};

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Stations x0 : dx : x1 plus the paper's, sorted, without duplicates. */
static rpiv_status stations(const rpiv_demo_params *p, double **out, size_t *n)
{
    size_t m = (size_t)floor((p->optics_x1 - p->optics_x0) / p->optics_dx + 1e-9) + 1;
    double *x = malloc((m + 2) * sizeof *x);
    if (!x)
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    for (size_t k = 0; k < m; k++)
        x[k] = p->optics_x0 + (double)k * p->optics_dx;
    x[m] = X_FIG11;
    x[m + 1] = X_FIG7;
    qsort(x, m + 2, sizeof *x, cmp_double);
    size_t k = 0;
    for (size_t i = 0; i < m + 2; i++)
        if (!k || fabs(x[i] - x[k - 1]) > 1e-9)
            x[k++] = x[i];
    *out = x;
    *n = k;
    return RPIV_OK;
}

static size_t nearest(const double *x, size_t n, double v)
{
    size_t best = 0;
    for (size_t k = 1; k < n; k++)
        if (fabs(x[k] - v) < fabs(x[best] - v))
            best = k;
    return best;
}

/* Fit the self-similar sheet on the stations of the band (one station step beyond it on each
 * side), or on all stations if fewer than 3 of those have metrics. */
static rpiv_status fit_sheet(demo_ctx *c)
{
    const rpiv_optics_result *t = c->trace;
    double lo = c->res->x0_star - c->p.optics_dx, hi = c->res->x1_star + c->p.optics_dx;
    size_t nin = 0;
    for (size_t k = 0; k < t->nx; k++)
        nin += t->xstar[k] >= lo && t->xstar[k] <= hi && isfinite(c->me[k]);
    int all = nin < 3;
    double *xs = malloc(t->nx * sizeof *xs);
    double *in = malloc(t->nx * t->nz * sizeof *in);
    if (!xs || !in) {
        free(xs);
        free(in);
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    }
    size_t m = 0;
    for (size_t k = 0; k < t->nx; k++)
        if (all || (t->xstar[k] >= lo && t->xstar[k] <= hi)) {
            xs[m] = t->xstar[k];
            memcpy(in + m * t->nz, t->inten + k * t->nz, t->nz * sizeof *in);
            m++;
        }
    rpiv_status st = rpiv_optics_selfsim_fit(xs, m, t->zstar, t->nz, in, 0.01, &c->fit);
    free(xs);
    free(in);
    if (st == RPIV_ENUMERIC) {
        demo_note(c, "  no self-similar fit: %s", rpiv_errmsg());
        rpiv_errclear();
        c->fit = NULL;
        return RPIV_OK;
    }
    return st;
}

/* The sheet of the R-PIV synthesis: the fit if it describes a lit, rising sheet over the
 * band, else the configuration's. */
static rpiv_status choose_sheet(demo_ctx *c)
{
    rpiv_demo_result *r = c->res;
    const rpiv_optics_selfsim *f = c->fit;
    double xm = 0.5 * (r->x0_star + r->x1_star);
    const char *why = NULL;
    if (!f)
        why = "the traced profiles give no self-similar fit";
    else if (!(f->e1 > 0 && isfinite(f->zm1)))
        why = "the fitted thickness does not grow along x*";
    else if (!(f->e0 + f->e1 * xm > 0))
        why = "the fitted sheet has no thickness at the centre of the band";
    else if (!(f->zm0 + f->zm1 * xm > 0 && f->zm0 + f->zm1 * xm < 1))
        why = "the fitted sheet's peak is outside the channel at the centre of the band";
    rpiv_status st;
    c->sheet_p = c->e.sheet;
    if (why) {
        r->sheet_traced = 0;
        int k = (int)c->e.sheet.kind;
        snprintf(r->sheet_note, sizeof r->sheet_note,
                 "the configuration's [sheet] (kind = %s), because %s",
                 k >= 0 && k <= 2 ? rpiv_sheet_kind_names[k] : "?", why);
    } else {
        char path[RPIV_PATH_MAX];
        if ((st = demo_path(c, "data/sheet_fit.txt", path, sizeof path)) ||
            (st = rpiv_optics_selfsim_save(f, path)))
            return st;
        /* the profile file's header carries e0, e1, zm0, zm1 and overrides the [sheet] keys
         * (which stay valid INI values: a fitted e0 may be negative, the key's range is not) */
        c->sheet_p.kind = RPIV_SHEET_SELFSIM;
        snprintf(c->sheet_p.profile, sizeof c->sheet_p.profile, "%s", path);
        r->sheet_traced = 1;
        double xdark = -f->e0 / f->e1;
        char dark[96] = "";
        if (xdark > r->x0_star)
            snprintf(dark, sizeof dark, "; its thickness is <= 0 (no light) for x* < %.3f", xdark);
        snprintf(r->sheet_note, sizeof r->sheet_note,
                 "the traced sheet, fitted self-similar on %zu stations: z*_max = %.4f + "
                 "%.5f x*, e* = %.4f + %.5f x*%s",
                 f->nused, f->zm0, f->zm1, f->e0, f->e1, dark);
    }
    if ((st = rpiv_sheet_new(&c->sheet_p, &c->sheet)))
        return st;
    if (c->sheet_p.kind == RPIV_SHEET_SELFSIM) {
        double e1 = why ? c->sheet_p.e1 : f->e1, zm0 = why ? c->sheet_p.zm0 : f->zm0,
               zm1 = why ? c->sheet_p.zm1 : f->zm1;
        r->sheet_incl_deg = rpiv_sheet_incl_deg(zm1);
        r->sheet_de_dx = e1;
        r->sheet_x_zop = zm1 != 0 ? (c->e.camera.zop_star - zm0) / zm1 : (double)NAN;
    } else {
        r->sheet_incl_deg = 0;
        r->sheet_de_dx = 0;
        r->sheet_x_zop = (double)NAN;
    }
    demo_note(c, "  R-PIV synthesis uses %s", r->sheet_note);
    return RPIV_OK;
}

rpiv_status demo_optics(demo_ctx *c)
{
    rpiv_status st;
    rpiv_demo_result *r = c->res;
    const rpiv_experiment *e = &c->e;
    demo_note(c, "step 1/6: ray tracing the refracted sheet (%ld rays, beta1 = %g deg)",
              e->laser.nrays, e->laser.beta1_deg);
    double *xs = NULL;
    size_t n = 0;
    if ((st = stations(&c->p, &xs, &n)))
        return st;
    rpiv_optics_opts o = rpiv_optics_opts_default();
    o.threads = c->p.threads;
    st = rpiv_optics_trace(&e->laser, &e->prism, e->channel.h_m, xs, n, &o, NULL, &c->trace);
    free(xs);
    if (st || (st = demo_tick(c, 1)))
        return st;
    const rpiv_optics_result *t = c->trace;
    c->mzinf = malloc(n * sizeof(double));
    c->mzmax = malloc(n * sizeof(double));
    c->mzsup = malloc(n * sizeof(double));
    c->me = malloc(n * sizeof(double));
    if (!c->mzinf || !c->mzmax || !c->mzsup || !c->me)
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    rpiv_optics_metrics_all(t, c->mzinf, c->mzmax, c->mzsup, c->me);
    c->kfig11 = nearest(t->xstar, n, X_FIG11);
    r->trace_it_ig = t->stats.transmitted;
    r->trace_elev_deg = t->axis.transmitted ? t->axis.elevation * 180 / M_PI : (double)NAN;
    r->trace_e_65 = c->me[nearest(t->xstar, n, X_FIG7)];
    char path[RPIV_PATH_MAX];
    if ((st = demo_path(c, "data/raytrace_metrics.txt", path, sizeof path)) ||
        (st = rpiv_optics_save_metrics(t, path)) ||
        (st = demo_path(c, "data/raytrace_profile_x4.455.txt", path, sizeof path)) ||
        (st = rpiv_optics_save_profile(t, c->kfig11, path)))
        return st;
    demo_note(c, "  It/Ig = %.3f, axis elevation in the water %.2f deg, e* at x* = 6.5: %.3f",
              r->trace_it_ig, r->trace_elev_deg, r->trace_e_65);

    /* fig 11: profiles at x* = 4.455 for a few beta1 */
    c->nsweep = sizeof sweep_beta / sizeof sweep_beta[0];
    memcpy(c->sweep_beta, sweep_beta, sizeof sweep_beta);
    size_t nz = rpiv_optics_nbins(&o);
    rpiv_optics_sweep_row rows[sizeof sweep_beta / sizeof sweep_beta[0]];
    c->sweep_prof = malloc(c->nsweep * nz * sizeof *c->sweep_prof);
    if (!c->sweep_prof)
        return rpiv_fail(RPIV_ENOMEM, "demo: out of memory");
    char ppath[RPIV_PATH_MAX];
    if ((st = rpiv_optics_sweep_beta1(&e->laser, &e->prism, e->channel.h_m, X_FIG11, c->sweep_beta,
                                      c->nsweep, &o, NULL, rows, c->sweep_prof)) ||
        (st = demo_path(c, "data/raytrace_sweep.txt", path, sizeof path)) ||
        (st = demo_path(c, "data/raytrace_sweep_profiles.txt", ppath, sizeof ppath)) ||
        (st = rpiv_optics_save_sweep(&e->laser, &e->prism, X_FIG11, rows, c->nsweep, path,
                                     c->sweep_prof, &o, ppath)) ||
        (st = demo_tick(c, 1)))
        return st;

    if ((st = fit_sheet(c)))
        return st;
    return choose_sheet(c);
}
