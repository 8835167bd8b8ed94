/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/series/checkpoint.c - the batch's checkpoints (rpiv/batch.h): what identifies a run,
 * the identity block a rank's checkpoint carries, and resuming from the ranks' files. The file
 * itself (header, predictor, sums, checksum, atomic writing) is the accumulator's:
 * rpiv_ensemble_save_block / rpiv_ensemble_load_new (rpiv/ensemble.h). */
#include "series_impl.h"

#include "base/hash.h"
#include "mpi_impl.h"

#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* The batch's block in a checkpoint: the rank, the run's identity (ck_ident), the repeat of the
 * final pass the sums are (ensemble_refine; 0 for a listed pass, and in the files of the
 * versions before it, where this was padding), then one state byte per pair (DONE: summed in
 * the checkpoint's pass; BAD: unreadable). */
typedef struct ck_block {
    int32_t rank, nranks, npass, repeat;
    uint64_t npairs, series_hash, plan_hash;
    char series[256], plan[768];
} ck_block;

void ck_ident_of(const rpiv_batch *b, const rpiv_piv *pv, ck_ident *id)
{
    const rpiv_pairs *pp = b->pairs;
    const rpiv_piv_params *p = rpiv_piv_params_of(pv);
    int w, h_px;
    rpiv_piv_size(pv, &w, &h_px);
    memset(id, 0, sizeof *id);
    uint64_t h = hash_bytes(HASH0, &pp->n, sizeof pp->n);
    for (size_t i = 0; i < pp->n; i++) {
        h = hash_bytes(h, pp->pair[i].path_a, strlen(pp->pair[i].path_a) + 1);
        if (pp->pair[i].path_b)
            h = hash_bytes(h, pp->pair[i].path_b, strlen(pp->pair[i].path_b) + 1);
        h = hash_bytes(h, "|", 1);
    }
    id->series_hash = h;
    /* each path's last 110 characters at most, so that the description (256 bytes) always
     * shows where the two ends differ */
    const char *first = pp->pair[0].path_a, *last = pp->pair[pp->n - 1].path_a;
    size_t lf = strlen(first), ll = strlen(last);
    snprintf(id->series, sizeof id->series, "%zu pairs, %s%s ... %s%s", pp->n,
             lf > 110 ? "..." : "", first + (lf > 110 ? lf - 110 : 0), ll > 110 ? "..." : "",
             last + (ll > 110 ? ll - 110 : 0));
    char win[256] = "";
    for (int k = 0; k < p->npass; k++)
        snprintf(win + strlen(win), sizeof win - strlen(win), "%s%dx%d", k ? "," : "", p->win_w[k],
                 p->win_h[k]);
    snprintf(id->plan, sizeof id->plan,
             "%dx%d frames, windows %.100s, overlap %.15g, step %d px, subpixel %s, median %.15g "
             "(eps %.15g px), deform %d, background %s, roi %d,%d,%d,%d, mask %.300s",
             w, h_px, win, p->overlap, p->step_px, rpiv_subpixel_names[p->subpixel], p->median_thr,
             p->median_eps, p->deform, rpiv_background_names[p->background], p->roi[0], p->roi[1],
             p->roi[2], p->roi[3], p->mask[0] ? p->mask : "none");
    /* the predictor's continuation beyond the grid shapes the sums (named when not 0, the
     * continuation of the versions before session 13, whose checkpoints then resume only
     * with edge_curvature 0; -1 is the default since) */
    if (p->edge_curvature)
        snprintf(id->plan + strlen(id->plan), sizeof id->plan - strlen(id->plan),
                 ", edge curvature %d", p->edge_curvature);
    /* the refinement denoiser's finest detail: named when it is not that of the versions
     * before session 13 (the second difference), whose checkpoints then resume only with it */
    if (p->refine_denoise && p->refine_denoise_order != 2)
        snprintf(id->plan + strlen(id->plan), sizeof id->plan - strlen(id->plan),
                 ", denoise order %d", p->refine_denoise_order);
    /* the deformation's samples only where their B-spline taps are pixels (session 15,
     * deform_takes: the edge windows' sums differ): checkpoints of the versions before it,
     * whose plan does not say so, are refused as another plan */
    if (p->deform)
        snprintf(id->plan + strlen(id->plan), sizeof id->plan - strlen(id->plan),
                 ", samples in [1, w - 2]");
    /* the final size's predictor notched instead of denoised (the sums differ) */
    if (!p->ensemble_denoise)
        snprintf(id->plan + strlen(id->plan), sizeof id->plan - strlen(id->plan),
                 ", ensemble denoise 0");
    /* the final pass's repeats (their count decides where the run stops) */
    if (p->ensemble_refine)
        snprintf(id->plan + strlen(id->plan), sizeof id->plan - strlen(id->plan),
                 ", ensemble refine %d (tol %.6g px)", p->ensemble_refine,
                 p->ensemble_refine_tol_px);
    double exact[3] = {p->overlap, p->median_thr, p->median_eps};
    h = hash_bytes(HASH0, id->plan, strlen(id->plan));
    h = hash_bytes(h, exact, sizeof exact);
    if (p->ensemble_refine) /* the tolerance itself, not its 6 digits */
        h = hash_bytes(h, &p->ensemble_refine_tol_px, sizeof p->ensemble_refine_tol_px);
    id->plan_hash = rpiv_piv_hash_frames(pv, h);
}

rpiv_status ck_save(const rpiv_batch *b, const ck_ident *id, int npass, int repeat,
                    const rpiv_ensemble *e)
{
    size_t n = b->pairs->n;
    unsigned char *buf = malloc(sizeof(ck_block) + n);
    if (!buf)
        return rpiv_fail(RPIV_ENOMEM, "checkpoint: out of memory");
    ck_block bk;
    memset(&bk, 0, sizeof bk);
    bk.rank = rpiv_mpi_rank(b->mpi);
    bk.nranks = rpiv_mpi_size(b->mpi);
    bk.npass = npass;
    bk.repeat = repeat;
    bk.npairs = n;
    bk.series_hash = id->series_hash;
    bk.plan_hash = id->plan_hash;
    memcpy(bk.series, id->series, sizeof bk.series);
    memcpy(bk.plan, id->plan, sizeof bk.plan);
    memcpy(buf, &bk, sizeof bk);
    memcpy(buf + sizeof bk, b->state, n);
    rpiv_status st = rpiv_ensemble_save_block(e, buf, sizeof bk + n, b->ckpt);
    free(buf);
    return st;
}

/* Is there a file at path? */
int ck_exists(const char *path)
{
    return access(path, F_OK) == 0;
}

/* A missing checkpoint: fine (*found = 0), unless the other team size's file is there. */
static rpiv_status ck_missing(const rpiv_batch *b, const char *user_path)
{
    char other[4200];
    if (rpiv_mpi_size(b->mpi) > 1) {
        if (ck_exists(user_path))
            return rpiv_fail(RPIV_EFORMAT,
                             "%s: checkpoint of a one-process run; this run has "
                             "%d ranks (resume it without mpirun)",
                             user_path, rpiv_mpi_size(b->mpi));
        return RPIV_OK;
    }
    snprintf(other, sizeof other, "%s.rank0", user_path);
    if (ck_exists(other))
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: no such checkpoint, but %s is one of a run with "
                         "several MPI ranks (resume it with the same mpirun -np)",
                         user_path, other);
    return RPIV_OK;
}

/* What check_block compares a checkpoint's block with. */
typedef struct ck_want {
    rpiv_batch *b;
    const rpiv_piv *pv;
    const ck_ident *id;
    int repeat; /* out: the block's repeat of the final pass */
} ck_want;

/* The block of this rank's checkpoint (rpiv_ensemble_block_fn): refuse one of another rank,
 * series or plan, naming what differs; else take the pair states. */
static rpiv_status check_block(void *user, const void *block, size_t nblock)
{
    ck_want *cw = user;
    rpiv_batch *b = cw->b;
    const char *path = b->ckpt;
    int K = rpiv_mpi_size(b->mpi), r = rpiv_mpi_rank(b->mpi);
    ck_block hd;
    if (nblock < sizeof hd)
        return rpiv_fail(RPIV_EFORMAT, "%s: corrupt checkpoint (identity block)", path);
    memcpy(&hd, block, sizeof hd);
    hd.series[sizeof hd.series - 1] = hd.plan[sizeof hd.plan - 1] = '\0';
    if (hd.nranks != K || hd.rank != r)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: checkpoint of rank %d of a %d-rank run; this is rank "
                         "%d of %d (resume with mpirun -np %d)",
                         path, hd.rank, hd.nranks, r, K, hd.nranks);
    if (hd.npairs != b->pairs->n || hd.series_hash != cw->id->series_hash)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: checkpoint of another series of pairs (%s); this "
                         "run has %s%s",
                         path, hd.series, cw->id->series,
                         strcmp(hd.series, cw->id->series)
                             ? ""
                             : ": the same count, first and last pair, another pair or order in "
                               "between (or another second frame)");
    if (hd.plan_hash != cw->id->plan_hash || hd.npass != rpiv_piv_npass(cw->pv))
        return rpiv_fail(RPIV_EFORMAT, "%s: checkpoint of another plan (%s); this run: %s%s", path,
                         hd.plan, cw->id->plan,
                         strcmp(hd.plan, cw->id->plan) ? ""
                                                       : " (the mask or background frames differ)");
    if (nblock != sizeof hd + b->pairs->n || hd.repeat < 0 ||
        hd.repeat > rpiv_piv_params_of(cw->pv)->ensemble_refine)
        return rpiv_fail(RPIV_EFORMAT, "%s: corrupt checkpoint (identity block)", path);
    cw->repeat = hd.repeat;
    memcpy(b->state, (const unsigned char *)block + sizeof hd, b->pairs->n);
    return RPIV_OK;
}

/* Read this rank's checkpoint: *found = 0 if there is none; else its pass, predictor (NULL in
 * pass 0), an accumulator holding its sums, and the pair states. */
static rpiv_status ck_load(rpiv_batch *b, rpiv_piv *pv, const ck_ident *id, const char *user_path,
                           int *found, int *pass, rpiv_field **pred, rpiv_ensemble **e)
{
    *found = 0;
    *pred = NULL;
    *e = NULL;
    if (access(b->ckpt, F_OK) != 0 && errno == ENOENT)
        return ck_missing(b, user_path);
    ck_want cw = {b, pv, id, 0};
    rpiv_status st = rpiv_ensemble_load_new(pv, b->ckpt, check_block, &cw, e);
    if (!st) {
        const rpiv_field *p = rpiv_ensemble_predictor(*e);
        *pass = rpiv_ensemble_pass(*e) + cw.repeat; /* the stage */
        if ((p != NULL) != (*pass > 0) ||
            (cw.repeat && rpiv_ensemble_pass(*e) != rpiv_piv_npass(pv) - 1))
            st = rpiv_fail(RPIV_EFORMAT, "%s: corrupt checkpoint (pass %d of %d)", b->ckpt,
                           *pass + 1, rpiv_piv_npass(pv));
        else if (p)
            st = rpiv_field_copy(p, pred);
    }
    if (st) {
        rpiv_ensemble_free(*e);
        *e = NULL;
        memset(b->state, 0, b->pairs->n);
        return st;
    }
    for (size_t i = 0; i < b->pairs->n; i++)
        b->state[i] &= DONE | BAD;
    *found = 1;
    return RPIV_OK;
}

/* Resume from the ranks' checkpoints (collective): *pass0 the pass to continue, *pred its
 * predictor and *e this rank's sums (NULL if this rank starts the pass afresh). */
rpiv_status ck_resume(rpiv_batch *b, rpiv_piv *pv, const ck_ident *id, const char *user_path,
                      int *pass0, rpiv_field **pred, rpiv_ensemble **e)
{
    const rpiv_mpi *m = b->mpi;
    int found = 0, pass = -1, r = rpiv_mpi_rank(m), K = rpiv_mpi_size(m);
    rpiv_status st = ck_load(b, pv, id, user_path, &found, &pass, pred, e);
    if ((st = rpiv_mpi_agree(m, st)))
        goto out_fail;
    long top = found ? pass : -1, holder;
    if ((st = mpi_max_long(m, &top)))
        goto out_fail;
    if (top < 0)
        return RPIV_OK; /* no checkpoint anywhere: begin */
    if (!found && top > 0)
        st = rpiv_fail(RPIV_EFORMAT,
                       "%s: missing, while the other ranks' checkpoints are in "
                       "pass %ld",
                       b->ckpt, top + 1);
    if ((st = rpiv_mpi_agree(m, st)))
        goto out_fail;
    /* a rank one pass behind (killed before it saved the new pass) starts that pass afresh
     * with the predictor of the lowest rank that has it */
    holder = found && pass == top ? -(long)r : -(long)K;
    if ((st = mpi_max_long(m, &holder)))
        goto out_fail;
    holder = -holder;
    if (found && pass < top) {
        rpiv_ensemble_free(*e);
        *e = NULL;
        for (size_t i = 0; i < b->pairs->n; i++)
            b->state[i] &= BAD;
    }
    if (r != holder) {
        rpiv_field_free(*pred);
        *pred = NULL;
    }
    if (top > 0 && (st = mpi_bcast_field(m, (int)holder, pred)))
        goto out_fail;
    size_t done = *e ? rpiv_ensemble_npairs(*e) : 0;
    if ((st = mpi_sum_size(m, &done)) || (st = batch_sync_bad(b)))
        goto out_fail;
    b->resumed = 1;
    b->resume_pass = (int)top;
    b->resume_done = done;
    *pass0 = (int)top;
    return RPIV_OK;
out_fail:
    rpiv_ensemble_free(*e);
    rpiv_field_free(*pred);
    *e = NULL;
    *pred = NULL;
    return st;
}

/* A failed run keeps its checkpoint: save the state and say so after the message. */
rpiv_status ck_stop(const rpiv_batch *b, const ck_ident *id, int npass, int repeat,
                    const rpiv_ensemble *e, rpiv_status st)
{
    char msg[1024];
    snprintf(msg, sizeof msg, "%s", rpiv_errmsg());
    rpiv_status cs = ck_save(b, id, npass, repeat, e);
    if (cs) {
        char cmsg[512];
        snprintf(cmsg, sizeof cmsg, "%s", rpiv_errmsg());
        return rpiv_fail(st, "%s (and the checkpoint: %s)", msg, cmsg);
    }
    return rpiv_fail(st,
                     "%s; checkpoint %s saved (pass %d, %zu pair%s summed there by this "
                     "process)",
                     msg, b->ckpt, rpiv_ensemble_pass(e) + repeat + 1, rpiv_ensemble_npairs(e),
                     rpiv_ensemble_npairs(e) == 1 ? "" : "s");
}
