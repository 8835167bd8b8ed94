/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/base/atomic.h - atomic replacement of a file (base's internal toolbox, not installed).
 * Every output of librpiv and of the rpiv program goes through it: the data are written
 * under a unique temporary name in the folder of the final path (O_EXCL), flushed and
 * fsync'd, renamed over the final path, and the folder is fsync'd so the rename is durable.
 * On any failure the temporary file is removed and the old file is left intact. */
#ifndef RPIV_BASE_ATOMIC_H
#define RPIV_BASE_ATOMIC_H

#include "rpiv/error.h"

#include <stdio.h>

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

/* Remove the temporary files that writers of path killed before their commit left in its
 * folder (path.tmp-<pid>-<hex>, and path.tmp<pid> of earlier rpiv versions). Best effort:
 * call it only where no other process may be writing path at the same time. */
void atomic_remove_stale(const char *path);

#endif /* RPIV_BASE_ATOMIC_H */
