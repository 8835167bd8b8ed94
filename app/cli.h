/* SPDX-License-Identifier: GPL-3.0-or-later */
/* app/cli.h - what the subcommands share: the experiment with its config file and overrides,
 * common options, progress on stderr, and the subcommand signature. No algorithm lives here. */
#ifndef RPIV_APP_CLI_H
#define RPIV_APP_CLI_H

#include "rpiv/config.h"
#include "rpiv/error.h"
#include "rpiv/progress.h"

#include <getopt.h>
#include <stddef.h>

/* A subcommand: argv[0] is the command name. Returns a status; RPIV_EINVAL / RPIV_ECONFIG map
 * to exit code 2 (usage), other failures to 1. */
typedef rpiv_status (*cli_run_fn)(int argc, char **argv);

typedef struct cli_cmd {
    const char *name;
    cli_run_fn run;
    const char *summary;
} cli_cmd;

/* State every command has. */
typedef struct cli_ctx {
    rpiv_experiment exp; /* starts from rpiv_experiment_default() */
    int quiet;
    int threads;        /* 0 = default */
    const char *config; /* --config path or NULL */
} cli_ctx;

void cli_ctx_init(cli_ctx *c);

/* Long options shared by all commands (--config, --set, --quiet, --threads, --help). Commands
 * append their own after these; see cli_options_merge. */
#define CLI_COMMON_LONGOPTS                                                                        \
    {"config", required_argument, 0, 'c'}, {"set", required_argument, 0, 'S'},                     \
        {"quiet", no_argument, 0, 'q'}, {"threads", required_argument, 0, 'j'},                    \
    {                                                                                              \
        "help", no_argument, 0, 'h'                                                                \
    }
#define CLI_COMMON_SHORTOPTS "c:S:qj:h"

/* Handle a common option. Returns 1 if handled (st set on error), 0 if not a common option.
 * --config is loaded at once, so later --set and flags override it. */
int cli_common_opt(cli_ctx *c, int opt, const char *arg, rpiv_status *st);

/* Apply "section.key=value". */
RPIV_NODISCARD rpiv_status cli_set(cli_ctx *c, const char *assignment);

/* Parse helpers naming the option in their message. */
RPIV_NODISCARD rpiv_status cli_parse_double(const char *opt, const char *s, double lo, double hi,
                                            double *out);
RPIV_NODISCARD rpiv_status cli_parse_int(const char *opt, const char *s, long lo, long hi,
                                         long *out);

/* Usage error: message "<cmd>: <text>" and RPIV_EINVAL. */
rpiv_status cli_usage_error(const char *cmd, const char *fmt, ...) RPIV_PRINTF(2, 3);

/* The usage error for what getopt_long returned as o ('?' or ':'; option strings start with
 * ':' so that a known option without its value gives ':'): "option '--x' needs a value" or
 * "unknown option '--x'". */
rpiv_status cli_bad_option(const char *cmd, int o, char **argv);

/* Progress on stderr: a bar with count, rate and ETA on a terminal, a line every ~10 %
 * otherwise, from one second into the run; nothing when quiet. Also the cancellation point for
 * SIGINT/SIGTERM. */
typedef struct cli_progress {
    const char *label;
    int quiet, tty;
    double t0;
    double delay; /* seconds before anything is printed (1; env RPIV_PROGRESS_DELAY) */
    int last_decile;
} cli_progress;
void cli_progress_init(cli_progress *p, const char *label, int quiet);
int cli_progress_fn(void *user, size_t done, size_t total); /* an rpiv_progress_fn */
rpiv_progress cli_progress_of(cli_progress *p);

/* Install SIGINT/SIGTERM handlers that set a flag; cli_progress_fn then asks to stop. */
void cli_catch_signals(void);
int cli_interrupted(void);

/* Make a directory and its parents (mkdir -p); error names the path. */
RPIV_NODISCARD rpiv_status cli_mkdirs(const char *path);

/* The command table (app/rpiv.c). */
extern const cli_cmd cli_commands[];
extern const size_t cli_ncommands;

#endif /* RPIV_APP_CLI_H */
