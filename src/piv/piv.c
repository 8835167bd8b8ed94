/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/piv.c - the PIV plan: grids, buffers, loading, deformation, one pass (the passes of a
 * whole run: src/piv/refine.c). */
#include "piv_impl.h"

#include "rpiv/validate.h"

#include "deform_impl.h"
#include "uncertainty_impl.h"
#include "validate_impl.h"

#include "base/hash.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

/* ---- plan --------------------------------------------------------------------------------- */

static void pass_free(piv_pass *ps, int nthreads)
{
    if (ps->ws)
        for (int t = 0; t < nthreads; t++)
            rpiv_xcorr_work_free(ps->ws[t]);
    free(ps->ws);
    rpiv_xcorr_free(ps->xc);
    free(ps->masked);
    memset(ps, 0, sizeof *ps);
}

void rpiv_piv_free(rpiv_piv *pv)
{
    if (!pv)
        return;
    for (int k = 0; k < pv->npass; k++)
        pass_free(&pv->pass[k], pv->nthreads);
    free(pv->mask);
    free(pv->bga);
    free(pv->bgb);
    free(pv->ia);
    free(pv->ib);
    free(pv->prep);
    unc_chain_free(pv->unc);
    free(pv);
}

/* The grid of pass k inside the ROI. */
static rpiv_status pass_grid(rpiv_piv *pv, int k)
{
    piv_pass *ps = &pv->pass[k];
    const rpiv_piv_params *p = &pv->p;
    int rw = pv->roi[2] - pv->roi[0], rh = pv->roi[3] - pv->roi[1];
    ps->ww = p->win_w[k];
    ps->wh = p->win_h[k];
    if (ps->ww > rw || ps->wh > rh)
        return rpiv_fail(RPIV_ESIZE,
                         "piv.windows: window %dx%d of pass %d is larger than the %s "
                         "(%dx%d px)",
                         ps->ww, ps->wh, k + 1, rw == pv->w && rh == pv->h ? "image" : "ROI", rw,
                         rh);
    ps->sx = p->step_px > 0 ? p->step_px : (int)lround(ps->ww * (1 - p->overlap));
    ps->sy = p->step_px > 0 ? p->step_px : (int)lround(ps->wh * (1 - p->overlap));
    ps->sx = ps->sx < 1 ? 1 : ps->sx;
    ps->sy = ps->sy < 1 ? 1 : ps->sy;
    ps->nx = (rw - ps->ww) / ps->sx + 1;
    ps->ny = (rh - ps->wh) / ps->sy + 1;
    ps->ox = pv->roi[0] + (rw - ps->ww - (ps->nx - 1) * ps->sx) / 2;
    ps->oy = pv->roi[1] + (rh - ps->wh - (ps->ny - 1) * ps->sy) / 2;
    ps->rect[0] = ps->ox;
    ps->rect[1] = ps->oy;
    ps->rect[2] = ps->ox + (ps->nx - 1) * ps->sx + ps->ww;
    ps->rect[3] = ps->oy + (ps->ny - 1) * ps->sy + ps->wh;
    ps->nwin = (size_t)ps->nx * (size_t)ps->ny;
    return RPIV_OK;
}

/* Flag the windows of pass k with more than half of their pixels masked. */
static rpiv_status pass_mask(rpiv_piv *pv, int k)
{
    piv_pass *ps = &pv->pass[k];
    ps->masked = calloc(ps->nwin, 1);
    if (!ps->masked)
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the mask");
#pragma omp parallel for schedule(static) num_threads(pv->nthreads)
    for (size_t win = 0; win < ps->nwin; win++) {
        int x0 = ps->ox + (int)(win % (size_t)ps->nx) * ps->sx;
        int y0 = ps->oy + (int)(win / (size_t)ps->nx) * ps->sy;
        long count = 0;
        for (int y = y0; y < y0 + ps->wh; y++) {
            const unsigned char *m = pv->mask + (size_t)y * (size_t)pv->w + (size_t)x0;
            for (int x = 0; x < ps->ww; x++)
                count += m[x];
        }
        ps->masked[win] = 2 * count > (long)ps->ww * ps->wh;
    }
    return RPIV_OK;
}

static float *frame_alloc(rpiv_piv *pv)
{
    size_t n = (size_t)pv->w * (size_t)pv->h;
    float *f = malloc(n * sizeof *f);
    if (f)
        pv->bytes += n * sizeof *f;
    return f;
}

rpiv_status rpiv_piv_new(const rpiv_piv_params *p, int w, int h, const rpiv_image *mask,
                         rpiv_piv **out)
{
    rpiv_status st;
    *out = NULL;
    if ((st = rpiv_piv_params_check(p)))
        return st;
    if (w < 1 || h < 1)
        return rpiv_fail(RPIV_EINVAL, "piv: image size %dx%d", w, h);
    if (mask && (mask->w != w || mask->h != h))
        return rpiv_fail(RPIV_ESIZE, "piv.mask: mask is %dx%d, the images %dx%d", mask->w, mask->h,
                         w, h);
    const int *r = p->roi;
    int whole = !r[0] && !r[1] && !r[2] && !r[3];
    if (!whole && (r[0] < 0 || r[1] < 0 || r[2] > w || r[3] > h || r[0] >= r[2] || r[1] >= r[3]))
        return rpiv_fail(RPIV_ESIZE,
                         "piv.roi: %d,%d,%d,%d is not a region of the %dx%d image "
                         "(x0,y0,x1,y1 with 0 <= x0 < x1 <= width, 0 <= y0 < y1 <= height)",
                         r[0], r[1], r[2], r[3], w, h);
    /* memory first, so that a refused run allocates nothing large */
    double frames = (2.0 + (mask ? 0.25 : 0)) * (double)w * (double)h * 4;
    if (frames / 1048576.0 > p->max_mem_mb)
        return rpiv_fail(RPIV_ELIMIT, "piv: %dx%d frames need %.0f MB, above piv.max_mem_mb = %g",
                         w, h, frames / 1048576.0, p->max_mem_mb);

    rpiv_piv *pv = calloc(1, sizeof *pv);
    if (!pv)
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory");
    pv->p = *p;
    pv->w = w;
    pv->h = h;
    pv->nthreads = p->threads > 0 ? p->threads : omp_get_max_threads();
    pv->npass = p->npass;
    if (whole) {
        pv->roi[2] = w;
        pv->roi[3] = h;
    } else {
        memcpy(pv->roi, r, sizeof pv->roi);
    }
    for (int k = 0; k < pv->npass; k++)
        if ((st = pass_grid(pv, k)))
            goto out_free;
    if (mask) {
        size_t n = (size_t)w * (size_t)h;
        pv->mask = malloc(n);
        if (!pv->mask)
            goto out_nomem;
        pv->bytes += n;
        for (size_t i = 0; i < n; i++)
            pv->mask[i] = mask->px[i] == 0;
        for (int k = 0; k < pv->npass; k++)
            if ((st = pass_mask(pv, k)))
                goto out_free;
    }
    pv->ia = frame_alloc(pv);
    pv->ib = frame_alloc(pv);
    if (!pv->ia || !pv->ib)
        goto out_nomem;
    if (p->prep.ops[0] && !(pv->prep = frame_alloc(pv)))
        goto out_nomem;
    pv->deforms = p->deform && p->npass > 1;
    for (int k = 0; k < pv->npass; k++) {
        piv_pass *ps = &pv->pass[k];
        /* passes with the same window size could share plans; they are cheap to make */
        if ((st = rpiv_xcorr_new(ps->ww, ps->wh, &ps->xc)))
            goto out_free;
        ps->ws = calloc((size_t)pv->nthreads, sizeof *ps->ws);
        if (!ps->ws)
            goto out_nomem;
        for (int t = 0; t < pv->nthreads; t++) {
            if ((st = rpiv_xcorr_work_new(ps->xc, &ps->ws[t])))
                goto out_free;
            pv->bytes += (size_t)ps->ww * (size_t)ps->wh * 4 * sizeof(float);
        }
    }
    *out = pv;
    return RPIV_OK;
out_nomem:
    st = rpiv_fail(RPIV_ENOMEM, "piv: out of memory for %dx%d frames", w, h);
out_free:
    rpiv_piv_free(pv);
    return st;
}

int rpiv_piv_npass(const rpiv_piv *pv)
{
    return pv->npass;
}

int rpiv_piv_threads(const rpiv_piv *pv)
{
    return pv->nthreads;
}

const rpiv_piv_params *rpiv_piv_params_of(const rpiv_piv *pv)
{
    return &pv->p;
}

size_t rpiv_piv_memory(const rpiv_piv *pv)
{
    return pv->bytes;
}

void rpiv_piv_size(const rpiv_piv *pv, int *w, int *h)
{
    *w = pv->w;
    *h = pv->h;
}

uint64_t rpiv_piv_hash_frames(const rpiv_piv *pv, uint64_t h)
{
    size_t npx = (size_t)pv->w * (size_t)pv->h;
    if (pv->mask)
        h = hash_bytes(h, pv->mask, npx);
    if (pv->bga) {
        h = hash_bytes(h, pv->bga, npx * sizeof *pv->bga);
        h = hash_bytes(h, pv->bgb, npx * sizeof *pv->bgb);
    }
    return h;
}

rpiv_status rpiv_piv_grid(const rpiv_piv *pv, int pass, rpiv_field **out)
{
    *out = NULL;
    if (pass < 0 || pass >= pv->npass)
        return rpiv_fail(RPIV_EINVAL, "piv: pass %d outside 0..%d", pass, pv->npass - 1);
    const piv_pass *ps = &pv->pass[pass];
    double c = piv_shift(pv, pass);
    rpiv_status st = rpiv_field_new(ps->nx, ps->ny, ps->ox + 0.5 * (ps->ww - 1) + c,
                                    ps->oy + 0.5 * (ps->wh - 1) + c, ps->sx, ps->sy, out);
    if (st)
        return st;
    (*out)->scale_mm_per_px = pv->p.scale_mm_per_px;
    (*out)->dt_s = pv->p.dt_s;
    return RPIV_OK;
}

rpiv_status rpiv_piv_set_background(rpiv_piv *pv, const rpiv_image *bg_a, const rpiv_image *bg_b)
{
    size_t n = (size_t)pv->w * (size_t)pv->h;
    if (pv->bga) {
        free(pv->bga);
        free(pv->bgb);
        pv->bga = pv->bgb = NULL;
        pv->bytes -= 2 * n * sizeof(float);
    }
    if (!bg_a && !bg_b)
        return RPIV_OK;
    if (!bg_a || !bg_b || bg_a->w != pv->w || bg_a->h != pv->h || bg_b->w != pv->w ||
        bg_b->h != pv->h)
        return rpiv_fail(RPIV_ESIZE, "piv: background frames must both be %dx%d", pv->w, pv->h);
    pv->bga = frame_alloc(pv);
    pv->bgb = frame_alloc(pv);
    if (!pv->bga || !pv->bgb) {
        rpiv_status st = rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the background");
        free(pv->bga);
        free(pv->bgb);
        pv->bga = pv->bgb = NULL;
        pv->bytes -= 2 * n * sizeof(float); /* frame_alloc counted what it got, roughly */
        return st;
    }
    memcpy(pv->bga, bg_a->px, n * sizeof(float));
    memcpy(pv->bgb, bg_b->px, n * sizeof(float));
    return RPIV_OK;
}

/* ---- loading ------------------------------------------------------------------------------- */

/* Lanes of the row sums in load_frame: independent float accumulators the compiler keeps in
 * vector registers (one running double sum is a serial chain of additions, ~4 cycles a
 * pixel). A lane sums at most w / 16 grey levels: exact for 16-bit integers up to w = 4096,
 * within 1e-7 relative otherwise; lanes are combined in double in a fixed order. */
#define ROW_LANES 16

/* dst = src - bg; the mean over unmasked pixels; masked pixels set to it. Row sums are
 * combined in row order, so the mean does not depend on the thread count. */
static float load_frame(const rpiv_piv *pv, const float *src, const float *bg, float *dst,
                        double *rows, long *counts)
{
    const int w = pv->w, h = pv->h;
#pragma omp parallel for schedule(static) num_threads(pv->nthreads)
    for (int y = 0; y < h; y++) {
        const size_t o = (size_t)y * (size_t)w;
        const float *restrict in = src + o, *restrict b = bg ? bg + o : NULL;
        float *restrict out = dst + o;
        if (b)
            for (int x = 0; x < w; x++)
                out[x] = in[x] - b[x];
        else if (out != in) /* in == out: frames given to the plan (piv_pairs.c) */
            memcpy(out, in, (size_t)w * sizeof *out);
        double s = 0;
        long c = 0;
        if (!pv->mask) {
            float acc[ROW_LANES] = {0};
            int x = 0;
            for (; x + ROW_LANES <= w; x += ROW_LANES)
                for (int l = 0; l < ROW_LANES; l++)
                    acc[l] += out[x + l];
            for (; x < w; x++)
                s += (double)out[x];
            for (int l = 0; l < ROW_LANES; l++)
                s += (double)acc[l];
            c = w;
        } else {
            const unsigned char *m = pv->mask + o;
            for (int x = 0; x < w; x++)
                if (!m[x]) {
                    s += (double)out[x];
                    c++;
                }
        }
        rows[y] = s;
        counts[y] = c;
    }
    double s = 0;
    long c = 0;
    for (int y = 0; y < h; y++) {
        s += rows[y];
        c += counts[y];
    }
    float mean = c ? (float)(s / (double)c) : 0.0f;
    if (pv->mask) {
        size_t n = (size_t)w * (size_t)h;
        for (size_t i = 0; i < n; i++)
            if (pv->mask[i])
                dst[i] = mean;
    }
    return mean;
}

rpiv_status rpiv_piv_load(rpiv_piv *pv, const rpiv_image *a, const rpiv_image *b)
{
    if (a->w != pv->w || a->h != pv->h || b->w != pv->w || b->h != pv->h)
        return rpiv_fail(RPIV_ESIZE, "piv: pair of %dx%d and %dx%d frames, the plan is for %dx%d",
                         a->w, a->h, b->w, b->h, pv->w, pv->h);
    double *rows = malloc((size_t)pv->h * (sizeof(double) + sizeof(long)));
    if (!rows)
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory");
    long *counts = (long *)(rows + pv->h);
    rpiv_status st = RPIV_OK;
    if (!pv->prep) {
        pv->fill_a = load_frame(pv, a->px, pv->bga, pv->ia, rows, counts);
        pv->fill_b = load_frame(pv, b->px, pv->bgb, pv->ib, rows, counts);
    } else {
        /* background first, then the preprocessing, then the mask's fill */
        for (int f = 0; !st && f < 2; f++) {
            const rpiv_image *src = f ? b : a;
            const float *bg = f ? pv->bgb : pv->bga;
            size_t n = (size_t)pv->w * (size_t)pv->h;
            for (size_t i = 0; i < n; i++)
                pv->prep[i] = bg ? src->px[i] - bg[i] : src->px[i];
            rpiv_image t = {pv->w, pv->h, src->bits, pv->prep};
            if ((st = rpiv_preprocess_run(&pv->p.prep, &t, pv->nthreads)))
                break;
            float fill = load_frame(pv, pv->prep, NULL, f ? pv->ib : pv->ia, rows, counts);
            *(f ? &pv->fill_b : &pv->fill_a) = fill;
        }
    }
    free(rows);
    if (st)
        return st;
    pv->state = PIV_RAW;
    pv->final_known = 0; /* a new pair: no refinement repeat yet */
    return RPIV_OK;
}

/* ---- one pass ------------------------------------------------------------------------------ */

double piv_shift(const rpiv_piv *pv, int k)
{
    return k > 0 && pv->deforms ? RPIV_DEFORM_SHIFT : 0.0;
}

int piv_edge_curved(const rpiv_piv *pv, int ensemble)
{
    return pv->p.edge_curvature < 0 ? ensemble != 0 : pv->p.edge_curvature;
}

rpiv_status piv_pred_new(const rpiv_piv *pv, const rpiv_field *predictor, int pass, double filter,
                         const piv_notch *notch, int ensemble, rpiv_deform_pred **out)
{
    const double shift = piv_shift(pv, pass);
    rpiv_field *f = NULL;
    rpiv_status st = rpiv_field_copy(predictor, &f);
    if (st)
        return st;
    /* a rejected vector already holds its replacement (the median, the line's median or the
     * inpainting its validation chose): only masked vectors are filled here. Refilling the
     * rejected ones by 3 x 3 medians put a shear's crests, which the line test replaces by
     * their row's median, back at the median across the layer (about 0), and the next repeat,
     * deformed by that, measured them wrong again (issue 15). */
    for (size_t k = 0; k < (size_t)f->nx * (size_t)f->ny; k++)
        if (f->flag[k] == RPIV_FLAG_REPLACED)
            f->flag[k] = RPIV_FLAG_VALID;
    /* a repeat of the final size: its detail shrunk above the noise (refine_denoise), then its
     * grid's Nyquist mode, which no repeat would correct, removed (refine_notch) */
    const int denoise =
        ensemble ? piv_pred_denoised_ensemble(pv, predictor) : piv_pred_denoised(pv, predictor);
    if (!(st = rpiv_validate_replace(f, 1, NULL)) &&
        !(filter > 0 && (st = piv_pred_filter(f, filter))) &&
        !(denoise && (st = piv_pred_denoise(pv, f))) && !(st = piv_pred_notch(f, notch))) {
        /* the curvature where the predictor's end nodes were measured (its own flags: f's
         * replaced ones are taken as valid above), where it is above what noise makes */
        const int curved = piv_edge_curved(pv, ensemble);
        double thr[2] = {0, 0};
        if (curved)
            piv_curv_threshold(f, thr);
        st = deform_pred_new_ext(f, pv->w, pv->h, shift, curved ? predictor->flag : NULL, thr, out);
    }
    rpiv_field_free(f);
    return st;
}

void piv_source_of(const rpiv_piv *pv, int k, const rpiv_deform_pred *pred, piv_source *src)
{
    *src = (piv_source){pv->ia, pv->ib, 0, pred, 0, 0, piv_shift(pv, k)};
    if (pred && src->shift == 0) /* window offsets: pass 0, or deformation off */
        src->offsets = 1;
    src->deform = pred && !src->offsets;
}

rpiv_status piv_prepare(rpiv_piv *pv, int k, const rpiv_deform_pred *pred, piv_source *src)
{
    if (pv->state == PIV_EMPTY)
        return rpiv_fail(RPIV_EINVAL, "piv: no pair loaded");
    piv_source_of(pv, k, pred, src);
    if (!src->deform) {
        /* windows straight from the loaded frames */
        if (pv->state != PIV_RAW)
            return rpiv_fail(RPIV_EINVAL,
                             "piv: pass %d reads the loaded frames, which a "
                             "deforming pass has prefiltered: load the pair again",
                             k + 1);
        return RPIV_OK;
    }
    if (pv->state == PIV_RAW) {
        deform_prefilter_pair(pv->ia, pv->ib, pv->w, pv->h, pv->nthreads);
        pv->state = PIV_COEF;
    }
    return RPIV_OK;
}

/* Copy a ww x wh window with top-left (x0, y0) from frame f (w x h) into dst; pixels outside
 * the frame take fill. */
static void copy_window(const float *f, int w, int h, int x0, int y0, int ww, int wh, float fill,
                        float *dst)
{
    if (x0 >= 0 && y0 >= 0 && x0 + ww <= w && y0 + wh <= h) {
        for (int j = 0; j < wh; j++)
            memcpy(dst + (size_t)j * (size_t)ww, f + (size_t)(y0 + j) * (size_t)w + (size_t)x0,
                   (size_t)ww * sizeof *dst);
        return;
    }
    for (int j = 0; j < wh; j++)
        for (int i = 0; i < ww; i++) {
            int x = x0 + i, y = y0 + j;
            dst[(size_t)j * (size_t)ww + (size_t)i] =
                (x >= 0 && y >= 0 && x < w && y < h) ? f[(size_t)y * (size_t)w + (size_t)x] : fill;
        }
}

/* The window pair's origins and the displacement it is shifted by. */
static void window_place(const piv_pass *ps, const piv_source *src, size_t win, int *ax, int *ay,
                         int *bx, int *by, double *pu, double *pv_)
{
    int i = (int)(win % (size_t)ps->nx), j = (int)(win / (size_t)ps->nx);
    int x0 = ps->ox + i * ps->sx, y0 = ps->oy + j * ps->sy;
    *ax = *bx = x0;
    *ay = *by = y0;
    *pu = *pv_ = 0;
    if (!src->pred)
        return;
    const double c = src->offsets ? 0 : src->shift;
    rpiv_deform_pred_eval(src->pred, x0 + 0.5 * (ps->ww - 1) + c, y0 + 0.5 * (ps->wh - 1) + c, pu,
                          pv_);
    if (src->offsets) {
        /* window offset: A moved back by half the rounded predictor, B forward */
        int su = (int)lround(*pu), sv = (int)lround(*pv_);
        *ax -= (int)floor(0.5 * su);
        *ay -= (int)floor(0.5 * sv);
        *bx = *ax + su;
        *by = *ay + sv;
        *pu = su;
        *pv_ = sv;
    }
}

void piv_window_shift(const piv_pass *ps, const piv_source *src, size_t win, double *pu,
                      double *pv_)
{
    int ax, ay, bx, by;
    window_place(ps, src, win, &ax, &ay, &bx, &by, pu, pv_);
}

/* Where window `win` of src is read: a pointer into the frames, or (only window offsets reach
 * past the frames, which they read whole: row0 = 0) a copy in the spare buffers a, b. */
static void window_src(const rpiv_piv *pv, const piv_pass *ps, const piv_source *src, size_t win,
                       float *a, float *b, rpiv_xcorr_src *xs, double *pu, double *pv_)
{
    int ax, ay, bx, by;
    window_place(ps, src, win, &ax, &ay, &bx, &by, pu, pv_);
    if (ax >= 0 && ay >= 0 && bx >= 0 && by >= 0 && ax + ps->ww <= pv->w && bx + ps->ww <= pv->w &&
        ay + ps->wh <= pv->h && by + ps->wh <= pv->h) {
        const size_t sw = (size_t)pv->w;
        *xs = (rpiv_xcorr_src){src->fa + (size_t)(ay - src->row0) * sw + (size_t)ax,
                               src->fb + (size_t)(by - src->row0) * sw + (size_t)bx, sw, sw};
        return;
    }
    copy_window(src->fa, pv->w, pv->h, ax, ay, ps->ww, ps->wh, pv->fill_a, a);
    copy_window(src->fb, pv->w, pv->h, bx, by, ps->ww, ps->wh, pv->fill_b, b);
    *xs = (rpiv_xcorr_src){a, b, (size_t)ps->ww, (size_t)ps->ww};
}

void piv_windows(const rpiv_piv *pv, const piv_pass *ps, const piv_source *src, rpiv_xcorr_work *ws,
                 size_t i, size_t j, piv_win_fn fn, void *ctx)
{
    size_t win[2];
    int n = 0;
    for (size_t k = i; k < i + 2 && k < (size_t)ps->nx; k++) {
        size_t wk = j * (size_t)ps->nx + k;
        if (!ps->masked || !ps->masked[wk])
            win[n++] = wk;
    }
    if (!n)
        return;
    rpiv_xcorr_src xs[2];
    double e[4], pu[2], pv_[2];
    if (!src->pred && i + 2 < (size_t)ps->nx) {
        /* Windows read straight from the frames: bring in the columns the next pair adds
         * (2 steps right of this pair's end). Each of a window's rows is its own stream, more
         * streams than the hardware prefetcher follows: without this the pass waits on the
         * last-level cache. */
        const size_t sw = (size_t)pv->w;
        const int x0 = ps->ox + (int)(i + 1) * ps->sx + ps->ww, x1 = x0 + 2 * ps->sx;
        const int y0 = ps->oy + (int)j * ps->sy;
        for (int y = y0; y < y0 + ps->wh; y++)
            for (int x = x0; x < x1 && x < pv->w; x += 16) {
                __builtin_prefetch(src->fa + (size_t)y * sw + (size_t)x);
                __builtin_prefetch(src->fb + (size_t)y * sw + (size_t)x);
            }
    }
    window_src(pv, ps, src, win[0], ws->a, ws->b, &xs[0], &pu[0], &pv_[0]);
    if (n > 1)
        window_src(pv, ps, src, win[1], ws->a2, ws->b2, &xs[1], &pu[1], &pv_[1]);
    rpiv_xcorr_run_pairs(ps->xc, ws, xs, n, RPIV_XCORR_RAW, e);
    fn(ctx, ws->plane, ws->colmax, win[0], e[0], e[1], pu[0], pv_[0], &xs[0]);
    if (n > 1)
        fn(ctx, ws->plane2, ws->colmax2, win[1], e[2], e[3], pu[1], pv_[1], &xs[1]);
}

/* piv_pass_run; cut = 1: stop (RPIV_EINTR) when the plan's cancel hook asks. */
static rpiv_status pass_run(rpiv_piv *pv, int k, const rpiv_deform_pred *pred, piv_win_fn fn,
                            void *ctx, int cut)
{
    const piv_pass *ps = &pv->pass[k];
    piv_source src;
    int stop = 0;
    cut = cut && pv->cancel.fn;
    rpiv_status st = piv_prepare(pv, k, pred, &src);
    if (st)
        return st;
    if (!src.deform) {
        /* windows two by two along each row: (0, 1), (2, 3), ... */
        const size_t half = ((size_t)ps->nx + 1) / 2, nslot = half * (size_t)ps->ny;
#pragma omp parallel num_threads(pv->nthreads)
        {
            size_t calls = 0;
            int mine = 0; /* this thread has seen the stop */
#pragma omp for schedule(dynamic, 4)
            for (size_t slot = 0; slot < nslot; slot++)
                if (!mine &&
                    !(cut && calls++ % 256 == 0 && (mine = piv_pass_stopped(pv, cut, &stop))))
                    piv_windows(pv, ps, &src, ps->ws[omp_get_thread_num()], 2 * (slot % half),
                                slot / half, fn, ctx);
        }
        return stop ? rpiv_fail(RPIV_EINTR, "piv: interrupted in pass %d", k + 1) : RPIV_OK;
    }
    /* Strips, without any synchronisation: the rows of windows are cut into chunks handed
     * out dynamically; a thread deforms the rows under its chunk into its own buffer of one
     * window height, rolling it down one row of windows at a time (the overlap kept, only the
     * new rows computed; the first strip of a chunk is computed whole, so a chunk
     * recomputes the overlap rows of the previous one). A pixel's deformed value does not
     * depend on who computes it, so results are the same for any chunking and threads. */
    const int x0 = ps->rect[0], x1 = ps->rect[2], wh = ps->wh, nt = pv->nthreads;
    /* two chunks per thread: each chunk computes its first strip whole (the overlap rows
     * twice), so fewer chunks cost less; two per thread still even out masked rows
     * (bench_piv, 2 threads: 121-125 ms with 2 chunks a thread, 125-139 ms with 4) */
    const int half = (ps->ny + 2 * nt - 1) / (2 * nt), chunk = half > 4 ? half : 4;
    const int nchunks = (ps->ny + chunk - 1) / chunk;
    const size_t sw = (size_t)pv->w, per = deform_row_scratch(pred, x0, x1);
    const size_t mine_n = 2 * (size_t)wh * sw + per;
    float *buf = malloc((size_t)nt * mine_n * sizeof *buf);
    if (!buf)
        return rpiv_fail(RPIV_ENOMEM, "piv: out of memory for the deformation strips");
#pragma omp parallel num_threads(nt)
    {
        float *sa = buf + (size_t)omp_get_thread_num() * mine_n, *sb = sa + (size_t)wh * sw;
        float *scr = sb + (size_t)wh * sw;
        rpiv_xcorr_work *ws = ps->ws[omp_get_thread_num()];
        piv_source my = src;
        my.fa = sa;
        my.fb = sb;
#pragma omp for schedule(dynamic, 1)
        for (int c = 0; c < nchunks; c++) {
            int prev_s = 0, prev_e = 0; /* rows held: [prev_s, prev_e) */
            int j1 = (c + 1) * chunk < ps->ny ? (c + 1) * chunk : ps->ny;
            for (int j = c * chunk; j < j1 && !(cut && piv_pass_stopped(pv, cut, &stop)); j++) {
                const int s = ps->oy + j * ps->sy, e = s + wh, keep = prev_e > s ? prev_e - s : 0;
                if (keep) { /* the overlap with the previous strip moves to the top */
                    memmove(sa, sa + (size_t)(s - prev_s) * sw, (size_t)keep * sw * sizeof *sa);
                    memmove(sb, sb + (size_t)(s - prev_s) * sw, (size_t)keep * sw * sizeof *sb);
                }
                for (int y = s + keep; y < e; y++)
                    deform_row(pv->ia, pv->ib, pv->w, pv->h, pred, x0, x1, y, pv->fill_a,
                               pv->fill_b, sa + (size_t)(y - s) * sw, sb + (size_t)(y - s) * sw,
                               scr);
                my.row0 = s;
                for (int i = 0; i < ps->nx; i += 2)
                    piv_windows(pv, ps, &my, ws, (size_t)i, (size_t)j, fn, ctx);
                prev_s = s;
                prev_e = e;
            }
        }
    }
    free(buf);
    return stop ? rpiv_fail(RPIV_EINTR, "piv: interrupted in pass %d", k + 1) : RPIV_OK;
}

rpiv_status piv_pass_run(rpiv_piv *pv, int k, const rpiv_deform_pred *pred, piv_win_fn fn,
                         void *ctx)
{
    return pass_run(pv, k, pred, fn, ctx, 0);
}

rpiv_status piv_pass_run_cut(rpiv_piv *pv, int k, const rpiv_deform_pred *pred, piv_win_fn fn,
                             void *ctx)
{
    return pass_run(pv, k, pred, fn, ctx, 1);
}
