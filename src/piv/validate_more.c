/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/validate_more.c - the validation tests beyond the normalised median (peak ratio,
 * global limits, global mean +- k std), replacement by inpainting, and penalised
 * least-squares smoothing (rpiv/validate.h, docs/postprocess.md). */
#include "rpiv/validate.h"

#include "validate_impl.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static size_t npoints(const rpiv_field *f)
{
    return (size_t)f->nx * (size_t)f->ny;
}

static void reject(rpiv_field *f, size_t k, size_t *count)
{
    f->flag[k] = RPIV_FLAG_REPLACED;
    (*count)++;
}

rpiv_status rpiv_validate_peak_ratio(rpiv_field *f, double min_ratio, size_t *nrejected)
{
    size_t count = 0;
    if (nrejected)
        *nrejected = 0;
    if (!(min_ratio >= 0))
        return rpiv_fail(RPIV_EINVAL, "validate: peak ratio threshold %g < 0", min_ratio);
    for (size_t k = 0; k < npoints(f); k++)
        if (f->flag[k] == RPIV_FLAG_VALID && f->peak_ratio[k] > 0 &&
            (double)f->peak_ratio[k] < min_ratio)
            reject(f, k, &count);
    if (nrejected)
        *nrejected = count;
    return RPIV_OK;
}

rpiv_status rpiv_validate_limits(rpiv_field *f, double umin, double umax, double vmin, double vmax,
                                 size_t *nrejected)
{
    size_t count = 0;
    const int tu = umin < umax, tv = vmin < vmax;
    for (size_t k = 0; k < npoints(f); k++) {
        if (f->flag[k] != RPIV_FLAG_VALID)
            continue;
        double u = (double)f->u[k], v = (double)f->v[k];
        if ((tu && (u < umin || u > umax)) || (tv && (v < vmin || v > vmax)))
            reject(f, k, &count);
    }
    if (nrejected)
        *nrejected = count;
    return RPIV_OK;
}

rpiv_status rpiv_validate_std(rpiv_field *f, double k_std, size_t *nrejected)
{
    size_t count = 0, m = 0;
    if (nrejected)
        *nrejected = 0;
    if (!(k_std > 0))
        return rpiv_fail(RPIV_EINVAL, "validate: std factor %g must be > 0", k_std);
    double su = 0, sv = 0, suu = 0, svv = 0;
    for (size_t k = 0; k < npoints(f); k++) /* two passes: mean, then deviations */
        if (f->flag[k] == RPIV_FLAG_VALID) {
            su += (double)f->u[k];
            sv += (double)f->v[k];
            m++;
        }
    if (m < 2)
        return RPIV_OK;
    const double mu = su / (double)m, mv = sv / (double)m;
    for (size_t k = 0; k < npoints(f); k++)
        if (f->flag[k] == RPIV_FLAG_VALID) {
            double du = (double)f->u[k] - mu, dv = (double)f->v[k] - mv;
            suu += du * du;
            svv += dv * dv;
        }
    const double lu = k_std * sqrt(suu / (double)(m - 1)), lv = k_std * sqrt(svv / (double)(m - 1));
    for (size_t k = 0; k < npoints(f); k++)
        if (f->flag[k] == RPIV_FLAG_VALID &&
            (fabs((double)f->u[k] - mu) > lu || fabs((double)f->v[k] - mv) > lv))
            reject(f, k, &count);
    if (nrejected)
        *nrejected = count;
    return RPIV_OK;
}

/* ---- inpainting ------------------------------------------------------------------------ */

#define INPAINT_TOL   1e-5
#define INPAINT_SWEEP 20000
#define INPAINT_OMEGA 1.7

rpiv_status rpiv_validate_inpaint(rpiv_field *f, int fill_masked, size_t *nfilled)
{
    const size_t n = npoints(f);
    const int nx = f->nx, ny = f->ny;
    /* the start: the median replacement (it also handles a field without valid vectors) */
    rpiv_status st = rpiv_validate_replace(f, fill_masked, nfilled);
    if (st)
        return st;
    /* role: 0 = unknown, 1 = fixed (valid), 2 = excluded (masked, not filled) */
    unsigned char *role = malloc(n);
    size_t *idx = malloc(n * sizeof *idx);
    if (!role || !idx) {
        free(role);
        free(idx);
        return rpiv_fail(RPIV_ENOMEM, "validate: out of memory");
    }
    size_t nu = 0, nfixed = 0;
    for (size_t k = 0; k < n; k++) {
        unsigned char fl = f->flag[k];
        role[k] = fl == RPIV_FLAG_VALID ? 1 : (fl == RPIV_FLAG_REPLACED || fill_masked ? 0 : 2);
        if (role[k] == 0)
            idx[nu++] = k;
        nfixed += role[k] == 1;
    }
    /* Gauss-Seidel with over-relaxation, in raster order (one thread: deterministic) */
    for (int sweep = 0; nu && nfixed && sweep < INPAINT_SWEEP; sweep++) {
        double change = 0;
        for (size_t q = 0; q < nu; q++) {
            size_t k = idx[q];
            int i = (int)(k % (size_t)nx), j = (int)(k / (size_t)nx), m = 0;
            double au = 0, av = 0;
            const int ni[4] = {i - 1, i + 1, i, i}, nj[4] = {j, j, j - 1, j + 1};
            for (int d = 0; d < 4; d++) {
                if (ni[d] < 0 || nj[d] < 0 || ni[d] >= nx || nj[d] >= ny)
                    continue;
                size_t e = (size_t)nj[d] * (size_t)nx + (size_t)ni[d];
                if (role[e] == 2)
                    continue;
                au += (double)f->u[e];
                av += (double)f->v[e];
                m++;
            }
            if (!m)
                continue;
            double du = INPAINT_OMEGA * (au / m - (double)f->u[k]),
                   dv = INPAINT_OMEGA * (av / m - (double)f->v[k]);
            f->u[k] = (float)((double)f->u[k] + du);
            f->v[k] = (float)((double)f->v[k] + dv);
            double c = fabs(du) > fabs(dv) ? fabs(du) : fabs(dv);
            change = c > change ? c : change;
        }
        if (change < INPAINT_TOL)
            break;
    }
    free(role);
    free(idx);
    return RPIV_OK;
}

/* ---- smoothing ------------------------------------------------------------------------- */

/* The orthonormal DCT-II matrix of size n: c[k * n + i] = a_k cos(pi (i + 1/2) k / n). */
static double *dct_matrix(int n)
{
    double *c = malloc((size_t)n * (size_t)n * sizeof *c);
    if (!c)
        return NULL;
    for (int k = 0; k < n; k++)
        for (int i = 0; i < n; i++)
            c[(size_t)k * (size_t)n + (size_t)i] =
                sqrt((k ? 2.0 : 1.0) / n) * cos(M_PI * (i + 0.5) * k / n);
    return c;
}

/* In place: a (ny x nx, row-major) <- Cy a Cx^T (forward) or Cy^T a Cx (inverse). */
static void dct2(double *a, double *tmp, const double *cx, const double *cy, int nx, int ny,
                 int inverse)
{
    for (int j = 0; j < ny; j++) /* rows */
        for (int k = 0; k < nx; k++) {
            double s = 0;
            for (int i = 0; i < nx; i++)
                s += (inverse ? cx[(size_t)i * (size_t)nx + (size_t)k]
                              : cx[(size_t)k * (size_t)nx + (size_t)i]) *
                     a[(size_t)j * (size_t)nx + (size_t)i];
            tmp[(size_t)j * (size_t)nx + (size_t)k] = s;
        }
    for (int i = 0; i < nx; i++) /* columns */
        for (int k = 0; k < ny; k++) {
            double s = 0;
            for (int j = 0; j < ny; j++)
                s += (inverse ? cy[(size_t)j * (size_t)ny + (size_t)k]
                              : cy[(size_t)k * (size_t)ny + (size_t)j]) *
                     tmp[(size_t)j * (size_t)nx + (size_t)i];
            a[(size_t)k * (size_t)nx + (size_t)i] = s;
        }
}

#define SMOOTH_ITER 200
#define SMOOTH_TOL  1e-5

rpiv_status rpiv_validate_smooth(rpiv_field *f, double s)
{
    if (!(s >= 0) || !isfinite(s))
        return rpiv_fail(RPIV_EINVAL, "validate: smoothing parameter %g must be >= 0", s);
    if (s == 0)
        return RPIV_OK;
    const int nx = f->nx, ny = f->ny;
    const size_t n = npoints(f);
    size_t nmask = 0;
    for (size_t k = 0; k < n; k++)
        nmask += f->flag[k] == RPIV_FLAG_MASKED;
    if (nmask == n)
        return RPIV_OK;
    double *cx = dct_matrix(nx), *cy = dct_matrix(ny);
    double *gam = malloc(n * sizeof *gam), *y = malloc(4 * n * sizeof *y);
    rpiv_field *g = NULL;
    rpiv_status st = RPIV_OK;
    if (!cx || !cy || !gam || !y) {
        st = rpiv_fail(RPIV_ENOMEM, "validate: out of memory");
        goto out_free;
    }
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            double lam = -2 + 2 * cos(M_PI * i / nx) - 2 + 2 * cos(M_PI * j / ny);
            gam[(size_t)j * (size_t)nx + (size_t)i] = 1.0 / (1.0 + s * lam * lam);
        }
    /* masked vectors (weight 0) start from the inpainted field */
    if (nmask && ((st = rpiv_field_copy(f, &g)) || (st = rpiv_validate_inpaint(g, 1, NULL))))
        goto out_free;
    double *yh = y + n, *z = y + 2 * n, *tmp = y + 3 * n;
    for (int c = 0; c < 2; c++) {
        float *a = c ? f->v : f->u;
        const float *start = g ? (c ? g->v : g->u) : a;
        for (size_t k = 0; k < n; k++) {
            y[k] = (double)a[k];
            yh[k] = (double)start[k];
        }
        for (int it = 0; it < (nmask ? SMOOTH_ITER : 1); it++) {
            for (size_t k = 0; k < n; k++)
                z[k] = f->flag[k] == RPIV_FLAG_MASKED ? yh[k] : y[k];
            dct2(z, tmp, cx, cy, nx, ny, 0);
            for (size_t k = 0; k < n; k++)
                z[k] *= gam[k];
            dct2(z, tmp, cx, cy, nx, ny, 1);
            double d = 0, r = 0;
            for (size_t k = 0; k < n; k++) {
                d += (z[k] - yh[k]) * (z[k] - yh[k]);
                r += z[k] * z[k];
                yh[k] = z[k];
            }
            if (d <= SMOOTH_TOL * SMOOTH_TOL * (r > 0 ? r : 1))
                break;
        }
        for (size_t k = 0; k < n; k++)
            if (f->flag[k] != RPIV_FLAG_MASKED)
                a[k] = (float)yh[k];
    }
out_free:
    rpiv_field_free(g);
    free(cx);
    free(cy);
    free(gam);
    free(y);
    return st;
}

rpiv_status validate_more(rpiv_field *f, const rpiv_piv_params *p)
{
    rpiv_status st = RPIV_OK;
    if (p->peak_ratio_min > 0 && (st = rpiv_validate_peak_ratio(f, p->peak_ratio_min, NULL)))
        return st;
    if ((p->u_min_px < p->u_max_px || p->v_min_px < p->v_max_px) &&
        (st = rpiv_validate_limits(f, p->u_min_px, p->u_max_px, p->v_min_px, p->v_max_px, NULL)))
        return st;
    if (p->std_k > 0)
        st = rpiv_validate_std(f, p->std_k, NULL);
    return st;
}
