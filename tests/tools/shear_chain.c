/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/tools/shear_chain.c - issue 15, the planes' skew link by link (docs/ccm.md, "Session 9:
 * the planes' skew"; diagnostics, not built by CMake). test_peak_shear's experiment (192 x
 * 128 px, the skewed R-PIV sheet, the duct at 5.9 px, d_e 1.8 px), N pairs rendered by synth;
 * the engine's three-pass ensemble (spline); for every window of the last pass, three planes on
 * the engine's lattice (about its predictor pu at the window's centre):
 *   engine    the engine's summed plane (deformed, mean-removed windows);
 *   particles synth's own particles of the same pairs, each an exact term (its A image's peak
 *             and sigma times its B image's, the pixels' triangle) at its displacement less the
 *             engine's predictor at its mid position (the deformation follows it), kept when
 *             its images lie in the deformed windows of both frames, less the mean removal's
 *             baseline (the kept volume over W^2);
 *   CCM       the CCM's terms at the window's centre with the pair loss and the baseline, as
 *             test_peak_shear's SHEAR_PLANE study.
 *   exact     the same particles' exact discrete correlation: each image's pixel integrals
 *             (erf) in the windows at the deformed positions (an ideal deformation), circular,
 *             less its own share of the mean removal, no pairs of different particles;
 *   full      (SC_FULL=1, slow) the windows drawn from those pixel integrals, all particles
 *             together, mean-removed and correlated: exact + the pairs of different particles
 *             (R_F); with SC_NONOISE it is the engine's plane but for the interpolation;
 *   CCM+interp the CCM's plane at the integer (undeformed) lattice convolved with the engine's
 *             interpolation kernel kappa (deformed runs), with the pair loss per term as the
 *             model has it, and "+tent" with the pair loss per shift of the deformed lattice
 *             (1 - |n|/W)(1 - |m|/H) instead (Keane & Adrian's F_I at the plane's shift).
 * Printed: the spline's estimate on each (means over the windows of the differences), the
 * planes along x relative to shift 0, and the engine's plane over the particles' and the exact
 * one at shifts 0, +-1 (absolute: all in counts^2).
 *   shear_chain pairs
 * Env: SC_NONOISE=1 (no shot or read noise), SC_NODEFORM=1 (whole-pixel offsets),
 * SC_SEED=S, SC_RAW=file (engine, particles, CCM, exact 7 x 7 blocks per window), SC_FULL=1,
 * SC_VERBOSE=1.
 * Build (from build/): cc -O2 -fopenmp -std=c11 -D_DEFAULT_SOURCE -I../tests -I../include
 *   -Iinclude -I../src/piv -I../src/base ../tests/tools/shear_chain.c -o shear_chain
 *   librpiv.a -lfftw3f -lgsl -lgslcblas -ltiff -lpng16 -lnetcdf -lplplot -lstb -ljpeg -lm
 *   -L/usr/lib/x86_64-linux-gnu/openmpi/lib -lmpi */
#include "piv_impl.h"
#include "rpiv/ccm.h"
#include "rpiv/config.h"
#include "rpiv/ensemble.h"
#include "rpiv/synth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static double g_k[3], g_kl[7], g_tl[7];
static float *g_planes;
static size_t g_nplanes;
static rpiv_deform_pred *g_dpred;

static rpiv_field *ensemble(const rpiv_experiment *ex, int w, int h, int npairs, float *img)
{
    rpiv_piv_params prm = ex->piv;
    prm.subpixel = RPIV_SUBPIXEL_AUTO;
    prm.ensemble = 1;
    if (getenv("SC_NODEFORM"))
        prm.deform = 0;
    rpiv_piv *pv = NULL;
    rpiv_field *pred = NULL;
    if (rpiv_piv_new(&prm, w, h, NULL, &pv))
        return NULL;
    size_t npx = (size_t)w * (size_t)h;
    for (int k = 0; k < rpiv_piv_npass(pv); k++) {
        rpiv_ensemble *e = NULL;
        rpiv_field *f = NULL;
        if (rpiv_ensemble_new(pv, k, pred, &e))
            return NULL;
        for (int i = 0; i < npairs; i++) {
            rpiv_image a = {w, h, 16, img + 2 * (size_t)i * npx};
            rpiv_image b = {w, h, 16, img + (2 * (size_t)i + 1) * npx};
            if (rpiv_ensemble_add(e, &a, &b))
                return NULL;
        }
        if (k == rpiv_piv_npass(pv) - 1) {
            if (pred && piv_pred_new(pv, pred, k, 0, NULL, 1, &g_dpred))
                return NULL;
            size_t nd = 0;
            const float *d = rpiv_ensemble_data(e, &nd);
            g_planes = malloc(nd * sizeof *g_planes);
            memcpy(g_planes, d, nd * sizeof *g_planes);
            g_nplanes = nd;
        }
        if (rpiv_ensemble_finish(e, &f))
            return NULL;
        rpiv_ensemble_free(e);
        rpiv_field_free(pred);
        pred = f;
    }
    rpiv_piv_free(pv);
    return pred;
}

/* The spline's estimate (x) on a w x w circular plane given at shifts -R..R about the lattice's
 * 0 (the rest: fill). */
enum { R = 6, NB = 2 * R + 1 };
static double spline_x(const double *blk, double fill, int w)
{
    float *pl = malloc((size_t)w * (size_t)w * sizeof *pl);
    for (int t = 0; t < w * w; t++)
        pl[t] = (float)fill;
    for (int j = -R; j <= R; j++)
        for (int i = -R; i <= R; i++)
            pl[((j + w) % w) * w + (i + w) % w] = (float)blk[(j + R) * NB + i + R];
    rpiv_peak pk;
    rpiv_peak_find(pl, w, w, 0, RPIV_SUBPIXEL_SPLINE, &pk);
    free(pl);
    return pk.ix + pk.dx;
}

/* The cardinal cubic B-spline (the engine's interpolant of prefiltered samples): eta(x) =
 * sum_k sqrt(3) z^|k| beta3(x - k), z = sqrt(3) - 2. */
static double beta3(double x)
{
    x = fabs(x);
    return x < 1 ? 2.0 / 3 - x * x + 0.5 * x * x * x : x < 2 ? (2 - x) * (2 - x) * (2 - x) / 6 : 0;
}
static double eta(double x)
{
    const double z = sqrt(3.0) - 2;
    double s = 0;
    int k0 = (int)floor(x);
    for (int k = k0 - 30; k <= k0 + 30; k++)
        s += sqrt(3.0) * pow(z, abs(k)) * beta3(x - k);
    return s;
}
/* kappa(j) = sum_u eta(u + ta) eta(u + j + tb): the expected plane of frames interpolated at
 * X + ta (a) and X + tb (b) is the integer-lattice plane S convolved, P(n) = sum_m
 * kappa(n - m) S(m). Tabulated for j = j0 .. j0 + nj - 1. */
static void kappa(double ta, double tb, int j0, int nj, double *out)
{
    enum { U = 24 };
    double ea[2 * U + 1];
    int ua = (int)floor(-ta);
    for (int u = -U; u <= U; u++)
        ea[u + U] = eta(ua + u + ta);
    for (int j = 0; j < nj; j++) {
        double s = 0;
        for (int u = -U; u <= U; u++)
            s += ea[u + U] * eta(ua + u + j0 + j + tb);
        out[j] = s;
    }
}

typedef struct tp {
    double mx, my, ax, ay, bx, by, pa, sa, pb, sb;
    int pair;
} tp;

/* Add the separable image va ax[x] ay[y] to the w x w window img. */
static void splat(double *img, int w, double v, const double *ax, const double *ay)
{
    for (int y = 0; y < w; y++)
        if (ay[y] * v > 1e-12)
            for (int x = 0; x < w; x++)
                img[y * w + x] += v * ay[y] * ax[x];
}

/* The mean-removed circular correlation of the windows a, b at shifts -R..R, added to blk. */
static void corr_add(const double *a, const double *b, int w, double *blk)
{
    double ma = 0, mb = 0;
    for (int t = 0; t < w * w; t++) {
        ma += a[t];
        mb += b[t];
    }
    ma /= w * w;
    mb /= w * w;
    for (int m = -R; m <= R; m++)
        for (int n = -R; n <= R; n++) {
            double acc = 0;
            for (int y = 0; y < w; y++) {
                const double *ra = a + y * w, *rb = b + ((y + m + w) % w) * w;
                for (int x = 0; x < w; x++)
                    acc += (ra[x] - ma) * (rb[(x + n + w) % w] - mb);
            }
            blk[(m + R) * NB + n + R] += acc;
        }
}

/* A particle's pixel integrals over the w window pixels 0..w-1 (centres at integers) of its
 * image centred at x (window coordinates), sigma s. */
static void pix(double x, double s, int w, double *o)
{
    double k = 1 / (M_SQRT2 * s), e0 = erf((-0.5 - x) * k);
    for (int i = 0; i < w; i++) {
        double e1 = erf((i + 0.5 - x) * k);
        o[i] = 0.5 * (e1 - e0);
        e0 = e1;
    }
}

/* Add the particle's exact circular correlation (window coordinates of its A and B images)
 * to blk at shifts -R..R; return |a| |b| (the light of each image in its window). */
static double exact_term(const tp *q, double xa, double xb, double ya, double yb, int w,
                         double *blk, double *wa, double *wb)
{
    enum { WM = 64 };
    double ax[WM], bx_[WM], ay[WM], by[WM], cx[NB], cy[NB];
    pix(xa, q->sa, w, ax);
    pix(xb, q->sb, w, bx_);
    pix(ya, q->sa, w, ay);
    pix(yb, q->sb, w, by);
    double va = q->pa * 2 * M_PI * q->sa * q->sa, vb = q->pb * 2 * M_PI * q->sb * q->sb;
    double sax = 0, sbx = 0, say = 0, sby = 0;
    for (int i = 0; i < w; i++) {
        sax += ax[i];
        sbx += bx_[i];
        say += ay[i];
        sby += by[i];
    }
    for (int n = -R; n <= R; n++) {
        cx[n + R] = cy[n + R] = 0;
        for (int i = 0; i < w; i++) {
            cx[n + R] += ax[i] * bx_[((i + n) % w + w) % w];
            cy[n + R] += ay[i] * by[((i + n) % w + w) % w];
        }
    }
    for (int m = 0; m < NB; m++)
        for (int n = 0; n < NB; n++)
            blk[m * NB + n] += va * vb * cx[n] * cy[m];
    if (wa) {
        splat(wa, w, va, ax, ay);
        splat(wb, w, vb, bx_, by);
    }
    return va * vb * sax * sbx * say * sby;
}

int main(int argc, char **argv)
{
    int npairs = argc > 1 ? atoi(argv[1]) : 300, W = 192, H = 128;
    rpiv_experiment ex = rpiv_experiment_default();
    ex.synth.width_px = W;
    ex.synth.height_px = H;
    ex.synth.pairs = npairs;
    ex.synth.dt_s = 0.8e-3;
    if (getenv("SC_SEED") && rpiv_config_set(&ex, "synth", "seed", getenv("SC_SEED"), "env"))
        return 1;
    if (getenv("SC_NONOISE")) {
        ex.synth.read_noise = 0;
        ex.synth.shot_noise = 0;
    }
    rpiv_synth *s = NULL;
    if (rpiv_config_synth_new(&ex, NULL, &s))
        return 1;
    rpiv_synth_info in;
    rpiv_synth_get_info(s, &in);
    size_t npx = (size_t)W * (size_t)H;
    float *img = malloc(2 * npx * (size_t)npairs * sizeof *img);
    for (int i = 0; i < npairs; i++) {
        rpiv_image a = {W, H, 16, img + 2 * (size_t)i * npx};
        rpiv_image b = {W, H, 16, img + (2 * (size_t)i + 1) * npx};
        if (rpiv_synth_pair(s, (unsigned long)i, &a, &b))
            return 1;
    }
    rpiv_field *f = ensemble(&ex, W, H, npairs, img);
    if (!f)
        return 1;
    size_t nwin = (size_t)f->nx * (size_t)f->ny;
    int w = (int)lround(sqrt((double)(g_nplanes - 2 * nwin) / (double)nwin));
    int deform = !getenv("SC_NODEFORM");
    /* the particles of every pair, moved and imaged by synth */
    size_t ntp = 0, cap = 0;
    tp *all = NULL;
    for (int i = 0; i < npairs; i++) {
        rpiv_synth_particle *p;
        size_t n;
        if (rpiv_synth_particles_new(s, (unsigned long)i, &p, &n))
            return 1;
        for (size_t q = 0; q < n; q++) {
            rpiv_synth_particle a, b;
            rpiv_synth_advect(s, &p[q], -0.5, &a);
            rpiv_synth_advect(s, &p[q], 0.5, &b);
            tp t = {p[q].x, p[q].y, a.x, a.y, b.x, b.y, 0, 0, 0, 0, i};
            rpiv_synth_image_model(s, &a, &t.pa, NULL, &t.sa);
            rpiv_synth_image_model(s, &b, &t.pb, NULL, &t.sb);
            if (!(t.pa > 0 && t.pb > 0))
                continue;
            if (ntp == cap) {
                cap = cap ? 2 * cap : 1 << 16;
                all = realloc(all, cap * sizeof *all);
            }
            all[ntp++] = t;
        }
        rpiv_synth_particles_free(p);
    }
    rpiv_sheet *sheet = NULL;
    rpiv_ccm_params prm = rpiv_ccm_params_default();
    rpiv_ccm_work *wk = NULL;
    if (rpiv_sheet_new(&ex.sheet, &sheet) || rpiv_ccm_work_new(&prm, &wk))
        return 1;
    rpiv_ccm_model mo0 = rpiv_config_ccm_model(&ex, ex.synth.dt_s);
    double c = deform ? RPIV_DEFORM_SHIFT : 0;
    double sum[3][3] = {{0}}, ln[4][7] = {{0}}, ratio[9] = {0}, cnt = 0, chk = 0;
    FILE *raw = getenv("SC_RAW") ? fopen(getenv("SC_RAW"), "w") : NULL;
    for (size_t k = 0; k < nwin; k++) {
        if (f->flag[k] != RPIV_FLAG_VALID)
            continue;
        int i = (int)(k % (size_t)f->nx), j = (int)(k / (size_t)f->nx);
        double xf = f->x0 + i * f->dx, yf = f->y0 + j * f->dy, pu = 0, pv = 0;
        if (g_dpred)
            rpiv_deform_pred_eval(g_dpred, xf, yf, &pu, &pv);
        if (!deform) {
            pu = lround(pu);
            pv = lround(pv);
        }
        const float *pl = g_planes + k * (size_t)w * (size_t)w;
        double be[NB * NB], bp[NB * NB], bc[NB * NB], bx[NB * NB];
        memset(bx, 0, sizeof bx);
        double volx = 0, bf[NB * NB];
        memset(bf, 0, sizeof bf);
        int full = getenv("SC_FULL") != NULL, cur = -1;
        double *wa = full ? calloc((size_t)w * w, sizeof *wa) : NULL;
        double *wb = full ? calloc((size_t)w * w, sizeof *wb) : NULL;
        for (int jj = -R; jj <= R; jj++)
            for (int ii = -R; ii <= R; ii++)
                be[(jj + R) * NB + ii + R] = pl[((jj + w) % w) * w + (ii + w) % w];
        /* the particles' terms */
        rpiv_ccm_corr *cp = NULL;
        if (rpiv_ccm_corr_new(0, &cp))
            return 1;
        double volp = 0;
        for (size_t t = 0; t < ntp; t++) {
            const tp *q = &all[t];
            if (fabs(q->mx - xf) > 24 || fabs(q->my - yf) > 24)
                continue;
            if (full && q->pair != cur) {
                if (cur >= 0)
                    corr_add(wa, wb, w, bf);
                memset(wa, 0, (size_t)w * w * sizeof *wa);
                memset(wb, 0, (size_t)w * w * sizeof *wb);
                cur = q->pair;
            }
            double lu = pu, lv = pv; /* the deformation at the particle's mid position */
            if (g_dpred && deform)
                rpiv_deform_pred_eval(g_dpred, q->mx, q->my, &lu, &lv);
            /* deformed frames: pixel X samples A at X + c - p/2, B at X + c + p/2; the
             * window's pixels X in [xf - c - 15.5, xf - c + 15.5] */
            double xa = q->ax - c + 0.5 * lu, xb = q->bx - c - 0.5 * lu;
            double ya = q->ay - c + 0.5 * lv, yb = q->by - c - 0.5 * lv;
            double lo = xf - c - 16, hi = xf - c + 16, loy = yf - c - 16, hiy = yf - c + 16;
            if (!deform) { /* whole-pixel offsets: A back by floor(su/2), B forward */
                int su = (int)pu, sv = (int)pv;
                xa = q->ax + floor(0.5 * su);
                xb = q->bx - su + floor(0.5 * su);
                ya = q->ay + floor(0.5 * sv);
                yb = q->by - sv + floor(0.5 * sv);
                lu = pu;
                lv = pv;
            }
            /* the exact discrete correlation of its two images in the windows (the ideal
             * deformation: the pixel-integrated image sampled at the deformed positions),
             * circular as the engine's, with its own part of the mean removal */
            if (fabs(xa - xf) < 24 && fabs(ya - yf) < 24)
                volx += exact_term(q, xa - (xf - c - 15.5), xb - (xf - c - 15.5),
                                   ya - (yf - c - 15.5), yb - (yf - c - 15.5), w, bx, wa, wb);
            if (!(xa >= lo && xa < hi && xb >= lo && xb < hi && ya >= loy && ya < hiy &&
                  yb >= loy && yb < hiy))
                continue;
            double vs = q->sa * q->sa + q->sb * q->sb;
            rpiv_ccm_gauss g = {q->pa * q->pb * 2 * M_PI * q->sa * q->sa * q->sb * q->sb / vs,
                                1 / (2 * vs), q->bx - q->ax - lu + pu, q->by - q->ay - lv + pv,
                                mo0.pixel_box};
            volp += g.amp * M_PI / g.c;
            if (rpiv_ccm_corr_add(cp, g))
                return 1;
        }
        if (full && cur >= 0)
            corr_add(wa, wb, w, bf);
        free(wa);
        free(wb);
        /* the CCM's terms at the window's centre, the pair loss */
        double xs = in.x0_star + (xf + 0.5) * in.star_per_px;
        double ys = in.y0_star + (yf + 0.5) * in.star_per_px;
        rpiv_ccm_model mo = mo0;
        mo.u = (rpiv_ccm_func){rpiv_ccm_duct_fn, &ys};
        rpiv_ccm_sheet_at at = {sheet, xs};
        mo.illum = (rpiv_ccm_func){rpiv_ccm_sheet_fn, &at};
        rpiv_ccm_corr *cc = NULL;
        if (rpiv_ccm_corr_new(0, &cc) || rpiv_ccm_stat_corr(&mo, wk, cc))
            return 1;
        double volc = 0;
        rpiv_ccm_corr *c0 = NULL;
        if (rpiv_ccm_corr_new(cc->n, &c0))
            return 1;
        for (size_t t = 0; t < cc->n; t++)
            if (rpiv_ccm_corr_add(c0, cc->g[t]))
                return 1;
        for (size_t t = 0; t < cc->n; t++) {
            rpiv_ccm_gauss *g = &cc->g[t];
            g->amp *= fmax(0, 1 - fabs(g->dx - pu) / w) * fmax(0, 1 - fabs(g->dy - pv) / w);
            volc += g->amp * M_PI / g->c;
        }
        for (int jj = -R; jj <= R; jj++)
            for (int ii = -R; ii <= R; ii++) {
                bp[(jj + R) * NB + ii + R] =
                    rpiv_ccm_corr_eval(cp, pu + ii, pv + jj) - volp / ((double)w * w);
                bc[(jj + R) * NB + ii + R] =
                    rpiv_ccm_corr_eval(cc, pu + ii, pv + jj) - volc / ((double)w * w);
            }
        for (int t = 0; t < NB * NB; t++)
            bx[t] -= volx / ((double)w * w);
        double ex_ = spline_x(bx, -volx / ((double)w * w), w);
        /* the CCM's plane through the engine's interpolation: S at the integer (undeformed)
         * lattice, convolved with kappa of the deformed samples' offsets; pair loss per term
         * (bk) or per shift of the deformed lattice (bt) */
        double bk[NB * NB] = {0}, bt[NB * NB] = {0};
        if (deform) {
            enum { M = 14, NM = 2 * M + 1 };
            int mx0 = (int)floor(pu), my0 = (int)floor(pv);
            static double S[NM][NM], kx[NB][NM], ky[NB][NM];
            for (int b = 0; b < NM; b++)
                for (int a = 0; a < NM; a++)
                    S[b][a] = rpiv_ccm_corr_eval(cc, mx0 - M + a, my0 - M + b);
            /* kappa(n - m) for n = -R..R, m = mx0 - M + a */
            for (int n = -R; n <= R; n++) {
                double tx[NM], ty[NM];
                kappa(c - 0.5 * pu, c + 0.5 * pu, n - (mx0 + M), NM, tx);
                kappa(c - 0.5 * pv, c + 0.5 * pv, n - (my0 + M), NM, ty);
                for (int a = 0; a < NM; a++) { /* out[j'] = kappa(n - m_a) at j' = NM - 1 - a */
                    kx[n + R][a] = tx[NM - 1 - a];
                    ky[n + R][a] = ty[NM - 1 - a];
                }
            }
            for (int m = -R; m <= R; m++)
                for (int n = -R; n <= R; n++) {
                    double acc = 0;
                    for (int b = 0; b < NM; b++)
                        for (int a = 0; a < NM; a++)
                            acc += kx[n + R][a] * ky[m + R][b] * S[b][a];
                    bk[(m + R) * NB + n + R] = acc - volc / ((double)w * w);
                }
            /* per shift: the unweighted terms, the deformed lattice's shift weighted */
            for (int b = 0; b < NM; b++)
                for (int a = 0; a < NM; a++)
                    S[b][a] = rpiv_ccm_corr_eval(c0, mx0 - M + a, my0 - M + b);
            for (int m = -R; m <= R; m++)
                for (int n = -R; n <= R; n++) {
                    double acc = 0;
                    for (int b = 0; b < NM; b++)
                        for (int a = 0; a < NM; a++)
                            acc += kx[n + R][a] * ky[m + R][b] * S[b][a];
                    bt[(m + R) * NB + n + R] =
                        acc * (1 - fabs((double)n) / w) * (1 - fabs((double)m) / w) -
                        volc / ((double)w * w);
                }
        }
        rpiv_ccm_corr_free(c0);
        double ek = deform ? spline_x(bk, -volc / ((double)w * w), w) : 0;
        double et = deform ? spline_x(bt, -volc / ((double)w * w), w) : 0;
        if (deform) {
            g_k[2] += spline_x(be, 0, w) - et;
            for (int ii = -3; ii <= 3; ii++)
                g_tl[ii + 3] += bt[R * NB + ii + R] / bt[R * NB + R];
        }
        double ee = spline_x(be, 0, w), ep = spline_x(bp, -volp / ((double)w * w), w),
               ec = spline_x(bc, -volc / ((double)w * w), w);
        /* the engine's result is its estimate on its plane plus pu (check) */
        chk = fmax(chk, fabs(ee + pu - (double)f->u[k]));
        g_k[0] += ee - ek;
        g_k[1] += ek - ec;
        for (int ii = -3; ii <= 3; ii++)
            g_kl[ii + 3] += bk[R * NB + ii + R] / bk[R * NB + R];
        sum[1][0] += ee - ex_;
        sum[1][1] += ex_ - ep;
        sum[0][0] += ee - ep;
        sum[0][1] += ep - ec;
        sum[0][2] += ee - ec;
        const double *b3[4] = {be, bp, bc, bx};
        for (int t = 0; t < 4; t++) {
            for (int ii = -3; ii <= 3; ii++)
                ln[t][ii + 3] += b3[t][R * NB + ii + R] / b3[t][R * NB + R];
        }
        ratio[0] += be[R * NB + R] / bp[R * NB + R];
        ratio[1] += be[R * NB + R - 1] / bp[R * NB + R - 1];
        ratio[2] += be[R * NB + R + 1] / bp[R * NB + R + 1];
        if (full) {
            double ef = spline_x(bf, 0, w);
            sum[2][0] += ee - ef;
            sum[2][1] += ef - ex_;
            ratio[6] += be[R * NB + R - 1] / bf[R * NB + R - 1];
            ratio[7] += be[R * NB + R] / bf[R * NB + R];
            ratio[8] += be[R * NB + R + 1] / bf[R * NB + R + 1];
        }
        ratio[3] += be[R * NB + R - 1] / bx[R * NB + R - 1];
        ratio[4] += be[R * NB + R] / bx[R * NB + R];
        ratio[5] += be[R * NB + R + 1] / bx[R * NB + R + 1];
        if (raw) {
            fprintf(raw, "%zu %d %d %.6f %.6f %.6f %.6f", k, i, j, pu, pv, (double)f->u[k], 0.0);
            for (int t = 0; t < 3; t++)
                for (int jj = -3; jj <= 3; jj++)
                    for (int ii = -3; ii <= 3; ii++)
                        fprintf(raw, " %.8g", b3[t][(jj + R) * NB + ii + R]);
            fprintf(raw, "\n");
        }
        if (getenv("SC_VERBOSE"))
            printf("  (%2d,%2d) pu %.4f: engine %+.4f particles %+.4f CCM %+.4f, %zu terms\n", i, j,
                   pu, ee, ep, ec, cp->n);
        cnt++;
        rpiv_ccm_corr_free(cp);
        rpiv_ccm_corr_free(cc);
    }
    if (raw)
        fclose(raw);
    printf("%d pairs%s%s, %g windows (engine's result = its plane's estimate + pu to %.1e px)\n",
           npairs, getenv("SC_NONOISE") ? ", no noise" : "", deform ? "" : ", whole-pixel offsets",
           cnt, chk);
    printf("  spline: engine - particles %+.4f, particles - CCM %+.4f, engine - CCM %+.4f px\n",
           sum[0][0] / cnt, sum[0][1] / cnt, sum[0][2] / cnt);
    if (deform) {
        printf(
            "  the CCM through the engine's interpolation: engine - CCM+interp %+.4f, CCM+interp "
            "- CCM %+.4f px; along x",
            g_k[0] / cnt, g_k[1] / cnt);
        for (int ii = 0; ii < 7; ii++)
            printf(" %.4f", g_kl[ii] / cnt);
        printf("\n  and the pair loss per shift: engine - CCM+interp+tent %+.4f px; along x",
               g_k[2] / cnt);
        for (int ii = 0; ii < 7; ii++)
            printf(" %.4f", g_tl[ii] / cnt);
        printf("\n");
    }
    printf("          engine - exact %+.4f, exact - particles %+.4f px\n", sum[1][0] / cnt,
           sum[1][1] / cnt);
    const char *nm[4] = {"engine   ", "particles", "CCM      ", "exact    "};
    for (int t = 0; t < 4; t++) {
        printf("  along x, relative to shift 0, %s", nm[t]);
        for (int ii = 0; ii < 7; ii++)
            printf(" %.4f", ln[t][ii] / cnt);
        printf("\n");
    }
    printf("  engine / particles (absolute): shift -1 %.4f, 0 %.4f, +1 %.4f\n", ratio[1] / cnt,
           ratio[0] / cnt, ratio[2] / cnt);
    if (getenv("SC_FULL"))
        printf("  full (the windows drawn from the particles' pixel integrals, all pairs of "
               "particles, no noise): engine - full %+.4f, full - exact %+.4f px; engine / full "
               "at -1, 0, +1: %.4f %.4f %.4f\n",
               sum[2][0] / cnt, sum[2][1] / cnt, ratio[6] / cnt, ratio[7] / cnt, ratio[8] / cnt);
    printf("  engine / exact (absolute): shift -1 %.4f, 0 %.4f, +1 %.4f\n", ratio[3] / cnt,
           ratio[4] / cnt, ratio[5] / cnt);
    free(all);
    free(img);
    free(g_planes);
    rpiv_deform_pred_free(g_dpred);
    rpiv_field_free(f);
    rpiv_ccm_work_free(wk);
    rpiv_sheet_free(sheet);
    rpiv_synth_free(s);
    return 0;
}
