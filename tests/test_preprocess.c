/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/test_preprocess.c - the preprocessing operations against what each must do: exact
 * point operations, backgrounds removed, local contrast equalised, the same bits for any
 * thread count, and the errors of the list's parser. */
#include "check.h"
#include "prep_impl.h" /* prep_clahe_clip */
#include "rpiv/piv.h"
#include "rpiv/preprocess.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static rpiv_image *image(int w, int h)
{
    rpiv_image *im = NULL;
    CHECK_OK(rpiv_image_new(w, h, &im));
    return im;
}

/* A particle image: Gaussian spots of diameter ~3 px at pseudo-random places (fixed seed) on
 * background bg(x, y), spot peak `amp`. */
static void particles(rpiv_image *im, double amp, double (*bg)(int, int), unsigned seed, int n)
{
    for (int y = 0; y < im->h; y++)
        for (int x = 0; x < im->w; x++)
            im->px[(size_t)y * (size_t)im->w + (size_t)x] = (float)bg(x, y);
    unsigned s = seed;
    for (int k = 0; k < n; k++) {
        s = s * 1103515245u + 12345u;
        double cx = (double)((s >> 8) % (unsigned)(im->w * 16)) / 16.0;
        s = s * 1103515245u + 12345u;
        double cy = (double)((s >> 8) % (unsigned)(im->h * 16)) / 16.0;
        for (int y = (int)cy - 4; y <= (int)cy + 4; y++)
            for (int x = (int)cx - 4; x <= (int)cx + 4; x++)
                if (x >= 0 && y >= 0 && x < im->w && y < im->h) {
                    double r2 = (x - cx) * (x - cx) + (y - cy) * (y - cy);
                    im->px[(size_t)y * (size_t)im->w + (size_t)x] += (float)(amp * exp(-r2 / 2.25));
                }
    }
}

static double ramp(int x, int y)
{
    return 200.0 + 3.1873 * x + 1.25 * y; /* a strong, smooth background */
}

static double dark(int x, int y)
{
    (void)x;
    (void)y;
    return 3.0;
}

static void parse_reads_the_list(void)
{
    rpiv_preprocess_params p = rpiv_preprocess_params_default();
    CHECK(p.ops[0] == '\0');
    rpiv_prep_op op[RPIV_PREPROCESS_MAX_OPS];
    int n = -1;
    CHECK_OK(rpiv_preprocess_parse("clahe:48,highpass,cap,normalize:21,invert", op, &n));
    CHECK(n == 5);
    CHECK(op[0].kind == RPIV_PREP_CLAHE && op[0].size_px == 48);
    CHECK(op[1].kind == RPIV_PREP_HIGHPASS && op[1].size_px == 0);
    CHECK(op[2].kind == RPIV_PREP_CAP && op[4].kind == RPIV_PREP_INVERT);
    CHECK(op[3].kind == RPIV_PREP_NORMALIZE && op[3].size_px == 21);
    CHECK_OK(rpiv_preprocess_parse("none", op, &n));
    CHECK(n == 0);
    CHECK_OK(rpiv_preprocess_parse("", op, &n));
    CHECK(n == 0);
}

static void parse_errors_name_the_word(void)
{
    rpiv_preprocess_params p = rpiv_preprocess_params_default();
    rpiv_prep_op op[RPIV_PREPROCESS_MAX_OPS];
    int n = 0;
    CHECK_FAILS(rpiv_preprocess_parse("clahe,sharpen", op, &n), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "'sharpen'") != NULL);
    CHECK_FAILS(rpiv_preprocess_parse("highpass:2", op, &n), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "3..1024") != NULL);
    CHECK_FAILS(rpiv_preprocess_parse("highpass:4294967311", op, &n), RPIV_EINVAL);
    CHECK_FAILS(rpiv_preprocess_parse("highpass:15x", op, &n), RPIV_EINVAL);
    CHECK_FAILS(rpiv_preprocess_parse("cap:3", op, &n), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "no size") != NULL);
    CHECK_FAILS(rpiv_preprocess_parse("clahe,,cap", op, &n), RPIV_EINVAL);
    CHECK_FAILS(rpiv_preprocess_parse("clahe,", op, &n), RPIV_EINVAL);
    CHECK_FAILS(rpiv_preprocess_parse("cap,cap,cap,cap,cap,cap,cap,cap,cap", op, &n), RPIV_EINVAL);
    CHECK(n == 0); /* nothing on failure */
    /* run refuses a bad list with the same message */
    strcpy(p.ops, "clahe,sharpen");
    rpiv_image *bad = image(8, 8);
    CHECK_FAILS(rpiv_preprocess_run(&p, bad, 1), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "'sharpen'") != NULL);
    rpiv_image_free(bad);
    p.ops[0] = '\0';
    p.clahe_clip = 1.5;
    rpiv_image *im = image(8, 8);
    CHECK_FAILS(rpiv_preprocess_run(&p, im, 1), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "clahe_clip") != NULL);
    rpiv_image_free(im);
}

static void invert_and_cap_are_exact(void)
{
    rpiv_image *im = image(5, 4);
    for (int i = 0; i < 20; i++)
        im->px[i] = (float)(i * i % 7) + 0.25f;
    im->px[13] = 100.0f; /* an outlier */
    rpiv_preprocess_params p = rpiv_preprocess_params_default();
    strcpy(p.ops, "invert");
    float before[20];
    memcpy(before, im->px, sizeof before);
    CHECK_OK(rpiv_preprocess_run(&p, im, 2));
    for (int i = 0; i < 20; i++)
        CHECK(im->px[i] == (100.0f - before[i]) + 0.25f);
    memcpy(im->px, before, sizeof before);
    /* cap: mean + 2 std over the 20 values, in double */
    double s = 0, s2 = 0;
    for (int i = 0; i < 20; i++)
        s += (double)before[i];
    for (int i = 0; i < 20; i++)
        s2 += ((double)before[i] - s / 20) * ((double)before[i] - s / 20);
    float top = (float)(s / 20 + 2 * sqrt(s2 / 20));
    strcpy(p.ops, "cap");
    CHECK_OK(rpiv_preprocess_run(&p, im, 1));
    CHECK(im->px[13] == top);
    for (int i = 0; i < 20; i++)
        if (i != 13)
            CHECK(im->px[i] == before[i]);
    rpiv_image_free(im);
}

/* The high-pass removes a smooth background: far from particles the result is ~0, particles
 * keep most of their height. */
static void highpass_removes_the_background(void)
{
    for (int how = 0; how < 2; how++) {
        rpiv_image *im = image(96, 80), *bare = image(96, 80);
        particles(im, 500, ramp, 11, 40);
        for (int y = 0; y < 80; y++)
            for (int x = 0; x < 96; x++)
                bare->px[y * 96 + x] = (float)ramp(x, y);
        rpiv_preprocess_params p = rpiv_preprocess_params_default();
        p.highpass_method = how ? RPIV_PREP_BG_BLUR : RPIV_PREP_BG_MIN;
        strcpy(p.ops, "highpass:15");
        rpiv_image *ref = NULL;
        CHECK_OK(rpiv_image_copy(im, &ref));
        CHECK_OK(rpiv_preprocess_run(&p, im, 2));
        /* the pure ramp: its background is itself, up to the windows' end effects */
        CHECK_OK(rpiv_preprocess_run(&p, bare, 2));
        /* the pure ramp: the blur's background is the ramp itself; the minimum's background
         * lags it by the slopes times a fixed distance, a constant that the correlation's
         * mean removal ignores: what matters is that it is flat and below the signal */
        double rlo = 1e30, rhi = -1e30;
        for (int y = 16; y < 64; y++) /* two half windows from the edges: no end effect */
            for (int x = 16; x < 80; x++) {
                double v = (double)bare->px[y * 96 + x];
                rlo = fmin(rlo, v);
                rhi = fmax(rhi, v);
            }
        printf("    %s: ramp 200..600 leaves %.4g .. %.4g above the background inside\n",
               how ? "blur" : "min", rlo, rhi);
        CHECK(rhi - rlo < 0.5);
        CHECK(how ? fabs(rhi) < 0.5 : rlo > 0);
        /* particles stand out: the brightest pixel keeps > 60 % of the spot amplitude */
        float mx = 0;
        for (int i = 0; i < 96 * 80; i++)
            mx = im->px[i] > mx ? im->px[i] : mx;
        CHECK(mx > 300.0f);
        for (int i = 0; i < 96 * 80; i++)
            CHECK(im->px[i] >= 0.0f);
        rpiv_image_free(ref);
        rpiv_image_free(im);
        rpiv_image_free(bare);
    }
}

/* Normalisation brings a dim half and a bright half of the same particle pattern to the same
 * local contrast. */
static void normalize_equalises_local_contrast(void)
{
    rpiv_image *im = image(128, 64);
    particles(im, 50, dark, 7, 120);
    for (int y = 0; y < 64; y++)
        for (int x = 64; x < 128; x++)
            im->px[y * 128 + x] *= 20.0f; /* the right half 20 times brighter */
    rpiv_preprocess_params p = rpiv_preprocess_params_default();
    strcpy(p.ops, "normalize");
    CHECK_OK(rpiv_preprocess_run(&p, im, 2));
    double sl = 0, sr = 0;
    for (int y = 0; y < 64; y++)
        for (int x = 8; x < 56; x++) {
            sl += (double)im->px[y * 128 + x];
            sr += (double)im->px[y * 128 + x + 64];
        }
    printf("    mean after normalisation: left %.4f, right %.4f\n", sl / 3072, sr / 3072);
    for (int i = 0; i < 128 * 64; i++)
        CHECK(im->px[i] >= 0 && im->px[i] <= 1);
    CHECK(sl > 0.02 && fabs(sl - sr) / sr < 0.35);
    rpiv_image_free(im);
}

/* CLAHE spreads a dark, low-contrast image over the grey range: the darkest quarter of the
 * pixels no longer holds 90 % of the range's bottom, and the result is within the input's
 * range. */
static void clahe_spreads_a_dark_image(void)
{
    rpiv_image *im = image(160, 128);
    particles(im, 40, dark, 5, 200);
    float lo = im->px[0], hi = im->px[0];
    for (int i = 0; i < 160 * 128; i++) {
        lo = fminf(lo, im->px[i]);
        hi = fmaxf(hi, im->px[i]);
    }
    double mean0 = 0, mean1 = 0;
    for (int i = 0; i < 160 * 128; i++)
        mean0 += (double)((im->px[i] - lo) / (hi - lo));
    rpiv_preprocess_params p = rpiv_preprocess_params_default();
    strcpy(p.ops, "clahe:32");
    CHECK_OK(rpiv_preprocess_run(&p, im, 2));
    for (int i = 0; i < 160 * 128; i++) {
        CHECK(im->px[i] >= lo - 1e-3f && im->px[i] <= hi + 1e-3f);
        mean1 += (double)((im->px[i] - lo) / (hi - lo));
    }
    mean0 /= 160 * 128;
    mean1 /= 160 * 128;
    printf("    mean grey (0..1 of the range): %.4f before, %.4f after\n", mean0, mean1);
    /* the mean grey rises by 1.96 times here (2.1 with the former spreading of the clipped
     * excess, which pushed bins above the limit) */
    CHECK(mean0 < 0.1 && mean1 > 1.8 * mean0);
    /* a constant image is left as it is */
    rpiv_image *flat = image(40, 40);
    for (int i = 0; i < 1600; i++)
        flat->px[i] = 7.5f;
    strcpy(p.ops, "clahe,normalize");
    CHECK_OK(rpiv_preprocess_run(&p, flat, 1));
    for (int i = 0; i < 1600; i++)
        CHECK(flat->px[i] == 7.5f);
    rpiv_image_free(flat);
    rpiv_image_free(im);
}

/* CLAHE's clipping as MATLAB's adapthisteq: the excess is redistributed so that no bin ends
 * above the limit. A histogram of known counts, worked by hand: 8 bins, limit 5, counts
 * {20, 0, 1, 4, 5, 0, 2, 0} (32). Clipping leaves 15 over; the share 15 / 8 = 1 goes to every
 * bin below the limit, bin 3 (4) taking only 1 to reach it: {5, 1, 2, 5, 5, 1, 3, 1}, 9 left;
 * then one count at a time on the bins below 5: step 8 / 9 -> 1 from bin 0 (bins 1, 2, 5, 6, 7:
 * 4 left), step 8 / 4 = 2 from bin 1 (bins 1, 5, 7: 1 left), step 8 from bin 2 (bin 2). The
 * old spreading (1 on every bin, then 1 on bins 0..6) gave {7, 2, 3, 6, 7, 2, 4, 1}: 4 bins
 * above the limit. */
static void clahe_clip_keeps_bins_at_the_limit(void)
{
    size_t h[8] = {20, 0, 1, 4, 5, 0, 2, 0};
    const size_t want[8] = {5, 3, 4, 5, 5, 3, 4, 3};
    prep_clahe_clip(h, 8, 5);
    for (int b = 0; b < 8; b++)
        CHECK(h[b] == want[b]);
    /* pseudo-random histograms: the total kept, no bin above the limit, no bin below its
     * clipped count */
    unsigned s = 99;
    for (int t = 0; t < 200; t++) {
        size_t n = 16 + (size_t)(t % 5) * 60, before[316], hh[316], total = 0, mx = 0;
        for (size_t b = 0; b < n; b++) {
            s = s * 1103515245u + 12345u;
            hh[b] = before[b] = (s >> 16) % 7 == 0 ? (s >> 8) % 3000 : (s >> 8) % 9;
            total += hh[b];
            mx = hh[b] > mx ? hh[b] : mx;
        }
        size_t minclip = (total + n - 1) / n;
        size_t limit = minclip + (size_t)(t % 7) * (mx - minclip) / 7;
        prep_clahe_clip(hh, n, limit);
        size_t after = 0;
        int ok = 1;
        for (size_t b = 0; b < n; b++) {
            after += hh[b];
            ok &= hh[b] <= limit && hh[b] >= (before[b] < limit ? before[b] : limit);
        }
        CHECK(ok && after == total);
    }
}

/* CLAHE's bins between percentiles (PIVlab's auto contrast stretch): on the values 0..999,
 * once each, the 1st percentile is 10 (the first value whose cumulative count exceeds 10 of
 * 1000) and the 99.5th is 994 (the first whose count reaches 995): with one tile (one map),
 * 0..10 fall in the first bin and 994..999 in the last, whose map value is the top of the
 * range, the upper edge of 994's fine bin (4096 bins over 0..999). Without percentiles, 0 and 10
 * are apart and the top is 999. An image of one level but for a few pixels keeps its whole range.
 */
static void clahe_percentiles_saturate_the_tails(void)
{
    const int w = 40, h = 25;
    rpiv_image *im = image(w, h);
    float out[2][1000];
    for (int pct = 0; pct < 2; pct++) {
        for (int i = 0; i < w * h; i++)
            im->px[i] = (float)((i * 7) % 1000); /* a permutation of 0..999 */
        rpiv_preprocess_params p = rpiv_preprocess_params_default();
        strcpy(p.ops, "clahe:64"); /* one tile over the whole image */
        if (pct) {
            p.clahe_low_pct = 1;
            p.clahe_high_pct = 99.5;
        }
        CHECK_OK(rpiv_preprocess_run(&p, im, 2));
        for (int i = 0; i < w * h; i++)
            out[pct][(i * 7) % 1000] = im->px[i];
    }
    const double fine = 999.0 / 4096;
    for (int v = 0; v <= 10; v++)
        CHECK(out[1][v] == out[1][10]);
    for (int v = 994; v <= 999; v++)
        CHECK(out[1][v] == out[1][999]);
    CHECK(out[1][9] != out[1][14] && out[1][990] != out[1][994]);
    CHECK_NEAR(out[1][999], (floor(994 / fine) + 1) * fine, 1e-3); /* 994.122 */
    CHECK(out[0][0] < out[0][10]);
    CHECK_NEAR(out[0][999], 999, 1e-3);
    /* zeros but for 3 pixels (0.3 %): both percentiles in the first fine bin: whole range */
    for (int i = 0; i < w * h; i++)
        im->px[i] = i % 300 == 7 ? 100.0f : 0.0f;
    rpiv_preprocess_params p = rpiv_preprocess_params_default();
    strcpy(p.ops, "clahe:64");
    p.clahe_low_pct = 1;
    p.clahe_high_pct = 99.5;
    CHECK_OK(rpiv_preprocess_run(&p, im, 1));
    CHECK_NEAR(im->px[7], 100, 1e-3);
    CHECK(im->px[0] < im->px[7]);
    p.clahe_low_pct = 99.5;
    CHECK_FAILS(rpiv_preprocess_run(&p, im, 1), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "clahe_low_pct") != NULL);
    rpiv_image_free(im);
}

/* The same bits for 1, 2 and 3 threads, every operation in one list; images smaller than the
 * windows too. */
static void any_thread_count_gives_the_same_bits(void)
{
    /* sizes off the filters' groups of 4 rows and strips of 64 columns, and below the windows */
    const int sizes[4][2] = {{200, 150}, {203, 151}, {17, 9}, {3, 64}};
    for (int s = 0; s < 4; s++) {
        int w = sizes[s][0], h = sizes[s][1];
        size_t bytes = (size_t)w * (size_t)h * sizeof(float);
        rpiv_image *a = image(w, h), *b = NULL, *c = NULL;
        particles(a, 300, ramp, 3, w * h / 60 + 1);
        CHECK_OK(rpiv_image_copy(a, &b));
        CHECK_OK(rpiv_image_copy(a, &c));
        rpiv_preprocess_params p = rpiv_preprocess_params_default();
        strcpy(p.ops, "clahe,highpass,cap,normalize,invert");
        for (int how = 0; how < 4; how++) {
            p.highpass_method = how == 1 ? RPIV_PREP_BG_BLUR : RPIV_PREP_BG_MIN;
            if (how == 2) { /* CLAHE's bins between percentiles */
                p.clahe_low_pct = 1;
                p.clahe_high_pct = 99.5;
            }
            if (how == 3) /* many tile rows: threads' shares of several, of unequal sizes */
                strcpy(p.ops, "clahe:7,highpass:5,clahe:9,normalize");
            CHECK_OK(rpiv_preprocess_run(&p, a, 1));
            CHECK_OK(rpiv_preprocess_run(&p, b, 2));
            CHECK_OK(rpiv_preprocess_run(&p, c, 3));
            CHECK(!memcmp(a->px, b->px, bytes) && !memcmp(a->px, c->px, bytes));
        }
        for (size_t i = 0; i < (size_t)w * (size_t)h; i++)
            CHECK(isfinite(a->px[i]));
        rpiv_image_free(a);
        rpiv_image_free(b);
        rpiv_image_free(c);
    }
}

/* "clahe,highpass" runs as one operation (the background's cell minima taken from CLAHE's
 * rows as they are written): the same bits as clahe, then highpass, for any thread count, for
 * bands of the background across the threads' shares, and for an image CLAHE leaves as it
 * is. */
static void clahe_highpass_in_one_gives_the_same_bits(void)
{
    const int sizes[3][2] = {{203, 151}, {64, 200}, {9, 5}};
    const char *const lists[3][3] = {{"clahe,highpass", "clahe", "highpass"},
                                     {"clahe:7,highpass:5", "clahe:7", "highpass:5"},
                                     {"clahe:20,highpass:41", "clahe:20", "highpass:41"}};
    for (int s = 0; s < 3; s++)
        for (int l = 0; l < 3; l++)
            for (int nt = 1; nt <= 3; nt++) {
                int w = sizes[s][0], h = sizes[s][1];
                rpiv_image *a = image(w, h), *b = NULL;
                particles(a, 300, s == 2 ? dark : ramp, 5, w * h / 50 + 1);
                if (s == 2 && l == 2) /* one grey level: CLAHE leaves it */
                    for (int i = 0; i < w * h; i++)
                        a->px[i] = 7.25f;
                CHECK_OK(rpiv_image_copy(a, &b));
                rpiv_preprocess_params p = rpiv_preprocess_params_default();
                strcpy(p.ops, lists[l][0]);
                CHECK_OK(rpiv_preprocess_run(&p, a, nt));
                strcpy(p.ops, lists[l][1]);
                CHECK_OK(rpiv_preprocess_run(&p, b, nt));
                strcpy(p.ops, lists[l][2]);
                CHECK_OK(rpiv_preprocess_run(&p, b, nt));
                CHECK(!memcmp(a->px, b->px, (size_t)w * (size_t)h * sizeof(float)));
                rpiv_image_free(a);
                rpiv_image_free(b);
            }
}

/* The plan applies its preprocessing to both frames of the pair it loads: the field equals the
 * one of a plan without preprocessing run on frames preprocessed beforehand. */
static void the_plan_preprocesses_both_frames(void)
{
    rpiv_image *a = image(192, 160), *b = image(192, 160);
    particles(a, 400, ramp, 21, 600);
    particles(b, 400, ramp, 21, 600);
    /* b: a shifted by (2, 1) px, so there is a displacement to find */
    for (int y = 159; y >= 0; y--)
        for (int x = 191; x >= 0; x--)
            b->px[y * 192 + x] = a->px[(y >= 1 ? y - 1 : 0) * 192 + (x >= 2 ? x - 2 : 0)];
    rpiv_piv_params p = rpiv_piv_params_default();
    p.threads = 2;
    strcpy(p.prep.ops, "clahe:48,highpass");
    rpiv_piv *with = NULL, *without = NULL;
    rpiv_field *f1 = NULL, *f2 = NULL;
    CHECK_OK(rpiv_piv_new(&p, 192, 160, NULL, &with));
    CHECK_OK(rpiv_piv_run(with, a, b, &f1));
    CHECK_OK(rpiv_preprocess_run(&p.prep, a, 2));
    CHECK_OK(rpiv_preprocess_run(&p.prep, b, 2));
    p.prep.ops[0] = '\0';
    CHECK_OK(rpiv_piv_new(&p, 192, 160, NULL, &without));
    CHECK_OK(rpiv_piv_run(without, a, b, &f2));
    if (f1 && f2) {
        size_t n = (size_t)f1->nx * (size_t)f1->ny;
        CHECK(f1->nx == f2->nx && f1->ny == f2->ny);
        CHECK(!memcmp(f1->u, f2->u, n * sizeof *f1->u) && !memcmp(f1->v, f2->v, n * sizeof *f1->v));
        double su = 0, sv = 0;
        for (size_t i = 0; i < n; i++) {
            su += (double)f1->u[i];
            sv += (double)f1->v[i];
        }
        printf("    mean displacement with preprocessing: %.3f, %.3f px (2, 1 expected)\n",
               su / (double)n, sv / (double)n);
        CHECK(fabs(su / (double)n - 2) < 0.1 && fabs(sv / (double)n - 1) < 0.1);
    }
    /* a bad list is refused when the plan is made */
    strcpy(p.prep.ops, "clahe,blur");
    rpiv_piv *bad = NULL;
    CHECK_FAILS(rpiv_piv_new(&p, 192, 160, NULL, &bad), RPIV_EINVAL);
    CHECK(bad == NULL && strstr(rpiv_errmsg(), "'blur'") != NULL);
    rpiv_field_free(f1);
    rpiv_field_free(f2);
    rpiv_piv_free(with);
    rpiv_piv_free(without);
    rpiv_image_free(a);
    rpiv_image_free(b);
}

int main(void)
{
    rpiv_init();
    RUN_TEST(parse_reads_the_list);
    RUN_TEST(parse_errors_name_the_word);
    RUN_TEST(invert_and_cap_are_exact);
    RUN_TEST(highpass_removes_the_background);
    RUN_TEST(normalize_equalises_local_contrast);
    RUN_TEST(clahe_spreads_a_dark_image);
    RUN_TEST(clahe_clip_keeps_bins_at_the_limit);
    RUN_TEST(clahe_percentiles_saturate_the_tails);
    RUN_TEST(any_thread_count_gives_the_same_bits);
    RUN_TEST(clahe_highpass_in_one_gives_the_same_bits);
    RUN_TEST(the_plan_preprocesses_both_frames);
    return check_summary();
}
