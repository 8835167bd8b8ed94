/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "check.h"
#include "rpiv/peak.h"
#include "test_peak_ref.h"

#include <math.h>
#include <stdint.h>
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

/* rpiv_peak_find_near: the highest local maximum within the radius, not the plane's highest
 * value; the ratio against the higher peak outside (< 1); the flank of a peak outside the
 * square is no peak (the plane's highest is taken then); column maxima given or not, the
 * same answer. */
static void peak_near_takes_the_local_maximum_within_the_radius(void)
{
    float p[W * H] = {0};
    add_gauss(p, 9, -6, 0.7, 1.0);           /* higher, outside |s| <= 4 */
    add_gauss(p, 1.3187, -0.7413, 0.9, 0.6); /* inside */
    float cm[W];
    for (int i = 0; i < W; i++) {
        cm[i] = -INFINITY;
        for (int j = 0; j < H; j++)
            cm[i] = p[j * W + i] > cm[i] ? p[j * W + i] : cm[i];
    }
    rpiv_peak pk, pc;
    rpiv_peak_find_near(p, W, H, 4, NULL, RPIV_SUBPIXEL_GAUSS, &pk);
    rpiv_peak_find_near(p, W, H, 4, cm, RPIV_SUBPIXEL_GAUSS, &pc);
    CHECK(pk.ix == 1 && pk.iy == -1 && pk.fit_ok);
    CHECK_NEAR(pk.dx, 1.3187, 1e-3);
    CHECK_NEAR(pk.dy, -0.7413, 1e-3);
    CHECK_NEAR(pk.second, 1.0, 1e-4);
    CHECK_NEAR(pk.ratio, (double)pk.value, 1e-5);
    CHECK(pk.ratio < 1.0f);
    CHECK(pc.ix == pk.ix && pc.iy == pk.iy && pc.dx == pk.dx && pc.ratio == pk.ratio);
    /* radius 0 or a square covering the plane: the whole plane */
    rpiv_peak_find_near(p, W, H, 0, cm, RPIV_SUBPIXEL_GAUSS, &pk);
    CHECK(pk.ix == 9 && pk.iy == -6);
    rpiv_peak_find_near(p, W, H, 16, cm, RPIV_SUBPIXEL_GAUSS, &pk);
    CHECK(pk.ix == 9 && pk.iy == -6);
    /* only the flank of the outside peak reaches into the square: no local maximum there */
    float q[W * H] = {0};
    add_gauss(q, 7, 0, 2.0, 1.0);
    rpiv_peak_find_near(q, W, H, 4, NULL, RPIV_SUBPIXEL_GAUSS, &pk);
    CHECK(pk.ix == 7 && pk.iy == 0);
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

/* Planes outside 3..RPIV_PEAK_MAX_SIZE on a side give no peak (and no write past the
 * search's buffers: the sanitizer build would see one). */
static void peak_sizes_outside_the_range_give_no_peak(void)
{
    const int n = RPIV_PEAK_MAX_SIZE + 7;
    float *p = calloc((size_t)n * 3, sizeof *p);
    if (!p)
        return;
    p[5] = 0.9187f;
    const int sizes[][2] = {{n, 3}, {3, n}, {2, 8}, {8, 2}};
    for (int k = 0; k < 4; k++) {
        rpiv_peak pk;
        memset(&pk, 0x5a, sizeof pk);
        rpiv_peak_find(p, sizes[k][0], sizes[k][1], 0, RPIV_SUBPIXEL_GAUSS, &pk);
        CHECK(!pk.fit_ok && pk.value == 0 && pk.ix == 0 && pk.iy == 0);
        CHECK(pk.ratio == RPIV_PEAK_RATIO_MAX);
    }
    /* the largest side still searched: the peak is found */
    rpiv_peak pk;
    rpiv_peak_find(p, RPIV_PEAK_MAX_SIZE, 3, 0, RPIV_SUBPIXEL_GAUSS, &pk);
    CHECK(pk.ix == 5 && pk.iy == 0 && pk.value == 0.9187f);
    free(p);
}

/* ---- the search against the reference (tests/test_peak_ref.h), bit for bit ---- */

static uint64_t rng = 0x51c3a7e90d2b6f48ULL;

static double urand(void) /* uniform in [0, 1) (splitmix64) */
{
    uint64_t z = (rng += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return (double)(z >> 11) * 0x1.0p-53;
}

static int irand(int n)
{
    return (int)(urand() * n);
}

/* The kinds of plane: 0 uniform noise, 1 few levels (ties everywhere), 2 a peak anywhere
 * (corners: wrap) over noise, 3 a broad peak whose flank tops the noise (the highest value
 * outside the neighbourhood is not a local maximum), 4 a broad peak alone (no local maximum
 * outside), 5 all equal, 6 +0 / -0 / -1 (signed zeros tie), 7 two equal peaks, 8 a kind of
 * 0-3 with NaN, +inf, -inf sprinkled, 9 a constant with one NaN or inf, 10 a correlation-like
 * sharp peak with several noise peaks of equal height, 11 a peak whose flank tops a background
 * of +0, -0 and -1 (the highest local maxima outside are zeros of both signs). */
enum { KINDS = 12 };

static void make_plane(float *p, int w, int h, int kind)
{
    int n = w * h;
    double x0 = urand() * w, y0 = urand() * h, s = 0.6 + 1.5 * urand();
    switch (kind) {
    case 0:
        for (int k = 0; k < n; k++)
            p[k] = (float)(2 * urand() - 0.7);
        break;
    case 1: {
        int lv = 2 + irand(3);
        for (int k = 0; k < n; k++)
            p[k] = (float)(irand(lv) - 1) * 0.3187f;
        break;
    }
    case 2:
    case 3:
    case 4:
    case 7:
    case 10:
        if (kind == 3)
            s = 1.7 + 1.5 * urand();
        if (kind == 4)
            s = 0.25 * (w < h ? w : h) + 2 * urand();
        for (int j = 0; j < h; j++)
            for (int i = 0; i < w; i++) {
                double dx = i - x0, dy = j - y0;
                dx -= w * round(dx / w);
                dy -= h * round(dy / h);
                double v = exp(-(dx * dx + dy * dy) / (2 * s * s));
                if (kind == 7) {
                    double ex = i - fmod(x0 + w / 2.0, w), ey = j - y0;
                    ex -= w * round(ex / w);
                    ey -= h * round(ey / h);
                    v += exp(-(ex * ex + ey * ey) / (2 * s * s));
                }
                double noise = kind == 4 ? 0 : (kind == 3 ? 0.05 : 0.2) * urand();
                p[j * w + i] = (float)(v + noise);
            }
        if (kind == 7 || kind == 10) /* quantise: equal peaks and equal noise maxima */
            for (int k = 0; k < n; k++)
                p[k] = roundf(p[k] * 8) / 8;
        if (kind == 10)
            for (int r = 0; r < 4; r++)
                p[irand(n)] = 0.375f;
        break;
    case 5: {
        const float c[] = {0.25f, 0.0f, -0.0f, -1.5f, -INFINITY, INFINITY, NAN};
        float v = c[irand(7)];
        for (int k = 0; k < n; k++)
            p[k] = v;
        break;
    }
    case 6: {
        const float c[] = {0.0f, -0.0f, -1.0f};
        for (int k = 0; k < n; k++)
            p[k] = c[irand(3)];
        break;
    }
    case 8: {
        make_plane(p, w, h, irand(4));
        const float c[] = {NAN, INFINITY, -INFINITY, -NAN};
        int m = 1 + irand(n / 4 + 1);
        for (int r = 0; r < m; r++)
            p[irand(n)] = c[irand(4)];
        break;
    }
    case 11: {
        const float c[] = {0.0f, -0.0f, -1.0f};
        for (int j = 0; j < h; j++)
            for (int i = 0; i < w; i++) {
                double dx = i - x0, dy = j - y0;
                dx -= w * round(dx / w);
                dy -= h * round(dy / h);
                double v = exp(-(dx * dx + dy * dy) / (2 * 1.3 * 1.3));
                p[j * w + i] = v > 0.04 ? (float)v : c[irand(3)];
            }
        break;
    }
    default: {
        const float c[] = {NAN, INFINITY, -INFINITY};
        for (int k = 0; k < n; k++)
            p[k] = 0.1187f;
        p[irand(n)] = c[irand(3)];
        break;
    }
    }
}

/* Every field of rpiv_peak_find's result the same bits as peak_find_ref's, on planes of
 * every kind and size, for every method and search range (whole plane, ranges smaller and
 * larger than half the plane); rpiv_peak_find_cm's too, given the column maxima. */
static void peak_find_matches_reference_bit_for_bit(void)
{
    const int sizes[][2] = {{32, 32}, {64, 64}, {16, 24}, {24, 16}, {5, 5}, {4, 4},
                            {3, 3},   {6, 6},   {7, 5},   {5, 7},   {3, 8}, {8, 3},
                            {8, 8},   {9, 12},  {12, 9},  {33, 31}, {6, 9}, {5, 16}};
    const int nsizes = (int)(sizeof sizes / sizeof sizes[0]);
    static float p[64 * 64];
    int bad = 0, cases = 0, nonfinite = 0, fits = 0;
    for (int rep = 0; rep < 40; rep++)
        for (int z = 0; z < nsizes; z++)
            for (int kind = 0; kind < KINDS; kind++) {
                int w = sizes[z][0], h = sizes[z][1];
                make_plane(p, w, h, kind);
                const int ranges[] = {0, -3, 1, 2, 3, w / 4, w / 2, h / 2, 100};
                for (int m = 0; m < 3; m++)
                    for (int r = 0; r < 9; r++) {
                        rpiv_peak a, b;
                        memset(&a, 0x5a, sizeof a);
                        memset(&b, 0xa5, sizeof b);
                        peak_find_ref(p, w, h, ranges[r], (rpiv_subpixel)m, &a);
                        rpiv_peak_find(p, w, h, ranges[r], (rpiv_subpixel)m, &b);
                        if (!ranges[r]) { /* given the column maxima (what the engine does) */
                            float cm[64];
                            rpiv_peak c;
                            memset(&c, 0x3c, sizeof c);
                            for (int i = 0; i < w; i++) {
                                cm[i] = -INFINITY;
                                for (int j = 0; j < h; j++)
                                    cm[i] = p[j * w + i] > cm[i] ? p[j * w + i] : cm[i];
                            }
                            rpiv_peak_find_cm(p, w, h, cm, (rpiv_subpixel)m, &c);
                            bad += !peak_same(&a, &c);
                        }
                        cases++;
                        fits += a.fit_ok;
                        nonfinite += kind >= 8;
                        if (!peak_same(&a, &b) && bad++ < 5)
                            fprintf(stderr,
                                    "%dx%d kind %d method %d max_shift %d: new (%d %d %a %a %a "
                                    "%a %a %d) ref (%d %d %a %a %a %a %a %d)\n",
                                    w, h, kind, m, ranges[r], b.ix, b.iy, b.dx, b.dy,
                                    (double)b.value, (double)b.second, (double)b.ratio, b.fit_ok,
                                    a.ix, a.iy, a.dx, a.dy, (double)a.value, (double)a.second,
                                    (double)a.ratio, a.fit_ok);
                    }
            }
    CHECK(bad == 0);
    CHECK(cases == 40 * nsizes * KINDS * 27);
    CHECK(fits > cases / 4 && fits < cases); /* both outcomes of the fit were compared */
    CHECK(nonfinite > 0);
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
    RUN_TEST(peak_near_takes_the_local_maximum_within_the_radius);
    RUN_TEST(peak_flat_plane_reports_failed_fit);
    RUN_TEST(peak_sizes_outside_the_range_give_no_peak);
    RUN_TEST(peak_find_matches_reference_bit_for_bit);
    return check_summary();
}
