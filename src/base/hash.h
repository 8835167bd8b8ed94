/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/base/hash.h - the one hash of librpiv (base's internal toolbox, not installed): 64-bit
 * FNV-1a, for the identities written into checkpoints and accumulator files. Changing it
 * invalidates every checkpoint written before. */
#ifndef RPIV_BASE_HASH_H
#define RPIV_BASE_HASH_H

#include <stddef.h>
#include <stdint.h>

#define HASH0 1469598103934665603ULL /* the FNV-1a offset basis: start here */

/* FNV-1a over n bytes at p, continuing from h (HASH0 to start). */
uint64_t hash_bytes(uint64_t h, const void *p, size_t n);

#endif /* RPIV_BASE_HASH_H */
