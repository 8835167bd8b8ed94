/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The window's area average in the prediction of what the engine measures (docs/ccm.md, "The
 * engine's window"): the model at sub-positions of the window, each moved by minus the part of
 * the field that the engine's deformation follows there, summed, and the engine's window on the
 * sum (ccm_window.c).
 *
 * What the deformation follows: the engine's predictor is the cubic B-spline through its
 * vectors (src/piv/deform_pred.c), which reproduces a quadratic exactly on an unbounded grid,
 * so across an interior window it follows the field's quadratic variation; the model fits the
 * least-squares quadratic through what the engine measures at the sub-positions. Beyond the
 * grid's last vector the engine's ghost vectors are the point reflections 2 g_0 - g_k of the
 * inner ones: an odd continuation that cannot follow the curvature (a x + c x^2 is continued
 * towards a x - c x^2, and the C2 spline through the kink departs from the quadratic on both
 * sides of the last vector). With the grid given, the model evaluates the engine's own
 * predictor (rpiv_deform_pred) through the fit's values at the grid's vectors. The
 * deformation's value at the window's centre is the window's own predictor, the fixed point of
 * ccm_window.c; only the variation about it moves the sub-positions. */
#include "ccm_impl.h"
#include "rpiv/deform.h"
#include "rpiv/field.h"

#include <gsl/gsl_multifit.h>
#include <math.h>
#include <stdlib.h>

rpiv_ccm_area_opts rpiv_ccm_area_opts_default(void)
{
    return (rpiv_ccm_area_opts){1, 0, 0, 0, 0, 0, 0, NULL, NULL};
}

/* The grid's vectors within GRID_REACH steps of the window enter its predictor (a cubic
 * B-spline interpolant's weight decays by 2 - sqrt 3 = 0.27 a step: 0.27^8 = 3e-5). */
#define GRID_REACH 8

enum { NB = 6 }; /* 1, x, y, x^2, x y, y^2 */

/* The basis at (x, y) (scaled offsets); nb = 3 (plane) or 6 (quadratic). */
static void basis(double x, double y, double *b)
{
    b[0] = 1;
    b[1] = x;
    b[2] = y;
    b[3] = x * x;
    b[4] = x * y;
    b[5] = y * y;
}

/* The least-squares coefficients r[0] (of du) and r[1] (of dv) over the basis's first nb
 * functions at the scaled offsets (ox, oy) / sc, by GSL's SVD; *ok = 0 when the sub-positions
 * do not fix them (reciprocal condition number below 1e-10). */
static rpiv_status fit(const double *ox, const double *oy, const double *du, const double *dv,
                       size_t n, int nb, double sc, double r[2][NB], int *ok)
{
    gsl_matrix *x = gsl_matrix_alloc(n, (size_t)nb),
               *cov = gsl_matrix_alloc((size_t)nb, (size_t)nb);
    gsl_vector *y = gsl_vector_alloc(n), *c = gsl_vector_alloc((size_t)nb);
    gsl_multifit_linear_workspace *ws = gsl_multifit_linear_alloc(n, (size_t)nb);
    rpiv_status st = RPIV_OK;
    *ok = 0;
    if (!x || !cov || !y || !c || !ws)
        st = rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for the area average's fit");
    for (size_t k = 0; k < n && !st; k++) {
        double b[NB];
        basis(ox[k] / sc, oy[k] / sc, b);
        for (int t = 0; t < nb; t++)
            gsl_matrix_set(x, k, (size_t)t, b[t]);
    }
    for (int comp = 0; comp < 2 && !st; comp++) {
        double chisq;
        for (size_t k = 0; k < n; k++)
            gsl_vector_set(y, k, comp ? dv[k] : du[k]);
        if (gsl_multifit_linear(x, y, c, cov, &chisq, ws) ||
            !(gsl_multifit_linear_rcond(ws) >= 1e-10))
            break;
        for (int t = 0; t < nb; t++)
            r[comp][t] = gsl_vector_get(c, (size_t)t);
        *ok = comp == 1;
    }
    gsl_multifit_linear_free(ws);
    gsl_vector_free(c);
    gsl_vector_free(y);
    gsl_matrix_free(cov);
    gsl_matrix_free(x);
    return st;
}

rpiv_status rpiv_ccm_predict_area(const rpiv_ccm_model *models, const double *ox, const double *oy,
                                  size_t n, const rpiv_ccm_area_opts *o, rpiv_ccm_work *w,
                                  rpiv_ccm_peak *out)
{
    rpiv_ccm_area_opts opt = o ? *o : rpiv_ccm_area_opts_default();
    const int nb = opt.quadratic ? 6 : 3;
    if (!models || !ox || !oy || n < (size_t)nb || n > 4096)
        return rpiv_fail(RPIV_EINVAL, "ccm: an area average needs %d..4096 sub-positions", nb);
    if ((opt.quadratic != 0 && opt.quadratic != 1) || opt.nx < 0 || opt.nx > 1000000 ||
        opt.ny < 0 || opt.ny > 1000000 ||
        (opt.nx > 0 &&
         (opt.ny < 1 || opt.i < 0 || opt.i >= opt.nx || opt.j < 0 || opt.j >= opt.ny ||
          !(opt.step_x > 0 && opt.step_x < 1e6) || !(opt.step_y > 0 && opt.step_y < 1e6))))
        return rpiv_fail(RPIV_EINVAL,
                         "ccm: area average's options out of range (quadratic %d, grid %d x %d, "
                         "window %d, %d, steps %g, %g px)",
                         opt.quadratic, opt.nx, opt.ny, opt.i, opt.j, opt.step_x, opt.step_y);
    const rpiv_ccm_model *m0 = &models[0];
    for (size_t k = 0; k < n; k++)
        if (models[k].window_w != m0->window_w || models[k].window_h != m0->window_h ||
            models[k].window_deform != m0->window_deform ||
            models[k].window_pairs != m0->window_pairs || !isfinite(ox[k]) || !isfinite(oy[k]))
            return rpiv_fail(RPIV_EINVAL,
                             "ccm: sub-position %zu has another window or a "
                             "non-finite offset",
                             k);
    double *du = malloc(2 * n * sizeof *du), *dv = du ? du + n : NULL;
    rpiv_ccm_corr *sum = NULL;
    rpiv_status st = du ? rpiv_ccm_corr_new(0, &sum)
                        : rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for %zu sub-positions", n);
    /* what the engine measures at every sub-position */
    double sc = 0;
    for (size_t k = 0; k < n && !st; k++) {
        rpiv_ccm_peak pk;
        if ((st = rpiv_ccm_predict(&models[k], w, &pk)))
            break;
        du[k] = pk.dx_sub;
        dv[k] = pk.dy_sub;
        sc += (ox[k] * ox[k] + oy[k] * oy[k]) / (double)n;
    }
    /* the least-squares plane or quadratic through them, in offsets scaled by their RMS */
    sc = sc > 0 ? sqrt(sc) : 1;
    double r[2][NB] = {{0}};
    int fixed = 1;
    if (!st)
        st = fit(ox, oy, du, dv, n, nb, sc, r, &fixed);
    if (!st && !fixed)
        st =
            rpiv_fail(RPIV_EINVAL, "ccm: the sub-positions of the area average do not fix a %s",
                      opt.quadratic ? "quadratic (too few, or on one conic)" : "plane (collinear)");
    /* the engine's predictor through the fit's values at the grid's vectors near the window */
    rpiv_deform_pred *pred = NULL;
    double p0u = 0, p0v = 0;
    if (!st && opt.nx > 0) {
        int i0 = opt.i > GRID_REACH ? opt.i - GRID_REACH : 0;
        int j0 = opt.j > GRID_REACH ? opt.j - GRID_REACH : 0;
        int i1 = opt.i + GRID_REACH < opt.nx - 1 ? opt.i + GRID_REACH : opt.nx - 1;
        int j1 = opt.j + GRID_REACH < opt.ny - 1 ? opt.j + GRID_REACH : opt.ny - 1;
        rpiv_field *g = NULL;
        st = rpiv_field_new(i1 - i0 + 1, j1 - j0 + 1, (i0 - opt.i) * opt.step_x,
                            (j0 - opt.j) * opt.step_y, opt.step_x, opt.step_y, &g);
        for (int jj = 0; !st && jj < g->ny; jj++)
            for (int ii = 0; ii < g->nx; ii++) {
                double b[NB], u = 0, v = 0;
                basis((g->x0 + ii * g->dx) / sc, (g->y0 + jj * g->dy) / sc, b);
                for (int t = 1; t < nb; t++) {
                    u += r[0][t] * b[t];
                    v += r[1][t] * b[t];
                }
                g->u[(size_t)jj * (size_t)g->nx + (size_t)ii] = (float)u;
                g->v[(size_t)jj * (size_t)g->nx + (size_t)ii] = (float)v;
            }
        if (!st)
            st = rpiv_deform_pred_new(g, 1, 1, 0, &pred);
        if (!st)
            rpiv_deform_pred_eval(pred, 0, 0, &p0u, &p0v);
        rpiv_field_free(g);
    }
    /* every sub-position's terms, amplitude / n, moved by minus the deformation's variation at
     * it */
    ccm_sub *sub = calloc(n, sizeof *sub);
    if (!sub && !st)
        st = rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for %zu sub-positions", n);
    for (size_t k = 0; k < n && !st; k++) {
        if ((st = rpiv_ccm_stat_corr(&models[k], w, w->corr)))
            break;
        double sx = 0, sy = 0;
        if (opt.def_u && opt.def_v) {
            sx = opt.def_u[k];
            sy = opt.def_v[k];
        } else if (pred) {
            rpiv_deform_pred_eval(pred, ox[k], oy[k], &sx, &sy);
            sx -= p0u;
            sy -= p0v;
        } else {
            double b[NB];
            basis(ox[k] / sc, oy[k] / sc, b);
            for (int i = 1; i < nb; i++) {
                sx += r[0][i] * b[i];
                sy += r[1][i] * b[i];
            }
        }
        sub[k] = (ccm_sub){sum->n, sum->n, sx, sy};
        for (size_t t = 0; t < w->corr->n && !st; t++) {
            rpiv_ccm_gauss g = w->corr->g[t];
            g.amp /= (double)n;
            g.dx -= sx;
            g.dy -= sy;
            st = rpiv_ccm_corr_add(sum, g);
        }
        sub[k].t1 = sum->n;
    }
    if (!st)
        st = ccm_corr_peak_window_sig(sum, sub, n, &w->p, m0->window_w, m0->window_h,
                                      m0->window_deform, m0->window_pairs, out, NULL);
    free(sub);
    rpiv_deform_pred_free(pred);
    rpiv_ccm_corr_free(sum);
    free(du);
    return st;
}
