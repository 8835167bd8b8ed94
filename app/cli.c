/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "cli.h"

#include <getopt.h>

#include <assert.h>
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <omp.h>

void cli_ctx_init(cli_ctx *c)
{
    memset(c, 0, sizeof *c);
    opterr = 0; /* errors are reported by the commands, on one line */
    optind = 1;
    c->exp = rpiv_experiment_default();
}

rpiv_status cli_usage_error(const char *cmd, const char *fmt, ...)
{
    char buf[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    return rpiv_fail(RPIV_EINVAL, "%s: %s (see 'rpiv %s --help')", cmd, buf, cmd);
}

rpiv_status cli_bad_option(const char *cmd, int o, char **argv)
{
    const char *arg = argv[optind - 1];
    if (o == ':')
        return cli_usage_error(cmd, "option '%s' needs a value", arg);
    if (optopt && strncmp(arg, "--", 2) != 0)
        return cli_usage_error(cmd, "unknown option '-%c'", optopt);
    return cli_usage_error(cmd, "unknown option '%s'", arg);
}

rpiv_status cli_parse_double(const char *opt, const char *s, double lo, double hi, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || *end || errno || !isfinite(v))
        return rpiv_fail(RPIV_EINVAL, "%s: '%s' is not a number", opt, s);
    if (v < lo || v > hi)
        return rpiv_fail(RPIV_EINVAL, "%s: %g outside the accepted range %g..%g", opt, v, lo, hi);
    *out = v;
    return RPIV_OK;
}

rpiv_status cli_parse_int(const char *opt, const char *s, long lo, long hi, long *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (end == s || *end || errno)
        return rpiv_fail(RPIV_EINVAL, "%s: '%s' is not an integer", opt, s);
    if (v < lo || v > hi)
        return rpiv_fail(RPIV_EINVAL, "%s: %ld outside the accepted range %ld..%ld", opt, v, lo,
                         hi);
    *out = v;
    return RPIV_OK;
}

rpiv_status cli_parse_size(const char *opt, const char *s, long lo, long hi, int *w, int *h)
{
    char *end, *end2;
    errno = 0;
    long a = strtol(s, &end, 10), b = 0;
    int ok = end != s && (*end == 'x' || *end == 'X') && !errno;
    if (ok) {
        b = strtol(end + 1, &end2, 10);
        ok = end2 != end + 1 && !*end2 && !errno;
    }
    if (!ok)
        return rpiv_fail(RPIV_EINVAL, "%s: '%s' is not WxH", opt, s);
    if (a < lo || a > hi || b < lo || b > hi)
        return rpiv_fail(RPIV_EINVAL, "%s: '%s' outside the accepted range %ld..%ld px per side",
                         opt, s, lo, hi);
    *w = (int)a;
    *h = (int)b;
    return RPIV_OK;
}

rpiv_status cli_set(cli_ctx *c, const char *assignment)
{
    char buf[1024];
    if (strlen(assignment) >= sizeof buf)
        return rpiv_fail(RPIV_EINVAL, "--set: assignment too long");
    strcpy(buf, assignment);
    char *eq = strchr(buf, '='), *dot = strchr(buf, '.');
    if (!eq || !dot || dot > eq)
        return rpiv_fail(RPIV_EINVAL, "--set: '%s' is not of the form section.key=value",
                         assignment);
    *eq = '\0';
    *dot = '\0';
    return rpiv_config_set(&c->exp, buf, dot + 1, eq + 1, "--set");
}

int cli_common_opt(cli_ctx *c, int opt, const char *arg, rpiv_status *st)
{
    long v;
    *st = RPIV_OK;
    switch (opt) {
    case 'c':
        c->config = arg;
        *st = rpiv_config_load(arg, &c->exp);
        return 1;
    case 'S':
        *st = cli_set(c, arg);
        return 1;
    case 'q':
        c->quiet = 1;
        return 1;
    case 'j':
        *st = cli_parse_int("--threads", arg, 0, 1024, &v);
        if (*st == RPIV_OK) {
            c->threads = (int)v;
            c->exp.piv.threads = (int)v;
            if (v > 0)
                omp_set_num_threads((int)v);
        }
        return 1;
    default:
        return 0;
    }
}

/* ---- signals ------------------------------------------------------------------------------ */

static volatile sig_atomic_t got_signal;

static void on_signal(int sig)
{
    got_signal = sig;
}

void cli_catch_signals(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGHUP, &sa, NULL); /* a closed terminal or session: stop as for SIGTERM */
}

int cli_interrupted(void)
{
    return got_signal != 0;
}

/* ---- progress ----------------------------------------------------------------------------- */

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void cli_progress_init(cli_progress *p, const char *label, int quiet)
{
    p->label = label;
    p->quiet = quiet;
    p->tty = isatty(STDERR_FILENO);
    p->t0 = now_s();
    p->last_decile = -1;
    /* RPIV_PROGRESS_DELAY (seconds, default 1) lets a user or a test see progress at once */
    const char *d = getenv("RPIV_PROGRESS_DELAY");
    p->delay = d ? atof(d) : 1.0;
}

int cli_progress_fn(void *user, size_t done, size_t total)
{
    cli_progress *p = user;
    double el = now_s() - p->t0;
    /* nothing for the first second: a short run (or one failing at once) prints no progress */
    if (!p->quiet && total > 0 && el >= p->delay) {
        double rate = (double)done / el;
        double eta = rate > 0 ? (double)(total - done) / rate : 0;
        if (p->tty) {
            int width = 30, fill = (int)((double)width * (double)done / (double)total);
            fprintf(stderr, "\r%s [%.*s%*s] %zu/%zu %.1f/s ETA %.0fs ", p->label, fill,
                    "##############################", width - fill, "", done, total, rate, eta);
            if (done == total)
                fputc('\n', stderr);
        } else {
            int dec = (int)(10 * done / total);
            if (dec != p->last_decile) {
                p->last_decile = dec;
                fprintf(stderr, "%s: %zu/%zu (%d%%) %.1f/s ETA %.0fs\n", p->label, done, total,
                        (int)(100 * done / total), rate, eta);
            }
        }
    }
    return cli_interrupted();
}

rpiv_progress cli_progress_of(cli_progress *p)
{
    return (rpiv_progress){.fn = cli_progress_fn, .user = p};
}

rpiv_status cli_mkdirs(const char *path)
{
    char buf[RPIV_PATH_MAX];
    if (strlen(path) >= sizeof buf)
        return rpiv_fail(RPIV_EINVAL, "%s: path too long", path);
    strcpy(buf, path);
    for (char *s = buf + 1;; s++) {
        if (*s == '/' || *s == '\0') {
            char keep = *s;
            *s = '\0';
            if (mkdir(buf, 0777) != 0 && errno != EEXIST)
                return rpiv_fail(RPIV_EIO, "%s: cannot create directory: %s", buf, strerror(errno));
            *s = keep;
            if (!keep)
                break;
        }
    }
    struct stat stt;
    if (stat(path, &stt) != 0 || !S_ISDIR(stt.st_mode))
        return rpiv_fail(RPIV_EIO, "%s: not a directory", path);
    return RPIV_OK;
}

/* ---- option tables ------------------------------------------------------------------------ */

static const cli_opt common_opt[] = {
    {.name = "config",
     .letter = 'c',
     .arg = "FILE",
     .help = "read the experiment from an INI file"},
    {.name = "set",
     .letter = 'S',
     .arg = "SEC.KEY=VALUE",
     .help = "override one configuration key (repeatable)"},
    {.name = "threads", .letter = 'j', .arg = "N", .help = "OpenMP threads (0 = all cores)"},
    {.name = "quiet", .letter = 'q', .help = "no progress on stderr"},
    {.name = "help", .letter = 'h', .help = "this text"},
};
enum { NCOMMON = sizeof common_opt / sizeof common_opt[0] };

/* The getopt code of row k: its letter, or 256 + the index of the row it is an alias of. */
static int opt_code(const cli_spec *spec, size_t k)
{
    while (k > 0 && !spec->opt[k].help)
        k--;
    return spec->opt[k].letter ? spec->opt[k].letter : 256 + (int)k;
}

static int has_value(const cli_opt *o)
{
    return o->arg ? (o->arg[0] == '[' ? optional_argument : required_argument) : no_argument;
}

/* Apply row o (the option given as `typed`) with argument arg. */
static rpiv_status apply(const cli_opt *o, cli_ctx *c, void *obj, const char *arg)
{
    char name[64];
    char *at = (char *)obj + o->off;
    long v;
    rpiv_status st;
    snprintf(name, sizeof name, "--%s", o->name);
    switch (o->kind) {
    case CLI_FLAG:
        *(int *)at = 1;
        return RPIV_OK;
    case CLI_STR:
        *(const char **)at = arg;
        return RPIV_OK;
    case CLI_DOUBLE:
        return cli_parse_double(name, arg, o->min, o->max, (double *)at);
    case CLI_LONG:
        if ((st = cli_parse_int(name, arg, (long)o->min, (long)o->max, &v)))
            return st;
        *(long *)at = v;
        return RPIV_OK;
    case CLI_KEY:
        return rpiv_config_set(&c->exp, o->section, o->key, arg, name);
    case CLI_FN:
        return o->fn(obj, arg);
    case CLI_HEAD:
        break;
    }
    return RPIV_OK;
}

rpiv_status cli_parse(const cli_spec *spec, cli_ctx *c, void *obj, int argc, char **argv, int *done)
{
    struct option lo[NCOMMON + 64 + 1];
    char so[2 * (NCOMMON + 64) + 2] = ":";
    size_t nl = 0, ns = 1;
    assert(spec->nopt <= 64);
    for (size_t k = 0; k < NCOMMON; k++) {
        const cli_opt *o = &common_opt[k];
        if (!spec->common && o->letter != 'h')
            continue;
        lo[nl++] = (struct option){o->name, has_value(o), NULL, o->letter};
        so[ns++] = (char)o->letter;
        if (o->arg)
            so[ns++] = ':';
    }
    for (size_t k = 0; k < spec->nopt; k++) {
        const cli_opt *o = &spec->opt[k];
        if (o->kind == CLI_HEAD)
            continue;
        lo[nl++] = (struct option){o->name, has_value(o), NULL, opt_code(spec, k)};
        if (o->letter) {
            so[ns++] = (char)o->letter;
            if (o->arg)
                so[ns++] = ':';
        }
    }
    lo[nl] = (struct option){NULL, 0, NULL, 0};
    so[ns] = '\0';
    *done = 0;
    optind = 1;
    opterr = 0;
    int code;
    rpiv_status st = RPIV_OK;
    while ((code = getopt_long(argc, argv, so, lo, NULL)) != -1) {
        if (spec->common && cli_common_opt(c, code, optarg, &st)) {
            if (st)
                return st;
            continue;
        }
        if (code == 'h') {
            cli_help(spec);
            *done = 1;
            return RPIV_OK;
        }
        if (code == '?' || code == ':')
            return cli_bad_option(spec->name, code, argv);
        size_t k = 0;
        while (k < spec->nopt &&
               (spec->opt[k].kind == CLI_HEAD || !spec->opt[k].help || opt_code(spec, k) != code))
            k++;
        if (k == spec->nopt) /* not reached: every code comes from the table */
            return cli_usage_error(spec->name, "unknown option '%s'", argv[optind - 1]);
        if (spec->check && (st = spec->check(obj, &spec->opt[k], argv[optind - 1])))
            return st;
        if ((st = apply(&spec->opt[k], c, obj, optarg)))
            return st;
    }
    return RPIV_OK;
}

/* "  -o, --out, --dir DIR" for row k and the aliases after it; returns the next row. */
static size_t left_column(const cli_opt *opt, size_t n, size_t k, char *buf, size_t size)
{
    const cli_opt *o = &opt[k];
    int at = snprintf(buf, size, "  %c%c%s--%s", o->letter ? '-' : ' ', o->letter ? o->letter : ' ',
                      o->letter ? ", " : "  ", o->name);
    size_t next = k + 1;
    for (; next < n && !opt[next].help && opt[next].kind != CLI_HEAD; next++)
        at += snprintf(buf + at, size - (size_t)at, ", --%s", opt[next].name);
    if (o->arg)
        snprintf(buf + at, size - (size_t)at, "%s%s", o->arg[0] == '[' ? "" : " ", o->arg);
    return next;
}

enum { HELP_COL = 26 };

static void print_rows(FILE *fp, const cli_opt *opt, size_t n)
{
    for (size_t k = 0; k < n;) {
        if (opt[k].kind == CLI_HEAD) {
            fprintf(fp, "%s\n", opt[k].help);
            k++;
            continue;
        }
        char left[160];
        size_t next = left_column(opt, n, k, left, sizeof left);
        const char *h = opt[k].help;
        int len = (int)strlen(left);
        if (len > HELP_COL - 2)
            fprintf(fp, "%s\n%*s", left, HELP_COL, "");
        else
            fprintf(fp, "%-*s", HELP_COL, left);
        for (const char *nl; (nl = strchr(h, '\n')); h = nl + 1)
            fprintf(fp, "%.*s\n%*s", (int)(nl - h), h, HELP_COL, "");
        fprintf(fp, "%s\n", h);
        k = next;
    }
}

void cli_help_common(FILE *fp)
{
    print_rows(fp, common_opt, NCOMMON);
}

void cli_help(const cli_spec *spec)
{
    fputs(spec->usage, stdout);
    print_rows(stdout, spec->opt, spec->nopt);
    if (spec->common) {
        printf("\noptions every command takes:\n");
        cli_help_common(stdout);
    } else {
        print_rows(stdout, &common_opt[NCOMMON - 1], 1);
    }
    if (spec->epilog)
        fputs(spec->epilog, stdout);
    if (spec->more)
        spec->more();
}

void cli_list_options(const cli_spec *spec)
{
    const char *cmd = spec->name;
    for (size_t k = 0; k < spec->nopt; k++)
        if (spec->opt[k].kind != CLI_HEAD)
            printf("%s --%s\n", cmd, spec->opt[k].name);
    for (size_t k = 0; k < NCOMMON; k++)
        if (spec->common || common_opt[k].letter == 'h')
            printf("%s --%s\n", cmd, common_opt[k].name);
}

void cli_list_common(void)
{
    for (size_t k = 0; k < NCOMMON; k++)
        printf("common --%s\n", common_opt[k].name);
}
