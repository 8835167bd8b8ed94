/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/progress.h - progress reporting and cancellation for long library calls.
 * The library calls the callback from the calling thread only, between work items. A non-zero
 * return asks the call to stop: it saves what it can and returns RPIV_EINTR. */
#ifndef RPIV_PROGRESS_H
#define RPIV_PROGRESS_H

#include <stddef.h>

typedef int (*rpiv_progress_fn)(void *user, size_t done, size_t total);

typedef struct rpiv_progress {
    rpiv_progress_fn fn; /* NULL: no reporting */
    void *user;
} rpiv_progress;

/* Call p->fn if set; returns its verdict (0 = go on). */
static inline int rpiv_progress_report(const rpiv_progress *p, size_t done, size_t total)
{
    return (p && p->fn) ? p->fn(p->user, done, total) : 0;
}

#endif /* RPIV_PROGRESS_H */
