/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "rpiv/sheet.h"

#include "base/atomic.h"
#include "base/text.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_interp.h>

const char *const rpiv_sheet_kind_names[] = {"gauss", "selfsim", "uniform", NULL};

struct rpiv_sheet {
    rpiv_sheet_params p;
    size_t n;          /* shape table rows (0 = default analytic shape) */
    double *zp, *in;   /* shape table */
    gsl_interp *shape; /* linear interpolation of the table, built once */
};

rpiv_sheet_params rpiv_sheet_params_default(void)
{
    return (rpiv_sheet_params){.kind = RPIV_SHEET_SELFSIM,
                               .zb_star = 0.5,
                               .e_star = 0.05,
                               .e0 = 0,
                               .e1 = 0.42 / 6.5,
                               .zm0 = 0,
                               .zm1 = 0.5 / 6.3,
                               .skew = 2,
                               .profile = ""};
}

rpiv_status rpiv_sheet_params_check(const rpiv_sheet_params *p)
{
    if (p->kind < RPIV_SHEET_GAUSS || p->kind > RPIV_SHEET_UNIFORM)
        return rpiv_fail(RPIV_EINVAL, "sheet.kind: unknown kind %d", (int)p->kind);
    if (!(p->e_star > 0 && p->e_star < 100))
        return rpiv_fail(RPIV_EINVAL, "sheet.thickness: %g outside (0, 100)", p->e_star);
    if (!isfinite(p->zb_star) || !isfinite(p->e0) || !isfinite(p->e1) || !isfinite(p->zm0) ||
        !isfinite(p->zm1))
        return rpiv_fail(RPIV_EINVAL, "sheet: parameters must be finite");
    if (!(p->skew > 0 && p->skew < 100))
        return rpiv_fail(RPIV_EINVAL, "sheet.skew: %g outside (0, 100)", p->skew);
    return RPIV_OK;
}

/* Read "# key value" header lines and "zplus I" rows. */
static rpiv_status load_profile(const char *path, rpiv_sheet *s)
{
    FILE *fp = fopen(path, "r");
    if (!fp)
        return rpiv_fail(RPIV_EIO, "%s: cannot open sheet profile: %s", path, strerror(errno));
    char *line = NULL;
    size_t cap = 0, lcap = 0;
    ssize_t len;
    long lineno = 0;
    int magic = 0;
    rpiv_status st = RPIV_OK;
    while ((len = text_getline(fp, &line, &lcap, path, &lineno, &st)) >= 0) {
        char key[32];
        double v;
        if (line[0] == '#') {
            if (strstr(line, "rpiv-sheet"))
                magic = 1;
            else if (sscanf(line, "# %31s %lf", key, &v) == 2) {
                if (!isfinite(v) && (!strcmp(key, "e0") || !strcmp(key, "e1") ||
                                     !strcmp(key, "zm0") || !strcmp(key, "zm1"))) {
                    st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: %s is %g, not a finite number", path,
                                   lineno, key, v);
                    goto out;
                }
                if (!strcmp(key, "e0"))
                    s->p.e0 = v;
                else if (!strcmp(key, "e1"))
                    s->p.e1 = v;
                else if (!strcmp(key, "zm0"))
                    s->p.zm0 = v;
                else if (!strcmp(key, "zm1"))
                    s->p.zm1 = v;
            }
            continue;
        }
        if (!text_is_data(line))
            continue;
        double row[2];
        int nc = text_columns(line, row, 2, path, lineno, &st);
        if (nc < 0)
            goto out;
        if (nc != 2 || !(row[1] >= 0 && row[1] <= 1.0001)) {
            st =
                rpiv_fail(RPIV_EFORMAT, "%s:%ld: expected 'zplus I' (two numbers) with 0 <= I <= 1",
                          path, lineno);
            goto out;
        }
        double a = row[0], b = row[1];
        if (s->n && a <= s->zp[s->n - 1]) {
            st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: zplus not increasing", path, lineno);
            goto out;
        }
        /* the interpolation divides by the step: it must be a finite number */
        if (s->n && !isfinite(a - s->zp[s->n - 1])) {
            st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: zplus %g is too far from the previous row's %g",
                           path, lineno, a, s->zp[s->n - 1]);
            goto out;
        }
        if (s->n == cap) {
            cap = cap ? 2 * cap : 64;
            double *zp = realloc(s->zp, cap * sizeof *zp);
            if (!zp) {
                st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
                goto out;
            }
            s->zp = zp;
            double *in = realloc(s->in, cap * sizeof *in);
            if (!in) {
                st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
                goto out;
            }
            s->in = in;
        }
        s->zp[s->n] = a;
        s->in[s->n] = b;
        s->n++;
    }
    if (len == -2)
        goto out;
    if (!magic)
        st =
            rpiv_fail(RPIV_EFORMAT, "%s: not an rpiv sheet profile (no '# rpiv-sheet' line)", path);
    else if (s->n < 3)
        st = rpiv_fail(RPIV_EFORMAT, "%s: fewer than 3 profile rows", path);
out:
    free(line);
    fclose(fp);
    return st;
}

rpiv_status rpiv_sheet_new(const rpiv_sheet_params *p, rpiv_sheet **out)
{
    *out = NULL;
    rpiv_status st = rpiv_sheet_params_check(p);
    if (st)
        return st;
    rpiv_sheet *s = calloc(1, sizeof *s);
    if (!s)
        return rpiv_fail(RPIV_ENOMEM, "sheet: out of memory");
    s->p = *p;
    if (p->kind == RPIV_SHEET_SELFSIM && p->profile[0]) {
        st = load_profile(p->profile, s);
        if (!st && !(s->shape = gsl_interp_alloc(gsl_interp_linear, s->n)))
            st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", p->profile);
        int gs = st ? GSL_SUCCESS : gsl_interp_init(s->shape, s->zp, s->in, s->n);
        if (gs)
            st = rpiv_fail(RPIV_EFORMAT, "%s: shape table: %s", p->profile, gsl_strerror(gs));
        if (st) {
            rpiv_sheet_free(s);
            return st;
        }
    }
    *out = s;
    return RPIV_OK;
}

void rpiv_sheet_free(rpiv_sheet *s)
{
    if (!s)
        return;
    if (s->shape)
        gsl_interp_free(s->shape);
    free(s->zp);
    free(s->in);
    free(s);
}

/* Default skewed shape of unit quarter-height width: half-Gaussians with quarter-height
 * half-widths wl (below the peak) and wu (above), wl + wu = 1, wl/wu = skew. */
static double default_shape(double skew, double zp)
{
    const double ln4 = 1.3862943611198906;
    double wl = skew / (1 + skew), wu = 1 / (1 + skew);
    double w = zp < 0 ? wl : wu;
    return exp(-ln4 * zp * zp / (w * w));
}

/* The table's shape at zp, 0 outside. No accelerator: a sheet is evaluated from many threads
 * at once, and GSL's bisection without one is the search this lookup always made. */
static double table_shape(const rpiv_sheet *s, double zp)
{
    if (zp < s->zp[0] || zp > s->zp[s->n - 1])
        return 0;
    double v;
    return gsl_interp_eval_e(s->shape, s->zp, s->in, zp, NULL, &v) == GSL_SUCCESS ? v : 0;
}

double rpiv_sheet_zplus(double zstar, double zmax, double e)
{
    return (zstar - zmax) / e;
}

double rpiv_sheet_eval(const rpiv_sheet *s, double xstar, double zstar)
{
    const double ln4 = 1.3862943611198906;
    if (zstar < 0 || zstar > 1)
        return 0;
    switch (s->p.kind) {
    case RPIV_SHEET_GAUSS: {
        double d = (zstar - s->p.zb_star) / s->p.e_star;
        return exp(-4 * ln4 * d * d);
    }
    case RPIV_SHEET_SELFSIM: {
        double e = s->p.e0 + s->p.e1 * xstar;
        if (!(e > 1e-9))
            return 0;
        double zp = rpiv_sheet_zplus(zstar, s->p.zm0 + s->p.zm1 * xstar, e);
        return s->n ? table_shape(s, zp) : default_shape(s->p.skew, zp);
    }
    case RPIV_SHEET_UNIFORM:
        return 1;
    }
    return 0;
}

rpiv_status rpiv_sheet_save_profile(const char *path, double e0, double e1, double zm0, double zm1,
                                    const double *zplus, const double *inten, size_t n)
{
    atomic_file af; /* unique temporary name, fsync, rename, fsync of the folder */
    rpiv_status st = atomic_begin(&af, path, 1);
    if (st)
        return st;
    fprintf(af.fp,
            "# rpiv-sheet 1\n# e0 %.17g\n# e1 %.17g\n# zm0 %.17g\n# zm1 %.17g\n"
            "# columns: zplus = (z* - z*_max(x*)) / e*(x*), I0/I0max\n",
            e0, e1, zm0, zm1);
    for (size_t i = 0; i < n; i++)
        fprintf(af.fp, "%.10g %.10g\n", zplus[i], inten[i]);
    return atomic_commit(&af);
}

rpiv_status rpiv_sheet_metrics_of(const double *z, const double *inten, size_t n,
                                  rpiv_sheet_metrics *m)
{
    if (n < 3)
        return rpiv_fail(RPIV_EINVAL, "sheet metrics: need at least 3 samples");
    size_t k = 0;
    for (size_t i = 1; i < n; i++)
        if (inten[i] > inten[k])
            k = i;
    if (!(inten[k] > 0))
        return rpiv_fail(RPIV_ENUMERIC, "sheet metrics: profile is zero everywhere");
    m->imax = inten[k];
    m->zmax = z[k];
    if (k > 0 && k < n - 1) {
        double a = inten[k - 1], b = inten[k], c = inten[k + 1], den = a - 2 * b + c;
        if (den < 0) {
            double off = 0.5 * (a - c) / den;
            m->zmax = z[k] + off * (off > 0 ? z[k + 1] - z[k] : z[k] - z[k - 1]);
        }
    }
    double q = 0.25 * inten[k];
    size_t i = k;
    while (i > 0 && inten[i - 1] > q)
        i--;
    if (i == 0)
        return rpiv_fail(RPIV_ENUMERIC, "sheet metrics: profile does not fall to 0.25 below");
    m->zinf = z[i - 1] + (q - inten[i - 1]) / (inten[i] - inten[i - 1]) * (z[i] - z[i - 1]);
    i = k;
    while (i < n - 1 && inten[i + 1] > q)
        i++;
    if (i == n - 1)
        return rpiv_fail(RPIV_ENUMERIC, "sheet metrics: profile does not fall to 0.25 above");
    m->zsup = z[i] + (inten[i] - q) / (inten[i] - inten[i + 1]) * (z[i + 1] - z[i]);
    m->e = m->zsup - m->zinf;
    return RPIV_OK;
}

double rpiv_sheet_incl_deg(double slope)
{
    return atan(slope) * 180 / M_PI;
}
