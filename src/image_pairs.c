/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image_pairs.c - image pairs from files, double-frame files, lists and globs. */
#include "image_impl.h"

#include <stdlib.h>

void rpiv_pairs_free(rpiv_pairs *p)
{
    if (!p)
        return;
    for (size_t i = 0; i < p->n; i++) {
        free(p->pair[i].path_a);
        free(p->pair[i].path_b);
    }
    free(p->pair);
    free(p);
}

rpiv_status rpiv_pairs_from_args(int nargs, char *const *args, rpiv_pairing rule,
                                 rpiv_pairs **out)
{
    (void)nargs, (void)args, (void)rule;
    *out = NULL;
    return rpiv_fail(RPIV_EINVAL, "image pairs: not implemented yet");
}

rpiv_status rpiv_pairs_load(const rpiv_pairs *p, size_t i, rpiv_image **a, rpiv_image **b)
{
    (void)p, (void)i;
    *a = *b = NULL;
    return rpiv_fail(RPIV_EINVAL, "image pairs: not implemented yet");
}
