/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/base/text.c - reading text inputs line by line. */
#include "text.h"

#include <math.h>
#include <stdlib.h>
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

int text_is_data(const char *line)
{
    const char *s = line + strspn(line, " \t\r\n");
    return *s != '\0' && *s != '#';
}

int text_columns(const char *line, double *vals, int max, const char *path, long lineno,
                 rpiv_status *st)
{
    static const char sep[] = " \t\r\n,";
    int nc = 0;
    for (const char *tok = line + strspn(line, sep); *tok; tok += strspn(tok, sep)) {
        size_t len = strcspn(tok, sep);
        char *end;
        double d = strtod(tok, &end);
        if (end != tok + len) {
            *st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: column %d: '%.*s' is not a number", path, lineno,
                            nc + 1, len < 40 ? (int)len : 40, tok);
            return -1;
        }
        if (!isfinite(d)) {
            *st = rpiv_fail(RPIV_EFORMAT, "%s:%ld: column %d is %s", path, lineno, nc + 1,
                            isnan(d) ? "NaN" : "infinite");
            return -1;
        }
        if (nc < max)
            vals[nc] = d;
        nc++;
        tok += len;
    }
    return nc;
}
