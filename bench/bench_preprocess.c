/* SPDX-License-Identifier: GPL-3.0-or-later */
/* bench/bench_preprocess.c - the cost of each preprocessing operation on a 2560 x 2160 pair
 * (both frames), against the default PIV run of the same pair measured in the same process
 * (rpiv_piv_run, 64 -> 32 -> 32), at 1 and 2 threads. Target (issue 16): clahe + highpass
 * <= 15 % of the default run. Each case's checksum is of its output frames. Arguments, if
 * any: the lists to time instead of the six (e.g. `bench_preprocess clahe,highpass`). */
#include "bench.h"
#include "rpiv/piv.h"
#include "rpiv/preprocess.h"

#include "../tests/piv_testimg.h"

#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { W = 2560, H = 2160, REPS = 5 };
static const double DISP[2] = {3.3187, -1.7421};

static void uniform(void *user, double x, double y, double *u, double *v)
{
    const double *d = user;
    (void)x;
    (void)y;
    *u = d[0];
    *v = d[1];
}

/* Median wall time (ms) of REPS runs of list on copies of a and b; *sum their checksum. */
static double time_list(const char *list, const rpiv_image *a, const rpiv_image *b, int nt,
                        uint64_t *sum)
{
    rpiv_preprocess_params p = rpiv_preprocess_params_default();
    snprintf(p.ops, sizeof p.ops, "%s", list);
    double t[REPS];
    rpiv_image *ca = NULL, *cb = NULL;
    for (int r = 0; r < REPS; r++) {
        if (rpiv_image_copy(a, &ca) || rpiv_image_copy(b, &cb))
            return -1;
        double t0 = bench_now();
        if (rpiv_preprocess_run(&p, ca, nt) || rpiv_preprocess_run(&p, cb, nt))
            return -1;
        t[r] = (bench_now() - t0) * 1e3;
        if (r == REPS - 1) {
            *sum = bench_checksum(bench_checksum(1469598103934665603ULL, ca->px, (size_t)W * H),
                                  cb->px, (size_t)W * H);
        }
        rpiv_image_free(ca);
        rpiv_image_free(cb);
    }
    return bench_median(t, REPS);
}

static double time_piv(const rpiv_image *a, const rpiv_image *b, int nt)
{
    rpiv_piv_params p = rpiv_piv_params_default();
    p.threads = nt;
    rpiv_piv *pv = NULL;
    if (rpiv_piv_new(&p, W, H, NULL, &pv))
        return -1;
    double t[REPS];
    for (int r = 0; r < REPS; r++) {
        rpiv_field *f = NULL;
        double t0 = bench_now();
        if (rpiv_piv_run(pv, a, b, &f))
            return -1;
        t[r] = (bench_now() - t0) * 1e3;
        rpiv_field_free(f);
    }
    rpiv_piv_free(pv);
    return bench_median(t, REPS);
}

int main(int argc, char **argv)
{
    rpiv_init();
    bench_header("bench_preprocess", omp_get_max_threads());
    rpiv_image *a = NULL, *b = NULL;
    if (rpiv_image_new(W, H, &a) || rpiv_image_new(W, H, &b))
        return 1;
    ti_params tp = {W, H, 0.05, 2.5, 3000, 0.01, 100, 4242};
    ti_pair(&tp, uniform, (void *)DISP, a->px, b->px);
    static const char *const all[] = {"clahe", "highpass",  "clahe,highpass",
                                      "cap",   "normalize", "invert"};
    /* arguments: the lists to time instead of all (e.g. for a profiler) */
    const char *const *lists = argc > 1 ? (const char *const *)(argv + 1) : all;
    size_t nlists = argc > 1 ? (size_t)(argc - 1) : sizeof all / sizeof all[0];
    int status = 0;
    printf("case                size       threads    rpiv_ms  piv_ms   ratio checksum\n");
    for (int nt = 1; nt <= 2; nt++) {
        double piv = time_piv(a, b, nt);
        if (piv <= 0) {
            fprintf(stderr, "bench_preprocess: piv: %s\n", rpiv_errmsg());
            return 1;
        }
        for (size_t k = 0; k < nlists; k++) {
            uint64_t sum = 0;
            double ms = time_list(lists[k], a, b, nt, &sum);
            if (ms < 0) {
                fprintf(stderr, "bench_preprocess: %s: %s\n", lists[k], rpiv_errmsg());
                return 1;
            }
            printf("%-19s %dx%d %7d %10.1f %7.1f %7.3f %016llx\n", lists[k], W, H, nt, ms, piv,
                   ms / piv, (unsigned long long)sum);
            if (!strcmp(lists[k], "clahe,highpass"))
                printf("#   clahe + highpass of the pair: %.1f %% of the default PIV run (target "
                       "<= 15 %%) %s\n",
                       100 * ms / piv, ms / piv <= 0.15 ? "ok" : "ABOVE");
        }
    }
    rpiv_image_free(a);
    rpiv_image_free(b);
    return status;
}
