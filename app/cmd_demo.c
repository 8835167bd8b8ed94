/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv demo - the paper's R-PIV study end to end on synthetic images, with report and plots
 * (the library's rpiv_demo_run; this file only reads options and shows progress). */
#include "cli.h"

#include "rpiv/demo.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

rpiv_status cmd_demo(int argc, char **argv);

static void help(void)
{
    printf("usage: rpiv demo [--config FILE] [--set SEC.KEY=VALUE]... [--out DIR] [--pairs N]\n"
           "                 [--ppiv-pairs N] [--width PX] [--quick] [--threads N] [--quiet]\n\n"
           "Run the study of the paper (Cabut et al.) end to end on images rpiv makes from the\n"
           "experiment (the embedded default, or --config): 1. trace the refracted sheet and fit\n"
           "it; 2. the square-duct flow; 3. a P-PIV z-scan of thin sheets, the reference volume;\n"
           "4. R-PIV pairs through the refracted sheet, sum of correlation; 5. R-PIV against\n"
           "P-PIV (figs 24-25), against the CCM (figs 26-27), and the bias-corrected profile;\n"
           "6. DIR/report.md and DIR/report.html with PNG plots, DIR/data (tables, vector\n"
           "files), DIR/images (sample pairs). Progress on stderr, key figures on stdout.\n"
           "docs/demo.md gives the equivalent commands for your own images.\n\n"
           "  --out DIR         output folder (output.dir)\n"
           "  --pairs N         R-PIV pairs (100; --quick: 16)\n"
           "  --ppiv-pairs N    pairs per P-PIV plane (12; --quick: 3)\n"
           "  --width PX        width of the image band (the sensor's; --quick: 512)\n"
           "  --quick           a small run for a first look and the tests (seconds)\n"
           "  --threads N       OpenMP threads (0 = all cores)\n"
           "  --quiet           no progress\n");
}

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
    static const struct option opts[] = {CLI_COMMON_LONGOPTS,
                                         {"out", required_argument, 0, 'o'},
                                         {"pairs", required_argument, 0, 'n'},
                                         {"ppiv-pairs", required_argument, 0, 'p'},
                                         {"width", required_argument, 0, 'w'},
                                         {"quick", no_argument, 0, 'Q'},
                                         {0, 0, 0, 0}};
    cli_ctx c;
    cli_ctx_init(&c);
    const char *dir = NULL;
    long pairs = -1, ppairs = -1, width = -1;
    int quick = 0, o;
    rpiv_status st = RPIV_OK;
    optind = 1;
    while ((o = getopt_long(argc, argv, ":" CLI_COMMON_SHORTOPTS, opts, NULL)) != -1) {
        if (cli_common_opt(&c, o, optarg, &st)) {
            if (st)
                return st;
            continue;
        }
        switch (o) {
        case 'h':
            help();
            return RPIV_OK;
        case 'o':
            dir = optarg;
            break;
        case 'n':
            st = cli_parse_int("--pairs", optarg, 1, 1000000, &pairs);
            break;
        case 'p':
            st = cli_parse_int("--ppiv-pairs", optarg, 1, 1000000, &ppairs);
            break;
        case 'w':
            st = cli_parse_int("--width", optarg, 64, 65536, &width);
            break;
        case 'Q':
            quick = 1;
            break;
        default:
            return cli_bad_option("demo", o, argv);
        }
        if (st)
            return st;
    }
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
