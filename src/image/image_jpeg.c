/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image/image_jpeg.c - JPEG through libjpeg(-turbo). stb_image, used for BMP, is built with its
 * assertions on in Debian and aborts on some corrupt JPEG streams (found by fuzz_bmp_jpeg):
 * libjpeg reports every error through its error manager, turned into an rpiv status here. */
#include "image_impl.h"

#include <limits.h>
#include <setjmp.h>
#include <stdio.h> /* before jpeglib.h, which uses FILE */
#include <stdlib.h>
#include <string.h>

#include <jpeglib.h>

typedef struct jerr {
    struct jpeg_error_mgr mgr; /* first: libjpeg hands this pointer back */
    jmp_buf jump;
    char msg[JMSG_LENGTH_MAX];
} jerr;

static void on_error(j_common_ptr cinfo)
{
    jerr *e = (jerr *)cinfo->err;
    (*cinfo->err->format_message)(cinfo, e->msg);
    longjmp(e->jump, 1);
}

/* Warnings (e.g. "premature end of data segment": libjpeg pads a cut scan with grey) are
 * corruption for a measurement: they fail the read too. */
static void on_message(j_common_ptr cinfo, int level)
{
    if (level < 0)
        on_error(cinfo);
}

rpiv_status img_jpeg_load(const char *path, const unsigned char *buf, size_t n, rpiv_image **out,
                          int *warned)
{
    struct jpeg_decompress_struct cinfo;
    jerr e;
    rpiv_image *volatile im = NULL;
    JSAMPLE *volatile row = NULL;
    rpiv_status st = RPIV_OK;
    *out = NULL;
    if (n > ULONG_MAX)
        return rpiv_fail(RPIV_EFORMAT, "%s: file too large for the JPEG decoder", path);
    memset(&e, 0, sizeof e);
    cinfo.err = jpeg_std_error(&e.mgr);
    e.mgr.error_exit = on_error;
    e.mgr.emit_message = on_message;
    if (setjmp(e.jump)) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: corrupt or truncated JPEG: %s", path, e.msg);
        goto out_destroy;
    }
    jpeg_create_decompress(&cinfo);
    jpeg_mem_src(&cinfo, buf, (unsigned long)n);
    jpeg_read_header(&cinfo, TRUE);
    if (cinfo.data_precision != 8) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: %d-bit JPEG not supported", path, cinfo.data_precision);
        goto out_destroy;
    }
    int colour = cinfo.num_components >= 3;
    /* grey from the luma channel: for YCbCr input this is the Rec. 601 luminance */
    cinfo.out_color_space = JCS_GRAYSCALE;
    if (cinfo.jpeg_color_space == JCS_CMYK || cinfo.jpeg_color_space == JCS_YCCK) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: CMYK JPEG not supported", path);
        goto out_destroy;
    }
    /* A Huffman-coded 8x8 block takes at least one bit, so a JPEG holds at most 512 pixels
     * per byte: refuse a header the file cannot fill before allocating for it. */
    uint64_t w = cinfo.image_width, h = cinfo.image_height;
    if (w * h > 1024 * (uint64_t)n + 65536) {
        st = rpiv_fail(RPIV_EFORMAT,
                       "%s: truncated or corrupt JPEG: %llux%llu pixels cannot be coded in %zu "
                       "bytes",
                       path, (unsigned long long)w, (unsigned long long)h, n);
        goto out_destroy;
    }
    rpiv_image *img;
    if ((st = img_alloc(path, w, h, 8, &img)))
        goto out_destroy;
    im = img;
    row = malloc((size_t)w);
    if (!row) {
        st = rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
        goto out_destroy;
    }
    jpeg_start_decompress(&cinfo);
    while (cinfo.output_scanline < cinfo.output_height) {
        JSAMPROW rows[1] = {row};
        size_t y = cinfo.output_scanline;
        if (jpeg_read_scanlines(&cinfo, rows, 1) != 1) {
            st = rpiv_fail(RPIV_EFORMAT, "%s: truncated JPEG at row %zu", path, y);
            goto out_destroy;
        }
        float *dst = im->px + y * (size_t)w;
        for (size_t x = 0; x < w; x++)
            dst[x] = (float)row[x];
    }
    jpeg_finish_decompress(&cinfo);
    *warned = colour;
    *out = im;
    im = NULL;
out_destroy:
    jpeg_destroy_decompress(&cinfo);
    free(row);
    rpiv_image_free(im);
    return st;
}
