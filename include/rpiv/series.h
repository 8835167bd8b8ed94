/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/series.h - the loops over the pairs of a series: instantaneous fields, background,
 * mean and RMS, and the ensemble (sum-of-correlation) run, over image files or over pairs made
 * in memory (rpiv_series_source). The loops are those of rpiv/batch.h, which adds
 * checkpoints, skipping of bad pairs and MPI dealing; here they run in one process. */
#ifndef RPIV_SERIES_H
#define RPIV_SERIES_H

#include "rpiv/ensemble.h"
#include "rpiv/error.h"
#include "rpiv/field.h"
#include "rpiv/image.h"
#include "rpiv/mpi.h"
#include "rpiv/pairs.h"
#include "rpiv/piv.h"
#include "rpiv/progress.h"

#include <stddef.h>

/* The background of a series: the per-pixel minimum or mean of all A frames (*bg_a) and of
 * all B frames (*bg_b), read once, streaming (memory: two frames, and two double sums for the
 * mean). RPIV_EINVAL for kind NONE or no pairs, RPIV_ESIZE (naming the pair) if the frames
 * change size, RPIV_EINTR on a stop request, and the image readers' errors. */
RPIV_NODISCARD rpiv_status rpiv_series_background(const rpiv_pairs *pairs, rpiv_background kind,
                                                  const rpiv_progress *progress, rpiv_image **bg_a,
                                                  rpiv_image **bg_b);

/* Called with every field of a series, in pair order; a non-OK return stops the series with
 * that status. The field is only lent for the call. */
typedef rpiv_status (*rpiv_series_sink)(void *user, size_t index, const rpiv_field *f);

/* Instantaneous processing of a series: every pair is read, loaded into the plan (its images
 * freed at once, so memory holds the plan's frames only) and run through all passes; each
 * final field goes to sink. Errors name the pair; RPIV_EINTR on a stop request. */
RPIV_NODISCARD rpiv_status rpiv_series_run(rpiv_piv *pv, const rpiv_pairs *pairs,
                                           rpiv_series_sink sink, void *user,
                                           const rpiv_progress *progress);

/* Mean and RMS (standard deviation) of a series of fields on one grid, point by point, over
 * the vectors flagged valid (Welford's update in double, in the order added). At a point with
 * no valid vector the replaced ones are used and the point is flagged RPIV_FLAG_REPLACED; a
 * point masked in every field stays RPIV_FLAG_MASKED with 0. peak_ratio and corr are the means
 * of the same vectors. */
typedef struct rpiv_series_stats rpiv_series_stats;
RPIV_NODISCARD rpiv_status rpiv_series_stats_new(const rpiv_field *grid, rpiv_series_stats **out);
void rpiv_series_stats_free(rpiv_series_stats *s); /* NULL is a no-op */
/* RPIV_ESIZE if f's grid differs from the first one's. */
RPIV_NODISCARD rpiv_status rpiv_series_stats_add(rpiv_series_stats *s, const rpiv_field *f);
size_t rpiv_series_stats_count(const rpiv_series_stats *s);
/* New fields *mean and *rms (u, v: mean and standard deviation, px). RPIV_EINVAL if empty. */
RPIV_NODISCARD rpiv_status rpiv_series_stats_finish(const rpiv_series_stats *s, rpiv_field **mean,
                                                    rpiv_field **rms);

/* The whole ensemble run over a series: for every pass, every pair of `pairs` is loaded and
 * added, then the pass is finished into the next predictor. Progress counts pairs over all
 * passes; a stop request returns RPIV_EINTR. *out is the last pass's field. */
RPIV_NODISCARD rpiv_status rpiv_series_ensemble(rpiv_piv *pv, const rpiv_pairs *pairs,
                                                const rpiv_progress *progress, rpiv_field **out);

/* A series whose pairs are made on demand rather than read from files (synthesised, decoded
 * from a stream). `pair` fills a and b, two images of the plan's size that the run owns and
 * reuses, with pair i (0-based) of pass `pass` (0-based): every pass reads every pair, in order,
 * so a source may cache them. `added` (NULL: none) is called after pair i was added in pass
 * `pass`: e then holds the sums of pairs 0..i of the pass (rpiv_ensemble_finish gives their
 * field). A non-OK return from either stops the run with that status and message. */
typedef struct rpiv_series_source {
    size_t n; /* pairs */
    rpiv_status (*pair)(void *user, size_t i, int pass, rpiv_image *a, rpiv_image *b);
    rpiv_status (*added)(void *user, int pass, size_t i, const rpiv_ensemble *e);
    void *user;
} rpiv_series_source;

/* rpiv_series_ensemble over the pairs of a source: the same loop (rpiv_batch_ensemble), with
 * the same result as over files holding the same pairs. RPIV_EINVAL for no pairs; the source's
 * and the hook's errors as they returned them. */
RPIV_NODISCARD rpiv_status rpiv_series_ensemble_source(rpiv_piv *pv, const rpiv_series_source *src,
                                                       const rpiv_progress *progress,
                                                       rpiv_field **out);

/* ---- a job per pair, dealt out to a team ----------------------------------------------- */

/* The job of pair i (0-based) of rpiv_series_each; a non-OK return stops the loop. */
typedef rpiv_status (*rpiv_series_pair_fn)(void *user, size_t i);

/* Run fn on this rank's share of the pairs 0..n-1 (pair i is rank i mod K's; mpi NULL or a
 * team of one: every pair), in increasing order, with progress over this rank's count. Stops
 * at the first failure (its status and message as fn left them) or at a stop request
 * (RPIV_EINTR, "<what>: interrupted after D of N pairs"). Not collective: the caller agrees
 * on the outcome (rpiv_mpi_agree). */
RPIV_NODISCARD rpiv_status rpiv_series_each(size_t n, const rpiv_mpi *mpi, rpiv_series_pair_fn fn,
                                            void *user, const rpiv_progress *progress,
                                            const char *what);

#endif /* RPIV_SERIES_H */
