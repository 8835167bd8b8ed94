/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/ensemble_unc.c - the random uncertainty of an ensemble field (docs/uncertainty.md,
 * "Ensemble fields"): correlation statistics summed over the pairs (the summed plane's C0,
 * C+, C- and the variance of C+ - C-, which adds over independent pairs), propagated through
 * the peak fit of the summed plane, and the predictor's noise (the previous pass's ensemble
 * field and its sigmas) carried in as in a single pair's passes (unc_chain.c). */
#include "ensemble_impl.h"
#include "peak_impl.h"
#include "piv_impl.h"
#include "rpiv/peak.h"
#include "uncertainty_impl.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

size_t ens_unc_floats(const rpiv_piv *pv, int pass)
{
    return pv->p.uncertainty ? ENS_UNC_STRIDE * pv->pass[pass].nwin : 0;
}

void ens_unc_pair(const rpiv_ensemble *e, const float *plane, const rpiv_xcorr_src *xs,
                  float *scratch, double sums[ENS_UNC_SUMS])
{
    const piv_pass *ps = &e->pv->pass[e->pass];
    int ix = 0, iy = 0;
    if (!e->pred) {
        /* no predictor: at this pair's own highest correlation (circular shifts) */
        size_t best = 0;
        for (size_t i = 1; i < e->plane; i++)
            if (plane[i] > plane[best])
                best = i;
        ix = (int)(best % (size_t)ps->ww);
        iy = (int)(best / (size_t)ps->ww);
        ix = ix > ps->ww / 2 ? ix - ps->ww : ix;
        iy = iy > ps->wh / 2 ? iy - ps->wh : iy;
    }
    /* with a predictor the windows are shifted onto each other: the peak is at 0 */
    unc_cs_sums(xs->a, xs->stride_a, xs->b, xs->stride_b, ps->ww, ps->wh, ix, iy, scratch, sums);
}

/* The plane index of shift (dx, dy), circular. */
static size_t mom_index(int dx, int dy, int w, int h)
{
    const int x = dx < 0 ? dx + w : dx, y = dy < 0 ? dy + h : dy;
    return (size_t)y * (size_t)w + (size_t)x;
}

#define ENS_UNC_N (2 * ENS_UNC_R + 1)
#define ENS_UNC_M (ENS_UNC_N * ENS_UNC_N)

/* The upper-triangle slot of moment (a, b), a <= b < ENS_UNC_M. */
static size_t tri(int a, int b)
{
    return (size_t)b * (size_t)(b + 1) / 2 + (size_t)a;
}

void ens_unc_add(rpiv_ensemble *e, size_t win, const double sums[ENS_UNC_SUMS], const float *plane)
{
    const piv_pass *ps = &e->pv->pass[e->pass];
    float *d = e->data + e->nwin * (e->plane + 2) + win * ENS_UNC_STRIDE;
    for (int k = 0; k < ENS_UNC_SUMS; k++)
        d[k] += (float)sums[k];
    if (ps->ww < ENS_UNC_N || ps->wh < ENS_UNC_N)
        return;
    double c[ENS_UNC_M];
    for (int j = 0; j < ENS_UNC_N; j++)
        for (int i = 0; i < ENS_UNC_N; i++)
            c[j * ENS_UNC_N + i] =
                (double)plane[mom_index(i - ENS_UNC_R, j - ENS_UNC_R, ps->ww, ps->wh)];
    float *m = d + ENS_UNC_SUMS;
    for (int b = 0; b < ENS_UNC_M; b++)
        for (int a = 0; a <= b; a++)
            m[tri(a, b)] += (float)(c[a] * c[b]);
}

/* The variances of the spline's maximum of the summed plane of window win from the spread of
 * the pairs' planes (docs/uncertainty.md, "Ensemble fields"): 1 and *vx, *vy, or 0 when the
 * estimator is not the spline, its maximum is not the spline's, or its samples are not all
 * within the moments' neighbourhood. */
static int spline_var(const rpiv_ensemble *e, size_t win, double *vx, double *vy)
{
    const rpiv_piv *pv = e->pv;
    const piv_pass *ps = &pv->pass[e->pass];
    const double np = (double)e->npairs;
    if (rpiv_subpixel_resolve(pv->p.subpixel, 1) != RPIV_SUBPIXEL_SPLINE || np < 2 ||
        ps->ww < ENS_UNC_N || ps->wh < ENS_UNC_N)
        return 0;
    const float *plane = e->data + win * e->plane;
    rpiv_peak pk;
    rpiv_peak_find(plane, ps->ww, ps->wh, 0, RPIV_SUBPIXEL_SPLINE, &pk);
    if (!pk.fit_ok)
        return 0;
    const int bi = pk.ix < 0 ? pk.ix + ps->ww : pk.ix, bj = pk.iy < 0 ? pk.iy + ps->wh : pk.iy;
    peak_sens s;
    if (!peak_spline_sens(plane, ps->ww, ps->wh, bi, bj, pk.dx - pk.ix, pk.dy - pk.iy, &s))
        return 0;
    const int r = (s.n - 1) / 2;
    if (abs(pk.ix) + r > ENS_UNC_R || abs(pk.iy) + r > ENS_UNC_R)
        return 0;
    const float *m = e->data + e->nwin * (e->plane + 2) + win * ENS_UNC_STRIDE + ENS_UNC_SUMS;
    int at[ENS_UNC_M]; /* the moments' index of each of the spline's samples */
    double sx = 0, sy = 0, qx = 0, qy = 0;
    for (int j = 0; j < s.n; j++)
        for (int i = 0; i < s.n; i++) {
            const int k = j * s.n + i, dx = pk.ix + i - r, dy = pk.iy + j - r;
            at[k] = (dy + ENS_UNC_R) * ENS_UNC_N + dx + ENS_UNC_R;
            const double c = (double)plane[mom_index(dx, dy, ps->ww, ps->wh)];
            sx += s.jx[k] * c;
            sy += s.jy[k] * c;
        }
    for (int k = 0; k < s.n * s.n; k++)
        for (int l = 0; l < s.n * s.n; l++) {
            const int a = at[k] < at[l] ? at[k] : at[l], b = at[k] < at[l] ? at[l] : at[k];
            const double mm = (double)m[tri(a, b)];
            qx += s.jx[k] * s.jx[l] * mm;
            qy += s.jy[k] * s.jy[l] * mm;
        }
    /* the summed plane's covariance: N times the pairs' sample covariance */
    *vx = np / (np - 1) * (qx - sx * sx / np);
    *vy = np / (np - 1) * (qy - sy * sy / np);
    return 1;
}

/* The 3-point curvature of ln c at the integer peak of window win's summed plane, x and y. */
static int plane_curv(const rpiv_ensemble *e, size_t win, double *hx, double *hy)
{
    const piv_pass *ps = &e->pv->pass[e->pass];
    const int w = ps->ww, h = ps->wh;
    const float *plane = e->data + win * e->plane;
    rpiv_peak pk;
    rpiv_peak_find(plane, w, h, 0, RPIV_SUBPIXEL_GAUSS, &pk);
    return unc_curv_at(plane, w, h, (pk.ix + w) % w, (pk.iy + h) % h, hx, hy) && *hx < 0 && *hy < 0;
}

/* The final pass's systematic term (docs/uncertainty.md, "The systematic floor"): the
 * engine's chain on a model particle image of the summed planes' width (unc_systematic). */
static rpiv_status ens_systematic(const rpiv_ensemble *e, const rpiv_field *f, float *su, float *sv)
{
    const rpiv_piv *pv = e->pv;
    const piv_pass *ps = &pv->pass[e->pass];
    piv_source src;
    piv_source_of(pv, e->pass, e->pred, &src);
    float *h = malloc(2 * e->nwin * sizeof *h);
    double *p = malloc(2 * e->nwin * sizeof *p);
    if (!h || !p) {
        free(h);
        free(p);
        return rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory for the uncertainty");
    }
    for (size_t w = 0; w < e->nwin; w++) {
        double hx = 0, hy = 0;
        piv_window_shift(ps, &src, w, &p[w], &p[e->nwin + w]);
        if (f->flag[w] == RPIV_FLAG_VALID && !plane_curv(e, w, &hx, &hy))
            hx = hy = 0;
        h[w] = (float)hx;
        h[e->nwin + w] = (float)hy;
    }
    const int frame[6] = {pv->w, pv->h, ps->ox, ps->oy, ps->sx, ps->sy};
    unc_systematic(f, ps->ww, ps->wh, h, h + e->nwin, p, p + e->nwin, src.deform,
                   src.offsets ? 0 : src.shift, frame, su, sv, pv->nthreads);
    free(h);
    free(p);
    return RPIV_OK;
}

rpiv_status ens_unc_finish(const rpiv_ensemble *e, rpiv_field *f, const unsigned char *fell)
{
    const rpiv_piv *pv = e->pv;
    const piv_pass *ps = &pv->pass[e->pass];
    const float *d = e->data + e->nwin * (e->plane + 2);
    unc_chain *c = NULL;
    float *su, *sv, *cs = malloc(2 * e->nwin * sizeof *cs);
    rpiv_status st = RPIV_OK;
    if (!cs)
        return rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory for the uncertainty");
#pragma omp parallel for schedule(dynamic, 8) num_threads(pv->nthreads)
    for (size_t w = 0; w < e->nwin; w++) {
        const float *s = d + w * ENS_UNC_STRIDE;
        double vx, vy;
        if (!fell[w] && spline_var(e, w, &vx, &vy)) {
            /* the spline estimator's sensitivity and the spread of the pairs' planes */
            const double ux = sqrt(vx > 0 ? vx : 0), uy = sqrt(vy > 0 ? vy : 0);
            cs[w] = (float)(ux < UNC_SIGMA_MAX ? ux : UNC_SIGMA_MAX);
            cs[e->nwin + w] = (float)(uy < UNC_SIGMA_MAX ? uy : UNC_SIGMA_MAX);
            continue;
        }
        /* else correlation statistics through the 3-point fit */
        cs[w] = (float)unc_cs_sigma((double)s[0], (double)s[1], (double)s[2], (double)s[3]);
        cs[e->nwin + w] =
            (float)unc_cs_sigma((double)s[4], (double)s[5], (double)s[6], (double)s[7]);
    }
    unc_geom g = {ps->ox, ps->oy,          ps->sx,
                  ps->sy, ps->ww,          ps->wh,
                  pv->w,  pv->h,           piv_shift(pv, e->pass),
                  0,      {{0, 0}, {0, 0}}};
    /* the predictor's noise: its sigmas, taken as the noise of its own windows */
    rpiv_field *p = e->predictor;
    const float *pu = p ? unc_quantity(p, "sigma_u") : NULL;
    const float *pvv = p ? unc_quantity(p, "sigma_v") : NULL;
    int linked = 0;
    if (pu && pvv && e->pass > 0 && g.shift != 0) {
        const piv_pass *pp = &pv->pass[e->pass - 1];
        if (pp->nx == p->nx && pp->ny == p->ny) {
            const unc_geom gp = {pp->ox, pp->oy,          pp->sx,
                                 pp->sy, pp->ww,          pp->wh,
                                 pv->w,  pv->h,           piv_shift(pv, e->pass - 1),
                                 0,      {{0, 0}, {0, 0}}};
            if ((st = unc_chain_push(&c, 0, &gp, 0, p, pu, pvv, NULL)))
                goto out_free;
            linked = 1;
        }
    }
    g.denoise = linked ? piv_pred_denoised_ensemble(pv, p) : 0;
    if (linked)
        g.notch = e->notch;
    {
        float *gain = NULL;
        /* the denoiser's linear part L (docs/uncertainty.md, "The denoiser in the chain": with
         * its weights the ensemble sweep got worse) */
        if (!(st = g.denoise ? unc_pred_weights(pv, p, 0, 0, &gain) : RPIV_OK))
            st = unc_chain_push(&c, linked, &g, 0, f, cs, cs + e->nwin, gain);
        free(gain);
        if (st)
            goto out_free;
    }
    if (linked && e->pass == pv->npass - 1 && p->nx == f->nx && p->ny == f->ny) {
        /* the predictor's error as this pass corrected it (unc_chain_pred_error) */
        rpiv_field *pe = NULL;
        if (!(st = unc_pred_error(pv, p, g.denoise, &g.notch, f, &pe)))
            st = unc_chain_pred_error(c, &g, pe);
        rpiv_field_free(pe);
        if (st)
            goto out_free;
    }
    if ((st = unc_add(f, &su, &sv)) || (st = unc_chain_total(c, f, su, sv, pv->nthreads)))
        goto out_free;
    if (e->pass == pv->npass - 1 && (st = ens_systematic(e, f, su, sv)))
        goto out_free;
    if (g.shift != 0)
        unc_edge_bias(f, ps->ww, ps->wh, piv_edge_curved(pv, 1), su, sv);
    unc_replaced(f);
out_free:
    unc_chain_free(c);
    free(cs);
    return st;
}
