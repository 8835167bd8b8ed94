/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/field_impl.h - helpers shared by the field writers (field.c, field_nc.c, field_ascii.c):
 * atomic file replacement and meta lookup. Not installed. */
#ifndef RPIV_FIELD_IMPL_H
#define RPIV_FIELD_IMPL_H

#include "rpiv/field.h"

#include <stdio.h>
#include <sys/types.h>

/* A file being written under a temporary name in the folder of its final path. */
typedef struct atomic_file {
    char *path; /* final path (owned copy)                 */
    char *tmp;  /* temporary path in the same folder       */
    FILE *fp;   /* open stream on tmp (NULL for NetCDF use) */
} atomic_file;

/* Create a new temporary file next to path (mode 0666 less the umask). With want_stream the
 * file is opened as a stdio stream in af->fp; otherwise it is created empty and closed, for a
 * library (NetCDF) that opens it by name. Error names path. */
RPIV_NODISCARD rpiv_status atomic_begin(atomic_file *af, const char *path, int want_stream);
/* Flush, fsync and close the stream (if any), then rename tmp over path and fsync the folder.
 * On failure the temporary file is removed and the old path is left untouched. Frees af. */
RPIV_NODISCARD rpiv_status atomic_commit(atomic_file *af);
/* Remove the temporary file and free af. */
void atomic_abort(atomic_file *af);

/* The extension of path after the last '.' of its last component, or "" if none. */
const char *field_ext(const char *path);

/* Writers by format; each writes into af (already open) and names af->path in messages. */
RPIV_NODISCARD rpiv_status field_write_txt(const rpiv_field *f, const rpiv_meta *meta, FILE *fp,
                                           const char *path);
RPIV_NODISCARD rpiv_status field_write_tecplot(const rpiv_field *f, const rpiv_meta *meta, FILE *fp,
                                               const char *path);
RPIV_NODISCARD rpiv_status field_write_vtk(const rpiv_field *f, const rpiv_meta *meta, FILE *fp,
                                           const char *path);
RPIV_NODISCARD rpiv_status field_save_nc(const rpiv_field *f, const rpiv_meta *meta,
                                         const char *path);

/* The next line of a text file into *line (getline), counting *lineno: its length, -1 at the
 * end, or -2 with *st set (RPIV_EFORMAT, "path:line: NUL byte") when the line holds a NUL
 * byte: a binary file, which the string functions would read only up to the NUL. */
ssize_t text_getline(FILE *fp, char **line, size_t *cap, const char *path, long *lineno,
                     rpiv_status *st);

/* 1 when the field carries physical units (both scale and dt set). */
int field_has_phys(const rpiv_field *f);

#endif /* RPIV_FIELD_IMPL_H */
