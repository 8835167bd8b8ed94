/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/series/batch_pairs.c - the batch's pairs: loading one (at the series' frame size),
 * marking the unreadable ones and agreeing on them across the ranks of a team. The loops
 * (batch.c), the checkpoints (checkpoint.c) and the background (background.c) build on it. */
#include "rpiv/batch.h"

#include "mpi_impl.h"
#include "series_impl.h"

#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- unreadable pairs -------------------------------------------------------------------- */

int batch_unreadable(rpiv_status st)
{
    return st == RPIV_EIO || st == RPIV_EFORMAT || st == RPIV_ESIZE;
}

/* Pair i could not be read (the message is current): mark it and tell the caller. */
void batch_mark_bad(rpiv_batch *b, size_t i, int notify)
{
    b->state[i] |= BAD;
    if (notify && b->p.on_skip)
        b->p.on_skip(b->p.user, i, rpiv_errmsg());
}

rpiv_status batch_pair_error(const rpiv_batch *b, size_t i, rpiv_status st)
{
    char msg[768];
    snprintf(msg, sizeof msg, "%s", rpiv_errmsg());
    return rpiv_fail(st, "pair %zu (%s): %s", i + 1, b->pairs->pair[i].path_a, msg);
}

/* Load pair i; frames of another size than w x h (w > 0) are an error naming the pair. */
rpiv_status batch_load_pair(const rpiv_batch *b, size_t i, int w, int h, rpiv_image **a,
                            rpiv_image **bb)
{
    rpiv_status st = RPIV_OK;
    rpiv_image *fa = NULL;
    if (b->first && b->first->i == i && (fa = atomic_exchange(&b->first->a, NULL))) {
        *a = fa;
        *bb = b->first->b;
        b->first->b = NULL;
    } else {
        st = rpiv_pairs_load(b->pairs, i, a, bb);
    }
    if (!st && w > 0 && ((*a)->w != w || (*a)->h != h)) {
        st = rpiv_fail(RPIV_ESIZE, "pair %zu of %zu: %s: %dx%d frames, the series' are %dx%d",
                       i + 1, b->pairs->n, b->pairs->pair[i].path_a, (*a)->w, (*a)->h, w, h);
        rpiv_image_free(*a);
        rpiv_image_free(*bb);
        *a = *bb = NULL;
    }
    return st;
}

/* Merge the BAD marks of all ranks and rebuild the list of skipped pairs. Collective. */
rpiv_status batch_sync_bad(rpiv_batch *b)
{
    size_t n = b->pairs->n, k = 0;
    unsigned char *bad = malloc(n);
    rpiv_status st =
        rpiv_mpi_agree(b->mpi, bad ? RPIV_OK : rpiv_fail(RPIV_ENOMEM, "batch: out of memory"));
    if (st)
        goto out_free;
    for (size_t i = 0; i < n; i++)
        bad[i] = b->state[i] & BAD;
    if ((st = mpi_max_bytes(b->mpi, bad, n)))
        goto out_free;
    for (size_t i = 0; i < n; i++) {
        b->state[i] = (unsigned char)((b->state[i] & DONE) | bad[i]);
        k += bad[i] != 0;
    }
    size_t *list = k ? malloc(k * sizeof *list) : NULL;
    if ((st = rpiv_mpi_agree(b->mpi, k && !list ? rpiv_fail(RPIV_ENOMEM, "batch: out of memory")
                                                : RPIV_OK))) {
        free(list);
        goto out_free;
    }
    free(b->skipped);
    b->skipped = list;
    b->nskipped = k;
    for (size_t i = 0, j = 0; i < n; i++)
        if (bad[i])
            list[j++] = i;
out_free:
    free(bad);
    return st;
}

/* Keep pair i's frames (taking them from *a, *bb) for the first batch_load_pair of i, if this
 * rank processes that pair; keep their statistics in any case. */
static void batch_keep_first(rpiv_batch *b, size_t i, rpiv_image **a, rpiv_image **bb)
{
    batch_first_free(b);
    batch_first *f = calloc(1, sizeof *f);
    if (!f)
        return; /* only a lost shortcut: the pair is read again */
    f->i = i;
    f->sa = rpiv_image_stats_of(*a);
    f->sb = rpiv_image_stats_of(*bb);
    f->have_stats = 1;
    atomic_init(&f->a, NULL);
    if (rpiv_mpi_mine(b->mpi, i) && !(b->state[i] & DONE)) {
        atomic_store(&f->a, *a);
        f->b = *bb;
        *a = *bb = NULL;
    }
    b->first = f;
}

void batch_first_free(rpiv_batch *b)
{
    if (!b->first)
        return;
    rpiv_image_free(atomic_exchange(&b->first->a, NULL));
    rpiv_image_free(b->first->b);
    free(b->first);
    b->first = NULL;
}

int rpiv_batch_first_stats(const rpiv_batch *b, size_t *i, rpiv_image_stats *sa,
                           rpiv_image_stats *sb)
{
    if (!b->first || !b->first->have_stats)
        return 0;
    *i = b->first->i;
    *sa = b->first->sa;
    *sb = b->first->sb;
    return 1;
}

rpiv_status rpiv_batch_size(rpiv_batch *b, int *w, int *h)
{
    rpiv_status st = RPIV_OK;
    *w = *h = 0;
    for (size_t i = 0; i < b->pairs->n && !*w && !st; i++) {
        rpiv_image *a = NULL, *bb = NULL;
        if (b->state[i] & BAD)
            continue;
        if (!(st = rpiv_pairs_load(b->pairs, i, &a, &bb))) {
            *w = a->w;
            *h = a->h;
            batch_keep_first(b, i, &a, &bb);
        } else if (b->p.skip_bad && batch_unreadable(st)) {
            batch_mark_bad(b, i, rpiv_mpi_mine(b->mpi, i));
            st = RPIV_OK;
        }
        rpiv_image_free(a);
        rpiv_image_free(bb);
    }
    if (!st && !*w)
        st = rpiv_fail(RPIV_EIO, "none of the %zu pairs can be read", b->pairs->n);
    st = rpiv_mpi_agree(b->mpi, st);
    rpiv_status ss = batch_sync_bad(b);
    return st ? st : ss;
}
