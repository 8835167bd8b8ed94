/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/ensemble.h - ensemble (sum-of-correlation) PIV: one accumulator per pass.
 *
 * The paper averages the correlation planes of hundreds of pairs before locating the peak
 * (section "Statistical aspect and convergence", Eq. "statform"): at every pass, for every
 * window, the planes of all pairs are summed, and the peak of the sum gives the ensemble
 * displacement; pass k's predictor is the ensemble field of pass k-1, so the series is read
 * once per pass. An accumulator holds, for one pass, the summed raw correlation plane of every
 * window, R(s) = sum over pairs of sum_x a'(x) b'(x + s) (not normalised pair by pair: each
 * particle image weighs by its intensity, as in the model's integral, Eq. "statform"), and the
 * summed window energies sum a'^2 and sum b'^2, from which the peak's correlation coefficient
 * is formed at the end.
 *
 * Memory: one float plane per window, independent of the number of pairs (2560 x 2160 frames,
 * 32 px windows at 50 % overlap: 21 306 planes of 4 KB, 87 MB). Sums are float: pair-by-pair
 * addition of planes whose values agree to a few percent loses ~1e-6 relative per step,
 * far below the pair-to-pair scatter, and halves the memory of double sums.
 *
 * Determinism: each window's sums are added pair by pair in the order of the add calls, by
 * one thread, so the result does not depend on the thread count. Merging accumulators (MPI
 * ranks, resumed checkpoints) adds the sums of several groups of pairs: the result equals the
 * single-process one up to float rounding of the different grouping.
 *
 * Scale-out and checkpoints: rpiv_ensemble_data exposes the raw sums as one float array
 * (MPI_Reduce with MPI_FLOAT/MPI_SUM into a root accumulator, then rpiv_ensemble_set_npairs
 * with the total). rpiv_ensemble_save/_load write and read an accumulator as a checkpoint
 * file, the one checkpoint format of rpiv (magic RPIVCKP4): a header that ties the sums to the
 * pass, the windows, the grid and the image size, a block of the caller's bytes (rpiv/batch.h
 * keeps the identity of its series, plan and rank there, and which pairs are done), the
 * predictor (and its sigma_u, sigma_v with piv.uncertainty), the sums (with piv.uncertainty,
 * 8 more per window: docs/uncertainty.md) and their pair count, and a 64-bit checksum of all
 * of it. */
#ifndef RPIV_ENSEMBLE_H
#define RPIV_ENSEMBLE_H

#include "rpiv/error.h"
#include "rpiv/field.h"
#include "rpiv/image.h"
#include "rpiv/piv.h"

#include <stddef.h>

typedef struct rpiv_ensemble rpiv_ensemble;

/* An empty accumulator for pass `pass` of plan pv, with the predictor of that pass (the
 * finished field of pass-1; NULL for the first pass). The predictor is copied; pv must
 * outlive the accumulator, and pairs added through it use pv's buffers (one add at a time
 * per plan). RPIV_ELIMIT when the plan's buffers and the sums exceed piv.max_mem_mb. */
RPIV_NODISCARD rpiv_status rpiv_ensemble_new(rpiv_piv *pv, int pass, const rpiv_field *predictor,
                                             rpiv_ensemble **out);
void rpiv_ensemble_free(rpiv_ensemble *e); /* NULL is a no-op */

/* Add one pair: load it into the plan (background, mask), deform it by the predictor,
 * correlate every window and add each plane and energy to its sum. */
RPIV_NODISCARD rpiv_status rpiv_ensemble_add(rpiv_ensemble *e, const rpiv_image *a,
                                             const rpiv_image *b);

/* Loads pair k (0-based within a rpiv_ensemble_add_pairs call) into *a, *b, which the caller
 * frees. May be called from several threads at once, for different k. */
typedef rpiv_status (*rpiv_ensemble_load_fn)(void *user, size_t k, rpiv_image **a, rpiv_image **b);
/* Told, on the calling thread and in the order of k, how pair k went: st is RPIV_OK when its
 * planes are in the sums, else its error (loaded = 0: from the load, 1: from the correlation;
 * its message is rpiv_errmsg()'s) and nothing of it was added. Returns RPIV_OK to go on, or
 * the status to stop with (the later pairs are then not added). */
typedef rpiv_status (*rpiv_ensemble_done_fn)(void *user, size_t k, rpiv_status st, int loaded);

/* Add n pairs as n calls of rpiv_ensemble_add would, pair k's planes added after pair k-1's,
 * so that the sums have the same bits for any thread count. Small images are correlated
 * several pairs at a time, one pair per thread of the plan (their parallel regions would
 * otherwise be too short for the threads to pay, and on a busy machine the threads wait for
 * each other at every one); large images one after another, the plan's threads inside each
 * pair. The first status a `done` call returns, RPIV_ENOMEM, or RPIV_OK. */
RPIV_NODISCARD rpiv_status rpiv_ensemble_add_pairs(rpiv_ensemble *e, size_t n,
                                                   rpiv_ensemble_load_fn load,
                                                   rpiv_ensemble_done_fn done, void *user);

/* dst += src: the sums of two accumulators of the same plan layout, pass and predictor.
 * RPIV_EINVAL if they do not match. */
RPIV_NODISCARD rpiv_status rpiv_ensemble_merge(rpiv_ensemble *dst, const rpiv_ensemble *src);

/* The raw sums, *n floats: for every window in grid order its plane (W*H, circular order as in
 * rpiv/peak.h), then for every window its two energies. Owned by e. */
float *rpiv_ensemble_data(rpiv_ensemble *e, size_t *n);
size_t rpiv_ensemble_npairs(const rpiv_ensemble *e);
void rpiv_ensemble_set_npairs(rpiv_ensemble *e, size_t npairs);
int rpiv_ensemble_pass(const rpiv_ensemble *e);

/* After the ensemble field f of the final pass (or of a repeat of it, repeats done so far),
 * made with the field prev as its predictor: 1 if the final pass is due once more
 * (rpiv_piv_params.ensemble_refine): fewer than ensemble_refine repeats are done, and prev is
 * on another grid (the final size has not been iterated yet) or the RMS change of u, v over the
 * vectors valid in both is above ensemble_refine_tol_px. 0 otherwise. A caller running the
 * passes itself runs the plan's last pass again with f as its predictor while this says so. */
int rpiv_ensemble_again(const rpiv_piv *pv, const rpiv_field *prev, const rpiv_field *f,
                        int repeats);
/* The RMS change of u, v from prev to f over the vectors valid in both, px; -1 if either is
 * NULL, they are on different grids or no vector is valid in both. */
double rpiv_ensemble_change(const rpiv_field *prev, const rpiv_field *f);

/* The predictor the accumulator was made with (its copy), NULL for none. */
const rpiv_field *rpiv_ensemble_predictor(const rpiv_ensemble *e);

/* Write e to path as a checkpoint (see above), atomically: under a temporary name in the same
 * folder, fsync'd, renamed over path; on failure the old file is left as it was. The header
 * records the pass, image size, windows, grid, pair count and a hash of the predictor. */
RPIV_NODISCARD rpiv_status rpiv_ensemble_save(const rpiv_ensemble *e, const char *path);
/* The same, with nblock bytes of the caller's (block may be NULL when nblock is 0) stored
 * between the header and the predictor, under the checksum. */
RPIV_NODISCARD rpiv_status rpiv_ensemble_save_block(const rpiv_ensemble *e, const void *block,
                                                    size_t nblock, const char *path);

/* Read a checkpoint written by rpiv_ensemble_save(_block) into e, replacing its sums and pair
 * count (a caller's block is passed over). RPIV_EIO (cannot open), RPIV_EFORMAT (not a
 * checkpoint, one of an older rpiv format, truncated, corrupt, or written for another pass,
 * layout or predictor: the message names the file and says which). On failure e is unchanged. */
RPIV_NODISCARD rpiv_status rpiv_ensemble_load(rpiv_ensemble *e, const char *path);

/* Checks the caller's block of a checkpoint being read (before the sums are): a non-OK return
 * (with its message) stops the reading with that status. */
typedef rpiv_status (*rpiv_ensemble_block_fn)(void *user, const void *block, size_t nblock);

/* Read a checkpoint into a new accumulator of plan pv for the pass and predictor the file
 * holds. `check` (may be NULL) is called with the caller's block once the header is read;
 * then the pass, layout, predictor, sums and checksum are read and checked. Errors as
 * rpiv_ensemble_load's, plus check's own; on failure *out is NULL. */
RPIV_NODISCARD rpiv_status rpiv_ensemble_load_new(rpiv_piv *pv, const char *path,
                                                  rpiv_ensemble_block_fn check, void *user,
                                                  rpiv_ensemble **out);

/* Locate the peak of every summed plane: the ensemble field of the pass (predictor plus
 * residual, correlation coefficient from the summed energies, peak ratio), validated and
 * with rejected vectors replaced; it is the predictor of the next pass. RPIV_EINVAL if no
 * pair was added. */
RPIV_NODISCARD rpiv_status rpiv_ensemble_finish(const rpiv_ensemble *e, rpiv_field **out);

#endif /* RPIV_ENSEMBLE_H */
