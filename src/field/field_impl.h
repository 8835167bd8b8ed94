/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field/field_impl.h - helpers shared by the field writers (field.c, field_nc.c,
 * field_ascii.c): atomic file replacement and meta lookup. Not installed. */
#ifndef RPIV_FIELD_IMPL_H
#define RPIV_FIELD_IMPL_H

#include "rpiv/field.h"

#include "base/atomic.h"
#include "base/text.h"

#include <stdio.h>
#include <sys/types.h>

/* Writers by format; each writes into af (already open) and names af->path in messages. */
RPIV_NODISCARD rpiv_status field_write_txt(const rpiv_field *f, const rpiv_meta *meta, FILE *fp,
                                           const char *path);
RPIV_NODISCARD rpiv_status field_write_tecplot(const rpiv_field *f, const rpiv_meta *meta, FILE *fp,
                                               const char *path);
RPIV_NODISCARD rpiv_status field_write_vtk(const rpiv_field *f, const rpiv_meta *meta, FILE *fp,
                                           const char *path);
/* RPIV_EFORMAT naming path when f's scale would put its mm or m/s columns beyond a float
 * (field_load.c; both loaders). */
RPIV_NODISCARD rpiv_status field_check_units(const rpiv_field *f, const char *path);
RPIV_NODISCARD rpiv_status field_save_nc(const rpiv_field *f, const rpiv_meta *meta,
                                         const char *path);

/* 1 when the field carries physical units (both scale and dt set). */
int field_has_phys(const rpiv_field *f);

/* One column (array) of the text, Tecplot and VTK writers. */
enum { FIELD_COL_X, FIELD_COL_Y, FIELD_COL_FLAG, FIELD_COL_FLOAT };
typedef struct field_col {
    char name[RPIV_QUANTITY_NAME_MAX + 8];
    const char *unit;
    int kind;          /* FIELD_COL_* */
    const float *data; /* FIELD_COL_FLOAT */
    double factor;     /* times the pixel value: 1, or the physical factor */
    int physical;      /* 1 for the physical copies (x_mm ... and <name>_<unit>) */
} field_col;
/* The columns every writer writes, in this order: x y u v flag peak_ratio correlation, the
 * extra quantities (in pixel units), then with scale and dt x_mm y_mm u_ms v_ms and each extra
 * quantity with a unit as <name>_mm, _ms or _per_s. *ncol gets the count; free() the array.
 * NULL when out of memory. */
field_col *field_columns(const rpiv_field *f, size_t *ncol);
/* The suffix of a unit kind's physical copy ("_mm", "_ms", "_per_s"; "" for RPIV_UNIT_ONE). */
const char *field_phys_suffix(int unit);
/* "image" or "y-up" */
const char *field_orientation(const rpiv_field *f);
/* The unit kind named by rpiv_unit_name(unit, 0), or -1. */
int field_unit_of_name(const char *name);

#endif /* RPIV_FIELD_IMPL_H */
