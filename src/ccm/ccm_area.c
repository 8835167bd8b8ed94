/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The window's area average in the prediction of what the engine measures (docs/ccm.md, "The
 * engine's window"): the model at sub-positions of the window, each moved by minus the linear
 * part of the field that the deformation follows, summed, and the engine's window on the sum
 * (ccm_window.c). */
#include "ccm_impl.h"

#include <math.h>
#include <stdlib.h>

rpiv_status rpiv_ccm_predict_area(const rpiv_ccm_model *models, const double *ox, const double *oy,
                                  size_t n, rpiv_ccm_work *w, rpiv_ccm_peak *out)
{
    if (!models || !ox || !oy || n < 3 || n > 4096)
        return rpiv_fail(RPIV_EINVAL, "ccm: an area average needs 3..4096 sub-positions");
    const rpiv_ccm_model *m0 = &models[0];
    for (size_t k = 0; k < n; k++)
        if (models[k].window_w != m0->window_w || models[k].window_h != m0->window_h ||
            models[k].window_deform != m0->window_deform || !isfinite(ox[k]) || !isfinite(oy[k]))
            return rpiv_fail(RPIV_EINVAL,
                             "ccm: sub-position %zu has another window or a "
                             "non-finite offset",
                             k);
    double *du = malloc(2 * n * sizeof *du), *dv = du ? du + n : NULL;
    rpiv_ccm_corr *sum = NULL;
    rpiv_status st = du ? rpiv_ccm_corr_new(0, &sum)
                        : rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for %zu sub-positions", n);
    /* what the engine measures at every sub-position, then the least-squares plane through
     * them: the linear part the deformation follows */
    double mx = 0, my = 0, mu = 0, mv = 0;
    for (size_t k = 0; k < n && !st; k++) {
        rpiv_ccm_peak pk;
        if ((st = rpiv_ccm_predict(&models[k], w, &pk)))
            break;
        du[k] = pk.dx_sub;
        dv[k] = pk.dy_sub;
        mx += ox[k] / n;
        my += oy[k] / n;
        mu += du[k] / n;
        mv += dv[k] / n;
    }
    double sxx = 0, sxy = 0, syy = 0, sxu = 0, syu = 0, sxv = 0, syv = 0;
    for (size_t k = 0; k < n && !st; k++) {
        double x = ox[k] - mx, y = oy[k] - my;
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
        sxu += x * (du[k] - mu);
        syu += y * (du[k] - mu);
        sxv += x * (dv[k] - mv);
        syv += y * (dv[k] - mv);
    }
    double det = sxx * syy - sxy * sxy;
    if (!st && !(det > 1e-12 * (sxx + syy) * (sxx + syy)))
        st = rpiv_fail(RPIV_EINVAL, "ccm: the sub-positions of the area average are collinear");
    double gux = (syy * sxu - sxy * syu) / det, guy = (sxx * syu - sxy * sxu) / det;
    double gvx = (syy * sxv - sxy * syv) / det, gvy = (sxx * syv - sxy * sxv) / det;
    /* every sub-position's terms, amplitude / n, moved by minus the linear part at it */
    for (size_t k = 0; k < n && !st; k++) {
        if ((st = rpiv_ccm_stat_corr(&models[k], w, w->corr)))
            break;
        double sx = gux * (ox[k] - mx) + guy * (oy[k] - my);
        double sy = gvx * (ox[k] - mx) + gvy * (oy[k] - my);
        for (size_t t = 0; t < w->corr->n && !st; t++) {
            rpiv_ccm_gauss g = w->corr->g[t];
            g.amp /= (double)n;
            g.dx -= sx;
            g.dy -= sy;
            st = rpiv_ccm_corr_add(sum, g);
        }
    }
    if (!st)
        st = rpiv_ccm_corr_peak_window(sum, &w->p, m0->window_w, m0->window_h, m0->window_deform,
                                       out);
    rpiv_ccm_corr_free(sum);
    free(du);
    return st;
}
