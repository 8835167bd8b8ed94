/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image_stb.c - BMP and JPEG through stb_image (Debian libstb, which provides the
 * implementation). stb_image reads past the end of a short file as zeros, so the file's
 * completeness is checked here first: uncompressed BMP pixel data must fit in the file, and a
 * JPEG must end its last scan with an EOI marker. */
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
    if (h < 0)
        h = -h; /* top-down rows */
    rpiv_status st = img_check_size(path, (uint64_t)(w < 0 ? 0 : w), (uint64_t)h);
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
    return RPIV_OK;
}

/* JPEG entropy-coded data escape 0xFF, so FF DA (start of scan) and FF D9 (end of image)
 * only occur as markers; a complete file has an EOI after its last scan. */
static rpiv_status jpeg_check(const char *path, const unsigned char *b, size_t n)
{
    size_t last_sos = 0, last_eoi = 0;
    for (size_t i = 0; i + 1 < n; i++) {
        if (b[i] != 0xFF)
            continue;
        if (b[i + 1] == 0xDA)
            last_sos = i + 1;
        else if (b[i + 1] == 0xD9)
            last_eoi = i + 1;
    }
    if (last_sos == 0)
        return rpiv_fail(RPIV_EFORMAT, "%s: truncated JPEG: no image scan", path);
    if (last_eoi < last_sos)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: truncated JPEG: no end-of-image marker after the "
                         "last scan",
                         path);
    return RPIV_OK;
}

/* stb_image decodes a scan with Huffman tables that no DHT segment defined, and frames
 * with quantisation tables that no DQT defined, from uninitialised memory: garbage table
 * offsets send it reading far outside its arrays (a crash found by fuzz_bmp_jpeg; upstream
 * nothings/stb#1535). So walk the marker segments (ITU-T T.81, B.1) and check that every
 * scan's tables were defined before it: DC tables for baseline scans and first DC scans of
 * progressive images, AC tables for baseline and progressive AC scans (a DC refinement scan
 * reads bits only). A segment that cannot be parsed ends the walk: stb_image reports it. */
static rpiv_status jpeg_tables_check(const char *path, const unsigned char *b, size_t n)
{
    unsigned dht = 0, dqt = 0; /* bit class * 4 + id; bit id */
    unsigned char tq[4];       /* quantisation table of each frame component */
    int ncomp = 0, progressive = 0;
    size_t i = 2;
    while (i + 4 <= n) {
        unsigned m = b[i + 1];
        if (b[i] != 0xFF || m == 0xFF || m == 0x00 || m == 0x01 || (m >= 0xD0 && m <= 0xD8)) {
            i += b[i] == 0xFF && m != 0xFF ? 2 : 1; /* entropy-coded data, fill, RST, SOI */
            continue;
        }
        if (m == 0xD9)
            break; /* EOI */
        size_t len = (size_t)b[i + 2] << 8 | b[i + 3];
        if (len < 2 || len > n - i - 2)
            break;
        const unsigned char *sg = b + i + 4;
        size_t sl = len - 2;
        if (m == 0xC4) { /* DHT: Tc|Th, 16 counts, the values */
            for (size_t p = 0; p + 17 <= sl;) {
                size_t nv = 0;
                for (int k = 1; k <= 16; k++)
                    nv += sg[p + (size_t)k];
                if ((sg[p] >> 4) <= 1 && (sg[p] & 15) <= 3)
                    dht |= 1u << ((sg[p] >> 4) * 4 + (sg[p] & 15));
                p += 17 + nv;
            }
        } else if (m == 0xDB) { /* DQT: Pq|Tq, 64 values of 8 or 16 bits */
            for (size_t p = 0; p < sl; p += 1 + ((sg[p] >> 4) ? 128 : 64))
                if ((sg[p] & 15) <= 3)
                    dqt |= 1u << (sg[p] & 15);
        } else if (m == 0xC0 || m == 0xC1 || m == 0xC2) { /* SOF: P, Y, X, Nf, components */
            progressive = m == 0xC2;
            ncomp = sl >= 6 ? sg[5] : 0;
            if (ncomp > 4 || sl < 6 + 3 * (size_t)ncomp)
                return RPIV_OK; /* stb_image refuses the frame */
            for (int c = 0; c < ncomp; c++)
                tq[c] = sg[6 + 3 * c + 2] & 15;
        } else if (m == 0xDA) { /* SOS: Ns, (Cs, Td|Ta) x Ns, Ss, Se, Ah|Al */
            for (int c = 0; c < ncomp; c++)
                if (tq[c] > 3 || !(dqt >> tq[c] & 1))
                    return rpiv_fail(RPIV_EFORMAT,
                                     "%s: corrupt JPEG: frame component %d uses quantisation "
                                     "table %u, which no DQT segment defines",
                                     path, c + 1, tq[c]);
            size_t ns = sl >= 1 ? sg[0] : 0;
            if (ns < 1 || ns > 4 || sl < 4 + 2 * ns)
                break;
            unsigned ss = sg[1 + 2 * ns], ah = sg[3 + 2 * ns] >> 4;
            int need_dc = !progressive || (ss == 0 && ah == 0), need_ac = !progressive || ss > 0;
            for (size_t k = 0; k < ns; k++) {
                unsigned td = sg[2 + 2 * k] >> 4, ta = sg[2 + 2 * k] & 15;
                if ((need_dc && (td > 3 || !(dht >> td & 1))) ||
                    (need_ac && (ta > 3 || !(dht >> (4 + ta) & 1))))
                    return rpiv_fail(RPIV_EFORMAT,
                                     "%s: corrupt JPEG: a scan uses Huffman table %s%u, which "
                                     "no DHT segment before it defines",
                                     path, need_dc && (td > 3 || !(dht >> td & 1)) ? "DC" : "AC",
                                     need_dc && (td > 3 || !(dht >> td & 1)) ? td : ta);
            }
        }
        i += 2 + len;
    }
    return RPIV_OK;
}

rpiv_status img_stb_load(const char *path, rpiv_image_format fmt, const unsigned char *buf,
                         size_t n, rpiv_image **out, int *warned)
{
    int palette = 0, w, h, comp;
    rpiv_status st;
    *out = NULL;
    if (n > INT_MAX)
        return rpiv_fail(RPIV_EFORMAT, "%s: file too large for the %s decoder", path,
                         rpiv_image_format_name(fmt));
    st = fmt == RPIV_IMAGE_BMP ? bmp_check(path, buf, n, &palette) : jpeg_check(path, buf, n);
    if (!st && fmt == RPIV_IMAGE_JPEG)
        st = jpeg_tables_check(path, buf, n);
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
    /* A Huffman-coded 8x8 block takes at least one bit (a DC code; baseline also an EOB), so
     * a JPEG holds at most 512 pixels per byte: refuse a header the file cannot fill before
     * stb_image allocates for it. */
    if (fmt == RPIV_IMAGE_JPEG && (uint64_t)w * (uint64_t)h > 1024 * (uint64_t)n + 65536)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: truncated or corrupt JPEG: %dx%d pixels cannot be coded in %zu "
                         "bytes",
                         path, w, h, n);
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
