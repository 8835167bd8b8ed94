/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/optics.h - ray tracing of the laser sheet through lens, air/PMMA and PMMA/water. */
#ifndef RPIV_OPTICS_H
#define RPIV_OPTICS_H

#include "rpiv/error.h"

typedef enum rpiv_polar {
    RPIV_POLAR_P = 0, /* p-polarised, the paper's Eq. "Desc" (default) */
    RPIV_POLAR_S = 1,
    RPIV_POLAR_UNPOLARISED = 2
} rpiv_polar;

/* The laser and its emitting optics. */
typedef struct rpiv_laser {
    double lambda_m;        /* wavelength, m (532e-9)                                   */
    double beam_d_m;        /* beam diameter at 1/e^2 at the laser output, m (6e-3)     */
    double expander;        /* beam expander factor (2)                                 */
    double divergence_rad;  /* full divergence angle, rad (3.5e-3)                      */
    double lens_f_m;        /* spherical converging lens focal length, m (0.5)          */
    double lens_dist_m;     /* lens to the prism's inclined face along the axis, m (0.27) */
    double beta1_deg;       /* incidence from the normal of the inclined face, deg (1.3) */
    long nrays;             /* rays traced (100000)                                     */
    rpiv_polar polar;       /* (p)                                                      */
} rpiv_laser;

/* The PMMA prism and the fluid. */
typedef struct rpiv_prism {
    double theta_p_deg;     /* inclination of the inclined face, deg (64)               */
    double thickness_m;     /* thickness of the block, m (49e-3)                        */
    double n_pmma;          /* refractive index of PMMA (1.49)                          */
    double n_water;         /* refractive index of the fluid (1.33)                     */
    double n_air;           /* refractive index of air (1.0)                            */
} rpiv_prism;

rpiv_laser rpiv_laser_default(void);
rpiv_prism rpiv_prism_default(void);
RPIV_NODISCARD rpiv_status rpiv_laser_check(const rpiv_laser *l);
RPIV_NODISCARD rpiv_status rpiv_prism_check(const rpiv_prism *p);

/* (The ray-tracer API follows; see the optics issue.) */

#endif /* RPIV_OPTICS_H */
