/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/field.h - vector fields on a regular grid of window centres, and their files;
 * velocity profiles (alpha, value) and the E1 comparison of profiles and fields.
 *
 * Point (i, j) (i along x, j along y) has centre (x0 + i*dx, y0 + j*dy) in pixel coordinates of
 * image A (0-based, pixel centres at integers). u is along +x (columns), v along +y (rows,
 * downward), both in pixels of displacement. Arrays are row-major: index j * nx + i.
 * A field turned y-up (rpiv_field_y_up) has its origin at the centre of the bottom-left pixel,
 * y upward and v positive upward; y_up records it and every file says which (orientation).
 *
 * Besides u, v, flag, peak_ratio and corr, a field carries any number of named per-vector
 * quantities (uncertainty, bias, vorticity...), each with its unit kind
 * (rpiv_field_add_quantity); they are copied with the field and written by every writer.
 *
 * Files are described in docs/formats.md. Every writer is atomic: the data go to a temporary
 * file in the destination folder, which is flushed, fsync'ed and renamed over the path, so a
 * failed or interrupted save never leaves a partial file nor destroys an existing one.
 * All functions are thread-safe on distinct objects (no global state). */
#ifndef RPIV_FIELD_H
#define RPIV_FIELD_H

#include "rpiv/error.h"

#include <stddef.h>

enum {
    RPIV_FLAG_VALID = 0,    /* measured and accepted                  */
    RPIV_FLAG_REPLACED = 1, /* rejected by validation and replaced    */
    RPIV_FLAG_MASKED = 2    /* inside the mask or outside the ROI     */
};

/* The unit kind of a per-vector quantity: its unit in pixels, and with scale and dt set its
 * physical unit (docs/formats.md). */
typedef enum rpiv_unit {
    RPIV_UNIT_ONE = 0,       /* dimensionless: "1"                                 */
    RPIV_UNIT_PX = 1,        /* a length: px, or mm (x scale)                      */
    RPIV_UNIT_PX_PER_DT = 2, /* a displacement per pair: px/dt, or m/s             */
    RPIV_UNIT_PER_DT = 3,    /* a rate (vorticity, strain): 1/dt, or 1/s           */
    RPIV_UNIT_PER_DT2 = 4    /* a rate squared (Q criterion): 1/dt^2, or 1/s^2     */
} rpiv_unit;
/* Or'ed into a unit: the quantity changes sign when y is reversed (v, vorticity, bias_v). */
#define RPIV_UNIT_ODD_Y        0x100
#define RPIV_QUANTITY_NAME_MAX 32 /* bytes, with the NUL */

/* One extra per-vector quantity: nx * ny floats, row-major like u. */
typedef struct rpiv_quantity {
    char name[RPIV_QUANTITY_NAME_MAX];
    int unit; /* rpiv_unit, | RPIV_UNIT_ODD_Y */
    float *data;
} rpiv_quantity;

typedef struct rpiv_field {
    int nx, ny;    /* grid size                                   */
    double x0, y0; /* centre of point (0,0), px                   */
    double dx, dy; /* grid step, px                               */
    float *u, *v;  /* displacement, px                            */
    unsigned char *flag;
    float *peak_ratio;      /* highest / second-highest correlation peak (0 if unknown) */
    float *corr;            /* normalised correlation value at the peak   */
    double scale_mm_per_px; /* 0 = not set; with dt_s gives mm and m/s columns */
    double dt_s;            /* 0 = not set */
    size_t nq;              /* extra quantities (rpiv_field_add_quantity), owned */
    rpiv_quantity *q;
    int y_up; /* 0: image coordinates (y down); 1: turned by rpiv_field_y_up */
} rpiv_field;

/* A new zeroed nx x ny field (flags RPIV_FLAG_VALID, scale and dt unset). RPIV_EINVAL if
 * nx or ny < 1, a step is not > 0 or a value is not finite; RPIV_ENOMEM. On failure *out is
 * NULL. Release with rpiv_field_free(). */
RPIV_NODISCARD rpiv_status rpiv_field_new(int nx, int ny, double x0, double y0, double dx,
                                          double dy, rpiv_field **out);
void rpiv_field_free(rpiv_field *f); /* NULL is a no-op */
/* A deep copy of f (all arrays, scale and dt). */
RPIV_NODISCARD rpiv_status rpiv_field_copy(const rpiv_field *f, rpiv_field **out);
/* Add a zeroed quantity `name` of unit kind `unit` (rpiv_unit, optionally | RPIV_UNIT_ODD_Y)
 * and set *data (if not NULL) to its nx * ny floats, owned by f. The name starts with a
 * letter, holds letters, digits and '_', is shorter than RPIV_QUANTITY_NAME_MAX and is none
 * of the names the files use already (x, y, t, u, v, flag, chc, peak_ratio, correlation,
 * velocity, x_px..., *_mm, *_ms, *_per_s, *_px): RPIV_EINVAL, also for a name f has. */
RPIV_NODISCARD rpiv_status rpiv_field_add_quantity(rpiv_field *f, const char *name, int unit,
                                                   float **data);
/* The quantity called name, or NULL. */
const rpiv_quantity *rpiv_field_quantity(const rpiv_field *f, const char *name);
/* The name of a unit kind: in pixels ("1", "pix", "pix/dt", "1/dt") or physical ("1", "mm",
 * "m/s", "1/s"). */
const char *rpiv_unit_name(int unit, int physical);
/* The factor from a unit kind's pixel value to its physical value for f's scale and dt (1 for
 * RPIV_UNIT_ONE; 0 if f has no scale and dt). */
double rpiv_unit_factor(const rpiv_field *f, int unit);
/* Turn an image-coordinate field y-up in place: origin at the centre of the bottom-left pixel
 * of an image `height` pixels high (y' = height - 1 - y), rows reordered so y' increases with
 * j, v and every RPIV_UNIT_ODD_Y quantity negated; y_up set. RPIV_EINVAL if it already is
 * or height < 1. */
RPIV_NODISCARD rpiv_status rpiv_field_y_up(rpiv_field *f, int height);

/* ---- derived quantities (src/field/field_derive.c, docs/postprocess.md) ----------------
 *
 * Velocity gradients by the least-squares stencil along each grid line,
 *     du/dx = (2 u[i+2] + u[i+1] - u[i-1] - 2 u[i-2]) / (10 dx),
 * where the four neighbours are unmasked (exact for polynomials up to degree 2); else the
 * central difference (u[i+1] - u[i-1]) / (2 dx); else a one-sided difference; else 0.
 * Derivatives are taken in the field's own coordinates, then turned into the PHYSICAL frame
 * (x right, y up as seen on the image): a field in image coordinates (y_up = 0, y and v down)
 * has its y-derivatives of u and v sign-reversed, so counter-clockwise rotation on the
 * image is positive vorticity whatever the orientation; the quantities do not change sign
 * when the field is turned y-up afterwards. Masked vectors get 0.
 *   vorticity          dv/dx - du/dy                      (1/dt)
 *   divergence         du/dx + dv/dy                      (1/dt)
 *   shear_strain       du/dy + dv/dx                      (1/dt)
 *   normal_strain      du/dx - dv/dy                      (1/dt)
 *   swirling_strength  imaginary part of the complex eigenvalues of the velocity gradient
 *                      tensor, sqrt(det - tr^2/4) where positive, else 0 (1/dt)
 *   q_criterion        (|Omega|^2 - |S|^2) / 2 = -(ux^2 + vy^2)/2 - uy vx  (1/dt^2)
 * Units are per pair interval (u, v in px per pair, x, y in px); with scale and dt set the
 * writers add the values per second. */
enum {
    RPIV_DERIVE_VORTICITY = 1,
    RPIV_DERIVE_DIVERGENCE = 2,
    RPIV_DERIVE_STRAIN = 4, /* shear_strain and normal_strain */
    RPIV_DERIVE_SWIRL = 8,
    RPIV_DERIVE_Q = 16
};
/* Parse a comma-separated list of vorticity, divergence, strain, swirl, q (or "all", or
 * "none"/"" for 0) into a RPIV_DERIVE_* mask. RPIV_EINVAL naming the unknown item. */
RPIV_NODISCARD rpiv_status rpiv_field_derive_parse(const char *list, unsigned *what);
/* Add (or overwrite) the quantities of `what` to f. RPIV_EINVAL for an unknown bit. */
RPIV_NODISCARD rpiv_status rpiv_field_derive(rpiv_field *f, unsigned what);

/* The number of vectors of f flagged `flag` (RPIV_FLAG_VALID, _REPLACED or _MASKED). */
size_t rpiv_field_count(const rpiv_field *f, int flag);

/* Free-form "key = value" lines recorded in file headers (processing parameters). Start
 * from a zeroed struct (rpiv_meta m = {0};) and release with rpiv_meta_clear(). */
typedef struct rpiv_meta {
    size_t n;
    char **key, **val; /* owned */
} rpiv_meta;
/* Add key = printf(fmt, ...), or replace the value if key is already there. The key must
 * start with a letter and hold only letters, digits, '_', '.', '-' (it becomes a NetCDF
 * attribute name): RPIV_EINVAL otherwise. Control characters in the value become spaces. */
RPIV_NODISCARD rpiv_status rpiv_meta_add(rpiv_meta *m, const char *key, const char *fmt, ...)
    RPIV_PRINTF(3, 4);
void rpiv_meta_clear(rpiv_meta *m); /* frees the entries; m is empty and reusable after */

/* The vector-file formats, named by a file's extension (case-insensitive). */
typedef enum rpiv_field_format {
    RPIV_FIELD_UNKNOWN = 0, /* no extension, or another one */
    RPIV_FIELD_TXT = 1,     /* .txt */
    RPIV_FIELD_NC = 2,      /* .nc  */
    RPIV_FIELD_DAT = 3,     /* .dat */
    RPIV_FIELD_VTK = 4      /* .vtk */
} rpiv_field_format;

/* The format path's extension names; *ext (if ext is not NULL) points into path at the
 * extension of its last component, dot included, or at "" when it has none. */
rpiv_field_format rpiv_field_format_of(const char *path, const char **ext);

/* Save by extension (case-insensitive): .txt (text columns x y u v flag peak_ratio
 * correlation, + x_mm y_mm u_ms v_ms when scale and dt are set), .nc (NetCDF-4, dims
 * (t,y,x) with t of length 1, t = 0), .dat (Tecplot ASCII POINT zone), .vtk (legacy VTK
 * ASCII structured grid). meta may be NULL. Written atomically. RPIV_EINVAL for another
 * extension (named in the message), RPIV_EIO if the file cannot be written (path named). */
RPIV_NODISCARD rpiv_status rpiv_field_save(const rpiv_field *f, const rpiv_meta *meta,
                                           const char *path);

/* Read a text vector file written by rpiv, or any whitespace (or comma) separated file with
 * columns x y u v [flag ...] on a regular grid, in any row order, '#' comments (OpenPIV's
 * text output reads as is). The grid (nx, ny, x0, y0, dx, dy; dx, dy > 0, so a file with y
 * decreasing comes back sorted ascending) is inferred from the coordinates. Columns 6 and 7
 * are peak ratio and correlation in rpiv's own files only (their first line is
 * "# rpiv vector field 1"); scale_mm_per_px and dt_s come back from rpiv's header.
 * RPIV_EIO if it cannot be opened; RPIV_EFORMAT with "file:line:" for a non-numeric or
 * non-finite value, fewer than 4 columns, a column count that changes, a flag that is not an
 * integer 0..255, a point off the grid or repeated, and "file:" for missing points or no
 * data. */
RPIV_NODISCARD rpiv_status rpiv_field_load_txt(const char *path, rpiv_field **out);

/* Read time step t (0: the first) of a NetCDF vector file: rpiv's own (.nc of rpiv piv, any
 * orientation, with or without physical units: the field comes back in pixels with its scale,
 * dt, orientation and extra quantities, as rpiv_field_save wrote it) or a pivpy-like file of
 * another tool (u, v on dims y, x, t with coordinates x, y on a regular increasing grid;
 * optional chc, 0 read as replaced; non-finite vectors masked; other float variables on
 * (y, x, t) become quantities, unit from their units attribute). RPIV_EIO if it cannot be
 * opened; RPIV_EFORMAT naming the file and what is missing or wrong; RPIV_EINVAL if t is not
 * below the file's number of time steps (the range named). */
RPIV_NODISCARD rpiv_status rpiv_field_load_nc(const char *path, size_t t, rpiv_field **out);

/* A series of fields of one grid written into one NetCDF-4 file along an unlimited t. The
 * file appears at path only when the series is closed without abort; until then it is a
 * temporary file next to it. grid gives the grid, scale and dt (its data are not written). */
typedef struct rpiv_field_series rpiv_field_series;
RPIV_NODISCARD rpiv_status rpiv_field_series_open(const char *path, const rpiv_field *grid,
                                                  const rpiv_meta *meta, rpiv_field_series **out);
/* Append f at time t (s). RPIV_ESIZE if f's grid differs from the series'; RPIV_EIO. */
RPIV_NODISCARD rpiv_status rpiv_field_series_append(rpiv_field_series *s, const rpiv_field *f,
                                                    double t);
/* Close and publish (rename into place). On abort=1 the temporary file is removed. s is
 * freed in every case; NULL is a no-op. */
RPIV_NODISCARD rpiv_status rpiv_field_series_close(rpiv_field_series *s, int abort);
/* Close and publish the fields appended so far at path instead of the series' own path,
 * which is left untouched (an interrupted run writes its partial series beside a complete
 * one, never over it), with the global attribute rpiv_partial = note if note is not NULL.
 * Nothing is written if no field was appended (*written = 0). s is freed in every case. */
RPIV_NODISCARD rpiv_status rpiv_field_series_close_as(rpiv_field_series *s, const char *path,
                                                      const char *note, int *written);

/* ---- profiles and comparisons ------------------------------------------------ */

/* A profile: value(alpha) at n >= 2 strictly increasing alpha (a generic coordinate such as
 * z*, y*, x*). */
typedef struct rpiv_profile {
    size_t n;
    double *alpha, *value; /* owned */
} rpiv_profile;

/* Read a profile text file: '#' comments, data lines "alpha value [ignored columns...]".
 * Alpha must be strictly monotonic (a decreasing file is reversed). RPIV_EIO if it cannot be
 * opened; RPIV_EFORMAT with file:line for a non-numeric or non-finite value, fewer than 2
 * columns, alpha not monotonic; "file:" if fewer than 2 points. */
RPIV_NODISCARD rpiv_status rpiv_profile_load(const char *path, rpiv_profile **out);
void rpiv_profile_free(rpiv_profile *p); /* NULL is a no-op */

/* The number of columns on the first data line of a text file ('#' comments and blank lines
 * skipped): 2 for a profile, 4 or more for a vector file. RPIV_EIO, RPIV_EFORMAT (no data). */
RPIV_NODISCARD rpiv_status rpiv_text_columns(const char *path, int *ncol);

/* E1 (Eq. "E1"): sqrt(int (ref - cmp)^2 da) / int ref da over the samples alpha[0..n-1]
 * (increasing), trapezoid rule. RPIV_EINVAL if n < 2, alpha not increasing, or int ref = 0. */
RPIV_NODISCARD rpiv_status rpiv_e1(const double *alpha, const double *ref, const double *cmp,
                                   size_t n, double *e1);

/* What a comparison measured: E1 (Eq. "E1" of the paper, see rpiv_e1), and the RMS and
 * largest absolute difference ref - cmp, in the unit of the values; n samples used; for
 * profiles, the alpha range [alpha0, alpha1] compared. */
typedef struct rpiv_compare {
    double e1, rms, max_abs;
    size_t n;
    double alpha0, alpha1;
} rpiv_compare;

/* E1 between two profiles, on the reference's samples that lie in the range of cmp, with
 * cmp interpolated linearly there (GSL). Alpha is rescaled to [0, 1] over the compared range
 * before Eq. "E1" is applied, so that E1 = RMS difference / mean reference whatever the unit
 * of alpha (the paper's alpha spans [0, 1]). RPIV_ESIZE if fewer than 2 reference samples lie
 * in cmp's range ("do not overlap"); RPIV_EINVAL if the reference integrates to zero. */
RPIV_NODISCARD rpiv_status rpiv_profile_compare(const rpiv_profile *ref, const rpiv_profile *cmp,
                                                rpiv_compare *out);

typedef enum rpiv_component {
    RPIV_COMPONENT_MAG = 0, /* |(u, v)| */
    RPIV_COMPONENT_U = 1,
    RPIV_COMPONENT_V = 2
} rpiv_component;

/* E1 between two fields on the same grid, over the points masked in neither: the discrete
 * form of Eq. "E1" on the grid, sqrt(mean (ref - cmp)^2) / mean ref of the chosen component
 * (px), with RMS and max |ref - cmp|. RPIV_ESIZE if the grids differ or no point is left;
 * RPIV_EINVAL if the mean reference is zero. */
RPIV_NODISCARD rpiv_status rpiv_field_compare(const rpiv_field *ref, const rpiv_field *cmp,
                                              rpiv_component c, rpiv_compare *out);

#endif /* RPIV_FIELD_H */
