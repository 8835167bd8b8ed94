/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field/field_impl.h - helpers shared by the field writers (field.c, field_nc.c, field_ascii.c):
 * atomic file replacement and meta lookup. Not installed. */
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
RPIV_NODISCARD rpiv_status field_save_nc(const rpiv_field *f, const rpiv_meta *meta,
                                         const char *path);

/* 1 when the field carries physical units (both scale and dt set). */
int field_has_phys(const rpiv_field *f);

#endif /* RPIV_FIELD_IMPL_H */
