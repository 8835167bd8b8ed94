/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/ensemble_impl.h - the accumulator's insides, shared by ensemble.c (one pair at a
 * time, checkpoints) and ensemble_pairs.c (several pairs at a time). */
#ifndef RPIV_SRC_ENSEMBLE_IMPL_H
#define RPIV_SRC_ENSEMBLE_IMPL_H

#include "rpiv/deform.h"
#include "rpiv/ensemble.h"

#include <stdint.h>

struct rpiv_ensemble {
    rpiv_piv *pv;
    int pass;
    rpiv_field *predictor;  /* copy, NULL for none */
    rpiv_deform_pred *pred; /* its interpolant     */
    uint64_t pred_hash;
    size_t plane; /* floats per plane    */
    size_t nwin;
    size_t n;    /* floats in data      */
    float *data; /* planes, then energies */
    size_t npairs;
};

#endif /* RPIV_SRC_ENSEMBLE_IMPL_H */
