/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Derived quantities (rpiv_field_derive) against analytic fields: solid-body rotation,
 * Lamb-Oseen vortex, pure strain; the physical sign in both orientations; masked points. */
#include "check.h"
#include "rpiv/field.h"

#include <string.h>

#define NX 41
#define NY 33
#define H  16.0 /* grid step, px */

static double xc(void)
{
    return 8 + H * (NX - 1) / 2.0;
}
static double yc(void)
{
    return 8 + H * (NY - 1) / 2.0;
}

/* A field in image coordinates (y down) on NX x NY points, x = 8 + 16 i, y = 8 + 16 j. */
static rpiv_field *grid(void)
{
    rpiv_field *f = NULL;
    if (rpiv_field_new(NX, NY, 8, 8, H, H, &f))
        return NULL;
    return f;
}

static double q_at(const rpiv_field *f, const char *name, int i, int j)
{
    const rpiv_quantity *q = rpiv_field_quantity(f, name);
    return q ? (double)q->data[j * f->nx + i] : (double)NAN;
}

static void parse_lists(void)
{
    unsigned w = 99;
    CHECK_OK(rpiv_field_derive_parse("vorticity,q", &w));
    CHECK(w == (RPIV_DERIVE_VORTICITY | RPIV_DERIVE_Q));
    CHECK_OK(rpiv_field_derive_parse("none", &w));
    CHECK(w == 0);
    CHECK_OK(rpiv_field_derive_parse("all", &w));
    CHECK(w == 31);
    CHECK_FAILS(rpiv_field_derive_parse("vorticity,curl", &w), RPIV_EINVAL);
    CHECK(strstr(rpiv_errmsg(), "'curl'") != NULL);
    CHECK_FAILS(rpiv_field_derive_parse("vort", &w), RPIV_EINVAL);
}

/* u = -W (y - yc), v = W (x - xc) in image coordinates: the point right of the centre
 * moves down the image, so the rotation is CLOCKWISE on the image: vorticity -2 W. */
static void solid_body_clockwise_on_image_is_negative(void)
{
    const double W = 0.004; /* rad per pair interval */
    rpiv_field *f = grid();
    CHECK(f != NULL);
    if (!f)
        return;
    for (int j = 0; j < NY; j++)
        for (int i = 0; i < NX; i++) {
            double x = 8 + H * i, y = 8 + H * j;
            f->u[j * NX + i] = (float)(-W * (y - yc()));
            f->v[j * NX + i] = (float)(W * (x - xc()));
        }
    /* masked points: a block and a lone one; their neighbours use shorter stencils */
    for (int j = 10; j < 14; j++)
        for (int i = 5; i < 9; i++)
            f->flag[j * NX + i] = RPIV_FLAG_MASKED;
    f->flag[20 * NX + 30] = RPIV_FLAG_MASKED;
    CHECK_OK(rpiv_field_derive(f, RPIV_DERIVE_VORTICITY | RPIV_DERIVE_DIVERGENCE |
                                      RPIV_DERIVE_STRAIN | RPIV_DERIVE_SWIRL | RPIV_DERIVE_Q));
    double worst = 0;
    for (int j = 0; j < NY; j++)
        for (int i = 0; i < NX; i++) {
            if (f->flag[j * NX + i] == RPIV_FLAG_MASKED) {
                CHECK(q_at(f, "vorticity", i, j) == 0);
                continue;
            }
            double e = fabs(q_at(f, "vorticity", i, j) - (-2 * W)) / (2 * W);
            worst = e > worst ? e : worst;
            CHECK_NEAR(q_at(f, "divergence", i, j), 0, 1e-6);
            CHECK_NEAR(q_at(f, "shear_strain", i, j), 0, 1e-6);
            CHECK_NEAR(q_at(f, "normal_strain", i, j), 0, 1e-6);
            CHECK_NEAR(q_at(f, "swirling_strength", i, j), W, 1e-3 * W);
            CHECK_NEAR(q_at(f, "q_criterion", i, j), W * W, 1e-3 * W * W);
        }
    printf("solid body: worst |vorticity + 2W| / 2W = %.2e\n", worst);
    CHECK(worst < 0.01);
    CHECK(worst < 1e-4); /* linear field: every stencil is exact up to float rounding */
    const rpiv_quantity *q = rpiv_field_quantity(f, "vorticity");
    CHECK(q && q->unit == RPIV_UNIT_PER_DT); /* a physical sign: not odd in y */
    q = rpiv_field_quantity(f, "q_criterion");
    CHECK(q && q->unit == RPIV_UNIT_PER_DT2);

    /* turned y-up afterwards: still -2 W (the quantity does not flip) */
    rpiv_field *g = NULL;
    CHECK_OK(rpiv_field_copy(f, &g));
    CHECK_OK(rpiv_field_y_up(g, 8 + (int)(H * NY)));
    CHECK_NEAR(q_at(g, "vorticity", 20, 16), -2 * W, 1e-4 * W);
    /* derived again in the y-up field: the same physical sign */
    CHECK_OK(rpiv_field_derive(g, RPIV_DERIVE_VORTICITY));
    CHECK_NEAR(q_at(g, "vorticity", 20, 16), -2 * W, 1e-4 * W);
    CHECK_NEAR(q_at(g, "vorticity", 0, 0), -2 * W, 1e-4 * W);
    rpiv_field_free(g);

    /* reversed: counter-clockwise on the image is positive */
    for (int k = 0; k < NX * NY; k++) {
        f->u[k] = -f->u[k];
        f->v[k] = -f->v[k];
    }
    CHECK_OK(rpiv_field_derive(f, RPIV_DERIVE_VORTICITY));
    CHECK_NEAR(q_at(f, "vorticity", 3, 3), 2 * W, 1e-4 * W);
    rpiv_field_free(f);
}

/* Lamb-Oseen vortex, counter-clockwise on the image (circulation G > 0 in the physical
 * frame, y up): u_theta = G / (2 pi r) (1 - exp(-r^2/rc^2)), omega = G/(pi rc^2)
 * exp(-r^2/rc^2). The stencil's truncation error is what is measured. */
static double lamb_oseen_at(double steps, double *err_max)
{
    const double G = 200.0, rc = steps * H; /* px^2 per pair, core radius in grid steps */
    const double w0 = G / (M_PI * rc * rc);
    rpiv_field *f = grid();
    CHECK(f != NULL);
    if (!f)
        return (double)NAN;
    for (int j = 0; j < NY; j++)
        for (int i = 0; i < NX; i++) {
            double X = 8 + H * i - xc(), Y = -(8 + H * j - yc()), r2 = X * X + Y * Y;
            double ut_over_r = r2 > 0 ? G / (2 * M_PI * r2) * (1 - exp(-r2 / (rc * rc)))
                                      : G / (2 * M_PI * rc * rc);
            double up = -ut_over_r * Y, vp = ut_over_r * X; /* physical, y up */
            f->u[j * NX + i] = (float)up;
            f->v[j * NX + i] = (float)-vp; /* image: v down */
        }
    CHECK_OK(rpiv_field_derive(f, RPIV_DERIVE_VORTICITY | RPIV_DERIVE_DIVERGENCE |
                                      RPIV_DERIVE_SWIRL | RPIV_DERIVE_Q));
    double emax = 0, dmax = 0;
    for (int j = 2; j < NY - 2; j++)
        for (int i = 2; i < NX - 2; i++) {
            double X = 8 + H * i - xc(), Y = -(8 + H * j - yc());
            double w = w0 * exp(-(X * X + Y * Y) / (rc * rc));
            double e = fabs(q_at(f, "vorticity", i, j) - w);
            emax = e > emax ? e : emax;
            double d = fabs(q_at(f, "divergence", i, j));
            dmax = d > dmax ? d : dmax;
        }
    const int ic = NX / 2, jc = NY / 2;
    double wc = q_at(f, "vorticity", ic, jc);
    double sc = q_at(f, "swirling_strength", ic, jc);
    printf("Lamb-Oseen rc = %g steps: vorticity at the centre %.6g (exact %.6g, %+.2f %%), max "
           "error %.2f %% of the peak; max |divergence| %.2e of the peak; swirl at the centre "
           "%+.2f %% off w0/2\n",
           steps, wc, w0, 100 * (wc - w0) / w0, 100 * emax / w0, dmax / w0,
           100 * (sc - w0 / 2) / (w0 / 2));
    CHECK(wc > 0);
    CHECK(dmax < 0.01 * w0);
    CHECK_NEAR(sc, wc / 2, 0.01 * wc);
    CHECK(q_at(f, "q_criterion", ic, jc) > 0);
    rpiv_field_free(f);
    *err_max = emax / w0;
    return (wc - w0) / w0;
}

/* The least-squares stencil's truncation error is 17/30 h^2 times the third derivative:
 * second order, so it falls four-fold when the core spans twice as many grid steps. */
static void lamb_oseen(void)
{
    double e5, e10, c5 = lamb_oseen_at(5, &e5), c10 = lamb_oseen_at(10, &e10);
    CHECK(c5 < 0 && c10 < 0); /* the stencil smooths the peak */
    CHECK(fabs(c5) < 0.08);   /* measured -6.5 % at 5 steps per core radius */
    CHECK(fabs(c10) < 0.02);  /* measured at 10 */
    CHECK(e5 < 0.08 && e10 < 0.02);
    CHECK_NEAR(c5 / c10, 4, 0.4);
}

/* Pure strain u = a X, v = -a Y (physical): divergence 0, normal strain 2a, no shear, no
 * rotation, Q = -a^2; in image coordinates v_img = a (y - yc). */
static void pure_strain(void)
{
    const double a = 0.003;
    rpiv_field *f = grid();
    CHECK(f != NULL);
    if (!f)
        return;
    f->scale_mm_per_px = 0.05;
    f->dt_s = 1e-3;
    for (int j = 0; j < NY; j++)
        for (int i = 0; i < NX; i++) {
            f->u[j * NX + i] = (float)(a * (8 + H * i - xc()));
            f->v[j * NX + i] = (float)(-a * (8 + H * j - yc()));
        }
    CHECK_OK(rpiv_field_derive(f, RPIV_DERIVE_VORTICITY | RPIV_DERIVE_DIVERGENCE |
                                      RPIV_DERIVE_STRAIN | RPIV_DERIVE_SWIRL | RPIV_DERIVE_Q));
    for (int j = 0; j < NY; j += 4)
        for (int i = 0; i < NX; i += 4) {
            CHECK_NEAR(q_at(f, "divergence", i, j), 0, 1e-6 * a);
            CHECK_NEAR(q_at(f, "vorticity", i, j), 0, 1e-6 * a);
            CHECK_NEAR(q_at(f, "normal_strain", i, j), 2 * a, 1e-5 * a);
            CHECK_NEAR(q_at(f, "shear_strain", i, j), 0, 1e-6 * a);
            CHECK(q_at(f, "swirling_strength", i, j) == 0);
            CHECK_NEAR(q_at(f, "q_criterion", i, j), -a * a, 1e-5 * a * a);
        }
    /* per second with dt: 1/dt and 1/dt^2 */
    CHECK_NEAR(rpiv_unit_factor(f, RPIV_UNIT_PER_DT), 1e3, 1e-9);
    CHECK_NEAR(rpiv_unit_factor(f, RPIV_UNIT_PER_DT2), 1e6, 1e-6);
    CHECK(strcmp(rpiv_unit_name(RPIV_UNIT_PER_DT2, 1), "1/s^2") == 0);
    rpiv_field_free(f);
}

/* A simple shear u = b (y - yc) in image coordinates: seen on the image the upper layer
 * (smaller y) moves left, the lower one right: counter-clockwise, vorticity +b. */
static void simple_shear_sign(void)
{
    const double b = 0.002;
    rpiv_field *f = grid();
    CHECK(f != NULL);
    if (!f)
        return;
    for (int j = 0; j < NY; j++)
        for (int i = 0; i < NX; i++)
            f->u[j * NX + i] = (float)(b * (8 + H * j - yc()));
    CHECK_OK(rpiv_field_derive(f, RPIV_DERIVE_VORTICITY | RPIV_DERIVE_STRAIN));
    /* physical: u = -b Y, omega = -du/dY = b, shear du/dY = -b */
    CHECK_NEAR(q_at(f, "vorticity", 10, 10), b, 1e-6 * b);
    CHECK_NEAR(q_at(f, "shear_strain", 10, 10), -b, 1e-6 * b);
    rpiv_field_free(f);
}

int main(void)
{
    RUN_TEST(parse_lists);
    RUN_TEST(solid_body_clockwise_on_image_is_negative);
    RUN_TEST(lamb_oseen);
    RUN_TEST(pure_strain);
    RUN_TEST(simple_shear_sign);
    return check_summary();
}
