/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Tabulated curves y(x): made from arrays, read from text files, or taken from a row of a
 * vector field (a measured profile along x*). */
#include "ccm_impl.h"

#include "base/text.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_interp.h>

/* ---- tabulated curves ----------------------------------------------------------------- */

static rpiv_status curve_alloc(size_t n, int with_w, rpiv_ccm_curve **out)
{
    rpiv_ccm_curve *c = calloc(1, sizeof *c);
    if (!c)
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
    c->x = malloc(n * sizeof *c->x);
    c->y = malloc(n * sizeof *c->y);
    c->w = with_w ? malloc(n * sizeof *c->w) : NULL;
    if (!c->x || !c->y || (with_w && !c->w)) {
        rpiv_ccm_curve_free(c);
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for a curve of %zu points", n);
    }
    c->n = n;
    *out = c;
    return RPIV_OK;
}

/* The curve's interpolation, built once its points are in (x increasing, n >= 2). On failure
 * the curve is freed. */
static rpiv_status curve_finish(rpiv_ccm_curve *c, rpiv_ccm_curve **out)
{
    gsl_interp *in = gsl_interp_alloc(gsl_interp_linear, c->n);
    c->interp = in;
    if (!in) {
        rpiv_ccm_curve_free(c);
        return rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for a curve of %zu points", c->n);
    }
    int gs = gsl_interp_init(in, c->x, c->y, c->n);
    if (gs) {
        rpiv_ccm_curve_free(c);
        return ccm_gsl_fail(gs, "a curve's interpolation");
    }
    *out = c;
    return RPIV_OK;
}

rpiv_status rpiv_ccm_curve_new(const double *x, const double *y, size_t n, rpiv_ccm_curve **out)
{
    *out = NULL;
    if (n < 2)
        return rpiv_fail(RPIV_EINVAL, "ccm: a curve needs at least 2 points, got %zu", n);
    for (size_t i = 0; i < n; i++) {
        if (!isfinite(x[i]) || !isfinite(y[i]))
            return rpiv_fail(RPIV_EINVAL, "ccm: curve point %zu is not finite", i);
        if (i && !(x[i] > x[i - 1]))
            return rpiv_fail(RPIV_EINVAL, "ccm: curve abscissae not increasing at point %zu", i);
    }
    rpiv_ccm_curve *c = NULL;
    rpiv_status st = curve_alloc(n, 0, &c);
    if (st)
        return st;
    memcpy(c->x, x, n * sizeof *x);
    memcpy(c->y, y, n * sizeof *y);
    return curve_finish(c, out);
}

rpiv_status rpiv_ccm_curve_load(const char *path, rpiv_ccm_curve **out)
{
    *out = NULL;
    FILE *fp = fopen(path, "r");
    if (!fp)
        return rpiv_fail(RPIV_EIO, "%s: cannot open: %s", path, strerror(errno));
    rpiv_status st = RPIV_OK;
    size_t n = 0, cap = 0;
    double *x = NULL, *y = NULL, *w = NULL;
    int ncol = 0;
    char *line = NULL;
    size_t lcap = 0;
    long lineno = 0;
    ssize_t len;
    while ((len = text_getline(fp, &line, &lcap, path, &lineno, &st)) >= 0) {
        if (!text_is_data(line))
            continue;
        double v[3];
        int k = text_columns(line, v, 3, path, lineno, &st);
        if (k < 0)
            goto out_free;
        if (k < 2 || k > 3) {
            st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: expected two or three numbers 'x y [w]'", path,
                           lineno);
            goto out_free;
        }
        if (!ncol)
            ncol = k;
        if (k != ncol) {
            st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: %d columns, the first row had %d", path, lineno,
                           k, ncol);
            goto out_free;
        }
        if (n && !(v[0] > x[n - 1])) {
            st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: first column not increasing", path, lineno);
            goto out_free;
        }
        if (n == cap) {
            cap = cap ? 2 * cap : 64;
            double *nx = realloc(x, cap * sizeof *nx);
            if (nx)
                x = nx;
            double *ny = nx ? realloc(y, cap * sizeof *ny) : NULL;
            if (ny)
                y = ny;
            double *nw = ny ? realloc(w, cap * sizeof *nw) : NULL;
            if (nw)
                w = nw;
            if (!nw) {
                st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
                goto out_free;
            }
        }
        x[n] = v[0];
        y[n] = v[1];
        w[n] = k == 3 ? v[2] : 0;
        n++;
    }
    if (len == -2)
        goto out_free;
    if (ferror(fp)) {
        st = rpiv_fail(RPIV_EIO, "%s: read error", path);
        goto out_free;
    }
    if (n < 2) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: fewer than 2 data rows", path);
        goto out_free;
    }
    rpiv_ccm_curve *c = NULL;
    st = curve_alloc(n, ncol == 3, &c);
    if (st)
        goto out_free;
    memcpy(c->x, x, n * sizeof *x);
    memcpy(c->y, y, n * sizeof *y);
    if (c->w)
        memcpy(c->w, w, n * sizeof *w);
    st = curve_finish(c, out);
out_free:
    free(line);
    free(x);
    free(y);
    free(w);
    fclose(fp);
    return st;
}

void rpiv_ccm_curve_free(rpiv_ccm_curve *c)
{
    if (!c)
        return;
    if (c->interp)
        gsl_interp_free(c->interp);
    free(c->x);
    free(c->y);
    free(c->w);
    free(c);
}

/* No accelerator: a curve is a model callback, evaluated from many threads at once; GSL's
 * bisection without one is the search this lookup always made. */
double rpiv_ccm_curve_eval(const rpiv_ccm_curve *c, double x)
{
    if (!(x >= c->x[0] && x <= c->x[c->n - 1]))
        return 0;
    double y;
    return gsl_interp_eval_e(c->interp, c->x, c->y, x, NULL, &y) == GSL_SUCCESS ? y : 0;
}

double rpiv_ccm_curve_fn(const void *user, double x)
{
    return rpiv_ccm_curve_eval(user, x);
}

rpiv_status rpiv_ccm_profile_of_field(const rpiv_field *f, const rpiv_ccm_geometry *g,
                                      double scale_px, double ystar, rpiv_ccm_curve **out)
{
    *out = NULL;
    if (!(g->star_per_px > 0) || !(fabs(scale_px) > 0) || !(f->dx > 0) || !(f->dy != 0) ||
        f->nx < 1 || f->ny < 1)
        return rpiv_fail(RPIV_EINVAL, "ccm: field or geometry with a zero step or scale");
    /* grid row j has y* = y0_star + (y0 + j dy + 0.5) star_per_px */
    double yp = (ystar - g->y0_star) / g->star_per_px - 0.5;
    double jj = (yp - f->y0) / f->dy;
    long j = lround(jj);
    if (jj < -1 || jj > f->ny) /* more than one step outside */
        return rpiv_fail(RPIV_EINVAL, "ccm: y* = %g is outside the vector field (y* %g to %g)",
                         ystar, g->y0_star + (f->y0 + 0.5) * g->star_per_px,
                         g->y0_star + (f->y0 + (f->ny - 1) * f->dy + 0.5) * g->star_per_px);
    j = j < 0 ? 0 : (j >= f->ny ? f->ny - 1 : j);
    double *x = malloc((size_t)f->nx * sizeof *x), *u = malloc((size_t)f->nx * sizeof *u);
    rpiv_status st = RPIV_OK;
    if (!x || !u) {
        st = rpiv_fail(RPIV_ENOMEM, "ccm: out of memory");
        goto out_free;
    }
    size_t n = 0;
    for (int i = 0; i < f->nx; i++) {
        size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
        if (f->flag[k] != RPIV_FLAG_VALID || !isfinite(f->u[k]))
            continue;
        x[n] = g->x0_star + (f->x0 + i * f->dx + 0.5) * g->star_per_px;
        u[n++] = (double)f->u[k] / scale_px;
    }
    if (n < 3) {
        st = rpiv_fail(RPIV_ENUMERIC, "ccm: %zu valid vectors in the field's row at y* = %g", n,
                       ystar);
        goto out_free;
    }
    st = rpiv_ccm_curve_new(x, u, n, out);
out_free:
    free(x);
    free(u);
    return st;
}
