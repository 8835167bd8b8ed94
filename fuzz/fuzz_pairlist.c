/* SPDX-License-Identifier: GPL-3.0-or-later */
/* Fuzz the pair-list reader: the input is a list file (".txt") in a scratch folder that also
 * holds a few small images (pairs, a double-frame image, a mismatched size, an odd height, a
 * zero-byte file), read by rpiv_pairs_from_args and loaded by rpiv_pairs_load.
 * Invariants: a list that reads has n >= 1 pairs, each with a non-empty path A; a failure
 * leaves *out NULL and names the list; loading a pair gives two finite images of one size,
 * or fails naming one of its files (and "pair i of n" when n > 1); a pair index past the end
 * is RPIV_EINVAL. */
#include "fuzz.h"
#include "rpiv/image.h"
#include "rpiv/pairs.h"

static void make_image(const char *name, int w, int h, double phase)
{
    char path[256];
    rpiv_image *im;
    snprintf(path, sizeof path, "%s/%s", fuzz_dir(), name);
    if (rpiv_image_new(w, h, &im) != RPIV_OK)
        abort();
    for (int k = 0; k < w * h; k++)
        im->px[k] = (float)(1000.0 + 900.0 * sin(0.7319 * k + phase));
    if (rpiv_image_save(im, path) != RPIV_OK)
        abort();
    rpiv_image_free(im);
}

static void setup(void)
{
    rpiv_init();
    make_image("f1_a.tif", 16, 8, 0.1);
    make_image("f1_b.tif", 16, 8, 0.2);
    make_image("f2_a.png", 16, 8, 0.3);
    make_image("f2_b.png", 16, 8, 0.4);
    make_image("g_a.tif", 12, 8, 0.5);
    make_image("df.tif", 16, 16, 0.6);
    make_image("odd.png", 16, 9, 0.7);
    char path[256];
    snprintf(path, sizeof path, "%s/empty.tif", fuzz_dir());
    FILE *f = fopen(path, "wb");
    if (!f)
        abort();
    fclose(f);
}

/* Load only files of the scratch folder (no absolute path elsewhere, no ".."). */
static int local(const char *p)
{
    size_t n = strlen(fuzz_dir());
    return p == NULL || (strncmp(p, fuzz_dir(), n) == 0 && p[n] == '/' && !strstr(p, ".."));
}

static void load(const rpiv_pairs *p, size_t i)
{
    const rpiv_pair_src *s = &p->pair[i];
    if (!local(s->path_a) || !local(s->path_b))
        return;
    rpiv_image *a = (rpiv_image *)&a, *b = (rpiv_image *)&b;
    rpiv_status st = rpiv_pairs_load(p, i, &a, &b);
    if (st == RPIV_OK) {
        fuzz_check_image(a, s->path_a);
        fuzz_check_image(b, s->path_b ? s->path_b : s->path_a);
        FUZZ_CHECK(a->w == b->w && a->h == b->h, "pair %zu: %dx%d vs %dx%d", i, a->w, a->h, b->w,
                   b->h);
    } else {
        FUZZ_CHECK(a == NULL && b == NULL, "pair %zu: failure left an image", i);
        const char *m = rpiv_errmsg();
        FUZZ_CHECK(m[0] && (strstr(m, s->path_a) || (s->path_b && strstr(m, s->path_b))),
                   "pair %zu: message names neither file: %s", i, m);
        if (p->n > 1) {
            char tag[64];
            snprintf(tag, sizeof tag, "pair %zu of %zu", i + 1, p->n);
            FUZZ_CHECK(strstr(m, tag) != NULL, "message lacks '%s': %s", tag, m);
        }
    }
    rpiv_image_free(a);
    rpiv_image_free(b);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int ready;
    if (!ready) {
        setup();
        ready = 1;
    }
    char path[256];
    snprintf(path, sizeof path, "%s/list.txt", fuzz_dir());
    FILE *f = fopen(path, "wb");
    if (!f)
        return 0;
    if (size)
        fwrite(data, 1, size, f);
    fclose(f);
    char *args[1] = {path};
    rpiv_pairs *p = (rpiv_pairs *)&p;
    rpiv_status st = rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p);
    if (st != RPIV_OK) {
        FUZZ_CHECK(p == NULL, "failure left a list");
        fuzz_check_failure(st, path);
        return 0;
    }
    FUZZ_CHECK(p && p->n >= 1 && p->pair, "empty list accepted");
    for (size_t i = 0; i < p->n; i++)
        FUZZ_CHECK(p->pair[i].path_a && p->pair[i].path_a[0] &&
                       (!p->pair[i].path_b || p->pair[i].path_b[0]),
                   "pair %zu: empty path", i);
    for (size_t i = 0; i < p->n && i < 3; i++)
        load(p, i);
    if (p->n > 3)
        load(p, p->n - 1);
    rpiv_image *a, *b;
    st = rpiv_pairs_load(p, p->n, &a, &b);
    FUZZ_CHECK(st == RPIV_EINVAL && !a && !b, "pair %zu of %zu: status %d", p->n + 1, p->n,
               (int)st);
    rpiv_pairs_free(p);
    return 0;
}
