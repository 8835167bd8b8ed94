/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "rpiv/error.h"

#include <gsl/gsl_errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <tiffio.h>

#define MSG_MAX 1024

static _Thread_local char msg[MSG_MAX];

const char *rpiv_errmsg(void)
{
    return msg;
}

void rpiv_errclear(void)
{
    msg[0] = '\0';
}

rpiv_status rpiv_fail(rpiv_status code, const char *fmt, ...)
{
    va_list ap, again;
    va_start(ap, fmt);
    va_copy(again, ap);
    int n = vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    /* too long (a long path): keep the start and the end, where the reason is (issue 20
     * item 10), and cut the middle */
    char *full = n >= MSG_MAX ? malloc((size_t)n + 1) : NULL;
    if (full) {
        vsnprintf(full, (size_t)n + 1, fmt, again);
        size_t head = 200, tail = MSG_MAX - head - 7;
        snprintf(msg, sizeof msg, "%.*s [...]%s", (int)head, full, full + (size_t)n - tail);
        free(full);
    }
    va_end(again);
    return code;
}

const char *rpiv_strerror(rpiv_status st)
{
    static const char *const text[] = {
        "success",         "out of memory",           "invalid argument",    "input/output error",
        "bad file format", "size mismatch",           "configuration error", "numerical failure",
        "interrupted",     "resource limit exceeded",
    };
    if ((unsigned)st < sizeof text / sizeof text[0])
        return text[st];
    return "unknown status";
}

void rpiv_init(void)
{
    gsl_set_error_handler_off();
    /* libtiff messages are collected per call by the image reader (TIFFOpenOptions);
     * the global handlers are silenced so nothing reaches stderr from the library. */
    TIFFSetErrorHandler(NULL);
    TIFFSetWarningHandler(NULL);
}
