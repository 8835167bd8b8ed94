/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/field.h - vector fields on a regular grid of window centres, and their files.
 *
 * Point (i, j) (i along x, j along y) has centre (x0 + i*dx, y0 + j*dy) in pixel coordinates of
 * image A (0-based, pixel centres at integers). u is along +x (columns), v along +y (rows,
 * downward), both in pixels of displacement. Arrays are row-major: index j * nx + i. */
#ifndef RPIV_FIELD_H
#define RPIV_FIELD_H

#include "rpiv/error.h"

#include <stddef.h>

enum {
    RPIV_FLAG_VALID = 0,    /* measured and accepted                  */
    RPIV_FLAG_REPLACED = 1, /* rejected by validation and replaced    */
    RPIV_FLAG_MASKED = 2    /* inside the mask or outside the ROI     */
};

typedef struct rpiv_field {
    int nx, ny;       /* grid size                                   */
    double x0, y0;    /* centre of point (0,0), px                   */
    double dx, dy;    /* grid step, px                               */
    float *u, *v;     /* displacement, px                            */
    unsigned char *flag;
    float *peak_ratio; /* highest / second-highest correlation peak (0 if unknown) */
    float *corr;       /* normalised correlation value at the peak   */
    double scale_mm_per_px; /* 0 = not set; with dt_s gives mm and m/s columns */
    double dt_s;            /* 0 = not set */
} rpiv_field;

/* A new zeroed nx x ny field. Release with rpiv_field_free(). */
RPIV_NODISCARD rpiv_status rpiv_field_new(int nx, int ny, double x0, double y0, double dx,
                                          double dy, rpiv_field **out);
void rpiv_field_free(rpiv_field *f); /* NULL is a no-op */
RPIV_NODISCARD rpiv_status rpiv_field_copy(const rpiv_field *f, rpiv_field **out);

/* Free-form "key = value" lines recorded in file headers (processing parameters). */
typedef struct rpiv_meta {
    size_t n;
    char **key, **val; /* owned */
} rpiv_meta;
RPIV_NODISCARD rpiv_status rpiv_meta_add(rpiv_meta *m, const char *key, const char *fmt, ...)
    RPIV_PRINTF(3, 4);
void rpiv_meta_clear(rpiv_meta *m);

/* Save by extension: .txt (text columns x y u v flag peak_ratio correlation [+ mm, m/s]),
 * .nc (NetCDF-4, dims (t,y,x)), .dat (Tecplot ASCII), .vtk (legacy VTK structured grid).
 * meta may be NULL. Written atomically. See docs/formats.md. */
RPIV_NODISCARD rpiv_status rpiv_field_save(const rpiv_field *f, const rpiv_meta *meta,
                                           const char *path);

/* Read a text vector file written by rpiv (or any file with columns x y u v [flag ...] on a
 * regular grid, '#' comments). Errors name file:line. */
RPIV_NODISCARD rpiv_status rpiv_field_load_txt(const char *path, rpiv_field **out);

/* A series of fields of one grid written into one NetCDF file along t. */
typedef struct rpiv_field_series rpiv_field_series;
RPIV_NODISCARD rpiv_status rpiv_field_series_open(const char *path, const rpiv_field *grid,
                                                  const rpiv_meta *meta,
                                                  rpiv_field_series **out);
RPIV_NODISCARD rpiv_status rpiv_field_series_append(rpiv_field_series *s, const rpiv_field *f,
                                                    double t);
/* Close and publish (rename into place). On abort=1 the temporary file is removed. */
RPIV_NODISCARD rpiv_status rpiv_field_series_close(rpiv_field_series *s, int abort);

#endif /* RPIV_FIELD_H */
