/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv raytrace - the refracted laser sheet by ray tracing (optics.h; docs/optics.md). */
#include "cli.h"

#include "rpiv/optics.h"
#include "rpiv/report.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

rpiv_status cmd_raytrace(int argc, char **argv);

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

static rpiv_status set_stations(void *obj, const char *arg)
{
    job *j = obj;
    free(j->stations);
    j->stations = NULL;
    return parse_range("--stations", arg, NULL, &j->stations, &j->nst);
}

static rpiv_status set_sweep(void *obj, const char *arg)
{
    job *j = obj;
    free(j->sweep);
    j->sweep = NULL;
    return parse_range("--sweep", arg, "beta1", &j->sweep, &j->nsweep);
}

static rpiv_status set_sensitivity(void *obj, const char *arg)
{
    job *j = obj;
    j->sensitivity = 1;
    return arg ? cli_parse_double("--sensitivity", arg, -45, 45, &j->sens_beta1) : RPIV_OK;
}

static const cli_opt options[] = {
    {.name = "x",
     .kind = CLI_DOUBLE,
     .arg = "X*",
     .off = offsetof(job, x),
     .min = -1e6,
     .max = 1e6,
     .help = "station of the profile (4.455)"},
    {.name = "stations",
     .kind = CLI_FN,
     .arg = "A:B:STEP",
     .fn = set_stations,
     .help = "stations of the metrics and the fit (1:9:0.5)"},
    {.name = "rays",
     .kind = CLI_LONG,
     .arg = "N",
     .off = offsetof(job, c.exp.laser.nrays),
     .min = 1,
     .max = 100000000L,
     .help = "rays traced (laser.rays; up to 1e8)"},
    {.name = "beta1",
     .kind = CLI_DOUBLE,
     .arg = "DEG",
     .off = offsetof(job, c.exp.laser.beta1_deg),
     .min = -45,
     .max = 45,
     .help = "incidence on the inclined face (laser.beta1_deg; the side it is\n"
             "measured on is laser.beta1_side = air|pmma)"},
    {.name = "polar",
     .kind = CLI_KEY,
     .arg = "P",
     .section = "laser",
     .key = "polarisation",
     .help = "Fresnel transmission: p (paper, default), s or unpolarised"},
    {.name = "dz",
     .kind = CLI_DOUBLE,
     .arg = "DZ*",
     .off = offsetof(job, o.dz_star),
     .min = 1e-5,
     .max = 0.5,
     .help = "profile bin width in z* (0.005)"},
    {.name = "smooth",
     .kind = CLI_DOUBLE,
     .arg = "SIGMA*",
     .off = offsetof(job, o.smooth_star),
     .min = 0,
     .max = 1,
     .help = "Gaussian smoothing of the profiles, sigma in z* (0)"},
    {.name = "sweep",
     .kind = CLI_FN,
     .arg = "beta1:A:B:STEP",
     .fn = set_sweep,
     .help = "profiles, e*, It/Ig, I*_peak at x* = X for each beta1\n"
             "(raytrace_sweep.txt, raytrace_sweep_profiles.txt; figs 11-12)"},
    {.name = "sensitivity",
     .kind = CLI_FN,
     .arg = "[=DEG]",
     .fn = set_sensitivity,
     .help = "the axis ray at beta1 = DEG (1.5, paper fig. 10):\n"
             "dtheta_t/theta_t0 and dT/T0 for deta in [-0.016, 0.016] with\n"
             "eta = n_pmma / n_water (raytrace_sensitivity.txt)"},
    {.name = "fit",
     .kind = CLI_STR,
     .arg = "FILE",
     .off = offsetof(job, fit),
     .help = "self-similar sheet fitted on the stations, written as a sheet\n"
             "profile file (use with sheet.kind = selfsim, sheet.profile = FILE)"},
    {.name = "out",
     .kind = CLI_STR,
     .arg = "DIR",
     .off = offsetof(job, dir),
     .help = "output folder (output.dir)"},
    {.name = "png",
     .kind = CLI_FLAG,
     .off = offsetof(job, png),
     .help = "also write PNG plots (raytrace_*.png; the sheet map\n"
             "raytrace_map.png traces 200 more stations)"},
};

const cli_spec cmd_raytrace_spec = {
    .name = "raytrace",
    .usage =
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
        "and print the power bookkeeping, the sheet's inclination and thickness growth.\n\n"
        "options:\n",
    .opt = options,
    .nopt = sizeof options / sizeof options[0],
    .epilog = "\nSee docs/optics.md for the geometry and every modelling choice.\n",
    .common = 1};

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
               f->nused, j->nst, f->zm0, f->zm1, rpiv_sheet_incl_deg(f->zm1), f->rms_zm, f->e0,
               f->e1, f->e1, f->rms_e, f->rms_shape);
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
    if (j->png &&
        ((st = rpiv_report_optics_profile(r, j->dir)) ||
         (st = rpiv_report_optics_metrics_plot(&view, f, j->dir)) ||
         (st = rpiv_report_optics_map(&j->c.exp.laser, &j->c.exp.prism, j->c.exp.channel.h_m,
                                      j->stations[j->nst - 1], &j->o, j->dir))))
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
    if (j->png && (st = rpiv_report_optics_sweep(rows, j->nsweep, prof, nz, j->x, j->dir)))
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
    if (j->png && (st = rpiv_report_optics_sensitivity(rows, SENS_ROWS, l.beta1_deg, j->dir)))
        return st;
    printf("one ray at beta1 %g deg (%s side): deta = -0.016 gives dtheta_t/theta_t0 = %+.4f, "
           "dT/T0 = %+.4f; totally reflected for deta > %.5f\n",
           l.beta1_deg, rpiv_beta1_side_name(l.beta1_side), rows[0].dtheta_rel, rows[0].dT_rel,
           cut);
    return RPIV_OK;
}

static rpiv_status parse(job *j, int argc, char **argv, int *done)
{
    rpiv_status st = cli_parse(&cmd_raytrace_spec, &j->c, j, argc, argv, done);
    if (st || *done)
        return st;
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
