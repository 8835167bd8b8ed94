/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/piv_mem.c - the peak memory of a run, estimated from its parameters and frame size
 * before anything is allocated (piv.max_mem_mb; issue 20 item 12). Each term follows an
 * allocation of the engine; the figures it was checked against are in docs/benchmarks.md. */
#include "rpiv/piv.h"

#include "ensemble_impl.h"
#include "pair_pool.h"
#include "piv_impl.h"

#include <math.h>
#include <omp.h>

/* A field's bytes per vector: u, v, peak ratio, correlation (float) and the flag; the
 * uncertainty adds sigma_u, sigma_v on the final grid. */
#define FIELD_B 17.0
#define SIGMA_B 8.0
/* Validation's work arrays per vector: the median test's rejection marks (2 bytes), then the
 * replacement's known marks and new values (2 + 8 bytes): the larger, with the flags. */
#define VALID_B 12.0
/* A predictor's cubic B-spline coefficients per grid point (u, v as float). */
#define SPLINE_B 8.0
/* Frames of at most this many pixels are correlated a pair per thread in an ensemble
 * (src/piv/ensemble_pairs.c: PAIRS_MAX_PX, ROUND_PER_THREAD, PAIRS_MAX_MB). */
#define PAIRS_MAX_PX     (1500.0 * 1000.0)
#define PAIRS_PER_THREAD 4
#define PAIRS_MAX_B      (256.0 * 1048576.0)

/* The grid of pass k (as the plan's pass_grid), vectors. */
static double pass_vectors(const rpiv_piv_params *p, int rw, int rh, int k)
{
    int ww = p->win_w[k], wh = p->win_h[k];
    int sx = p->step_px > 0 ? p->step_px : (int)lround(ww * (1 - p->overlap));
    int sy = p->step_px > 0 ? p->step_px : (int)lround(wh * (1 - p->overlap));
    sx = sx < 1 ? 1 : sx;
    sy = sy < 1 ? 1 : sy;
    if (ww > rw || wh > rh)
        return 0;
    return (double)((rw - ww) / sx + 1) * (double)((rh - wh) / sy + 1);
}

rpiv_piv_mem rpiv_piv_mem_estimate(const rpiv_piv_params *p, int w, int h, int mask, size_t npairs,
                                   int held)
{
    rpiv_piv_mem m = {0};
    const int *r = p->roi;
    const int whole = !r[0] && !r[1] && !r[2] && !r[3];
    const int rw = whole ? w : r[2] - r[0], rh = whole ? h : r[3] - r[1];
    const int nt = p->threads > 0 ? p->threads : omp_get_max_threads();
    const double px = (double)w * (double)h, frame = 4 * px;
    const int last = p->npass - 1;
    const double nlast = pass_vectors(p, rw, rh, last);
    const double final_b = FIELD_B + (p->uncertainty && !p->ensemble ? SIGMA_B : 0);

    m.base = RPIV_PIV_MEM_BASE_MB * 1048576.0;
    /* the plan's two frames (then their spline coefficients, in place), the preprocessing
     * frame, the mask as bytes and as the caller's float image, the background frames */
    m.frames = 2 * frame + (p->prep.ops[0] ? frame : 0) + (mask ? px + frame : 0) +
               (p->background != RPIV_BACKGROUND_NONE ? 2 * frame : 0);
    for (int k = 0; k < p->npass; k++) /* correlation workspaces, per thread and pass */
        m.frames += (double)nt * 4 * 4.0 * p->win_w[k] * p->win_h[k];
    /* a pair being loaded: its two decoded frames and the reader's 16-bit rows of one; a
     * single pair without background or preprocessing gives its frames to the plan
     * (piv_pairs.c), whose own are never touched: the rows only */
    const int give =
        npairs == 1 && !p->ensemble && !p->prep.ops[0] && p->background == RPIV_BACKGROUND_NONE;
    m.load = (give ? 0.5 : 2.5) * frame;
    /* the fields the caller keeps from the first pair on */
    m.held = held * nlast * final_b;

    if (!p->ensemble) {
        double work = 0;
        for (int k = 0; k < p->npass; k++) {
            const double n = pass_vectors(p, rw, rh, k), fb = k == last ? final_b : FIELD_B;
            double pass = n * (fb + VALID_B); /* the new field, validated */
            if (p->cbc) /* the correlation-based correction's planes (piv_cbc.c) */
                pass += n * piv_cbc_bytes(p->win_w[k], p->win_h[k],
                                          piv_params_search_radius(p, k, k > 0));
            if (k > 0) {
                const double n0 = pass_vectors(p, rw, rh, k - 1);
                /* the previous field, held; its copy being filled, or its spline
                 * coefficients while the pass runs; the deformation strips */
                double pred = n0 * (FIELD_B + FIELD_B + 10), run = n0 * SPLINE_B + pass;
                run += p->deform ? (double)nt * 2 * p->win_h[k] * 4.0 * w : 0;
                pass = n0 * FIELD_B + (pred > run ? pred : run);
            }
            work = pass > work ? pass : work;
        }
        /* the repeats of the final size (refine.c) keep the field of the smallest change
         * beside the two they compare */
        if (p->refine_max > 0 && p->refine_stop && p->deform && p->npass > 1)
            work += nlast * final_b;
        /* the last field and the caller's copy of it (the first pair's) */
        const double end = nlast * final_b + m.held;
        m.work = npairs > 1 ? work + m.held : work;
        m.work = end > m.work ? end : m.work;
        /* small frames, several pairs and threads: a pair per thread (rpiv_piv_run_pairs,
         * pair_pool.h), each thread with a one-thread copy of the plan (its frames and
         * workspaces), a pair being loaded and a pair's work; the slots hold fields */
        if (npairs > 1 && nt > 1 && px <= POOL_MAX_PX) {
            double copy = 2 * frame + (p->prep.ops[0] ? frame : 0) + (mask ? px : 0) +
                          (p->background != RPIV_BACKGROUND_NONE ? 2 * frame : 0);
            for (int k = 0; k < p->npass; k++)
                copy += 4 * 4.0 * p->win_w[k] * p->win_h[k];
            /* as pool_slots decides: the ring (slots and copies) within POOL_MAX_MB and
             * what piv.max_mem_mb leaves beside the plan */
            const double ring = POOL_PER_THREAD * nt * nlast * 2 * 4.0 * 2 + nt * copy;
            const double budget = p->max_mem_mb * 1048576.0 - m.frames;
            if (ring <= POOL_MAX_MB * 1048576.0 && ring <= budget)
                m.work += ring + nt * work + (nt - 1) * m.load;
        }
    } else {
        /* the summed planes and energies of the largest pass with a pair being loaded, the
         * predictor field and its coefficients (the sums of the pass before are freed) */
        double work = 0;
        for (int k = 0; k < p->npass; k++) {
            const double n = pass_vectors(p, rw, rh, k);
            const double plane = (double)p->win_w[k] * p->win_h[k];
            /* with the uncertainty, each window's statistics sums and the second moments of
             * its plane's samples near zero shift (ensemble_unc.c) */
            const double sums = n * (plane + 2 + (p->uncertainty ? ENS_UNC_STRIDE : 0)) * 4;
            double pass =
                sums + m.load + (k ? pass_vectors(p, rw, rh, k - 1) * (FIELD_B + SPLINE_B) : 0);
            /* pairs in flight, as rpiv_ensemble_add_pairs decides: a slot of planes per
             * pair, 4 per thread, fewer to fit piv.max_mem_mb, none above PAIRS_MAX_B; a
             * plan (frames) and a pair being loaded per thread */
            if (npairs > 1 && nt > 1 && px <= PAIRS_MAX_PX) {
                const double slot = n * (plane * 4 + 16), plan = m.frames;
                const double budget = p->max_mem_mb * 1048576.0 - plan - sums;
                double s =
                    PAIRS_PER_THREAD * nt < (double)npairs ? PAIRS_PER_THREAD * nt : (double)npairs;
                while (s > nt && s * slot + nt * plan > budget)
                    s--;
                const double ring = s * slot + nt * plan;
                if (ring <= budget && ring <= PAIRS_MAX_B)
                    pass += ring + nt * 2.5 * frame;
            }
            work = pass > work ? pass : work;
        }
        /* a multi-pass ensemble's peak RSS exceeds its heap's by about 2 frames (measured
         * at 2048^2: massif's heap peak 128.6 MB, RSS 183 MiB; the same at 4096^2); the
         * cause (pages the allocator keeps after the pass's pair is freed?) is not pinned
         * down: counted as measured (docs/benchmarks.md) */
        m.work = work + nlast * FIELD_B + (p->npass > 1 ? 2 * frame : 0);
    }
    m.total = m.base + m.frames + (m.load > m.work ? m.load : m.work);
    return m;
}
