/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image/prep_impl.h - what the preprocessing files share (preprocess.c, prep_local.c,
 * prep_clahe.c). Not installed. */
#ifndef RPIV_PREP_IMPL_H
#define RPIV_PREP_IMPL_H

#include "rpiv/preprocess.h"

/* The operations, each on im in place with nt threads (nt >= 1). */
RPIV_NODISCARD rpiv_status prep_clahe(rpiv_image *im, int tile, double clip, int bins, int nt);
RPIV_NODISCARD rpiv_status prep_highpass(rpiv_image *im, int size, rpiv_prep_background how,
                                         int nt);
RPIV_NODISCARD rpiv_status prep_normalize(rpiv_image *im, int size, int nt);

/* The smallest and largest value of im (rpiv_image_stats_of). */
static inline void prep_range(const rpiv_image *im, float *lo, float *hi)
{
    rpiv_image_stats st = rpiv_image_stats_of(im);
    *lo = (float)st.min;
    *hi = (float)st.max;
}

#endif /* RPIV_PREP_IMPL_H */
