/* SPDX-License-Identifier: GPL-3.0-or-later */
/* fuzz/fuzz_image.h - the image readers' harness shared by fuzz_tiff, fuzz_png, fuzz_pgm and
 * fuzz_bmp_jpeg: each target keeps inputs of its own format (by magic bytes, as
 * rpiv_image_load detects them) and loads them through the public API. Invariants: a success
 * gives a sane size and finite levels within the bit depth (fuzz_check_image); a failure
 * leaves *out NULL and a message naming the file; for multi-page TIFF the last page loads or
 * fails the same way, and a page past the end fails with RPIV_EINVAL. */
#ifndef RPIV_FUZZ_IMAGE_H
#define RPIV_FUZZ_IMAGE_H

#include "fuzz.h"
#include "rpiv/image.h"

static inline void fuzz_load_page(const char *path, int page)
{
    rpiv_image *im = (rpiv_image *)&im; /* must be reset to NULL on failure */
    int warned = -1;
    rpiv_status st = rpiv_image_load(path, page, &im, &warned);
    if (st == RPIV_OK) {
        fuzz_check_image(im, path);
        FUZZ_CHECK(warned == 0 || warned == 1, "%s: warned = %d", path, warned);
        rpiv_image_stats s = rpiv_image_stats_of(im);
        FUZZ_CHECK(isfinite(s.mean) && s.min <= s.mean && s.mean <= s.max, "%s: stats %g %g %g",
                   path, s.min, s.mean, s.max);
    } else {
        FUZZ_CHECK(im == NULL, "%s: failure left an image", path);
        fuzz_check_failure(st, path);
    }
    rpiv_image_free(im);
}

/* Load an input of format `want` (other inputs are skipped); returns 0. */
static inline int fuzz_image_input(const uint8_t *data, size_t size, rpiv_image_format want,
                                   const char *suffix)
{
    static int ready;
    if (!ready) {
        rpiv_init();
        ready = 1;
    }
    if (rpiv_image_format_of_bytes(data, size) != want)
        return 0;
    const char *path = fuzz_file(data, size, suffix);
    if (!path)
        return 0;
    rpiv_image_format fmt;
    FUZZ_CHECK(rpiv_image_format_of(path, &fmt) == RPIV_OK && fmt == want, "%s: format", path);
    fuzz_load_page(path, 0);
    if (want == RPIV_IMAGE_TIFF) {
        int np = -1;
        rpiv_status st = rpiv_image_count_pages(path, &np);
        if (st != RPIV_OK) {
            fuzz_check_failure(st, path);
            return 0;
        }
        FUZZ_CHECK(np >= 1, "%s: %d pages", path, np);
        if (np > 1)
            fuzz_load_page(path, np - 1);
        rpiv_image *im = NULL;
        st = rpiv_image_load(path, np, &im, NULL);
        FUZZ_CHECK(st == RPIV_EINVAL && im == NULL, "%s: page %d of %d: status %d", path, np, np,
                   (int)st);
        fuzz_check_failure(st, path);
    }
    return 0;
}

#endif /* RPIV_FUZZ_IMAGE_H */
