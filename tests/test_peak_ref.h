/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/test_peak_ref.h - the reference for rpiv_peak_find: a frozen copy of src/piv/peak.c as it
 * was before the search was made faster (commit 4afb3d7), its helpers renamed ref_* and
 * rpiv_peak_find renamed peak_find_ref (rpiv_peak_fit3 copied too, as ref_fit3). The tests
 * (test_peak) and bench_peak require the library's rpiv_peak_find to give the same bits as
 * this copy for every field. Header-only; include it in one translation unit. */
#ifndef RPIV_TESTS_PEAK_REF_H
#define RPIV_TESTS_PEAK_REF_H

#include "rpiv/peak.h"
#include "simd.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

static double ref_fit3(double cm, double c0, double cp, rpiv_subpixel method, int *ok)
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
static int ref_shift_of(int i, int n)
{
    return i < n / 2 ? i : i - n;
}

static int ref_wrap(int i, int n)
{
    return i < 0 ? i + n : (i >= n ? i - n : i);
}

/* 1 if the circular distance between indices i and c on an axis of n is <= r. */
static int ref_near(int i, int c, int n, int r)
{
    int d = ref_shift_of(ref_wrap(i - c + n, n), n);
    return d >= -r && d <= r;
}

/* 1 if plane(i, j) is >= its 8 circular neighbours. */
static int ref_local_max(const float *p, int w, int h, int i, int j)
{
    const float *row = p + (size_t)j * (size_t)w;
    float v = row[i];
    if (i > 0 && i < w - 1 && j > 0 && j < h - 1) {
        const float *up = row - w, *dn = row + w;
        return v >= row[i - 1] && v >= row[i + 1] && v >= up[i - 1] && v >= up[i] &&
               v >= up[i + 1] && v >= dn[i - 1] && v >= dn[i] && v >= dn[i + 1];
    }
    for (int dj = -1; dj <= 1; dj++) {
        const float *r = p + (size_t)ref_wrap(j + dj, h) * (size_t)w;
        for (int di = -1; di <= 1; di++)
            if ((di || dj) && r[ref_wrap(i + di, w)] > v)
                return 0;
    }
    return 1;
}

static void ref_centroid3x3(const float *p, int w, int h, int i, int j, double *dx, double *dy,
                            int *ok)
{
    double s = 0, sx = 0, sy = 0;
    for (int dj = -1; dj <= 1; dj++)
        for (int di = -1; di <= 1; di++) {
            double c =
                (double)p[(size_t)ref_wrap(j + dj, h) * (size_t)w + (size_t)ref_wrap(i + di, w)];
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

/* Column maxima: cm[i] = max over the rows j of [j0, j1) (taken modulo h) of plane(i, j),
 * for the columns of the segments [a0, a1) and [b0, b1); element-wise over whole rows, so
 * the compiler vectorises it, instead of one serial chain of compares. */
RPIV_KERNEL static void ref_colmax_rows(const float *plane, int w, int h, int j0, int j1, int a0,
                                        int a1, int b0, int b1, float *cm)
{
    for (int jj = j0; jj < j1; jj++) {
        const float *row = plane + (size_t)ref_wrap(jj % h, h) * (size_t)w;
        for (int i = a0; i < a1; i++)
            cm[i] = row[i] > cm[i] ? row[i] : cm[i];
        for (int i = b0; i < b1; i++)
            cm[i] = row[i] > cm[i] ? row[i] : cm[i];
    }
}

/* The largest of v[0..n-1] and its first index (-1 if none). */
static float ref_max_index(const float *v, int n, int *at)
{
    float m = -INFINITY;
    *at = -1;
    for (int i = 0; i < n; i++)
        if (v[i] > m) {
            m = v[i];
            *at = i;
        }
    return m;
}

/* The indices of an axis of n whose shift is within -r..r (all if r <= 0), in index order. */
static int ref_axis_indices(int n, int r, int *idx)
{
    int m = 0;
    for (int i = 0; i < n; i++) {
        int s = ref_shift_of(i, n);
        if (r <= 0 || (s >= -r && s <= r))
            idx[m++] = i;
    }
    return m;
}

static void peak_find_ref(const float *plane, int w, int h, int max_shift, rpiv_subpixel method,
                          rpiv_peak *out)
{
    int full = max_shift <= 0 || (max_shift >= w / 2 && max_shift >= h / 2);
    int rows[4096], cols[4096], nr = h, nc = w;
    if (!full) {
        nr = ref_axis_indices(h, max_shift, rows);
        nc = ref_axis_indices(w, max_shift, cols);
    }
    /* highest value; on ties the lowest column, then the lowest row */
    int bi = -1, bj = -1;
    float best = -INFINITY;
    float cm[4096];
    if (full) {
        /* column maxima, then the best column, then its first row holding the maximum */
        for (int i = 0; i < w; i++)
            cm[i] = -INFINITY;
        ref_colmax_rows(plane, w, h, 0, h, 0, w, 0, 0, cm);
        best = ref_max_index(cm, w, &bi);
        for (int j = 0; j < h && bi >= 0; j++)
            if (plane[(size_t)j * (size_t)w + (size_t)bi] == best) {
                bj = j;
                break;
            }
    } else {
        for (int jj = 0; jj < nr; jj++) {
            const float *row = plane + (size_t)rows[jj] * (size_t)w;
            for (int ii = 0; ii < nc; ii++)
                if (row[cols[ii]] > best) {
                    best = row[cols[ii]];
                    bi = cols[ii];
                    bj = rows[jj];
                }
        }
    }
    *out = (rpiv_peak){0};
    out->ratio = RPIV_PEAK_RATIO_MAX;
    if (bi < 0 || !isfinite(best))
        return;
    out->ix = ref_shift_of(bi, w);
    out->iy = ref_shift_of(bj, h);
    out->value = best;

    double fx = 0, fy = 0;
    int okx = 0, oky = 0;
    if (method == RPIV_SUBPIXEL_CENTROID) {
        ref_centroid3x3(plane, w, h, bi, bj, &fx, &fy, &okx);
        oky = okx;
    } else {
        const float *row = plane + (size_t)bj * (size_t)w;
        fx = ref_fit3((double)row[ref_wrap(bi - 1, w)], (double)best,
                      (double)row[ref_wrap(bi + 1, w)], method, &okx);
        fy = ref_fit3(
            (double)plane[(size_t)ref_wrap(bj - 1, h) * (size_t)w + (size_t)bi], (double)best,
            (double)plane[(size_t)ref_wrap(bj + 1, h) * (size_t)w + (size_t)bi], method, &oky);
    }
    out->fit_ok = okx && oky;
    out->dx = out->ix + (out->fit_ok ? fx : 0);
    out->dy = out->iy + (out->fit_ok ? fy : 0);

    /* second peak: the highest local maximum outside the first peak's neighbourhood. The
     * highest value outside it usually is one (a noise peak); if not, every value above the
     * best local maximum so far is examined. */
    const int ex = RPIV_PEAK_EXCLUDE;
    float second = -INFINITY;
    int done = 0;
    if (full && 2 * ex + 1 < h) {
        /* column maxima over the rows away from the first peak, and over the rows near it
         * but only in the columns away from it */
        for (int i = 0; i < w; i++)
            cm[i] = -INFINITY;
        ref_colmax_rows(plane, w, h, bj + ex + 1, bj + h - ex, 0, w, 0, 0, cm);
        if (2 * ex + 1 < w) {
            int lo = bi - ex, hi = bi + ex + 1; /* excluded columns: [lo, hi) modulo w */
            int a0 = 0, a1 = lo, b0 = hi, b1 = w;
            if (lo < 0)
                a0 = a1 = 0, b0 = hi, b1 = lo + w;
            else if (hi > w)
                a0 = hi - w, a1 = lo, b0 = b1 = 0;
            ref_colmax_rows(plane, w, h, bj - ex + h, bj + ex + 1 + h, a0, a1, b0, b1, cm);
        }
        int i2, j2 = -1;
        float m2 = ref_max_index(cm, w, &i2);
        for (int j = 0; j < h && i2 >= 0; j++)
            if (plane[(size_t)j * (size_t)w + (size_t)i2] == m2 &&
                !(ref_near(j, bj, h, ex) && ref_near(i2, bi, w, ex))) {
                j2 = j;
                break;
            }
        if (j2 < 0) {
            done = 1; /* nothing outside the neighbourhood */
        } else if (ref_local_max(plane, w, h, i2, j2)) {
            second = m2;
            done = 1;
        }
    }
    for (int jj = 0; jj < nr && !done; jj++) {
        int j = full ? jj : rows[jj];
        int ny = ref_near(j, bj, h, ex);
        const float *row = plane + (size_t)j * (size_t)w;
        for (int ii = 0; ii < nc; ii++) {
            int i = full ? ii : cols[ii];
            if (!(row[i] > second) || (ny && ref_near(i, bi, w, ex)) ||
                !ref_local_max(plane, w, h, i, j))
                continue;
            second = row[i];
        }
    }
    int found = second > -INFINITY;
    out->second = found ? second : 0;
    if (found && second > 0 && best < RPIV_PEAK_RATIO_MAX * second)
        out->ratio = best / second;
}

/* 1 if a and b hold the same bits in every field (padding ignored). */
static int peak_same(const rpiv_peak *a, const rpiv_peak *b)
{
    return !memcmp(&a->dx, &b->dx, sizeof a->dx) && !memcmp(&a->dy, &b->dy, sizeof a->dy) &&
           a->ix == b->ix && a->iy == b->iy && !memcmp(&a->value, &b->value, sizeof a->value) &&
           !memcmp(&a->second, &b->second, sizeof a->second) &&
           !memcmp(&a->ratio, &b->ratio, sizeof a->ratio) && a->fit_ok == b->fit_ok;
}

#endif /* RPIV_TESTS_PEAK_REF_H */
