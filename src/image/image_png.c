/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image/image_png.c - PNG through libpng: reading 1..16-bit grey, palette, grey+alpha and
 * RGB(A) (colour converted to luminance); writing 16-bit grey. libpng errors come back through
 * png_set_error_fn + setjmp; a bad CRC in any chunk is an error. */
#include "image_impl.h"

#include <errno.h>
#include <math.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

/* The largest ancillary chunk libpng may allocate (image data is read row by row, outside
 * this limit): text, a colour profile, a palette are far smaller. */
#define IMG_PNG_CHUNK_MAX (4u << 20)

/* The stdio buffer the file is read through. */
#define IMG_PNG_IOBUF ((size_t)1 << 18)

typedef struct pctx {
    const char *path;
    char msg[512];
    FILE *f;
    char *iobuf; /* f's stdio buffer */
    uint64_t fsize;
    png_structp png;
    png_infop info;
    unsigned char *data; /* raw rows: the whole image if interlaced, else one row */
    png_bytep *rows;     /* row pointers into data (interlaced) */
    rpiv_image *im;      /* the image, or its top half (split) */
    rpiv_image *im2;     /* the bottom half (split), or NULL */
    int split;           /* asked for the two halves */
    int warned;
    int bad_index; /* a palette index without a PLTE entry was seen */
    int no_plte;   /* a palette image without PLTE chunk */
    /* the layout of the rows libpng hands back, and the palette's luminance */
    int ctype, nchan, bps, colour;
    float lut[256];
} pctx;

static void on_error(png_structp png, png_const_charp m)
{
    pctx *c = png_get_error_ptr(png);
    snprintf(c->msg, sizeof c->msg, "%s", m);
    png_longjmp(png, 1);
}

static void on_warning(png_structp png, png_const_charp m)
{
    (void)png;
    (void)m; /* warnings (unknown chunks, gamma) are not errors; nothing is printed */
}

static rpiv_status pfail(const pctx *c)
{
    if (strstr(c->msg, "Read Error") || strstr(c->msg, "Not enough image data") ||
        strstr(c->msg, "too short") || strstr(c->msg, "truncated"))
        return rpiv_fail(RPIV_EFORMAT, "%s: truncated PNG (libpng: %s)", c->path, c->msg);
    if (strstr(c->msg, "CRC"))
        return rpiv_fail(RPIV_EFORMAT, "%s: corrupt PNG, bad CRC (libpng: %s)", c->path, c->msg);
    return rpiv_fail(RPIV_EFORMAT, "%s: bad PNG (libpng: %s)", c->path, c->msg);
}

/* One row of 16-bit grey samples (big-endian, nchan channels a pixel, the first one is
 * the grey level) as floats. The same values as the general loop in png_row, at vector
 * speed: the conversion was 155 M of the 1.2 G instructions of reading a 2560x4320 16-bit
 * PNG (issue 15). */
static void row_grey16(const unsigned char *s, float *d, size_t w, int nchan)
{
    size_t x = 0;
#ifdef __SSE2__
    if (nchan == 1) {
        const __m128i z = _mm_setzero_si128();
        for (; x + 8 <= w; x += 8) {
            __m128i v = _mm_loadu_si128((const __m128i *)(const void *)(s + 2 * x));
            v = _mm_or_si128(_mm_slli_epi16(v, 8), _mm_srli_epi16(v, 8)); /* to host order */
            _mm_storeu_ps(d + x, _mm_cvtepi32_ps(_mm_unpacklo_epi16(v, z)));
            _mm_storeu_ps(d + x + 4, _mm_cvtepi32_ps(_mm_unpackhi_epi16(v, z)));
        }
    }
#endif
    const size_t step = 2 * (size_t)nchan;
    for (; x < w; x++)
        d[x] = (float)((unsigned)s[x * step] << 8 | s[x * step + 1]);
}

/* Raw row r (as libpng returns it after its transforms) to the floats d[0..w-1]. A palette
 * index without a PLTE entry sets c->bad_index: png_decode reports it after the whole file
 * is read, so a later CRC error or truncation still comes first, as when the rows were
 * converted after the read. */
static void png_row(pctx *c, const unsigned char *r, float *d, png_uint_32 w)
{
    const size_t bps = (size_t)c->bps, nchan = (size_t)c->nchan;
    if (!c->colour && c->ctype != PNG_COLOR_TYPE_PALETTE) {
        if (bps == 2)
            row_grey16(r, d, w, c->nchan);
        else
            for (png_uint_32 x = 0; x < w; x++)
                d[x] = (float)r[(size_t)x * nchan];
        return;
    }
    for (png_uint_32 x = 0; x < w; x++) {
        double v[3];
        for (size_t ch = 0; ch < (c->colour ? 3u : 1u); ch++) {
            const unsigned char *s = r + ((size_t)x * nchan + ch) * bps;
            v[ch] = bps == 2 ? (double)((s[0] << 8) | s[1]) : (double)s[0];
        }
        if (c->colour) {
            d[x] = img_luma(v[0], v[1], v[2]);
        } else {
            d[x] = c->lut[(int)v[0]];
            if (isnan(d[x]))
                c->bad_index = 1;
        }
    }
}

/* Everything that calls libpng after setjmp lives here, with its state in *c (not in locals
 * of this function), so nothing is indeterminate after a longjmp. Returns 0 on success, -1
 * after a libpng error (c->msg set), or a positive rpiv_status for our own failures. */
static int png_decode(pctx *c)
{
    if (setjmp(png_jmpbuf(c->png)))
        return -1;
    png_init_io(c->png, c->f);
    /* Issue 20 item 4: a tEXt chunk declaring 0x7ffffff0 bytes in a 4 KB file made libpng
     * 1.6 allocate (and touch) 2 GB: its text handlers allocate the declared length without
     * looking at the chunk_malloc_max limit. The reader needs no ancillary chunk (only IHDR,
     * PLTE, IDAT: no gamma, no transparency, no text), so every one of them is discarded
     * unread (skipped through a small buffer, its CRC still checked) and never allocated.
     * The limits are set too, for whatever libpng still allocates per chunk. */
    static const png_byte ancillary[] = "bKGD\0cHRM\0eXIf\0gAMA\0hIST\0iCCP\0iTXt\0oFFs\0pCAL\0"
                                        "pHYs\0sBIT\0sCAL\0sPLT\0sRGB\0tEXt\0tIME\0tRNS\0zTXt";
    png_set_keep_unknown_chunks(c->png, PNG_HANDLE_CHUNK_NEVER, NULL, 0);
    png_set_keep_unknown_chunks(c->png, PNG_HANDLE_CHUNK_NEVER, ancillary,
                                (int)(sizeof ancillary / 5));
    png_set_chunk_malloc_max(c->png, IMG_PNG_CHUNK_MAX);
    png_set_chunk_cache_max(c->png, 1000);
    png_set_user_limits(c->png, 1000000, 1000000);
    /* A CRC error in a critical or ancillary chunk stops the read (libpng only warns about
     * ancillary ones by default). */
    png_set_crc_action(c->png, PNG_CRC_ERROR_QUIT, PNG_CRC_ERROR_QUIT);
    png_read_info(c->png, c->info);
    png_uint_32 w, h;
    int depth, interlace;
    png_get_IHDR(c->png, c->info, &w, &h, &depth, &c->ctype, &interlace, NULL, NULL);
    int bits = c->ctype == PNG_COLOR_TYPE_PALETTE ? 8 : depth;
    rpiv_status st = img_check_size(c->path, w, h);
    if (st)
        return (int)st;
    /* Deflate expands at most 1032:1, so a header whose filtered rows cannot come out of the
     * file is refused before the image is allocated. */
    uint64_t raw = ((uint64_t)w * png_get_channels(c->png, c->info) * (uint64_t)depth + 7) / 8;
    raw = (raw + 1) * h;
    if (raw > 1032 * c->fsize + 65536)
        return (int)rpiv_fail(RPIV_EFORMAT,
                              "%s: truncated or corrupt PNG: %ux%u pixels (%llu bytes of rows) "
                              "cannot be inflated from a %llu-byte file",
                              c->path, (unsigned)w, (unsigned)h, (unsigned long long)raw,
                              (unsigned long long)c->fsize);
    /* Every pixel is written below (or the read fails), so the pixels need no zeroing. The
     * limit applies to the whole file's image, split or not. */
    int halves = c->split && h % 2 == 0;
    png_uint_32 h0 = halves ? h / 2 : h;
    if ((st = img_check_limit(c->path, w, h)) ||
        (st = img_alloc_ex(c->path, w, h0, bits, 0, &c->im)) ||
        (halves && (st = img_alloc_ex(c->path, w, h0, bits, 0, &c->im2))))
        return (int)st;
    img_populate(c->im, c->fsize);
    img_populate(c->im2, c->fsize);
    if (depth < 8)
        png_set_packing(c->png); /* one index or grey level per byte, not rescaled */
    int passes = png_set_interlace_handling(c->png);
    png_read_update_info(c->png, c->info);
    size_t rowbytes = png_get_rowbytes(c->png, c->info);
    c->nchan = png_get_channels(c->png, c->info);
    c->bps = depth == 16 ? 2 : 1;
    c->colour = (c->ctype & PNG_COLOR_MASK_COLOR) && c->ctype != PNG_COLOR_TYPE_PALETTE;
    if (rowbytes < (size_t)w * (size_t)c->nchan * (size_t)c->bps)
        png_error(c->png, "unexpected row size");
    if (c->ctype == PNG_COLOR_TYPE_PALETTE) {
        png_colorp pal = NULL;
        int npal = 0;
        c->no_plte = !png_get_PLTE(c->png, c->info, &pal, &npal); /* reported after the read */
        for (int i = 0; i < 256; i++)
            c->lut[i] = i < npal ? img_luma(pal[i].red, pal[i].green, pal[i].blue) : NAN;
    }
    /* A non-interlaced image is read a row at a time into one row buffer and converted at
     * once (no copy of the whole raw image: 22 MB less to allocate and touch for a
     * 2560x4320 16-bit file); an interlaced one needs all its rows before any is complete. */
    size_t nbuf = passes > 1 ? h : 1;
    c->data = malloc(rowbytes * nbuf);
    c->rows = malloc(nbuf * sizeof *c->rows);
    if (!c->data || !c->rows)
        return (int)rpiv_fail(RPIV_ENOMEM, "%s: out of memory for %ux%u PNG rows", c->path,
                              (unsigned)w, (unsigned)h);
    for (size_t y = 0; y < nbuf; y++)
        c->rows[y] = c->data + y * rowbytes;
    if (passes > 1)
        png_read_image(c->png, c->rows);
    for (png_uint_32 y = 0; y < h; y++) {
        const unsigned char *r = passes > 1 ? c->rows[y] : c->data;
        if (passes <= 1)
            png_read_row(c->png, c->data, NULL);
        float *d = y < h0 ? c->im->px + (size_t)y * w : c->im2->px + (size_t)(y - h0) * w;
        png_row(c, r, d, w);
    }
    png_read_end(c->png, NULL); /* checks the CRC of the last IDAT and of later chunks */
    if (c->no_plte)
        png_error(c->png, "palette image without PLTE chunk");
    if (c->bad_index)
        png_error(c->png, "palette index beyond the PLTE entries");
    c->warned = c->colour;
    return 0;
}

rpiv_status img_png_load(const char *path, rpiv_image **out, rpiv_image **b, int *warned)
{
    pctx c;
    memset(&c, 0, sizeof c);
    c.path = path;
    c.split = b != NULL;
    *out = NULL;
    if (b)
        *b = NULL;
    c.f = fopen(path, "rb");
    if (!c.f)
        return rpiv_fail(RPIV_EIO, "%s: cannot open: %s", path, strerror(errno));
    /* libpng reads through stdio: with its 4 kB buffer a 17 MB file took 4262 read() calls
     * (if this buffer cannot be had, stdio keeps its own) */
    c.iobuf = malloc(IMG_PNG_IOBUF);
    if (c.iobuf)
        (void)setvbuf(c.f, c.iobuf, _IOFBF, IMG_PNG_IOBUF);
    struct stat sb;
    c.fsize = fstat(fileno(c.f), &sb) == 0 ? (uint64_t)sb.st_size : 0;
    rpiv_status st = RPIV_OK;
    c.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &c, on_error, on_warning);
    if (c.png)
        c.info = png_create_info_struct(c.png);
    if (!c.png || !c.info) {
        st = rpiv_fail(RPIV_ENOMEM, "%s: cannot create the PNG reader", path);
        goto out_free;
    }
    int r = png_decode(&c);
    if (r < 0)
        st = pfail(&c);
    else
        st = (rpiv_status)r;
out_free:
    png_destroy_read_struct(&c.png, &c.info, NULL);
    fclose(c.f);
    free(c.iobuf);
    free(c.data);
    free(c.rows);
    if (st) {
        rpiv_image_free(c.im);
        rpiv_image_free(c.im2);
        return st;
    }
    *out = c.im;
    if (b)
        *b = c.im2;
    *warned = c.warned;
    return RPIV_OK;
}

/* ---- writing --------------------------------------------------------------------------- */

typedef struct wctx {
    char msg[512];
    const rpiv_image *im;
    FILE *f;
    png_structp png;
    png_infop info;
    unsigned char *row;
} wctx;

static void on_werror(png_structp png, png_const_charp m)
{
    wctx *c = png_get_error_ptr(png);
    snprintf(c->msg, sizeof c->msg, "%s", m);
    png_longjmp(png, 1);
}

static int png_encode(wctx *c)
{
    if (setjmp(png_jmpbuf(c->png)))
        return -1;
    const rpiv_image *im = c->im;
    png_init_io(c->png, c->f);
    png_set_IHDR(c->png, c->info, (png_uint_32)im->w, (png_uint_32)im->h, 16, PNG_COLOR_TYPE_GRAY,
                 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    /* Fast settings: zlib level 1 with the Sub filter wrote a 1720x2304 camera image in
     * 0.19-0.21 s against 1.7-1.9 s with libpng's defaults, 9% larger (docs/images.md). */
    png_set_compression_level(c->png, 1);
    png_set_filter(c->png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB);
    png_write_info(c->png, c->info);
    for (int y = 0; y < im->h; y++) {
        const float *s = im->px + (size_t)y * im->w;
        for (int x = 0; x < im->w; x++) {
            float v = s[x];
            unsigned q = !(v > 0.0f) ? 0u : v >= 65535.0f ? 65535u : (unsigned)floorf(v + 0.5f);
            c->row[2 * x] = (unsigned char)(q >> 8);
            c->row[2 * x + 1] = (unsigned char)(q & 0xff);
        }
        png_write_row(c->png, c->row);
    }
    png_write_end(c->png, NULL);
    return 0;
}

rpiv_status rpiv_image_save_png16(const rpiv_image *im, const char *path)
{
    atomic_file af;
    wctx c;
    memset(&c, 0, sizeof c);
    c.im = im;
    rpiv_status st = atomic_begin(&af, path, 1);
    if (st)
        return st;
    c.f = af.fp;
    c.row = malloc((size_t)im->w * 2);
    c.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &c, on_werror, on_warning);
    if (c.png)
        c.info = png_create_info_struct(c.png);
    if (!c.row || !c.png || !c.info)
        st = rpiv_fail(RPIV_ENOMEM, "%s: cannot create the PNG writer", path);
    else if (png_encode(&c) < 0)
        st = rpiv_fail(RPIV_EIO, "%s: cannot write PNG: %s", path, c.msg);
    png_destroy_write_struct(&c.png, &c.info);
    free(c.row);
    if (st) {
        atomic_abort(&af);
        return st;
    }
    return atomic_commit(&af); /* flush, fsync, rename, fsync of the folder */
}
