/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/xcorr.h - FFT cross-correlation of interrogation windows (FFTW, single precision).
 *
 * One rpiv_xcorr holds the complex forward and backward plans of one window size. Plans are made
 * once, on one thread (the FFTW planner is not thread-safe), with FFTW_ESTIMATE so that the same
 * algorithm, hence the same bits, come out on every run. Each thread then owns an
 * rpiv_xcorr_work (aligned buffers from fftwf_malloc) and runs the plans on it through
 * FFTW's new-array execute functions, which are thread-safe.
 *
 * The correlation is circular (no zero padding): R(s) = sum_x a'(x) b'(x + s), indices
 * modulo the window size, with a' = a - mean(a), b' = b - mean(b). Circular correlation has
 * no built-in bias towards zero shift (zero padding weights the plane by the overlap
 * triangle and pulls sub-pixel peaks towards 0); its cost is wrap-around of particles that
 * leave the window, which is negligible once the images are deformed by a predictor (the
 * residual shift is then a fraction of a pixel). See docs/piv.md. */
#ifndef RPIV_XCORR_H
#define RPIV_XCORR_H

#include "rpiv/error.h"

#include <stddef.h>

typedef struct rpiv_xcorr rpiv_xcorr;

/* A thread's workspace: the caller fills a and b (w*h floats each, row-major, stride w)
 * and reads plane after rpiv_xcorr_run. The buffers are owned by the workspace. a2 and b2
 * are spare window buffers for a second pair (rpiv_xcorr_run_pairs). */
typedef struct rpiv_xcorr_work {
    float *a, *b;   /* the two windows (left unchanged by rpiv_xcorr_run)             */
    float *a2, *b2; /* spare windows, w*h each                                        */
    float *plane;   /* the correlation, w*h, circular (FFT) order: see rpiv/peak.h      */
    float *plane2;  /* the second pair's correlation after rpiv_xcorr_run_pairs         */
    float *colmax;  /* column maxima of plane over its rows, w floats (rpiv_peak_find_cm) */
    float *colmax2; /* those of plane2 (after a run of two pairs)                       */
    void *priv;     /* complex buffers, private                                        */
} rpiv_xcorr_work;

/* A window pair read from frames: w x h floats at a (rows stride_a floats apart) and at b. */
typedef struct rpiv_xcorr_src {
    const float *a, *b;
    size_t stride_a, stride_b;
} rpiv_xcorr_src;

enum {
    RPIV_XCORR_RAW = 0,      /* plane = R(s) = sum_x a'(x) b'(x + s)                       */
    RPIV_XCORR_NORMALISE = 1 /* plane = R(s) / sqrt(sum a'^2 sum b'^2): a correlation
                                coefficient, 1 at zero shift for b = a (0 if an energy is 0) */
};

/* Plans for w x h windows (4 <= w, h <= 4096). Call from one thread at a time. */
RPIV_NODISCARD rpiv_status rpiv_xcorr_new(int w, int h, rpiv_xcorr **out);
void rpiv_xcorr_free(rpiv_xcorr *x); /* NULL is a no-op */
void rpiv_xcorr_size(const rpiv_xcorr *x, int *w, int *h);

/* A workspace for x. Call from one thread at a time (outside parallel regions). */
RPIV_NODISCARD rpiv_status rpiv_xcorr_work_new(const rpiv_xcorr *x, rpiv_xcorr_work **out);
void rpiv_xcorr_work_free(rpiv_xcorr_work *ws); /* NULL is a no-op */

/* Correlate ws->a with ws->b into ws->plane (mode RPIV_XCORR_RAW or _NORMALISE). The window
 * energies sum a'^2 and sum b'^2 go to *ea, *eb (either may be NULL). Thread-safe for
 * distinct workspaces. */
void rpiv_xcorr_run(const rpiv_xcorr *x, rpiv_xcorr_work *ws, int mode, double *ea, double *eb);

/* As rpiv_xcorr_run, the windows read from frames: w x h floats starting at a (rows
 * stride_a floats apart) and at b (stride_b). */
void rpiv_xcorr_run_from(const rpiv_xcorr *x, rpiv_xcorr_work *ws, const float *a, size_t stride_a,
                         const float *b, size_t stride_b, int mode, double *ea, double *eb);

/* Correlate count (1 or 2) window pairs src[0..count-1] into ws->plane and ws->plane2; the
 * energies sum a'^2, sum b'^2 of pair k go to e[2k], e[2k+1] (2 count values). Two pairs
 * share each complex transform (a + i b forward, then both cross-spectra in one inverse):
 * 1.5 complex transforms per pair instead of 2 r2c + 1 c2r. A plane's rounding depends (at
 * the 1e-7 level) on the pair it was packed with; callers pair windows in a fixed order. */
void rpiv_xcorr_run_pairs(const rpiv_xcorr *x, rpiv_xcorr_work *ws, const rpiv_xcorr_src *src,
                          int count, int mode, double *e);

#endif /* RPIV_XCORR_H */
