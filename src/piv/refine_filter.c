/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/refine_filter.c - the denoiser of the refinement's predictor (docs/piv.md,
 * "Refinement at the final size"): at dilations 1, 2 and 4 grid steps in turn (an a-trous
 * split), the field split, line by line along x and then along y, into a [1/4, 1/2, 1/4]
 * smoothing and its detail, the detail shrunk (non-negative garrote) with a threshold set from
 * the field's own noise level, sigma sqrt(2 ln n) (Donoho and Johnstone's universal
 * threshold), sigma the median absolute detail / 0.6745 along the grid direction where it is
 * smallest, at the coarser dilations at most what the first one's sigma predicts for the
 * noise of a window average. */
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

/* The median of v[0..n-1] (rearranged): GSL's quickselect, linear in n (the sort it replaces
 * took 7 % of a default 2560 x 2160 run); the same value as the sort's. */
static double median_of(double *v, size_t n)
{
    if (!n)
        return 0;
    const double hi = gsl_stats_select(v, 1, n, n / 2);
    return n % 2 ? hi : 0.5 * (gsl_stats_select(v, 1, n, n / 2 - 1) + hi);
}

/* Noise level of one component at dilation `step` (grid steps between the samples of a
 * detail): the smallest over the four grid directions (x, y and the diagonals) of the median
 * absolute inner detail / 0.6745. A shear or wave along one direction has no detail across
 * it, so at least one direction sees the noise alone. The details of a dilation are taken
 * every `step` nodes along x and y: closer ones share their samples' noise (and cost the
 * time of 1 + 1/4 + 1/16 of one level instead of three). */
static double noise_sigma(const float *g, int nx, int ny, int step, double *buf)
{
    const ptrdiff_t sx = step, sy = (ptrdiff_t)step * nx;
    const ptrdiff_t dirs[4] = {sx, sy, sy + sx, sy - sx};
    double best = (double)INFINITY;
    for (int d = 0; d < 4; d++) {
        const int ix = d != 1 ? step : 0, iy = d != 0 ? step : 0; /* inner along x, along y */
        size_t m = 0;
        for (int j = iy; j < ny - iy; j += step)
            for (int i = ix; i < nx - ix; i += step) {
                const float *c = g + (size_t)j * (size_t)nx + (size_t)i;
                buf[m++] =
                    fabs(2.0 * (double)c[0] - (double)c[-dirs[d]] - (double)c[dirs[d]]) / 4.0;
            }
        if (m >= 8) {
            double s = median_of(buf, m) / 0.6745;
            best = s < best ? s : best;
        }
    }
    return best;
}

/* Shrink the details of the lines of g (count lines, n samples each, sample stride s, line
 * stride ls) with threshold t (t * 2/3 at the ends, whose detail has 2/3 of the noise). */
static void shrink_lines(float *g, int count, int n, size_t s, size_t ls, double t, double *line)
{
    for (int l = 0; l < count; l++) {
        float *r = g + (size_t)l * ls;
        for (int i = 0; i < n; i++)
            line[i] = detail(r, n, s, i);
        for (int i = 0; i < n; i++) {
            double d = line[i], ti = (i == 0 || i == n - 1) ? t * (2.0 / 3.0) : t;
            /* non-negative garrote: d - t^2 / d above the threshold, 0 below */
            double kept = fabs(d) > ti ? d - ti * ti / d : 0;
            r[(size_t)i * s] = (float)((double)r[(size_t)i * s] - d + kept);
        }
    }
}

/* Shrink, at dilation `step`, the lines along one axis (n samples a line at stride s, count
 * lines at stride ls): each line split into its `step` interleaved sub-lines. */
static void shrink_axis(float *g, int count, int n, size_t s, size_t ls, int step, double t,
                        double *line)
{
    for (int o = 0; o < step; o++) {
        const int m = (n - o + step - 1) / step;
        if (m >= 3)
            shrink_lines(g + (size_t)o * s, count, m, s * (size_t)step, ls, t, line);
    }
}

/* Levels of the denoiser: details at dilations 1, 2, 4 grid steps. In the linear picture of
 * the iteration (docs/piv.md) the repeat keeps (1 - H) G of the predictor's noise and adds the
 * same measurement noise again, so the fixed point's noise is e / (1 - (1 - H) G): with the
 * window's response H (top hat, 50 % overlap) and the noise's G the product of the levels'
 * smoothings, the largest (1 - H) G is 0.18 with one level (at 3.8 grid steps a wavelength),
 * 0.051 with two and 0.014 with three. */
enum { LEVELS = 3, NF = 32 };

/* The noise model of a level: the standard deviation of the detail at dilation 2^level of a
 * field whose noise has the power spectrum of a top-hat window average, |H|^2, H =
 * sinc(w rx / 2) sinc(w ry / 2) (rx, ry: the window over the grid step), after the
 * [1/4, 1/2, 1/4] smoothings of the levels before it along x and y; the smallest of the four
 * grid directions. Mean over an NF x NF grid of frequencies (radians per grid step). */
static double model_detail(int level, double rx, double ry)
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
        for (int l = 0; l < level; l++)
            a[i] *= 0.5 * (1 + cos(w * (double)(1 << l)));
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
                const double k = a[i] * a[j] * 0.5 * (1 - cp);
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

rpiv_status piv_pred_denoise(const rpiv_piv *pv, rpiv_field *f)
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
    double ratio[LEVELS], sigma1[2] = {(double)INFINITY, (double)INFINITY};
    for (int lev = 0; lev < LEVELS; lev++)
        ratio[lev] = model_detail(lev, rx, ry);
    for (int lev = 0, step = 1; lev < LEVELS; lev++, step *= 2)
        for (int comp = 0; comp < 2; comp++) {
            float *g = comp ? f->v : f->u;
            double sigma = noise_sigma(g, nx, ny, step, buf);
            if (lev == 0)
                sigma1[comp] = sigma;
            else if (isfinite(sigma1[comp])) /* a smooth flow's own detail is no noise */
                sigma = fmin(sigma, sigma1[comp] * ratio[lev] / ratio[0]);
            if (!isfinite(sigma))
                continue;
            const double t = sigma * universal;
            shrink_axis(g, ny, nx, 1, (size_t)nx, step, t, line);
            shrink_axis(g, nx, ny, (size_t)nx, 1, step, t, line);
        }
    free(buf);
    return RPIV_OK;
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
