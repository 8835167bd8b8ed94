/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/piv_cbc.c - correlation-based correction (Hart 2000): the peak of a window chosen
 * on its correlation plane combined with its four neighbours' planes, which share the true
 * peak and not the noise peaks. Only the choice of the integer peak uses the neighbours: the
 * sub-pixel fit is the window's own plane's (docs/piv.md, "Correlation-based correction"). */
#include "piv_impl.h"

#include "peak_impl.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* i modulo n, in 0..n-1 */
static int wrap(int i, int n)
{
    i %= n;
    return i < 0 ? i + n : i;
}

/* The search reach for windows of side `side` and search radius near; < 1: no correction. */
static int cbc_reach(int side, int near)
{
    int reach = near > 0 ? near : side / 4;
    return reach > side / 2 - 3 ? side / 2 - 3 : reach;
}

rpiv_status piv_cbc_new(const piv_pass *ps, int near, int mode, piv_cbc **out)
{
    *out = NULL;
    /* the search reach: the predictor's radius, or a quarter of the window without one */
    const int reach = cbc_reach(ps->ww < ps->wh ? ps->ww : ps->wh, near);
    if (reach < 1)
        return RPIV_OK; /* windows too small for a choice among peaks: no correction */
    piv_cbc *cb = calloc(1, sizeof *cb);
    if (!cb)
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the correlation-based correction");
    cb->mode = mode;
    cb->reach = reach;
    cb->r = reach + 2;
    cb->s = 2 * cb->r + 1;
    cb->nx = ps->nx;
    cb->ny = ps->ny;
    cb->nwin = ps->nwin;
    const size_t n = ps->nwin;
    cb->crop = malloc(n * (size_t)cb->s * (size_t)cb->s * sizeof *cb->crop);
    cb->top = malloc(n * sizeof *cb->top);
    cb->val = malloc(n * sizeof *cb->val);
    cb->ratio = malloc(n * sizeof *cb->ratio);
    cb->cmax = malloc(n * sizeof *cb->cmax);
    cb->scale = malloc(n * sizeof *cb->scale);
    cb->pu = malloc(2 * n * sizeof *cb->pu);
    cb->ixy = malloc(2 * n * sizeof *cb->ixy);
    cb->has = calloc(n, 1);
    cb->moved = calloc(n, 1);
    if (!cb->crop || !cb->top || !cb->val || !cb->ratio || !cb->cmax || !cb->scale || !cb->pu ||
        !cb->ixy || !cb->has || !cb->moved) {
        piv_cbc_free(cb);
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the correlation-based correction");
    }
    *out = cb;
    return RPIV_OK;
}

void piv_cbc_free(piv_cbc *cb)
{
    if (!cb)
        return;
    free(cb->crop);
    free(cb->top);
    free(cb->val);
    free(cb->ratio);
    free(cb->cmax);
    free(cb->scale);
    free(cb->pu);
    free(cb->ixy);
    free(cb->has);
    free(cb->moved);
    free(cb);
}

double piv_cbc_bytes(int ww, int wh, int near)
{
    const int reach = cbc_reach(ww < wh ? ww : wh, near);
    if (reach < 1)
        return 0;
    const double s = 2.0 * reach + 5;
    return s * s * sizeof(float) + 5 * sizeof(float) + 2 * sizeof(double) + 2 * sizeof(int) + 2;
}

void piv_cbc_store(piv_cbc *cb, const float *plane, const float *colmax, int w, int h, size_t win,
                   const rpiv_peak *pk, double ea, double eb, double pu, double pv_)
{
    const int r = cb->r, s = cb->s;
    float *c = cb->crop + win * (size_t)s * (size_t)s, top = -INFINITY, cmax = -INFINITY;
    const float *scan = colmax ? colmax : plane; /* the plane's top: its column maxima's */
    for (size_t k = 0; k < (size_t)w * (colmax ? 1 : (size_t)h); k++)
        top = scan[k] > top ? scan[k] : top;
    for (int dy = -r; dy <= r; dy++) {
        const float *row = plane + (size_t)wrap(dy, h) * (size_t)w;
        float *crow = c + (size_t)(dy + r) * (size_t)s;
        /* shifts -r..-1 at the row's end, 0..r at its start (r < w / 2) */
        memcpy(crow, row + (w - r), (size_t)r * sizeof *crow);
        memcpy(crow + r, row, (size_t)(r + 1) * sizeof *crow);
        for (int q = 0; q < s; q++)
            cmax = crow[q] > cmax ? crow[q] : cmax;
    }
    cb->top[win] = top;
    cb->val[win] = pk->value;
    cb->ratio[win] = pk->ratio;
    cb->cmax[win] = cmax;
    cb->scale[win] = (float)sqrt(ea * eb);
    cb->pu[2 * win] = pu;
    cb->pu[2 * win + 1] = pv_;
    cb->ixy[2 * win] = pk->ix;
    cb->ixy[2 * win + 1] = pk->iy;
    cb->has[win] = 1;
}

/* The value of crop c (side s = 2 r + 1) at shift (dx, dy), |dx|, |dy| <= r. */
static float at(const float *c, int r, int dx, int dy)
{
    return c[(size_t)(dy + r) * (size_t)(2 * r + 1) + (size_t)(dx + r)];
}

/* The correction of window win: 1 and its new vector in f when its peak moved. comb: room for
 * (2 reach + 1)^2 doubles. */
static int cbc_window(const piv_cbc *cb, int offsets, rpiv_subpixel method, rpiv_field *f,
                      size_t win, double *comb)
{
    enum { MAXN = 5 };
    const int s = cb->s, reach = cb->reach;
    const size_t plane = (size_t)s * (size_t)s;
    const int i = (int)(win % (size_t)cb->nx), j = (int)(win / (size_t)cb->nx);
    const int nb[MAXN][2] = {{0, 0}, {-1, 0}, {1, 0}, {0, -1}, {0, 1}};
    const float *cn[MAXN];
    double inv[MAXN];
    int dn[MAXN][2], n = 0;
    if (!cb->has[win] || !(cb->cmax[win] > 0) || abs(cb->ixy[2 * win]) > reach ||
        abs(cb->ixy[2 * win + 1]) > reach || !(cb->ratio[win] < PIV_CBC_RATIO))
        return 0; /* not measured, its peak beyond the reach, or clear: kept */
    for (int k = 0; k < MAXN; k++) {
        const int ii = i + nb[k][0], jj = j + nb[k][1];
        if (ii < 0 || jj < 0 || ii >= cb->nx || jj >= cb->ny)
            continue;
        const size_t w2 = (size_t)jj * (size_t)cb->nx + (size_t)ii;
        if (!cb->has[w2] || !(cb->cmax[w2] > 0))
            continue;
        /* plane index q of window w2 is the displacement pu(w2) + q: aligned with this
         * window's by the difference of the integer offsets; a deformed pass's planes are
         * residuals of a smooth predictor, aligned as they are */
        int ox = 0, oy = 0;
        if (offsets) {
            ox = (int)lround(cb->pu[2 * w2] - cb->pu[2 * win]);
            oy = (int)lround(cb->pu[2 * w2 + 1] - cb->pu[2 * win + 1]);
            if (abs(ox) > 1 || abs(oy) > 1)
                continue; /* too different a neighbour to share the peak */
        }
        cn[n] = cb->crop + w2 * plane;
        inv[n] = 1.0 / (double)cb->cmax[w2];
        dn[n][0] = ox;
        dn[n][1] = oy;
        n++;
    }
    if (n < 2)
        return 0; /* no neighbour */
    /* the combination over |shift| <= reach, neighbour after neighbour (each position sums or
     * multiplies its terms in the same order as one at a time would) */
    const int m = 2 * reach + 1, r = cb->r;
    for (int q = 0; q < m * m; q++)
        comb[q] = cb->mode == 2 ? 0 : 1;
    for (int k = 0; k < n; k++)
        for (int dy = -reach; dy <= reach; dy++) {
            const float *row = cn[k] + (size_t)(dy - dn[k][1] + r) * (size_t)s + (r - dn[k][0]);
            double *out = comb + (size_t)(dy + reach) * (size_t)m + reach;
            if (cb->mode == 2)
                for (int dx = -reach; dx <= reach; dx++)
                    out[dx] += row[dx] > 0 ? (double)row[dx] * inv[k] : 0;
            else
                for (int dx = -reach; dx <= reach; dx++)
                    out[dx] *= row[dx] > 0 ? (double)row[dx] * inv[k] : 0;
        }
    double best = 0;
    int lx = 0, ly = 0, found = 0;
    for (int dy = -reach; dy <= reach; dy++)
        for (int dx = -reach; dx <= reach; dx++) {
            const double p = comb[(size_t)(dy + reach) * (size_t)m + (size_t)(dx + reach)];
            if (p > best) {
                best = p;
                lx = dx;
                ly = dy;
                found = 1;
            }
        }
    if (!found)
        return 0;

    /* the window's own local maximum that the combination points at: steepest ascent */
    const float *c0 = cn[0];
    const int lim = r - (method == RPIV_SUBPIXEL_SPLINE ? PEAK_SPLINE_R : 1);
    for (int step = 0; step < s * s; step++) {
        float v = at(c0, r, lx, ly);
        int bx = lx, by = ly;
        for (int ddy = -1; ddy <= 1; ddy++)
            for (int ddx = -1; ddx <= 1; ddx++) {
                const int x = lx + ddx, y = ly + ddy;
                if (abs(x) <= r - 1 && abs(y) <= r - 1 && at(c0, r, x, y) > v) {
                    v = at(c0, r, x, y);
                    bx = x;
                    by = y;
                }
            }
        if (bx == lx && by == ly)
            break;
        lx = bx;
        ly = by;
    }
    if ((lx == cb->ixy[2 * win] && ly == cb->ixy[2 * win + 1]) || abs(lx) > lim || abs(ly) > lim)
        return 0;
    const float vm = at(c0, r, lx, ly);
    double fx, fy;
    if (!(vm > 0) || !peak_fit_at(c0, s, s, lx + r, ly + r, method, &fx, &fy))
        return 0;
    f->u[win] = (float)(cb->pu[2 * win] + lx + fx);
    f->v[win] = (float)(cb->pu[2 * win + 1] + ly + fy);
    /* the ratio against the higher of the plane's top and the peak it replaces (< 1) */
    const float own = cb->val[win], other = cb->top[win] > own ? cb->top[win] : own;
    f->peak_ratio[win] = other > 0 ? vm / other : RPIV_PEAK_RATIO_MAX;
    f->corr[win] = cb->scale[win] > 0 ? vm / cb->scale[win] : 0;
    return 1;
}

size_t piv_cbc_apply(piv_cbc *cb, int offsets, rpiv_subpixel method, rpiv_field *f, int nthreads)
{
    size_t moved = 0;
    const size_t m = 2 * (size_t)cb->reach + 1;
    /* every window reads the stored planes only and writes its own vector: any thread count
     * gives the same field */
#pragma omp parallel num_threads(nthreads) reduction(+ : moved)
    {
        double *comb = malloc(m * m * sizeof *comb);
#pragma omp for schedule(static)
        for (size_t win = 0; win < cb->nwin; win++) {
            cb->moved[win] = 0;
            if (comb && f->flag[win] == RPIV_FLAG_VALID &&
                cbc_window(cb, offsets, method, f, win, comb)) {
                cb->moved[win] = 1;
                moved++;
            }
        }
        free(comb);
    }
    return moved;
}
