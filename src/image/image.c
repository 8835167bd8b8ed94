/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image.c - float images: allocation, format detection, load/save dispatch, statistics,
 * and the atomic-write plumbing shared by the writers. */
#include "image_impl.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

uint64_t img_max_pixels(void)
{
    const char *s = getenv("RPIV_MAX_IMAGE_PIXELS");
    if (s && *s) {
        char *end;
        unsigned long long v = strtoull(s, &end, 10);
        if (!*end && v >= 1)
            return v < IMG_MAX_PIXELS ? (uint64_t)v : IMG_MAX_PIXELS;
    }
    return IMG_DEFAULT_MAX_PIXELS;
}

rpiv_status img_check_size(const char *path, uint64_t w, uint64_t h)
{
    if (w < 1 || h < 1)
        return rpiv_fail(RPIV_EFORMAT, "%s: invalid image size %llux%llu", path,
                         (unsigned long long)w, (unsigned long long)h);
    if (w > INT_MAX || h > INT_MAX || w * h > IMG_MAX_PIXELS)
        return rpiv_fail(RPIV_EFORMAT, "%s: image size %llux%llu is absurd (more than 2^31 pixels)",
                         path, (unsigned long long)w, (unsigned long long)h);
    return RPIV_OK;
}

rpiv_status img_alloc(const char *path, uint64_t w, uint64_t h, int bits, rpiv_image **out)
{
    *out = NULL;
    rpiv_status st = img_check_size(path, w, h);
    if (st)
        return st;
    /* the configurable limit, after the readers' own checks that the file can hold the
     * pixels its header claims (so a cut file is still reported as cut) */
    uint64_t lim = img_max_pixels();
    if (w * h > lim)
        return rpiv_fail(RPIV_ELIMIT,
                         "%s: image size %llux%llu exceeds the limit of %llu pixels "
                         "(set RPIV_MAX_IMAGE_PIXELS to allow more)",
                         path, (unsigned long long)w, (unsigned long long)h,
                         (unsigned long long)lim);
    rpiv_image *im = malloc(sizeof *im);
    if (!im)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory for the image header", path);
    im->w = (int)w;
    im->h = (int)h;
    im->bits = bits;
    im->px = calloc((size_t)(w * h), sizeof *im->px);
    if (!im->px) {
        free(im);
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory for a %llux%llu image", path,
                         (unsigned long long)w, (unsigned long long)h);
    }
    *out = im;
    return RPIV_OK;
}

rpiv_status rpiv_image_new(int w, int h, rpiv_image **out)
{
    *out = NULL;
    if (w < 1 || h < 1)
        return rpiv_fail(RPIV_EINVAL, "image size %dx%d: both sides must be >= 1", w, h);
    if ((uint64_t)w * (uint64_t)h > IMG_MAX_PIXELS)
        return rpiv_fail(RPIV_EINVAL, "image size %dx%d: more than 2^31 pixels", w, h);
    rpiv_status st = img_alloc("new image", (uint64_t)w, (uint64_t)h, 32, out);
    return st == RPIV_EFORMAT ? RPIV_EINVAL : st;
}

void rpiv_image_free(rpiv_image *im)
{
    if (!im)
        return;
    free(im->px);
    free(im);
}

rpiv_status rpiv_image_copy(const rpiv_image *im, rpiv_image **out)
{
    rpiv_status st = rpiv_image_new(im->w, im->h, out);
    if (st)
        return st;
    (*out)->bits = im->bits;
    memcpy((*out)->px, im->px, (size_t)im->w * (size_t)im->h * sizeof *im->px);
    return RPIV_OK;
}

rpiv_image_stats rpiv_image_stats_of(const rpiv_image *im)
{
    rpiv_image_stats s = {(double)im->px[0], (double)im->px[0], 0.0};
    size_t n = (size_t)im->w * (size_t)im->h;
    double sum = 0.0;
    for (size_t i = 0; i < n; i++) {
        double v = (double)im->px[i];
        if (v < s.min)
            s.min = v;
        if (v > s.max)
            s.max = v;
        sum += v;
    }
    s.mean = sum / (double)n;
    return s;
}

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

const char *rpiv_image_format_name(rpiv_image_format fmt)
{
    switch (fmt) {
    case RPIV_IMAGE_TIFF:
        return "TIFF";
    case RPIV_IMAGE_PNG:
        return "PNG";
    case RPIV_IMAGE_PGM:
        return "PGM";
    case RPIV_IMAGE_BMP:
        return "BMP";
    case RPIV_IMAGE_JPEG:
        return "JPEG";
    case RPIV_IMAGE_UNKNOWN:
        break;
    }
    return "unknown";
}

/* Open path, check it is a non-empty regular file and read its first bytes. */
static rpiv_status read_magic(const char *path, rpiv_image_format *fmt, FILE **fp, size_t *size)
{
    unsigned char m[8];
    *fmt = RPIV_IMAGE_UNKNOWN;
    FILE *f = fopen(path, "rb");
    if (!f)
        return rpiv_fail(RPIV_EIO, "%s: cannot open: %s", path, strerror(errno));
    struct stat sb;
    if (fstat(fileno(f), &sb) != 0 || !S_ISREG(sb.st_mode)) {
        fclose(f);
        return rpiv_fail(RPIV_EIO, "%s: cannot read: not a regular file", path);
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
        st = img_png_load(path, out, &warn);
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

rpiv_status rpiv_image_save(const rpiv_image *im, const char *path)
{
    if (has_ext(path, ".tif") || has_ext(path, ".tiff"))
        return rpiv_image_save_tiff16(im, path);
    if (has_ext(path, ".png"))
        return rpiv_image_save_png16(im, path);
    return rpiv_fail(RPIV_EINVAL, "%s: cannot choose an image writer: use .tif, .tiff or .png",
                     path);
}

rpiv_status img_tmp_open(const char *path, char *tmp, size_t cap, int *fd)
{
    struct timespec ts;
    *fd = -1;
    clock_gettime(CLOCK_REALTIME, &ts);
    for (unsigned attempt = 0; attempt < 100; attempt++) {
        /* The name only has to be unlikely to collide; O_EXCL makes it safe when it does. */
        unsigned long tag =
            (unsigned long)ts.tv_nsec * 2654435761UL + (unsigned long)getpid() + attempt * 7919UL;
        int n = snprintf(tmp, cap, "%s.tmp%06lx", path, tag & 0xffffffUL);
        if (n < 0 || (size_t)n >= cap)
            return rpiv_fail(RPIV_EINVAL, "%s: path too long", path);
        *fd = open(tmp, O_WRONLY | O_CREAT | O_EXCL, 0666);
        if (*fd >= 0)
            return RPIV_OK;
        if (errno != EEXIST)
            return rpiv_fail(RPIV_EIO, "%s: cannot create a file in its folder: %s", path,
                             strerror(errno));
    }
    return rpiv_fail(RPIV_EIO, "%s: cannot find a free temporary name next to it", path);
}

rpiv_status img_tmp_commit(const char *tmp, const char *path)
{
    if (rename(tmp, path) != 0) {
        int e = errno;
        unlink(tmp);
        return rpiv_fail(RPIV_EIO, "%s: cannot rename the temporary file into place: %s", path,
                         strerror(e));
    }
    /* Make the rename itself durable: sync the folder (best effort). */
    char dir[4096];
    const char *slash = strrchr(path, '/');
    if (!slash)
        snprintf(dir, sizeof dir, ".");
    else if (slash == path)
        snprintf(dir, sizeof dir, "/");
    else
        snprintf(dir, sizeof dir, "%.*s", (int)(slash - path), path);
    int dfd = open(dir, O_RDONLY | O_DIRECTORY);
    if (dfd >= 0) {
        (void)fsync(dfd);
        close(dfd);
    }
    return RPIV_OK;
}
