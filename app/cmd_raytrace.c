/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv raytrace - the refracted laser sheet by ray tracing (optics.h; docs/optics.md). */
#include "cli.h"

#include "rpiv/optics.h"
#include "rpiv/plot.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

rpiv_status cmd_raytrace(int argc, char **argv);

static void help(void)
{
    printf(
        "usage: rpiv raytrace [--config FILE] [--set SEC.KEY=VALUE]... [--rays N] [--x X*]\n"
        "                     [--beta1 DEG] [--polar p|s|unpolarised] [--stations A:B:STEP]\n"
        "                     [--dz DZ*] [--smooth SIGMA*] [--sweep beta1:A:B:STEP]\n"
        "                     [--sensitivity[=DEG]] [--fit PROFILE_OUT] [--out DIR] [--png]\n"
        "                     [--threads N] [--quiet]\n\n"
        "Trace the laser sheet through the lens, the prism's inclined face (air/PMMA) and the\n"
        "channel floor (PMMA/water) with Snell-Descartes and Fresnel at each interface, from\n"
        "the [laser] and [prism] sections of the configuration, and write into DIR:\n"
        "  raytrace_profile.txt    I0(z*) at x* = X (default 4.455, paper fig. 11)\n"
        "  raytrace_metrics.txt    z*_inf, z*_max, z*_sup, e* at the stations (default 1:9:0.5)\n"
        "and print the power bookkeeping, the sheet's inclination and thickness growth.\n"
        "  --x X*            station of the profile (4.455)\n"
        "  --stations A:B:STEP  stations of the metrics and the fit (1:9:0.5)\n"
        "  --rays N          rays traced (laser.rays; up to 1e8)\n"
        "  --beta1 DEG       incidence on the inclined face (laser.beta1_deg; the side it is\n"
        "                    measured on is laser.beta1_side = air|pmma)\n"
        "  --polar P         Fresnel transmission: p (paper, default), s or unpolarised\n"
        "  --dz DZ*          profile bin width in z* (0.005); --smooth: Gaussian sigma in z*\n"
        "  --sweep beta1:A:B:STEP  profiles, e*, It/Ig, I*_peak at x* = X for each beta1\n"
        "                    (raytrace_sweep.txt, raytrace_sweep_profiles.txt; figs 11-12)\n"
        "  --sensitivity[=DEG]  the axis ray at beta1 = DEG (1.5, paper fig. 10):\n"
        "                    dtheta_t/theta_t0 and dT/T0 for deta in [-0.016, 0.016] with\n"
        "                    eta = n_pmma / n_water (raytrace_sensitivity.txt)\n"
        "  --fit FILE        self-similar sheet fitted on the stations, written as a sheet\n"
        "                    profile file (use with sheet.kind = selfsim, sheet.profile = FILE)\n"
        "  --out DIR         output folder (output.dir)\n"
        "  --png             also write PNG plots (raytrace_*.png; the sheet map\n"
        "                    raytrace_map.png traces 200 more stations)\n"
        "See docs/optics.md for the geometry and every modelling choice.\n");
}

/* "A:B:STEP" (with an optional "NAME:" prefix checked against `name`). */
static rpiv_status parse_range(const char *opt, const char *arg, const char *name, double **out,
                               size_t *n)
{
    const char *s = arg;
    if (name) {
        size_t ln = strlen(name);
        if (strncmp(s, name, ln) != 0 || s[ln] != ':')
            return rpiv_fail(RPIV_EINVAL, "%s: '%s' is not of the form %s:A:B:STEP", opt, arg,
                             name);
        s += ln + 1;
    }
    char *end;
    double a = strtod(s, &end), b, step;
    if (end == s || *end != ':')
        goto bad;
    s = end + 1;
    b = strtod(s, &end);
    if (end == s || *end != ':')
        goto bad;
    s = end + 1;
    step = strtod(s, &end);
    if (end == s || *end)
        goto bad;
    if (!isfinite(a) || !isfinite(b) || !(step > 0) || !(b >= a))
        return rpiv_fail(RPIV_EINVAL, "%s: '%s' needs A <= B and STEP > 0", opt, arg);
    double cnt = floor((b - a) / step + 1e-9) + 1;
    if (cnt > 10000)
        return rpiv_fail(RPIV_EINVAL, "%s: '%s' gives %.0f values (at most 10000)", opt, arg, cnt);
    *n = (size_t)cnt;
    *out = malloc(*n * sizeof **out);
    if (!*out)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", opt);
    for (size_t i = 0; i < *n; i++)
        (*out)[i] = a + step * (double)i;
    return RPIV_OK;
bad:
    return rpiv_fail(RPIV_EINVAL, "%s: '%s' is not of the form %sA:B:STEP", opt, arg,
                     name ? "beta1:" : "");
}

static rpiv_status out_path(char *buf, const char *dir, const char *name)
{
    if ((size_t)snprintf(buf, RPIV_PATH_MAX, "%s/%s", dir, name) >= RPIV_PATH_MAX)
        return rpiv_fail(RPIV_EINVAL, "%s/%s: path too long", dir, name);
    return RPIV_OK;
}

typedef struct job {
    cli_ctx c;
    double x;         /* profile station */
    double *stations; /* metrics stations */
    size_t nst;
    double *sweep; /* beta1 values */
    size_t nsweep;
    int sensitivity, png;
    double sens_beta1; /* beta1 of the one-ray sensitivity (1.5 deg, paper fig. 10) */
    const char *fit, *dir;
    rpiv_optics_opts o;
} job;

/* ---- plots ------------------------------------------------------------------------------ */

/* Copy the series that have a finite point (the plot refuses the others); returns how many. */
static size_t finite_series(const rpiv_plot_series *in, size_t n, rpiv_plot_series *out)
{
    size_t nu = 0;
    for (size_t q = 0; q < n; q++) {
        int any = 0;
        for (size_t k = 0; k < in[q].n; k++)
            any |= isfinite(in[q].y[k]);
        if (any)
            out[nu++] = in[q];
    }
    return nu;
}

/* Profile k of r as I0* (x) against z* (y), the way the paper draws sheet profiles. */
static rpiv_status plot_profile(const rpiv_optics_result *r, const char *dir)
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
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.ymin = 0;
    o.ymax = 1;
    if (!(st = out_path(path, dir, "raytrace_profile.png")))
        st = rpiv_plot_lines(path, title, "I#d0#u* = I / I#dmax#u", "z*", &ser, 1, &o);
    free(in);
    return st;
}

/* z*_inf, z*_max, z*_sup along x* (paper fig. 8) with the fitted z*_max line. */
static rpiv_status plot_metrics(const rpiv_optics_result *v, const rpiv_optics_selfsim *f,
                                const char *dir)
{
    char path[RPIV_PATH_MAX];
    rpiv_status st;
    size_t n = v->nx;
    double *a = malloc(5 * n * sizeof *a);
    if (!a)
        return rpiv_fail(RPIV_ENOMEM, "raytrace: out of memory (plot)");
    double *zi = a, *zm = a + n, *zs = a + 2 * n, *fit = a + 3 * n, *e = a + 4 * n;
    for (size_t k = 0; k < n; k++) {
        rpiv_sheet_metrics m;
        if (rpiv_optics_metrics(v, k, &m)) {
            rpiv_errclear();
            m.zinf = m.zmax = m.zsup = m.e = (double)NAN;
        }
        zi[k] = m.zinf;
        zm[k] = m.zmax;
        zs[k] = m.zsup;
        e[k] = m.e;
        fit[k] = f ? f->zm0 + f->zm1 * v->xstar[k] : (double)NAN;
    }
    rpiv_plot_series ser[5] = {{v->xstar, zs, n, "z*#dsup#u", RPIV_PLOT_BOTH},
                               {v->xstar, zm, n, "z*#dmax#u", RPIV_PLOT_BOTH},
                               {v->xstar, zi, n, "z*#dinf#u", RPIV_PLOT_BOTH},
                               {v->xstar, e, n, "e*", RPIV_PLOT_POINTS},
                               {v->xstar, fit, n, "z*#dmax#u fit", RPIV_PLOT_LINE}};
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.ymin = 0;
    o.ymax = 1;
    st = out_path(path, dir, "raytrace_metrics.png");
    if (!st) {
        rpiv_plot_series use[5];
        size_t nu = finite_series(ser, 5, use);
        st = nu ? rpiv_plot_lines(path, "sheet edges and thickness along x*", "x*", "z*, e*", use,
                                  nu, &o)
                : RPIV_OK;
    }
    free(a);
    return st;
}

/* The sheet's normalised fluence rate over (x*, z*): a trace at many stations. */
static rpiv_status plot_map(const job *j, const char *dir)
{
    enum { NXM = 200 };
    double xs[NXM], x0 = -0.5, x1 = j->stations[j->nst - 1] > 1 ? j->stations[j->nst - 1] : 9;
    char path[RPIV_PATH_MAX];
    rpiv_optics_result *r = NULL;
    rpiv_status st;
    for (int k = 0; k < NXM; k++)
        xs[k] = x0 + (x1 - x0) * (k + 0.5) / NXM;
    if ((st = rpiv_optics_trace(&j->c.exp.laser, &j->c.exp.prism, j->c.exp.channel.h_m, xs, NXM,
                                &j->o, NULL, &r)))
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
    if (!(st = out_path(path, dir, "raytrace_map.png")))
        st = rpiv_plot_map(path, "the refracted sheet, normalised at each x*", z, NXM, (int)nz, ext,
                           &o);
out:
    free(z);
    free(col);
    rpiv_optics_result_free(r);
    return st;
}

static rpiv_status plot_sweep(const job *j, const rpiv_optics_sweep_row *rows, const double *prof,
                              const char *dir)
{
    char path[RPIV_PATH_MAX], title[96];
    size_t n = j->nsweep, nz = rpiv_optics_nbins(&j->o), ns = n < 12 ? n : 12;
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
        size_t i = ns > 1 ? s * (n - 1) / (ns - 1) : 0;
        snprintf(lab[s], sizeof lab[s], "%g deg", rows[i].beta1_deg);
        ser[s] = (rpiv_plot_series){prof + i * nz, z, nz, lab[s], RPIV_PLOT_LINE};
    }
    rpiv_plot_opts o = rpiv_plot_opts_default();
    o.ymin = 0;
    o.ymax = 1;
    snprintf(title, sizeof title, "profiles at x* = %g against #gb#d1#u", j->x);
    if ((st = out_path(path, dir, "raytrace_sweep_profiles.png")) ||
        (st = rpiv_plot_lines(path, title, "I#d0#u*", "z*", ser, ns, &o)))
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
    rpiv_plot_series use[3];
    size_t nu = finite_series(s3, 3, use);
    snprintf(title, sizeof title, "transmission, peak and thickness at x* = %g", j->x);
    if (!(st = out_path(path, dir, "raytrace_sweep.png")) && nu)
        st = rpiv_plot_lines(path, title, "#gb#d1#u (deg)", "", use, nu, NULL);
out:
    free(z);
    free(a);
    free(ser);
    free(lab);
    return st;
}

static rpiv_status plot_sensitivity(const rpiv_optics_sens_row *rows, size_t n, double beta1,
                                    const char *dir)
{
    char path[RPIV_PATH_MAX], title[96];
    double de[128], th[128], tt[128];
    for (size_t i = 0; i < n && i < 128; i++) {
        de[i] = rows[i].deta;
        th[i] = rows[i].transmitted ? rows[i].dtheta_rel : (double)NAN;
        tt[i] = rows[i].dT_rel;
    }
    rpiv_plot_series ser[2] = {{de, th, n, "#gd#gh#dt#u/#gh#dt0#u", RPIV_PLOT_BOTH},
                               {de, tt, n, "#gdT/T#d0#u", RPIV_PLOT_BOTH}};
    snprintf(title, sizeof title, "one ray at #gb#d1#u = %g deg", beta1);
    rpiv_status st = out_path(path, dir, "raytrace_sensitivity.png");
    return st ? st
              : rpiv_plot_lines(path, title, "#gd#gy  (#gy = n#dPMMA#u / n#dwater#u)",
                                "relative change", ser, 2, NULL);
}

static void print_summary(const rpiv_optics_result *r)
{
    const rpiv_optics_axis *a = &r->axis;
    const rpiv_optics_stats *s = &r->stats;
    printf("rays %ld, beta1 %g deg (%s side: %.4f deg in air, %.4f deg in the PMMA), "
           "polarisation %s\n",
           s->n_rays, r->laser.beta1_deg, rpiv_beta1_side_name(r->laser.beta1_side),
           a->beta1_air * 180 / M_PI, a->beta1_pmma * 180 / M_PI, rpiv_polar_name(r->laser.polar));
    printf("axis: incidence on the floor %.4f deg (critical %.4f deg), ", a->theta_i * 180 / M_PI,
           a->theta_c * 180 / M_PI);
    if (a->transmitted)
        printf("elevation in the water %.4f deg\n", a->elevation * 180 / M_PI);
    else
        printf("totally reflected\n");
    printf("power / Ig: transmitted It/Ig %.5f, reflected by the face %.5f, by the floor %.5f, "
           "lost by total internal reflection %.5f (%ld rays), missed %.3g\n",
           s->transmitted, s->refl_face, s->refl_floor, s->tir, s->n_tir, s->missed);
}

static rpiv_status run_trace(job *j, const rpiv_progress *prog)
{
    rpiv_status st;
    char path[RPIV_PATH_MAX];
    size_t nx = j->nst + 1;
    double *xs = malloc(nx * sizeof *xs);
    rpiv_optics_result *r = NULL;
    rpiv_optics_selfsim *f = NULL;
    if (!xs)
        return rpiv_fail(RPIV_ENOMEM, "raytrace: out of memory");
    xs[0] = j->x;
    memcpy(xs + 1, j->stations, j->nst * sizeof *xs);
    st = rpiv_optics_trace(&j->c.exp.laser, &j->c.exp.prism, j->c.exp.channel.h_m, xs, nx, &j->o,
                           prog, &r);
    if (st)
        goto out;
    if (!j->c.quiet)
        print_summary(r);
    rpiv_sheet_metrics m;
    if (rpiv_optics_metrics(r, 0, &m) == RPIV_OK)
        printf("x* = %g: z*_inf %.4f  z*_max %.4f  z*_sup %.4f  e* %.4f  I_max %.4g Ig/h\n", j->x,
               m.zinf, m.zmax, m.zsup, m.e, m.imax);
    else
        printf("x* = %g: no sheet metrics (%s)\n", j->x, rpiv_errmsg());
    if ((st = out_path(path, j->dir, "raytrace_profile.txt")) ||
        (st = rpiv_optics_save_profile(r, 0, path)))
        goto out;
    /* metrics and the fit: the stations only (row 0 is the profile station) */
    rpiv_optics_result view = *r;
    view.nx = j->nst;
    view.xstar = r->xstar + 1;
    view.inten = r->inten + r->nz;
    if ((st = out_path(path, j->dir, "raytrace_metrics.txt")) ||
        (st = rpiv_optics_save_metrics(&view, path)))
        goto out;
    st = rpiv_optics_selfsim_fit(view.xstar, view.nx, r->zstar, r->nz, view.inten, 0.01, &f);
    if (st == RPIV_OK) {
        printf("sheet along x* (%zu of %zu stations): z*_max = %.4f + %.5f x* (inclination %.3f "
               "deg, rms %.3g), e* = %.4f + %.5f x* (de*/dx* %.5f, rms %.3g); shape rms %.3g "
               "from self-similar\n",
               f->nused, j->nst, f->zm0, f->zm1, atan(f->zm1) * 180 / M_PI, f->rms_zm, f->e0, f->e1,
               f->e1, f->rms_e, f->rms_shape);
        if (j->fit && (st = rpiv_optics_selfsim_save(f, j->fit)))
            goto out;
        if (j->fit && !j->c.quiet)
            printf("wrote %s (sheet.kind = selfsim, sheet.profile = %s)\n", j->fit, j->fit);
    } else if (j->fit) {
        goto out; /* asked for a fit that cannot be made */
    } else {
        printf("sheet along x*: no fit (%s)\n", rpiv_errmsg());
        st = RPIV_OK;
    }
    if (j->png && ((st = plot_profile(r, j->dir)) || (st = plot_metrics(&view, f, j->dir)) ||
                   (st = plot_map(j, j->dir))))
        goto out;
out:
    rpiv_optics_selfsim_free(f);
    rpiv_optics_result_free(r);
    free(xs);
    return st;
}

static rpiv_status run_sweep(job *j, const rpiv_progress *prog)
{
    rpiv_status st;
    char path[RPIV_PATH_MAX], ppath[RPIV_PATH_MAX];
    size_t nz = rpiv_optics_nbins(&j->o);
    rpiv_optics_sweep_row *rows = malloc(j->nsweep * sizeof *rows);
    double *prof = malloc(j->nsweep * nz * sizeof *prof);
    if (!rows || !prof) {
        st = rpiv_fail(RPIV_ENOMEM, "raytrace: out of memory (sweep)");
        goto out;
    }
    if ((st = rpiv_optics_sweep_beta1(&j->c.exp.laser, &j->c.exp.prism, j->c.exp.channel.h_m, j->x,
                                      j->sweep, j->nsweep, &j->o, prog, rows, prof)))
        goto out;
    if ((st = out_path(path, j->dir, "raytrace_sweep.txt")) ||
        (st = out_path(ppath, j->dir, "raytrace_sweep_profiles.txt")) ||
        (st = rpiv_optics_save_sweep(&j->c.exp.laser, &j->c.exp.prism, j->x, rows, j->nsweep, path,
                                     prof, &j->o, ppath)))
        goto out;
    if (j->png && (st = plot_sweep(j, rows, prof, j->dir)))
        goto out;
    if (!j->c.quiet) {
        printf("beta1 sweep at x* = %g (I*_peak = I_peak / I_peak(2 deg)):\n", j->x);
        printf("  beta1_deg       e*   z*_max    It/Ig  I*_peak\n");
        for (size_t i = 0; i < j->nsweep; i++)
            printf("  %9.4g %8.4f %8.4f %8.5f %8.4f\n", rows[i].beta1_deg, rows[i].e, rows[i].zmax,
                   rows[i].it_ig, rows[i].ipeak_star);
    }
out:
    free(rows);
    free(prof);
    return st;
}

#define SENS_ROWS 65 /* deta step 0.0005 over [-0.016, 0.016] */

static rpiv_status run_sensitivity(job *j)
{
    rpiv_optics_sens_row rows[SENS_ROWS];
    char path[RPIV_PATH_MAX];
    double cut;
    rpiv_laser l = j->c.exp.laser;
    l.beta1_deg = j->sens_beta1;
    rpiv_status st =
        rpiv_optics_sensitivity(&l, &j->c.exp.prism, -0.016, 0.016, SENS_ROWS, rows, &cut);
    if (st || (st = out_path(path, j->dir, "raytrace_sensitivity.txt")) ||
        (st = rpiv_optics_save_sensitivity(&l, &j->c.exp.prism, rows, SENS_ROWS, cut, path)))
        return st;
    if (j->png && (st = plot_sensitivity(rows, SENS_ROWS, l.beta1_deg, j->dir)))
        return st;
    printf("one ray at beta1 %g deg (%s side): deta = -0.016 gives dtheta_t/theta_t0 = %+.4f, "
           "dT/T0 = %+.4f; totally reflected for deta > %.5f\n",
           l.beta1_deg, rpiv_beta1_side_name(l.beta1_side), rows[0].dtheta_rel, rows[0].dT_rel,
           cut);
    return RPIV_OK;
}

static rpiv_status parse(job *j, int argc, char **argv, int *done)
{
    static const struct option opts[] = {CLI_COMMON_LONGOPTS,
                                         {"rays", required_argument, 0, 'n'},
                                         {"x", required_argument, 0, 'x'},
                                         {"beta1", required_argument, 0, 'b'},
                                         {"polar", required_argument, 0, 'P'},
                                         {"stations", required_argument, 0, 't'},
                                         {"dz", required_argument, 0, 'z'},
                                         {"smooth", required_argument, 0, 'm'},
                                         {"sweep", required_argument, 0, 'w'},
                                         {"sensitivity", optional_argument, 0, 'e'},
                                         {"fit", required_argument, 0, 'f'},
                                         {"out", required_argument, 0, 'o'},
                                         {"png", no_argument, 0, 'g'},
                                         {0, 0, 0, 0}};
    rpiv_status st = RPIV_OK;
    long v;
    int o;
    optind = 1;
    while ((o = getopt_long(argc, argv, ":" CLI_COMMON_SHORTOPTS, opts, NULL)) != -1) {
        if (cli_common_opt(&j->c, o, optarg, &st)) {
            if (st)
                return st;
            continue;
        }
        switch (o) {
        case 'h':
            help();
            *done = 1;
            return RPIV_OK;
        case 'n':
            st = cli_parse_int("--rays", optarg, 1, 100000000L, &v);
            j->c.exp.laser.nrays = v;
            break;
        case 'x':
            st = cli_parse_double("--x", optarg, -1e6, 1e6, &j->x);
            break;
        case 'b':
            st = cli_parse_double("--beta1", optarg, -45, 45, &j->c.exp.laser.beta1_deg);
            break;
        case 'P':
            st = rpiv_config_set(&j->c.exp, "laser", "polarisation", optarg, "--polar");
            break;
        case 't':
            free(j->stations);
            j->stations = NULL;
            st = parse_range("--stations", optarg, NULL, &j->stations, &j->nst);
            break;
        case 'z':
            st = cli_parse_double("--dz", optarg, 1e-5, 0.5, &j->o.dz_star);
            break;
        case 'm':
            st = cli_parse_double("--smooth", optarg, 0, 1, &j->o.smooth_star);
            break;
        case 'w':
            free(j->sweep);
            j->sweep = NULL;
            st = parse_range("--sweep", optarg, "beta1", &j->sweep, &j->nsweep);
            break;
        case 'e':
            j->sensitivity = 1;
            if (optarg)
                st = cli_parse_double("--sensitivity", optarg, -45, 45, &j->sens_beta1);
            break;
        case 'f':
            j->fit = optarg;
            break;
        case 'o':
            j->dir = optarg;
            break;
        case 'g':
            j->png = 1;
            break;
        default:
            return cli_bad_option("raytrace", o, argv);
        }
        if (st)
            return st;
    }
    if (optind < argc)
        return cli_usage_error("raytrace", "unexpected argument '%s'", argv[optind]);
    if (!j->dir)
        j->dir = j->c.exp.output.dir;
    if (!j->stations && (st = parse_range("--stations", "1:9:0.5", NULL, &j->stations, &j->nst)))
        return st;
    return RPIV_OK;
}

rpiv_status cmd_raytrace(int argc, char **argv)
{
    job j;
    memset(&j, 0, sizeof j);
    cli_ctx_init(&j.c);
    j.x = 4.455;
    j.sens_beta1 = 1.5;
    j.o = rpiv_optics_opts_default();
    int done = 0;
    rpiv_status st = parse(&j, argc, argv, &done);
    if (st || done)
        goto out;
    j.o.threads = j.c.threads;
    if ((st = rpiv_experiment_check(&j.c.exp)) || (st = rpiv_optics_opts_check(&j.o)))
        goto out;
    if ((st = cli_mkdirs(j.dir)))
        goto out;
    cli_catch_signals();
    cli_progress pr;
    /* progress only when it is worth a line: a few million rays in all */
    double work = (double)j.c.exp.laser.nrays * (1.0 + (double)j.nsweep);
    cli_progress_init(&pr, "raytrace", j.c.quiet);
    rpiv_progress prog = cli_progress_of(&pr);
    const rpiv_progress *pp = work >= 2e6 ? &prog : NULL;
    if ((st = run_trace(&j, pp)))
        goto out;
    cli_progress_init(&pr, "raytrace sweep", j.c.quiet);
    if (j.nsweep && (st = run_sweep(&j, pp)))
        goto out;
    if (j.sensitivity && (st = run_sensitivity(&j)))
        goto out;
    if (!j.c.quiet)
        printf("tables%s in %s/ (raytrace_*)\n", j.png ? " and plots" : "", j.dir);
out:
    free(j.stations);
    free(j.sweep);
    return st;
}
