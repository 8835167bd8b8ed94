/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "rpiv/optics.h"

#include <math.h>

rpiv_laser rpiv_laser_default(void)
{
    return (rpiv_laser){.lambda_m = 532e-9,
                        .beam_d_m = 6e-3,
                        .expander = 2,
                        .divergence_rad = 3.5e-3,
                        .lens_f_m = 0.5,
                        .lens_dist_m = 0.27,
                        .beta1_deg = 1.3,
                        .nrays = 100000,
                        .polar = RPIV_POLAR_P};
}

rpiv_prism rpiv_prism_default(void)
{
    return (rpiv_prism){
        .theta_p_deg = 64, .thickness_m = 49e-3, .n_pmma = 1.49, .n_water = 1.33, .n_air = 1.0};
}

static int bad(double v, double lo, double hi)
{
    return !(v >= lo && v <= hi);
}

rpiv_status rpiv_laser_check(const rpiv_laser *l)
{
    if (bad(l->lambda_m, 1e-7, 2e-6))
        return rpiv_fail(RPIV_EINVAL, "laser: wavelength %g m outside 1e-7..2e-6", l->lambda_m);
    if (bad(l->beam_d_m, 1e-5, 1))
        return rpiv_fail(RPIV_EINVAL, "laser: beam diameter %g m outside 1e-5..1", l->beam_d_m);
    if (bad(l->expander, 0.01, 100))
        return rpiv_fail(RPIV_EINVAL, "laser: expander %g outside 0.01..100", l->expander);
    if (bad(l->divergence_rad, 0, 0.5))
        return rpiv_fail(RPIV_EINVAL, "laser: divergence %g rad outside 0..0.5",
                         l->divergence_rad);
    if (bad(l->lens_f_m, 1e-3, 100) || bad(l->lens_dist_m, 0, 100))
        return rpiv_fail(RPIV_EINVAL, "laser: lens focal length or distance out of range");
    if (bad(l->beta1_deg, -45, 45))
        return rpiv_fail(RPIV_EINVAL, "laser: beta1 %g deg outside -45..45", l->beta1_deg);
    if (l->nrays < 1 || l->nrays > 100000000L)
        return rpiv_fail(RPIV_EINVAL, "laser: rays %ld outside 1..1e8", l->nrays);
    return RPIV_OK;
}

rpiv_status rpiv_prism_check(const rpiv_prism *p)
{
    if (bad(p->theta_p_deg, 1, 89))
        return rpiv_fail(RPIV_EINVAL, "prism: inclination %g deg outside 1..89", p->theta_p_deg);
    if (bad(p->thickness_m, 1e-4, 10))
        return rpiv_fail(RPIV_EINVAL, "prism: thickness %g m outside 1e-4..10", p->thickness_m);
    if (bad(p->n_pmma, 1, 4) || bad(p->n_water, 1, 4) || bad(p->n_air, 1, 4))
        return rpiv_fail(RPIV_EINVAL, "prism: refractive indices must be in 1..4");
    return RPIV_OK;
}
