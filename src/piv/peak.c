/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/peak.c - correlation peak search, sub-pixel fits, second peak and peak ratio. */
#include "rpiv/peak.h"

#include "peak_impl.h"

#include "base/simd.h"

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#if defined(__SSE__)
#include <xmmintrin.h>
#endif

/* Four floats in a vector register (GCC/Clang vector extension; SSE2 on x86-64, NEON on
 * arm64), for the short maxima the compiler does not vectorise by itself. */
typedef float v4f __attribute__((vector_size(16)));
typedef int32_t v4i __attribute__((vector_size(16)));

static inline v4f load4(const float *p)
{
    v4f v;
    memcpy(&v, p, sizeof v);
    return v;
}

/* Lane by lane r > m ? r : m: a NaN in r never enters, as in the scalar form. SSE's maxps
 * is exactly that (its first operand if greater, else the second). */
static inline v4f vmax(v4f r, v4f m)
{
#if defined(__SSE__)
    return (v4f)_mm_max_ps((__m128)r, (__m128)m);
#else
    v4i k = r > m;
    return (v4f)((k & (v4i)r) | (~k & (v4i)m));
#endif
}

rpiv_subpixel rpiv_subpixel_resolve(rpiv_subpixel method, int ensemble)
{
    if (method != RPIV_SUBPIXEL_AUTO)
        return method;
    return ensemble ? RPIV_SUBPIXEL_SPLINE : RPIV_SUBPIXEL_GAUSS;
}

double rpiv_peak_fit3(double cm, double c0, double cp, rpiv_subpixel method, int *ok)
{
    *ok = 0;
    if (method == RPIV_SUBPIXEL_SPLINE || method == RPIV_SUBPIXEL_AUTO)
        method = RPIV_SUBPIXEL_GAUSS;
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

/* 1 if the circular distance between indices i and c on an axis of n is <= r. */
static int near(int i, int c, int n, int r)
{
    int d = shift_of(wrap(i - c + n, n), n);
    return d >= -r && d <= r;
}

/* 1 if plane(i, j) is >= its 8 circular neighbours. */
static int local_max(const float *p, int w, int h, int i, int j)
{
    const float *row = p + (size_t)j * (size_t)w;
    float v = row[i];
    if (i > 0 && i < w - 1 && j > 0 && j < h - 1) {
        const float *up = row - w, *dn = row + w;
        return v >= row[i - 1] && v >= row[i + 1] && v >= up[i - 1] && v >= up[i] &&
               v >= up[i + 1] && v >= dn[i - 1] && v >= dn[i] && v >= dn[i + 1];
    }
    for (int dj = -1; dj <= 1; dj++) {
        const float *r = p + (size_t)wrap(j + dj, h) * (size_t)w;
        for (int di = -1; di <= 1; di++)
            if ((di || dj) && r[wrap(i + di, w)] > v)
                return 0;
    }
    return 1;
}

static void centroid3x3(const float *p, int w, int h, int i, int j, double *dx, double *dy, int *ok)
{
    double s = 0, sx = 0, sy = 0;
    for (int dj = -1; dj <= 1; dj++)
        for (int di = -1; di <= 1; di++) {
            double c = (double)p[(size_t)wrap(j + dj, h) * (size_t)w + (size_t)wrap(i + di, w)];
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

/* Column maxima over every row: cm[i] = the first of the largest values of column i (rows in
 * order; NaNs never enter; -inf if none), element-wise over whole rows so that the compiler
 * vectorises it. The usual widths get their own copy with the width known (the maxima then
 * stay in registers). */
static inline void colmax_w(const float *restrict plane, int w, int h, float *restrict cm)
{
    for (int i = 0; i < w; i++)
        cm[i] = -INFINITY;
    for (int j = 0; j < h; j++) {
        const float *row = plane + (size_t)j * (size_t)w;
        for (int i = 0; i < w; i++)
            cm[i] = row[i] > cm[i] ? row[i] : cm[i];
    }
}

RPIV_KERNEL static void colmax_all(const float *restrict plane, int w, int h, float *restrict cm)
{
    if (w == 32)
        colmax_w(plane, 32, h, cm);
    else if (w == 64)
        colmax_w(plane, 64, h, cm);
    else
        colmax_w(plane, w, h, cm);
}

/* The largest of v[0..n-1] (no NaN) and its first index; -inf and -1 if all are -inf. The
 * largest by lanes (vectorised), then the first element equal to it, returned as stored (of
 * +0 and -0, the one the search found first, as a serial search would). */
static float max_index(const float *v, int n, int *at)
{
    const v4f ninf = {-INFINITY, -INFINITY, -INFINITY, -INFINITY};
    v4f a = ninf, b = ninf;
    int i = 0;
    for (; i + 8 <= n; i += 8) {
        a = vmax(load4(v + i), a);
        b = vmax(load4(v + i + 4), b);
    }
    a = vmax(b, a);
    float m = -INFINITY;
    for (int k = 0; k < 4; k++)
        m = a[k] > m ? a[k] : m;
    for (; i < n; i++)
        m = v[i] > m ? v[i] : m;
    *at = -1;
    if (!(m > -INFINITY))
        return m;
    for (i = 0; v[i] != m; i++)
        ;
    *at = i;
    return v[i];
}

/* The indices of an axis of n whose shift is within -r..r (all if r <= 0), in index order. */
static int axis_indices(int n, int r, int *idx)
{
    int m = 0;
    for (int i = 0; i < n; i++) {
        int s = shift_of(i, n);
        if (r <= 0 || (s >= -r && s <= r))
            idx[m++] = i;
    }
    return m;
}

/* 3-point fit of method in x and in y through (bi, bj) of value best (finite); the Gaussian
 * fit takes log(best) once for both axes (rpiv_peak_fit3's operations otherwise). */
static void fit_xy(const float *plane, int w, int h, int bi, int bj, float best,
                   rpiv_subpixel method, double *fx, double *fy, int *okx, int *oky)
{
    const float *row = plane + (size_t)bj * (size_t)w;
    double c[2][3] = {{(double)row[wrap(bi - 1, w)], (double)best, (double)row[wrap(bi + 1, w)]},
                      {(double)plane[(size_t)wrap(bj - 1, h) * (size_t)w + (size_t)bi],
                       (double)best,
                       (double)plane[(size_t)wrap(bj + 1, h) * (size_t)w + (size_t)bi]}};
    double *f[2] = {fx, fy}, l0 = 0;
    int *ok[2] = {okx, oky}, have_l0 = 0;
    for (int a = 0; a < 2; a++) {
        double cm = c[a][0], c0 = c[a][1], cp = c[a][2];
        *ok[a] = 0;
        *f[a] = 0;
        if (method != RPIV_SUBPIXEL_GAUSS || !isfinite(cm) || !isfinite(cp) || !(cm > 0) ||
            !(c0 > 0) || !(cp > 0)) {
            *f[a] = rpiv_peak_fit3(cm, c0, cp, method, ok[a]);
            continue;
        }
        if (!have_l0) {
            l0 = log(c0);
            have_l0 = 1;
        }
        double lm = log(cm), lp = log(cp), den = 2 * (lm - 2 * l0 + lp);
        if (!(den < 0))
            continue;
        *ok[a] = 1;
        *f[a] = (lm - lp) / den;
    }
}

/* The second peak by the definition: the highest local maximum outside the first peak's
 * neighbourhood, over the rows rows[0..nr-1] and columns cols[0..nc-1] (all if full), in
 * raster order (of equal values, the first). -inf if none. */
static float second_scan(const float *plane, int w, int h, int bi, int bj, int full,
                         const int *rows, int nr, const int *cols, int nc)
{
    const int ex = RPIV_PEAK_EXCLUDE;
    float second = -INFINITY;
    for (int jj = 0; jj < nr; jj++) {
        int j = full ? jj : rows[jj];
        int ny = near(j, bj, h, ex);
        const float *row = plane + (size_t)j * (size_t)w;
        for (int ii = 0; ii < nc; ii++) {
            int i = full ? ii : cols[ii];
            if (!(row[i] > second) || (ny && near(i, bi, w, ex)) || !local_max(plane, w, h, i, j))
                continue;
            second = row[i];
        }
    }
    return second;
}

/* m[l] = the largest value of column s0 + l, m[4 + l] that of column s1 + l (l < 4), over the
 * rows away from row bj (circular distance > ex); -inf if none. Two rows at a time into two
 * sets of lanes (two chains of maxima). */
static void far_max8(const float *plane, int w, int h, int bj, int s0, int s1, float *m)
{
    const int ex = RPIV_PEAK_EXCLUDE;
    const v4f ninf = {-INFINITY, -INFINITY, -INFINITY, -INFINITY};
    v4f a0 = ninf, a1 = ninf, b0 = ninf, b1 = ninf;
    for (int k = ex + 1; k < h - ex; k += 2) {
        int j0 = bj + k < h ? bj + k : bj + k - h, j1 = j0 + 1 < h ? j0 + 1 : 0;
        if (k + 1 == h - ex)
            j1 = j0; /* the last row, odd one out: again into b */
        const float *r0 = plane + (size_t)j0 * (size_t)w, *r1 = plane + (size_t)j1 * (size_t)w;
        a0 = vmax(load4(r0 + s0), a0);
        a1 = vmax(load4(r0 + s1), a1);
        b0 = vmax(load4(r1 + s0), b0);
        b1 = vmax(load4(r1 + s1), b1);
    }
    a0 = vmax(b0, a0);
    a1 = vmax(b1, a1);
    memcpy(m, &a0, sizeof a0);
    memcpy(m + 4, &a1, sizeof a1);
}

/* The second peak of the whole plane (2 ex + 1 < h), the first peak at (bi, bj); cm holds
 * the column maxima over all rows and is overwritten. The result, bit for bit, of the search
 * this replaced (tests/test_peak_ref.h): the highest value m2 outside the neighbourhood,
 * from column maxima over the rows away from the first peak, then over the near rows in the
 * columns away from it (as that search took them: of +0 and -0, the first in that order),
 * if the first place holding it is a local maximum; otherwise second_scan's value. */
static float second_full(const float *plane, int w, int h, int bi, int bj, float *cm)
{
    const int ex = RPIV_PEAK_EXCLUDE, nx = 2 * ex + 1 < w ? 2 * ex + 1 : w;
    /* the maxima outside the neighbourhood: in the columns of the neighbourhood (all of them
     * if w <= 2 ex + 1), over the rows away from it; elsewhere, the column maxima */
    int xc[2 * RPIV_PEAK_EXCLUDE + 1];
    for (int d = 0; d < nx; d++)
        xc[d] = nx < w ? wrap(bi - ex + d, w) : d;
    if (nx < w && w >= 8) {
        /* the excluded columns lie in the 8 from s0, or (wrapping) in the first and last 4 */
        float mf[8];
        int wraps = bi - ex < 0 || bi + ex >= w, s0 = bi - ex < w - 8 ? bi - ex : w - 8;
        if (wraps)
            s0 = 0;
        int s1 = wraps ? w - 4 : s0 + 4;
        far_max8(plane, w, h, bj, s0, s1, mf);
        for (int d = 0; d < nx; d++)
            cm[xc[d]] = xc[d] - s0 < 4 ? mf[xc[d] - s0] : mf[4 + xc[d] - s1];
    } else {
        for (int d = 0; d < nx; d++)
            cm[xc[d]] = -INFINITY;
        for (int k = ex + 1; k < h - ex; k++) {
            const float *row = plane + (size_t)wrap(bj + k - h, h) * (size_t)w;
            for (int d = 0; d < nx; d++)
                cm[xc[d]] = row[xc[d]] > cm[xc[d]] ? row[xc[d]] : cm[xc[d]];
        }
    }
    int i2, j2 = -1;
    float m2 = max_index(cm, w, &i2);
    if (i2 < 0)
        return -INFINITY;
    int xi2 = near(i2, bi, w, ex);
    for (int j = 0; j < h; j++)
        if (plane[(size_t)j * (size_t)w + (size_t)i2] == m2 && !(xi2 && near(j, bj, h, ex))) {
            j2 = j;
            break;
        }
    if (j2 < 0)
        return -INFINITY; /* not reached: m2 is a value outside the neighbourhood */
    if (local_max(plane, w, h, i2, j2)) {
        if (m2 == 0) { /* the first zero of the column from the row after the neighbourhood */
            int n = xi2 ? h - 2 * ex - 1 : h;
            for (int k = 0; k < n; k++) {
                float v = plane[(size_t)((bj + ex + 1 + k) % h) * (size_t)w + (size_t)i2];
                if (v == m2)
                    return v;
            }
        }
        return m2;
    }
    /* m2 is on the flank of the first peak. Some local maximum of value t: the largest value
     * of the next columns, by decreasing column maximum; then every value >= t outside the
     * neighbourhood, in the columns whose maximum reaches t, is a candidate. When w <= 2 ex +
     * 1, cm holds the maxima over the far rows in every column, but one column of a plane 5
     * wide is not near the first peak's (shift_of(2, 5) is -3): the plain search then. */
    if (nx == w)
        return second_scan(plane, w, h, bi, bj, 1, NULL, h, NULL, w);
    float t = -INFINITY, held[8];
    int tried[8], ntried = 0, c = i2;
    while (ntried < 8 && !(t > -INFINITY)) {
        held[ntried] = cm[c]; /* set aside while the next column is sought */
        tried[ntried++] = c;
        cm[c] = -INFINITY;
        float v = max_index(cm, w, &c);
        if (c < 0)
            break;
        int xcol = near(c, bi, w, ex);
        for (int j = 0; j < h; j++)
            if (plane[(size_t)j * (size_t)w + (size_t)c] == v && !(xcol && near(j, bj, h, ex))) {
                if (local_max(plane, w, h, c, j))
                    t = v;
                break;
            }
    }
    while (ntried > 0) {
        ntried--;
        cm[tried[ntried]] = held[ntried];
    }
    if (!(t > -INFINITY))
        return second_scan(plane, w, h, bi, bj, 1, NULL, h, NULL, w);
    float best = -INFINITY;
    int sj = h;
    for (int i = 0; i < w; i++) {
        if (!(cm[i] >= t))
            continue;
        int xcol = near(i, bi, w, ex);
        for (int j = 0; j < h; j++) {
            float v = plane[(size_t)j * (size_t)w + (size_t)i];
            if (!(v >= t) || (xcol && near(j, bj, h, ex)) || !local_max(plane, w, h, i, j))
                continue;
            /* of equal values the first in raster order (the columns come in order) */
            if (v > best || (v == best && j < sj)) {
                best = v;
                sj = j;
            }
        }
    }
    return best;
}

/* The highest local maximum of the plane among shifts within -r..r on both axes (of equal
 * values the first in raster order); -inf and *bi = *bj = -1 if there is none. */
static float near_max(const float *plane, int w, int h, int r, int *bi, int *bj)
{
    int rows[RPIV_PEAK_MAX_SIZE], cols[RPIV_PEAK_MAX_SIZE];
    const int nr = axis_indices(h, r, rows), nc = axis_indices(w, r, cols);
    float best = -INFINITY;
    *bi = *bj = -1;
    for (int jj = 0; jj < nr; jj++) {
        const float *row = plane + (size_t)rows[jj] * (size_t)w;
        for (int ii = 0; ii < nc; ii++)
            if (row[cols[ii]] > best && local_max(plane, w, h, cols[ii], rows[jj])) {
                best = row[cols[ii]];
                *bi = cols[ii];
                *bj = rows[jj];
            }
    }
    return best;
}

int peak_fit_at(const float *plane, int w, int h, int bi, int bj, rpiv_subpixel method, double *fx,
                double *fy)
{
    const float best = plane[(size_t)bj * (size_t)w + (size_t)bi];
    int okx = 0, oky = 0;
    *fx = *fy = 0;
    if (method == RPIV_SUBPIXEL_AUTO)
        method = RPIV_SUBPIXEL_GAUSS;
    if (method == RPIV_SUBPIXEL_CENTROID) {
        centroid3x3(plane, w, h, bi, bj, fx, fy, &okx);
        oky = okx;
    } else if (method == RPIV_SUBPIXEL_SPLINE) {
        /* the 3-point Gaussian, the start of the spline's search and its fallback */
        fit_xy(plane, w, h, bi, bj, best, RPIV_SUBPIXEL_GAUSS, fx, fy, &okx, &oky);
        double sx, sy;
        if (peak_fit_spline(plane, w, h, bi, bj, okx ? *fx : 0, oky ? *fy : 0, &sx, &sy)) {
            *fx = sx;
            *fy = sy;
            okx = oky = 1;
        }
    } else {
        fit_xy(plane, w, h, bi, bj, best, method, fx, fy, &okx, &oky);
    }
    if (!(okx && oky))
        *fx = *fy = 0;
    return okx && oky;
}

/* rpiv_peak_find, with the column maxima colmax of the plane given (full plane) or not;
 * near > 0: rpiv_peak_find_near's choice of the peak. */
static void peak_find(const float *plane, int w, int h, int max_shift, int near_r,
                      const float *colmax, rpiv_subpixel method, rpiv_peak *out)
{
    if (w < 3 || h < 3 || w > RPIV_PEAK_MAX_SIZE || h > RPIV_PEAK_MAX_SIZE) {
        *out = (rpiv_peak){0};
        out->ratio = RPIV_PEAK_RATIO_MAX;
        return; /* outside the documented sizes: no peak */
    }
    int full = max_shift <= 0 || (max_shift >= w / 2 && max_shift >= h / 2);
    int rows[RPIV_PEAK_MAX_SIZE], cols[RPIV_PEAK_MAX_SIZE], nr = h, nc = w;
    if (!full) {
        nr = axis_indices(h, max_shift, rows);
        nc = axis_indices(w, max_shift, cols);
    }
    /* highest value; on ties the lowest column, then the lowest row */
    int bi = -1, bj = -1;
    float best = -INFINITY;
    float cm[RPIV_PEAK_MAX_SIZE];
    if (full) {
        /* column maxima, then the best column, then its first row holding the maximum */
        if (colmax)
            memcpy(cm, colmax, (size_t)w * sizeof *cm);
        else
            colmax_all(plane, w, h, cm);
        best = max_index(cm, w, &bi);
        for (int j = 0; j < h && bi >= 0; j++)
            if (plane[(size_t)j * (size_t)w + (size_t)bi] == best) {
                bj = j;
                break;
            }
        /* near: the highest value, if it lies within the radius, is the highest local
         * maximum there (the plane's own choice, at no cost); otherwise look there */
        if (near_r > 0 && bi >= 0 && bj >= 0 &&
            (abs(shift_of(bi, w)) > near_r || abs(shift_of(bj, h)) > near_r)) {
            int ni, nj;
            float nb = near_max(plane, w, h, near_r, &ni, &nj);
            if (ni >= 0) {
                best = nb;
                bi = ni;
                bj = nj;
            }
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
    if (method == RPIV_SUBPIXEL_AUTO)
        method = RPIV_SUBPIXEL_GAUSS;
    if (bi < 0 || !isfinite(best))
        return;
    out->ix = shift_of(bi, w);
    out->iy = shift_of(bj, h);
    out->value = best;

    double fx, fy;
    out->fit_ok = peak_fit_at(plane, w, h, bi, bj, method, &fx, &fy);
    out->dx = out->ix + fx;
    out->dy = out->iy + fy;

    /* second peak: the highest local maximum outside the first peak's neighbourhood */
    float second;
    if (full && 2 * RPIV_PEAK_EXCLUDE + 1 < h)
        second = second_full(plane, w, h, bi, bj, cm);
    else
        second =
            second_scan(plane, w, h, bi, bj, full, full ? NULL : rows, nr, full ? NULL : cols, nc);
    int found = second > -INFINITY;
    out->second = found ? second : 0;
    if (found && second > 0 && best < RPIV_PEAK_RATIO_MAX * second)
        out->ratio = best / second;
}

void rpiv_peak_find(const float *plane, int w, int h, int max_shift, rpiv_subpixel method,
                    rpiv_peak *out)
{
    peak_find(plane, w, h, max_shift, 0, NULL, method, out);
}

void rpiv_peak_find_cm(const float *plane, int w, int h, const float *colmax, rpiv_subpixel method,
                       rpiv_peak *out)
{
    peak_find(plane, w, h, 0, 0, colmax, method, out);
}

void rpiv_peak_find_near(const float *plane, int w, int h, int radius, const float *colmax,
                         rpiv_subpixel method, rpiv_peak *out)
{
    peak_find(plane, w, h, 0, radius, colmax, method, out);
}
