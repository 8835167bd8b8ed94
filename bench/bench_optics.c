/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Ray tracer timings: 1e5 rays traced and binned (target < 20 ms), and 1e7 rays on 1 and 2
 * threads (the ratio is the speed-up). Each case checks its own result: the power balances
 * and the 2-thread profiles equal the 1-thread ones bit for bit.
 * Prints: case rays stations threads ms ref_ms ratio cpu_ms checksum, where ms is the median
 * wall time, ref_ms the target (20 ms) or the 1-thread time, ratio = ms / ref_ms for the
 * target and ref_ms / ms (the speed-up) otherwise, and cpu_ms the process CPU time of the
 * median run (all threads): on a machine shared with other jobs the wall time of one thread
 * is longer than its CPU time. */
#include "rpiv/optics.h"

#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return 1e3 * (double)ts.tv_sec + 1e-6 * (double)ts.tv_nsec;
}

static double cpu_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return 1e3 * (double)ts.tv_sec + 1e-6 * (double)ts.tv_nsec;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median time of `reps` traces (after one warm-up); *out keeps the last result. */
static double time_trace(long nrays, const double *xs, size_t nx, int threads, int reps,
                         rpiv_optics_result **out, double *cpu)
{
    double c[64];
    rpiv_laser l = rpiv_laser_default();
    rpiv_prism p = rpiv_prism_default();
    rpiv_optics_opts o = rpiv_optics_opts_default();
    double t[64];
    l.nrays = nrays;
    o.threads = threads;
    *out = NULL;
    for (int r = -1; r < reps; r++) {
        rpiv_optics_result *res;
        double t0 = now_ms(), c0 = cpu_ms();
        if (rpiv_optics_trace(&l, &p, 8e-3, xs, nx, &o, NULL, &res)) {
            fprintf(stderr, "bench_optics: %s\n", rpiv_errmsg());
            exit(1);
        }
        if (r >= 0) {
            t[r] = now_ms() - t0;
            c[r] = cpu_ms() - c0;
        }
        rpiv_optics_result_free(*out);
        *out = res;
    }
    qsort(c, (size_t)reps, sizeof c[0], cmp_double);
    *cpu = c[reps / 2];
    qsort(t, (size_t)reps, sizeof t[0], cmp_double);
    return t[reps / 2];
}

static double checksum(const rpiv_optics_result *r)
{
    double s = r->stats.transmitted;
    for (size_t i = 0; i < r->nx * r->nz; i++)
        s += r->inten[i] * r->dz_star * (double)(i % 7 + 1);
    return s;
}

static int check(const rpiv_optics_result *r, const rpiv_optics_result *ref, const char *what)
{
    const rpiv_optics_stats *s = &r->stats;
    double bal = s->transmitted + s->refl_face + s->refl_floor + s->tir + s->missed;
    if (fabs(bal - 1) > 1e-12) {
        fprintf(stderr, "bench_optics: %s: power does not balance (%.17g)\n", what, bal);
        return 1;
    }
    if (ref && memcmp(r->inten, ref->inten, r->nx * r->nz * sizeof(double)) != 0) {
        fprintf(stderr, "bench_optics: %s: result depends on the thread count\n", what);
        return 1;
    }
    return 0;
}

int main(void)
{
    double x1 = 4.455, xs[17], c1, c2, load = -1;
    for (int k = 0; k < 17; k++)
        xs[k] = 1 + 0.5 * k;
    int bad = 0, maxthr = omp_get_max_threads();
    rpiv_optics_result *a, *b;
    FILE *fl = fopen("/proc/loadavg", "r");
    if (fl) {
        if (fscanf(fl, "%lf", &load) != 1)
            load = -1;
        fclose(fl);
    }
    printf("# bench_optics: omp max threads %d, load average %.2f\n", maxthr, load);
    printf("# case rays stations threads ms ref_ms ratio cpu_ms checksum\n");

    double t1 = time_trace(100000, &x1, 1, 1, 21, &a, &c1);
    bad |= check(a, NULL, "1e5 x 1");
    printf("trace_bin 100000 1 1 %.3f 20 %.3f %.3f %.12g\n", t1, t1 / 20, c1, checksum(a));
    double t2 = time_trace(100000, &x1, 1, 2, 21, &b, &c2);
    bad |= check(b, a, "1e5 x 1, 2 threads");
    printf("trace_bin 100000 1 2 %.3f %.3f %.3f %.3f %.12g\n", t2, t1, t1 / t2, c2, checksum(b));
    rpiv_optics_result_free(a);
    rpiv_optics_result_free(b);

    t1 = time_trace(100000, xs, 17, 1, 21, &a, &c1);
    bad |= check(a, NULL, "1e5 x 17");
    printf("trace_bin 100000 17 1 %.3f 20 %.3f %.3f %.12g\n", t1, t1 / 20, c1, checksum(a));
    rpiv_optics_result_free(a);

    t1 = time_trace(10000000, xs, 17, 1, 3, &a, &c1);
    bad |= check(a, NULL, "1e7 x 17");
    printf("trace_bin 10000000 17 1 %.1f %.1f 1 %.1f %.12g\n", t1, t1, c1, checksum(a));
    t2 = time_trace(10000000, xs, 17, 2, 3, &b, &c2);
    bad |= check(b, a, "1e7 x 17, 2 threads");
    printf("trace_bin 10000000 17 2 %.1f %.1f %.3f %.1f %.12g\n", t2, t1, t1 / t2, c2, checksum(b));
    printf("# speed-up 1 -> 2 threads at 1e7 rays: %.2f (wall); CPU per ray %.1f ns\n", t1 / t2,
           1e6 * c1 / 1e7);
    rpiv_optics_result_free(a);
    rpiv_optics_result_free(b);
    return bad;
}
