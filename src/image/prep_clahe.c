/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/image/prep_clahe.c - contrast-limited adaptive histogram equalisation (Zuiderveld 1994,
 * the form of MATLAB's adapthisteq that PIVlab applies): the image is cut into tiles; each
 * tile's histogram (bins over the image's grey range) is clipped at a limit and the excess
 * redistributed so that no bin exceeds the limit (prep_clahe_clip); its cumulative sum is the
 * tile's grey-level map; each pixel takes the bilinear blend of the maps of the four tiles
 * whose centres surround it. The output spans the input's grey range. docs/preprocess.md.
 *
 * Speed: the frame is read twice: for its range (SSE min/max), then once by tile rows, each
 * thread on a run of whole tile rows: a tile row's bins and maps, then the output rows of the
 * tile row before it from the same bins, still in cache (clahe_share). The bins of a row are
 * computed in one vectorisable loop; the histogram counts into four sub-histograms in turn (a
 * dark image puts most pixels in a few bins: one histogram would make each increment wait for
 * the previous store to the same bin); the blend walks a row span by span between tile
 * centres, so the four maps of a span are fixed. A prep_sink takes the output rows while they
 * are in cache (highpass after clahe: prep_clahe_highpass). */
#include "prep_impl.h"

#include <math.h>
#include <omp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

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

/* b[i] = the bin of x[i], i < n: (x - lo) * scale truncated, clamped to 0..bins-1 (a NaN to
 * 0). Clamping the float before the truncation gives the same bin as clamping the integer. */
static void bins_of(const tiling *g, const float *restrict x, int n, uint16_t *restrict b)
{
    const float lo = g->lo, scale = g->scale, top = (float)(g->bins - 1);
    for (int i = 0; i < n; i++) {
        float v = (x[i] - lo) * scale;
        v = v >= 0 ? v : 0;
        v = v < top ? v : top;
        b[i] = (uint16_t)(int32_t)v;
    }
}

void prep_clahe_clip(size_t *hist, size_t nbins, size_t limit)
{
    size_t excess = 0;
    for (size_t b = 0; b < nbins; b++)
        if (hist[b] > limit)
            excess += hist[b] - limit;
    /* the whole share of each bin first: a bin that it would lift above the limit is filled
     * to the limit only, the rest of its share stays in the excess */
    const size_t each = excess / nbins;
    for (size_t b = 0; b < nbins; b++) {
        if (hist[b] >= limit) {
            hist[b] = limit; /* its excess is counted */
        } else if (hist[b] + each >= limit) {
            excess -= limit - hist[b];
            hist[b] = limit;
        } else {
            excess -= each;
            hist[b] += each;
        }
    }
    /* what remains, one count at a time on the bins below the limit, every step-th bin from a
     * start that moves on by one each round; the step grows as the excess shrinks. It ends:
     * the limit is at least the uniform height, so the bins can hold the whole tile, and each
     * bin is a start once every nbins rounds. */
    for (size_t start = 0; excess > 0; start = start + 1 < nbins ? start + 1 : 0) {
        size_t step = nbins / excess > 1 ? nbins / excess : 1;
        for (size_t b = start; b < nbins && excess > 0; b += step)
            if (hist[b] < limit) {
                hist[b]++;
                excess--;
            }
    }
}

/* Per-thread scratch of the histograms. */
typedef struct clahe_scratch {
    uint32_t *h4; /* 4 sub-histograms of bins counts */
    size_t *hist; /* bins counts */
} clahe_scratch;

/* The bins of the input rows of tile row ty (of px) into bin (tile x w), row by row. */
static void band_bins(const tiling *g, const float *px, int ty, uint16_t *bin)
{
    const int y0 = tile_lo(ty, g->tile), y1 = tile_hi(ty, g->tile, g->h);
    for (int y = y0; y < y1; y++)
        bins_of(g, px + (size_t)y * (size_t)g->w, g->w, bin + (size_t)(y - y0) * (size_t)g->w);
}

/* The grey-level maps of the tiles of tile row ty into maps[tx * bins ...] from the bins of
 * its rows (band_bins), each tile's histogram in turn. */
static void band_maps(const tiling *g, int ty, double clip, float hi, const uint16_t *bin,
                      const clahe_scratch *s, float *maps)
{
    const int y0 = tile_lo(ty, g->tile), y1 = tile_hi(ty, g->tile, g->h);
    const size_t B = (size_t)g->bins, W = (size_t)g->w;
    for (int tx = 0; tx < g->ntx; tx++) {
        const int x0 = tile_lo(tx, g->tile), x1 = tile_hi(tx, g->tile, g->w), n = x1 - x0;
        const size_t npix = (size_t)n * (size_t)(y1 - y0);
        uint32_t *h4 = s->h4;
        memset(h4, 0, 4 * B * sizeof *h4);
        for (int y = y0; y < y1; y++) {
            const uint16_t *b = bin + (size_t)(y - y0) * W + (size_t)x0;
            int x = 0;
            for (; x + 4 <= n; x += 4) {
                h4[b[x]]++;
                h4[B + b[x + 1]]++;
                h4[2 * B + b[x + 2]]++;
                h4[3 * B + b[x + 3]]++;
            }
            for (; x < n; x++)
                h4[b[x]]++;
        }
        size_t *hist = s->hist;
        for (size_t k = 0; k < B; k++)
            hist[k] = (size_t)h4[k] + h4[B + k] + h4[2 * B + k] + h4[3 * B + k];
        /* the clip limit as MATLAB normalises it: from the uniform height (clip = 0) to the
         * whole tile (clip = 1) */
        size_t minclip = (npix + B - 1) / B;
        size_t limit =
            minclip + (size_t)llround(clip * (double)(npix - (minclip < npix ? minclip : npix)));
        prep_clahe_clip(hist, B, limit);
        size_t cum = 0;
        double span = (double)hi - (double)g->lo;
        float *map = maps + (size_t)tx * B;
        for (size_t k = 0; k < B; k++) {
            cum += hist[k];
            map[k] = (float)((double)g->lo + span * (double)cum / (double)npix);
        }
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

/* One span of a row whose pixels lie between the same two tile columns t0, t1: q[4 bin ...]
 * the maps {upper t0, lower t0, upper t1, lower t1} of each bin, weights fx (per pixel) and
 * fy. With SSE2, four pixels at a time: their four quads loaded and transposed, the same
 * operations lane by lane as the scalar form (the same bits). */
static void blend_span(float *restrict row, const uint16_t *restrict bin, const float *restrict fx,
                       int n, const float *restrict q, float fy)
{
    int x = 0;
#if defined(__SSE2__)
    const __m128 vfy = _mm_set1_ps(fy);
    for (; x + 4 <= n; x += 4) {
        __m128 m00 = _mm_load_ps(q + 4 * (size_t)bin[x]),
               m10 = _mm_load_ps(q + 4 * (size_t)bin[x + 1]);
        __m128 m01 = _mm_load_ps(q + 4 * (size_t)bin[x + 2]),
               m11 = _mm_load_ps(q + 4 * (size_t)bin[x + 3]);
        _MM_TRANSPOSE4_PS(m00, m10, m01, m11); /* rows: upper t0, lower t0, upper t1, lower t1 */
        __m128 f = _mm_loadu_ps(fx + x);
        __m128 top = _mm_add_ps(m00, _mm_mul_ps(f, _mm_sub_ps(m01, m00)));
        __m128 bot = _mm_add_ps(m10, _mm_mul_ps(f, _mm_sub_ps(m11, m10)));
        _mm_storeu_ps(row + x, _mm_add_ps(top, _mm_mul_ps(vfy, _mm_sub_ps(bot, top))));
    }
#endif
    for (; x < n; x++) {
        const float *m = q + 4 * (size_t)bin[x];
        float top = m[0] + fx[x] * (m[2] - m[0]);
        float bot = m[1] + fx[x] * (m[3] - m[1]);
        row[x] = top + fy * (bot - top);
    }
}

enum { PCT_BINS = 4096 }; /* the fine histogram of the percentiles */

/* The range of the CLAHE bins: [*a, *b] from the low-th to the high-th percentile (in %) of
 * im, whose range is lo < hi, as MATLAB's stretchlim finds them (the auto contrast stretch
 * that PIVlab applies before CLAHE by default): on a histogram of PCT_BINS bins over
 * [lo, hi], *a the lower edge of the first bin whose cumulative count exceeds low % of the
 * pixels, *b the upper edge of the first bin whose cumulative count reaches high %; if both
 * are the same bin (an image of one level but for a few pixels), the whole range. Counts in
 * integers, per thread then summed: exact for any thread count. */
static rpiv_status pct_range(const rpiv_image *im, float lo, float hi, double low, double high,
                             int nt, float *a, float *b)
{
    *a = lo;
    *b = hi;
    if (low <= 0 && high >= 100)
        return RPIV_OK;
    const size_t w = (size_t)im->w, h = (size_t)im->h, n = w * h;
    uint32_t *cnt = calloc((size_t)nt * 4 * PCT_BINS, sizeof *cnt);
    if (!cnt)
        return rpiv_fail(RPIV_ENOMEM, "preprocess: out of memory for CLAHE's percentiles");
    const float scale = (float)PCT_BINS / (hi - lo), top = (float)(PCT_BINS - 1);
    const float *px = im->px;
#pragma omp parallel for schedule(static) num_threads(nt)
    for (size_t y = 0; y < h; y++) {
        /* four sub-histograms in turn: a dark image puts most pixels in a few bins */
        uint32_t *c = cnt + (size_t)omp_get_thread_num() * 4 * PCT_BINS;
        const float *r = px + y * w;
        for (size_t x = 0; x < w; x++) {
            float v = (r[x] - lo) * scale;
            v = v >= 0 ? v : 0;
            v = v < top ? v : top;
            c[(x & 3) * PCT_BINS + (size_t)(int32_t)v]++;
        }
    }
    size_t k = 0, klo = 0, khi = PCT_BINS - 1;
    double cum = 0, tlo = low / 100 * (double)n, thi = high / 100 * (double)n;
    int have_lo = 0;
    for (; k < PCT_BINS; k++) {
        for (size_t t = 0; t < 4 * (size_t)nt; t++)
            cum += (double)cnt[t * PCT_BINS + k];
        if (!have_lo && cum > tlo) {
            klo = k;
            have_lo = 1;
        }
        if (cum >= thi) {
            khi = k;
            break;
        }
    }
    free(cnt);
    if (khi > klo) {
        const double step = ((double)hi - (double)lo) / PCT_BINS;
        *a = (float)((double)lo + step * (double)klo);
        *b = khi + 1 >= PCT_BINS ? hi : (float)((double)lo + step * (double)(khi + 1));
    }
    return RPIV_OK;
}

/* The least and greatest values of im: the rows' ranges, then combined in row order (the same
 * bits for any thread count). rng: 2 h floats. */
static void image_range(const rpiv_image *im, float *rng, int nt, float *lo, float *hi)
{
    const size_t w = (size_t)im->w, h = (size_t)im->h;
    const float *px = im->px;
#pragma omp parallel for schedule(static) num_threads(nt)
    for (size_t y = 0; y < h; y++)
        prep_row_range(px + y * w, w, &rng[2 * y], &rng[2 * y + 1]);
    float mn = px[0], mx = px[0];
    for (size_t y = 0; y < h; y++) {
        mn = rng[2 * y] < mn ? rng[2 * y] : mn;
        mx = rng[2 * y + 1] > mx ? rng[2 * y + 1] : mx;
    }
    *lo = mn;
    *hi = mx;
}

/* What the threads of prep_clahe share. */
typedef struct clahe_job {
    const tiling *g;
    double clip;
    float hi;
    float *px, *maps;     /* the image (input, then output), the maps of every tile */
    size_t band;          /* the bins of a tile row's rows: min(tile, h) x w */
    const int *tx, *span; /* the tile columns t0, t1 of each pixel column, the spans' starts */
    const float *fxs;     /* each pixel column's weight of t1 */
    int nspan;
    const prep_sink *sink; /* or NULL */
} clahe_job;

/* The output rows of tile row ty from the bins b of its input rows and the maps of tile rows
 * ty - 1 .. ty + 1 (those that exist). q: the thread's quads, of the tile rows *q0, *q1. */
static void blend_band(const clahe_job *j, int ty, const uint16_t *b, float *q, int *q0, int *q1)
{
    const tiling *g = j->g;
    const size_t B = (size_t)g->bins, W = (size_t)g->w;
    const int y0 = tile_lo(ty, g->tile), y1 = tile_hi(ty, g->tile, g->h);
    for (int y = y0; y < y1; y++) {
        int ty0, ty1;
        float fy;
        between(y, g->tile, g->h, g->nty, &ty0, &ty1, &fy);
        if (ty0 != *q0 || ty1 != *q1) {
            /* per span, its four maps interleaved bin by bin: {upper t0, lower t0, upper t1,
             * lower t1} */
            const float *r0 = j->maps + (size_t)ty0 * (size_t)g->ntx * B;
            const float *r1 = j->maps + (size_t)ty1 * (size_t)g->ntx * B;
            for (int k = 0; k < j->nspan; k++) {
                size_t a0 = (size_t)j->tx[2 * j->span[k]] * B,
                       a1 = (size_t)j->tx[2 * j->span[k] + 1] * B;
                float *qk = q + (size_t)k * B * 4;
                for (size_t v = 0; v < B; v++) {
                    qk[4 * v] = r0[a0 + v];
                    qk[4 * v + 1] = r1[a0 + v];
                    qk[4 * v + 2] = r0[a1 + v];
                    qk[4 * v + 3] = r1[a1 + v];
                }
            }
            *q0 = ty0;
            *q1 = ty1;
        }
        float *row = j->px + (size_t)y * W;
        const uint16_t *by = b + (size_t)(y - y0) * W;
        for (int k = 0; k < j->nspan; k++) {
            int x0 = j->span[k];
            blend_span(row + x0, by + x0, j->fxs + x0, j->span[k + 1] - x0, q + (size_t)k * B * 4,
                       fy);
        }
    }
}

/* One thread's share, the tile rows ta..tb-1, in place: their maps, then their output rows.
 * First the maps of the share's first and last tile rows, then a barrier: the output rows
 * next to a share's ends are blended from maps that the neighbouring thread computes from its
 * input rows, which must all be read before any is overwritten. Then tile row by tile row,
 * the maps of the next one (from its bins, which stay in cache for its own output rows at the
 * next turn) and the output rows of this one, whose three maps are now there. bin2: two bands'
 * bins (tile x w each). */
static void clahe_share(const clahe_job *j, int ta, int tb, const clahe_scratch *s, uint16_t *bin2,
                        float *q)
{
    const tiling *g = j->g;
    const size_t B = (size_t)g->bins, band = j->band, row_maps = (size_t)g->ntx * B;
    if (ta < tb) {
        band_bins(g, j->px, ta, bin2 + (size_t)(ta & 1) * band);
        band_maps(g, ta, j->clip, j->hi, bin2 + (size_t)(ta & 1) * band, s,
                  j->maps + (size_t)ta * row_maps);
    }
    if (tb - 1 > ta) { /* its bins are computed again at its turn: the other buffer is in use */
        uint16_t *b = bin2 + (size_t)((ta + 1) & 1) * band;
        band_bins(g, j->px, tb - 1, b);
        band_maps(g, tb - 1, j->clip, j->hi, b, s, j->maps + (size_t)(tb - 1) * row_maps);
    }
#pragma omp barrier
    int q0 = -1, q1 = -1;
    for (int ty = ta; ty < tb; ty++) {
        uint16_t *b = bin2 + (size_t)(ty & 1) * band, *bn = bin2 + (size_t)((ty + 1) & 1) * band;
        if (ty == tb - 1 && ty > ta)
            band_bins(g, j->px, ty, b);
        if (ty + 1 < tb - 1) { /* an inner tile row */
            band_bins(g, j->px, ty + 1, bn);
            band_maps(g, ty + 1, j->clip, j->hi, bn, s, j->maps + (size_t)(ty + 1) * row_maps);
        }
        blend_band(j, ty, b, q, &q0, &q1);
        if (j->sink)
            j->sink->rows(j->sink->ctx, tile_lo(ta, g->tile), tile_hi(tb - 1, g->tile, g->h),
                          tile_lo(ty, g->tile), tile_hi(ty, g->tile, g->h));
    }
}

rpiv_status prep_clahe(rpiv_image *im, int tile, double clip, int bins, double low_pct,
                       double high_pct, int nt, const prep_sink *sink)
{
    float lo, hi;
    float *rng = malloc(2 * (size_t)im->h * sizeof *rng);
    if (!rng)
        return rpiv_fail(RPIV_ENOMEM, "preprocess: out of memory for CLAHE's range");
    image_range(im, rng, nt, &lo, &hi);
    free(rng);
    if (!(hi > lo))
        return RPIV_OK; /* one grey level: no contrast to equalise */
    rpiv_status st = pct_range(im, lo, hi, low_pct, high_pct, nt, &lo, &hi);
    if (st)
        return st;
    tiling g = {im->w,
                im->h,
                tile,
                (im->w + tile - 1) / tile,
                (im->h + tile - 1) / tile,
                bins,
                lo,
                (float)bins / (hi - lo)};
    const size_t ntiles = (size_t)g.ntx * (size_t)g.nty, B = (size_t)bins, W = (size_t)g.w;
    const size_t band = (size_t)(tile < g.h ? tile : g.h) * W;
    float *maps = malloc(ntiles * B * sizeof *maps);
    uint32_t *h4 = malloc((size_t)nt * 4 * B * sizeof *h4);
    uint16_t *bin = malloc((size_t)nt * 2 * band * sizeof *bin);
    size_t *hist = malloc((size_t)nt * B * sizeof *hist);
    /* the tile columns t0, t1 of each pixel column, its weight of t1, the spans' starts */
    int *tx = malloc(2 * W * sizeof *tx), *span = malloc((W + 1) * sizeof *span);
    float *fxs = malloc(W * sizeof *fxs), *quads = NULL;
    if (!maps || !h4 || !bin || !hist || !tx || !span || !fxs) {
        st = rpiv_fail(RPIV_ENOMEM, "preprocess: out of memory for CLAHE (%zu tiles)", ntiles);
        goto cleanup;
    }
    /* the column weights are the same for every row: once */
    int nspan = 0;
    for (int x = 0; x < g.w; x++) {
        between(x, tile, g.w, g.ntx, &tx[2 * x], &tx[2 * x + 1], &fxs[x]);
        if (x == 0 || tx[2 * x] != tx[2 * x - 2] || tx[2 * x + 1] != tx[2 * x - 1])
            span[nspan++] = x;
    }
    span[nspan] = g.w;
    quads = malloc((size_t)nt * (size_t)nspan * B * 4 * sizeof *quads);
    if (!quads) {
        st = rpiv_fail(RPIV_ENOMEM, "preprocess: out of memory for CLAHE (%zu tiles)", ntiles);
        goto cleanup;
    }
    const clahe_job job = {&g, clip, hi, im->px, maps, band, tx, span, fxs, nspan, sink};
    /* each thread a run of whole tile rows; every output row is computed from the same maps
     * and bins whatever the share: the same bits for any thread count */
#pragma omp parallel num_threads(nt)
    {
        const int me = omp_get_thread_num(), team = omp_get_num_threads();
        const clahe_scratch s = {h4 + (size_t)me * 4 * B, hist + (size_t)me * B};
        clahe_share(&job, (int)((long)g.nty * me / team), (int)((long)g.nty * (me + 1) / team), &s,
                    bin + (size_t)me * 2 * band, quads + (size_t)me * (size_t)nspan * B * 4);
    }
cleanup:
    free(quads);
    free(fxs);
    free(span);
    free(tx);
    free(hist);
    free(bin);
    free(h4);
    free(maps);
    return st;
}
