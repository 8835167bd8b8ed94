/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Fuzz the PGM reader through rpiv_image_load (invariants in fuzz_image.h). */
#include "fuzz_image.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_image_input(data, size, RPIV_IMAGE_PGM, ".pgm");
}
