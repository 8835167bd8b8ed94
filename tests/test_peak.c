/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "check.h"
#include "rpiv/peak.h"

#include <string.h>

enum { W = 32, H = 24 };

static int shift(int i, int n)
{
    return i < n / 2 ? i : i - n;
}

/* A plane in circular order holding amp * exp(-((sx-x0)^2 + (sy-y0)^2) / (2 s^2)), the
 * circular distance being used so that peaks near the plane's edge wrap. */
static void add_gauss(float *p, double x0, double y0, double s, double amp)
{
    for (int j = 0; j < H; j++)
        for (int i = 0; i < W; i++) {
            double dx = shift(i, W) - x0, dy = shift(j, H) - y0;
            dx -= W * round(dx / W);
            dy -= H * round(dy / H);
            p[j * W + i] += (float)(amp * exp(-(dx * dx + dy * dy) / (2 * s * s)));
        }
}

static void peak_gauss3_is_exact_on_a_gaussian(void)
{
    const double xs[][2] = {{3.3187, -2.7413}, {-0.4173, 0.2861}, {-7.0912, 5.4999}};
    for (int k = 0; k < 3; k++) {
        float p[W * H] = {0};
        add_gauss(p, xs[k][0], xs[k][1], 1.137, 0.8713);
        rpiv_peak pk;
        rpiv_peak_find(p, W, H, 0, RPIV_SUBPIXEL_GAUSS, &pk);
        CHECK(pk.fit_ok);
        CHECK_NEAR(pk.dx, xs[k][0], 2e-5);
        CHECK_NEAR(pk.dy, xs[k][1], 2e-5);
        CHECK(pk.ix == (int)lround(xs[k][0]) && pk.iy == (int)lround(xs[k][1]));
    }
}

/* Near zero shift the neighbours wrap to the far side of the plane. */
static void peak_neighbours_wrap_around(void)
{
    float p[W * H] = {0};
    add_gauss(p, -0.3129, 0.2217, 0.9, 1.0);
    rpiv_peak pk;
    rpiv_peak_find(p, W, H, 0, RPIV_SUBPIXEL_GAUSS, &pk);
    CHECK(pk.ix == 0 && pk.iy == 0);
    CHECK_NEAR(pk.dx, -0.3129, 2e-5);
    CHECK_NEAR(pk.dy, 0.2217, 2e-5);
}

static void peak_parabola_is_exact_on_a_parabola_and_biased_on_a_gaussian(void)
{
    float p[W * H];
    const double x0 = 1.2713, y0 = -3.4092;
    for (int j = 0; j < H; j++)
        for (int i = 0; i < W; i++) {
            double dx = shift(i, W) - x0, dy = shift(j, H) - y0;
            p[j * W + i] = (float)(50.0 - dx * dx - 0.5 * dy * dy);
        }
    rpiv_peak pk;
    rpiv_peak_find(p, W, H, 0, RPIV_SUBPIXEL_PARABOLA, &pk);
    CHECK_NEAR(pk.dx, x0, 1e-5);
    CHECK_NEAR(pk.dy, y0, 1e-5);

    /* on a Gaussian of sigma 1 the parabola is pulled towards the integer (peak locking) */
    float g[W * H] = {0};
    add_gauss(g, 0.2891, 0, 1.0, 1.0);
    rpiv_peak_find(g, W, H, 0, RPIV_SUBPIXEL_PARABOLA, &pk);
    double bias = pk.dx - 0.2891;
    CHECK(bias < -0.01 && bias > -0.1);
}

/* The 3x3 centroid of a separable Gaussian equals the 1-D three-sample centroid. */
static void peak_centroid_matches_analytic_value(void)
{
    const double x0 = 0.2417, y0 = -0.1388, s = 0.8;
    float p[W * H] = {0};
    add_gauss(p, x0, y0, s, 1.0);
    rpiv_peak pk;
    rpiv_peak_find(p, W, H, 0, RPIV_SUBPIXEL_CENTROID, &pk);
#define G(t) exp(-(t) * (t) / (2 * s * s))
    double ex = (G(1 - x0) - G(-1 - x0)) / (G(-1 - x0) + G(-x0) + G(1 - x0));
    double ey = (G(1 - y0) - G(-1 - y0)) / (G(-1 - y0) + G(-y0) + G(1 - y0));
#undef G
    CHECK_NEAR(pk.dx, ex, 1e-6);
    CHECK_NEAR(pk.dy, ey, 1e-6);
    CHECK(fabs(pk.dx) < fabs(x0)); /* the centroid is biased towards the integer */
}

static void peak_ratio_of_two_peaks(void)
{
    float p[W * H] = {0};
    add_gauss(p, 4, -3, 0.7, 0.9137);
    add_gauss(p, -9, 6, 0.7, 0.3511);
    rpiv_peak pk;
    rpiv_peak_find(p, W, H, 0, RPIV_SUBPIXEL_GAUSS, &pk);
    CHECK(pk.ix == 4 && pk.iy == -3);
    CHECK_NEAR(pk.value, 0.9137, 1e-6);
    CHECK_NEAR(pk.second, 0.3511, 1e-6);
    CHECK_NEAR(pk.ratio, 0.9137 / 0.3511, 1e-5);
    /* the shoulder of the first peak (within 2 px) is not a second peak */
    float q[W * H] = {0};
    add_gauss(q, 4, -3, 2.5, 1.0);
    rpiv_peak_find(q, W, H, 0, RPIV_SUBPIXEL_GAUSS, &pk);
    CHECK(pk.second < 1e-3f || pk.ratio > 100);
}

/* The highest value outside the first peak's 5x5 neighbourhood is the flank of a broad first
 * peak, not a peak: the second peak is the lower, separate one. */
static void peak_second_peak_is_a_local_maximum(void)
{
    float p[W * H] = {0};
    add_gauss(p, 2, 1, 2.6, 1.0);
    add_gauss(p, -10, -8, 0.8, 0.2713);
    rpiv_peak pk;
    rpiv_peak_find(p, W, H, 0, RPIV_SUBPIXEL_GAUSS, &pk);
    CHECK(pk.ix == 2 && pk.iy == 1);
    CHECK_NEAR(pk.second, 0.2713, 1e-4);
    CHECK_NEAR(pk.ratio, 1.0 / 0.2713, 2e-3);
    /* and a plane with only the broad peak has no second peak above its far tails */
    float q[W * H] = {0};
    add_gauss(q, -3, 4, 2.6, 1.0);
    rpiv_peak_find(q, W, H, 0, RPIV_SUBPIXEL_GAUSS, &pk);
    CHECK(pk.second < 1e-3f);
}

static void peak_search_range_is_honoured(void)
{
    float p[W * H] = {0};
    add_gauss(p, 10, 0, 0.7, 1.0);        /* higher, but outside |s| <= 6 */
    add_gauss(p, 2.2389, -1.1, 0.9, 0.5); /* inside */
    rpiv_peak pk;
    rpiv_peak_find(p, W, H, 6, RPIV_SUBPIXEL_GAUSS, &pk);
    CHECK(pk.ix == 2 && pk.iy == -1);
    CHECK_NEAR(pk.dx, 2.2389, 1e-3);
    rpiv_peak_find(p, W, H, 0, RPIV_SUBPIXEL_GAUSS, &pk);
    CHECK(pk.ix == 10 && pk.iy == 0);
}

static void peak_flat_plane_reports_failed_fit(void)
{
    float p[W * H];
    for (int i = 0; i < W * H; i++)
        p[i] = 0.25f;
    rpiv_peak pk;
    rpiv_peak_find(p, W, H, 0, RPIV_SUBPIXEL_GAUSS, &pk);
    CHECK(!pk.fit_ok);
    CHECK(pk.dx == pk.ix && pk.dy == pk.iy);
    int ok = 1;
    CHECK(rpiv_peak_fit3(1, -1, 1, RPIV_SUBPIXEL_PARABOLA, &ok) == 0 && !ok);
    CHECK(rpiv_peak_fit3((double)NAN, 1, 0.5, RPIV_SUBPIXEL_GAUSS, &ok) == 0 && !ok);
    /* Gaussian with a negative neighbour falls back to the parabola */
    CHECK_NEAR(rpiv_peak_fit3(-0.1, 1, 0.3, RPIV_SUBPIXEL_GAUSS, &ok),
               (-0.1 - 0.3) / (2 * (-0.1 - 2 + 0.3)), 1e-12);
    CHECK(ok);
}

int main(void)
{
    RUN_TEST(peak_gauss3_is_exact_on_a_gaussian);
    RUN_TEST(peak_neighbours_wrap_around);
    RUN_TEST(peak_parabola_is_exact_on_a_parabola_and_biased_on_a_gaussian);
    RUN_TEST(peak_centroid_matches_analytic_value);
    RUN_TEST(peak_ratio_of_two_peaks);
    RUN_TEST(peak_second_peak_is_a_local_maximum);
    RUN_TEST(peak_search_range_is_honoured);
    RUN_TEST(peak_flat_plane_reports_failed_fit);
    return check_summary();
}
