/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field/field_compare.c - E1 (Eq. "E1"), RMS and largest difference between two profiles or two
 * vector fields. */
#include "rpiv/field.h"

#include <gsl/gsl_errno.h>
#include <gsl/gsl_interp.h>
#include <math.h>
#include <stdlib.h>

rpiv_status rpiv_e1(const double *alpha, const double *ref, const double *cmp, size_t n, double *e1)
{
    if (n < 2)
        return rpiv_fail(RPIV_EINVAL, "E1: need at least 2 samples, got %zu", n);
    double num = 0, den = 0;
    for (size_t i = 1; i < n; i++) {
        double h = alpha[i] - alpha[i - 1];
        if (!(h > 0))
            return rpiv_fail(RPIV_EINVAL, "E1: coordinates not increasing at sample %zu", i);
        double d0 = ref[i - 1] - cmp[i - 1], d1 = ref[i] - cmp[i];
        num += 0.5 * h * (d0 * d0 + d1 * d1);
        den += 0.5 * h * (ref[i - 1] + ref[i]);
    }
    if (!(fabs(den) > 0) || !isfinite(num))
        return rpiv_fail(RPIV_EINVAL, "E1: the reference integrates to zero or is not finite");
    *e1 = sqrt(num) / den;
    return RPIV_OK;
}

rpiv_status rpiv_profile_compare(const rpiv_profile *ref, const rpiv_profile *cmp,
                                 rpiv_compare *out)
{
    double c0 = cmp->alpha[0], c1 = cmp->alpha[cmp->n - 1];
    /* a reference sample on the end of cmp's range counts as inside despite rounding */
    double tol = 1e-9 * fmax(c1 - c0, fmax(fabs(c0), fabs(c1)));
    size_t a = 0, b;
    while (a < ref->n && ref->alpha[a] < c0 - tol)
        a++;
    b = a;
    while (b < ref->n && ref->alpha[b] <= c1 + tol)
        b++;
    size_t n = b - a;
    if (n < 2)
        return rpiv_fail(RPIV_ESIZE,
                         "profiles do not overlap: reference alpha %g..%g has %zu "
                         "sample%s in the compared range %g..%g",
                         ref->alpha[0], ref->alpha[ref->n - 1], n, n == 1 ? "" : "s", c0, c1);
    double *x = malloc(n * sizeof *x), *y = malloc(n * sizeof *y);
    gsl_interp *it = gsl_interp_alloc(gsl_interp_linear, cmp->n);
    gsl_interp_accel *acc = gsl_interp_accel_alloc();
    rpiv_status st = RPIV_OK;
    if (!x || !y || !it || !acc) {
        st = rpiv_fail(RPIV_ENOMEM, "compare: out of memory for %zu samples", n);
        goto out_free;
    }
    if (gsl_interp_init(it, cmp->alpha, cmp->value, cmp->n)) {
        st = rpiv_fail(RPIV_EINVAL, "compare: the compared profile's alpha is not increasing");
        goto out_free;
    }
    double lo = ref->alpha[a], span = ref->alpha[b - 1] - lo;
    double sum2 = 0, mx = 0;
    for (size_t k = 0; k < n; k++) {
        double al = fmin(fmax(ref->alpha[a + k], c0), c1);
        double v = gsl_interp_eval(it, cmp->alpha, cmp->value, al, acc);
        double d = ref->value[a + k] - v;
        y[k] = v;
        x[k] = (ref->alpha[a + k] - lo) / span; /* alpha rescaled to [0, 1] */
        sum2 += d * d;
        mx = fmax(mx, fabs(d));
    }
    st = rpiv_e1(x, ref->value + a, y, n, &out->e1);
    if (st)
        goto out_free;
    out->e1 = fabs(out->e1); /* a negative reference (flow along -alpha) gives a positive E1 */
    out->rms = sqrt(sum2 / (double)n);
    out->max_abs = mx;
    out->n = n;
    out->alpha0 = ref->alpha[a];
    out->alpha1 = ref->alpha[b - 1];
out_free:
    gsl_interp_accel_free(acc);
    gsl_interp_free(it);
    free(x);
    free(y);
    return st;
}

static double component(const rpiv_field *f, size_t k, rpiv_component c)
{
    if (c == RPIV_COMPONENT_U)
        return (double)f->u[k];
    if (c == RPIV_COMPONENT_V)
        return (double)f->v[k];
    return hypot((double)f->u[k], (double)f->v[k]);
}

rpiv_status rpiv_field_compare(const rpiv_field *ref, const rpiv_field *cmp, rpiv_component c,
                               rpiv_compare *out)
{
    if (ref->nx != cmp->nx || ref->ny != cmp->ny || fabs(ref->x0 - cmp->x0) > 1e-6 * ref->dx ||
        fabs(ref->y0 - cmp->y0) > 1e-6 * ref->dy || fabs(ref->dx - cmp->dx) > 1e-6 * ref->dx ||
        fabs(ref->dy - cmp->dy) > 1e-6 * ref->dy)
        return rpiv_fail(RPIV_ESIZE,
                         "compare: grids differ: %d x %d from (%g, %g) step (%g, %g) "
                         "vs %d x %d from (%g, %g) step (%g, %g)",
                         ref->nx, ref->ny, ref->x0, ref->y0, ref->dx, ref->dy, cmp->nx, cmp->ny,
                         cmp->x0, cmp->y0, cmp->dx, cmp->dy);
    size_t np = (size_t)ref->nx * (size_t)ref->ny, n = 0;
    double sum2 = 0, sumr = 0, mx = 0;
    for (size_t k = 0; k < np; k++) {
        if (ref->flag[k] == RPIV_FLAG_MASKED || cmp->flag[k] == RPIV_FLAG_MASKED)
            continue;
        double r = component(ref, k, c), d = r - component(cmp, k, c);
        sum2 += d * d;
        sumr += r;
        mx = fmax(mx, fabs(d));
        n++;
    }
    if (!n)
        return rpiv_fail(RPIV_ESIZE, "compare: every point is masked in one of the fields");
    if (!(fabs(sumr) > 0))
        return rpiv_fail(RPIV_EINVAL, "compare: the reference %s averages to zero: E1 undefined",
                         c == RPIV_COMPONENT_U   ? "u"
                         : c == RPIV_COMPONENT_V ? "v"
                                                 : "|u|");
    out->rms = sqrt(sum2 / (double)n);
    out->e1 = out->rms / fabs(sumr / (double)n);
    out->max_abs = mx;
    out->n = n;
    out->alpha0 = out->alpha1 = 0;
    return RPIV_OK;
}
