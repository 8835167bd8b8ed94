/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/pairs.h - image pairs of a series: from two files, double-frame files, lists and globs;
 * each pair loaded on demand. */
#ifndef RPIV_PAIRS_H
#define RPIV_PAIRS_H

#include "rpiv/error.h"
#include "rpiv/image.h"

#include <stddef.h>

/* One pair: frame A and frame B from two files, or from one double-frame file (frame A in the
 * top half, frame B in the bottom half; or pages 0 and 1 of a multi-page TIFF). */
typedef struct rpiv_pair_src {
    char *path_a; /* owned */
    char *path_b; /* owned; NULL for a double-frame file */
} rpiv_pair_src;

typedef struct rpiv_pairs {
    size_t n;
    rpiv_pair_src *pair; /* n entries, owned */
} rpiv_pairs;

typedef enum rpiv_pairing {
    RPIV_PAIR_AB = 0,           /* stems ending in a/b (so _a/_b), A/B or 1/2: matched      */
    RPIV_PAIR_CONSECUTIVE = 1,  /* sorted frames 1-2, 3-4, ...                              */
    RPIV_PAIR_TIME_RESOLVED = 2 /* sorted frames 1-2, 2-3, ...                             */
} rpiv_pairing;

/* Build the pair list from command-line words:
 *   two image files                  -> one pair;
 *   one image file                   -> a double-frame pair;
 *   a .txt/.lst file                 -> a list, one pair a line: "A B" or "AB" (double frame),
 *                                       '#' comments, paths relative to the list's folder,
 *                                       "..." quotes a path with spaces;
 *   a glob pattern (quoted, with * ? [) -> files matched (glob(3)) and paired by `rule`;
 *   two patterns                     -> k-th match of the first with k-th of the second;
 *   three or more files              -> paired by `rule`, like a pattern the shell expanded.
 * Files are sorted in natural order (frame_9 before frame_10). Only names are looked at
 * (list files are read); images are opened by rpiv_pairs_load. *out owns the list (release
 * with rpiv_pairs_free). Errors name the word at fault: RPIV_EINVAL (odd count, unmatched
 * a/b, a name without an a/b marker, a pattern mixed with files), RPIV_EIO (no match,
 * missing list), RPIV_EFORMAT (list line with three paths, as "list.txt:12: ..."). */
RPIV_NODISCARD rpiv_status rpiv_pairs_from_args(int nargs, char *const *args, rpiv_pairing rule,
                                                rpiv_pairs **out);
void rpiv_pairs_free(rpiv_pairs *p);

/* Load pair i (0-based) into two new images of equal size. A double-frame file gives pages
 * 0 and 1 if it has two or more pages, else its top and bottom halves (odd height:
 * RPIV_ESIZE). Errors: those of rpiv_image_load; RPIV_ESIZE if the frames differ in size,
 * naming both files and sizes; RPIV_EINVAL if i >= n. With more than one pair the message
 * starts "pair I of N: " (1-based). On failure *a and *b are NULL. */
RPIV_NODISCARD rpiv_status rpiv_pairs_load(const rpiv_pairs *p, size_t i, rpiv_image **a,
                                           rpiv_image **b);

#endif /* RPIV_PAIRS_H */
