/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/base/simd.h - clones of hot loops for wider vector units, picked at load time. */
#ifndef RPIV_SRC_SIMD_H
#define RPIV_SRC_SIMD_H

/* RPIV_KERNEL before a function compiles it twice on x86-64 with GCC or Clang, for AVX2 and
 * for the baseline (SSE2), the better one picked when the library loads (target_clones, an
 * ifunc). Kernels use only multiplies, adds, subtracts and compares, never fused
 * multiply-adds (FMA is not part of the "avx2" target), so both clones give the same bits.
 * Define RPIV_NO_CLONES to build a single version. */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(RPIV_NO_CLONES)
#define RPIV_KERNEL __attribute__((target_clones("avx2", "default")))
#else
#define RPIV_KERNEL
#endif

#endif /* RPIV_SRC_SIMD_H */
