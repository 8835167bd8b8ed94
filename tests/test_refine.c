/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Iterative refinement at the final window size, by default (issue 15; docs/piv.md,
 * "Refinement at the final size"): synthetic shears u = A sin(2 pi y / lambda) on 512 x 512
 * pairs of 2.5 px particle images, 0.05 ppp, 1 % noise, 8 bit; the final window W = 32 px.
 * Targets: amplitude >= 0.85 at lambda = 2 W with <= 2 % replaced, >= 0.97 at 4 W, at W no
 * amplification above 1 and no growth of the error with the repeats; uniform shifts 0..8 px
 * RMS <= 0.006 px, |bias| <= 0.002 px. */
#include "check.h"
#include "piv_testimg.h"
#include "rpiv/piv.h"

#include <string.h>

typedef struct pair {
    int w, h;
    float *a, *b;
    rpiv_image ia, ib;
} pair;

typedef struct wave {
    double amp, lambda, phase; /* u = amp sin(2 pi y / lambda + phase) */
} wave;

static void shear(void *user, double x, double y, double *u, double *v)
{
    const wave *s = user;
    (void)x;
    *u = s->amp * sin(2 * M_PI * y / s->lambda + s->phase);
    *v = 0;
}

/* 512 x 512, 2.5 px, 0.05 ppp, peak 200 grey levels on 20, 1 % noise, rounded to 8 bit. */
static void pair_make(pair *p, int w, int h, uint64_t seed, ti_flow_fn fn, void *user)
{
    ti_params tp = {w, h, 0.05, 2.5, 200, 0.01, 20, seed};
    if (seed >= 100000) /* clean: no noise, no rounding (test_piv's uniform sweep) */
        tp = (ti_params){w, h, 0.05, 2.5, 1000, 0, 0, seed};
    size_t n = (size_t)w * (size_t)h;
    p->w = w;
    p->h = h;
    p->a = malloc(n * sizeof *p->a);
    p->b = malloc(n * sizeof *p->b);
    ti_pair(&tp, fn, user, p->a, p->b);
    for (size_t k = 0; seed < 100000 && k < n; k++) {
        p->a[k] = floorf(fminf(p->a[k], 255) + 0.5f);
        p->b[k] = floorf(fminf(p->b[k], 255) + 0.5f);
    }
    p->ia = (rpiv_image){w, h, 8, p->a};
    p->ib = (rpiv_image){w, h, 8, p->b};
}

static void pair_free(pair *p)
{
    free(p->a);
    free(p->b);
}

typedef struct result {
    double amp;   /* fitted amplitude / true amplitude (shears)             */
    double rms;   /* RMS vector error, px                                   */
    double mean;  /* the larger |mean error| of u and v, px                */
    double repl;  /* share of vectors replaced                              */
    int nrefine;  /* repeats of the final pass done                        */
    int outliers; /* vectors off by more than 0.5 px                        */
} result;

/* The measured wave's amplitude over the true one: the regression of the measured u onto the
 * true u at the vectors (at lambda = W, two grid steps, the truth sampled at the grid is the
 * alternating pattern +-amp, with phase pi/2). */
static double fit_amplitude(const rpiv_field *f, const wave *s)
{
    double ut2 = 0, umt = 0;
    for (int j = 0; j < f->ny; j++)
        for (int i = 0; i < f->nx; i++) {
            double u, v;
            shear((void *)s, f->x0 + i * f->dx, f->y0 + j * f->dy, &u, &v);
            ut2 += u * u;
            umt += u * (double)f->u[(size_t)j * (size_t)f->nx + (size_t)i];
        }
    return umt / ut2;
}

static result run(const rpiv_piv_params *prm, const pair *p, ti_flow_fn fn, void *user)
{
    result r = {0};
    rpiv_piv *pv = NULL;
    rpiv_field *f = NULL;
    CHECK_OK(rpiv_piv_new(prm, p->w, p->h, NULL, &pv));
    if (pv && !rpiv_piv_load(pv, &p->ia, &p->ib))
        CHECK_OK(rpiv_piv_passes(pv, &f, &r.nrefine));
    if (f) {
        double su = 0, sv = 0, s2 = 0;
        int n = f->nx * f->ny, nr = 0;
        for (int j = 0; j < f->ny; j++)
            for (int i = 0; i < f->nx; i++) {
                size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
                double u, v;
                fn(user, f->x0 + i * f->dx, f->y0 + j * f->dy, &u, &v);
                double eu = (double)f->u[k] - u, ev = (double)f->v[k] - v;
                su += eu;
                sv += ev;
                s2 += eu * eu + ev * ev;
                nr += f->flag[k] == RPIV_FLAG_REPLACED;
                r.outliers += eu * eu + ev * ev > 0.25;
            }
        r.rms = sqrt(s2 / n);
        r.mean = fmax(fabs(su / n), fabs(sv / n));
        r.repl = (double)nr / n;
        if (fn == shear)
            r.amp = fit_amplitude(f, user);
    }
    rpiv_field_free(f);
    rpiv_piv_free(pv);
    return r;
}

static void print(const char *what, const result *r)
{
    printf("    %-34s amplitude %.3f, RMS error %.4f px, %.1f %% replaced, %d off > 0.5 px, "
           "%d repeats\n",
           what, r->amp, r->rms, 100 * r->repl, r->outliers, r->nrefine);
}

/* ---- the shears ---------------------------------------------------------------------------- */

static void refine_recovers_shears_by_default(void)
{
    const rpiv_piv_params d = rpiv_piv_params_default();
    rpiv_piv_params none = d;
    none.refine_max = 0;
    /* lambda = 2 W and 4 W, 3 px */
    const double lambdas[2] = {64, 128}, floor_amp[2] = {0.85, 0.97};
    for (int k = 0; k < 2; k++) {
        wave s = {3, lambdas[k], 0};
        pair p;
        pair_make(&p, 512, 512, 4242 + (uint64_t)k, shear, &s);
        result r = run(&d, &p, shear, &s), r0 = run(&none, &p, shear, &s);
        char what[64];
        snprintf(what, sizeof what, "3 px, lambda %.0f px, defaults:", lambdas[k]);
        print(what, &r);
        snprintf(what, sizeof what, "3 px, lambda %.0f px, no repeats:", lambdas[k]);
        print(what, &r0);
        CHECK(r.amp >= floor_amp[k] && r.amp <= 1.02);
        CHECK(r.repl <= 0.02);
        CHECK(r.rms < r0.rms);
        pair_free(&p);
    }
}

/* The RMS error of field f against the flow (no result struct: for the step-by-step runs). */
static double field_rms(const rpiv_field *f, ti_flow_fn fn, void *user)
{
    double s2 = 0;
    for (int j = 0; j < f->ny; j++)
        for (int i = 0; i < f->nx; i++) {
            size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
            double u, v;
            fn(user, f->x0 + i * f->dx, f->y0 + j * f->dy, &u, &v);
            s2 += ((double)f->u[k] - u) * ((double)f->u[k] - u) +
                  ((double)f->v[k] - v) * ((double)f->v[k] - v);
        }
    return sqrt(s2 / (f->nx * f->ny));
}

/* The listed passes 64, 32 and then `reps` repeats of the 32 px pass, step by step, as
 * rpiv_piv_passes runs them without its stops: the RMS error of the 64, 32 field (*first) and
 * the largest RMS error of the repeats (returned). */
static double worst_repeat(const pair *p, ti_flow_fn fn, void *user, int reps, double *first)
{
    rpiv_piv_params d = rpiv_piv_params_default();
    rpiv_piv *pv = NULL;
    rpiv_field *prev = NULL, *f = NULL;
    double worst = (double)NAN;
    *first = (double)NAN;
    CHECK_OK(rpiv_piv_new(&d, p->w, p->h, NULL, &pv));
    if (!pv || rpiv_piv_load(pv, &p->ia, &p->ib))
        goto out_free;
    CHECK_OK(rpiv_piv_step(pv, 0, NULL, &f));
    if (!f)
        goto out_free;
    CHECK_OK(rpiv_piv_step(pv, 1, f, &prev));
    rpiv_field_free(f);
    f = NULL;
    if (!prev)
        goto out_free;
    *first = field_rms(prev, fn, user);
    worst = 0;
    for (int k = 0; k < reps; k++) {
        CHECK_OK(rpiv_piv_step(pv, 2, prev, &f));
        if (!f) {
            worst = (double)NAN;
            break;
        }
        worst = fmax(worst, field_rms(f, fn, user));
        rpiv_field_free(prev);
        prev = f;
        f = NULL;
    }
out_free:
    rpiv_field_free(prev);
    rpiv_piv_free(pv);
    return worst;
}

/* lambda = W: the window's response is nil there, so the iteration cannot recover the wave
 * and must not amplify it or its own noise. Phase pi/2: the grid samples the crests, +-1 px
 * (measured: amplitude -0.000, RMS error 1.0082 px with the defaults and after 20 repeats;
 * session 4's 3 passes 1.0135 px). Phase 0: the truth is 0 at the grid, the error is the
 * noise the wave leaves (measured: 0.1465 px after 64, 32; 0.1422 px with the defaults and
 * after every one of 20 repeats; session 5's one-level denoiser grew it to 0.1638 px, because
 * its predictor kept half of the noise at 4 grid steps a wavelength, which the repeat, blind
 * to a third of it, measured again: docs/piv.md). The error must not grow with the repeats:
 * no repeat's error above that of the 64, 32 field it starts from. */
static void refine_is_stable_at_the_window_size(void)
{
    const rpiv_piv_params d = rpiv_piv_params_default();
    rpiv_piv_params none = d, more = d, prev = d;
    none.refine_max = 0;
    more.refine_max = 20;
    more.refine_tol_px = 0;
    prev.refine_max = 0;
    prev.refine_denoise = 0;
    prev.median_lines = 0;
    for (int crest = 1; crest >= 0; crest--) {
        wave s = {1, 32, crest ? M_PI / 2 : 0};
        pair p;
        pair_make(&p, 512, 512, 99, shear, &s);
        result r = run(&d, &p, shear, &s), r0 = run(&none, &p, shear, &s),
               r20 = run(&more, &p, shear, &s), old = run(&prev, &p, shear, &s);
        double first, worst = worst_repeat(&p, shear, &s, 20, &first);
        char what[4][64];
        const char *tag = crest ? "crests" : "zeros";
        snprintf(what[0], 64, "1 px, lambda 32 px, %s, defaults:", tag);
        snprintf(what[1], 64, "1 px, lambda 32 px, %s, no repeats:", tag);
        snprintf(what[2], 64, "1 px, lambda 32 px, %s, 20 repeats:", tag);
        snprintf(what[3], 64, "1 px, lambda 32 px, %s, session 4:", tag);
        print(what[0], &r);
        print(what[1], &r0);
        print(what[2], &r20);
        print(what[3], &old);
        printf("    1 px, lambda 32 px, %s: RMS error after 64, 32 %.4f px, worst of 20 repeats "
               "%.4f px\n",
               tag, first, worst);
        if (crest)
            CHECK(fabs(r.amp) <= 0.05 && fabs(r20.amp) <= 0.05); /* H = 0: nothing, not more */
        /* no growth: not above the field the repeats start from (0.1 % for float rounding) */
        CHECK(worst <= first * 1.001);
        CHECK(r.rms <= first * 1.001 && r20.rms <= first * 1.001);
        CHECK(r20.rms <= r0.rms * 1.001);
        CHECK(r.rms < old.rms);
        pair_free(&p);
    }
}

/* ---- smooth flows ------------------------------------------------------------------------- */

/* Shifts 0..8.3 px in both components, 512 x 512 (the size; 256 x 256 until session
 * 11): clean images and noisy 8-bit ones, the RMS <= 0.006 px and |bias| <= 0.002 px
 * for both (at 256 x 256 the noisy sweep's worst of 17 RMS figures scatters more: 0.0061 px,
 * asserted there at the 3 passes of session 4, 0.0080 px measured with them, less 0.001). */
static void refine_keeps_uniform_shifts(void)
{
    const rpiv_piv_params d = rpiv_piv_params_default();
    /* RPIV_SWEEP_SIZE: another image size (docs/piv.md) */
    const int size = getenv("RPIV_SWEEP_SIZE") ? atoi(getenv("RPIV_SWEEP_SIZE")) : 512;
    CHECK(size >= 128 && size <= 2048);
    for (int clean = 1; clean >= 0 && size >= 128 && size <= 2048; clean--) {
        double worst_rms = 0, worst_mean = 0;
        int repeats = 0;
        for (int k = 0; k <= 16; k++) {
            double sft[2] = {0.5 * k + 0.013 * k, -(0.5 * k + 0.021 * k)};
            pair p;
            pair_make(&p, size, size, (clean ? 100000 : 500) + (uint64_t)k, ti_uniform, sft);
            result r = run(&d, &p, ti_uniform, sft);
            worst_rms = fmax(worst_rms, r.rms / sqrt(2));
            worst_mean = fmax(worst_mean, r.mean);
            repeats += r.nrefine;
            pair_free(&p);
        }
        printf("    uniform shifts 0..8.3 px, %d x %d, %s: worst RMS %.4f px a component, worst "
               "|bias| %.4f px, %d repeats in all\n",
               size, size, clean ? "clean" : "1 % noise, 8 bit", worst_rms, worst_mean, repeats);
        CHECK(worst_rms <= (clean || size >= 512 ? 0.006 : 0.0070));
        CHECK(worst_mean <= 0.002);
        CHECK(repeats == 0); /* smooth flows stop at once */
    }
}

/* The response, amplitude against lambda / W (RPIV_SLOW_TESTS=1; docs/piv.md): 3 px waves,
 * 12 pairs a wavelength (their means), the defaults against the second difference at the
 * denoiser's first dilation (refine_denoise_order 2, sessions 6-12) and session 4's (no
 * repeats, no denoiser, the 3 x 3 median test). */
static void refine_response_table(void)
{
    enum { NP = 12 };
    rpiv_piv_params cfg[3] = {rpiv_piv_params_default(), rpiv_piv_params_default(),
                              rpiv_piv_params_default()};
    cfg[1].refine_denoise_order = 2;
    cfg[1].refine_notch = 0;
    cfg[2].refine_max = 0;
    cfg[2].refine_denoise = 0;
    cfg[2].median_lines = 0;
    const double lambdas[] = {32, 40, 48, 64, 80, 96, 128, 192, 256};
    printf("    | lambda / W | defaults: amplitude, RMS px, replaced %%, repeats | "
           "refine_denoise_order 2 | session 4 |\n");
    for (size_t k = 0; k < sizeof lambdas / sizeof *lambdas; k++) {
        wave s = {3, lambdas[k], lambdas[k] == 32 ? M_PI / 2 : 0};
        double m[3][4] = {{0}};
        for (int q = 0; q < NP; q++) {
            pair p;
            pair_make(&p, 512, 512, 7000 + (uint64_t)k + 100 * (uint64_t)q, shear, &s);
            for (int c = 0; c < 3; c++) {
                result r = run(&cfg[c], &p, shear, &s);
                m[c][0] += r.amp / NP;
                m[c][1] += r.rms / NP;
                m[c][2] += 100 * r.repl / NP;
                m[c][3] += (double)r.nrefine / NP;
                CHECK(c == 2 || r.amp <= 1.05);
            }
            pair_free(&p);
        }
        printf(
            "    | %.2f | %.3f, %.3f, %.1f, %.1f | %.3f, %.3f, %.1f, %.1f | %.3f, %.3f, %.1f |\n",
            lambdas[k] / 32, m[0][0], m[0][1], m[0][2], m[0][3], m[1][0], m[1][1], m[1][2], m[1][3],
            m[2][0], m[2][1], m[2][2]);
    }
}

int main(void)
{
    RUN_TEST(refine_recovers_shears_by_default);
    RUN_TEST(refine_is_stable_at_the_window_size);
    RUN_TEST(refine_keeps_uniform_shifts);
    if (getenv("RPIV_SLOW_TESTS") && atoi(getenv("RPIV_SLOW_TESTS")) == 1)
        RUN_TEST(refine_response_table);
    return check_summary();
}
