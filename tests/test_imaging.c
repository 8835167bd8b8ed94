/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "check.h"
#include "rpiv/imaging.h"

static void diameter_in_focus_is_geometric_plus_diffraction(void)
{
    rpiv_camera c = rpiv_camera_default();
    /* by hand: M dp = 3.9 um; diffraction 2.44 (1+M) lambda f# with 2.44 = sqrt(5.95)... */
    double geo = 0.39 * 10e-6, dif2 = 5.95 * (1.39 * 570e-9 * 5.6) * (1.39 * 570e-9 * 5.6);
    CHECK_NEAR(rpiv_imaging_de_m(&c, 10e-6, 0), sqrt(geo * geo + dif2), 1e-15);
    CHECK_NEAR(rpiv_imaging_de_m(&c, 10e-6, 0), 11.5e-6, 0.2e-6);
}

static void defocus_term_uses_the_aperture_and_working_distance(void)
{
    rpiv_camera c = rpiv_camera_default();
    double zdef = rpiv_imaging_defocus_m(&c, 8e-3, 0.45 + 0.3187);
    CHECK_NEAR(zdef, 8e-3 * 0.3187 / 1.33, 1e-15); /* apparent depth through the wall */
    c.n_medium = 1;
    CHECK_NEAR(rpiv_imaging_defocus_m(&c, 8e-3, 0.45 - 0.3187), 8e-3 * 0.3187, 1e-15);
    double da = 0.135 / 5.6, foc = 0.39 * zdef * da / (0.5 + zdef);
    double d0 = rpiv_imaging_de_m(&c, 10e-6, 0);
    CHECK_NEAR(rpiv_imaging_de_m(&c, 10e-6, zdef), sqrt(d0 * d0 + foc * foc), 1e-15);
}

static void particle_image_integral_is_independent_of_blur(void)
{
    rpiv_camera c = rpiv_camera_default();
    double de1 = 12e-6, de2 = 40e-6, z = 1e-3;
    /* integral of peak exp(-4 beta^2 r^2/de^2) = peak pi de^2 / (4 beta^2) */
    double i1 = rpiv_imaging_peak(&c, 2.385, de1, z) * M_PI * de1 * de1 / (4 * c.beta2);
    double i2 = rpiv_imaging_peak(&c, 2.385, de2, z) * M_PI * de2 * de2 / (4 * c.beta2);
    double da = 0.135 / 5.6;
    CHECK_NEAR(i1, i2, 1e-12 * i1);
    CHECK_NEAR(i1, 2.385 * da * da / (16 * (0.5 + z) * (0.5 + z)), 1e-12 * i1);
    /* sigma: exp(-4 beta^2 r^2/de^2) = exp(-r^2 / (2 sigma^2)) */
    double s = rpiv_imaging_sigma_m(&c, de1);
    CHECK_NEAR(4 * c.beta2 / (de1 * de1), 1 / (2 * s * s), 1e-6 / (s * s));
}

static void bad_camera_values_are_refused(void)
{
    rpiv_camera c = rpiv_camera_default();
    c.fnumber = 0;
    CHECK_FAILS(rpiv_camera_check(&c), RPIV_EINVAL);
    c = rpiv_camera_default();
    c.magnification = (double)NAN;
    CHECK_FAILS(rpiv_camera_check(&c), RPIV_EINVAL);
    rpiv_particles p = rpiv_particles_default();
    p.dp_sigma_m = 2 * p.dp_m;
    CHECK_FAILS(rpiv_particles_check(&p), RPIV_EINVAL);
}

int main(void)
{
    rpiv_init();
    RUN_TEST(diameter_in_focus_is_geometric_plus_diffraction);
    RUN_TEST(defocus_term_uses_the_aperture_and_working_distance);
    RUN_TEST(particle_image_integral_is_independent_of_blur);
    RUN_TEST(bad_camera_values_are_refused);
    return check_summary();
}
