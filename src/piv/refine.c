/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/refine.c - the passes of one pair and the iterative refinement at the final window
 * size (docs/piv.md, "Refinement at the final size"). */
#include "piv_impl.h"

#include "rpiv/validate.h"

#include "uncertainty_impl.h"

#include <math.h>

double piv_field_change(const rpiv_field *a, const rpiv_field *b, int valid, size_t *count)
{
    size_t n = (size_t)a->nx * (size_t)a->ny, m = 0;
    double s = 0;
    for (size_t k = 0; k < n; k++) {
        if (valid ? a->flag[k] != RPIV_FLAG_VALID || b->flag[k] != RPIV_FLAG_VALID
                  : a->flag[k] == RPIV_FLAG_MASKED)
            continue;
        double du = (double)a->u[k] - (double)b->u[k], dv = (double)a->v[k] - (double)b->v[k];
        s += du * du + dv * dv;
        m++;
    }
    if (count)
        *count = m;
    return m ? sqrt(s / (double)m) : 0;
}

/* Is pass k a repeat of the final window size, as are all the passes after it? Such passes
 * are the iteration: with refine_defer their validation waits for the field they converge
 * to. */
static int iterates(const rpiv_piv *pv, int k)
{
    for (int j = k; j < pv->npass; j++)
        if (!piv_repeats(pv, j))
            return 0;
    return 1;
}

/* The passes from k0 on (prev: pass k0 - 1's field, taken over; NULL for k0 = 0), and the
 * refinement until it stops (stop < 0), or exactly stop repeats of the final size (stop >= 0;
 * the listed passes' last field for 0): the steps of the field a run with stop < 0 returned,
 * so the same field (rpiv_piv_passes). */
static rpiv_status passes(rpiv_piv *pv, int k0, rpiv_field *prev, rpiv_field **out, int *nrefine,
                          int stop);

rpiv_status rpiv_piv_passes(rpiv_piv *pv, rpiv_field **out, int *nrefine)
{
    *out = NULL;
    if (!pv->p.uncertainty || !pv->deforms || pv->p.refine_max == 0 || pv->npass < 2)
        return passes(pv, 0, NULL, out, nrefine, -1);
    /* The uncertainty of the field the refinement returns, computed once: each repeat of the
     * final size is a last pass whose field would get its sigma (the whole chain, the most
     * costly part of the uncertainty), while only one of the iterates is returned, possibly
     * one two repeats back (the noise-floor stop). After the first pass (the only one that
     * reads the frames as loaded; the deforming passes prefilter them), a run without the
     * uncertainty finds which (the vectors do not depend on it); a second run from the same
     * first field makes the same steps up to it with the uncertainty, its total at that step
     * only (docs/uncertainty.md, "Cost"). */
    rpiv_field *f0 = NULL, *f0b = NULL, *probe = NULL;
    int nr = 0;
    pv->unc_no_total = 0;
    rpiv_status st = piv_step(pv, 0, NULL, pv->p.refine_defer && iterates(pv, 0), &f0);
    if (!st)
        st = rpiv_field_copy(f0, &f0b);
    if (st) {
        rpiv_field_free(f0);
        return st;
    }
    pv->p.uncertainty = 0;
    st = passes(pv, 1, f0, &probe, &nr, -1);
    pv->p.uncertainty = 1;
    rpiv_field_free(probe);
    if (st) {
        rpiv_field_free(f0b);
        return st;
    }
    st = passes(pv, 1, f0b, out, NULL, nr);
    pv->unc_no_total = 0;
    if (nrefine && !st)
        *nrefine = nr;
    return st;
}

static rpiv_status passes(rpiv_piv *pv, int k0, rpiv_field *prev, rpiv_field **out, int *nrefine,
                          int stop)
{
    rpiv_field *f = NULL;
    rpiv_status st = RPIV_OK;
    const int last = pv->npass - 1;
    double change = (double)INFINITY;
    int it = 0, deferred = 0, stale = 0, best_it = 0;
    rpiv_field *best = NULL;
    double least = (double)INFINITY;
    *out = NULL;
    if (nrefine)
        *nrefine = 0;
    for (int k = k0; k < pv->npass; k++) {
        deferred = pv->p.refine_defer && iterates(pv, k);
        pv->unc_no_total = k == last && stop > 0;
        if ((st = piv_step(pv, k, prev, deferred, &f)))
            goto out_free;
        /* the listed passes may already end with a repeat of the final size */
        if (k == last && piv_repeats(pv, k))
            change = piv_field_change(f, prev, 0, NULL);
        rpiv_field_free(prev);
        prev = f;
        f = NULL;
    }
    if (!pv->deforms)
        it = pv->p.refine_max;             /* window offsets do not iterate */
    for (; stop >= 0 && it < stop; it++) { /* the steps of the field to return, known */
        pv->unc_no_total = it + 1 < stop;
        if ((st = piv_step(pv, last, prev, pv->p.refine_defer, &f)))
            goto out_free;
        deferred = pv->p.refine_defer;
        rpiv_field_free(prev);
        prev = f;
        f = NULL;
    }
    if (stop >= 0)
        it = pv->p.refine_max; /* no other repeat */
    /* the listed passes' own repeat is the first candidate of the noise-floor stop */
    if (pv->p.refine_stop && it < pv->p.refine_max && isfinite(change) &&
        !(change < pv->p.refine_tol_px)) {
        if ((st = rpiv_field_copy(prev, &best)))
            goto out_free;
        least = change;
    }
    for (; it < pv->p.refine_max && !(change < pv->p.refine_tol_px); it++) {
        if ((st = piv_step(pv, last, prev, pv->p.refine_defer, &f)))
            goto out_free;
        deferred = pv->p.refine_defer;
        double now = piv_field_change(f, prev, 0, NULL);
        /* the noise floor: the change has not fallen below its smallest for two repeats,
         * the repeats only stir the measurement noise (docs/piv.md): end with the iterate
         * that came with the smallest change */
        change = now;
        if (pv->p.refine_stop && now < least) {
            least = now;
            stale = 0;
            rpiv_field_free(best);
            best = NULL;
            if ((st = rpiv_field_copy(f, &best)))
                goto out_free;
            best_it = it + 1;
        } else if (pv->p.refine_stop && ++stale >= 2) {
            rpiv_field_free(prev);
            prev = best;
            best = NULL;
            rpiv_field_free(f);
            f = NULL;
            if (nrefine)
                *nrefine = best_it;
            break;
        }
        rpiv_field_free(prev);
        prev = f;
        f = NULL;
        if (nrefine)
            *nrefine = it + 1;
    }
    /* the median test and replacement on the field the iteration converged to */
    if (deferred) {
        if ((st = piv_validate(pv, prev)))
            goto out_free;
        unc_replaced(prev);
    }
    /* optional smoothing of the final field (off by default) */
    if (pv->p.smooth > 0 && (st = rpiv_validate_smooth(prev, pv->p.smooth)))
        goto out_free;
    *out = prev;
    prev = NULL;
out_free:
    rpiv_field_free(best);
    rpiv_field_free(f);
    rpiv_field_free(prev);
    return st;
}

rpiv_status rpiv_piv_run(rpiv_piv *pv, const rpiv_image *a, const rpiv_image *b, rpiv_field **out)
{
    rpiv_status st;
    *out = NULL;
    if ((st = rpiv_piv_load(pv, a, b)))
        return st;
    return rpiv_piv_passes(pv, out, NULL);
}
