/* SPDX-License-Identifier: GPL-3.0-or-later */
/* bench/gpiv_noise.c - libgpiv against rpiv on the noisy small-particle pairs of bench_noise
 * (issue 15): 1.5 px particle images (e^-2 diameter), SNR 10 (noise standard deviation 0.1 of
 * a centred full-intensity particle's grey level), 512 x 512, uniform shifts u = s, v = -s,
 * s = 0 .. 2 px by 0.1 px, 0.02 and 0.05 ppp, seeds as bench_noise's first NSEEDS. The pairs
 * get a background of 200 counts and are rounded to integers (16 bits) for libgpiv; rpiv
 * reads the same rounded pairs. RMS error (over libgpiv's vectors with a peak, all of
 * rpiv's) and peak-locking as bench_noise computes them.
 *   libgpiv: single pass 32 px, 50 % overlap, Gaussian fit; and its deformation mode
 *            64 -> 32 (int_scheme GPIV_IMG_DEFORM).
 *   rpiv:    the defaults (64, 32, 32).
 * Built only with libgpiv (bench/CMakeLists.txt), like gpiv_ref.c. Env NSEEDS (default 2). */
#include "bench.h"

#ifndef RPIV_HAVE_GPIV
int main(void)
{
    printf("# gpiv_noise: built without libgpiv (RPIV_HAVE_GPIV undefined), nothing to do\n");
    return 0;
}
#else

#include "../tests/peak_locking.h"
#include "../tests/piv_testimg.h"
#include "rpiv/piv.h"

#include "gpiv_params.h"

#include <gpiv.h>
#include <omp.h>

enum { N = 512, NS = 21 };

/* Sums of one method over a sweep. */
typedef struct acc {
    double sq, sq_in, mu[NS], mv[NS];
    long n, nk[NS], dropped, out;
} acc;

static void add(acc *c, int k, double eu, double ev)
{
    c->sq += eu * eu + ev * ev;
    if (eu * eu + ev * ev > 0.25)
        c->out++;
    else
        c->sq_in += eu * eu + ev * ev;
    c->mu[k] += eu;
    c->mv[k] += ev;
    c->nk[k]++;
    c->n++;
}

static void report(const char *name, double ppp, const acc *c)
{
    double fr[2 * NS], me[2 * NS];
    for (int k = 0; k < NS; k++) {
        fr[2 * k] = 0.1 * k;
        me[2 * k] = c->mu[k] / (double)c->nk[k];
        fr[2 * k + 1] = -0.1 * k;
        me[2 * k + 1] = c->mv[k] / (double)c->nk[k];
    }
    printf("ppp %.3f %-28s RMS %.4f px, peak-locking %.4f px; %.2f %% off by > 0.5 px, RMS "
           "without them %.4f px (%ld vectors, %ld without a peak left out)\n",
           ppp, name, sqrt(c->sq / (2.0 * (double)c->n)), ti_peak_locking(fr, me, 2 * NS),
           100.0 * (double)c->out / (double)c->n, sqrt(c->sq_in / (2.0 * (double)(c->n - c->out))),
           c->n, c->dropped);
}

static int run_gpiv(const float *a, const float *b, int deform, int k, const double d[2], acc *c)
{
    GpivImagePar ipar;
    memset(&ipar, 0, sizeof ipar);
    gpiv_img_default_parameters(&ipar, TRUE);
    ipar.ncolumns = N;
    ipar.ncolumns__set = TRUE;
    ipar.nrows = N;
    ipar.nrows__set = TRUE;
    ipar.depth = 16;
    ipar.depth__set = TRUE;
    ipar.x_corr = TRUE;
    ipar.x_corr__set = TRUE;
    GpivImage *img = gpiv_alloc_img(&ipar);
    if (!img)
        return 1;
    for (int y = 0; y < N; y++)
        for (int x = 0; x < N; x++) {
            img->frame1[y][x] = (guint16)a[(size_t)y * N + (size_t)x];
            img->frame2[y][x] = (guint16)b[(size_t)y * N + (size_t)x];
        }
    GpivPivPar ppar;
    GpivValidPar vpar;
    bench_gpiv_params(N, N, deform, &ppar, &vpar);
    GpivPivData *pd = gpiv_piv_interrogate_img(img, &ppar, &vpar, FALSE);
    if (!pd) {
        gpiv_free_img(img);
        return 1;
    }
    /* libgpiv's dy follows the rows (downward), as rpiv's v does */
    for (unsigned j = 0; j < pd->ny; j++)
        for (unsigned i = 0; i < pd->nx; i++) {
            if (pd->peak_no[j][i] < 1) {
                c->dropped++;
                continue;
            }
            add(c, k, pd->dx[j][i] - d[0], pd->dy[j][i] - d[1]);
        }
    gpiv_free_pivdata(pd);
    gpiv_free_img(img);
    return 0;
}

int main(void)
{
    rpiv_init();
    omp_set_num_threads(1);
    const char *e = getenv("NSEEDS");
    const int nseeds = e && atoi(e) > 0 ? atoi(e) : 2;
    const double ppps[2] = {0.02, 0.05};
    float *a = malloc(sizeof *a * N * N), *b = malloc(sizeof *b * N * N);
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.threads = 1;
    rpiv_piv *pv = NULL;
    if (!a || !b || rpiv_piv_new(&prm, N, N, NULL, &pv))
        return 1;
    printf("# gpiv_noise: 1.5 px particles, SNR 10, 512 x 512, shifts 0..2 px, %d seeds\n", nseeds);
    for (int q = 0; q < 2; q++) {
        static acc c[3];
        memset(c, 0, sizeof c);
        for (int k = 0; k < NS; k++)
            for (int sd = 0; sd < nseeds; sd++) {
                double s = 0.1 * k, d[2] = {s, -s};
                ti_params tp = {
                    N,    N,   ppps[q], 1.5,
                    1000, 0.1, 0,       (uint64_t)(7919 * (sd + 1) + 31 * k + 1000 * q + 1)};
                ti_pair(&tp, ti_uniform, d, a, b);
                for (size_t i = 0; i < (size_t)N * N; i++) {
                    a[i] = fminf(65535.0f, fmaxf(0.0f, rintf(a[i] + 200.0f)));
                    b[i] = fminf(65535.0f, fmaxf(0.0f, rintf(b[i] + 200.0f)));
                }
                if (run_gpiv(a, b, 0, k, d, &c[0]) || run_gpiv(a, b, 1, k, d, &c[1])) {
                    fprintf(stderr, "gpiv_noise: libgpiv failed\n");
                    return 1;
                }
                rpiv_image ia = {N, N, 16, a}, ib = {N, N, 16, b};
                rpiv_field *f = NULL;
                if (rpiv_piv_run(pv, &ia, &ib, &f)) {
                    fprintf(stderr, "gpiv_noise: %s\n", rpiv_errmsg());
                    return 1;
                }
                for (size_t i = 0; i < (size_t)f->nx * (size_t)f->ny; i++)
                    add(&c[2], k, (double)f->u[i] - d[0], (double)f->v[i] - d[1]);
                rpiv_field_free(f);
            }
        report("libgpiv 32 px single pass:", ppps[q], &c[0]);
        report("libgpiv deformation 64->32:", ppps[q], &c[1]);
        report("rpiv defaults 64,32,32:", ppps[q], &c[2]);
        fflush(stdout);
    }
    rpiv_piv_free(pv);
    free(a);
    free(b);
    return 0;
}

#endif /* RPIV_HAVE_GPIV */
