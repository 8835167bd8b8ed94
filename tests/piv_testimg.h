/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/piv_testimg.h - synthetic PIV pairs for the PIV engine's tests and benchmark:
 * pixel-integrated Gaussian particles (erf integration), placed symmetrically about their
 * midpoint so that the displacement field is known exactly at every point:
 *     particle at x_m (uniform random), in A at x_m - d(x_m)/2, in B at x_m + d(x_m)/2.
 * The particle image diameter d_tau is the e^-2 diameter, d_tau = 4 sigma. Fixed seeds. */
#ifndef RPIV_TESTS_PIV_TESTIMG_H
#define RPIV_TESTS_PIV_TESTIMG_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef void (*ti_flow_fn)(void *user, double x, double y, double *u, double *v);

typedef struct ti_params {
    int w, h;
    double ppp;    /* particles per pixel */
    double d_tau;  /* particle image diameter, px */
    double peak;   /* grey level of a centred particle of full intensity */
    double noise;  /* Gaussian noise std, as a fraction of `peak` (0 = none) */
    double offset; /* constant background grey level */
    uint64_t seed;
} ti_params;

static inline double ti_rnd(uint64_t *s)
{
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    return (double)((*s * 2685821657736338717ULL) >> 11) * (1.0 / 9007199254740992.0);
}

static inline double ti_gauss(uint64_t *s)
{
    double u1 = ti_rnd(s), u2 = ti_rnd(s);
    if (u1 < 1e-300)
        u1 = 1e-300;
    return sqrt(-2 * log(u1)) * cos(6.283185307179586 * u2);
}

/* Add a pixel-integrated Gaussian particle of intensity amp at (xp, yp) to img (w x h). */
static inline void ti_particle(float *img, int w, int h, double xp, double yp, double sigma,
                               double amp)
{
    enum { R = 5 };
    double ex[2 * R + 1], ey[2 * R + 1], gx[2 * R + 2], gy[2 * R + 2];
    int cx = (int)floor(xp + 0.5), cy = (int)floor(yp + 0.5);
    double k = 1.0 / (sqrt(2.0) * sigma);
    /* erf at the pixels' edges, each edge shared by its two pixels */
    for (int i = -R; i <= R + 1; i++) {
        gx[i + R] = erf((cx + i - 0.5 - xp) * k);
        gy[i + R] = erf((cy + i - 0.5 - yp) * k);
    }
    for (int i = -R; i <= R; i++) {
        ex[i + R] = 0.5 * (gx[i + R + 1] - gx[i + R]);
        ey[i + R] = 0.5 * (gy[i + R + 1] - gy[i + R]);
    }
    /* normalised so that a particle centred on a pixel has that pixel at amp */
    double c0 = erf(0.5 * k);
    double s = amp / (c0 * c0);
    for (int j = -R; j <= R; j++) {
        int y = cy + j;
        if (y < 0 || y >= h)
            continue;
        for (int i = -R; i <= R; i++) {
            int x = cx + i;
            if (x < 0 || x >= w)
                continue;
            img[(size_t)y * (size_t)w + (size_t)x] += (float)(s * ex[i + R] * ey[j + R]);
        }
    }
}

/* Render a pair (a, b: w*h floats each, overwritten) of the flow fn. */
static inline void ti_pair(const ti_params *p, ti_flow_fn fn, void *user, float *a, float *b)
{
    uint64_t s = p->seed ? p->seed : 0x9e3779b97f4a7c15ULL;
    size_t n = (size_t)p->w * (size_t)p->h;
    const double margin = 16;
    double area = (p->w + 2 * margin) * (p->h + 2 * margin);
    long np = lround(p->ppp * area);
    double sigma = p->d_tau / 4;
    for (size_t i = 0; i < n; i++)
        a[i] = b[i] = (float)p->offset;
    for (long k = 0; k < np; k++) {
        double xm = -margin + ti_rnd(&s) * (p->w + 2 * margin);
        double ym = -margin + ti_rnd(&s) * (p->h + 2 * margin);
        double amp = p->peak * (0.6 + 0.4 * ti_rnd(&s)), u, v;
        fn(user, xm, ym, &u, &v);
        ti_particle(a, p->w, p->h, xm - 0.5 * u, ym - 0.5 * v, sigma, amp);
        ti_particle(b, p->w, p->h, xm + 0.5 * u, ym + 0.5 * v, sigma, amp);
    }
    if (p->noise > 0)
        for (size_t i = 0; i < n; i++) {
            a[i] += (float)(p->noise * p->peak * ti_gauss(&s));
            b[i] += (float)(p->noise * p->peak * ti_gauss(&s));
        }
}

/* Common flows. user points to a double[2] (uniform: u, v). */
static inline void ti_uniform(void *user, double x, double y, double *u, double *v)
{
    const double *d = user;
    (void)x;
    (void)y;
    *u = d[0];
    *v = d[1];
}

#endif /* RPIV_TESTS_PIV_TESTIMG_H */
