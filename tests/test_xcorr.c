/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "check.h"
#include "rpiv/error.h"
#include "rpiv/peak.h"
#include "rpiv/xcorr.h"

#include <stdint.h>
#include <string.h>

/* A fixed-seed generator (xorshift64*), uniform in [0, 1). */
static double rnd(uint64_t *s)
{
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    return (double)((*s * 2685821657736338717ULL) >> 11) * (1.0 / 9007199254740992.0);
}

static void fill_random(float *v, int n, uint64_t seed, double scale, double offset)
{
    for (int i = 0; i < n; i++)
        v[i] = (float)(offset + scale * rnd(&seed));
}

static void xcorr_identical_windows_normalise_to_one(void)
{
    rpiv_xcorr *x = NULL;
    rpiv_xcorr_work *ws = NULL;
    CHECK_OK(rpiv_xcorr_new(32, 32, &x));
    CHECK_OK(rpiv_xcorr_work_new(x, &ws));
    if (!ws)
        goto out;
    /* 16-bit-like grey levels with a large offset: the mean must not spoil the result */
    fill_random(ws->a, 32 * 32, 0x5eed1234ULL, 4000.0, 1187.0);
    memcpy(ws->b, ws->a, sizeof(float) * 32 * 32);
    double ea, eb;
    rpiv_xcorr_run(x, ws, RPIV_XCORR_NORMALISE, &ea, &eb);
    CHECK_NEAR(ws->plane[0], 1.0, 2e-6);
    CHECK_NEAR(ea, eb, 1e-9 * ea);
    float mx = -1;
    for (int i = 1; i < 32 * 32; i++)
        mx = ws->plane[i] > mx ? ws->plane[i] : mx;
    CHECK(mx < 0.3f); /* white noise: off-peak values are O(1/sqrt(n)) */
out:
    rpiv_xcorr_work_free(ws);
    rpiv_xcorr_free(x);
}

/* b is a circularly shifted by (+5, -3): the peak sits at shift (5, -3) with value 1. */
static void xcorr_known_shift_of_random_pattern(void)
{
    const int w = 48, h = 40, sx = 5, sy = -3;
    rpiv_xcorr *x = NULL;
    rpiv_xcorr_work *ws = NULL;
    CHECK_OK(rpiv_xcorr_new(w, h, &x));
    CHECK_OK(rpiv_xcorr_work_new(x, &ws));
    if (!ws)
        goto out;
    fill_random(ws->a, w * h, 77, 1.0, 0.0);
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++)
            ws->b[j * w + i] = ws->a[((j - sy + h) % h) * w + (i - sx + w) % w];
    rpiv_xcorr_run(x, ws, RPIV_XCORR_NORMALISE, NULL, NULL);
    rpiv_peak pk;
    rpiv_peak_find(ws->plane, w, h, 0, RPIV_SUBPIXEL_GAUSS, &pk);
    CHECK(pk.ix == sx && pk.iy == sy);
    CHECK_NEAR(pk.value, 1.0, 2e-6);
    CHECK_NEAR(pk.dx, sx, 0.02); /* white noise: the neighbours are ~0, the fit stays put */
    CHECK_NEAR(pk.dy, sy, 0.02);
    CHECK(pk.ratio > 3);
out:
    rpiv_xcorr_work_free(ws);
    rpiv_xcorr_free(x);
}

/* The raw plane equals the direct circular sum R(s) = sum_x a'(x) b'(x + s) on a
 * non-square window, element by element: orientation and sign convention. */
static void xcorr_raw_plane_equals_direct_sum(void)
{
    enum { W = 12, H = 8 };
    float a[W * H], b[W * H];
    rpiv_xcorr *x = NULL;
    rpiv_xcorr_work *ws = NULL;
    CHECK_OK(rpiv_xcorr_new(W, H, &x));
    CHECK_OK(rpiv_xcorr_work_new(x, &ws));
    if (!ws)
        goto out;
    fill_random(a, W * H, 991, 2.0, 3.0);
    fill_random(b, W * H, 4242, 5.0, -1.0);
    memcpy(ws->a, a, sizeof a);
    memcpy(ws->b, b, sizeof b);
    double ea, eb;
    rpiv_xcorr_run(x, ws, RPIV_XCORR_RAW, &ea, &eb);
    double ma = 0, mb = 0, ea2 = 0, eb2 = 0;
    for (int i = 0; i < W * H; i++) {
        ma += (double)a[i] / (double)(W * H);
        mb += (double)b[i] / (double)(W * H);
    }
    for (int i = 0; i < W * H; i++) {
        ea2 += ((double)a[i] - ma) * ((double)a[i] - ma);
        eb2 += ((double)b[i] - mb) * ((double)b[i] - mb);
    }
    CHECK_NEAR(ea, ea2, 1e-5 * ea2);
    CHECK_NEAR(eb, eb2, 1e-5 * eb2);
    double maxerr = 0;
    for (int sy = 0; sy < H; sy++)
        for (int sx = 0; sx < W; sx++) {
            double r = 0;
            for (int j = 0; j < H; j++)
                for (int i = 0; i < W; i++)
                    r += ((double)a[j * W + i] - ma) *
                         ((double)b[((j + sy) % H) * W + (i + sx) % W] - mb);
            double e = fabs((double)ws->plane[sy * W + sx] - r);
            maxerr = e > maxerr ? e : maxerr;
        }
    CHECK(maxerr < 1e-4);
out:
    rpiv_xcorr_work_free(ws);
    rpiv_xcorr_free(x);
}

static void xcorr_blank_window_gives_zero_plane(void)
{
    rpiv_xcorr *x = NULL;
    rpiv_xcorr_work *ws = NULL;
    CHECK_OK(rpiv_xcorr_new(16, 16, &x));
    CHECK_OK(rpiv_xcorr_work_new(x, &ws));
    if (!ws)
        goto out;
    for (int i = 0; i < 256; i++)
        ws->a[i] = 113.25f;
    fill_random(ws->b, 256, 5, 1.0, 0.0);
    double ea = -1;
    rpiv_xcorr_run(x, ws, RPIV_XCORR_NORMALISE, &ea, NULL);
    CHECK(ea == 0);
    int zero = 1;
    for (int i = 0; i < 256; i++)
        zero &= ws->plane[i] == 0;
    CHECK(zero);
out:
    rpiv_xcorr_work_free(ws);
    rpiv_xcorr_free(x);
}

static void xcorr_rejects_bad_sizes(void)
{
    rpiv_xcorr *x = (rpiv_xcorr *)&x;
    CHECK_FAILS(rpiv_xcorr_new(2, 32, &x), RPIV_EINVAL);
    CHECK(x == NULL);
    CHECK_FAILS(rpiv_xcorr_new(32, 5000, &x), RPIV_EINVAL);
}

int main(void)
{
    RUN_TEST(xcorr_identical_windows_normalise_to_one);
    RUN_TEST(xcorr_known_shift_of_random_pattern);
    RUN_TEST(xcorr_raw_plane_equals_direct_sum);
    RUN_TEST(xcorr_blank_window_gives_zero_plane);
    RUN_TEST(xcorr_rejects_bad_sizes);
    return check_summary();
}
