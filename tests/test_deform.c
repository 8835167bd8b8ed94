/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "check.h"
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
            double r = ref[i], da = (double)oa[i] - r, db = (double)ob[i] - r;
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

int main(void)
{
    RUN_TEST(deform_bspline_interpolates_pixels_and_reproduces_cubics);
    RUN_TEST(deform_prefilter_small_images);
    RUN_TEST(deform_predictor_keeps_linear_fields_linear);
    RUN_TEST(deform_predictor_interpolates_nodes);
    RUN_TEST(deform_shifts_a_bspline_interpolated_image);
    RUN_TEST(deform_is_thread_count_independent);
    return check_summary();
}
