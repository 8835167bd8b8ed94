/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "check.h"
#include "piv_testimg.h"
#include "rpiv/field.h"
#include "rpiv/validate.h"

/* A smooth field with small measurement noise (0.02 px): up to 0.43 px change per grid
 * step, with a gradient across the left and right edges. */
static rpiv_field *smooth(int nx, int ny, uint64_t seed)
{
    rpiv_field *f = NULL;
    if (rpiv_field_new(nx, ny, 16, 16, 16, 16, &f))
        return NULL;
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            double x = 16 + 16.0 * i, y = 16 + 16.0 * j;
            f->u[j * nx + i] = (float)(1.7 * sin(2 * M_PI * x / 400.0) + 0.02 * ti_gauss(&seed));
            f->v[j * nx + i] = (float)(-1.3 + 0.004 * y + 0.02 * ti_gauss(&seed));
        }
    return f;
}

static double true_u(int i)
{
    return 1.7 * sin(2 * M_PI * (16 + 16.0 * i) / 400.0);
}

static void validate_keeps_a_smooth_field(void)
{
    rpiv_field *f = smooth(24, 18, 11);
    size_t nrej = 99;
    CHECK_OK(rpiv_validate_median(f, 2, 0.1, &nrej));
    CHECK(nrej == 0);
    for (int k = 0; k < 24 * 18; k++)
        CHECK(f->flag[k] == RPIV_FLAG_VALID);
    rpiv_field_free(f);
}

static void validate_finds_planted_outliers_and_replaces_them(void)
{
    enum { NX = 24, NY = 18 };
    rpiv_field *f = smooth(NX, NY, 23);
    /* isolated outliers, one on an edge, one in a corner, and an adjacent pair */
    const int at[][2] = {{5, 4}, {12, 9}, {0, 7}, {23, 17}, {17, 3}, {18, 3}, {9, 14}};
    const float du[] = {3.1f, -2.2f, 1.7f, 4.4f, -3.3f, 2.9f, 0.0f};
    const float dv[] = {0.0f, 0.9f, 0.0f, 0.0f, 0.0f, 0.0f, -1.6f};
    for (int k = 0; k < 7; k++) {
        f->u[at[k][1] * NX + at[k][0]] += du[k];
        f->v[at[k][1] * NX + at[k][0]] += dv[k];
    }
    size_t nrej = 0, nfill = 0;
    CHECK_OK(rpiv_validate_median(f, 2, 0.1, &nrej));
    CHECK(nrej == 7);
    for (int k = 0; k < 7; k++)
        CHECK(f->flag[at[k][1] * NX + at[k][0]] == RPIV_FLAG_REPLACED);
    CHECK_OK(rpiv_validate_replace(f, 0, &nfill));
    CHECK(nfill == 7);
    for (int k = 0; k < 7; k++) {
        int i = at[k][0], j = at[k][1];
        CHECK_NEAR(f->u[j * NX + i], true_u(i), 0.12);
        CHECK_NEAR(f->v[j * NX + i], -1.3 + 0.004 * (16 + 16.0 * j), 0.08);
    }
    rpiv_field_free(f);
}

/* A cluster: the wrong vector X at (5, 5) has four wrong diagonal neighbours, each of which
 * fails against its own (mostly right) block; X itself, with half of its block wrong, passes a
 * single round (median midway, large spread) and must fall in the next one. */
static void validate_tests_again_a_vector_hidden_by_a_cluster(void)
{
    enum { NX = 12, NY = 11 };
    rpiv_field *f = smooth(NX, NY, 31);
    const int at[][2] = {{5, 5}, {4, 4}, {6, 4}, {4, 6}, {6, 6}};
    for (int k = 0; k < 5; k++)
        f->u[at[k][1] * NX + at[k][0]] += 5.0f;
    size_t nrej = 0;
    CHECK_OK(rpiv_validate_median(f, 2, 0.1, &nrej));
    CHECK(nrej == 5);
    for (int k = 0; k < 5; k++)
        CHECK(f->flag[at[k][1] * NX + at[k][0]] == RPIV_FLAG_REPLACED);
    rpiv_field_free(f);
}

/* The hand-worked case: neighbours 1..8 give Um = 4.5, rm = 2, so r0* = |U0 - 4.5| / 2.1;
 * U0 = 8.6 gives 1.952 (kept), U0 = 8.8 gives 2.048 (rejected). */
static void validate_threshold_matches_the_formula(void)
{
    const float vals[2] = {8.6f, 8.8f};
    const int expect[2] = {RPIV_FLAG_VALID, RPIV_FLAG_REPLACED};
    for (int t = 0; t < 2; t++) {
        rpiv_field *f = NULL;
        CHECK_OK(rpiv_field_new(3, 3, 0, 0, 1, 1, &f));
        const float nb[9] = {1, 2, 3, 4, 0, 5, 6, 7, 8};
        for (int k = 0; k < 9; k++)
            f->u[k] = nb[k];
        f->u[4] = vals[t];
        /* keep the neighbours out of the test: only the centre is examined */
        CHECK_OK(rpiv_validate_median(f, 2, 0.1, NULL));
        CHECK(f->flag[4] == expect[t]);
        rpiv_field_free(f);
    }
}

static void validate_masked_vectors_are_skipped_and_optionally_filled(void)
{
    enum { NX = 10, NY = 8 };
    rpiv_field *f = smooth(NX, NY, 5);
    for (int i = 0; i < NX; i++) {
        f->flag[3 * NX + i] = RPIV_FLAG_MASKED;
        f->u[3 * NX + i] = 55; /* garbage under the mask must not reject its neighbours */
        f->v[3 * NX + i] = 55;
    }
    size_t nrej = 9, nfill = 0;
    CHECK_OK(rpiv_validate_median(f, 2, 0.1, &nrej));
    CHECK(nrej == 0);
    CHECK_OK(rpiv_validate_replace(f, 0, &nfill));
    CHECK(nfill == 0 && f->u[3 * NX + 4] == 55);
    CHECK_OK(rpiv_validate_replace(f, 1, &nfill));
    CHECK(nfill == NX);
    CHECK(f->flag[3 * NX + 4] == RPIV_FLAG_MASKED);
    CHECK_NEAR(f->u[3 * NX + 4], true_u(4), 0.12);
    rpiv_field_free(f);
}

/* A hole bigger than a 3x3 neighbourhood fills from its rim inwards; a field with no valid
 * vector becomes 0. */
static void validate_fills_large_holes_and_empty_fields(void)
{
    enum { NX = 12, NY = 12 };
    rpiv_field *f = smooth(NX, NY, 8);
    for (int j = 3; j < 9; j++)
        for (int i = 3; i < 9; i++)
            f->flag[j * NX + i] = RPIV_FLAG_REPLACED;
    /* median fills stay within the range of the valid rim around the hole */
    float lo = 1e9f, hi = -1e9f;
    for (int j = 2; j < 10; j++)
        for (int i = 2; i < 10; i++)
            if (i == 2 || j == 2 || i == 9 || j == 9) {
                lo = fminf(lo, f->u[j * NX + i]);
                hi = fmaxf(hi, f->u[j * NX + i]);
            }
    size_t nfill = 0;
    CHECK_OK(rpiv_validate_replace(f, 0, &nfill));
    CHECK(nfill == 36);
    for (int j = 3; j < 9; j++)
        for (int i = 3; i < 9; i++)
            CHECK(f->u[j * NX + i] >= lo && f->u[j * NX + i] <= hi);
    rpiv_field_free(f);

    f = smooth(4, 3, 9);
    for (int k = 0; k < 12; k++)
        f->flag[k] = RPIV_FLAG_REPLACED;
    CHECK_OK(rpiv_validate_replace(f, 0, &nfill));
    CHECK(nfill == 12 && f->u[5] == 0 && f->v[7] == 0);
    CHECK_FAILS(rpiv_validate_median(f, 0, 0.1, NULL), RPIV_EINVAL);
    CHECK_FAILS(rpiv_validate_median(f, 2, -0.1, NULL), RPIV_EINVAL);
    rpiv_field_free(f);
}

/* A parabolic profile steep at the edges (0.9 px per grid step across the top and bottom
 * rows, as a Poiseuille flow gives): no vector is rejected, yet an outlier on the edge is. */
static void validate_edge_vectors_in_a_steep_gradient_are_kept(void)
{
    enum { NX = 15, NY = 15 };
    rpiv_field *f = NULL;
    CHECK_OK(rpiv_field_new(NX, NY, 15.5, 15.5, 16, 16, &f));
    if (!f)
        return;
    uint64_t seed = 4;
    for (int j = 0; j < NY; j++)
        for (int i = 0; i < NX; i++) {
            double s = (15.5 + 16 * j) / 256.0;
            f->u[j * NX + i] = (float)(16 * s * (1 - s) * 4.1 / 4 + 0.01 * ti_gauss(&seed));
            f->v[j * NX + i] = (float)(0.01 * ti_gauss(&seed));
        }
    size_t nrej = 9;
    CHECK_OK(rpiv_validate_median(f, 2, 0.1, &nrej));
    CHECK(nrej == 0);
    f->u[0 * NX + 6] += 3.1f;  /* r0* = 3.1 / (0.9 + 0.1): the gradient widens rm */
    f->v[14 * NX + 0] -= 1.2f; /* a corner */
    CHECK_OK(rpiv_validate_median(f, 2, 0.1, &nrej));
    CHECK(nrej == 2);
    CHECK(f->flag[6] == RPIV_FLAG_REPLACED && f->flag[14 * NX] == RPIV_FLAG_REPLACED);
    rpiv_field_free(f);
}

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* A replaced interior vector gets the median of its 8 neighbours (the sorting network's
 * path), against qsort, over 2000 random neighbourhoods with values drawn from 7 levels, so
 * that ties are common. */
static void validate_replacement_is_the_exact_median(void)
{
    rpiv_field *f = NULL;
    CHECK_OK(rpiv_field_new(3, 3, 0, 0, 1, 1, &f));
    if (!f)
        return;
    uint64_t seed = 0x3187;
    int bad = 0;
    for (int t = 0; t < 2000; t++) {
        float nb[8];
        int m = 0;
        for (int k = 0; k < 9; k++) {
            f->u[k] = (float)(0.25 * (int)(7 * ti_rnd(&seed))) - 0.6187f;
            f->v[k] = (float)(13.7 * ti_rnd(&seed));
            f->flag[k] = RPIV_FLAG_VALID;
            if (k != 4)
                nb[m++] = f->u[k];
        }
        f->flag[4] = RPIV_FLAG_REPLACED;
        qsort(nb, 8, sizeof *nb, cmp_float);
        double want = 0.5 * ((double)nb[3] + (double)nb[4]);
        CHECK_OK(rpiv_validate_replace(f, 0, NULL));
        bad += (double)f->u[4] != (double)(float)want;
    }
    CHECK(bad == 0);
    rpiv_field_free(f);
}

int main(void)
{
    RUN_TEST(validate_keeps_a_smooth_field);
    RUN_TEST(validate_finds_planted_outliers_and_replaces_them);
    RUN_TEST(validate_tests_again_a_vector_hidden_by_a_cluster);
    RUN_TEST(validate_threshold_matches_the_formula);
    RUN_TEST(validate_masked_vectors_are_skipped_and_optionally_filled);
    RUN_TEST(validate_fills_large_holes_and_empty_fields);
    RUN_TEST(validate_edge_vectors_in_a_steep_gradient_are_kept);
    RUN_TEST(validate_replacement_is_the_exact_median);
    return check_summary();
}
