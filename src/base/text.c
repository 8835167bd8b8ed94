/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/base/text.c - reading text inputs line by line. */
#include "text.h"

#include <string.h>

ssize_t text_getline(FILE *fp, char **line, size_t *cap, const char *path, long *lineno,
                     rpiv_status *st)
{
    ssize_t len = getline(line, cap, fp);
    if (len < 0)
        return -1;
    ++*lineno;
    if (memchr(*line, '\0', (size_t)len)) {
        *st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: NUL byte: not a text file", path, *lineno);
        return -2;
    }
    return len;
}
