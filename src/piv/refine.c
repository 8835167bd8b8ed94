/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/refine.c - the passes of one pair and the iterative refinement at the final window
 * size (docs/piv.md, "Refinement at the final size"). */
#include "piv_impl.h"

#include "rpiv/validate.h"

#include "uncertainty_impl.h"

#include <math.h>

/* RMS difference of the vectors of two fields on the same grid (masked ones left out). */
static double field_change(const rpiv_field *a, const rpiv_field *b)
{
    size_t n = (size_t)a->nx * (size_t)a->ny, m = 0;
    double s = 0;
    for (size_t k = 0; k < n; k++) {
        if (a->flag[k] == RPIV_FLAG_MASKED)
            continue;
        double du = (double)a->u[k] - (double)b->u[k], dv = (double)a->v[k] - (double)b->v[k];
        s += du * du + dv * dv;
        m++;
    }
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

rpiv_status rpiv_piv_passes(rpiv_piv *pv, rpiv_field **out, int *nrefine)
{
    rpiv_field *prev = NULL, *f = NULL;
    rpiv_status st = RPIV_OK;
    const int last = pv->npass - 1;
    double change = (double)INFINITY;
    int it = 0, deferred = 0, stale = 0, best_it = 0;
    rpiv_field *best = NULL;
    double least = (double)INFINITY;
    *out = NULL;
    if (nrefine)
        *nrefine = 0;
    for (int k = 0; k < pv->npass; k++) {
        deferred = pv->p.refine_defer && iterates(pv, k);
        if ((st = piv_step(pv, k, prev, deferred, &f)))
            goto out_free;
        /* the listed passes may already end with a repeat of the final size */
        if (k == last && piv_repeats(pv, k))
            change = field_change(f, prev);
        rpiv_field_free(prev);
        prev = f;
        f = NULL;
    }
    if (!pv->deforms)
        it = pv->p.refine_max; /* window offsets do not iterate */
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
        double now = field_change(f, prev);
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
