/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Noisy, small particle images (issue 15): pairs of tests/piv_testimg.h with particle images
 * of 1.5 px (e^-2 diameter) at SNR 10 (Gaussian noise of standard deviation 0.1 of the grey
 * level of a centred particle of full intensity), uniform shifts u = s, v = -s, s = 0 .. 2 px
 * in steps of 0.1 px, 512 x 512, the default 64, 32, 32 passes. RMS error over every vector
 * (borders included) and peak-locking: the largest value of the periodic part (two
 * harmonics, period 1 px) fitted to the mean error against the shift. docs/deform.md,
 * "Noisy small particles", gives the study these figures come from (bench/bench_noise.c). */
#include "check.h"
#include "peak_locking.h"
#include "piv_testimg.h"
#include "rpiv/piv.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { N = 512 };

typedef struct sweep {
    double rms, locking;
} sweep;

/* The sweep 0 .. smax px of one configuration at density ppp (seeds as bench_noise's first). */
static sweep run_sweep(const rpiv_piv_params *prm, double ppp, double smax)
{
    sweep r = {(double)NAN, (double)NAN};
    const int ns = (int)lround(smax / 0.1) + 1;
    float *a = malloc(sizeof *a * N * N), *b = malloc(sizeof *b * N * N);
    double fr[64], me[64], sq = 0;
    long cnt = 0;
    rpiv_piv *pv = NULL;
    CHECK(a && b && ns <= 32);
    if (!a || !b || ns > 32)
        goto out_free;
    CHECK_OK(rpiv_piv_new(prm, N, N, NULL, &pv));
    if (!pv)
        goto out_free;
    for (int k = 0; k < ns; k++) {
        double s = 0.1 * k, d[2] = {s, -s}, mu = 0, mv = 0;
        ti_params tp = {N, N, ppp, 1.5, 1000, 0.1, 0, (uint64_t)(7919 + 31 * k + 1)};
        ti_pair(&tp, ti_uniform, d, a, b);
        rpiv_image ia = {N, N, 16, a}, ib = {N, N, 16, b};
        rpiv_field *f = NULL;
        CHECK_OK(rpiv_piv_run(pv, &ia, &ib, &f));
        if (!f)
            goto out_free;
        size_t nv = (size_t)f->nx * (size_t)f->ny;
        for (size_t i = 0; i < nv; i++) {
            double eu = (double)f->u[i] - d[0], ev = (double)f->v[i] - d[1];
            sq += eu * eu + ev * ev;
            mu += eu;
            mv += ev;
        }
        cnt += (long)nv;
        fr[2 * k] = s;
        me[2 * k] = mu / (double)nv;
        fr[2 * k + 1] = -s;
        me[2 * k + 1] = mv / (double)nv;
        rpiv_field_free(f);
    }
    r.rms = sqrt(sq / (2.0 * (double)cnt));
    r.locking = ti_peak_locking(fr, me, 2 * ns);
out_free:
    rpiv_piv_free(pv);
    free(a);
    free(b);
    return r;
}

/* The default settings on 1.5 px particles at SNR 10 and 0.05 ppp (~50 particles per 32 px
 * window): the targets, RMS <= 0.055 px and peak-locking <= 0.015 px (measured
 * 0.0338 and 0.0107 px; session 5's one-level denoiser 0.0369 px). */
static void noise_default_settings_meet_the_target_at_005_ppp(void)
{
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.threads = 2;
    sweep s = run_sweep(&prm, 0.05, 2.0);
    printf("    1.5 px, SNR 10, 0.05 ppp, 64-32-32: RMS %.4f px, peak-locking %.4f px\n", s.rms,
           s.locking);
    CHECK(s.rms <= 0.055);
    CHECK(s.locking <= 0.015);
}

/* Sparser pairs, 0.03 and 0.02 ppp (~30 and ~20 particles per 32 px window), with the
 * defaults of session 5 (the final size repeated with a denoised predictor, refine.c) against
 * those of session 4 (refine_max 0, no denoiser, no line test: the listed third pass deformed
 * by the raw second-pass field, which counted the window-scale noise twice: 0.078 px at 0.02
 * ppp over 3 seeds and shifts 0..2, docs/deform.md). The target is met at 0.03 ppp; at 0.02 ppp
 * one 32 px correlation alone is at 0.058 px, so it is not, but the repeats no longer add:
 * measured 0.0452 and 0.0586 px (session 5's one-level denoiser 0.0493 and 0.0640 px, whose
 * repeats kept up to 18 % of the window-scale noise: docs/piv.md), session 4's 0.0767 px. */
static void noise_defaults_at_003_and_002_ppp(void)
{
    rpiv_piv_params prm = rpiv_piv_params_default();
    prm.threads = 2;
    sweep s3 = run_sweep(&prm, 0.03, 1.0);
    sweep s2 = run_sweep(&prm, 0.02, 1.0);
    rpiv_piv_params old = prm;
    old.refine_max = 0;
    old.refine_denoise = 0;
    old.median_lines = 0;
    sweep o2 = run_sweep(&old, 0.02, 1.0);
    printf("    1.5 px, SNR 10, shifts 0..1 px: RMS defaults 0.03 ppp %.4f, 0.02 ppp %.4f px "
           "(session 4's defaults %.4f px); peak-locking %.4f %.4f %.4f px\n",
           s3.rms, s2.rms, o2.rms, s3.locking, s2.locking, o2.locking);
    CHECK(s3.rms <= 0.055 && s3.locking <= 0.015);
    CHECK(s2.rms < 0.8 * o2.rms && s2.locking <= 0.015);
    CHECK(s2.rms <= 0.060); /* at the floor of one 32 px correlation (0.058 px), not above */
}

int main(void)
{
    RUN_TEST(noise_default_settings_meet_the_target_at_005_ppp);
    RUN_TEST(noise_defaults_at_003_and_002_ppp);
    return check_summary();
}
