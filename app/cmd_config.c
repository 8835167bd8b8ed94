/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv config - print the effective configuration (defaults, --config, --set) as INI. */
#include "cli.h"

#include <stdio.h>
#include <string.h>

rpiv_status cmd_config(int argc, char **argv);

static void help(void)
{
    printf("usage: rpiv config [--config FILE] [--set SEC.KEY=VALUE]... [--doc]\n\n"
           "Print the effective configuration as a complete INI file: the embedded default\n"
           "(the paper's channel experiment), then FILE, then each --set. Feeding the output\n"
           "back with --config reproduces the run. --doc prints the key reference (Markdown).\n");
}

rpiv_status cmd_config(int argc, char **argv)
{
    static const struct option opts[] = {
        CLI_COMMON_LONGOPTS, {"doc", no_argument, 0, 'D'}, {0, 0, 0, 0}};
    cli_ctx c;
    int doc = 0, o;
    rpiv_status st;
    cli_ctx_init(&c);
    optind = 1;
    while ((o = getopt_long(argc, argv, ":" CLI_COMMON_SHORTOPTS, opts, NULL)) != -1) {
        if (cli_common_opt(&c, o, optarg, &st)) {
            if (st)
                return st;
            continue;
        }
        if (o == 'h') {
            help();
            return RPIV_OK;
        }
        if (o == 'D') {
            doc = 1;
            continue;
        }
        return cli_bad_option("config", o, argv);
    }
    if (optind < argc)
        return cli_usage_error("config", "unexpected argument '%s'", argv[optind]);
    if (doc)
        return rpiv_config_write_doc(stdout);
    if ((st = rpiv_experiment_check(&c.exp)))
        return st;
    return rpiv_config_write(&c.exp, stdout);
}
