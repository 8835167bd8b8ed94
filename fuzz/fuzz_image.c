/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Fuzz the image readers (format detection, TIFF, PNG, PGM, BMP, JPEG): any input either
 * loads into a well-formed image or fails with a message; no crash, leak or UB. The seed
 * corpus (fuzz/corpus/image) holds small files of every layout tests/test_image.c writes.
 * Each call takes under 100 MB of heap over what was live before it (fuzz_heap_begin). */
#include "fuzz.h"
#include "rpiv/image.h"

#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int ready;
    if (!ready) {
        rpiv_init();
        ready = 1;
    }
    const char *path = fuzz_file(data, size, ".img");
    if (!path)
        return 0;
    int pages = 0;
    size_t h0 = fuzz_heap_begin();
    rpiv_status st = rpiv_image_count_pages(path, &pages);
    fuzz_heap_end(h0, path, "rpiv_image_count_pages");
    if (st != RPIV_OK && strlen(rpiv_errmsg()) == 0)
        __builtin_trap();
    int last = st == RPIV_OK && pages > 1 ? (pages < 4 ? pages - 1 : 3) : 0;
    for (int page = 0; page <= last; page++) {
        rpiv_image *im = NULL;
        int warned = 0;
        h0 = fuzz_heap_begin();
        st = rpiv_image_load(path, page, &im, &warned);
        fuzz_heap_end(h0, path, "rpiv_image_load");
        if (st == RPIV_OK) {
            if (!im || im->w < 1 || im->h < 1 || !im->px)
                __builtin_trap();
            rpiv_image_stats s = rpiv_image_stats_of(im); /* touches every pixel */
            (void)s;
            rpiv_image_free(im);
        } else if (im != NULL || strlen(rpiv_errmsg()) == 0) {
            __builtin_trap(); /* a failure leaves no image and carries a message */
        }
    }
    return 0;
}
