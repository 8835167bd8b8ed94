/* SPDX-License-Identifier: GPL-3.0-or-later */
/* fuzz/fuzz_image.h - the image readers' harness shared by fuzz_tiff, fuzz_png, fuzz_pgm and
 * fuzz_bmp_jpeg: each target keeps inputs of its own format (by magic bytes, as
 * rpiv_image_load detects them) and loads them through the public API. Invariants: a success
 * gives a sane size and finite levels within the bit depth (fuzz_check_image); a failure
 * leaves *out NULL and a message naming the file; for multi-page TIFF the last page loads or
 * fails the same way, and a page past the end fails with RPIV_EINVAL; page 0 read as a
 * double frame gives the whole image's halves (fuzz_check_halves); each call takes under
 * 100 MB of heap over what was live before it (fuzz_heap_begin). */
#ifndef RPIV_FUZZ_IMAGE_H
#define RPIV_FUZZ_IMAGE_H

#include "fuzz.h"
#include "rpiv/image.h"

/* The double-frame reader (rpiv_image_load_halves, which decodes a PNG straight into two
 * halves) against the whole image im (NULL if rpiv_image_load failed with status st): the
 * same pixels, bit for bit, for an even height; RPIV_ESIZE for an odd one; the same status
 * for a file that does not load. */
static inline void fuzz_check_halves(const char *path, const rpiv_image *im, rpiv_status st)
{
    rpiv_image *a = (rpiv_image *)&a, *b = (rpiv_image *)&b;
    size_t h0 = fuzz_heap_begin();
    rpiv_status sh = rpiv_image_load_halves(path, &a, &b, NULL);
    fuzz_heap_end(h0, path, "rpiv_image_load_halves");
    if (!im || im->h % 2) {
        FUZZ_CHECK(sh == (im ? RPIV_ESIZE : st), "%s: halves status %d, whole %d", path, (int)sh,
                   (int)st);
        FUZZ_CHECK(a == NULL && b == NULL, "%s: failed halves left an image", path);
        fuzz_check_failure(sh, path);
        return;
    }
    size_t half = (size_t)im->w * (size_t)(im->h / 2);
    FUZZ_CHECK(sh == RPIV_OK && a && b, "%s: halves status %d", path, (int)sh);
    FUZZ_CHECK(a->w == im->w && b->w == im->w && a->h == im->h / 2 && b->h == im->h / 2 &&
                   a->bits == im->bits && b->bits == im->bits,
               "%s: halves %dx%d %dx%d of %dx%d", path, a->w, a->h, b->w, b->h, im->w, im->h);
    FUZZ_CHECK(memcmp(a->px, im->px, half * sizeof *im->px) == 0 &&
                   memcmp(b->px, im->px + half, half * sizeof *im->px) == 0,
               "%s: halves differ from the whole image", path);
    rpiv_image_free(a);
    rpiv_image_free(b);
}

static inline void fuzz_load_page(const char *path, int page)
{
    rpiv_image *im = (rpiv_image *)&im; /* must be reset to NULL on failure */
    int warned = -1;
    size_t h0 = fuzz_heap_begin();
    rpiv_status st = rpiv_image_load(path, page, &im, &warned);
    fuzz_heap_end(h0, path, "rpiv_image_load");
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
    if (page == 0)
        fuzz_check_halves(path, im, st);
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
        size_t h0 = fuzz_heap_begin();
        rpiv_status st = rpiv_image_count_pages(path, &np);
        fuzz_heap_end(h0, path, "rpiv_image_count_pages");
        if (st != RPIV_OK) {
            fuzz_check_failure(st, path);
            return 0;
        }
        FUZZ_CHECK(np >= 1, "%s: %d pages", path, np);
        if (np > 1)
            fuzz_load_page(path, np - 1);
        rpiv_image *im = NULL;
        h0 = fuzz_heap_begin();
        st = rpiv_image_load(path, np, &im, NULL);
        fuzz_heap_end(h0, path, "rpiv_image_load past the last page");
        FUZZ_CHECK(st == RPIV_EINVAL && im == NULL, "%s: page %d of %d: status %d", path, np, np,
                   (int)st);
        fuzz_check_failure(st, path);
    }
    return 0;
}

#endif /* RPIV_FUZZ_IMAGE_H */
