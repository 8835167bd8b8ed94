/* SPDX-License-Identifier: GPL-3.0-or-later */
/* bench/bench_preprocess.c - the cost of each preprocessing operation on a 2560 x 2160 pair
 * (both frames), against the default PIV run of the same pair measured in the same process
 * (rpiv_piv_run, 64 -> 32 -> 32), at 1 and 2 threads, the runs interleaved (PIV, each list,
 * PIV, each list, ...). Target (issue 16): clahe + highpass <= 15 % of the default run (the
 * list clahe,highpass runs the two fused, prep_clahe_highpass: the same bits). Each
 * case's checksum is of its output frames. Arguments, if
 * any: the lists to time instead of the six (e.g. `bench_preprocess clahe,highpass`). */
#include "bench.h"
#include "rpiv/piv.h"
#include "rpiv/preprocess.h"

#include "../tests/piv_testimg.h"

#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

enum { W = 2560, H = 2160, REPS = 7 };
static const double DISP[2] = {3.3187, -1.7421};

static void uniform(void *user, double x, double y, double *u, double *v)
{
    const double *d = user;
    (void)x;
    (void)y;
    *u = d[0];
    *v = d[1];
}

/* The process's CPU time (all threads), s. */
static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Wall time (ms) of one run of list on copies of a and b, *cpu its CPU time (ms, all
 * threads); *sum the checksum of the result. */
static double time_list(const rpiv_preprocess_params *p, const rpiv_image *a, const rpiv_image *b,
                        int nt, uint64_t *sum, double *cpu)
{
    rpiv_image *ca = NULL, *cb = NULL;
    if (rpiv_image_copy(a, &ca) || rpiv_image_copy(b, &cb))
        return -1;
    double t0 = bench_now(), c0 = cpu_now();
    if (rpiv_preprocess_run(p, ca, nt) || rpiv_preprocess_run(p, cb, nt))
        return -1;
    double ms = (bench_now() - t0) * 1e3;
    *cpu = (cpu_now() - c0) * 1e3;
    *sum = bench_checksum(bench_checksum(1469598103934665603ULL, ca->px, (size_t)W * H), cb->px,
                          (size_t)W * H);
    rpiv_image_free(ca);
    rpiv_image_free(cb);
    return ms;
}

/* Wall time (ms) of one default PIV run of the pair, *cpu its CPU time (ms). */
static double time_piv(rpiv_piv *pv, const rpiv_image *a, const rpiv_image *b, double *cpu)
{
    rpiv_field *f = NULL;
    double t0 = bench_now(), c0 = cpu_now();
    if (rpiv_piv_run(pv, a, b, &f))
        return -1;
    double ms = (bench_now() - t0) * 1e3;
    *cpu = (cpu_now() - c0) * 1e3;
    rpiv_field_free(f);
    return ms;
}

static double least(const double *v, int n)
{
    double m = v[0];
    for (int i = 1; i < n; i++)
        m = v[i] < m ? v[i] : m;
    return m;
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
    if (nlists > 16) {
        fprintf(stderr, "bench_preprocess: at most 16 lists\n");
        return 1;
    }
    rpiv_preprocess_params pp[16];
    for (size_t k = 0; k < nlists; k++) {
        pp[k] = rpiv_preprocess_params_default();
        snprintf(pp[k].ops, sizeof pp[k].ops, "%s", lists[k]);
    }
    /* A B A B: each repetition times the PIV run, then every list once, so that a change of
     * the machine's load (it is shared) falls on all of them alike. The median and the least
     * of the REPS times are printed: the least is the estimate of an unloaded machine; cpu_rat
     * the ratio of the median CPU times (all threads; with OMP_WAIT_POLICY=passive the threads
     * waiting at a barrier burn none, so it is the ratio of the work). */
    printf("case                size       threads    med_ms  piv_med   ratio    min_ms  piv_min "
           "  ratio cpu_rat checksum\n");
    for (int nt = 1; nt <= 2; nt++) {
        rpiv_piv_params p = rpiv_piv_params_default();
        p.threads = nt;
        rpiv_piv *pv = NULL;
        if (rpiv_piv_new(&p, W, H, NULL, &pv)) {
            fprintf(stderr, "bench_preprocess: piv: %s\n", rpiv_errmsg());
            return 1;
        }
        double piv[REPS], t[16][REPS], cpiv[REPS], ct[16][REPS];
        uint64_t sum[16] = {0};
        for (int r = 0; r < REPS; r++) {
            piv[r] = time_piv(pv, a, b, &cpiv[r]);
            if (piv[r] < 0) {
                fprintf(stderr, "bench_preprocess: piv: %s\n", rpiv_errmsg());
                return 1;
            }
            for (size_t k = 0; k < nlists; k++) {
                t[k][r] = time_list(&pp[k], a, b, nt, &sum[k], &ct[k][r]);
                if (t[k][r] < 0) {
                    fprintf(stderr, "bench_preprocess: %s: %s\n", lists[k], rpiv_errmsg());
                    return 1;
                }
            }
        }
        rpiv_piv_free(pv);
        double pmin = least(piv, REPS), pmed = bench_median(piv, REPS),
               pcpu = bench_median(cpiv, REPS);
        for (size_t k = 0; k < nlists; k++) {
            double mn = least(t[k], REPS), md = bench_median(t[k], REPS),
                   cpu = bench_median(ct[k], REPS);
            printf("%-19s %dx%d %7d %9.1f %8.1f %7.3f %9.1f %8.1f %7.3f %7.3f %016llx\n", lists[k],
                   W, H, nt, md, pmed, md / pmed, mn, pmin, mn / pmin, cpu / pcpu,
                   (unsigned long long)sum[k]);
            if (!strcmp(lists[k], "clahe,highpass"))
                printf("#   clahe + highpass of the pair, %d thread%s: %.1f %% (medians), %.1f %% "
                       "(least times), %.1f %% (CPU times) of the default PIV run (target <= "
                       "15 %%)\n",
                       nt, nt > 1 ? "s" : "", 100 * md / pmed, 100 * mn / pmin, 100 * cpu / pcpu);
        }
    }
    rpiv_image_free(a);
    rpiv_image_free(b);
    return 0;
}
