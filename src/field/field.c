/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field/field.c - the vector field: allocation, copy, meta data. */
#include "rpiv/field.h"

#include "field_impl.h"

#include <assert.h>
#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

/* ---- fields --------------------------------------------------------------- */

rpiv_status rpiv_field_new(int nx, int ny, double x0, double y0, double dx, double dy,
                           rpiv_field **out)
{
    *out = NULL;
    if (nx < 1 || ny < 1)
        return rpiv_fail(RPIV_EINVAL, "field: grid %d x %d is empty", nx, ny);
    if ((size_t)nx > SIZE_MAX / 16 / (size_t)ny)
        return rpiv_fail(RPIV_EINVAL, "field: grid %d x %d is too large", nx, ny);
    if (!isfinite(x0) || !isfinite(y0) || !isfinite(dx) || !isfinite(dy) || !(dx > 0) || !(dy > 0))
        return rpiv_fail(RPIV_EINVAL,
                         "field: grid origin (%g, %g) step (%g, %g) must be finite "
                         "with positive steps",
                         x0, y0, dx, dy);
    size_t n = (size_t)nx * (size_t)ny;
    rpiv_field *f = calloc(1, sizeof *f);
    if (!f)
        return rpiv_fail(RPIV_ENOMEM, "field: out of memory for %d x %d", nx, ny);
    f->nx = nx;
    f->ny = ny;
    f->x0 = x0;
    f->y0 = y0;
    f->dx = dx;
    f->dy = dy;
    f->u = calloc(n, sizeof *f->u);
    f->v = calloc(n, sizeof *f->v);
    f->flag = calloc(n, sizeof *f->flag);
    f->peak_ratio = calloc(n, sizeof *f->peak_ratio);
    f->corr = calloc(n, sizeof *f->corr);
    if (!f->u || !f->v || !f->flag || !f->peak_ratio || !f->corr) {
        rpiv_field_free(f);
        return rpiv_fail(RPIV_ENOMEM, "field: out of memory for %d x %d", nx, ny);
    }
    *out = f;
    return RPIV_OK;
}

void rpiv_field_free(rpiv_field *f)
{
    if (!f)
        return;
    free(f->u);
    free(f->v);
    free(f->flag);
    free(f->peak_ratio);
    free(f->corr);
    for (size_t k = 0; k < f->nq; k++)
        free(f->q[k].data);
    free(f->q);
    free(f);
}

rpiv_status rpiv_field_copy(const rpiv_field *f, rpiv_field **out)
{
    rpiv_field *c;
    rpiv_status st = rpiv_field_new(f->nx, f->ny, f->x0, f->y0, f->dx, f->dy, &c);
    *out = NULL;
    if (st)
        return st;
    size_t n = (size_t)f->nx * (size_t)f->ny;
    memcpy(c->u, f->u, n * sizeof *c->u);
    memcpy(c->v, f->v, n * sizeof *c->v);
    memcpy(c->flag, f->flag, n * sizeof *c->flag);
    memcpy(c->peak_ratio, f->peak_ratio, n * sizeof *c->peak_ratio);
    memcpy(c->corr, f->corr, n * sizeof *c->corr);
    c->scale_mm_per_px = f->scale_mm_per_px;
    c->dt_s = f->dt_s;
    c->y_up = f->y_up;
    for (size_t q = 0; q < f->nq; q++) {
        float *d;
        if ((st = rpiv_field_add_quantity(c, f->q[q].name, f->q[q].unit, &d))) {
            rpiv_field_free(c);
            return st;
        }
        memcpy(d, f->q[q].data, n * sizeof *d);
    }
    *out = c;
    return RPIV_OK;
}

int field_has_phys(const rpiv_field *f)
{
    return f->scale_mm_per_px > 0 && f->dt_s > 0;
}

/* ---- extra quantities ------------------------------------------------------------ */

static int ends_with(const char *s, const char *tail)
{
    size_t n = strlen(s), m = strlen(tail);
    return n >= m && strcmp(s + n - m, tail) == 0;
}

/* Names the writers use for their own columns, variables and arrays. */
static int name_reserved(const char *name)
{
    static const char *const taken[] = {"x",           "y",        "t",         "u",
                                        "v",           "flag",     "chc",       "peak_ratio",
                                        "correlation", "velocity", "coords_mm", "velocity_ms"};
    for (size_t k = 0; k < sizeof taken / sizeof taken[0]; k++)
        if (strcmp(name, taken[k]) == 0)
            return 1;
    return ends_with(name, "_mm") || ends_with(name, "_ms") || ends_with(name, "_per_s") ||
           ends_with(name, "_per_s2") || ends_with(name, "_px");
}

rpiv_status rpiv_field_add_quantity(rpiv_field *f, const char *name, int unit, float **data)
{
    if (data)
        *data = NULL;
    int kind = unit & ~RPIV_UNIT_ODD_Y;
    size_t len = strlen(name);
    int ok = len > 0 && len < RPIV_QUANTITY_NAME_MAX && isalpha((unsigned char)name[0]);
    for (const char *p = name; ok && *p; p++)
        ok = isalnum((unsigned char)*p) || *p == '_';
    if (!ok)
        return rpiv_fail(RPIV_EINVAL,
                         "field: quantity name '%s' must start with a letter, hold only "
                         "letters, digits and '_' and be shorter than %d characters",
                         name, RPIV_QUANTITY_NAME_MAX);
    if (name_reserved(name) || rpiv_field_quantity(f, name))
        return rpiv_fail(RPIV_EINVAL, "field: quantity name '%s' is already used", name);
    if (kind < RPIV_UNIT_ONE || kind > RPIV_UNIT_PER_DT2 || (unit & ~(RPIV_UNIT_ODD_Y | 0xff)))
        return rpiv_fail(RPIV_EINVAL, "field: quantity '%s': unknown unit kind %d", name, unit);
    size_t n = (size_t)f->nx * (size_t)f->ny;
    float *d = calloc(n, sizeof *d);
    rpiv_quantity *q = d ? realloc(f->q, (f->nq + 1) * sizeof *q) : NULL;
    if (!q) {
        free(d);
        return rpiv_fail(RPIV_ENOMEM, "field: out of memory for quantity '%s'", name);
    }
    f->q = q;
    memcpy(q[f->nq].name, name, len + 1);
    q[f->nq].unit = unit;
    q[f->nq].data = d;
    f->nq++;
    if (data)
        *data = d;
    return RPIV_OK;
}

const rpiv_quantity *rpiv_field_quantity(const rpiv_field *f, const char *name)
{
    for (size_t k = 0; k < f->nq; k++)
        if (strcmp(f->q[k].name, name) == 0)
            return &f->q[k];
    return NULL;
}

const char *rpiv_unit_name(int unit, int physical)
{
    static const char *const px[] = {"1", "pix", "pix/dt", "1/dt", "1/dt^2"};
    static const char *const si[] = {"1", "mm", "m/s", "1/s", "1/s^2"};
    int k = unit & ~RPIV_UNIT_ODD_Y;
    if (k < 0 || k > RPIV_UNIT_PER_DT2)
        return "?";
    return physical ? si[k] : px[k];
}

double rpiv_unit_factor(const rpiv_field *f, int unit)
{
    int k = unit & ~RPIV_UNIT_ODD_Y;
    if (k == RPIV_UNIT_ONE)
        return 1.0;
    if (!field_has_phys(f))
        return 0.0;
    if (k == RPIV_UNIT_PX)
        return f->scale_mm_per_px;
    if (k == RPIV_UNIT_PX_PER_DT)
        return f->scale_mm_per_px * 1e-3 / f->dt_s;
    if (k == RPIV_UNIT_PER_DT2)
        return 1.0 / (f->dt_s * f->dt_s);
    return 1.0 / f->dt_s; /* (px/dt) / px */
}

/* Reverse the rows of an nx x ny array of `size`-byte elements in place. */
static void flip_rows(void *a, int nx, int ny, size_t size)
{
    unsigned char *p = a, tmp[64];
    size_t row = (size_t)nx * size;
    for (int j = 0, k = ny - 1; j < k; j++, k--) {
        unsigned char *r0 = p + (size_t)j * row, *r1 = p + (size_t)k * row;
        for (size_t b = 0; b < row; b += sizeof tmp) {
            size_t m = row - b < sizeof tmp ? row - b : sizeof tmp;
            memcpy(tmp, r0 + b, m);
            memcpy(r0 + b, r1 + b, m);
            memcpy(r1 + b, tmp, m);
        }
    }
}

static void negate(float *a, size_t n)
{
    for (size_t k = 0; k < n; k++)
        a[k] = a[k] == 0 ? 0.0f : -a[k]; /* no -0 in the files */
}

rpiv_status rpiv_field_y_up(rpiv_field *f, int height)
{
    if (f->y_up)
        return rpiv_fail(RPIV_EINVAL, "field: already y-up");
    if (height < 1)
        return rpiv_fail(RPIV_EINVAL, "field: image height %d for y-up", height);
    size_t n = (size_t)f->nx * (size_t)f->ny;
    double ylast = f->y0 + (f->ny - 1) * f->dy;
    f->y0 = (double)(height - 1) - ylast;
    flip_rows(f->u, f->nx, f->ny, sizeof *f->u);
    flip_rows(f->v, f->nx, f->ny, sizeof *f->v);
    flip_rows(f->flag, f->nx, f->ny, sizeof *f->flag);
    flip_rows(f->peak_ratio, f->nx, f->ny, sizeof *f->peak_ratio);
    flip_rows(f->corr, f->nx, f->ny, sizeof *f->corr);
    negate(f->v, n);
    for (size_t k = 0; k < f->nq; k++) {
        flip_rows(f->q[k].data, f->nx, f->ny, sizeof *f->q[k].data);
        if (f->q[k].unit & RPIV_UNIT_ODD_Y)
            negate(f->q[k].data, n);
    }
    f->y_up = 1;
    return RPIV_OK;
}

/* ---- meta ----------------------------------------------------------------- */

/* Keys become NetCDF attribute names and header words: a letter, then letters, digits, _ . - */
static int key_ok(const char *k)
{
    if (!isalpha((unsigned char)k[0]))
        return 0;
    for (const char *p = k; *p; p++)
        if (!isalnum((unsigned char)*p) && *p != '_' && *p != '.' && *p != '-')
            return 0;
    return 1;
}

rpiv_status rpiv_meta_add(rpiv_meta *m, const char *key, const char *fmt, ...)
{
    if (!key_ok(key))
        return rpiv_fail(RPIV_EINVAL,
                         "meta: key '%s' must start with a letter and hold only "
                         "letters, digits, '_', '.', '-'",
                         key);
    va_list ap;
    va_start(ap, fmt);
    int len = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (len < 0)
        return rpiv_fail(RPIV_EINVAL, "meta: cannot format the value of '%s'", key);
    char *val = malloc((size_t)len + 1);
    if (!val)
        return rpiv_fail(RPIV_ENOMEM, "meta: out of memory for '%s'", key);
    va_start(ap, fmt);
    vsnprintf(val, (size_t)len + 1, fmt, ap);
    va_end(ap);
    /* one header line per entry: control characters (newlines) become spaces */
    for (char *p = val; *p; p++)
        if (iscntrl((unsigned char)*p))
            *p = ' ';
    for (size_t i = 0; i < m->n; i++) {
        if (strcmp(m->key[i], key) == 0) {
            free(m->val[i]);
            m->val[i] = val;
            return RPIV_OK;
        }
    }
    char *k = strdup(key);
    char **nk = k ? realloc(m->key, (m->n + 1) * sizeof *nk) : NULL;
    if (nk)
        m->key = nk;
    char **nv = nk ? realloc(m->val, (m->n + 1) * sizeof *nv) : NULL;
    if (nv)
        m->val = nv;
    if (!k || !nk || !nv) {
        free(k);
        free(val);
        return rpiv_fail(RPIV_ENOMEM, "meta: out of memory for '%s'", key);
    }
    m->key[m->n] = k;
    m->val[m->n] = val;
    m->n++;
    return RPIV_OK;
}

void rpiv_meta_clear(rpiv_meta *m)
{
    for (size_t i = 0; i < m->n; i++) {
        free(m->key[i]);
        free(m->val[i]);
    }
    free(m->key);
    free(m->val);
    m->key = m->val = NULL;
    m->n = 0;
}

size_t rpiv_field_count(const rpiv_field *f, int flag)
{
    size_t n = (size_t)f->nx * (size_t)f->ny, k = 0;
    for (size_t i = 0; i < n; i++)
        k += f->flag[i] == flag;
    return k;
}

/* ---- the columns of the writers ------------------------------------------------ */

const char *field_phys_suffix(int unit)
{
    static const char *const sfx[] = {"", "_mm", "_ms", "_per_s", "_per_s2"};
    int k = unit & ~RPIV_UNIT_ODD_Y;
    return k >= 0 && k <= RPIV_UNIT_PER_DT2 ? sfx[k] : "";
}

const char *field_orientation(const rpiv_field *f)
{
    return f->y_up ? "y-up" : "image";
}

int field_unit_of_name(const char *name)
{
    for (int k = RPIV_UNIT_ONE; k <= RPIV_UNIT_PER_DT2; k++)
        if (strcmp(name, rpiv_unit_name(k, 0)) == 0)
            return k;
    return -1;
}

static void col_set(field_col *c, const char *name, const char *sfx, const char *unit, int kind,
                    const float *data, double factor, int physical)
{
    snprintf(c->name, sizeof c->name, "%s%s", name, sfx);
    c->unit = unit;
    c->kind = kind;
    c->data = data;
    c->factor = factor;
    c->physical = physical;
}

field_col *field_columns(const rpiv_field *f, size_t *ncol)
{
    field_col *c = calloc(11 + 2 * f->nq, sizeof *c);
    size_t n = 0;
    if (!c)
        return NULL;
    col_set(&c[n++], "x", "", "pix", FIELD_COL_X, NULL, 1, 0);
    col_set(&c[n++], "y", "", "pix", FIELD_COL_Y, NULL, 1, 0);
    col_set(&c[n++], "u", "", "pix/dt", FIELD_COL_FLOAT, f->u, 1, 0);
    col_set(&c[n++], "v", "", "pix/dt", FIELD_COL_FLOAT, f->v, 1, 0);
    col_set(&c[n++], "flag", "", "1", FIELD_COL_FLAG, NULL, 1, 0);
    col_set(&c[n++], "peak_ratio", "", "1", FIELD_COL_FLOAT, f->peak_ratio, 1, 0);
    col_set(&c[n++], "correlation", "", "1", FIELD_COL_FLOAT, f->corr, 1, 0);
    for (size_t q = 0; q < f->nq; q++)
        col_set(&c[n++], f->q[q].name, "", rpiv_unit_name(f->q[q].unit, 0), FIELD_COL_FLOAT,
                f->q[q].data, 1, 0);
    if (field_has_phys(f)) {
        double s = f->scale_mm_per_px, ms = rpiv_unit_factor(f, RPIV_UNIT_PX_PER_DT);
        col_set(&c[n++], "x", "_mm", "mm", FIELD_COL_X, NULL, s, 1);
        col_set(&c[n++], "y", "_mm", "mm", FIELD_COL_Y, NULL, s, 1);
        col_set(&c[n++], "u", "_ms", "m/s", FIELD_COL_FLOAT, f->u, ms, 1);
        col_set(&c[n++], "v", "_ms", "m/s", FIELD_COL_FLOAT, f->v, ms, 1);
        for (size_t q = 0; q < f->nq; q++)
            if ((f->q[q].unit & ~RPIV_UNIT_ODD_Y) != RPIV_UNIT_ONE)
                col_set(&c[n++], f->q[q].name, field_phys_suffix(f->q[q].unit),
                        rpiv_unit_name(f->q[q].unit, 1), FIELD_COL_FLOAT, f->q[q].data,
                        rpiv_unit_factor(f, f->q[q].unit), 1);
    }
    *ncol = n;
    return c;
}
