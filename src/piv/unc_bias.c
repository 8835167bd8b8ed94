/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/unc_bias.c - the systematic error of the engine's own chain (deformation by the
 * cubic B-spline interpolator, then the sub-pixel estimator) on a model particle image, for
 * the uncertainty's systematic term (docs/uncertainty.md, "The systematic floor").
 *
 * The model: pixel-integrated Gaussian particle images of standard deviation s (px), at every
 * sub-pixel phase (16 phases averaged: an ensemble's expectation over the particles' random
 * positions), displaced by d between the frames; with a deforming pass both frames are
 * resampled with the engine's interpolator as rpiv_deform_run does (A at x + c - p/2, B at
 * x + c + p/2, p the predictor, c its sampling shift), else read as they are. Their
 * correlation is separable in x and y, so each axis is a 1-D model and the plane their
 * product, each weighted by the window's share of pixel pairs at the shift, 1 - |k| / w;
 * the engine's estimator (rpiv_peak_find) is run on it: bias = estimate - (d - p).
 * s comes from the measured peak: the model's estimator curvature matched to the field's. */
#include "peak_impl.h"
#include "rpiv/deform.h"
#include "rpiv/peak.h"
#include "uncertainty_impl.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum {
    ML = 48,  /* model row, px                   */
    MPH = 16, /* sub-pixel phases                */
    MR = 4,   /* lags kept either side of k0     */
    MW = 16,  /* the model plane's size          */
    MROWS = 1 /* the 1-D model images are rows of this height */
};

/* One axis: the correlation at lags k0 - MR .. k0 + MR, k0 = round(d - p). */
static void model_1d(double s, double d, double p, int deform, double c, int k0, int ww,
                     double C[2 * MR + 1])
{
    float fa[ML * MROWS], fb[ML * MROWS];
    double a[ML], b[ML];
    const double k = 1.0 / (sqrt(2.0) * s);
    memset(C, 0, (2 * MR + 1) * sizeof *C);
    for (int ph = 0; ph < MPH; ph++) {
        const double xi = (ph + 0.5) / MPH - 0.5;
        const double xa = 0.5 * ML + xi - 0.5 * d, xb = 0.5 * ML + xi + 0.5 * d;
        for (int x = 0; x < ML; x++) {
            a[x] = 0.5 * (erf((x + 0.5 - xa) * k) - erf((x - 0.5 - xa) * k));
            b[x] = 0.5 * (erf((x + 0.5 - xb) * k) - erf((x - 0.5 - xb) * k));
        }
        if (deform) {
            for (int r = 0; r < MROWS; r++)
                for (int x = 0; x < ML; x++) {
                    fa[r * ML + x] = (float)a[x];
                    fb[r * ML + x] = (float)b[x];
                }
            rpiv_deform_prefilter(fa, ML, MROWS, 1);
            rpiv_deform_prefilter(fb, ML, MROWS, 1);
            for (int x = 0; x < ML; x++) {
                a[x] = (double)rpiv_deform_sample(fa, ML, MROWS, x + c - 0.5 * p, 0.0, 0.0f);
                b[x] = (double)rpiv_deform_sample(fb, ML, MROWS, x + c + 0.5 * p, 0.0, 0.0f);
            }
        }
        for (int l = -MR; l <= MR; l++)
            for (int x = 0; x < ML; x++) {
                const int y = x + k0 + l;
                if (y >= 0 && y < ML)
                    C[l + MR] += a[x] * b[y];
            }
    }
    /* a window of ww px pairs only ww - |k| of its pixels at the shift k (the particles
     * uniform over it): the expected correlation is weighted by 1 - |k| / ww */
    for (int l = -MR; l <= MR && ww > 0; l++) {
        const double f = 1.0 - fabs((double)(k0 + l)) / ww;
        C[l + MR] *= f > 0 ? f : 0;
    }
}

/* The model plane (lags relative to (k0x, k0y) at its origin, circular) and the estimate. */
static int model_est(const unc_model *m, double dx, double dy, double px, double py, rpiv_peak *pk,
                     int *k0x, int *k0y, float plane[MW * MW])
{
    double cx[2 * MR + 1], cy[2 * MR + 1];
    *k0x = (int)lround(dx - px);
    *k0y = (int)lround(dy - py);
    model_1d(m->sx, dx, px, m->deform, m->c, *k0x, m->ww, cx);
    model_1d(m->sy, dy, py, m->deform, m->c, *k0y, m->wh, cy);
    memset(plane, 0, MW * MW * sizeof *plane);
    for (int l = -MR; l <= MR; l++)
        for (int i = -MR; i <= MR; i++)
            plane[((l + MW) % MW) * MW + (i + MW) % MW] = (float)(cx[i + MR] * cy[l + MR]);
    rpiv_peak_find(plane, MW, MW, 0, m->method, pk);
    return pk->fit_ok;
}

int unc_model_bias(const unc_model *m, double dx, double dy, double px, double py, double *bx,
                   double *by)
{
    float plane[MW * MW];
    rpiv_peak pk;
    int k0x, k0y;
    *bx = *by = 0;
    if (!model_est(m, dx, dy, px, py, &pk, &k0x, &k0y, plane))
        return 0;
    *bx = k0x + pk.dx - (dx - px);
    *by = k0y + pk.dy - (dy - py);
    return 1;
}

/* The estimator's curvature of ln c at the model's maximum, x and y: the spline's Hessian
 * diagonal, else the 3-point one (ln c- - 2 ln c0 + ln c+). */
static int model_curv(const unc_model *m, double dx, double dy, double px, double py, double *hx,
                      double *hy)
{
    float plane[MW * MW];
    rpiv_peak pk;
    int k0x, k0y;
    if (!model_est(m, dx, dy, px, py, &pk, &k0x, &k0y, plane))
        return 0;
    const int bi = (pk.ix + MW) % MW, bj = (pk.iy + MW) % MW;
    if (m->method == RPIV_SUBPIXEL_SPLINE) {
        peak_sens s;
        if (peak_spline_sens(plane, MW, MW, bi, bj, pk.dx - pk.ix, pk.dy - pk.iy, &s)) {
            *hx = s.hxx;
            *hy = s.hyy;
            return 1;
        }
    }
    return unc_curv_at(plane, MW, MW, bi, bj, hx, hy);
}

int unc_model_fit(unc_model *m, double hx, double hy, double dx, double dy, double px, double py)
{
    /* the curvature falls monotonically with the particle size: bisection on ln s per axis */
    double want[2] = {hx, hy}, lo[2] = {log(0.15), log(0.15)}, hi[2] = {log(6.0), log(6.0)};
    if (!(hx < 0) || !(hy < 0))
        return 0;
    for (int it = 0; it < 30; it++) {
        m->sx = exp(0.5 * (lo[0] + hi[0]));
        m->sy = exp(0.5 * (lo[1] + hi[1]));
        double h[2];
        if (!model_curv(m, dx, dy, px, py, &h[0], &h[1]))
            return 0;
        for (int a = 0; a < 2; a++) {
            /* more curved than measured: the particle is wider */
            if (h[a] < want[a])
                lo[a] = 0.5 * (lo[a] + hi[a]);
            else
                hi[a] = 0.5 * (lo[a] + hi[a]);
        }
    }
    m->sx = exp(0.5 * (lo[0] + hi[0]));
    m->sy = exp(0.5 * (lo[1] + hi[1]));
    return 1;
}

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The median of x[0..n-1] (n > 0; reordered). */
static double median(double *x, size_t n)
{
    qsort(x, n, sizeof *x, cmp_double);
    return n % 2 ? x[n / 2] : 0.5 * (x[n / 2 - 1] + x[n / 2]);
}

/* Samples of the bias tables over the predictor's period (below). */
#define UNC_TAB 64

void unc_systematic(const rpiv_field *f, int ww, int wh, const float *hx, const float *hy,
                    const double *pu, const double *pv, int deform, double c, float *su, float *sv,
                    int nthreads)
{
    const size_t n = (size_t)f->nx * (size_t)f->ny;
    double *q = malloc(6 * (n ? n : 1) * sizeof *q);
    if (!q)
        return; /* no memory for the term: sigma keeps its random part */
    size_t m = 0;
    for (size_t k = 0; k < n; k++) {
        if (f->flag[k] != RPIV_FLAG_VALID || !(hx[k] < 0) || !(hy[k] < 0))
            continue;
        q[m] = (double)hx[k];
        q[n + m] = (double)hy[k];
        q[2 * n + m] = (double)f->u[k];
        q[3 * n + m] = (double)f->v[k];
        q[4 * n + m] = pu ? pu[k] : deform ? (double)f->u[k] : 0;
        q[5 * n + m] = pv ? pv[k] : deform ? (double)f->v[k] : 0;
        m++;
    }
    double med[6];
    for (int a = 0; a < 6 && m; a++)
        med[a] = median(q + (size_t)a * n, m);
    free(q);
    unc_model md = {0, 0, deform ? c : 0, deform, RPIV_SUBPIXEL_GAUSS, ww, wh};
    if (!m || !unc_model_fit(&md, med[0], med[1], med[2], med[3], med[4], med[5]))
        return;
    /* The bias as a function of one variable per axis, tabulated: with deformation, of the
     * predictor p (frame A is sampled at the fraction c - p/2 and B at c + p/2 of a pixel, so
     * the bias has a period of 2 px in p), the residual d - p taken as 0 (a converged pass;
     * the estimator's own peak locking at the residual is of second order there); without,
     * of the displacement d (period 1 px). The model's axes are separable: one run gives both. */
    const double period = deform ? 2.0 : 1.0;
    double tx[UNC_TAB + 1], ty[UNC_TAB + 1];
#pragma omp parallel for schedule(dynamic, 4) num_threads(nthreads)
    for (int j = 0; j < UNC_TAB; j++) {
        const double t = period * j / UNC_TAB;
        if (!unc_model_bias(&md, t, t, deform ? t : 0, deform ? t : 0, &tx[j], &ty[j]))
            tx[j] = ty[j] = 0;
    }
    tx[UNC_TAB] = tx[0];
    ty[UNC_TAB] = ty[0];
    for (size_t k = 0; k < n; k++) {
        if (f->flag[k] != RPIV_FLAG_VALID)
            continue;
        const double u = (double)f->u[k], v = (double)f->v[k];
        const double kx = deform ? (pu ? pu[k] : u) : u, ky = deform ? (pv ? pv[k] : v) : v;
        double b[2];
        const double key[2] = {kx, ky}, *tab[2] = {tx, ty};
        for (int a = 0; a < 2; a++) {
            /* linear interpolation on the periodic table */
            double x = key[a] / period;
            x = (x - floor(x)) * UNC_TAB;
            int i = (int)x;
            i = i < 0 ? 0 : (i >= UNC_TAB ? UNC_TAB - 1 : i);
            const double w = x - i;
            b[a] = (1 - w) * tab[a][i] + w * tab[a][i + 1];
        }
        su[k] = (float)hypot((double)su[k], b[0]);
        sv[k] = (float)hypot((double)sv[k], b[1]);
    }
}
