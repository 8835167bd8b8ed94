/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv ccm - the cross-correlation model: the paper's scenarios, the Monte-Carlo convergence,
 * and the correction of the R-PIV bias (docs/ccm.md). */
#include "cli.h"
#include "rpiv/ccm.h"
#include "rpiv/report.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

rpiv_status cmd_ccm(int argc, char **argv);

typedef struct opts {
    const char *out, *profile, *presence, *input;
    double dt, zop, ystar, xstar, lambda, sigma;
    double thick[8];
    size_t nthick;
    double range[3];
    int have_range, have_zop, nomirror, symmetric, compare, measured;
    long particles, repeats, seed, coef;
    size_t nim[64], nnim;
} opts;

/* Comma-separated numbers. */
static rpiv_status parse_list(const char *opt, const char *s, double lo, double hi, double *v,
                              size_t cap, size_t *n)
{
    char buf[1024];
    if (strlen(s) >= sizeof buf)
        return rpiv_fail(RPIV_EINVAL, "%s: list too long", opt);
    strcpy(buf, s);
    *n = 0;
    for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok;
         tok = strtok_r(NULL, ",", &save)) {
        if (*n == cap)
            return rpiv_fail(RPIV_EINVAL, "%s: at most %zu values", opt, cap);
        rpiv_status st = cli_parse_double(opt, tok, lo, hi, &v[(*n)++]);
        if (st)
            return st;
    }
    if (!*n)
        return rpiv_fail(RPIV_EINVAL, "%s: empty list", opt);
    return RPIV_OK;
}

/* Everything a run needs, loaded from the options. */
typedef struct run {
    cli_ctx c;
    opts o;
    rpiv_ccm_model m;
    rpiv_ccm_params p;
    rpiv_ccm_curve *profile, *presence;
    rpiv_sheet *sheet;
    char out[RPIV_PATH_MAX];
} run;

static rpiv_status set_thickness(void *obj, const char *arg)
{
    opts *o = &((run *)obj)->o;
    return parse_list("--thickness", arg, 1e-4, 100, o->thick, 8, &o->nthick);
}

static rpiv_status set_zop(void *obj, const char *arg)
{
    opts *o = &((run *)obj)->o;
    rpiv_status st = cli_parse_double("--zop", arg, -10, 10, &o->zop);
    o->have_zop = 1;
    return st;
}

static rpiv_status set_range(void *obj, const char *arg)
{
    opts *o = &((run *)obj)->o;
    double v[3];
    size_t n;
    rpiv_status st = parse_list("--range", arg, -1e6, 1e6, v, 3, &n);
    if (st)
        return st;
    if (n != 3 || v[2] != floor(v[2]))
        return rpiv_fail(RPIV_EINVAL, "--range: expected Z0,Z1,N, got '%s'", arg);
    memcpy(o->range, v, sizeof o->range);
    o->have_range = 1;
    return RPIV_OK;
}

static rpiv_status set_nim(void *obj, const char *arg)
{
    opts *o = &((run *)obj)->o;
    double v[64];
    size_t n;
    rpiv_status st = parse_list("--nim", arg, 1, 1e7, v, 64, &n);
    if (st)
        return st;
    for (size_t k = 0; k < n; k++) {
        if (v[k] != floor(v[k]) || (k && v[k] <= v[k - 1]))
            return rpiv_fail(RPIV_EINVAL, "--nim: expected increasing integers, got '%s'", arg);
        o->nim[k] = (size_t)v[k];
    }
    o->nnim = n;
    return RPIV_OK;
}

#define OFF(field) offsetof(run, o.field)

static const cli_opt options[] = {
    {.name = "out",
     .letter = 'o',
     .kind = CLI_STR,
     .arg = "DIR",
     .off = OFF(out),
     .help = "output folder (default: [output] dir)"},
    {.name = "dt",
     .kind = CLI_DOUBLE,
     .arg = "S",
     .off = OFF(dt),
     .min = 1e-9,
     .max = 100,
     .help = "pulse separation, s (default: [synth] dt_s); sets the\n"
             "displacement scale U_b dt M / pixel"},
    {.name = "thickness",
     .kind = CLI_FN,
     .arg = "LIST",
     .fn = set_thickness,
     .help = "P-PIV sheet thicknesses e* (default 0.05,0.19)"},
    {.name = "zop",
     .kind = CLI_FN,
     .arg = "Z",
     .fn = set_zop,
     .help = "fixed object plane (default 0.5; convergence: [camera] zop)"},
    {.name = "range",
     .kind = CLI_FN,
     .arg = "Z0,Z1,N",
     .fn = set_range,
     .help = "positions z*_B or z*_max (ppiv: 0.0625,0.9375,15;\n"
             "rpiv: 0.03125,0.5,16)"},
    {.name = "no-mirror",
     .kind = CLI_FLAG,
     .off = OFF(nomirror),
     .help = "rpiv: do not extend by symmetry"},
    {.name = "ystar",
     .kind = CLI_DOUBLE,
     .arg = "Y",
     .off = OFF(ystar),
     .min = 0,
     .max = 1,
     .help = "reference profile: the duct at y* = Y (default 0.5)"},
    {.name = "profile",
     .kind = CLI_STR,
     .arg = "FILE",
     .off = OFF(profile),
     .help = "reference profile U*(z*) as two columns instead of the duct"},
    {.name = "presence",
     .kind = CLI_STR,
     .arg = "FILE",
     .off = OFF(presence),
     .help = "particle-presence law P(z*), two columns (default: [synth]\n"
             "pz_profile if set, else uniform)"},
    {.kind = CLI_HEAD, .help = "convergence:"},
    {.name = "xstar",
     .kind = CLI_DOUBLE,
     .arg = "X",
     .off = OFF(xstar),
     .min = -1e6,
     .max = 1e6,
     .help = "section of the [sheet] (default 6.5)"},
    {.name = "particles",
     .kind = CLI_LONG,
     .arg = "N",
     .off = OFF(particles),
     .min = 1,
     .max = 100000,
     .help = "particles per window (15)"},
    {.name = "repeats",
     .kind = CLI_LONG,
     .arg = "R",
     .off = OFF(repeats),
     .min = 2,
     .max = 100000,
     .help = "repetitions (20)"},
    {.name = "nim",
     .kind = CLI_FN,
     .arg = "LIST",
     .fn = set_nim,
     .help = "N_im values (1,2,3,5,7,10,15,20,30,50,70,100,150,200,300,400,500)"},
    {.name = "seed",
     .kind = CLI_LONG,
     .arg = "S",
     .off = OFF(seed),
     .min = 0,
     .max = 2147483647L,
     .help = "random seed (1)"},
    {.kind = CLI_HEAD, .help = "invert:"},
    {.name = "input",
     .kind = CLI_STR,
     .arg = "FILE",
     .off = OFF(input),
     .help = "measured R-PIV velocities: rows 'x* U* [sigma]', or a vector\n"
             "file of rpiv piv (.txt), read along the row at --ystar with\n"
             "the image placed as rpiv synth places it ([channel] fov_*)"},
    {.name = "coef",
     .kind = CLI_LONG,
     .arg = "N",
     .off = OFF(coef),
     .min = 5,
     .max = 200,
     .help = "B-spline coefficients (16)"},
    {.name = "lambda",
     .kind = CLI_DOUBLE,
     .arg = "L",
     .off = OFF(lambda),
     .min = 0,
     .max = 1e12,
     .help = "smoothness weight (1e-4)"},
    {.name = "symmetric",
     .kind = CLI_FLAG,
     .off = OFF(symmetric),
     .help = "assume U*(z*) = U*(1 - z*)"},
    {.name = "sigma",
     .kind = CLI_DOUBLE,
     .arg = "S",
     .off = OFF(sigma),
     .min = 0,
     .max = 1e6,
     .help = "measurement sigma, U* (default: from the data)"},
    {.name = "measured",
     .kind = CLI_FLAG,
     .off = OFF(measured),
     .help = "invert: fit what the engine measures (the [piv] estimator on its\n"
             "final window's plane, [bias] window_model) instead of the continuous\n"
             "peak; for measured R-PIV rows (docs/bias.md)"},
    {.name = "compare",
     .kind = CLI_FLAG,
     .off = OFF(compare),
     .help = "print E1 of the association and of the correction against\n"
             "the reference profile (--ystar / --profile)"},
};

const cli_spec cmd_ccm_spec = {
    .name = "ccm",
    .usage =
        "usage: rpiv ccm SCENARIO [options]\n\n"
        "The cross-correlation model of the paper (Eq. CCM_simp, Eq. statform): the measured\n"
        "velocity is the peak of the correlation averaged over the particles' heights.\n\n"
        "Scenarios:\n"
        "  ppiv-scan     P-PIV, object plane on the Gaussian sheet (z*_OP = z*_B), z*_B scanned\n"
        "  ppiv-fixed    P-PIV, object plane fixed (--zop), Gaussian sheet scanned\n"
        "  rpiv          R-PIV: the [sheet] of the configuration at the x* where its maximum\n"
        "                is at z*, object plane fixed (--zop), mirrored to z* > 0.5\n"
        "  convergence   Monte-Carlo sum of correlation: N particles, N_im pairs, R repeats\n"
        "  invert        reconstruct U*(z*) from R-PIV velocities along x* (--input)\n\n"
        "options:\n",
    .opt = options,
    .nopt = sizeof options / sizeof options[0],
    .epilog =
        "\nOutputs: DIR/ccm_<scenario>[_e<e*>].txt tables (x* z* U*_ref U*_model U*_subpixel\n"
        "err err_subpixel mirrored), DIR/ccm_convergence.txt, DIR/ccm_invert.txt, and PNG\n"
        "figures like the paper's 18-22 unless [output] plots = 0; a summary with E1 (Eq. E1)\n"
        "and the largest pointwise relative error on stdout.\n",
    .common = 1};

static rpiv_status run_setup(run *r)
{
    rpiv_status st;
    rpiv_experiment *e = &r->c.exp;
    if ((st = rpiv_experiment_check(e)))
        return st;
    double dt = r->o.dt > 0 ? r->o.dt : e->synth.dt_s;
    r->m = rpiv_config_ccm_model(e, dt);
    r->p = rpiv_ccm_params_default();
    r->p.subpixel = e->piv.subpixel;
    if (r->o.profile) {
        if ((st = rpiv_ccm_curve_load(r->o.profile, &r->profile)))
            return st;
        r->m.u = (rpiv_ccm_func){rpiv_ccm_curve_fn, r->profile};
        r->p.utab = 0; /* a table is cheap to evaluate, and a spline would round its kinks */
    } else {
        r->m.u = (rpiv_ccm_func){rpiv_ccm_duct_fn, &r->o.ystar};
    }
    const char *pz = r->o.presence ? r->o.presence : e->synth.pz_profile;
    if (pz && pz[0]) {
        if ((st = rpiv_ccm_curve_load(pz, &r->presence)))
            return st;
        r->m.presence = (rpiv_ccm_func){rpiv_ccm_curve_fn, r->presence};
    }
    if ((st = rpiv_sheet_new(&e->sheet, &r->sheet)))
        return st;
    const char *dir = r->o.out ? r->o.out : e->output.dir;
    if (strlen(dir) + 64 >= sizeof r->out)
        return rpiv_fail(RPIV_EINVAL, "%s: output folder path too long", dir);
    strcpy(r->out, dir);
    return cli_mkdirs(r->out);
}

static void run_free(run *r)
{
    rpiv_ccm_curve_free(r->profile);
    rpiv_ccm_curve_free(r->presence);
    rpiv_sheet_free(r->sheet);
}

static void header(const run *r, const char *scenario, char *buf, size_t n)
{
    const rpiv_camera *cam = &r->m.camera;
    char prof[RPIV_PATH_MAX + 32];
    if (r->o.profile)
        snprintf(prof, sizeof prof, "%s", r->o.profile);
    else
        snprintf(prof, sizeof prof, "duct at y* = %g", r->o.ystar);
    snprintf(n ? buf : NULL, n,
             "scenario = %s\nscale_px = %.10g (px of displacement per U_b: U_b dt M / pixel)\n"
             "camera: f = %g mm, f# = %g, M = %g, s0 = %g mm, lambda_p = %g nm, pixel = %g um\n"
             "channel h = %g mm, particle d_p = %g um\nreference profile = %s\n"
             "presence law = %s",
             scenario, r->m.scale_px, cam->focal_m * 1e3, cam->fnumber, cam->magnification,
             cam->s0_m * 1e3, cam->lambda_p_m * 1e9, rpiv_camera_pixel_m(cam) * 1e6, r->m.h_m * 1e3,
             r->m.dp_m * 1e6, prof, r->presence ? "tabulated" : "uniform");
}

static rpiv_status do_scenario(run *r, rpiv_ccm_kind kind, const char *name)
{
    rpiv_status st = RPIV_OK;
    rpiv_ccm_scenario sc = rpiv_ccm_scenario_default(kind);
    if (r->o.have_zop)
        sc.zop_star = r->o.zop;
    if (r->o.have_range) {
        sc.z0 = r->o.range[0];
        sc.z1 = r->o.range[1];
        sc.n = (size_t)r->o.range[2];
    }
    sc.symmetric = !r->o.nomirror;
    size_t nt = kind == RPIV_CCM_RPIV ? 1 : r->o.nthick, done = 0;
    rpiv_ccm_table *tabs[8] = {0};
    for (size_t k = 0; k < nt && !st; k++) {
        sc.e_star = r->o.thick[k];
        cli_progress pr;
        cli_progress_init(&pr, name, r->c.quiet);
        rpiv_progress prog = cli_progress_of(&pr);
        rpiv_ccm_table *t = NULL;
        if ((st = rpiv_ccm_scenario_run(&sc, &r->m, r->sheet, &r->p, r->c.threads, &prog, &t)))
            break;
        tabs[done++] = t;
        char path[RPIV_PATH_MAX + 64], hdr[1536], h0[1024];
        header(r, name, h0, sizeof h0);
        if (kind == RPIV_CCM_RPIV) {
            snprintf(path, sizeof path, "%s/ccm_%s.txt", r->out, name);
            snprintf(hdr, sizeof hdr, "%s\nz*_OP = %g\nsheet = [sheet] of the configuration", h0,
                     sc.zop_star);
        } else {
            snprintf(path, sizeof path, "%s/ccm_%s_e%g.txt", r->out, name, sc.e_star);
            snprintf(hdr, sizeof hdr, "%s\ne* = %g\nz*_OP = %s", h0, sc.e_star,
                     kind == RPIV_CCM_PPIV_SCAN ? "z*_B" : "fixed");
        }
        if ((st = rpiv_ccm_table_save(t, hdr, path)))
            break;
        size_t worst = rpiv_ccm_table_worst(t);
        printf("%s", name);
        if (kind != RPIV_CCM_RPIV)
            printf(" e*=%g", sc.e_star);
        printf(": E1 = %.4f %%, max |err| = %.4f %% at z* = %.5g (sub-pixel estimator: E1 "
               "%.4f %%, max %.4f %%) -> %s\n",
               100 * t->e1, 100 * t->maxerr, t->row[worst].zstar, 100 * t->e1_sub,
               100 * t->maxerr_sub, path);
    }
    if (!st && r->c.exp.output.plots)
        st = rpiv_report_ccm_tables(r->out, name, tabs, kind == RPIV_CCM_RPIV ? NULL : r->o.thick,
                                    done);
    for (size_t k = 0; k < done; k++)
        rpiv_ccm_table_free(tabs[k]);
    return st;
}

static rpiv_status do_convergence(run *r)
{
    rpiv_ccm_mc_params mc = rpiv_ccm_mc_params_default();
    if (r->o.particles)
        mc.nparticles = (size_t)r->o.particles;
    if (r->o.repeats)
        mc.repeats = (size_t)r->o.repeats;
    if (r->o.nnim) {
        mc.nnim = r->o.nnim;
        memcpy(mc.nim, r->o.nim, r->o.nnim * sizeof *mc.nim);
    }
    mc.seed = (unsigned long)r->o.seed;
    mc.threads = r->c.threads;
    rpiv_ccm_sheet_at at = {r->sheet, r->o.xstar};
    r->m.illum = (rpiv_ccm_func){rpiv_ccm_sheet_fn, &at};
    if (r->o.have_zop)
        r->m.camera.zop_star = r->o.zop;
    rpiv_ccm_work *w = NULL;
    rpiv_ccm_mc_result *res = NULL;
    rpiv_ccm_peak pk;
    rpiv_status st = rpiv_ccm_work_new(&r->p, &w);
    if (st || (st = rpiv_ccm_predict(&r->m, w, &pk)))
        goto out_free;
    cli_progress pr;
    cli_progress_init(&pr, "convergence", r->c.quiet);
    rpiv_progress prog = cli_progress_of(&pr);
    if ((st = rpiv_ccm_mc_run(&r->m, &r->p, &mc, &prog, &res)))
        goto out_free;
    char path[RPIV_PATH_MAX + 64], hdr[1536], h0[1024];
    header(r, "convergence", h0, sizeof h0);
    snprintf(hdr, sizeof hdr, "%s\nx* = %g, z*_OP = %g, N = %zu particles, seed = %lu", h0,
             r->o.xstar, r->m.camera.zop_star, mc.nparticles, mc.seed);
    snprintf(path, sizeof path, "%s/ccm_convergence.txt", r->out);
    if ((st = rpiv_ccm_mc_save(res, r->m.scale_px, pk.dx, pk.dx_sub, hdr, path)))
        goto out_free;
    if (r->c.exp.output.plots &&
        (st = rpiv_report_ccm_convergence(r->out, res, r->m.scale_px, pk.dx)))
        goto out_free;
    size_t k = res->nnim - 1;
    printf("convergence: integral U* = %.6f; N_im = %zu: mean %.6f std %.6f (sub-pixel %.6f "
           "std %.6f); N_im = %zu: std %.6f -> %s\n",
           pk.dx / r->m.scale_px, res->nim[k], res->mean[k] / r->m.scale_px,
           res->std[k] / r->m.scale_px, res->mean_sub[k] / r->m.scale_px,
           res->std_sub[k] / r->m.scale_px, res->nim[0], res->std[0] / r->m.scale_px, path);
out_free:
    rpiv_ccm_mc_free(res);
    rpiv_ccm_work_free(w);
    return st;
}

static rpiv_status do_invert(run *r)
{
    if (!r->o.input)
        return cli_usage_error("ccm", "invert needs --input FILE");
    rpiv_ccm_curve *in = NULL;
    rpiv_ccm_invert_result *res = NULL;
    rpiv_status st =
        rpiv_config_ccm_measurements(&r->c.exp, r->o.input, r->m.scale_px, r->o.ystar, &in);
    if (st)
        return st;
    rpiv_ccm_invert_params ip = rpiv_ccm_invert_params_default();
    if (r->o.coef)
        ip.ncoef = (size_t)r->o.coef;
    if (r->o.lambda >= 0)
        ip.lambda = r->o.lambda;
    ip.symmetric = r->o.symmetric;
    ip.measured = r->o.measured;
    ip.sigma = r->o.sigma;
    if (r->o.have_zop)
        r->m.camera.zop_star = r->o.zop;
    cli_progress pr;
    cli_progress_init(&pr, "invert", r->c.quiet);
    rpiv_progress prog = cli_progress_of(&pr);
    if ((st =
             rpiv_ccm_invert(&r->m, r->sheet, in->x, in->y, in->w, in->n, &ip, &r->p, &prog, &res)))
        goto out_free;
    char path[RPIV_PATH_MAX + 64], hdr[1536], h0[1024];
    header(r, "invert", h0, sizeof h0);
    snprintf(hdr, sizeof hdr,
             "%s\ninput = %s\nz*_OP = %g, B-spline coefficients = %zu, lambda = %g, "
             "symmetric = %d, measured = %d",
             h0, r->o.input, r->m.camera.zop_star, ip.ncoef, ip.lambda, ip.symmetric, ip.measured);
    snprintf(path, sizeof path, "%s/ccm_invert.txt", r->out);
    if ((st = rpiv_ccm_invert_save(res, hdr, path)))
        goto out_free;
    if (r->c.exp.output.plots &&
        (st = rpiv_report_ccm_invert(r->out, res, r->o.compare ? &r->m.u : NULL)))
        goto out_free;
    printf("invert: %zu measurements, %zu iterations, sigma %.5g, chi2 %.5g -> %s\n", res->nmeas,
           res->iterations, res->sigma, res->chi2, path);
    if (r->o.compare) {
        double ea, ec;
        if ((st = rpiv_ccm_invert_e1(res, r->m.u, 1, &ea, &ec)))
            goto out_free;
        printf("invert: E1 against the reference: association (U at z*_max) %.4f %%, "
               "corrected %.4f %%\n",
               100 * ea, 100 * ec);
    }
out_free:
    rpiv_ccm_invert_free(res);
    rpiv_ccm_curve_free(in);
    return st;
}

rpiv_status cmd_ccm(int argc, char **argv)
{
    run *r = calloc(1, sizeof *r);
    if (!r)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
    cli_ctx_init(&r->c);
    opts *o = &r->o;
    o->ystar = 0.5;
    o->xstar = 6.5;
    o->lambda = -1;
    o->seed = 1;
    o->thick[0] = 0.05;
    o->thick[1] = 0.19;
    o->nthick = 2;
    int done;
    rpiv_status st = cli_parse(&cmd_ccm_spec, &r->c, r, argc, argv, &done);
    if (st || done)
        goto out_free;
    if (optind != argc - 1) {
        st = optind >= argc ? cli_usage_error("ccm", "missing SCENARIO")
                            : cli_usage_error("ccm", "unexpected argument '%s'", argv[optind + 1]);
        goto out_free;
    }
    static const char *const names[] = {"ppiv-scan", "ppiv-fixed", "rpiv", "convergence", "invert"};
    const char *sc = argv[optind];
    int which = -1;
    for (int k = 0; k < 5; k++)
        if (!strcmp(sc, names[k]))
            which = k;
    if (which < 0) {
        st = cli_usage_error("ccm", "unknown scenario '%s'", sc);
        goto out_free;
    }
    cli_catch_signals();
    if ((st = run_setup(r)))
        goto out_cleanup;
    switch (which) {
    case 0:
        st = do_scenario(r, RPIV_CCM_PPIV_SCAN, sc);
        break;
    case 1:
        st = do_scenario(r, RPIV_CCM_PPIV_FIXED, sc);
        break;
    case 2:
        st = do_scenario(r, RPIV_CCM_RPIV, sc);
        break;
    case 3:
        st = do_convergence(r);
        break;
    default:
        st = do_invert(r);
        break;
    }
out_cleanup:
    run_free(r);
out_free:
    free(r);
    return st;
}
