/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Fuzz the BMP and JPEG readers (stb_image behind rpiv's completeness checks) through
 * rpiv_image_load (invariants in fuzz_image.h). */
#include "fuzz_image.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    rpiv_image_format f = rpiv_image_format_of_bytes(data, size);
    return fuzz_image_input(data, size, f == RPIV_IMAGE_JPEG ? f : RPIV_IMAGE_BMP,
                            f == RPIV_IMAGE_JPEG ? ".jpg" : ".bmp");
}
