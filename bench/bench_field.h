/* SPDX-License-Identifier: GPL-3.0-or-later */
/* bench/bench_field.h - a field's error against the benchmarks' uniform displacement. */
#ifndef RPIV_BENCH_FIELD_H
#define RPIV_BENCH_FIELD_H

#include "rpiv/field.h"

#include <math.h>

/* RMS error of f against the uniform displacement d, worst component, over every vector. */
static inline double bench_field_rms(const rpiv_field *f, const double d[2])
{
    double su = 0, sv = 0;
    size_t n = (size_t)f->nx * (size_t)f->ny;
    for (size_t k = 0; k < n; k++) {
        double eu = (double)f->u[k] - d[0], ev = (double)f->v[k] - d[1];
        su += eu * eu;
        sv += ev * ev;
    }
    return sqrt(fmax(su, sv) / (double)n);
}

#endif /* RPIV_BENCH_FIELD_H */
