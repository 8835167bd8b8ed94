/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image/prep_clahe.c - contrast-limited adaptive histogram equalisation (Zuiderveld 1994,
 * the form of MATLAB's adapthisteq that PIVlab applies): the image is cut into tiles; each
 * tile's histogram (bins over the image's grey range) is clipped at a limit, the excess spread
 * over all bins, and its cumulative sum is the tile's grey-level map; each pixel takes the
 * bilinear blend of the maps of the four tiles whose centres surround it. The output spans the
 * input's grey range. docs/preprocess.md. */
#include "prep_impl.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

typedef struct tiling {
    int w, h, tile, ntx, nty, bins;
    float lo, scale; /* bin = (v - lo) * scale */
} tiling;

static int tile_lo(int t, int tile)
{
    return t * tile;
}

static int tile_hi(int t, int tile, int n)
{
    int e = (t + 1) * tile;
    return e < n ? e : n;
}

/* Centre of tile t along an axis of n pixels. */
static double centre(int t, int tile, int n)
{
    return 0.5 * (double)(tile_lo(t, tile) + tile_hi(t, tile, n) - 1);
}

static int bin_of(const tiling *g, float v)
{
    int b = (int)((v - g->lo) * g->scale);
    return b < 0 ? 0 : (b >= g->bins ? g->bins - 1 : b);
}

/* The grey-level map of tile (tx, ty) into map[0..bins-1], using hist (bins counts). */
static void tile_map(const rpiv_image *im, const tiling *g, int tx, int ty, double clip, float hi,
                     size_t *hist, float *map)
{
    int x0 = tile_lo(tx, g->tile), x1 = tile_hi(tx, g->tile, g->w);
    int y0 = tile_lo(ty, g->tile), y1 = tile_hi(ty, g->tile, g->h);
    size_t B = (size_t)g->bins, npix = (size_t)(x1 - x0) * (size_t)(y1 - y0);
    memset(hist, 0, B * sizeof *hist);
    for (int y = y0; y < y1; y++)
        for (int x = x0; x < x1; x++)
            hist[bin_of(g, im->px[(size_t)y * (size_t)g->w + (size_t)x])]++;
    /* the clip limit as MATLAB normalises it: from the uniform height (clip = 0) to the whole
     * tile (clip = 1) */
    size_t minclip = (npix + B - 1) / B;
    size_t limit =
        minclip + (size_t)llround(clip * (double)(npix - (minclip < npix ? minclip : npix)));
    size_t excess = 0;
    for (size_t b = 0; b < B; b++)
        if (hist[b] > limit) {
            excess += hist[b] - limit;
            hist[b] = limit;
        }
    /* spread the excess evenly, the remainder one count per bin at an even step */
    size_t each = excess / B, rest = excess % B;
    for (size_t b = 0; b < B; b++)
        hist[b] += each;
    if (rest) {
        size_t step = B / rest;
        for (size_t b = 0, k = 0; k < rest; b += step, k++)
            hist[b]++;
    }
    size_t cum = 0;
    double span = (double)hi - (double)g->lo;
    for (size_t b = 0; b < B; b++) {
        cum += hist[b];
        map[b] = (float)((double)g->lo + span * (double)cum / (double)npix);
    }
}

/* The tiles t0 <= t1 whose centres surround coordinate c, and the weight of t1. */
static void between(double c, int tile, int n, int nt, int *t0, int *t1, float *f)
{
    int t = (int)(c / tile);
    if (t >= nt)
        t = nt - 1;
    if (c < centre(t, tile, n))
        t--;
    if (t < 0) {
        *t0 = *t1 = 0;
        *f = 0;
    } else if (t >= nt - 1) {
        *t0 = *t1 = nt - 1;
        *f = 0;
    } else {
        double a = centre(t, tile, n), b = centre(t + 1, tile, n);
        *t0 = t;
        *t1 = t + 1;
        *f = (float)((c - a) / (b - a));
    }
}

rpiv_status prep_clahe(rpiv_image *im, int tile, double clip, int bins, int nt)
{
    float lo, hi;
    prep_range(im, &lo, &hi);
    if (!(hi > lo))
        return RPIV_OK; /* one grey level: no contrast to equalise */
    tiling g = {im->w,
                im->h,
                tile,
                (im->w + tile - 1) / tile,
                (im->h + tile - 1) / tile,
                bins,
                lo,
                (float)bins / (hi - lo)};
    size_t ntiles = (size_t)g.ntx * (size_t)g.nty, B = (size_t)bins;
    float *maps = malloc(ntiles * B * sizeof *maps);
    size_t *hists = malloc((size_t)nt * B * sizeof *hists);
    if (!maps || !hists) {
        free(maps);
        free(hists);
        return rpiv_fail(RPIV_ENOMEM, "preprocess: out of memory for CLAHE (%zu tiles)", ntiles);
    }
#pragma omp parallel for schedule(static) num_threads(nt)
    for (size_t k = 0; k < ntiles; k++)
        tile_map(im, &g, (int)(k % (size_t)g.ntx), (int)(k / (size_t)g.ntx), clip, hi,
                 hists + (size_t)omp_get_thread_num() * B, maps + k * B);
    /* the column weights are the same for every row: once */
    int *tx = malloc(2 * (size_t)g.w * sizeof *tx);
    float *fxs = malloc((size_t)g.w * sizeof *fxs);
    if (!tx || !fxs) {
        free(tx);
        free(fxs);
        free(maps);
        free(hists);
        return rpiv_fail(RPIV_ENOMEM, "preprocess: out of memory for CLAHE");
    }
    for (int x = 0; x < g.w; x++)
        between(x, tile, g.w, g.ntx, &tx[2 * x], &tx[2 * x + 1], &fxs[x]);
    float *px = im->px;
#pragma omp parallel for schedule(static) num_threads(nt)
    for (int y = 0; y < g.h; y++) {
        int ty0, ty1;
        float fy;
        between(y, tile, g.h, g.nty, &ty0, &ty1, &fy);
        const float *r0 = maps + (size_t)ty0 * (size_t)g.ntx * B;
        const float *r1 = maps + (size_t)ty1 * (size_t)g.ntx * B;
        float *row = px + (size_t)y * (size_t)g.w;
        for (int x = 0; x < g.w; x++) {
            size_t b = (size_t)bin_of(&g, row[x]);
            size_t a0 = (size_t)tx[2 * x] * B + b, a1 = (size_t)tx[2 * x + 1] * B + b;
            float fx = fxs[x];
            float top = r0[a0] + fx * (r0[a1] - r0[a0]);
            float bot = r1[a0] + fx * (r1[a1] - r1[a0]);
            row[x] = top + fy * (bot - top);
        }
    }
    free(tx);
    free(fxs);
    free(maps);
    free(hists);
    return RPIV_OK;
}
