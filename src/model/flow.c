/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "rpiv/flow.h"

#include <math.h>

rpiv_channel rpiv_channel_default(void)
{
    return (rpiv_channel){.h_m = 8e-3,
                          .reynolds = 465,
                          .nu_m2s = 1.0e-6,
                          .x0_star = 7,
                          .fov_x0_star = 1.0,
                          .fov_y0_star = 0.5 - 0.5 * 4.46};
}

rpiv_status rpiv_channel_check(const rpiv_channel *c)
{
    if (!(c->h_m > 0 && c->h_m < 10))
        return rpiv_fail(RPIV_EINVAL, "channel.height_mm: %g mm must be in (0, 10000)",
                         c->h_m * 1e3);
    if (!(c->reynolds >= 0 && c->reynolds <= 1e6))
        return rpiv_fail(RPIV_EINVAL, "channel.reynolds: %g outside 0..1e6", c->reynolds);
    if (!(c->nu_m2s > 0 && c->nu_m2s < 1))
        return rpiv_fail(RPIV_EINVAL, "channel.nu_m2s: %g outside (0, 1)", c->nu_m2s);
    if (!isfinite(c->x0_star) || !isfinite(c->fov_x0_star) || !isfinite(c->fov_y0_star))
        return rpiv_fail(RPIV_EINVAL, "channel: positions must be finite");
    return RPIV_OK;
}

double rpiv_channel_bulk_ms(const rpiv_channel *c)
{
    return c->reynolds * c->nu_m2s / c->h_m;
}

/* K = 1 - 192/pi^5 sum_{i odd} tanh(i pi/2)/i^5, the flow-rate factor of the square duct.
 * rpiv_duct_k() computes it (tanh = 1 - 2/(e^{i pi}+1), so the slowly converging part is
 * (1 - 2^-5) zeta(5) exactly); rpiv_duct_u uses the value below, which tests/test_flow.c
 * checks against rpiv_duct_k(), to keep the series evaluation free of the constant's cost. */
#define DUCT_K 0.42173104486546664

double rpiv_duct_k(void)
{
    const double zeta5 = 1.0369277551433699263;
    double s = (31.0 / 32.0) * zeta5;
    for (int i = 1; i < 40; i += 2)
        s -= 2.0 / (pow(i, 5) * (exp(i * M_PI) + 1.0));
    return 1.0 - 192.0 / pow(M_PI, 5) * s;
}

/* U* from the series of Eq. "White" rewritten as
 *   U* = 48/(pi^3 K) [ pi^3/32 (1 - 4 s^2) - sum (-1)^k cosh(i pi t)/cosh(i pi/2) cos(i pi s)/i^3 ]
 * (the '1' part of the bracket sums in closed form), with s, t = y*-1/2, z*-1/2 chosen so that
 * |t| <= |s| (the problem is symmetric in y and z). The remaining terms are bounded by
 * 2 exp(-i pi (1/2 - |t|)) / i^3; summation stops when the bound of the tail is below 1e-14
 * or after RPIV_DUCT_TERMS terms, where the tail is below 1/(e N^2) < 1e-9 (within about 1e-4 h
 * of the four corners only; measured against a long-double reference: at most 6.2e-10 within
 * 3e-5 h of a corner, 4.4e-15 elsewhere). */
double rpiv_duct_u(double ystar, double zstar)
{
    if (!(ystar > 0 && ystar < 1 && zstar > 0 && zstar < 1))
        return 0;
    double s = ystar - 0.5, t = zstar - 0.5;
    if (fabs(t) > fabs(s)) {
        double tmp = s;
        s = t;
        t = tmp;
    }
    double at = fabs(t), d = 0.5 - at, sum = 0;
    double geo = 1.0 / (1.0 - exp(-2 * M_PI * (d > 1e-6 ? d : 1e-6)));
    for (int i = 1, k = 0; i <= RPIV_DUCT_TERMS; i += 2, k++) {
        double ip = i * M_PI;
        double ratio = exp(ip * (at - 0.5)) * (1 + exp(-2 * ip * at)) / (1 + exp(-ip));
        double term = ratio * cos(ip * s) / ((double)i * i * i);
        sum += (k & 1) ? -term : term;
        double bound = 2 * exp(-(ip + 2 * M_PI) * d) / ((double)i * i * i) * geo;
        if (bound < 1e-14)
            break;
    }
    double p3 = M_PI * M_PI * M_PI;
    return 48.0 / (p3 * DUCT_K) * (p3 / 32.0 * (1 - 4 * s * s) - sum);
}

void rpiv_flow_eval(const rpiv_flow *f, double x, double y, double zstar, double *u, double *v)
{
    double dx, dy, r2, rc2, fac;
    *u = 0;
    *v = 0;
    switch (f->kind) {
    case RPIV_FLOW_UNIFORM:
        *u = f->a;
        *v = f->b;
        break;
    case RPIV_FLOW_DUCT:
        *u = f->a * rpiv_duct_u(f->y0_star + y * f->ystar_per_px, zstar);
        break;
    case RPIV_FLOW_POISEUILLE:
        *u = (zstar > 0 && zstar < 1) ? f->a * 6 * zstar * (1 - zstar) : 0;
        break;
    case RPIV_FLOW_POISEUILLE_Y: {
        double sy = y / f->height_px;
        *u = (sy > 0 && sy < 1) ? f->a * 4 * sy * (1 - sy) : 0;
        break;
    }
    case RPIV_FLOW_OSEEN:
        /* swirl v_theta(r) = a * g(r)/g_max with g(r) = (1 - exp(-r^2/rc^2))/r, peak at
         * r = 1.1209 rc where g = 0.6382/rc */
        dx = x - f->cx;
        dy = y - f->cy;
        r2 = dx * dx + dy * dy;
        rc2 = f->b * f->b;
        if (r2 < 1e-12)
            break;
        fac = f->a / (0.638161 / f->b) * (1 - exp(-r2 / rc2)) / r2;
        *u = -fac * dy;
        *v = fac * dx;
        break;
    case RPIV_FLOW_SINE:
        *u = f->a * sin(2 * M_PI * y / f->b);
        break;
    }
}
