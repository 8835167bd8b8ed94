/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field/field_ascii.c - the text writers: rpiv's columns (OpenPIV-like), Tecplot ASCII
 * (POINT zone) and legacy VTK (ASCII structured grid, the arrays as FIELD data so that VTK's
 * default reader settings load all of them). All three write the same columns, from
 * field_columns(), with their units in the header. */
#include "field_fmt.h"
#include "field_impl.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static rpiv_status write_check(FILE *fp, const char *path)
{
    if (fflush(fp) == EOF || ferror(fp))
        return rpiv_fail(RPIV_EIO, "%s: cannot write: %s", path, strerror(errno));
    return RPIV_OK;
}

/* Column c's value at point (i, j), index k, into out (FIELD_FMT_MAX bytes); its length.
 * Floats in the shortest %g form (6 to 9 digits) that reads back as the same float, so text
 * files round-trip exactly and stay readable (0.3187, not 0.318699986). */
static int put_value(char *out, const rpiv_field *f, const field_col *c, int i, int j, size_t k)
{
    switch (c->kind) {
    case FIELD_COL_X:
        return field_fmt_g(out, (f->x0 + i * f->dx) * c->factor, 10);
    case FIELD_COL_Y:
        return field_fmt_g(out, (f->y0 + j * f->dy) * c->factor, 10);
    case FIELD_COL_FLAG: { /* 0 .. 255 */
        unsigned v = f->flag[k];
        int n = 0;
        if (v >= 100)
            out[n++] = (char)('0' + v / 100);
        if (v >= 10)
            out[n++] = (char)('0' + v / 10 % 10);
        out[n++] = (char)('0' + v % 10);
        return n;
    }
    default:
        if (c->physical)
            return field_fmt_g(out, (double)c->data[k] * c->factor, 9);
        return field_fmt_float(out, c->data[k]);
    }
}

/* The data rows, a point per line, columns c[0..nc-1] separated by one space, in grid order
 * (x fastest). Large fields are formatted by blocks of rows on several threads, each block
 * into its own buffer, and written in order: the bytes do not depend on the threads. */
static rpiv_status write_rows(FILE *fp, const rpiv_field *f, const field_col *c, size_t nc,
                              const char *path)
{
    enum { BLOCK = 16 }; /* rows per block */
    const int nblocks = (f->ny + BLOCK - 1) / BLOCK;
    const int par = (size_t)f->nx * (size_t)f->ny >= 20000;
    const size_t line_max = nc * (FIELD_FMT_MAX + 1) + 1;
    const size_t cap = (size_t)BLOCK * (size_t)f->nx * line_max;
    int bad = 0, err = 0;
#pragma omp parallel if (par)
    {
        char *buf = malloc(cap); /* one per thread, reused block after block */
#pragma omp for ordered schedule(static, 1)
        for (int b = 0; b < nblocks; b++) {
            size_t len = 0;
            for (int j = b * BLOCK; buf && j < f->ny && j < (b + 1) * BLOCK; j++)
                for (int i = 0; i < f->nx; i++) {
                    size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
                    for (size_t m = 0; m < nc; m++) {
                        if (m)
                            buf[len++] = ' ';
                        len += (size_t)put_value(buf + len, f, &c[m], i, j, k);
                    }
                    buf[len++] = '\n';
                }
#pragma omp ordered
            {
                if (!buf) {
                    bad = 1;
                } else if (!bad && !err && len && fwrite(buf, 1, len, fp) != len) {
                    err = errno ? errno : EIO;
                }
            }
        }
        free(buf);
    }
    if (bad)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
    if (err)
        return rpiv_fail(RPIV_EIO, "%s: cannot write: %s", path, strerror(err));
    return RPIV_OK;
}

/* The header lines shared by the text and Tecplot files (after "# rpiv vector field 1"). */
static void common_header(FILE *fp, const rpiv_field *f, const rpiv_meta *meta)
{
    fprintf(fp, "# orientation = %s\n", f->y_up ? "y-up" : "image");
    if (f->scale_mm_per_px > 0)
        fprintf(fp, "# scale_mm_per_px = %.17g\n", f->scale_mm_per_px);
    if (f->dt_s > 0)
        fprintf(fp, "# dt_s = %.17g\n", f->dt_s);
    for (size_t q = 0; q < f->nq; q++)
        fprintf(fp, "# quantity = %s %s%s\n", f->q[q].name, rpiv_unit_name(f->q[q].unit, 0),
                f->q[q].unit & RPIV_UNIT_ODD_Y ? " odd_y" : "");
    for (size_t k = 0; meta && k < meta->n; k++)
        fprintf(fp, "# %s = %s\n", meta->key[k], meta->val[k]);
}

static void units_line(FILE *fp, const field_col *c, size_t nc)
{
    fputs("# units =", fp);
    for (size_t k = 0; k < nc; k++)
        fprintf(fp, " %s", c[k].unit);
    fputc('\n', fp);
}

rpiv_status field_write_tecplot(const rpiv_field *f, const rpiv_meta *meta, FILE *fp,
                                const char *path)
{
    size_t nc;
    field_col *c = field_columns(f, &nc);
    if (!c)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
    /* Tecplot's ASCII reader skips lines that start with '#' */
    fprintf(fp, "# rpiv vector field 1\n");
    common_header(fp, f, meta);
    units_line(fp, c, nc);
    fprintf(fp, "TITLE = \"rpiv vector field\"\nVARIABLES =");
    for (size_t k = 0; k < nc; k++)
        fprintf(fp, "%s\"%s\"", k ? "," : " ", c[k].name);
    fprintf(fp, "\nZONE T=\"rpiv\", I=%d, J=%d, F=POINT\n", f->nx, f->ny);
    /* POINT order: I (x) varies fastest, as in rpiv's row-major arrays */
    rpiv_status st = write_rows(fp, f, c, nc, path);
    free(c);
    return st ? st : write_check(fp, path);
}

/* Legacy VTK: the velocity as VECTORS (the active vectors), every other array as FIELD data
 * (VTK's legacy reader loads all FIELD arrays, but only the first SCALARS unless told to read
 * them all). The title line (at most 255 characters) gives orientation and units. */
rpiv_status field_write_vtk(const rpiv_field *f, const rpiv_meta *meta, FILE *fp, const char *path)
{
    (void)meta; /* legacy VTK has one title line and no place for key = value pairs */
    size_t n = (size_t)f->nx * (size_t)f->ny, nc;
    int phys = field_has_phys(f);
    field_col *c = field_columns(f, &nc);
    if (!c)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
    char title[256];
    int at = snprintf(title, sizeof title,
                      "rpiv vector field %d x %d, orientation %s (%s); units: x y pix, velocity "
                      "pix/dt",
                      f->nx, f->ny, f->y_up ? "y-up" : "image", f->y_up ? "y up" : "y down");
    for (size_t k = 0; k < nc && at < (int)sizeof title; k++)
        if (c[k].kind == FIELD_COL_FLOAT && k >= 7 && !c[k].physical)
            at += snprintf(title + at, sizeof title - (size_t)at, ", %s %s", c[k].name, c[k].unit);
    if (phys && at < (int)sizeof title)
        at += snprintf(title + at, sizeof title - (size_t)at,
                       ", coords_mm mm, velocity_ms m/s, *_mm mm, *_ms m/s, *_per_s 1/s");
    if (at >= (int)sizeof title)
        memcpy(title + sizeof title - 4, "...", 4);
    fprintf(fp, "# vtk DataFile Version 3.0\n%s\n", title);
    fprintf(fp, "ASCII\nDATASET STRUCTURED_GRID\n");
    fprintf(fp, "DIMENSIONS %d %d 1\n", f->nx, f->ny);
    fprintf(fp, "POINTS %zu double\n", n);
    for (int j = 0; j < f->ny; j++)
        for (int i = 0; i < f->nx; i++)
            fprintf(fp, "%.10g %.10g 0\n", f->x0 + i * f->dx, f->y0 + j * f->dy);
    fprintf(fp, "POINT_DATA %zu\n", n);
    fprintf(fp, "VECTORS velocity float\n");
    for (size_t k = 0; k < n; k++)
        fprintf(fp, "%.9g %.9g 0\n", (double)f->u[k], (double)f->v[k]);
    /* FIELD arrays: flag, peak_ratio, correlation, extras, then the physical ones (the
     * coordinates and the velocity as 3-component arrays) */
    size_t narr = 3 + f->nq + (phys ? 2 : 0);
    for (size_t k = 11 + f->nq; k < nc; k++)
        narr += c[k].physical;
    fprintf(fp, "FIELD point_arrays %zu\n", narr);
    for (size_t m = 4; m < nc; m++) {
        if (m >= 7 + f->nq && m < 11 + f->nq) /* x_mm .. v_ms: as coords_mm and velocity_ms below */
            continue;
        if (c[m].kind == FIELD_COL_FLAG) {
            fprintf(fp, "flag 1 %zu int\n", n);
            for (size_t k = 0; k < n; k++)
                fprintf(fp, "%d\n", f->flag[k]);
            continue;
        }
        fprintf(fp, "%s 1 %zu float\n", c[m].name, n);
        for (size_t k = 0; k < n; k++)
            fprintf(fp, "%.9g\n", (double)c[m].data[k] * c[m].factor);
        if (m == 6 + f->nq && phys) {
            double s = f->scale_mm_per_px, ms = rpiv_unit_factor(f, RPIV_UNIT_PX_PER_DT);
            fprintf(fp, "coords_mm 3 %zu double\n", n);
            for (int j = 0; j < f->ny; j++)
                for (int i = 0; i < f->nx; i++)
                    fprintf(fp, "%.10g %.10g 0\n", (f->x0 + i * f->dx) * s,
                            (f->y0 + j * f->dy) * s);
            fprintf(fp, "velocity_ms 3 %zu float\n", n);
            for (size_t k = 0; k < n; k++)
                fprintf(fp, "%.9g %.9g 0\n", (double)f->u[k] * ms, (double)f->v[k] * ms);
        }
    }
    free(c);
    return write_check(fp, path);
}

/* ---- text columns ----------------------------------------------------------- */

rpiv_status field_write_txt(const rpiv_field *f, const rpiv_meta *meta, FILE *fp, const char *path)
{
    size_t nc;
    field_col *c = field_columns(f, &nc);
    if (!c)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
    fprintf(fp, "# rpiv vector field 1\n");
    fprintf(fp, "# nx = %d\n# ny = %d\n", f->nx, f->ny);
    fprintf(fp, "# x0 = %.17g\n# y0 = %.17g\n# dx = %.17g\n# dy = %.17g\n", f->x0, f->y0, f->dx,
            f->dy);
    common_header(fp, f, meta);
    units_line(fp, c, nc);
    fputc('#', fp);
    for (size_t k = 0; k < nc; k++)
        fprintf(fp, " %s", c[k].name);
    fputc('\n', fp);
    rpiv_status st = write_rows(fp, f, c, nc, path);
    free(c);
    return st ? st : write_check(fp, path);
}
