/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image/image_file.c - image files: format detection, loading and saving dispatched to
 * the format readers and writers (image_tiff.c, image_png.c, image_pgm.c, image_bmp.c,
 * image_jpeg.c). */
#include "image_impl.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---- format detection ------------------------------------------------------------------ */

rpiv_image_format rpiv_image_format_of_bytes(const unsigned char *m, size_t n)
{
    if (n >= 4 && ((m[0] == 'I' && m[1] == 'I' && (m[2] == 42 || m[2] == 43) && m[3] == 0) ||
                   (m[0] == 'M' && m[1] == 'M' && m[2] == 0 && (m[3] == 42 || m[3] == 43))))
        return RPIV_IMAGE_TIFF;
    if (n >= 8 && memcmp(m, "\x89PNG\r\n\x1a\n", 8) == 0)
        return RPIV_IMAGE_PNG;
    if (n >= 2 && m[0] == 'P' && (m[1] == '2' || m[1] == '5'))
        return RPIV_IMAGE_PGM;
    if (n >= 2 && m[0] == 'B' && m[1] == 'M')
        return RPIV_IMAGE_BMP;
    if (n >= 3 && m[0] == 0xFF && m[1] == 0xD8 && m[2] == 0xFF)
        return RPIV_IMAGE_JPEG;
    return RPIV_IMAGE_UNKNOWN;
}

/* Open path, check it is a non-empty regular file and read its first bytes. */
static rpiv_status read_magic(const char *path, rpiv_image_format *fmt, FILE **fp, size_t *size)
{
    unsigned char m[8];
    *fmt = RPIV_IMAGE_UNKNOWN;
    /* O_NONBLOCK: a FIFO blocks in a plain open() until a writer comes (forever); it is
     * refused by the check that follows instead. A regular file ignores the flag. */
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0)
        return rpiv_fail(RPIV_EIO, "%s: cannot open: %s", path, strerror(errno));
    struct stat sb;
    if (fstat(fd, &sb) != 0 || !S_ISREG(sb.st_mode)) {
        close(fd);
        return rpiv_fail(RPIV_EIO, "%s: cannot read: not a regular file", path);
    }
    FILE *f = fdopen(fd, "rb");
    if (!f) {
        int err = errno;
        close(fd);
        return rpiv_fail(RPIV_EIO, "%s: cannot open: %s", path, strerror(err));
    }
    if (sb.st_size == 0) {
        fclose(f);
        return rpiv_fail(RPIV_EFORMAT, "%s: empty file (0 bytes)", path);
    }
    size_t n = fread(m, 1, sizeof m, f);
    if (n == 0 && ferror(f)) {
        fclose(f);
        return rpiv_fail(RPIV_EIO, "%s: cannot read: %s", path, strerror(errno));
    }
    *fmt = rpiv_image_format_of_bytes(m, n);
    if (*fmt == RPIV_IMAGE_UNKNOWN) {
        fclose(f);
        return rpiv_fail(RPIV_EFORMAT, "%s: unknown image format (not TIFF, PNG, PGM, BMP or JPEG)",
                         path);
    }
    *size = (size_t)sb.st_size;
    if (fp)
        *fp = f;
    else
        fclose(f);
    return RPIV_OK;
}

rpiv_status rpiv_image_format_of(const char *path, rpiv_image_format *fmt)
{
    size_t size;
    return read_magic(path, fmt, NULL, &size);
}

/* The whole file in memory (formats decoded from a buffer). */
static rpiv_status slurp(const char *path, FILE *f, size_t size, unsigned char **buf)
{
    *buf = malloc(size);
    if (!*buf)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory reading %zu bytes", path, size);
    rewind(f);
    if (fread(*buf, 1, size, f) != size) {
        free(*buf);
        *buf = NULL;
        return rpiv_fail(RPIV_EIO, "%s: cannot read %zu bytes", path, size);
    }
    return RPIV_OK;
}

rpiv_status rpiv_image_load(const char *path, int page, rpiv_image **out, int *warned)
{
    rpiv_image_format fmt;
    FILE *f = NULL;
    size_t size = 0;
    unsigned char *buf = NULL;
    int warn = 0;
    *out = NULL;
    if (warned)
        *warned = 0;
    if (page < 0)
        return rpiv_fail(RPIV_EINVAL, "%s: page %d: pages are numbered from 0", path, page);
    rpiv_status st = read_magic(path, &fmt, &f, &size);
    if (st)
        return st;
    if (fmt != RPIV_IMAGE_TIFF && page != 0) {
        fclose(f);
        return rpiv_fail(RPIV_EINVAL, "%s: page %d requested but a %s file has only page 0", path,
                         page, rpiv_image_format_name(fmt));
    }
    switch (fmt) {
    case RPIV_IMAGE_TIFF:
        fclose(f);
        st = img_tiff_load(path, page, out, &warn);
        break;
    case RPIV_IMAGE_PNG:
        fclose(f);
        st = img_png_load(path, out, NULL, &warn);
        break;
    case RPIV_IMAGE_PGM:
    case RPIV_IMAGE_BMP:
    case RPIV_IMAGE_JPEG:
        st = slurp(path, f, size, &buf);
        fclose(f);
        if (st)
            break;
        if (fmt == RPIV_IMAGE_PGM)
            st = img_pgm_load(path, buf, size, out);
        else if (fmt == RPIV_IMAGE_JPEG)
            st = img_jpeg_load(path, buf, size, out, &warn);
        else
            st = img_bmp_load(path, buf, size, out, &warn);
        free(buf);
        break;
    case RPIV_IMAGE_UNKNOWN:
        fclose(f);
        st = rpiv_fail(RPIV_EFORMAT, "%s: unknown image format", path);
        break;
    }
    if (st == RPIV_OK && warned)
        *warned = warn;
    return st;
}

/* Split a double-frame image into its top and bottom halves: the top half keeps im's pixel
 * buffer (cut down in place), the bottom half is a copy. im is consumed. */
static rpiv_status split_halves(const char *path, rpiv_image *im, rpiv_image **a, rpiv_image **b)
{
    if (im->h % 2) {
        rpiv_status st = rpiv_fail(RPIV_ESIZE,
                                   "%s: a double-frame image needs an even height (frame A "
                                   "above frame B), got %dx%d",
                                   path, im->w, im->h);
        rpiv_image_free(im);
        return st;
    }
    int hh = im->h / 2;
    rpiv_status st = img_alloc_ex(path, (uint64_t)im->w, (uint64_t)hh, im->bits, 0, b);
    if (st) {
        rpiv_image_free(im);
        return st;
    }
    size_t half = (size_t)im->w * (size_t)hh;
    memcpy((*b)->px, im->px + half, half * sizeof *im->px); /* every pixel of *b */
    float *px = realloc(im->px, half * sizeof *im->px);     /* shrinks: cannot fail in practice */
    if (px)
        im->px = px;
    im->h = hh;
    *a = im;
    return RPIV_OK;
}

rpiv_status rpiv_image_load_halves(const char *path, rpiv_image **a, rpiv_image **b, int *warned)
{
    rpiv_image_format fmt;
    size_t size = 0;
    int warn = 0;
    *a = *b = NULL;
    if (warned)
        *warned = 0;
    rpiv_status st = read_magic(path, &fmt, NULL, &size);
    if (st)
        return st;
    rpiv_image *im = NULL;
    if (fmt == RPIV_IMAGE_PNG) {
        /* decoded straight into the two halves (no whole image, no copy) unless the height
         * is odd: then the whole image, refused below after a complete read as for any
         * format */
        st = img_png_load(path, &im, b, &warn);
        if (!st && *b) {
            *a = im;
            if (warned)
                *warned = warn;
            return RPIV_OK;
        }
    } else {
        st = rpiv_image_load(path, 0, &im, &warn);
    }
    if (!st)
        st = split_halves(path, im, a, b);
    if (!st && warned)
        *warned = warn;
    return st;
}

rpiv_status rpiv_image_count_pages(const char *path, int *npages)
{
    rpiv_image_format fmt;
    *npages = 0;
    rpiv_status st = rpiv_image_format_of(path, &fmt);
    if (st)
        return st;
    if (fmt == RPIV_IMAGE_TIFF)
        return img_tiff_pages(path, npages);
    *npages = 1;
    return RPIV_OK;
}

/* ---- writing --------------------------------------------------------------------------- */

static int has_ext(const char *path, const char *ext)
{
    size_t n = strlen(path), e = strlen(ext);
    return n > e && strcasecmp(path + n - e, ext) == 0;
}

rpiv_status rpiv_image_save_check(const char *path)
{
    if (has_ext(path, ".tif") || has_ext(path, ".tiff") || has_ext(path, ".png"))
        return RPIV_OK;
    return rpiv_fail(RPIV_EINVAL, "%s: cannot choose an image writer: use .tif, .tiff or .png",
                     path);
}

rpiv_status rpiv_image_save(const rpiv_image *im, const char *path)
{
    rpiv_status st = rpiv_image_save_check(path);
    if (st)
        return st;
    if (has_ext(path, ".png"))
        return rpiv_image_save_png16(im, path);
    return rpiv_image_save_tiff16(im, path);
}
