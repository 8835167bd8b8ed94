/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv demo - the paper's R-PIV study end to end on synthetic images, with report and plots
 * (the library's rpiv_demo_run; this file only reads options and shows progress). */
#include "cli.h"

#include "rpiv/demo.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

rpiv_status cmd_demo(int argc, char **argv);

typedef struct opts {
    cli_ctx c;
    const char *dir;
    long pairs, ppairs, width;
    int quick;
} opts;

static const cli_opt options[] = {
    {.name = "out",
     .kind = CLI_STR,
     .arg = "DIR",
     .off = offsetof(opts, dir),
     .help = "output folder (output.dir)"},
    {.name = "pairs",
     .kind = CLI_LONG,
     .arg = "N",
     .off = offsetof(opts, pairs),
     .min = 1,
     .max = 1000000,
     .help = "R-PIV pairs (100; --quick: 16)"},
    {.name = "ppiv-pairs",
     .kind = CLI_LONG,
     .arg = "N",
     .off = offsetof(opts, ppairs),
     .min = 1,
     .max = 1000000,
     .help = "pairs per P-PIV plane (12; --quick: 3)"},
    {.name = "width",
     .kind = CLI_LONG,
     .arg = "PX",
     .off = offsetof(opts, width),
     .min = 64,
     .max = 65536,
     .help = "width of the image band (the sensor's; --quick: 512)"},
    {.name = "quick",
     .kind = CLI_FLAG,
     .off = offsetof(opts, quick),
     .help = "a small run for a first look and the tests (seconds)"},
};

const cli_spec cmd_demo_spec = {
    .name = "demo",
    .usage =
        "usage: rpiv demo [--config FILE] [--set SEC.KEY=VALUE]... [--out DIR] [--pairs N]\n"
        "                 [--ppiv-pairs N] [--width PX] [--quick] [--threads N] [--quiet]\n\n"
        "Run the study of the paper (Cabut et al.) end to end on images rpiv makes from the\n"
        "experiment (the embedded default, or --config): 1. trace the refracted sheet and fit\n"
        "it; 2. the square-duct flow; 3. a P-PIV z-scan of thin sheets, the reference volume;\n"
        "4. R-PIV pairs through the refracted sheet, sum of correlation; 5. R-PIV against\n"
        "P-PIV (figs 24-25), against the CCM (figs 26-27), and the bias-corrected profile;\n"
        "6. DIR/report.md and DIR/report.html with PNG plots, DIR/data (tables, vector\n"
        "files), DIR/images (sample pairs). Progress on stderr, key figures on stdout.\n"
        "docs/demo.md gives the equivalent commands for your own images.\n\noptions:\n",
    .opt = options,
    .nopt = sizeof options / sizeof options[0],
    .common = 1};

static void log_line(void *user, const char *line)
{
    const int *quiet = user;
    if (*quiet)
        return;
    /* clear a progress bar drawn on the same terminal line */
    fprintf(stderr, "%s%s\n", isatty(STDERR_FILENO) ? "\r\033[K" : "", line);
}

static void print_pct(const char *what, double v)
{
    if (isfinite(v))
        printf("  %-58s %7.2f %%\n", what, 100 * v);
    else
        printf("  %-58s     n/a\n", what);
}

static void summary(const rpiv_demo_result *r, const char *dir)
{
    printf("rpiv demo: %s/report.md, %s/report.html (%zu plots), %.1f s on %d thread%s\n", dir, dir,
           r->nplots, r->seconds, r->threads, r->threads > 1 ? "s" : "");
    printf("  sheet: %s\n", r->sheet_traced ? "traced and fitted" : "from the configuration");
    printf("  %-58s %7.2f deg\n", "sheet inclination (paper: about 5 deg)", r->sheet_incl_deg);
    print_pct("P-PIV planes vs analytic, mean E1", r->ppiv_e1_mean);
    print_pct("P-PIV U*(z*) at y* = 0.5 vs analytic, E1 along z*", r->ppiv_e1_z);
    print_pct("R-PIV vs P-PIV at z*_max, E1 along y* (mean over x*)", r->e1_zmax);
    print_pct("R-PIV vs P-PIV at z*_inf", r->e1_zinf);
    print_pct("R-PIV vs P-PIV at z*_sup", r->e1_zsup);
    print_pct("  ... at z*_max, core columns", r->e1_zmax_core);
    print_pct("  ... at z*_max, columns near the floor", r->e1_zmax_wall);
    print_pct("R-PIV vs CCM at y* = 0.5, E1 along x*", r->e1_model);
    if (r->nconv)
        printf("  %-58s %7.2f %% -> %.2f %% (%d -> %d pairs)\n", "  ... as pairs are added",
               100 * r->conv_e1[0], 100 * r->conv_e1[r->nconv - 1], r->conv_n[0],
               r->conv_n[r->nconv - 1]);
    print_pct("bias-corrected U*(z*) vs truth (CCM inversion)", r->e1_corr);
    print_pct("  the paper's association (U at z*_max) vs truth", r->e1_assoc);
}

rpiv_status cmd_demo(int argc, char **argv)
{
    opts op = {.pairs = -1, .ppairs = -1, .width = -1};
    int done;
    rpiv_status st;
    cli_ctx_init(&op.c);
    if ((st = cli_parse(&cmd_demo_spec, &op.c, &op, argc, argv, &done)) || done)
        return st;
    cli_ctx c = op.c;
    const char *dir = op.dir;
    long pairs = op.pairs, ppairs = op.ppairs, width = op.width;
    int quick = op.quick;
    if (optind < argc)
        return cli_usage_error("demo", "unexpected argument '%s'", argv[optind]);
    rpiv_demo_params p = quick ? rpiv_demo_params_quick() : rpiv_demo_params_default();
    if (pairs > 0)
        p.rpiv_pairs = (int)pairs;
    if (ppairs > 0)
        p.ppiv_pairs = (int)ppairs;
    if (width > 0)
        p.width_px = (int)width;
    p.threads = c.threads;
    if (!dir)
        dir = c.exp.output.dir;

    cli_catch_signals();
    cli_progress pr;
    cli_progress_init(&pr, "demo", c.quiet);
    rpiv_progress prog = cli_progress_of(&pr);
    rpiv_demo_log log = {log_line, &c.quiet};
    rpiv_demo_result r;
    if ((st = rpiv_demo_run(&c.exp, &p, dir, &prog, &log, &r)))
        return st;
    summary(&r, dir);
    return RPIV_OK;
}
