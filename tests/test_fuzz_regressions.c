/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Regression tests for the inputs the fuzzers found (docs/fuzzing.md): every file of
 * tests/data/fuzz-regressions/ is listed below with the call that once misbehaved on it and
 * the clean outcome expected now (status and a word of the message, which must also name the
 * file). A file in the folder without an entry fails the test, so each new crash gets its
 * expectation written down. The loaded results are also checked as the fuzzers check them:
 * sane sizes, finite values, nothing returned on failure. */
#include "check.h"
#include "child_rss.h"

#include "rpiv/config.h"
#include "rpiv/field.h"
#include "rpiv/image.h"
#include "rpiv/sheet.h"

#include <dirent.h>
#include <math.h>
#include <png.h>
#include <setjmp.h>
#include <stdint.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

typedef enum kind {
    IMAGE,   /* rpiv_image_load(file, page) */
    PAGES,   /* rpiv_image_count_pages(file) == page (status RPIV_OK) */
    VECTORS, /* rpiv_field_load_txt */
    PROFILE, /* rpiv_profile_load */
    SHEET,   /* rpiv_sheet_new with the file as a self-similar sheet's profile */
    CONFIG   /* rpiv_config_load */
} kind;

typedef struct expect {
    const char *file;
    kind k;
    int page;
    rpiv_status status;
    const char *word; /* in the message on failure */
} expect;

static const expect table[] = {
    /* libtiff opens the directory of a page whose link to the next directory is cut, while
     * TIFFNumberOfDirectories does not count it: page 1 loaded although the file "has" 1 */
    {"tiff_page_past_cut_ifd_link.tif", PAGES, 1, RPIV_OK, NULL},
    {"tiff_page_past_cut_ifd_link.tif", IMAGE, 0, RPIV_OK, NULL},
    {"tiff_page_past_cut_ifd_link.tif", IMAGE, 1, RPIV_EINVAL, "has 1 page"},
    /* a 32-bit float TIFF with a NaN sample loaded as is */
    {"tiff_float_nan.tif", IMAGE, 0, RPIV_EFORMAT, "NaN"},
    /* 52 bytes announcing 327689 x 2057 pixels: 2.7 GB reserved before reading any row */
    {"png_rows_beyond_file.png", IMAGE, 0, RPIV_EFORMAT, "cannot be inflated"},
    /* 56-byte 24-bit BMP with compression code 0x9b9b9b6d: decoded by stb_image as
     * uncompressed 33 x 4194564 pixels, zeros past the end (2.5 s, 1 GB) */
    {"bmp_unknown_compression.bmp", IMAGE, 0, RPIV_EFORMAT, "compression"},
    /* an 8-bit BMP whose pixels index past its 248-colour palette: stb_image read palette
     * entries it never set, a different image at each load (fuzz_bmp_jpeg, session 8) */
    {"bmp_index_beyond_palette.bmp", IMAGE, 0, RPIV_EFORMAT, "palette index"},
    /* 365-byte JPEG whose frame header announces 30000 x 30000: stb_image decoded the short
     * scan and 900 Mpx of zeros (63 s, 4.4 GB) and the load succeeded */
    {"jpeg_scan_shorter_than_image.jpg", IMAGE, 0, RPIV_EFORMAT, "cannot be coded"},
    /* a progressive scan whose AC Huffman table no DHT defined: stb_image decoded it from
     * uninitialised memory (nothings/stb#1535) and crashed (SEGV under ASan, found by the
     * 30-s make fuzz run) */
    {"jpeg_undefined_huffman_table.jpg", IMAGE, 0, RPIV_EFORMAT, "corrupt"}, /* libjpeg now */
    /* the 7 x 5 seed with its component pointed at quantisation table 1, never defined: the
     * image "loaded" with levels computed from uninitialised memory (valgrind) */
    {"jpeg_undefined_quant_table.jpg", IMAGE, 0, RPIV_EFORMAT, "table"}, /* libjpeg now */
    /* the size check must keep real files that compress well: a uniform 800 x 600 grey
     * JPEG (cjpeg -optimize, 2 bits per block, 1 byte per 256 pixels) loads */
    {"jpeg_uniform_800x600_loads.jpg", IMAGE, 0, RPIV_OK, NULL},
    /* a corrupt Huffman code: Debian's stb_image is built with assertions and aborted the
     * process (fuzz_bmp_jpeg, 455 000 runs); JPEG is now read with libjpeg */
    {"jpeg_huffman_assert.jpg", IMAGE, 0, RPIV_EFORMAT, "JPEG"},
    /* a TIFF header announcing 1.7 Gpx with a codec libtiff lacks: 7 GB reserved (fuzz_image,
     * out of memory); refused for its codec before allocating (and, were the codec known, by
     * the configurable pixel limit RPIV_MAX_IMAGE_PIXELS) */
    {"tiff_header_7gb.tif", IMAGE, 0, RPIV_EFORMAT, "compression"},
    /* the TIFF size check (4096:1 for compressed data) refused a valid ZSTD TIFF: a uniform
     * 2000 x 2000 image (a mask, a background) packs into 260 bytes */
    {"tiff_zstd_uniform_loads.tif", IMAGE, 0, RPIV_OK, NULL},
    /* compression code 65 (no codec) on a 32774 x 61441 16-bit header: the 8 GB image was
     * reserved before libtiff said it cannot decode (found by fuzz_image, OOM; the size
     * bound above no longer covered codes outside its list) */
    {"tiff_unknown_compression.tif", IMAGE, 0, RPIV_EFORMAT, "compression 65 not supported"},
    /* and a ZSTD header announcing 30000 x 30000 in 260 bytes (the bound for codecs outside
     * that list, 65536:1) */
    {"tiff_zstd_header_beyond_file.tif", IMAGE, 0, RPIV_EFORMAT, "cannot be stored"},
    /* 260 bytes of CCITT RLE for a 30000 x 30000 1-bit image: libtiff's fax decoder only
     * warned ("Premature EOL") and filled the rows, and 900 Mpx of blank "loaded" (9 s,
     * 3.6 GB; a timeout in fuzz_tiff) */
    {"tiff_fax_rows_cut_short.tif", IMAGE, 0, RPIV_EFORMAT, "30000 fax-coded rows"},
    /* a valid 800 x 600 CCITT RLE file whose strip byte count was halved (written by hand):
     * only warnings from libtiff, blank rows after line 271 */
    {"tiff_fax_strip_count_halved.tif", IMAGE, 0, RPIV_EFORMAT, "strip 1 of 1, rows 0-599"},
    /* a 1 x 5 float image with tiles 469762064 pixels wide: the 9.4 GB tile buffer was
     * allocated (fuzz_tiff, allocation above the readers' cap) */
    {"tiff_tile_wider_than_image.tif", IMAGE, 0, RPIV_EFORMAT, "tiles of 9395241280 bytes"},
    /* and a valid G4 mask (4000 x 3000, 632 bytes, 19000:1) still loads */
    {"tiff_g4_mask_4000x3000_loads.tif", IMAGE, 0, RPIV_OK, NULL},
    /* u = 3e39 does not fit the field's float: it became +inf in a field that loaded */
    {"vectors_u_beyond_float.txt", VECTORS, 0, RPIV_EFORMAT, ":1: column 3"},
    /* header "# scale_mm_per_px = 0.0065e9999" (infinite): the field loaded with an infinite
     * scale, and its mm and m/s columns came out infinite when saved; then it was ignored
     * (the field left unscaled), and a finite 6.5e87 mm/px wrote coordinates of 4e89 mm that
     * no float reads back (fuzz_vectors, session 6): now a scale outside the [piv] key's
     * (0, 1e6] or a dt outside [1e-12, 1e6] s is refused, naming the line */
    {"vectors_scale_overflows.txt", VECTORS, 0, RPIV_EFORMAT, ":2: scale_mm_per_px = inf"},
    {"vectors_scale_beyond_float.txt", VECTORS, 0, RPIV_EFORMAT, ":12: scale_mm_per_px = 6.5e+87"},
    /* in range, but 3e35 px at 1000 mm/px and 1 us is 3e41 m/s: refused as well */
    {"vectors_velocity_beyond_float_in_m_s.txt", VECTORS, 0, RPIV_EFORMAT, "beyond a float"},
    /* the fuzzer's file: header "# zm1 1e3086" (infinite) loaded and I0 evaluated to NaN;
     * its line 5 holds NUL bytes, refused first since lines with a NUL are */
    {"sheet_header_not_finite.sheet", SHEET, 0, RPIV_EFORMAT, ":5: NUL byte"},
    /* the same header finding in a clean text file (written by hand) */
    {"sheet_header_inf.sheet", SHEET, 0, RPIV_EFORMAT, ":5: zm1 is inf"},
    /* rows -1e308 and 1.7e308: their step overflows and I0 evaluated to NaN (written by hand
     * after the fuzzer's header finding; the fuzzer did not reach it in 10 s) */
    {"sheet_zplus_step_overflows.sheet", SHEET, 0, RPIV_EFORMAT, ":7: zplus"},
};
#define NTABLE (sizeof table / sizeof *table)

static char dir[1024];

static void path_of(const char *file, char *out, size_t cap)
{
    snprintf(out, cap, "%s/%s", dir, file);
}

static int image_ok(const rpiv_image *im)
{
    if (!im || !im->px || im->w < 1 || im->h < 1)
        return 0;
    double top = im->bits <= 16 ? ldexp(1.0, im->bits) - 1.0 : 3.4e38;
    for (size_t i = 0; i < (size_t)im->w * (size_t)im->h; i++) {
        double v = (double)im->px[i];
        if (!isfinite(v) || (im->bits <= 16 && (v < 0 || v > top * (1 + 1e-6))))
            return 0;
    }
    return 1;
}

static int field_ok(const rpiv_field *f)
{
    if (f->nx < 1 || f->ny < 1 || !(f->dx > 0) || !(f->dy > 0) || !isfinite(f->dx) ||
        !isfinite(f->dy) || !isfinite(f->x0) || !isfinite(f->y0) || !isfinite(f->scale_mm_per_px) ||
        !isfinite(f->dt_s))
        return 0;
    for (size_t k = 0; k < (size_t)f->nx * (size_t)f->ny; k++)
        if (!isfinite(f->u[k]) || !isfinite(f->v[k]))
            return 0;
    return 1;
}

/* Run the call of e; returns its status; *sane = 0 if a success gave a broken result or a
 * failure left a result behind. */
static rpiv_status run(const expect *e, const char *path, int *sane)
{
    rpiv_status st;
    *sane = 1;
    switch (e->k) {
    case IMAGE: {
        rpiv_image *im = NULL;
        st = rpiv_image_load(path, e->page, &im, NULL);
        *sane = st == RPIV_OK ? image_ok(im) : im == NULL;
        rpiv_image_free(im);
        return st;
    }
    case PAGES: {
        int n = -1;
        st = rpiv_image_count_pages(path, &n);
        if (st == RPIV_OK && n != e->page) {
            fprintf(stderr, "%s: %d pages, expected %d\n", path, n, e->page);
            *sane = 0;
        }
        return st;
    }
    case VECTORS: {
        rpiv_field *f = NULL;
        st = rpiv_field_load_txt(path, &f);
        *sane = st == RPIV_OK ? field_ok(f) : f == NULL;
        rpiv_field_free(f);
        return st;
    }
    case PROFILE: {
        rpiv_profile *p = NULL;
        st = rpiv_profile_load(path, &p);
        if (st == RPIV_OK) {
            *sane = p->n >= 2;
            for (size_t i = 0; i < p->n; i++)
                if (!isfinite(p->alpha[i]) || !isfinite(p->value[i]) ||
                    (i && !(p->alpha[i] > p->alpha[i - 1])))
                    *sane = 0;
        } else {
            *sane = p == NULL;
        }
        rpiv_profile_free(p);
        return st;
    }
    case SHEET: {
        rpiv_sheet_params sp = rpiv_sheet_params_default();
        rpiv_sheet *s = NULL;
        sp.kind = RPIV_SHEET_SELFSIM;
        size_t n = strlen(path);
        if (n >= sizeof sp.profile)
            return RPIV_EINVAL;
        memcpy(sp.profile, path, n + 1);
        st = rpiv_sheet_new(&sp, &s);
        if (st == RPIV_OK) {
            for (int i = 0; i <= 10; i++)
                for (int k = 0; k <= 64; k++) {
                    double v = rpiv_sheet_eval(s, i, k / 64.0);
                    if (!isfinite(v) || v < 0 || v > 1.0001)
                        *sane = 0;
                }
        } else {
            *sane = s == NULL;
        }
        rpiv_sheet_free(s);
        return st;
    }
    case CONFIG: {
        rpiv_experiment ex = rpiv_experiment_default();
        st = rpiv_config_load(path, &ex);
        if (st == RPIV_OK)
            *sane = rpiv_experiment_check(&ex) == RPIV_OK;
        return st;
    }
    }
    return RPIV_EINVAL;
}

static void every_file_has_an_expectation(void)
{
    DIR *d = opendir(dir);
    CHECK(d != NULL);
    if (!d)
        return;
    struct dirent *de;
    int nfiles = 0;
    while ((de = readdir(d)) != NULL) {
        if (de->d_name[0] == '.')
            continue;
        nfiles++;
        int listed = 0;
        for (size_t i = 0; i < NTABLE; i++)
            listed |= strcmp(table[i].file, de->d_name) == 0;
        if (!listed)
            fprintf(stderr, "%s/%s: no expectation in test_fuzz_regressions.c\n", dir, de->d_name);
        CHECK(listed);
    }
    closedir(d);
    CHECK(nfiles > 0);
}

static void each_regression_ends_cleanly(void)
{
    for (size_t i = 0; i < NTABLE; i++) {
        const expect *e = &table[i];
        char path[1300];
        int sane;
        path_of(e->file, path, sizeof path);
        rpiv_status st = run(e, path, &sane);
        const char *m = rpiv_errmsg();
        if (st != e->status || !sane)
            fprintf(stderr, "%s (call %d, page %d): status %d (expected %d), sane %d: %s\n",
                    e->file, (int)e->k, e->page, (int)st, (int)e->status, sane, st ? m : "");
        CHECK(st == e->status);
        CHECK(sane);
        if (st != RPIV_OK) {
            int named = strstr(m, path) != NULL, worded = e->word && strstr(m, e->word);
            if (!named || !worded)
                fprintf(stderr, "%s: message lacks the path or '%s': %s\n", e->file,
                        e->word ? e->word : "(none)", m);
            CHECK(named);
            CHECK(worded);
        }
    }
}

/* The PNG size check (Deflate expands at most 1032:1) must not refuse a real file that
 * compresses as well as Deflate can: a uniform 1500 x 1100 8-bit grey PNG written at zlib
 * level 9 (about 1000:1) still loads. */
static void png_size_check_keeps_highly_compressed_images(void)
{
    const char *path = "fuzz_regressions_uniform.png";
    const int w = 1500, h = 1100;
    FILE *f = fopen(path, "wb");
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    unsigned char *row = calloc((size_t)w, 1);
    CHECK(f && png && info && row);
    if (f && png && info && row && !setjmp(png_jmpbuf(png))) {
        png_init_io(png, f);
        png_set_compression_level(png, 9);
        png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, 8, PNG_COLOR_TYPE_GRAY,
                     PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
        png_write_info(png, info);
        for (int y = 0; y < h; y++)
            png_write_row(png, row);
        png_write_end(png, NULL);
    }
    png_destroy_write_struct(&png, &info);
    free(row);
    long size = -1;
    if (f) {
        fflush(f);
        size = ftell(f);
        fclose(f);
    }
    double ratio = (double)h * (1 + w) / (double)size;
    printf("uniform %dx%d 8-bit PNG at zlib level 9: %ld bytes, %.0f:1\n", w, h, size, ratio);
    CHECK(size > 0 && ratio > 900); /* close to the bound: a real test of it */
    rpiv_image *im = NULL;
    CHECK_OK(rpiv_image_load(path, 0, &im, NULL));
    if (im)
        CHECK(im->w == w && im->h == h && im->px[0] == 0.0f && im->px[(size_t)w * h - 1] == 0.0f);
    rpiv_image_free(im);
    remove(path);
}

static int load_one(void *path)
{
    rpiv_image *im = NULL;
    rpiv_status s = rpiv_image_load(path, 0, &im, NULL);
    rpiv_image_free(im);
    return (int)s;
}

/* Peak RSS (KB) of a child process that loads path, and its status. */
static long child_load_rss_kb(const char *path, rpiv_status *st)
{
    int code = 0;
    long kb = ti_child_rss_kb(load_one, (void *)path, &code);
    *st = (rpiv_status)code;
    return kb;
}

/* Issue 20 item 4: a 4 KB PNG whose tEXt chunk declares 0x7ffffff0 bytes made libpng
 * allocate and touch 2 GB (peak RSS 2.1 GB) before the read ran out of file. Any file under
 * 1 MB must load or fail within 100 MB of peak RSS over the process's own. */
static void huge_chunk_declarations_stay_small(void)
{
    static const unsigned char head[] = {
        0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d,
        0x49, 0x48, 0x44, 0x52, 0x00, 0x00, 0x00, 0x08, 0x00, 0x00, 0x00, 0x08,
        0x08, 0x00, 0x00, 0x00, 0x00, 0xe1, 0x64, 0xe1, 0x57, /* signature, IHDR 8x8 grey 8-bit */
        0x7f, 0xff, 0xff, 0xf0, 't',  'E',  'X',  't',  'C',  'o',  'm',  'm',
        'e',  'n',  't',  0};
    const char *path = "fuzz_regressions_huge_text.png";
    FILE *f = fopen(path, "wb");
    CHECK(f != NULL);
    if (!f)
        return;
    fwrite(head, 1, sizeof head, f);
    for (int i = 0; i < 4000; i++)
        fputc('x', f);
    fclose(f);
    /* the growth over a child that loads nothing (a sanitizer's shadow memory alone is
     * about 100 MB of RSS) */
    rpiv_status st = RPIV_OK, st0 = RPIV_OK;
    long kb0 = child_load_rss_kb("fuzz_regressions_no_such_file.png", &st0);
    long kb = child_load_rss_kb(path, &st);
    printf("4 KB PNG declaring a 2 GB tEXt chunk: status %d, peak RSS %ld KB (%ld KB loading "
           "nothing)\n",
           (int)st, kb, kb0);
    CHECK(st == RPIV_EFORMAT && st0 == RPIV_EIO);
    CHECK(kb0 > 0 && kb > 0 && kb - kb0 < 100 * 1024);
    remove(path);
}

int main(void)
{
    rpiv_init();
    const char *data = getenv("RPIV_TEST_DATA");
    snprintf(dir, sizeof dir, "%s/fuzz-regressions", data ? data : "tests/data");
    RUN_TEST(every_file_has_an_expectation);
    RUN_TEST(each_regression_ends_cleanly);
    RUN_TEST(png_size_check_keeps_highly_compressed_images);
    RUN_TEST(huge_chunk_declarations_stay_small);
    return check_summary();
}
