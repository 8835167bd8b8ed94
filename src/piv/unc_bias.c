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
#include "deform_impl.h"
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

/* ---- the image's edge (docs/uncertainty.md, "The image's edge") ------------------------- */

enum {
    EL = 256,  /* longest model frame, px */
    EPOS = 2,  /* particle positions per px */
    ELEAK = 12 /* px over which the prefilter's mirror boundary reaches (0.268^12 ~ 1e-7) */
};

/* One axis of a window of ww px whose first pixel is o px from the frame's first: the part of
 * the expected correlation at lags k0 - MR .. k0 + MR contributed by the particles within
 * `span` px of the window's first pixel (from `reach` px before it), EPOS per px, each
 * pixel-integrated (s px) and cut by the frame as the camera cuts it, at x - d/2 and x + d/2;
 * both frames turned into B-spline coefficients (mirror boundaries) and sampled at
 * x + c -+ p/2 as rpiv_deform_run does, a pixel whose either sample it does not take
 * (deform_takes: within 1 px of the frame's edge) adding nothing (it takes the frame's mean), the
 * pairs of pixels within the window (the circular correlation's other pairs are unrelated
 * particles). The model frame ends a few px beyond what these particles reach (the same place
 * relative to the window whatever o, so that end cancels between two o). 0 if it would be longer
 * than EL. */
static int edge_part(double s, double d, double p, double c, int o, int ww, int k0, double reach,
                     double span, double C[2 * MR + 1])
{
    int Y = (int)ceil(span + reach) + 2;
    Y = Y < ww ? Y : ww;
    const int L = o + Y + (int)ceil(0.5 * fabs(p) + fabs(c)) + ELEAK;
    if (L > EL)
        return 0;
    float fa[EL], fb[EL];
    double ta[EL], tb[EL], a[EL], b[EL];
    int ok[EL];
    const double k = 1.0 / (sqrt(2.0) * s);
    for (int y = 0; y < Y; y++) {
        ta[y] = o + y + c - 0.5 * p;
        tb[y] = o + y + c + 0.5 * p;
        ok[y] = deform_takes(ta[y], L) && deform_takes(tb[y], L);
    }
    memset(C, 0, (2 * MR + 1) * sizeof *C);
    const int np = (int)ceil((span + reach) * EPOS);
    for (int q = 0; q < np; q++) {
        const double xm = o - reach + (q + 0.5) / EPOS;
        const double xc[2] = {xm - 0.5 * d, xm + 0.5 * d};
        float *fr[2] = {fa, fb};
        for (int f = 0; f < 2; f++) {
            memset(fr[f], 0, (size_t)L * sizeof *fr[f]);
            const int x0 = (int)floor(xc[f] - 4 * s - 1), x1 = (int)ceil(xc[f] + 4 * s + 1);
            for (int x = x0 > 0 ? x0 : 0; x <= x1 && x < L; x++)
                fr[f][x] = (float)(0.5 * (erf((x + 0.5 - xc[f]) * k) - erf((x - 0.5 - xc[f]) * k)));
        }
        rpiv_deform_prefilter(fa, L, 1, 1);
        rpiv_deform_prefilter(fb, L, 1, 1);
        for (int y = 0; y < Y; y++) {
            a[y] = ok[y] ? (double)rpiv_deform_sample(fa, L, 1, ta[y], 0.0, 0.0f) : 0;
            b[y] = ok[y] ? (double)rpiv_deform_sample(fb, L, 1, tb[y], 0.0, 0.0f) : 0;
        }
        for (int l = -MR; l <= MR; l++) {
            double t = 0;
            for (int y = 0; y < Y; y++) {
                const int z = y + k0 + l;
                if (z >= 0 && z < Y)
                    t += a[y] * b[z];
            }
            C[l + MR] += t;
        }
    }
    return 1;
}

/* The estimate of the plane cx (x) cy (lags -MR .. MR about 0). */
static int plane_est(const double cx[2 * MR + 1], const double cy[2 * MR + 1], rpiv_subpixel method,
                     double *ex, double *ey)
{
    float plane[MW * MW];
    rpiv_peak pk;
    memset(plane, 0, sizeof plane);
    for (int l = -MR; l <= MR; l++)
        for (int i = -MR; i <= MR; i++)
            plane[((l + MW) % MW) * MW + (i + MW) % MW] = (float)(cx[i + MR] * cy[l + MR]);
    rpiv_peak_find(plane, MW, MW, 0, method, &pk);
    *ex = pk.dx;
    *ey = pk.dy;
    return pk.fit_ok;
}

/* The image edge's share of the systematic error of one window, per axis (added to the bias
 * of a window far from it): lo[a], hi[a] the window's distance (px) from the frame's first
 * and last pixel along axis a; p the predictor (the pass converged: d = p). Only where the
 * window's samples or its particles' images reach the frame's edge. The window's expected
 * correlation far from the edge is model_1d's (its 16 phases a density of MPH particles per
 * px, the window's EPOS); near it, the particles within reach of the edge contribute
 * differently: edge_part at the window's distance minus edge_part far from any edge. The
 * last pixel's side is the first's with the axis reversed (x -> -x: d, p and c change sign,
 * and so does the estimate). */
static void edge_bias(const unc_model *m, const int lo[2], const int hi[2], const double p[2],
                      double out[2])
{
    const double s[2] = {m->sx, m->sy};
    const int w[2] = {m->ww, m->wh};
    int near[2][2];
    double reach[2];
    out[0] = out[1] = 0;
    for (int a = 0; a < 2; a++) {
        reach[a] = 0.5 * fabs(p[a]) + fabs(m->c) + 3 * s[a] + 2;
        near[a][0] = lo[a] < reach[a];
        near[a][1] = hi[a] < reach[a];
    }
    for (int a = 0; a < 2; a++)
        for (int side = 0; side < 2; side++) {
            if (!near[a][side] || w[a] <= 0 || w[1 - a] <= 0)
                continue;
            const int o = 1 - a;
            const double sg = side ? -1 : 1, span = reach[a] + ELEAK;
            const int ofar = (int)ceil(reach[a]) + ELEAK;
            double cf[2][2 * MR + 1], ce[2][2 * MR + 1], pe[2 * MR + 1], pf[2 * MR + 1], ef[2],
                ee[2];
            model_1d(s[o], p[o], p[o], 1, m->c, 0, w[o], cf[o]);
            model_1d(s[a], sg * p[a], sg * p[a], 1, sg * m->c, 0, w[a], cf[a]);
            if (!edge_part(s[a], sg * p[a], sg * p[a], sg * m->c, side ? hi[a] : lo[a], w[a], 0,
                           reach[a], span, pe) ||
                !edge_part(s[a], sg * p[a], sg * p[a], sg * m->c, ofar, w[a], 0, reach[a], span,
                           pf))
                continue;
            const double scale = (double)w[a] * EPOS / MPH;
            memcpy(ce[o], cf[o], sizeof cf[o]);
            for (int l = 0; l <= 2 * MR; l++) {
                cf[a][l] *= scale;
                ce[a][l] = cf[a][l] + pe[l] - pf[l];
            }
            if (plane_est(cf[0], cf[1], m->method, &ef[0], &ef[1]) &&
                plane_est(ce[0], ce[1], m->method, &ee[0], &ee[1]))
                out[a] += sg * (ee[a] - ef[a]);
        }
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
/* Sub-samples of a window per axis for the average over its pixels' predictors. */
#define UNC_SUB 8

/* The periodic table tab (UNC_TAB + 1 samples over period) at x, linearly interpolated. */
static double tab_at(const double *tab, double period, double x)
{
    x /= period;
    x = (x - floor(x)) * UNC_TAB;
    int i = (int)x;
    i = i < 0 ? 0 : (i >= UNC_TAB ? UNC_TAB - 1 : i);
    const double w = x - i;
    return (1 - w) * tab[i] + w * tab[i + 1];
}

/* The mean of tab over a window of w x h px whose key varies linearly across it, key0 at its
 * centre, gradients gx, gy (per px): the window's plane sums its pixels' correlations, each
 * with the predictor at that pixel, so its bias and its curvature are (to first order) those
 * of its pixels, averaged. */
static double tab_window(const double *tab, double period, double key0, double gx, double gy, int w,
                         int h)
{
    double s = 0;
    for (int j = 0; j < UNC_SUB; j++)
        for (int i = 0; i < UNC_SUB; i++) {
            const double x = ((i + 0.5) / UNC_SUB - 0.5) * w, y = ((j + 0.5) / UNC_SUB - 0.5) * h;
            s += tab_at(tab, period, key0 + gx * x + gy * y);
        }
    return s / (UNC_SUB * UNC_SUB);
}

/* The gradient (per px) of g at node (i, j) of an nx x ny grid of steps dx, dy px: central
 * differences of the valid neighbours, one-sided where one is missing, 0 where both are. */
static void node_grad(const double *g, const rpiv_field *f, int i, int j, double *gx, double *gy)
{
    const int nx = f->nx, ny = f->ny;
#define OK(a, b)                                                                                   \
    ((a) >= 0 && (a) < nx && (b) >= 0 && (b) < ny &&                                               \
     f->flag[(size_t)(b) * (size_t)nx + (size_t)(a)] == RPIV_FLAG_VALID)
#define G(a, b) g[(size_t)(b) * (size_t)nx + (size_t)(a)]
    const int l = OK(i - 1, j), r = OK(i + 1, j), d = OK(i, j - 1), u = OK(i, j + 1);
    *gx = l && r ? (G(i + 1, j) - G(i - 1, j)) / (2 * f->dx)
          : r    ? (G(i + 1, j) - G(i, j)) / f->dx
          : l    ? (G(i, j) - G(i - 1, j)) / f->dx
                 : 0;
    *gy = d && u ? (G(i, j + 1) - G(i, j - 1)) / (2 * f->dy)
          : u    ? (G(i, j + 1) - G(i, j)) / f->dy
          : d    ? (G(i, j) - G(i, j - 1)) / f->dy
                 : 0;
#undef OK
#undef G
}

void unc_systematic(const rpiv_field *f, int ww, int wh, const float *hx, const float *hy,
                    const double *pu, const double *pv, int deform, double c, const int *frame,
                    float *su, float *sv, int nthreads)
{
    const size_t n = (size_t)f->nx * (size_t)f->ny;
    /* q: 6 columns for the medians, then the keys (the predictor with deformation, else the
     * displacement; period 2 and 1 px) and their gradients, u and v */
    double *q = malloc(12 * (n ? n : 1) * sizeof *q);
    if (!q)
        return; /* no memory for the term: sigma keeps its random part */
    double *key[2] = {q + 6 * n, q + 7 * n}, *grad = q + 8 * n; /* grad: [4 k + 2 a + axis] */
    for (size_t k = 0; k < n; k++) {
        key[0][k] = deform ? (pu ? pu[k] : (double)f->u[k]) : (double)f->u[k];
        key[1][k] = deform ? (pv ? pv[k] : (double)f->v[k]) : (double)f->v[k];
    }
    for (int j = 0; j < f->ny; j++)
        for (int i = 0; i < f->nx; i++) {
            const size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
            for (int a = 0; a < 2; a++)
                node_grad(key[a], f, i, j, &grad[4 * k + 2 * a], &grad[4 * k + 2 * a + 1]);
        }
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
    for (int a = 2; a < 6 && m; a++)
        med[a] = median(q + (size_t)a * n, m);
    const double period = deform ? 2.0 : 1.0;
    unc_model md = {0, 0, deform ? c : 0, deform, RPIV_SUBPIXEL_GAUSS, ww, wh};
    /* The measured curvature depends on the predictor too (the interpolator smooths each frame
     * by its sampling fraction, c -+ p/2): each window's is brought to the medians' predictor
     * with the model's own dependence at a first fit's width, and the width refitted to the
     * median of those. */
    double ch[2][UNC_TAB + 1] = {{0}}, chref[2] = {0, 0};
    int ok = m > 0;
    for (int round = 0; round < 2 && ok; round++) {
        size_t mm = 0;
        for (size_t k = 0; k < n; k++) {
            if (f->flag[k] != RPIV_FLAG_VALID || !(hx[k] < 0) || !(hy[k] < 0))
                continue;
            double h[2] = {(double)hx[k], (double)hy[k]};
            for (int a = 0; a < 2 && round; a++)
                h[a] -= tab_window(ch[a], period, key[a][k], grad[4 * k + 2 * a],
                                   grad[4 * k + 2 * a + 1], ww, wh) -
                        chref[a];
            q[mm] = h[0];
            q[n + mm] = h[1];
            mm++;
        }
        med[0] = median(q, mm);
        med[1] = median(q + n, mm);
        if (!(ok = unc_model_fit(&md, med[0], med[1], med[2], med[3], med[4], med[5])))
            break;
        if (round)
            break;
        int bad = 0;
#pragma omp parallel for schedule(dynamic, 4) num_threads(nthreads) reduction(| : bad)
        for (int j = 0; j < UNC_TAB; j++) {
            const double t = period * j / UNC_TAB;
            if (!model_curv(&md, t, t, deform ? t : 0, deform ? t : 0, &ch[0][j], &ch[1][j]))
                bad = 1;
        }
        ch[0][UNC_TAB] = ch[0][0];
        ch[1][UNC_TAB] = ch[1][0];
        /* the medians' own key (the fit's predictor, or displacement without deformation) */
        chref[0] = tab_at(ch[0], period, deform ? med[4] : med[2]);
        chref[1] = tab_at(ch[1], period, deform ? med[5] : med[3]);
        if (bad)
            break; /* keep the first fit */
    }
    if (!ok) {
        free(q);
        return;
    }
    /* The bias as a function of one variable per axis, tabulated: with deformation, of the
     * predictor p (frame A is sampled at the fraction c - p/2 and B at c + p/2 of a pixel, so
     * the bias has a period of 2 px in p), the residual d - p taken as 0 (a converged pass;
     * the estimator's own peak locking at the residual is of second order there); without,
     * of the displacement d (period 1 px). The model's axes are separable: one run gives both.
     * Each window's bias is the table's mean over its pixels' predictors. */
    double tx[UNC_TAB + 1], ty[UNC_TAB + 1];
#pragma omp parallel for schedule(dynamic, 4) num_threads(nthreads)
    for (int j = 0; j < UNC_TAB; j++) {
        const double t = period * j / UNC_TAB;
        if (!unc_model_bias(&md, t, t, deform ? t : 0, deform ? t : 0, &tx[j], &ty[j]))
            tx[j] = ty[j] = 0;
    }
    tx[UNC_TAB] = tx[0];
    ty[UNC_TAB] = ty[0];
    /* with the frame known, a window near the image's edge adds the edge's share (edge_bias) */
#pragma omp parallel for schedule(dynamic, 4) num_threads(nthreads)
    for (size_t k = 0; k < n; k++) {
        if (f->flag[k] != RPIV_FLAG_VALID)
            continue;
        double eb[2] = {0, 0};
        if (frame && deform) {
            const int i = (int)(k % (size_t)f->nx), j = (int)(k / (size_t)f->nx);
            const int lo[2] = {frame[2] + i * frame[4], frame[3] + j * frame[5]};
            const int hi[2] = {frame[0] - lo[0] - ww, frame[1] - lo[1] - wh};
            const double p[2] = {key[0][k], key[1][k]};
            edge_bias(&md, lo, hi, p, eb);
        }
        const double bx =
            tab_window(tx, period, key[0][k], grad[4 * k], grad[4 * k + 1], ww, wh) + eb[0];
        const double by =
            tab_window(ty, period, key[1][k], grad[4 * k + 2], grad[4 * k + 3], ww, wh) + eb[1];
        su[k] = (float)hypot((double)su[k], bx);
        sv[k] = (float)hypot((double)sv[k], by);
    }
    free(q);
}
