/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The engine's window in the prediction of what the engine measures (docs/ccm.md, "The
 * engine's window"): the expected plane of a W x H top-hat window of mean-removed images,
 * correlated circularly by FFT, differs from the model's infinite-window R in three derived
 * ways, all modelled here on the sampled plane the estimator reads:
 *  - pairs lost at the window's edges: a particle at a uniformly random place in window a
 *    whose image moves by the residual shift s (its displacement less the predictor, which the
 *    deformation removes) stays in window b with probability (1 - |s_x|/W)(1 - |s_y|/H), so
 *    its term is weighted by that;
 *  - the mean removal: the circular plane of mean-removed windows sums to zero over its W H
 *    shifts, and the uncorrelated pairs add a constant in expectation, so the expected plane
 *    is the weighted terms minus their lattice sum over W H;
 *  - the deformation: the final pass correlates frames deformed by the predictor, so the plane
 *    is R sampled at integer shifts about the predictor (not about 0), and the estimate is the
 *    predictor plus the estimator's offset on that plane; the engine's passes converge to the
 *    predictor that the estimate reproduces (a fixed point, found by repeating the pass);
 *    where the estimator's path changes between two predictors (the spline's fall to the
 *    3-point Gaussian) there may be none, and the passes alternate between two estimates: the
 *    estimate is then the last of WINDOW_ITER passes', found once the alternation repeats.
 *    With the interpolation (deform 2, docs/ccm.md "Session 10") the estimator's path is
 *    weighted by its probability under the ensemble's noise (noisy_subpixel), which makes the
 *    passes' map continuous; after PLAIN passes without a fixed point the predictor moves by a
 *    decreasing share of each pass's change (Mann's iteration), which converges to the fixed
 *    point of a continuous map (noise-free: to the predictor where the map jumps across it).
 * The baseline's lattice sum: a term's lattice sum is its
 *    volume amp pi / c (the box keeps the volume) to the aliasing of a sampled Gaussian,
 *    exp(-pi^2 / c) relative (Poisson's summation): below 1e-3 for a term narrower than
 *    c = 1.4 px^-2, and the baseline is itself below 1 % of the peak at 32 px windows. */
#include "ccm_impl.h"

#include "rpiv/deform.h"

#include <gsl/gsl_sf_erf.h>
#include <math.h>
#include <stdlib.h>

#define WINDOW_ITER  20
#define WINDOW_ITER2 40
#define PLAIN        8

/* ---- the deformed pass: the interpolation's kernel and the window's overlap ------------- */

/* The cubic B-spline and the cardinal spline eta through unit samples that the engine
 * interpolates its frames with (prefiltered coefficients, rpiv/deform.h): eta(x) = sqrt 3
 * sum_k z^|k| beta3(x - k), z = sqrt 3 - 2 (eta(0) = 1, eta(k) = 0 at the other integers). */
static double beta3(double x)
{
    x = fabs(x);
    return x < 1 ? 2.0 / 3 - x * x + 0.5 * x * x * x : x < 2 ? (2 - x) * (2 - x) * (2 - x) / 6 : 0;
}

static double eta(double x)
{
    const double z = sqrt(3.0) - 2;
    const int k0 = (int)floor(x);
    double s = 0;
    for (int k = k0 - 1; k <= k0 + 2; k++)
        s += pow(z, abs(k)) * beta3(x - k);
    return sqrt(3.0) * s;
}

/* Half-widths: the deformed plane's shifts -NR..NR; eta below 1e-9 beyond KR px. */
enum { NR = 6, KR = 16, NP = 2 * NR + 1, NM = 2 * (NR + KR) + 2 };

/* k[n + NR][a] = kappa(n - (m0 + a)), n = -NR..NR, a = 0..NM-1, where kappa(j) = sum_u
 * eta(u + ta) eta(u + j + tb): frames interpolated at X + ta (a) and X + tb (b) have, over
 * particles at uniformly random sub-pixel places, the expected plane P(n) = sum_m kappa(n - m)
 * S(m), S the frames' plane at the integer shifts m (Sum_X a'(X) b'(X + n) with a'(X) = sum_u
 * a(u) eta(X + ta - u), and E a(u) b(v) = S(v - u)). An ideal interpolator would give the
 * band-limited S at n + tb - ta; the cubic spline's kernel also widens it a little. */
static void kappa_table(double ta, double tb, int m0, double k[NP][NM])
{
    const int u0 = -KR - 1 - (int)floor(ta), nu = 2 * KR + 3;
    const int jlo = -NR - (m0 + NM - 1), jhi = NR - m0, nj = jhi - jlo + 1;
    double ea[2 * KR + 3], eb[2 * KR + 3 + NM + NP], kap[NM + NP];
    for (int u = 0; u < nu; u++)
        ea[u] = eta(u0 + u + ta);
    for (int v = 0; v < nu + nj - 1; v++)
        eb[v] = eta(u0 + jlo + v + tb);
    for (int j = 0; j < nj; j++) {
        double acc = 0;
        for (int u = 0; u < nu; u++)
            acc += ea[u] * eb[u + j];
        kap[j] = acc;
    }
    for (int n = -NR; n <= NR; n++)
        for (int a = 0; a < NM; a++)
            k[n + NR][a] = kap[n - (m0 + a) - jlo];
}

/* The lattice S of the whole list at its last origin (m0x, m0y): the passes' predictors
 * usually keep their whole pixel, and then only the kernels change. */
typedef struct lat_cache {
    int valid, m0x, m0y;
    double S[NM * NM];
} lat_cache;

/* The expected plane of the engine's final, deformed pass about the predictor (px, py), at
 * its shifts n, m = -NR..NR (P[m + NR][n + NR]), before the mean removal's baseline: the
 * infinite window's R at the integer lattice, through the interpolation's kernel of the frames'
 * sampling offsets c -+ p/2 (c = RPIV_DEFORM_SHIFT, each axis), times the share of the window's
 * pixel pairs that overlap at that shift, (1 - |n|/W)(1 - |m|/H) (the window's overlap at the
 * plane's shift, not at each term's own displacement: docs/ccm.md, "The planes' skew"). With
 * sub-positions (sub, nsub; NULL: the whole list, not deformed), each one's terms c->g[t0..t1)
 * (moved by minus its deformation s) are put back and sampled about its own predictor p + s:
 * the window's plane is the sum of its parts' planes, each deformed by its own predictor.
 * lc (NULL: none): the whole list's lattice kept between calls. */
static rpiv_status deformed_plane(const rpiv_ccm_corr *c, const ccm_sub *sub, size_t nsub,
                                  int win_w, int win_h, double px, double py, lat_cache *lc,
                                  double P[NP][NP])
{
    const double sh = RPIV_DEFORM_SHIFT;
    const ccm_sub whole = {0, c->n, 0, 0};
    double *S = malloc((size_t)NM * NM * sizeof *S), *kx = malloc(sizeof(double[NP][NM])),
           *ky = malloc(sizeof(double[NP][NM])), *T = malloc(sizeof(double[NM][NP]));
    rpiv_ccm_corr *one = NULL;
    rpiv_status st = RPIV_OK;
    if (!S || !kx || !ky || !T) {
        st = rpiv_fail(RPIV_ENOMEM, "ccm: out of memory for the deformed window's plane");
        goto out_free;
    }
    if (!sub) {
        sub = &whole;
        nsub = 1;
    } else if ((st = rpiv_ccm_corr_new(0, &one))) {
        goto out_free;
    }
    double fx[NM], fy[NM];
    double(*kxa)[NM] = (double(*)[NM])kx, (*kya)[NM] = (double(*)[NM])ky;
    double(*Ta)[NP] = (double(*)[NP])T;
    for (int m = 0; m < NP; m++)
        for (int n = 0; n < NP; n++)
            P[m][n] = 0;
    for (size_t o = 0; o < nsub; o++) {
        /* sub-position o: its terms where they are (moved back by its deformation s), the
         * frames sampled about its own predictor p + s */
        const rpiv_ccm_corr *co = c;
        if (one) {
            one->n = 0;
            for (size_t t = sub[o].t0; t < sub[o].t1 && !st; t++) {
                rpiv_ccm_gauss g = c->g[t];
                g.dx += sub[o].sx;
                g.dy += sub[o].sy;
                st = rpiv_ccm_corr_add(one, g);
            }
            if (st)
                goto out_free;
            co = one;
        }
        const double qx = px + sub[o].sx, qy = py + sub[o].sy;
        const int m0x = (int)floor(qx) - NR - KR, m0y = (int)floor(qy) - NR - KR;
        const double *So = S;
        if (lc && !one) { /* the whole list: its lattice kept between passes */
            if (!(lc->valid && lc->m0x == m0x && lc->m0y == m0y))
                ccm_lattice(co, m0x, NM, m0y, NM, lc->S, fx, fy);
            lc->valid = 1;
            lc->m0x = m0x;
            lc->m0y = m0y;
            So = lc->S;
        } else {
            ccm_lattice(co, m0x, NM, m0y, NM, S, fx, fy);
        }
        kappa_table(sh - 0.5 * qx, sh + 0.5 * qx, m0x, kxa);
        kappa_table(sh - 0.5 * qy, sh + 0.5 * qy, m0y, kya);
        for (int b = 0; b < NM; b++) /* along x, every row of the lattice */
            for (int n = 0; n < NP; n++) {
                double acc = 0;
                for (int a = 0; a < NM; a++)
                    acc += kxa[n][a] * So[(size_t)b * NM + (size_t)a];
                Ta[b][n] = acc;
            }
        for (int m = 0; m < NP; m++) /* then along y */
            for (int n = 0; n < NP; n++) {
                double acc = 0;
                for (int b = 0; b < NM; b++)
                    acc += kya[m][b] * Ta[b][n];
                P[m][n] += acc;
            }
    }
    for (int m = 0; m < NP; m++) /* the window's overlap at the plane's shift */
        for (int n = 0; n < NP; n++)
            P[m][n] *= (1 - fabs((double)(n - NR)) / win_w) * (1 - fabs((double)(m - NR)) / win_h);
out_free:
    rpiv_ccm_corr_free(one);
    free(S);
    free(kx);
    free(ky);
    free(T);
    return st;
}

/* E[v + e | v + e > 0] for e ~ N(0, s^2): a sample's mean over the planes on which the
 * estimator reads it as positive (phi(z) / Phi(z) = the hazard of -z). */
static double cond_pos(double v, double s)
{
    const double z = v / s;
    if (z > -5)
        return v + s * exp(-0.5 * z * z) / sqrt(2 * M_PI) / (0.5 * erfc(-z / M_SQRT2));
    return v + s * gsl_sf_hazard(-z); /* (its asymptotic form, without cancellation) */
}

/* The engine's estimator on the modelled plane rows (+ base) when each sample the estimator
 * reads carries the ensemble's noise, relative sigma: its path is the 7 x 7 spline when all
 * 48 samples are positive, the 5 x 5 when only the inner 24 are, else the 3-point Gaussian
 * (peak_fit.c); with independent Gaussian noise each path's probability is a product of
 * Phi(v / sigma), and on each path the samples it reads are their means given positive. The
 * estimate is the paths' expected estimate. sigma = 0: the expected plane's own path. */
static void noisy_subpixel(double rows[7][7], const rpiv_ccm_params *p, double base, double sigma,
                           int mx, int my, double *ex, double *ey, ccm_wsig *sig)
{
    if (!(sigma > 0) || ccm_subpixel_rad(p) != 3) {
        ccm_subpixel(rows, p, base, mx, my, ex, ey, sig ? &sig->sig : NULL);
        return;
    }
    const double r0 = rows[3][3] + base;
    double v[7][7], p5 = 1, pring = 1;
    for (int j = 0; j < 7; j++)
        for (int i = 0; i < 7; i++) {
            v[j][i] = (rows[j][i] + base) / r0;
            if (i == 3 && j == 3)
                continue;
            double q = 0.5 * erfc(-v[j][i] / sigma / M_SQRT2);
            if (abs(i - 3) <= 2 && abs(j - 3) <= 2)
                p5 *= q;
            else
                pring *= q;
        }
    const double w[3] = {p5 * pring, p5 * (1 - pring), 1 - p5};
    double sx = 0, sy = 0;
    for (int b = 0; b < 3; b++) {
        if (!(w[b] > 1e-9))
            continue;
        double r[7][7] = {{0}}, bx, by;
        rpiv_ccm_params q = *p;
        if (b < 2) { /* the spline on the block's samples given positive (the ring: 0 on 5 x 5) */
            int lim = b == 0 ? 3 : 2;
            for (int j = 0; j < 7; j++)
                for (int i = 0; i < 7; i++)
                    r[j][i] = abs(i - 3) <= lim && abs(j - 3) <= lim
                                  ? (i == 3 && j == 3 ? 1 : cond_pos(v[j][i], sigma))
                                  : 0;
        } else { /* the 3-point Gaussian on the row and column through the centre */
            q.subpixel = RPIV_SUBPIXEL_GAUSS;
            for (int j = 0; j < 3; j++)
                for (int i = 0; i < 3; i++)
                    r[j][i] = v[j + 2][i + 2];
        }
        ccm_subpixel(r, &q, 0, mx, my, &bx, &by, NULL);
        sx += w[b] * bx;
        sy += w[b] * by;
    }
    *ex = sx;
    *ey = sy;
    if (sig) { /* the paths blend continuously: one signature (ccm_bias.c checks the bends) */
        sig->sig = (uint64_t)1 << 63;
        sig->w7 = w[0];
        sig->w3 = w[2];
    }
}

/* The estimate on the plane of the window about the predictor (px, py), lowered by the mean
 * removal's baseline -V / (W H), V the volume of the pairs kept (every term weighted by the
 * share of its pairs that stay in the window at its residual shift). deform 0: the weighted
 * terms at the integer shifts; 1: moved by -(px, py), at integer residual shifts; 2 (opt-in,
 * [bias] window_interp): the plane of the deformed pass through the interpolation's kernel,
 * the pairs lost per shift (deformed_plane). *ex, *ey: the estimate (px, py added with
 * deform). */
static rpiv_status window_estimate(const rpiv_ccm_corr *c, const ccm_sub *sub, size_t nsub,
                                   const rpiv_ccm_params *p, int win_w, int win_h, int deform,
                                   double npairs, double px, double py, rpiv_ccm_corr *cw,
                                   lat_cache *lc, double *ex, double *ey, ccm_wsig *sig)
{
    double vol = 0;
    rpiv_status st;
    cw->n = 0;
    for (size_t k = 0; k < c->n; k++) {
        rpiv_ccm_gauss g = c->g[k];
        if (!(g.amp > 0))
            continue;
        g.amp *= fmax(0, 1 - fabs(g.dx - px) / win_w) * fmax(0, 1 - fabs(g.dy - py) / win_h);
        if (!(g.amp > 0))
            continue;
        vol += g.amp * M_PI / g.c;
        if (deform == 1) { /* the deformed frames are correlated at integer residual shifts */
            g.dx -= px;
            g.dy -= py;
        }
        if (deform != 2 && (st = rpiv_ccm_corr_add(cw, g)))
            return st;
    }
    if (!(vol > 0))
        return rpiv_fail(RPIV_ENUMERIC, "ccm: no pair stays inside the %d x %d px window", win_w,
                         win_h);
    double rows[7][7] = {{0}};
    int mx = 0, my = 0;
    if (deform == 2) {
        double P[NP][NP];
        if ((st = deformed_plane(c, sub, nsub, win_w, win_h, px, py, lc, P)))
            return st;
        /* the highest sample within NR - rad of the predictor (first of equal values, y outer)
         * and the samples the estimator reads around it */
        const int rad = ccm_subpixel_rad(p), lim = NR - rad;
        double best = -HUGE_VAL;
        for (int m = -lim; m <= lim; m++)
            for (int n = -lim; n <= lim; n++)
                if (P[m + NR][n + NR] > best) {
                    best = P[m + NR][n + NR];
                    mx = n;
                    my = m;
                }
        for (int j = -rad; j <= rad; j++)
            for (int i = -rad; i <= rad; i++)
                rows[j + rad][i + rad] = P[my + j + NR][mx + i + NR];
    } else if ((st = ccm_sampled_rows(cw, p, rows, &mx, &my))) {
        return st;
    }
    const double base = -vol / ((double)win_w * (double)win_h);
    const int rad = ccm_subpixel_rad(p);
    double sigma = 0;
    if (deform == 2 && npairs > 0) /* the random pairs' noise of an ensemble of npairs pairs */
        sigma = sqrt(-base / (rows[rad][rad] + base) / (2 * npairs));
    noisy_subpixel(rows, p, base, sigma, mx, my, ex, ey, sig);
    if (sig) {
        sig->mx = mx;
        sig->my = my;
    }
    if (deform) {
        *ex += px;
        *ey += py;
    }
    return RPIV_OK;
}

rpiv_status rpiv_ccm_corr_peak_window(const rpiv_ccm_corr *c, const rpiv_ccm_params *p, int win_w,
                                      int win_h, int deform, rpiv_ccm_peak *out)
{
    return ccm_corr_peak_window_sig(c, NULL, 0, p, win_w, win_h, deform, 0, out, NULL);
}

rpiv_status ccm_corr_peak_window_sig(const rpiv_ccm_corr *c, const ccm_sub *sub, size_t nsub,
                                     const rpiv_ccm_params *p, int win_w, int win_h, int deform,
                                     double npairs, rpiv_ccm_peak *out, ccm_wsig *sig)
{
    if (!(win_w == 0 && win_h == 0) && (win_w < 4 || win_h < 4 || win_w > 4096 || win_h > 4096))
        return rpiv_fail(RPIV_EINVAL, "ccm: window %d x %d px outside 4..4096 px", win_w, win_h);
    rpiv_status st = rpiv_ccm_corr_peak(c, p, out);
    if (st)
        return st;
    if (sig)
        *sig = (ccm_wsig){1, 0, 0, 0, 0, 0};
    if (win_w == 0 && win_h == 0)
        return RPIV_OK;
    /* the predictor: from the infinite window's estimate, the engine's passes repeated until
     * the estimate is its own predictor (to 1e-5 px, at most WINDOW_ITER passes) */
    double px = isfinite(out->dx_sub) ? out->dx_sub : out->dx;
    double py = isfinite(out->dy_sub) ? out->dy_sub : out->dy, ex = px, ey = py;
    rpiv_ccm_corr *cw = NULL;
    if ((st = rpiv_ccm_corr_new(c->n, &cw)))
        return st;
    lat_cache cache; /* the whole list's lattice, kept between the passes (deform 2) */
    cache.valid = 0;
    lat_cache *lc = deform == 2 && !sub ? &cache : NULL;
    int done = 0;
    double qx = (double)NAN, qy = (double)NAN; /* the predictor of the previous pass */
    const int niter = deform == 2 ? WINDOW_ITER2 : WINDOW_ITER;
    for (int it = 0; it < niter && !done; it++) {
        if ((st = window_estimate(c, sub, nsub, p, win_w, win_h, deform, npairs, px, py, cw, lc,
                                  &ex, &ey, sig)))
            break;
        done = fabs(ex - px) < 1e-5 && fabs(ey - py) < 1e-5;
        if (deform == 2 && !done) {
            /* no fixed point within PLAIN passes: the predictor moves by a decreasing share
             * of the passes' change (Mann's iteration), to the fixed point of a continuous
             * map, or to where a discontinuous one jumps across it */
            const double a = it < PLAIN ? 1 : 1.0 / (it - PLAIN + 2);
            px += a * (ex - px);
            py += a * (ey - py);
            continue;
        }
        if (!done && fabs(ex - qx) < 1e-5 && fabs(ey - qy) < 1e-5) {
            /* the passes alternate between two estimates (no fixed point: the estimator's
             * path changes between them): the last pass's is the one of this parity */
            if ((WINDOW_ITER - 1 - it) % 2) {
                ex = px;
                ey = py;
            }
            break;
        }
        qx = px;
        qy = py;
        px = ex;
        py = ey;
    }
    if (!st && deform == 2 && !done) { /* the averaged passes' predictor */
        ex = px;
        ey = py;
    }
    if (!st) {
        out->dx_sub = ex;
        out->dy_sub = ey;
        if (sig)
            sig->conv = done;
    }
    rpiv_ccm_corr_free(cw);
    return st;
}
