/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "cli.h"

#include <getopt.h>

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
