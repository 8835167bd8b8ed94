/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/batch.h - long runs over a series of pairs: dealt out to the ranks of a team
 * (rpiv/mpi.h), crash-safe through checkpoints, and tolerant of unreadable pairs.
 *
 * A batch holds a pair list, its parameters and a team. The same batch serves the steps of a
 * run in turn: the frame size (rpiv_batch_size), the background (rpiv_batch_background), then
 * the ensemble (rpiv_batch_ensemble) or the per-pair fields (rpiv_batch_series). Pair i
 * (0-based) is processed by rank i % K of K; a team of one does every pair, in order.
 *
 * Results. Per pair, a field does not depend on the rank that made it, so per-pair fields and
 * their mean and RMS are identical for any K. The ensemble sums are float (rpiv/ensemble.h):
 * each rank adds its pairs in order, and the K partial sums are added in double at rank 0,
 * rounded once to float and broadcast, so every rank finishes the pass on the same sums and
 * a run is reproducible for a given K. A K-rank sum groups the additions differently from a
 * single process, so it agrees with it to float rounding, not to the bit: a few float ulps of
 * the displacement (measured: at most 6e-7 px on 2.3 px shifts, 1e-6 px on 6 px ones;
 * tests/cli/mpi.sh fails above 1e-6 px; docs/cluster.md).
 *
 * Checkpoints (ensemble only). With params.checkpoint = FILE, every rank writes its state to
 * FILE (one process) or FILE.rank<r> (K > 1): the pass, its predictor (the field of the
 * previous pass), the float sums of the pairs it added in this pass, which pairs are done and
 * which were skipped, and what identifies the series and the plan, in the accumulator's
 * checkpoint format (rpiv_ensemble_save_block, rpiv/ensemble.h). It is written atomically
 * (temporary file in the same folder, fsync, rename, fsync of the folder) at the start of
 * every pass, after every params.checkpoint_every pairs the rank added, and when the run
 * stops on an error or a stop request; a finished run removes it. With params.resume the
 * run continues from it and ends with the same field, to the bit, as a run that was never
 * interrupted (the pairs are added in the same order); a checkpoint of another series, plan
 * or number of ranks is refused, naming what differs. No checkpoint at all: the run starts
 * from the beginning (rpiv_batch_resumed says so). Without resume, an existing checkpoint
 * file is not overwritten: RPIV_EINVAL. Temporary files of a killed save are removed.
 *
 * Unreadable pairs. A pair whose images cannot be read or do not have the series' size is
 * reported with its index and file. With params.skip_bad it is left out of every step and
 * listed (rpiv_batch_skipped); params.on_skip is called once for it, on the rank that found
 * it. Without skip_bad the run stops with that error (a checkpoint, if any, is kept). */
#ifndef RPIV_BATCH_H
#define RPIV_BATCH_H

#include "rpiv/error.h"
#include "rpiv/field.h"
#include "rpiv/image.h"
#include "rpiv/mpi.h"
#include "rpiv/piv.h"
#include "rpiv/progress.h"
#include "rpiv/series.h"

#include <stddef.h>

/* Called on the rank that found unreadable pair `index` (0-based); msg names file and pair. */
typedef void (*rpiv_batch_skip_fn)(void *user, size_t index, const char *msg);

typedef struct rpiv_batch_params {
    const char *checkpoint;     /* checkpoint file, NULL = none (copied)                     */
    size_t checkpoint_every;    /* pairs added by a rank between checkpoints; 0 = only at
                                   pass starts and on stopping (100)                         */
    int resume;                 /* 1: continue from the checkpoint (0)                        */
    int skip_bad;               /* 1: skip and list unreadable pairs; 0: stop on them (0)     */
    rpiv_batch_skip_fn on_skip; /* NULL = not called                                       */
    void *user;                 /* for on_skip                                             */
} rpiv_batch_params;

rpiv_batch_params rpiv_batch_params_default(void);
/* RPIV_EINVAL for resume without a checkpoint file, or an empty file name. */
RPIV_NODISCARD rpiv_status rpiv_batch_params_check(const rpiv_batch_params *p);

typedef struct rpiv_batch rpiv_batch;

/* A batch over `pairs` for team `mpi` (NULL: this process alone); both must outlive it.
 * p NULL = defaults. RPIV_EINVAL (params, no pairs), RPIV_ENOMEM. */
RPIV_NODISCARD rpiv_status rpiv_batch_new(const rpiv_pairs *pairs, const rpiv_batch_params *p,
                                          const rpiv_mpi *mpi, rpiv_batch **out);
void rpiv_batch_free(rpiv_batch *b); /* NULL is a no-op */

/* The frame size of the series: that of the first pair that can be read (earlier ones are
 * skipped with skip_bad, else their error is returned). Every rank reads the same pairs. */
RPIV_NODISCARD rpiv_status rpiv_batch_size(rpiv_batch *b, int *w, int *h);
/* The grey-level statistics of the frames of the pair rpiv_batch_size read, and its index
 * (0-based) in *i: 1, or 0 if it read none. The frames themselves are kept for the first use of
 * that pair by this rank, so that the files are not read twice. */
int rpiv_batch_first_stats(const rpiv_batch *b, size_t *i, rpiv_image_stats *sa,
                           rpiv_image_stats *sb);

/* The background of the series (rpiv_series_background) for w x h frames: each rank computes it
 * over its own pairs and the ranks combine them (minimum: exact; mean: the ranks' means
 * weighted by their pair counts, in double). With one rank it is rpiv_series_background over
 * the readable pairs. With skip_bad, a pair that fails is found, listed, and the background
 * made again without it. Collective. Errors as rpiv_series_background's. */
RPIV_NODISCARD rpiv_status rpiv_batch_background(rpiv_batch *b, rpiv_background kind, int w, int h,
                                                 const rpiv_progress *progress, rpiv_image **bg_a,
                                                 rpiv_image **bg_b);

/* The ensemble run (rpiv_series_ensemble) of plan pv over the batch's pairs, with the
 * checkpoints, resume, skipping and dealing above; collective. Every rank gets the final
 * field in *out. Progress counts this rank's pairs over all passes. Errors: those of
 * rpiv_series_ensemble, naming the pair; RPIV_EFORMAT (a checkpoint that is not one, is
 * corrupt, or belongs to another series, plan or team: the message says which);
 * RPIV_EIO (a checkpoint cannot be written, or no pair could be read); RPIV_EINTR on a stop
 * request (the checkpoint, if any, is saved first). */
RPIV_NODISCARD rpiv_status rpiv_batch_ensemble(rpiv_batch *b, rpiv_piv *pv,
                                               const rpiv_progress *progress, rpiv_field **out);

/* Per-pair processing (rpiv_series_run) of the batch's pairs; collective, in rounds of K
 * pairs (one per rank). `local` (may be NULL) gets each field on the rank that made it;
 * `root` (may be NULL) gets every field on rank 0, in pair order (they are gathered there).
 * With one rank both are called for each pair, local first. Skipped pairs reach neither.
 * A non-OK return from a sink stops the run on every rank. Checkpoint parameters are not
 * used (each pair's output is complete when its sink returns). */
RPIV_NODISCARD rpiv_status rpiv_batch_series(rpiv_batch *b, rpiv_piv *pv, rpiv_series_sink local,
                                             rpiv_series_sink root, void *user,
                                             const rpiv_progress *progress);

/* The pairs skipped so far on any rank (after a collective step), ascending: the number, and
 * the 0-based index of the k-th. */
size_t rpiv_batch_nskipped(const rpiv_batch *b);
size_t rpiv_batch_skipped(const rpiv_batch *b, size_t k);

/* After rpiv_batch_ensemble with resume: 1 if a checkpoint was found, with the pass (0-based)
 * it was in and the pairs (all ranks) already summed in that pass; 0 if the run began anew. */
int rpiv_batch_resumed(const rpiv_batch *b, int *pass, size_t *done);

/* After rpiv_batch_ensemble: the repeats of the final pass it ran (piv.ensemble_refine), and
 * in *change (may be NULL) the RMS change of the field in its last pass of the final size
 * (rpiv_ensemble_change; -1 where the pass before was on another grid). A run whose repeats
 * reached ensemble_refine with the change still above ensemble_refine_tol_px has not
 * converged: rpiv piv says so. */
int rpiv_batch_repeats(const rpiv_batch *b, double *change);

/* The number of pairs summed in the last ensemble pass (all ranks). */
size_t rpiv_batch_npairs(const rpiv_batch *b);

#endif /* RPIV_BATCH_H */
