/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "check.h"
#include "deform_impl.h"
#include "piv_impl.h"
#include "piv_testimg.h"
#include "rpiv/deform.h"
#include "rpiv/field.h"

#include <string.h>

static double cubic(double x, double y)
{
    return 0.0013 * x * x * x - 0.021 * x * x * y + 0.17 * y * y - 3.1 * y + 7.25;
}

/* Interpolation is exact at the pixels and reproduces a cubic polynomial between them (away
 * from the border, where the mirror extension of a cubic is no longer a cubic). */
static void deform_bspline_interpolates_pixels_and_reproduces_cubics(void)
{
    enum { W = 64, H = 56 };
    float *img = malloc(sizeof(float) * W * H), *c = malloc(sizeof(float) * W * H);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            img[y * W + x] = (float)cubic(x, y);
    memcpy(c, img, sizeof(float) * W * H);
    rpiv_deform_prefilter(c, W, H, 1);
    double maxerr = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            double e = fabs((double)rpiv_deform_sample(c, W, H, x, y, 0) - (double)img[y * W + x]);
            maxerr = e > maxerr ? e : maxerr;
        }
    CHECK(maxerr < 1e-4 * 300); /* values reach ~300: float rounding */
    const double pts[][2] = {{20.3187, 30.7413}, {31.9021, 17.0517}, {40.5, 25.25}};
    for (int k = 0; k < 3; k++)
        CHECK_NEAR(rpiv_deform_sample(c, W, H, pts[k][0], pts[k][1], 0),
                   cubic(pts[k][0], pts[k][1]), 2e-3);
    /* outside [-0.5, w-0.5] the fill value comes back */
    CHECK(rpiv_deform_sample(c, W, H, -0.6, 10, 42.5f) == 42.5f);
    CHECK(rpiv_deform_sample(c, W, H, 10, H - 0.4, -3.0f) == -3.0f);
    free(img);
    free(c);
}

/* A short line (n <= the causal horizon) uses the exact mirror initialisation. */
static void deform_prefilter_small_images(void)
{
    float v[5] = {1.5f, -2.25f, 3.0f, 0.125f, 4.0f}, c[5];
    memcpy(c, v, sizeof v);
    rpiv_deform_prefilter(c, 5, 1, 1);
    for (int i = 0; i < 5; i++)
        CHECK_NEAR(rpiv_deform_sample(c, 5, 1, i, 0, 0), v[i], 1e-5);
    float one = 3.5f;
    rpiv_deform_prefilter(&one, 1, 1, 1);
    CHECK(one == 3.5f);
}

typedef struct lin {
    double a, bx, by;
} lin;

static rpiv_field *grid_field(int nx, int ny, double x0, double y0, double d, lin lu, lin lv)
{
    rpiv_field *f = NULL;
    if (rpiv_field_new(nx, ny, x0, y0, d, d, &f))
        return NULL;
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            double x = x0 + i * d, y = y0 + j * d;
            f->u[j * nx + i] = (float)(lu.a + lu.bx * x + lu.by * y);
            f->v[j * nx + i] = (float)(lv.a + lv.bx * x + lv.by * y);
        }
    return f;
}

/* The curvature continued beyond the grid (piv.edge_curvature): a field quadratic in y, u =
 * 2 + 0.004 (y - 40)^2 on a 9 x 7 grid (nodes y = 15.5 ... 111.5, step 16): half a step
 * beyond the last row (y = 119.5) the linear continuation is off by the curvature's share,
 * 0.004 * 8^2 = 0.256 px; with the curvature continued it is within 1 % of that. A line
 * whose end nodes are not all measured (a replaced one) keeps the linear continuation; noise, whose
 * second differences change sign, is not continued (deform_edge_curv 0). */
static double quad_y(double y)
{
    return 2 + 0.004 * (y - 40) * (y - 40);
}

static void deform_predictor_continues_the_curvature(void)
{
    enum { NX = 9, NY = 7 };
    rpiv_field *f = NULL;
    CHECK_OK(rpiv_field_new(NX, NY, 15.5, 15.5, 16, 16, &f));
    if (!f)
        return;
    unsigned char flag[NX * NY];
    for (int j = 0; j < NY; j++)
        for (int i = 0; i < NX; i++) {
            f->u[j * NX + i] = (float)quad_y(15.5 + 16 * j);
            f->v[j * NX + i] = 0;
            flag[j * NX + i] = RPIV_FLAG_VALID;
        }
    rpiv_deform_pred *pl = NULL, *cur = NULL, *part = NULL;
    CHECK_OK(rpiv_deform_pred_new(f, 160, 128, 0, &pl));
    CHECK_OK(deform_pred_new_ext(f, 160, 128, 0, flag, NULL, &cur));
    flag[(NY - 2) * NX + 4] = RPIV_FLAG_REPLACED; /* column 4: among its last 4 nodes */
    CHECK_OK(deform_pred_new_ext(f, 160, 128, 0, flag, NULL, &part));
    if (pl && cur && part) {
        double ul, uc, up, v;
        rpiv_deform_pred_eval(pl, 79.5, 119.5, &ul, &v);
        rpiv_deform_pred_eval(cur, 79.5, 119.5, &uc, &v);
        rpiv_deform_pred_eval(part, 79.5, 119.5, &up, &v);
        const double t = quad_y(119.5);
        printf("    y = 119.5: linear continuation %+.4f px, curvature continued %+.4f px, one "
               "node replaced %+.4f px\n",
               ul - t, uc - t, up - t);
        CHECK(fabs(ul - t) > 0.2);
        CHECK(fabs(uc - t) < 0.01 * fabs(ul - t));
        CHECK_NEAR(up, ul, 1e-3 * fabs(ul - t));
        /* inside the grid the three agree to the spline's accuracy on a quadratic */
        rpiv_deform_pred_eval(cur, 79.5, 63.5, &uc, &v);
        CHECK_NEAR(uc, quad_y(63.5), 1e-4);
    }
    const float noisy[5] = {1.0f, 1.2f, 0.9f, 1.15f, 1.05f}, bent[5] = {4, 2, 1, 0.5f, 0.3f};
    CHECK(deform_edge_curv(noisy, 5, 1, 0) == 0);
    CHECK_NEAR(deform_edge_curv(bent, 5, 1, 0), 0.5, 1e-9); /* minmod(1.0, 0.5) */
    /* with a threshold: the garrote, 0.5 - 0.3^2 / 0.5; nothing below it */
    CHECK_NEAR(deform_edge_curv(bent, 5, 1, 0.3), 0.32, 1e-6);
    CHECK(deform_edge_curv(bent, 5, 1, 0.6) == 0);
    rpiv_deform_pred_free(pl);
    rpiv_deform_pred_free(cur);
    rpiv_deform_pred_free(part);
    rpiv_field_free(f);
}

/* The threshold of the continued curvature (piv_curv_threshold): on a 15 x 15 grid of white
 * noise of sigma 0.05 px the second differences' noise is sigma sqrt(6) = 0.122 px and the
 * threshold 4 sigma_d sqrt(2 ln 225) with sigma_d = sigma sqrt(6) / 4, 0.403 px. The estimate
 * is a median of ~200 details (8 % standard error), the smallest over the four grid directions
 * where none has flow detail (measured 0.328 and 0.318 px; 0.433 for the quadratic's u, where
 * only the direction across it is free of it): asserted within 0.6-1.25 times 0.403. None of
 * the 30 column ends of the noise has its curvature continued (without the threshold minmod
 * keeps those whose two second differences agree in sign: 7). A quadratic of second
 * difference 2.048 px (u = 0.004 y^2, step 16) plus that noise keeps its curvature at every
 * end, 2.048 less the garrote's t^2 / c and the noise. */
static void deform_curvature_threshold_is_the_noise(void)
{
    enum { N = 15 };
    rpiv_field *f = NULL;
    CHECK_OK(rpiv_field_new(N, N, 15.5, 15.5, 16, 16, &f));
    if (!f)
        return;
    uint64_t seed = 77;
    for (int q = 0; q < 2; q++) {
        for (int k = 0; k < N * N; k++) {
            const double y = 16.0 * (k / N);
            f->u[k] = (float)(0.05 * ti_gauss(&seed) + (q ? 0.004 * y * y : 0));
            f->v[k] = (float)(0.05 * ti_gauss(&seed));
        }
        double thr[2];
        piv_curv_threshold(f, thr);
        int kept = 0, kept0 = 0;
        double worst = 0;
        for (int i = 0; i < N; i++)
            for (int side = 0; side < 2; side++) { /* the columns' ends: along y */
                const float *g = f->u + (side ? (size_t)(N - 1) * N : 0) + (size_t)i;
                const ptrdiff_t st = side ? -N : N;
                const double c = deform_edge_curv(g, N, st, thr[0]);
                kept += c != 0;
                kept0 += deform_edge_curv(g, N, st, 0) != 0;
                worst = fmax(worst, fabs(c - 2.048));
            }
        printf("    %s: threshold u %.3f v %.3f px, column ends continued %d of %d (%d without "
               "the threshold), largest |c - 2.048| %.3f px\n",
               q ? "quadratic + noise" : "noise", thr[0], thr[1], kept, 2 * N, kept0, worst);
        CHECK(thr[1] > 0.6 * 0.403 && thr[1] < 1.25 * 0.403);
        if (q) {
            CHECK(kept == 2 * N);
            /* t^2 / c 0.09 px and the smaller of two second differences of noise 0.122 px each,
             * over 30 ends: measured 0.361 */
            CHECK(worst < 0.6);
        } else {
            CHECK(thr[0] > 0.6 * 0.403 && thr[0] < 1.25 * 0.403);
            CHECK(kept == 0 && kept0 > 5);
        }
    }
    rpiv_field_free(f);
}

/* The predictor reproduces a linear field everywhere, also beyond the outermost grid
 * points (point-symmetric ghosts), through both the point and the row evaluation. */
static void deform_predictor_keeps_linear_fields_linear(void)
{
    lin lu = {1.1379, 0.0213, -0.0311}, lv = {-0.4127, 0.0087, 0.0152};
    rpiv_field *f = grid_field(9, 7, 15.5, 15.5, 16, lu, lv);
    rpiv_deform_pred *p = NULL, *q = NULL;
    CHECK(f != NULL);
    if (!f)
        return;
    CHECK_OK(rpiv_deform_pred_new(f, 160, 128, 0, &p));
    if (!p)
        goto out;
    double u, v;
    const double pts[][2] = {{0, 0}, {159, 127}, {77.3, 45.9}, {2.5, 120.25}};
    for (int k = 0; k < 4; k++) {
        rpiv_deform_pred_eval(p, pts[k][0], pts[k][1], &u, &v);
        CHECK_NEAR(u, lu.a + lu.bx * pts[k][0] + lu.by * pts[k][1], 2e-5);
        CHECK_NEAR(v, lv.a + lv.bx * pts[k][0] + lv.by * pts[k][1], 2e-5);
    }
    float ru[160], rv[160], *scr = malloc(sizeof(float) * rpiv_deform_pred_scratch(p));
    double maxerr = 0;
    for (int y = 0; y < 128; y += 7) {
        rpiv_deform_pred_row(p, y, 0, 160, ru, rv, scr);
        for (int x = 0; x < 160; x++) {
            double e = fabs((double)ru[x] - (lu.a + lu.bx * x + lu.by * y));
            e = fmax(e, fabs((double)rv[x] - (lv.a + lv.bx * x + lv.by * y)));
            maxerr = fmax(maxerr, e);
        }
    }
    CHECK(maxerr < 2e-5);
    /* with a shift, rows are evaluated at (x + shift, y + shift) */
    CHECK_OK(rpiv_deform_pred_new(f, 160, 128, 0.25, &q));
    maxerr = 0;
    for (int y = 0; q && y < 128; y += 5) {
        rpiv_deform_pred_row(q, y, 3, 150, ru, rv, scr);
        for (int x = 3; x < 150; x++) {
            double X = x + 0.25, Y = y + 0.25;
            double e = fabs((double)ru[x - 3] - (lu.a + lu.bx * X + lu.by * Y));
            e = fmax(e, fabs((double)rv[x - 3] - (lv.a + lv.bx * X + lv.by * Y)));
            maxerr = fmax(maxerr, e);
        }
    }
    CHECK(maxerr < 2e-5);
    free(scr);
out:
    rpiv_deform_pred_free(q);
    rpiv_deform_pred_free(p);
    rpiv_field_free(f);
}

/* At the grid nodes the predictor returns the field's values (interpolation). */
static void deform_predictor_interpolates_nodes(void)
{
    rpiv_field *f = NULL;
    rpiv_deform_pred *p = NULL;
    CHECK_OK(rpiv_field_new(6, 5, 31.5, 23.5, 32, 24, &f));
    if (!f)
        return;
    uint64_t s = 31337;
    for (int i = 0; i < 30; i++) {
        f->u[i] = (float)(8 * ti_rnd(&s) - 4);
        f->v[i] = (float)(8 * ti_rnd(&s) - 4);
    }
    CHECK_OK(rpiv_deform_pred_new(f, 256, 160, 0, &p));
    if (p)
        for (int j = 0; j < 5; j++)
            for (int i = 0; i < 6; i++) {
                double u, v;
                rpiv_deform_pred_eval(p, 31.5 + 32 * i, 23.5 + 24 * j, &u, &v);
                CHECK_NEAR(u, f->u[j * 6 + i], 2e-5);
                CHECK_NEAR(v, f->v[j * 6 + i], 2e-5);
            }
    rpiv_deform_pred_free(p);
    rpiv_field_free(f);
}

/* Deforming a particle image by a uniform predictor shifts it: out_a(x) = A(x - d/2) and
 * out_b(x) = B(x + d/2) must both match the particles rendered at their midpoints. Returns
 * the relative RMS errors of the B-spline (worst of A, B) and of bilinear interpolation. */
static void shift_errors(double d_tau, double *e_bspline, double *e_bilinear)
{
    enum { W = 96, H = 80 };
    const double d[2] = {1.3187, -0.7413}, zero[2] = {0, 0};
    ti_params tp = {W, H, 0.05, d_tau, 1000, 0, 0, 12345};
    float *a = malloc(sizeof(float) * W * H), *b = malloc(sizeof(float) * W * H);
    float *ref = malloc(sizeof(float) * W * H), *junk = malloc(sizeof(float) * W * H);
    float *ca = malloc(sizeof(float) * W * H), *cb = malloc(sizeof(float) * W * H);
    float *oa = calloc(W * H, sizeof(float)), *ob = calloc(W * H, sizeof(float));
    ti_pair(&tp, ti_uniform, (void *)d, a, b);
    ti_pair(&tp, ti_uniform, (void *)zero, ref, junk); /* same particles, at the midpoints */
    rpiv_field *f = grid_field(3, 3, 20, 20, 28, (lin){d[0], 0, 0}, (lin){d[1], 0, 0});
    rpiv_deform_pred *p = NULL;
    CHECK_OK(rpiv_deform_pred_new(f, W, H, 0, &p));
    memcpy(ca, a, sizeof(float) * W * H);
    memcpy(cb, b, sizeof(float) * W * H);
    rpiv_deform_prefilter(ca, W, H, 1);
    rpiv_deform_prefilter(cb, W, H, 1);
    const int rect[4] = {8, 8, W - 8, H - 8};
    CHECK_OK(rpiv_deform_run(ca, cb, W, H, p, rect, 0, 0, oa, ob, 1));
    double ea = 0, eb = 0, el = 0, sig = 0;
    for (int y = 8; y < H - 8; y++)
        for (int x = 8; x < W - 8; x++) {
            size_t i = (size_t)y * W + (size_t)x;
            double r = (double)ref[i], da = (double)oa[i] - r, db = (double)ob[i] - r;
            double X = x - 0.5 * d[0], Y = y - 0.5 * d[1], tx = X - floor(X), ty = Y - floor(Y);
            size_t k = (size_t)floor(Y) * W + (size_t)floor(X);
            double bl = (1 - ty) * ((1 - tx) * (double)a[k] + tx * (double)a[k + 1]) +
                        ty * ((1 - tx) * (double)a[k + W] + tx * (double)a[k + W + 1]);
            ea += da * da;
            eb += db * db;
            el += (bl - r) * (bl - r);
            sig += r * r;
        }
    *e_bspline = sqrt(fmax(ea, eb) / sig);
    *e_bilinear = sqrt(el / sig);
    printf("    shift of a d_tau = %.1f px particle image: relative RMS error B-spline %.4f, "
           "bilinear %.4f\n",
           d_tau, *e_bspline, *e_bilinear);
    rpiv_deform_pred_free(p);
    rpiv_field_free(f);
    free(a), free(b), free(ref), free(junk), free(ca), free(cb), free(oa), free(ob);
}

static void deform_shifts_a_bspline_interpolated_image(void)
{
    double eb, el;
    /* well-sampled particles: the interpolated shift converges to the true one */
    shift_errors(4.0, &eb, &el);
    CHECK(eb < 0.02);
    CHECK(el > 4 * eb);
    /* d_tau = 2.5 px is near the sampling limit (aliasing bounds any interpolator), yet the
     * B-spline error is less than half the bilinear one */
    shift_errors(2.5, &eb, &el);
    CHECK(eb < 0.125);
    CHECK(el > 2 * eb);
}

/* The same results with 1 and 2 threads, bit for bit. */
static void deform_is_thread_count_independent(void)
{
    enum { W = 200, H = 150 };
    const double d[2] = {2.2719, 1.0391};
    ti_params tp = {W, H, 0.05, 2.5, 1000, 0.01, 100, 777};
    size_t n = (size_t)W * H;
    float *a = malloc(sizeof(float) * n), *b = malloc(sizeof(float) * n);
    float *a2 = malloc(sizeof(float) * n), *b2 = malloc(sizeof(float) * n);
    float *o[4];
    for (int k = 0; k < 4; k++)
        o[k] = calloc(n, sizeof(float));
    ti_pair(&tp, ti_uniform, (void *)d, a, b);
    memcpy(a2, a, sizeof(float) * n);
    memcpy(b2, b, sizeof(float) * n);
    rpiv_deform_prefilter(a, W, H, 1);
    rpiv_deform_prefilter(b, W, H, 1);
    rpiv_deform_prefilter(a2, W, H, 2);
    rpiv_deform_prefilter(b2, W, H, 2);
    CHECK(memcmp(a, a2, sizeof(float) * n) == 0 && memcmp(b, b2, sizeof(float) * n) == 0);
    rpiv_field *f =
        grid_field(5, 4, 30, 25, 30, (lin){d[0], 0.01, 0.002}, (lin){d[1], -0.003, 0.02});
    rpiv_deform_pred *p = NULL;
    CHECK_OK(rpiv_deform_pred_new(f, W, H, RPIV_DEFORM_SHIFT, &p));
    const int rect[4] = {0, 0, W, H};
    CHECK_OK(rpiv_deform_run(a, b, W, H, p, rect, 100, 100, o[0], o[1], 1));
    CHECK_OK(rpiv_deform_run(a, b, W, H, p, rect, 100, 100, o[2], o[3], 2));
    CHECK(memcmp(o[0], o[2], sizeof(float) * n) == 0 && memcmp(o[1], o[3], sizeof(float) * n) == 0);
    const int bad[4] = {0, 0, W + 1, H};
    CHECK_FAILS(rpiv_deform_run(a, b, W, H, p, bad, 0, 0, o[0], o[1], 1), RPIV_EINVAL);
    rpiv_deform_pred_free(p);
    rpiv_field_free(f);
    free(a), free(b), free(a2), free(b2);
    for (int k = 0; k < 4; k++)
        free(o[k]);
}

/* A random field on a grid of step d whose predictor changes fast (several px over a few
 * grid steps, steeper still in one column of nodes), for the vector blocks' tests. */
static rpiv_field *wild_field(int nx, int ny, double x0, double y0, double d, uint64_t seed)
{
    rpiv_field *f = NULL;
    if (rpiv_field_new(nx, ny, x0, y0, d, d, &f))
        return NULL;
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            double steep = i == nx / 2 ? 9.0 : 0.0;
            f->u[j * nx + i] = (float)(6 * ti_rnd(&seed) - 3 + steep);
            f->v[j * nx + i] = (float)(5 * ti_rnd(&seed) - 2.5 - 0.5 * steep);
        }
    return f;
}

/* The predictor rows by runs of common taps give the bits of the per-pixel code, for any
 * column range (runs cut anywhere, runs shorter than a vector). */
static void deform_predictor_rows_match_per_pixel_code(void)
{
    enum { W = 157, H = 61 };
    rpiv_field *f = wild_field(13, 6, 3.7, 4.1, 11.3, 91);
    rpiv_deform_pred *p = NULL;
    CHECK(f != NULL);
    if (!f)
        return;
    CHECK_OK(rpiv_deform_pred_new(f, W, H, RPIV_DEFORM_SHIFT, &p));
    float *s = malloc(sizeof(float) * rpiv_deform_pred_scratch(p));
    float u[W], v[W], ur[W], vr[W];
    const int cuts[][2] = {{0, W}, {5, W - 3}, {11, 14}, {W - 1, W}, {40, 47}};
    int same = 1;
    for (int y = 0; p && y < H; y += 3)
        for (int c = 0; c < 5; c++) {
            int x0 = cuts[c][0], x1 = cuts[c][1];
            rpiv_deform_pred_row(p, y, x0, x1, u, v, s);
            deform_pred_row_ref(p, y, x0, x1, ur, vr, s);
            same &= !memcmp(u, ur, sizeof(float) * (size_t)(x1 - x0)) &&
                    !memcmp(v, vr, sizeof(float) * (size_t)(x1 - x0));
        }
    CHECK(same);
    free(s);
    rpiv_deform_pred_free(p);
    rpiv_field_free(f);
}

/* deform_row's vector blocks (8 wide where the CPU has AVX2, 4 wide) against its per-pixel
 * path, the per-pixel code they replaced and rpiv_deform_sample, on random coefficients with
 * a predictor whose integer part changes inside the rows (by up to 1 within a block, and
 * more in the steep column), samples near and beyond the borders (fill values), a width that
 * is not a multiple of the blocks, and rows cut into ranges at arbitrary columns. */
static void deform_blocks_match_per_pixel_path(void)
{
    enum { W = 203, H = 77 };
    const size_t n = (size_t)W * H;
    const float fa = 31.5f, fb = -7.25f;
    float *ca = malloc(sizeof(float) * n), *cb = malloc(sizeof(float) * n), *o[8];
    uint64_t seed = 2718;
    for (size_t i = 0; i < n; i++) {
        ca[i] = (float)(200 * ti_rnd(&seed) - 50);
        cb[i] = (float)(200 * ti_rnd(&seed) - 50);
    }
    for (int k = 0; k < 8; k++)
        o[k] = malloc(sizeof(float) * n);
    rpiv_field *f = wild_field(14, 6, 6.2, 5.9, 14.7, 4321);
    rpiv_deform_pred *p = NULL;
    CHECK(f != NULL);
    if (f)
        CHECK_OK(rpiv_deform_pred_new(f, W, H, RPIV_DEFORM_SHIFT, &p));
    if (!p)
        goto out;
    float *s = malloc(sizeof(float) * deform_row_scratch(p, 0, W));
    float *pu = malloc(sizeof(float) * W), *pv = malloc(sizeof(float) * W);
    /* the field is what the test needs: integer parts changing inside blocks of 8, by 1 and
     * by more, and samples outside the frames */
    int changes = 0, wide = 0;
    for (int y = 0; y < H; y++) {
        rpiv_deform_pred_row(p, y, 0, W, pu, pv, s);
        for (int x = 0; x + 8 <= W; x += 8) {
            int lo = 1 << 20, hi = -(1 << 20);
            for (int j = 0; j < 8; j++) {
                int fx = (int)floorf(0.25f - 0.5f * pu[x + j]);
                lo = fx < lo ? fx : lo;
                hi = fx > hi ? fx : hi;
            }
            changes += hi - lo == 1;
            wide += hi - lo > 1;
        }
    }
    printf("    blocks of 8 with integer parts differing by 1: %d, by more: %d (of %d)\n", changes,
           wide, H * (W / 8));
    CHECK(changes > 100 && wide > 10);
    const int vls[3] = {8, 4, 0};
    for (int k = 0; k < 3; k++)
        for (int y = 0; y < H; y++)
            deform_row_blocks(vls[k], ca, cb, W, H, p, 0, W, y, fa, fb, o[2 * k] + (size_t)y * W,
                              o[2 * k + 1] + (size_t)y * W, s);
    CHECK(!memcmp(o[0], o[4], sizeof(float) * n) && !memcmp(o[1], o[5], sizeof(float) * n));
    CHECK(!memcmp(o[2], o[4], sizeof(float) * n) && !memcmp(o[3], o[5], sizeof(float) * n));
    /* rows cut into ranges: the same bits */
    const int cuts[] = {0, 3, 17, 18, 61, 100, 131, 190, 197, W};
    for (int y = 0; y < H; y++)
        for (int c = 0; c + 1 < (int)(sizeof cuts / sizeof cuts[0]); c++)
            deform_row(ca, cb, W, H, p, cuts[c], cuts[c + 1], y, fa, fb, o[6] + (size_t)y * W,
                       o[7] + (size_t)y * W, s);
    CHECK(!memcmp(o[0], o[6], sizeof(float) * n) && !memcmp(o[1], o[7], sizeof(float) * n));
    /* the replaced code and the sampling of the interpolant: last bits only */
    for (int y = 0; y < H; y++)
        deform_row_ref(ca, cb, W, H, p, 0, W, y, fa, fb, o[2] + (size_t)y * W, o[3] + (size_t)y * W,
                       s);
    /* errors relative to the largest coefficient (the bound of the interpolant: the weights
     * are convex), 150 */
    const double cmax = 150;
    double eref = 0, esam = 0;
    int nfill = 0, nfill_ref = 0;
    for (int y = 0; y < H; y++) {
        rpiv_deform_pred_row(p, y, 0, W, pu, pv, s);
        for (int x = 0; x < W; x++) {
            size_t i = (size_t)y * W + (size_t)x;
            for (int k = 0; k < 2; k++)
                eref = fmax(eref, fabs((double)o[k][i] - (double)o[k + 2][i]) / cmax);
            nfill += o[0][i] == fa && o[1][i] == fb;
            nfill_ref += o[2][i] == fa && o[3][i] == fb;
            double c = RPIV_DEFORM_SHIFT, hx = 0.5 * (double)pu[x], hy = 0.5 * (double)pv[x];
            float sa = rpiv_deform_sample(ca, W, H, x + c - hx, y + c - hy, fa);
            float sb = rpiv_deform_sample(cb, W, H, x + c + hx, y + c + hy, fb);
            /* rpiv_deform_sample takes [-0.5, w - 0.5], the deformation [1, w - 2] (deform_takes);
             * within rounding of the border the two may choose differently */
            if (sa == fa || sb == fb || (o[0][i] == fa && o[1][i] == fb))
                continue;
            esam = fmax(esam, fabs((double)o[0][i] - (double)sa) / cmax);
            esam = fmax(esam, fabs((double)o[1][i] - (double)sb) / cmax);
        }
    }
    printf("    against the replaced code: %.2g, against rpiv_deform_sample: %.2g (relative to the "
           "largest coefficient); "
           "%d filled pixels (replaced code %d)\n",
           eref, esam, nfill, nfill_ref);
    CHECK(eref < 1e-6 && esam < 1e-6);
    CHECK(nfill > 100 && nfill == nfill_ref);
    free(s), free(pu), free(pv);
out:
    rpiv_deform_pred_free(p);
    rpiv_field_free(f);
    free(ca), free(cb);
    for (int k = 0; k < 8; k++)
        free(o[k]);
}

/* The prefilter (16 rows through 4 x 4 transposed tiles, 8 rows interleaved, the gain within
 * the recursion, columns swept in slabs of whole rows) gives the bits of the code it
 * replaced, for sizes around the causal horizon, the tiles and the groups of rows, and any
 * thread count; so does the pair's prefilter (rows and causal columns in one sweep). */
static void deform_prefilter_matches_replaced_code(void)
{
    const int sizes[][2] = {{203, 77}, {17, 9}, {16, 23}, {5, 40},  {64, 16}, {33, 1}, {1, 19},
                            {20, 33},  {2, 48}, {19, 47}, {37, 16}, {37, 17}, {9, 45}};
    uint64_t seed = 1618;
    int same = 1;
    for (int k = 0; k < (int)(sizeof sizes / sizeof sizes[0]); k++) {
        const int w = sizes[k][0], h = sizes[k][1];
        const size_t n = (size_t)w * (size_t)h;
        float *a = malloc(sizeof(float) * n), *b = malloc(sizeof(float) * n);
        float *c = malloc(sizeof(float) * n);
        for (size_t i = 0; i < n; i++)
            a[i] = b[i] = c[i] = (float)(300 * ti_rnd(&seed) - 100);
        rpiv_deform_prefilter(a, w, h, 1);
        rpiv_deform_prefilter(b, w, h, 3);
        deform_prefilter_ref(c, w, h, 1);
        same &= !memcmp(a, c, sizeof(float) * n) && !memcmp(b, c, sizeof(float) * n);
        /* a pair, fused on one and two threads, split on three */
        for (int nt = 1; nt <= 3; nt++) {
            for (size_t i = 0; i < n; i++)
                a[i] = b[i] = c[i] = (float)(300 * ti_rnd(&seed) - 100);
            for (size_t i = 0; i < n; i++)
                b[i] = 0.37f * a[i] + 41.0f;
            float *d = malloc(sizeof(float) * n);
            memcpy(d, b, sizeof(float) * n);
            deform_prefilter_pair(a, b, w, h, nt);
            deform_prefilter_ref(c, w, h, 1);
            deform_prefilter_ref(d, w, h, 1);
            same &= !memcmp(a, c, sizeof(float) * n) && !memcmp(b, d, sizeof(float) * n);
            free(d);
        }
        free(a), free(b), free(c);
    }
    CHECK(same);
}

int main(void)
{
    RUN_TEST(deform_bspline_interpolates_pixels_and_reproduces_cubics);
    RUN_TEST(deform_prefilter_small_images);
    RUN_TEST(deform_predictor_keeps_linear_fields_linear);
    RUN_TEST(deform_predictor_continues_the_curvature);
    RUN_TEST(deform_curvature_threshold_is_the_noise);
    RUN_TEST(deform_predictor_interpolates_nodes);
    RUN_TEST(deform_shifts_a_bspline_interpolated_image);
    RUN_TEST(deform_is_thread_count_independent);
    RUN_TEST(deform_prefilter_matches_replaced_code);
    RUN_TEST(deform_predictor_rows_match_per_pixel_code);
    RUN_TEST(deform_blocks_match_per_pixel_path);
    return check_summary();
}
