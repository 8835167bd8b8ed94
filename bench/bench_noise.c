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
 *   deform_smooth=S (params deform_smooth) weight=W (params window_weight) */
#include "../tests/piv_testimg.h"
#include "rpiv/piv.h"

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
    double deform_smooth, weight, rfilter;
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

/* Least-squares fit of e(f) = a0 + sum_{h=1,2} a_h sin(2 pi h f) + b_h cos(2 pi h f) to n
 * points (Gauss-Jordan on the 5 x 5 normal equations); the largest |periodic part| over f. */
static double locking(const double *f, const double *e, int n)
{
    double A[5][6] = {{0}};
    for (int i = 0; i < n; i++) {
        double b[5] = {1, sin(2 * M_PI * f[i]), cos(2 * M_PI * f[i]), sin(4 * M_PI * f[i]),
                       cos(4 * M_PI * f[i])};
        for (int r = 0; r < 5; r++) {
            for (int c = 0; c < 5; c++)
                A[r][c] += b[r] * b[c];
            A[r][5] += b[r] * e[i];
        }
    }
    for (int c = 0; c < 5; c++) {
        int piv = c;
        for (int r = c + 1; r < 5; r++)
            if (fabs(A[r][c]) > fabs(A[piv][c]))
                piv = r;
        for (int k = 0; k < 6; k++) {
            double t = A[c][k];
            A[c][k] = A[piv][k];
            A[piv][k] = t;
        }
        for (int r = 0; r < 5; r++)
            if (r != c) {
                double m = A[r][c] / A[c][c];
                for (int k = 0; k < 6; k++)
                    A[r][k] -= m * A[c][k];
            }
    }
    double co[5], amp = 0;
    for (int r = 0; r < 5; r++)
        co[r] = A[r][5] / A[r][r];
    for (int k = 0; k < 200; k++) {
        double t = k / 200.0;
        double v = co[1] * sin(2 * M_PI * t) + co[2] * cos(2 * M_PI * t) +
                   co[3] * sin(4 * M_PI * t) + co[4] * cos(4 * M_PI * t);
        amp = fmax(amp, fabs(v));
    }
    return amp;
}

int main(int argc, char **argv)
{
    opts o = {512, 3, {0.02, 0.05}, 2, 1.5, 0.1, 2.0, "64,32,32", "gauss", "none", 0, 0, 0};
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
        else if (!strncmp(a, "deform_smooth=", 14))
            o.deform_smooth = atof(v);
        else if (!strncmp(a, "rfilter=", 8))
            o.rfilter = atof(v);
        else if (!strncmp(a, "weight=", 7))
            o.weight = atof(v);
        else {
            fprintf(stderr, "bench_noise: unknown key in '%s'\n", a);
            return 2;
        }
    }
    rpiv_piv_params prm = rpiv_piv_params_default();
    parse_passes(o.passes, &prm);
    prm.refine_filter = o.rfilter;
    prm.subpixel = !strcmp(o.sub, "parabola")   ? RPIV_SUBPIXEL_PARABOLA
                   : !strcmp(o.sub, "centroid") ? RPIV_SUBPIXEL_CENTROID
                                                : RPIV_SUBPIXEL_GAUSS;
#ifdef BENCH_NOISE_HAVE_PARAMS
    prm.deform_smooth = o.deform_smooth;
    prm.window_weight = o.weight;
#endif
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
    printf("# size %d, d %.2f px, SNR %.1f, passes %s, sub %s, pre %s, deform_smooth %g, "
           "weight %g, %d seeds, shifts 0..%.1f px\n",
           n, o.d, o.noise > 0 ? 1 / o.noise : (double)INFINITY, o.passes, o.sub, o.pre,
           o.deform_smooth, o.weight, o.seeds, o.smax);
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
               o.ppp[q], sqrt(sq / (2.0 * (double)cnt)), locking(fr, me, 2 * ns), worst_mean,
               100.0 * (double)repl / (double)cnt, 100.0 * (double)out / (double)cnt,
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
