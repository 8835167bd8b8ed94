/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/tools/shear_particles.c - issue 15, the planes' skew at the particle level
 * (docs/ccm.md, "Session 9: the planes' skew"; diagnostics, not built by CMake). The
 * experiment of test_peak_shear (192 x 128 px, the skewed R-PIV sheet, the duct at 5.9 px,
 * d_e 1.8 px) : synth's own particles of pairs 0 .. N-1, moved and imaged by synth's own
 * functions (rpiv_synth_advect, rpiv_synth_image_model), each particle one exact correlation
 * term (its A image's peak and sigma times its B image's, at its displacement, the pixels'
 * triangle), summed over the particles whose mid position lies in a box of half-side H px
 * about the window's centre; against the CCM's term list of that window (rpiv_ccm_stat_corr,
 * as rpiv_config_ccm_predict). Printed per window: the volume-weighted mean, standard
 * deviation and third central moment of the displacement, the mean term variance, the
 * continuous peak and the spline's estimate, and the planes along x about the CCM's
 * estimate relative to its value there.
 *   shear_particles pairs half_box [xc yc ...]
 * Env: SP_SAME_ILLUM=1 (both frames lit at the particle's mid position: the CCM's hypothesis
 * I1 = I2), SP_NOSPREAD=1 (every d_p the model's), SP_SEED=S.
 * Build (from build/): cc -O2 -fopenmp -std=c11 -D_DEFAULT_SOURCE -I../tests -I../include
 *   -Iinclude -I../src/piv -I../src/base ../tests/tools/shear_particles.c -o shear_particles
 *   librpiv.a -lfftw3f -lgsl -lgslcblas -ltiff -lpng16 -lnetcdf -lplplot -lstb -ljpeg -lm
 *   -L/usr/lib/x86_64-linux-gnu/openmpi/lib -lmpi */
#include "rpiv/ccm.h"
#include "rpiv/config.h"
#include "rpiv/synth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct mom {
    double v, m1, m2, m3, w; /* volume, sums of V dx, V dx^2, V dx^3, V var */
} mom;

static void mom_add(mom *m, const rpiv_ccm_gauss *g)
{
    double v = g->amp * M_PI / g->c;
    m->v += v;
    m->m1 += v * g->dx;
    m->m2 += v * g->dx * g->dx;
    m->m3 += v * g->dx * g->dx * g->dx;
    m->w += v / (2 * g->c);
}

static void mom_print(const char *what, const mom *m)
{
    double a = m->m1 / m->v, b = m->m2 / m->v - a * a;
    double c3 = m->m3 / m->v - 3 * a * m->m2 / m->v + 2 * a * a * a;
    printf("    %-9s mean %.4f std %.4f third %.4f (skew %.4f), term variance %.4f px^2\n", what, a,
           sqrt(b), c3, c3 / pow(b, 1.5), m->w / m->v);
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: shear_particles pairs half_box [xc yc ...]\n");
        return 2;
    }
    int npairs = atoi(argv[1]);
    double hb = atof(argv[2]);
    rpiv_experiment ex = rpiv_experiment_default();
    ex.synth.width_px = 192;
    ex.synth.height_px = 128;
    ex.synth.pairs = npairs;
    ex.synth.dt_s = 0.8e-3;
    if (getenv("SP_SEED") && rpiv_config_set(&ex, "synth", "seed", getenv("SP_SEED"), "env"))
        return 1;
    int same = getenv("SP_SAME_ILLUM") != NULL, nospread = getenv("SP_NOSPREAD") != NULL;
    rpiv_synth *s = NULL;
    if (rpiv_config_synth_new(&ex, NULL, &s))
        return 1;
    rpiv_synth_info in;
    rpiv_synth_get_info(s, &in);
    printf("x* %.4f..%.4f (%.3e per px), bulk %.3f px, d_e %.3f px, %zu particles a pair\n",
           in.x0_star, in.x0_star + 192 * in.star_per_px, in.star_per_px, in.bulk_px,
           in.de_focus_px, in.nparticles);
    int nw = (argc - 3) / 2;
    double def[] = {24, 64, 96, 64, 168, 64, 96, 24, 96, 104};
    double *cen = nw ? NULL : def;
    if (!nw)
        nw = 5;
    rpiv_ccm_corr **pc = calloc((size_t)nw, sizeof *pc);
    mom *pm = calloc((size_t)nw, sizeof *pm);
    double *xc = malloc((size_t)nw * sizeof *xc), *yc = malloc((size_t)nw * sizeof *yc);
    for (int k = 0; k < nw; k++) {
        xc[k] = cen ? cen[2 * k] : atof(argv[3 + 2 * k]);
        yc[k] = cen ? cen[2 * k + 1] : atof(argv[4 + 2 * k]);
        if (rpiv_ccm_corr_new(0, &pc[k]))
            return 1;
    }
    rpiv_ccm_model mo0 = rpiv_config_ccm_model(&ex, ex.synth.dt_s);
    for (int i = 0; i < npairs; i++) {
        rpiv_synth_particle *p;
        size_t n;
        if (rpiv_synth_particles_new(s, (unsigned long)i, &p, &n))
            return 1;
        for (size_t q = 0; q < n; q++) {
            if (nospread)
                p[q].dp_m = ex.particles.dp_m;
            for (int k = 0; k < nw; k++) {
                if (fabs(p[q].x - xc[k]) > hb || fabs(p[q].y - yc[k]) > hb)
                    continue;
                rpiv_synth_particle a, b;
                rpiv_synth_advect(s, &p[q], -0.5, &a);
                rpiv_synth_advect(s, &p[q], 0.5, &b);
                double pa, pb, sa, sb;
                if (same) { /* both frames lit at the mid position, imaged where they are */
                    rpiv_synth_image_model(s, &p[q], &pa, NULL, &sa);
                    pb = pa;
                    sb = sa;
                } else {
                    rpiv_synth_image_model(s, &a, &pa, NULL, &sa);
                    rpiv_synth_image_model(s, &b, &pb, NULL, &sb);
                }
                double vs = sa * sa + sb * sb;
                rpiv_ccm_gauss g = {pa * pb * 2 * M_PI * sa * sa * sb * sb / vs, 1 / (2 * vs),
                                    b.x - a.x, b.y - a.y, mo0.pixel_box};
                if (!(g.amp > 0))
                    continue;
                mom_add(&pm[k], &g);
                if (rpiv_ccm_corr_add(pc[k], g))
                    return 1;
            }
        }
        rpiv_synth_particles_free(p);
    }
    rpiv_sheet *sheet = NULL;
    rpiv_ccm_params prm = rpiv_ccm_params_default();
    rpiv_ccm_work *w = NULL;
    if (rpiv_sheet_new(&ex.sheet, &sheet) || rpiv_ccm_work_new(&prm, &w))
        return 1;
    for (int k = 0; k < nw; k++) {
        double xs = in.x0_star + (xc[k] + 0.5) * in.star_per_px;
        double ys = in.y0_star + (yc[k] + 0.5) * in.star_per_px;
        rpiv_ccm_model mo = mo0;
        mo.u = (rpiv_ccm_func){rpiv_ccm_duct_fn, &ys};
        rpiv_ccm_sheet_at at = {sheet, xs};
        mo.illum = (rpiv_ccm_func){rpiv_ccm_sheet_fn, &at};
        rpiv_ccm_corr *c = NULL;
        if (rpiv_ccm_corr_new(0, &c) || rpiv_ccm_stat_corr(&mo, w, c))
            return 1;
        mom cm = {0};
        for (size_t t = 0; t < c->n; t++)
            mom_add(&cm, &c->g[t]);
        rpiv_ccm_peak kc, kp;
        if (rpiv_ccm_corr_peak(c, &prm, &kc) || rpiv_ccm_corr_peak(pc[k], &prm, &kp))
            return 1;
        printf("window (%g, %g) x* %.4f y* %.4f: %zu particles\n", xc[k], yc[k], xs, ys, pc[k]->n);
        mom_print("CCM", &cm);
        mom_print("particles", &pm[k]);
        printf("    peak: CCM %.4f (spline %.4f), particles %.4f (spline %.4f): diff %+.4f "
               "(%+.4f)\n",
               kc.dx, kc.dx_sub, kp.dx, kp.dx_sub, kp.dx - kc.dx, kp.dx_sub - kc.dx_sub);
        double up = kc.dx_sub, vp = 0, c0 = rpiv_ccm_corr_eval(c, up, vp),
               p0 = rpiv_ccm_corr_eval(pc[k], up, vp);
        printf("    plane along x about %.3f: CCM      ", up);
        for (int i = -3; i <= 3; i++)
            printf(" %.4f", rpiv_ccm_corr_eval(c, up + i, vp) / c0);
        printf("\n                             particles");
        for (int i = -3; i <= 3; i++)
            printf(" %.4f", rpiv_ccm_corr_eval(pc[k], up + i, vp) / p0);
        printf("\n");
        rpiv_ccm_corr_free(c);
        rpiv_ccm_corr_free(pc[k]);
    }
    rpiv_ccm_work_free(w);
    rpiv_sheet_free(sheet);
    rpiv_synth_free(s);
    free(pc);
    free(pm);
    free(xc);
    free(yc);
    return 0;
}
