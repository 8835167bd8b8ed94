/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field/field_load_nc.c - reading one time step of a NetCDF vector file back into a field:
 * rpiv's own files (pivpy's layout, field_nc.c: the pixel values x_px, u_px... when the file is
 * physical) and pivpy-like files of other tools (u, v and optional chc on dims y, x, t). */
#include "rpiv/field.h"

#include "field_impl.h"

#include <math.h>
#include <netcdf.h>
#include <stdlib.h>
#include <string.h>

/* What the file holds, as found. */
typedef struct ncin {
    const char *path;
    int ncid, dy, dx, dt; /* dimension ids */
    size_t nx, ny, nt, t;
} ncin;

static rpiv_status nc_fault(const ncin *c, const char *what, int e)
{
    return rpiv_fail(e == NC_ENOTNC ? RPIV_EFORMAT : RPIV_EIO, "%s: NetCDF %s: %s", c->path, what,
                     nc_strerror(e));
}

static int has_var(const ncin *c, const char *name, int *var)
{
    return nc_inq_varid(c->ncid, name, var) == NC_NOERR;
}

/* A text attribute (NC_CHAR) into buf, "" when absent or not text. */
static void text_att(const ncin *c, int var, const char *name, char *buf, size_t size)
{
    nc_type type;
    size_t len;
    buf[0] = '\0';
    if (nc_inq_att(c->ncid, var, name, &type, &len) || type != NC_CHAR || len >= size)
        return;
    if (nc_get_att_text(c->ncid, var, name, buf) == NC_NOERR)
        buf[len] = '\0';
    else
        buf[0] = '\0';
}

/* A positive finite double global attribute, or 0. */
static double pos_att(const ncin *c, const char *name)
{
    double v = 0;
    size_t len;
    if (nc_inq_attlen(c->ncid, NC_GLOBAL, name, &len) || len != 1 ||
        nc_get_att_double(c->ncid, NC_GLOBAL, name, &v))
        return 0;
    return v > 0 && isfinite(v) ? v : 0;
}

/* 1 when var is a per-vector variable: the three dimensions y, x, t in any order. */
static int is_data(const ncin *c, int var)
{
    int nd, dims[NC_MAX_VAR_DIMS];
    if (nc_inq_varndims(c->ncid, var, &nd) || nd != 3 || nc_inq_vardimid(c->ncid, var, dims))
        return 0;
    int seen = 0;
    for (int k = 0; k < 3; k++)
        seen |= dims[k] == c->dy ? 1 : dims[k] == c->dx ? 2 : dims[k] == c->dt ? 4 : 8;
    return seen == 7;
}

/* Time step c->t of a per-vector variable as nx * ny values, row-major (j * nx + i), whatever
 * the order of its dimensions (pivpy's (y, x, t), rpiv's former (t, y, x)). */
static rpiv_status read_data(const ncin *c, int var, const char *name, double *out, double *tmp)
{
    int dims[3], role[3]; /* role: 0 y, 1 x, 2 t */
    size_t start[3], count[3], stride_of[3];
    if (!is_data(c, var) || nc_inq_vardimid(c->ncid, var, dims))
        return rpiv_fail(RPIV_EFORMAT, "%s: variable '%s' is not on the dimensions (y, x, t)",
                         c->path, name);
    for (int k = 0; k < 3; k++) {
        role[k] = dims[k] == c->dy ? 0 : dims[k] == c->dx ? 1 : 2;
        start[k] = role[k] == 2 ? c->t : 0;
        count[k] = role[k] == 0 ? c->ny : role[k] == 1 ? c->nx : 1;
    }
    int e = nc_get_vara_double(c->ncid, var, start, count, tmp);
    if (e)
        return nc_fault(c, name, e);
    /* tmp is in the variable's order: index = (a * count[1] + b) * count[2] + d */
    stride_of[2] = 1;
    stride_of[1] = count[2];
    stride_of[0] = count[1] * count[2];
    size_t n = c->nx * c->ny;
    for (size_t m = 0; m < n; m++) {
        size_t ji[3] = {m / c->nx, m % c->nx, 0}, src = 0;
        for (int k = 0; k < 3; k++)
            src += ji[role[k]] * stride_of[k];
        out[m] = tmp[src];
    }
    return RPIV_OK;
}

/* The regular axis of coordinate variable `name` (n values): first value and step. */
static rpiv_status read_axis(const ncin *c, const char *name, size_t n, double *o0, double *step)
{
    int var, nd;
    if (!has_var(c, name, &var) || nc_inq_varndims(c->ncid, var, &nd) || nd != 1)
        return rpiv_fail(RPIV_EFORMAT, "%s: no coordinate variable '%s'", c->path, name);
    double *a = malloc(n * sizeof *a);
    if (!a)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", c->path);
    int e = nc_get_var_double(c->ncid, var, a);
    if (e) {
        free(a);
        return nc_fault(c, name, e);
    }
    *o0 = a[0];
    *step = n > 1 ? (a[n - 1] - a[0]) / (double)(n - 1) : 0;
    int ok = isfinite(a[0]) && (n == 1 || (*step > 0 && isfinite(*step)));
    for (size_t k = 1; ok && k < n; k++)
        ok = fabs(a[k] - (a[0] + (double)k * *step)) <= 1e-6 * *step;
    free(a);
    if (!ok)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: coordinate '%s' is not a regular increasing grid (rpiv reads "
                         "fields on a regular grid, x and y increasing)",
                         c->path, name);
    return RPIV_OK;
}

static const char *const known[] = {"u", "v", "chc", "flag", "peak_ratio", "correlation"};

/* 1 for the variables read as u, v, flags and the pixel copies of a physical file. */
static int is_known(const ncin *c, const char *name)
{
    for (size_t k = 0; k < sizeof known / sizeof known[0]; k++)
        if (!strcmp(name, known[k]))
            return 1;
    size_t len = strlen(name);
    char base[NC_MAX_NAME + 1];
    int var;
    if (len > 3 && !strcmp(name + len - 3, "_px")) {
        memcpy(base, name, len - 3);
        base[len - 3] = '\0';
        return has_var(c, base, &var); /* the pixel copy of base */
    }
    return 0;
}

/* The extra quantities: every other float variable on (y, x, t); in a physical file a
 * quantity with a unit is read from its pixel copy <name>_px. Names rpiv cannot carry
 * (reserved ones) are left out. */
static rpiv_status read_quantities(const ncin *c, rpiv_field *f, double *buf, double *tmp)
{
    int nvars;
    int e = nc_inq_nvars(c->ncid, &nvars);
    if (e)
        return nc_fault(c, "inquire", e);
    size_t n = c->nx * c->ny;
    for (int var = 0; var < nvars; var++) {
        char name[NC_MAX_NAME + 1], units[32], parity[16];
        nc_type type;
        if (nc_inq_varname(c->ncid, var, name) || nc_inq_vartype(c->ncid, var, &type) ||
            (type != NC_FLOAT && type != NC_DOUBLE) || !is_data(c, var) || is_known(c, name) ||
            strlen(name) >= RPIV_QUANTITY_NAME_MAX)
            continue;
        int src = var;
        char pxname[NC_MAX_NAME + 8];
        snprintf(pxname, sizeof pxname, "%s_px", name);
        int pxvar;
        if (has_var(c, pxname, &pxvar) && is_data(c, pxvar))
            src = pxvar;
        text_att(c, src, "units", units, sizeof units);
        int unit = field_unit_of_name(units);
        if (unit < 0)
            unit = RPIV_UNIT_ONE;
        text_att(c, var, "y_parity", parity, sizeof parity);
        if (!strcmp(parity, "odd"))
            unit |= RPIV_UNIT_ODD_Y;
        float *d;
        if (rpiv_field_add_quantity(f, name, unit, &d))
            continue; /* a name rpiv reserves: not carried */
        rpiv_status st = read_data(c, src, name, buf, tmp);
        if (st)
            return st;
        for (size_t m = 0; m < n; m++)
            d[m] = (float)buf[m];
    }
    return RPIV_OK;
}

/* u, v (pixel values), flags, peak ratio and correlation of time step c->t. */
static rpiv_status read_vectors(const ncin *c, rpiv_field *f, int px, double *buf, double *tmp)
{
    size_t n = c->nx * c->ny;
    int var;
    rpiv_status st;
    double *v = malloc(n * sizeof *v);
    if (!v)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", c->path);
    const char *un = px ? "u_px" : "u", *vn = px ? "v_px" : "v";
    if (!has_var(c, un, &var)) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: no variable '%s' (a vector file has u and v)", c->path,
                       un);
        goto cleanup_v;
    }
    if ((st = read_data(c, var, un, buf, tmp)))
        goto cleanup_v;
    if (!has_var(c, vn, &var)) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: no variable '%s' (a vector file has u and v)", c->path,
                       vn);
        goto cleanup_v;
    }
    if ((st = read_data(c, var, vn, v, tmp)))
        goto cleanup_v;
    for (size_t m = 0; m < n; m++) {
        f->u[m] = (float)buf[m];
        f->v[m] = (float)v[m];
    }
    /* rpiv's flag, else pivpy's chc (0: replaced or masked, taken as replaced), else valid;
     * a vector that is not finite is masked */
    int have_flag = has_var(c, "flag", &var);
    if (have_flag || has_var(c, "chc", &var)) {
        if ((st = read_data(c, var, have_flag ? "flag" : "chc", buf, tmp)))
            goto cleanup_v;
        for (size_t m = 0; m < n; m++) {
            double g = buf[m];
            if (have_flag &&
                !(g == RPIV_FLAG_VALID || g == RPIV_FLAG_REPLACED || g == RPIV_FLAG_MASKED)) {
                st = rpiv_fail(RPIV_EFORMAT, "%s: flag %g at (%zu, %zu) is not 0, 1 or 2", c->path,
                               g, m % c->nx, m / c->nx);
                goto cleanup_v;
            }
            f->flag[m] = have_flag ? (unsigned char)g
                         : g == 1  ? (unsigned char)RPIV_FLAG_VALID
                                   : (unsigned char)RPIV_FLAG_REPLACED;
        }
    }
    for (size_t m = 0; m < n; m++)
        if (!isfinite(f->u[m]) || !isfinite(f->v[m])) {
            f->u[m] = f->v[m] = 0;
            f->flag[m] = RPIV_FLAG_MASKED;
        }
    float *dst[2] = {f->peak_ratio, f->corr};
    const char *nm[2] = {"peak_ratio", "correlation"};
    for (int k = 0; k < 2; k++) {
        if (!has_var(c, nm[k], &var))
            continue;
        if ((st = read_data(c, var, nm[k], buf, tmp)))
            goto cleanup_v;
        for (size_t m = 0; m < n; m++)
            dst[k][m] = (float)buf[m];
    }
cleanup_v:
    free(v);
    return st;
}

rpiv_status rpiv_field_load_nc(const char *path, size_t t, rpiv_field **out)
{
    *out = NULL;
    ncin c = {.path = path, .t = t};
    int e = nc_open(path, NC_NOWRITE, &c.ncid);
    if (e)
        return e == NC_ENOTNC ? rpiv_fail(RPIV_EFORMAT, "%s: not a NetCDF file", path)
                              : rpiv_fail(RPIV_EIO, "%s: cannot open: %s", path, nc_strerror(e));
    rpiv_status st = RPIV_OK;
    rpiv_field *f = NULL;
    double *buf = NULL, *tmp = NULL;
    const char *dn[3] = {"y", "x", "t"};
    int *did[3] = {&c.dy, &c.dx, &c.dt};
    size_t *len[3] = {&c.ny, &c.nx, &c.nt};
    for (int k = 0; k < 3; k++)
        if (nc_inq_dimid(c.ncid, dn[k], did[k]) || nc_inq_dimlen(c.ncid, *did[k], len[k])) {
            st = rpiv_fail(RPIV_EFORMAT,
                           "%s: no dimension '%s' (rpiv reads pivpy's layout: dims y, x, t)", path,
                           dn[k]);
            goto cleanup_nc;
        }
    if (c.nx < 1 || c.ny < 1 || c.nx > (size_t)1 << 20 || c.ny > (size_t)1 << 20) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: grid %zu x %zu is empty or too large", path, c.nx, c.ny);
        goto cleanup_nc;
    }
    if (t >= c.nt) {
        st = c.nt ? rpiv_fail(RPIV_EINVAL, "%s: time step %zu outside 0..%zu", path, t, c.nt - 1)
                  : rpiv_fail(RPIV_EFORMAT, "%s: no time step (t is empty)", path);
        goto cleanup_nc;
    }
    /* a physical file keeps the pixel values as x_px, y_px, u_px, v_px */
    int var, px = has_var(&c, "x_px", &var) && has_var(&c, "y_px", &var) &&
                  has_var(&c, "u_px", &var) && has_var(&c, "v_px", &var);
    double x0, y0, dx, dy;
    if ((st = read_axis(&c, px ? "x_px" : "x", c.nx, &x0, &dx)) ||
        (st = read_axis(&c, px ? "y_px" : "y", c.ny, &y0, &dy)))
        goto cleanup_nc;
    /* a single row or column has no step: the other one's, or 1 */
    if (c.nx == 1)
        dx = c.ny > 1 ? dy : 1;
    if (c.ny == 1)
        dy = c.nx > 1 ? dx : 1;
    if ((st = rpiv_field_new((int)c.nx, (int)c.ny, x0, y0, dx, dy, &f)))
        goto cleanup_nc;
    f->scale_mm_per_px = pos_att(&c, "scale_mm_per_px");
    f->dt_s = pos_att(&c, "dt_s");
    char orient[16];
    text_att(&c, NC_GLOBAL, "orientation", orient, sizeof orient);
    f->y_up = !strcmp(orient, "y-up");
    size_t n = c.nx * c.ny;
    buf = malloc(n * sizeof *buf);
    tmp = malloc(n * sizeof *tmp);
    if (!buf || !tmp) {
        st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory for a %zu x %zu field", path, c.nx, c.ny);
        goto cleanup_nc;
    }
    if ((st = read_vectors(&c, f, px, buf, tmp)) || (st = read_quantities(&c, f, buf, tmp)) ||
        (st = field_check_units(f, path)))
        goto cleanup_nc;
    *out = f;
    f = NULL;
cleanup_nc:
    free(buf);
    free(tmp);
    rpiv_field_free(f);
    nc_close(c.ncid);
    return st;
}
