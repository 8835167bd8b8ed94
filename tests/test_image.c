/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/test_image.c - image module: round trips, readers of every format, bad input. */
#include "check.h"
#include "rpiv/image.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char tmpdir[256];

static const char *tpath(const char *name)
{
    static char buf[512];
    snprintf(buf, sizeof buf, "%s/%s", tmpdir, name);
    return buf;
}

/* A test image with high-entropy 16-bit values: v = (x * 7919 + y * 104729 + 12345) % 65536. */
static rpiv_image *pattern16(int w, int h)
{
    rpiv_image *im = NULL;
    if (rpiv_image_new(w, h, &im) != RPIV_OK)
        return NULL;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            im->px[y * w + x] = (float)((x * 7919L + y * 104729L + 12345L) % 65536L);
    return im;
}

static void roundtrip_tiff16_exact(void)
{
    rpiv_image *im = pattern16(37, 23), *back = NULL;
    int warned = -1;
    CHECK_OK(rpiv_image_save_tiff16(im, tpath("rt16.tif")));
    CHECK_OK(rpiv_image_load(tpath("rt16.tif"), 0, &back, &warned));
    CHECK(back && back->w == 37 && back->h == 23 && back->bits == 16 && warned == 0);
    if (back)
        CHECK(memcmp(back->px, im->px, 37 * 23 * sizeof(float)) == 0);
    rpiv_image_free(back);
    rpiv_image_free(im);
}

static void roundtrip_png16_exact(void)
{
    rpiv_image *im = pattern16(41, 19), *back = NULL;
    int warned = -1;
    CHECK_OK(rpiv_image_save_png16(im, tpath("rt16.png")));
    CHECK_OK(rpiv_image_load(tpath("rt16.png"), 0, &back, &warned));
    CHECK(back && back->w == 41 && back->h == 19 && back->bits == 16 && warned == 0);
    if (back)
        CHECK(memcmp(back->px, im->px, 41 * 19 * sizeof(float)) == 0);
    rpiv_image_free(back);
    rpiv_image_free(im);
}

static void roundtrip_float_tiff_exact(void)
{
    rpiv_image *im = NULL, *back = NULL;
    CHECK_OK(rpiv_image_new(29, 31, &im));
    for (int i = 0; i < 29 * 31; i++)
        im->px[i] = (float)(sin(0.3187 * i) * 1234.567 - 17.0 / (i + 1.0));
    CHECK_OK(rpiv_image_save_tiff_float(im, tpath("rtf.tif")));
    CHECK_OK(rpiv_image_load(tpath("rtf.tif"), 0, &back, NULL));
    CHECK(back && back->w == 29 && back->h == 31 && back->bits == 32);
    if (back)
        CHECK(memcmp(back->px, im->px, 29 * 31 * sizeof(float)) == 0);
    rpiv_image_free(back);
    rpiv_image_free(im);
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/rpiv_test_image_XXXXXX");
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    RUN_TEST(roundtrip_tiff16_exact);
    RUN_TEST(roundtrip_png16_exact);
    RUN_TEST(roundtrip_float_tiff_exact);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0)
        fprintf(stderr, "cannot remove %s\n", tmpdir);
    return check_summary();
}
