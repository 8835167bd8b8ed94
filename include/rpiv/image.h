/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/image.h - float32 grey images; reading TIFF/PNG/PGM/BMP/JPEG, writing TIFF/PNG;
 * image pairs from files, double-frame files, lists and globs.
 *
 * Pixel (x, y) is px[y * w + x]; x runs along columns (rightward), y along rows (downward),
 * pixel centres at integer coordinates. Values keep the file's grey levels (0..255 for 8-bit,
 * 0..65535 for 16-bit); palette images are mapped to grey through the palette's luminance. */
#ifndef RPIV_IMAGE_H
#define RPIV_IMAGE_H

#include "rpiv/error.h"

#include <stddef.h>

typedef struct rpiv_image {
    int w, h;  /* size in pixels, >= 1 */
    int bits;  /* bit depth of the source (8, 12, 16, 32 for float), informative */
    float *px; /* w*h values, row-major, owned by the image */
} rpiv_image;

/* A new w x h image filled with zeros. Release with rpiv_image_free(). */
RPIV_NODISCARD rpiv_status rpiv_image_new(int w, int h, rpiv_image **out);
void rpiv_image_free(rpiv_image *im); /* NULL is a no-op */
RPIV_NODISCARD rpiv_status rpiv_image_copy(const rpiv_image *im, rpiv_image **out);

/* File formats recognised from their first bytes. */
typedef enum rpiv_image_format {
    RPIV_IMAGE_UNKNOWN = 0,
    RPIV_IMAGE_TIFF = 1, /* "II*\0" / "MM\0*" (classic) or BigTIFF           */
    RPIV_IMAGE_PNG = 2,  /* "\x89PNG\r\n\x1a\n"                              */
    RPIV_IMAGE_PGM = 3,  /* "P2" (ASCII) or "P5" (binary) portable grey map   */
    RPIV_IMAGE_BMP = 4,  /* "BM"                                              */
    RPIV_IMAGE_JPEG = 5  /* FF D8 FF                                          */
} rpiv_image_format;

/* Detect the format of a file from its magic bytes. Errors: RPIV_EIO (cannot open/read),
 * RPIV_EFORMAT (zero-byte file or unknown magic), each naming the file. */
RPIV_NODISCARD rpiv_status rpiv_image_format_of(const char *path, rpiv_image_format *fmt);

/* The format of the first n bytes of an image (RPIV_IMAGE_UNKNOWN if none matches): the
 * detection rpiv_image_format_of applies to a file's start. */
rpiv_image_format rpiv_image_format_of_bytes(const unsigned char *bytes, size_t n);

/* A short name for a format: "TIFF", "PNG", "PGM", "BMP", "JPEG" or "unknown". */
const char *rpiv_image_format_name(rpiv_image_format fmt);

/* Grey-level statistics of an image (summed in double, in row order: deterministic). */
typedef struct rpiv_image_stats {
    double min, max, mean;
} rpiv_image_stats;
rpiv_image_stats rpiv_image_stats_of(const rpiv_image *im);

/* Read page `page` (0-based; multi-page TIFF) of a grey image; the format is detected from
 * the file's magic bytes, not its name. RGB input is converted to luminance (Rec. 601) and
 * *warned is set to 1 if warned is not NULL; palette images give the palette's luminance
 * (no warning). On success *out owns a new image (release with rpiv_image_free); on failure
 * *out is NULL. Thread-safe (no shared state). Errors, each naming the file: RPIV_EIO
 * (missing/unreadable), RPIV_EFORMAT (zero-byte, truncated, bad CRC, unsupported depth or
 * sample format, more than 2^31 pixels, a header the file's data cannot fill), RPIV_EINVAL
 * (page out of range), RPIV_ENOMEM. See docs/images.md for the layouts read. */
RPIV_NODISCARD rpiv_status rpiv_image_load(const char *path, int page, rpiv_image **out,
                                           int *warned);

/* Number of pages (frames) in an image file: 1 except for multi-page TIFF. Errors as for
 * rpiv_image_format_of, and RPIV_EFORMAT for an unreadable TIFF directory. */
RPIV_NODISCARD rpiv_status rpiv_image_count_pages(const char *path, int *npages);

/* Write as 16-bit grey TIFF/PNG (values rounded half up and clamped to 0..65535, NaN -> 0),
 * or as 32-bit float TIFF (rpiv_image_save_tiff_float, bit-exact). The file is written
 * atomically: a temporary file in the same folder, fsync, rename over path; on failure path
 * is untouched and the temporary removed. Errors: RPIV_EIO naming path, RPIV_ENOMEM. */
RPIV_NODISCARD rpiv_status rpiv_image_save_tiff16(const rpiv_image *im, const char *path);
RPIV_NODISCARD rpiv_status rpiv_image_save_png16(const rpiv_image *im, const char *path);
RPIV_NODISCARD rpiv_status rpiv_image_save_tiff_float(const rpiv_image *im, const char *path);
/* Chooses the writer from the extension (any case): .tif/.tiff (16-bit), .png (16-bit);
 * another extension is RPIV_EINVAL. */
RPIV_NODISCARD rpiv_status rpiv_image_save(const rpiv_image *im, const char *path);

/* ---- image pairs ------------------------------------------------------------------------ */

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

#endif /* RPIV_IMAGE_H */
