/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image/image_tiff.c - TIFF through libtiff: reading grey, palette and RGB pages stored in
 * strips or tiles; writing 16-bit and 32-bit float grey. libtiff's messages go to a per-open
 * handler (TIFFOpenOptions, libtiff >= 4.5) and end up in rpiv's message; nothing is printed. */
#include "image_impl.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <tiffio.h>
#include <unistd.h>

typedef struct tctx {
    char msg[512]; /* first error libtiff reported for this handle */
    int nerr;
    int corrupt; /* a decoder warned that coded rows were cut short or too long */
} tctx;

/* libtiff hands its handlers a printf format and its arguments. */
static int on_error(TIFF *t, void *user, const char *module, const char *fmt, va_list ap)
    RPIV_PRINTF(4, 0);
static int on_error(TIFF *t, void *user, const char *module, const char *fmt, va_list ap)
{
    (void)t;
    (void)module;
    tctx *c = user;
    if (c->nerr++ == 0)
        vsnprintf(c->msg, sizeof c->msg, fmt, ap);
    return 1; /* handled: the global handler is not called */
}

static int on_warning(TIFF *t, void *user, const char *module, const char *fmt, va_list ap)
    RPIV_PRINTF(4, 0);
static int on_warning(TIFF *t, void *user, const char *module, const char *fmt, va_list ap)
{
    (void)t, (void)module;
    tctx *c = user;
    char m[sizeof c->msg];
    vsnprintf(m, sizeof m, fmt, ap);
    /* The fax decoders only warn when a row's codes end early or run long, and fill the
     * row: a 260-byte file then "held" 30000 x 30000 blank pixels. That is corrupt data. */
    if (strstr(m, "Premature EO") || strstr(m, "Line length mismatch")) {
        if (!c->corrupt && c->nerr++ == 0)
            snprintf(c->msg, sizeof c->msg, "%s", m);
        c->corrupt = 1;
    }
    return 1; /* the others are silenced (unknown tags and the like) */
}

/* The smallest bound on libtiff's single allocations when reading (bytes). */
#define IMG_TIFF_ALLOC_MIN ((tmsize_t)64 << 20)

static TIFF *topen(const char *path, const char *mode, int fd, tctx *c)
{
    memset(c, 0, sizeof *c);
    TIFFOpenOptions *o = TIFFOpenOptionsAlloc();
    if (!o) {
        snprintf(c->msg, sizeof c->msg, "out of memory");
        return NULL;
    }
    /* Bound every single allocation libtiff makes while reading (tag arrays, raw strips): a
     * little more than the file could hold, never the 4 GB a hostile count may declare
     * (issue 20 item 4). Strips are decoded into buffers rpiv allocates after its own
     * checks, outside this limit. */
    struct stat sb;
    if (mode[0] == 'r' && (fd >= 0 ? fstat(fd, &sb) : stat(path, &sb)) == 0)
        TIFFOpenOptionsSetMaxSingleMemAlloc(o, (tmsize_t)(IMG_TIFF_ALLOC_MIN + 2 * sb.st_size));
    TIFFOpenOptionsSetErrorHandlerExtR(o, on_error, c);
    TIFFOpenOptionsSetWarningHandlerExtR(o, on_warning, c);
    TIFF *t = fd >= 0 ? TIFFFdOpenExt(fd, path, mode, o) : TIFFOpenExt(path, mode, o);
    TIFFOpenOptionsFree(o);
    if (!t && !c->msg[0])
        snprintf(c->msg, sizeof c->msg, "not a readable TIFF file");
    return t;
}

/* libtiff says "Read error ..." or "... Not enough data ..." when data are missing. */
static rpiv_status tfail(const char *path, const tctx *c, const char *what)
{
    if (strstr(c->msg, "Read error") || strstr(c->msg, "Not enough data") ||
        strstr(c->msg, "Cannot read") || strstr(c->msg, "Can not read") ||
        strstr(c->msg, "Incorrect count") || strstr(c->msg, "end of file") ||
        strstr(c->msg, "Premature EO") || strstr(c->msg, "Line length mismatch"))
        return rpiv_fail(RPIV_EFORMAT, "%s: truncated or corrupt TIFF (%s: %s)", path, what,
                         c->msg);
    return rpiv_fail(RPIV_EFORMAT, "%s: %s: %s", path, what, c->msg[0] ? c->msg : "failed");
}

rpiv_status img_tiff_pages(const char *path, int *npages)
{
    tctx c;
    *npages = 0;
    TIFF *t = topen(path, "r", -1, &c);
    if (!t)
        return tfail(path, &c, "cannot open as TIFF");
    tdir_t n = TIFFNumberOfDirectories(t);
    TIFFClose(t);
    if (n < 1)
        return rpiv_fail(RPIV_EFORMAT, "%s: TIFF file without any image", path);
    *npages = (int)n;
    return RPIV_OK;
}

/* ---- reading --------------------------------------------------------------------------- */

typedef struct tinfo {
    uint32_t w, h;
    uint16_t bps, spp, sf, photo, planar, nextra;
    int extra_alpha; /* every extra sample is declared alpha (and so may be ignored) */
    int nch;         /* colour channels used: 1 (grey, palette) or 3 (RGB) */
} tinfo;

/* Sample k of a decoded row (host byte order, as libtiff returns it). */
static double sample(const unsigned char *row, uint64_t k, int bps, int isfloat)
{
    switch (bps) {
    case 8:
        return row[k];
    case 16: {
        uint16_t v;
        memcpy(&v, row + 2 * k, 2);
        return v;
    }
    case 32: {
        if (isfloat) {
            float f;
            memcpy(&f, row + 4 * k, 4);
            return (double)f;
        }
        uint32_t v;
        memcpy(&v, row + 4 * k, 4);
        return v;
    }
    default: { /* 1, 2, 4 bits, most significant first */
        uint64_t bit = k * (uint64_t)bps;
        unsigned shift = (unsigned)(8 - bps - (int)(bit % 8));
        return (row[bit / 8] >> shift) & ((1u << bps) - 1u);
    }
    }
}

/* A row of n grey samples of 8 or 16 bits, or 32-bit floats, into out: the values sample()
 * gives (every conversion is exact), in loops the compiler vectorises; 0 (nothing written)
 * for the other depths. */
static int grey_row(const unsigned char *row, int bps, int isfloat, uint32_t n, float *out)
{
    if (bps == 8) {
        for (uint32_t i = 0; i < n; i++)
            out[i] = row[i];
        return 1;
    }
    if (bps == 16) {
        for (uint32_t i = 0; i < n; i++) {
            uint16_t v;
            memcpy(&v, row + 2 * (size_t)i, 2);
            out[i] = v;
        }
        return 1;
    }
    if (bps == 32 && isfloat) {
        memcpy(out, row, 4 * (size_t)n);
        return 1;
    }
    return 0;
}

/* The current directory's Photometric value and ColorMap count as stored in the file
 * (*count 0: no colour map). libtiff reads a palette image whose colour map is missing, or
 * has the wrong count (a warning, "tag ignored"), as grey or RGB without telling the caller
 * (issue 20 item 14): only the file's own entry shows what it was. 0 if the directory
 * cannot be read here. */
static int raw_palette_entry(TIFF *t, uint16_t *photo, uint64_t *count)
{
    int fd = TIFFFileno(t), big = TIFFIsBigTIFF(t), swab = TIFFIsByteSwapped(t);
    uint64_t off = TIFFCurrentDirOffset(t), n = 0;
    unsigned char head[8], e[20];
    size_t esz = big ? 20 : 12, nsz = big ? 8 : 2;
    *photo = 0, *count = 0;
    if (fd < 0 || off == 0 || pread(fd, head, nsz, (off_t)off) != (ssize_t)nsz)
        return 0;
    if (big) {
        memcpy(&n, head, 8);
        if (swab)
            TIFFSwabLong8(&n);
    } else {
        uint16_t n16;
        memcpy(&n16, head, 2);
        if (swab)
            TIFFSwabShort(&n16);
        n = n16;
    }
    int found = 0;
    for (uint64_t i = 0; i < n && i < 65536; i++) {
        if (pread(fd, e, esz, (off_t)(off + nsz + i * esz)) != (ssize_t)esz)
            return 0;
        uint16_t tag, type;
        memcpy(&tag, e, 2);
        memcpy(&type, e + 2, 2);
        if (swab)
            TIFFSwabShort(&tag), TIFFSwabShort(&type);
        if (tag == TIFFTAG_PHOTOMETRIC && type == TIFF_SHORT) {
            memcpy(photo, e + (big ? 12 : 8), 2);
            if (swab)
                TIFFSwabShort(photo);
            found = 1;
        } else if (tag == TIFFTAG_COLORMAP) {
            if (big) {
                memcpy(count, e + 4, 8);
                if (swab)
                    TIFFSwabLong8(count);
            } else {
                uint32_t c32;
                memcpy(&c32, e + 4, 4);
                if (swab)
                    TIFFSwabLong(&c32);
                *count = c32;
            }
        }
    }
    return found;
}

static rpiv_status read_info(TIFF *t, const char *path, int page, tinfo *ti)
{
    uint16_t *extra = NULL;
    memset(ti, 0, sizeof *ti);
    if (!TIFFGetField(t, TIFFTAG_IMAGEWIDTH, &ti->w) ||
        !TIFFGetField(t, TIFFTAG_IMAGELENGTH, &ti->h))
        return rpiv_fail(RPIV_EFORMAT, "%s: page %d: TIFF without image width or length", path,
                         page);
    TIFFGetFieldDefaulted(t, TIFFTAG_BITSPERSAMPLE, &ti->bps);
    TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLESPERPIXEL, &ti->spp);
    TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLEFORMAT, &ti->sf);
    TIFFGetFieldDefaulted(t, TIFFTAG_PLANARCONFIG, &ti->planar);
    TIFFGetFieldDefaulted(t, TIFFTAG_EXTRASAMPLES, &ti->nextra, &extra);
    if (!TIFFGetField(t, TIFFTAG_PHOTOMETRIC, &ti->photo))
        ti->photo = ti->spp >= 3 ? PHOTOMETRIC_RGB : PHOTOMETRIC_MINISBLACK;
    uint16_t raw;
    uint64_t ncmap;
    if (ti->photo != PHOTOMETRIC_PALETTE && raw_palette_entry(t, &raw, &ncmap) &&
        raw == PHOTOMETRIC_PALETTE) {
        if (ncmap == 0)
            return rpiv_fail(RPIV_EFORMAT,
                             "%s: page %d: palette TIFF without a colour map (its pixels are "
                             "indices, not grey levels)",
                             path, page);
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: page %d: palette TIFF colour map has %llu values, %llu expected "
                         "(3 x 2^%u)",
                         path, page, (unsigned long long)ncmap,
                         ti->bps < 32 ? 3ull << ti->bps : 0ull, ti->bps);
    }
    if (ti->sf == SAMPLEFORMAT_VOID)
        ti->sf = SAMPLEFORMAT_UINT;
    ti->extra_alpha = 1;
    for (uint16_t i = 0; i < ti->nextra; i++)
        if (!extra || (extra[i] != EXTRASAMPLE_ASSOCALPHA && extra[i] != EXTRASAMPLE_UNASSALPHA))
            ti->extra_alpha = 0;
    return RPIV_OK;
}

/* Check the sample layout is one we read; set nch. */
static rpiv_status check_layout(const char *path, tinfo *ti)
{
    int colour = ti->photo == PHOTOMETRIC_RGB;
    int grey = ti->photo == PHOTOMETRIC_MINISBLACK || ti->photo == PHOTOMETRIC_MINISWHITE ||
               ti->photo == PHOTOMETRIC_PALETTE;
    if (!colour && !grey)
        return rpiv_fail(RPIV_EFORMAT, "%s: TIFF photometric interpretation %u not supported", path,
                         ti->photo);
    if (ti->sf == SAMPLEFORMAT_INT)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: signed %u-bit integer TIFF samples not supported "
                         "(8- or 16-bit unsigned, or 32-bit float)",
                         path, ti->bps);
    if (ti->sf == SAMPLEFORMAT_IEEEFP) {
        if (ti->bps != 32 || ti->photo == PHOTOMETRIC_PALETTE ||
            ti->photo == PHOTOMETRIC_MINISWHITE)
            return rpiv_fail(RPIV_EFORMAT,
                             "%s: %u-bit floating-point TIFF not supported (32-bit float grey "
                             "or RGB only)",
                             path, ti->bps);
    } else if (ti->sf == SAMPLEFORMAT_UINT) {
        if (ti->bps != 1 && ti->bps != 2 && ti->bps != 4 && ti->bps != 8 && ti->bps != 16)
            return rpiv_fail(RPIV_EFORMAT,
                             "%s: %u-bit unsigned integer TIFF samples not supported "
                             "(1, 2, 4, 8 or 16 bits, or 32-bit float)",
                             path, ti->bps);
    } else {
        return rpiv_fail(RPIV_EFORMAT, "%s: TIFF sample format %u not supported", path, ti->sf);
    }
    ti->nch = colour ? 3 : 1;
    if (ti->spp < ti->nextra || ti->spp - ti->nextra != ti->nch)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: %u samples per pixel (%u extra) do not fit a %s TIFF "
                         "(%d colour sample%s expected)",
                         path, ti->spp, ti->nextra, colour ? "RGB" : "grey", ti->nch,
                         ti->nch > 1 ? "s" : "");
    /* An extra sample of unknown meaning may be data (two frames interleaved, say): refuse
     * it rather than drop it. libtiff declares undeclared extra samples "unspecified". */
    if (ti->nextra && !ti->extra_alpha)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: %u samples per pixel in a %s TIFF, %u of them neither colour nor "
                         "alpha: not supported",
                         path, ti->spp, colour ? "RGB" : "grey", ti->nextra);
    if (colour && ti->bps < 8)
        return rpiv_fail(RPIV_EFORMAT, "%s: %u-bit RGB TIFF not supported", path, ti->bps);
    return RPIV_OK;
}

/* Refuse, before allocating the image, a header whose pixel data cannot be in the file:
 * uncompressed data take their full size; no codec rpiv meets (LZW, Deflate, PackBits, ...)
 * packs more than 4096:1. Fax and JBIG codes for 1-bit images can, so they are not checked. */
static rpiv_status check_plausible(TIFF *t, const char *path, const tinfo *ti)
{
    uint16_t comp = COMPRESSION_NONE;
    TIFFGetFieldDefaulted(t, TIFFTAG_COMPRESSION, &comp);
    /* an unknown codec cannot decode anything: say so before allocating */
    if (!TIFFIsCODECConfigured(comp))
        return rpiv_fail(RPIV_EFORMAT, "%s: TIFF compression %u not supported", path,
                         (unsigned)comp);
    /* The decoding buffer holds one tile: a tile far larger than the image (a 469762064-px
     * wide tile on a 1 x 5 image asked for 9.4 GB) is refused. Legitimate tiles larger than
     * the image are small (a 256 x 256 tile on a thumbnail). */
    uint64_t raw = ((uint64_t)ti->w * ti->spp * ti->bps + 7) / 8 * ti->h;
    uint64_t tile = TIFFIsTiled(t) ? (uint64_t)TIFFTileSize64(t) : 0;
    if (tile > 4 * raw && tile > ((uint64_t)64 << 20))
        return rpiv_fail(RPIV_EFORMAT, "%s: corrupt TIFF: tiles of %llu bytes for a %ux%u image",
                         path, (unsigned long long)tile, ti->w, ti->h);
    uint64_t fsize = (uint64_t)TIFFGetSizeProc(t)(TIFFClientdata(t));
    /* Fax codes (CCITT RLE, G3, G4) take at least one bit per row whatever the width (a blank
     * G4 row is one V0 code), so only the height can be bounded; JBIG not even that. */
    if (ti->bps == 1 &&
        (comp == COMPRESSION_CCITTRLE || comp == COMPRESSION_CCITTRLEW ||
         comp == COMPRESSION_CCITTFAX3 || comp == COMPRESSION_CCITTFAX4) &&
        ti->h > 8 * fsize + 4096)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: truncated or corrupt TIFF: %u fax-coded rows cannot be stored in "
                         "a %llu-byte file",
                         path, ti->h, (unsigned long long)fsize);
    if (ti->bps == 1 && comp != COMPRESSION_NONE)
        return RPIV_OK;
    /* Expansion bounds: LZW < 2560:1, Deflate 1032:1, PackBits 64:1, JPEG < 1536:1 (4096
     * covers them); ZSTD < 32768:1 (a block of at most 128 KiB takes at least 4 bytes; a
     * uniform 8000 x 8000 image reaches 30592:1), LZMA about 10^4:1 (6698:1 there). Other
     * codecs get 65536:1: only a constant image of tens of Mpx in a few hundred bytes (WebP,
     * LERC) would be refused. */
    int known = comp == COMPRESSION_NONE || comp == COMPRESSION_LZW ||
                comp == COMPRESSION_DEFLATE || comp == COMPRESSION_ADOBE_DEFLATE ||
                comp == COMPRESSION_PACKBITS || comp == COMPRESSION_JPEG;
    uint64_t cap = comp == COMPRESSION_NONE ? fsize : (known ? 4096 : 65536) * fsize + (1u << 20);
    if (raw > cap)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: truncated or corrupt TIFF: %ux%u pixels (%llu bytes of samples) "
                         "cannot be stored in a %llu-byte file",
                         path, ti->w, ti->h, (unsigned long long)raw, (unsigned long long)fsize);
    return RPIV_OK;
}

/* Decode every strip or tile into im->px (nch == 1) or rgb (3 planes of w*h). */
static rpiv_status read_blocks(TIFF *t, tctx *c, const char *path, const tinfo *ti, float *px,
                               float *rgb)
{
    int tiled = TIFFIsTiled(t);
    uint32_t bw = ti->w, bh;
    int separate = ti->planar == PLANARCONFIG_SEPARATE && ti->spp > 1;
    uint64_t nsp = separate ? 1 : ti->spp; /* samples per pixel in one block */
    int isfloat = ti->sf == SAMPLEFORMAT_IEEEFP;
    if (tiled) {
        if (!TIFFGetField(t, TIFFTAG_TILEWIDTH, &bw) || !TIFFGetField(t, TIFFTAG_TILELENGTH, &bh) ||
            bw == 0 || bh == 0)
            return rpiv_fail(RPIV_EFORMAT, "%s: tiled TIFF without a valid tile size", path);
    } else {
        TIFFGetFieldDefaulted(t, TIFFTAG_ROWSPERSTRIP, &bh);
        if (bh == 0 || bh > ti->h)
            bh = ti->h;
    }
    uint64_t rowbytes = ((uint64_t)bw * nsp * ti->bps + 7) / 8;
    tmsize_t bsize = tiled ? TIFFTileSize(t) : TIFFStripSize(t);
    if (bsize <= 0 || (uint64_t)bsize < rowbytes)
        return tfail(path, c, "cannot size the TIFF strips or tiles");
    unsigned char *buf = _TIFFmalloc(bsize);
    if (!buf)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory for a TIFF block of %lld bytes", path,
                         (long long)bsize);
    rpiv_status st = RPIV_OK;
    int nplanes = separate ? ti->nch : 1;
    size_t npx = (size_t)ti->w * ti->h;
    for (int p = 0; p < nplanes && !st; p++) {
        for (uint32_t y0 = 0; y0 < ti->h && !st; y0 += bh) {
            for (uint32_t x0 = 0; x0 < ti->w && !st; x0 += bw) {
                uint32_t rows = ti->h - y0 < bh ? ti->h - y0 : bh;
                uint32_t cols = ti->w - x0 < bw ? ti->w - x0 : bw;
                tmsize_t got;
                uint32_t idx;
                if (tiled) {
                    idx = TIFFComputeTile(t, x0, y0, 0, (uint16_t)p);
                    got = TIFFReadEncodedTile(t, idx, buf, bsize);
                } else {
                    idx = TIFFComputeStrip(t, y0, (uint16_t)p);
                    got = TIFFReadEncodedStrip(t, idx, buf, bsize);
                }
                if (got < 0 || c->corrupt ||
                    (uint64_t)got < (uint64_t)(rows - 1) * rowbytes +
                                        ((uint64_t)cols * nsp * ti->bps + 7) / 8) {
                    char what[96];
                    snprintf(what, sizeof what, "%s %u of %u, rows %u-%u", tiled ? "tile" : "strip",
                             idx + 1, tiled ? TIFFNumberOfTiles(t) : TIFFNumberOfStrips(t), y0,
                             y0 + rows - 1);
                    if (got >= 0 && !c->msg[0])
                        snprintf(c->msg, sizeof c->msg, "Read error: short block");
                    st = tfail(path, c, what);
                    break;
                }
                for (uint32_t r = 0; r < rows; r++) {
                    const unsigned char *row = buf + r * rowbytes;
                    size_t o = (size_t)(y0 + r) * ti->w + x0;
                    if (ti->nch == 1 && nsp == 1 && grey_row(row, ti->bps, isfloat, cols, px + o))
                        continue;
                    for (uint32_t col = 0; col < cols; col++) {
                        if (ti->nch == 1) {
                            px[o + col] = (float)sample(row, col * nsp, ti->bps, isfloat);
                        } else if (separate) {
                            rgb[(size_t)p * npx + o + col] =
                                (float)sample(row, col, ti->bps, isfloat);
                        } else {
                            for (int ch = 0; ch < 3; ch++)
                                rgb[(size_t)ch * npx + o + col] =
                                    (float)sample(row, col * nsp + (uint64_t)ch, ti->bps, isfloat);
                        }
                    }
                }
            }
        }
    }
    _TIFFfree(buf);
    return st;
}

/* Grey levels of the palette entries: luminance of the colour map, on the scale of the
 * index depth (0..255 for up to 8 bits, 0..65535 for 16). Colour maps written with 8-bit
 * values (all <= 255, a common writer bug) are taken as 8-bit. */
static rpiv_status palette_lut(TIFF *t, const char *path, const tinfo *ti, float **lut)
{
    uint16_t *r, *g, *b;
    size_t n = (size_t)1 << ti->bps;
    *lut = NULL;
    if (!TIFFGetField(t, TIFFTAG_COLORMAP, &r, &g, &b))
        return rpiv_fail(RPIV_EFORMAT, "%s: palette TIFF without a colour map", path);
    int eight = 1;
    for (size_t i = 0; i < n; i++)
        if (r[i] > 255 || g[i] > 255 || b[i] > 255)
            eight = 0;
    double to8 = eight ? 1.0 : 1.0 / 257.0, to16 = eight ? 257.0 : 1.0;
    double scale = ti->bps <= 8 ? to8 : to16;
    *lut = malloc(n * sizeof **lut);
    if (!*lut)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory for the palette", path);
    for (size_t i = 0; i < n; i++)
        (*lut)[i] = img_luma(r[i] * scale, g[i] * scale, b[i] * scale);
    return RPIV_OK;
}

rpiv_status img_tiff_load(const char *path, int page, rpiv_image **out, int *warned)
{
    tctx c;
    tinfo ti;
    rpiv_image *im = NULL;
    float *rgb = NULL, *lut = NULL;
    rpiv_status st;
    *out = NULL;
    /* "c": no strip chopping, so strip numbers in messages are the file's own */
    TIFF *t = topen(path, "rc", -1, &c);
    if (!t)
        return tfail(path, &c, "cannot open as TIFF");
    /* the page must be one rpiv_image_count_pages counts (libtiff can open the directory of
     * a page whose "next directory" link is cut, which TIFFNumberOfDirectories does not
     * count) */
    if (page > 0 &&
        ((tdir_t)page >= TIFFNumberOfDirectories(t) || !TIFFSetDirectory(t, (tdir_t)page))) {
        tdir_t n = TIFFNumberOfDirectories(t);
        st = rpiv_fail(RPIV_EINVAL, "%s: page %d requested but the file has %u page%s", path, page,
                       (unsigned)n, n == 1 ? "" : "s");
        goto out_close;
    }
    st = read_info(t, path, page, &ti);
    if (st)
        goto out_close;
    st = check_layout(path, &ti);
    if (st)
        goto out_close;
    st = img_check_size(path, ti.w, ti.h);
    if (!st)
        st = check_plausible(t, path, &ti);
    if (st)
        goto out_close;
    int bits = ti.sf == SAMPLEFORMAT_IEEEFP ? 32 : ti.bps;
    if (ti.photo == PHOTOMETRIC_PALETTE)
        bits = ti.bps <= 8 ? 8 : 16;
    st = img_alloc_ex(path, ti.w, ti.h, bits, 0, &im); /* read_blocks writes every pixel */
    if (st)
        goto out_close;
    img_populate(im, (uint64_t)TIFFGetSizeProc(t)(TIFFClientdata(t)));
    size_t npx = (size_t)ti.w * ti.h;
    if (ti.nch == 3) {
        rgb = malloc(3 * npx * sizeof *rgb);
        if (!rgb) {
            st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory for the RGB planes", path);
            goto out_free;
        }
    }
    st = read_blocks(t, &c, path, &ti, im->px, rgb);
    if (st)
        goto out_free;
    if (ti.sf == SAMPLEFORMAT_IEEEFP) { /* NaN or infinite levels would poison every sum */
        const float *v = ti.nch == 3 ? rgb : im->px;
        for (size_t i = 0; i < (size_t)ti.nch * npx; i++) {
            if (!isfinite(v[i])) {
                st = rpiv_fail(
                    RPIV_EFORMAT, "%s: pixel (%zu, %zu) is %s: float TIFF samples must be finite",
                    path, i % npx % ti.w, i % npx / ti.w, isnan(v[i]) ? "NaN" : "infinite");
                goto out_free;
            }
        }
    }
    if (ti.nch == 3) {
        for (size_t i = 0; i < npx; i++)
            im->px[i] = img_luma((double)rgb[i], (double)rgb[npx + i], (double)rgb[2 * npx + i]);
        *warned = 1;
    } else if (ti.photo == PHOTOMETRIC_PALETTE) {
        st = palette_lut(t, path, &ti, &lut);
        if (st)
            goto out_free;
        for (size_t i = 0; i < npx; i++)
            im->px[i] = lut[(size_t)im->px[i]];
    } else if (ti.photo == PHOTOMETRIC_MINISWHITE) {
        float top = (float)((1u << ti.bps) - 1u);
        for (size_t i = 0; i < npx; i++)
            im->px[i] = top - im->px[i];
    }
    *out = im;
    im = NULL;
out_free:
    free(lut);
    free(rgb);
    rpiv_image_free(im);
out_close:
    TIFFClose(t);
    return st;
}

/* ---- writing --------------------------------------------------------------------------- */

static rpiv_status tiff_save(const rpiv_image *im, const char *path, int isfloat)
{
    atomic_file af;
    tctx c;
    rpiv_status st = atomic_begin(&af, path, 0); /* libtiff opens the temporary file by name */
    if (st)
        return st;
    TIFF *t = topen(af.tmp, "w", -1, &c);
    if (!t) {
        atomic_abort(&af);
        return rpiv_fail(RPIV_EIO, "%s: cannot write TIFF: %s", path, c.msg);
    }
    size_t rowbytes = (size_t)im->w * (isfloat ? 4 : 2);
    void *row = malloc(rowbytes);
    if (!row) {
        st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory for a row", path);
        goto out_close;
    }
    TIFFSetField(t, TIFFTAG_IMAGEWIDTH, (uint32_t)im->w);
    TIFFSetField(t, TIFFTAG_IMAGELENGTH, (uint32_t)im->h);
    TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, isfloat ? 32 : 16);
    TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 1);
    TIFFSetField(t, TIFFTAG_SAMPLEFORMAT, isfloat ? SAMPLEFORMAT_IEEEFP : SAMPLEFORMAT_UINT);
    TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
    TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
    TIFFSetField(t, TIFFTAG_COMPRESSION, COMPRESSION_NONE);
    TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, TIFFDefaultStripSize(t, 0));
    TIFFSetField(t, TIFFTAG_SOFTWARE, "rpiv");
    for (int y = 0; y < im->h; y++) {
        const float *src = im->px + (size_t)y * im->w;
        if (isfloat) {
            memcpy(row, src, rowbytes);
        } else {
            uint16_t *d = row;
            for (int x = 0; x < im->w; x++) {
                float v = src[x];
                d[x] = !(v > 0.0f) ? 0 : v >= 65535.0f ? 65535 : (uint16_t)floorf(v + 0.5f);
            }
        }
        if (TIFFWriteScanline(t, row, (uint32_t)y, 0) < 0) {
            st = rpiv_fail(RPIV_EIO, "%s: cannot write row %d: %s", path, y, c.msg);
            goto out_close;
        }
    }
    if (!TIFFFlush(t)) {
        st = rpiv_fail(RPIV_EIO, "%s: cannot write the TIFF directory: %s", path, c.msg);
        goto out_close;
    }
out_close:
    free(row);
    TIFFClose(t);
    if (st) {
        atomic_abort(&af);
        return st;
    }
    return atomic_commit(&af); /* fsync, rename, fsync of the folder */
}

rpiv_status rpiv_image_save_tiff16(const rpiv_image *im, const char *path)
{
    return tiff_save(im, path, 0);
}

rpiv_status rpiv_image_save_tiff_float(const rpiv_image *im, const char *path)
{
    return tiff_save(im, path, 1);
}
