/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The particles' presence law P(z*) of the generator: its table file (synth.pz_profile) and
 * the heights drawn from it. */
#include "synth_impl.h"

#include "base/text.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_interp.h>

/* ---- P(z*) table ------------------------------------------------------------------------ */

rpiv_status synth_pz_load(rpiv_synth *s, const char *path)
{
    FILE *fp = fopen(path, "r");
    if (!fp)
        return rpiv_fail(RPIV_EIO, "%s: cannot open P(z) table: %s", path, strerror(errno));
    char *line = NULL;
    size_t cap = 0, lcap = 0;
    long lineno = 0;
    ssize_t len;
    rpiv_status st = RPIV_OK;
    while ((len = text_getline(fp, &line, &lcap, path, &lineno, &st)) >= 0) {
        if (!text_is_data(line))
            continue;
        double row[2];
        int nc = text_columns(line, row, 2, path, lineno, &st);
        if (nc < 0)
            goto out_close;
        if (nc != 2) {
            st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: expected two numbers 'z* P'", path, lineno);
            goto out_close;
        }
        double z = row[0], p = row[1];
        if (z < 0 || z > 1 || p < 0) {
            st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: need 0 <= z* <= 1 and P >= 0, got %g %g", path,
                           lineno, z, p);
            goto out_close;
        }
        if (s->npz && !(z > s->pz_z[s->npz - 1])) {
            st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: z* not increasing", path, lineno);
            goto out_close;
        }
        if (s->npz == cap) {
            cap = cap ? 2 * cap : 64;
            double *nz = realloc(s->pz_z, cap * sizeof *nz);
            if (nz)
                s->pz_z = nz;
            double *np = realloc(s->pz_p, cap * sizeof *np);
            if (np)
                s->pz_p = np;
            if (!nz || !np) {
                st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
                goto out_close;
            }
        }
        s->pz_z[s->npz] = z;
        s->pz_p[s->npz] = p;
        s->npz++;
    }
    if (len == -2)
        goto out_close;
    if (ferror(fp)) {
        st = rpiv_fail(RPIV_EIO, "%s: read error", path);
        goto out_close;
    }
    if (s->npz < 2) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: a P(z) table needs at least 2 rows", path);
        goto out_close;
    }
    s->pz_c = malloc(s->npz * sizeof *s->pz_c);
    if (!s->pz_c) {
        st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
        goto out_close;
    }
    s->pz_c[0] = 0;
    for (size_t k = 1; k < s->npz; k++)
        s->pz_c[k] =
            s->pz_c[k - 1] + 0.5 * (s->pz_p[k - 1] + s->pz_p[k]) * (s->pz_z[k] - s->pz_z[k - 1]);
    if (!(s->pz_c[s->npz - 1] > 0))
        st = rpiv_fail(RPIV_EFORMAT, "%s: P(z) integrates to zero", path);
out_close:
    free(line);
    fclose(fp);
    return st;
}

/* z* from the density: uniform on [0, 1], or the inverse of the cumulative integral of the
 * piecewise-linear table (exact: a quadratic in each segment). */
double synth_pz_sample(const rpiv_synth *s, gsl_rng *r)
{
    double u = gsl_rng_uniform(r);
    if (!s->npz)
        return u;
    double t = u * s->pz_c[s->npz - 1];
    /* the segment by GSL's bisection (the cumulative integral may be flat where P = 0, which
     * gsl_interp refuses, and the inversion in the segment is quadratic, not linear) */
    size_t lo = gsl_interp_bsearch(s->pz_c, t, 0, s->npz - 1), hi = lo + 1;
    double dz = s->pz_z[hi] - s->pz_z[lo], p0 = s->pz_p[lo];
    double a = (s->pz_p[hi] - p0) / dz, rem = t - s->pz_c[lo];
    double den = p0 + sqrt(p0 * p0 + 2 * a * rem);
    double xi = den > 0 ? 2 * rem / den : 0;
    if (xi > dz)
        xi = dz;
    return s->pz_z[lo] + xi;
}
