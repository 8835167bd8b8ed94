/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The validation tests beyond the median (peak ratio, global limits, mean +- k std), the
 * inpainting replacement and the penalised least-squares smoothing, on fields with outliers
 * of known position. */
#include "check.h"
#include "piv_testimg.h"
#include "rpiv/field.h"
#include "rpiv/piv.h"
#include "rpiv/series.h"
#include "rpiv/validate.h"

#define NX 30
#define NY 24

/* u = 0.5 + 0.03 i - 0.02 j, v = -1 + 0.01 i + 0.04 j (linear), peak ratio 3 everywhere */
static rpiv_field *linear(void)
{
    rpiv_field *f = NULL;
    if (rpiv_field_new(NX, NY, 16, 16, 16, 16, &f))
        return NULL;
    for (int j = 0; j < NY; j++)
        for (int i = 0; i < NX; i++) {
            f->u[j * NX + i] = (float)(0.5 + 0.03 * i - 0.02 * j);
            f->v[j * NX + i] = (float)(-1 + 0.01 * i + 0.04 * j);
            f->peak_ratio[j * NX + i] = 3;
        }
    return f;
}

static double lin_u(int i, int j)
{
    return 0.5 + 0.03 * i - 0.02 * j;
}
static double lin_v(int i, int j)
{
    return -1 + 0.01 * i + 0.04 * j;
}

static void peak_ratio_threshold(void)
{
    rpiv_field *f = linear();
    CHECK(f != NULL);
    if (!f)
        return;
    f->peak_ratio[5 * NX + 7] = 1.1f;
    f->peak_ratio[9 * NX + 20] = 1.4f;
    f->peak_ratio[10 * NX + 10] = 0; /* unknown: kept */
    f->flag[11 * NX + 11] = RPIV_FLAG_MASKED;
    f->peak_ratio[11 * NX + 11] = 1.0f; /* masked: left alone */
    size_t n = 0;
    CHECK_OK(rpiv_validate_peak_ratio(f, 1.3, &n));
    CHECK(n == 1 && f->flag[5 * NX + 7] == RPIV_FLAG_REPLACED);
    CHECK(f->flag[9 * NX + 20] == RPIV_FLAG_VALID && f->flag[10 * NX + 10] == RPIV_FLAG_VALID);
    CHECK(f->flag[11 * NX + 11] == RPIV_FLAG_MASKED);
    CHECK_OK(rpiv_validate_peak_ratio(f, 1.5, &n));
    CHECK(n == 1 && f->flag[9 * NX + 20] == RPIV_FLAG_REPLACED);
    CHECK_FAILS(rpiv_validate_peak_ratio(f, -1, &n), RPIV_EINVAL);
    rpiv_field_free(f);
}

static void global_limits_and_std(void)
{
    rpiv_field *f = linear();
    CHECK(f != NULL);
    if (!f)
        return;
    f->u[3 * NX + 4] = 6;     /* far outlier in u */
    f->v[15 * NX + 25] = -9;  /* far outlier in v */
    f->u[20 * NX + 2] = 1.9f; /* a mild one: within limits, 5 std off */
    size_t n = 0;
    /* only u limited */
    CHECK_OK(rpiv_validate_limits(f, -2, 2, 0, 0, &n));
    CHECK(n == 1 && f->flag[3 * NX + 4] == RPIV_FLAG_REPLACED);
    CHECK(f->flag[15 * NX + 25] == RPIV_FLAG_VALID);
    CHECK_OK(rpiv_validate_limits(f, -2, 2, -3, 3, &n));
    CHECK(n == 1 && f->flag[15 * NX + 25] == RPIV_FLAG_REPLACED);
    /* the linear field spans u 0.04..1.37 (std 0.27): 1.9 is 4.4 std above the mean 0.71 */
    CHECK_OK(rpiv_validate_std(f, 5, &n));
    CHECK(n == 0);
    CHECK_OK(rpiv_validate_std(f, 3, &n));
    CHECK(n == 1 && f->flag[20 * NX + 2] == RPIV_FLAG_REPLACED);
    CHECK_FAILS(rpiv_validate_std(f, 0, &n), RPIV_EINVAL);
    int bad = 0;
    for (int k = 0; k < NX * NY; k++)
        bad += f->flag[k] == RPIV_FLAG_REPLACED;
    CHECK(bad == 3);
    rpiv_field_free(f);
}

/* A 5 x 4 hole of outliers in a linear field: the Laplace inpainting restores the linear
 * field (harmonic) where the gap is enclosed by valid vectors, the 3x3 median fills with a
 * visible error. */
static void inpaint_fills_a_large_gap(void)
{
    rpiv_field *f = linear(), *g = NULL;
    CHECK(f != NULL);
    if (!f)
        return;
    for (int j = 8; j < 12; j++)
        for (int i = 10; i < 15; i++) {
            f->u[j * NX + i] = 5;
            f->v[j * NX + i] = -5;
            f->flag[j * NX + i] = RPIV_FLAG_REPLACED;
        }
    /* an edge gap and a masked block next to it (Neumann at both) */
    for (int i = 0; i < 3; i++)
        f->flag[0 * NX + i] = RPIV_FLAG_REPLACED;
    for (int j = 2; j < 5; j++)
        for (int i = 20; i < 23; i++)
            f->flag[j * NX + i] = RPIV_FLAG_MASKED;
    CHECK_OK(rpiv_field_copy(f, &g));
    size_t nf = 0;
    CHECK_OK(rpiv_validate_inpaint(f, 0, &nf));
    CHECK(nf == 23);
    CHECK_OK(rpiv_validate_replace(g, 0, NULL));
    double ei = 0, em = 0, ee = 0;
    for (int j = 0; j < NY; j++)
        for (int i = 0; i < NX; i++) {
            int k = j * NX + i;
            if (f->flag[k] != RPIV_FLAG_REPLACED)
                continue;
            double a =
                fmax(fabs((double)f->u[k] - lin_u(i, j)), fabs((double)f->v[k] - lin_v(i, j)));
            double b =
                fmax(fabs((double)g->u[k] - lin_u(i, j)), fabs((double)g->v[k] - lin_v(i, j)));
            if (j == 0) { /* the edge gap: zero normal gradient at the edge, not exact */
                ee = a > ee ? a : ee;
                continue;
            }
            ei = a > ei ? a : ei;
            em = b > em ? b : em;
        }
    printf("gap of 5x4 in a linear field: max error inpaint %.2e px, median %.3f px; edge gap: "
           "inpaint %.3f px\n",
           ei, em, ee);
    CHECK(ei < 1e-4);
    CHECK(ee < 0.06); /* measured 0.043 px (the u slope is 0.03 px per step) */
    CHECK(em > 0.01); /* the median's fill is not exact: the test can tell them apart */
    CHECK(f->flag[2 * NX + 20] == RPIV_FLAG_MASKED && f->u[2 * NX + 20] == (float)lin_u(20, 2));
    rpiv_field_free(f);
    rpiv_field_free(g);
}

/* Smoothing: a smooth field plus 0.1 px noise gets closer to the truth; a constant field
 * is unchanged; masked vectors keep their values. */
static void smoothing_reduces_noise(void)
{
    rpiv_field *f = NULL;
    CHECK_OK(rpiv_field_new(40, 32, 8, 8, 16, 16, &f));
    if (!f)
        return;
    uint64_t seed = 7;
    double e0 = 0, e1 = 0;
    for (int j = 0; j < 32; j++)
        for (int i = 0; i < 40; i++) {
            f->u[j * 40 + i] = (float)(sin(2 * M_PI * i / 40.0) + 0.1 * ti_gauss(&seed));
            f->v[j * 40 + i] = (float)(cos(2 * M_PI * j / 32.0) + 0.1 * ti_gauss(&seed));
        }
    f->flag[100] = RPIV_FLAG_MASKED;
    f->u[100] = 42;
    for (int j = 0; j < 32; j++)
        for (int i = 0; i < 40; i++)
            if (j * 40 + i != 100)
                e0 += pow((double)f->u[j * 40 + i] - sin(2 * M_PI * i / 40.0), 2) +
                      pow((double)f->v[j * 40 + i] - cos(2 * M_PI * j / 32.0), 2);
    CHECK_OK(rpiv_validate_smooth(f, 2.0));
    for (int j = 0; j < 32; j++)
        for (int i = 0; i < 40; i++)
            if (j * 40 + i != 100)
                e1 += pow((double)f->u[j * 40 + i] - sin(2 * M_PI * i / 40.0), 2) +
                      pow((double)f->v[j * 40 + i] - cos(2 * M_PI * j / 32.0), 2);
    e0 = sqrt(e0 / (2 * 40 * 32 - 2));
    e1 = sqrt(e1 / (2 * 40 * 32 - 2));
    printf("smoothing s = 2: RMS error %.4f px -> %.4f px\n", e0, e1);
    CHECK(e1 < 0.5 * e0);
    CHECK(f->u[100] == 42);
    CHECK_FAILS(rpiv_validate_smooth(f, -1), RPIV_EINVAL);
    for (int k = 0; k < 40 * 32; k++) {
        f->u[k] = 1.25f;
        f->v[k] = -0.5f;
    }
    CHECK_OK(rpiv_validate_smooth(f, 10));
    CHECK_NEAR(f->u[500], 1.25, 1e-5);
    CHECK_NEAR(f->v[777], -0.5, 1e-5);
    rpiv_field_free(f);
}

/* The engine: off by default (the defaults reject nothing more), params checked. */
/* u = 1.5 + 0.5 sin(2 pi y / 1024) px, v = 0.5 px: smooth on the scale of the grid */
static void wave(void *user, double x, double y, double *u, double *v)
{
    (void)user;
    (void)x;
    *u = 1.5 + 0.5 * sin(2 * M_PI * y / 1024.0);
    *v = 0.5;
}

typedef struct sparse_src {
    int pairs_made;
} sparse_src;

/* Pair i of a sparse, noisy ensemble: 128 x 128, 0.006 particles per pixel, 10 % noise. */
static rpiv_status sparse_pair(void *user, size_t i, int pass, rpiv_image *a, rpiv_image *b)
{
    (void)pass;
    ti_params tp = {128, 128, 0.006, 2.5, 1000, 0.10, 50, 4242 + (uint64_t)i};
    ti_pair(&tp, wave, NULL, a->px, b->px);
    ((sparse_src *)user)->pairs_made++;
    return RPIV_OK;
}

static double wave_err(const rpiv_field *f)
{
    double s = 0;
    size_t n = (size_t)f->nx * (size_t)f->ny;
    for (int j = 0; j < f->ny; j++)
        for (int i = 0; i < f->nx; i++) {
            double u, v;
            wave(NULL, f->x0 + i * f->dx, f->y0 + j * f->dy, &u, &v);
            double e = (double)f->u[j * f->nx + i] - u;
            s += e * e;
        }
    return sqrt(s / (double)n);
}

/* [piv] smooth applies to the ensemble's field as to a pair's: the ensemble run with smooth
 * gives rpiv_validate_smooth of the run without, bit for bit, and it is closer to the truth
 * on a sparse ensemble of 3 pairs. */
static void smoothing_applies_to_ensembles(void)
{
    rpiv_piv_params p = rpiv_piv_params_default();
    p.threads = 1;
    rpiv_field *raw = NULL, *sm = NULL;
    sparse_src us = {0};
    rpiv_series_source src = {3, sparse_pair, NULL, &us};
    rpiv_piv *pv = NULL;
    p.ensemble = 1;
    CHECK_OK(rpiv_piv_new(&p, 128, 128, NULL, &pv));
    CHECK_OK(rpiv_series_ensemble_source(pv, &src, NULL, &raw));
    rpiv_piv_free(pv);
    p.smooth = 2;
    CHECK_OK(rpiv_piv_new(&p, 128, 128, NULL, &pv));
    CHECK_OK(rpiv_series_ensemble_source(pv, &src, NULL, &sm));
    rpiv_piv_free(pv);
    double e_raw = wave_err(raw);
    CHECK_OK(rpiv_validate_smooth(raw, 2));
    size_t n = (size_t)raw->nx * (size_t)raw->ny, same = 0;
    for (size_t k = 0; k < n; k++)
        same += raw->u[k] == sm->u[k] && raw->v[k] == sm->v[k];
    CHECK(same == n);
    double e_sm = wave_err(sm);
    printf("  ensemble of 3 sparse pairs: RMS error of u %.4f px raw, %.4f px smoothed (S = 2)\n",
           e_raw, e_sm);
    CHECK(e_sm < 0.8 * e_raw);
    rpiv_field_free(raw);
    rpiv_field_free(sm);
}

static void params_defaults_off(void)
{
    rpiv_piv_params p = rpiv_piv_params_default();
    CHECK(p.peak_ratio_min == 0 && p.std_k == 0 && p.replace == 0 && p.smooth == 0);
    CHECK(!(p.u_min_px < p.u_max_px) && !(p.v_min_px < p.v_max_px));
    CHECK_OK(rpiv_piv_params_check(&p));
    p.replace = 2;
    CHECK_FAILS(rpiv_piv_params_check(&p), RPIV_EINVAL);
    p.replace = 1;
    p.smooth = -1;
    CHECK_FAILS(rpiv_piv_params_check(&p), RPIV_EINVAL);
}

int main(void)
{
    RUN_TEST(peak_ratio_threshold);
    RUN_TEST(global_limits_and_std);
    RUN_TEST(inpaint_fills_a_large_gap);
    RUN_TEST(smoothing_reduces_noise);
    RUN_TEST(smoothing_applies_to_ensembles);
    RUN_TEST(params_defaults_off);
    return check_summary();
}
