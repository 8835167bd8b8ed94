/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image/image_pgm.c - portable grey maps (Netpbm PGM): P5 binary and P2 ASCII, maxval up to
 * 65535 (> 255: two bytes per sample, most significant first). Only the first image of a
 * file is read. Grey levels are kept as stored (not rescaled by maxval). */
#include "image_impl.h"

#include <stdio.h>

/* Skip whitespace and '#' comments; return the position of the next token. */
static size_t skip_space(const unsigned char *b, size_t n, size_t i)
{
    while (i < n) {
        if (b[i] == '#') {
            while (i < n && b[i] != '\n' && b[i] != '\r')
                i++;
        } else if (b[i] == ' ' || b[i] == '\t' || b[i] == '\n' || b[i] == '\r' || b[i] == '\v' ||
                   b[i] == '\f') {
            i++;
        } else {
            break;
        }
    }
    return i;
}

/* Parse an unsigned decimal at *i (at most 10 digits); 0 on failure. */
static int number(const unsigned char *b, size_t n, size_t *i, uint64_t *v)
{
    size_t j = skip_space(b, n, *i), k = 0;
    *v = 0;
    while (j < n && b[j] >= '0' && b[j] <= '9' && k < 11) {
        *v = *v * 10 + (uint64_t)(b[j] - '0');
        j++;
        k++;
    }
    if (k == 0 || k > 10)
        return 0;
    *i = j;
    return 1;
}

/* One ASCII (P2) sample at *i, k-th of npx: a clear message for a missing, negative,
 * non-numeric or out-of-range value. */
static rpiv_status ascii_value(const char *path, const unsigned char *b, size_t n, size_t *i,
                               uint64_t k, uint64_t npx, uint64_t w, uint64_t maxval, uint64_t *v)
{
    size_t j = skip_space(b, n, *i), j0 = j;
    unsigned long long kk = (unsigned long long)k + 1, nn = (unsigned long long)npx;
    if (j >= n)
        return rpiv_fail(RPIV_EFORMAT, "%s: truncated PGM: value %llu of %llu missing", path, kk,
                         nn);
    if (b[j] == '-')
        return rpiv_fail(RPIV_EFORMAT, "%s: PGM value %llu of %llu is negative", path, kk, nn);
    if (b[j] < '0' || b[j] > '9')
        return rpiv_fail(RPIV_EFORMAT, "%s: PGM value %llu of %llu is not a number ('%c')", path,
                         kk, nn, b[j] >= 32 && b[j] < 127 ? b[j] : '?');
    *v = 0;
    while (j < n && b[j] >= '0' && b[j] <= '9') {
        if (*v <= maxval) /* past maxval the value no longer matters; no overflow */
            *v = *v * 10 + (uint64_t)(b[j] - '0');
        j++;
    }
    if (*v > maxval) {
        int len = j - j0 > 20 ? 20 : (int)(j - j0);
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: PGM value %llu of %llu (%.*s%s) exceeds maxval %llu "
                         "at (%llu, %llu)",
                         path, kk, nn, len, (const char *)b + j0, j - j0 > 20 ? "..." : "",
                         (unsigned long long)maxval, (unsigned long long)(k % w),
                         (unsigned long long)(k / w));
    }
    *i = j;
    return RPIV_OK;
}

static int bits_for(uint64_t maxval)
{
    int b = 0;
    while (b < 16 && ((uint64_t)1 << b) <= maxval)
        b++;
    return b;
}

rpiv_status img_pgm_load(const char *path, const unsigned char *b, size_t n, rpiv_image **out)
{
    uint64_t w, h, maxval;
    size_t i = 2;
    int ascii = b[1] == '2';
    *out = NULL;
    if (!number(b, n, &i, &w) || !number(b, n, &i, &h) || !number(b, n, &i, &maxval))
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: PGM header is truncated or malformed "
                         "(expected width, height and maxval)",
                         path);
    if (maxval < 1 || maxval > 65535)
        return rpiv_fail(RPIV_EFORMAT, "%s: PGM maxval %llu outside 1..65535", path,
                         (unsigned long long)maxval);
    rpiv_status st = img_check_size(path, w, h);
    if (st)
        return st;
    if (i >= n || !(b[i] == ' ' || b[i] == '\t' || b[i] == '\n' || b[i] == '\r'))
        return rpiv_fail(RPIV_EFORMAT, "%s: PGM header is not followed by pixel data", path);
    i++; /* the single whitespace after maxval */
    uint64_t bps = maxval > 255 ? 2 : 1, npx = w * h;
    if (!ascii && n - i < npx * bps)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: truncated PGM: %llu bytes of pixel data expected, %zu found", path,
                         (unsigned long long)(npx * bps), n - i);
    if (ascii && (n - i + 1) / 2 < npx) /* each value takes a digit and a separator */
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: truncated PGM: %llu values expected, at most %zu "
                         "present",
                         path, (unsigned long long)npx, (n - i + 1) / 2);
    rpiv_image *im;
    st = img_alloc(path, w, h, bits_for(maxval), &im);
    if (st)
        return st;
    for (uint64_t k = 0; k < npx; k++) {
        uint64_t v = 0;
        if (ascii) {
            st = ascii_value(path, b, n, &i, k, npx, w, maxval, &v);
            if (st) {
                rpiv_image_free(im);
                return st;
            }
        } else if (bps == 2) {
            v = (uint64_t)b[i + 2 * k] << 8 | b[i + 2 * k + 1];
        } else {
            v = b[i + k];
        }
        if (v > maxval) {
            rpiv_image_free(im);
            return rpiv_fail(RPIV_EFORMAT, "%s: PGM value %llu at (%llu, %llu) exceeds maxval %llu",
                             path, (unsigned long long)v, (unsigned long long)(k % w),
                             (unsigned long long)(k / w), (unsigned long long)maxval);
        }
        im->px[k] = (float)v;
    }
    *out = im;
    return RPIV_OK;
}
