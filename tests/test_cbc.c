/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The correlation-based correction (piv.cbc, issue 16; src/piv/piv_cbc.c): each window's peak
 * chosen on its correlation plane combined with its four neighbours' (1: product, 2: sum).
 * Against the truth of synthetic pairs with weak peaks (sparse, noisy, particles without a
 * partner): fewer wrong vectors; on a clean pair the same bits; the same bits for any thread
 * count; refused with an ensemble; the uncertainty of a moved vector from its own peak. */
#include "check.h"
#include "piv_testimg.h"
#include "rpiv/piv.h"

#include <string.h>

static void sine_drift(void *user, double x, double y, double *u, double *v)
{
    (void)user;
    (void)x;
    *u = 2.3 + 2.0 * sin(2 * M_PI * y / 256.0);
    *v = -1.1;
}

/* The side of the weak pairs: 512 px, 256 under valgrind (check_memcheck(): the same code
 * paths on a quarter of the windows; the statistics are asserted at 512 by the ASan run). */
static int side = 512;

/* A side^2 pair of 2 px particles at ppp with noise, and `lost` x ppp particles per frame
 * without a partner (half in A, half in B). */
static void weak_pair(uint64_t seed, double ppp, double noise, double lost, float *a, float *b)
{
    ti_params tp = {side, side, ppp, 2.0, 1000, noise, 0, seed};
    ti_pair(&tp, sine_drift, NULL, a, b);
    uint64_t s = 77 + seed;
    for (int k = 0; k < (int)(lost * ppp * 2 * side * side); k++) {
        float *img = k % 2 ? b : a;
        double x = side * ti_rnd(&s), y = side * ti_rnd(&s);
        ti_particle(img, side, side, x, y, 0.5, 1000 * (0.6 + 0.4 * ti_rnd(&s)));
    }
}

/* Two n x n frames: 1, or 0 (a failed check) when out of memory. */
static int frames_new(int n, float **a, float **b)
{
    *a = malloc(sizeof(float) * (size_t)n * (size_t)n);
    *b = malloc(sizeof(float) * (size_t)n * (size_t)n);
    if (*a && *b)
        return 1;
    CHECK(0);
    free(*a);
    free(*b);
    return 0;
}

static rpiv_field *run(const rpiv_piv_params *prm, const float *a, const float *b, int w, int h)
{
    rpiv_image ia = {w, h, 16, (float *)a}, ib = {w, h, 16, (float *)b};
    rpiv_piv *pv = NULL;
    rpiv_field *f = NULL;
    CHECK_OK(rpiv_piv_new(prm, w, h, NULL, &pv));
    if (pv)
        CHECK_OK(rpiv_piv_run(pv, &ia, &ib, &f));
    rpiv_piv_free(pv);
    return f;
}

/* Vectors more than lim px from the truth, replaced ones included. */
static int wrong(const rpiv_field *f, double lim)
{
    int n = 0;
    for (int j = 0; j < f->ny; j++)
        for (int i = 0; i < f->nx; i++) {
            size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
            double u, v;
            sine_drift(NULL, f->x0 + i * f->dx, f->y0 + j * f->dy, &u, &v);
            n += hypot((double)f->u[k] - u, (double)f->v[k] - v) > lim;
        }
    return n;
}

static int same_field(const rpiv_field *f0, const rpiv_field *f1)
{
    size_t n = (size_t)f0->nx * (size_t)f0->ny;
    return f0->nx == f1->nx && f0->ny == f1->ny && !memcmp(f0->u, f1->u, n * sizeof *f0->u) &&
           !memcmp(f0->v, f1->v, n * sizeof *f0->v) &&
           !memcmp(f0->flag, f1->flag, n * sizeof *f0->flag);
}

static void cbc_fewer_wrong_vectors_on_weak_peaks(void)
{
    /* the weakest peaks of docs/piv.md's 54 pairs: 0.006 ppp, noise 20 %, none to twice as
     * many particles without a partner, two seeds */
    int w1[3] = {0}, w5[3] = {0}, n = 0;
    int quick = check_memcheck(); /* one pair under valgrind: the counts need all six */
    float *a, *b;
    if (!frames_new(side, &a, &b))
        return;
    for (int lost = quick; lost <= (quick ? 1 : 2); lost++)
        for (uint64_t seed = 1; seed <= (quick ? 1u : 2u); seed++) {
            weak_pair(seed, 0.006, 0.2, lost, a, b);
            for (int m = 0; m < 3; m++) {
                rpiv_piv_params prm = rpiv_piv_params_default();
                prm.cbc = m;
                rpiv_field *f = run(&prm, a, b, side, side);
                if (!f)
                    continue;
                w1[m] += wrong(f, 1);
                w5[m] += wrong(f, 0.5);
                n += m ? 0 : f->nx * f->ny;
                rpiv_field_free(f);
            }
        }
    free(a);
    free(b);
    printf("    weak peaks (%d pairs %d^2, 0.006 ppp, noise 20 %%, 0 to 0.012 ppp unpaired): "
           "vectors > 1 px off: off %d, product %d, sum %d; > 0.5 px: %d, %d, %d of %d\n",
           quick ? 1 : 6, side, w1[0], w1[1], w1[2], w5[0], w5[1], w5[2], n);
    /* measured: > 1 px 667, 521, 552; > 0.5 px 2126, 2058, 2037 of 5766 (the 54 pairs of
     * docs/piv.md: below). These counts swing by +-50 with any change of the refinement:
     * session 13's 678, 505, 528; with the notch of order 4 or 8 instead of 6 (refine_notch)
     * 747, 551, 527 and 682, 524, 492: the correction's share 0.72-0.83 of the wrong vectors */
    CHECK(n > 0);
    if (!quick) {
        CHECK(w1[1] < 0.85 * w1[0] && w1[2] < 0.85 * w1[0]);
        CHECK(w5[1] < w5[0] && w5[2] < w5[0]);
    }
}

static void cbc_leaves_a_clean_pair_alone(void)
{
    /* clear peaks: the neighbours agree with each window's own choice, the same bits */
    double d[2] = {3.3187, -1.7413};
    ti_params tp = {256, 256, 0.05, 2.5, 1000, 0.01, 0, 4242};
    float *a, *b;
    if (!frames_new(256, &a, &b))
        return;
    ti_pair(&tp, ti_uniform, d, a, b);
    rpiv_piv_params prm = rpiv_piv_params_default();
    rpiv_field *f0 = run(&prm, a, b, 256, 256);
    for (int m = 1; m <= 2 && f0; m++) {
        prm.cbc = m;
        rpiv_field *f = run(&prm, a, b, 256, 256);
        CHECK(f && same_field(f0, f));
        rpiv_field_free(f);
    }
    rpiv_field_free(f0);
    free(a);
    free(b);
}

static void cbc_same_bits_for_any_thread_count(void)
{
    float *a, *b;
    if (!frames_new(side, &a, &b))
        return;
    weak_pair(5, 0.01, 0.2, 1, a, b);
    /* under valgrind the sum with 1 and 2 threads (the weak-peaks case runs the product there) */
    int quick = check_memcheck();
    for (int m = 1 + quick; m <= 2; m++) {
        rpiv_piv_params prm = rpiv_piv_params_default();
        prm.cbc = m;
        prm.threads = 1;
        rpiv_field *f1 = run(&prm, a, b, side, side);
        for (int t = 2; t <= (quick ? 2 : 3) && f1; t++) {
            prm.threads = t;
            rpiv_field *ft = run(&prm, a, b, side, side);
            CHECK(ft && same_field(f1, ft));
            rpiv_field_free(ft);
        }
        rpiv_field_free(f1);
    }
    free(a);
    free(b);
}

static void cbc_refused_with_an_ensemble_or_out_of_range(void)
{
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.cbc = 3;
    CHECK_FAILS(rpiv_piv_params_check(&prm), RPIV_EINVAL);
    prm.cbc = -1;
    CHECK_FAILS(rpiv_piv_params_check(&prm), RPIV_EINVAL);
    prm.cbc = 2;
    CHECK_OK(rpiv_piv_params_check(&prm));
    prm.ensemble = 1;
    CHECK_FAILS(rpiv_piv_params_check(&prm), RPIV_EINVAL);
}

/* With --uncertainty, a vector the correction moved to another peak of its plane gets the
 * statistics of that peak (a second sweep): every valid vector's sigma is positive, and the
 * vectors' coverage of the truth is that of the field without the correction. */
static void cbc_uncertainty_of_moved_vectors(void)
{
    float *a, *b;
    if (!frames_new(side, &a, &b))
        return;
    weak_pair(2, 0.01, 0.2, 1, a, b);
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.uncertainty = 1;
    prm.cbc = 2;
    rpiv_field *f = run(&prm, a, b, side, side);
    const rpiv_quantity *qu = f ? rpiv_field_quantity(f, "sigma_u") : NULL;
    const rpiv_quantity *qv = f ? rpiv_field_quantity(f, "sigma_v") : NULL;
    int bad = 0, valid = 0, covered = 0;
    for (size_t k = 0; qu && qv && k < (size_t)f->nx * (size_t)f->ny; k++) {
        if (f->flag[k] != RPIV_FLAG_VALID)
            continue;
        valid++;
        bad += !(qu->data[k] > 0) || !(qv->data[k] > 0);
        double u, v;
        sine_drift(NULL, f->x0 + (double)(k % (size_t)f->nx) * f->dx,
                   f->y0 + (double)(k / (size_t)f->nx) * f->dy, &u, &v);
        covered += fabs((double)f->u[k] - u) <= (double)qu->data[k];
    }
    printf("    uncertainty with the correction: %d valid vectors, %d without a positive sigma, "
           "|error u| <= sigma_u for %.3f\n",
           valid, bad, valid ? (double)covered / valid : 0.0);
    CHECK(qu && qv && valid > 0 && bad == 0);
    rpiv_field_free(f);
    free(a);
    free(b);
}

int main(void)
{
    if (check_memcheck())
        side = 256;
    RUN_TEST(cbc_refused_with_an_ensemble_or_out_of_range);
    RUN_TEST(cbc_leaves_a_clean_pair_alone);
    RUN_TEST(cbc_fewer_wrong_vectors_on_weak_peaks);
    RUN_TEST(cbc_same_bits_for_any_thread_count);
    RUN_TEST(cbc_uncertainty_of_moved_vectors);
    return check_summary();
}
