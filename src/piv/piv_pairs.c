/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/piv_pairs.c - the fields of many pairs (rpiv_piv_run_pairs): small frames a pair per
 * thread (pair_pool.h), large ones one after another with the plan's threads inside. Each
 * field is what rpiv_piv_load + rpiv_piv_passes give on the plan, whose results do not depend
 * on its thread count, so the fields have the same bits either way. */
#include "pair_pool.h"

#include <stdio.h>
#include <stdlib.h>

typedef struct field_slot {
    rpiv_status st;
    int loaded;     /* the pair was loaded: an error came from the passes */
    char msg[1024]; /* its message                                        */
    rpiv_field *f;  /* its field, until taken                             */
} field_slot;

typedef struct pairs_ctx {
    rpiv_piv_load_fn load;
    rpiv_piv_done_fn done;
    void *user;
    field_slot *slots;
    int give; /* one pair: its frames are given to the plan (load_given) */
} pairs_ctx;

/* rpiv_piv_load of a pair freed next: without background or preprocessing the images' pixel
 * buffers become the plan's frames and the plan's go to the images, swapped instead of
 * copied (rpiv_piv_load then skips the copy onto itself): 44 MB of copy and first touches
 * saved on a 2560 x 2160 pair (issue 15). The same frames and fills. */
static rpiv_status load_given(rpiv_piv *pv, rpiv_image *a, rpiv_image *b)
{
    if (pv->prep || pv->bga || a->w != pv->w || a->h != pv->h || b->w != pv->w || b->h != pv->h)
        return rpiv_piv_load(pv, a, b);
    float *t = pv->ia;
    pv->ia = a->px;
    a->px = t;
    t = pv->ib;
    pv->ib = b->px;
    b->px = t;
    rpiv_image fa = {pv->w, pv->h, a->bits, pv->ia}, fb = {pv->w, pv->h, b->bits, pv->ib};
    return rpiv_piv_load(pv, &fa, &fb);
}

/* Load pair k and run every pass on plan c: *f its field or NULL, *loaded as for done. */
static rpiv_status one_pair(const pairs_ctx *c, rpiv_piv *plan, size_t k, rpiv_field **f,
                            int *loaded)
{
    rpiv_image *a = NULL, *b = NULL;
    *f = NULL;
    *loaded = 0;
    rpiv_status st = c->load(c->user, k, &a, &b);
    if (!st) {
        *loaded = 1;
        st = c->give ? load_given(plan, a, b) : rpiv_piv_load(plan, a, b);
    }
    rpiv_image_free(a);
    rpiv_image_free(b);
    if (!st)
        st = rpiv_piv_passes(plan, f, NULL);
    return st;
}

static void fill(void *ctx, rpiv_piv *plan, size_t k, size_t slot)
{
    pairs_ctx *c = ctx;
    field_slot *s = &c->slots[slot];
    s->st = one_pair(c, plan, k, &s->f, &s->loaded);
    if (s->st)
        snprintf(s->msg, sizeof s->msg, "%s", rpiv_errmsg());
}

static rpiv_status take(void *ctx, size_t k, size_t slot)
{
    pairs_ctx *c = ctx;
    field_slot *s = &c->slots[slot];
    rpiv_field *f = s->f;
    s->f = NULL;
    if (s->st)
        (void)rpiv_fail(s->st, "%s", s->msg);
    return c->done(c->user, k, s->st, s->loaded, f);
}

rpiv_status rpiv_piv_run_pairs(rpiv_piv *pv, size_t n, rpiv_piv_load_fn load, rpiv_piv_done_fn done,
                               void *user)
{
    pairs_ctx c = {load, done, user, NULL, n == 1};
    /* a slot holds one field: nx ny (u, v, peak ratio, correlation, flag) */
    const piv_pass *last = &pv->pass[pv->npass - 1];
    size_t m = pool_slots(pv, n, (double)last->nwin * 4 * sizeof(float) * 2, 0);
    if (m && !(c.slots = calloc(m, sizeof *c.slots)))
        m = 0;
    if (!m) { /* one pair after another, the plan's threads inside each */
        rpiv_status st = RPIV_OK;
        for (size_t k = 0; k < n && !st; k++) {
            rpiv_field *f = NULL;
            int loaded;
            rpiv_status ps = one_pair(&c, pv, k, &f, &loaded);
            st = done(user, k, ps, loaded, f);
        }
        return st;
    }
    pool_job job = {n, m, fill, take, &c};
    rpiv_status st = pool_run(pv, &job);
    for (size_t j = 0; j < m; j++)
        rpiv_field_free(c.slots[j].f);
    free(c.slots);
    return st;
}
