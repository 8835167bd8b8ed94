/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/series/background.c - the background of a series: streamed over a list of pairs in one
 * process (rpiv_series_background), and over a team's shares, with unreadable pairs found and
 * left out (rpiv_batch_background). */
#include "rpiv/series.h"

#include "mpi_impl.h"
#include "series_impl.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

rpiv_status rpiv_series_background(const rpiv_pairs *pairs, rpiv_background kind,
                                   const rpiv_progress *progress, rpiv_image **bg_a,
                                   rpiv_image **bg_b)
{
    *bg_a = *bg_b = NULL;
    if (kind != RPIV_BACKGROUND_MIN && kind != RPIV_BACKGROUND_MEAN)
        return rpiv_fail(RPIV_EINVAL, "piv.background: no background kind chosen");
    if (!pairs->n)
        return rpiv_fail(RPIV_EINVAL, "piv.background: no image pairs");
    rpiv_image *ga = NULL, *gb = NULL;
    double *sum = NULL;
    rpiv_status st = RPIV_OK;
    size_t n = 0;
    for (size_t i = 0; i < pairs->n && !st; i++) {
        rpiv_image *a = NULL, *b = NULL;
        if ((st = rpiv_pairs_load(pairs, i, &a, &b)))
            break;
        if (!ga) {
            n = (size_t)a->w * (size_t)a->h;
            if ((st = rpiv_image_copy(a, &ga)) || (st = rpiv_image_copy(b, &gb)))
                goto next;
            if (kind == RPIV_BACKGROUND_MEAN) {
                sum = calloc(2 * n, sizeof *sum);
                if (!sum) {
                    st = rpiv_fail(RPIV_ENOMEM, "piv.background: out of memory");
                    goto next;
                }
            }
        } else if (a->w != ga->w || a->h != ga->h) {
            st = rpiv_fail(RPIV_ESIZE,
                           "pair %zu (%s): %dx%d frames, the series' first pair "
                           "has %dx%d",
                           i + 1, pairs->pair[i].path_a, a->w, a->h, ga->w, ga->h);
            goto next;
        }
        if (kind == RPIV_BACKGROUND_MEAN) {
            for (size_t k = 0; k < n; k++) {
                sum[k] += (double)a->px[k];
                sum[n + k] += (double)b->px[k];
            }
        } else {
            for (size_t k = 0; k < n; k++) {
                ga->px[k] = fminf(ga->px[k], a->px[k]);
                gb->px[k] = fminf(gb->px[k], b->px[k]);
            }
        }
        if (rpiv_progress_report(progress, i + 1, pairs->n))
            st = rpiv_fail(RPIV_EINTR, "piv.background: interrupted after %zu of %zu pairs", i + 1,
                           pairs->n);
    next:
        rpiv_image_free(a);
        rpiv_image_free(b);
    }
    if (!st && kind == RPIV_BACKGROUND_MEAN)
        for (size_t k = 0; k < n; k++) {
            ga->px[k] = (float)(sum[k] / (double)pairs->n);
            gb->px[k] = (float)(sum[n + k] / (double)pairs->n);
        }
    free(sum);
    if (st) {
        rpiv_image_free(ga);
        rpiv_image_free(gb);
        return st;
    }
    *bg_a = ga;
    *bg_b = gb;
    return RPIV_OK;
}

/* ---- background -------------------------------------------------------------------------- */

/* This rank's readable pairs as a list borrowing the paths of b->pairs (not to be freed with
 * rpiv_pairs_free), with their indices in idx. */
static rpiv_status share_of(const rpiv_batch *b, rpiv_pairs *view, size_t *idx)
{
    view->n = 0;
    for (size_t i = 0; i < b->pairs->n; i++)
        if (rpiv_mpi_mine(b->mpi, i) && !(b->state[i] & BAD)) {
            view->pair[view->n] = b->pairs->pair[i];
            idx[view->n++] = i;
        }
    return RPIV_OK;
}

/* After rpiv_series_background failed on a view with `st` (message current): find the first pair
 * of the view that cannot be read. Returns its position, or view->n if every pair reads (then
 * the original failure stands); *err is the pair's own failure (message current). */
static size_t find_bad(const rpiv_batch *b, const rpiv_pairs *view, const size_t *idx, int w, int h,
                       rpiv_status *err)
{
    char keep[1024];
    rpiv_status orig = *err;
    snprintf(keep, sizeof keep, "%s", rpiv_errmsg());
    for (size_t j = 0; j < view->n; j++) {
        rpiv_image *a = NULL, *bb = NULL;
        rpiv_status st = batch_load_pair(b, idx[j], w, h, &a, &bb);
        rpiv_image_free(a);
        rpiv_image_free(bb);
        if (st) {
            *err = st;
            return j;
        }
    }
    *err = rpiv_fail(orig, "%s", keep);
    return view->n;
}

/* Combine the ranks' backgrounds of n_r pairs each (ga, gb: this rank's, NULL if n_r = 0). */
static rpiv_status combine_background(rpiv_batch *b, rpiv_background kind, int w, int h, size_t nr,
                                      rpiv_image **ga, rpiv_image **gb)
{
    size_t total = nr, n = (size_t)w * (size_t)h;
    rpiv_status st = mpi_sum_size(b->mpi, &total);
    if (!st && !total)
        st = rpiv_fail(RPIV_EIO, "piv.background: none of the %zu pairs can be read", b->pairs->n);
    if (st)
        return st;
    rpiv_image **g[2] = {ga, gb};
    double *sum = kind == RPIV_BACKGROUND_MEAN ? malloc(n * sizeof *sum) : NULL;
    for (int f = 0; f < 2 && !st; f++) /* a rank without pairs: the neutral element */
        if (!*g[f] && !(st = rpiv_image_new(w, h, g[f])) && kind == RPIV_BACKGROUND_MIN)
            for (size_t k = 0; k < n; k++)
                (*g[f])->px[k] = INFINITY;
    if (!st && kind == RPIV_BACKGROUND_MEAN && !sum)
        st = rpiv_fail(RPIV_ENOMEM, "piv.background: out of memory");
    if ((st = rpiv_mpi_agree(b->mpi, st)))
        goto out_free;
    for (int f = 0; f < 2 && !st; f++) {
        float *px = (*g[f])->px;
        if (kind == RPIV_BACKGROUND_MIN) {
            st = mpi_min_floats(b->mpi, px, n);
            continue;
        }
        for (size_t k = 0; k < n; k++)
            sum[k] = nr ? (double)px[k] * (double)nr : 0.0;
        if (!(st = mpi_sum_doubles(b->mpi, sum, n)))
            for (size_t k = 0; k < n; k++)
                px[k] = (float)(sum[k] / (double)total);
    }
out_free:
    free(sum);
    return st;
}

rpiv_status rpiv_batch_background(rpiv_batch *b, rpiv_background kind, int w, int h,
                                  const rpiv_progress *progress, rpiv_image **bg_a,
                                  rpiv_image **bg_b)
{
    *bg_a = *bg_b = NULL;
    rpiv_pairs view = {0};
    size_t *idx = malloc(b->pairs->n * sizeof *idx);
    view.pair = malloc(b->pairs->n * sizeof *view.pair);
    rpiv_image *ga = NULL, *gb = NULL;
    rpiv_status st = RPIV_OK;
    if (!idx || !view.pair) {
        st = rpiv_fail(RPIV_ENOMEM, "piv.background: out of memory");
        goto out_agree;
    }
    if ((st = share_of(b, &view, idx)))
        goto out_agree;
    while (view.n) {
        if (!(st = rpiv_series_background(&view, kind, progress, &ga, &gb)) ||
            !batch_unreadable(st))
            break;
        size_t j = find_bad(b, &view, idx, w, h, &st);
        if (j == view.n || !b->p.skip_bad)
            break;
        batch_mark_bad(b, idx[j], 1);
        memmove(view.pair + j, view.pair + j + 1, (view.n - j - 1) * sizeof *view.pair);
        memmove(idx + j, idx + j + 1, (view.n - j - 1) * sizeof *idx);
        view.n--;
        st = RPIV_OK;
    }
    if (!st && rpiv_mpi_size(b->mpi) == 1 && !view.n)
        st = rpiv_fail(RPIV_EIO, "piv.background: none of the %zu pairs can be read", b->pairs->n);
out_agree:
    st = rpiv_mpi_agree(b->mpi, st);
    if (!st)
        st = batch_sync_bad(b);
    if (!st && rpiv_mpi_size(b->mpi) > 1)
        st = combine_background(b, kind, w, h, view.n, &ga, &gb);
    free(idx);
    free(view.pair);
    if (st) {
        rpiv_image_free(ga);
        rpiv_image_free(gb);
        return st;
    }
    *bg_a = ga;
    *bg_b = gb;
    return RPIV_OK;
}
