/* SPDX-License-Identifier: GPL-3.0-or-later */
#include "rpiv/error.h"

#include <gsl/gsl_errno.h>
#include <stdarg.h>
#include <stdio.h>
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
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
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
