/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/pair_pool.c - many small pairs, a pair per thread: the ring of slots and its workers
 * (pair_pool.h). */
#include "pair_pool.h"

#include <stdlib.h>
#include <string.h>
#include <threads.h>

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
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory for a copy of the plan");
    }
    *out = c;
    return RPIV_OK;
}

size_t pool_slots(const rpiv_piv *pv, size_t n, double slot_bytes, double held_bytes)
{
    const int nt = pv->nthreads;
    size_t m = (size_t)POOL_PER_THREAD * (size_t)nt;
    m = m < n ? m : n;
    const double budget = pv->p.max_mem_mb * 1048576.0 - ((double)pv->bytes + held_bytes);
#define ROUND_BYTES(m) ((double)(m)*slot_bytes + (double)nt * (double)pv->bytes)
    while (m > (size_t)nt && ROUND_BYTES(m) > budget)
        m--;
    if (nt < 2 || n < 2 || (double)pv->w * (double)pv->h > POOL_MAX_PX || ROUND_BYTES(m) > budget ||
        ROUND_BYTES(m) > POOL_MAX_MB * 1048576.0)
        return 0;
#undef ROUND_BYTES
    return m;
}

/* The workers and the calling thread share the ring: pair k goes into slot k % m once pair
 * k - m has been taken. Everyone waits on a condition variable (asleep, not spinning: on a
 * busy machine a spinning thread takes the core the thread it waits for needs). */
typedef struct ring {
    const pool_job *job;
    unsigned char *ready; /* m flags: slot holds its pair's result */
    size_t next;          /* next pair a worker takes              */
    size_t taken;         /* pairs taken so far                    */
    int stop;             /* the calling thread stopped the run    */
    mtx_t mu;
    cnd_t cv;
} ring;

typedef struct worker {
    ring *r;
    rpiv_piv *plan; /* its one-thread copy */
} worker;

static int worker_main(void *arg)
{
    worker *w = arg;
    ring *r = w->r;
    const pool_job *job = r->job;
    mtx_lock(&r->mu);
    for (;;) {
        while (!r->stop && r->next < job->n && r->next >= r->taken + job->m)
            cnd_wait(&r->cv, &r->mu);
        if (r->stop || r->next >= job->n)
            break;
        size_t k = r->next++;
        mtx_unlock(&r->mu);
        job->fill(job->ctx, w->plan, k, k % job->m);
        mtx_lock(&r->mu);
        r->ready[k % job->m] = 1;
        cnd_broadcast(&r->cv);
    }
    mtx_unlock(&r->mu);
    return 0;
}

rpiv_status pool_run(const rpiv_piv *pv, const pool_job *job)
{
    const int nt = pv->nthreads;
    rpiv_status st = RPIV_OK;
    ring r = {.job = job};
    worker *ws = calloc((size_t)nt, sizeof *ws);
    thrd_t *th = calloc((size_t)nt, sizeof *th);
    r.ready = calloc(job->m, 1);
    int started = 0, sync = 0;
    if (!ws || !th || !r.ready) {
        st = rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the pair slots");
        goto out_free;
    }
    for (int t = 0; t < nt; t++) {
        ws[t].r = &r;
        if ((st = plan_copy(pv, &ws[t].plan)))
            goto out_free;
    }
    if (mtx_init(&r.mu, mtx_plain) != thrd_success || cnd_init(&r.cv) != thrd_success) {
        st = rpiv_fail(RPIV_ENOMEM, "piv: cannot make the workers' lock");
        goto out_free;
    }
    sync = 1;
    for (; started < nt; started++)
        if (thrd_create(&th[started], worker_main, &ws[started]) != thrd_success)
            break;
    if (!started) {
        st = rpiv_fail(RPIV_ENOMEM, "piv: cannot start a worker thread");
        goto out_free;
    }
    for (size_t k = 0; k < job->n && !st; k++) {
        mtx_lock(&r.mu);
        while (!r.ready[k % job->m])
            cnd_wait(&r.cv, &r.mu);
        mtx_unlock(&r.mu);
        st = job->take(job->ctx, k, k % job->m);
        mtx_lock(&r.mu);
        r.ready[k % job->m] = 0;
        r.taken = k + 1;
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
    free(r.ready);
    for (int t = 0; ws && t < nt; t++)
        rpiv_piv_free(ws[t].plan);
    free(ws);
    free(th);
    return st;
}
