/* SPDX-License-Identifier: GPL-3.0-or-later */
/* bench_deform - the image deformation of the PIV passes on the full sensor (2560 x 2160,
 * random particles, 0.05 particles/px, d_tau 2.5 px) with a smooth non-uniform predictor of a
 * few px on a 16 px grid. Cases: the prefilter of both frames (OpenMP's threads); the
 * predictor rows alone (into a rolling buffer of 8 rows, as deform_row uses its scratch); one
 * whole deformation of both frames through deform_row (every row, all columns, one thread, as
 * each PIV strip calls it). rpiv_ms is the current code, ref_ms the code it replaced
 * (deform_prefilter_ref, deform_pred_row_ref, deform_row_ref, kept in the library as the
 * tests' reference), measured in the same run; the checksum is that of the current results.
 * The program fails (exit 1, "FAILED") if the prefiltered frames or the predictor rows differ
 * from the reference's by a bit, the deformed frames by more than 1e-5 (relative), or
 * deform_row from its own per-pixel path (deform_row_blocks, vl = 0) or its 4-wide blocks by
 * a bit. Median of the repeats (argument 1, default 5), wall time. Single-thread figures:
 *     OMP_NUM_THREADS=1 build/bench/bench_deform 9 */
#include "../tests/piv_testimg.h"
#include "bench.h"
#include "deform_impl.h"
#include "rpiv/deform.h"
#include "rpiv/field.h"

#include <math.h>
#include <omp.h>

enum { W = 2560, H = 2160, STEP = 16, MAXREP = 31 };

typedef void (*row_fn)(const float *, const float *, int, int, const rpiv_deform_pred *, int, int,
                       int, float, float, float *, float *, float *);
typedef void (*pred_fn)(const rpiv_deform_pred *, int, int, int, float *, float *, float *);

static void row0(const float *ca, const float *cb, int w, int h, const rpiv_deform_pred *p, int x0,
                 int x1, int y, float fa, float fb, float *ra, float *rb, float *scr)
{
    deform_row_blocks(0, ca, cb, w, h, p, x0, x1, y, fa, fb, ra, rb, scr);
}

static void row4(const float *ca, const float *cb, int w, int h, const rpiv_deform_pred *p, int x0,
                 int x1, int y, float fa, float fb, float *ra, float *rb, float *scr)
{
    deform_row_blocks(4, ca, cb, w, h, p, x0, x1, y, fa, fb, ra, rb, scr);
}

static void flow(void *user, double x, double y, double *u, double *v)
{
    (void)user;
    *u = 3.3187 + 2.1 * sin(6.2831853 * x / 713.0) * cos(6.2831853 * y / 911.0);
    *v = -1.7421 + 1.6 * cos(6.2831853 * x / 1031.0 + 0.4) * sin(6.2831853 * y / 587.0);
}

static double deform_all(row_fn fn, const float *ca, const float *cb, const rpiv_deform_pred *p,
                         float *oa, float *ob, float *scr)
{
    double t0 = bench_now();
    for (int y = 0; y < H; y++)
        fn(ca, cb, W, H, p, 0, W, y, 100, 100, oa + (size_t)y * W, ob + (size_t)y * W, scr);
    return 1e3 * (bench_now() - t0);
}

static double pred_all(pred_fn fn, const rpiv_deform_pred *p, float *u, float *v, float *scr)
{
    double t0 = bench_now();
    for (int y = 0; y < H; y++)
        fn(p, y, 0, W, u + (size_t)(y % 8) * W, v + (size_t)(y % 8) * W, scr);
    return 1e3 * (bench_now() - t0);
}

static void line(const char *name, int thr, double *mnew, double *mref, int reps, double nsamp,
                 uint64_t sum)
{
    double a = bench_median(mnew, reps), b = bench_median(mref, reps);
    bench_line(name, W, H, thr, a, b, sum);
    printf("#   %-16s %.3f ns per sample (reference %.3f), speed-up %.2fx\n", name, 1e6 * a / nsamp,
           1e6 * b / nsamp, b / a);
}

int main(int argc, char **argv)
{
    int reps = argc > 1 ? atoi(argv[1]) : 5;
    if (reps < 1 || reps > MAXREP)
        reps = 5;
    int thr = omp_get_max_threads();
    bench_header("bench_deform", thr);
    printf("# %d repeats, median wall time; ref = the per-pixel code (deform_row_ref)\n", reps);
    const size_t n = (size_t)W * H;
    float *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b), *ca = malloc(n * sizeof *ca),
          *cb = malloc(n * sizeof *cb), *o[4];
    for (int k = 0; k < 4; k++)
        o[k] = malloc(n * sizeof *o[k]);
    ti_params tp = {W, H, 0.05, 2.5, 1000, 0.01, 100, 4242};
    ti_pair(&tp, flow, NULL, a, b);
    rpiv_field *f = NULL;
    rpiv_deform_pred *p = NULL;
    int nx = W / STEP, ny = H / STEP, bad = 0;
    if (rpiv_field_new(nx, ny, 0.5 * STEP - 0.5, 0.5 * STEP - 0.5, STEP, STEP, &f))
        return 1;
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            double u, v;
            flow(NULL, f->x0 + i * STEP, f->y0 + j * STEP, &u, &v);
            f->u[j * nx + i] = (float)u;
            f->v[j * nx + i] = (float)v;
        }
    if (rpiv_deform_pred_new(f, W, H, RPIV_DEFORM_SHIFT, &p))
        return 1;
    float *scr = malloc(deform_row_scratch(p, 0, W) * sizeof *scr);
    double mnew[MAXREP], mref[MAXREP];
    bench_columns();

    /* prefilter of both frames */
    for (int r = 0; r < reps; r++) {
        memcpy(ca, a, n * sizeof *ca);
        memcpy(cb, b, n * sizeof *cb);
        double t0 = bench_now();
        rpiv_deform_prefilter(ca, W, H, thr);
        rpiv_deform_prefilter(cb, W, H, thr);
        mnew[r] = 1e3 * (bench_now() - t0);
        memcpy(o[0], a, n * sizeof *ca);
        memcpy(o[1], b, n * sizeof *cb);
        t0 = bench_now();
        deform_prefilter_ref(o[0], W, H, thr);
        deform_prefilter_ref(o[1], W, H, thr);
        mref[r] = 1e3 * (bench_now() - t0);
    }
    bad |= memcmp(ca, o[0], n * sizeof *ca) || memcmp(cb, o[1], n * sizeof *cb);
    line("prefilter-pair", thr, mnew, mref, reps, 2.0 * (double)n,
         bench_checksum(bench_checksum(0, ca, n), cb, n));
    /* the same through deform_prefilter_pair (what the engine calls: with 1 or 2 threads, a
     * frame per thread, rows and causal columns in one sweep) */
    for (int r = 0; r < reps; r++) {
        memcpy(ca, a, n * sizeof *ca);
        memcpy(cb, b, n * sizeof *cb);
        double t0 = bench_now();
        deform_prefilter_pair(ca, cb, W, H, thr);
        mnew[r] = 1e3 * (bench_now() - t0);
    }
    bad |= memcmp(ca, o[0], n * sizeof *ca) || memcmp(cb, o[1], n * sizeof *cb);
    line("prefilter-fused", thr, mnew, mref, reps, 2.0 * (double)n,
         bench_checksum(bench_checksum(0, ca, n), cb, n));

    /* predictor rows alone */
    for (int r = 0; r < reps; r++) {
        mnew[r] = pred_all(rpiv_deform_pred_row, p, o[0], o[1], scr);
        mref[r] = pred_all(deform_pred_row_ref, p, o[2], o[3], scr);
    }
    bad |= memcmp(o[0], o[2], 8 * W * sizeof *ca) || memcmp(o[1], o[3], 8 * W * sizeof *cb);
    line("predictor-rows", 1, mnew, mref, reps, (double)n,
         bench_checksum(bench_checksum(0, o[0], 8 * W), o[1], 8 * W));

    /* one deformation of both frames, rows through deform_row (one thread: the PIV strips
     * call it per row from their own threads) */
    for (int r = 0; r < reps; r++) {
        mnew[r] = deform_all(deform_row, ca, cb, p, o[0], o[1], scr);
        mref[r] = deform_all(deform_row_ref, ca, cb, p, o[2], o[3], scr);
    }
    /* against the old per-pixel code: last bits (another order of the weights' terms) */
    double maxrel = 0;
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 2; k++) {
            double d = fabs((double)o[k][i] - (double)o[k + 2][i]);
            double r = d / fmax(1.0, fabs((double)o[k + 2][i]));
            maxrel = r > maxrel ? r : maxrel;
        }
    bad |= !(maxrel < 1e-5);
    line("deform-pair", 1, mnew, mref, reps, 2.0 * (double)n,
         bench_checksum(bench_checksum(0, o[0], n), o[1], n));
    printf("# deform-pair: largest difference to the old code %.2g (relative to max(1, |value|))\n",
           maxrel);
    /* the blocks against deform_row's own per-pixel path (vl = 0) and the 4-wide blocks */
    static const int vls[2] = {0, 4};
    for (int v = 0; v < 2; v++) {
        mref[0] = deform_all(v ? row4 : row0, ca, cb, p, o[2], o[3], scr);
        size_t ndiff = 0;
        for (size_t i = 0; i < n; i++)
            ndiff += memcmp(&o[0][i], &o[2][i], sizeof(float)) != 0 ||
                     memcmp(&o[1][i], &o[3][i], sizeof(float)) != 0;
        bad |= ndiff != 0;
        printf("# deform_row with vl = %d: %.1f ms, %zu pixels differ from deform_row's\n", vls[v],
               mref[0], ndiff);
    }
    printf("# %s\n", bad ? "FAILED" : "ok");
    free(scr);
    rpiv_deform_pred_free(p);
    rpiv_field_free(f);
    free(a), free(b), free(ca), free(cb);
    for (int k = 0; k < 4; k++)
        free(o[k]);
    return bad;
}
