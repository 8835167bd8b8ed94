/* SPDX-License-Identifier: GPL-3.0-or-later */
/* bench_xcorr - rpiv_xcorr_run_pairs from cache: what the correlation of two window pairs
 * costs with its glue (packing and mean removal, cross-spectra, unpacking with the column
 * maxima) against its FFTs alone (two forward complex transforms and one inverse, the same
 * FFTW plans as xcorr.c makes: FFTW_ESTIMATE, in place). Window pairs are read with a stride
 * from a 256 x 256 frame of random 12-bit values (cached), as the engine reads them from its
 * frames and strips; one thread; medians of the repeats (argument 1, default 9) of 20 000
 * calls, CPU time. The line's ratio is the whole call over its FFTs; the checksum is that of
 * the last planes.
 *     build/bench/bench_xcorr 9 */
#include "bench.h"
#include "rpiv/xcorr.h"

#include <fftw3.h>

enum { MAXREP = 51, FW = 256, CALLS = 20000 };

static uint64_t rng_state = 0x2f6e2b1a9c0d3e47ULL;

static double rnd(void) /* uniform in [0, 1) */
{
    return bench_rand(&rng_state);
}

/* Microseconds per call of two window pairs n x n: with the glue (*whole) and FFTs alone. */
static int one_size(int n, int reps, const float *fa, const float *fb, double *whole, double *ffts,
                    uint64_t *sum)
{
    rpiv_xcorr *x = NULL;
    rpiv_xcorr_work *ws = NULL;
    fftwf_complex *z = fftwf_malloc((size_t)n * (size_t)n * sizeof *z);
    if (!z || rpiv_xcorr_new(n, n, &x) || rpiv_xcorr_work_new(x, &ws)) {
        fprintf(stderr, "bench_xcorr: out of memory\n");
        fftwf_free(z);
        rpiv_xcorr_free(x);
        return 1;
    }
    for (int i = 0; i < 2 * n * n; i++)
        ((float *)z)[i] = (float)rnd();
    fftwf_plan pf = fftwf_plan_dft_2d(n, n, z, z, FFTW_FORWARD, FFTW_ESTIMATE);
    fftwf_plan pb = fftwf_plan_dft_2d(n, n, z, z, FFTW_BACKWARD, FFTW_ESTIMATE);
    double tw[MAXREP], tf[MAXREP];
    for (int r = 0; r < reps; r++) {
        double t0 = bench_cpu();
        for (int k = 0; k < CALLS; k++) {
            const int o = (k * 37) % (FW - n), p = (k * 91) % (FW - n);
            const rpiv_xcorr_src src[2] = {
                {fa + (size_t)o * FW + (size_t)p, fb + (size_t)p * FW + (size_t)o, FW, FW},
                {fa + (size_t)p * FW + (size_t)o, fb + (size_t)o * FW + (size_t)p, FW, FW}};
            double e[4];
            rpiv_xcorr_run_pairs(x, ws, src, 2, RPIV_XCORR_RAW, e);
        }
        double t1 = bench_cpu();
        for (int k = 0; k < CALLS; k++) { /* as bench_piv's bound: values left to grow */
            fftwf_execute_dft(pf, z, z);
            fftwf_execute_dft(pf, z, z);
            fftwf_execute_dft(pb, z, z);
        }
        double t2 = bench_cpu();
        tw[r] = 1e6 * (t1 - t0) / CALLS;
        tf[r] = 1e6 * (t2 - t1) / CALLS;
    }
    *whole = bench_median(tw, reps);
    *ffts = bench_median(tf, reps);
    *sum = bench_checksum(bench_checksum(0, ws->plane, (size_t)n * (size_t)n), ws->plane2,
                          (size_t)n * (size_t)n);
    fftwf_destroy_plan(pf);
    fftwf_destroy_plan(pb);
    fftwf_free(z);
    rpiv_xcorr_work_free(ws);
    rpiv_xcorr_free(x);
    return 0;
}

int main(int argc, char **argv)
{
    int reps = argc > 1 ? atoi(argv[1]) : 9;
    reps = reps < 1 ? 1 : (reps > MAXREP ? MAXREP : reps);
    bench_header("bench_xcorr", 1);
    printf("# %d calls of rpiv_xcorr_run_pairs (two window pairs) from cache, %d repeats, "
           "median CPU time; ref = its FFTs alone (2 forward + 1 inverse complex)\n",
           CALLS, reps);
    float *fa = malloc(sizeof(float) * FW * FW), *fb = malloc(sizeof(float) * FW * FW);
    if (!fa || !fb)
        return 1;
    for (int i = 0; i < FW * FW; i++) {
        fa[i] = (float)(int)(4096 * rnd());
        fb[i] = (float)(int)(4096 * rnd());
    }
    bench_columns();
    int bad = 0;
    const int sizes[2] = {32, 64};
    for (int k = 0; k < 2; k++) {
        double whole, ffts;
        uint64_t sum;
        if (one_size(sizes[k], reps, fa, fb, &whole, &ffts, &sum)) {
            bad = 1;
            continue;
        }
        /* the line's times are for 1000 calls, in ms (= us per call) */
        bench_line("xcorr_two_pairs", sizes[k], sizes[k], 1, whole, ffts, sum);
        printf("#   %d px: %.2f us per call of two pairs, FFTs %.2f us, glue %.2f us (%.0f %%)\n",
               sizes[k], whole, ffts, whole - ffts, 100 * (whole - ffts) / whole);
    }
    free(fa);
    free(fb);
    return bad;
}
