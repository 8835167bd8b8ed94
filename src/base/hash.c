/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/base/hash.c - 64-bit FNV-1a. */
#include "hash.h"

uint64_t hash_bytes(uint64_t h, const void *p, size_t n)
{
    const unsigned char *c = p;
    for (size_t i = 0; i < n; i++) {
        h ^= c[i];
        h *= 1099511628211ULL;
    }
    return h;
}
