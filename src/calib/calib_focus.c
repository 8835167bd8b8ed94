/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The focus curve of the depth-of-focus analysis (rpiv_calib_focus): 1/I* - 1 against z*, its
 * half-maximum crossings (DOF*), the object plane z*_OP at its maximum, and its text form.
 * Shared by the measurement and the model (calib_dof.c). */
#include "calib_impl.h"

#include <gsl/gsl_errno.h>
#include <gsl/gsl_fit.h>
#include <gsl/gsl_multifit.h>
#include <gsl/gsl_vector.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void rpiv_calib_focus_free(rpiv_calib_focus *c)
{
    if (!c)
        return;
    free(c->z);
    free(c->istar);
    free(c->inv);
    free(c->g);
    free(c->gfit);
    free(c->count);
    memset(c, 0, sizeof *c);
}

rpiv_status calib_focus_alloc(rpiv_calib_focus *c, size_t n, int counts)
{
    memset(c, 0, sizeof *c);
    c->z = malloc(n * sizeof *c->z);
    c->istar = malloc(n * sizeof *c->istar);
    c->inv = malloc(n * sizeof *c->inv);
    c->g = malloc(n * sizeof *c->g);
    c->gfit = malloc(n * sizeof *c->gfit);
    if (counts)
        c->count = calloc(n, sizeof *c->count);
    if (!c->z || !c->istar || !c->inv || !c->g || !c->gfit || (counts && !c->count)) {
        rpiv_calib_focus_free(c);
        return rpiv_fail(RPIV_ENOMEM, "calib dof: out of memory");
    }
    c->n = n;
    return RPIV_OK;
}

/* Half-maximum crossings of v (normalised so the peak is 1) walking out from index k, by linear
 * interpolation. */
static int crossings(const double *z, const double *v, size_t n, size_t k, double *lo, double *hi)
{
    size_t i = k;
    while (i > 0 && v[i - 1] >= 0.5)
        i--;
    if (i == 0)
        return 0;
    *lo = z[i - 1] + (0.5 - v[i - 1]) / (v[i] - v[i - 1]) * (z[i] - z[i - 1]);
    i = k;
    while (i + 1 < n && v[i + 1] >= 0.5)
        i++;
    if (i + 1 >= n)
        return 0;
    *hi = z[i] + (v[i] - 0.5) / (v[i] - v[i + 1]) * (z[i + 1] - z[i]);
    return 1;
}

/* Index of the maximum. */
static size_t argmax(const double *v, size_t n)
{
    size_t k = 0;
    for (size_t i = 1; i < n; i++)
        if (v[i] > v[k])
            k = i;
    return k;
}

/* Local quadratic regression: out[i] is the least-squares parabola through the samples
 * i - m .. i + m (clipped to the curve) evaluated at z[i]. It removes the column-to-column
 * scatter (pixel phase of each column of dots, noise) and keeps peaks and slopes that are
 * smooth over 2m + 1 columns. m = 0 copies. */
static rpiv_status local_quad(const double *z, const double *v, size_t n, int m, double *out)
{
    if (m <= 0 || n < 3) {
        memcpy(out, v, n * sizeof *out);
        return RPIV_OK;
    }
    size_t wmax = 2 * (size_t)m + 1;
    gsl_matrix *X = gsl_matrix_alloc(wmax, 3), *cov = gsl_matrix_alloc(3, 3);
    gsl_vector *y = gsl_vector_alloc(wmax), *c = gsl_vector_alloc(3);
    gsl_multifit_linear_workspace *ws = gsl_multifit_linear_alloc(wmax, 3);
    rpiv_status st = RPIV_OK;
    if (!X || !cov || !y || !c || !ws) {
        st = rpiv_fail(RPIV_ENOMEM, "calib dof: out of memory");
        goto out_free;
    }
    for (size_t i = 0; i < n; i++) {
        size_t a = i >= (size_t)m ? i - (size_t)m : 0,
               b = i + (size_t)m < n ? i + (size_t)m : n - 1;
        size_t len = b - a + 1;
        if (len < 3) {
            out[i] = v[i];
            continue;
        }
        gsl_matrix_view Xv = gsl_matrix_submatrix(X, 0, 0, len, 3);
        gsl_vector_view yv = gsl_vector_subvector(y, 0, len);
        for (size_t j = 0; j < len; j++) {
            double d = z[a + j] - z[i];
            gsl_matrix_set(&Xv.matrix, j, 0, 1);
            gsl_matrix_set(&Xv.matrix, j, 1, d);
            gsl_matrix_set(&Xv.matrix, j, 2, d * d);
            gsl_vector_set(&yv.vector, j, v[a + j]);
        }
        double chisq;
        if (gsl_multifit_linear(&Xv.matrix, &yv.vector, c, cov, &chisq, ws) != GSL_SUCCESS) {
            st = rpiv_fail(RPIV_ENUMERIC, "calib dof: local fit of the focus curve failed");
            goto out_free;
        }
        out[i] = gsl_vector_get(c, 0);
    }
out_free:
    gsl_multifit_linear_free(ws);
    gsl_matrix_free(X);
    gsl_matrix_free(cov);
    gsl_vector_free(y);
    gsl_vector_free(c);
    return st;
}

/* Least-squares parabola through the samples in [zlo, zhi]; its vertex, or NAN. */
static double parabola_vertex(const double *z, const double *g, size_t n, double zlo, double zhi)
{
    size_t m = 0, first = 0;
    for (size_t i = 0; i < n; i++)
        if (z[i] >= zlo && z[i] <= zhi) {
            if (!m)
                first = i;
            m++;
        }
    if (m < 3)
        return (double)NAN;
    double zc = 0.5 * (zlo + zhi), vertex = (double)NAN;
    gsl_matrix *X = gsl_matrix_alloc(m, 3), *cov = gsl_matrix_alloc(3, 3);
    gsl_vector *y = gsl_vector_alloc(m), *c = gsl_vector_alloc(3);
    gsl_multifit_linear_workspace *ws = gsl_multifit_linear_alloc(m, 3);
    if (X && cov && y && c && ws) {
        for (size_t i = 0; i < m; i++) {
            double d = z[first + i] - zc;
            gsl_matrix_set(X, i, 0, 1);
            gsl_matrix_set(X, i, 1, d);
            gsl_matrix_set(X, i, 2, d * d);
            gsl_vector_set(y, i, g[first + i]);
        }
        double chisq;
        if (gsl_multifit_linear(X, y, c, cov, &chisq, ws) == GSL_SUCCESS) {
            double b = gsl_vector_get(c, 1), a = gsl_vector_get(c, 2);
            if (a < 0) {
                double v = zc - b / (2 * a);
                if (v >= zlo && v <= zhi)
                    vertex = v;
            }
        }
    }
    gsl_multifit_linear_free(ws);
    gsl_matrix_free(X);
    gsl_matrix_free(cov);
    gsl_vector_free(y);
    gsl_vector_free(c);
    return vertex;
}

/* From z and I* (filled by the caller), compute 1/I*, its local fit (m columns each side), g,
 * the crossings, DOF*, z*_OP and the secondary widths. */
rpiv_status calib_focus_analyse(rpiv_calib_focus *c, int m, const char *what)
{
    size_t n = c->n;
    for (size_t i = 0; i < n; i++) {
        if (!(c->istar[i] > 0))
            return rpiv_fail(RPIV_ENUMERIC, "%s: grey level %g at z* = %.4f is not above dark",
                             what, c->istar[i], c->z[i]);
        c->inv[i] = 1 / c->istar[i];
    }
    double *fit = malloc(n * sizeof *fit), *v = malloc(n * sizeof *v), lo, hi;
    rpiv_status st = RPIV_OK;
    if (!fit || !v) {
        st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", what);
        goto out_free;
    }
    if ((st = local_quad(c->z, c->inv, n, m, fit)))
        goto out_free;
    size_t k = argmax(fit, n);
    c->inv_max = fit[k];
    if (!(c->inv_max > 1 + 1e-9)) {
        st = rpiv_fail(RPIV_ENUMERIC,
                       "%s: no dot is darker than the local mean grey (no focus signal)", what);
        goto out_free;
    }
    for (size_t i = 0; i < n; i++) {
        c->g[i] = (c->inv[i] - 1) / (c->inv_max - 1);
        c->gfit[i] = (fit[i] - 1) / (c->inv_max - 1);
    }
    if (!crossings(c->z, c->gfit, n, k, &c->zlo, &c->zhi)) {
        st = rpiv_fail(RPIV_ENUMERIC,
                       "%s: the focus curve does not fall to half its maximum on both sides "
                       "of z* = %.3f (depth of focus wider than the target, z* %.3f..%.3f)",
                       what, c->z[k], c->z[0], c->z[n - 1]);
        goto out_free;
    }
    c->dof = c->zhi - c->zlo;
    c->zmid = 0.5 * (c->zlo + c->zhi);
    c->zop = parabola_vertex(c->z, c->g, n, c->zlo, c->zhi);
    if (!isfinite(c->zop))
        c->zop = c->zmid;
    /* secondary widths, for comparison (docs/calib.md) */
    c->dof_raw = (double)NAN;
    for (size_t i = 0; i < n; i++)
        v[i] = fit[i] / c->inv_max;
    if (crossings(c->z, v, n, k, &lo, &hi))
        c->dof_raw = hi - lo;
    c->dof_contrast = (double)NAN;
    for (size_t i = 0; i < n; i++)
        v[i] = 1 - c->istar[i];
    if ((st = local_quad(c->z, v, n, m, fit)))
        goto out_free;
    size_t kc = argmax(fit, n);
    if (fit[kc] > 0) {
        for (size_t i = 0; i < n; i++)
            fit[i] /= fit[kc];
        if (crossings(c->z, fit, n, kc, &lo, &hi))
            c->dof_contrast = hi - lo;
    }
out_free:
    free(fit);
    free(v);
    return st;
}

rpiv_status rpiv_calib_focus_write(const rpiv_calib_focus *c, FILE *fp)
{
    fprintf(fp,
            "# rpiv calib dof: focus curve (one line per column of dots along the span)\n"
            "# z*_OP %.5f  DOF* %.5f  (half maximum at z* %.5f and %.5f; midpoint %.5f)\n"
            "# DOF* of 1/I* without baseline %.5f, of the darkness 1 - I* %.5f\n"
            "# zstar dots Istar inv_Istar g g_fit\n",
            c->zop, c->dof, c->zlo, c->zhi, c->zmid, c->dof_raw, c->dof_contrast);
    for (size_t i = 0; i < c->n; i++)
        fprintf(fp, "%.6f %zu %.6f %.6f %.6f %.6f\n", c->z[i], c->count ? c->count[i] : 0,
                c->istar[i], c->inv[i], c->g[i], c->gfit[i]);
    if (ferror(fp))
        return rpiv_fail(RPIV_EIO, "calib dof: write error");
    return RPIV_OK;
}
