/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/piv_step.c - one pass of one pair: the vector of each window (the peak, its
 * search near the predictor), validation and replacement, the pass as a step
 * (rpiv_piv_step); the plan and the pass's loop over windows: src/piv/piv.c. */
#include "piv_impl.h"

#include "rpiv/validate.h"

#include "deform_impl.h"
#include "uncertainty_impl.h"
#include "validate_impl.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>

void piv_vector(const rpiv_piv *pv, const piv_pass *ps, const float *plane, const float *colmax,
                double ea, double eb, double pu, double pv_, rpiv_field *f, size_t win,
                int ensemble, int near, rpiv_peak *peak)
{
    rpiv_peak pk;
    rpiv_subpixel method = rpiv_subpixel_resolve(pv->p.subpixel, ensemble);
    /* near 0: the whole plane, with or without the column maxima */
    rpiv_peak_find_near(plane, ps->ww, ps->wh, near, colmax, method, &pk);
    if (peak)
        *peak = pk;
    if (!(ea > 0) || !(eb > 0) || !pk.fit_ok || !(pk.value > 0)) {
        /* nothing to measure: rejected, replaced by validation */
        f->u[win] = (float)pu;
        f->v[win] = (float)pv_;
        f->flag[win] = RPIV_FLAG_REPLACED;
        f->peak_ratio[win] = 0;
        f->corr[win] = 0;
        return;
    }
    f->u[win] = (float)(pu + pk.dx);
    f->v[win] = (float)(pv_ + pk.dy);
    f->flag[win] = RPIV_FLAG_VALID;
    f->peak_ratio[win] = pk.ratio;
    f->corr[win] = (float)((double)pk.value / sqrt(ea * eb));
}

int piv_params_search_radius(const rpiv_piv_params *p, int pass, int has_predictor)
{
    const int r = p->search_radius;
    if (!has_predictor || r == 0)
        return 0;
    if (r > 0)
        return r;
    /* the window of the pass that made the predictor (the pass before; the first pass's own) */
    const int k = pass > 0 ? pass - 1 : 0;
    const int side = p->win_w[k] < p->win_h[k] ? p->win_w[k] : p->win_h[k];
    return side / 8 > 2 ? side / 8 : 2;
}

int piv_search_radius(const rpiv_piv *pv, int pass, int has_predictor)
{
    return piv_params_search_radius(&pv->p, pass, has_predictor);
}

rpiv_status piv_validate(const rpiv_piv *pv, rpiv_field *f)
{
    rpiv_status st = validate_more(f, &pv->p);
    if (st)
        return st;
    if (pv->p.median_thr > 0 && (st = validate_median_nt(f, pv->p.median_thr, pv->p.median_eps,
                                                         pv->p.median_lines, NULL, pv->nthreads)))
        return st;
    if (pv->p.replace == 1)
        return rpiv_validate_inpaint(f, 0, NULL);
    return validate_replace_lines(f, 0, pv->p.median_lines, NULL);
}

typedef struct step_ctx {
    const rpiv_piv *pv;
    const piv_pass *ps;
    rpiv_field *f;
    float *su, *sv; /* sigma_u, sigma_v of f; NULL: no uncertainty   */
    float *scratch; /* 2 ww wh floats per thread for the uncertainty */
    int near;       /* the peak search radius (piv_search_radius)    */
    piv_cbc *cbc;   /* the correlation-based correction, or NULL     */
} step_ctx;

/* The window's own sigmas and curvatures at its vector's integer shift (unc_cs). */
static void step_unc(step_ctx *c, size_t win, double pu, double pv_, const rpiv_xcorr_src *xs)
{
    const piv_pass *ps = c->ps;
    double su, sv;
    float *scr = c->scratch + 2 * (size_t)omp_get_thread_num() * (size_t)ps->ww * (size_t)ps->wh;
    double curv[2];
    unc_cs(xs->a, xs->stride_a, xs->b, xs->stride_b, ps->ww, ps->wh,
           (int)lround((double)c->f->u[win] - pu), (int)lround((double)c->f->v[win] - pv_), scr,
           &su, &sv, curv);
    c->su[win] = (float)su;
    c->sv[win] = (float)sv;
    c->su[2 * ps->nwin + win] = (float)curv[0]; /* after the sigmas: the curvatures */
    c->su[3 * ps->nwin + win] = (float)curv[1];
}

static void step_vector(void *ctx, const float *plane, const float *colmax, size_t win, double ea,
                        double eb, double pu, double pv_, const rpiv_xcorr_src *xs)
{
    step_ctx *c = ctx;
    rpiv_peak pk;
    piv_vector(c->pv, c->ps, plane, colmax, ea, eb, pu, pv_, c->f, win, 0, c->near, &pk);
    if (c->f->flag[win] != RPIV_FLAG_VALID)
        return;
    if (c->cbc)
        piv_cbc_store(c->cbc, plane, colmax, c->ps->ww, c->ps->wh, win, &pk, ea, eb, pu, pv_);
    if (c->su)
        step_unc(c, win, pu, pv_, xs);
}

/* The uncertainty again for the windows the correlation-based correction moved (their
 * vector's integer shift changed): a second sweep over the pass's windows. */
static void step_unc_moved(void *ctx, const float *plane, const float *colmax, size_t win,
                           double ea, double eb, double pu, double pv_, const rpiv_xcorr_src *xs)
{
    (void)plane, (void)colmax, (void)ea, (void)eb;
    step_ctx *c = ctx;
    if (c->cbc->moved[win])
        step_unc(c, win, pu, pv_, xs);
}

int piv_repeats(const rpiv_piv *pv, int pass)
{
    return pass > 0 && pv->deforms && pv->pass[pass].ww == pv->pass[pass - 1].ww &&
           pv->pass[pass].wh == pv->pass[pass - 1].wh;
}

rpiv_status rpiv_piv_step(rpiv_piv *pv, int pass, const rpiv_field *predictor, rpiv_field **out)
{
    return piv_step(pv, pass, predictor, 0, out);
}

rpiv_status piv_step(rpiv_piv *pv, int pass, const rpiv_field *predictor, int defer,
                     rpiv_field **out)
{
    *out = NULL;
    if (pass < 0 || pass >= pv->npass)
        return rpiv_fail(RPIV_EINVAL, "piv: pass %d outside 0..%d", pass, pv->npass - 1);
    if (pv->state == PIV_EMPTY)
        return rpiv_fail(RPIV_EINVAL, "piv: no pair loaded");
    if (piv_cancelled(pv))
        return rpiv_fail(RPIV_EINTR, "piv: interrupted before pass %d", pass + 1);
    const piv_pass *ps = &pv->pass[pass];
    rpiv_deform_pred *pred = NULL;
    rpiv_field *f = NULL;
    float *scratch = NULL, *cs = NULL; /* cs: the windows' own sigmas, u then v */
    piv_cbc *cbc = NULL;
    rpiv_status st;
    /* a repeat of the window size before it (a refinement): its predictor low-passed */
    const int refines = piv_repeats(pv, pass);
    /* a refinement repeat's predictor is notched (refine_notch); decided once for the step */
    piv_notch notch = {{0, 0}, {0, 0}};
    if (predictor)
        piv_pred_notch_orders(pv, pass, piv_pred_denoised(pv, predictor), predictor, &notch);
    if (predictor && (st = piv_pred_new(pv, predictor, pass, refines ? pv->p.refine_filter : 0,
                                        &notch, 0, &pred)))
        return st;
    if ((st = rpiv_piv_grid(pv, pass, &f)))
        goto out_free;
    for (size_t win = 0; ps->masked && win < ps->nwin; win++)
        if (ps->masked[win])
            f->flag[win] = RPIV_FLAG_MASKED;
    step_ctx c = {pv,  ps, f, NULL, NULL, NULL, piv_search_radius(pv, pass, predictor != NULL),
                  NULL};
    if (pv->p.cbc && (st = piv_cbc_new(ps, c.near, pv->p.cbc, &cbc)))
        goto out_free;
    c.cbc = cbc;
    if (pv->p.uncertainty) {
        /* every pass: the final vectors carry the predictors' noise (docs/uncertainty.md) */
        const size_t nscr = 2 * (size_t)pv->nthreads * (size_t)ps->ww * (size_t)ps->wh;
        c.scratch = scratch = malloc(nscr * sizeof *scratch);
        cs = calloc(4 * ps->nwin, sizeof *cs);
        if (!scratch || !cs) {
            st = rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the uncertainty");
            goto out_free;
        }
        c.su = cs;
        c.sv = cs + ps->nwin;
    }
    if ((st = piv_pass_run_cut(pv, pass, pred, step_vector, &c)))
        goto out_free;
    if (cbc) {
        piv_source src;
        piv_source_of(pv, pass, pred, &src);
        const size_t moved = piv_cbc_apply(
            cbc, src.offsets, rpiv_subpixel_resolve(pv->p.subpixel, 0), f, pv->nthreads);
        if (moved && c.su && (st = piv_pass_run_cut(pv, pass, pred, step_unc_moved, &c)))
            goto out_free;
    }
    if (defer && refines && predictor && predictor->nx == f->nx && predictor->ny == f->ny) {
        /* validation deferred to the converged field: a window without a peak keeps the
         * predictor's vector (flagged replaced) */
        for (size_t win = 0; win < ps->nwin; win++)
            if (f->flag[win] == RPIV_FLAG_REPLACED) {
                f->u[win] = predictor->u[win];
                f->v[win] = predictor->v[win];
            }
    } else if ((st = piv_validate(pv, f)))
        goto out_free;
    if (cs && (st = piv_step_uncertainty(pv, pass, piv_shift(pv, pass), predictor, &notch, refines,
                                         f, cs)))
        goto out_free;
    if (pass == pv->npass - 1) { /* a step on this field is a refinement repeat */
        pv->final_hash = piv_field_hash(f);
        pv->final_known = 1;
    }
    *out = f;
    f = NULL;
out_free:
    piv_cbc_free(cbc);
    free(cs);
    free(scratch);
    rpiv_field_free(f);
    rpiv_deform_pred_free(pred);
    return st;
}
