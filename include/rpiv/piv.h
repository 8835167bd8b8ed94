/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/piv.h - multi-pass deforming FFT cross-correlation PIV of one pair (the loops over a
 * series of pairs are rpiv/series.h; the ensemble accumulator is rpiv/ensemble.h). */
#ifndef RPIV_PIV_H
#define RPIV_PIV_H

#include "rpiv/error.h"
#include "rpiv/field.h"
#include "rpiv/image.h"
#include "rpiv/peak.h"
#include "rpiv/preprocess.h"
#include "rpiv/progress.h"

#include <stddef.h>
#include <stdint.h>

#define RPIV_PIV_MAX_PASSES 8
/* The largest order of the refinement's notch (rpiv_piv_params.refine_notch). */
#define RPIV_PIV_NOTCH_MAX 8

typedef enum rpiv_background {
    RPIV_BACKGROUND_NONE = 0,
    RPIV_BACKGROUND_MIN = 1, /* subtract the series' per-pixel minimum */
    RPIV_BACKGROUND_MEAN = 2 /* subtract the series' per-pixel mean    */
} rpiv_background;

/* The kinds' names in enum order (NULL-terminated): "none", "min", "mean". */
extern const char *const rpiv_background_names[];
/* The replacement methods (params replace) in order: "median", "inpaint". */
extern const char *const rpiv_replace_names[];

typedef struct rpiv_piv_params {
    int npass;                      /* number of passes, 1..8 (3)                  */
    int win_w[RPIV_PIV_MAX_PASSES]; /* window width per pass, px (64, 32, 32)      */
    int win_h[RPIV_PIV_MAX_PASSES]; /* window height per pass, px (64, 32, 32)     */
    double overlap;                 /* window overlap fraction, 0..0.95 (0.5)      */
    int step_px;                    /* grid step, px; 0 = from overlap (0)         */
    int ensemble;                   /* 1: sum of correlation over all pairs (0)    */
    rpiv_subpixel subpixel;         /* (auto: spline for ensembles, else gauss)   */
    double median_thr;              /* normalised median threshold; 0 = off (2)    */
    double median_eps;              /* median test epsilon, px (0.1)               */
    int median_lines;               /* 1: keep a vector failing the 3x3 test that
                                       agrees with a row, column or diagonal (1)   */
    int search_radius;              /* passes with a predictor: the peak is the
                                       highest local maximum within this many px of
                                       the predicted shift; 0 = whole plane, -1 = an
                                       eighth of the previous pass's window (the
                                       predictor's), >= 2 px (-1)                  */
    int cbc;                        /* correlation-based correction of instantaneous
                                       passes: each window's peak chosen on its plane
                                       combined with its 4 neighbours'; 0 off, 1 their
                                       product, 2 their sum (0)                     */
    rpiv_background background;     /* (none)                                      */
    int roi[4];                     /* x0, y0, x1, y1 px; all 0 = whole image      */
    char mask[512];                 /* mask image, 0 = masked ("" = none)          */
    int threads;                    /* OpenMP threads; 0 = all cores (0)           */
    double scale_mm_per_px;         /* physical scale, 0 = unset (0)               */
    double dt_s;                    /* pulse separation, s; 0 = unset (0)          */
    int deform;                     /* 1: deform images between passes (1)         */
    double max_mem_mb;              /* refuse runs needing more memory, MB (4096)  */
    /* Iterative refinement at the final window size (rpiv_piv_passes): the last pass is
     * repeated, each time deformed by the denoised result of the one before, until the RMS
     * change of the field falls below refine_tol_px, stops falling (refine_stop) or
     * refine_max repeats are done (docs/piv.md, "Refinement at the final size"). */
    int refine_max;       /* repeats of the last pass, 0..20 (10) */
    double refine_tol_px; /* convergence: RMS change between iterations, px (0.02) */
    double refine_filter; /* predictor low-pass weight a of [a/2, 1-a, a/2], 0..0.5 (0; 0.1
                             suggested with refine_defer) */
    int refine_denoise;   /* 1: shrink the predictor's detail, threshold from its noise (1) */
    /* The denoiser's detail at its finest dilation: 4, the fourth difference (its smoothing
     * exact on cubics: a smooth flow's curvature is not taken for noise), 2 the second
     * (session 6's) (4; docs/piv.md, "Refinement at the final size"). */
    int refine_denoise_order;
    /* The denoised predictor's notch of its grid's Nyquist mode, order 2..8 (response 1 -
     * 2^-m at 4 grid steps a wavelength), 0 off: a window of 2 grid steps or more does not see
     * that mode (nor, with 4 grid steps or more, the wave of 4 steps, notched too), so the repeats
     * would keep whatever an earlier pass's noise put there. On the
     * refinement's repeats only (not the listed passes, nor ensembles, which run those only)
     * (6; docs/piv.md, "The grid's Nyquist mode"). */
    int refine_notch;
    int refine_stop;  /* 1: stop when the change has not fallen below its smallest for two
                         repeats; end with the iterate of the smallest change (1) */
    int refine_defer; /* 1: no median test between repeats of the final size, only on the
                         field they converge to (0; experimental, docs/piv.md) */
    /* The predictor beyond the grid's edge (docs/piv.md, "The grid's edge"): 0 continued
     * linearly, 1 with its curvature (limited, where the 4 end nodes of a grid line are
     * measured, and shrunk by the field's noise threshold), -1 the curvature for ensembles only
     * (-1 since session 13: better on synthetic ensembles and neutral on the demo's; single
     * pairs' noisy edges lose with it). */
    int edge_curvature;
    /* 1: where an ensemble's estimator is the spline, its correction of the 3-point Gaussian is
     * tested against the neighbours' and a vector that fails takes the Gaussian plus their
     * median correction (docs/piv.md, "The spline's correction checked") (1). */
    int spline_check;
    /* Ensembles: the final pass repeated, each time deformed by the ensemble field of the one
     * before, while the RMS change of the field between two passes of the final size is above
     * ensemble_refine_tol_px, at most ensemble_refine times (0: the listed passes only). An
     * ensemble's noise is that of one pair over the square root of its pairs, so its change is
     * the convergence of the deformation, not noise (docs/piv.md, "Ensembles: the final pass
     * repeated") (0). */
    int ensemble_refine;           /* 0..20 (0) */
    double ensemble_refine_tol_px; /* RMS change, px (0.002) */
    /* 1: an ensemble's predictor of the final size is denoised as a pair's repeats are
     * (refine_denoise); 0: not denoised but notched (refine_notch). The denoiser's threshold
     * comes from the field's own detail, which in an ensemble of many pairs is mostly the
     * flow's: it shrinks a curved flow (a vortex's ensemble, 3 px images, with ensemble_refine:
     * RMS error of u 0.0077 px with it, 0.0044 without), while an ensemble of few noisy pairs
     * needs it (docs/piv.md, "Ensembles: the final pass repeated") (1). */
    int ensemble_denoise;
    /* Image preprocessing applied to both frames of every pair on loading, after the
     * background subtraction (rpiv/preprocess.h; ops "" = none, the default). */
    rpiv_preprocess_params prep;
    /* Validation beyond the median test, every pass, before it (rpiv/validate.h; all off by
     * default): peak ratio below peak_ratio_min; u outside [u_min_px, u_max_px] or v outside
     * [v_min_px, v_max_px] (px per pair, image coordinates, each pair off while min >= max);
     * farther than std_k standard deviations from the mean of the valid vectors. */
    double peak_ratio_min;                         /* 0 = off (0)                     */
    double u_min_px, u_max_px, v_min_px, v_max_px; /* off while min >= max (0, 0)     */
    double std_k;                                  /* 0 = off (0)                     */
    int replace;   /* rejected vectors: 0 local median, 1 inpainting (Laplace) (0)        */
    double smooth; /* final field: penalised least-squares smoothing parameter, 0 = off (0) */
    int y_up;      /* output files: 1 origin bottom-left, y and v up; 0 image coordinates (0) */
    /* Random uncertainty of every vector of the final window size, instantaneous or ensemble:
     * the quantities sigma_u, sigma_v (1 standard deviation, px per pair), correlation
     * statistics (Wieneke 2015) of every pass with the predictors' noise carried through the
     * passes (docs/uncertainty.md). */
    int uncertainty; /* 1: add sigma_u, sigma_v (0) */
} rpiv_piv_params;

rpiv_piv_params rpiv_piv_params_default(void);
RPIV_NODISCARD rpiv_status rpiv_piv_params_check(const rpiv_piv_params *p);

/* ---- memory ------------------------------------------------------------------------------
 *
 * The peak memory of a run, estimated before anything is allocated, in bytes: what
 * piv.max_mem_mb is compared with (rpiv piv refuses a run above it). total = base + frames +
 * the larger of load and work:
 *   base    the process itself: code, libraries, FFTW plans (RPIV_PIV_MEM_BASE_MB);
 *   frames  the plan's two frames, the preprocessing frame, the mask (bytes, and the caller's
 *           float image), the background frames, the correlation workspaces;
 *   load    a pair being decoded: its two frames as float and the reader's rows of one;
 *   held    fields of the final grid the caller keeps (rpiv piv keeps a copy of the first
 *           pair's field: held = 1), from the end of the first pair on;
 *   work    per pair: the largest pass (its field, validated; the predictor field, its copy
 *           and its cubic-spline coefficients; the deformation strips), with the held fields
 *           when there are later pairs, or the last field with the held ones; ensemble: the
 *           summed planes of the largest pass with a pair being loaded, the predictor,
 *           the pairs in flight (small frames, several threads) and the final field.
 * Checked within 25 % of the peak RSS of rpiv piv (test_mem; docs/benchmarks.md). mask: 1 if
 * a mask image is used; npairs: pairs in the run. rpiv_piv_new itself refuses only frames
 * above the limit (it does not know the pairs or what the caller keeps): a caller compares
 * total with piv.max_mem_mb before it, as rpiv piv does. */
#define RPIV_PIV_MEM_BASE_MB 18
typedef struct rpiv_piv_mem {
    double base, frames, load, held, work, total; /* bytes */
} rpiv_piv_mem;
rpiv_piv_mem rpiv_piv_mem_estimate(const rpiv_piv_params *p, int w, int h, int mask, size_t npairs,
                                   int held);

/* ---- the engine ---------------------------------------------------------------------------
 *
 * A plan (rpiv_piv) is made once for an image size and a set of parameters: the grid of every
 * pass (windows inside the ROI, centred in it), the FFTW plans of every window size, one
 * workspace per thread and per pass, and the frame buffers. Each pass k:
 *   1. interpolates the predictor (the validated field of pass k-1) to every pixel with a
 *      cubic B-spline on its grid, and deforms both frames symmetrically by -+1/2 of it
 *      (cubic B-spline image interpolation; rpiv/deform.h); pass 0 has no predictor;
 *   2. correlates every window pair by FFT (rpiv/xcorr.h), windows mean-removed;
 *   3. locates the highest peak with the sub-pixel fit chosen (rpiv/peak.h): the vector is
 *      the predictor at the window centre plus the residual shift;
 *   4. validates with the normalised median test and replaces rejected vectors by the median
 *      of their valid neighbours (rpiv/validate.h).
 * Window (i, j) of a pass covers pixels ox + i*sx .. ox + i*sx + W-1 (likewise in y); its
 * vector sits at the window's centre, x = ox + i*sx + (W-1)/2 (pixel centres at integers, so
 * a 32 px window starting at 0 is centred at 15.5), plus RPIV_DEFORM_SHIFT (1/4 px) in x and y
 * for the passes that deform, whose frames are resampled a quarter pixel off to cancel the
 * interpolation bias (rpiv/deform.h); the grid of each field says where its vectors are.
 * Vectors whose window has more than half of its pixels masked are flagged
 * RPIV_FLAG_MASKED with u = v = 0. Windows whose plane has no usable peak (a blank window, a
 * flat plane) are rejected like outliers and replaced. Deforming passes work strip by strip
 * and never hold whole deformed frames: a plan's memory is two frames plus small buffers.
 *
 * Results are identical for any thread count: threads split windows, rows and columns, and
 * nothing is summed across threads. */
typedef struct rpiv_piv rpiv_piv;

/* A plan for pairs of w x h frames. mask (NULL = none) is a w x h image, 0 = masked pixel
 * (the file named by p->mask is the caller's to load). Errors: RPIV_EINVAL (parameters),
 * RPIV_ESIZE (a window larger than the image or ROI, a ROI outside the image, a mask of
 * another size), RPIV_ELIMIT (buffers above p->max_mem_mb), RPIV_ENOMEM. Makes FFTW plans:
 * call from one thread at a time. */
RPIV_NODISCARD rpiv_status rpiv_piv_new(const rpiv_piv_params *p, int w, int h,
                                        const rpiv_image *mask, rpiv_piv **out);
void rpiv_piv_free(rpiv_piv *pv); /* NULL is a no-op */

int rpiv_piv_npass(const rpiv_piv *pv);
int rpiv_piv_threads(const rpiv_piv *pv);
const rpiv_piv_params *rpiv_piv_params_of(const rpiv_piv *pv);
/* Bytes held by the plan's buffers (frames, workspaces). */
size_t rpiv_piv_memory(const rpiv_piv *pv);
/* The frame size the plan was made for. */
void rpiv_piv_size(const rpiv_piv *pv, int *w, int *h);
/* What identifies the plan beyond its parameters, for a checkpoint: the 64-bit FNV-1a hash h
 * continued over the mask and the background frames the plan holds (h itself if none). */
uint64_t rpiv_piv_hash_frames(const rpiv_piv *pv, uint64_t h);

/* Cancellation inside one pair (a large image with small windows can take minutes): the plan
 * calls cancel->fn(cancel->user, 0, 0) from the calling thread before each pass and every
 * few rows of windows of rpiv_piv_step / rpiv_piv_passes / rpiv_piv_run; a non-zero return
 * stops the pair with RPIV_EINTR (no field). The ensemble's passes are not cut (the series
 * loop asks between pairs). NULL or fn NULL: never asked (the default). Copied. */
void rpiv_piv_set_cancel(rpiv_piv *pv, const rpiv_progress *cancel);

/* A zeroed field on the grid of pass `pass` (0-based), scale and dt set from the params. */
RPIV_NODISCARD rpiv_status rpiv_piv_grid(const rpiv_piv *pv, int pass, rpiv_field **out);

/* Background frames subtracted on loading (bg_a from frame A, bg_b from frame B), copied;
 * NULL, NULL removes them. RPIV_ESIZE if a size differs from the plan's. */
RPIV_NODISCARD rpiv_status rpiv_piv_set_background(rpiv_piv *pv, const rpiv_image *bg_a,
                                                   const rpiv_image *bg_b);

/* Load a pair into the plan (copied: background subtracted, masked pixels set to the frame's
 * mean over unmasked pixels). The caller may free a and b afterwards. RPIV_ESIZE if their
 * size differs from the plan's. */
RPIV_NODISCARD rpiv_status rpiv_piv_load(rpiv_piv *pv, const rpiv_image *a, const rpiv_image *b);

/* Run pass `pass` on the loaded pair with `predictor` (any grid; NULL: none, windows
 * correlated where they are) into a new field on the pass's grid: measured, validated,
 * rejected vectors replaced. Passes after the first deform the frames by the predictor
 * (params deform = 1); pass 0 given a predictor, and every pass with deform = 0, shift the
 * window pairs by the predictor rounded to whole pixels instead (window offset). RPIV_EINVAL
 * if nothing is loaded, pass is out of range, or an offset pass follows a deforming one on the
 * same load (the frames are prefiltered in place: load the pair again). */
RPIV_NODISCARD rpiv_status rpiv_piv_step(rpiv_piv *pv, int pass, const rpiv_field *predictor,
                                         rpiv_field **out);

/* Every pass on the loaded pair, each pass's field being the next one's predictor, then the
 * refinement at the final window size: the last pass repeated (deformed by the field before
 * it, denoised with refine_denoise, low-passed with refine_filter) until the RMS change of the
 * field between two passes of the final size is below refine_tol_px or, with refine_stop, has
 * not fallen below its smallest for two repeats (the field of the smallest change is kept), at
 * most refine_max times (none with deformation off). *out is the last field; *nrefine (may be
 * NULL) the repeats of the field returned. With the uncertainty and a refinement, the passes
 * after the first run twice: without it, to find the field returned, then with it up to that
 * field, whose sigma alone is computed (the same numbers as computing it after every repeat,
 * at a fraction of the cost; docs/uncertainty.md, "Cost"). */
RPIV_NODISCARD rpiv_status rpiv_piv_passes(rpiv_piv *pv, rpiv_field **out, int *nrefine);

/* The whole run on one pair: rpiv_piv_load, then rpiv_piv_passes. */
RPIV_NODISCARD rpiv_status rpiv_piv_run(rpiv_piv *pv, const rpiv_image *a, const rpiv_image *b,
                                        rpiv_field **out);

/* Loads pair k (0-based within a rpiv_piv_run_pairs call) into *a, *b, which the callee frees.
 * May be called from several threads at once, for different k. */
typedef rpiv_status (*rpiv_piv_load_fn)(void *user, size_t k, rpiv_image **a, rpiv_image **b);
/* Told, on the calling thread and in the order of k, how pair k went: st RPIV_OK and f its field
 * (owned by the callee from then on), or its error (f NULL; loaded = 0: from the load, 1: from
 * the passes; the message is rpiv_errmsg()'s). Returns RPIV_OK to go on, or the status to stop
 * with (the later pairs are then not done). */
typedef rpiv_status (*rpiv_piv_done_fn)(void *user, size_t k, rpiv_status st, int loaded,
                                        rpiv_field *f);
/* The fields of n pairs, each as rpiv_piv_load + rpiv_piv_passes give it, handed to `done` in
 * pair order. Small frames (up to 1.5 Mpx) go a pair per thread of the plan, each thread on its
 * own one-thread copy (their parallel regions would otherwise be too short for the threads to
 * pay, and on a busy machine the threads would wait for each other at every one); large frames
 * one after another, the plan's threads inside each. The fields have the same bits either way.
 * The first status a `done` call returns, RPIV_ENOMEM, or RPIV_OK. */
RPIV_NODISCARD rpiv_status rpiv_piv_run_pairs(rpiv_piv *pv, size_t n, rpiv_piv_load_fn load,
                                              rpiv_piv_done_fn done, void *user);

#endif /* RPIV_PIV_H */
