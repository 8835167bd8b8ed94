/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/validate.c - normalised median test and median replacement. */
#include "rpiv/validate.h"

#include "validate_impl.h"

#include <math.h>
#include <omp.h>
#if defined(__SSE__)
#include <xmmintrin.h>
#endif
#include <stdlib.h>
#include <string.h>

/* min and max of two floats as single instructions where SSE is there: written as
 * conditionals, GCC turns the network's compare-exchanges back into branches. */
#if defined(__SSE__)
static inline float min2(float a, float b)
{
    return _mm_cvtss_f32(_mm_min_ss(_mm_set_ss(a), _mm_set_ss(b)));
}
static inline float max2(float a, float b)
{
    return _mm_cvtss_f32(_mm_max_ss(_mm_set_ss(a), _mm_set_ss(b)));
}
#else
static inline float min2(float a, float b)
{
    return b < a ? b : a;
}
static inline float max2(float a, float b)
{
    return b < a ? a : b;
}
#endif

/* One comparator of a sorting network on locals: a <= b afterwards. */
#define CSWAP(a, b)                                                                                \
    do {                                                                                           \
        float lo_ = min2(a, b), hi_ = max2(a, b);                                                  \
        a = lo_;                                                                                   \
        b = hi_;                                                                                   \
    } while (0)

/* Median of v[0..n-1] (n <= 8, reordered in place). A full neighbourhood (n = 8, nearly every
 * vector) goes through the optimal 19-comparator sorting network, branch-free, instead of an
 * insertion sort's unpredictable branches: the same sorted values (fields hold no NaN), hence
 * the same median. */
static double median(float *v, int n)
{
    if (n == 8) {
        float a0 = v[0], a1 = v[1], a2 = v[2], a3 = v[3], a4 = v[4], a5 = v[5], a6 = v[6],
              a7 = v[7];
        CSWAP(a0, a2);
        CSWAP(a1, a3);
        CSWAP(a4, a6);
        CSWAP(a5, a7);
        CSWAP(a0, a4);
        CSWAP(a1, a5);
        CSWAP(a2, a6);
        CSWAP(a3, a7);
        CSWAP(a0, a1);
        CSWAP(a2, a3);
        CSWAP(a4, a5);
        CSWAP(a6, a7);
        CSWAP(a2, a4);
        CSWAP(a3, a5);
        CSWAP(a1, a4);
        CSWAP(a3, a6);
        CSWAP(a1, a2);
        CSWAP(a3, a4);
        CSWAP(a5, a6);
        return 0.5 * ((double)a3 + (double)a4);
    }
    for (int i = 1; i < n; i++) {
        float x = v[i];
        int j = i - 1;
        for (; j >= 0 && v[j] > x; j--)
            v[j + 1] = v[j];
        v[j + 1] = x;
    }
    return n % 2 ? (double)v[n / 2] : 0.5 * ((double)v[n / 2 - 1] + (double)v[n / 2]);
}

/* Value of the neighbour (ii, jj) of (i, j): the vector itself when inside the grid and
 * usable; beyond the grid's edge the point-symmetric extrapolation 2 U(E) - U(M), with E the
 * in-grid point nearest to it and M its mirror image through E, when both are usable and E
 * is not (i, j) itself. Returns 0 when there is no value. */
static int neighbour(const rpiv_field *f, const unsigned char *ok, int i, int j, int ii, int jj,
                     float *u, float *v)
{
    const int nx = f->nx, ny = f->ny;
    if (ii >= 0 && jj >= 0 && ii < nx && jj < ny) {
        size_t q = (size_t)jj * (size_t)nx + (size_t)ii;
        if (ok[q] != 1)
            return 0;
        *u = f->u[q];
        *v = f->v[q];
        return 1;
    }
    int ei = ii < 0 ? 0 : (ii >= nx ? nx - 1 : ii);
    int ej = jj < 0 ? 0 : (jj >= ny ? ny - 1 : jj);
    int mi = 2 * ei - ii, mj = 2 * ej - jj;
    if ((ei == i && ej == j) || mi < 0 || mj < 0 || mi >= nx || mj >= ny)
        return 0;
    size_t e = (size_t)ej * (size_t)nx + (size_t)ei, q = (size_t)mj * (size_t)nx + (size_t)mi;
    if (ok[e] != 1 || ok[q] != 1)
        return 0;
    *u = 2 * f->u[e] - f->u[q];
    *v = 2 * f->v[e] - f->v[q];
    return 1;
}

/* The neighbourhood of (i, j) (ok[k] == 1: usable) into nu/nv; returns the count.
 * Inside the grid it is the usable vectors of the 3 x 3 block (Westerweel & Scarano). At an
 * edge the block is completed by extrapolation (see neighbour()) and a vector is used only if
 * its point-symmetric partner about (i, j) is there too: the neighbourhood stays balanced,
 * so a linear velocity gradient across the edge does not move its median. (Without this,
 * the median of a one-sided neighbourhood is the value half a grid step inside, and the
 * edge vectors of a steep profile are all rejected.) */
static int gather(const rpiv_field *f, const unsigned char *ok, int i, int j, float *nu, float *nv)
{
    const int nx = f->nx, ny = f->ny;
    int m = 0;
    for (int dj = -1; dj <= 1; dj++)
        for (int di = -1; di <= 1; di++) {
            if (!di && !dj)
                continue;
            int ii = i + di, jj = j + dj, pi = i - di, pj = j - dj;
            int inside = ii >= 0 && jj >= 0 && ii < nx && jj < ny;
            int partner_out = pi < 0 || pj < 0 || pi >= nx || pj >= ny;
            float u, v, pu, pv;
            if (!neighbour(f, ok, i, j, ii, jj, &u, &v))
                continue;
            if (inside && partner_out && !neighbour(f, ok, i, j, pi, pj, &pu, &pv))
                continue;
            nu[m] = u;
            nv[m] = v;
            m++;
        }
    return m;
}

/* Normalised residual of component c0 against neighbours nb[0..n-1]; *rm_out gets rm. */
static double residual_rm(double c0, const float *nb, int n, double eps, double *rm_out)
{
    float tmp[8], r[8];
    memcpy(tmp, nb, (size_t)n * sizeof *tmp);
    double um = median(tmp, n);
    for (int i = 0; i < n; i++)
        r[i] = (float)fabs((double)nb[i] - um);
    double rm = median(r, n);
    *rm_out = rm;
    return fabs(c0 - um) / (rm + eps);
}

static double residual(double c0, const float *nb, int n, double eps)
{
    double rm;
    return residual_rm(c0, nb, n, eps, &rm);
}

/* The mean absolute deviation of nb[0..n-1] from their median. */
static double spread_of(const float *nb, int n)
{
    float tmp[8];
    memcpy(tmp, nb, (size_t)n * sizeof *tmp);
    const double um = median(tmp, n);
    double s = 0;
    for (int i = 0; i < n; i++)
        s += fabs((double)nb[i] - um);
    return s / n;
}

/* Does the vector (i, j) agree with its neighbours along the grid line (a row, a column or a
 * diagonal) on which the field varies least? A line's neighbourhood is the usable vectors 1
 * and 2 steps either way (at least 2 of them: a line cut by the grid's edge keeps 2); the line
 * chosen is the one whose neighbours scatter least about their median (mean absolute
 * deviation of u plus that of v; the first in the order row, column, diagonals on a tie), and
 * the vector is tested against it as against the block. (The median deviation rm chose
 * badly: a diagonal of 3 across a shear layer, two of them on its zero crossings, has a small
 * rm and a large mean deviation; at the grid's edges, where rows had only 2 members, the
 * extrema of a shear were rejected and replaced by such a diagonal's median, 0.) A vector
 * that fails the block's test but agrees with the most uniform line sits on a ridge or a
 * trough of the flow, not off it: a shear layer sampled with only a few vectors per
 * wavelength, whose extrema the block's median (taken across the layer) calls outliers. An
 * outlier agrees with no line; a line across the layer, along which the field swings, is never
 * the one chosen where a line along the layer is there. */
static int best_line(const rpiv_field *f, const unsigned char *ok, int i, int j, double eps,
                     double *ru, double *rv, float *mu, float *mv)
{
    static const int dir[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
    const int nx = f->nx, ny = f->ny;
    const size_t k = (size_t)j * (size_t)nx + (size_t)i;
    double best = (double)INFINITY;
    for (int d = 0; d < 4; d++) {
        float nu[4], nv[4];
        int m = 0;
        for (int s = -2; s <= 2; s++) {
            int ii = i + s * dir[d][0], jj = j + s * dir[d][1];
            if (!s || ii < 0 || jj < 0 || ii >= nx || jj >= ny)
                continue;
            size_t q = (size_t)jj * (size_t)nx + (size_t)ii;
            if (ok[q] != 1)
                continue;
            nu[m] = f->u[q];
            nv[m] = f->v[q];
            m++;
        }
        if (m < 2)
            continue;
        double rmu, rmv, r_u = residual_rm((double)f->u[k], nu, m, eps, &rmu),
                         r_v = residual_rm((double)f->v[k], nv, m, eps, &rmv);
        const double spread = spread_of(nu, m) + spread_of(nv, m);
        if (spread < best) {
            best = spread;
            *ru = r_u;
            *rv = r_v;
            *mu = (float)median(nu, m);
            *mv = (float)median(nv, m);
        }
    }
    return best < (double)INFINITY;
}

static int agrees_along_a_line(const rpiv_field *f, const unsigned char *ok, int i, int j,
                               double threshold, double eps)
{
    double ru = 0, rv = 0;
    float mu = 0, mv = 0;
    return best_line(f, ok, i, j, eps, &ru, &rv, &mu, &mv) && ru <= threshold && rv <= threshold;
}

rpiv_status rpiv_validate_median(rpiv_field *f, double threshold, double eps, size_t *nrejected)
{
    return validate_median_nt(f, threshold, eps, 0, nrejected, 0);
}

rpiv_status validate_median_nt(rpiv_field *f, double threshold, double eps, int lines,
                               size_t *nrejected, int nthreads)
{
    if (nrejected)
        *nrejected = 0;
    if (!(threshold > 0) || !(eps >= 0))
        return rpiv_fail(RPIV_EINVAL, "validate: threshold %g must be > 0 and eps %g >= 0",
                         threshold, eps);
    const int nx = f->nx, ny = f->ny;
    size_t n = (size_t)nx * (size_t)ny, count = 0;
    unsigned char *rej = calloc(2 * n, 1);
    if (!rej)
        return rpiv_fail(RPIV_ENOMEM, "validate: out of memory");
    unsigned char *ok = rej + n;
    for (size_t k = 0; k < n; k++)
        ok[k] = f->flag[k] == RPIV_FLAG_VALID;
    /* each vector's test reads the flags of its neighbours only: rows in parallel, the same
     * result. Rounds: a vector that passed only because outliers made up half of its
     * neighbourhood (a cluster of wrong vectors) is tested again without the ones rejected in
     * round before (see below which), until a round rejects nothing (a clean field: one
     * round, as before). */
    const int nt = nthreads > 0 ? nthreads : omp_get_max_threads();
    unsigned char *retest = malloc(n);
    if (!retest) {
        free(rej);
        return rpiv_fail(RPIV_ENOMEM, "validate: out of memory");
    }
    memset(retest, 1, n);
    for (;;) {
        size_t fresh = 0;
#pragma omp parallel for schedule(static) num_threads(nt) if (n >= 4096)
        for (int j = 0; j < ny; j++)
            for (int i = 0; i < nx; i++) {
                size_t k = (size_t)j * (size_t)nx + (size_t)i;
                if (!ok[k] || rej[k] || !retest[k])
                    continue;
                float nu[8], nv[8];
                int m = gather(f, ok, i, j, nu, nv);
                if (m < 2)
                    continue;
                if ((residual((double)f->u[k], nu, m, eps) > threshold ||
                     residual((double)f->v[k], nv, m, eps) > threshold) &&
                    !(lines && agrees_along_a_line(f, ok, i, j, threshold, eps)))
                    rej[k] = 1;
            }
        for (size_t k = 0; k < n; k++)
            fresh += rej[k] && ok[k] == 1;
        if (!fresh)
            break;
        /* a survivor is tested again when at least half of the usable vectors of its block
         * were rejected in this round: it passed against a neighbourhood of outliers. (Not
         * every neighbour of a rejection: on a shear's crests that cascade eroded true
         * gradients.) */
        memset(retest, 0, n);
        for (int j = 0; j < ny; j++)
            for (int i = 0; i < nx; i++) {
                const size_t k = (size_t)j * (size_t)nx + (size_t)i;
                if (ok[k] != 1 || rej[k])
                    continue;
                int all = 0, bad = 0;
                for (int jj = j - 1; jj <= j + 1; jj++)
                    for (int ii = i - 1; ii <= i + 1; ii++) {
                        if ((ii == i && jj == j) || ii < 0 || jj < 0 || ii >= nx || jj >= ny)
                            continue;
                        const size_t q = (size_t)jj * (size_t)nx + (size_t)ii;
                        all += ok[q] == 1;
                        bad += ok[q] == 1 && rej[q];
                    }
                retest[k] = bad > 0 && 2 * bad >= all;
            }
        for (size_t k = 0; k < n; k++)
            if (rej[k])
                ok[k] = 0;
    }
    free(retest);
    for (size_t k = 0; k < n; k++)
        if (rej[k]) {
            f->flag[k] = RPIV_FLAG_REPLACED;
            count++;
        }
    free(rej);
    if (nrejected)
        *nrejected = count;
    return RPIV_OK;
}

rpiv_status rpiv_validate_replace(rpiv_field *f, int fill_masked, size_t *nfilled)
{
    return validate_replace_lines(f, fill_masked, 0, nfilled);
}

rpiv_status validate_replace_lines(rpiv_field *f, int fill_masked, int lines, size_t *nfilled)
{
    if (nfilled)
        *nfilled = 0;
    const int nx = f->nx, ny = f->ny;
    size_t n = (size_t)nx * (size_t)ny, pending = 0, filled = 0;
    /* known: 1 = usable as a neighbour; 0 = to fill; 2 = neither (masked, not filled) */
    unsigned char *known = malloc(2 * n);
    float *nu = malloc(2 * n * sizeof *nu);
    if (!known || !nu) {
        free(known);
        free(nu);
        return rpiv_fail(RPIV_ENOMEM, "validate: out of memory");
    }
    unsigned char *now = known + n;
    float *nv = nu + n;
    for (size_t k = 0; k < n; k++) {
        unsigned char fl = f->flag[k];
        known[k] = fl == RPIV_FLAG_VALID ? 1 : (fl == RPIV_FLAG_REPLACED || fill_masked ? 0 : 2);
        pending += known[k] == 0;
    }
    while (pending) {
        size_t done = 0;
        memset(now, 0, n);
        for (int j = 0; j < ny; j++)
            for (int i = 0; i < nx; i++) {
                size_t k = (size_t)j * (size_t)nx + (size_t)i;
                if (known[k] != 0)
                    continue;
                float bu[8], bv[8];
                double ru, rv;
                if (lines && best_line(f, known, i, j, 0.1, &ru, &rv, &bu[0], &bv[0])) {
                    nu[k] = bu[0];
                    nv[k] = bv[0];
                    now[k] = 1;
                    done++;
                    continue;
                }
                int m = gather(f, known, i, j, bu, bv);
                if (m) {
                    nu[k] = (float)median(bu, m);
                    nv[k] = (float)median(bv, m);
                    now[k] = 1;
                    done++;
                }
            }
        if (!done)
            break;
        for (size_t k = 0; k < n; k++)
            if (now[k]) {
                f->u[k] = nu[k];
                f->v[k] = nv[k];
                known[k] = 1;
            }
        pending -= done;
        filled += done;
    }
    if (pending) /* no valid vector anywhere */
        for (size_t k = 0; k < n; k++)
            if (known[k] == 0) {
                f->u[k] = f->v[k] = 0;
                filled++;
            }
    free(known);
    free(nu);
    if (nfilled)
        *nfilled = filled;
    return RPIV_OK;
}
