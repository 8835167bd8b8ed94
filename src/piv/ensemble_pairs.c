/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/ensemble_pairs.c - adding many pairs to an accumulator (rpiv_ensemble_add_pairs):
 * small images a pair per thread, large ones one after another with the threads inside.
 *
 * Why: a pair of small frames (256 x 256) is a few milliseconds of work cut into some thirty
 * parallel regions (loading, prefilter, deformation strips, correlation); at two threads the
 * workers spent more time spinning and yielding at the regions' ends than working (600 pairs:
 * 1.5 s on one thread, 6.2 s on two, 54 s on two of a busy machine, issue 20 item 6). Here
 * the threads of the plan each take whole pairs, on their own one-thread copy of the plan
 * (C11 threads, not OpenMP: they sleep on a condition variable when they wait, never spin).
 *
 * Determinism: each pair's planes and energies go into a slot of the round; the slots are
 * then added to the sums in pair order on the calling thread, the very float additions
 * rpiv_ensemble_add makes, so the sums have the same bits for any thread count. */
#include "ensemble_impl.h"
#include "piv_impl.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <threads.h>

/* Frames of at most this many pixels are correlated a pair per thread (docs/benchmarks.md,
 * "Threads on small images and busy machines": at 1024 x 1024 a pair per thread still beats
 * the threads inside each pair; at 2560 x 2160 the slots would take 87 MB each). */
#define PAIRS_MAX_PX (1500 * 1000)
/* Slots per thread: pairs done ahead of the one being added. */
#define ROUND_PER_THREAD 4
/* Memory the slots and plan copies may take, MB, besides piv.max_mem_mb's check. */
#define PAIRS_MAX_MB 256.0

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
            ens_unc_add(e, win, s->unc + win * ENS_UNC_SUMS);
    }
    e->npairs++;
}

/* A one-thread copy of plan pv (its mask, masked windows and backgrounds copied). */
static rpiv_status plan_copy(const rpiv_piv *pv, rpiv_piv **out)
{
    rpiv_piv_params p = pv->p;
    p.threads = 1;
    p.max_mem_mb = 1e9; /* counted by the caller */
    rpiv_piv *c = NULL;
    rpiv_status st = rpiv_piv_new(&p, pv->w, pv->h, NULL, &c);
    if (st)
        return st;
    const size_t n = (size_t)pv->w * (size_t)pv->h;
    int bad = 0;
    if (pv->mask) {
        bad |= !(c->mask = malloc(n));
        if (c->mask)
            memcpy(c->mask, pv->mask, n);
        for (int k = 0; k < pv->npass; k++) {
            const size_t nw = pv->pass[k].nwin;
            bad |= !(c->pass[k].masked = malloc(nw));
            if (c->pass[k].masked)
                memcpy(c->pass[k].masked, pv->pass[k].masked, nw);
        }
    }
    if (pv->bga) {
        bad |= !(c->bga = malloc(n * sizeof *c->bga)) || !(c->bgb = malloc(n * sizeof *c->bgb));
        if (!bad) {
            memcpy(c->bga, pv->bga, n * sizeof *c->bga);
            memcpy(c->bgb, pv->bgb, n * sizeof *c->bgb);
        }
    }
    if (bad) {
        rpiv_piv_free(c);
        return rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory for a copy of the plan");
    }
    *out = c;
    return RPIV_OK;
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

/* Bytes m slots and nt plan copies take. */
static double round_bytes(const rpiv_ensemble *e, int nt, size_t m)
{
    const double slot = (double)e->nwin * ((double)e->plane * sizeof(float) + 2 * sizeof(double));
    return (double)m * slot + (double)nt * (double)e->pv->bytes;
}

/* The workers and the calling thread share a ring of slots: pair k goes into slot k % m once
 * pair k - m has been added. Everyone waits on a condition variable (asleep, not spinning:
 * on a busy machine a spinning thread takes the core the thread it waits for needs). */
typedef struct ring {
    rpiv_ensemble *e;
    rpiv_ensemble_load_fn load;
    void *user;
    size_t n, m;
    pair_slot *slots;
    unsigned char *ready; /* m flags: slot holds its pair's result */
    size_t next;          /* next pair a worker takes              */
    size_t added;         /* pairs added so far                    */
    int stop;             /* the calling thread stopped the run    */
    mtx_t mu;
    cnd_t cv;
} ring;

typedef struct worker {
    ring *r;
    rpiv_piv *plan; /* its one-thread copy */
} worker;

/* Load and correlate pair k into slot s with plan c. */
static void slot_fill(ring *r, rpiv_piv *c, pair_slot *s, size_t k)
{
    rpiv_image *a = NULL, *b = NULL;
    s->loaded = 0;
    s->st = r->load(r->user, k, &a, &b);
    if (!s->st) {
        s->loaded = 1;
        slot_ctx sc = {r->e, s};
        if (!(s->st = rpiv_piv_load(c, a, b)))
            s->st = piv_pass_run(c, r->e->pass, r->e->pred, slot_plane, &sc);
    }
    if (s->st)
        snprintf(s->msg, sizeof s->msg, "%s", rpiv_errmsg());
    rpiv_image_free(a);
    rpiv_image_free(b);
}

static int worker_main(void *arg)
{
    worker *w = arg;
    ring *r = w->r;
    mtx_lock(&r->mu);
    for (;;) {
        while (!r->stop && r->next < r->n && r->next >= r->added + r->m)
            cnd_wait(&r->cv, &r->mu);
        if (r->stop || r->next >= r->n)
            break;
        size_t k = r->next++;
        mtx_unlock(&r->mu);
        slot_fill(r, w->plan, &r->slots[k % r->m], k);
        mtx_lock(&r->mu);
        r->ready[k % r->m] = 1;
        cnd_broadcast(&r->cv);
    }
    mtx_unlock(&r->mu);
    return 0;
}

rpiv_status rpiv_ensemble_add_pairs(rpiv_ensemble *e, size_t n, rpiv_ensemble_load_fn load,
                                    rpiv_ensemble_done_fn done, void *user)
{
    const rpiv_piv *pv = e->pv;
    const int nt = pv->nthreads;
    size_t m = (size_t)ROUND_PER_THREAD * (size_t)nt;
    m = m < n ? m : n;
    /* what the run holds already, and what the slots and copies would add */
    const double held = (double)pv->bytes + (double)e->n * sizeof(float);
    const double budget = pv->p.max_mem_mb * 1048576.0 - held;
    while (m > (size_t)nt && round_bytes(e, nt, m) > budget)
        m--;
    if (nt < 2 || n < 2 || (double)pv->w * (double)pv->h > PAIRS_MAX_PX ||
        round_bytes(e, nt, m) > budget || round_bytes(e, nt, m) > PAIRS_MAX_MB * 1048576.0)
        return add_serial(e, n, load, done, user);

    rpiv_status st = RPIV_OK;
    ring r = {.e = e, .load = load, .user = user, .n = n, .m = m};
    worker *ws = calloc((size_t)nt, sizeof *ws);
    thrd_t *th = calloc((size_t)nt, sizeof *th);
    r.slots = calloc(m, sizeof *r.slots);
    r.ready = calloc(m, 1);
    int started = 0, sync = 0;
    if (!ws || !th || !r.slots || !r.ready) {
        st = rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory for the pair slots");
        goto out_free;
    }
    for (int t = 0; t < nt; t++) {
        ws[t].r = &r;
        if ((st = plan_copy(pv, &ws[t].plan)))
            goto out_free;
    }
    for (size_t j = 0; j < m; j++) {
        r.slots[j].planes = malloc(e->nwin * e->plane * sizeof *r.slots[j].planes);
        r.slots[j].energy = calloc(2 * e->nwin, sizeof *r.slots[j].energy);
        if (e->scratch) {
            r.slots[j].unc = malloc(e->nwin * ENS_UNC_SUMS * sizeof *r.slots[j].unc);
            r.slots[j].scratch = malloc(2 * e->plane * sizeof *r.slots[j].scratch);
        }
        if (!r.slots[j].planes || !r.slots[j].energy ||
            (e->scratch && (!r.slots[j].unc || !r.slots[j].scratch))) {
            st = rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory for the pair slots");
            goto out_free;
        }
    }
    if (mtx_init(&r.mu, mtx_plain) != thrd_success || cnd_init(&r.cv) != thrd_success) {
        st = rpiv_fail(RPIV_ENOMEM, "ensemble: cannot make the workers' lock");
        goto out_free;
    }
    sync = 1;
    for (; started < nt; started++)
        if (thrd_create(&th[started], worker_main, &ws[started]) != thrd_success)
            break;
    if (!started) {
        st = rpiv_fail(RPIV_ENOMEM, "ensemble: cannot start a worker thread");
        goto out_free;
    }
    for (size_t k = 0; k < n && !st; k++) {
        pair_slot *s = &r.slots[k % m];
        mtx_lock(&r.mu);
        while (!r.ready[k % m])
            cnd_wait(&r.cv, &r.mu);
        mtx_unlock(&r.mu);
        rpiv_status ps = s->st;
        if (!ps)
            slot_add(e, s);
        else
            (void)rpiv_fail(ps, "%s", s->msg);
        st = done(user, k, ps, s->loaded);
        mtx_lock(&r.mu);
        r.ready[k % m] = 0;
        r.added = k + 1;
        r.stop = st != RPIV_OK;
        cnd_broadcast(&r.cv);
        mtx_unlock(&r.mu);
    }
out_free:
    if (sync) {
        mtx_lock(&r.mu);
        r.stop = 1;
        cnd_broadcast(&r.cv);
        mtx_unlock(&r.mu);
    }
    for (int t = 0; t < started; t++)
        thrd_join(th[t], NULL);
    if (sync) {
        cnd_destroy(&r.cv);
        mtx_destroy(&r.mu);
    }
    for (size_t j = 0; r.slots && j < m; j++) {
        free(r.slots[j].planes);
        free(r.slots[j].energy);
        free(r.slots[j].unc);
        free(r.slots[j].scratch);
    }
    free(r.slots);
    free(r.ready);
    for (int t = 0; ws && t < nt; t++)
        rpiv_piv_free(ws[t].plan);
    free(ws);
    free(th);
    return st;
}
