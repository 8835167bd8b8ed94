/* SPDX-License-Identifier: GPL-3.0-or-later */
/* bench/bench_threads.c - do more threads ever make a run slower (issue 20 item 6)? Ensembles
 * (the default 64 -> 32 -> 32 run, sum of correlation) of 256 x 256, 1024 x 1024 and
 * 2560 x 2160 synthetic pairs read from TIFF files, on 1 and 2 threads, on the machine as it
 * is ("idle") and with a busy loop per core in the background ("loaded", as `yes >
 * /dev/null` per core). Each line's reference is the one-thread run of the same size and
 * condition, measured just before it, so its ratio is t(2 threads) / t(1 thread): above 1.0
 * more threads were slower. The checksum of the field must be the same for 1 and 2 threads,
 * and the RMS error against the known displacement <= 0.012 px, else the line is FAILED.
 * Environment: BENCH_THREADS_SCALE=S multiplies the pair counts (default 1). */
#include "bench.h"
#include "bench_field.h"

#include "../tests/piv_testimg.h"
#include "rpiv/image.h"
#include "rpiv/piv.h"
#include "rpiv/series.h"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

enum { NDISTINCT = 4 };
static const double DISP[2] = {3.3, -1.7};
static char dir[64];

static void pair_paths(int w, int i, char *pa, char *pb, size_t n)
{
    snprintf(pa, n, "%s/p%d_%da.tif", dir, w, i);
    snprintf(pb, n, "%s/p%d_%db.tif", dir, w, i);
}

static int make_pair(int w, int h, int i)
{
    rpiv_image *a = NULL, *b = NULL;
    char pa[128], pb[128];
    if (rpiv_image_new(w, h, &a) || rpiv_image_new(w, h, &b))
        return 1;
    ti_params tp = {w, h, 0.05, 2.5, 3000, 0.01, 100, 7100 + (uint64_t)i};
    ti_pair(&tp, ti_uniform, (void *)DISP, a->px, b->px);
    for (size_t k = 0; k < (size_t)w * (size_t)h; k++) {
        a->px[k] = fminf(65535.0f, fmaxf(0.0f, rintf(a->px[k])));
        b->px[k] = fminf(65535.0f, fmaxf(0.0f, rintf(b->px[k])));
    }
    pair_paths(w, i, pa, pb, sizeof pa);
    int bad = rpiv_image_save_tiff16(a, pa) || rpiv_image_save_tiff16(b, pb);
    rpiv_image_free(a);
    rpiv_image_free(b);
    return bad;
}

static rpiv_pairs *pairs_of(int w, int n)
{
    char list[128], pa[128], pb[128];
    snprintf(list, sizeof list, "%s/pairs%d.txt", dir, w);
    FILE *fp = fopen(list, "w");
    for (int i = 0; fp && i < n; i++) {
        pair_paths(w, i % NDISTINCT, pa, pb, sizeof pa);
        fprintf(fp, "%s %s\n", pa, pb);
    }
    if (fp)
        fclose(fp);
    rpiv_pairs *p = NULL;
    char *one[1] = {list};
    if (rpiv_pairs_from_args(1, one, RPIV_PAIR_AB, &p))
        fprintf(stderr, "bench_threads: %s\n", rpiv_errmsg());
    return p;
}

/* One ensemble run: wall and CPU time (ms), checksum, RMS error. */
typedef struct result {
    double ms, cpu_ms, err;
    uint64_t sum;
} result;

static int ensemble(int w, int h, int n, int threads, result *r)
{
    rpiv_pairs *pairs = pairs_of(w, n);
    rpiv_piv *pv = NULL;
    rpiv_field *f = NULL;
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.threads = threads;
    prm.ensemble = 1;
    double t0 = bench_now(), c0 = bench_cpu();
    int bad =
        !pairs || rpiv_piv_new(&prm, w, h, NULL, &pv) || rpiv_series_ensemble(pv, pairs, NULL, &f);
    if (bad)
        fprintf(stderr, "bench_threads: %s\n", rpiv_errmsg());
    else {
        r->ms = 1e3 * (bench_now() - t0);
        r->cpu_ms = 1e3 * (bench_cpu() - c0);
        size_t nv = (size_t)f->nx * (size_t)f->ny;
        r->sum = bench_checksum(bench_checksum(0, f->u, nv), f->v, nv);
        r->err = bench_field_rms(f, DISP);
    }
    rpiv_field_free(f);
    rpiv_piv_free(pv);
    rpiv_pairs_free(pairs);
    return bad;
}

/* The per-pair series' sink: the fields' checksum in pair order and their squared error. */
typedef struct series_acc {
    uint64_t sum;
    double sq;
    size_t n;
} series_acc;

static rpiv_status series_sink(void *user, size_t i, const rpiv_field *f)
{
    series_acc *a = user;
    (void)i;
    size_t nv = (size_t)f->nx * (size_t)f->ny;
    a->sum = bench_checksum(bench_checksum(a->sum, f->u, nv), f->v, nv);
    double e = bench_field_rms(f, DISP);
    a->sq += e * e;
    a->n++;
    return RPIV_OK;
}

/* One per-pair series run (a field per pair, rpiv_series_run): as ensemble(). */
static int series(int w, int h, int n, int threads, result *r)
{
    rpiv_pairs *pairs = pairs_of(w, n);
    rpiv_piv *pv = NULL;
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.threads = threads;
    series_acc acc = {0, 0, 0};
    double t0 = bench_now(), c0 = bench_cpu();
    int bad = !pairs || rpiv_piv_new(&prm, w, h, NULL, &pv) ||
              rpiv_series_run(pv, pairs, series_sink, &acc, NULL);
    if (bad)
        fprintf(stderr, "bench_threads: %s\n", rpiv_errmsg());
    else {
        r->ms = 1e3 * (bench_now() - t0);
        r->cpu_ms = 1e3 * (bench_cpu() - c0);
        r->sum = acc.sum;
        r->err = acc.n ? sqrt(acc.sq / (double)acc.n) : 1e9;
    }
    rpiv_piv_free(pv);
    rpiv_pairs_free(pairs);
    return bad;
}

/* Busy loops, one per core, in child processes; their pids into pids[]. */
static int load_start(pid_t *pids, int n)
{
    for (int i = 0; i < n; i++) {
        pids[i] = fork();
        if (pids[i] == 0) {
            volatile unsigned long x = 0;
            for (;;)
                x++;
        }
        if (pids[i] < 0)
            return 1;
    }
    usleep(200000);
    return 0;
}

static void load_stop(pid_t *pids, int n)
{
    for (int i = 0; i < n; i++)
        if (pids[i] > 0) {
            kill(pids[i], SIGKILL);
            waitpid(pids[i], NULL, 0);
        }
}

int main(void)
{
    rpiv_init();
    const char *sc = getenv("BENCH_THREADS_SCALE");
    const double scale = sc && atof(sc) > 0 ? atof(sc) : 1.0;
    const int ncores = (int)sysconf(_SC_NPROCESSORS_ONLN);
    bench_header("bench_threads", 2);
    snprintf(dir, sizeof dir, "/tmp/rpiv_bench_XXXXXX");
    if (!mkdtemp(dir)) {
        perror("bench_threads: mkdtemp");
        return 1;
    }
    static const int sizes[3][3] = {{256, 256, 600}, {1024, 1024, 40}, {2560, 2160, 8}};
    for (int s = 0; s < 3; s++)
        for (int i = 0; i < NDISTINCT; i++)
            if (make_pair(sizes[s][0], sizes[s][1], i)) {
                fprintf(stderr, "bench_threads: %s\n", rpiv_errmsg());
                return 1;
            }
    printf("# ensembles (ens) and per-pair series (pairs, half as many pairs) of 4 distinct "
           "synthetic 16-bit pairs listed repeatedly, default passes; "
           "ref = the 1-thread run just before (ratio = 2 threads / 1 thread; > 1: slower); "
           "loaded = %d busy loop(s) in the background, one per core\n",
           ncores);
    bench_columns();
    int bad = 0;
    pid_t *pids = calloc((size_t)ncores, sizeof *pids);
    for (int loaded = 0; loaded < 2 && pids; loaded++) {
        if (loaded && load_start(pids, ncores)) {
            load_stop(pids, ncores);
            fprintf(stderr, "bench_threads: cannot start the background load\n");
            return 1;
        }
        for (int q = 0; q < 6; q++) {
            const int s = q % 3, per_pair = q >= 3;
            const int w = sizes[s][0], h = sizes[s][1];
            const int n = (int)fmax(2, sizes[s][2] * scale / (per_pair ? 2 : 1));
            result r1 = {0}, r2 = {0};
            /* 1, 2, 1, 2: the better of two of each, taken in one stretch */
            result t[4];
            for (int k = 0; k < 4; k++)
                bad |= (per_pair ? series : ensemble)(w, h, n, k % 2 ? 2 : 1, &t[k]);
            r1 = t[0].ms < t[2].ms ? t[0] : t[2];
            r2 = t[1].ms < t[3].ms ? t[1] : t[3];
            char name[32];
            snprintf(name, sizeof name, "%s%d_%s", per_pair ? "pairs" : "ens", n,
                     loaded ? "loaded" : "idle");
            const int ok = t[0].sum == t[1].sum && t[0].sum == t[2].sum && t[1].sum == t[3].sum &&
                           r1.err <= 0.012 && r2.err <= 0.012;
            bench_line(name, w, h, 2, r2.ms, r1.ms, r2.sum);
            printf("#   1 thread %.0f ms (CPU %.0f ms), 2 threads %.0f ms (CPU %.0f ms); "
                   "%.1f pairs/s on 2 threads; RMS error %.4f px%s\n",
                   r1.ms, r1.cpu_ms, r2.ms, r2.cpu_ms, 1e3 * n / r2.ms, r2.err,
                   ok ? "" : " FAILED (checksums differ or error too large)");
            fflush(stdout);
            bad |= !ok;
        }
        if (loaded)
            load_stop(pids, ncores);
    }
    free(pids);
    char pa[128], pb[128];
    for (int s = 0; s < 3; s++) {
        for (int i = 0; i < NDISTINCT; i++) {
            pair_paths(sizes[s][0], i, pa, pb, sizeof pa);
            remove(pa);
            remove(pb);
        }
        snprintf(pa, sizeof pa, "%s/pairs%d.txt", dir, sizes[s][0]);
        remove(pa);
    }
    rmdir(dir);
    return bad;
}
