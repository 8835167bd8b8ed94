/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field/field_ascii.c - the text writers: rpiv's columns (OpenPIV-like), Tecplot ASCII
 * (POINT zone) and legacy VTK (ASCII structured grid), in the form ParaView, Tecplot and
 * Insight/DaVis exports use. */
#include "field_impl.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static rpiv_status write_check(FILE *fp, const char *path)
{
    if (ferror(fp))
        return rpiv_fail(RPIV_EIO, "%s: cannot write: %s", path, strerror(errno));
    return RPIV_OK;
}

rpiv_status field_write_tecplot(const rpiv_field *f, const rpiv_meta *meta, FILE *fp,
                                const char *path)
{
    int phys = field_has_phys(f);
    /* Tecplot's ASCII reader skips lines that start with '#' */
    fprintf(fp, "# rpiv vector field 1\n");
    if (f->scale_mm_per_px > 0)
        fprintf(fp, "# scale_mm_per_px = %.17g\n", f->scale_mm_per_px);
    if (f->dt_s > 0)
        fprintf(fp, "# dt_s = %.17g\n", f->dt_s);
    for (size_t k = 0; meta && k < meta->n; k++)
        fprintf(fp, "# %s = %s\n", meta->key[k], meta->val[k]);
    fprintf(fp, "TITLE = \"rpiv vector field\"\n");
    fprintf(fp, "VARIABLES = \"x\",\"y\",\"u\",\"v\",\"flag\",\"peak_ratio\",\"correlation\"%s\n",
            phys ? ",\"x_mm\",\"y_mm\",\"u_ms\",\"v_ms\"" : "");
    fprintf(fp, "ZONE T=\"rpiv\", I=%d, J=%d, F=POINT\n", f->nx, f->ny);
    /* POINT order: I (x) varies fastest, as in rpiv's row-major arrays */
    for (int j = 0; j < f->ny; j++) {
        for (int i = 0; i < f->nx; i++) {
            size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
            double x = f->x0 + i * f->dx, y = f->y0 + j * f->dy;
            fprintf(fp, "%.10g %.10g %.9g %.9g %d %.9g %.9g", x, y, (double)f->u[k],
                    (double)f->v[k], f->flag[k], (double)f->peak_ratio[k], (double)f->corr[k]);
            if (phys) {
                double s = f->scale_mm_per_px, ms = s * 1e-3 / f->dt_s;
                fprintf(fp, " %.10g %.10g %.9g %.9g", x * s, y * s, (double)f->u[k] * ms,
                        (double)f->v[k] * ms);
            }
            fputc('\n', fp);
        }
    }
    return write_check(fp, path);
}

rpiv_status field_write_vtk(const rpiv_field *f, const rpiv_meta *meta, FILE *fp, const char *path)
{
    (void)meta; /* legacy VTK has one title line and no place for key = value pairs */
    size_t n = (size_t)f->nx * (size_t)f->ny;
    fprintf(fp, "# vtk DataFile Version 3.0\n");
    fprintf(fp, "rpiv vector field %d x %d, x y u v in px (y downward)\n", f->nx, f->ny);
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
    fprintf(fp, "SCALARS flag int 1\nLOOKUP_TABLE default\n");
    for (size_t k = 0; k < n; k++)
        fprintf(fp, "%d\n", f->flag[k]);
    fprintf(fp, "SCALARS peak_ratio float 1\nLOOKUP_TABLE default\n");
    for (size_t k = 0; k < n; k++)
        fprintf(fp, "%.9g\n", (double)f->peak_ratio[k]);
    fprintf(fp, "SCALARS correlation float 1\nLOOKUP_TABLE default\n");
    for (size_t k = 0; k < n; k++)
        fprintf(fp, "%.9g\n", (double)f->corr[k]);
    return write_check(fp, path);
}

/* ---- text columns ----------------------------------------------------------- */

/* The shortest %g form (6 to 9 digits) that reads back as the same float, so text files
 * round-trip exactly and stay readable (0.3187, not 0.318699986). */
static void put_float(FILE *fp, float v)
{
    char buf[32];
    for (int p = 6; p <= 9; p++) {
        snprintf(buf, sizeof buf, "%.*g", p, (double)v);
        if (strtof(buf, NULL) == v)
            break;
    }
    fputs(buf, fp);
}

rpiv_status field_write_txt(const rpiv_field *f, const rpiv_meta *meta, FILE *fp, const char *path)
{
    int phys = field_has_phys(f);
    fprintf(fp, "# rpiv vector field 1\n");
    fprintf(fp, "# nx = %d\n# ny = %d\n", f->nx, f->ny);
    fprintf(fp, "# x0 = %.17g\n# y0 = %.17g\n# dx = %.17g\n# dy = %.17g\n", f->x0, f->y0, f->dx,
            f->dy);
    if (f->scale_mm_per_px > 0)
        fprintf(fp, "# scale_mm_per_px = %.17g\n", f->scale_mm_per_px);
    if (f->dt_s > 0)
        fprintf(fp, "# dt_s = %.17g\n", f->dt_s);
    for (size_t k = 0; meta && k < meta->n; k++)
        fprintf(fp, "# %s = %s\n", meta->key[k], meta->val[k]);
    fprintf(fp, "# x y u v flag peak_ratio correlation%s\n", phys ? " x_mm y_mm u_ms v_ms" : "");
    for (int j = 0; j < f->ny; j++) {
        for (int i = 0; i < f->nx; i++) {
            size_t k = (size_t)j * (size_t)f->nx + (size_t)i;
            double x = f->x0 + i * f->dx, y = f->y0 + j * f->dy;
            fprintf(fp, "%.10g %.10g ", x, y);
            put_float(fp, f->u[k]);
            fputc(' ', fp);
            put_float(fp, f->v[k]);
            fprintf(fp, " %d ", f->flag[k]);
            put_float(fp, f->peak_ratio[k]);
            fputc(' ', fp);
            put_float(fp, f->corr[k]);
            if (phys) {
                double s = f->scale_mm_per_px, ms = s * 1e-3 / f->dt_s;
                fprintf(fp, " %.10g %.10g %.9g %.9g", x * s, y * s, (double)f->u[k] * ms,
                        (double)f->v[k] * ms);
            }
            if (fputc('\n', fp) == EOF)
                return rpiv_fail(RPIV_EIO, "%s: cannot write: %s", path, strerror(errno));
        }
    }
    if (ferror(fp))
        return rpiv_fail(RPIV_EIO, "%s: cannot write: %s", path, strerror(errno));
    return RPIV_OK;
}
