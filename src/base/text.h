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

/* 1 if line holds data: not blank (spaces, tabs, CR, LF only) and not a comment (its first
 * non-blank character is '#'). */
int text_is_data(const char *line);

/* The numbers of one data line: fields separated by blanks (space, tab, CR, LF) or commas,
 * each read whole by strtod and finite. The first max of them go into vals (max may be 0);
 * returns how many fields the line holds (more than max if it has more; 0 if blank), or -1
 * with *st set (RPIV_EFORMAT, "path:line: column K: 'text' is not a number" or
 * "path:line: column K is NaN" / "... is infinite"). The line is not modified. */
int text_columns(const char *line, double *vals, int max, const char *path, long lineno,
                 rpiv_status *st);

#endif /* RPIV_BASE_TEXT_H */
