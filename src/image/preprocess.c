/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image/preprocess.c - the preprocessing list: parameters, parsing, the run in order, and
 * the two point operations (capping, inversion). The local filters are prep_local.c, CLAHE is
 * prep_clahe.c. */
#include "prep_impl.h"

#include <errno.h>
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *const rpiv_prep_background_names[] = {"min", "blur", NULL};
const char *const rpiv_prep_kind_names[] = {"clahe",     "highpass", "cap",
                                            "normalize", "invert",   NULL};

rpiv_preprocess_params rpiv_preprocess_params_default(void)
{
    rpiv_preprocess_params p;
    memset(&p, 0, sizeof p);
    p.clahe_tile_px = 64;
    p.clahe_clip = 0.01;
    p.clahe_bins = 256;
    p.clahe_low_pct = 0.0;
    p.clahe_high_pct = 100.0;
    p.highpass_px = 15;
    p.highpass_method = RPIV_PREP_BG_MIN;
    p.cap_k = 2.0;
    p.normalize_px = 15;
    return p;
}

static int size_ok(int s)
{
    return s >= 3 && s <= 1024;
}

rpiv_status rpiv_preprocess_params_check(const rpiv_preprocess_params *p)
{
    rpiv_prep_op op[RPIV_PREPROCESS_MAX_OPS];
    int n;
    if (!memchr(p->ops, '\0', sizeof p->ops))
        return rpiv_fail(RPIV_EINVAL, "preprocess.ops: longer than %d characters",
                         RPIV_PREPROCESS_LIST_MAX - 1);
    rpiv_status st = rpiv_preprocess_parse(p->ops, op, &n);
    if (st)
        return st;
    if (!size_ok(p->clahe_tile_px))
        return rpiv_fail(RPIV_EINVAL, "preprocess.clahe_tile_px = %d outside 3..1024",
                         p->clahe_tile_px);
    if (!(p->clahe_clip >= 0 && p->clahe_clip <= 1))
        return rpiv_fail(RPIV_EINVAL, "preprocess.clahe_clip = %g outside 0..1", p->clahe_clip);
    if (p->clahe_bins < 16 || p->clahe_bins > 65536)
        return rpiv_fail(RPIV_EINVAL, "preprocess.clahe_bins = %d outside 16..65536",
                         p->clahe_bins);
    if (!(p->clahe_low_pct >= 0 && p->clahe_low_pct < p->clahe_high_pct &&
          p->clahe_high_pct <= 100))
        return rpiv_fail(RPIV_EINVAL,
                         "preprocess.clahe_low_pct = %g, clahe_high_pct = %g: need 0 <= low < "
                         "high <= 100",
                         p->clahe_low_pct, p->clahe_high_pct);
    if (!size_ok(p->highpass_px))
        return rpiv_fail(RPIV_EINVAL, "preprocess.highpass_px = %d outside 3..1024",
                         p->highpass_px);
    if (p->highpass_method != RPIV_PREP_BG_MIN && p->highpass_method != RPIV_PREP_BG_BLUR)
        return rpiv_fail(RPIV_EINVAL, "preprocess.highpass_method: unknown method %d",
                         (int)p->highpass_method);
    if (!(p->cap_k >= 0.1 && p->cap_k <= 100))
        return rpiv_fail(RPIV_EINVAL, "preprocess.cap_k = %g outside 0.1..100", p->cap_k);
    if (!size_ok(p->normalize_px))
        return rpiv_fail(RPIV_EINVAL, "preprocess.normalize_px = %d outside 3..1024",
                         p->normalize_px);
    return RPIV_OK;
}

static const char accepted[] = "clahe[:TILE], highpass[:SIZE], cap, normalize[:SIZE], invert";

rpiv_status rpiv_preprocess_parse(const char *list, rpiv_prep_op op[RPIV_PREPROCESS_MAX_OPS],
                                  int *nops)
{
    int n = 0;
    rpiv_prep_op ops[RPIV_PREPROCESS_MAX_OPS];
    *nops = 0;
    if (!strcmp(list, "none"))
        return RPIV_OK;
    for (const char *w = list; *w;) {
        size_t len = strcspn(w, ",");
        if (len == 0)
            return rpiv_fail(RPIV_EINVAL, "preprocess '%s': an empty operation (expected %s)", list,
                             accepted);
        const char *colon = memchr(w, ':', len);
        size_t nlen = colon ? (size_t)(colon - w) : len;
        int k = 0;
        while (rpiv_prep_kind_names[k] && !(strlen(rpiv_prep_kind_names[k]) == nlen &&
                                            !strncmp(rpiv_prep_kind_names[k], w, nlen)))
            k++;
        if (!rpiv_prep_kind_names[k])
            return rpiv_fail(RPIV_EINVAL, "preprocess '%.*s': unknown operation (expected %s)",
                             (int)len, w, accepted);
        long size = 0;
        if (colon) {
            char *end;
            errno = 0;
            size = strtol(colon + 1, &end, 10);
            if (end == colon + 1 || end != w + len || errno ||
                !size_ok((int)(size > 2000 ? 2000 : size)))
                return rpiv_fail(RPIV_EINVAL,
                                 "preprocess '%.*s': the size must be a whole number 3..1024 (px)",
                                 (int)len, w);
            if (k == RPIV_PREP_CAP || k == RPIV_PREP_INVERT)
                return rpiv_fail(RPIV_EINVAL, "preprocess '%.*s': %s takes no size", (int)len, w,
                                 rpiv_prep_kind_names[k]);
        }
        if (n == RPIV_PREPROCESS_MAX_OPS)
            return rpiv_fail(RPIV_EINVAL, "preprocess '%s': more than %d operations", list,
                             RPIV_PREPROCESS_MAX_OPS);
        ops[n].kind = (rpiv_prep_kind)k;
        ops[n].size_px = (int)size;
        n++;
        w += len;
        if (*w == ',' && !*++w)
            return rpiv_fail(RPIV_EINVAL, "preprocess '%s': an empty operation at the end", list);
    }
    memcpy(op, ops, (size_t)n * sizeof *ops);
    *nops = n;
    return RPIV_OK;
}

/* The sum over row r (w values) of (v - c)^p, p = 1 or 2, in double: four partial sums over
 * x mod 4, added at the end (a fixed order whatever the threads). */
static double row_sum(const float *r, size_t w, double c, int p)
{
    double s[4] = {0, 0, 0, 0};
    size_t x = 0;
    for (; x + 4 <= w; x += 4)
        for (int k = 0; k < 4; k++) {
            double d = (double)r[x + (size_t)k] - c;
            s[k] += p == 1 ? d : d * d;
        }
    for (; x < w; x++) {
        double d = (double)r[x] - c;
        s[0] += p == 1 ? d : d * d;
    }
    return (s[0] + s[1]) + (s[2] + s[3]);
}

/* The sum over the image of (v - c)^p: each row's sum by one thread, then the rows in order,
 * so the same bits for any thread count. sums: h doubles. */
static double image_sum(const rpiv_image *im, double c, int p, double *sums, int nt)
{
    const size_t w = (size_t)im->w, h = (size_t)im->h;
    const float *px = im->px;
#pragma omp parallel for schedule(static) num_threads(nt)
    for (size_t y = 0; y < h; y++)
        sums[y] = row_sum(px + y * w, w, c, p);
    double s = 0;
    for (size_t y = 0; y < h; y++)
        s += sums[y];
    return s;
}

/* Values above mean + k std (over the whole image, in double) set to it. */
static rpiv_status cap(rpiv_image *im, double k, int nt)
{
    size_t n = (size_t)im->w * (size_t)im->h;
    double *sums = malloc((size_t)im->h * sizeof *sums);
    if (!sums)
        return rpiv_fail(RPIV_ENOMEM, "preprocess: out of memory for the capping");
    double mean = image_sum(im, 0, 1, sums, nt) / (double)n;
    double s2 = image_sum(im, mean, 2, sums, nt);
    free(sums);
    float top = (float)(mean + k * sqrt(s2 / (double)n));
    float *px = im->px;
#pragma omp parallel for schedule(static) num_threads(nt)
    for (size_t i = 0; i < n; i++)
        px[i] = px[i] > top ? top : px[i];
    return RPIV_OK;
}

static void invert(rpiv_image *im, int nt)
{
    float lo, hi;
    prep_range(im, &lo, &hi, nt);
    size_t n = (size_t)im->w * (size_t)im->h;
    float *px = im->px;
#pragma omp parallel for schedule(static) num_threads(nt)
    for (size_t i = 0; i < n; i++)
        px[i] = (hi - px[i]) + lo;
}

rpiv_status rpiv_preprocess_run(const rpiv_preprocess_params *p, rpiv_image *im, int nthreads)
{
    rpiv_prep_op op[RPIV_PREPROCESS_MAX_OPS];
    int n = 0;
    rpiv_status st = rpiv_preprocess_params_check(p);
    if (!st)
        st = rpiv_preprocess_parse(p->ops, op, &n);
    int nt = nthreads > 0 ? nthreads : omp_get_max_threads();
    for (int k = 0; !st && k < n; k++) {
        const rpiv_prep_op *o = &op[k];
        switch (o->kind) {
        case RPIV_PREP_CLAHE:
            if (k + 1 < n && op[k + 1].kind == RPIV_PREP_HIGHPASS &&
                p->highpass_method == RPIV_PREP_BG_MIN) { /* the two in one (the same bits) */
                st = prep_clahe_highpass(
                    im, o->size_px ? o->size_px : p->clahe_tile_px, p->clahe_clip, p->clahe_bins,
                    p->clahe_low_pct, p->clahe_high_pct,
                    op[k + 1].size_px ? op[k + 1].size_px : p->highpass_px, nt);
                k++;
            } else {
                st = prep_clahe(im, o->size_px ? o->size_px : p->clahe_tile_px, p->clahe_clip,
                                p->clahe_bins, p->clahe_low_pct, p->clahe_high_pct, nt, NULL);
            }
            break;
        case RPIV_PREP_HIGHPASS:
            st =
                prep_highpass(im, o->size_px ? o->size_px : p->highpass_px, p->highpass_method, nt);
            break;
        case RPIV_PREP_CAP:
            st = cap(im, p->cap_k, nt);
            break;
        case RPIV_PREP_NORMALIZE:
            st = prep_normalize(im, o->size_px ? o->size_px : p->normalize_px, nt);
            break;
        case RPIV_PREP_INVERT:
            invert(im, nt);
            break;
        }
    }
    return st;
}
