/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/unc_step.c - the uncertainty of one pass of a pair (docs/uncertainty.md): the pass
 * joins the chain of the passes before it (unc_chain.c), the final pass gets sigma_u,
 * sigma_v. */
#include "piv_impl.h"
#include "uncertainty_impl.h"

#include "rpiv/validate.h"

#include <stdlib.h>

/* A field as piv_pred_new prepares it (the replaced vectors taken as they are, the masked ones
 * filled), into *out. */
static rpiv_status unc_prepared(const rpiv_field *src, rpiv_field **out)
{
    rpiv_status st = rpiv_field_copy(src, out);
    if (st)
        return st;
    const size_t n = (size_t)(*out)->nx * (size_t)(*out)->ny;
    for (size_t k = 0; k < n; k++)
        if ((*out)->flag[k] == RPIV_FLAG_REPLACED)
            (*out)->flag[k] = RPIV_FLAG_VALID;
    if ((st = rpiv_validate_replace(*out, 1, NULL))) {
        rpiv_field_free(*out);
        *out = NULL;
    }
    return st;
}

rpiv_status unc_pred_error(const rpiv_piv *pv, const rpiv_field *predictor, int denoise,
                           const piv_notch *notch, const rpiv_field *f, rpiv_field **out)
{
    rpiv_field *q = NULL, *d = NULL;
    rpiv_status st;
    *out = NULL;
    if ((st = unc_prepared(predictor, &q)) || (st = unc_prepared(f, &d)) ||
        (denoise && (st = piv_pred_denoise(pv, q))) || (st = piv_pred_notch(q, notch))) {
        rpiv_field_free(q);
        rpiv_field_free(d);
        return st;
    }
    const size_t n = (size_t)d->nx * (size_t)d->ny;
    for (size_t k = 0; k < n; k++) {
        d->u[k] = q->u[k] - d->u[k];
        d->v[k] = q->v[k] - d->v[k];
    }
    rpiv_field_free(q);
    *out = d;
    return RPIV_OK;
}

rpiv_status unc_pred_weights(const rpiv_piv *pv, const rpiv_field *predictor, double filter,
                             int kept, float **gain)
{
    rpiv_field *q = NULL;
    rpiv_status st;
    *gain = NULL;
    if (!(st = unc_prepared(predictor, &q)) && !(filter > 0 && (st = piv_pred_filter(q, filter))))
        st = piv_pred_denoise_weights(pv, q, gain);
    if (!st && !kept) { /* every detail taken as dropped: the denoiser's linear part L */
        const size_t m = (size_t)PIV_DENOISE_STAGES * 2 * (size_t)q->nx * (size_t)q->ny;
        for (size_t k = 0; k < m; k++)
            (*gain)[k] = (*gain)[k] < 1 ? 0 : (*gain)[k];
    }
    rpiv_field_free(q);
    return st;
}

/* The predictor's error: what the refinement's denoiser removed from it (unc_pred_error
 * against the predictor's own field, docs/uncertainty.md "The vortex"), handed to the chain
 * (unc_chain_pred_error). */
static rpiv_status unc_shrink(const rpiv_piv *pv, const rpiv_field *predictor, const unc_geom *g)
{
    rpiv_field *d = NULL;
    rpiv_status st = unc_pred_error(pv, predictor, 1, &g->notch, predictor, &d);
    if (!st)
        st = unc_chain_pred_error(pv->unc, g, d);
    rpiv_field_free(d);
    return st;
}

rpiv_status piv_step_uncertainty(rpiv_piv *pv, int pass, double shift, const rpiv_field *predictor,
                                 const piv_notch *notch, int refines, rpiv_field *f,
                                 const float *cs)
{
    const piv_pass *ps = &pv->pass[pass];
    const int denoise = piv_pred_denoised(pv, predictor);
    const unc_geom g = {ps->ox, ps->oy, ps->sx, ps->sy,  ps->ww, ps->wh,
                        pv->w,  pv->h,  shift,  denoise, *notch};
    const int linked = shift != 0 && unc_chain_links(pv->unc, predictor);
    const double filter = refines ? pv->p.refine_filter : 0;
    float *gain = NULL;
    rpiv_status st =
        linked && g.denoise ? unc_pred_weights(pv, predictor, filter, 1, &gain) : RPIV_OK;
    if (!st)
        st = unc_chain_push(&pv->unc, linked, &g, filter, f, cs, cs + ps->nwin, gain);
    free(gain);
    if (st)
        return st;
    if (!linked && shift == 0 && pass < pv->npass - 1) { /* the first level, not deformed */
        rpiv_field *q = NULL;
        if ((st = unc_prepared(f, &q)) || (st = unc_chain_keep_first(pv->unc, q))) {
            rpiv_field_free(q);
            return st;
        }
        rpiv_field_free(q);
    }
    /* the final field's own terms (the first level's measured error, the denoiser's
     * shrinkage, the total): only for the field whose sigma is wanted (refine.c) */
    const int total = pass == pv->npass - 1 && !pv->unc_no_total;
    if (total && linked) { /* the first level's error, measured */
        rpiv_field *q = NULL;
        if ((st = unc_prepared(f, &q)) || (st = unc_chain_first_error(pv->unc, q, pv->w, pv->h))) {
            rpiv_field_free(q);
            return st;
        }
        rpiv_field_free(q);
    }
    if (total && linked && g.denoise && !(refines && pv->p.refine_filter > 0) &&
        (st = unc_shrink(pv, predictor, &g)))
        return st;
    if (total) {
        float *su, *sv;
        if ((st = unc_add(f, &su, &sv)) || (st = unc_chain_total(pv->unc, f, su, sv, pv->nthreads)))
            return st;
        const int frame[6] = {pv->w, pv->h, ps->ox, ps->oy, ps->sx, ps->sy};
        if (shift != 0) /* a deforming final pass: the systematic term (unc_bias.c) */
            unc_systematic(f, ps->ww, ps->wh, cs + 2 * ps->nwin, cs + 3 * ps->nwin, NULL, NULL, 1,
                           shift, frame, su, sv, pv->nthreads);
        if (pv->deforms)
            unc_edge_bias(f, ps->ww, ps->wh, piv_edge_curved(pv, 0), su, sv);
        unc_replaced(f);
    }
    unc_chain_set_hash(pv->unc, f);
    return RPIV_OK;
}
