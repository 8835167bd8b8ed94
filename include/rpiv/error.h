/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/error.h - status codes and the per-thread error message.
 *
 * Every fallible rpiv function returns an rpiv_status; RPIV_OK (0) is success. On failure a
 * one-line message naming the file, key or value at fault is left in a thread-local buffer,
 * read with rpiv_errmsg(). The library never prints, exits or aborts on user error. */
#ifndef RPIV_ERROR_H
#define RPIV_ERROR_H

#if defined(__GNUC__) || defined(__clang__)
#define RPIV_NODISCARD    __attribute__((warn_unused_result))
#define RPIV_PRINTF(a, b) __attribute__((format(printf, a, b)))
#else
#define RPIV_NODISCARD
#define RPIV_PRINTF(a, b)
#endif

typedef enum rpiv_status {
    RPIV_OK = 0,       /* success                                                  */
    RPIV_ENOMEM = 1,   /* an allocation failed                                     */
    RPIV_EINVAL = 2,   /* an argument or parameter is out of its documented range  */
    RPIV_EIO = 3,      /* a file could not be opened, read or written              */
    RPIV_EFORMAT = 4,  /* a file is corrupt, truncated or of an unsupported kind   */
    RPIV_ESIZE = 5,    /* sizes do not match (image pair, window larger than image) */
    RPIV_ECONFIG = 6,  /* a configuration file or option is wrong                  */
    RPIV_ENUMERIC = 7, /* a numerical method failed to converge or gave NaN        */
    RPIV_EINTR = 8,    /* the run was interrupted (signal); work so far is saved   */
    RPIV_ELIMIT = 9    /* the work would exceed a configured resource limit        */
} rpiv_status;

/* The message of the last failure on this thread ("" if none). Valid until the next failure. */
const char *rpiv_errmsg(void);

/* A short fixed description of a status code ("out of memory", ...). */
const char *rpiv_strerror(rpiv_status st);

/* Record a formatted message for this thread and return code (so callers write
 * `return rpiv_fail(RPIV_EIO, "%s: cannot open", path);`). */
rpiv_status rpiv_fail(rpiv_status code, const char *fmt, ...) RPIV_PRINTF(2, 3);

/* Clear this thread's message. */
void rpiv_errclear(void);

/* Once per process, before other calls: switch off the error channels of GSL, libtiff and
 * FFTW's abort paths so that their failures come back as rpiv codes. Idempotent. */
void rpiv_init(void);

#endif /* RPIV_ERROR_H */
