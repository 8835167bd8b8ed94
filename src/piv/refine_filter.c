/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/refine_filter.c - the denoiser of the refinement's predictor (docs/piv.md,
 * "Refinement at the final size"): at dilations 1, 2 and 4 grid steps in turn (an a-trous
 * split), the field split, line by line along x and then along y, into a smoothing and its
 * detail (the fourth difference at dilations 1 and 2, the second at 4; refine_denoise_order 2:
 * the second at dilation 1 too, session 6's), the detail shrunk
 * (non-negative garrote) with a threshold set from the field's own noise level, sigma
 * sqrt(2 ln n) (Donoho and Johnstone's universal threshold), sigma the median absolute detail
 * / 0.6745 along the grid direction where it is smallest, at the coarser dilations at most
 * what the noise of a window average gives there, scaled from a noise level that a smooth
 * flow's own detail cannot raise (that of the fourth differences at dilation 1). Also the
 * repeat's fixed low-pass filter of the predictor and its transpose (for the uncertainty's
 * chain). */
#include "piv_impl.h"

#include "rpiv/deform.h"

#include <gsl/gsl_statistics_double.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Detail of sample i of a line of n >= 3 samples (stride s): U_i minus its smoothing.
 * Inside, (2 U_i - U_{i-1} - U_{i+1}) / 4; at an end, U_0 minus the least-squares line
 * through the first three samples, (U_0 - 2 U_1 + U_2) / 6, whose noise is 2/3 of the inner
 * one's (white noise). Both vanish on linear fields. */
static double detail(const float *g, int n, size_t s, int i)
{
    if (i == 0)
        return ((double)g[0] - 2.0 * (double)g[s] + (double)g[2 * s]) / 6.0;
    if (i == n - 1) {
        const float *e = g + (size_t)(n - 1) * s;
        return ((double)e[0] - 2.0 * (double)e[-(ptrdiff_t)s] + (double)e[-2 * (ptrdiff_t)s]) / 6.0;
    }
    const float *c = g + (size_t)i * s;
    return (2.0 * (double)c[0] - (double)c[-(ptrdiff_t)s] - (double)c[s]) / 4.0;
}

/* Sample i of a line of n samples (stride s), the line continued past its ends by odd
 * reflection about the end samples (U_-i = 2 U_0 - U_i): linear fields continue linearly. */
static double reflected(const float *g, int n, size_t s, int i)
{
    if (i < 0)
        return 2.0 * (double)g[0] - (double)g[(size_t)(-i) * s];
    if (i >= n)
        return 2.0 * (double)g[(size_t)(n - 1) * s] - (double)g[(size_t)(2 * (n - 1) - i) * s];
    return (double)g[(size_t)i * s];
}

/* Fourth-order detail of sample i of a line of n >= 5 samples (stride s): U_i minus its
 * smoothing [-1/16, 1/4, 5/8, 1/4, -1/16], (6 U_i - 4 (U_i-1 + U_i+1) + U_i-2 + U_i+2) / 16,
 * response ((1 - cos w) / 2)^2: 1 at 2 samples a wavelength as the second difference's, but
 * w^4 / 16 instead of w^2 / 4 for long waves, and nil on cubics. With the odd reflection it
 * is 0 at the end samples (left as they are) and (5 U_1 - 2 U_0 - 4 U_2 + U_3) / 16 at the
 * second ones, whose white-noise share is sqrt(46 / 70) of the inner one's. */
static double detail4(const float *g, int n, size_t s, int i)
{
    return (6.0 * reflected(g, n, s, i) -
            4.0 * (reflected(g, n, s, i - 1) + reflected(g, n, s, i + 1)) +
            reflected(g, n, s, i - 2) + reflected(g, n, s, i + 2)) /
           16.0;
}

/* The median of v[0..n-1] (rearranged): GSL's quickselect, linear in n (the sort it replaces
 * took 7 % of a default 2560 x 2160 run); the same value as the sort's. */
static double median_of(double *v, size_t n)
{
    if (!n)
        return 0;
    const double hi = gsl_stats_select(v, 1, n, n / 2);
    return n % 2 ? hi : 0.5 * (gsl_stats_select(v, 1, n, n / 2 - 1) + hi);
}

/* The details a level can use: the second difference (its line's ends against the
 * least-squares line through their first three samples), the fourth (the line continued by
 * odd reflection), and the fourth inside a line with the second difference's at its two end
 * samples on either side (DET42: the ends of a smooth flow's line are not continued by a
 * reflection that bends it; docs/piv.md). */
enum { DET2 = 2, DET4 = 4, DET42 = 42 };

/* Noise level of one component at dilation `step` (grid steps between the samples of a
 * detail) for the detail of the given kind (DET2 or DET4; DET42's inner one is DET4): the smallest
 * over the four grid directions (x, y and the diagonals) of the median absolute inner detail /
 * 0.6745. A shear or wave along one direction has no detail across it, so at least one direction
 * sees the noise alone. The details of a dilation are taken every `step` nodes along x and y:
 * closer ones share their samples' noise (and cost the time of 1 + 1/4 + 1/16 of one level instead
 * of three). */
static double noise_sigma(const float *g, int nx, int ny, int step, int order, double *buf)
{
    const ptrdiff_t sx = step, sy = (ptrdiff_t)step * nx;
    const ptrdiff_t dirs[4] = {sx, sy, sy + sx, sy - sx};
    double best = (double)INFINITY;
    for (int d = 0; d < 4; d++) {
        const int r = order != DET2 ? 2 * step : step;      /* the stencil's reach */
        const int ix = d != 1 ? r : 0, iy = d != 0 ? r : 0; /* inner along x, along y */
        const ptrdiff_t e = dirs[d];
        size_t m = 0;
        for (int j = iy; j < ny - iy; j += step)
            for (int i = ix; i < nx - ix; i += step) {
                const float *c = g + (size_t)j * (size_t)nx + (size_t)i;
                const double c0 = (double)c[0], c1 = (double)c[-e] + (double)c[e];
                buf[m++] =
                    order != DET2
                        ? fabs(6.0 * c0 - 4.0 * c1 + (double)c[-2 * e] + (double)c[2 * e]) / 16.0
                        : fabs(2.0 * c0 - c1) / 4.0;
            }
        if (m >= 8) {
            double s = median_of(buf, m) / 0.6745;
            best = s < best ? s : best;
        }
    }
    return best;
}

/* Is sample i of a line of n a DET42 line's end sample (the second difference's detail)? */
static int det42_end(int n, int i)
{
    return i < 2 || i > n - 3;
}

/* Shrink the details of the given kind of the lines of g (count lines, n samples each, sample
 * stride s, line stride ls) with threshold t (DET2: t * 2/3 at the ends, whose detail has 2/3
 * of the noise; DET4: t * sqrt(46/70) next to them; DET42: t inside, t2 and t2 * 2/3 at its
 * end samples). gain (NULL: not wanted; laid out as g): the factor the garrote applied to
 * each sample's detail (its output over its detail: 0 where the detail is dropped,
 * 1 - t^2 / d^2 where kept). */
static void shrink_lines(float *g, int count, int n, size_t s, size_t ls, int order, double t,
                         double t2, double *line, float *gain)
{
    const double te = order == DET4 ? t * sqrt(46.0 / 70.0) : t * (2.0 / 3.0);
    const int ie = order == DET4; /* the sample with the end threshold: 0 or 1 from either end */
    for (int l = 0; l < count; l++) {
        float *r = g + (size_t)l * ls;
        for (int i = 0; i < n; i++)
            line[i] = order == DET4 || (order == DET42 && !det42_end(n, i)) ? detail4(r, n, s, i)
                                                                            : detail(r, n, s, i);
        for (int i = 0; i < n; i++) {
            double d = line[i], ti = (i == ie || i == n - 1 - ie) ? te : t;
            if (order == DET42 && det42_end(n, i))
                ti = i == 0 || i == n - 1 ? t2 * (2.0 / 3.0) : t2;
            /* non-negative garrote: d - t^2 / d above the threshold, 0 below */
            double kept = fabs(d) > ti ? d - ti * ti / d : 0;
            r[(size_t)i * s] = (float)((double)r[(size_t)i * s] - d + kept);
            if (gain)
                gain[(size_t)l * ls + (size_t)i * s] =
                    (float)(fabs(d) > ti ? 1 - ti * ti / (d * d) : 0);
        }
    }
}

/* Shrink, at dilation `step`, the lines along one axis (n samples a line at stride s, count
 * lines at stride ls): each line split into its `step` interleaved sub-lines. t, t2, gain: as
 * shrink_lines's. */
static void shrink_axis(float *g, int count, int n, size_t s, size_t ls, int step, int order,
                        double t, double t2, double *line, float *gain)
{
    for (int o = 0; o < step; o++) {
        const int m = (n - o + step - 1) / step;
        if (m >= (order == DET4 ? 5 : 3))
            shrink_lines(g + (size_t)o * s, count, m, s * (size_t)step, ls, order, t, t2, line,
                         gain ? gain + (size_t)o * s : NULL);
    }
}

/* Levels of the denoiser: details at dilations 1, 2, 4 grid steps. In the linear picture of
 * the iteration (docs/piv.md) the repeat keeps (1 - H) G of the predictor's noise and adds the
 * same measurement noise again, so the fixed point's noise is e / (1 - (1 - H) G): with the
 * window's response H (top hat, 50 % overlap) and the noise's G the product of the levels'
 * smoothings, the largest (1 - H) G is 0.18 with one level (at 3.8 grid steps a wavelength),
 * 0.014 with three second differences and 0.022 with the fourth at dilation 2. That level is
 * there for the noise at 4 grid steps a wavelength, where both details are the whole field;
 * for a smooth flow's longer waves the fourth difference's detail is 1/2 (8 steps) to 1/7
 * (16 steps) of the second's, below no threshold it was above (session 6: lambda = 4 W RMS
 * 0.078 px instead of 0.082, the response at 1.5 W 0.93 instead of 0.89 over three pairs). */
enum { LEVELS = 3, NF = 32 };
_Static_assert(2 * LEVELS == PIV_DENOISE_STAGES, "a stage per level and axis");

/* The levels' details for refine_denoise_order `fine`: 2, session 6's (DET2, DET4, DET2);
 * 4, the fourth difference at dilation 1 too (DET42). With the second difference at dilation 1
 * a smooth flow's curvature is detail there (h^2 u'' / 4 a node, Lamb-Oseen's core RMS 0.022
 * px against the fourth's 0.008), which the garrote drops or shrinks by T^2 / d and the
 * refinement's repeats then keep as a common error (docs/uncertainty.md, Session 11); the
 * fourth vanishes on cubics. Its largest noise gain of the iteration, max (1 - H) G, is 0.038
 * instead of 0.022 (docs/piv.md). */
static void level_orders(int fine, int order[LEVELS])
{
    order[0] = fine == 4 ? DET42 : DET2;
    order[1] = DET4;
    order[2] = DET2;
}

/* The noise model of a level: the standard deviation of the detail of the given order at
 * dilation 2^level of a field whose noise has the power spectrum of a top-hat window average,
 * |H|^2, H = sinc(w rx / 2) sinc(w ry / 2) (rx, ry: the window over the grid step), after the
 * smoothings of the levels before it along x and y; the smallest of the four grid directions.
 * Mean over an NF x NF grid of frequencies (radians per grid step). */
static double model_detail(const int *orders, int level, int order, double rx, double ry)
{
    double px[NF], py[NF], a[NF], c[NF], sn[NF];
    const double st = (double)(1 << level);
    for (int i = 0; i < NF; i++) {
        const double w = M_PI * (2.0 * (i + 0.5) / NF - 1.0);
        const double hx = sin(0.5 * w * rx) / (0.5 * w * rx),
                     hy = sin(0.5 * w * ry) / (0.5 * w * ry);
        px[i] = hx * hx;
        py[i] = hy * hy;
        a[i] = 1; /* the smoothings of the levels before, one axis */
        for (int l = 0; l < level; l++) {
            const double q = 0.5 * (1 - cos(w * (double)(1 << l))); /* the second's detail */
            a[i] *= orders[l] != DET2 ? 1 - q * q : 1 - q;
        }
        c[i] = cos(w * st);
        sn[i] = sin(w * st);
    }
    double best = (double)INFINITY;
    for (int d = 0; d < 4; d++) {
        double sum = 0;
        for (int j = 0; j < NF; j++)
            for (int i = 0; i < NF; i++) {
                /* cos of the detail's phase: along x, y, x + y, x - y */
                const double cp = d == 0   ? c[i]
                                  : d == 1 ? c[j]
                                  : d == 2 ? c[i] * c[j] - sn[i] * sn[j]
                                           : c[i] * c[j] + sn[i] * sn[j];
                const double q = 0.5 * (1 - cp), k = a[i] * a[j] * (order != DET2 ? q * q : q);
                sum += k * k * px[i] * py[j];
            }
        const double sd = sqrt(sum / (NF * NF));
        best = sd < best ? sd : best;
    }
    return best;
}

/* The pass whose grid the predictor is on (-1 if none). */
static int pred_pass(const rpiv_piv *pv, const rpiv_field *predictor)
{
    /* piv_shift (src/piv/piv.c) spelled out: this file calls nothing there */
    for (int j = 0; j < pv->npass; j++) {
        const piv_pass *ps = &pv->pass[j];
        const double c = j > 0 && pv->deforms ? RPIV_DEFORM_SHIFT : 0.0;
        if (ps->nx == predictor->nx && ps->ny == predictor->ny && ps->sx == predictor->dx &&
            ps->sy == predictor->dy && ps->ox + 0.5 * (ps->ww - 1) + c == predictor->x0 &&
            ps->oy + 0.5 * (ps->wh - 1) + c == predictor->y0)
            return j;
    }
    return -1;
}

/* piv_pred_denoise, and with gain (NULL: not wanted) the weights of its stages
 * (piv_pred_denoise_weights). */
static rpiv_status denoise(const rpiv_piv *pv, rpiv_field *f, float *gain)
{
    const int nx = f->nx, ny = f->ny;
    const size_t n = (size_t)nx * (size_t)ny;
    if (nx < 3 && ny < 3)
        return RPIV_OK;
    double *buf = malloc((n + (size_t)(nx > ny ? nx : ny)) * sizeof *buf);
    if (!buf)
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the predictor denoiser");
    double *line = buf + n;
    const double universal = sqrt(2.0 * log((double)n));
    const int j = pred_pass(pv, f);
    const double rx = j >= 0 ? pv->pass[j].ww / (double)f->dx : 2,
                 ry = j >= 0 ? pv->pass[j].wh / (double)f->dy : 2;
    int order[LEVELS];
    level_orders(pv->p.refine_denoise_order, order);
    double ratio[LEVELS], noise[2] = {(double)INFINITY, (double)INFINITY};
    for (int lev = 0; lev < LEVELS; lev++)
        ratio[lev] = model_detail(order, lev, order[lev], rx, ry);
    /* the first level's deviations of both details (one of them is ratio[0]) */
    const double ratio2 = order[0] == DET2 ? ratio[0] : model_detail(order, 0, DET2, rx, ry),
                 ratio4 = order[0] == DET2 ? model_detail(order, 0, DET4, rx, ry) : ratio[0];
    for (int lev = 0, step = 1; lev < LEVELS; lev++, step *= 2)
        for (int comp = 0; comp < 2; comp++) {
            float *g = comp ? f->v : f->u;
            double sigma = noise_sigma(g, nx, ny, step, order[lev], buf);
            double t2 = 0; /* DET42's end samples: the second differences' threshold */
            if (lev == 0) {
                /* The noise level the coarser caps scale from: a smooth flow's own detail,
                 * which has no direction free of it in a vortex, raises the second
                 * differences' sigma (Lamb-Oseen: 0.022 px) far more than the fourth's
                 * (0.008 px); on noise alone the fourth's, scaled by the model, is 1.06 times
                 * the second's (0.95..1.17 on test_noise's fields), so the smaller of the two,
                 * in the units of the level's detail. */
                const double s2 = order[0] == DET2 ? sigma : noise_sigma(g, nx, ny, 1, DET2, buf);
                const double s4 = order[0] == DET2 ? noise_sigma(g, nx, ny, 1, DET4, buf) : sigma;
                noise[comp] = order[0] == DET2 ? fmin(s2, s4 * ratio2 / ratio4)
                                               : fmin(s2 * ratio4 / ratio2, s4);
                /* The first dilation's threshold stays session 5's, its second differences'
                 * sigma (a smaller one kept the core's few large errors, docs/piv.md), in the
                 * units of the fourth difference's detail when that is the level's. */
                sigma = order[0] == DET2 ? s2 : s2 * ratio4 / ratio2;
                t2 = s2 * universal;
            } else if (isfinite(noise[comp])) /* a smooth flow's own detail is no noise */
                sigma = fmin(sigma, noise[comp] * ratio[lev] / ratio[0]);
            if (!isfinite(sigma))
                continue;
            const double t = sigma * universal;
            float *gx = gain ? gain + ((size_t)(comp * LEVELS + lev) * 2) * n : NULL;
            shrink_axis(g, ny, nx, 1, (size_t)nx, step, order[lev], t, t2, line, gx);
            shrink_axis(g, nx, ny, (size_t)nx, 1, step, order[lev], t, t2, line,
                        gx ? gx + n : NULL);
        }
    free(buf);
    return RPIV_OK;
}

void piv_curv_threshold(const rpiv_field *f, double thr[2])
{
    const size_t n = (size_t)f->nx * (size_t)f->ny;
    double *buf = malloc((n ? n : 1) * sizeof *buf);
    for (int c = 0; c < 2; c++) {
        /* the second difference c = -4 d (d the detail, DET2), so its noise is 4 sigma_d */
        const double s =
            buf ? noise_sigma(c ? f->v : f->u, f->nx, f->ny, 1, DET2, buf) : (double)INFINITY;
        thr[c] = 4 * s * sqrt(2.0 * log((double)(n > 1 ? n : 2)));
    }
    free(buf);
}

rpiv_status piv_pred_denoise(const rpiv_piv *pv, rpiv_field *f)
{
    return denoise(pv, f, NULL);
}

rpiv_status piv_pred_denoise_weights(const rpiv_piv *pv, rpiv_field *f, float **gain)
{
    const size_t n = (size_t)f->nx * (size_t)f->ny, m = (size_t)PIV_DENOISE_STAGES * 2 * n;
    *gain = malloc(m * sizeof **gain);
    if (!*gain)
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the denoiser's weights");
    for (size_t k = 0; k < m; k++)
        (*gain)[k] = 1; /* a stage that does not run: the identity */
    rpiv_status st = denoise(pv, f, *gain);
    if (st) {
        free(*gain);
        *gain = NULL;
    }
    return st;
}

/* The stencil of the detail of the given order of sample i of a line of n samples: the
 * samples idx[] and weights w[] with detail = sum w U_idx (detail, detail4 with the odd
 * reflection at the ends spelled out). Returns their count (at most 5). */
static int stencil(int n, int order, int i, int *idx, double *w)
{
    int c = 0;
    if (order == DET42)
        order = det42_end(n, i) ? DET2 : DET4;
    if (order == DET2) {
        const int e = i == 0 ? 1 : i == n - 1 ? -1 : 0; /* an end: the inward direction */
        for (int q = 0; q < 3; q++) {
            idx[c] = e ? i + q * e : i - 1 + q;
            w[c++] = e ? (q == 1 ? -2.0 : 1.0) / 6.0 : (q == 1 ? 0.5 : -0.25);
        }
        return c;
    }
    static const double k4[5] = {1.0 / 16, -4.0 / 16, 6.0 / 16, -4.0 / 16, 1.0 / 16};
    for (int o = -2; o <= 2; o++) {
        const int m = i + o;
        int at[2], na = 0;
        double wt[2];
        if (m < 0) /* U_m = 2 U_0 - U_-m */
            at[0] = 0, wt[0] = 2 * k4[o + 2], at[1] = -m, wt[1] = -k4[o + 2], na = 2;
        else if (m >= n)
            at[0] = n - 1, wt[0] = 2 * k4[o + 2], at[1] = 2 * (n - 1) - m, wt[1] = -k4[o + 2],
            na = 2;
        else
            at[0] = m, wt[0] = k4[o + 2], na = 1;
        for (int a = 0; a < na; a++) {
            int q = 0;
            while (q < c && idx[q] != at[a])
                q++;
            if (q == c)
                idx[c] = at[a], w[c++] = 0;
            w[q] += wt[a];
        }
    }
    return c;
}

/* Place p of a line of len samples at dilation 2^lev: its sub-line o = p mod 2^lev, its index
 * k on it, the sub-line's sample count m. */
static void subline(int p, int lev, int len, int *o, int *k, int *m)
{
    *o = p & ((1 << lev) - 1);
    *k = p >> lev;
    *m = (len - *o + (1 << lev) - 1) >> lev;
}

int piv_pred_denoise_map_t(const float *gain, int fine, int nx, int ny, int comp, double *c,
                           int bx0, int bw, int by0, int bh, double *tmp)
{
    int orders[LEVELS];
    level_orders(fine, orders);
    const size_t n = (size_t)nx * (size_t)ny, nb = (size_t)bw * (size_t)bh;
    /* the box of c's non-zero samples (lo[axis] .. hi[axis]): the samples outside it have no
     * detail to scatter; each stage widens it along its axis by its stencils' reach */
    int lo[2] = {bw, bh}, hi[2] = {-1, -1};
    for (int j = 0; j < bh; j++)
        for (int i = 0; i < bw; i++)
            if (c[(size_t)j * (size_t)bw + (size_t)i] != 0) {
                lo[0] = i < lo[0] ? i : lo[0], hi[0] = i > hi[0] ? i : hi[0];
                lo[1] = j < lo[1] ? j : lo[1], hi[1] = j > hi[1] ? j : hi[1];
            }
    if (hi[0] < 0)
        return 0; /* A^T 0 = 0 */
    /* a: the details' factors (g - 1) c of the samples whose stencil is the interior one, the
     * same at every such sample and symmetric, so that D^T of them is a convolution along the
     * axis (rows: vectorised); the few samples at a sub-line's ends scatter their own stencil.
     * Each row of a has PAD zeros either side (the widest reach, 2 sub-line steps at dilation
     * 4). */
    enum { PAD = 8 };
    const size_t as = (size_t)bw + 2 * PAD;
    const int nmax = bw > bh ? bw : bh;
    double *a = calloc(as * (size_t)bh, sizeof *a);
    int *kind = malloc(2 * (size_t)nmax * sizeof *kind);
    if (!a || !kind) {
        free(a);
        free(kind);
        return -1;
    }
    for (int lev = LEVELS - 1; lev >= 0; lev--) {
        const int step = 1 << lev, order = orders[lev], rad = order != DET2 ? 2 : 1;
        /* the interior stencil, kw[|d|] at d sub-line steps (stencil() of a line just long
         * enough for one interior sample) */
        int kat[5];
        double kw5[5], kw[3] = {0, 0, 0};
        const int kc = stencil(2 * rad + 1, order, rad, kat, kw5);
        for (int q = 0; q < kc; q++)
            kw[abs(kat[q] - rad)] = kw5[q];
        for (int axis = 1; axis >= 0; axis--) {
            const float *gs = gain + ((size_t)(comp * LEVELS + lev) * 2 + (size_t)axis) * n;
            const int len = axis ? ny : nx, b0 = axis ? by0 : bx0, blen = axis ? bh : bw;
            int *const ends = kind + nmax;
            memcpy(tmp, c, nb * sizeof *tmp);
            /* each place along the axis: 1 if its stencil is the interior one (step a power
             * of 2: the sub-line o = p mod step, k = p / step, of m samples); the others (a
             * sub-line's ends) listed in ends[] */
            int nend = 0;
            for (int r = lo[axis]; r <= hi[axis]; r++) {
                int o, k, m;
                subline(b0 + r, lev, len, &o, &k, &m);
                kind[r] = k >= rad && k <= m - 1 - rad;
                if (!kind[r])
                    ends[nend++] = r;
            }
            /* a = (g - 1) c at the interior places, 0 at the ends */
            for (int j = lo[1]; j <= hi[1]; j++) {
                const float *gr = gs + (size_t)(by0 + j) * (size_t)nx + (size_t)bx0;
                const double *cr = c + (size_t)j * (size_t)bw;
                double *ar = a + (size_t)j * as + PAD;
                if (axis && !kind[j]) {
                    for (int i = lo[0]; i <= hi[0]; i++)
                        ar[i] = 0;
                    continue;
                }
                for (int i = lo[0]; i <= hi[0]; i++)
                    ar[i] = ((double)gr[i] - 1) * cr[i];
                if (!axis)
                    for (int e = 0; e < nend; e++)
                        ar[ends[e]] = 0;
            }
            /* the ends: each scatters its own stencil */
            for (int e = 0; e < nend; e++) {
                const int r = ends[e];
                int o, k, m, at[5];
                subline(b0 + r, lev, len, &o, &k, &m);
                double w[5];
                const int cnt = stencil(m, order, k, at, w);
                const int j0 = axis ? r : lo[1], j1 = axis ? r : hi[1];
                const int i0 = axis ? lo[0] : r, i1 = axis ? hi[0] : r;
                for (int j = j0; j <= j1; j++)
                    for (int i = i0; i <= i1; i++) {
                        const size_t at0 = (size_t)j * (size_t)bw + (size_t)i;
                        const double v =
                            ((double)gs[(size_t)(by0 + j) * (size_t)nx + (size_t)(bx0 + i)] - 1) *
                            c[at0];
                        if (v == 0)
                            continue;
                        for (int q = 0; q < cnt; q++) {
                            const int t = o + at[q] * step - b0;
                            if (t >= 0 && t < blen)
                                tmp[axis ? (size_t)t * (size_t)bw + (size_t)i
                                         : (size_t)j * (size_t)bw + (size_t)t] += w[q] * v;
                        }
                    }
            }
            /* the interior stencils' part: targets within 2 sub-line steps of the box */
            const int reach = 2 * step;
            const int tlo = lo[axis] - reach < 0 ? 0 : lo[axis] - reach;
            const int thi = hi[axis] + reach > blen - 1 ? blen - 1 : hi[axis] + reach;
            if (axis == 0) {
                for (int j = lo[1]; j <= hi[1]; j++) {
                    const double *ar = a + (size_t)j * as + PAD;
                    double *tr = tmp + (size_t)j * (size_t)bw;
                    for (int t = tlo; t <= thi; t++)
                        tr[t] += kw[0] * ar[t] + kw[1] * (ar[t - step] + ar[t + step]) +
                                 kw[2] * (ar[t - 2 * step] + ar[t + 2 * step]);
                }
            } else {
                for (int t = tlo; t <= thi; t++) {
                    double *tr = tmp + (size_t)t * (size_t)bw;
                    for (int d = -rad; d <= rad; d++) {
                        const int src = t + d * step;
                        if (src < lo[1] || src > hi[1])
                            continue;
                        const double kd = kw[abs(d)], *ar = a + (size_t)src * as + PAD;
                        for (int i = lo[0]; i <= hi[0]; i++)
                            tr[i] += kd * ar[i];
                    }
                }
            }
            memcpy(c, tmp, nb * sizeof *c);
            lo[axis] = tlo;
            hi[axis] = thi;
        }
    }
    free(a);
    free(kind);
    return 0;
}

int piv_pred_repeats(const rpiv_piv *pv, const rpiv_field *predictor)
{
    /* piv_repeats (src/piv/piv.c) spelled out for the pass the predictor feeds */
    const int j = pred_pass(pv, predictor);
    if (j < 0)
        return 0;
    const int k = j + 1 < pv->npass ? j + 1 : j; /* the pass it predicts */
    return k > 0 && pv->deforms && pv->pass[k].ww == pv->pass[k - 1].ww &&
           pv->pass[k].wh == pv->pass[k - 1].wh;
}

int piv_pred_denoised(const rpiv_piv *pv, const rpiv_field *predictor)
{
    return predictor && pv->p.refine_denoise && piv_pred_repeats(pv, predictor)
               ? pv->p.refine_denoise_order
               : 0;
}

/* The predictor's low-pass filter: [a/2, 1 - a, a/2] along x, then along y. At the edge of
 * the grid the missing neighbour is the point-symmetric extension 2 U(0) - U(1), with which
 * the filter leaves the edge value as it is (and a linear field linear anywhere). Its response
 * to a wave of k grid steps per wavelength is 1 - a (1 - cos(2 pi / k)): 1 - 2a at the grid's
 * Nyquist limit, where the window's own response is nil and the iteration would otherwise
 * keep every error it once made (docs/piv.md, "Refinement"). */
rpiv_status piv_pred_filter(rpiv_field *f, double a)
{
    const int nx = f->nx, ny = f->ny, n = nx > ny ? nx : ny;
    float *line = malloc((size_t)n * sizeof *line);
    if (!line)
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the predictor filter");
    const float c0 = (float)(1 - a), c1 = (float)(0.5 * a);
    for (int comp = 0; comp < 2; comp++) {
        float *g = comp ? f->v : f->u;
        for (int j = 0; nx > 2 && j < ny; j++) {
            float *r = g + (size_t)j * (size_t)nx;
            memcpy(line, r, (size_t)nx * sizeof *line);
            for (int i = 1; i < nx - 1; i++)
                r[i] = c0 * line[i] + c1 * (line[i - 1] + line[i + 1]);
        }
        for (int i = 0; ny > 2 && i < nx; i++) {
            for (int j = 0; j < ny; j++)
                line[j] = g[(size_t)j * (size_t)nx + (size_t)i];
            for (int j = 1; j < ny - 1; j++)
                g[(size_t)j * (size_t)nx + (size_t)i] =
                    c0 * line[j] + c1 * (line[j - 1] + line[j + 1]);
        }
    }
    free(line);
    return RPIV_OK;
}

void piv_pred_filter_t(double *c, double a, int nx, int ny, int bx0, int bw, int by0, int bh,
                       double *tmp)
{
    const size_t nb = (size_t)bw * (size_t)bh;
    for (int axis = 0; axis < 2; axis++) {
        const int len = axis ? ny : nx;
        if (len <= 2)
            continue;
        memset(tmp, 0, nb * sizeof *tmp);
        for (int j = 0; j < bh; j++)
            for (int i = 0; i < bw; i++) {
                const double v = c[(size_t)j * (size_t)bw + (size_t)i];
                const int g = axis ? by0 + j : bx0 + i;
                const size_t at = (size_t)j * (size_t)bw + (size_t)i, st = axis ? (size_t)bw : 1;
                const int pos = axis ? j : i, lim = axis ? bh : bw;
                if (g == 0 || g == len - 1) {
                    tmp[at] += v;
                    continue;
                }
                tmp[at] += (1 - a) * v;
                if (pos > 0)
                    tmp[at - st] += 0.5 * a * v;
                if (pos < lim - 1)
                    tmp[at + st] += 0.5 * a * v;
            }
        memcpy(c, tmp, nb * sizeof *c);
    }
}

/* ---- the grid's Nyquist notch (refine_notch; docs/piv.md, "The grid's Nyquist mode") ---- */

/* The notch of order m along a line: U - (-d2 / 4)^m U (d2 the second difference), response
 * 1 - q^m to a wave of frequency w, q = (1 - cos w) / 2. The line is continued m samples beyond
 * either end by the cubic through its 4 end samples, so that cubics pass unchanged everywhere.
 * w[2m + 1]: the taps of (-d2 / 4)^m, (-1)^k C(2m, m + k) / 4^m; ext[m][4]: the weights of the
 * end samples 0..3 at the continued sample -1 - k (Lagrange). */
typedef struct notch_taps {
    int m;
    double w[2 * PIV_NOTCH_MAX + 1];
    double ext[PIV_NOTCH_MAX][4];
} notch_taps;

static void notch_taps_init(notch_taps *t, int m)
{
    t->m = m;
    double c = 1;
    for (int k = 0; k < m; k++)
        c *= 0.25;
    for (int k = -m; k <= m; k++) {
        double b = 1; /* C(2m, m + k) */
        for (int j = 1; j <= m + k; j++)
            b = b * (2 * m - j + 1) / j;
        t->w[k + m] = (k % 2 ? -b : b) * c; /* (-1)^k */
    }
    for (int k = 0; k < m; k++) {
        const double x = -1 - k;
        t->ext[k][0] = (x - 1) * (x - 2) * (x - 3) / -6.0;
        t->ext[k][1] = x * (x - 2) * (x - 3) / 2.0;
        t->ext[k][2] = x * (x - 1) * (x - 3) / -2.0;
        t->ext[k][3] = x * (x - 1) * (x - 2) / 6.0;
    }
}

/* The notch on the n samples of a line g (stride st; n >= 4). line: n + 2m doubles. */
static void notch_line(const notch_taps *t, float *g, size_t st, int n, double *line)
{
    const int m = t->m;
    for (int i = 0; i < n; i++)
        line[m + i] = (double)g[(size_t)i * st];
    for (int k = 0; k < m; k++) {
        double a = 0, b = 0;
        for (int j = 0; j < 4; j++) {
            a += t->ext[k][j] * line[m + j];
            b += t->ext[k][j] * line[m + n - 1 - j];
        }
        line[m - 1 - k] = a;
        line[m + n + k] = b;
    }
    for (int i = 0; i < n; i++) {
        double d = 0;
        for (int k = 0; k <= 2 * m; k++)
            d += t->w[k] * line[i + k];
        g[(size_t)i * st] = (float)(line[m + i] - d);
    }
}

/* The notch of pass `pass`'s predictor when on: along each axis the dilations d = 1, 2, 4 with
 * the window spanning 2 d grid steps or more, of order refine_notch; none when off. */
static void notch_of(const rpiv_piv *pv, int pass, int on, piv_notch *n)
{
    const piv_pass *ps = &pv->pass[pass];
    const int w[2] = {ps->ww, ps->wh}, st[2] = {ps->sx, ps->sy};
    for (int a = 0; a < 2; a++) {
        n->levels[a] = 0;
        for (int d = 1; on && d <= PIV_NOTCH_DILATIONS && w[a] >= 2 * d * st[a]; d *= 2)
            n->levels[a]++;
        n->m[a] = n->levels[a] ? pv->p.refine_notch : 0;
    }
}

void piv_pred_notch_orders(const rpiv_piv *pv, int pass, int denoise, const rpiv_field *predictor,
                           piv_notch *n)
{
    notch_of(pv, pass,
             denoise && pv->p.refine_notch > 0 && pass == pv->npass - 1 && predictor &&
                 pv->final_known && piv_field_hash(predictor) == pv->final_hash,
             n);
}

int piv_pred_denoised_ensemble(const rpiv_piv *pv, const rpiv_field *predictor)
{
    return pv->p.ensemble_denoise ? piv_pred_denoised(pv, predictor) : 0;
}

void piv_pred_notch_ensemble(const rpiv_piv *pv, int pass, const rpiv_field *predictor,
                             piv_notch *n)
{
    notch_of(pv, pass,
             !pv->p.ensemble_denoise && pv->p.refine_notch > 0 && predictor &&
                 piv_pred_repeats(pv, predictor),
             n);
}

/* The dilations of level k: 1, 2, 4, ... */
#define NOTCH_DIL(k) (1 << (k))

rpiv_status piv_pred_notch(rpiv_field *f, const piv_notch *n)
{
    if (!n || (n->m[0] <= 0 && n->m[1] <= 0))
        return RPIV_OK;
    const int nx = f->nx, ny = f->ny, len = nx > ny ? nx : ny;
    double *line = malloc(((size_t)len + 2 * PIV_NOTCH_MAX) * sizeof *line);
    if (!line)
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the predictor's notch");
    for (int a = 0; a < 2; a++) {
        if (n->m[a] <= 0)
            continue;
        notch_taps t;
        notch_taps_init(&t, n->m[a]);
        const int lines = a ? nx : ny, along = a ? ny : nx;
        const size_t step = a ? (size_t)nx : 1, across = a ? 1 : (size_t)nx;
        for (int comp = 0; comp < 2; comp++) {
            float *g = comp ? f->v : f->u;
            for (int k = 0; k < n->levels[a]; k++) {
                const int d = NOTCH_DIL(k);
                for (int j = 0; j < lines; j++)
                    for (int r = 0; r < d && r < along; r++) {
                        const int sub = (along - 1 - r) / d + 1; /* the sub-line's length */
                        if (sub >= 4)
                            notch_line(&t, g + (size_t)j * across + (size_t)r * step,
                                       (size_t)d * step, sub, line);
                    }
            }
        }
    }
    free(line);
    return RPIV_OK;
}

void piv_pred_notch_t(double *c, const piv_notch *n, int nx, int ny, int bx0, int bw, int by0,
                      int bh, double *tmp)
{
    const size_t nb = (size_t)bw * (size_t)bh;
    for (int axis = 0; axis < 2; axis++) {
        const int len = axis ? ny : nx, b0 = axis ? by0 : bx0, lim = axis ? bh : bw;
        if (n->m[axis] <= 0)
            continue;
        notch_taps t;
        notch_taps_init(&t, n->m[axis]);
        const int mm = t.m;
        const size_t st = axis ? (size_t)bw : 1;
        /* the forward applies dilation 1 first: its transpose last */
        for (int k = n->levels[axis] - 1; k >= 0; k--) {
            const int d = NOTCH_DIL(k);
            memcpy(tmp, c, nb * sizeof *tmp); /* the identity's share */
            for (int j = 0; j < bh; j++)
                for (int i = 0; i < bw; i++) {
                    const size_t at = (size_t)j * (size_t)bw + (size_t)i;
                    const int pos = axis ? j : i, g = b0 + pos, r = g % d;
                    const int sub = (len - 1 - r) / d + 1, p = (g - r) / d;
                    if (sub < 4)
                        continue;
                    const double v = c[at];
                    const size_t line0 = at - (size_t)pos * st; /* the block line's first node */
                    /* output p of the sub-line took -w_k times its continued sample p + k - m */
                    for (int q = 0; q <= 2 * mm; q++) {
                        const int s = p + q - mm;
                        const double a = -t.w[q] * v;
                        if (s >= 0 && s < sub) {
                            const int node = r + s * d;
                            if (node - b0 >= 0 && node - b0 < lim)
                                tmp[line0 + (size_t)(node - b0) * st] += a;
                            continue;
                        }
                        const int e = s < 0 ? -1 - s : s - sub; /* which continued sample */
                        for (int h = 0; h < 4; h++) {
                            const int node = r + (s < 0 ? h : sub - 1 - h) * d;
                            if (node - b0 >= 0 && node - b0 < lim)
                                tmp[line0 + (size_t)(node - b0) * st] += a * t.ext[e][h];
                        }
                    }
                }
            memcpy(c, tmp, nb * sizeof *c);
        }
    }
}
