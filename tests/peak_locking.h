/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/peak_locking.h - the peak-locking figure of a sweep of sub-pixel shifts, shared by
 * test_noise, bench_noise and bench_gpiv_noise: the least-squares fit (GSL's
 * gsl_multifit_linear) of e(f) = a0 + sum_{h=1,2} a_h sin(2 pi h f) + b_h cos(2 pi h f) to the
 * mean errors e[i] at the sub-pixel shifts f[i], and the largest |periodic part| over one
 * period (200 samples). NAN if n < 5 or out of memory. */
#ifndef RPIV_TESTS_PEAK_LOCKING_H
#define RPIV_TESTS_PEAK_LOCKING_H

#include <gsl/gsl_multifit.h>
#include <math.h>

static inline double ti_peak_locking(const double *f, const double *e, int n)
{
    if (n < 5)
        return (double)NAN;
    gsl_matrix *X = gsl_matrix_alloc((size_t)n, 5), *cov = gsl_matrix_alloc(5, 5);
    gsl_vector *y = gsl_vector_alloc((size_t)n), *c = gsl_vector_alloc(5);
    gsl_multifit_linear_workspace *w = gsl_multifit_linear_alloc((size_t)n, 5);
    double amp = (double)NAN, chisq;
    if (X && cov && y && c && w) {
        for (int i = 0; i < n; i++) {
            const double b[5] = {1, sin(2 * M_PI * f[i]), cos(2 * M_PI * f[i]),
                                 sin(4 * M_PI * f[i]), cos(4 * M_PI * f[i])};
            for (size_t k = 0; k < 5; k++)
                gsl_matrix_set(X, (size_t)i, k, b[k]);
            gsl_vector_set(y, (size_t)i, e[i]);
        }
        if (!gsl_multifit_linear(X, y, c, cov, &chisq, w)) {
            amp = 0;
            for (int k = 0; k < 200; k++) {
                const double t = k / 200.0;
                const double v = gsl_vector_get(c, 1) * sin(2 * M_PI * t) +
                                 gsl_vector_get(c, 2) * cos(2 * M_PI * t) +
                                 gsl_vector_get(c, 3) * sin(4 * M_PI * t) +
                                 gsl_vector_get(c, 4) * cos(4 * M_PI * t);
                amp = fmax(amp, fabs(v));
            }
        }
    }
    gsl_multifit_linear_free(w);
    gsl_vector_free(c);
    gsl_vector_free(y);
    gsl_matrix_free(cov);
    gsl_matrix_free(X);
    return amp;
}

#endif /* RPIV_TESTS_PEAK_LOCKING_H */
