/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/flow.h - analytic reference flows and the E1 error (Eq. "White", Eq. "E1").
 *
 * Coordinates are normalised by the channel height h: x* streamwise, y* spanwise, z* height
 * above the floor the sheet enters through (the camera looks up through it). Velocities are
 * normalised by the bulk velocity U_b for the duct, or given in the flow's own unit. */
#ifndef RPIV_FLOW_H
#define RPIV_FLOW_H

#include "rpiv/error.h"

#include <stddef.h>

/* The channel. */
typedef struct rpiv_channel {
    double h_m;         /* side of the square duct, m (8e-3)                       */
    double reynolds;    /* Re = U_b h / nu on the bulk velocity (465)               */
    double nu_m2s;      /* kinematic viscosity of the fluid, m^2/s (1.0e-6, water 20 C) */
    double x0_star;     /* emerging point of the sheet, x* = 0 at 7 h upstream of the end (7) */
    double fov_x0_star; /* x* of the left edge of the field of view (0.6)          */
    double fov_y0_star; /* y* of the top edge of the field of view (-1.73)         */
} rpiv_channel;

rpiv_channel rpiv_channel_default(void);
RPIV_NODISCARD rpiv_status rpiv_channel_check(const rpiv_channel *c);
/* Bulk velocity U_b = Re nu / h, m/s. */
double rpiv_channel_bulk_ms(const rpiv_channel *c);

/* Most terms of the series summed by rpiv_duct_u. The summation stops when a bound on the
 * tail is below 1e-14; the cap matters only within about 1e-4 h of the four corners, where the
 * truncation error is below 1e-9 of the bulk velocity (src/model/flow.c derives the bound). */
#define RPIV_DUCT_TERMS 20001

/* Fully developed laminar flow in the square duct, U*(y*, z*) = U/U_b, for 0 <= y*, z* <= 1
 * (0 outside). Prefactor 48 / (pi^3 (1 - 192/pi^5 sum tanh(i pi/2)/i^5)) so that the bulk
 * mean is 1 (the paper's dimensional prefactor reduces to this). */
double rpiv_duct_u(double ystar, double zstar);

/* The flow-rate factor K = 1 - 192/pi^5 sum_{i odd} tanh(i pi/2)/i^5 (about 0.4217). */
double rpiv_duct_k(void);

/* Other flows, as displacement fields in pixels for the generator and the tests. */
typedef enum rpiv_flow_kind {
    RPIV_FLOW_UNIFORM = 0,     /* (u, v) = (a, b)                                        */
    RPIV_FLOW_DUCT = 1,        /* u = a * U*(y*, z*), y* from image y, z* from particle   */
    RPIV_FLOW_POISEUILLE = 2,  /* plane Poiseuille in z: u = a * 6 z*(1-z*) (bulk a)      */
    RPIV_FLOW_OSEEN = 3,       /* Lamb-Oseen vortex at (cx, cy), peak swirl a px, core r_c = b px */
    RPIV_FLOW_SINE = 4,        /* sinusoidal shear u = a sin(2 pi y / lambda), lambda = b px */
    RPIV_FLOW_POISEUILLE_Y = 5 /* parabolic in image y: u = a * 4 s (1 - s), s = y / height */
} rpiv_flow_kind;

typedef struct rpiv_flow {
    rpiv_flow_kind kind;
    double a, b;      /* amplitudes / lengths, see rpiv_flow_kind                   */
    double cx, cy;    /* centre (Oseen), px                                         */
    double height_px; /* image height for FLOW_POISEUILLE_Y                          */
    /* for FLOW_DUCT: the mapping from image pixel to y* */
    double y0_star; /* y* at image row 0                                          */
    double ystar_per_px;
} rpiv_flow;

/* Displacement (u, v) in pixels of a particle at image position (x, y) px and height z*. */
void rpiv_flow_eval(const rpiv_flow *f, double x, double y, double zstar, double *u, double *v);

#endif /* RPIV_FLOW_H */
