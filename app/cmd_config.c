/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv config - print the effective configuration (defaults, --config, --set) as INI. */
#include "cli.h"

#include <stddef.h>
#include <stdio.h>

rpiv_status cmd_config(int argc, char **argv);

typedef struct opts {
    cli_ctx c;
    int doc;
} opts;

static const cli_opt options[] = {
    {.name = "doc",
     .kind = CLI_FLAG,
     .off = offsetof(opts, doc),
     .help = "print the key reference (Markdown) instead"},
};

const cli_spec cmd_config_spec = {
    .name = "config",
    .usage = "usage: rpiv config [--config FILE] [--set SEC.KEY=VALUE]... [--doc]\n\n"
             "Print the effective configuration as a complete INI file: the embedded default\n"
             "(the paper's channel experiment), then FILE, then each --set. Feeding the output\n"
             "back with --config reproduces the run.\n\noptions:\n",
    .opt = options,
    .nopt = sizeof options / sizeof options[0],
    .common = 1};

rpiv_status cmd_config(int argc, char **argv)
{
    opts o = {0};
    int done;
    rpiv_status st;
    cli_ctx_init(&o.c);
    if ((st = cli_parse(&cmd_config_spec, &o.c, &o, argc, argv, &done)) || done)
        return st;
    if (optind < argc)
        return cli_usage_error("config", "unexpected argument '%s'", argv[optind]);
    if (o.doc)
        return rpiv_config_write_doc(stdout);
    if ((st = rpiv_experiment_check(&o.c.exp)))
        return st;
    return rpiv_config_write(&o.c.exp, stdout);
}
