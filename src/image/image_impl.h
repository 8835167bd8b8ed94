/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image/image_impl.h - helpers shared by the image module's source files (not installed). */
#ifndef RPIV_IMAGE_IMPL_H
#define RPIV_IMAGE_IMPL_H

#include "rpiv/image.h"

#include "base/atomic.h"

#include <stddef.h>
#include <stdint.h>

#if defined(__GNUC__) || defined(__clang__)
#define IMG_HIDDEN __attribute__((visibility("hidden")))
#else
#define IMG_HIDDEN
#endif

/* Largest image accepted by default, in pixels: 2^28 (268 Mpx, 1 GiB as float), far above any
 * PIV camera; the environment variable RPIV_MAX_IMAGE_PIXELS changes it (up to 2^31). Readers
 * check it against the header before allocating. */
#define IMG_MAX_PIXELS         ((uint64_t)1 << 31)
#define IMG_DEFAULT_MAX_PIXELS ((uint64_t)1 << 28)
IMG_HIDDEN uint64_t img_max_pixels(void);

/* Luminance of an RGB triple, ITU-R BT.601 weights; a grey triple keeps its exact level. */
static inline float img_luma(double r, double g, double b)
{
    if (r == g && g == b)
        return (float)r;
    return (float)(0.299 * r + 0.587 * g + 0.114 * b);
}

/* RPIV_OK if a w x h image is acceptable: w, h >= 1 and w*h <= IMG_MAX_PIXELS; else
 * RPIV_EFORMAT naming path. */
IMG_HIDDEN rpiv_status img_check_size(const char *path, uint64_t w, uint64_t h);

/* A new w x h image (uninitialised pixels are zero) after checking the size: w, h >= 1 and
 * w*h <= IMG_MAX_PIXELS, else RPIV_EFORMAT naming path. */
IMG_HIDDEN rpiv_status img_alloc(const char *path, uint64_t w, uint64_t h, int bits,
                                 rpiv_image **out);
/* img_check_size, then the configurable limit (RPIV_MAX_IMAGE_PIXELS): RPIV_ELIMIT naming
 * path if w*h exceeds it. */
IMG_HIDDEN rpiv_status img_check_limit(const char *path, uint64_t w, uint64_t h);
/* img_alloc with the pixels left uninitialised unless zeroed (for a reader that writes every
 * pixel: a zeroed 22 MB image that comes from the heap rather than mmap costs a memset). */
IMG_HIDDEN rpiv_status img_alloc_ex(const char *path, uint64_t w, uint64_t h, int bits, int zeroed,
                                    rpiv_image **out);

/* Map the pages of a new image a reader is about to write in full, in one call (madvise
 * MADV_POPULATE_WRITE; the pixels are not touched): faulting 44 MB in one call took 27-36 ms
 * on this machine, a fault per 4 kB page as the reader first writes it 40-93 ms. Only for
 * images of 4 MB or more that the file (fsize bytes) can plausibly fill: at most 32 bytes of
 * floats a byte of file, so a small file claiming a large image commits no more memory than
 * its decoding reaches (issue 20 item 4). */
IMG_HIDDEN void img_populate(const rpiv_image *im, uint64_t fsize);

/* Readers: each fills *out (NULL on failure) and sets *warned to 1 for colour input. */
IMG_HIDDEN rpiv_status img_tiff_load(const char *path, int page, rpiv_image **out, int *warned);
IMG_HIDDEN rpiv_status img_tiff_pages(const char *path, int *npages);
/* img_png_load: with b not NULL and an even height, the image's top half goes to *out and its
 * bottom half to *b, decoded straight into them (a double-frame file); otherwise *b is NULL
 * and *out the whole image. */
IMG_HIDDEN rpiv_status img_png_load(const char *path, rpiv_image **out, rpiv_image **b,
                                    int *warned);
IMG_HIDDEN rpiv_status img_pgm_load(const char *path, const unsigned char *buf, size_t n,
                                    rpiv_image **out);
IMG_HIDDEN rpiv_status img_jpeg_load(const char *path, const unsigned char *buf, size_t n,
                                     rpiv_image **out, int *warned);
IMG_HIDDEN rpiv_status img_bmp_load(const char *path, const unsigned char *buf, size_t n,
                                    rpiv_image **out, int *warned);

#endif /* RPIV_IMAGE_IMPL_H */
