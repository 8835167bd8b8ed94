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
    *out = c;
    return RPIV_OK;
}

int field_has_phys(const rpiv_field *f)
{
    return f->scale_mm_per_px > 0 && f->dt_s > 0;
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
