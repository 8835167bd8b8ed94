/* SPDX-License-Identifier: GPL-3.0-or-later */
/* tests/test_pairs.c - image pairs: two files, double-frame files (halves and 2-page TIFF),
 * list files, glob patterns with the A/B, consecutive and time-resolved rules, and every
 * error (size mismatch, odd count, unmatched A/B, missing file named with its pair index). */
#include "image_test_util.h"
#include "rpiv/pairs.h"

/* A small 16-bit frame whose pixels encode its id: v = id * 1000 + x + 10 y. */
static int make_frame(const char *name, int id, int w, int h)
{
    rpiv_image *im = NULL;
    if (rpiv_image_new(w, h, &im))
        return 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            im->px[y * w + x] = (float)(id * 1000 + x + 10 * y);
    int ok = rpiv_image_save_tiff16(im, tu_path(name)) == RPIV_OK;
    rpiv_image_free(im);
    return ok;
}

/* Id of a loaded frame (from pixel (0,0)). */
static int frame_id(const rpiv_image *im)
{
    return im ? (int)(im->px[0] / 1000.0f) : -1;
}

static int ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), m = strlen(suffix);
    return n >= m && strcmp(s + n - m, suffix) == 0;
}

static void two_files(void)
{
    CHECK(make_frame("one.tif", 1, 8, 6) && make_frame("two.tif", 2, 8, 6));
    char *args[2] = {(char *)tu_path("one.tif"), (char *)tu_path("two.tif")};
    rpiv_pairs *p = NULL;
    CHECK_OK(rpiv_pairs_from_args(2, args, RPIV_PAIR_AB, &p));
    CHECK(p && p->n == 1);
    rpiv_image *a = NULL, *b = NULL;
    if (p) {
        CHECK_OK(rpiv_pairs_load(p, 0, &a, &b));
        CHECK(frame_id(a) == 1 && frame_id(b) == 2 && a && a->w == 8 && b && b->h == 6);
        rpiv_image_free(a);
        rpiv_image_free(b);
        CHECK_FAILS(rpiv_pairs_load(p, 1, &a, &b), RPIV_EINVAL);
    }
    rpiv_pairs_free(p);
}

static void size_mismatch_names_both(void)
{
    CHECK(make_frame("s1.tif", 1, 8, 6) && make_frame("s2.tif", 2, 8, 7));
    char *args[2] = {(char *)tu_path("s1.tif"), (char *)tu_path("s2.tif")};
    rpiv_pairs *p = NULL;
    CHECK_OK(rpiv_pairs_from_args(2, args, RPIV_PAIR_AB, &p));
    rpiv_image *a = (rpiv_image *)&a, *b = (rpiv_image *)&b;
    if (p) {
        CHECK_ERR(rpiv_pairs_load(p, 0, &a, &b), RPIV_ESIZE, "s1.tif");
        CHECK(strstr(rpiv_errmsg(), "s2.tif") && strstr(rpiv_errmsg(), "8x6") &&
              strstr(rpiv_errmsg(), "8x7"));
        CHECK(a == NULL && b == NULL);
    }
    rpiv_pairs_free(p);
}

static void double_frame_halves_and_pages(void)
{
    /* one 9x10 image: rows 0-4 frame A, rows 5-9 frame B */
    CHECK(make_frame("df.tif", 3, 9, 10));
    char *args[1] = {(char *)tu_path("df.tif")};
    rpiv_pairs *p = NULL;
    rpiv_image *a = NULL, *b = NULL;
    CHECK_OK(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p));
    CHECK(p && p->n == 1 && p->pair[0].path_b == NULL);
    if (p) {
        CHECK_OK(rpiv_pairs_load(p, 0, &a, &b));
        CHECK(a && b && a->w == 9 && a->h == 5 && b->h == 5 && a->bits == 16);
        if (a && b) {
            CHECK_NEAR(a->px[4 * 9 + 7], 3000 + 7 + 40, 0.0);
            CHECK_NEAR(b->px[0], 3000 + 50, 0.0);
            CHECK_NEAR(b->px[4 * 9 + 8], 3000 + 8 + 90, 0.0);
        }
        rpiv_image_free(a);
        rpiv_image_free(b);
    }
    rpiv_pairs_free(p);
    /* odd height */
    CHECK(make_frame("odd.tif", 3, 9, 11));
    args[0] = (char *)tu_path("odd.tif");
    CHECK_OK(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p));
    if (p)
        CHECK_ERR(rpiv_pairs_load(p, 0, &a, &b), RPIV_ESIZE, "odd.tif");
    rpiv_pairs_free(p);
    /* 2-page TIFF: pages 0 and 1 */
    TIFF *t = TIFFOpen(tu_path("twopage.tif"), "w");
    uint16_t d0[12], d1[12];
    for (int i = 0; i < 12; i++)
        d0[i] = (uint16_t)(4000 + i), d1[i] = (uint16_t)(5000 + 3 * i);
    tu_tiff o = {.w = 4, .h = 3, .bps = 16, .spp = 1, .photo = PHOTOMETRIC_MINISBLACK};
    CHECK(t && tu_tiff_page(t, &o, d0) && tu_tiff_page(t, &o, d1));
    if (t)
        TIFFClose(t);
    args[0] = (char *)tu_path("twopage.tif");
    CHECK_OK(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p));
    if (p) {
        CHECK_OK(rpiv_pairs_load(p, 0, &a, &b));
        CHECK(a && b && a->w == 4 && a->h == 3 && b->h == 3);
        if (a && b) {
            CHECK_NEAR(a->px[11], 4011, 0.0);
            CHECK_NEAR(b->px[11], 5033, 0.0);
        }
        rpiv_image_free(a);
        rpiv_image_free(b);
    }
    rpiv_pairs_free(p);
    /* 2-page TIFF with different page sizes */
    t = TIFFOpen(tu_path("twosizes.tif"), "w");
    tu_tiff o2 = {.w = 3, .h = 4, .bps = 16, .spp = 1, .photo = PHOTOMETRIC_MINISBLACK};
    CHECK(t && tu_tiff_page(t, &o, d0) && tu_tiff_page(t, &o2, d1));
    if (t)
        TIFFClose(t);
    args[0] = (char *)tu_path("twosizes.tif");
    CHECK_OK(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p));
    if (p)
        CHECK_ERR(rpiv_pairs_load(p, 0, &a, &b), RPIV_ESIZE, "twosizes.tif");
    rpiv_pairs_free(p);
}

static void list_file(void)
{
    CHECK(system(NULL) != 0);
    char sub[600];
    snprintf(sub, sizeof sub, "%s/sub dir", tu_dir);
    CHECK(mkdir(sub, 0777) == 0);
    CHECK(make_frame("la.tif", 11, 6, 4) && make_frame("lb.tif", 12, 6, 4) &&
          make_frame("sub dir/lc.tif", 13, 6, 4) && make_frame("ldf.tif", 14, 6, 8));
    char list[2048];
    snprintf(list, sizeof list,
             "# pairs for test_pairs\n"
             "\n"
             "la.tif lb.tif   # relative to the list's folder\n"
             "  \"sub dir/lc.tif\"\t%s/la.tif\n" /* quoted, then absolute */
             "ldf.tif\n"                         /* double frame */
             "   # indented comment\n",
             tu_dir);
    CHECK(tu_write(tu_path("pairs.txt"), list, strlen(list)));
    char *args[1] = {(char *)tu_path("pairs.txt")};
    rpiv_pairs *p = NULL;
    CHECK_OK(rpiv_pairs_from_args(1, args, RPIV_PAIR_CONSECUTIVE, &p));
    CHECK(p && p->n == 3);
    if (p && p->n == 3) {
        CHECK(ends_with(p->pair[0].path_a, "/la.tif") && ends_with(p->pair[0].path_b, "/lb.tif"));
        CHECK(ends_with(p->pair[1].path_a, "/sub dir/lc.tif"));
        CHECK(p->pair[2].path_b == NULL);
        const int ida[3] = {11, 13, 14}, idb[3] = {12, 11, 14};
        for (size_t i = 0; i < 3; i++) {
            rpiv_image *a = NULL, *b = NULL;
            CHECK_OK(rpiv_pairs_load(p, i, &a, &b));
            CHECK(frame_id(a) == ida[i] && frame_id(b) == idb[i]);
            if (i == 2 && b)
                CHECK_NEAR(b->px[0], 14000 + 40, 0.0); /* row 4 of the 6x8 image */
            rpiv_image_free(a);
            rpiv_image_free(b);
        }
    }
    rpiv_pairs_free(p);
    /* errors: three paths on a line (file:line), no pair at all, missing list */
    const char *three = "la.tif lb.tif\nla.tif lb.tif la.tif\n";
    CHECK(tu_write(tu_path("three.lst"), three, strlen(three)));
    args[0] = (char *)tu_path("three.lst");
    CHECK_ERR(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p), RPIV_EFORMAT, "three.lst:2");
    CHECK(p == NULL);
    const char *empty = "# nothing\n\n";
    CHECK(tu_write(tu_path("empty.txt"), empty, strlen(empty)));
    args[0] = (char *)tu_path("empty.txt");
    CHECK_ERR(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p), RPIV_EFORMAT, "empty.txt");
    args[0] = (char *)tu_path("absent.txt");
    CHECK_ERR(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p), RPIV_EIO, "absent.txt");
    /* a comment line of 6000 characters does not cut the list (no line-length limit), and a
     * NUL byte (a binary file named .txt) is refused with its line */
    size_t nlong = 6000;
    char *longlist = malloc(nlong + 64);
    CHECK(longlist != NULL);
    if (longlist) {
        longlist[0] = '#';
        memset(longlist + 1, 'x', nlong - 1);
        strcpy(longlist + nlong, "\nla.tif lb.tif\n");
        CHECK(tu_write(tu_path("long.txt"), longlist, strlen(longlist)));
        args[0] = (char *)tu_path("long.txt");
        CHECK_OK(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p));
        CHECK(p && p->n == 1 && ends_with(p->pair[0].path_b, "/lb.tif"));
        rpiv_pairs_free(p);
        free(longlist);
    }
    const char nul[] = "la.tif lb.tif\nla.tif\0lb.tif\n";
    CHECK(tu_write(tu_path("nul.txt"), nul, sizeof nul - 1));
    args[0] = (char *)tu_path("nul.txt");
    CHECK_ERR(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p), RPIV_EFORMAT, "nul.txt:2");
    CHECK(p == NULL);
}

/* Issue 20 item 11: an unterminated quote took the line's newline into the path (a 2-line
 * message), and a UTF-8 BOM became part of the first path. */
static void list_quote_and_bom(void)
{
    CHECK(make_frame("qa.tif", 21, 6, 4) && make_frame("qb.tif", 22, 6, 4));
    rpiv_pairs *p = NULL;
    char *args[1];
    const char *quote = "qa.tif qb.tif\n\"qa.tif qb.tif\n";
    CHECK(tu_write(tu_path("quote.txt"), quote, strlen(quote)));
    args[0] = (char *)tu_path("quote.txt");
    CHECK_ERR(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p), RPIV_EFORMAT, "quote.txt:2");
    CHECK(strstr(rpiv_errmsg(), "double quote") && !strchr(rpiv_errmsg(), '\n'));
    CHECK(p == NULL);
    const char *bom = "\xef\xbb\xbfqa.tif qb.tif\n";
    CHECK(tu_write(tu_path("bom.txt"), bom, strlen(bom)));
    args[0] = (char *)tu_path("bom.txt");
    CHECK_OK(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p));
    CHECK(p && p->n == 1 && ends_with(p->pair[0].path_a, "/qa.tif") &&
          !strstr(p->pair[0].path_a, "\xef"));
    if (p && p->n == 1) {
        rpiv_image *a = NULL, *b = NULL;
        CHECK_OK(rpiv_pairs_load(p, 0, &a, &b));
        CHECK(frame_id(a) == 21 && frame_id(b) == 22);
        rpiv_image_free(a);
        rpiv_image_free(b);
    }
    rpiv_pairs_free(p);
}

static void glob_ab_rule(void)
{
    char d[600];
    snprintf(d, sizeof d, "%s/ab", tu_dir);
    CHECK(mkdir(d, 0777) == 0);
    CHECK(make_frame("ab/run10_a.tif", 21, 5, 4) && make_frame("ab/run10_b.tif", 22, 5, 4) &&
          make_frame("ab/run9_a.tif", 23, 5, 4) && make_frame("ab/run9_b.tif", 24, 5, 4) &&
          make_frame("ab/imgA.tif", 25, 5, 4) && make_frame("ab/imgB.tif", 26, 5, 4) &&
          make_frame("ab/cam1.tif", 27, 5, 4) && make_frame("ab/cam2.tif", 28, 5, 4));
    char pat[700];
    snprintf(pat, sizeof pat, "%s/*.tif", d);
    char *args[1] = {pat};
    rpiv_pairs *p = NULL;
    CHECK_OK(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p));
    CHECK(p && p->n == 4);
    if (p && p->n == 4) {
        /* sorted by key: cam, img, run10, run9 (keys compare byte-wise) */
        const int ida[4] = {27, 25, 21, 23};
        for (size_t i = 0; i < 4; i++) {
            rpiv_image *a = NULL, *b = NULL;
            CHECK_OK(rpiv_pairs_load(p, i, &a, &b));
            CHECK(frame_id(a) == ida[i] && frame_id(b) == ida[i] + 1);
            rpiv_image_free(a);
            rpiv_image_free(b);
        }
    }
    rpiv_pairs_free(p);
    /* an unmatched A frame, then a name without any marker */
    CHECK(make_frame("ab/lonely_a.tif", 29, 5, 4));
    CHECK_ERR(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p), RPIV_EINVAL, "lonely_a.tif");
    CHECK(strstr(rpiv_errmsg(), "no matching B") != NULL);
    CHECK(p == NULL);
    CHECK(make_frame("ab/lonely_b.tif", 30, 5, 4) && make_frame("ab/other.tif", 31, 5, 4));
    CHECK_ERR(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p), RPIV_EINVAL, "other.tif");
    /* a/b must not pair with A/B */
    char pat2[700];
    snprintf(pat2, sizeof pat2, "%s/x*", tu_dir);
    CHECK(make_frame("xa.tif", 32, 5, 4) && make_frame("xB.tif", 33, 5, 4));
    args[0] = pat2;
    CHECK_ERR(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p), RPIV_EINVAL, "xB.tif");
    /* two patterns: the k-th A with the k-th B */
    char pa[700], pb[700];
    snprintf(pa, sizeof pa, "%s/ab/run*_a.tif", tu_dir);
    snprintf(pb, sizeof pb, "%s/ab/run*_b.tif", tu_dir);
    char *two[2] = {pa, pb};
    CHECK_OK(rpiv_pairs_from_args(2, two, RPIV_PAIR_AB, &p));
    CHECK(p && p->n == 2 && ends_with(p->pair[0].path_a, "run9_a.tif") &&
          ends_with(p->pair[0].path_b, "run9_b.tif") &&
          ends_with(p->pair[1].path_b, "run10_b.tif"));
    rpiv_pairs_free(p);
    snprintf(pb, sizeof pb, "%s/ab/*_b.tif", tu_dir); /* 3 B frames for 2 A frames */
    CHECK_ERR(rpiv_pairs_from_args(2, two, RPIV_PAIR_AB, &p), RPIV_EINVAL, "_b.tif");
}

static void glob_consecutive_and_time_resolved(void)
{
    char d[600];
    snprintf(d, sizeof d, "%s/seq", tu_dir);
    CHECK(mkdir(d, 0777) == 0);
    /* frame_1 .. frame_10 unpadded: natural order puts frame_10 last */
    for (int i = 1; i <= 10; i++) {
        char name[64];
        snprintf(name, sizeof name, "seq/frame_%d.tif", i);
        CHECK(make_frame(name, 40 + i, 4, 4));
    }
    char pat[700];
    snprintf(pat, sizeof pat, "%s/frame_*.tif", d);
    char *args[1] = {pat};
    rpiv_pairs *p = NULL;
    CHECK_OK(rpiv_pairs_from_args(1, args, RPIV_PAIR_CONSECUTIVE, &p));
    CHECK(p && p->n == 5);
    for (size_t i = 0; p && p->n == 5 && i < 5; i++) {
        rpiv_image *a = NULL, *b = NULL;
        CHECK_OK(rpiv_pairs_load(p, i, &a, &b));
        CHECK(frame_id(a) == 41 + 2 * (int)i && frame_id(b) == 42 + 2 * (int)i);
        rpiv_image_free(a);
        rpiv_image_free(b);
    }
    rpiv_pairs_free(p);
    CHECK_OK(rpiv_pairs_from_args(1, args, RPIV_PAIR_TIME_RESOLVED, &p));
    CHECK(p && p->n == 9);
    for (size_t i = 0; p && p->n == 9 && i < 9; i++) {
        rpiv_image *a = NULL, *b = NULL;
        CHECK_OK(rpiv_pairs_load(p, i, &a, &b));
        CHECK(frame_id(a) == 41 + (int)i && frame_id(b) == 42 + (int)i);
        rpiv_image_free(a);
        rpiv_image_free(b);
    }
    rpiv_pairs_free(p);
    /* the same files given one by one (a pattern expanded by the shell), in shuffled order */
    char names[10][700];
    char *many[10];
    for (int i = 0; i < 10; i++) {
        snprintf(names[i], sizeof names[i], "%s/frame_%d.tif", d, (i * 7) % 10 + 1);
        many[i] = names[i];
    }
    CHECK_OK(rpiv_pairs_from_args(10, many, RPIV_PAIR_CONSECUTIVE, &p));
    CHECK(p && p->n == 5 && ends_with(p->pair[4].path_a, "frame_9.tif") &&
          ends_with(p->pair[4].path_b, "frame_10.tif"));
    rpiv_pairs_free(p);
    /* odd count */
    CHECK(make_frame("seq/frame_11.tif", 51, 4, 4));
    CHECK_ERR(rpiv_pairs_from_args(1, args, RPIV_PAIR_CONSECUTIVE, &p), RPIV_EINVAL,
              "frame_11.tif");
    CHECK(strstr(rpiv_errmsg(), "11 files") != NULL);
    /* time-resolved needs two frames */
    snprintf(pat, sizeof pat, "%s/frame_11.t?f", d);
    CHECK_ERR(rpiv_pairs_from_args(1, args, RPIV_PAIR_TIME_RESOLVED, &p), RPIV_EINVAL,
              "frame_11.t?f");
    /* nothing matches */
    snprintf(pat, sizeof pat, "%s/nothing_*.png", d);
    CHECK_ERR(rpiv_pairs_from_args(1, args, RPIV_PAIR_CONSECUTIVE, &p), RPIV_EIO, "nothing_*.png");
    /* a pattern mixed with a file */
    char *mixed[3] = {pat, (char *)tu_path("one.tif"), (char *)tu_path("two.tif")};
    CHECK_FAILS(rpiv_pairs_from_args(3, mixed, RPIV_PAIR_CONSECUTIVE, &p), RPIV_EINVAL);
    CHECK_FAILS(rpiv_pairs_from_args(0, mixed, RPIV_PAIR_CONSECUTIVE, &p), RPIV_EINVAL);
}

/* A file that disappears from a series is named with the pair's index. */
static void missing_file_in_series_has_index(void)
{
    char d[600];
    snprintf(d, sizeof d, "%s/series", tu_dir);
    CHECK(mkdir(d, 0777) == 0);
    for (int i = 1; i <= 80; i++) {
        char name[64];
        snprintf(name, sizeof name, "series/frame_%04d.tif", i);
        CHECK(make_frame(name, i, 4, 2));
    }
    char pat[700];
    snprintf(pat, sizeof pat, "%s/frame_*.tif", d);
    char *args[1] = {pat};
    rpiv_pairs *p = NULL;
    CHECK_OK(rpiv_pairs_from_args(1, args, RPIV_PAIR_CONSECUTIVE, &p));
    CHECK(p && p->n == 40);
    char gone[700];
    snprintf(gone, sizeof gone, "%s/frame_0034.tif", d);
    CHECK(remove(gone) == 0);
    rpiv_image *a = NULL, *b = NULL;
    if (p) {
        CHECK_OK(rpiv_pairs_load(p, 15, &a, &b)); /* pair 16: frames 31, 32 */
        CHECK(frame_id(a) == 31 && frame_id(b) == 32);
        rpiv_image_free(a);
        rpiv_image_free(b);
        CHECK_ERR(rpiv_pairs_load(p, 16, &a, &b), RPIV_EIO, "frame_0034.tif");
        CHECK(strncmp(rpiv_errmsg(), "pair 17 of 40: ", 15) == 0);
        CHECK(a == NULL && b == NULL);
    }
    rpiv_pairs_free(p);
    /* a truncated file in a list */
    CHECK(tu_cut(tu_path("one.tif"), tu_path("trunc.tif"), 40));
    char list[256];
    snprintf(list, sizeof list, "one.tif two.tif\none.tif trunc.tif\n");
    CHECK(tu_write(tu_path("withbad.txt"), list, strlen(list)));
    args[0] = (char *)tu_path("withbad.txt");
    CHECK_OK(rpiv_pairs_from_args(1, args, RPIV_PAIR_AB, &p));
    if (p) {
        CHECK_ERR(rpiv_pairs_load(p, 1, &a, &b), RPIV_EFORMAT, "trunc.tif");
        CHECK(strncmp(rpiv_errmsg(), "pair 2 of 2: ", 13) == 0);
    }
    rpiv_pairs_free(p);
}

int main(void)
{
    if (!tu_init("test_pairs"))
        return 1;
    RUN_TEST(two_files);
    RUN_TEST(size_mismatch_names_both);
    RUN_TEST(double_frame_halves_and_pages);
    RUN_TEST(list_file);
    RUN_TEST(list_quote_and_bom);
    RUN_TEST(glob_ab_rule);
    RUN_TEST(glob_consecutive_and_time_resolved);
    RUN_TEST(missing_file_in_series_has_index);
    tu_cleanup();
    return check_summary();
}
