/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/ensemble_pairs.c - adding many pairs to an accumulator (rpiv_ensemble_add_pairs):
 * small images a pair per thread, large ones one after another with the threads inside.
 *
 * Why: a pair of small frames (256 x 256) is a few milliseconds of work cut into some thirty
 * parallel regions (loading, prefilter, deformation strips, correlation); at two threads the
 * workers spent more time spinning and yielding at the regions' ends than working (600 pairs:
 * 1.5 s on one thread, 6.2 s on two, 54 s on two of a busy machine, issue 20 item 6). Here
 * the threads of the plan each take whole pairs, on their own one-thread copy of the plan
 * (the pool of pair_pool.h: C11 threads, asleep on a condition variable when they wait).
 *
 * Determinism: each pair's planes and energies go into a slot of the round; the slots are
 * then added to the sums in pair order on the calling thread, the very float additions
 * rpiv_ensemble_add makes, so the sums have the same bits for any thread count. */
#include "ensemble_impl.h"
#include "pair_pool.h"
#include "piv_impl.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct pair_slot {
    rpiv_status st;
    int loaded;     /* the pair was loaded: an error came from the correlation */
    char msg[1024]; /* its message                                              */
    float *planes;  /* nwin planes                                              */
    double *energy; /* 2 nwin energies                                          */
    double *unc;    /* with the uncertainty: ENS_UNC_SUMS per window, else NULL */
    float *scratch; /* with the uncertainty: two planes                        */
} pair_slot;

typedef struct slot_ctx {
    const rpiv_ensemble *e;
    pair_slot *s;
} slot_ctx;

static void slot_plane(void *ctx, const float *plane, const float *colmax, size_t win, double ea,
                       double eb, double pu, double pv_, const rpiv_xcorr_src *xs)
{
    slot_ctx *c = ctx;
    (void)colmax;
    (void)pu;
    (void)pv_;
    if (c->s->unc)
        ens_unc_pair(c->e, plane, xs, c->s->scratch, c->s->unc + win * ENS_UNC_SUMS);
    memcpy(c->s->planes + win * c->e->plane, plane, c->e->plane * sizeof *plane);
    c->s->energy[2 * win] = ea;
    c->s->energy[2 * win + 1] = eb;
}

/* The slot's planes and energies added to the sums, as add_plane (ensemble.c) does. */
static void slot_add(rpiv_ensemble *e, const pair_slot *s)
{
    const piv_pass *ps = &e->pv->pass[e->pass];
    float *energy = e->data + e->nwin * e->plane;
    for (size_t win = 0; win < e->nwin; win++) {
        if (ps->masked && ps->masked[win])
            continue;
        float *restrict sum = e->data + win * e->plane;
        const float *restrict p = s->planes + win * e->plane;
        for (size_t i = 0; i < e->plane; i++)
            sum[i] += p[i];
        energy[2 * win] += (float)s->energy[2 * win];
        energy[2 * win + 1] += (float)s->energy[2 * win + 1];
        if (s->unc)
            ens_unc_add(e, win, s->unc + win * ENS_UNC_SUMS, p);
    }
    e->npairs++;
}

/* One pair after another, the plan's threads inside each. */
static rpiv_status add_serial(rpiv_ensemble *e, size_t n, rpiv_ensemble_load_fn load,
                              rpiv_ensemble_done_fn done, void *user)
{
    rpiv_status st = RPIV_OK;
    for (size_t k = 0; k < n && !st; k++) {
        rpiv_image *a = NULL, *b = NULL;
        int loaded = 0;
        rpiv_status ps = load(user, k, &a, &b);
        if (!ps) {
            loaded = 1;
            ps = rpiv_ensemble_add(e, a, b);
        }
        rpiv_image_free(a);
        rpiv_image_free(b);
        st = done(user, k, ps, loaded);
    }
    return st;
}

typedef struct ens_ctx {
    rpiv_ensemble *e;
    rpiv_ensemble_load_fn load;
    rpiv_ensemble_done_fn done;
    void *user;
    pair_slot *slots;
} ens_ctx;

/* On a worker: load and correlate pair k into its slot with the worker's plan. */
static void ens_fill(void *ctx, rpiv_piv *plan, size_t k, size_t slot)
{
    ens_ctx *c = ctx;
    pair_slot *s = &c->slots[slot];
    rpiv_image *a = NULL, *b = NULL;
    s->loaded = 0;
    s->st = c->load(c->user, k, &a, &b);
    if (!s->st) {
        s->loaded = 1;
        slot_ctx sc = {c->e, s};
        if (!(s->st = rpiv_piv_load(plan, a, b)))
            s->st = piv_pass_run(plan, c->e->pass, c->e->pred, slot_plane, &sc);
    }
    if (s->st)
        snprintf(s->msg, sizeof s->msg, "%s", rpiv_errmsg());
    rpiv_image_free(a);
    rpiv_image_free(b);
}

/* On the calling thread, in pair order: the slot added to the sums. */
static rpiv_status ens_take(void *ctx, size_t k, size_t slot)
{
    ens_ctx *c = ctx;
    pair_slot *s = &c->slots[slot];
    rpiv_status ps = s->st;
    if (!ps)
        slot_add(c->e, s);
    else
        (void)rpiv_fail(ps, "%s", s->msg);
    return c->done(c->user, k, ps, s->loaded);
}

rpiv_status rpiv_ensemble_add_pairs(rpiv_ensemble *e, size_t n, rpiv_ensemble_load_fn load,
                                    rpiv_ensemble_done_fn done, void *user)
{
    /* a slot: the planes and energies of every window (and the uncertainty's sums) */
    const double slot = (double)e->nwin * ((double)e->plane * sizeof(float) + 2 * sizeof(double));
    const size_t m = pool_slots(e->pv, n, slot, (double)e->n * sizeof(float));
    if (!m)
        return add_serial(e, n, load, done, user);
    ens_ctx c = {e, load, done, user, calloc(m, sizeof(pair_slot))};
    rpiv_status st =
        c.slots ? RPIV_OK : rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory for the pair slots");
    for (size_t j = 0; !st && j < m; j++) {
        pair_slot *s = &c.slots[j];
        s->planes = malloc(e->nwin * e->plane * sizeof *s->planes);
        s->energy = calloc(2 * e->nwin, sizeof *s->energy);
        if (e->scratch) {
            s->unc = malloc(e->nwin * ENS_UNC_SUMS * sizeof *s->unc);
            s->scratch = malloc(2 * e->plane * sizeof *s->scratch);
        }
        if (!s->planes || !s->energy || (e->scratch && (!s->unc || !s->scratch)))
            st = rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory for the pair slots");
    }
    if (!st) {
        pool_job job = {n, m, ens_fill, ens_take, &c};
        st = pool_run(e->pv, &job);
    }
    for (size_t j = 0; c.slots && j < m; j++) {
        free(c.slots[j].planes);
        free(c.slots[j].energy);
        free(c.slots[j].unc);
        free(c.slots[j].scratch);
    }
    free(c.slots);
    return st;
}
