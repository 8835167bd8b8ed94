/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "rpiv/imaging.h"

#include <math.h>

rpiv_camera rpiv_camera_default(void)
{
    return (rpiv_camera){.width_px = 2560,
                         .height_px = 2160,
                         .sensor_w_m = 16.6e-3,
                         .sensor_h_m = 14.0e-3,
                         .focal_m = 0.135,
                         .fnumber = 5.6,
                         .magnification = 0.39,
                         .s0_m = 0.5,
                         .zop_star = 0.45,
                         .lambda_p_m = 570e-9,
                         .beta2 = 3.67,
                         .n_medium = 1.33};
}

rpiv_particles rpiv_particles_default(void)
{
    return (rpiv_particles){.dp_m = 10e-6, .dp_sigma_m = 4e-6, .density_ppp = 0.015};
}

static int bad(double v, double lo, double hi)
{
    return !(v >= lo && v <= hi); /* also true for NaN */
}

rpiv_status rpiv_camera_check(const rpiv_camera *c)
{
    if (c->width_px < 8 || c->width_px > 65536 || c->height_px < 8 || c->height_px > 65536)
        return rpiv_fail(RPIV_EINVAL, "camera: sensor size %dx%d px outside 8..65536", c->width_px,
                         c->height_px);
    if (bad(c->sensor_w_m, 1e-4, 1) || bad(c->sensor_h_m, 1e-4, 1))
        return rpiv_fail(RPIV_EINVAL, "camera: sensor size must be in 1e-4..1 m");
    if (bad(c->focal_m, 1e-3, 10))
        return rpiv_fail(RPIV_EINVAL, "camera: focal length %g m outside 1e-3..10", c->focal_m);
    if (bad(c->fnumber, 0.5, 128))
        return rpiv_fail(RPIV_EINVAL, "camera: f-number %g outside 0.5..128", c->fnumber);
    if (bad(c->magnification, 1e-3, 100))
        return rpiv_fail(RPIV_EINVAL, "camera: magnification %g outside 1e-3..100",
                         c->magnification);
    if (bad(c->s0_m, 1e-3, 100))
        return rpiv_fail(RPIV_EINVAL, "camera: working distance %g m outside 1e-3..100", c->s0_m);
    if (bad(c->zop_star, -10, 10))
        return rpiv_fail(RPIV_EINVAL, "camera: object plane z*_OP %g outside -10..10", c->zop_star);
    if (bad(c->lambda_p_m, 1e-7, 2e-6))
        return rpiv_fail(RPIV_EINVAL, "camera: wavelength %g m outside 1e-7..2e-6", c->lambda_p_m);
    if (bad(c->n_medium, 1, 4))
        return rpiv_fail(RPIV_EINVAL, "camera: medium index %g outside 1..4", c->n_medium);
    if (bad(c->beta2, 0.1, 100))
        return rpiv_fail(RPIV_EINVAL, "camera: beta2 %g outside 0.1..100", c->beta2);
    return RPIV_OK;
}

rpiv_status rpiv_particles_check(const rpiv_particles *p)
{
    if (bad(p->dp_m, 1e-8, 1e-2))
        return rpiv_fail(RPIV_EINVAL, "particles: diameter %g m outside 1e-8..1e-2", p->dp_m);
    if (bad(p->dp_sigma_m, 0, p->dp_m))
        return rpiv_fail(RPIV_EINVAL, "particles: diameter spread %g m outside 0..d_p",
                         p->dp_sigma_m);
    if (bad(p->density_ppp, 0, 1))
        return rpiv_fail(RPIV_EINVAL, "particles: density %g particles/px outside 0..1",
                         p->density_ppp);
    return RPIV_OK;
}

double rpiv_camera_pixel_m(const rpiv_camera *c)
{
    return c->sensor_w_m / c->width_px;
}

double rpiv_camera_aperture_m(const rpiv_camera *c)
{
    return c->focal_m / c->fnumber;
}

double rpiv_imaging_defocus_m(const rpiv_camera *c, double h_m, double zstar)
{
    return h_m * fabs(zstar - c->zop_star) / c->n_medium;
}

double rpiv_imaging_de_m(const rpiv_camera *c, double dp_m, double zdef_m)
{
    double m = c->magnification, da = rpiv_camera_aperture_m(c);
    double geo = m * dp_m;
    double dif = (m + 1) * c->lambda_p_m * c->fnumber;
    double foc = m * zdef_m * da / (c->s0_m + zdef_m);
    return sqrt(geo * geo + 5.95 * dif * dif + foc * foc);
}

double rpiv_imaging_peak(const rpiv_camera *c, double ip, double de_m, double zdef_m)
{
    double da = rpiv_camera_aperture_m(c), s = c->s0_m + zdef_m;
    return ip * da * da * c->beta2 / (4 * M_PI * de_m * de_m * s * s);
}

double rpiv_imaging_sigma_m(const rpiv_camera *c, double de_m)
{
    return de_m / (sqrt(8.0 * c->beta2));
}
