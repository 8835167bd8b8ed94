/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/uncertainty.c - random uncertainty of each vector by correlation statistics
 * (Wieneke 2015): the noise of the correlation values either side of the peak, from the
 * pixel-wise products of the deformed windows, propagated through the 3-point Gaussian fit.
 * Equations and their checks: docs/uncertainty.md. */
#include "uncertainty_impl.h"

#include <math.h>
#include <string.h>

/* Half-width of the lags over which the products' differences are taken as correlated
 * (particle images up to ~4 px: their products decorrelate within 2 px). */
#define UNC_LAG 2

/* Widest window the uncertainty handles (the engine's limit, piv.windows). */
#define UNC_MAX_W 1024

static int wrap(int i, int n)
{
    return ((i % n) + n) % n;
}

/* One direction (dx, dy = (1, 0) or (0, 1)) of unc_cs_sums: C0, C+, C-, var(C+ - C-). */
static void cs_dir(const float *a, size_t sa, const float *b, size_t sb, int w, int h, int ix,
                   int iy, double ma, double mb, int dx, int dy, float *dc, double out[4])
{
    double c0 = 0, cp = 0, cm = 0, sum = 0;
    const size_t n = (size_t)w * (size_t)h;
    int xo[UNC_MAX_W], xp[UNC_MAX_W], xm[UNC_MAX_W], xa[UNC_MAX_W];
    for (int x = 0; x < w; x++) {
        xo[x] = wrap(x + ix, w);
        xp[x] = wrap(xo[x] + dx, w);
        xm[x] = wrap(xo[x] - dx, w);
        xa[x] = wrap(x + dx, w);
    }
    for (int y = 0; y < h; y++) {
        const int y0 = wrap(y + iy, h);
        const float *ar = a + (size_t)y * sa, *an = a + (size_t)wrap(y + dy, h) * sa;
        const float *b0 = b + (size_t)y0 * sb, *bp = b + (size_t)wrap(y0 + dy, h) * sb;
        const float *bm = b + (size_t)wrap(y0 - dy, h) * sb;
        float *d = dc + (size_t)y * (size_t)w;
        for (int x = 0; x < w; x++) {
            const double av = (double)ar[x] - ma, anv = (double)an[xa[x]] - ma;
            const double v0 = (double)b0[xo[x]] - mb, vp = (double)bp[xp[x]] - mb;
            const double vm = (double)bm[xm[x]] - mb;
            c0 += av * v0;
            cp += av * vp;
            cm += av * vm;
            /* this pixel's share of C(+1) - C(-1): a(x) b(x+s+1) - a(x+1) b(x+s) */
            const double e = av * vp - anv * v0;
            d[x] = (float)e;
            sum += e;
        }
    }
    const float mean = (float)(sum / (double)n);
    for (size_t k = 0; k < n; k++)
        dc[k] -= mean;
    /* variance of the sum of the differences: their covariance summed over nearby lags,
     * sum_x dc(x) sum_{|k|,|l| <= UNC_LAG} dc(x + (k, l)), the inner sum a separable box */
    float *row = dc + n;
    for (int y = 0; y < h; y++) {
        const float *d = dc + (size_t)y * (size_t)w;
        float *r = row + (size_t)y * (size_t)w;
        for (int x = 0; x < w; x++) {
            double t = 0;
            for (int k = -UNC_LAG; k <= UNC_LAG; k++)
                t += (double)d[x + k >= 0 && x + k < w ? x + k : wrap(x + k, w)];
            r[x] = (float)t;
        }
    }
    double var = 0;
    const float *rr[2 * UNC_LAG + 1];
    for (int y = 0; y < h; y++) {
        for (int l = -UNC_LAG; l <= UNC_LAG; l++)
            rr[l + UNC_LAG] = row + (size_t)wrap(y + l, h) * (size_t)w;
        const float *d = dc + (size_t)y * (size_t)w;
        for (int x = 0; x < w; x++) {
            double t = 0;
            for (int l = 0; l <= 2 * UNC_LAG; l++)
                t += (double)rr[l][x];
            var += (double)d[x] * t;
        }
    }
    out[0] = c0;
    out[1] = cp;
    out[2] = cm;
    out[3] = var > 0 ? var : 0;
}

double unc_cs_sigma(double c0, double cp, double cm, double var)
{
    if (!(var > 0))
        return 0;
    const double sd = sqrt(var), cpm = 0.5 * (cp + cm);
    const double hi = cpm + 0.5 * sd, lo = cpm - 0.5 * sd;
    if (!(lo > 0) || !(c0 > hi))
        return UNC_SIGMA_MAX;
    const double lhi = log(hi), llo = log(lo);
    const double s = (lhi - llo) / (4 * log(c0) - 2 * lhi - 2 * llo);
    return s < UNC_SIGMA_MAX ? s : UNC_SIGMA_MAX;
}

void unc_cs_sums(const float *a, size_t sa, const float *b, size_t sb, int w, int h, int ix, int iy,
                 float *scratch, double sums[8])
{
    double ma = 0, mb = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            ma += (double)a[(size_t)y * sa + (size_t)x];
            mb += (double)b[(size_t)y * sb + (size_t)x];
        }
    ma /= (double)w * h;
    mb /= (double)w * h;
    cs_dir(a, sa, b, sb, w, h, ix, iy, ma, mb, 1, 0, scratch, sums);
    cs_dir(a, sa, b, sb, w, h, ix, iy, ma, mb, 0, 1, scratch, sums + 4);
}

/* ln c- - 2 ln c0 + ln c+, or 0 where a value is not positive. */
static double curv3(double c0, double cp, double cm)
{
    return c0 > 0 && cp > 0 && cm > 0 ? log(cm) - 2 * log(c0) + log(cp) : 0;
}

int unc_curv_at(const float *plane, int w, int h, int bi, int bj, double *hx, double *hy)
{
    const size_t W = (size_t)w, row = (size_t)bj * W;
    const double c0 = (double)plane[row + (size_t)bi];
    const double cxm = (double)plane[row + (size_t)((bi + w - 1) % w)];
    const double cxp = (double)plane[row + (size_t)((bi + 1) % w)];
    const double cym = (double)plane[(size_t)((bj + h - 1) % h) * W + (size_t)bi];
    const double cyp = (double)plane[(size_t)((bj + 1) % h) * W + (size_t)bi];
    if (!(c0 > 0 && cxm > 0 && cxp > 0 && cym > 0 && cyp > 0))
        return 0;
    *hx = curv3(c0, cxp, cxm);
    *hy = curv3(c0, cyp, cym);
    return 1;
}

void unc_cs(const float *a, size_t sa, const float *b, size_t sb, int w, int h, int ix, int iy,
            float *scratch, double *su, double *sv, double curv[2])
{
    double s[8];
    unc_cs_sums(a, sa, b, sb, w, h, ix, iy, scratch, s);
    *su = unc_cs_sigma(s[0], s[1], s[2], s[3]);
    *sv = unc_cs_sigma(s[4], s[5], s[6], s[7]);
    curv[0] = curv3(s[0], s[1], s[2]);
    curv[1] = curv3(s[4], s[5], s[6]);
}

float *unc_quantity(rpiv_field *f, const char *name)
{
    for (size_t k = 0; k < f->nq; k++)
        if (!strcmp(f->q[k].name, name))
            return f->q[k].data;
    return NULL;
}

rpiv_status unc_add(rpiv_field *f, float **su, float **sv)
{
    rpiv_status st;
    const size_t n = (size_t)f->nx * (size_t)f->ny;
    const char *names[2] = {"sigma_u", "sigma_v"};
    float **out[2] = {su, sv};
    for (int c = 0; c < 2; c++) {
        *out[c] = unc_quantity(f, names[c]);
        if (*out[c])
            memset(*out[c], 0, n * sizeof **out[c]);
        else if ((st = rpiv_field_add_quantity(f, names[c], RPIV_UNIT_PX_PER_DT, out[c])))
            return st;
    }
    return RPIV_OK;
}

void unc_replaced(rpiv_field *f)
{
    float *g[2] = {unc_quantity(f, "sigma_u"), unc_quantity(f, "sigma_v")};
    if (!g[0] || !g[1])
        return;
    const int nx = f->nx, ny = f->ny;
    for (int c = 0; c < 2; c++) {
        float *s = g[c], top = 0;
        for (size_t k = 0; k < (size_t)nx * (size_t)ny; k++)
            if (f->flag[k] == RPIV_FLAG_VALID && s[k] > top)
                top = s[k];
        /* in raster order reading valid neighbours only: the result does not depend on it */
        for (int j = 0; j < ny; j++)
            for (int i = 0; i < nx; i++) {
                const size_t k = (size_t)j * (size_t)nx + (size_t)i;
                if (f->flag[k] == RPIV_FLAG_MASKED) {
                    s[k] = 0;
                    continue;
                }
                if (f->flag[k] != RPIV_FLAG_REPLACED)
                    continue;
                double ss = 0;
                int m = 0;
                for (int l = -1; l <= 1; l++)
                    for (int q = -1; q <= 1; q++) {
                        const int x = i + q, y = j + l;
                        if (x < 0 || y < 0 || x >= nx || y >= ny)
                            continue;
                        const size_t kk = (size_t)y * (size_t)nx + (size_t)x;
                        if (f->flag[kk] == RPIV_FLAG_VALID) {
                            ss += (double)s[kk] * (double)s[kk];
                            m++;
                        }
                    }
                s[k] = m ? (float)sqrt(ss / m) : top;
            }
    }
}
