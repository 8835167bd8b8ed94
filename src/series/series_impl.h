/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/series/series_impl.h - what the files of the series module share: the batch's state
 * (batch.c: dealing, skipping, the loops), its checkpoints (checkpoint.c) and its background
 * (background.c). */
#ifndef RPIV_SERIES_IMPL_H
#define RPIV_SERIES_IMPL_H

#include "rpiv/batch.h"
#include "rpiv/ensemble.h"

#include <stdatomic.h>

#include <stddef.h>
#include <stdint.h>

enum { DONE = 1, BAD = 2 }; /* per-pair state bits: added in this pass; unreadable */

/* The frames of the pair rpiv_batch_size read (pair i), handed to the first batch_load_pair of
 * that pair instead of reading the files again (the first of several threads to ask takes
 * them; the others read the files), and their statistics. */
typedef struct batch_first {
    size_t i;
    _Atomic(rpiv_image *) a; /* frame A, or NULL once taken */
    rpiv_image *b;           /* frame B, owned with a        */
    rpiv_image_stats sa, sb;
    int have_stats;
} batch_first;

struct rpiv_batch {
    const rpiv_pairs *pairs;       /* the files, or &made for a source                   */
    const rpiv_series_source *src; /* pairs made in memory (rpiv/series.h), or NULL     */
    rpiv_pairs made;               /* {src->n, NULL} for a source                       */
    rpiv_image *ia, *ib;           /* a source's pair, reused for every pair            */
    const rpiv_mpi *mpi;
    rpiv_batch_params p;
    char *ckpt;           /* this rank's checkpoint path, NULL = none         */
    unsigned char *state; /* pairs->n entries                                 */
    size_t *skipped, nskipped;
    int resumed, resume_pass;
    size_t resume_done, npairs_last;
    int repeats;        /* the last ensemble run's repeats of its final pass     */
    double last_change; /* and the RMS change of its last pass of the final size */
    batch_first *first; /* the pair rpiv_batch_size read, kept for its first use */
};

/* ---- batch.c, batch_pairs.c: making a batch, unreadable pairs
 * ------------------------------------------------------------ */

/* A batch of this process alone over the pairs of a source, with default parameters (no
 * checkpoint, no skipping), for rpiv_batch_ensemble only; its two images have pv's size. */
RPIV_NODISCARD rpiv_status batch_new_source(const rpiv_series_source *src, const rpiv_piv *pv,
                                            rpiv_batch **out);
/* The failures that make a pair unreadable (skipped with skip_bad). */
int batch_unreadable(rpiv_status st);
/* Pair i could not be read (the message is current): mark it and tell the caller. */
void batch_mark_bad(rpiv_batch *b, size_t i, int notify);
/* Load pair i; frames of another size than w x h (w > 0) are an error naming the pair. */
RPIV_NODISCARD rpiv_status batch_load_pair(const rpiv_batch *b, size_t i, int w, int h,
                                           rpiv_image **a, rpiv_image **bb);
/* The current error st of pair i's processing, its message prefixed by the pair's number and
 * first file: "pair N (FILE): message". Returns st. */
rpiv_status batch_pair_error(const rpiv_batch *b, size_t i, rpiv_status st);
/* Release the pair kept by rpiv_batch_size, if any. */
void batch_first_free(rpiv_batch *b);
/* Merge the BAD marks of all ranks and rebuild the list of skipped pairs. Collective. */
RPIV_NODISCARD rpiv_status batch_sync_bad(rpiv_batch *b);

/* ---- checkpoint.c ------------------------------------------------------------------------- */

/* What ties a checkpoint to its run: the series and the plan, as text (for messages) and as
 * a hash (the plan's also covers the mask and background frames). */
typedef struct ck_ident {
    char series[256], plan[768];
    uint64_t series_hash, plan_hash;
} ck_ident;

/* The identity of the run of plan pv over b's pairs. */
void ck_ident_of(const rpiv_batch *b, const rpiv_piv *pv, ck_ident *id);
/* Write this rank's state to its checkpoint b->ckpt: the identity block (the rank, id, npass,
 * the repeat of the final pass e is, 0 for a listed pass, the pair states) and the accumulator
 * e (its pass, predictor, sums and their pair count), in the accumulator's file format
 * (rpiv_ensemble_save_block). */
RPIV_NODISCARD rpiv_status ck_save(const rpiv_batch *b, const ck_ident *id, int npass, int repeat,
                                   const rpiv_ensemble *e);
/* Is there a file at path? */
int ck_exists(const char *path);
/* Resume from the ranks' checkpoints (collective): *pass0 the stage to continue (the pass, or
 * npass - 1 plus the repeat of the final pass), *pred its
 * predictor and *e this rank's sums (NULL if this rank starts the pass afresh). */
RPIV_NODISCARD rpiv_status ck_resume(rpiv_batch *b, rpiv_piv *pv, const ck_ident *id,
                                     const char *user_path, int *pass0, rpiv_field **pred,
                                     rpiv_ensemble **e);
/* A failed run keeps its checkpoint: save the state (ck_save) and say so after the message of
 * st, which is returned. */
RPIV_NODISCARD rpiv_status ck_stop(const rpiv_batch *b, const ck_ident *id, int npass, int repeat,
                                   const rpiv_ensemble *e, rpiv_status st);

#endif /* RPIV_SERIES_IMPL_H */
