/* SPDX-License-Identifier: GPL-3.0-or-later */
/* bench/bench_piv.c - speed and memory of the PIV engine on a synthetic 2560 x 2160 16-bit
 * pair (the paper's camera): particles d_tau = 2.5 px, 0.05 per pixel, uniform displacement
 * (3.3, -1.7) px, 1 % Gaussian noise.
 *
 * Cases (each in its own process, so that its peak RSS is its own):
 *   piv_3pass    the full 64 -> 32 -> 32 run at 50 % overlap on the pair in memory (load,
 *                three passes with deformation and validation), 1 and 2 threads; reference:
 *                the bare FFTs the run needs (the same FFTW plans, the same count:
 *                per window and pass one forward complex transform, per two windows one
 *                inverse, on cached buffers), same threads.
 *   one_pair     the pair read from its TIFF files and processed as `rpiv piv` does; peak RSS.
 *   ensemble     sum of correlation over N pairs (default 100: four distinct pairs listed 25
 *                times) read from TIFF files; reference: N times the bare FFTs. Pairs per
 *                second and peak RSS.
 * Every case checks its result: RMS error against the known displacement must be <= 0.012
 * px per component, otherwise the line is marked FAILED and the exit status is 1.
 * Environment: BENCH_ENSEMBLE_PAIRS=N (default 100), BENCH_REPEATS=R (default 5, at most 16),
 * BENCH_ONLY=1 (only the one-thread run, for a profiler). */
#include "bench.h"
#include "bench_field.h"

#include "../tests/piv_testimg.h"
#include "rpiv/ensemble.h"
#include "rpiv/image.h"
#include "rpiv/piv.h"
#include "rpiv/series.h"

#include <fftw3.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <omp.h>
#include <sys/wait.h>
#include <unistd.h>

enum { W = 2560, H = 2160, NDISTINCT = 4 };
static const double DISP[2] = {3.3, -1.7};
static char dir[64];

static void pair_paths(int i, char *pa, char *pb, size_t n)
{
    snprintf(pa, n, "%s/pair%da.tif", dir, i);
    snprintf(pb, n, "%s/pair%db.tif", dir, i);
}

/* The 16-bit pair i: offset 100, particle peak 3000, noise 1 % of the peak, rounded. */
static int make_pair(int i)
{
    rpiv_image *a = NULL, *b = NULL;
    char pa[128], pb[128];
    if (rpiv_image_new(W, H, &a) || rpiv_image_new(W, H, &b))
        return 1;
    ti_params tp = {W, H, 0.05, 2.5, 3000, 0.01, 100, 20240 + (uint64_t)i};
    ti_pair(&tp, ti_uniform, (void *)DISP, a->px, b->px);
    for (size_t k = 0; k < (size_t)W * H; k++) {
        a->px[k] = fminf(65535.0f, fmaxf(0.0f, rintf(a->px[k])));
        b->px[k] = fminf(65535.0f, fmaxf(0.0f, rintf(b->px[k])));
    }
    pair_paths(i, pa, pb, sizeof pa);
    int bad = rpiv_image_save_tiff16(a, pa) || rpiv_image_save_tiff16(b, pb);
    rpiv_image_free(a);
    rpiv_image_free(b);
    return bad;
}

static rpiv_pairs *pairs_of(int n)
{
    char **args = calloc(2 * (size_t)n, sizeof *args);
    rpiv_pairs *p = NULL;
    for (int i = 0; i < n; i++) {
        args[2 * i] = malloc(128);
        args[2 * i + 1] = malloc(128);
        pair_paths(i % NDISTINCT, args[2 * i], args[2 * i + 1], 128);
    }
    /* a list file keeps repeated pairs (the a/b matcher would reject duplicates) */
    char list[128];
    snprintf(list, sizeof list, "%s/pairs.txt", dir);
    FILE *fp = fopen(list, "w");
    for (int i = 0; fp && i < n; i++)
        fprintf(fp, "%s %s\n", args[2 * i], args[2 * i + 1]);
    if (fp)
        fclose(fp);
    char *one[1] = {list};
    if (rpiv_pairs_from_args(1, one, RPIV_PAIR_AB, &p))
        fprintf(stderr, "bench_piv: %s\n", rpiv_errmsg());
    for (int i = 0; i < 2 * n; i++)
        free(args[i]);
    free(args);
    return p;
}

static uint64_t field_sum(const rpiv_field *f)
{
    size_t n = (size_t)f->nx * (size_t)f->ny;
    return bench_checksum(bench_checksum(0, f->u, n), f->v, n);
}

/* The bare FFTs of a run of plan pv, FFTW_ESTIMATE plans on cached buffers, rows of windows
 * split among `threads`. As the engine runs them (conventional = 0): per pass and row, one
 * forward complex transform per window (a + i b packed) and one inverse per two windows (two
 * cross-spectra packed), in place. For comparison only (conventional = 1): 2 r2c + 1 c2r per
 * window, what rpiv ran before it packed windows. ms (CPU time in *cpu_ms). */
static double fft_bound(const rpiv_piv *pv, int threads, int repeats, int conventional,
                        double *cpu_ms)
{
    const rpiv_piv_params *p = rpiv_piv_params_of(pv);
    double t[16], tc[16];
    for (int r = 0; r < repeats; r++) {
        double total = 0, ctotal = 0;
        for (int k = 0; k < p->npass; k++) {
            rpiv_field *g = NULL;
            if (rpiv_piv_grid(pv, k, &g))
                return -1;
            int ww = p->win_w[k], wh = p->win_h[k], nx = g->nx, ny = g->ny;
            rpiv_field_free(g);
            size_t nc = (size_t)ww * (size_t)wh;
            float *in[64];
            fftwf_complex *z[64][2];
            for (int th = 0; th < threads; th++) {
                in[th] = fftwf_malloc(nc * sizeof(float));
                for (int q = 0; q < 2; q++)
                    z[th][q] = fftwf_malloc(nc * sizeof(fftwf_complex));
                for (size_t i = 0; i < nc; i++) {
                    in[th][i] = (float)((i * 7919) % 113);
                    for (int q = 0; q < 2; q++) {
                        z[th][q][i][0] = in[th][i];
                        z[th][q][i][1] = (float)((i * 104729) % 127);
                    }
                }
            }
            fftwf_plan fwd, inv;
            if (conventional) {
                fwd = fftwf_plan_dft_r2c_2d(wh, ww, in[0], z[0][0], FFTW_ESTIMATE);
                inv = fftwf_plan_dft_c2r_2d(wh, ww, z[0][1], in[0], FFTW_ESTIMATE);
            } else {
                fwd = fftwf_plan_dft_2d(wh, ww, z[0][0], z[0][0], FFTW_FORWARD, FFTW_ESTIMATE);
                inv = fftwf_plan_dft_2d(wh, ww, z[0][1], z[0][1], FFTW_BACKWARD, FFTW_ESTIMATE);
            }
            double t0 = bench_now(), c0 = bench_cpu();
#pragma omp parallel for schedule(dynamic, 4) num_threads(threads)
            for (int row = 0; row < ny; row++) {
                int th = omp_get_thread_num();
                for (int i = 0; i < nx; i += 2) {
                    const int nwin = i + 1 < nx ? 2 : 1;
                    if (conventional) {
                        for (int q = 0; q < nwin; q++) {
                            fftwf_execute_dft_r2c(fwd, in[th], z[th][0]);
                            fftwf_execute_dft_r2c(fwd, in[th], z[th][1]);
                            fftwf_execute_dft_c2r(inv, z[th][1], in[th]);
                            in[th][0] = 1.0f; /* keep the values bounded */
                        }
                        continue;
                    }
                    for (int q = 0; q < nwin; q++)
                        fftwf_execute_dft(fwd, z[th][q], z[th][q]);
                    fftwf_execute_dft(inv, z[th][1], z[th][1]);
                    z[th][0][0][0] = z[th][1][0][0] = 1.0f; /* keep the values bounded */
                }
            }
            total += bench_now() - t0;
            ctotal += bench_cpu() - c0;
            fftwf_destroy_plan(fwd);
            fftwf_destroy_plan(inv);
            for (int th = 0; th < threads; th++) {
                fftwf_free(in[th]);
                for (int q = 0; q < 2; q++)
                    fftwf_free(z[th][q]);
            }
        }
        t[r] = 1e3 * total;
        tc[r] = 1e3 * ctotal;
    }
    if (cpu_ms)
        *cpu_ms = bench_median(tc, repeats);
    return bench_median(t, repeats);
}

/* One FFTW transform of each kind the engine could use, per window size: microseconds per
 * transform (FFTW_ESTIMATE plans, cached buffers, one thread). Why the engine packs windows
 * into complex transforms: FFTW's complex codelets are SIMD, its real ones mostly not. */
static void fft_kinds(void)
{
    const int sizes[2] = {32, 64};
    for (int k = 0; k < 2; k++) {
        int n = sizes[k], reps = 4000000 / (n * n);
        size_t nn = (size_t)n * (size_t)n;
        float *r = fftwf_malloc(nn * sizeof *r);
        fftwf_complex *c = fftwf_malloc(nn * sizeof *c), *z = fftwf_malloc(nn * sizeof *z);
        for (size_t i = 0; i < nn; i++) {
            r[i] = (float)((i * 7919) % 113);
            z[i][0] = r[i];
            z[i][1] = (float)((i * 104729) % 127);
        }
        fftwf_plan f = fftwf_plan_dft_r2c_2d(n, n, r, c, FFTW_ESTIMATE);
        fftwf_plan b = fftwf_plan_dft_c2r_2d(n, n, c, r, FFTW_ESTIMATE);
        fftwf_plan cz = fftwf_plan_dft_2d(n, n, z, z, FFTW_FORWARD, FFTW_ESTIMATE);
        double us[3];
        for (int kind = 0; kind < 3; kind++) {
            double t0 = bench_now();
            for (int i = 0; i < reps; i++) {
                if (kind == 0)
                    fftwf_execute_dft_r2c(f, r, c);
                else if (kind == 1)
                    fftwf_execute_dft_c2r(b, c, r);
                else
                    fftwf_execute_dft(cz, z, z);
                r[0] = z[0][0] = 1.0f; /* keep the values bounded */
            }
            us[kind] = 1e6 * (bench_now() - t0) / reps;
            if (kind == 0) /* c2r destroys its input: give it a spectrum again */
                fftwf_execute_dft_r2c(f, r, c);
        }
        printf("#   FFTW %dx%d, one transform: r2c %.2f us, c2r %.2f us, complex %.2f us -> per "
               "window: 2 r2c + 1 c2r %.2f us, packed 1.5 complex %.2f us\n",
               n, n, us[0], us[1], us[2], 2 * us[0] + us[1], 1.5 * us[2]);
        fftwf_destroy_plan(f);
        fftwf_destroy_plan(b);
        fftwf_destroy_plan(cz);
        fftwf_free(r);
        fftwf_free(c);
        fftwf_free(z);
    }
}

static int env_int(const char *name, int def)
{
    const char *s = getenv(name);
    return s && atoi(s) > 0 ? atoi(s) : def;
}

/* ---- cases (run in a child process) ------------------------------------------------------ */

/* As the rpiv program does (app/rpiv.c): frames freed and loaded again stay in the heap. Set
 * in the child, so that it does not inherit the parent's retained blocks (written there, they
 * would be copied on write). */
static void keep_large_blocks(void)
{
#if defined(__GLIBC__) && defined(M_MMAP_THRESHOLD) && defined(M_TRIM_THRESHOLD)
    mallopt(M_MMAP_THRESHOLD, 1 << 30);
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

static int case_run(int threads)
{
    int repeats = env_int("BENCH_REPEATS", 5);
    rpiv_pairs *pairs = pairs_of(1);
    rpiv_image *a = NULL, *b = NULL;
    rpiv_piv *pv = NULL;
    rpiv_field *f = NULL;
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.threads = threads;
    if (!pairs || rpiv_pairs_load(pairs, 0, &a, &b) || rpiv_piv_new(&prm, W, H, NULL, &pv) ||
        rpiv_piv_run(pv, a, b, &f)) { /* warm-up */
        fprintf(stderr, "bench_piv: %s\n", rpiv_errmsg());
        return 1;
    }
    double err = bench_field_rms(f, DISP);
    uint64_t sum = field_sum(f);
    rpiv_field_free(f);
    double t[16], tc[16], ph[4][16];
    for (int r = 0; r < repeats; r++) {
        rpiv_field *fk[3] = {NULL, NULL, NULL};
        double t0 = bench_now(), c0 = bench_cpu();
        if (rpiv_piv_load(pv, a, b))
            return 1;
        double t1 = bench_now();
        ph[0][r] = 1e3 * (t1 - t0);
        for (int k = 0; k < 3; k++) {
            double s0 = bench_now();
            if (rpiv_piv_step(pv, k, k ? fk[k - 1] : NULL, &fk[k]))
                return 1;
            ph[k + 1][r] = 1e3 * (bench_now() - s0);
        }
        t[r] = 1e3 * (bench_now() - t0);
        tc[r] = 1e3 * (bench_cpu() - c0);
        if (field_sum(fk[2]) != sum) {
            printf("# FAILED: repeated runs give different results\n");
            return 1;
        }
        for (int k = 0; k < 3; k++)
            rpiv_field_free(fk[k]);
    }
    double fft_cpu = 0, run = bench_median(t, repeats),
           fft = fft_bound(pv, threads, 3, 0, &fft_cpu);
    double run_cpu = bench_median(tc, repeats);
    bench_line("piv_3pass", W, H, threads, run, fft, sum);
    printf("#   CPU time (all threads): run %.1f ms, bare FFTs %.1f ms, ratio %.2f\n", run_cpu,
           fft_cpu, run_cpu / fft_cpu);
    double conv_cpu = 0;
    fft_bound(pv, threads, 3, 1, &conv_cpu);
    printf("#   for comparison, the conventional 2 r2c + 1 c2r per window: bare FFTs %.1f ms CPU, "
           "run / those %.2f\n",
           conv_cpu, run_cpu / conv_cpu);
    printf("#   phases (median ms): load %.1f, pass 1 (64 px) %.1f, pass 2 (32 px, deform) %.1f, "
           "pass 3 %.1f; RMS error %.4f px (limit 0.012)%s\n",
           bench_median(ph[0], repeats), bench_median(ph[1], repeats), bench_median(ph[2], repeats),
           bench_median(ph[3], repeats), err, err <= 0.012 ? "" : " FAILED");
    rpiv_piv_free(pv);
    rpiv_image_free(a);
    rpiv_image_free(b);
    rpiv_pairs_free(pairs);
    return err <= 0.012 ? 0 : 1;
}

typedef struct sink_ctx {
    double err;
} sink_ctx;

static rpiv_status sink(void *user, size_t i, const rpiv_field *f)
{
    (void)i;
    ((sink_ctx *)user)->err = bench_field_rms(f, DISP);
    return RPIV_OK;
}

static int case_one_pair(int threads)
{
    keep_large_blocks();
    rpiv_pairs *pairs = pairs_of(1);
    rpiv_piv *pv = NULL;
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.threads = threads;
    sink_ctx s = {1e9};
    double t0 = bench_now();
    if (!pairs || rpiv_piv_new(&prm, W, H, NULL, &pv) ||
        rpiv_series_run(pv, pairs, sink, &s, NULL)) {
        fprintf(stderr, "bench_piv: %s\n", rpiv_errmsg());
        return 1;
    }
    double ms = 1e3 * (bench_now() - t0);
    printf("#   one pair read from 16-bit TIFF files and processed, %d threads: %.0f ms, RMS "
           "error %.4f px, peak RSS %.0f MB (target < 150 MB)%s\n",
           threads, ms, s.err, bench_maxrss_mb(),
           s.err <= 0.012 && bench_maxrss_mb() < 150 ? "" : " FAILED");
    rpiv_piv_free(pv);
    rpiv_pairs_free(pairs);
    return s.err <= 0.012 ? 0 : 1;
}

static int case_ensemble(int threads, int n)
{
    keep_large_blocks();
    rpiv_pairs *pairs = pairs_of(n);
    rpiv_piv *pv = NULL;
    rpiv_field *f = NULL;
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.threads = threads;
    prm.ensemble = 1;
    double t0 = bench_now();
    if (!pairs || rpiv_piv_new(&prm, W, H, NULL, &pv) ||
        rpiv_series_ensemble(pv, pairs, NULL, &f)) {
        fprintf(stderr, "bench_piv: %s\n", rpiv_errmsg());
        return 1;
    }
    double ms = 1e3 * (bench_now() - t0), err = bench_field_rms(f, DISP);
    char name[32];
    snprintf(name, sizeof name, "ensemble_%d", n);
    bench_line(name, W, H, threads, ms, n * fft_bound(pv, threads, 1, 0, NULL), field_sum(f));
    printf("#   %.2f pairs/s (each pair read and correlated once per pass, 3 passes); RMS "
           "error %.4f px; peak RSS %.0f MB (target < 300 MB)%s\n",
           1e3 * n / ms, err, bench_maxrss_mb(),
           err <= 0.012 && bench_maxrss_mb() < 300 ? "" : " FAILED");
    rpiv_field_free(f);
    rpiv_piv_free(pv);
    rpiv_pairs_free(pairs);
    return err <= 0.012 ? 0 : 1;
}

/* Run fn(arg, arg2) in a child process; its exit status. */
static int in_child(int (*fn)(int, int), int arg, int arg2)
{
    fflush(stdout);
    pid_t pid = fork();
    if (pid == 0) {
        int rc = fn(arg, arg2);
        fflush(stdout);
        _exit(rc);
    }
    int status = 0;
    if (pid < 0 || waitpid(pid, &status, 0) < 0)
        return 1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 1;
}

static int run1(int threads, int unused)
{
    (void)unused;
    return case_run(threads);
}

static int one1(int threads, int unused)
{
    (void)unused;
    return case_one_pair(threads);
}

int main(void)
{
    rpiv_init();
    int maxt = omp_get_max_threads(), nens = env_int("BENCH_ENSEMBLE_PAIRS", 100), bad = 0;
    bench_header("bench_piv", maxt);
    snprintf(dir, sizeof dir, "/tmp/rpiv_bench_XXXXXX");
    if (!mkdtemp(dir)) {
        perror("bench_piv: mkdtemp");
        return 1;
    }
    double t0 = bench_now();
    for (int i = 0; i < NDISTINCT; i++)
        if (make_pair(i)) {
            fprintf(stderr, "bench_piv: %s\n", rpiv_errmsg());
            return 1;
        }
    printf("# %d synthetic 16-bit %dx%d pairs written in %.1f s; reference = bare FFTs of the "
           "run (same FFTW plans, same count)\n",
           NDISTINCT, W, H, bench_now() - t0);
    fft_kinds();
    bench_columns();
    /* BENCH_ONLY=1: only the one-thread run (for a profiler) */
    const int only = env_int("BENCH_ONLY", 0);
    bad |= in_child(run1, 1, 0);
    if (maxt >= 2 && !only)
        bad |= in_child(run1, 2, 0);
    if (!only) {
        bad |= in_child(one1, maxt, 0);
        bad |= in_child(case_ensemble, maxt, nens);
    }
    char pa[128], pb[128];
    for (int i = 0; i < NDISTINCT; i++) {
        pair_paths(i, pa, pb, sizeof pa);
        remove(pa);
        remove(pb);
    }
    snprintf(pa, sizeof pa, "%s/pairs.txt", dir);
    remove(pa);
    rmdir(dir);
    return bad;
}
