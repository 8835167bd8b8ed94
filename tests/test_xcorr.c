/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "check.h"
#include "rpiv/error.h"
#include "rpiv/peak.h"
#include "rpiv/xcorr.h"
#include "xcorr_impl.h"

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

/* The direct circular correlation of two w x h windows, in double: the largest |difference|
 * from plane; *maxr gets the largest |R| (maxr may be NULL). */
static double direct_error_abs(const float *a, const float *b, int w, int h, const float *plane,
                               double *maxr)
{
    double ma = 0, mb = 0, maxerr = 0, mr = 0;
    for (int i = 0; i < w * h; i++) {
        ma += (double)a[i] / (double)(w * h);
        mb += (double)b[i] / (double)(w * h);
    }
    for (int sy = 0; sy < h; sy++)
        for (int sx = 0; sx < w; sx++) {
            double r = 0;
            for (int j = 0; j < h; j++)
                for (int i = 0; i < w; i++)
                    r += ((double)a[j * w + i] - ma) *
                         ((double)b[((j + sy) % h) * w + (i + sx) % w] - mb);
            double e = fabs((double)plane[sy * w + sx] - r);
            maxerr = e > maxerr ? e : maxerr;
            mr = fabs(r) > mr ? fabs(r) : mr;
        }
    if (maxr)
        *maxr = mr;
    return maxerr;
}

/* The same, relative to the largest |R|. */
static double direct_error(const float *a, const float *b, int w, int h, const float *plane)
{
    double maxr;
    double e = direct_error_abs(a, b, w, h, plane, &maxr);
    return e / maxr;
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
    double maxerr = direct_error_abs(a, b, W, H, ws->plane, NULL);
    CHECK(maxerr < 1e-4);
out:
    rpiv_xcorr_work_free(ws);
    rpiv_xcorr_free(x);
}

/* Window sizes of the packing tests: all vector paths (32 x 32), vector cross-spectra with a
 * scalar tail in the packing (20 x 12), scalar (13 x 9), the smallest halved spectrum (8 x 4)
 * and an odd height, computed whole (16 x 7). */
static const int sizes[][2] = {{32, 32}, {20, 12}, {13, 9}, {8, 4}, {16, 7}};
enum { NSIZES = (int)(sizeof sizes / sizeof sizes[0]) };

/* Two window pairs packed in one set of transforms give each its own plane and energies,
 * even when one pair is 10^4 times weaker than the other (both planes are scaled to
 * correlation coefficients before packing), for widths that take the vector paths (32), the
 * partly vector ones (20, 12) and the scalar ones (13); the cross-spectra of 32 x 32, 20 x 12 and
 * 8 x 4 are computed by halves (Hermitian partners), those of 16 x 7 (odd height) whole. One
 * pair alone gives the same. */
static void xcorr_two_pairs_packed_match_direct_sums(void)
{
    for (int c = 0; c < NSIZES; c++) {
        int w = sizes[c][0], h = sizes[c][1], n = w * h;
        rpiv_xcorr *x = NULL;
        rpiv_xcorr_work *ws = NULL;
        CHECK_OK(rpiv_xcorr_new(w, h, &x));
        CHECK_OK(rpiv_xcorr_work_new(x, &ws));
        float *a0 = malloc(sizeof(float) * 4 * (size_t)n), *b0 = a0 + n, *a1 = b0 + n, *b1 = a1 + n;
        if (!ws || !a0)
            goto next;
        fill_random(a0, n, 17 + (uint64_t)c, 3000.0, 150.0);
        fill_random(b0, n, 29 + (uint64_t)c, 2800.0, 90.0);
        fill_random(a1, n, 31 + (uint64_t)c, 0.37, 12.0); /* 10^4 x weaker in amplitude */
        for (int i = 0; i < n; i++)                       /* b1: a1 shifted by (2, 1) */
            b1[i] = a1[((i / w + h - 1) % h) * w + (i % w + w - 2) % w];
        rpiv_xcorr_src src[2] = {{a0, b0, (size_t)w, (size_t)w}, {a1, b1, (size_t)w, (size_t)w}};
        double e[4];
        rpiv_xcorr_run_pairs(x, ws, src, 2, RPIV_XCORR_RAW, e);
        CHECK(direct_error(a0, b0, w, h, ws->plane) < 2e-6);
        CHECK(direct_error(a1, b1, w, h, ws->plane2) < 2e-6);
        CHECK(e[0] > 1e4 * e[2]);
        /* the column maxima of both planes, as rpiv_peak_find takes them */
        int cm_ok = 1;
        for (int i = 0; i < w; i++) {
            float m0 = -INFINITY, m1 = -INFINITY;
            for (int j = 0; j < h; j++) {
                m0 = ws->plane[j * w + i] > m0 ? ws->plane[j * w + i] : m0;
                m1 = ws->plane2[j * w + i] > m1 ? ws->plane2[j * w + i] : m1;
            }
            cm_ok &= ws->colmax[i] == m0 && ws->colmax2[i] == m1;
        }
        CHECK(cm_ok);
        double lone[2];
        rpiv_xcorr_run_pairs(x, ws, src + 1, 1, RPIV_XCORR_RAW, lone);
        CHECK(direct_error(a1, b1, w, h, ws->plane) < 2e-6);
        CHECK(lone[0] == e[2] && lone[1] == e[3]);
        /* the shifted copy peaks at (2, 1) with a coefficient of 1 */
        rpiv_xcorr_run_pairs(x, ws, src, 2, RPIV_XCORR_NORMALISE, e);
        CHECK_NEAR(ws->plane2[1 * w + 2], 1.0, 1e-5);
    next:
        free(a0);
        rpiv_xcorr_work_free(ws);
        rpiv_xcorr_free(x);
    }
}

/* The 4-wide glue (SSE2, NEON) and the 8-wide one (AVX2) give the same bits: planes and
 * energies, on windows of 32 x 32 (all vector paths), 20 x 12 (vector cross-spectra, a
 * scalar tail in the packing) and 13 x 9 (scalar), read from frames with a stride. */
static void xcorr_vector_widths_give_the_same_bits(void)
{
    enum { FW = 101 };
    float *fa = malloc(sizeof(float) * FW * 40), *fb = malloc(sizeof(float) * FW * 40);
    if (!fa || !fb)
        goto out;
    fill_random(fa, FW * 40, 0x7e57, 3187.0, 211.0);
    fill_random(fb, FW * 40, 0x7e58, 2903.0, 187.0);
    for (int c = 0; c < NSIZES; c++) {
        int w = sizes[c][0], h = sizes[c][1], n = w * h;
        rpiv_xcorr *x = NULL;
        rpiv_xcorr_work *ws = NULL;
        CHECK_OK(rpiv_xcorr_new(w, h, &x));
        CHECK_OK(rpiv_xcorr_work_new(x, &ws));
        float *keep = malloc(sizeof(float) * 2 * (size_t)n);
        if (!ws || !keep)
            goto next;
        rpiv_xcorr_src src[2] = {{fa + 3, fb + 5, FW, FW}, {fa + 7 + FW, fb + 2 + 3 * FW, FW, FW}};
        double e4[4], e8[4];
        float cm[2 * 32];
        xcorr_run_pairs_vl(x, ws, src, 2, RPIV_XCORR_RAW, e4, 4);
        memcpy(keep, ws->plane, sizeof(float) * (size_t)n);
        memcpy(keep + n, ws->plane2, sizeof(float) * (size_t)n);
        memcpy(cm, ws->colmax, sizeof(float) * 2 * (size_t)w);
        xcorr_run_pairs_vl(x, ws, src, 2, RPIV_XCORR_RAW, e8, 8);
        CHECK(memcmp(keep, ws->plane, sizeof(float) * (size_t)n) == 0);
        CHECK(memcmp(keep + n, ws->plane2, sizeof(float) * (size_t)n) == 0);
        CHECK(memcmp(cm, ws->colmax, sizeof(float) * 2 * (size_t)w) == 0);
        CHECK(memcmp(e4, e8, sizeof e4) == 0);
    next:
        free(keep);
        rpiv_xcorr_work_free(ws);
        rpiv_xcorr_free(x);
    }
out:
    free(fa);
    free(fb);
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
    RUN_TEST(xcorr_two_pairs_packed_match_direct_sums);
    RUN_TEST(xcorr_vector_widths_give_the_same_bits);
    RUN_TEST(xcorr_blank_window_gives_zero_plane);
    RUN_TEST(xcorr_rejects_bad_sizes);
    return check_summary();
}
