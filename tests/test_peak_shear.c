/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Issue 15's broad, skewed ensemble peaks: a sum of correlation over pairs made by the synth
 * module through the skewed R-PIV sheet (the experiment's default) with the duct's velocity
 * varying across the depth (0 to ~6 px), against the CCM of the same sheet, particles and
 * flow (rpiv_config_ccm_predict, Eq. "statform"): its continuous peak (the ideal) and its
 * prediction of what the engine measures (the engine's estimator on the CCM's sampled
 * correlation). Measured with the ensemble's default estimator (auto: spline) and with the
 * 3-point Gaussian; the CCM also with its terms blurred by the pixels. Study knobs:
 * SHEAR_PAIRS=N (default 100), SHEAR_SIZE=WxH (default 192x128), SHEAR_VERBOSE=1 (every
 * vector), SHEAR_FNUMBER=F (both cases), SHEAR_NODEFORM=1 (integer window offsets), SHEAR_STUDY=D
 * (the last pass again from its result moved by +-D px). */
#include "check.h"
#include "rpiv/ccm.h"
#include "rpiv/config.h"
#include "rpiv/ensemble.h"
#include "rpiv/synth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct run {
    int w, h, npairs;
    float *img; /* npairs pairs of w x h frames, a then b */
} run;

/* The three-pass ensemble of the cached pairs with estimator m; with SHEAR_STUDY set, the
 * last pass again from the result shifted by +-SHEAR_STUDY px in u (does the measurement
 * follow its predictor?). */
static rpiv_field *ensemble(const rpiv_experiment *ex, const run *r, rpiv_subpixel m)
{
    const char *study = getenv("SHEAR_STUDY");
    rpiv_piv_params prm = ex->piv;
    prm.subpixel = m;
    prm.ensemble = 1;
    if (getenv("SHEAR_NODEFORM"))
        prm.deform = 0; /* study: integer window offsets, no interpolation */
    rpiv_piv *pv = NULL;
    rpiv_field *pred = NULL;
    CHECK_OK(rpiv_piv_new(&prm, r->w, r->h, NULL, &pv));
    if (!pv)
        return NULL;
    size_t npx = (size_t)r->w * (size_t)r->h;
    for (int k = 0; k < rpiv_piv_npass(pv); k++) {
        rpiv_ensemble *e = NULL;
        rpiv_field *f = NULL;
        CHECK_OK(rpiv_ensemble_new(pv, k, pred, &e));
        for (int i = 0; e && i < r->npairs; i++) {
            rpiv_image a = {r->w, r->h, 16, r->img + 2 * (size_t)i * npx};
            rpiv_image b = {r->w, r->h, 16, r->img + (2 * (size_t)i + 1) * npx};
            CHECK_OK(rpiv_ensemble_add(e, &a, &b));
        }
        if (e)
            CHECK_OK(rpiv_ensemble_finish(e, &f));
        rpiv_ensemble_free(e);
        rpiv_field_free(pred);
        pred = f;
    }
    for (int sgn = -1; study && pred && sgn <= 1; sgn += 2) {
        double d = sgn * atof(study), mean = 0;
        rpiv_field *p2 = NULL, *f = NULL;
        rpiv_ensemble *e = NULL;
        CHECK_OK(rpiv_field_copy(pred, &p2));
        size_t n = (size_t)pred->nx * (size_t)pred->ny;
        for (size_t k = 0; k < n; k++)
            p2->u[k] += (float)d;
        CHECK_OK(rpiv_ensemble_new(pv, rpiv_piv_npass(pv) - 1, p2, &e));
        for (int i = 0; e && i < r->npairs; i++) {
            rpiv_image a = {r->w, r->h, 16, r->img + 2 * (size_t)i * npx};
            rpiv_image b = {r->w, r->h, 16, r->img + (2 * (size_t)i + 1) * npx};
            CHECK_OK(rpiv_ensemble_add(e, &a, &b));
        }
        if (e)
            CHECK_OK(rpiv_ensemble_finish(e, &f));
        for (size_t k = 0; f && k < n; k++)
            mean += (double)(f->u[k] - pred->u[k]) / (double)n;
        printf("  predictor moved by %+.3f px: the result moves by %+.4f px\n", d, mean);
        rpiv_ensemble_free(e);
        rpiv_field_free(p2);
        rpiv_field_free(f);
    }
    rpiv_piv_free(pv);
    return pred;
}

/* The CCM's peak of one window (as rpiv_config_ccm_predict), with every term of the
 * correlation blurred by the pixels (box of 1 px in each frame: the correlation's variance
 * grows by 1/6 px^2, amplitude scaled to keep the term's integral) when blur is 1. */
static void ccm_peak(const rpiv_experiment *ex, double xs, double ys, rpiv_subpixel m, int blur,
                     rpiv_ccm_peak *pk)
{
    rpiv_ccm_model mo = rpiv_config_ccm_model(ex, ex->synth.dt_s);
    rpiv_ccm_params p = rpiv_ccm_params_default();
    p.subpixel = m;
    mo.u = (rpiv_ccm_func){rpiv_ccm_duct_fn, &ys};
    rpiv_sheet *sheet = NULL;
    rpiv_ccm_work *w = NULL;
    rpiv_ccm_corr *c = NULL;
    CHECK_OK(rpiv_sheet_new(&ex->sheet, &sheet));
    rpiv_ccm_sheet_at at = {sheet, xs};
    mo.illum = (rpiv_ccm_func){rpiv_ccm_sheet_fn, &at};
    CHECK_OK(rpiv_ccm_work_new(&p, &w));
    CHECK_OK(rpiv_ccm_corr_new(0, &c));
    if (w && c) {
        CHECK_OK(rpiv_ccm_stat_corr(&mo, w, c));
        for (size_t k = 0; blur && k < c->n; k++) {
            double c1 = c->g[k].c / (1 + c->g[k].c / 3);
            c->g[k].amp *= c1 / c->g[k].c;
            c->g[k].c = c1;
        }
        CHECK_OK(rpiv_ccm_corr_peak(c, &p, pk));
    }
    rpiv_ccm_corr_free(c);
    rpiv_ccm_work_free(w);
    rpiv_sheet_free(sheet);
}

/* Means over the valid vectors, px: [estimator][0] ensemble - ideal, [1] ensemble -
 * predicted, [2] predicted - ideal, [3] ensemble - pixel-blurred ideal; [estimator][4] the
 * largest |ensemble - ideal|, [5] the standard deviation of ensemble - predicted. */
typedef struct shear_result {
    double m[2][6];
    int n;
} shear_result;

/* The ensemble of npairs pairs through the skewed sheet (aperture number fnumber; NULL: the
 * experiment's), the duct's centre at 5.9 px, against the CCM of every vector; estimators
 * auto (spline) and gauss. */
static void shear_case(const char *fnumber, int npairs, shear_result *res)
{
    const char *np = getenv("SHEAR_PAIRS"), *sz = getenv("SHEAR_SIZE");
    run r = {192, 128, np ? atoi(np) : npairs, NULL};
    memset(res, 0, sizeof *res);
    if (sz && sscanf(sz, "%dx%d", &r.w, &r.h) != 2) {
        CHECK(0);
        return;
    }
    rpiv_experiment ex = rpiv_experiment_default();
    ex.synth.width_px = r.w;
    ex.synth.height_px = r.h;
    ex.synth.pairs = r.npairs;
    ex.synth.dt_s = 0.8e-3; /* the duct's centre at 5.9 px */
    if (getenv("SHEAR_FNUMBER"))
        fnumber = getenv("SHEAR_FNUMBER");
    if (fnumber)
        CHECK_OK(rpiv_config_set(&ex, "camera", "fnumber", fnumber, "test"));
    rpiv_synth *s = NULL;
    CHECK_OK(rpiv_config_synth_new(&ex, NULL, &s));
    if (!s)
        return;
    rpiv_synth_info in;
    rpiv_synth_get_info(s, &in);
    printf("  %dx%d px, %d pairs, %zu particles per pair, bulk %.3f px, d_e in focus %.2f px, "
           "x* %.3f..%.3f\n",
           r.w, r.h, r.npairs, in.nparticles, in.bulk_px, in.de_focus_px, in.x0_star,
           in.x0_star + r.w * in.star_per_px);
    size_t npx = (size_t)r.w * (size_t)r.h;
    r.img = malloc(2 * npx * (size_t)r.npairs * sizeof *r.img);
    CHECK(r.img != NULL);
    if (!r.img) {
        rpiv_synth_free(s);
        return;
    }
    for (int i = 0; i < r.npairs; i++) {
        rpiv_image a = {r.w, r.h, 16, r.img + 2 * (size_t)i * npx};
        rpiv_image b = {r.w, r.h, 16, r.img + (2 * (size_t)i + 1) * npx};
        CHECK_OK(rpiv_synth_pair(s, (unsigned long)i, &a, &b));
    }
    const rpiv_subpixel ms[2] = {RPIV_SUBPIXEL_AUTO, RPIV_SUBPIXEL_GAUSS};
    for (int q = 0; q < 2; q++) {
        rpiv_field *f = ensemble(&ex, &r, ms[q]);
        if (!f)
            continue;
        rpiv_experiment ec = ex;
        ec.piv.subpixel = ms[q];
        ec.bias.pixel_box = 0; /* the ideal: the paper's continuous images; ccm_peak blurs */
        double *m = res->m[q], ss = 0;
        int n = 0;
        for (int j = 0; j < f->ny; j++)
            for (int i = 0; i < f->nx; i++) {
                size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
                if (f->flag[k] != RPIV_FLAG_VALID)
                    continue;
                double x = f->x0 + i * f->dx, y = f->y0 + j * f->dy;
                double xs = in.x0_star + (x + 0.5) * in.star_per_px;
                double ys = in.y0_star + (y + 0.5) * in.star_per_px;
                rpiv_ccm_peak pk, pb;
                double scale, u = (double)f->u[k];
                CHECK_OK(rpiv_config_ccm_predict(&ec, ex.synth.dt_s, xs, ys, -1, &pk, &scale));
                ccm_peak(&ec, xs, ys, ms[q], 1, &pb);
                if (getenv("SHEAR_VERBOSE"))
                    printf("    %s (%6.2f, %6.2f) x* %.3f y* %.3f: ensemble %.4f, ideal %.4f, "
                           "predicted %.4f, pixel-blurred ideal %.4f\n",
                           rpiv_subpixel_names[ms[q]], x, y, xs, ys, u, pk.dx, pk.dx_sub, pb.dx);
                m[0] += u - pk.dx;
                m[1] += u - pk.dx_sub;
                m[2] += pk.dx_sub - pk.dx;
                m[3] += u - pb.dx;
                m[4] = fmax(m[4], fabs(u - pk.dx));
                ss += (u - pk.dx_sub) * (u - pk.dx_sub);
                n++;
            }
        CHECK(n > 0);
        if (n) {
            for (int t = 0; t < 4; t++)
                m[t] /= n;
            m[5] = sqrt(fmax(ss / n - m[1] * m[1], 0));
            printf("  %-5s %d vectors: ensemble - ideal %+.4f (max |.| %.4f), ensemble - "
                   "predicted %+.4f (std %.4f), predicted - ideal %+.4f, ensemble - "
                   "pixel-blurred ideal %+.4f px\n",
                   rpiv_subpixel_names[ms[q]], n, m[0], m[4], m[1], m[5], m[2], m[3]);
        }
        res->n = n;
        rpiv_field_free(f);
    }
    free(r.img);
    rpiv_synth_free(s);
}

/* The experiment's particles (d_e 1.8 px in focus): the spline removes the estimator's bias on
 * the CCM's own planes (predicted - ideal), and the ensemble moves towards the ideal; the
 * rest is image formation the CCM's sum of Gaussians leaves out (pixels, interpolation). */
static void small_particle_images(void)
{
    shear_result r;
    shear_case(NULL, 100, &r);
    if (!r.n)
        return;
    CHECK(fabs(r.m[0][2]) <= 0.01); /* spline on the CCM's plane: -0.003 px */
    CHECK(r.m[1][2] <= -0.06);      /* the 3-point Gaussian: -0.077 px    */
    CHECK(fabs(r.m[0][0]) < fabs(r.m[1][0]) - 0.03);
    CHECK(fabs(r.m[0][3]) < fabs(r.m[0][0])); /* the pixels explain part of the rest */
}

/* Particle images of 4.8 px (f# 16): the targets, on the mean over the vectors. */
static void large_particle_images(void)
{
    shear_result r;
    shear_case("16", 100, &r);
    if (!r.n)
        return;
    CHECK(fabs(r.m[0][0]) <= 0.03);
    CHECK(fabs(r.m[0][1]) <= 0.02);
    CHECK(fabs(r.m[0][2]) <= 0.005);
}

int main(void)
{
    RUN_TEST(small_particle_images);
    RUN_TEST(large_particle_images);
    return check_summary();
}
