/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image/image.c - the float image: allocation under the size limit, copy, statistics,
 * the format names.
 * The format readers build on it; image_file.c dispatches files to them. */
#include "image_impl.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <time.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
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

rpiv_status img_check_limit(const char *path, uint64_t w, uint64_t h)
{
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
    return RPIV_OK;
}

rpiv_status img_alloc_ex(const char *path, uint64_t w, uint64_t h, int bits, int zeroed,
                         rpiv_image **out)
{
    *out = NULL;
    rpiv_status st = img_check_limit(path, w, h);
    if (st)
        return st;
    rpiv_image *im = malloc(sizeof *im);
    if (!im)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory for the image header", path);
    im->w = (int)w;
    im->h = (int)h;
    im->bits = bits;
    im->px =
        zeroed ? calloc((size_t)(w * h), sizeof *im->px) : malloc((size_t)(w * h) * sizeof *im->px);
    if (!im->px) {
        free(im);
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory for a %llux%llu image", path,
                         (unsigned long long)w, (unsigned long long)h);
    }
    *out = im;
    return RPIV_OK;
}

void img_populate(const rpiv_image *im, uint64_t fsize)
{
#ifdef MADV_POPULATE_WRITE
    if (!im)
        return;
    const size_t n = (size_t)im->w * (size_t)im->h * sizeof *im->px;
    const long pg = sysconf(_SC_PAGESIZE);
    if (pg <= 0 || n < ((size_t)4 << 20) || n / 32 > fsize)
        return;
    uintptr_t a = (uintptr_t)im->px, e = a + n, m = (uintptr_t)pg - 1;
    a = (a + m) & ~m;
    e &= ~m;
    if (e > a)
        (void)madvise((void *)a, e - a, MADV_POPULATE_WRITE); /* an old kernel: EINVAL */
#else
    (void)im;
    (void)fsize;
#endif
}

rpiv_status img_alloc(const char *path, uint64_t w, uint64_t h, int bits, rpiv_image **out)
{
    return img_alloc_ex(path, w, h, bits, 1, out);
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
    /* min and max in float (exact), the sum in four double partial sums added in a fixed
     * order (lane k takes the pixels i = k mod 4 in turn): one pass at vector speed, the same
     * result for any run. With SSE2 the min and max run on 4 + 4 lanes (minps(v, lo) is
     * v < lo ? v : lo, lane by lane): the compiler keeps one chain per pixel otherwise, 2
     * cycles a pixel, 7 ms of a one-pair run (issue 15). */
    size_t n = (size_t)im->w * (size_t)im->h, i = 0;
    const float *px = im->px;
    float lo = px[0], hi = px[0];
    double s4[4] = {0, 0, 0, 0};
#ifdef __SSE2__
    if (n >= 8) {
        __m128 l0 = _mm_set1_ps(lo), l1 = l0, h0 = l0, h1 = l0;
        __m128d s01 = _mm_setzero_pd(), s23 = _mm_setzero_pd();
        for (; i + 8 <= n; i += 8) {
            __m128 a = _mm_loadu_ps(px + i), b = _mm_loadu_ps(px + i + 4);
            l0 = _mm_min_ps(a, l0);
            h0 = _mm_max_ps(a, h0);
            l1 = _mm_min_ps(b, l1);
            h1 = _mm_max_ps(b, h1);
            s01 = _mm_add_pd(s01, _mm_cvtps_pd(a));
            s23 = _mm_add_pd(s23, _mm_cvtps_pd(_mm_movehl_ps(a, a)));
            s01 = _mm_add_pd(s01, _mm_cvtps_pd(b));
            s23 = _mm_add_pd(s23, _mm_cvtps_pd(_mm_movehl_ps(b, b)));
        }
        float l[8], h[8];
        _mm_storeu_ps(l, l0);
        _mm_storeu_ps(l + 4, l1);
        _mm_storeu_ps(h, h0);
        _mm_storeu_ps(h + 4, h1);
        for (int k = 0; k < 8; k++) {
            lo = l[k] < lo ? l[k] : lo;
            hi = h[k] > hi ? h[k] : hi;
        }
        _mm_storeu_pd(s4, s01);
        _mm_storeu_pd(s4 + 2, s23);
    }
#endif
    for (; i + 4 <= n; i += 4)
        for (int k = 0; k < 4; k++) {
            const float v = px[i + (size_t)k];
            lo = v < lo ? v : lo;
            hi = v > hi ? v : hi;
            s4[k] += (double)v;
        }
    for (; i < n; i++) {
        const float v = px[i];
        lo = v < lo ? v : lo;
        hi = v > hi ? v : hi;
        s4[0] += (double)v;
    }
    return (rpiv_image_stats){(double)lo, (double)hi,
                              ((s4[0] + s4[1]) + (s4[2] + s4[3])) / (double)n};
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
