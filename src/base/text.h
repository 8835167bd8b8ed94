/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/base/text.h - reading text inputs (base's internal toolbox, not installed). */
#ifndef RPIV_BASE_TEXT_H
#define RPIV_BASE_TEXT_H

#include "rpiv/error.h"

#include <stdio.h>
#include <sys/types.h>

/* The next line of a text file into *line (getline), counting *lineno: its length, -1 at the
 * end, or -2 with *st set (RPIV_EFORMAT, "path:line: NUL byte") when the line holds a NUL
 * byte: a binary file, which the string functions would read only up to the NUL. */
ssize_t text_getline(FILE *fp, char **line, size_t *cap, const char *path, long *lineno,
                     rpiv_status *st);

#endif /* RPIV_BASE_TEXT_H */
