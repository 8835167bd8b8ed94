/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image/image_bmp.c - BMP through stb_image (Debian libstb, which provides the implementation;
 * JPEG goes through libjpeg-turbo, image_jpeg.c). stb_image reads past the end of a short file
 * as zeros, so the file's completeness is checked here first: uncompressed BMP pixel data must
 * fit in the file. */
#include "image_impl.h"

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <stb/stb_image.h>

static uint32_t le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static unsigned le16(const unsigned char *p)
{
    return (unsigned)p[0] | (unsigned)p[1] << 8;
}

/* BMP header checks; *palette = 1 for an indexed (<= 8 bits per pixel) image. */
static rpiv_status bmp_check(const char *path, const unsigned char *b, size_t n, int *palette)
{
    if (n < 26)
        return rpiv_fail(RPIV_EFORMAT, "%s: truncated BMP header (%zu bytes)", path, n);
    uint32_t off = le32(b + 10), hsize = le32(b + 14), comp = 0;
    int64_t w, h;
    unsigned bpp;
    if (hsize == 12) { /* OS/2 BITMAPCOREHEADER */
        w = le16(b + 18);
        h = le16(b + 20);
        bpp = le16(b + 24);
    } else {
        if (n < 54 || hsize < 40)
            return rpiv_fail(RPIV_EFORMAT, "%s: truncated or unknown BMP header", path);
        w = (int32_t)le32(b + 18);
        h = (int32_t)le32(b + 22);
        bpp = le16(b + 28);
        comp = le32(b + 30);
    }
    if (w < 0) /* only the height's sign has a meaning (top-down rows) */
        return rpiv_fail(RPIV_EFORMAT, "%s: BMP with a negative width %lld", path, (long long)w);
    if (h < 0)
        h = -h; /* top-down rows */
    rpiv_status st = img_check_size(path, (uint64_t)w, (uint64_t)h);
    if (st)
        return st;
    if (bpp != 1 && bpp != 4 && bpp != 8 && bpp != 16 && bpp != 24 && bpp != 32)
        return rpiv_fail(RPIV_EFORMAT, "%s: %u bits per pixel BMP not supported", path, bpp);
    *palette = bpp <= 8;
    /* stb_image reads uncompressed (BI_RGB) and bit-field (BI_BITFIELDS) pixel data only;
     * both have a fixed size, which must be in the file. */
    if (comp != 0 && comp != 3)
        return rpiv_fail(RPIV_EFORMAT, "%s: BMP compression type %u not supported", path,
                         (unsigned)comp);
    uint64_t rowbytes = ((uint64_t)w * bpp + 31) / 32 * 4;
    uint64_t need = (uint64_t)off + rowbytes * (uint64_t)h;
    if (need > n)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: truncated BMP: pixel data end at byte %llu, file has %zu", path,
                         (unsigned long long)need, n);
    if (bpp > 8)
        return RPIV_OK;
    /* An index beyond the palette the file holds would make stb_image read palette entries
     * it never set (uninitialised memory: a different image at each load): refused. The
     * palette's size as stb_image counts it. */
    int64_t psize = hsize == 12 ? ((int64_t)off - 14 - 24) / 3 : ((int64_t)off - 14 - hsize) / 4;
    if (psize >= (1 << bpp))
        return RPIV_OK;
    for (int64_t y = 0; y < h; y++) {
        const unsigned char *row = b + off + (uint64_t)y * rowbytes;
        for (int64_t x = 0; x < w; x++) {
            const uint64_t bit = (uint64_t)x * bpp;
            const unsigned v = (row[bit / 8] >> (8 - bpp - bit % 8)) & ((1u << bpp) - 1);
            if ((int64_t)v >= psize)
                return rpiv_fail(RPIV_EFORMAT,
                                 "%s: BMP pixel (%lld, %lld) has palette index %u, beyond its "
                                 "palette of %lld colours",
                                 path, (long long)x, (long long)y, v,
                                 (long long)(psize > 0 ? psize : 0));
        }
    }
    return RPIV_OK;
}

rpiv_status img_bmp_load(const char *path, const unsigned char *buf, size_t n, rpiv_image **out,
                         int *warned)
{
    const rpiv_image_format fmt = RPIV_IMAGE_BMP;
    int palette = 0, w, h, comp;
    rpiv_status st;
    *out = NULL;
    if (n > INT_MAX)
        return rpiv_fail(RPIV_EFORMAT, "%s: file too large for the %s decoder", path,
                         rpiv_image_format_name(fmt));
    st = bmp_check(path, buf, n, &palette);
    if (st)
        return st;
    if (!stbi_info_from_memory(buf, (int)n, &w, &h, &comp))
        return rpiv_fail(RPIV_EFORMAT, "%s: cannot decode %s header: %s", path,
                         rpiv_image_format_name(fmt), stbi_failure_reason());
    /* stb reports a top-down BMP's height as negative */
    st = img_check_size(path, (uint64_t)(w < 0 ? -(int64_t)w : w),
                        (uint64_t)(h < 0 ? -(int64_t)h : h));
    if (st)
        return st;
    unsigned char *p = stbi_load_from_memory(buf, (int)n, &w, &h, &comp, 0);
    if (!p)
        return rpiv_fail(RPIV_EFORMAT, "%s: cannot decode %s: %s", path,
                         rpiv_image_format_name(fmt), stbi_failure_reason());
    rpiv_image *im;
    st = img_alloc(path, (uint64_t)w, (uint64_t)h, 8, &im);
    if (st) {
        stbi_image_free(p);
        return st;
    }
    size_t npx = (size_t)w * (size_t)h;
    int colour = comp >= 3;
    for (size_t i = 0; i < npx; i++) {
        const unsigned char *s = p + i * (size_t)comp;
        im->px[i] = colour ? img_luma(s[0], s[1], s[2]) : (float)s[0];
    }
    stbi_image_free(p);
    /* stb expands a BMP palette to RGB: its luminance is the palette's grey, no warning. */
    *warned = colour && !palette;
    *out = im;
    return RPIV_OK;
}
