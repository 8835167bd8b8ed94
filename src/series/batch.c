/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/series/batch.c - long runs over a series (rpiv/batch.h): pairs dealt out to a team,
 * skipped when unreadable, and the loops over pairs (ensemble passes, per-pair fields). The
 * numerical work is rpiv_ensemble_add/_finish and rpiv_piv_load/_step; this file decides which
 * pair goes where and when. Checkpoints are in checkpoint.c, the background in background.c,
 * loading pairs and agreeing on the unreadable ones in batch_pairs.c. */
#include "rpiv/batch.h"
#include "rpiv/validate.h"

#include "rpiv/ensemble.h"

#include "base/atomic.h"

#include "mpi_impl.h"
#include "series_impl.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

rpiv_batch_params rpiv_batch_params_default(void)
{
    return (rpiv_batch_params){.checkpoint = NULL, .checkpoint_every = 100};
}

rpiv_status rpiv_batch_params_check(const rpiv_batch_params *p)
{
    if (p->checkpoint && !p->checkpoint[0])
        return rpiv_fail(RPIV_EINVAL, "batch: empty checkpoint file name");
    if (p->resume && !p->checkpoint)
        return rpiv_fail(RPIV_EINVAL, "batch: resume needs a checkpoint file");
    return RPIV_OK;
}

void rpiv_batch_free(rpiv_batch *b)
{
    if (!b)
        return;
    batch_first_free(b);
    free(b->ckpt);
    free(b->state);
    free(b->skipped);
    rpiv_image_free(b->ia);
    rpiv_image_free(b->ib);
    free(b);
}

rpiv_status rpiv_batch_new(const rpiv_pairs *pairs, const rpiv_batch_params *p, const rpiv_mpi *mpi,
                           rpiv_batch **out)
{
    *out = NULL;
    rpiv_batch_params def = rpiv_batch_params_default();
    if (!p)
        p = &def;
    rpiv_status st = rpiv_batch_params_check(p);
    if (st)
        return st;
    if (!pairs->n)
        return rpiv_fail(RPIV_EINVAL, "batch: no image pairs");
    rpiv_batch *b = calloc(1, sizeof *b);
    if (!b)
        return rpiv_fail(RPIV_ENOMEM, "batch: out of memory");
    b->pairs = pairs;
    b->mpi = mpi;
    b->p = *p;
    b->p.checkpoint = NULL; /* not kept: b->ckpt is the copy */
    b->state = calloc(pairs->n, 1);
    if (!b->state)
        goto out_nomem;
    if (p->checkpoint) {
        size_t len = strlen(p->checkpoint) + 32;
        if (!(b->ckpt = malloc(len)))
            goto out_nomem;
        if (rpiv_mpi_size(mpi) > 1)
            snprintf(b->ckpt, len, "%s.rank%d", p->checkpoint, rpiv_mpi_rank(mpi));
        else
            snprintf(b->ckpt, len, "%s", p->checkpoint);
    }
    *out = b;
    return RPIV_OK;
out_nomem:
    rpiv_batch_free(b);
    return rpiv_fail(RPIV_ENOMEM, "batch: out of memory");
}

rpiv_status batch_new_source(const rpiv_series_source *src, const rpiv_piv *pv, rpiv_batch **out)
{
    *out = NULL;
    if (!src->n)
        return rpiv_fail(RPIV_EINVAL, "batch: no image pairs");
    rpiv_batch *b = calloc(1, sizeof *b);
    if (!b)
        return rpiv_fail(RPIV_ENOMEM, "batch: out of memory");
    int w, h;
    rpiv_piv_size(pv, &w, &h);
    b->src = src;
    b->made.n = src->n;
    b->pairs = &b->made;
    b->p = rpiv_batch_params_default();
    rpiv_status st = RPIV_OK;
    if (!(b->state = calloc(src->n, 1)))
        st = rpiv_fail(RPIV_ENOMEM, "batch: out of memory");
    if (st || (st = rpiv_image_new(w, h, &b->ia)) || (st = rpiv_image_new(w, h, &b->ib))) {
        rpiv_batch_free(b);
        return st;
    }
    *out = b;
    return RPIV_OK;
}

size_t rpiv_batch_nskipped(const rpiv_batch *b)
{
    return b->nskipped;
}

size_t rpiv_batch_skipped(const rpiv_batch *b, size_t k)
{
    return b->skipped[k];
}

int rpiv_batch_resumed(const rpiv_batch *b, int *pass, size_t *done)
{
    if (pass)
        *pass = b->resume_pass;
    if (done)
        *done = b->resume_done;
    return b->resumed;
}

size_t rpiv_batch_npairs(const rpiv_batch *b)
{
    return b->npairs_last;
}

int rpiv_batch_repeats(const rpiv_batch *b, double *change)
{
    if (change)
        *change = b->last_change;
    return b->repeats;
}

/* ---- the ensemble run -------------------------------------------------------------------- */

/* Pair i of a source (b->src) into the batch's images, added to e, then the source's hook:
 * the errors are the source's, the accumulator's and the hook's, as they are. */
static rpiv_status add_made(rpiv_batch *b, rpiv_ensemble *e, int pass, size_t i)
{
    const rpiv_series_source *src = b->src;
    rpiv_status st;
    if ((st = src->pair(src->user, i, pass, b->ia, b->ib)) ||
        (st = rpiv_ensemble_add(e, b->ia, b->ib)))
        return st;
    return src->added ? src->added(src->user, pass, i, e) : RPIV_OK;
}

/* Add pair i of a source to e in pass `pass`: RPIV_OK when added or (skip_bad) skipped; else
 * the error. */
static rpiv_status add_pair(rpiv_batch *b, rpiv_ensemble *e, int pass, size_t i, int *added)
{
    rpiv_status st = add_made(b, e, pass, i);
    *added = 0;
    if (!st) {
        b->state[i] |= DONE;
        *added = 1;
    } else if (b->p.skip_bad && batch_unreadable(st)) {
        batch_mark_bad(b, i, 1);
        st = RPIV_OK;
    }
    return st;
}

/* One pass's loop over this rank's pairs, and the bookkeeping after each pair. */
typedef struct pass_run {
    rpiv_batch *b;
    const rpiv_piv *pv;
    rpiv_ensemble *e;
    int pass, stage; /* the plan's pass; the stage: pass, or npass - 1 + its repeat */
    const ck_ident *id;
    int npass;
    const rpiv_progress *progress;
    size_t *done, total, nmine;
    size_t since;  /* pairs added since the last checkpoint */
    int *saved_ok; /* the last checkpoint was written        */
    size_t *idx;   /* run_files: the pairs it adds           */
} pass_run;

/* Pair i was added (added = 1) or skipped: the checkpoint when due, the progress. */
static rpiv_status after_pair(pass_run *c, size_t i, int added)
{
    rpiv_batch *b = c->b;
    rpiv_status st = RPIV_OK;
    c->since += (size_t)added;
    if (b->ckpt && b->p.checkpoint_every && c->since >= b->p.checkpoint_every) {
        *c->saved_ok = !(st = ck_save(b, c->id, c->npass, c->stage - c->pass, c->e));
        c->since = 0;
    }
    if (!st && rpiv_progress_report(c->progress, ++*c->done, c->total))
        st = rpiv_fail(RPIV_EINTR, "ensemble: interrupted in pass %d after %zu of %zu pairs",
                       c->stage + 1, i / (size_t)rpiv_mpi_size(b->mpi) + 1, c->nmine);
    return st;
}

/* A source's pairs (b->src), one at a time: its hook sees the accumulator after each. */
static rpiv_status run_made(pass_run *c)
{
    rpiv_batch *b = c->b;
    size_t N = b->pairs->n, K = (size_t)rpiv_mpi_size(b->mpi);
    rpiv_status st = RPIV_OK;
    for (size_t i = (size_t)rpiv_mpi_rank(b->mpi); i < N && !st; i += K) {
        int added;
        if (b->state[i] & (DONE | BAD))
            continue;
        if (!(st = add_pair(b, c->e, c->pass, i, &added)))
            st = after_pair(c, i, added);
    }
    return st;
}

static rpiv_status files_load(void *user, size_t k, rpiv_image **a, rpiv_image **bb)
{
    const pass_run *c = user;
    int w, h;
    rpiv_piv_size(c->pv, &w, &h);
    return batch_load_pair(c->b, c->idx[k], w, h, a, bb);
}

static rpiv_status files_done(void *user, size_t k, rpiv_status st, int loaded)
{
    pass_run *c = user;
    rpiv_batch *b = c->b;
    size_t i = c->idx[k];
    if (st && loaded)
        st = batch_pair_error(b, i, st);
    if (!st)
        b->state[i] |= DONE;
    else if (b->p.skip_bad && batch_unreadable(st))
        batch_mark_bad(b, i, 1);
    else
        return st;
    return after_pair(c, i, !st);
}

/* The listed pairs: several at a time when the images are small (rpiv_ensemble_add_pairs),
 * added in the order of the list. */
static rpiv_status run_files(pass_run *c)
{
    rpiv_batch *b = c->b;
    size_t N = b->pairs->n, K = (size_t)rpiv_mpi_size(b->mpi), n = 0;
    size_t *idx = malloc((N / K + 1) * sizeof *idx);
    if (!idx)
        return rpiv_fail(RPIV_ENOMEM, "batch: out of memory");
    for (size_t i = (size_t)rpiv_mpi_rank(b->mpi); i < N; i += K)
        if (!(b->state[i] & (DONE | BAD)))
            idx[n++] = i;
    c->idx = idx;
    rpiv_status st = rpiv_ensemble_add_pairs(c->e, n, files_load, files_done, c);
    c->idx = NULL;
    free(idx);
    return st;
}

/* The pass is complete on every rank: combine the sums, locate the peaks. Collective. */
static rpiv_status finish_pass(rpiv_batch *b, rpiv_ensemble *e, int pass, rpiv_field **f)
{
    size_t n, np = rpiv_ensemble_npairs(e);
    float *data = rpiv_ensemble_data(e, &n);
    rpiv_status st;
    if ((st = batch_sync_bad(b)) || (st = mpi_sum_floats(b->mpi, data, n)) ||
        (st = mpi_sum_size(b->mpi, &np)))
        return st;
    rpiv_ensemble_set_npairs(e, np);
    b->npairs_last = np;
    if (!np)
        return rpiv_fail(RPIV_EIO, "ensemble pass %d: none of the %zu pairs could be read",
                         pass + 1, b->pairs->n);
    return rpiv_mpi_agree(b->mpi, rpiv_ensemble_finish(e, f));
}

rpiv_status rpiv_batch_ensemble(rpiv_batch *b, rpiv_piv *pv, const rpiv_progress *progress,
                                rpiv_field **out)
{
    *out = NULL;
    const rpiv_mpi *m = b->mpi;
    size_t N = b->pairs->n, K = (size_t)rpiv_mpi_size(m), r = (size_t)rpiv_mpi_rank(m);
    int npass = rpiv_piv_npass(pv), pass0 = 0, saved_ok = 1;
    rpiv_field *pred = NULL;
    rpiv_ensemble *e = NULL;
    rpiv_status st = RPIV_OK;
    ck_ident id;
    char user_path[4096] = "";
    if (b->ckpt) {
        ck_ident_of(b, pv, &id);
        snprintf(user_path, sizeof user_path, "%s", b->ckpt);
        if (K > 1)
            *strrchr(user_path, '.') = '\0';
    }
    for (size_t i = 0; i < N; i++)
        b->state[i] &= BAD;
    b->resumed = 0;
    b->repeats = 0;
    b->last_change = -1;
    if (b->ckpt) {
        atomic_remove_stale(b->ckpt);
        /* an interrupted run's checkpoint is not overwritten by a new run by mistake */
        if (!b->p.resume && ck_exists(b->ckpt))
            st = rpiv_fail(RPIV_EINVAL,
                           "%s: a checkpoint is already there: continue it (rpiv piv "
                           "--resume) or remove it to start again",
                           b->ckpt);
        if ((st = rpiv_mpi_agree(m, st)))
            return st;
    }
    if (b->ckpt && b->p.resume && (st = ck_resume(b, pv, &id, user_path, &pass0, &pred, &e)))
        return st;
    size_t nmine = 0, done = 0;
    for (size_t i = r; i < N; i += K) {
        nmine++;
        done += (b->state[i] & (DONE | BAD)) != 0;
    }
    /* stage k: the plan's pass k, then (ensemble_refine) repeats of its last pass while
     * rpiv_ensemble_again says so; the progress's total grows by a pass with each repeat */
    size_t total = nmine * (size_t)(pass0 < npass ? npass : pass0 + 1);
    done += nmine * (size_t)pass0;
    for (int k = pass0, more = 1; more; k++) {
        const int pass = k < npass ? k : npass - 1;
        if (!e) {
            for (size_t i = 0; i < N; i++)
                b->state[i] &= BAD;
            if (!(st = rpiv_ensemble_new(pv, pass, pred, &e)) && b->ckpt)
                saved_ok = !(st = ck_save(b, &id, npass, k - pass, e));
        }
        if ((st = rpiv_mpi_agree(m, st)))
            break;
        pass_run run = {b,        pv,    e,     pass,  k, &id,       npass,
                        progress, &done, total, nmine, 0, &saved_ok, NULL};
        st = b->src ? run_made(&run) : run_files(&run);
        if ((st = rpiv_mpi_agree(m, st))) {
            if (b->ckpt && saved_ok)
                st = ck_stop(b, &id, npass, k - pass, e, st);
            break;
        }
        rpiv_field *f = NULL;
        st = finish_pass(b, e, k, &f);
        rpiv_ensemble_free(e);
        e = NULL;
        /* the same decision on every rank: the fields are the reduced sums' */
        more = !st && (k < npass - 1 || rpiv_ensemble_again(pv, pred, f, k - pass));
        if (!st && k >= npass - 1) {
            b->repeats = k - pass;
            b->last_change = rpiv_ensemble_change(pred, f);
        }
        if (more && k >= npass - 1)
            total += nmine;
        rpiv_field_free(pred);
        pred = f;
        if (st)
            break;
    }
    rpiv_ensemble_free(e);
    if (st) {
        rpiv_field_free(pred);
        return st;
    }
    /* optional smoothing of the final field (off by default), as for a pair's field */
    double s = rpiv_piv_params_of(pv)->smooth;
    if (s > 0 && (st = rpiv_validate_smooth(pred, s))) {
        rpiv_field_free(pred);
        return st;
    }
    if (b->ckpt)
        remove(b->ckpt); /* the run is complete: nothing to resume */
    *out = pred;
    return RPIV_OK;
}

/* ---- per-pair fields --------------------------------------------------------------------- */

/* Process pair i: *f its field, NULL if skipped. The images are freed as soon as the plan
 * holds them (rpiv_piv_load), so memory holds the plan's frames only; then every pass runs,
 * as in rpiv_piv_run. */
static rpiv_status run_pair(rpiv_batch *b, rpiv_piv *pv, size_t i, rpiv_field **f)
{
    rpiv_image *a = NULL, *bb = NULL;
    rpiv_field *prev = NULL;
    int w, h_px;
    *f = NULL;
    rpiv_piv_size(pv, &w, &h_px);
    rpiv_status st = batch_load_pair(b, i, w, h_px, &a, &bb);
    if (!st) {
        st = rpiv_piv_load(pv, a, bb);
        rpiv_image_free(a);
        rpiv_image_free(bb);
        if (!st)
            st = rpiv_piv_passes(pv, &prev, NULL);
        if (st) {
            st = batch_pair_error(b, i, st);
            rpiv_field_free(prev);
            prev = NULL;
        }
    }
    *f = prev;
    if (st && b->p.skip_bad && batch_unreadable(st)) {
        batch_mark_bad(b, i, 1);
        st = RPIV_OK;
    }
    return st;
}

/* A team of one: the readable pairs through rpiv_piv_run_pairs (small frames a pair per
 * thread), the sinks called in pair order as the loop below calls them. */
typedef struct solo_ctx {
    rpiv_batch *b;
    const size_t *idx; /* the pairs to do */
    int w, h;
    rpiv_series_sink local, root;
    void *user;
    const rpiv_progress *progress;
    size_t done, n;
} solo_ctx;

static rpiv_status solo_load(void *user, size_t k, rpiv_image **a, rpiv_image **bb)
{
    const solo_ctx *c = user;
    return batch_load_pair(c->b, c->idx[k], c->w, c->h, a, bb);
}

static rpiv_status solo_done(void *user, size_t k, rpiv_status st, int loaded, rpiv_field *f)
{
    solo_ctx *c = user;
    rpiv_batch *b = c->b;
    size_t i = c->idx[k];
    if (st == RPIV_EINTR) /* the plan's cancel hook, inside the pair: not done */
        return rpiv_fail(RPIV_EINTR, "piv: interrupted after %zu of %zu pairs", c->done, c->n);
    if (st && loaded)
        st = batch_pair_error(b, i, st);
    if (st && b->p.skip_bad && batch_unreadable(st)) {
        batch_mark_bad(b, i, 1);
        st = RPIV_OK;
    }
    if (!st && f && c->local)
        st = c->local(c->user, i, f);
    if (!st && f && c->root)
        st = c->root(c->user, i, f);
    rpiv_field_free(f);
    if (!st && rpiv_progress_report(c->progress, ++c->done, c->n))
        st = rpiv_fail(RPIV_EINTR, "piv: interrupted after %zu of %zu pairs", c->done, c->n);
    return st;
}

static rpiv_status series_solo(rpiv_batch *b, rpiv_piv *pv, rpiv_series_sink local,
                               rpiv_series_sink root, void *user, const rpiv_progress *progress)
{
    size_t N = b->pairs->n, n = 0;
    size_t *idx = malloc((N ? N : 1) * sizeof *idx);
    if (!idx)
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory");
    for (size_t i = 0; i < N; i++)
        if (!(b->state[i] & BAD))
            idx[n++] = i;
    solo_ctx c = {b, idx, 0, 0, local, root, user, progress, N - n, N};
    rpiv_piv_size(pv, &c.w, &c.h);
    rpiv_status st = rpiv_piv_run_pairs(pv, n, solo_load, solo_done, &c);
    free(idx);
    rpiv_status ss = batch_sync_bad(b);
    return st ? st : ss;
}

rpiv_status rpiv_batch_series(rpiv_batch *b, rpiv_piv *pv, rpiv_series_sink local,
                              rpiv_series_sink root, void *user, const rpiv_progress *progress)
{
    const rpiv_mpi *m = b->mpi;
    if (rpiv_mpi_size(m) == 1)
        return series_solo(b, pv, local, root, user, progress);
    size_t N = b->pairs->n, K = (size_t)rpiv_mpi_size(m), r = (size_t)rpiv_mpi_rank(m);
    size_t nmine = N / K + (r < N % K), done = 0;
    rpiv_field *grid = NULL, **all = calloc(K, sizeof *all);
    rpiv_status st = all ? RPIV_OK : rpiv_fail(RPIV_ENOMEM, "piv: out of memory");
    if (!st && root && K > 1)
        st = rpiv_piv_grid(pv, rpiv_piv_npass(pv) - 1, &grid);
    st = rpiv_mpi_agree(m, st);
    for (size_t j = 0; !st && j * K < N; j++) {
        size_t i = j * K + r;
        rpiv_field *f = NULL;
        if (i < N && !(b->state[i] & BAD)) {
            if (!(st = run_pair(b, pv, i, &f)) && f && local)
                st = local(user, i, f);
            if (st == RPIV_EINTR) /* the plan's cancel hook, inside the pair: not done */
                st = rpiv_fail(RPIV_EINTR, "piv: interrupted after %zu of %zu pairs", done, nmine);
            if (!st && K == 1 && f && root)
                st = root(user, i, f);
        }
        if (!st && i < N && rpiv_progress_report(progress, ++done, nmine))
            st = rpiv_fail(RPIV_EINTR, "piv: interrupted after %zu of %zu pairs", done, nmine);
        st = rpiv_mpi_agree(m, st);
        if (!st && root && K > 1) {
            st = mpi_gather_fields(m, f, grid, all);
            for (size_t q = 0; q < K; q++) {
                if (!st && all[q])
                    st = root(user, j * K + q, all[q]);
                rpiv_field_free(all[q]);
                all[q] = NULL;
            }
            st = rpiv_mpi_agree(m, st);
        }
        rpiv_field_free(f);
    }
    rpiv_status ss = batch_sync_bad(b);
    rpiv_field_free(grid);
    free(all);
    return st ? st : ss;
}
