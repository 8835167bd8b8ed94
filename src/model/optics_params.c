/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Laser and prism parameters: the paper's emitting optics and PMMA block (docs/optics.md). */
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
                        .beta1_side = RPIV_BETA1_AIR,
                        .bundle_m = 19e-3,
                        .nrays = 100000,
                        .polar = RPIV_POLAR_P};
}

rpiv_prism rpiv_prism_default(void)
{
    return (rpiv_prism){
        .theta_p_deg = 64, .thickness_m = 49e-3, .n_pmma = 1.49, .n_water = 1.33, .n_air = 1.0};
}

const char *const rpiv_polar_names[] = {"p", "s", "unpolarised", NULL};
const char *const rpiv_beta1_side_names[] = {"air", "pmma", NULL};

const char *rpiv_polar_name(rpiv_polar pol)
{
    return pol >= RPIV_POLAR_P && pol <= RPIV_POLAR_UNPOLARISED ? rpiv_polar_names[pol] : "?";
}

const char *rpiv_beta1_side_name(rpiv_beta1_side side)
{
    return side >= RPIV_BETA1_AIR && side <= RPIV_BETA1_PMMA ? rpiv_beta1_side_names[side] : "?";
}

static int bad(double v, double lo, double hi)
{
    return !(v >= lo && v <= hi);
}

rpiv_status rpiv_laser_check(const rpiv_laser *l)
{
    if (bad(l->lambda_m, 1e-7, 2e-6))
        return rpiv_fail(RPIV_EINVAL, "laser.lambda_nm: %g outside 100..2000", l->lambda_m * 1e9);
    if (bad(l->beam_d_m, 1e-5, 1))
        return rpiv_fail(RPIV_EINVAL, "laser.beam_diameter_mm: %g outside 0.01..1000",
                         l->beam_d_m * 1e3);
    if (bad(l->expander, 0.01, 100))
        return rpiv_fail(RPIV_EINVAL, "laser.expander: %g outside 0.01..100", l->expander);
    if (bad(l->divergence_rad, 0, 0.5))
        return rpiv_fail(RPIV_EINVAL, "laser.divergence_mrad: %g outside 0..500",
                         l->divergence_rad * 1e3);
    if (bad(l->lens_f_m, 1e-3, 100))
        return rpiv_fail(RPIV_EINVAL, "laser.lens_focal_mm: %g outside 1..100000",
                         l->lens_f_m * 1e3);
    if (bad(l->lens_dist_m, 0, 100))
        return rpiv_fail(RPIV_EINVAL, "laser.lens_distance_mm: %g outside 0..100000",
                         l->lens_dist_m * 1e3);
    if (bad(l->beta1_deg, -45, 45))
        return rpiv_fail(RPIV_EINVAL, "laser.beta1_deg: %g outside -45..45", l->beta1_deg);
    if (l->beta1_side != RPIV_BETA1_PMMA && l->beta1_side != RPIV_BETA1_AIR)
        return rpiv_fail(RPIV_EINVAL, "laser.beta1_side: unknown value %d", (int)l->beta1_side);
    if (bad(l->bundle_m, 1e-5, 1))
        return rpiv_fail(RPIV_EINVAL, "laser.bundle_mm: %g outside 0.01..1000", l->bundle_m * 1e3);
    if (l->nrays < 1 || l->nrays > 100000000L)
        return rpiv_fail(RPIV_EINVAL, "laser.rays: %ld outside 1..100000000", l->nrays);
    if (l->polar != RPIV_POLAR_P && l->polar != RPIV_POLAR_S && l->polar != RPIV_POLAR_UNPOLARISED)
        return rpiv_fail(RPIV_EINVAL, "laser.polarisation: unknown value %d", (int)l->polar);
    return RPIV_OK;
}

rpiv_status rpiv_prism_check(const rpiv_prism *p)
{
    if (bad(p->theta_p_deg, 1, 89))
        return rpiv_fail(RPIV_EINVAL, "prism.inclination_deg: %g outside 1..89", p->theta_p_deg);
    if (bad(p->thickness_m, 1e-4, 10))
        return rpiv_fail(RPIV_EINVAL, "prism.thickness_mm: %g outside 0.1..10000",
                         p->thickness_m * 1e3);
    if (bad(p->n_pmma, 1, 4))
        return rpiv_fail(RPIV_EINVAL, "prism.n_pmma: %g outside 1..4", p->n_pmma);
    if (bad(p->n_water, 1, 4))
        return rpiv_fail(RPIV_EINVAL, "prism.n_water: %g outside 1..4", p->n_water);
    if (bad(p->n_air, 1, 4))
        return rpiv_fail(RPIV_EINVAL, "prism.n_air: %g outside 1..4", p->n_air);
    return RPIV_OK;
}
