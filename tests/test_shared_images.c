/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/test_shared_images.c - every image in ../shared/data (env RPIV_SHARED_DATA) is read
 * with the right format, size and bit depth, a few pixel values and its grey statistics; and
 * each folder's pair loads through rpiv_pairs. Skipped (exit 77) where the folder is absent.
 *
 * How the expected values were obtained (independently of rpiv; see docs/images.md):
 *  - TIFF: tags read with `tiffinfo`/`tiffdump` and a Python script parsing the IFD (all
 *    files are uncompressed strips); pixels taken from the raw strip bytes; for the palette
 *    TIFF through the ColorMap (which is the identity grey ramp 257*i there).
 *  - PNG: a Python script (zlib + the PNG filter definitions) inflating the IDAT stream.
 *  - BMP: a Python script reading the bottom-up rows through the palette (an identity grey
 *    ramp in both BMP pairs, so grey level = palette entry = index here; tests/test_image.c
 *    checks a non-identity palette).
 *  - JPEG: libjpeg-turbo's `djpeg -grayscale -pnm`. stb_image's IDCT rounds differently from
 *    libjpeg-turbo's: 2928 and 3237 of 1447680 pixels differ by 1 grey level (none by more),
 *    so JPEG pixels are checked within 1 and the mean within 0.01. */
#include "check.h"
#include "rpiv/image.h"
#include "rpiv/pairs.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

typedef struct shared_img {
    const char *path; /* relative to RPIV_SHARED_DATA */
    rpiv_image_format fmt;
    int w, h, bits;
    double min, max, mean;
    int px[5][3]; /* x, y, value */
} shared_img;

static const shared_img imgs[] = {
    {"openpiv_camera/Camera1-0101.tif",
     RPIV_IMAGE_TIFF,
     1720,
     2304,
     8,
     42,
     255,
     99.869680,
     {{0, 0, 55}, {1719, 2303, 60}, {137, 59, 57}, {873, 775, 103}, {1715, 3, 65}}},
    {"openpiv_camera/Camera1-0102.tif",
     RPIV_IMAGE_TIFF,
     1720,
     2304,
     8,
     44,
     255,
     101.893128,
     {{0, 0, 54}, {1719, 2303, 71}, {137, 59, 57}, {873, 775, 102}, {1715, 3, 65}}},
    {"openpiv_palette/2image_00.tif",
     RPIV_IMAGE_TIFF,
     1008,
     1012,
     8,
     13,
     255,
     34.511490,
     {{0, 0, 22}, {1007, 1011, 21}, {137, 59, 21}, {517, 344, 41}, {1003, 3, 30}}},
    {"openpiv_palette/2image_01.tif",
     RPIV_IMAGE_TIFF,
     1008,
     1012,
     8,
     14,
     255,
     30.093964,
     {{0, 0, 21}, {1007, 1011, 19}, {137, 59, 31}, {517, 344, 44}, {1003, 3, 30}}},
    {"pivchallenge2014_E/im00001.tif",
     RPIV_IMAGE_TIFF,
     1024,
     1024,
     16,
     0,
     55936,
     1944.926830,
     {{0, 0, 1984}, {1023, 1023, 384}, {137, 59, 1984}, {525, 348, 1088}, {1019, 3, 1280}}},
    {"pivchallenge2014_E/im00002.tif",
     RPIV_IMAGE_TIFF,
     1024,
     1024,
     16,
     0,
     56896,
     1992.845744,
     {{0, 0, 2240}, {1023, 1023, 512}, {137, 59, 1856}, {525, 348, 1344}, {1019, 3, 1664}}},
    {"uvmat_oseen/Oseen_center_01.tif",
     RPIV_IMAGE_TIFF,
     400,
     300,
     8,
     0,
     255,
     32.340208,
     {{0, 0, 1}, {399, 299, 0}, {137, 59, 90}, {213, 107, 27}, {395, 3, 16}}},
    {"uvmat_oseen/Oseen_center_02.tif",
     RPIV_IMAGE_TIFF,
     400,
     300,
     8,
     0,
     255,
     32.480817,
     {{0, 0, 16}, {399, 299, 0}, {137, 59, 16}, {213, 107, 0}, {395, 3, 22}}},
    {"milestone/im00505a.png",
     RPIV_IMAGE_PNG,
     1560,
     1362,
     8,
     0,
     255,
     8.200593,
     {{0, 0, 7}, {1559, 1361, 4}, {137, 59, 6}, {793, 461, 7}, {1555, 3, 5}}},
    {"milestone/im00505b.png",
     RPIV_IMAGE_PNG,
     1560,
     1362,
     8,
     0,
     255,
     7.693948,
     {{0, 0, 6}, {1559, 1361, 4}, {137, 59, 6}, {793, 461, 10}, {1555, 3, 5}}},
    {"uvmat_jet/c060a.png",
     RPIV_IMAGE_PNG,
     512,
     512,
     16,
     0,
     65535,
     8919.484486,
     {{0, 0, 5911}, {511, 511, 0}, {137, 59, 17476}, {269, 177, 16705}, {507, 3, 0}}},
    {"uvmat_jet/c060b.png",
     RPIV_IMAGE_PNG,
     512,
     512,
     16,
     0,
     65535,
     8175.287018,
     {{0, 0, 6425}, {511, 511, 0}, {137, 59, 15163}, {269, 177, 13364}, {507, 3, 0}}},
    {"openpiv_exp1/exp1_001_a.bmp",
     RPIV_IMAGE_BMP,
     511,
     369,
     8,
     0,
     250,
     29.438022,
     {{0, 0, 8}, {510, 368, 15}, {137, 59, 78}, {268, 130, 6}, {506, 3, 247}}},
    {"openpiv_exp1/exp1_001_b.bmp",
     RPIV_IMAGE_BMP,
     511,
     369,
     8,
     0,
     249,
     37.449870,
     {{0, 0, 41}, {510, 368, 14}, {137, 59, 22}, {268, 130, 15}, {506, 3, 16}}},
    {"pivlab_karman/PIVlab_Karman_01.bmp",
     RPIV_IMAGE_BMP,
     1024,
     765,
     8,
     5,
     255,
     32.434028,
     {{0, 0, 22}, {1023, 764, 18}, {137, 59, 31}, {525, 262, 27}, {1019, 3, 49}}},
    {"pivlab_karman/PIVlab_Karman_02.bmp",
     RPIV_IMAGE_BMP,
     1024,
     765,
     8,
     3,
     255,
     32.284582,
     {{0, 0, 23}, {1023, 764, 17}, {137, 59, 86}, {525, 262, 24}, {1019, 3, 49}}},
    {"pivlab_jet/Jet_0001A.jpg",
     RPIV_IMAGE_JPEG,
     1392,
     1040,
     8,
     0,
     255,
     12.629891,
     {{0, 0, 7}, {1391, 1039, 15}, {137, 59, 9}, {709, 353, 8}, {1387, 3, 10}}},
    {"pivlab_jet/Jet_0001B.jpg",
     RPIV_IMAGE_JPEG,
     1392,
     1040,
     8,
     0,
     255,
     13.973337,
     {{0, 0, 8}, {1391, 1039, 12}, {137, 59, 10}, {709, 353, 10}, {1387, 3, 13}}},
};
#define NIMG (sizeof imgs / sizeof imgs[0])

static const char *root;

static void check_image(const shared_img *s)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", root, s->path);
    rpiv_image_format fmt = RPIV_IMAGE_UNKNOWN;
    rpiv_image *im = NULL;
    int warned = -1, pages = 0;
    CHECK_OK(rpiv_image_format_of(path, &fmt));
    CHECK(fmt == s->fmt);
    CHECK_OK(rpiv_image_count_pages(path, &pages));
    CHECK(pages == 1);
    CHECK_OK(rpiv_image_load(path, 0, &im, &warned));
    if (!im) {
        printf("    %s: %s\n", s->path, rpiv_errmsg());
        return;
    }
    CHECK(im->w == s->w && im->h == s->h && im->bits == s->bits && warned == 0);
    double tol = s->fmt == RPIV_IMAGE_JPEG ? 1.0 : 0.0;
    for (int k = 0; k < 5; k++)
        CHECK_NEAR(im->px[(size_t)s->px[k][1] * (size_t)im->w + (size_t)s->px[k][0]], s->px[k][2],
                   tol);
    rpiv_image_stats st = rpiv_image_stats_of(im);
    CHECK_NEAR(st.min, s->min, tol);
    CHECK_NEAR(st.max, s->max, tol);
    CHECK_NEAR(st.mean, s->mean, s->fmt == RPIV_IMAGE_JPEG ? 0.01 : 5e-7);
    printf("    %-36s %s %dx%d %2d-bit mean %.6f\n", s->path, rpiv_image_format_name(fmt), im->w,
           im->h, im->bits, st.mean);
    rpiv_image_free(im);
}

static void every_shared_image(void)
{
    for (size_t i = 0; i < NIMG; i++)
        check_image(&imgs[i]);
}

/* Consecutive entries of the table are the two frames of one folder's pair. */
static void every_shared_pair(void)
{
    for (size_t i = 0; i + 1 < NIMG; i += 2) {
        char pa[1024], pb[1024];
        snprintf(pa, sizeof pa, "%s/%s", root, imgs[i].path);
        snprintf(pb, sizeof pb, "%s/%s", root, imgs[i + 1].path);
        char *args[2] = {pa, pb};
        rpiv_pairs *p = NULL;
        rpiv_image *a = NULL, *b = NULL;
        CHECK_OK(rpiv_pairs_from_args(2, args, RPIV_PAIR_AB, &p));
        if (p)
            CHECK_OK(rpiv_pairs_load(p, 0, &a, &b));
        CHECK(a && b && a->w == imgs[i].w && b->h == imgs[i + 1].h);
        rpiv_image_free(a);
        rpiv_image_free(b);
        rpiv_pairs_free(p);
    }
}

int main(void)
{
    struct stat sb;
    root = getenv("RPIV_SHARED_DATA");
    if (!root || stat(root, &sb) != 0 || !S_ISDIR(sb.st_mode)) {
        check_skip("RPIV_SHARED_DATA unset or absent (../shared/data is not part of a clone)");
        return 77;
    }
    RUN_TEST(every_shared_image);
    RUN_TEST(every_shared_pair);
    return check_summary();
}
