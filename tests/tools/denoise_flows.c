/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/tools/denoise_flows.c - the refinement denoiser's finest detail, refine_denoise_order 2
 * (second difference) against 4 (fourth, the default since session 13), on assorted flows with
 * known truth (docs/piv.md, "The first dilation's detail is the fourth difference"): 384 x 320
 * px pairs of tests/piv_testimg.h (0.05 ppp), 4 seeds a flow, the defaults otherwise; prints the
 * RMS error of all vectors (u and v) and the vectors off by more than 0.5 px.
 * Usage: denoise_flows [noise (fraction of the peak, 0.02)] [d_tau (px, 2.5)]
 * Build (from build/): cc -O2 -fopenmp -std=c11 -D_DEFAULT_SOURCE -I../tests -I../include
 *   -Iinclude ../tests/tools/denoise_flows.c -o denoise_flows librpiv.a -lfftw3f
 *   -lfftw3f_threads -lgsl -lgslcblas -ltiff -lpng16 -lnetcdf -lplplot -ljpeg -lm */
#include "piv_testimg.h"
#include "rpiv/field.h"
#include "rpiv/piv.h"

#include <math.h>
#include <stdio.h>

typedef struct {
    int kind;
    double a, b, cx, cy;
} flw;
static void fn(void *user, double x, double y, double *u, double *v)
{
    const flw *f = user;
    double dx = x - f->cx, dy = y - f->cy, r = sqrt(dx * dx + dy * dy);
    *u = *v = 0;
    switch (f->kind) {
    case 0: { /* Rankine vortex, peak a at rc = b */
        double ut = r < f->b ? f->a * r / f->b : f->a * f->b / (r > 1e-9 ? r : 1e-9);
        if (r > 1e-9) {
            *u = -ut * dy / r;
            *v = ut * dx / r;
        }
        break;
    }
    case 1: /* tanh shear layer u = a tanh(dy / b) */
        *u = f->a * tanh(dy / f->b);
        break;
    case 2: /* Gaussian jet u = a exp(-(dy/b)^2) */
        *u = f->a * exp(-dy * dy / (f->b * f->b));
        break;
    case 3: { /* Lamb-Oseen, peak a, rc b */
        double s = r / f->b, g = 0.6381726863;
        if (r > 1e-9) {
            double ut = f->a * (1 - exp(-s * s)) / s / g;
            *u = -ut * dy / r;
            *v = ut * dx / r;
        }
        break;
    }
    case 4: /* stagnation point + uniform */
        *u = 2.0 + f->a * dx / 100;
        *v = -f->a * dy / 100;
        break;
    case 5: /* boundary layer near y = cy: u = a (1 - exp(-dy/b)) for dy > 0, 0 below */
        *u = dy > 0 ? f->a * (1 - exp(-dy / f->b)) : 0;
        break;
    case 6: /* two counter-rotating Lamb-Oseen vortices */
    {
        flw g1 = {3, f->a, f->b, f->cx - 60, f->cy}, g2 = {3, -f->a, f->b, f->cx + 60, f->cy};
        double u1, v1, u2, v2;
        fn(&g1, x, y, &u1, &v1);
        fn(&g2, x, y, &u2, &v2);
        *u = u1 + u2;
        *v = v1 + v2;
    } break;
    }
}

int main(int argc, char **argv)
{
    const int W = 384, H = 320, NS = 4;
    const char *name[] = {
        "rankine 5px rc32",    "tanh 4px d8",    "tanh 4px d16", "jet 6px s20",
        "oseen 4px rc24",      "oseen 8px rc96", "stagnation",   "boundary layer 5px d10",
        "vortex pair 4px rc30"};
    flw cases[] = {{0, 5, 32, 191.3, 160.7}, {1, 4, 8, 191.3, 160.7},  {1, 4, 16, 191.3, 160.7},
                   {2, 6, 20, 191.3, 160.7}, {3, 4, 24, 191.3, 160.7}, {3, 8, 96, 191.3, 160.7},
                   {4, 3, 0, 191.3, 160.7},  {5, 5, 10, 100.3, 100.2}, {6, 4, 30, 191.3, 160.7}};
    double noise = argc > 1 ? atof(argv[1]) : 0.02, dtau = argc > 2 ? atof(argv[2]) : 2.5;
    float *a = malloc(W * H * 4), *b = malloc(W * H * 4);
    for (int c = 0; c < (int)(sizeof cases / sizeof *cases); c++) {
        double rms[2] = {0, 0};
        int nout[2] = {0, 0};
        for (int o = 0; o < 2; o++) {
            double se = 0;
            int n = 0;
            for (int s = 0; s < NS; s++) {
                ti_params tp = {W, H, 0.05, dtau, 1000, noise, 0, 900 + 17 * c + s};
                ti_pair(&tp, fn, &cases[c], a, b);
                rpiv_image ia = {W, H, 16, a}, ib = {W, H, 16, b};
                rpiv_piv_params prm = rpiv_piv_params_default();
                prm.refine_denoise_order = o ? 4 : 2;
                rpiv_piv *pv = NULL;
                rpiv_field *f = NULL;
                if (rpiv_piv_new(&prm, W, H, NULL, &pv) || rpiv_piv_run(pv, &ia, &ib, &f)) {
                    fprintf(stderr, "denoise_flows: the run failed\n");
                    return 1;
                }
                for (int j = 0; j < f->ny; j++)
                    for (int i = 0; i < f->nx; i++) {
                        double u, v;
                        fn(&cases[c], f->x0 + i * f->dx, f->y0 + j * f->dy, &u, &v);
                        size_t k = (size_t)j * f->nx + i;
                        double eu = f->u[k] - u, ev = f->v[k] - v;
                        se += eu * eu + ev * ev;
                        n += 2;
                        if (hypot(eu, ev) > 0.5)
                            nout[o]++;
                    }
                rpiv_field_free(f);
                rpiv_piv_free(pv);
            }
            rms[o] = sqrt(se / n);
        }
        printf("%-26s order 2: RMS %.4f (%d > 0.5 px)  order 4: RMS %.4f (%d)  ratio %.2f\n",
               name[c], rms[0], nout[0], rms[1], nout[1], rms[1] / rms[0]);
    }
    free(a);
    free(b);
    return 0;
}
