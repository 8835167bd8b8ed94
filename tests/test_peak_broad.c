/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The spline sub-pixel estimator (RPIV_SUBPIXEL_SPLINE, src/piv/peak_fit.c) against analytic
 * planes of known continuous maximum: anisotropic and rotated Gaussians of sigma 1-4 px, skew
 * normals, sums of two Gaussians 1-3 px apart. The 3-point Gaussian is measured on the same
 * planes: exact on axis-aligned Gaussians, biased on the rest. Then its fallbacks. */
#include "check.h"
#include "rpiv/peak.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define N 32

typedef double (*fn1)(const double *q, double x);

/* A separable peak g(x) h(y), or a rotated Gaussian. */
typedef struct peak2 {
    fn1 gx, gy;
    double qx[4], qy[4];
    int rotated; /* 1: exp(-1/2 r^T S^-1 r) with sigmas qx[1], qy[1], angle qx[2], centre qx[0],
                    qy[0] */
} peak2;

static double gauss1(const double *q, double x) /* centre q0, sigma q1 */
{
    double t = (x - q[0]) / q[1];
    return exp(-0.5 * t * t);
}

static double skewnorm1(const double *q, double x) /* location q0, scale q1, shape q2 */
{
    double t = (x - q[0]) / q[1];
    return exp(-0.5 * t * t) * 0.5 * erfc(-q[2] * t / sqrt(2.0));
}

static double twogauss1(const double *q, double x) /* centres q0, q0 + q2, sigma q1, ratio q3 */
{
    double a = (x - q[0]) / q[1], b = (x - q[0] - q[2]) / q[1];
    return exp(-0.5 * a * a) + q[3] * exp(-0.5 * b * b);
}

static double eval2(const peak2 *p, double x, double y)
{
    if (!p->rotated)
        return p->gx(p->qx, x) * p->gy(p->qy, y);
    double c = cos(p->qx[2]), s = sin(p->qx[2]);
    double dx = x - p->qx[0], dy = y - p->qy[0];
    double u = (c * dx + s * dy) / p->qx[1], v = (-s * dx + c * dy) / p->qy[1];
    return exp(-0.5 * (u * u + v * v));
}

/* The maximum of a unimodal g near x0 (golden section on [x0 - 3, x0 + 3]). */
static double argmax1(fn1 g, const double *q, double x0)
{
    const double r = (sqrt(5.0) - 1) / 2;
    double a = x0 - 3, b = x0 + 3, c = b - r * (b - a), d = a + r * (b - a);
    double fc = g(q, c), fd = g(q, d);
    while (b - a > 1e-11) {
        if (fc > fd) {
            b = d;
            d = c;
            fd = fc;
            c = b - r * (b - a);
            fc = g(q, c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + r * (b - a);
            fd = g(q, d);
        }
    }
    return (a + b) / 2;
}

/* The plane of p in circular order (values scaled to a peak near 1000), and the errors of
 * the two estimators against its continuous maximum (tx, ty). */
static void measure(const peak2 *p, double tx, double ty, double err[2][2])
{
    static float plane[N * N];
    for (int j = 0; j < N; j++)
        for (int i = 0; i < N; i++) {
            int sx = i < N / 2 ? i : i - N, sy = j < N / 2 ? j : j - N;
            plane[j * N + i] = (float)(1000 * eval2(p, sx, sy));
        }
    const rpiv_subpixel m[2] = {RPIV_SUBPIXEL_GAUSS, RPIV_SUBPIXEL_SPLINE};
    for (int k = 0; k < 2; k++) {
        rpiv_peak pk;
        rpiv_peak_find(plane, N, N, 0, m[k], &pk);
        CHECK(pk.fit_ok);
        err[k][0] = pk.dx - tx;
        err[k][1] = pk.dy - ty;
    }
}

static double amax(const double e[2])
{
    return fmax(fabs(e[0]), fabs(e[1]));
}

/* Sub-pixel positions of the peaks: across a pixel, and a few pixels off the origin. */
static const double OFFS[] = {0.0, 0.13, 0.29, 0.5, 0.71, 0.87, -2.38, 3.61};
#define NOFF (int)(sizeof OFFS / sizeof OFFS[0])

/* Axis-aligned anisotropic Gaussians: both exact (the 3-point Gaussian by construction, the
 * spline because the logarithm is a quadratic); rotated ones: the 3-point fit is biased, the
 * spline is not. */
static void gaussians(void)
{
    const double sig[][2] = {{1, 1}, {2, 1}, {1.5, 3}, {4, 2}, {3, 4}, {4, 4}};
    double wa[2] = {0, 0}, wr[2] = {0, 0};
    for (size_t s = 0; s < sizeof sig / sizeof sig[0]; s++)
        for (int o = 0; o < NOFF; o++) {
            double cx = OFFS[o], cy = -0.6 * OFFS[(o + 3) % NOFF];
            peak2 p = {gauss1, gauss1, {cx, sig[s][0]}, {cy, sig[s][1]}, 0};
            double e[2][2];
            measure(&p, cx, cy, e);
            for (int k = 0; k < 2; k++)
                wa[k] = fmax(wa[k], amax(e[k]));
            /* the same, rotated by 30 degrees */
            peak2 r = {NULL, NULL, {cx, sig[s][0], M_PI / 6}, {cy, sig[s][1]}, 1};
            measure(&r, cx, cy, e);
            for (int k = 0; k < 2; k++)
                wr[k] = fmax(wr[k], amax(e[k]));
        }
    printf("  Gaussians sigma 1-4 px: max |error| gauss %.5f spline %.5f px; rotated 30 deg: "
           "gauss %.4f spline %.5f px\n",
           wa[0], wa[1], wr[0], wr[1]);
    CHECK(wa[0] < 1e-4 && wa[1] < 1e-4);
    CHECK(wr[1] < 0.005);
    CHECK(wr[0] > 0.05); /* the 3-point fit reads only the row and the column */
}

/* Skew-normal peaks in x (a Gaussian in y): the skew normal of scale w and shape a is a
 * Gaussian of sigma s1 = w / sqrt(1 + a^2) (here the particle images' correlation, >= 1 px)
 * convolved with a half-normal of scale s2 = a s1 (the spread of the displacements across
 * the depth, one-sided). s1 = 1-2 px, s2 = 1-4 s1. */
static void skew_normals(void)
{
    const double s1[] = {1, 1.5, 2}, shape[] = {1, 2, 3, 4};
    double worst[2] = {0, 0};
    for (size_t a = 0; a < 3; a++) {
        for (size_t b = 0; b < 4; b++) {
            double w1[2] = {0, 0}, scale = s1[a] * sqrt(1 + shape[b] * shape[b]);
            for (int o = 0; o < NOFF; o++) {
                peak2 p = {skewnorm1, gauss1, {OFFS[o], scale, shape[b]}, {0.31, 1.3}, 0};
                /* the location that puts the maximum at OFFS[o] */
                double m0 = argmax1(skewnorm1, p.qx, OFFS[o]);
                p.qx[0] += OFFS[o] - m0;
                double tx = argmax1(skewnorm1, p.qx, OFFS[o]);
                double e[2][2];
                measure(&p, tx, 0.31, e);
                for (int k = 0; k < 2; k++)
                    w1[k] = fmax(w1[k], amax(e[k]));
            }
            printf("  skew normal s1 %.1f px, s2 %.1f px (scale %.2f, shape %.0f): max |error| "
                   "gauss %.4f spline %.4f px\n",
                   s1[a], s1[a] * shape[b], scale, shape[b], w1[0], w1[1]);
            for (int k = 0; k < 2; k++)
                worst[k] = fmax(worst[k], w1[k]);
            CHECK(w1[1] <= 0.01);
            CHECK(w1[0] > 5 * w1[1]);
        }
    }
    printf("  skew normals: worst gauss %.4f spline %.4f px\n", worst[0], worst[1]);
}

/* Two Gaussians of sigma 1.5-2 px, 1-3 px apart, the second 0.3-0.7 as high (one broad,
 * asymmetric peak). */
static void two_gaussians(void)
{
    const double sig[] = {1.5, 2}, sep[] = {1, 2, 3}, ratio[] = {0.3, 0.7};
    double worst[2] = {0, 0};
    for (size_t a = 0; a < 2; a++)
        for (size_t b = 0; b < 3; b++)
            for (size_t c = 0; c < 2; c++) {
                double w1[2] = {0, 0};
                for (int o = 0; o < NOFF; o++) {
                    peak2 p = {twogauss1, gauss1, {0, sig[a], sep[b], ratio[c]}, {-0.42, 1.1}, 0};
                    double m0 = argmax1(twogauss1, p.qx, OFFS[o]);
                    p.qx[0] += OFFS[o] - m0;
                    double tx = argmax1(twogauss1, p.qx, OFFS[o]);
                    double e[2][2];
                    measure(&p, tx, -0.42, e);
                    for (int k = 0; k < 2; k++)
                        w1[k] = fmax(w1[k], amax(e[k]));
                }
                printf("  two Gaussians sigma %.1f, %.0f px apart, ratio %.1f: max |error| "
                       "gauss %.4f spline %.4f px\n",
                       sig[a], sep[b], ratio[c], w1[0], w1[1]);
                for (int k = 0; k < 2; k++)
                    worst[k] = fmax(worst[k], w1[k]);
                CHECK(w1[1] <= (sep[b] < 3 ? 0.005 : 0.015));
                CHECK(w1[0] >= 3 * w1[1]);
            }
    printf("  two Gaussians: worst gauss %.4f spline %.4f px\n", worst[0], worst[1]);
    CHECK(worst[0] > 3 * worst[1]);
}

/* Fallbacks: a non-positive sample in the 5 x 5 neighbourhood, or a plane too small, gives
 * the 3-point Gaussian (bit for bit); the result does not depend on anything else. */
static void falls_back_to_the_3_point_gaussian(void)
{
    static float plane[N * N];
    peak2 p = {skewnorm1, gauss1, {0.2, 3, 3}, {0.1, 1.2}, 0};
    for (int j = 0; j < N; j++)
        for (int i = 0; i < N; i++) {
            int sx = i < N / 2 ? i : i - N, sy = j < N / 2 ? j : j - N;
            plane[j * N + i] = (float)(1000 * eval2(&p, sx, sy));
        }
    rpiv_peak g, s;
    rpiv_peak_find(plane, N, N, 0, RPIV_SUBPIXEL_SPLINE, &s);
    rpiv_peak_find(plane, N, N, 0, RPIV_SUBPIXEL_GAUSS, &g);
    CHECK(s.fit_ok && g.fit_ok && fabs(s.dx - g.dx) > 0.02); /* the spline did its own fit */
    /* a zero corner sample, at shift (-2, +2) from the integer peak */
    size_t corner = (size_t)((g.iy + 2 + N) % N) * N + (size_t)((g.ix - 2 + N) % N);
    plane[corner] = 0;
    rpiv_peak_find(plane, N, N, 0, RPIV_SUBPIXEL_SPLINE, &s);
    rpiv_peak_find(plane, N, N, 0, RPIV_SUBPIXEL_GAUSS, &g);
    CHECK(s.fit_ok && s.dx == g.dx && s.dy == g.dy);
    plane[corner] = -5;
    rpiv_peak_find(plane, N, N, 0, RPIV_SUBPIXEL_SPLINE, &s);
    CHECK(s.fit_ok && s.dx == g.dx && s.dy == g.dy);
    plane[corner] = NAN;
    rpiv_peak_find(plane, N, N, 0, RPIV_SUBPIXEL_SPLINE, &s);
    CHECK(s.fit_ok && s.dx == g.dx && s.dy == g.dy);
    /* 4 x 4: no 5 x 5 neighbourhood */
    float small[16];
    for (int j = 0; j < 4; j++)
        for (int i = 0; i < 4; i++) {
            int sx = i < 2 ? i : i - 4, sy = j < 2 ? j : j - 4;
            small[j * 4 + i] = (float)eval2(&p, sx, sy);
        }
    rpiv_peak_find(small, 4, 4, 0, RPIV_SUBPIXEL_SPLINE, &s);
    rpiv_peak_find(small, 4, 4, 0, RPIV_SUBPIXEL_GAUSS, &g);
    CHECK(s.fit_ok && s.dx == g.dx && s.dy == g.dy);
    /* a flat plane: no fit either way */
    for (int k = 0; k < N * N; k++)
        plane[k] = 1;
    rpiv_peak_find(plane, N, N, 0, RPIV_SUBPIXEL_SPLINE, &s);
    CHECK(!s.fit_ok && s.dx == s.ix && s.dy == s.iy);
    /* AUTO: gauss on a pair, spline on a sum */
    CHECK(rpiv_subpixel_resolve(RPIV_SUBPIXEL_AUTO, 0) == RPIV_SUBPIXEL_GAUSS);
    CHECK(rpiv_subpixel_resolve(RPIV_SUBPIXEL_AUTO, 1) == RPIV_SUBPIXEL_SPLINE);
    CHECK(rpiv_subpixel_resolve(RPIV_SUBPIXEL_PARABOLA, 1) == RPIV_SUBPIXEL_PARABOLA);
    CHECK(!strcmp(rpiv_subpixel_names[RPIV_SUBPIXEL_SPLINE], "spline"));
    CHECK(!strcmp(rpiv_subpixel_names[RPIV_SUBPIXEL_AUTO], "auto"));
}

int main(void)
{
    RUN_TEST(gaussians);
    RUN_TEST(skew_normals);
    RUN_TEST(two_gaussians);
    RUN_TEST(falls_back_to_the_3_point_gaussian);
    return check_summary();
}
