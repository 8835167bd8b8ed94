/* SPDX-License-Identifier: GPL-3.0-or-later */
/* fuzz/gen_corpus.c - writes the small image seeds of fuzz/corpus/{tiff,png,pgm,bmp_jpeg}:
 * valid files of every layout the readers accept, and slightly broken ones. Not part of the
 * build (the fuzz CMakeLists globs fuzz_*.c only); run by hand when the seeds change:
 *   cc -O1 -o /tmp/gen_corpus fuzz/gen_corpus.c -ltiff -lpng && /tmp/gen_corpus fuzz/corpus
 * The JPEG seeds are made with ImageMagick (docs/fuzzing.md). */
#include <png.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <tiffio.h>

static const char *top;

static void die(const char *what)
{
    fprintf(stderr, "gen_corpus: %s\n", what);
    exit(1);
}

static char *pth(const char *dir, const char *name)
{
    static char buf[4096];
    snprintf(buf, sizeof buf, "%s/%s/%s", top, dir, name);
    return buf;
}

/* A deterministic grey level in 0..maxv for pixel (x, y) of channel c. */
static unsigned level(int x, int y, int c, unsigned maxv)
{
    unsigned long v = (unsigned long)(x * 37 + y * 91 + c * 53 + (x * y) % 17) * 2654435761UL;
    return (unsigned)((v >> 7) % (maxv + 1UL));
}

/* ---- TIFF ---------------------------------------------------------------------------- */

typedef struct tspec {
    const char *name, *mode;
    int w, h, bps, spp, sf, photo, planar, comp, rps, tile, pages, nextra, minis;
} tspec;

static void tiff_page(TIFF *t, const tspec *s, int page)
{
    TIFFSetField(t, TIFFTAG_IMAGEWIDTH, (uint32_t)s->w);
    TIFFSetField(t, TIFFTAG_IMAGELENGTH, (uint32_t)s->h);
    TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, (uint16_t)s->bps);
    TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, (uint16_t)s->spp);
    TIFFSetField(t, TIFFTAG_SAMPLEFORMAT, (uint16_t)s->sf);
    TIFFSetField(t, TIFFTAG_PHOTOMETRIC, (uint16_t)s->photo);
    TIFFSetField(t, TIFFTAG_PLANARCONFIG, (uint16_t)s->planar);
    TIFFSetField(t, TIFFTAG_COMPRESSION, (uint16_t)s->comp);
    if (s->nextra) {
        uint16_t ex[2] = {EXTRASAMPLE_UNASSALPHA, EXTRASAMPLE_UNSPECIFIED};
        TIFFSetField(t, TIFFTAG_EXTRASAMPLES, (uint16_t)s->nextra, ex);
    }
    if (s->photo == PHOTOMETRIC_PALETTE) {
        size_t n = (size_t)1 << s->bps;
        uint16_t *r = malloc(3 * n * sizeof *r);
        for (size_t i = 0; i < n; i++) {
            r[i] = (uint16_t)(i * 65535 / (n - 1));
            r[n + i] = (uint16_t)((n - 1 - i) * 65535 / (n - 1));
            r[2 * n + i] = (uint16_t)((i * 7 % n) * 65535 / (n - 1));
        }
        TIFFSetField(t, TIFFTAG_COLORMAP, r, r + n, r + 2 * n);
        free(r);
    }
    if (s->pages > 1) {
        TIFFSetField(t, TIFFTAG_SUBFILETYPE, FILETYPE_PAGE);
        TIFFSetField(t, TIFFTAG_PAGENUMBER, (uint16_t)page, (uint16_t)s->pages);
    }
    int nsp = s->planar == PLANARCONFIG_SEPARATE ? 1 : s->spp;
    int nplanes = s->planar == PLANARCONFIG_SEPARATE ? s->spp : 1;
    unsigned maxv = s->bps >= 16 ? 65535u : (1u << s->bps) - 1u;
    if (s->tile) {
        TIFFSetField(t, TIFFTAG_TILEWIDTH, (uint32_t)s->tile);
        TIFFSetField(t, TIFFTAG_TILELENGTH, (uint32_t)s->tile);
        tmsize_t ts = TIFFTileSize(t);
        unsigned char *buf = calloc(1, (size_t)ts);
        for (int p = 0; p < nplanes; p++)
            for (int y0 = 0; y0 < s->h; y0 += s->tile)
                for (int x0 = 0; x0 < s->w; x0 += s->tile) {
                    memset(buf, 0, (size_t)ts);
                    for (int y = 0; y < s->tile; y++)
                        for (int x = 0; x < s->tile; x++)
                            for (int c = 0; c < nsp; c++) {
                                size_t k = ((size_t)y * s->tile + x) * nsp + c;
                                unsigned v = level(x0 + x, y0 + y, c + p + page, maxv);
                                if (s->bps == 8)
                                    buf[k] = (unsigned char)v;
                                else
                                    ((uint16_t *)buf)[k] = (uint16_t)v;
                            }
                    if (TIFFWriteEncodedTile(
                            t, TIFFComputeTile(t, (uint32_t)x0, (uint32_t)y0, 0, (uint16_t)p), buf,
                            ts) < 0)
                        die("tile write");
                }
        free(buf);
        return;
    }
    TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, (uint32_t)s->rps);
    size_t rowbytes = ((size_t)s->w * nsp * s->bps + 7) / 8;
    unsigned char *row = calloc(1, rowbytes);
    for (int p = 0; p < nplanes; p++)
        for (int y = 0; y < s->h; y++) {
            memset(row, 0, rowbytes);
            for (int x = 0; x < s->w; x++)
                for (int c = 0; c < nsp; c++) {
                    size_t k = (size_t)x * nsp + c;
                    unsigned v = level(x, y, c + p + page, maxv);
                    if (s->sf == SAMPLEFORMAT_IEEEFP) {
                        float f = (float)v * 0.0173f - 3.1f;
                        memcpy(row + 4 * k, &f, 4);
                    } else if (s->bps == 32) {
                        uint32_t u = v;
                        memcpy(row + 4 * k, &u, 4);
                    } else if (s->bps == 16 || s->bps == 12) {
                        uint16_t u = (uint16_t)v;
                        if (s->bps == 16)
                            memcpy(row + 2 * k, &u, 2);
                        else
                            row[k] = (unsigned char)v;
                    } else if (s->bps == 8) {
                        row[k] = (unsigned char)v;
                    } else {
                        size_t bit = k * (size_t)s->bps;
                        row[bit / 8] |= (unsigned char)(v << (8 - s->bps - (int)(bit % 8)));
                    }
                }
            if (TIFFWriteScanline(t, row, (uint32_t)y, (uint16_t)p) < 0)
                die("scanline write");
        }
    free(row);
}

static void tiff(const tspec *s)
{
    TIFF *t = TIFFOpen(pth("tiff", s->name), s->mode);
    if (!t)
        die(s->name);
    for (int page = 0; page < (s->pages ? s->pages : 1); page++) {
        tiff_page(t, s, page);
        if (!TIFFWriteDirectory(t))
            die("directory");
    }
    TIFFClose(t);
}

/* ---- PNG ----------------------------------------------------------------------------- */

typedef struct pspec {
    const char *name;
    int w, h, depth, ctype, interlace, npal, trns;
} pspec;

static void pngw(const pspec *s)
{
    FILE *f = fopen(pth("png", s->name), "wb");
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png_create_info_struct(png);
    if (!f || !png || !info || setjmp(png_jmpbuf(png)))
        die(s->name);
    png_init_io(png, f);
    png_set_IHDR(png, info, (png_uint_32)s->w, (png_uint_32)s->h, s->depth, s->ctype, s->interlace,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_color pal[256];
    if (s->ctype == PNG_COLOR_TYPE_PALETTE) {
        for (int i = 0; i < s->npal; i++)
            pal[i] = (png_color){(png_byte)(i * 47), (png_byte)(255 - i * 13), (png_byte)(i * 5)};
        png_set_PLTE(png, info, pal, s->npal);
        if (s->npal == 3)
            png_set_check_for_invalid_index(png, 0); /* write indices past the PLTE */
    }
    if (s->trns) {
        png_byte tr[2] = {0, 128};
        png_color_16 tc = {0, 0, 0, 0, 1};
        png_set_tRNS(png, info, tr, 2, &tc);
    }
    png_write_info(png, info);
    int nch = png_get_channels(png, info);
    size_t rowbytes = png_get_rowbytes(png, info);
    unsigned char *row = calloc(1, rowbytes);
    unsigned maxv = s->ctype == PNG_COLOR_TYPE_PALETTE
                        ? (s->npal == 3 ? 7u : (unsigned)s->npal - 1u)
                    : s->depth == 16 ? 65535u
                                     : (1u << s->depth) - 1u;
    int passes = s->interlace ? png_set_interlace_handling(png) : 1;
    for (int pass = 0; pass < passes; pass++)
        for (int y = 0; y < s->h; y++) {
            memset(row, 0, rowbytes);
            for (int x = 0; x < s->w; x++)
                for (int c = 0; c < nch; c++) {
                    size_t k = (size_t)x * nch + c;
                    unsigned v = level(x, y, c, maxv);
                    if (s->depth == 16) {
                        row[2 * k] = (unsigned char)(v >> 8);
                        row[2 * k + 1] = (unsigned char)v;
                    } else if (s->depth == 8) {
                        row[k] = (unsigned char)v;
                    } else {
                        size_t bit = k * (size_t)s->depth;
                        row[bit / 8] |= (unsigned char)(v << (8 - s->depth - (int)(bit % 8)));
                    }
                }
            png_write_row(png, row);
        }
    png_write_end(png, NULL);
    png_destroy_write_struct(&png, &info);
    free(row);
    fclose(f);
}

/* ---- raw files ----------------------------------------------------------------------- */

static void put(const char *dir, const char *name, const void *data, size_t n)
{
    FILE *f = fopen(pth(dir, name), "wb");
    if (!f || fwrite(data, 1, n, f) != n || fclose(f))
        die(name);
}

static unsigned char *slurp(const char *dir, const char *name, size_t *n)
{
    FILE *f = fopen(pth(dir, name), "rb");
    if (!f)
        die(name);
    fseek(f, 0, SEEK_END);
    *n = (size_t)ftell(f);
    rewind(f);
    unsigned char *b = malloc(*n);
    if (fread(b, 1, *n, f) != *n)
        die(name);
    fclose(f);
    return b;
}

/* A copy of dir/src cut to keep bytes, or with byte at flip xor'ed with 0x5a. */
static void variant(const char *dir, const char *src, const char *dst, size_t keep, long flip)
{
    size_t n;
    unsigned char *b = slurp(dir, src, &n);
    if (flip >= 0 && (size_t)flip < n)
        b[flip] ^= 0x5a;
    put(dir, dst, b, keep && keep < n ? keep : n);
    free(b);
}

static void pgm(void)
{
    char buf[1024];
    int n = snprintf(buf, sizeof buf, "P5\n# rpiv seed\n7 5\n255\n");
    for (int k = 0; k < 35; k++)
        buf[n++] = (char)level(k % 7, k / 7, 0, 255);
    put("pgm", "p5_8bit.pgm", buf, (size_t)n);
    put("pgm", "p5_truncated.pgm", buf, (size_t)n - 9);
    n = snprintf(buf, sizeof buf, "P5 6 4 4095 ");
    for (int k = 0; k < 24; k++) {
        unsigned v = level(k % 6, k / 6, 0, 4095);
        buf[n++] = (char)(v >> 8);
        buf[n++] = (char)(v & 255);
    }
    put("pgm", "p5_12bit.pgm", buf, (size_t)n);
    n = snprintf(buf, sizeof buf, "P5\n3 2\n65535\n");
    for (int k = 0; k < 6; k++) {
        unsigned v = level(k % 3, k / 3, 0, 65535);
        buf[n++] = (char)(v >> 8);
        buf[n++] = (char)(v & 255);
    }
    put("pgm", "p5_16bit.pgm", buf, (size_t)n);
    n = snprintf(buf, sizeof buf, "P2\n# ascii\n5 3\n# maxval next\n15\n");
    for (int k = 0; k < 15; k++)
        n += snprintf(buf + n, sizeof buf - (size_t)n, "%u%c", level(k % 5, k / 5, 0, 15),
                      k % 5 == 4 ? '\n' : ' ');
    put("pgm", "p2_4bit.pgm", buf, (size_t)n);
    put("pgm", "p2_over_maxval.pgm", "P2 2 2 3\n0 1\n2 9\n", 18);
    put("pgm", "p5_maxval0.pgm", "P5 1 1 0\n\x00", 10);
    put("pgm", "p5_huge.pgm", "P5 99999 99999 255\n\x01\x02", 21);
}

static void le16(unsigned char *p, unsigned v)
{
    p[0] = (unsigned char)v;
    p[1] = (unsigned char)(v >> 8);
}

static void le32(unsigned char *p, uint32_t v)
{
    le16(p, v & 0xffff);
    le16(p + 2, v >> 16);
}

/* Windows BMP, BITMAPINFOHEADER, bpp 1/4/8 (palette) or 24; negative h = top-down;
 * rle = 1 writes 8-bit RLE (each row as one encoded run per pixel pair). */
static void bmp(const char *name, int w, int h, int bpp, int rle)
{
    int ah = h < 0 ? -h : h, npal = bpp <= 8 ? 1 << bpp : 0;
    size_t rowbytes = ((size_t)w * bpp + 31) / 32 * 4;
    size_t off = 54 + 4 * (size_t)npal,
           datasz = rle ? (size_t)ah * ((size_t)w * 2 + 2) + 2 : rowbytes * (size_t)ah;
    unsigned char *b = calloc(1, off + datasz);
    b[0] = 'B';
    b[1] = 'M';
    le32(b + 2, (uint32_t)(off + datasz));
    le32(b + 10, (uint32_t)off);
    le32(b + 14, 40);
    le32(b + 18, (uint32_t)w);
    le32(b + 22, (uint32_t)h);
    le16(b + 26, 1);
    le16(b + 28, (unsigned)bpp);
    le32(b + 30, rle ? 1 : 0);
    le32(b + 34, (uint32_t)datasz);
    le32(b + 46, (uint32_t)npal);
    for (int i = 0; i < npal; i++) {
        unsigned g = (unsigned)(i * 255 / (npal - 1));
        b[54 + 4 * i] = b[55 + 4 * i] = b[56 + 4 * i] = (unsigned char)g;
    }
    unsigned char *d = b + off;
    for (int y = 0; y < ah; y++) {
        if (rle) {
            for (int x = 0; x < w; x++) {
                *d++ = 1;
                *d++ = (unsigned char)level(x, y, 0, 255);
            }
            *d++ = 0;
            *d++ = 0; /* end of line */
            continue;
        }
        unsigned char *r = d + (size_t)y * rowbytes;
        for (int x = 0; x < w; x++) {
            if (bpp == 24) {
                for (int c = 0; c < 3; c++)
                    r[3 * x + c] = (unsigned char)level(x, y, c, 255);
            } else {
                unsigned v = level(x, y, 0, (unsigned)npal - 1);
                size_t bit = (size_t)x * bpp;
                r[bit / 8] |= (unsigned char)(v << (8 - bpp - (int)(bit % 8)));
            }
        }
    }
    if (rle) {
        *d++ = 0;
        *d++ = 1; /* end of bitmap */
    }
    put("bmp_jpeg", name, b, off + datasz);
    free(b);
}

int main(int argc, char **argv)
{
    if (argc != 2)
        die("usage: gen_corpus CORPUS_DIR");
    top = argv[1];
    TIFFSetWarningHandler(NULL);
    const uint16_t MB = PHOTOMETRIC_MINISBLACK, U = SAMPLEFORMAT_UINT, C = PLANARCONFIG_CONTIG,
                   N = COMPRESSION_NONE;
    const tspec ts[] = {
        {"g8_strips.tif", "w", 13, 9, 8, 1, U, MB, C, N, 4, 0, 0, 0, 0},
        {"g8_be.tif", "wb", 11, 5, 8, 1, U, MB, C, N, 2, 0, 0, 0, 0},
        {"g16_be.tif", "wb", 9, 6, 16, 1, U, MB, C, N, 6, 0, 0, 0, 0},
        {"g16.tif", "w", 10, 7, 16, 1, U, MB, C, N, 3, 0, 0, 0, 0},
        {"f32.tif", "w", 8, 5, 32, 1, SAMPLEFORMAT_IEEEFP, MB, C, N, 5, 0, 0, 0, 0},
        {"g8_lzw.tif", "w", 16, 8, 8, 1, U, MB, C, COMPRESSION_LZW, 8, 0, 0, 0, 0},
        {"g8_deflate.tif", "w", 16, 8, 8, 1, U, MB, C, COMPRESSION_ADOBE_DEFLATE, 3, 0, 0, 0, 0},
        {"g8_packbits.tif", "w", 16, 8, 8, 1, U, MB, C, COMPRESSION_PACKBITS, 8, 0, 0, 0, 0},
        {"g16_tiled.tif", "w", 20, 18, 16, 1, U, MB, C, N, 0, 16, 0, 0, 0},
        {"rgb8_tiled_lzw.tif", "w", 17, 17, 8, 3, U, PHOTOMETRIC_RGB, C, COMPRESSION_LZW, 0, 16, 0,
         0, 0},
        {"pal8.tif", "w", 12, 6, 8, 1, U, PHOTOMETRIC_PALETTE, C, N, 6, 0, 0, 0, 0},
        {"pal4.tif", "w", 9, 4, 4, 1, U, PHOTOMETRIC_PALETTE, C, N, 4, 0, 0, 0, 0},
        {"rgb8.tif", "w", 7, 5, 8, 3, U, PHOTOMETRIC_RGB, C, N, 5, 0, 0, 0, 0},
        {"rgb16_planar.tif", "w", 6, 4, 16, 3, U, PHOTOMETRIC_RGB, PLANARCONFIG_SEPARATE, N, 2, 0,
         0, 0, 0},
        {"rgba8.tif", "w", 6, 3, 8, 4, U, PHOTOMETRIC_RGB, C, N, 3, 0, 0, 1, 0},
        {"ga8.tif", "w", 6, 3, 8, 2, U, MB, C, N, 3, 0, 0, 1, 0},
        {"gx8_unspecified.tif", "w", 6, 3, 8, 3, U, MB, C, N, 3, 0, 0, 2, 0},
        {"miniswhite8.tif", "w", 8, 4, 8, 1, U, PHOTOMETRIC_MINISWHITE, C, N, 4, 0, 0, 0, 0},
        {"bilevel.tif", "w", 19, 6, 1, 1, U, PHOTOMETRIC_MINISWHITE, C, N, 6, 0, 0, 0, 0},
        {"g2.tif", "w", 11, 3, 2, 1, U, MB, C, N, 3, 0, 0, 0, 0},
        {"g4_packbits.tif", "w", 13, 5, 4, 1, U, MB, C, COMPRESSION_PACKBITS, 2, 0, 0, 0, 0},
        {"multipage3.tif", "w", 8, 6, 8, 1, U, MB, C, N, 6, 0, 3, 0, 0},
        {"g12_unsupported.tif", "w", 4, 2, 12, 1, U, MB, C, N, 2, 0, 0, 0, 0},
        {"s16_unsupported.tif", "w", 4, 2, 16, 1, SAMPLEFORMAT_INT, MB, C, N, 2, 0, 0, 0, 0},
        {"u32_unsupported.tif", "w", 4, 2, 32, 1, U, MB, C, N, 2, 0, 0, 0, 0},
    };
    for (size_t i = 0; i < sizeof ts / sizeof *ts; i++)
        tiff(&ts[i]);
    variant("tiff", "g8_strips.tif", "g8_truncated.tif", 60, -1);
    variant("tiff", "g16_tiled.tif", "g16_tiled_truncated.tif", 700, -1);
    variant("tiff", "g8_lzw.tif", "g8_lzw_corrupt.tif", 0, 20);
    variant("tiff", "g8_deflate.tif", "g8_deflate_corrupt.tif", 0, 14);
    variant("tiff", "multipage3.tif", "multipage3_truncated.tif", 150, -1);

    const pspec ps[] = {
        {"g8.png", 9, 7, 8, PNG_COLOR_TYPE_GRAY, 0, 0, 0},
        {"g16.png", 6, 5, 16, PNG_COLOR_TYPE_GRAY, 0, 0, 0},
        {"g1.png", 13, 3, 1, PNG_COLOR_TYPE_GRAY, 0, 0, 0},
        {"g2.png", 7, 3, 2, PNG_COLOR_TYPE_GRAY, 0, 0, 0},
        {"g4_interlaced.png", 9, 9, 4, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_ADAM7, 0, 0},
        {"g8_interlaced.png", 11, 10, 8, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_ADAM7, 0, 0},
        {"pal8.png", 8, 4, 8, PNG_COLOR_TYPE_PALETTE, 0, 200, 0},
        {"pal2_trns.png", 8, 4, 2, PNG_COLOR_TYPE_PALETTE, 0, 4, 1},
        {"rgb8.png", 5, 4, 8, PNG_COLOR_TYPE_RGB, 0, 0, 0},
        {"rgba16.png", 4, 3, 16, PNG_COLOR_TYPE_RGB_ALPHA, 0, 0, 0},
        {"ga8.png", 5, 3, 8, PNG_COLOR_TYPE_GRAY_ALPHA, 0, 0, 0},
        {"ga16_interlaced.png", 6, 6, 16, PNG_COLOR_TYPE_GRAY_ALPHA, PNG_INTERLACE_ADAM7, 0, 0},
    };
    for (size_t i = 0; i < sizeof ps / sizeof *ps; i++)
        pngw(&ps[i]);
    variant("png", "g8.png", "g8_truncated.png", 50, -1);
    variant("png", "g16.png", "g16_no_iend.png", 0, -1);
    { /* drop the 12-byte IEND chunk */
        size_t n;
        unsigned char *b = slurp("png", "g16.png", &n);
        put("png", "g16_no_iend.png", b, n - 12);
        free(b);
    }
    variant("png", "g8.png", "g8_bad_crc_ihdr.png", 0, 30);
    { /* flip a byte of the IDAT CRC (the 4 bytes before IEND's 12) */
        size_t n;
        unsigned char *b = slurp("png", "rgb8.png", &n);
        b[n - 13] ^= 0x21;
        put("png", "rgb8_bad_crc_idat.png", b, n);
        free(b);
    }
    { /* palette image whose indices run past a 3-entry PLTE: rewrite PLTE length */
        pspec s = {"pal8_short_plte.png", 8, 4, 8, PNG_COLOR_TYPE_PALETTE, 0, 3, 0};
        pngw(&s);
    }
    pgm();
    bmp("pal8.bmp", 9, 5, 8, 0);
    bmp("pal8_topdown.bmp", 6, -4, 8, 0);
    bmp("pal4.bmp", 7, 3, 4, 0);
    bmp("pal1.bmp", 17, 3, 1, 0);
    bmp("rgb24.bmp", 5, 4, 24, 0);
    bmp("rle8.bmp", 6, 3, 8, 1);
    variant("bmp_jpeg", "pal8.bmp", "pal8_truncated.bmp", 1000, -1);
    variant("bmp_jpeg", "rgb24.bmp", "rgb24_truncated.bmp", 80, -1);
    return 0;
}
