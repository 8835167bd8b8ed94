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
#include <stdio.h>

/* A subcommand: argv[0] is the command name. Returns a status; RPIV_EINVAL / RPIV_ECONFIG map
 * to exit code 2 (usage), other failures to 1. */
typedef rpiv_status (*cli_run_fn)(int argc, char **argv);

/* State every command has. */
typedef struct cli_ctx {
    rpiv_experiment exp; /* starts from rpiv_experiment_default() */
    int quiet;
    int threads;        /* 0 = default */
    const char *config; /* --config path or NULL */
} cli_ctx;

void cli_ctx_init(cli_ctx *c);

/* ---- option tables ------------------------------------------------------------------------
 * Each subcommand describes its options in one table of cli_opt rows (as config.c describes
 * the configuration keys): getopt_long's option array, the parsing of each value, the option
 * list of `rpiv CMD --help` and `rpiv --list-options` (which the CTest cli_help_docs checks
 * against --help and docs/rpiv.1) are all made from it, so they cannot drift apart. */

typedef enum cli_kind {
    CLI_FLAG,   /* int at off = 1                                                          */
    CLI_STR,    /* const char * at off = the argument                                       */
    CLI_DOUBLE, /* double at off, a number in min..max (cli_parse_double's message)         */
    CLI_LONG,   /* long at off, an integer in min..max (cli_parse_int's message)            */
    CLI_KEY,    /* the configuration key section.key (rpiv_config_set's message)            */
    CLI_FN,     /* fn(obj, argument); the argument is NULL for an absent optional value      */
    CLI_HEAD    /* no option: a heading in --help (help is printed as it is)                 */
} cli_kind;

typedef struct cli_opt {
    const char *name; /* long name without "--"                                             */
    int letter;       /* short option letter, 0 for none                                    */
    cli_kind kind;
    const char *arg;  /* the value's name in --help ("DIR"); "[=DEG]": optional; NULL: none */
    const char *help; /* --help text ('\n' starts a continuation line); NULL: an alias of the
                         option of the row above (same code, listed with it)                */
    size_t off;       /* CLI_FLAG .. CLI_LONG: offset of the value in the command's struct  */
    double min, max;  /* CLI_DOUBLE, CLI_LONG: accepted range                                 */
    const char *section, *key;                     /* CLI_KEY                                */
    rpiv_status (*fn)(void *obj, const char *arg); /* CLI_FN                                 */
    unsigned scope; /* for the command's check (calib: bit m = sub-command m accepts it)    */
} cli_opt;

/* A subcommand's options and help. */
typedef struct cli_spec {
    const char *name;  /* in messages: "<name>: ..." (calib: "calib sheet")              */
    const char *usage; /* --help before the options: usage lines and description         */
    const cli_opt *opt;
    size_t nopt;
    const char *epilog; /* --help after the options (may be NULL)                          */
    void (*more)(void); /* prints more of --help after the epilog (may be NULL)            */
    int common;         /* 1: the options every command takes are accepted (and listed)    */
    /* called before a command row is applied, with the option as typed (may be NULL) */
    rpiv_status (*check)(void *obj, const cli_opt *o, const char *typed);
} cli_spec;

/* Parse argv (argv[0] is the command) against spec and the common options (into c, which may
 * be NULL when !spec->common), storing values into obj. On --help prints the help and sets
 * *done. Returns with optind at the first operand; usage errors name the option. */
RPIV_NODISCARD rpiv_status cli_parse(const cli_spec *spec, cli_ctx *c, void *obj, int argc,
                                     char **argv, int *done);
/* Print `rpiv <cmd> --help` from spec. */
void cli_help(const cli_spec *spec);
/* The options every command takes, for `rpiv --help`. */
void cli_help_common(FILE *fp);
/* One line "<cmd> --<option>" per option spec accepts, the common ones included; and one
 * line "common --<option>" per common option. */
void cli_list_options(const cli_spec *spec);
void cli_list_common(void);

typedef struct cli_cmd {
    const char *name;
    cli_run_fn run;
    const char *summary;
    const cli_spec *spec; /* its options */
} cli_cmd;

/* Handle a common option (--config, --set, --quiet, --threads; --help is cli_parse's).
 * Returns 1 if handled (st set on error), 0 if not a common option. --config is loaded at
 * once, so later --set and flags override it. */
int cli_common_opt(cli_ctx *c, int opt, const char *arg, rpiv_status *st);

/* Apply "section.key=value". */
RPIV_NODISCARD rpiv_status cli_set(cli_ctx *c, const char *assignment);

/* Parse helpers naming the option in their message. */
RPIV_NODISCARD rpiv_status cli_parse_double(const char *opt, const char *s, double lo, double hi,
                                            double *out);
RPIV_NODISCARD rpiv_status cli_parse_int(const char *opt, const char *s, long lo, long hi,
                                         long *out);
/* "WxH", both integers in lo..hi (strtol with errno: no wrap past 2^32). */
RPIV_NODISCARD rpiv_status cli_parse_size(const char *opt, const char *s, long lo, long hi, int *w,
                                          int *h);

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

/* The options of each command (app/cmd_<name>.c). */
extern const cli_spec cmd_piv_spec, cmd_synth_spec, cmd_raytrace_spec, cmd_ccm_spec, cmd_calib_spec,
    cmd_duct_spec, cmd_compare_spec, cmd_demo_spec, cmd_config_spec, cmd_info_spec, cmd_plot_spec;

/* The command table (app/rpiv.c). */
extern const cli_cmd cli_commands[];
extern const size_t cli_ncommands;

#endif /* RPIV_APP_CLI_H */
