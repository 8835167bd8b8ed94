/* SPDX-License-Identifier: GPL-3.0-or-later */
/* bench_synth - pairs per second of the synthetic-image generator on the full sensor
 * (2560 x 2160, 0.05 particles/px: the figure), for 1 thread and all threads: the
 * median wall time and the median CPU time of all threads per pair. Checks the particle count
 * and that the pair is identical for every thread count (checksum). */
#include "rpiv/config.h"
#include "rpiv/synth.h"

#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double clock_s(clockid_t id)
{
    struct timespec ts;
    clock_gettime(id, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double checksum(const rpiv_image *a, const rpiv_image *b)
{
    double s = 0;
    size_t n = (size_t)a->w * (size_t)a->h;
    for (size_t i = 0; i < n; i++)
        s += (double)a->px[i] * (double)(i % 7 + 1) + (double)b->px[i] * (double)(i % 5 + 1);
    return s;
}

/* One case: returns 0 if its checks pass. */
static int run_case(const char *name, rpiv_experiment *e, int reps)
{
    rpiv_synth *s;
    if (rpiv_config_synth_new(e, NULL, &s)) {
        fprintf(stderr, "%s: %s\n", name, rpiv_errmsg());
        return 1;
    }
    rpiv_synth_info in;
    rpiv_synth_get_info(s, &in);
    double expect =
        e->particles.density_ppp * (in.region[2] - in.region[0]) * (in.region[3] - in.region[1]);
    int bad = !(in.nparticles == (size_t)(expect + 0.5));
    rpiv_image a = {in.width_px, in.height_px, 0, NULL}, b = a;
    size_t npx = (size_t)in.width_px * (size_t)in.height_px;
    a.px = malloc(npx * sizeof *a.px);
    b.px = malloc(npx * sizeof *b.px);
    if (!a.px || !b.px) {
        fprintf(stderr, "%s: out of memory\n", name);
        return 1;
    }
    int maxt = omp_get_max_threads();
    double ref_sum = 0;
    for (int t = 1; t <= maxt; t = t < maxt ? maxt : maxt + 1) {
        omp_set_num_threads(t);
        double ms[16], cpu[16], sum = 0;
        if (rpiv_synth_pair(s, 0, &a, &b)) /* warm-up */
            bad = 1;
        for (int r = 0; r < reps; r++) {
            double t0 = clock_s(CLOCK_MONOTONIC), c0 = clock_s(CLOCK_PROCESS_CPUTIME_ID);
            if (rpiv_synth_pair(s, (unsigned long)r, &a, &b))
                bad = 1;
            ms[r] = 1e3 * (clock_s(CLOCK_MONOTONIC) - t0);
            cpu[r] = 1e3 * (clock_s(CLOCK_PROCESS_CPUTIME_ID) - c0);
            if (r == 0)
                sum = checksum(&a, &b);
        }
        qsort(ms, (size_t)reps, sizeof ms[0], cmp_double);
        qsort(cpu, (size_t)reps, sizeof cpu[0], cmp_double);
        if (t == 1)
            ref_sum = sum;
        else if (sum != ref_sum)
            bad = 1;
        printf("%-20s %dx%d %7zu %2d %9.1f %8.1f %8.1f %7.2f %.17g%s\n", name, in.width_px,
               in.height_px, in.nparticles, t, ms[reps / 2], ms[0], cpu[reps / 2],
               1e3 / ms[reps / 2], sum, bad ? "  FAILED" : "");
    }
    omp_set_num_threads(maxt);
    free(a.px);
    free(b.px);
    rpiv_synth_free(s);
    return bad;
}

int main(int argc, char **argv)
{
    int reps = argc > 1 ? atoi(argv[1]) : 5;
    if (reps < 1 || reps > 16)
        reps = 5;
    rpiv_init();
    printf("# bench_synth: %d repeats, median and min wall time per pair, threads up to %d\n", reps,
           omp_get_max_threads());
    printf("# case               size      particles thr median_ms   min_ms   cpu_ms pairs/s "
           "checksum\n");
    int bad = 0;
    rpiv_experiment e = rpiv_experiment_default();
    e.particles.density_ppp = 0.05; /* the figure: about 280 000 particles */
    strcpy(e.synth.flow, "uniform:3.3187,-1.7421");
    bad |= run_case("rpiv-sheet-uniform", &e, reps);
    e.sheet.kind = RPIV_SHEET_UNIFORM;
    bad |= run_case("volume-uniform", &e, reps);
    e.sheet.kind = RPIV_SHEET_GAUSS;
    strcpy(e.synth.flow, "oseen:6,48");
    bad |= run_case("ppiv-sheet-oseen", &e, reps);
    e = rpiv_experiment_default();
    e.particles.density_ppp = 0.05;
    bad |= run_case("default-duct", &e, reps);
    return bad;
}
