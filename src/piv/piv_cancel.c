/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/piv_cancel.c - stopping a long pair: the plan's cancel hook (rpiv_piv_set_cancel),
 * asked before each pass and every few rows of windows (piv.c). */
#include "piv_impl.h"

#include <omp.h>

void rpiv_piv_set_cancel(rpiv_piv *pv, const rpiv_progress *cancel)
{
    pv->cancel = cancel ? *cancel : (rpiv_progress){NULL, NULL};
}

int piv_cancelled(const rpiv_piv *pv)
{
    return pv->cancel.fn && rpiv_progress_report(&pv->cancel, 0, 0);
}

int piv_pass_stopped(const rpiv_piv *pv, int cut, int *stop)
{
    int s;
    if (cut && omp_get_thread_num() == 0 && piv_cancelled(pv)) {
#pragma omp atomic write
        *stop = 1;
    }
#pragma omp atomic read
    s = *stop;
    return s;
}
