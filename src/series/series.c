/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/series/series.c - series of pairs: instantaneous processing, mean and RMS, the ensemble
 * run (the background is in background.c). */
#include "rpiv/series.h"

#include "rpiv/batch.h"

#include "series_impl.h"

#include <math.h>
#include <stdlib.h>

rpiv_status rpiv_series_run(rpiv_piv *pv, const rpiv_pairs *pairs, rpiv_series_sink sink,
                            void *user, const rpiv_progress *progress)
{
    /* the loop (with skipping and MPI dealing when asked) is rpiv_batch_series */
    if (!pairs->n)
        return rpiv_fail(RPIV_EINVAL, "piv: no image pairs");
    rpiv_batch *b = NULL;
    rpiv_status st = rpiv_batch_new(pairs, NULL, NULL, &b);
    if (!st)
        st = rpiv_batch_series(b, pv, sink, NULL, user, progress);
    rpiv_batch_free(b);
    return st;
}

/* ---- mean and RMS ------------------------------------------------------------------------ */

struct rpiv_series_stats {
    rpiv_field *grid;
    size_t nfields;
    /* per point, for valid vectors (index 0) and for replaced ones (index 1) */
    double *cnt[2], *mu[2], *mv[2], *su[2], *sv[2], *pr[2], *cr[2];
    double *block;
};

void rpiv_series_stats_free(rpiv_series_stats *s)
{
    if (!s)
        return;
    rpiv_field_free(s->grid);
    free(s->block);
    free(s);
}

rpiv_status rpiv_series_stats_new(const rpiv_field *grid, rpiv_series_stats **out)
{
    *out = NULL;
    rpiv_series_stats *s = calloc(1, sizeof *s);
    if (!s)
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory for statistics");
    rpiv_status st =
        rpiv_field_new(grid->nx, grid->ny, grid->x0, grid->y0, grid->dx, grid->dy, &s->grid);
    size_t n = (size_t)grid->nx * (size_t)grid->ny;
    if (!st) {
        s->grid->scale_mm_per_px = grid->scale_mm_per_px;
        s->grid->dt_s = grid->dt_s;
        s->block = calloc(14 * n, sizeof *s->block);
        if (!s->block)
            st = rpiv_fail(RPIV_ENOMEM, "piv: out of memory for statistics");
    }
    if (st) {
        rpiv_series_stats_free(s);
        return st;
    }
    double **arr[7] = {s->cnt, s->mu, s->mv, s->su, s->sv, s->pr, s->cr};
    for (int a = 0; a < 7; a++)
        for (int c = 0; c < 2; c++)
            arr[a][c] = s->block + (size_t)(2 * a + c) * n;
    *out = s;
    return RPIV_OK;
}

rpiv_status rpiv_series_stats_add(rpiv_series_stats *s, const rpiv_field *f)
{
    const rpiv_field *g = s->grid;
    if (f->nx != g->nx || f->ny != g->ny || f->x0 != g->x0 || f->y0 != g->y0 || f->dx != g->dx ||
        f->dy != g->dy)
        return rpiv_fail(RPIV_ESIZE,
                         "piv: field of %dx%d points at (%g, %g) step (%g, %g) "
                         "added to statistics of %dx%d at (%g, %g) step (%g, %g)",
                         f->nx, f->ny, f->x0, f->y0, f->dx, f->dy, g->nx, g->ny, g->x0, g->y0,
                         g->dx, g->dy);
    size_t n = (size_t)g->nx * (size_t)g->ny;
    for (size_t k = 0; k < n; k++) {
        int c = f->flag[k] == RPIV_FLAG_VALID ? 0 : (f->flag[k] == RPIV_FLAG_REPLACED ? 1 : -1);
        if (c < 0)
            continue;
        double m = ++s->cnt[c][k], du = (double)f->u[k] - s->mu[c][k],
               dv = (double)f->v[k] - s->mv[c][k];
        s->mu[c][k] += du / m;
        s->mv[c][k] += dv / m;
        s->su[c][k] += du * ((double)f->u[k] - s->mu[c][k]);
        s->sv[c][k] += dv * ((double)f->v[k] - s->mv[c][k]);
        s->pr[c][k] += ((double)f->peak_ratio[k] - s->pr[c][k]) / m;
        s->cr[c][k] += ((double)f->corr[k] - s->cr[c][k]) / m;
    }
    s->nfields++;
    return RPIV_OK;
}

size_t rpiv_series_stats_count(const rpiv_series_stats *s)
{
    return s->nfields;
}

rpiv_status rpiv_series_stats_finish(const rpiv_series_stats *s, rpiv_field **mean,
                                     rpiv_field **rms)
{
    *mean = *rms = NULL;
    if (!s->nfields)
        return rpiv_fail(RPIV_EINVAL, "piv: no field to average");
    rpiv_field *m = NULL, *r = NULL;
    rpiv_status st;
    if ((st = rpiv_field_copy(s->grid, &m)) || (st = rpiv_field_copy(s->grid, &r))) {
        rpiv_field_free(m);
        return st;
    }
    size_t n = (size_t)s->grid->nx * (size_t)s->grid->ny;
    for (size_t k = 0; k < n; k++) {
        int c = s->cnt[0][k] > 0 ? 0 : (s->cnt[1][k] > 0 ? 1 : -1);
        if (c < 0) {
            m->flag[k] = r->flag[k] = RPIV_FLAG_MASKED;
            continue;
        }
        double cnt = s->cnt[c][k];
        m->flag[k] = r->flag[k] = c ? RPIV_FLAG_REPLACED : RPIV_FLAG_VALID;
        m->u[k] = (float)s->mu[c][k];
        m->v[k] = (float)s->mv[c][k];
        r->u[k] = (float)sqrt(s->su[c][k] / cnt);
        r->v[k] = (float)sqrt(s->sv[c][k] / cnt);
        m->peak_ratio[k] = r->peak_ratio[k] = (float)s->pr[c][k];
        m->corr[k] = r->corr[k] = (float)s->cr[c][k];
    }
    *mean = m;
    *rms = r;
    return RPIV_OK;
}

/* ---- the ensemble run ------------------------------------------------------------------------ */

rpiv_status rpiv_series_ensemble(rpiv_piv *pv, const rpiv_pairs *pairs,
                                 const rpiv_progress *progress, rpiv_field **out)
{
    /* the loop (with checkpoints, skipping and MPI dealing when asked) is rpiv_batch_ensemble */
    *out = NULL;
    if (!pairs->n)
        return rpiv_fail(RPIV_EINVAL, "ensemble: no image pairs");
    rpiv_batch *b = NULL;
    rpiv_status st = rpiv_batch_new(pairs, NULL, NULL, &b);
    if (!st)
        st = rpiv_batch_ensemble(b, pv, progress, out);
    rpiv_batch_free(b);
    return st;
}

rpiv_status rpiv_series_ensemble_source(rpiv_piv *pv, const rpiv_series_source *src,
                                        const rpiv_progress *progress, rpiv_field **out)
{
    *out = NULL;
    if (!src->n)
        return rpiv_fail(RPIV_EINVAL, "ensemble: no image pairs");
    rpiv_batch *b = NULL;
    rpiv_status st = batch_new_source(src, pv, &b);
    if (!st)
        st = rpiv_batch_ensemble(b, pv, progress, out);
    rpiv_batch_free(b);
    return st;
}

/* ---- a job per pair ------------------------------------------------------------------------- */

rpiv_status rpiv_series_each(size_t n, const rpiv_mpi *mpi, rpiv_series_pair_fn fn, void *user,
                             const rpiv_progress *progress, const char *what)
{
    size_t K = (size_t)rpiv_mpi_size(mpi), first = (size_t)rpiv_mpi_rank(mpi);
    size_t mine = first < n ? n / K + (first < n % K) : 0, done = 0;
    rpiv_status st = RPIV_OK;
    for (size_t i = first; i < n && !st; i += K) {
        st = fn(user, i);
        if (!st && rpiv_progress_report(progress, ++done, mine))
            st = rpiv_fail(RPIV_EINTR, "%s: interrupted after %zu of %zu pairs", what, done, mine);
    }
    return st;
}
