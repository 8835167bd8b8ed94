/* SPDX-License-Identifier: GPL-3.0-or-later */
/* bench_peak - rpiv_peak_find on correlation planes like the PIV engine's: windows of random
 * Gaussian particles (0.05 particles/px, amplitudes 0.3-1, uniform noise), b moved by a
 * known shift: one plane in three by up to a quarter of the window (a first pass), the others
 * by less than half a pixel (the deformed passes: the peak wraps around the plane's corner),
 * correlated with rpiv_xcorr_run (raw, as the engine correlates). 32 x 32 and 64 x 64
 * windows, two kinds of particles: "d2.5" (d_tau 2.5 px, sigma 0.625 px, 1 % noise, every
 * particle in both windows: like bench_piv's pair; in 1-2 % of the planes the highest value
 * outside the peak's neighbourhood is on the peak's flank, 2 % in bench_piv) and "d3.6"
 * (sigma 0.9 px, 2 % noise, 5 % of the particles of b replaced by others: the broader peak's
 * flank tops the noise in 10-30 % of the planes). The current rpiv_peak_find (new_ns) is
 * timed against the copy of the code it replaced (peak_find_ref, tests/test_peak_ref.h;
 * ref_ns), both on every plane with the Gaussian fit and the whole plane searched (the
 * engine's call), 1 MB of planes at a time brought into the cache first, the two in
 * alternating order; figures are ns per plane, medians of the repeats (argument 1, default
 * 9), CPU time (steadier than the wall clock on a shared machine), one thread. The checksum
 * is that of the results. The program fails (exit 1, "FAIL") if a field of any result
 * differs from the reference's by a bit, for each sub-pixel method, with max_shift 0 and
 * w/4. Each size is followed by the spline estimator's cost (a "#" line).
 *     build/bench/bench_peak 15 */
#include "../tests/test_peak_ref.h"
#include "bench.h"
#include "rpiv/peak.h"
#include "rpiv/xcorr.h"

#include <math.h>

enum { MAXREP = 51 };

static uint64_t rng_state = 0x3187a2b9c4d5e6f1ULL;

static double rnd(void) /* uniform in [0, 1) */
{
    return bench_rand(&rng_state);
}

static void splat(float *win, int n, double x, double y, double amp, double s)
{
    int i0 = (int)floor(x - 3 * s), i1 = (int)ceil(x + 3 * s);
    int j0 = (int)floor(y - 3 * s), j1 = (int)ceil(y + 3 * s);
    for (int j = j0 < 0 ? 0 : j0; j <= j1 && j < n; j++)
        for (int i = i0 < 0 ? 0 : i0; i <= i1 && i < n; i++) {
            double dx = i - x, dy = j - y;
            win[j * n + i] += (float)(amp * exp(-(dx * dx + dy * dy) / (2 * s * s)));
        }
}

/* One window pair of n x n with b moved by (dx, dy), into a and b: particle images of sigma
 * s, uniform noise of amplitude noise, a fraction loss of the particles of b replaced. */
static void make_pair(float *a, float *b, int n, double dx, double dy, double s, double noise,
                      double loss)
{
    const double margin = 12, side = n + 2 * margin;
    int np = (int)(0.05 * side * side);
    for (int k = 0; k < n * n; k++) {
        a[k] = (float)(noise * rnd());
        b[k] = (float)(noise * rnd());
    }
    for (int k = 0; k < np; k++) {
        double x = rnd() * side - margin, y = rnd() * side - margin, amp = 0.3 + 0.7 * rnd();
        double fate = rnd();
        splat(a, n, x, y, amp, s);
        if (fate < loss) /* lost in b, another one appears */
            splat(b, n, rnd() * side - margin, rnd() * side - margin, amp, s);
        else
            splat(b, n, x + dx, y + dy, amp, s);
    }
}

static uint64_t hash_bytes(uint64_t h, const void *v, size_t n)
{
    const unsigned char *c = v;
    for (size_t i = 0; i < n; i++) {
        h ^= c[i];
        h *= 1099511628211ULL;
    }
    return h;
}

typedef void (*find_fn)(const float *, int, int, int, rpiv_subpixel, rpiv_peak *);

/* Called through a volatile pointer: the compiler cannot specialise the reference (a static
 * function here) for the constant arguments, which the library's function does not get. */
static find_fn volatile fn_new = rpiv_peak_find, fn_ref = peak_find_ref;

static void run(find_fn fn, const float *planes, int n, int k0, int k1, int max_shift,
                rpiv_subpixel m, rpiv_peak *out)
{
    for (int k = k0; k < k1; k++)
        fn(planes + (size_t)k * (size_t)n * (size_t)n, n, n, max_shift, m, out + k);
}

/* One repeat: ns per plane of new (tn) and reference (tr) over all planes, a chunk of 1 MB
 * at a time brought into the cache first (the engine searches a plane the FFT just wrote). */
static void time_all(const float *planes, int n, int count, int order, rpiv_peak *pa, rpiv_peak *pb,
                     double *tn, double *tr)
{
    const int chunk = (1 << 18) / (n * n);
    double sn = 0, sr = 0;
    for (int k0 = 0; k0 < count; k0 += chunk) {
        int k1 = k0 + chunk < count ? k0 + chunk : count;
        volatile float sink = 0;
        float acc = 0;
        for (size_t e = (size_t)k0 * (size_t)(n * n); e < (size_t)k1 * (size_t)(n * n); e += 16)
            acc += planes[e]; /* a float of each cache line */
        sink = acc;
        (void)sink;
        for (int pass = 0; pass < 2; pass++) {
            double t0 = bench_cpu();
            if ((pass + order) % 2 == 0) {
                run(fn_new, planes, n, k0, k1, 0, RPIV_SUBPIXEL_GAUSS, pb);
                sn += bench_cpu() - t0;
            } else {
                run(fn_ref, planes, n, k0, k1, 0, RPIV_SUBPIXEL_GAUSS, pa);
                sr += bench_cpu() - t0;
            }
        }
    }
    *tn = 1e9 * sn / count;
    *tr = 1e9 * sr / count;
}

/* The spline estimator's cost against the 3-point Gaussian's on the same planes (whole plane
 * searched, as the engine does; medians of reps, in alternating order), and how often it
 * keeps the 3-point fit (a non-positive sample in its 5 x 5 neighbourhood, ...). */
static void spline_cost(const float *planes, int n, int count, int reps, rpiv_peak *pa,
                        rpiv_peak *pb)
{
    double tg[MAXREP], ts[MAXREP];
    for (int r = 0; r < reps; r++)
        for (int pass = 0; pass < 2; pass++) {
            int spline = (pass + r) % 2;
            double t0 = bench_cpu();
            run(fn_new, planes, n, 0, count, 0, spline ? RPIV_SUBPIXEL_SPLINE : RPIV_SUBPIXEL_GAUSS,
                spline ? pb : pa);
            (spline ? ts : tg)[r] = 1e9 * (bench_cpu() - t0) / count;
        }
    int same = 0;
    for (int k = 0; k < count; k++)
        same += pa[k].dx == pb[k].dx && pa[k].dy == pb[k].dy;
    printf("#   spline: %.1f ns per plane, gauss %.1f ns; %.1f %% of the planes keep the 3-point "
           "fit\n",
           bench_median(ts, reps), bench_median(tg, reps), 100.0 * same / count);
}

static int bench_size(const char *kind, int n, int count, int reps, double s, double noise,
                      double loss)
{
    rpiv_xcorr *x = NULL;
    rpiv_xcorr_work *ws = NULL;
    float *planes = malloc((size_t)count * (size_t)n * (size_t)n * sizeof *planes);
    rpiv_peak *pa = malloc((size_t)count * sizeof *pa), *pb = malloc((size_t)count * sizeof *pb);
    int fail = 1;
    if (!planes || !pa || !pb || rpiv_xcorr_new(n, n, &x) || rpiv_xcorr_work_new(x, &ws))
        goto cleanup;
    for (int k = 0; k < count; k++) {
        double big = 0.25 * n, dx, dy;
        if (k % 3 == 0)
            dx = big * (2 * rnd() - 1), dy = big * (2 * rnd() - 1);
        else
            dx = rnd() - 0.5, dy = rnd() - 0.5;
        make_pair(ws->a, ws->b, n, dx, dy, s, noise, loss);
        rpiv_xcorr_run(x, ws, RPIV_XCORR_RAW, NULL, NULL);
        memcpy(planes + (size_t)k * (size_t)n * (size_t)n, ws->plane,
               (size_t)n * (size_t)n * sizeof *planes);
    }

    /* agreement: every method, whole plane and a search range */
    int bad = 0;
    uint64_t h = 1469598103934665603ULL;
    for (int m = 0; m < 3; m++)
        for (int r = 0; r < 2; r++) {
            int ms = r ? n / 4 : 0;
            run(fn_ref, planes, n, 0, count, ms, (rpiv_subpixel)m, pa);
            run(fn_new, planes, n, 0, count, ms, (rpiv_subpixel)m, pb);
            for (int k = 0; k < count; k++) {
                if (!peak_same(pa + k, pb + k) && bad++ < 5)
                    printf("FAIL: %s %dx%d plane %d method %d max_shift %d: new (%d %d %.17g %.17g "
                           "%.9g %.9g %.9g %d) ref (%d %d %.17g %.17g %.9g %.9g %.9g %d)\n",
                           kind, n, n, k, m, ms, pb[k].ix, pb[k].iy, pb[k].dx, pb[k].dy,
                           (double)pb[k].value, (double)pb[k].second, (double)pb[k].ratio,
                           pb[k].fit_ok, pa[k].ix, pa[k].iy, pa[k].dx, pa[k].dy,
                           (double)pa[k].value, (double)pa[k].second, (double)pa[k].ratio,
                           pa[k].fit_ok);
                const rpiv_peak *q = pb + k;
                h = hash_bytes(h, &q->dx, sizeof q->dx);
                h = hash_bytes(h, &q->dy, sizeof q->dy);
                h = hash_bytes(h, &q->ix, sizeof q->ix);
                h = hash_bytes(h, &q->iy, sizeof q->iy);
                h = hash_bytes(h, &q->value, sizeof q->value);
                h = hash_bytes(h, &q->second, sizeof q->second);
                h = hash_bytes(h, &q->ratio, sizeof q->ratio);
                h = hash_bytes(h, &q->fit_ok, sizeof q->fit_ok);
            }
        }

    double tn[MAXREP], tr[MAXREP], q[MAXREP];
    for (int r = 0; r < reps; r++) {
        time_all(planes, n, count, r % 2, pa, pb, tn + r, tr + r);
        q[r] = tn[r] / tr[r];
    }
    char size[32];
    snprintf(size, sizeof size, "%dx%d", n, n);
    double mn = bench_median(tn, reps), mr = bench_median(tr, reps), mq = bench_median(q, reps);
    printf("%-6s %-8s %7d %10.1f %10.1f %7.3f %016llx%s\n", kind, size, count, mn, mr, mq,
           (unsigned long long)h, bad ? " FAIL" : "");
    fflush(stdout);
    fail = bad != 0;
    spline_cost(planes, n, count, reps, pa, pb);
cleanup:
    rpiv_xcorr_work_free(ws);
    rpiv_xcorr_free(x);
    free(planes);
    free(pa);
    free(pb);
    return fail;
}

int main(int argc, char **argv)
{
    int reps = argc > 1 ? atoi(argv[1]) : 9;
    if (reps < 1 || reps > MAXREP)
        reps = 9;
    bench_header("bench_peak", 1);
    printf("# ns per plane, median of %d repeats; ratio = median of new/ref\n", reps);
    printf("%-6s %-8s %7s %10s %10s %7s %s\n", "planes", "size", "count", "new_ns", "ref_ns",
           "ratio", "checksum");
    int fail = bench_size("d2.5", 32, 4000, reps, 0.625, 0.01, 0);
    fail |= bench_size("d2.5", 64, 2000, reps, 0.625, 0.01, 0);
    fail |= bench_size("d3.6", 32, 4000, reps, 0.9, 0.02, 0.05);
    fail |= bench_size("d3.6", 64, 2000, reps, 0.9, 0.02, 0.05);
    if (fail)
        printf("FAIL: rpiv_peak_find differs from the reference\n");
    return fail;
}
