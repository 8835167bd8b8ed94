/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Shared inside the synth part of the model module (synth.c, synth_presence.c,
 * synth_noise.c); not installed. */
#ifndef RPIV_SYNTH_IMPL_H
#define RPIV_SYNTH_IMPL_H

#include "rpiv/synth.h"

#include <gsl/gsl_randist.h>
#include <gsl/gsl_rng.h>

/* Shot noise draws Poisson(m) as Poisson(m_k) + Poisson(m - m_k), exact in distribution,
 * with m_k = background + k POIS_STEP the largest tabulated mean below m (Walker tables of
 * GSL, O(1) per draw) and the small remainder from gsl_ran_poisson's direct method; means
 * beyond the last table draw the whole excess from gsl_ran_poisson. */
#define POIS_STEP    4.0
#define POIS_ENTRIES 2e6
enum { POIS_TABLES = 512 };

struct rpiv_synth {
    rpiv_synth_setup e;         /* the parameters, copied                           */
    rpiv_sheet *sheet;          /* I0(x*, z*)                                       */
    rpiv_flow flow;             /* displacement over dt, px                         */
    int w, h;                   /* image size                                       */
    double pix_m;               /* sensor pixel pitch                               */
    double spp;                 /* x* (= y*) per image pixel                        */
    double x0s, y0s;            /* x*, y* of the left and top image edges           */
    double reg[4];              /* particle region x0, y0, x1, y1, px               */
    size_t n;                   /* particles per pair                               */
    double norm;                /* peak_counts / model peak of the reference particle */
    double de0_m;               /* d_e of the reference particle in focus           */
    int invariant;              /* 1: the displacement is constant along a path     */
    size_t npz;                 /* P(z*) table rows (0 = uniform)                   */
    double *pz_z, *pz_p, *pz_c; /* nodes, density, cumulative integral      */
    gsl_ran_discrete_t **ptab;  /* shot noise: Poisson(background + k POIS_STEP) */
    long *ptab_k0;              /* first count of each table                */
    int npt;                    /* number of tables                         */
    double maxval;              /* 2^bits - 1                               */
};

/* Read the P(z*) table at path into s->npz, pz_z, pz_p and pz_c (synth_presence.c).
 * Errors: RPIV_EIO, RPIV_EFORMAT naming path:line, RPIV_ENOMEM. */
RPIV_NODISCARD rpiv_status synth_pz_load(rpiv_synth *s, const char *path);
/* A height z* drawn from P(z*) (uniform on [0, 1] without a table). */
double synth_pz_sample(const rpiv_synth *s, gsl_rng *r);
/* The shot-noise tables s->ptab, ptab_k0, npt for s->e.synth.background (synth_noise.c). */
RPIV_NODISCARD rpiv_status synth_poisson_tables(rpiv_synth *s);

#endif /* RPIV_SYNTH_IMPL_H */
