/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/image.h - float32 grey images; reading TIFF/PNG/PGM/BMP/JPEG, writing TIFF/PNG
 * (image pairs, from files, double-frame files, lists and globs, are rpiv/pairs.h).
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

/* Read a one-page double-frame image: frame A is the top half of the image, frame B the
 * bottom half (*a and *b, each w x h/2, new images). A PNG is decoded straight into the two
 * halves. Errors as for rpiv_image_load (page 0), and RPIV_ESIZE naming the file for an odd
 * height; on failure *a and *b are NULL. */
RPIV_NODISCARD rpiv_status rpiv_image_load_halves(const char *path, rpiv_image **a, rpiv_image **b,
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
/* RPIV_OK if rpiv_image_save can choose a writer for path's extension, else its
 * RPIV_EINVAL: for checking an output name before the work that makes the image. */
RPIV_NODISCARD rpiv_status rpiv_image_save_check(const char *path);

#endif /* RPIV_IMAGE_H */
