/* SPDX-License-Identifier: GPL-3.0-or-later */
/* bench_noise - the engine on noisy pairs of small particle images (issue 15): uniform shifts
 * u = s, v = -s for s = 0 .. smax px in steps of 0.1 px, several seeds; RMS error and
 * peak-locking (the amplitude of the periodic part of the mean error against the sub-pixel
 * shift). The pairs are tests/piv_testimg.h's: pixel-integrated Gaussian particles of e^-2
 * diameter d (sigma = d/4), intensities uniform in 60-100 % of `peak`, Gaussian noise of
 * standard deviation noise * peak added to every pixel: SNR = 1 / noise = the grey level of a
 * centred particle of full intensity over the noise's standard deviation.
 *
 * usage: bench_noise [key=value ...]   (docs/deform.md, "Noisy small particles")
 *   size=512 ppp=0.02,0.05 d=1.5 noise=0.1 seeds=3 smax=2 passes=64,32,32 sub=gauss
 *   pre=none|b3|gauss:SIGMA (applied to both frames before the engine: b3 is the cubic
 *   B-spline's [1 4 1]/6 in x and y, so that the engine's prefilter gives back the frames
 *   themselves as coefficients: interpolation by the (smoothing) B-spline approximation)
 *   rfilter=A (params refine_filter: the repeat's predictor low-passed by [A/2, 1-A, A/2])
 *   mode=estimators: the sub-pixel estimators on the planes of single 32 px windows instead */
#include "../tests/peak_locking.h"
#include "../tests/piv_testimg.h"
#include "rpiv/peak.h"
#include "rpiv/piv.h"
#include "rpiv/xcorr.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct opts {
    int size, seeds;
    double ppp[4];
    int nppp;
    double d, noise, smax;
    char passes[64], sub[16], pre[32];
    double rfilter;
    int estimators;
} opts;

static void smooth3(float *img, int w, int h, const double k[3])
{
    float *t = malloc(sizeof *t * (size_t)w * (size_t)h);
    if (!t)
        exit(2);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            int xm = x > 0 ? x - 1 : 1, xp = x < w - 1 ? x + 1 : w - 2;
            const float *r = img + (size_t)y * (size_t)w;
            t[(size_t)y * (size_t)w + (size_t)x] =
                (float)(k[0] * (double)r[xm] + k[1] * (double)r[x] + k[2] * (double)r[xp]);
        }
    for (int y = 0; y < h; y++) {
        int ym = y > 0 ? y - 1 : 1, yp = y < h - 1 ? y + 1 : h - 2;
        for (int x = 0; x < w; x++)
            img[(size_t)y * (size_t)w + (size_t)x] =
                (float)(k[0] * (double)t[(size_t)ym * (size_t)w + (size_t)x] +
                        k[1] * (double)t[(size_t)y * (size_t)w + (size_t)x] +
                        k[2] * (double)t[(size_t)yp * (size_t)w + (size_t)x]);
    }
    free(t);
}

static void prep(const char *pre, float *img, int w, int h)
{
    if (!strcmp(pre, "none"))
        return;
    if (!strcmp(pre, "b3")) {
        const double k[3] = {1.0 / 6, 4.0 / 6, 1.0 / 6};
        smooth3(img, w, h, k);
    } else if (!strncmp(pre, "gauss:", 6)) {
        double s = atof(pre + 6), e = exp(-0.5 / (s * s)), k[3] = {e, 1, e};
        double sum = 1 + 2 * e;
        for (int i = 0; i < 3; i++)
            k[i] /= sum;
        smooth3(img, w, h, k);
    } else {
        fprintf(stderr, "bench_noise: unknown pre '%s'\n", pre);
        exit(2);
    }
}

static int parse_passes(const char *s, rpiv_piv_params *p)
{
    int n = 0;
    const char *c = s;
    while (*c && n < RPIV_PIV_MAX_PASSES) {
        p->win_w[n] = p->win_h[n] = atoi(c);
        n++;
        c = strchr(c, ',');
        if (!c)
            break;
        c++;
    }
    p->npass = n;
    return n;
}

/* The plane value at circular shift (sx, sy). */
static double pl(const float *p, int w, int h, int sx, int sy)
{
    return (double)p[(size_t)(((sy % h) + h) % h) * (size_t)w + (size_t)(((sx % w) + w) % w)];
}

/* Least-squares 2-D Gaussian over the 3 x 3 neighbourhood of the integer peak (ix, iy): the
 * logarithms of the 9 values fitted by a + b x + c y + d x^2 + e y^2 + f x y; the maximum of
 * that quadratic. Returns 0 if a value is not positive or the quadratic has no maximum. */
static int lsq3x3(const float *p, int w, int h, int ix, int iy, double *dx, double *dy)
{
    double L[3][3];
    for (int j = -1; j <= 1; j++)
        for (int i = -1; i <= 1; i++) {
            double v = pl(p, w, h, ix + i, iy + j);
            if (!(v > 0))
                return 0;
            L[j + 1][i + 1] = log(v);
        }
    /* the 3 x 3 grid is orthogonal for these terms: closed forms */
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0, s0 = 0;
    for (int j = -1; j <= 1; j++)
        for (int i = -1; i <= 1; i++) {
            double v = L[j + 1][i + 1];
            s0 += v;
            sx += i * v;
            sy += j * v;
            sxx += i * i * v;
            syy += j * j * v;
            sxy += i * j * v;
        }
    /* b, c, f decouple (sum x^2 = 6, sum x^2 y^2 = 4 over the 9 points); a, d, e solve
     * [9 6 6; 6 6 4; 6 4 6] (a d e)' = (sum v, sum x^2 v, sum y^2 v)' */
    double b = sx / 6, c = sy / 6, f = sxy / 4;
    double A[3][4] = {{9, 6, 6, s0}, {6, 6, 4, sxx}, {6, 4, 6, syy}};
    for (int col = 0; col < 3; col++)
        for (int r = 0; r < 3; r++)
            if (r != col) {
                double m = A[r][col] / A[col][col];
                for (int k = 0; k < 4; k++)
                    A[r][k] -= m * A[col][k];
            }
    double d = A[1][3] / A[1][1], e = A[2][3] / A[2][2];
    double det = 4 * d * e - f * f;
    if (!(d < 0 && e < 0 && det > 0))
        return 0;
    *dx = ix + (f * c - 2 * e * b) / det;
    *dy = iy + (f * b - 2 * d * c) / det;
    return 1;
}

/* The sub-pixel estimators on the planes of 32 x 32 windows (no deformation), shifts 0..1 px */
static void estimators(const opts *o)
{
    const int n = o->size, W = 32;
    float *a = malloc(sizeof *a * (size_t)n * (size_t)n),
          *b = malloc(sizeof *b * (size_t)n * (size_t)n);
    rpiv_xcorr *x = NULL;
    rpiv_xcorr_work *ws = NULL;
    if (!a || !b || rpiv_xcorr_new(W, W, &x) || rpiv_xcorr_work_new(x, &ws))
        exit(2);
    for (int q = 0; q < o->nppp; q++) {
        double sq[3] = {0, 0, 0};
        long cnt = 0, nfb = 0;
        for (int k = 0; k <= 10; k++)
            for (int sd = 0; sd < o->seeds; sd++) {
                double s = 0.1 * k, d[2] = {s, -s};
                ti_params tp = {
                    n,    n,        o->ppp[q], o->d,
                    1000, o->noise, 0,         (uint64_t)(7919 * (sd + 1) + 31 * k + 1000 * q + 1)};
                ti_pair(&tp, ti_uniform, d, a, b);
                for (int y0 = 0; y0 + W <= n; y0 += W)
                    for (int x0 = 0; x0 + W <= n; x0 += W) {
                        const float *pa = a + (size_t)y0 * (size_t)n + (size_t)x0;
                        const float *pb = b + (size_t)y0 * (size_t)n + (size_t)x0;
                        rpiv_xcorr_run_from(x, ws, pa, (size_t)n, pb, (size_t)n, RPIV_XCORR_RAW,
                                            NULL, NULL);
                        rpiv_peak pk;
                        rpiv_peak_find(ws->plane, W, W, 0, RPIV_SUBPIXEL_GAUSS, &pk);
                        double ex[3], ey[3];
                        ex[0] = pk.dx - d[0];
                        ey[0] = pk.dy - d[1];
                        rpiv_peak_find(ws->plane, W, W, 0, RPIV_SUBPIXEL_PARABOLA, &pk);
                        ex[1] = pk.dx - d[0];
                        ey[1] = pk.dy - d[1];
                        double lx, ly;
                        if (!lsq3x3(ws->plane, W, W, pk.ix, pk.iy, &lx, &ly)) {
                            lx = ex[0] + d[0];
                            ly = ey[0] + d[1];
                            nfb++;
                        }
                        ex[2] = lx - d[0];
                        ey[2] = ly - d[1];
                        for (int m = 0; m < 3; m++)
                            sq[m] += ex[m] * ex[m] + ey[m] * ey[m];
                        cnt++;
                    }
            }
        printf("ppp %.3f, one 32 px window, shifts 0..1 px: RMS gauss 3-point %.4f, parabola "
               "%.4f, least-squares 3x3 Gaussian %.4f px (3-point where a value is not positive: "
               "%.1f %%)\n",
               o->ppp[q], sqrt(sq[0] / (2.0 * (double)cnt)), sqrt(sq[1] / (2.0 * (double)cnt)),
               sqrt(sq[2] / (2.0 * (double)cnt)), 100.0 * (double)nfb / (double)cnt);
    }
    rpiv_xcorr_work_free(ws);
    rpiv_xcorr_free(x);
    free(a);
    free(b);
}

int main(int argc, char **argv)
{
    opts o = {512, 3, {0.02, 0.05}, 2, 1.5, 0.1, 2.0, "64,32,32", "gauss", "none", 0, 0};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = strchr(a, '=');
        if (!v) {
            fprintf(stderr, "bench_noise: expected key=value, got '%s'\n", a);
            return 2;
        }
        v++;
        if (!strncmp(a, "size=", 5))
            o.size = atoi(v);
        else if (!strncmp(a, "seeds=", 6))
            o.seeds = atoi(v);
        else if (!strncmp(a, "ppp=", 4)) {
            o.nppp = 0;
            for (const char *c = v; c && o.nppp < 4; c = strchr(c, ','), c = c ? c + 1 : c)
                o.ppp[o.nppp++] = atof(c);
        } else if (!strncmp(a, "d=", 2))
            o.d = atof(v);
        else if (!strncmp(a, "noise=", 6))
            o.noise = atof(v);
        else if (!strncmp(a, "smax=", 5))
            o.smax = atof(v);
        else if (!strncmp(a, "passes=", 7))
            snprintf(o.passes, sizeof o.passes, "%s", v);
        else if (!strncmp(a, "sub=", 4))
            snprintf(o.sub, sizeof o.sub, "%s", v);
        else if (!strncmp(a, "pre=", 4))
            snprintf(o.pre, sizeof o.pre, "%s", v);
        else if (!strncmp(a, "mode=", 5))
            o.estimators = !strcmp(v, "estimators");
        else if (!strncmp(a, "rfilter=", 8))
            o.rfilter = atof(v);
        else {
            fprintf(stderr, "bench_noise: unknown key in '%s'\n", a);
            return 2;
        }
    }
    if (o.estimators) {
        estimators(&o);
        return 0;
    }
    rpiv_piv_params prm = rpiv_piv_params_default();
    parse_passes(o.passes, &prm);
    prm.refine_filter = o.rfilter;
    prm.subpixel = !strcmp(o.sub, "parabola")   ? RPIV_SUBPIXEL_PARABOLA
                   : !strcmp(o.sub, "centroid") ? RPIV_SUBPIXEL_CENTROID
                                                : RPIV_SUBPIXEL_GAUSS;
    const int ns = (int)lround(o.smax / 0.1) + 1, n = o.size;
    double *fr = malloc(sizeof *fr * 2 * (size_t)ns), *me = malloc(sizeof *me * 2 * (size_t)ns);
    float *a = malloc(sizeof *a * (size_t)n * (size_t)n),
          *b = malloc(sizeof *b * (size_t)n * (size_t)n);
    if (!fr || !me || !a || !b)
        return 2;
    rpiv_piv *pv = NULL;
    if (rpiv_piv_new(&prm, n, n, NULL, &pv) != RPIV_OK) {
        fprintf(stderr, "bench_noise: %s\n", rpiv_errmsg());
        return 1;
    }
    printf("# size %d, d %.2f px, SNR %.1f, passes %s, sub %s, pre %s, refine_filter %g, "
           "%d seeds, shifts 0..%.1f px\n",
           n, o.d, o.noise > 0 ? 1 / o.noise : (double)INFINITY, o.passes, o.sub, o.pre, o.rfilter,
           o.seeds, o.smax);
    for (int q = 0; q < o.nppp; q++) {
        double sq = 0, sq_in = 0, worst_mean = 0;
        long cnt = 0, repl = 0, out = 0;
        for (int k = 0; k < ns; k++) {
            double s = 0.1 * k, d[2] = {s, -s}, mu = 0, mv = 0;
            long nk = 0;
            for (int sd = 0; sd < o.seeds; sd++) {
                ti_params tp = {
                    n,    n,       o.ppp[q], o.d,
                    1000, o.noise, 0,        (uint64_t)(7919 * (sd + 1) + 31 * k + 1000 * q + 1)};
                ti_pair(&tp, ti_uniform, d, a, b);
                prep(o.pre, a, n, n);
                prep(o.pre, b, n, n);
                rpiv_image ia = {n, n, 16, a}, ib = {n, n, 16, b};
                rpiv_field *f = NULL;
                if (rpiv_piv_run(pv, &ia, &ib, &f) != RPIV_OK) {
                    fprintf(stderr, "bench_noise: %s\n", rpiv_errmsg());
                    return 1;
                }
                size_t nv = (size_t)f->nx * (size_t)f->ny;
                for (size_t i = 0; i < nv; i++) {
                    double eu = (double)f->u[i] - d[0], ev = (double)f->v[i] - d[1];
                    sq += eu * eu + ev * ev;
                    if (eu * eu + ev * ev > 0.25)
                        out++;
                    else
                        sq_in += eu * eu + ev * ev;
                    mu += eu;
                    mv += ev;
                    repl += f->flag[i] == RPIV_FLAG_REPLACED;
                }
                cnt += (long)nv;
                nk += (long)nv;
                rpiv_field_free(f);
            }
            mu /= (double)nk;
            mv /= (double)nk;
            fr[2 * k] = s;
            me[2 * k] = mu;
            fr[2 * k + 1] = -s;
            me[2 * k + 1] = mv;
            worst_mean = fmax(worst_mean, fmax(fabs(mu), fabs(mv)));
        }
        printf("ppp %.3f: RMS %.4f px, peak-locking %.4f px, worst |mean| %.4f px, replaced "
               "%.2f %%, off by > 0.5 px %.2f %% (RMS without them %.4f px)\n",
               o.ppp[q], sqrt(sq / (2.0 * (double)cnt)), ti_peak_locking(fr, me, 2 * ns),
               worst_mean, 100.0 * (double)repl / (double)cnt, 100.0 * (double)out / (double)cnt,
               sqrt(sq_in / (2.0 * (double)(cnt - out))));
        fflush(stdout);
    }
    rpiv_piv_free(pv);
    free(fr);
    free(me);
    free(a);
    free(b);
    return 0;
}
