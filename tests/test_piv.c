/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Accuracy of the multi-pass engine on synthetic pairs with known displacement (issue 3):
 * pixel-integrated Gaussian particles, d_tau = 2.5 px, 0.05 particles per pixel, windows
 * 64, 32, 32 at 50 % overlap. RPIV_SLOW_TESTS=1 runs the full 0..8 px sweep. */
#include "check.h"
#include "piv_testimg.h"
#include "rpiv/piv.h"

#include <string.h>

typedef struct pair {
    int w, h;
    float *a, *b;
    rpiv_image ia, ib;
} pair;

static void pair_make(pair *p, const ti_params *tp, ti_flow_fn fn, void *user)
{
    p->w = tp->w;
    p->h = tp->h;
    p->a = malloc(sizeof(float) * (size_t)tp->w * (size_t)tp->h);
    p->b = malloc(sizeof(float) * (size_t)tp->w * (size_t)tp->h);
    ti_pair(tp, fn, user, p->a, p->b);
    p->ia = (rpiv_image){tp->w, tp->h, 16, p->a};
    p->ib = (rpiv_image){tp->w, tp->h, 16, p->b};
}

static void pair_free(pair *p)
{
    free(p->a);
    free(p->b);
}

static rpiv_field *run(const rpiv_piv_params *prm, const pair *p)
{
    rpiv_piv *pv = NULL;
    rpiv_field *f = NULL;
    CHECK_OK(rpiv_piv_new(prm, p->w, p->h, NULL, &pv));
    if (pv)
        CHECK_OK(rpiv_piv_run(pv, &p->ia, &p->ib, &f));
    rpiv_piv_free(pv);
    return f;
}

typedef struct errs {
    double mean_u, mean_v, rms_u, rms_v;
    int n, replaced, outliers; /* outliers: |error| > 0.5 px */
} errs;

static errs field_errors(const rpiv_field *f, ti_flow_fn fn, void *user)
{
    errs e = {0};
    for (int j = 0; j < f->ny; j++)
        for (int i = 0; i < f->nx; i++) {
            size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
            double u, v;
            fn(user, f->x0 + i * f->dx, f->y0 + j * f->dy, &u, &v);
            double eu = (double)f->u[k] - u, ev = (double)f->v[k] - v;
            e.mean_u += eu;
            e.mean_v += ev;
            e.rms_u += eu * eu;
            e.rms_v += ev * ev;
            e.replaced += f->flag[k] == RPIV_FLAG_REPLACED;
            e.outliers += sqrt(eu * eu + ev * ev) > 0.5;
            e.n++;
        }
    e.mean_u /= e.n;
    e.mean_v /= e.n;
    e.rms_u = sqrt(e.rms_u / e.n);
    e.rms_v = sqrt(e.rms_v / e.n);
    return e;
}

static ti_params base(int w, int h, uint64_t seed)
{
    return (ti_params){w, h, 0.05, 2.5, 1000, 0, 0, seed};
}

/* ---- uniform displacements: no peak locking ------------------------------------------------ */

static void piv_uniform_shifts_have_no_peak_locking(void)
{
    static double shifts[81];
    int n = 0;
    if (getenv("RPIV_SLOW_TESTS") && atoi(getenv("RPIV_SLOW_TESTS")) == 1) {
        for (int k = 0; k <= 80; k++)
            shifts[n++] = 0.1 * k;
    } else {
        for (int k = 0; k <= 10; k++)
            shifts[n++] = 0.1 * k;
        const double spread[] = {1.3, 2.2, 2.7, 3.4, 4.1, 4.9, 5.5, 6.3, 7.2, 7.6, 8.0};
        for (size_t k = 0; k < sizeof spread / sizeof *spread; k++)
            shifts[n++] = spread[k];
    }
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.threads = 1; /* piv_results_identical_for_1_and_2_threads covers the threads */
    double worst_rms = 0, worst_mean = 0;
    for (int k = 0; k < n; k++) {
        /* both components, u = s and v = -s: every sub-pixel fraction in each */
        double d[2] = {shifts[k], -shifts[k]};
        ti_params tp = base(256, 256, 1000 + (uint64_t)k);
        pair p;
        pair_make(&p, &tp, ti_uniform, d);
        rpiv_field *f = run(&prm, &p);
        if (f) {
            errs e = field_errors(f, ti_uniform, d);
            double rms = fmax(e.rms_u, e.rms_v), mean = fmax(fabs(e.mean_u), fabs(e.mean_v));
            worst_rms = fmax(worst_rms, rms);
            worst_mean = fmax(worst_mean, mean);
            if (rms > 0.015 || mean > 0.005)
                printf("    shift %.1f: mean %+.4f %+.4f rms %.4f %.4f\n", shifts[k], e.mean_u,
                       e.mean_v, e.rms_u, e.rms_v);
            CHECK(rms <= 0.015);
            CHECK(mean <= 0.005);
            CHECK(e.replaced == 0);
        }
        rpiv_field_free(f);
        pair_free(&p);
    }
    printf("    %d shifts 0..8 px, 256x256: worst RMS error %.4f px, worst |mean error| %.4f px\n",
           n, worst_rms, worst_mean);
}

/* ---- noise -------------------------------------------------------------------------------- */

static void piv_uniform_with_noise(void)
{
    double d[2] = {3.3, -1.7};
    ti_params tp = base(512, 512, 77);
    tp.noise = 0.01;
    tp.offset = 100;
    pair p;
    pair_make(&p, &tp, ti_uniform, d);
    rpiv_piv_params prm = rpiv_piv_params_default();
    rpiv_field *f = run(&prm, &p);
    if (f) {
        errs e = field_errors(f, ti_uniform, d);
        printf("    (3.3, -1.7) px, 1 %% noise, 512x512: mean %+.4f %+.4f, RMS %.4f %.4f px\n",
               e.mean_u, e.mean_v, e.rms_u, e.rms_v);
        CHECK(e.rms_u <= 0.012 && e.rms_v <= 0.012);
    }
    rpiv_field_free(f);
    pair_free(&p);
}

/* The windows on the grid's edge as accurate as the others: a uniform flow (3.27, -1.61) px,
 * 3 px particle images, no noise, 4 pairs of 256 px, the default passes. The deformation takes
 * a frame's sample only where all its B-spline taps are pixels (deform_takes): with samples
 * up to the frame's area, [-0.5, w - 0.5], the mirrored taps gave the edge nodes 3 times the
 * interior's RMS error (0.0038 against 0.0012 px) and a mean error of +0.0037 px in the first
 * column (test_uncertainty's seeds). Here, measured before -> after: RMS error of the edge nodes
 * over the interior's 3.15 -> 1.27, largest mean error of an edge line 0.0042 -> 0.0003 px. */
static void piv_edge_windows_as_accurate_as_interior(void)
{
    double d[2] = {3.27, -1.61};
    double se = 0, si = 0, sum[4] = {0};
    int ne = 0, ni = 0, nl[4] = {0};
    for (int q = 0; q < 4; q++) {
        ti_params tp = base(256, 256, 4242 + (uint64_t)q);
        tp.d_tau = 3.0;
        pair p;
        pair_make(&p, &tp, ti_uniform, d);
        rpiv_piv_params prm = rpiv_piv_params_default();
        rpiv_field *f = run(&prm, &p);
        for (int j = 0; f && j < f->ny; j++)
            for (int i = 0; i < f->nx; i++) {
                const size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
                if (f->flag[k] != RPIV_FLAG_VALID)
                    continue;
                const double eu = (double)f->u[k] - d[0], ev = (double)f->v[k] - d[1];
                /* the edge lines: first and last column (u, across them), rows (v) */
                const int line[4] = {i == 0, i == f->nx - 1, j == 0, j == f->ny - 1};
                for (int l = 0; l < 4; l++)
                    if (line[l]) {
                        sum[l] += l < 2 ? eu : ev;
                        nl[l]++;
                    }
                if (line[0] || line[1] || line[2] || line[3]) {
                    se += eu * eu + ev * ev;
                    ne++;
                } else {
                    si += eu * eu + ev * ev;
                    ni++;
                }
            }
        rpiv_field_free(f);
        pair_free(&p);
    }
    CHECK(ne > 100 && ni > 300);
    if (ne <= 100 || ni <= 300)
        return;
    const double re = sqrt(se / ne), ri = sqrt(si / ni);
    double worst = 0;
    for (int l = 0; l < 4; l++)
        worst = fmax(worst, fabs(sum[l] / nl[l]));
    printf("    edge nodes RMS %.4f px, interior %.4f px (ratio %.2f); largest mean error of an "
           "edge line %.4f px\n",
           re / sqrt(2), ri / sqrt(2), re / ri, worst);
    CHECK(re < 1.6 * ri);
    CHECK(worst < 0.0015);
}

/* ---- sinusoidal shear --------------------------------------------------------------------- */

static void sine(void *user, double x, double y, double *u, double *v)
{
    (void)user;
    (void)x;
    *u = 3.0 * sin(2 * M_PI * y / 64.0);
    *v = 0;
}

/* Least-squares amplitude of u(y) = A sin(2 pi y / 64) + B cos(...) over the field. */
static double sine_amplitude(const rpiv_field *f)
{
    double ss = 0, cc = 0, sc = 0, us = 0, uc = 0;
    for (int j = 0; j < f->ny; j++)
        for (int i = 0; i < f->nx; i++) {
            double y = f->y0 + j * f->dy, s = sin(2 * M_PI * y / 64), c = cos(2 * M_PI * y / 64);
            double u = (double)f->u[(size_t)j * (size_t)f->nx + (size_t)i];
            ss += s * s;
            cc += c * c;
            sc += s * c;
            us += u * s;
            uc += u * c;
        }
    double det = ss * cc - sc * sc, A = (us * cc - uc * sc) / det, B = (uc * ss - us * sc) / det;
    return sqrt(A * A + B * B);
}

static void piv_sinusoidal_shear_amplitude(void)
{
    ti_params tp = base(256, 256, 4242);
    pair p;
    pair_make(&p, &tp, sine, NULL);
    /* At 4 vectors per wavelength the extrema look like outliers to a 3x3 median test (their
     * 6 neighbours across the zero crossings all differ by the full amplitude): the test is
     * switched off, as it must be for any field sampled this coarsely. */
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.median_thr = 0;
    prm.refine_max = 0; /* the listed passes (the refinement: test_refine) */
    rpiv_field *f = run(&prm, &p);
    rpiv_piv_params one = prm;
    one.npass = 1;
    one.win_w[0] = one.win_h[0] = 32;
    rpiv_field *g = run(&one, &p);
    rpiv_piv_params four = prm;
    four.npass = 4;
    four.win_w[3] = four.win_h[3] = 32;
    rpiv_field *h4 = run(&four, &p);
    if (f && g && h4) {
        double a3 = sine_amplitude(f) / 3, a1 = sine_amplitude(g) / 3, a4 = sine_amplitude(h4) / 3;
        printf("    sine 3 px / 64 px: amplitude kept %.1f %% (64,32,32), %.1f %% (one 32 px pass),"
               " %.1f %% (64,32,32,32)\n",
               100 * a3, 100 * a1, 100 * a4);
        CHECK(a3 >= 0.85);
        CHECK(a1 < 0.75 && a1 > 0.55); /* the top-hat window's sinc(pi/2) = 0.64, about */
        CHECK(a4 > a3);
    }
    rpiv_field_free(f);
    rpiv_field_free(g);
    rpiv_field_free(h4);
    pair_free(&p);
}

/* Iterative refinement at the final size (opt-in: refine_max, refine_filter, median_lines,
 * refine_defer) on the shear of issue 15: u = 3 sin(2 pi y / 64), 512 x 512, 8 bit, 1 % noise,
 * validation on. Measured: defaults amplitude 0.377, 23.3 % replaced; refine_max 6,
 * refine_filter 0.2, median_lines 1: 0.906, 0.3 % (0.902, 4.8 % before the predictor kept the
 * line replacement); refine_max 10, refine_filter 0.1, median_lines 1: 0.960, 0.0 % validated
 * between repeats, 0.960, 0.1 % with refine_defer 1 (the targets 0.85 and 2 %). */
static void piv_refinement_recovers_a_shear(void)
{
    ti_params tp = {512, 512, 0.05, 2.5, 200, 0.01, 20, 4242};
    pair p;
    pair_make(&p, &tp, sine, NULL);
    for (size_t k = 0; k < (size_t)512 * 512; k++) {
        p.a[k] = floorf(fminf(p.a[k], 255) + 0.5f);
        p.b[k] = floorf(fminf(p.b[k], 255) + 0.5f);
    }
    rpiv_piv_params d = rpiv_piv_params_default(), r, qd, qv;
    d.refine_max = 0; /* session 4's defaults (now: test_refine) */
    d.refine_denoise = 0;
    d.median_lines = 0;
    r = qd = d;
    r.refine_max = 6;
    r.refine_filter = 0.2;
    r.median_lines = 1;
    qd.refine_max = 10;
    qd.refine_filter = 0.1;
    qd.median_lines = 1;
    qv = qd;
    qd.refine_defer = 1;
    rpiv_field *fd = run(&d, &p), *fr = run(&r, &p), *fq = run(&qd, &p), *fv = run(&qv, &p);
    if (fd && fr && fq && fv) {
        double ad = sine_amplitude(fd) / 3, ar = sine_amplitude(fr) / 3,
               aq = sine_amplitude(fq) / 3, av = sine_amplitude(fv) / 3;
        int nd = 0, nr = 0, nq = 0, nv = 0, n = fd->nx * fd->ny;
        for (int k = 0; k < n; k++) {
            nd += fd->flag[k] == RPIV_FLAG_REPLACED;
            nr += fr->flag[k] == RPIV_FLAG_REPLACED;
            nq += fq->flag[k] == RPIV_FLAG_REPLACED;
            nv += fv->flag[k] == RPIV_FLAG_REPLACED;
        }
        printf("    shear 3 px / 64 px, noisy 8 bit: amplitude %.3f, %.1f %% replaced (defaults); "
               "%.3f, %.1f %% (refinement); %.3f, %.1f %% (refinement, deferred validation); "
               "%.3f, %.1f %% (the same, validated between repeats)\n",
               ad, 100.0 * nd / n, ar, 100.0 * nr / n, aq, 100.0 * nq / n, av, 100.0 * nv / n);
        /* validated between repeats: the crests the line test keeps and replaces stay in the
         * predictor (they were refilled by 3 x 3 medians, about 0, and measured wrong again:
         * 0.944, 6.7 % replaced before the fix) */
        CHECK(av >= 0.85 && av <= 1.02);
        CHECK(nv <= 0.02 * n);
        CHECK(ar >= 0.85 && ar <= 1.02);
        CHECK(ar > ad + 0.2);
        CHECK(nr <= 0.02 * n && nr < nd / 2);
        CHECK(aq >= 0.85 && aq <= 1.02); /* the targets */
        CHECK(nq <= 0.02 * n);
    }
    rpiv_field_free(fv);
    rpiv_field_free(fq);
    rpiv_field_free(fd);
    rpiv_field_free(fr);
    /* a smooth flow is not changed by more than noise, and converges at once */
    double u[2] = {3.3, -1.7};
    pair q;
    tp.w = tp.h = 256;
    pair_make(&q, &tp, ti_uniform, u);
    rpiv_piv *pv = NULL;
    rpiv_field *f = NULL;
    int nref = -1;
    CHECK_OK(rpiv_piv_new(&r, 256, 256, NULL, &pv));
    if (pv && !rpiv_piv_load(pv, &q.ia, &q.ib) && !rpiv_piv_passes(pv, &f, &nref) && f) {
        errs e = field_errors(f, ti_uniform, u);
        printf("    uniform (3.3, -1.7), refinement on: %d repeats, RMS %.4f %.4f px\n", nref,
               e.rms_u, e.rms_v);
        CHECK(nref == 0);
        CHECK(fmax(e.rms_u, e.rms_v) < 0.03);
    }
    rpiv_field_free(f);
    rpiv_piv_free(pv);
    pair_free(&q);
    pair_free(&p);
}

/* ---- Lamb-Oseen vortex -------------------------------------------------------------------- */

/* Swirl u_theta(r) = a * g(r / rc) / g_max, g(s) = (1 - exp(-s^2)) / s; the peak a is
 * reached at r = 1.1209 rc; the core turns by a / (g_max rc) rad between the frames. */
typedef struct vortex {
    double cx, cy, a, rc;
} vortex;

static void oseen(void *user, double x, double y, double *u, double *v)
{
    const vortex *c = user;
    const double a = c->a, rc = c->rc, gmax = 0.6381726863;
    double dx = x - c->cx, dy = y - c->cy, r = sqrt(dx * dx + dy * dy);
    if (r < 1e-9) {
        *u = *v = 0;
        return;
    }
    double s = r / rc, ut = a * (1 - exp(-s * s)) / s / gmax;
    *u = -ut * dy / r;
    *v = ut * dx / r;
}

static void piv_lamb_oseen_vortex_has_few_outliers(void)
{
    vortex c[1] = {{191.37, 160.81, 6, 48}};
    ti_params tp = base(384, 320, 555);
    pair p;
    pair_make(&p, &tp, oseen, c);
    rpiv_piv_params prm = rpiv_piv_params_default(), old = prm, s13 = prm;
    old.refine_denoise_order = 2; /* sessions 6-12 */
    old.refine_notch = 0;
    s13.refine_notch = 0; /* session 13 */
    rpiv_field *f = run(&prm, &p), *f2 = run(&old, &p), *f3 = run(&s13, &p);
    if (f && f2 && f3) {
        errs e = field_errors(f, oseen, c), e2 = field_errors(f2, oseen, c);
        errs e3 = field_errors(f3, oseen, c);
        printf("    Lamb-Oseen 6 px, rc 48 px, 384x320: %d vectors, %d outliers (> 0.5 px), "
               "%d replaced, RMS %.4f %.4f px (without the notch %.4f %.4f; "
               "refine_denoise_order 2 too: %.4f %.4f px)\n",
               e.n, e.outliers, e.replaced, e.rms_u, e.rms_v, e3.rms_u, e3.rms_v, e2.rms_u,
               e2.rms_v);
        CHECK(e.outliers < 0.005 * e.n);
        /* measured 0.0063 / 0.0061 px; without the grid's Nyquist notch (refine_notch 0,
         * session 13) 0.0088 / 0.0086; with the second difference at the denoiser's first
         * dilation as well (refine_denoise_order 2, sessions 6-12) 0.0259 / 0.0230: the
         * vortex's curvature taken for noise there (docs/piv.md); session 5's one-level
         * denoiser 0.0244 / 0.0209 */
        CHECK(e.rms_u < 0.008 && e.rms_v < 0.008);
        CHECK(e.rms_u < 0.8 * e3.rms_u && e.rms_v < 0.8 * e3.rms_v);
        CHECK(e.rms_u < 0.4 * e2.rms_u && e.rms_v < 0.4 * e2.rms_v);
    }
    rpiv_field_free(f);
    rpiv_field_free(f2);
    rpiv_field_free(f3);
    pair_free(&p);
}

/* The grid's Nyquist mode (docs/piv.md, "The grid's Nyquist mode"): a Lamb-Oseen core turning
 * by 0.2 rad between the frames (5 px at most, rc 40 px), 384 x 384 px, 2.2 px particle images,
 * no noise. The first pass (64 px, not deformed) is off by up to 2 px in the core, the first
 * 32 px pass measures there with large noise, and the part of that noise that alternates from
 * node to node is not seen by a window of two grid steps: without the notch the repeats keep
 * it. Six seeds: the RMS error over them, the notch (refine_notch 6, the default) against none
 * (session 13): measured 0.0084 px (worst pair 0.0123) against 0.0314 (worst 0.0520); with 75 %
 * overlap (3 pairs; the notch at dilations 1 and 2) 0.0170 (0.0196) against 0.1117 (0.1292). */
/* The RMS error over ns pairs of the 0.2 rad core with `overlap`, the notch on (rms[0]) and off
 * (rms[1]); worst: the worst pair's. */
static void core_errors(int ns, double overlap, double rms[2], double worst[2])
{
    vortex c[1] = {{192.37, 191.79, 5, 40}};
    double se[2] = {0, 0};
    int n = 0;
    worst[0] = worst[1] = 0;
    for (int k = 0; k < ns; k++) {
        ti_params tp = base(384, 384, 900 + (uint64_t)k);
        tp.d_tau = 2.2;
        pair p;
        pair_make(&p, &tp, oseen, c);
        rpiv_piv_params prm[2] = {rpiv_piv_params_default(), rpiv_piv_params_default()};
        prm[0].overlap = prm[1].overlap = overlap;
        prm[1].refine_notch = 0;
        for (int q = 0; q < 2; q++) {
            rpiv_field *f = run(&prm[q], &p);
            if (f) {
                errs e = field_errors(f, oseen, c);
                se[q] += (e.rms_u * e.rms_u + e.rms_v * e.rms_v) * e.n;
                worst[q] = fmax(worst[q], fmax(e.rms_u, e.rms_v));
                n += q == 0 ? e.n : 0;
            }
            rpiv_field_free(f);
        }
        pair_free(&p);
    }
    CHECK(n > 0);
    rms[0] = n ? sqrt(se[0] / (2.0 * n)) : 0;
    rms[1] = n ? sqrt(se[1] / (2.0 * n)) : 0;
}

static void piv_vortex_core_keeps_no_grid_mode(void)
{
    double rms[2], worst[2];
    core_errors(6, 0.5, rms, worst);
    printf("    Lamb-Oseen 5 px, rc 40 px, 384x384, 6 pairs: RMS error %.4f px (worst pair %.4f), "
           "without the notch %.4f px (worst %.4f)\n",
           rms[0], worst[0], rms[1], worst[1]);
    CHECK(rms[0] < 0.5 * rms[1]);
    /* 75 % overlap: the window of 4 grid steps misses the wave of 4 steps too (dilation 2) */
    core_errors(3, 0.75, rms, worst);
    printf("    the same, 75 %% overlap, 3 pairs: RMS error %.4f px (worst pair %.4f), without the "
           "notch %.4f px (worst %.4f)\n",
           rms[0], worst[0], rms[1], worst[1]);
    CHECK(rms[0] < 0.5 * rms[1]);
}

/* ---- weak peaks: the peak searched near the predictor ---------------------------------------- */

static void sine_drift(void *user, double x, double y, double *u, double *v)
{
    (void)user;
    (void)x;
    *u = 2.3 + 2.0 * sin(2 * M_PI * y / 256.0);
    *v = -1.1;
}

/* Sparse, noisy pairs where half of each frame's particles have no partner in the other (out
 * of plane), the situation of weak correlation peaks: the passes after the first take the
 * highest peak within an eighth of the previous window of the predicted shift (the default) instead
 * of the plane's highest. Wrong vectors (> 1 px off the truth, replaced ones included) fall to a
 * fraction of what the whole-plane search leaves; a clean pair gives the same bits. */
static void piv_search_near_the_predictor_on_weak_peaks(void)
{
    int wrong[2] = {0, 0}, n = 0;
    for (uint64_t seed = 1; seed <= 3; seed++) {
        ti_params tp = {512, 512, 0.01, 2.0, 1000, 0.2, 0, seed};
        pair p;
        pair_make(&p, &tp, sine_drift, NULL);
        uint64_t s = 77 + seed;
        for (int k = 0; k < (int)(0.02 * 512 * 512); k++) { /* unpaired particles, A then B */
            float *img = k % 2 ? p.b : p.a;
            double x = 512 * ti_rnd(&s), y = 512 * ti_rnd(&s);
            ti_particle(img, 512, 512, x, y, 0.5, 1000 * (0.6 + 0.4 * ti_rnd(&s)));
        }
        for (int r = 0; r < 2; r++) {
            rpiv_piv_params prm = rpiv_piv_params_default();
            prm.search_radius = r ? -1 : 0;
            rpiv_field *f = run(&prm, &p);
            if (!f)
                continue;
            n += r ? f->nx * f->ny : 0;
            for (int j = 0; j < f->ny; j++)
                for (int i = 0; i < f->nx; i++) {
                    size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
                    double u, v;
                    sine_drift(NULL, f->x0 + i * f->dx, f->y0 + j * f->dy, &u, &v);
                    wrong[r] += hypot((double)f->u[k] - u, (double)f->v[k] - v) > 1;
                }
            rpiv_field_free(f);
        }
        pair_free(&p);
    }
    printf("    weak peaks (3 pairs 512^2, 0.01 ppp paired + 0.01 unpaired, noise 20 %%): vectors "
           "> 1 px off: whole plane %d, near the predictor %d of %d\n",
           wrong[0], wrong[1], n);
    /* over 54 such pairs (0.006 to 0.02 ppp, noise 5 to 20 %, none to twice as many unpaired
     * particles; docs/piv.md): 2845 and 804 */
    CHECK(n > 0 && wrong[1] < 0.5 * wrong[0] && wrong[1] < 0.03 * n);
    pair p;
    /* a clean pair: the highest peak is the one near the predictor, the same bits */
    double d[2] = {3.3187, -1.7413};
    ti_params tc = base(256, 256, 4242);
    pair_make(&p, &tc, ti_uniform, d);
    rpiv_piv_params prm = rpiv_piv_params_default();
    rpiv_field *f0 = run(&prm, &p);
    prm.search_radius = 0;
    rpiv_field *f1 = run(&prm, &p);
    if (f0 && f1)
        CHECK(!memcmp(f0->u, f1->u, sizeof(float) * (size_t)(f0->nx * f0->ny)) &&
              !memcmp(f0->v, f1->v, sizeof(float) * (size_t)(f0->nx * f0->ny)));
    rpiv_field_free(f0);
    rpiv_field_free(f1);
    pair_free(&p);
}

/* ---- determinism ---------------------------------------------------------------------------- */

/* The same bits with 1, 2 and 3 threads (3: an odd split of the deformation strips and of the
 * window pairs among threads), on an odd number of grid columns (a lone window per row). */
static void piv_results_identical_for_1_and_2_threads(void)
{
    vortex c[1] = {{128.3, 101.9, 6, 48}};
    ti_params tp = base(256, 208, 31);
    tp.noise = 0.02;
    pair p;
    pair_make(&p, &tp, oseen, c);
    rpiv_piv_params p1 = rpiv_piv_params_default();
    rpiv_field *f1 = NULL;
    p1.threads = 1;
    f1 = run(&p1, &p);
    CHECK(f1 && f1->nx % 2 == 1);
    for (int t = 2; t <= 3 && f1; t++) {
        rpiv_piv_params pt = p1;
        pt.threads = t;
        rpiv_field *f2 = run(&pt, &p);
        if (f2) {
            size_t n = (size_t)f1->nx * (size_t)f1->ny;
            CHECK(f1->nx == f2->nx && f1->ny == f2->ny);
            CHECK(!memcmp(f1->u, f2->u, n * sizeof(float)) &&
                  !memcmp(f1->v, f2->v, n * sizeof(float)));
            CHECK(!memcmp(f1->flag, f2->flag, n));
            CHECK(!memcmp(f1->peak_ratio, f2->peak_ratio, n * sizeof(float)));
            CHECK(!memcmp(f1->corr, f2->corr, n * sizeof(float)));
        }
        rpiv_field_free(f2);
    }
    rpiv_field_free(f1);
    pair_free(&p);
}

/* ---- options --------------------------------------------------------------------------------- */

static void piv_grid_and_peak_values(void)
{
    double d[2] = {1.2731, 0.4418};
    ti_params tp = base(256, 200, 8);
    pair p;
    pair_make(&p, &tp, ti_uniform, d);
    rpiv_piv_params prm = rpiv_piv_params_default();
    rpiv_field *f = run(&prm, &p);
    if (f) {
        /* 32 px windows every 16 px, centred in the image; deformed passes sample a quarter
         * pixel right of and below the window centre (RPIV_DEFORM_SHIFT) */
        CHECK(f->nx == 15 && f->ny == 11);
        CHECK_NEAR(f->x0, 15.75, 1e-12);
        CHECK_NEAR(f->y0, (200 - 32 - 160) / 2 + 15.75, 1e-12);
        CHECK(f->dx == 16 && f->dy == 16);
        double cmin = 1, rmin = 1e9;
        for (int k = 0; k < f->nx * f->ny; k++) {
            cmin = fmin(cmin, (double)f->corr[k]);
            rmin = fmin(rmin, (double)f->peak_ratio[k]);
        }
        /* noise-free deformed windows correlate almost perfectly */
        CHECK(cmin > 0.9 && cmin <= 1.0);
        CHECK(rmin > 2);
    }
    rpiv_field_free(f);
    pair_free(&p);
}

static void piv_subpixel_methods_and_window_offset_mode(void)
{
    double d[2] = {2.3187, -1.6402};
    ti_params tp = base(192, 192, 19);
    pair p;
    pair_make(&p, &tp, ti_uniform, d);
    const rpiv_subpixel m[3] = {RPIV_SUBPIXEL_GAUSS, RPIV_SUBPIXEL_PARABOLA,
                                RPIV_SUBPIXEL_CENTROID};
    for (int k = 0; k < 3; k++) {
        rpiv_piv_params prm = rpiv_piv_params_default();
        prm.subpixel = m[k];
        rpiv_field *f = run(&prm, &p);
        if (f) {
            errs e = field_errors(f, ti_uniform, d);
            printf("    sub-pixel method %d: mean %+.4f %+.4f RMS %.4f %.4f px\n", (int)m[k],
                   e.mean_u, e.mean_v, e.rms_u, e.rms_v);
            /* Each pass corrects the last one's residual by the estimator's gain at small
             * shifts: ~1 for the Gaussian, a little less for the parabola, much less for the
             * centroid of a narrow peak, so after three passes the centroid keeps a few
             * hundredths of the first residual. */
            const double tol[3] = {0.008, 0.012, 0.06};
            CHECK(fmax(e.rms_u, e.rms_v) < tol[k]);
        }
        rpiv_field_free(f);
    }
    /* without deformation: integer window offsets; the Gaussian fit's peak locking shows */
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.deform = 0;
    rpiv_field *f = run(&prm, &p);
    if (f) {
        errs e = field_errors(f, ti_uniform, d);
        printf("    window offset (no deformation), shift (2.3187, -1.6402): mean error %+.4f "
               "%+.4f, RMS %.4f %.4f px\n",
               e.mean_u, e.mean_v, e.rms_u, e.rms_v);
        CHECK(fmax(e.rms_u, e.rms_v) < 0.08);
        CHECK(f->x0 == 15.5);
    }
    rpiv_field_free(f);
    pair_free(&p);
}

static void piv_roi_and_mask(void)
{
    double d[2] = {2.1931, 0.8377};
    ti_params tp = base(256, 224, 61);
    pair p;
    pair_make(&p, &tp, ti_uniform, d);
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.roi[0] = 40, prm.roi[1] = 24, prm.roi[2] = 210, prm.roi[3] = 200;
    rpiv_field *f = run(&prm, &p);
    if (f) {
        /* 170 x 176 px: 9 x 10 windows of 32 every 16, centred in the ROI */
        CHECK(f->nx == 9 && f->ny == 10);
        CHECK_NEAR(f->x0, 40 + (170 - 32 - 128) / 2 + 15.75, 1e-12);
        CHECK_NEAR(f->y0, 24 + (176 - 32 - 144) / 2 + 15.75, 1e-12);
        errs e = field_errors(f, ti_uniform, d);
        CHECK(fmax(e.rms_u, e.rms_v) < 0.01);
    }
    rpiv_field_free(f);

    /* a horizontal band masked (a wall with a reflection): its vectors flagged 2, u = v = 0 */
    float *m = malloc(sizeof(float) * 256 * 224);
    for (int y = 0; y < 224; y++)
        for (int x = 0; x < 256; x++) {
            int in = y >= 96 && y < 136;
            m[y * 256 + x] = in ? 0.0f : 1.0f;
            if (in) /* saturated garbage that must not leak into the neighbours */
                p.a[y * 256 + x] = p.b[y * 256 + x] = (float)(4000 * ((x * 7 + y * 13) % 5));
        }
    rpiv_image mask = {256, 224, 8, m};
    prm = rpiv_piv_params_default();
    rpiv_piv *pv = NULL;
    CHECK_OK(rpiv_piv_new(&prm, 256, 224, &mask, &pv));
    if (pv)
        CHECK_OK(rpiv_piv_run(pv, &p.ia, &p.ib, &f));
    if (pv && f) {
        int nmask = 0;
        double r2 = 0;
        int n = 0;
        for (int j = 0; j < f->ny; j++)
            for (int i = 0; i < f->nx; i++) {
                size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
                double y = f->y0 + j * f->dy;
                if (f->flag[k] == RPIV_FLAG_MASKED) {
                    nmask++;
                    CHECK(f->u[k] == 0 && f->v[k] == 0);
                    CHECK(y > 96 - 16 && y < 136 + 16);
                } else if (y < 96 - 16 || y > 136 + 16) {
                    double eu = (double)f->u[k] - d[0], ev = (double)f->v[k] - d[1];
                    r2 += eu * eu + ev * ev;
                    n++;
                }
            }
        CHECK(nmask >= 15 && nmask <= 45);
        CHECK(sqrt(r2 / n) < 0.02);
        rpiv_field_free(f);
    }
    rpiv_piv_free(pv);
    free(m);
    pair_free(&p);
}

/* A static background (a gradient and bright spots, identical in both frames) pulls the peak
 * to zero; subtracting it restores the result. */
static void piv_background_subtraction(void)
{
    double d[2] = {3.6123, 1.2077};
    ti_params tp = base(192, 160, 71);
    pair p;
    pair_make(&p, &tp, ti_uniform, d);
    size_t n = 192 * 160;
    float *bg = malloc(sizeof(float) * n);
    for (int y = 0; y < 160; y++)
        for (int x = 0; x < 192; x++) {
            double v =
                300 + 2.0 * x +
                200 * exp(-((x % 37 - 18) * (x % 37 - 18) + (y % 29 - 14) * (y % 29 - 14)) / 8.0);
            bg[y * 192 + x] = (float)v;
            p.a[y * 192 + x] += (float)v;
            p.b[y * 192 + x] += (float)v;
        }
    rpiv_image ibg = {192, 160, 16, bg};
    rpiv_piv_params prm = rpiv_piv_params_default();
    rpiv_piv *pv = NULL;
    rpiv_field *f = NULL;
    CHECK_OK(rpiv_piv_new(&prm, 192, 160, NULL, &pv));
    if (pv) {
        CHECK_OK(rpiv_piv_set_background(pv, &ibg, &ibg));
        CHECK_OK(rpiv_piv_run(pv, &p.ia, &p.ib, &f));
        if (f) {
            errs e = field_errors(f, ti_uniform, d);
            CHECK(fmax(e.rms_u, e.rms_v) < 0.01);
        }
        rpiv_field_free(f);
        rpiv_image small = {100, 160, 16, bg};
        CHECK_FAILS(rpiv_piv_set_background(pv, &small, &ibg), RPIV_ESIZE);
        CHECK_OK(rpiv_piv_set_background(pv, NULL, NULL));
    }
    rpiv_piv_free(pv);
    free(bg);
    pair_free(&p);
}

/* ---- errors ------------------------------------------------------------------------------- */

static void piv_errors_are_reported(void)
{
    rpiv_piv_params prm = rpiv_piv_params_default();
    rpiv_piv *pv = (rpiv_piv *)&prm;
    /* a window larger than the image */
    CHECK_FAILS(rpiv_piv_new(&prm, 48, 200, NULL, &pv), RPIV_ESIZE);
    CHECK(pv == NULL);
    CHECK(strstr(rpiv_errmsg(), "64x64") && strstr(rpiv_errmsg(), "larger than the image"));
    /* ... or than the ROI */
    prm.roi[0] = 10, prm.roi[1] = 10, prm.roi[2] = 60, prm.roi[3] = 190;
    CHECK_FAILS(rpiv_piv_new(&prm, 256, 256, NULL, &pv), RPIV_ESIZE);
    CHECK(strstr(rpiv_errmsg(), "ROI") != NULL);
    /* a ROI outside the image */
    prm.roi[2] = 300;
    CHECK_FAILS(rpiv_piv_new(&prm, 256, 256, NULL, &pv), RPIV_ESIZE);
    prm = rpiv_piv_params_default();
    prm.overlap = 0.97;
    CHECK_FAILS(rpiv_piv_new(&prm, 256, 256, NULL, &pv), RPIV_EINVAL);
    prm = rpiv_piv_params_default();
    prm.max_mem_mb = 1;
    CHECK_FAILS(rpiv_piv_new(&prm, 1024, 1024, NULL, &pv), RPIV_ELIMIT);
    prm = rpiv_piv_params_default();
    float px[64 * 64] = {0};
    rpiv_image small = {64, 64, 8, px};
    CHECK_FAILS(rpiv_piv_new(&prm, 128, 128, &small, &pv), RPIV_ESIZE);
    CHECK_OK(rpiv_piv_new(&prm, 128, 128, NULL, &pv));
    if (pv) {
        rpiv_field *f = (rpiv_field *)&prm;
        CHECK_FAILS(rpiv_piv_step(pv, 0, NULL, &f), RPIV_EINVAL); /* nothing loaded */
        CHECK(f == NULL);
        CHECK_FAILS(rpiv_piv_step(pv, 3, NULL, &f), RPIV_EINVAL);
        CHECK_FAILS(rpiv_piv_run(pv, &small, &small, &f), RPIV_ESIZE);
        CHECK(strstr(rpiv_errmsg(), "64x64") != NULL);
    }
    rpiv_piv_free(pv);
}

int main(void)
{
    RUN_TEST(piv_uniform_shifts_have_no_peak_locking);
    RUN_TEST(piv_uniform_with_noise);
    RUN_TEST(piv_edge_windows_as_accurate_as_interior);
    RUN_TEST(piv_sinusoidal_shear_amplitude);
    RUN_TEST(piv_refinement_recovers_a_shear);
    RUN_TEST(piv_lamb_oseen_vortex_has_few_outliers);
    RUN_TEST(piv_vortex_core_keeps_no_grid_mode);
    RUN_TEST(piv_search_near_the_predictor_on_weak_peaks);
    RUN_TEST(piv_results_identical_for_1_and_2_threads);
    RUN_TEST(piv_grid_and_peak_values);
    RUN_TEST(piv_subpixel_methods_and_window_offset_mode);
    RUN_TEST(piv_roi_and_mask);
    RUN_TEST(piv_background_subtraction);
    RUN_TEST(piv_errors_are_reported);
    return check_summary();
}
