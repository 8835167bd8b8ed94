/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/peak_fit.c - the "spline" sub-pixel estimator: the continuous maximum of a cubic
 * spline through the logarithm of the 7 x 7 (else 5 x 5) samples around the integer peak
 * (docs/piv.md, "Peak").
 *
 * Along each axis the interpolant is the not-a-knot cubic spline through n = 7 (or 5)
 * unit-spaced nodes -r..r; in 2-D the tensor product of two of them,
 * f(x, y) = sum_ij wy_j(y) L_ji wx_i(x), with L = ln(c / c0) the samples' logarithm. The spline
 * reproduces cubics exactly, hence the logarithm of a Gaussian of any width and orientation (a
 * quadratic): no 3-point bias there; on a broad or skewed peak it follows the shape over 7
 * samples instead of 3 and its maximum tracks the continuous one (tests/test_peak_broad.c). */
#include "peak_impl.h"

#include <math.h>
#include <stddef.h>

#define NMAX (2 * PEAK_SPLINE_R + 1)

/* The second derivatives M = A y of the not-a-knot spline through y_0..y_n-1 (unit spacing):
 * the rows M_i-1 + 4 M_i + M_i+1 = 6 (y_i-1 - 2 y_i + y_i+1), i = 1..n-2, and the third
 * derivative continuous at nodes 1 and n-2 (M_0 - 2 M_1 + M_2 = 0, likewise at the end),
 * solved once for each unit vector y (exact rationals). */
static const double A5[5][5] = {{9 / 4.0, -24 / 4.0, 22 / 4.0, -8 / 4.0, 1 / 4.0},
                                {1, -2, 1, 0, 0},
                                {-1 / 4.0, 8 / 4.0, -14 / 4.0, 8 / 4.0, -1 / 4.0},
                                {0, 0, 1, -2, 1},
                                {1 / 4.0, -8 / 4.0, 22 / 4.0, -24 / 4.0, 9 / 4.0}};
static const double A7[7][7] = {
    {127 / 56.0, -344 / 56.0, 331 / 56.0, -144 / 56.0, 37 / 56.0, -8 / 56.0, 1 / 56.0},
    {1, -2, 1, 0, 0, 0, 0},
    {-15 / 56.0, 120 / 56.0, -219 / 56.0, 144 / 56.0, -37 / 56.0, 8 / 56.0, -1 / 56.0},
    {4 / 56.0, -32 / 56.0, 148 / 56.0, -240 / 56.0, 148 / 56.0, -32 / 56.0, 4 / 56.0},
    {-1 / 56.0, 8 / 56.0, -37 / 56.0, 144 / 56.0, -219 / 56.0, 120 / 56.0, -15 / 56.0},
    {0, 0, 0, 0, 1, -2, 1},
    {1 / 56.0, -8 / 56.0, 37 / 56.0, -144 / 56.0, 331 / 56.0, -344 / 56.0, 127 / 56.0}};

static double amat(int n, int i, int k)
{
    return n == 7 ? A7[i][k] : A5[i][k];
}

/* The weights of the n node values giving the spline's value, first and second derivatives
 * at x (offset from the centre node, -r..r). On the interval [k, k+1] (node indices),
 * t = x + r - k: s = (1-t) y_k + t y_k+1 + ((1-t)^3 - (1-t))/6 M_k + (t^3 - t)/6 M_k+1. */
static void weights(int n, double x, double w[NMAX], double wd[NMAX], double wdd[NMAX])
{
    double u = x + (n - 1) / 2;
    int k = (int)floor(u);
    k = k < 0 ? 0 : (k > n - 2 ? n - 2 : k);
    double t = u - k, s = 1 - t;
    double a = (s * s * s - s) / 6, b = (t * t * t - t) / 6;
    double ad = (1 - 3 * s * s) / 6, bd = (3 * t * t - 1) / 6;
    for (int i = 0; i < n; i++) {
        w[i] = a * amat(n, k, i) + b * amat(n, k + 1, i);
        wd[i] = ad * amat(n, k, i) + bd * amat(n, k + 1, i);
        wdd[i] = s * amat(n, k, i) + t * amat(n, k + 1, i);
    }
    w[k] += s;
    w[k + 1] += t;
    wd[k] -= 1;
    wd[k + 1] += 1;
}

/* f, its gradient (gx, gy) and Hessian (hxx, hxy, hyy) at (x, y). */
static void eval(int n, double L[NMAX][NMAX], double x, double y, double *f, double g[2],
                 double h[3])
{
    double wx[NMAX], wxd[NMAX], wxdd[NMAX], wy[NMAX], wyd[NMAX], wydd[NMAX];
    weights(n, x, wx, wxd, wxdd);
    weights(n, y, wy, wyd, wydd);
    double v = 0, gx = 0, gy = 0, hxx = 0, hxy = 0, hyy = 0;
    for (int j = 0; j < n; j++) {
        double r = 0, rd = 0, rdd = 0; /* row j combined along x: value, d/dx, d2/dx2 */
        for (int i = 0; i < n; i++) {
            r += L[j][i] * wx[i];
            rd += L[j][i] * wxd[i];
            rdd += L[j][i] * wxdd[i];
        }
        v += wy[j] * r;
        gx += wy[j] * rd;
        gy += wyd[j] * r;
        hxx += wy[j] * rdd;
        hxy += wyd[j] * rd;
        hyy += wydd[j] * r;
    }
    *f = v;
    g[0] = gx;
    g[1] = gy;
    h[0] = hxx;
    h[1] = hxy;
    h[2] = hyy;
}

/* The plane's sample at (col, row), one period away at most: the plane is circular. */
static double sample(const float *plane, int w, int h, int col, int row)
{
    row = row < 0 ? row + h : (row >= h ? row - h : row);
    col = col < 0 ? col + w : (col >= w ? col - w : col);
    return (double)plane[(size_t)row * (size_t)w + (size_t)col];
}

/* The logarithms of the n x n samples around (bi, bj) relative to the centre; 0 if one of
 * them is not positive or not finite. */
static int logs(const float *plane, int w, int h, int bi, int bj, int n, double L[NMAX][NMAX])
{
    int r = (n - 1) / 2;
    if (w < n || h < n)
        return 0;
    double c0 = (double)plane[(size_t)bj * (size_t)w + (size_t)bi];
    if (!(c0 > 0) || !isfinite(c0))
        return 0;
    for (int j = 0; j < n; j++) {
        for (int i = 0; i < n; i++) {
            double v = sample(plane, w, h, bi + i - r, bj + j - r);
            if (!(v > 0) || !isfinite(v))
                return 0;
            L[j][i] = log(v / c0);
        }
    }
    return 1;
}

/* Newton's method on the spline through L from (x, y); 1 and the maximum on success. */
static int newton(int n, double L[NMAX][NMAX], double x, double y, double *fx, double *fy)
{
    enum { MAX_IT = 40 };
    const double max_step = 0.25, tol = 1e-9;
    for (int it = 0; it < MAX_IT; it++) {
        double f, g[2], H[3];
        eval(n, L, x, y, &f, g, H);
        double det = H[0] * H[2] - H[1] * H[1], sx, sy;
        if (H[0] < 0 && det > 0) { /* Newton's step to the stationary point */
            sx = -(H[2] * g[0] - H[1] * g[1]) / det;
            sy = -(H[0] * g[1] - H[1] * g[0]) / det;
        } else { /* not concave here: uphill along the gradient */
            double gn = hypot(g[0], g[1]);
            if (!(gn > 0))
                return 0;
            sx = max_step * g[0] / gn;
            sy = max_step * g[1] / gn;
        }
        double sn = fmax(fabs(sx), fabs(sy));
        if (!isfinite(sn))
            return 0;
        if (sn > max_step) {
            sx *= max_step / sn;
            sy *= max_step / sn;
        }
        x += sx;
        y += sy;
        if (!(fabs(x) <= 1.5 && fabs(y) <= 1.5))
            return 0; /* the maximum is not near the integer peak */
        if (sn < tol) {
            eval(n, L, x, y, &f, g, H);
            /* a maximum, within 1 px, at least as high as the integer peak (L = 0 there) */
            if (!(H[0] < 0 && H[0] * H[2] - H[1] * H[1] > 0) || !(f >= 0) || fabs(x) > 1 ||
                fabs(y) > 1)
                return 0;
            *fx = x;
            *fy = y;
            return 1;
        }
    }
    return 0;
}

int peak_fit_spline(const float *plane, int w, int h, int bi, int bj, double x0, double y0,
                    double *fx, double *fy)
{
    double L[NMAX][NMAX];
    *fx = 0;
    *fy = 0;
    double x = isfinite(x0) && fabs(x0) <= 1 ? x0 : 0, y = isfinite(y0) && fabs(y0) <= 1 ? y0 : 0;
    for (int n = NMAX; n >= 5; n -= 2)
        if (logs(plane, w, h, bi, bj, n, L))
            return newton(n, L, x, y, fx, fy);
    return 0;
}

int peak_spline_sens(const float *plane, int w, int h, int bi, int bj, double fx, double fy,
                     peak_sens *out)
{
    double L[NMAX][NMAX];
    int n = 0;
    for (int m = NMAX; m >= 5 && !n; m -= 2)
        if (logs(plane, w, h, bi, bj, m, L))
            n = m;
    if (!n)
        return 0;
    double f, g[2], H[3];
    eval(n, L, fx, fy, &f, g, H);
    const double det = H[0] * H[2] - H[1] * H[1];
    if (!(H[0] < 0 && det > 0))
        return 0;
    /* (fx, fy) must be the spline's maximum (Newton's step from it below 1e-6 px) */
    const double ix = H[2] / det, ixy = -H[1] / det, iy = H[0] / det; /* H^-1 */
    if (!(fabs(ix * g[0] + ixy * g[1]) < 1e-6 && fabs(ixy * g[0] + iy * g[1]) < 1e-6))
        return 0;
    double wx[NMAX], wxd[NMAX], wxdd[NMAX], wy[NMAX], wyd[NMAX], wydd[NMAX];
    weights(n, fx, wx, wxd, wxdd);
    weights(n, fy, wy, wyd, wydd);
    const int r = (n - 1) / 2;
    out->n = n;
    out->hxx = H[0];
    out->hxy = H[1];
    out->hyy = H[2];
    for (int j = 0; j < n; j++) {
        for (int i = 0; i < n; i++) {
            const double c = sample(plane, w, h, bi + i - r, bj + j - r);
            /* d g / d c_ji: g is linear in L, dL_ji = dc_ji / c_ji - dc_0 / c_0, and the
             * weights of each gradient component sum to 0 (the spline's slope of a constant) */
            const double gx = wy[j] * wxd[i] / c, gy = wyd[j] * wx[i] / c;
            out->jx[j * n + i] = -(ix * gx + ixy * gy);
            out->jy[j * n + i] = -(ixy * gx + iy * gy);
        }
    }
    return 1;
}
