/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/ensemble_unc.c - the random uncertainty of an ensemble field (docs/uncertainty.md,
 * "Ensemble fields"): correlation statistics summed over the pairs (the summed plane's C0,
 * C+, C- and the variance of C+ - C-, which adds over independent pairs), propagated through
 * the peak fit of the summed plane, and the predictor's noise (the previous pass's ensemble
 * field and its sigmas) carried in as in a single pair's passes (unc_chain.c). */
#include "ensemble_impl.h"
#include "piv_impl.h"
#include "uncertainty_impl.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

size_t ens_unc_floats(const rpiv_piv *pv, int pass)
{
    return pv->p.uncertainty ? ENS_UNC_SUMS * pv->pass[pass].nwin : 0;
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

void ens_unc_add(rpiv_ensemble *e, size_t win, const double sums[ENS_UNC_SUMS])
{
    float *d = e->data + e->nwin * (e->plane + 2) + win * ENS_UNC_SUMS;
    for (int k = 0; k < ENS_UNC_SUMS; k++)
        d[k] += (float)sums[k];
}

rpiv_status ens_unc_finish(const rpiv_ensemble *e, rpiv_field *f)
{
    const rpiv_piv *pv = e->pv;
    const piv_pass *ps = &pv->pass[e->pass];
    const float *d = e->data + e->nwin * (e->plane + 2);
    unc_chain *c = NULL;
    float *su, *sv, *cs = malloc(2 * e->nwin * sizeof *cs);
    rpiv_status st = RPIV_OK;
    if (!cs)
        return rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory for the uncertainty");
    for (size_t w = 0; w < e->nwin; w++) {
        const float *s = d + w * ENS_UNC_SUMS;
        cs[w] = (float)unc_cs_sigma((double)s[0], (double)s[1], (double)s[2], (double)s[3]);
        cs[e->nwin + w] =
            (float)unc_cs_sigma((double)s[4], (double)s[5], (double)s[6], (double)s[7]);
    }
    unc_geom g = {
        ps->ox, ps->oy, ps->sx, ps->sy, ps->ww, ps->wh, pv->w, pv->h, piv_shift(pv, e->pass), 0};
    /* the predictor's noise: its sigmas, taken as the noise of its own windows */
    rpiv_field *p = e->predictor;
    const float *pu = p ? unc_quantity(p, "sigma_u") : NULL;
    const float *pvv = p ? unc_quantity(p, "sigma_v") : NULL;
    int linked = 0;
    if (pu && pvv && e->pass > 0 && g.shift != 0) {
        const piv_pass *pp = &pv->pass[e->pass - 1];
        if (pp->nx == p->nx && pp->ny == p->ny) {
            const unc_geom gp = {pp->ox, pp->oy, pp->sx,
                                 pp->sy, pp->ww, pp->wh,
                                 pv->w,  pv->h,  piv_shift(pv, e->pass - 1),
                                 0};
            if ((st = unc_chain_push(&c, 0, &gp, 0, p, pu, pvv)))
                goto out_free;
            linked = 1;
        }
    }
    g.denoise = linked && pv->p.refine_denoise && piv_pred_repeats(pv, p);
    if ((st = unc_chain_push(&c, linked, &g, 0, f, cs, cs + e->nwin)) ||
        (st = unc_add(f, &su, &sv)) || (st = unc_chain_total(c, f, su, sv, pv->nthreads)))
        goto out_free;
    if (g.shift != 0)
        unc_edge_bias(f, ps->ww, ps->wh, su, sv);
    unc_replaced(f);
out_free:
    unc_chain_free(c);
    free(cs);
    return st;
}
