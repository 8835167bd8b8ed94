/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The engine's window in the prediction of what the engine measures (docs/ccm.md, "The
 * engine's window"): the expected plane of a W x H top-hat window of mean-removed images,
 * correlated circularly by FFT, differs from the model's infinite-window R in three derived
 * ways, all modelled here on the sampled plane the estimator reads:
 *  - pairs lost at the window's edges: a particle at a uniformly random place in window a
 *    whose image moves by the residual shift s (its displacement less the predictor, which the
 *    deformation removes) stays in window b with probability (1 - |s_x|/W)(1 - |s_y|/H), so
 *    its term is weighted by that;
 *  - the mean removal: the circular plane of mean-removed windows sums to zero over its W H
 *    shifts, and the uncorrelated pairs add a constant in expectation, so the expected plane
 *    is the weighted terms minus their lattice sum over W H;
 *  - the deformation: the final pass correlates frames deformed by the predictor, so the plane
 *    is R sampled at integer shifts about the predictor (not about 0), and the estimate is the
 *    predictor plus the estimator's offset on that plane; the engine's passes converge to the
 *    predictor that the estimate reproduces (a fixed point, found by repeating the pass);
 *    where the estimator's path changes between two predictors (the spline's fall to the
 *    3-point Gaussian) there may be none, and the passes alternate between two estimates: the
 *    estimate is then the last of WINDOW_ITER passes', found once the alternation repeats.
 * The baseline's lattice sum: a term's lattice sum is its
 *    volume amp pi / c (the box keeps the volume) to the aliasing of a sampled Gaussian,
 *    exp(-pi^2 / c) relative (Poisson's summation): below 1e-3 for a term narrower than
 *    c = 1.4 px^-2, and the baseline is itself below 1 % of the peak at 32 px windows. */
#include "ccm_impl.h"

#include <math.h>
#include <stdlib.h>

#define WINDOW_ITER 20

/* The estimate on the plane of the window about the predictor (px, py): every term weighted by
 * its pairs kept and, with deform, moved by -(px, py) (the deformed frames are correlated at
 * integer residual shifts), the plane lowered by the baseline; *ex, *ey: the estimate's
 * offset from the lattice's origin (px, py with deform, else 0). */
static rpiv_status window_estimate(const rpiv_ccm_corr *c, const rpiv_ccm_params *p, int win_w,
                                   int win_h, int deform, double px, double py, rpiv_ccm_corr *cw,
                                   double *ex, double *ey, ccm_wsig *sig)
{
    double vol = 0, ox = deform ? px : 0, oy = deform ? py : 0;
    rpiv_status st;
    cw->n = 0;
    for (size_t k = 0; k < c->n; k++) {
        rpiv_ccm_gauss g = c->g[k];
        if (!(g.amp > 0))
            continue;
        g.amp *= fmax(0, 1 - fabs(g.dx - px) / win_w) * fmax(0, 1 - fabs(g.dy - py) / win_h);
        if (!(g.amp > 0))
            continue;
        g.dx -= ox;
        g.dy -= oy;
        vol += g.amp * M_PI / g.c;
        if ((st = rpiv_ccm_corr_add(cw, g)))
            return st;
    }
    if (!cw->n)
        return rpiv_fail(RPIV_ENUMERIC, "ccm: no pair stays inside the %d x %d px window", win_w,
                         win_h);
    double rows[7][7] = {{0}};
    int mx = 0, my = 0;
    if ((st = ccm_sampled_rows(cw, p, rows, &mx, &my)))
        return st;
    ccm_subpixel(rows, p, -vol / ((double)win_w * (double)win_h), mx, my, ex, ey,
                 sig ? &sig->sig : NULL);
    if (sig) {
        sig->mx = mx;
        sig->my = my;
    }
    *ex += ox;
    *ey += oy;
    return RPIV_OK;
}

rpiv_status rpiv_ccm_corr_peak_window(const rpiv_ccm_corr *c, const rpiv_ccm_params *p, int win_w,
                                      int win_h, int deform, rpiv_ccm_peak *out)
{
    return ccm_corr_peak_window_sig(c, p, win_w, win_h, deform, out, NULL);
}

rpiv_status ccm_corr_peak_window_sig(const rpiv_ccm_corr *c, const rpiv_ccm_params *p, int win_w,
                                     int win_h, int deform, rpiv_ccm_peak *out, ccm_wsig *sig)
{
    if (!(win_w == 0 && win_h == 0) && (win_w < 4 || win_h < 4 || win_w > 4096 || win_h > 4096))
        return rpiv_fail(RPIV_EINVAL, "ccm: window %d x %d px outside 4..4096 px", win_w, win_h);
    rpiv_status st = rpiv_ccm_corr_peak(c, p, out);
    if (st)
        return st;
    if (sig)
        *sig = (ccm_wsig){1, 0, 0, 0};
    if (win_w == 0 && win_h == 0)
        return RPIV_OK;
    /* the predictor: from the infinite window's estimate, the engine's passes repeated until
     * the estimate is its own predictor (to 1e-5 px, at most WINDOW_ITER passes) */
    double px = isfinite(out->dx_sub) ? out->dx_sub : out->dx;
    double py = isfinite(out->dy_sub) ? out->dy_sub : out->dy, ex = px, ey = py;
    rpiv_ccm_corr *cw = NULL;
    if ((st = rpiv_ccm_corr_new(c->n, &cw)))
        return st;
    int done = 0;
    double qx = (double)NAN, qy = (double)NAN; /* the predictor of the previous pass */
    for (int it = 0; it < WINDOW_ITER && !done; it++) {
        if ((st = window_estimate(c, p, win_w, win_h, deform, px, py, cw, &ex, &ey, sig)))
            break;
        done = fabs(ex - px) < 1e-5 && fabs(ey - py) < 1e-5;
        if (!done && fabs(ex - qx) < 1e-5 && fabs(ey - qy) < 1e-5) {
            /* the passes alternate between two estimates (no fixed point: the estimator's
             * path changes between them): the last pass's is the one of this parity */
            if ((WINDOW_ITER - 1 - it) % 2) {
                ex = px;
                ey = py;
            }
            break;
        }
        qx = px;
        qy = py;
        px = ex;
        py = ey;
    }
    if (!st) {
        out->dx_sub = ex;
        out->dy_sub = ey;
        if (sig)
            sig->conv = done;
    }
    rpiv_ccm_corr_free(cw);
    return st;
}
