/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/pair_pool.h - many small pairs, a pair per thread (internal to the piv module).
 *
 * A pair of small frames is a few milliseconds of work cut into some thirty parallel regions;
 * at two threads, and worse on a busy machine, the threads spend more time waiting for each
 * other at the regions' ends than working (issue 20 item 6). The pool gives each thread whole
 * pairs instead, on its own one-thread copy of the plan (C11 threads, asleep on a condition
 * variable when they wait, never spinning), each result into a slot of a ring, and hands the
 * results to the calling thread in pair order: what the caller does with them (add to sums,
 * write a field) happens in the order of one pair after another, so the output has the same
 * bits for any thread count. Used by rpiv_ensemble_add_pairs (ensemble_pairs.c) and
 * rpiv_piv_run_pairs (piv_pairs.c). */
#ifndef RPIV_PIV_PAIR_POOL_H
#define RPIV_PIV_PAIR_POOL_H

#include "piv_impl.h"

/* Frames of at most this many pixels go a pair per thread (docs/benchmarks.md, "Threads on
 * small images and busy machines": at 1024 x 1024 a pair per thread still beats the threads
 * inside each pair; at 2560 x 2160 the slots would be large). */
#define POOL_MAX_PX (1500 * 1000)
/* Slots per thread: pairs done ahead of the one the calling thread takes. */
#define POOL_PER_THREAD 4
/* Memory the slots and plan copies may take, MB, besides piv.max_mem_mb's check. */
#define POOL_MAX_MB 256.0

/* The work of a pool: n pairs, m slots (the caller owns the slots' memory). */
typedef struct pool_job {
    size_t n, m;
    /* On a worker: do pair k with the worker's one-thread plan into slot k % m. */
    void (*fill)(void *ctx, rpiv_piv *plan, size_t k, size_t slot);
    /* On the calling thread, k = 0, 1, ... in order, once slot k % m is filled: use it.
     * A non-OK status stops the pool (the later pairs are not taken) and is returned. */
    rpiv_status (*take)(void *ctx, size_t k, size_t slot);
    void *ctx;
} pool_job;

/* The slots to use for n pairs on pv's threads, given the bytes one slot takes and the bytes
 * the caller holds besides the plan: 0 if the pool does not pay or does not fit (one thread,
 * fewer than 2 pairs, frames above POOL_MAX_PX, over piv.max_mem_mb or POOL_MAX_MB): then the
 * caller runs the pairs one after another with the plan's threads inside. */
size_t pool_slots(const rpiv_piv *pv, size_t n, double slot_bytes, double held_bytes);

/* Run the job on pv's threads (each with its one-thread copy of pv). RPIV_ENOMEM (no thread,
 * no memory for the copies), or the first non-OK status of `take`, or RPIV_OK. */
RPIV_NODISCARD rpiv_status pool_run(const rpiv_piv *pv, const pool_job *job);

#endif /* RPIV_PIV_PAIR_POOL_H */
