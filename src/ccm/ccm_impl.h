/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Shared inside the ccm module (src/ccm*.c); not installed. */
#ifndef RPIV_CCM_IMPL_H
#define RPIV_CCM_IMPL_H

#include "rpiv/ccm.h"

#include <gsl/gsl_errno.h>
#include <gsl/gsl_integration.h>
#include <stdint.h>
#include <stdio.h>

struct rpiv_ccm_work {
    rpiv_ccm_params p;
    gsl_integration_workspace *iw;
    gsl_integration_glfixed_table *gl;
    double *scan_z, *scan_v; /* p.scan samples */
    double *ia, *ib;         /* intervals of the last adaptive pass (p.limit) */
    size_t nint;
    rpiv_ccm_corr *corr;                /* the rule of rpiv_ccm_predict */
    gsl_integration_glfixed_table *gl1; /* coarse rule of the first pass */
    double *zn;                         /* heights of the terms of the last rule built */
    size_t zcap;
};

/* Per-model quantities fixed for one window: the reference amplitude and pixel pitch. */
typedef struct ccm_frame {
    const rpiv_ccm_model *m;
    double pixel_m; /* sensor pixel pitch */
    double ref;     /* R_D peak of the reference particle (normalisation) */
    double pnorm;   /* 1 / int P dz */
} ccm_frame;

void ccm_frame_init(ccm_frame *f, const rpiv_ccm_model *m);

/* The term of one particle (Eq. "CCM_gen"), relative to the reference. */
rpiv_ccm_gauss ccm_term(const ccm_frame *f, double z1, double z2, double i1, double i2, double dp1,
                        double dp2, double ddx, double ddy);
/* The Eq. "CCM_simp" term of a particle at height z (I0, d_e, DX, DY from the model);
 * ccm_amp_term: the same without evaluating the velocity (DX = DY = 0). */
rpiv_ccm_gauss ccm_amp_term(const ccm_frame *f, double z);
rpiv_ccm_gauss ccm_simp_term(const ccm_frame *f, double z);

/* The velocity profile of a model tabulated on p->utab nodes of [zlo, zhi] (Akima spline),
 * when p->utab > 0: *tm is a copy of m whose u (and v) read the table. Release with
 * ccm_utab_free. */
typedef struct ccm_utab {
    void *su, *sv; /* gsl_spline */
    rpiv_ccm_func u0, v0;
    double zlo, zhi;
} ccm_utab;
RPIV_NODISCARD rpiv_status ccm_utab_init(ccm_utab *t, const rpiv_ccm_model *m,
                                         const rpiv_ccm_params *p, rpiv_ccm_model *tm);
void ccm_utab_free(ccm_utab *t);

/* Presence law P(z) (unnormalised; 1 when the model has none). */
double ccm_presence(const rpiv_ccm_model *m, double z);

/* Along one axis, exp(-c e^2) convolved with the unit-area triangle of half-width b (the
 * pixels' box of side b correlated with itself; b = 0: the Gaussian): value, first and second
 * derivatives at e. ccm_term_eval: one term at offset (ex, ey) from its displacement. */
void ccm_axis(double e, double c, double b, double *f, double *fd, double *fdd);
double ccm_term_eval(const rpiv_ccm_gauss *g, double ex, double ey);

/* The integer-sampled maximum of R (1-D along the common DY row when all DY are equal). */
RPIV_NODISCARD rpiv_status ccm_sampled_max(const rpiv_ccm_corr *c, const rpiv_ccm_params *p,
                                           int *mx, int *my);

/* The sampled plane (R at (mx + i, my + j), |i|, |j| <= ccm_subpixel_rad(p), into
 * rows[j + rad][i + rad]) around the integer-sampled maximum (mx, my), and the engine's
 * sub-pixel estimator on it with base added to every sample (ccm_subpixel: the estimate
 * (dx_sub, dy_sub), px). rad: 3 for the spline, else 1. */
/* R at the integer lattice (xa + i, ya + j), 0 <= i < nx, 0 <= j < ny, into r (row j at
 * r + j nx); fx, fy: scratch of nx and ny values. */
void ccm_lattice(const rpiv_ccm_corr *c, int xa, int nx, int ya, int ny, double *r, double *fx,
                 double *fy);
int ccm_subpixel_rad(const rpiv_ccm_params *p);
RPIV_NODISCARD rpiv_status ccm_sampled_rows(const rpiv_ccm_corr *c, const rpiv_ccm_params *p,
                                            double rows[7][7], int *mx, int *my);
/* sig (or NULL): the estimator's branch on this plane, equal for two planes on which it takes
 * the same path: bit k = sample k it reads is > 0 (its logarithms need that; the 7 x 7 spline
 * falls to 5 x 5, then to the 3-point Gaussian), bit 62 = the spline fell back to the 3-point
 * Gaussian, bit 63 = the fit succeeded. */
void ccm_subpixel(double rows[7][7], const rpiv_ccm_params *p, double base, int mx, int my,
                  double *dx_sub, double *dy_sub, uint64_t *sig);

/* What the window's estimate depends on discontinuously (ccm_bias.c interpolates it between
 * vectors of equal signatures): the sampled maximum (mx, my) and the estimator's path (sig,
 * ccm_subpixel's) on the last pass's plane, and whether the passes converged (0: they cycle
 * between two estimates, and the estimate is the last pass's). */
typedef struct ccm_wsig {
    int conv, mx, my;
    uint64_t sig;
    double w7, w3; /* with the ensemble's noise: the 7 x 7 and 3-point paths' weights */
} ccm_wsig;

/* A part of a window (the area average, ccm_area.c): its terms c->g[t0 .. t1) of the summed
 * list, moved there by minus the deformation's variation (sx, sy) at it. */
typedef struct ccm_sub {
    size_t t0, t1;
    double sx, sy;
} ccm_sub;

/* rpiv_ccm_corr_peak_window with the signature (sig may be NULL; with an infinite window
 * conv = 1 and the rest 0) and, with deform, the window's parts (sub, nsub; NULL: c is one
 * part, not moved), each deformed by its own predictor. */
RPIV_NODISCARD rpiv_status ccm_corr_peak_window_sig(const rpiv_ccm_corr *c, const ccm_sub *sub,
                                                    size_t nsub, const rpiv_ccm_params *p,
                                                    int win_w, int win_h, int deform, double npairs,
                                                    rpiv_ccm_peak *out, ccm_wsig *sig);
/* rpiv_ccm_predict with the signature (NULL: none). */
RPIV_NODISCARD rpiv_status ccm_predict_sig(const rpiv_ccm_model *m, rpiv_ccm_work *w,
                                           rpiv_ccm_peak *out, ccm_wsig *sig);

/* Breakpoints for the quadrature over [zlo, zhi]: zlo, the model's breaks, z*_OP, the sampled
 * maxima and quarter-height crossings of I0 and P, zhi; sorted, unique. Returns the count. */
size_t ccm_breakpoints(const rpiv_ccm_model *m, rpiv_ccm_work *w, double *pts, size_t cap);

/* Mix (seed, index) into one 32-bit-safe RNG seed (splitmix64). */
unsigned long ccm_seed(unsigned long seed, unsigned long index);

/* Write each line of hdr prefixed with "# ". */
void ccm_file_header(FILE *fp, const char *hdr);

/* GSL status -> rpiv status with a message naming what failed. */
static inline rpiv_status ccm_gsl_fail(int gsl_status, const char *what)
{
    return rpiv_fail(RPIV_ENUMERIC, "ccm: %s failed: %s", what, gsl_strerror(gsl_status));
}

#endif /* RPIV_CCM_IMPL_H */
