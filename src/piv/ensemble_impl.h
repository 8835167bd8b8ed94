/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/ensemble_impl.h - the accumulator's insides, shared by ensemble.c (one pair at a
 * time, checkpoints) and ensemble_pairs.c (several pairs at a time). */
#ifndef RPIV_SRC_ENSEMBLE_IMPL_H
#define RPIV_SRC_ENSEMBLE_IMPL_H

#include "rpiv/deform.h"
#include "rpiv/ensemble.h"
#include "rpiv/xcorr.h"

#include "piv_impl.h"

#include <stdint.h>

struct rpiv_ensemble {
    rpiv_piv *pv;
    int pass;
    rpiv_field *predictor;  /* copy, NULL for none */
    rpiv_deform_pred *pred; /* its interpolant     */
    piv_notch notch;        /* the interpolant's notch (piv_pred_notch_ensemble) */
    uint64_t pred_hash;
    size_t plane; /* floats per plane    */
    size_t nwin;
    size_t n;    /* floats in data      */
    float *data; /* planes, then energies */
    size_t npairs;
    float *scratch; /* with piv.uncertainty: two planes per thread (ensemble_unc.c), else NULL */
};

/* One pair's correlation-statistics sums per window (ensemble_unc.c). */
#define ENS_UNC_SUMS 8
/* The second moments of the pairs' plane samples within +-ENS_UNC_R px of zero shift (the
 * upper triangle of the (2R+1)^2 x (2R+1)^2 matrix), per window after the 8 sums. */
#define ENS_UNC_R 3
#define ENS_UNC_MOM                                                                                \
    ((2 * ENS_UNC_R + 1) * (2 * ENS_UNC_R + 1) * ((2 * ENS_UNC_R + 1) * (2 * ENS_UNC_R + 1) + 1) / \
     2)
/* Floats per window of the uncertainty's sums, after the energies. */
#define ENS_UNC_STRIDE (ENS_UNC_SUMS + ENS_UNC_MOM)

/* The floats the uncertainty adds to pass `pass`'s sums: 0 with piv.uncertainty off. */
size_t ens_unc_floats(const rpiv_piv *pv, int pass);

/* One pair's sums of window win's correlation statistics (plane: its raw plane; xs: the
 * window pair as correlated; scratch: two planes of floats). */
void ens_unc_pair(const rpiv_ensemble *e, const float *plane, const rpiv_xcorr_src *xs,
                  float *scratch, double sums[ENS_UNC_SUMS]);

/* Add one pair's sums of window win to e's, and the second moments of its plane's samples
 * near zero shift, in the order of the pairs. */
void ens_unc_add(rpiv_ensemble *e, size_t win, const double sums[ENS_UNC_SUMS], const float *plane);

/* sigma_u, sigma_v of the finished field f of e (validated); fell[win] 1 where the spline's
 * check (ensemble.c) put the 3-point fit plus the neighbours' correction in its place. */
RPIV_NODISCARD rpiv_status ens_unc_finish(const rpiv_ensemble *e, rpiv_field *f,
                                          const unsigned char *fell);

#endif /* RPIV_SRC_ENSEMBLE_IMPL_H */
