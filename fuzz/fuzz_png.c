/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Fuzz the PNG reader through rpiv_image_load (invariants in fuzz_image.h). Each chunk's CRC
 * protects it, so almost every mutation would only reach the CRC check: each input is loaded
 * as it is, then again with every complete chunk's CRC recomputed (zlib's crc32), which lets
 * mutations of headers, palettes and compressed data reach the decoder. */
#include "fuzz_image.h"

#include <zlib.h>

static uint32_t be32(const uint8_t *p)
{
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_image_input(data, size, RPIV_IMAGE_PNG, ".png");
    if (size < 8 || size > 1 << 20)
        return 0;
    uint8_t *fixed = malloc(size);
    if (!fixed)
        return 0;
    memcpy(fixed, data, size);
    int changed = 0;
    for (size_t at = 8; at + 12 <= size;) {
        uint32_t len = be32(fixed + at);
        if (len > size - at - 12)
            break;
        uint32_t crc = (uint32_t)crc32(0L, fixed + at + 4, (uInt)len + 4);
        uint8_t *c = fixed + at + 8 + len;
        if (be32(c) != crc) {
            c[0] = (uint8_t)(crc >> 24);
            c[1] = (uint8_t)(crc >> 16);
            c[2] = (uint8_t)(crc >> 8);
            c[3] = (uint8_t)crc;
            changed = 1;
        }
        at += 12 + (size_t)len;
    }
    if (changed)
        fuzz_image_input(fixed, size, RPIV_IMAGE_PNG, ".png");
    free(fixed);
    return 0;
}
