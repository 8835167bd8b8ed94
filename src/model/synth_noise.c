/* SPDX-License-Identifier: GPL-3.0-or-later */
/* The shot-noise tables of the generator: Walker tables of Poisson(background + k POIS_STEP)
 * (synth_impl.h); the draw itself is in synth.c, next to the pixels. */
#include "synth_impl.h"

#include <math.h>
#include <stdlib.h>

/* Range of counts tabulated for Poisson(mu): beyond 12 sd + 40 counts either side the mass is
 * below 1e-30. */
static void pois_range(double mu, long *k0, long *k1)
{
    double sd = sqrt(mu);
    *k0 = (long)floor(mu - 12 * sd - 40);
    *k1 = (long)ceil(mu + 12 * sd + 40);
    if (*k0 < 0)
        *k0 = 0;
}

rpiv_status synth_poisson_tables(rpiv_synth *s)
{
    double bg = s->e.synth.background;
    long k0, k1;
    /* at most POIS_ENTRIES table entries in all (16 bytes each): fewer tables for a high
     * background */
    int nt = POIS_TABLES;
    for (;;) {
        pois_range(bg + (nt - 1) * POIS_STEP, &k0, &k1);
        if (nt == 1 || (double)nt * (double)(k1 - k0 + 1) <= POIS_ENTRIES)
            break;
        nt /= 2;
    }
    s->npt = nt;
    s->ptab = calloc((size_t)nt, sizeof *s->ptab);
    s->ptab_k0 = calloc((size_t)nt, sizeof *s->ptab_k0);
    double *p = malloc((size_t)(k1 - k0 + 1) * sizeof *p); /* the largest table */
    if (!s->ptab || !s->ptab_k0 || !p)
        goto out_nomem;
    for (int t = 0; t < nt; t++) {
        double mu = bg + t * POIS_STEP;
        if (mu == 0)
            continue; /* Poisson(0) = 0: no table */
        pois_range(mu, &k0, &k1);
        /* the pmf from its mode outward by the ratios p(k+1)/p(k) = mu/(k+1) */
        long km = (long)floor(mu), n = k1 - k0 + 1;
        p[km - k0] = gsl_ran_poisson_pdf((unsigned int)km, mu);
        for (long k = km + 1; k <= k1; k++)
            p[k - k0] = p[k - 1 - k0] * mu / (double)k;
        for (long k = km - 1; k >= k0; k--)
            p[k - k0] = p[k + 1 - k0] * (double)(k + 1) / mu;
        s->ptab[t] = gsl_ran_discrete_preproc((size_t)n, p);
        if (!s->ptab[t])
            goto out_nomem;
        s->ptab_k0[t] = k0;
    }
    free(p);
    return RPIV_OK;
out_nomem:
    free(p);
    return rpiv_fail(RPIV_ENOMEM, "synth: out of memory (shot-noise tables)");
}
