/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/field_hash.c - a field's identity for the passes: which predictor a step was given
 * (the uncertainty's chain, an ensemble's checkpoint, the refinement's repeats). The value is
 * the one ensemble checkpoints have stored since RPIVCKP4 (grid size, u, v, flags). */
#include "piv_impl.h"

#include "base/hash.h"

uint64_t piv_field_hash(const rpiv_field *f)
{
    uint64_t h = HASH0;
    if (!f)
        return h;
    const size_t n = (size_t)f->nx * (size_t)f->ny;
    const int dims[2] = {f->nx, f->ny};
    h = hash_bytes(h, dims, sizeof dims);
    h = hash_bytes(h, f->u, n * sizeof *f->u);
    h = hash_bytes(h, f->v, n * sizeof *f->v);
    return hash_bytes(h, f->flag, n);
}
