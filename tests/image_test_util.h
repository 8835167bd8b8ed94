/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/image_test_util.h - helpers shared by the image tests: a temporary folder, small file
 * writers, and a libtiff writer for test images in any layout. */
#ifndef RPIV_TESTS_IMAGE_TEST_UTIL_H
#define RPIV_TESTS_IMAGE_TEST_UTIL_H

#include "check.h"
#include "rpiv/image.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <tiffio.h>
#include <unistd.h>

static char tu_dir[256];

/* Make a fresh temporary folder for this test program. */
static inline int tu_init(const char *name)
{
    snprintf(tu_dir, sizeof tu_dir, "/tmp/rpiv_%s_XXXXXX", name);
    if (!mkdtemp(tu_dir)) {
        perror("mkdtemp");
        return 0;
    }
    return 1;
}

static inline void tu_cleanup(void)
{
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tu_dir);
    if (system(cmd) != 0)
        fprintf(stderr, "cannot remove %s\n", tu_dir);
}

/* tu_path(name): tu_dir/name in one of 8 rotating static buffers. */
static inline const char *tu_path(const char *name)
{
    static char buf[8][512];
    static int k;
    k = (k + 1) % 8;
    snprintf(buf[k], sizeof buf[k], "%s/%s", tu_dir, name);
    return buf[k];
}

static inline int tu_write(const char *path, const void *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    if (!f)
        return 0;
    size_t w = fwrite(data, 1, n, f);
    return fclose(f) == 0 && w == n;
}

/* Whole file into a malloc'd buffer (NULL on failure). */
static inline unsigned char *tu_read(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    rewind(f);
    unsigned char *b = malloc(len > 0 ? (size_t)len : 1);
    *n = b ? fread(b, 1, (size_t)len, f) : 0;
    fclose(f);
    return b;
}

/* Copy the first n bytes of src to dst. */
static inline int tu_cut(const char *src, const char *dst, size_t n)
{
    size_t len;
    unsigned char *b = tu_read(src, &len);
    int ok = b && n <= len && tu_write(dst, b, n);
    free(b);
    return ok;
}

/* Check a failed call: the status and that the message names the file. */
#define CHECK_ERR(call, code, name)                                                                \
    do {                                                                                           \
        CHECK_FAILS(call, code);                                                                   \
        CHECK(strstr(rpiv_errmsg(), (name)) != NULL);                                              \
        printf("    (%s)\n", rpiv_errmsg());                                                       \
    } while (0)

/* ---- a libtiff writer for test images ------------------------------------------------- */

typedef struct tu_tiff {
    uint32_t w, h;
    uint16_t bps, spp, sf, photo, planar, nextra;
    uint32_t rps;         /* rows per strip (0: libtiff default) */
    uint32_t tile;        /* tile side (multiple of 16) or 0 for strips */
    const uint16_t *cmap; /* 3 * 2^bps entries for palette images */
    uint16_t compression;
} tu_tiff;

/* Write one page. data: contig rows of ceil(w*spp*bps/8) bytes, or for separate planes spp
 * planes of h rows of ceil(w*bps/8) bytes. Tiles need bps >= 8. Returns 1 on success. */
static inline int tu_tiff_page(TIFF *t, const tu_tiff *o, const void *data)
{
    const unsigned char *d = data;
    int separate = o->planar == PLANARCONFIG_SEPARATE;
    uint32_t nsp = separate ? 1 : o->spp;
    size_t rowbytes = ((size_t)o->w * nsp * o->bps + 7) / 8;
    TIFFSetField(t, TIFFTAG_IMAGEWIDTH, o->w);
    TIFFSetField(t, TIFFTAG_IMAGELENGTH, o->h);
    TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, o->bps);
    TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, o->spp);
    TIFFSetField(t, TIFFTAG_SAMPLEFORMAT, o->sf ? o->sf : SAMPLEFORMAT_UINT);
    TIFFSetField(t, TIFFTAG_PHOTOMETRIC, o->photo);
    TIFFSetField(t, TIFFTAG_PLANARCONFIG, o->planar ? o->planar : PLANARCONFIG_CONTIG);
    TIFFSetField(t, TIFFTAG_COMPRESSION, o->compression ? o->compression : COMPRESSION_NONE);
    if (o->nextra) {
        uint16_t ex[4] = {EXTRASAMPLE_UNASSALPHA, 0, 0, 0};
        TIFFSetField(t, TIFFTAG_EXTRASAMPLES, o->nextra, ex);
    }
    if (o->cmap) {
        size_t n = (size_t)1 << o->bps;
        TIFFSetField(t, TIFFTAG_COLORMAP, o->cmap, o->cmap + n, o->cmap + 2 * n);
    }
    int nplanes = separate ? o->spp : 1;
    if (o->tile) {
        TIFFSetField(t, TIFFTAG_TILEWIDTH, o->tile);
        TIFFSetField(t, TIFFTAG_TILELENGTH, o->tile);
        size_t bpp = nsp * o->bps / 8, tsize = (size_t)o->tile * o->tile * bpp;
        unsigned char *tb = malloc(tsize);
        if (!tb)
            return 0;
        for (int p = 0; p < nplanes; p++)
            for (uint32_t y0 = 0; y0 < o->h; y0 += o->tile)
                for (uint32_t x0 = 0; x0 < o->w; x0 += o->tile) {
                    memset(tb, 0xAB, tsize); /* padding outside the image: garbage */
                    for (uint32_t r = 0; r < o->tile && y0 + r < o->h; r++)
                        for (uint32_t c = 0; c < o->tile && x0 + c < o->w; c++)
                            memcpy(tb + ((size_t)r * o->tile + c) * bpp,
                                   d + (size_t)p * o->h * rowbytes + (size_t)(y0 + r) * rowbytes +
                                       (size_t)(x0 + c) * bpp,
                                   bpp);
                    if (TIFFWriteTile(t, tb, x0, y0, 0, (uint16_t)p) < 0) {
                        free(tb);
                        return 0;
                    }
                }
        free(tb);
    } else {
        TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, o->rps ? o->rps : TIFFDefaultStripSize(t, 0));
        for (int p = 0; p < nplanes; p++)
            for (uint32_t y = 0; y < o->h; y++)
                if (TIFFWriteScanline(t, (void *)(d + ((size_t)p * o->h + y) * rowbytes), y,
                                      (uint16_t)p) < 0)
                    return 0;
    }
    return TIFFWriteDirectory(t);
}

static inline int tu_tiff_write(const char *path, const tu_tiff *o, const void *data)
{
    TIFF *t = TIFFOpen(path, "w");
    if (!t)
        return 0;
    int ok = tu_tiff_page(t, o, data);
    TIFFClose(t);
    return ok;
}

#endif /* RPIV_TESTS_IMAGE_TEST_UTIL_H */
