/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv duct - print (and plot) the analytic square-duct profile U*(y*, z*) along y* or z*. */
#include "cli.h"

#include "rpiv/report.h"

#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

rpiv_status cmd_duct(int argc, char **argv);

#define MAX_POINTS 1000000

typedef struct opts {
    cli_ctx c;
    const char *y, *z, *png;
} opts;

static const cli_opt options[] = {
    {.name = "y",
     .kind = CLI_STR,
     .arg = "V|A:B:S",
     .off = offsetof(opts, y),
     .help = "spanwise coordinate y* (0..1)"},
    {.name = "z",
     .kind = CLI_STR,
     .arg = "V|A:B:S",
     .off = offsetof(opts, z),
     .help = "height z* above the floor (0..1)"},
    {.name = "png",
     .kind = CLI_STR,
     .arg = "FILE",
     .off = offsetof(opts, png),
     .help = "also plot the profile into FILE (PNG)"},
};

const cli_spec cmd_duct_spec = {
    .name = "duct",
    .usage = "usage: rpiv duct [--y Y|START:STOP:STEP] [--z Z|START:STOP:STEP] [--png FILE]\n\n"
             "Print the fully developed laminar velocity in the square duct (Eq. \"White\" of the\n"
             "paper), U* = U / U_bulk, as a two-column table: the coordinate given as a range,\n"
             "then U*. One of --y, --z is a single value in 0..1, the other a range (inclusive\n"
             "of STOP). Default: --y 0.5 --z 0:1:0.01. The table is a profile file that\n"
             "'rpiv compare' reads.\n\noptions:\n",
    .opt = options,
    .nopt = sizeof options / sizeof options[0],
    .common = 1};

/* A number of option opt, or a usage error naming the option and the text. */
static rpiv_status number(const char *opt, const char *what, const char *s, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || *end || errno || !isfinite(v))
        return cli_usage_error("duct", "%s: %s '%s' is not a number", opt, what, s);
    *out = v;
    return RPIV_OK;
}

/* "V" (one value) or "START:STOP:STEP" (STOP included when it falls on the step), all in
 * 0..1. On success *vals is malloc'ed with *n values. */
static rpiv_status parse_range(const char *opt, const char *arg, double **vals, size_t *n,
                               int *is_range)
{
    char buf[256];
    double a = 0, b = 0, s = 0;
    rpiv_status st;
    *vals = NULL;
    if (strlen(arg) >= sizeof buf)
        return cli_usage_error("duct", "%s: argument too long", opt);
    strcpy(buf, arg);
    char *c1 = strchr(buf, ':'), *c2 = c1 ? strchr(c1 + 1, ':') : NULL;
    if (!c1) {
        if ((st = number(opt, "value", buf, &a)))
            return st;
        b = a;
        s = 1;
        *is_range = 0;
    } else {
        if (!c2 || strchr(c2 + 1, ':'))
            return cli_usage_error("duct", "%s: '%s' is neither a value nor START:STOP:STEP", opt,
                                   arg);
        *c1 = *c2 = '\0';
        if ((st = number(opt, "start", buf, &a)) || (st = number(opt, "stop", c1 + 1, &b)) ||
            (st = number(opt, "step", c2 + 1, &s)))
            return st;
        if (!(s > 0))
            return cli_usage_error("duct", "%s: step %g must be > 0", opt, s);
        if (b < a)
            return cli_usage_error("duct", "%s: stop %g is below start %g", opt, b, a);
        *is_range = 1;
    }
    if (a < 0 || b > 1)
        return cli_usage_error("duct", "%s: '%s' leaves the duct: coordinates are 0..1", opt, arg);
    double count = floor((b - a) / s + 1e-9) + 1;
    if (count > MAX_POINTS)
        return cli_usage_error("duct", "%s: '%s' gives %.0f points, more than %d", opt, arg, count,
                               MAX_POINTS);
    *n = (size_t)count;
    *vals = malloc(*n * sizeof **vals);
    if (!*vals)
        return rpiv_fail(RPIV_ENOMEM, "duct: out of memory for %zu points", *n);
    for (size_t k = 0; k < *n; k++)
        (*vals)[k] = fmin(a + (double)k * s, b); /* k * step: no accumulated rounding */
    return RPIV_OK;
}

rpiv_status cmd_duct(int argc, char **argv)
{
    opts op = {0};
    int done;
    rpiv_status st;
    cli_ctx_init(&op.c);
    if ((st = cli_parse(&cmd_duct_spec, &op.c, &op, argc, argv, &done)) || done)
        return st;
    const char *yarg = op.y, *zarg = op.z, *png = op.png;
    if (optind < argc)
        return cli_usage_error("duct", "unexpected argument '%s'", argv[optind]);
    if (!yarg && !zarg)
        yarg = "0.5";
    if (!zarg && yarg && !strchr(yarg, ':'))
        zarg = "0:1:0.01";
    if (!yarg)
        yarg = strchr(zarg, ':') ? "0.5" : "0:1:0.01";
    double *ys = NULL, *zs = NULL;
    size_t ny = 0, nz = 0;
    int yr = 0, zr = 0;
    if ((st = parse_range("--y", yarg, &ys, &ny, &yr)) ||
        (st = parse_range("--z", zarg, &zs, &nz, &zr)))
        goto out;
    if (yr && zr) {
        st = cli_usage_error("duct", "--y %s and --z %s are both ranges: give one as a value", yarg,
                             zarg);
        goto out;
    }
    /* the range is the abscissa; a single point counts as a range along z */
    int along_y = yr;
    const double *al = along_y ? ys : zs;
    size_t n = along_y ? ny : nz;
    double fixed = along_y ? zs[0] : ys[0];
    st = rpiv_report_duct(stdout, al, n, along_y, fixed, png);
out:
    free(ys);
    free(zs);
    return st;
}
