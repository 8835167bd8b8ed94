/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field/field_nc.c - NetCDF-4 vector fields: one field, or a series along an unlimited t.
 * Layout (docs/formats.md): dimensions (t, y, x); coordinates x(x), y(y), t(t); variables
 * u, v, peak_ratio, correlation (float) and flag (byte) over (t, y, x); units as attributes;
 * the meta entries as global attributes. xarray (pivpy) and h5py read it as is. */
#include "rpiv/field.h"
#include "rpiv/version.h"

#include "field_impl.h"

#include <math.h>
#include <netcdf.h>
#include <stdlib.h>
#include <string.h>

struct rpiv_field_series {
    atomic_file af;
    int ncid;
    int nx, ny;
    double x0, y0, dx, dy;
    size_t nt;
    int vt, vu, vv, vflag, vpr, vcc;
};

static rpiv_status nc_err(const char *path, const char *what, int e)
{
    return rpiv_fail(RPIV_EIO, "%s: NetCDF %s: %s", path, what, nc_strerror(e));
}

static int put_text(int ncid, int var, const char *name, const char *val)
{
    return nc_put_att_text(ncid, var, name, strlen(val), val);
}

/* Define a (t, y, x) data variable with its attributes; chunks are one field. */
static int def_data(rpiv_field_series *s, const int *dims, const char *name, nc_type type,
                    const char *units, const char *long_name, int *var)
{
    size_t chunk[3] = {1, (size_t)s->ny, (size_t)s->nx};
    int e = nc_def_var(s->ncid, name, type, 3, dims, var);
    if (!e)
        e = nc_def_var_chunking(s->ncid, *var, NC_CHUNKED, chunk);
    if (!e)
        e = nc_def_var_deflate(s->ncid, *var, 1, 1, 1);
    if (!e && units)
        e = put_text(s->ncid, *var, "units", units);
    if (!e)
        e = put_text(s->ncid, *var, "long_name", long_name);
    return e;
}

static int define(rpiv_field_series *s, const rpiv_field *g, const rpiv_meta *meta)
{
    int ncid = s->ncid, dt, dy, dx, vx, vy, e;
    if ((e = nc_def_dim(ncid, "t", NC_UNLIMITED, &dt)) ||
        (e = nc_def_dim(ncid, "y", (size_t)g->ny, &dy)) ||
        (e = nc_def_dim(ncid, "x", (size_t)g->nx, &dx)))
        return e;
    if ((e = nc_def_var(ncid, "x", NC_DOUBLE, 1, &dx, &vx)) ||
        (e = put_text(ncid, vx, "units", "pix")) ||
        (e = put_text(ncid, vx, "long_name", "window centre x, image A columns")) ||
        (e = nc_def_var(ncid, "y", NC_DOUBLE, 1, &dy, &vy)) ||
        (e = put_text(ncid, vy, "units", "pix")) ||
        (e = put_text(ncid, vy, "long_name", "window centre y, image A rows (downward)")) ||
        (e = nc_def_var(ncid, "t", NC_DOUBLE, 1, &dt, &s->vt)) ||
        (e = put_text(ncid, s->vt, "units", "s")) ||
        (e = put_text(ncid, s->vt, "long_name", "time of the field")))
        return e;
    int dims[3] = {dt, dy, dx};
    if ((e = def_data(s, dims, "u", NC_FLOAT, "pix/dt", "displacement along x", &s->vu)) ||
        (e = def_data(s, dims, "v", NC_FLOAT, "pix/dt", "displacement along y", &s->vv)) ||
        (e = def_data(s, dims, "flag", NC_BYTE, NULL, "vector status", &s->vflag)) ||
        (e = def_data(s, dims, "peak_ratio", NC_FLOAT, "1",
                      "highest / second-highest correlation peak", &s->vpr)) ||
        (e = def_data(s, dims, "correlation", NC_FLOAT, "1", "normalised correlation at the peak",
                      &s->vcc)))
        return e;
    signed char fv[3] = {RPIV_FLAG_VALID, RPIV_FLAG_REPLACED, RPIV_FLAG_MASKED};
    if ((e = nc_put_att_schar(ncid, s->vflag, "flag_values", NC_BYTE, 3, fv)) ||
        (e = put_text(ncid, s->vflag, "flag_meanings", "valid replaced masked")))
        return e;
    if ((e = put_text(ncid, NC_GLOBAL, "title", "rpiv vector field")) ||
        (e = put_text(ncid, NC_GLOBAL, "source", "rpiv " RPIV_VERSION_STRING)) ||
        (e = put_text(ncid, NC_GLOBAL, "rpiv_format", "rpiv vector field 1")))
        return e;
    if (g->scale_mm_per_px > 0 && (e = nc_put_att_double(ncid, NC_GLOBAL, "scale_mm_per_px",
                                                         NC_DOUBLE, 1, &g->scale_mm_per_px)))
        return e;
    if (g->dt_s > 0 && (e = nc_put_att_double(ncid, NC_GLOBAL, "dt_s", NC_DOUBLE, 1, &g->dt_s)))
        return e;
    for (size_t k = 0; meta && k < meta->n; k++)
        if ((e = put_text(ncid, NC_GLOBAL, meta->key[k], meta->val[k])))
            return e;
    if ((e = nc_enddef(ncid)))
        return e;
    double *c = malloc((size_t)(g->nx > g->ny ? g->nx : g->ny) * sizeof *c);
    if (!c)
        return NC_ENOMEM;
    for (int i = 0; i < g->nx; i++)
        c[i] = g->x0 + i * g->dx;
    e = nc_put_var_double(ncid, vx, c);
    for (int j = 0; !e && j < g->ny; j++)
        c[j] = g->y0 + j * g->dy;
    if (!e)
        e = nc_put_var_double(ncid, vy, c);
    free(c);
    return e;
}

rpiv_status rpiv_field_series_open(const char *path, const rpiv_field *grid, const rpiv_meta *meta,
                                   rpiv_field_series **out)
{
    *out = NULL;
    rpiv_field_series *s = calloc(1, sizeof *s);
    if (!s)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
    rpiv_status st = atomic_begin(&s->af, path, 0);
    if (st) {
        free(s);
        return st;
    }
    s->nx = grid->nx;
    s->ny = grid->ny;
    s->x0 = grid->x0;
    s->y0 = grid->y0;
    s->dx = grid->dx;
    s->dy = grid->dy;
    int e = nc_create(s->af.tmp, NC_NETCDF4 | NC_CLOBBER, &s->ncid);
    if (e) {
        st = nc_err(path, "create", e);
        atomic_abort(&s->af);
        free(s);
        return st;
    }
    e = define(s, grid, meta);
    if (e) {
        st = nc_err(path, "define", e);
        nc_close(s->ncid);
        atomic_abort(&s->af);
        free(s);
        return st;
    }
    *out = s;
    return RPIV_OK;
}

static int same(double a, double b)
{
    return fabs(a - b) <= 1e-9 * fmax(1.0, fmax(fabs(a), fabs(b)));
}

rpiv_status rpiv_field_series_append(rpiv_field_series *s, const rpiv_field *f, double t)
{
    const char *path = s->af.path;
    if (f->nx != s->nx || f->ny != s->ny || !same(f->x0, s->x0) || !same(f->y0, s->y0) ||
        !same(f->dx, s->dx) || !same(f->dy, s->dy))
        return rpiv_fail(RPIV_ESIZE,
                         "%s: field %d: grid %d x %d differs from the series' %d x %d "
                         "(or its origin/step)",
                         path, (int)s->nt, f->nx, f->ny, s->nx, s->ny);
    size_t start[3] = {s->nt, 0, 0}, count[3] = {1, (size_t)s->ny, (size_t)s->nx};
    int e = nc_put_var1_double(s->ncid, s->vt, start, &t);
    if (!e)
        e = nc_put_vara_float(s->ncid, s->vu, start, count, f->u);
    if (!e)
        e = nc_put_vara_float(s->ncid, s->vv, start, count, f->v);
    if (!e)
        e = nc_put_vara_uchar(s->ncid, s->vflag, start, count, f->flag);
    if (!e)
        e = nc_put_vara_float(s->ncid, s->vpr, start, count, f->peak_ratio);
    if (!e)
        e = nc_put_vara_float(s->ncid, s->vcc, start, count, f->corr);
    if (e)
        return nc_err(path, "write", e);
    s->nt++;
    return RPIV_OK;
}

rpiv_status rpiv_field_series_close(rpiv_field_series *s, int abort)
{
    if (!s)
        return RPIV_OK;
    rpiv_status st = RPIV_OK;
    int e = nc_close(s->ncid);
    if (abort) {
        atomic_abort(&s->af);
    } else if (e) {
        st = nc_err(s->af.path, "close", e);
        atomic_abort(&s->af);
    } else {
        st = atomic_commit(&s->af);
    }
    free(s);
    return st;
}

rpiv_status field_save_nc(const rpiv_field *f, const rpiv_meta *meta, const char *path)
{
    rpiv_field_series *s;
    rpiv_status st = rpiv_field_series_open(path, f, meta, &s);
    if (st)
        return st;
    st = rpiv_field_series_append(s, f, 0.0);
    rpiv_status st2 = rpiv_field_series_close(s, st != RPIV_OK);
    return st ? st : st2;
}
