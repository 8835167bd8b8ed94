/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/peak.c - correlation peak search, sub-pixel fits, second peak and peak ratio. */
#include "rpiv/peak.h"

#include <math.h>
#include <stddef.h>

double rpiv_peak_fit3(double cm, double c0, double cp, rpiv_subpixel method, int *ok)
{
    *ok = 0;
    if (!isfinite(cm) || !isfinite(c0) || !isfinite(cp))
        return 0;
    if (method == RPIV_SUBPIXEL_CENTROID) {
        double a = cm > 0 ? cm : 0, b = c0 > 0 ? c0 : 0, c = cp > 0 ? cp : 0;
        if (!(a + b + c > 0))
            return 0;
        *ok = 1;
        return (c - a) / (a + b + c);
    }
    if (method == RPIV_SUBPIXEL_GAUSS && cm > 0 && c0 > 0 && cp > 0) {
        double lm = log(cm), l0 = log(c0), lp = log(cp), den = 2 * (lm - 2 * l0 + lp);
        if (!(den < 0))
            return 0;
        *ok = 1;
        return (lm - lp) / den;
    }
    double den = 2 * (cm - 2 * c0 + cp);
    if (!(den < 0))
        return 0;
    *ok = 1;
    return (cm - cp) / den;
}

/* The shift of index i on a circular axis of n. */
static int shift_of(int i, int n)
{
    return i < n / 2 ? i : i - n;
}

static int wrap(int i, int n)
{
    return i < 0 ? i + n : (i >= n ? i - n : i);
}

static int allowed(int i, int n, int r)
{
    if (r <= 0)
        return 1;
    int s = shift_of(i, n);
    return s >= -r && s <= r;
}

/* 1 if plane(i, j) is >= its 8 circular neighbours. */
static int local_max(const float *p, int w, int h, int i, int j)
{
    float v = p[(size_t)j * (size_t)w + (size_t)i];
    for (int dj = -1; dj <= 1; dj++) {
        const float *row = p + (size_t)wrap(j + dj, h) * (size_t)w;
        for (int di = -1; di <= 1; di++)
            if ((di || dj) && row[wrap(i + di, w)] > v)
                return 0;
    }
    return 1;
}

static void centroid3x3(const float *p, int w, int h, int i, int j, double *dx, double *dy,
                        int *ok)
{
    double s = 0, sx = 0, sy = 0;
    for (int dj = -1; dj <= 1; dj++)
        for (int di = -1; di <= 1; di++) {
            double c = p[(size_t)wrap(j + dj, h) * (size_t)w + (size_t)wrap(i + di, w)];
            if (!isfinite(c)) {
                *ok = 0;
                return;
            }
            if (c > 0) {
                s += c;
                sx += c * di;
                sy += c * dj;
            }
        }
    *ok = s > 0;
    *dx = *ok ? sx / s : 0;
    *dy = *ok ? sy / s : 0;
}

void rpiv_peak_find(const float *plane, int w, int h, int max_shift, rpiv_subpixel method,
                    rpiv_peak *out)
{
    int bi = -1, bj = -1;
    float best = 0;
    for (int j = 0; j < h; j++) {
        if (!allowed(j, h, max_shift))
            continue;
        const float *row = plane + (size_t)j * (size_t)w;
        for (int i = 0; i < w; i++)
            if (allowed(i, w, max_shift) && (bi < 0 ? isfinite(row[i]) : row[i] > best)) {
                best = row[i];
                bi = i;
                bj = j;
            }
    }
    *out = (rpiv_peak){0};
    out->ratio = RPIV_PEAK_RATIO_MAX;
    if (bi < 0)
        return;
    out->ix = shift_of(bi, w);
    out->iy = shift_of(bj, h);
    out->value = best;

    double fx = 0, fy = 0;
    int okx = 0, oky = 0;
    if (method == RPIV_SUBPIXEL_CENTROID) {
        centroid3x3(plane, w, h, bi, bj, &fx, &fy, &okx);
        oky = okx;
    } else {
        const float *row = plane + (size_t)bj * (size_t)w;
        fx = rpiv_peak_fit3(row[wrap(bi - 1, w)], best, row[wrap(bi + 1, w)], method, &okx);
        fy = rpiv_peak_fit3(plane[(size_t)wrap(bj - 1, h) * (size_t)w + (size_t)bi], best,
                            plane[(size_t)wrap(bj + 1, h) * (size_t)w + (size_t)bi], method,
                            &oky);
    }
    out->fit_ok = okx && oky;
    out->dx = out->ix + (out->fit_ok ? fx : 0);
    out->dy = out->iy + (out->fit_ok ? fy : 0);

    /* second peak: the highest local maximum outside the first peak's neighbourhood */
    int found = 0;
    float second = 0;
    for (int j = 0; j < h; j++) {
        if (!allowed(j, h, max_shift))
            continue;
        int ddy = shift_of(wrap(j - bj + h, h), h);
        int near_y = ddy >= -RPIV_PEAK_EXCLUDE && ddy <= RPIV_PEAK_EXCLUDE;
        const float *row = plane + (size_t)j * (size_t)w;
        for (int i = 0; i < w; i++) {
            float v = row[i];
            if (!(found ? v > second : isfinite(v)) || !allowed(i, w, max_shift))
                continue;
            if (near_y) {
                int ddx = shift_of(wrap(i - bi + w, w), w);
                if (ddx >= -RPIV_PEAK_EXCLUDE && ddx <= RPIV_PEAK_EXCLUDE)
                    continue;
            }
            if (local_max(plane, w, h, i, j)) {
                second = v;
                found = 1;
            }
        }
    }
    out->second = found ? second : 0;
    if (found && second > 0 && best < RPIV_PEAK_RATIO_MAX * second)
        out->ratio = best / second;
}
