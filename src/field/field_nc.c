/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field/field_nc.c - NetCDF-4 vector fields in pivpy's xarray layout: one field, or a series
 * along an unlimited t. Layout (docs/formats.md): every per-vector variable on dims (y, x, t);
 * coordinates x(x), y(y), t(t) (t: the pair index, units "frame"); u, v, chc (pivpy's validity:
 * 1 valid, 0 replaced or masked), flag (rpiv's: 0 valid, 1 replaced, 2 masked), peak_ratio,
 * correlation and the extra quantities, each with units and long_name. With scale and dt the
 * plain names are physical (x, y mm; u, v m/s; rates 1/s) and the pixel values are kept as
 * x_px, y_px, u_px, v_px, <name>_px. Global attributes: delta_t, files, orientation,
 * Conventions, rpiv_version and the meta entries. xarray.open_dataset reads it as pivpy wants. */
#include "rpiv/field.h"
#include "rpiv/version.h"

#include "field_impl.h"

#include <errno.h>
#include <math.h>
#include <netcdf.h>
#include <netcdf_mem.h>
#include <stdlib.h>
#include <string.h>

/* One float variable of the file: which array of the field, times which factor. */
typedef struct nc_var {
    int id;
    int src; /* -1 u, -2 v, -3 peak_ratio, -4 correlation, q >= 0: extra quantity q */
    double factor;
} nc_var;

struct rpiv_field_series {
    atomic_file af;
    int ncid;
    int nx, ny;
    double x0, y0, dx, dy;
    int y_up;
    size_t nt, nq;
    char (*qname)[RPIV_QUANTITY_NAME_MAX]; /* the grid's quantities, in order */
    int vt, vchc, vflag;
    nc_var *var;
    size_t nvar;
    float *buf;        /* nx * ny */
    signed char *bbuf; /* nx * ny */
};

static rpiv_status nc_err(const char *path, const char *what, int e)
{
    return rpiv_fail(RPIV_EIO, "%s: NetCDF %s: %s", path, what, nc_strerror(e));
}

static int put_text(int ncid, int var, const char *name, const char *val)
{
    return nc_put_att_text(ncid, var, name, strlen(val), val);
}

/* Define a (y, x, t) data variable with its attributes; chunks are one field. */
static int def_data(rpiv_field_series *s, const int *dims, const char *name, nc_type type,
                    const char *units, const char *long_name, int *var)
{
    size_t chunk[3] = {(size_t)s->ny, (size_t)s->nx, 1};
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

static int def_float(rpiv_field_series *s, const int *dims, const char *name, const char *sfx,
                     const char *units, const char *long_name, int src, double factor)
{
    char nm[RPIV_QUANTITY_NAME_MAX + 8];
    snprintf(nm, sizeof nm, "%s%s", name, sfx);
    nc_var *v = &s->var[s->nvar];
    v->src = src;
    v->factor = factor;
    int e = def_data(s, dims, nm, NC_FLOAT, units, long_name, &v->id);
    if (!e)
        s->nvar++;
    return e;
}

/* A coordinate variable of n values c0 + k * step, times factor. */
static int def_coord(int ncid, const char *name, int dim, const char *units, const char *long_name,
                     int *var)
{
    int e = nc_def_var(ncid, name, NC_DOUBLE, 1, &dim, var);
    if (!e)
        e = put_text(ncid, *var, "units", units);
    if (!e)
        e = put_text(ncid, *var, "long_name", long_name);
    return e;
}

static int put_coord(int ncid, int var, int n, double c0, double step, double factor)
{
    double *c = malloc((size_t)n * sizeof *c);
    if (!c)
        return NC_ENOMEM;
    for (int k = 0; k < n; k++)
        c[k] = (c0 + k * step) * factor;
    int e = nc_put_var_double(ncid, var, c);
    free(c);
    return e;
}

/* The meta entry "files" ("A B; C D; ...") as a string-array attribute, one pair each. */
static int put_files(int ncid, const char *val)
{
    size_t n = 1, len = strlen(val);
    for (const char *p = val; (p = strstr(p, "; ")); p += 2)
        n++;
    char *copy = malloc(len + 1);
    const char **item = malloc(n * sizeof *item);
    int e = NC_ENOMEM;
    if (copy && item) {
        memcpy(copy, val, len + 1);
        size_t k = 0;
        char *p = copy;
        item[k++] = p;
        while ((p = strstr(p, "; "))) {
            *p = '\0';
            p += 2;
            item[k++] = p;
        }
        e = nc_put_att_string(ncid, NC_GLOBAL, "files", n, item);
    }
    free(copy);
    free(item);
    return e;
}

static const char *long_name_of(const char *name)
{
    if (!strcmp(name, "u"))
        return "velocity along x";
    if (!strcmp(name, "v"))
        return "velocity along y";
    if (!strcmp(name, "peak_ratio"))
        return "highest / second-highest correlation peak";
    if (!strcmp(name, "correlation"))
        return "normalised correlation at the peak";
    return name;
}

static int define(rpiv_field_series *s, const rpiv_field *g, const rpiv_meta *meta)
{
    int ncid = s->ncid, dt, dy, dx, vx, vy, vxp = -1, vyp = -1, e;
    int phys = field_has_phys(g);
    const char *down = g->y_up ? "up" : "down";
    char lny[96];
    snprintf(lny, sizeof lny, "window centre y, %s",
             g->y_up ? "upward from the bottom row" : "image A rows (downward)");
    if ((e = nc_def_dim(ncid, "y", (size_t)g->ny, &dy)) ||
        (e = nc_def_dim(ncid, "x", (size_t)g->nx, &dx)) ||
        (e = nc_def_dim(ncid, "t", NC_UNLIMITED, &dt)))
        return e;
    if ((e = def_coord(ncid, "x", dx, phys ? "mm" : "pix", "window centre x, image A columns",
                       &vx)) ||
        (e = def_coord(ncid, "y", dy, phys ? "mm" : "pix", lny, &vy)) ||
        (e = def_coord(ncid, "t", dt, "frame", "pair index (0 = first pair)", &s->vt)))
        return e;
    if (phys &&
        ((e = def_coord(ncid, "x_px", dx, "pix", "window centre x, image A columns", &vxp)) ||
         (e = def_coord(ncid, "y_px", dy, "pix", lny, &vyp))))
        return e;
    int dims[3] = {dy, dx, dt};
    const char *vu = phys ? "m/s" : "pix/dt";
    double ms = phys ? rpiv_unit_factor(g, RPIV_UNIT_PX_PER_DT) : 1.0;
    char lnv[64];
    snprintf(lnv, sizeof lnv, "velocity along y (positive %s)", down);
    if ((e = def_float(s, dims, "u", "", vu, "velocity along x", -1, ms)) ||
        (e = def_float(s, dims, "v", "", vu, lnv, -2, ms)) ||
        (e = def_data(s, dims, "chc", NC_BYTE, "1", "valid vector (1), replaced or masked (0)",
                      &s->vchc)) ||
        (e = def_data(s, dims, "flag", NC_BYTE, "1", "vector status", &s->vflag)) ||
        (e = def_float(s, dims, "peak_ratio", "", "1", long_name_of("peak_ratio"), -3, 1)) ||
        (e = def_float(s, dims, "correlation", "", "1", long_name_of("correlation"), -4, 1)))
        return e;
    for (size_t q = 0; q < g->nq; q++) {
        int u = g->q[q].unit, has = (u & ~RPIV_UNIT_ODD_Y) != RPIV_UNIT_ONE;
        if ((e = def_float(s, dims, g->q[q].name, "", rpiv_unit_name(u, phys && has), g->q[q].name,
                           (int)q, phys && has ? rpiv_unit_factor(g, u) : 1)) ||
            (e = put_text(ncid, s->var[s->nvar - 1].id, "y_parity",
                          u & RPIV_UNIT_ODD_Y ? "odd" : "even")))
            return e;
    }
    if (phys) {
        if ((e = def_float(s, dims, "u", "_px", "pix/dt", "displacement along x", -1, 1)) ||
            (e = def_float(s, dims, "v", "_px", "pix/dt", lnv, -2, 1)))
            return e;
        for (size_t q = 0; q < g->nq; q++)
            if ((g->q[q].unit & ~RPIV_UNIT_ODD_Y) != RPIV_UNIT_ONE &&
                (e = def_float(s, dims, g->q[q].name, "_px", rpiv_unit_name(g->q[q].unit, 0),
                               g->q[q].name, (int)q, 1)))
                return e;
    }
    signed char fv[3] = {RPIV_FLAG_VALID, RPIV_FLAG_REPLACED, RPIV_FLAG_MASKED}, cv[2] = {0, 1};
    if ((e = nc_put_att_schar(ncid, s->vflag, "flag_values", NC_BYTE, 3, fv)) ||
        (e = put_text(ncid, s->vflag, "flag_meanings", "valid replaced masked")) ||
        (e = nc_put_att_schar(ncid, s->vchc, "flag_values", NC_BYTE, 2, cv)) ||
        (e = put_text(ncid, s->vchc, "flag_meanings", "replaced_or_masked valid")))
        return e;
    double delta_t = g->dt_s > 0 ? g->dt_s : 0.0;
    if ((e = put_text(ncid, NC_GLOBAL, "title", "rpiv vector field")) ||
        (e = put_text(ncid, NC_GLOBAL, "Conventions", "pivpy")) ||
        (e = put_text(ncid, NC_GLOBAL, "pivpy_schema_version", "1")) ||
        (e = put_text(ncid, NC_GLOBAL, "source", "rpiv " RPIV_VERSION_STRING)) ||
        (e = put_text(ncid, NC_GLOBAL, "rpiv_version", RPIV_VERSION_STRING)) ||
        (e = put_text(ncid, NC_GLOBAL, "rpiv_format", "rpiv vector field 1")) ||
        (e = put_text(ncid, NC_GLOBAL, "orientation", field_orientation(g))) ||
        (e = nc_put_att_double(ncid, NC_GLOBAL, "delta_t", NC_DOUBLE, 1, &delta_t)))
        return e;
    if (g->scale_mm_per_px > 0 && (e = nc_put_att_double(ncid, NC_GLOBAL, "scale_mm_per_px",
                                                         NC_DOUBLE, 1, &g->scale_mm_per_px)))
        return e;
    if (g->dt_s > 0 && (e = nc_put_att_double(ncid, NC_GLOBAL, "dt_s", NC_DOUBLE, 1, &g->dt_s)))
        return e;
    int have_files = 0;
    for (size_t k = 0; meta && k < meta->n; k++) {
        if (strcmp(meta->key[k], "files") == 0) {
            have_files = 1;
            e = put_files(ncid, meta->val[k]);
        } else {
            e = put_text(ncid, NC_GLOBAL, meta->key[k], meta->val[k]);
        }
        if (e)
            return e;
    }
    if (!have_files && (e = nc_put_att_string(ncid, NC_GLOBAL, "files", 0, NULL)))
        return e;
    if ((e = nc_enddef(ncid)))
        return e;
    double s_mm = phys ? g->scale_mm_per_px : 1.0;
    if ((e = put_coord(ncid, vx, g->nx, g->x0, g->dx, s_mm)) ||
        (e = put_coord(ncid, vy, g->ny, g->y0, g->dy, s_mm)))
        return e;
    if (phys && ((e = put_coord(ncid, vxp, g->nx, g->x0, g->dx, 1)) ||
                 (e = put_coord(ncid, vyp, g->ny, g->y0, g->dy, 1))))
        return e;
    return NC_NOERR;
}

static void series_free(rpiv_field_series *s)
{
    free(s->qname);
    free(s->var);
    free(s->buf);
    free(s->bbuf);
    free(s);
}

rpiv_status rpiv_field_series_open(const char *path, const rpiv_field *grid, const rpiv_meta *meta,
                                   rpiv_field_series **out)
{
    *out = NULL;
    size_t n = (size_t)grid->nx * (size_t)grid->ny;
    rpiv_field_series *s = calloc(1, sizeof *s);
    if (s) {
        s->var = calloc(6 + 2 * grid->nq, sizeof *s->var);
        s->qname = calloc(grid->nq ? grid->nq : 1, sizeof *s->qname);
        s->buf = malloc(n * sizeof *s->buf);
        s->bbuf = malloc(n * sizeof *s->bbuf);
    }
    if (!s || !s->var || !s->qname || !s->buf || !s->bbuf) {
        if (s)
            series_free(s);
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
    }
    /* the file is built in memory (HDF5's core driver) and written out by rpiv's atomic
     * writer at close: a full disk is then an ordinary write error, where HDF5 writing it
     * itself fails its close and crashes at exit (issue #20) */
    rpiv_status st = atomic_begin(&s->af, path, 1);
    if (st) {
        series_free(s);
        return st;
    }
    s->nx = grid->nx;
    s->ny = grid->ny;
    s->x0 = grid->x0;
    s->y0 = grid->y0;
    s->dx = grid->dx;
    s->dy = grid->dy;
    s->y_up = grid->y_up;
    s->nq = grid->nq;
    for (size_t q = 0; q < grid->nq; q++)
        memcpy(s->qname[q], grid->q[q].name, sizeof s->qname[q]);
    int e = nc_create_mem(s->af.tmp, NC_NETCDF4, 4096, &s->ncid);
    if (e) {
        st = nc_err(path, "create", e);
        atomic_abort(&s->af);
        series_free(s);
        return st;
    }
    e = define(s, grid, meta);
    if (e) {
        st = nc_err(path, "define", e);
        NC_memio mem = {0};
        nc_close_memio(s->ncid, &mem);
        free(mem.memory);
        atomic_abort(&s->af);
        series_free(s);
        return st;
    }
    *out = s;
    return RPIV_OK;
}

static int same(double a, double b)
{
    return fabs(a - b) <= 1e-9 * fmax(1.0, fmax(fabs(a), fabs(b)));
}

static const float *source(const rpiv_field *f, int src)
{
    switch (src) {
    case -1:
        return f->u;
    case -2:
        return f->v;
    case -3:
        return f->peak_ratio;
    case -4:
        return f->corr;
    default:
        return f->q[src].data;
    }
}

rpiv_status rpiv_field_series_append(rpiv_field_series *s, const rpiv_field *f, double t)
{
    const char *path = s->af.path;
    size_t n = (size_t)s->nx * (size_t)s->ny;
    if (f->nx != s->nx || f->ny != s->ny || !same(f->x0, s->x0) || !same(f->y0, s->y0) ||
        !same(f->dx, s->dx) || !same(f->dy, s->dy) || f->y_up != s->y_up)
        return rpiv_fail(RPIV_ESIZE,
                         "%s: field %d: grid %d x %d differs from the series' %d x %d "
                         "(or its origin/step/orientation)",
                         path, (int)s->nt, f->nx, f->ny, s->nx, s->ny);
    int qok = f->nq == s->nq;
    for (size_t q = 0; qok && q < s->nq; q++)
        qok = strcmp(f->q[q].name, s->qname[q]) == 0;
    if (!qok)
        return rpiv_fail(RPIV_ESIZE, "%s: field %d: its quantities differ from the series'", path,
                         (int)s->nt);
    size_t start[3] = {0, 0, s->nt}, count[3] = {(size_t)s->ny, (size_t)s->nx, 1};
    int e = nc_put_var1_double(s->ncid, s->vt, &start[2], &t);
    for (size_t k = 0; !e && k < s->nvar; k++) {
        const float *a = source(f, s->var[k].src);
        if (s->var[k].factor != 1.0) {
            for (size_t m = 0; m < n; m++)
                s->buf[m] = (float)((double)a[m] * s->var[k].factor);
            a = s->buf;
        }
        e = nc_put_vara_float(s->ncid, s->var[k].id, start, count, a);
    }
    for (size_t m = 0; !e && m < n; m++)
        s->bbuf[m] = (signed char)f->flag[m];
    if (!e)
        e = nc_put_vara_schar(s->ncid, s->vflag, start, count, s->bbuf);
    for (size_t m = 0; !e && m < n; m++)
        s->bbuf[m] = f->flag[m] == RPIV_FLAG_VALID;
    if (!e)
        e = nc_put_vara_schar(s->ncid, s->vchc, start, count, s->bbuf);
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
    NC_memio mem = {0};
    int e = nc_close_memio(s->ncid, &mem);
    if (abort) {
        atomic_abort(&s->af);
    } else if (e) {
        st = nc_err(s->af.path, "close", e);
        atomic_abort(&s->af);
    } else if (fwrite(mem.memory, 1, mem.size, s->af.fp) != mem.size || fflush(s->af.fp)) {
        st = rpiv_fail(RPIV_EIO, "%s: cannot write: %s", s->af.path, strerror(errno));
        atomic_abort(&s->af);
    } else {
        st = atomic_commit(&s->af);
    }
    free(mem.memory);
    series_free(s);
    return st;
}

rpiv_status rpiv_field_series_close_as(rpiv_field_series *s, const char *path, const char *note,
                                       int *written)
{
    *written = 0;
    if (!s)
        return RPIV_OK;
    if (s->nt == 0) /* nothing done: nothing to publish */
        return rpiv_field_series_close(s, 1);
    atomic_file af;
    rpiv_status st = atomic_begin(&af, path, 1);
    if (st) {
        rpiv_status ign = rpiv_field_series_close(s, 1);
        (void)ign;
        return st;
    }
    int e = 0;
    if (note && !(e = nc_redef(s->ncid)) &&
        !(e = put_text(s->ncid, NC_GLOBAL, "rpiv_partial", note)))
        e = nc_enddef(s->ncid);
    if (e) {
        st = nc_err(path, "attribute rpiv_partial", e);
        atomic_abort(&af);
        rpiv_status ign = rpiv_field_series_close(s, 1);
        (void)ign;
        return st;
    }
    /* the series' own temporary file is dropped; its bytes go to path's */
    atomic_abort(&s->af);
    s->af = af;
    st = rpiv_field_series_close(s, 0);
    *written = st == RPIV_OK;
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
