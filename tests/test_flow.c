/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "check.h"
#include "rpiv/field.h"
#include "rpiv/flow.h"

#include <gsl/gsl_integration.h>

static double duct_of_z(double z, void *p)
{
    double y = *(double *)p;
    return rpiv_duct_u(y, z);
}

static double duct_line(double y, void *p)
{
    (void)p;
    gsl_integration_workspace *w = gsl_integration_workspace_alloc(200);
    gsl_function f = {duct_of_z, &y};
    double r = 0, err;
    int st = gsl_integration_qag(&f, 0, 1, 1e-12, 1e-11, 200, GSL_INTEG_GAUSS31, w, &r, &err);
    gsl_integration_workspace_free(w);
    return st ? (double)NAN : r;
}

static void duct_bulk_mean_is_one(void)
{
    gsl_integration_workspace *w = gsl_integration_workspace_alloc(200);
    gsl_function f = {duct_line, NULL};
    double r = 0, err;
    CHECK(gsl_integration_qag(&f, 0, 1, 1e-11, 1e-10, 200, GSL_INTEG_GAUSS31, w, &r, &err) == 0);
    gsl_integration_workspace_free(w);
    CHECK_NEAR(r, 1.0, 1e-6);
}

static void duct_centre_value_matches_white(void)
{
    /* 2.0962 is the classical centre/bulk ratio of the square duct */
    CHECK_NEAR(rpiv_duct_u(0.5, 0.5), 2.0962, 5e-4);
}

static void duct_flow_rate_factor_matches_its_series(void)
{
    /* the direct series, summed far: tail below sum_{i > 4001} 1/i^5 < 1e-14 */
    double s = 0;
    for (int i = 1; i < 4001; i += 2)
        s += tanh(i * M_PI / 2) / pow(i, 5);
    CHECK_NEAR(rpiv_duct_k(), 1 - 192 / pow(M_PI, 5) * s, 1e-13);
    /* the constant rpiv_duct_u uses: U* at the centre with K computed */
    double p3 = M_PI * M_PI * M_PI, sum = 0;
    for (int i = 1, k = 0; i < 200; i += 2, k++)
        sum += (k & 1 ? -1 : 1) / (cosh(i * M_PI / 2) * i * i * i);
    CHECK_NEAR(rpiv_duct_u(0.5, 0.5), 48 / (p3 * rpiv_duct_k()) * (p3 / 32 - sum), 1e-12);
}

static void duct_is_symmetric_and_zero_on_walls(void)
{
    const double ys[] = {0.0713, 0.2385, 0.4917};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double y = ys[i], z = ys[j], u = rpiv_duct_u(y, z);
            CHECK_NEAR(rpiv_duct_u(1 - y, z), u, 1e-12);
            CHECK_NEAR(rpiv_duct_u(y, 1 - z), u, 1e-12);
            CHECK_NEAR(rpiv_duct_u(z, y), u, 1e-12);
        }
    CHECK(rpiv_duct_u(0, 0.3) == 0);
    CHECK(rpiv_duct_u(0.3, 1) == 0);
    CHECK_NEAR(rpiv_duct_u(0.5, 1e-7), 0, 1e-5);
    CHECK_NEAR(rpiv_duct_u(1e-7, 0.5), 0, 1e-5);
}

static void e1_of_known_profiles(void)
{
    /* ref = 1, cmp = 1 + 0.1 => E1 = 0.1 exactly */
    double a[11], r[11], c[11], e;
    for (int i = 0; i <= 10; i++) {
        a[i] = 0.1 * i;
        r[i] = 1;
        c[i] = 1.1;
    }
    CHECK_OK(rpiv_e1(a, r, c, 11, &e));
    CHECK_NEAR(e, 0.1, 1e-12);
    CHECK_OK(rpiv_e1(a, r, r, 11, &e));
    CHECK_NEAR(e, 0, 0);
    a[5] = a[4];
    CHECK_FAILS(rpiv_e1(a, r, c, 11, &e), RPIV_EINVAL);
    CHECK_FAILS(rpiv_e1(a, r, c, 1, &e), RPIV_EINVAL);
}

static void oseen_peak_swirl_is_the_amplitude(void)
{
    rpiv_flow f = {.kind = RPIV_FLOW_OSEEN, .a = 6, .b = 48, .cx = 100, .cy = 100};
    double u, v, best = 0;
    for (double r = 1; r < 200; r += 0.25) {
        rpiv_flow_eval(&f, 100 + r, 100, 0.5, &u, &v);
        if (v > best)
            best = v;
    }
    CHECK_NEAR(best, 6, 1e-3);
    rpiv_flow_eval(&f, 100, 100 + 10, 0.5, &u, &v); /* below the centre: u < 0 */
    CHECK(u < 0 && fabs(v) < 1e-12);
}

int main(void)
{
    rpiv_init();
    RUN_TEST(duct_bulk_mean_is_one);
    RUN_TEST(duct_centre_value_matches_white);
    RUN_TEST(duct_flow_rate_factor_matches_its_series);
    RUN_TEST(duct_is_symmetric_and_zero_on_walls);
    RUN_TEST(e1_of_known_profiles);
    RUN_TEST(oseen_peak_swirl_is_the_amplitude);
    return check_summary();
}
