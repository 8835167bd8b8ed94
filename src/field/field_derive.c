/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field/field_derive.c - derived quantities of a vector field: vorticity, divergence,
 * strain rates, swirling strength, Q criterion (rpiv/field.h, docs/postprocess.md). */
#include "rpiv/field.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const struct {
    const char *item;
    unsigned bit;
} derive_items[] = {{"vorticity", RPIV_DERIVE_VORTICITY},
                    {"divergence", RPIV_DERIVE_DIVERGENCE},
                    {"strain", RPIV_DERIVE_STRAIN},
                    {"swirl", RPIV_DERIVE_SWIRL},
                    {"q", RPIV_DERIVE_Q}};
#define NITEMS (sizeof derive_items / sizeof derive_items[0])
#define ALL_BITS                                                                                   \
    (RPIV_DERIVE_VORTICITY | RPIV_DERIVE_DIVERGENCE | RPIV_DERIVE_STRAIN | RPIV_DERIVE_SWIRL |     \
     RPIV_DERIVE_Q)

rpiv_status rpiv_field_derive_parse(const char *list, unsigned *what)
{
    *what = 0;
    if (!list || !list[0] || !strcmp(list, "none"))
        return RPIV_OK;
    const char *s = list;
    while (*s) {
        size_t len = strcspn(s, ",");
        unsigned bit = 0;
        if (len == 3 && !strncmp(s, "all", 3))
            bit = ALL_BITS;
        for (size_t k = 0; k < NITEMS && !bit; k++)
            if (strlen(derive_items[k].item) == len && !strncmp(s, derive_items[k].item, len))
                bit = derive_items[k].bit;
        if (!bit)
            return rpiv_fail(RPIV_EINVAL,
                             "derived: '%.*s' is not vorticity, divergence, strain, swirl, q "
                             "or all",
                             (int)len, s);
        *what |= bit;
        s += len;
        if (*s == ',')
            s++;
    }
    return RPIV_OK;
}

/* Is point (i, j) usable for a difference: inside the grid and not masked. */
static int usable(const rpiv_field *f, int i, int j)
{
    return i >= 0 && j >= 0 && i < f->nx && j < f->ny &&
           f->flag[(size_t)j * (size_t)f->nx + (size_t)i] != RPIV_FLAG_MASKED;
}

/* d(a)/ds at (i, j) along the grid direction (di, dj) with step h: least squares over
 * +-2 points, else central, else one-sided, else 0. */
static double diff(const rpiv_field *f, const float *a, int i, int j, int di, int dj, double h)
{
    const size_t nx = (size_t)f->nx;
#define A(s)  ((double)a[(size_t)(j + (s)*dj) * nx + (size_t)(i + (s)*di)])
#define OK(s) usable(f, i + (s)*di, j + (s)*dj)
    if (OK(1) && OK(-1)) {
        if (OK(2) && OK(-2))
            return (2 * A(2) + A(1) - A(-1) - 2 * A(-2)) / (10 * h);
        return (A(1) - A(-1)) / (2 * h);
    }
    if (OK(1))
        return (A(1) - A(0)) / h;
    if (OK(-1))
        return (A(0) - A(-1)) / h;
    return 0;
#undef A
#undef OK
}

/* *d: the quantity `name` of f, added if absent, if bit is in what; else NULL. */
static rpiv_status quantity(rpiv_field *f, unsigned what, unsigned bit, const char *name, int unit,
                            float **d)
{
    *d = NULL;
    if (!(what & bit))
        return RPIV_OK;
    const rpiv_quantity *q = rpiv_field_quantity(f, name);
    if (q) {
        *d = q->data;
        return RPIV_OK;
    }
    return rpiv_field_add_quantity(f, name, unit, d);
}

rpiv_status rpiv_field_derive(rpiv_field *f, unsigned what)
{
    if (what & ~(unsigned)ALL_BITS)
        return rpiv_fail(RPIV_EINVAL, "derived: unknown quantity bits 0x%x", what);
    float *w = NULL, *dv = NULL, *sh = NULL, *nm = NULL, *sw = NULL, *qc = NULL;
    rpiv_status st;
    if ((st = quantity(f, what, RPIV_DERIVE_VORTICITY, "vorticity", RPIV_UNIT_PER_DT, &w)) ||
        (st = quantity(f, what, RPIV_DERIVE_DIVERGENCE, "divergence", RPIV_UNIT_PER_DT, &dv)) ||
        (st = quantity(f, what, RPIV_DERIVE_STRAIN, "shear_strain", RPIV_UNIT_PER_DT, &sh)) ||
        (st = quantity(f, what, RPIV_DERIVE_STRAIN, "normal_strain", RPIV_UNIT_PER_DT, &nm)) ||
        (st = quantity(f, what, RPIV_DERIVE_SWIRL, "swirling_strength", RPIV_UNIT_PER_DT, &sw)) ||
        (st = quantity(f, what, RPIV_DERIVE_Q, "q_criterion", RPIV_UNIT_PER_DT2, &qc)))
        return st;
    /* image coordinates (y down): d/dy and v both reverse in the physical frame, so
     * du/dy -> -du/dy, dv/dy -> dv/dy, dv/dx -> -dv/dx */
    const double s = f->y_up ? 1.0 : -1.0;
    for (int j = 0; j < f->ny; j++)
        for (int i = 0; i < f->nx; i++) {
            size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
            double ux = 0, uy = 0, vx = 0, vy = 0;
            if (f->flag[k] != RPIV_FLAG_MASKED) {
                ux = diff(f, f->u, i, j, 1, 0, f->dx);
                uy = s * diff(f, f->u, i, j, 0, 1, f->dy);
                vx = s * diff(f, f->v, i, j, 1, 0, f->dx);
                vy = diff(f, f->v, i, j, 0, 1, f->dy);
            }
            if (w)
                w[k] = (float)(vx - uy);
            if (dv)
                dv[k] = (float)(ux + vy);
            if (sh) {
                sh[k] = (float)(uy + vx);
                nm[k] = (float)(ux - vy);
            }
            if (sw) {
                double tr = ux + vy, det = ux * vy - uy * vx, d = det - 0.25 * tr * tr;
                sw[k] = d > 0 ? (float)sqrt(d) : 0.0f;
            }
            if (qc)
                qc[k] = (float)(-0.5 * (ux * ux + vy * vy) - uy * vx);
        }
    return RPIV_OK;
}
