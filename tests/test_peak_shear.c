/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Issue 15's broad, skewed ensemble peaks: a sum of correlation over pairs made by the synth
 * module through the skewed R-PIV sheet (the experiment's default) with the duct's velocity
 * varying across the depth (0 to ~6 px), against the CCM of the same sheet, particles and
 * flow (rpiv_config_ccm_predict, Eq. "statform", pixel-integrated images): its continuous peak
 * (the ideal) and its prediction of what the engine measures (the engine's estimator on the
 * CCM's sampled correlation); also the point-sampled ideal (pixel_box 0) and session 5's
 * Gaussian stand-in for the pixels' triangle. Measured with the ensemble's default estimator
 * (auto: spline) and with the 3-point Gaussian. Study knobs: SHEAR_PAIRS=N (default 100),
 * SHEAR_SIZE=WxH (default 192x128), SHEAR_VERBOSE=1 (every vector), SHEAR_FNUMBER=F (both
 * cases), SHEAR_NODEFORM=1 (integer window offsets), SHEAR_STUDY=D (the last pass again from
 * its result moved by +-D px), SHEAR_SPREAD_UM=S (the particles' diameter spread),
 * SHEAR_SPLIT=K (K disjoint groups of the pairs against all: the estimator's noise bias),
 * SHEAR_CASE=small|large (one case), SHEAR_SEED=S (another realisation), SHEAR_BORDER=P (the pairs
 * rendered P px larger on every side and cropped: the border's effect on the engine, same
 * particles), SHEAR_PLANE=1 (the engine's summed planes against the CCM's, the window's pair loss
 * and mean removal, the spline's block; 2: also the window's area average, slow). Each case also
 * gives the prediction with the engine's window modelled ([bias] window_model = 1,
 * rpiv_ccm_corr_peak_window), per term and with the interpolation (the default, its plane
 * with the noise of these pairs; SHEAR_NOISEFREE=1: without); SHEAR_AREA=1 also with the window's
 * area average (rpiv_ccm_predict_area, slow), its deformation following the plane, the quadratic,
 * the engine's spline of it on the grid (the outer ring's border) and, white-box, the engine's own
 * final-pass predictor. docs/ccm.md, "What the engine measures", "The engine's window". */
#include "check.h"
#include "piv_impl.h"
#include "rpiv/ccm.h"
#include "rpiv/config.h"
#include "rpiv/ensemble.h"
#include "rpiv/synth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* SHEAR_PLANE=1 (study): the last pass's summed planes and its predictor, kept for the
 * comparison of the engine's plane with the CCM's samples. */
static float *g_planes;
static size_t g_nplanes;
static rpiv_field *g_pred;
/* SHEAR_AREA=1: the engine's own predictor of the last pass (denoised, as it deforms by) */
static rpiv_deform_pred *g_dpred;
static int g_nostudy; /* 1 while ensembles of other pairs run (SHEAR_SPLIT, SHEAR_BORDER) */

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
        if (e && pred && !g_nostudy && getenv("SHEAR_AREA") && k == rpiv_piv_npass(pv) - 1) {
            rpiv_deform_pred_free(g_dpred);
            g_dpred = NULL;
            CHECK_OK(piv_pred_new(pv, pred, k, 0, NULL, 1, &g_dpred));
        }
        if (e && !g_nostudy && getenv("SHEAR_PLANE") && k == rpiv_piv_npass(pv) - 1) {
            size_t nd = 0;
            const float *d = rpiv_ensemble_data(e, &nd);
            free(g_planes);
            rpiv_field_free(g_pred);
            g_pred = NULL;
            g_planes = malloc(nd * sizeof *g_planes);
            if (g_planes)
                memcpy(g_planes, d, nd * sizeof *g_planes);
            g_nplanes = nd;
            if (pred)
                CHECK_OK(rpiv_field_copy(pred, &g_pred));
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

/* Study (SHEAR_PLANE=1): the engine's summed plane of window k along x through the shift 0
 * (the predictor, up, vp) against the CCM's (pixel_box of ec) at up + i, both relative to
 * their value at shift 0; accumulated, printed by plane_report. */
static double g_ln[2][7], g_cnt, g_est[4], g_avg[2], g_spp, g_blk[3], g_bsub[3];

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}
static void plane_study(const rpiv_experiment *ec, double xs, double ys, const rpiv_field *f,
                        size_t k, double up, double vp)
{
    size_t nwin = (size_t)f->nx * (size_t)f->ny;
    int w = (int)lround(sqrt((double)(g_nplanes - 2 * nwin) / (double)nwin));
    const float *pl = g_planes + k * (size_t)w * (size_t)w;
    rpiv_ccm_model mo = rpiv_config_ccm_model(ec, ec->synth.dt_s);
    rpiv_ccm_params p = rpiv_ccm_params_default();
    mo.u = (rpiv_ccm_func){rpiv_ccm_duct_fn, &ys};
    rpiv_sheet *sheet = NULL;
    rpiv_ccm_work *wk = NULL;
    rpiv_ccm_corr *c = NULL;
    CHECK_OK(rpiv_sheet_new(&ec->sheet, &sheet));
    rpiv_ccm_sheet_at at = {sheet, xs};
    mo.illum = (rpiv_ccm_func){rpiv_ccm_sheet_fn, &at};
    CHECK_OK(rpiv_ccm_work_new(&p, &wk));
    CHECK_OK(rpiv_ccm_corr_new(0, &c));
    if (wk && c && rpiv_ccm_stat_corr(&mo, wk, c) == RPIV_OK) {
        /* which block the spline reads on this plane: the 7 x 7 around the integer maximum
         * near 0 if all positive, else the 5 x 5, else the 3-point Gaussian */
        {
            int bi = 0, bj = 0;
            for (int jj = -1; jj <= 1; jj++)
                for (int ii = -1; ii <= 1; ii++)
                    if (pl[((jj + w) % w) * w + (ii + w) % w] >
                        pl[((bj + w) % w) * w + (bi + w) % w]) {
                        bi = ii;
                        bj = jj;
                    }
            int ok7 = 1, ok5 = 1;
            for (int jj = -3; jj <= 3; jj++)
                for (int ii = -3; ii <= 3; ii++) {
                    float v = pl[((bj + jj + w) % w) * w + (bi + ii + w) % w];
                    if (!(v > 0)) {
                        ok7 = 0;
                        if (abs(ii) <= 2 && abs(jj) <= 2)
                            ok5 = 0;
                    }
                }
            g_blk[ok7 ? 0 : ok5 ? 1 : 2]++;
            /* the same estimator after subtracting the plane's far-field level (the median of
             * the shifts beyond w/4 in x or y: the mean removal's constant baseline) */
            float *cp = malloc((size_t)w * (size_t)w * sizeof *cp);
            float *far = malloc((size_t)w * (size_t)w * sizeof *far);
            if (cp && far) {
                size_t nf = 0;
                for (int jj = 0; jj < w; jj++)
                    for (int ii = 0; ii < w; ii++) {
                        int sx = ii < w / 2 ? ii : ii - w, sy = jj < w / 2 ? jj : jj - w;
                        if (abs(sx) > w / 4 || abs(sy) > w / 4)
                            far[nf++] = pl[jj * w + ii];
                    }
                qsort(far, nf, sizeof *far, cmp_float);
                float med = far[nf / 2];
                for (int t = 0; t < w * w; t++)
                    cp[t] = pl[t] - med;
                rpiv_peak f0, f1;
                rpiv_peak_find(pl, w, w, 0, RPIV_SUBPIXEL_SPLINE, &f0);
                rpiv_peak_find(cp, w, w, 0, RPIV_SUBPIXEL_SPLINE, &f1);
                g_bsub[0] += (f0.ix + f0.dx + up) - (double)f->u[k];
                g_bsub[1] += (f1.ix + f1.dx) - (f0.ix + f0.dx);
                g_bsub[2] += (double)med / (double)pl[0];
            }
            free(cp);
            free(far);
        }
        double c0 = rpiv_ccm_corr_eval(c, up, vp), e0 = (double)pl[0];
        for (int i = -3; i <= 3; i++) {
            double e = (double)pl[(i + w) % w] / e0, r = rpiv_ccm_corr_eval(c, up + i, vp) / c0;
            g_ln[0][i + 3] += e;
            g_ln[1][i + 3] += r;
        }
        g_cnt++;
        /* the expected engine plane: each term weighted by the pairs its residual shift keeps
         * in the circular window, (1 - |sx|/W)(1 - |sy|/W), minus the mean removal's baseline
         * (the plane sums to 0: minus the weighted volume over W^2); 4 variants */
        double vol = 0, vol0 = 0;
        for (size_t t = 0; t < c->n; t++) {
            double sx = c->g[t].dx - up, sy = c->g[t].dy - vp;
            double wt = fmax(0, 1 - fabs(sx) / w) * fmax(0, 1 - fabs(sy) / w);
            vol += c->g[t].amp * wt * M_PI / c->g[t].c;
            vol0 += c->g[t].amp * M_PI / c->g[t].c;
        }
        rpiv_ccm_corr *cw = NULL;
        CHECK_OK(rpiv_ccm_corr_new(c->n, &cw));
        for (size_t t = 0; cw && t < c->n; t++) {
            rpiv_ccm_gauss g = c->g[t];
            double sx = g.dx - up, sy = g.dy - vp;
            g.amp *= fmax(0, 1 - fabs(sx) / w) * fmax(0, 1 - fabs(sy) / w);
            CHECK_OK(rpiv_ccm_corr_add(cw, g));
        }
        for (int v = 0; cw && v < 4; v++) {
            const rpiv_ccm_corr *cc = v & 1 ? cw : c;
            double base = v & 2 ? -(v & 1 ? vol : vol0) / ((double)w * w) : 0;
            int mx = 0;
            double best = -HUGE_VAL;
            for (int i = -2; i <= 2; i++) {
                double r = rpiv_ccm_corr_eval(cc, up + i, vp);
                if (r > best) {
                    best = r;
                    mx = i;
                }
            }
            enum { PW = 8 };
            float pl8[PW * PW];
            for (int jj = -4; jj < 4; jj++)
                for (int ii = -4; ii < 4; ii++)
                    pl8[((jj + PW) % PW) * PW + (ii + PW) % PW] =
                        (float)(rpiv_ccm_corr_eval(cc, up + mx + ii, vp + jj) + base);
            rpiv_peak fit;
            rpiv_peak_find(pl8, PW, PW, 1, RPIV_SUBPIXEL_SPLINE, &fit);
            g_est[v] += up + mx + fit.ix + fit.dx - (double)f->u[k];
        }
        /* SHEAR_DUMP=file (study): the engine's 7 x 7 summed samples about its predictor and
         * the expected plane's (pair loss and baseline), with the ideal, one window a line */
        if (cw && getenv("SHEAR_DUMP")) {
            FILE *fd = fopen(getenv("SHEAR_DUMP"), "a");
            rpiv_ccm_peak pc;
            if (fd && rpiv_ccm_corr_peak(c, &p, &pc) == RPIV_OK) {
                fprintf(fd, "%zu %.6f %.6f %.6f %.6f %.6f", k, up, vp, (double)f->u[k], pc.dx,
                        pc.dy);
                for (int jj = -3; jj <= 3; jj++)
                    for (int ii = -3; ii <= 3; ii++)
                        fprintf(fd, " %.8g", (double)pl[((jj + w) % w) * w + (ii + w) % w]);
                for (int jj = -3; jj <= 3; jj++)
                    for (int ii = -3; ii <= 3; ii++)
                        fprintf(fd, " %.8g",
                                rpiv_ccm_corr_eval(cw, up + ii, vp + jj) - vol / ((double)w * w));
                fprintf(fd, "\n");
            }
            if (fd)
                fclose(fd);
        }
        rpiv_ccm_corr_free(cw);
        /* the window's average over its area (hypothesis 2): the CCM's terms at 4 x 4
         * sub-positions of the final window, each shifted by the linear part of the
         * prediction's variation over the window (the deformation follows it), summed; its
         * continuous peak against the centre's */
        rpiv_ccm_corr *ca = NULL;
        if (atoi(getenv("SHEAR_PLANE")) >= 2)
            CHECK_OK(rpiv_ccm_corr_new(0, &ca));
        double pj[4][4], dd[4] = {-12, -4, 4, 12};
        for (int a = 0; ca && a < 4; a++)
            for (int b = 0; b < 4; b++) {
                rpiv_ccm_peak pk;
                double sx = xs + dd[b] * g_spp, sy = ys + dd[a] * g_spp;
                CHECK_OK(rpiv_config_ccm_predict(ec, ec->synth.dt_s, sx, sy, -1, &pk, NULL));
                pj[a][b] = pk.dx;
            }
        double gx = 0, gy = 0;
        for (int a = 0; a < 4; a++)
            for (int b = 0; b < 4; b++) {
                gx += pj[a][b] * dd[b] / (4 * 320.0);
                gy += pj[a][b] * dd[a] / (4 * 320.0);
            }
        for (int a = 0; ca && a < 4; a++)
            for (int b = 0; b < 4; b++) {
                double sy = ys + dd[a] * g_spp, sx = xs + dd[b] * g_spp;
                rpiv_ccm_model m2 = rpiv_config_ccm_model(ec, ec->synth.dt_s);
                m2.u = (rpiv_ccm_func){rpiv_ccm_duct_fn, &sy};
                rpiv_ccm_sheet_at at2 = {sheet, sx};
                m2.illum = (rpiv_ccm_func){rpiv_ccm_sheet_fn, &at2};
                rpiv_ccm_corr *c2 = NULL;
                CHECK_OK(rpiv_ccm_corr_new(0, &c2));
                if (c2 && rpiv_ccm_stat_corr(&m2, wk, c2) == RPIV_OK)
                    for (size_t t = 0; t < c2->n; t++) {
                        rpiv_ccm_gauss g = c2->g[t];
                        g.dx -= gx * dd[b] + gy * dd[a];
                        g.amp /= 16;
                        CHECK_OK(rpiv_ccm_corr_add(ca, g));
                    }
                rpiv_ccm_corr_free(c2);
            }
        rpiv_ccm_peak pa, pc;
        if (ca && rpiv_ccm_corr_peak(ca, &p, &pa) == RPIV_OK &&
            rpiv_ccm_corr_peak(c, &p, &pc) == RPIV_OK) {
            g_avg[0] += pa.dx - pc.dx;
            g_avg[1] += pa.dx_sub - pc.dx_sub;
        }
        rpiv_ccm_corr_free(ca);
    }
    rpiv_ccm_corr_free(c);
    rpiv_ccm_work_free(wk);
    rpiv_sheet_free(sheet);
}

static void plane_report(void)
{
    if (!(g_cnt > 0))
        return;
    printf("  plane along x, relative to shift 0 (mean over %g windows):\n   engine", g_cnt);
    for (int i = 0; i < 7; i++)
        printf(" %8.5f", g_ln[0][i] / g_cnt);
    printf("\n   CCM   ");
    for (int i = 0; i < 7; i++)
        printf(" %8.5f", g_ln[1][i] / g_cnt);
    printf("\n");
    printf("   predicted - ensemble (spline on the expected plane): infinite window %+.4f, pair "
           "loss %+.4f, baseline %+.4f, both %+.4f px\n",
           g_est[0] / g_cnt, g_est[1] / g_cnt, g_est[2] / g_cnt, g_est[3] / g_cnt);
    printf("   the window's area average - its centre: continuous %+.4f, spline %+.4f px\n",
           g_avg[0] / g_cnt, g_avg[1] / g_cnt);
    printf(
        "   the spline's block on the engine's planes: 7 x 7 %g, 5 x 5 %g, 3-point Gaussian %g\n",
        g_blk[0], g_blk[1], g_blk[2]);
    printf("   far-field level %+.4f of the peak; subtracting it moves the spline by %+.4f px "
           "(re-estimate - engine %+.2g)\n",
           g_bsub[2] / g_cnt, g_bsub[1] / g_cnt, g_bsub[0] / g_cnt);
    memset(g_bsub, 0, sizeof g_bsub);
    memset(g_blk, 0, sizeof g_blk);
    memset(g_avg, 0, sizeof g_avg);
    memset(g_est, 0, sizeof g_est);
    memset(g_ln, 0, sizeof g_ln);
    g_cnt = 0;
}

/* SHEAR_AREA=1: what the engine measures with the window's area average too
 * (rpiv_ccm_predict_area): the model at 4 x 4 sub-positions of the final window (8 px
 * squares; the duct at each y*, the sheet at each x*), the engine's window modelled. */
static void area_peak(const rpiv_experiment *ew, double xs, double ys, double spp,
                      const rpiv_ccm_area_opts *o, rpiv_ccm_peak *pk)
{
    enum { NS = 4 };
    const double dd[NS] = {-12, -4, 4, 12};
    rpiv_ccm_model mk[NS * NS];
    rpiv_ccm_sheet_at at[NS * NS];
    double yk[NS * NS], ox[NS * NS], oy[NS * NS];
    rpiv_ccm_params p = rpiv_ccm_params_default();
    p.subpixel = ew->piv.subpixel;
    rpiv_sheet *sheet = NULL;
    rpiv_ccm_work *w = NULL;
    CHECK_OK(rpiv_sheet_new(&ew->sheet, &sheet));
    CHECK_OK(rpiv_ccm_work_new(&p, &w));
    for (int a = 0; a < NS; a++)
        for (int b = 0; b < NS; b++) {
            int k = a * NS + b;
            ox[k] = dd[b];
            oy[k] = dd[a];
            yk[k] = ys + dd[a] * spp;
            at[k] = (rpiv_ccm_sheet_at){sheet, xs + dd[b] * spp};
            mk[k] = rpiv_config_ccm_model(ew, ew->synth.dt_s);
            mk[k].u = (rpiv_ccm_func){rpiv_ccm_duct_fn, &yk[k]};
            mk[k].illum = (rpiv_ccm_func){rpiv_ccm_sheet_fn, &at[k]};
        }
    memset(pk, 0, sizeof *pk);
    if (sheet && w)
        CHECK_OK(rpiv_ccm_predict_area(mk, ox, oy, NS * NS, o, w, pk));
    rpiv_ccm_work_free(w);
    rpiv_sheet_free(sheet);
}

/* Study (SHEAR_BORDER=P): the ensemble of the larger pairs rb, of which the w x h pairs of f
 * are the centre; every vector of f against the same window of the larger pairs (same
 * particles, away from the border): the border's effect on what the engine measures, by
 * side of the outer ring (left, right, top, bottom column/row, corners in both) and inside. */
static void border_study(const rpiv_experiment *exb, const run *rb, rpiv_subpixel m,
                         const rpiv_field *f, int pad)
{
    g_nostudy = 1;
    rpiv_field *fb = ensemble(exb, rb, m);
    g_nostudy = 0;
    double s[5] = {0}, n[5] = {0};
    for (int j = 0; fb && j < f->ny; j++)
        for (int i = 0; i < f->nx; i++) {
            size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
            double x = f->x0 + i * f->dx + pad, y = f->y0 + j * f->dy + pad;
            int ib = (int)lround((x - fb->x0) / fb->dx), jb = (int)lround((y - fb->y0) / fb->dy);
            if (ib < 0 || jb < 0 || ib >= fb->nx || jb >= fb->ny ||
                fabs(fb->x0 + ib * fb->dx - x) > 1e-3 || fabs(fb->y0 + jb * fb->dy - y) > 1e-3)
                continue;
            size_t kb = (size_t)jb * (size_t)fb->nx + (size_t)ib;
            if (f->flag[k] != RPIV_FLAG_VALID || fb->flag[kb] != RPIV_FLAG_VALID)
                continue;
            double d = (double)f->u[k] - (double)fb->u[kb];
            int side[4] = {i == 0, i == f->nx - 1, j == 0, j == f->ny - 1};
            int ring = 0;
            for (int t = 0; t < 4; t++)
                if (side[t]) {
                    s[t] += d;
                    n[t]++;
                    ring = 1;
                }
            if (!ring) {
                s[4] += d;
                n[4]++;
            }
            if (getenv("SHEAR_VERBOSE"))
                printf("    border %s (%3d, %3d): cropped %.4f, whole %.4f, diff %+.4f\n",
                       rpiv_subpixel_names[m], i, j, (double)f->u[k], (double)fb->u[kb], d);
        }
    printf("  %s: cropped - whole pairs (same windows), mean px: left %+.4f (%g), right %+.4f "
           "(%g), top %+.4f (%g), bottom %+.4f (%g), interior %+.4f (%g)\n",
           rpiv_subpixel_names[m], n[0] ? s[0] / n[0] : 0, n[0], n[1] ? s[1] / n[1] : 0, n[1],
           n[2] ? s[2] / n[2] : 0, n[2], n[3] ? s[3] / n[3] : 0, n[3], n[4] ? s[4] / n[4] : 0,
           n[4]);
    rpiv_field_free(fb);
}

/* Means over the valid vectors, px: [estimator][0] ensemble - ideal (the CCM's continuous
 * peak, pixel-integrated images), [1] ensemble - predicted (the estimator on the CCM's sampled
 * plane), [2] predicted - ideal, [3] ensemble - continuous peak of point-sampled images
 * (pixel_box 0, the paper's), [4] ensemble - prediction with the pixels' triangle replaced
 * by the Gaussian of its variance (session 5's stand-in); [5] the largest |ensemble - ideal|,
 * [6] the standard deviation of ensemble - predicted; [7] ensemble - ideal and [8] ensemble -
 * predicted over the interior vectors (not the outer ring of windows, whose deformed windows
 * reach beyond the images' border); [9] ensemble - predicted with the engine's window
 * modelled ([bias] window_model = 1: pair loss, mean removal) and [10] the same over the
 * interior vectors; [11], [12] the same with the window's area average too (SHEAR_AREA=1), the
 * deformation following the plane; [13], [14] the quadratic; [15], [16] the engine's spline of
 * it on the grid; [17], [18] the engine's own predictor. */
typedef struct shear_result {
    double m[2][21];
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
    if (getenv("SHEAR_SEED")) /* study: another realisation of the particles and noise */
        CHECK_OK(rpiv_config_set(&ex, "synth", "seed", getenv("SHEAR_SEED"), "test"));
    if (getenv("SHEAR_SPREAD_UM"))
        CHECK_OK(rpiv_config_set(&ex, "particles", "diameter_spread_um", getenv("SHEAR_SPREAD_UM"),
                                 "test"));
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
    g_spp = in.star_per_px;
    size_t npx = (size_t)r.w * (size_t)r.h;
    r.img = malloc(2 * npx * (size_t)r.npairs * sizeof *r.img);
    CHECK(r.img != NULL);
    if (!r.img) {
        rpiv_synth_free(s);
        return;
    }
    /* study (SHEAR_BORDER=P): the pairs rendered P px larger on every side (the same field of
     * view's centre, so the same x*, y* at every pixel) and cropped to w x h; the larger pairs
     * are kept (rb) to measure the same windows away from the images' border */
    int pad = getenv("SHEAR_BORDER") ? atoi(getenv("SHEAR_BORDER")) : 0;
    rpiv_experiment exb = ex;
    run rb = {r.w + 2 * pad, r.h + 2 * pad, r.npairs, NULL};
    if (pad > 0) {
        exb.synth.width_px = rb.w;
        exb.synth.height_px = rb.h;
        rpiv_synth_free(s);
        s = NULL;
        CHECK_OK(rpiv_config_synth_new(&exb, NULL, &s));
        rb.img = malloc(2 * (size_t)rb.w * (size_t)rb.h * (size_t)r.npairs * sizeof *rb.img);
        CHECK(rb.img != NULL && s != NULL);
        if (!rb.img || !s) {
            free(r.img);
            rpiv_synth_free(s);
            return;
        }
    }
    for (int i = 0; i < r.npairs; i++) {
        rpiv_image a = {r.w, r.h, 16, r.img + 2 * (size_t)i * npx};
        rpiv_image b = {r.w, r.h, 16, r.img + (2 * (size_t)i + 1) * npx};
        if (pad > 0) {
            size_t nb = (size_t)rb.w * (size_t)rb.h;
            rpiv_image ab = {rb.w, rb.h, 16, rb.img + 2 * (size_t)i * nb};
            rpiv_image bb = {rb.w, rb.h, 16, rb.img + (2 * (size_t)i + 1) * nb};
            CHECK_OK(rpiv_synth_pair(s, (unsigned long)i, &ab, &bb));
            for (int y = 0; y < r.h; y++) {
                size_t o = (size_t)(y + pad) * (size_t)rb.w + (size_t)pad;
                memcpy(a.px + (size_t)y * (size_t)r.w, ab.px + o, (size_t)r.w * sizeof *a.px);
                memcpy(b.px + (size_t)y * (size_t)r.w, bb.px + o, (size_t)r.w * sizeof *b.px);
            }
        } else
            CHECK_OK(rpiv_synth_pair(s, (unsigned long)i, &a, &b));
    }
    const rpiv_subpixel ms[2] = {RPIV_SUBPIXEL_AUTO, RPIV_SUBPIXEL_GAUSS};
    for (int q = 0; q < 2; q++) {
        rpiv_field *f = ensemble(&ex, &r, ms[q]);
        if (!f)
            continue;
        /* study (SHEAR_SPLIT=K): the ensembles of K disjoint groups of the pairs against the
         * whole one: the sampled estimator's bias from the plane's noise goes as 1/pairs */
        int split = getenv("SHEAR_SPLIT") ? atoi(getenv("SHEAR_SPLIT")) : 0;
        if (split > 1 && q == 0) {
            double dsum = 0;
            int dn = 0;
            for (int g = 0; g < split; g++) {
                run rg = r;
                rg.npairs = r.npairs / split;
                rg.img = r.img + 2 * (size_t)g * (size_t)rg.npairs * (size_t)r.w * (size_t)r.h;
                g_nostudy = 1;
                rpiv_field *fg = ensemble(&ex, &rg, ms[q]);
                g_nostudy = 0;
                size_t nv = (size_t)f->nx * (size_t)f->ny;
                for (size_t k = 0; fg && k < nv; k++)
                    if (f->flag[k] == RPIV_FLAG_VALID && fg->flag[k] == RPIV_FLAG_VALID) {
                        dsum += (double)fg->u[k] - (double)f->u[k];
                        dn++;
                    }
                rpiv_field_free(fg);
            }
            printf("  %d groups of %d pairs: mean (group - all) %+.4f px over %d vectors\n", split,
                   r.npairs / split, dn ? dsum / dn : 0.0, dn);
        }
        rpiv_experiment ec = ex, e0 = ex, ew = ex, ei;
        ec.piv.subpixel = e0.piv.subpixel = ew.piv.subpixel = ms[q];
        ec.bias.window_model = 0;  /* the infinite window, whatever the default */
        ew.bias.window_model = 1;  /* the final [piv] window (docs/ccm.md) */
        ew.bias.window_interp = 0; /* per term (the default before session 10) */
        ew.bias.window_area = 1;   /* its centre only; area_peak averages */
        e0.bias.pixel_box = 0;     /* the paper's continuous images; ccm_peak blurs them */
        ei = ew;
        ei.bias.window_interp = 1; /* the default: the deformation's interpolation, the pairs
                                    * lost per shift, the noise of these pairs' planes */
        ei.bias.window_pairs = getenv("SHEAR_NOISEFREE") ? 0 : r.npairs;
        double *m = res->m[q], ss = 0;
        int n = 0, nin = 0;
        for (int j = 0; j < f->ny; j++)
            for (int i = 0; i < f->nx; i++) {
                size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
                if (f->flag[k] != RPIV_FLAG_VALID)
                    continue;
                double x = f->x0 + i * f->dx, y = f->y0 + j * f->dy;
                double xs = in.x0_star + (x + 0.5) * in.star_per_px;
                double ys = in.y0_star + (y + 0.5) * in.star_per_px;
                rpiv_ccm_peak pk, p0, pb, pw;
                double scale, u = (double)f->u[k];
                CHECK_OK(rpiv_config_ccm_predict(&ec, ex.synth.dt_s, xs, ys, -1, &pk, &scale));
                CHECK_OK(rpiv_config_ccm_predict(&e0, ex.synth.dt_s, xs, ys, -1, &p0, &scale));
                CHECK_OK(rpiv_config_ccm_predict(&ew, ex.synth.dt_s, xs, ys, -1, &pw, &scale));
                rpiv_ccm_peak pi;
                CHECK_OK(rpiv_config_ccm_predict(&ei, ex.synth.dt_s, xs, ys, -1, &pi, &scale));
                m[9] += u - pw.dx_sub;
                m[19] += u - pi.dx_sub;
                /* the area average: the deformation following the plane (session 6), the
                 * quadratic, the engine's predictor on the grid (edges) */
                rpiv_ccm_peak pa = pw, pq = pw, pg = pw, pe = pw;
                if (getenv("SHEAR_AREA")) {
                    rpiv_ccm_area_opts o = rpiv_ccm_area_opts_default();
                    o.quadratic = 0;
                    area_peak(&ew, xs, ys, in.star_per_px, &o, &pa);
                    o.quadratic = 1;
                    area_peak(&ew, xs, ys, in.star_per_px, &o, &pq);
                    o = (rpiv_ccm_area_opts){1, f->nx, f->ny, i, j, f->dx, f->dy, NULL, NULL};
                    area_peak(&ew, xs, ys, in.star_per_px, &o, &pg);
                    /* the engine's own predictor's variation at the 4 x 4 sub-positions */
                    double du[16], dv[16], u0, v0;
                    if (g_dpred) {
                        rpiv_deform_pred_eval(g_dpred, x, y, &u0, &v0);
                        for (int t = 0; t < 16; t++) {
                            rpiv_deform_pred_eval(g_dpred, x + 8.0 * (t % 4) - 12,
                                                  y + 8.0 * (t / 4) - 12, &du[t], &dv[t]);
                            du[t] -= u0;
                            dv[t] -= v0;
                        }
                        o.def_u = du;
                        o.def_v = dv;
                        area_peak(&ew, xs, ys, in.star_per_px, &o, &pe);
                    }
                }
                m[11] += u - pa.dx_sub;
                m[13] += u - pq.dx_sub;
                m[15] += u - pg.dx_sub;
                m[17] += u - pe.dx_sub;
                ccm_peak(&e0, xs, ys, ms[q], 1, &pb);
                if (getenv("SHEAR_VERBOSE"))
                    printf("    %s (%6.2f, %6.2f) x* %.3f y* %.3f: ensemble %.4f, ideal %.4f, "
                           "predicted %.4f, point-sampled %.4f, Gaussian stand-in %.4f (%.4f), "
                           "window %.4f, area %.4f\n",
                           rpiv_subpixel_names[ms[q]], x, y, xs, ys, u, pk.dx, pk.dx_sub, p0.dx,
                           pb.dx, pb.dx_sub, pw.dx_sub, pa.dx_sub);
                if (getenv("SHEAR_VERBOSE") && getenv("SHEAR_AREA"))
                    printf("    area (%2d, %2d): plane %.4f, quadratic %.4f, grid %.4f, engine's "
                           "predictor %.4f\n",
                           i, j, pa.dx_sub, pq.dx_sub, pg.dx_sub, pe.dx_sub);
                if (g_planes && g_pred && q == 0)
                    plane_study(&ec, xs, ys, f, k, (double)g_pred->u[k], (double)g_pred->v[k]);
                m[0] += u - pk.dx;
                m[1] += u - pk.dx_sub;
                m[2] += pk.dx_sub - pk.dx;
                m[3] += u - p0.dx;
                m[4] += u - pb.dx_sub;
                m[5] = fmax(m[5], fabs(u - pk.dx));
                if (i > 0 && j > 0 && i < f->nx - 1 && j < f->ny - 1) {
                    m[7] += u - pk.dx;
                    m[8] += u - pk.dx_sub;
                    m[10] += u - pw.dx_sub;
                    m[12] += u - pa.dx_sub;
                    m[14] += u - pq.dx_sub;
                    m[16] += u - pg.dx_sub;
                    m[18] += u - pe.dx_sub;
                    m[20] += u - pi.dx_sub;
                    nin++;
                }
                ss += (u - pk.dx_sub) * (u - pk.dx_sub);
                n++;
            }
        CHECK(n > 0);
        if (n) {
            for (int t = 0; t < 5; t++)
                m[t] /= n;
            m[6] = sqrt(fmax(ss / n - m[1] * m[1], 0));
            m[7] /= nin > 0 ? nin : 1;
            m[8] /= nin > 0 ? nin : 1;
            m[9] /= n;
            m[10] /= nin > 0 ? nin : 1;
            m[11] /= n;
            m[12] /= nin > 0 ? nin : 1;
            m[13] /= n;
            m[14] /= nin > 0 ? nin : 1;
            m[15] /= n;
            m[16] /= nin > 0 ? nin : 1;
            m[17] /= n;
            m[18] /= nin > 0 ? nin : 1;
            m[19] /= n;
            m[20] /= nin > 0 ? nin : 1;
            printf(
                "  %-5s %d vectors: ensemble - ideal %+.4f (max |.| %.4f), ensemble - "
                "predicted %+.4f (std %.4f), predicted - ideal %+.4f; ensemble - "
                "point-sampled ideal %+.4f, ensemble - Gaussian stand-in's prediction %+.4f px\n",
                rpiv_subpixel_names[ms[q]], n, m[0], m[5], m[1], m[6], m[2], m[3], m[4]);
            printf("        %d interior vectors: ensemble - ideal %+.4f, ensemble - predicted "
                   "%+.4f px\n",
                   nin, m[7], m[8]);
            printf("        the engine's window modelled: ensemble - predicted %+.4f px (interior "
                   "%+.4f)\n",
                   m[9], m[10]);
            printf("        with the deformation's interpolation ([bias] window_interp): "
                   "ensemble - predicted %+.4f px (interior %+.4f)\n",
                   m[19], m[20]);
            if (getenv("SHEAR_AREA"))
                printf(
                    "        and its area average: ensemble - predicted %+.4f px (interior "
                    "%+.4f) following the plane, %+.4f (%+.4f) the quadratic, %+.4f "
                    "(%+.4f) the engine's spline of the quadratic on the grid, %+.4f (%+.4f) the "
                    "engine's own predictor\n",
                    m[11], m[12], m[13], m[14], m[15], m[16], m[17], m[18]);
        }
        plane_report();
        res->n = n;
        if (pad > 0) /* after the comparison: it replaces the last pass's study state */
            border_study(&exb, &rb, ms[q], f, pad);
        rpiv_field_free(f);
    }
    free(r.img);
    free(rb.img);
    rpiv_synth_free(s);
}

/* The experiment's particles (d_e 1.8 px in focus): the spline removes the estimator's bias on
 * the CCM's own planes (predicted - ideal); the pixels' box (the exact triangle) explains most
 * of the gap to the point-sampled ideal, and the Gaussian that stood for the triangle gives
 * nearly the same prediction (hypothesis 1 of issue 15: not the rest). What remains at 100
 * pairs (-0.04 px) is listed in docs/ccm.md, "What the engine measures". */
static void small_particle_images(void)
{
    shear_result r;
    shear_case(NULL, 100, &r);
    if (!r.n)
        return;
    CHECK(fabs(r.m[0][2]) <= 0.01); /* spline on the CCM's plane: +0.003 px */
    CHECK(r.m[1][2] <= -0.04);      /* the 3-point Gaussian: -0.049 px    */
    CHECK(fabs(r.m[0][0]) < fabs(r.m[1][0]) - 0.03);
    CHECK(fabs(r.m[0][0]) < fabs(r.m[0][3]) - 0.04); /* pixels: -0.092 -> -0.039 px */
    CHECK(fabs(r.m[0][0]) <= 0.05);
    CHECK(fabs(r.m[0][1] - r.m[0][4]) < 0.005); /* triangle vs its Gaussian: 0.002 px */
    /* the engine's window modelled (pair loss, mean removal, the deformed lattice): the gap
     * to the prediction shrinks, -0.042 -> -0.039 px (spline), -0.030 -> -0.024 (Gaussian) */
    CHECK(fabs(r.m[0][9]) < fabs(r.m[0][1]) - 0.002);
    CHECK(fabs(r.m[1][9]) < fabs(r.m[1][1]) - 0.004);
    /* the default ([bias] window_interp, docs/ccm.md "The planes' skew", "Session 10"): the
     * deformation's interpolation, the pairs lost per shift and the noise of these 100 pairs'
     * planes weighting the spline's paths: -0.0386 -> -0.0112 px (spline; noise-free -0.0250),
     * -0.0237 -> -0.0124 (the 3-point Gaussian): the target, 0.02 px, met */
    CHECK(fabs(r.m[0][19]) < fabs(r.m[0][9]) - 0.015); /* at 300 pairs: -0.0291 -> -0.0097 */
    CHECK(fabs(r.m[1][19]) < fabs(r.m[1][9]) - 0.008);
    CHECK(fabs(r.m[0][19]) <= 0.02);
    CHECK(fabs(r.m[1][19]) <= 0.02);
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
    /* with the engine's window the spline's gap grows here (-0.0095 -> -0.012 px): the
     * engine's plane is narrower than the model's beyond the mean removal (docs/ccm.md) */
    CHECK(fabs(r.m[0][9]) <= 0.02);
    CHECK(fabs(r.m[0][19]) <= fabs(r.m[0][9])); /* window_interp: -0.0122 -> -0.0086 px */
    CHECK(fabs(r.m[1][19]) <= fabs(r.m[1][9])); /* 3-point Gaussian: -0.0102 -> -0.0069 px */
}

int main(void)
{
    const char *only = getenv("SHEAR_CASE"); /* study: small or large only */
    if (!only || !strcmp(only, "small"))
        RUN_TEST(small_particle_images);
    if (!only || !strcmp(only, "large"))
        RUN_TEST(large_particle_images);
    rpiv_deform_pred_free(g_dpred);
    rpiv_field_free(g_pred);
    free(g_planes);
    return check_summary();
}
