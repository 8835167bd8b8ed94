/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv - command-line front end: a table of subcommands, each in app/cmd_<name>.c. */
#include "cli.h"
#include "rpiv/version.h"

#include <stdio.h>
#include <string.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

rpiv_status cmd_piv(int argc, char **argv);
rpiv_status cmd_synth(int argc, char **argv);
rpiv_status cmd_raytrace(int argc, char **argv);
rpiv_status cmd_ccm(int argc, char **argv);
rpiv_status cmd_calib(int argc, char **argv);
rpiv_status cmd_duct(int argc, char **argv);
rpiv_status cmd_compare(int argc, char **argv);
rpiv_status cmd_demo(int argc, char **argv);
rpiv_status cmd_config(int argc, char **argv);
rpiv_status cmd_info(int argc, char **argv);
rpiv_status cmd_derive(int argc, char **argv);
extern const cli_spec cmd_derive_spec;
rpiv_status cmd_plot(int argc, char **argv);

const cli_cmd cli_commands[] = {
    {"piv", cmd_piv, "image pairs -> displacement fields (multi-pass, ensemble)", &cmd_piv_spec},
    {"synth", cmd_synth, "synthetic PIV image pairs with ground truth", &cmd_synth_spec},
    {"raytrace", cmd_raytrace, "trace the refracted laser sheet; profiles and metrics",
     &cmd_raytrace_spec},
    {"ccm", cmd_ccm, "cross-correlation model: bias predictions and correction", &cmd_ccm_spec},
    {"calib", cmd_calib, "light-sheet profile and depth of focus from target images",
     &cmd_calib_spec},
    {"duct", cmd_duct, "analytic square-duct velocity profile", &cmd_duct_spec},
    {"derive", cmd_derive, "vorticity, divergence, strain, swirl, Q of a vector file",
     &cmd_derive_spec},
    {"plot", cmd_plot, "the figure of a vector file: colour map, arrows, key", &cmd_plot_spec},
    {"compare", cmd_compare, "E1 error between two profiles or vector files", &cmd_compare_spec},
    {"demo", cmd_demo, "the paper's study end to end, with report and plots", &cmd_demo_spec},
    {"config", cmd_config, "print the effective configuration as an INI file", &cmd_config_spec},
    {"info", cmd_info, "describe image files: size, bit depth, pages, grey levels", &cmd_info_spec},
};
const size_t cli_ncommands = sizeof cli_commands / sizeof cli_commands[0];

static void usage(FILE *fp)
{
    fprintf(fp, "usage: rpiv COMMAND [options]\n"
                "       rpiv --help | --version | --list-options | COMMAND --help\n\n"
                "PIV through a refracted light sheet (R-PIV), after Cabut et al.\n\n"
                "commands:\n");
    for (size_t i = 0; i < cli_ncommands; i++)
        fprintf(fp, "  %-10s %s\n", cli_commands[i].name, cli_commands[i].summary);
    fprintf(fp, "\noptions every command takes:\n");
    cli_help_common(fp);
    fprintf(fp, "\nDocumentation: docs/ and 'man rpiv'.\n");
}

/* Long series load one pair of frames after another (22 MB each for the paper's camera) and
 * free them. glibc serves such blocks with mmap and returns them at free, so every pair's
 * frames were fresh pages: a page fault per 4 kB, about a quarter of an ensemble run's time.
 * Kept in the heap instead, they are reused from one pair to the next (a 4-pair ensemble:
 * 2.2 -> 1.65 s; peak RSS 202 -> 241 MB). */
static void keep_large_blocks(void)
{
#if defined(__GLIBC__) && defined(M_MMAP_THRESHOLD) && defined(M_TRIM_THRESHOLD)
    mallopt(M_MMAP_THRESHOLD, 1 << 30);
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

int main(int argc, char **argv)
{
    keep_large_blocks();
    if (argc < 2) {
        usage(stderr);
        return 2;
    }
    if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") || !strcmp(argv[1], "help")) {
        usage(stdout);
        return 0;
    }
    if (!strcmp(argv[1], "--list-options")) { /* for scripts and the CTest cli_help_docs */
        cli_list_common();
        for (size_t i = 0; i < cli_ncommands; i++)
            cli_list_options(cli_commands[i].spec);
        return 0;
    }
    if (!strcmp(argv[1], "--version")) {
        printf("rpiv %s\n", RPIV_VERSION_STRING);
        return 0;
    }
    const cli_cmd *cmd = NULL;
    for (size_t i = 0; i < cli_ncommands; i++)
        if (!strcmp(argv[1], cli_commands[i].name))
            cmd = &cli_commands[i];
    if (!cmd) {
        fprintf(stderr, "rpiv: error: unknown command '%s' (see 'rpiv --help')\n", argv[1]);
        return 2;
    }
    rpiv_init();
    cli_catch_signals();
    rpiv_status st = cmd->run(argc - 1, argv + 1);
    if (st != RPIV_OK) {
        fprintf(stderr, "rpiv: error: %s\n", *rpiv_errmsg() ? rpiv_errmsg() : rpiv_strerror(st));
        return st == RPIV_EINVAL || st == RPIV_ECONFIG ? 2 : 1;
    }
    return 0;
}
