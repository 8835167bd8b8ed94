/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/piv/ensemble.c - sum-of-correlation accumulators and their checkpoint files (the one
 * checkpoint format of rpiv; rpiv/batch.h adds its identity block to them). */
#include "rpiv/ensemble.h"

#include "ensemble_impl.h"
#include "piv_impl.h"
#include "uncertainty_impl.h"
#include "validate_impl.h"

#include "base/atomic.h"
#include "base/hash.h"

#include <errno.h>
#include <omp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void rpiv_ensemble_free(rpiv_ensemble *e)
{
    if (!e)
        return;
    rpiv_field_free(e->predictor);
    rpiv_deform_pred_free(e->pred);
    free(e->scratch);
    free(e->data);
    free(e);
}

rpiv_status rpiv_ensemble_new(rpiv_piv *pv, int pass, const rpiv_field *predictor,
                              rpiv_ensemble **out)
{
    *out = NULL;
    if (pass < 0 || pass >= pv->npass)
        return rpiv_fail(RPIV_EINVAL, "ensemble: pass %d outside 0..%d", pass, pv->npass - 1);
    if (pv->p.cbc)
        return rpiv_fail(RPIV_EINVAL, "ensemble: piv.cbc (the correlation-based correction) is "
                                      "for instantaneous fields; an ensemble sums the planes");
    const piv_pass *ps = &pv->pass[pass];
    size_t plane = (size_t)ps->ww * (size_t)ps->wh;
    const size_t n = ps->nwin * (plane + 2) + ens_unc_floats(pv, pass);
    double mb = ((double)pv->bytes + (double)n * sizeof(float)) / 1048576.0;
    if (mb > pv->p.max_mem_mb)
        return rpiv_fail(RPIV_ELIMIT,
                         "ensemble: pass %d needs %.0f MB (%zu correlation planes of "
                         "%dx%d and the frames), above piv.max_mem_mb = %g",
                         pass + 1, mb, ps->nwin, ps->ww, ps->wh, pv->p.max_mem_mb);
    rpiv_ensemble *e = calloc(1, sizeof *e);
    if (!e)
        return rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory");
    rpiv_status st = RPIV_OK;
    e->pv = pv;
    e->pass = pass;
    e->plane = plane;
    e->nwin = ps->nwin;
    e->n = n;
    e->data = calloc(n, sizeof *e->data);
    if (!e->data) {
        st = rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory for %zu correlation planes of %dx%d",
                       ps->nwin, ps->ww, ps->wh);
        goto out_free;
    }
    if (pv->p.uncertainty &&
        !(e->scratch = malloc(2 * (size_t)pv->nthreads * plane * sizeof *e->scratch))) {
        st = rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory for the uncertainty");
        goto out_free;
    }
    if (predictor) {
        piv_pred_notch_ensemble(pv, pass, predictor, &e->notch);
        if ((st = rpiv_field_copy(predictor, &e->predictor)) ||
            (st = piv_pred_new(pv, predictor, pass, 0, &e->notch, 1, &e->pred)))
            goto out_free;
    }
    e->pred_hash = piv_field_hash(predictor);
    *out = e;
    return RPIV_OK;
out_free:
    rpiv_ensemble_free(e);
    return st;
}

/* prev and f on the same grid */
static int same_grid(const rpiv_field *prev, const rpiv_field *f)
{
    return prev && f && prev->nx == f->nx && prev->ny == f->ny && prev->x0 == f->x0 &&
           prev->y0 == f->y0 && prev->dx == f->dx && prev->dy == f->dy;
}

double rpiv_ensemble_change(const rpiv_field *prev, const rpiv_field *f)
{
    if (!same_grid(prev, f))
        return -1;
    size_t n;
    const double c = piv_field_change(f, prev, 1, &n);
    return n ? c : -1;
}

int rpiv_ensemble_again(const rpiv_piv *pv, const rpiv_field *prev, const rpiv_field *f,
                        int repeats)
{
    if (!f || repeats >= pv->p.ensemble_refine)
        return 0;
    if (!same_grid(prev, f))
        return 1; /* the final size not iterated yet: no change to measure */
    const double c = rpiv_ensemble_change(prev, f);
    return c > pv->p.ensemble_refine_tol_px; /* -1: no vector valid in both */
}

static void add_plane(void *ctx, const float *plane, const float *colmax, size_t win, double ea,
                      double eb, double pu, double pv_, const rpiv_xcorr_src *xs)
{
    rpiv_ensemble *e = ctx;
    (void)colmax;
    if (e->scratch) {
        double us[ENS_UNC_SUMS];
        ens_unc_pair(e, plane, xs, e->scratch + 2 * (size_t)omp_get_thread_num() * e->plane, us);
        ens_unc_add(e, win, us, plane);
    }
    float *sum = e->data + win * e->plane, *energy = e->data + e->nwin * e->plane;
    (void)pu;
    (void)pv_;
    for (size_t i = 0; i < e->plane; i++)
        sum[i] += plane[i];
    energy[2 * win] += (float)ea;
    energy[2 * win + 1] += (float)eb;
}

rpiv_status rpiv_ensemble_add(rpiv_ensemble *e, const rpiv_image *a, const rpiv_image *b)
{
    rpiv_status st;
    if ((st = rpiv_piv_load(e->pv, a, b)) ||
        (st = piv_pass_run(e->pv, e->pass, e->pred, add_plane, e)))
        return st;
    e->npairs++;
    return RPIV_OK;
}

static int same_layout(const rpiv_ensemble *a, const rpiv_ensemble *b)
{
    const piv_pass *pa = &a->pv->pass[a->pass], *pb = &b->pv->pass[b->pass];
    return a->pass == b->pass && a->n == b->n && pa->ww == pb->ww && pa->wh == pb->wh &&
           pa->nx == pb->nx && pa->ny == pb->ny && pa->ox == pb->ox && pa->oy == pb->oy &&
           a->pv->w == b->pv->w && a->pv->h == b->pv->h && a->pred_hash == b->pred_hash;
}

rpiv_status rpiv_ensemble_merge(rpiv_ensemble *dst, const rpiv_ensemble *src)
{
    if (!same_layout(dst, src))
        return rpiv_fail(RPIV_EINVAL, "ensemble: cannot merge sums of different plans, passes "
                                      "or predictors");
    for (size_t i = 0; i < dst->n; i++)
        dst->data[i] += src->data[i];
    dst->npairs += src->npairs;
    return RPIV_OK;
}

float *rpiv_ensemble_data(rpiv_ensemble *e, size_t *n)
{
    *n = e->n;
    return e->data;
}

size_t rpiv_ensemble_npairs(const rpiv_ensemble *e)
{
    return e->npairs;
}

void rpiv_ensemble_set_npairs(rpiv_ensemble *e, size_t npairs)
{
    e->npairs = npairs;
}

int rpiv_ensemble_pass(const rpiv_ensemble *e)
{
    return e->pass;
}

const rpiv_field *rpiv_ensemble_predictor(const rpiv_ensemble *e)
{
    return e->predictor;
}

/* The spline estimator's correction of the 3-point Gaussian, d = spline - Gaussian, tested
 * against its neighbours' (docs/piv.md, "The spline estimator"): on narrow peaks from a few
 * pairs the spline's tail samples carry the plane's noise many times over and a few windows get
 * errors of several hundredths of a px, while its correction where it pays (skewed peaks) varies
 * slowly across the field. A vector whose d fails the engine's normalised median test
 * (threshold SPLINE_CHECK_THR, floor SPLINE_CHECK_EPS px) gets the Gaussian's estimate plus the
 * median of its neighbours' d (fell[win] = 1 there, the uncertainty's 3-point branch).
 * params spline_check 0: not done. */
#define SPLINE_CHECK_THR 2.0
#define SPLINE_CHECK_EPS 0.002
static rpiv_status spline_check(const rpiv_ensemble *e, const piv_source *src, rpiv_field *f,
                                unsigned char *fell)
{
    const rpiv_piv *pv = e->pv;
    const piv_pass *ps = &pv->pass[e->pass];
    if (!pv->p.spline_check || rpiv_subpixel_resolve(pv->p.subpixel, 1) != RPIV_SUBPIXEL_SPLINE)
        return RPIV_OK;
    rpiv_field *d = NULL;
    double *gauss = malloc(2 * ps->nwin * sizeof *gauss); /* the Gaussian's u, v */
    rpiv_status st = gauss
                         ? rpiv_field_copy(f, &d)
                         : rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory for the spline's check");
    if (st) {
        free(gauss);
        return st;
    }
#pragma omp parallel for schedule(dynamic, 8) num_threads(pv->nthreads)
    for (size_t win = 0; win < ps->nwin; win++) {
        if (f->flag[win] != RPIV_FLAG_VALID)
            continue;
        rpiv_peak g;
        double pu, pv_;
        piv_window_shift(ps, src, win, &pu, &pv_);
        rpiv_peak_find(e->data + win * e->plane, ps->ww, ps->wh, 0, RPIV_SUBPIXEL_GAUSS, &g);
        d->u[win] = (float)((double)f->u[win] - pu - g.dx);
        d->v[win] = (float)((double)f->v[win] - pv_ - g.dy);
        gauss[win] = pu + g.dx;
        gauss[ps->nwin + win] = pv_ + g.dy;
        if (!g.fit_ok) /* no Gaussian to fall back to: neither tested nor a neighbour */
            d->flag[win] = RPIV_FLAG_MASKED;
    }
    size_t nrej = 0;
    if (!(st = validate_median_nt(d, SPLINE_CHECK_THR, SPLINE_CHECK_EPS, 0, &nrej, pv->nthreads)) &&
        nrej && !(st = validate_replace_lines(d, 0, 0, NULL))) {
        for (size_t win = 0; win < ps->nwin; win++) {
            if (f->flag[win] != RPIV_FLAG_VALID || d->flag[win] != RPIV_FLAG_REPLACED)
                continue;
            f->u[win] = (float)(gauss[win] + (double)d->u[win]);
            f->v[win] = (float)(gauss[ps->nwin + win] + (double)d->v[win]);
            if (fell)
                fell[win] = 1;
        }
    }
    free(gauss);
    rpiv_field_free(d);
    return st;
}

rpiv_status rpiv_ensemble_finish(const rpiv_ensemble *e, rpiv_field **out)
{
    *out = NULL;
    if (!e->npairs)
        return rpiv_fail(RPIV_EINVAL, "ensemble: pass %d has no pair added", e->pass + 1);
    const rpiv_piv *pv = e->pv;
    const piv_pass *ps = &pv->pass[e->pass];
    rpiv_field *f = NULL;
    rpiv_status st = rpiv_piv_grid(pv, e->pass, &f);
    if (st)
        return st;
    piv_source src;
    piv_source_of(pv, e->pass, e->pred, &src);
    const float *energy = e->data + e->nwin * e->plane;
#pragma omp parallel for schedule(dynamic, 8) num_threads(pv->nthreads)
    for (size_t win = 0; win < ps->nwin; win++) {
        if (ps->masked && ps->masked[win]) {
            f->flag[win] = RPIV_FLAG_MASKED;
            continue;
        }
        double pu, pv_;
        piv_window_shift(ps, &src, win, &pu, &pv_);
        piv_vector(pv, ps, e->data + win * e->plane, NULL, (double)energy[2 * win],
                   (double)energy[2 * win + 1], pu, pv_, f, win, 1, 0, NULL);
    }
    unsigned char *fell = e->scratch ? calloc(ps->nwin, 1) : NULL;
    if (e->scratch && !fell)
        st = rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory for the spline's check");
    if (st || (st = spline_check(e, &src, f, fell)) || (st = piv_validate(pv, f)) ||
        (e->scratch && (st = ens_unc_finish(e, f, fell)))) {
        free(fell);
        rpiv_field_free(f);
        return st;
    }
    free(fell);
    *out = f;
    return RPIV_OK;
}

/* ---- checkpoint files ------------------------------------------------------------------------ */

/* The one checkpoint format of rpiv, in the byte order of the machine that wrote it:
 *   header     file_header below; `length` is the file's size in bytes, so that a file cut
 *              short or with bytes appended is refused before anything else is read
 *   block      nblock bytes of the caller's (rpiv/batch.h: its run's identity, the pair states)
 *   predictor  if has_pred: nx, ny (int32), x0, y0, dx, dy, scale_mm_per_px, dt_s (double),
 *              u, v, peak_ratio, corr (nx*ny floats each), flag (nx*ny bytes), then if
 *              flags & CK_PRED_SIGMA its sigma_u, sigma_v (nx*ny floats each)
 *   sums       nsums floats, as rpiv_ensemble_data gives them (with piv.uncertainty,
 *              ENS_UNC_STRIDE more per window: ensemble_unc.c)
 *   checksum   FNV-1a (base/hash.h) of every byte before it, uint64
 * RPIVENS1 (an accumulator's sums), RPIVCKP1 (the batch's checkpoint), RPIVCKP2 (no
 * length) and RPIVCKP3 (no uncertainty) came before. */
#define MAGIC         "RPIVCKP4"
#define ENDIAN        0x01020304u
#define CK_PRED_SIGMA 1 /* flags: the predictor's sigma_u, sigma_v follow its flags */

typedef struct file_header {
    char magic[8];
    uint32_t endian; /* ENDIAN as written */
    int32_t pass, ww, wh, nx, ny, ox, oy, w, h, has_pred, flags;
    uint64_t npairs, nsums, pred_hash, nblock, length;
} file_header;

/* The layout of pass `pass` of pv as a header (magic, byte order, pass and layout only). */
static void layout_of(const rpiv_piv *pv, int pass, file_header *hd)
{
    const piv_pass *ps = &pv->pass[pass];
    memset(hd, 0, sizeof *hd);
    memcpy(hd->magic, MAGIC, 8);
    hd->endian = ENDIAN;
    hd->pass = pass;
    hd->ww = ps->ww;
    hd->wh = ps->wh;
    hd->nx = ps->nx;
    hd->ny = ps->ny;
    hd->ox = ps->ox;
    hd->oy = ps->oy;
    hd->w = pv->w;
    hd->h = pv->h;
    hd->nsums = ps->nwin * ((size_t)ps->ww * (size_t)ps->wh + 2) + ens_unc_floats(pv, pass);
}

/* Sequential writing and reading with a running hash of the bytes. */
typedef struct ck_io {
    FILE *fp;
    uint64_t h;
    int bad;
} ck_io;

static void put(ck_io *io, const void *p, size_t n)
{
    if (!io->bad && n && fwrite(p, 1, n, io->fp) != n)
        io->bad = 1;
    io->h = hash_bytes(io->h, p, n);
}

static int get(ck_io *io, void *p, size_t n)
{
    if (io->bad || (n && fread(p, 1, n, io->fp) != n))
        return !(io->bad = 1);
    io->h = hash_bytes(io->h, p, n);
    return 1;
}

rpiv_status rpiv_ensemble_save_block(const rpiv_ensemble *e, const void *block, size_t nblock,
                                     const char *path)
{
    const rpiv_field *f = e->predictor;
    file_header hd;
    layout_of(e->pv, e->pass, &hd);
    hd.has_pred = f != NULL;
    hd.npairs = e->npairs;
    hd.nsums = e->n;
    hd.pred_hash = e->pred_hash;
    hd.nblock = nblock;
    size_t npred = f ? (size_t)f->nx * (size_t)f->ny : 0;
    const float *psu = NULL, *psv = NULL;
    if (f) {
        psu = unc_quantity((rpiv_field *)f, "sigma_u");
        psv = unc_quantity((rpiv_field *)f, "sigma_v");
        hd.flags = psu && psv ? CK_PRED_SIGMA : 0;
    }
    hd.length = sizeof hd + nblock + e->n * sizeof *e->data + sizeof(uint64_t);
    if (f)
        hd.length += 2 * sizeof(int32_t) + 6 * sizeof(double) + npred * (4 * sizeof(float) + 1) +
                     (hd.flags & CK_PRED_SIGMA ? 2 * npred * sizeof(float) : 0);
    atomic_file af;
    rpiv_status st = atomic_begin(&af, path, 1);
    if (st)
        return st;
    ck_io io = {af.fp, HASH0, 0};
    put(&io, &hd, sizeof hd);
    put(&io, block, nblock);
    if (f) {
        size_t n = npred;
        int32_t dims[2] = {f->nx, f->ny};
        double g[6] = {f->x0, f->y0, f->dx, f->dy, f->scale_mm_per_px, f->dt_s};
        put(&io, dims, sizeof dims);
        put(&io, g, sizeof g);
        put(&io, f->u, n * sizeof *f->u);
        put(&io, f->v, n * sizeof *f->v);
        put(&io, f->peak_ratio, n * sizeof *f->peak_ratio);
        put(&io, f->corr, n * sizeof *f->corr);
        put(&io, f->flag, n);
        if (hd.flags & CK_PRED_SIGMA) {
            put(&io, psu, n * sizeof *psu);
            put(&io, psv, n * sizeof *psv);
        }
    }
    put(&io, e->data, e->n * sizeof *e->data);
    uint64_t sum = io.h;
    put(&io, &sum, sizeof sum);
    if (io.bad) {
        int err = errno;
        atomic_abort(&af);
        return rpiv_fail(RPIV_EIO, "%s: cannot write: %s", path, strerror(err));
    }
    return atomic_commit(&af);
}

rpiv_status rpiv_ensemble_save(const rpiv_ensemble *e, const char *path)
{
    return rpiv_ensemble_save_block(e, NULL, 0, path);
}

/* A checkpoint being read. */
typedef struct reader {
    const char *path;
    ck_io io;
    long size; /* of the file, bytes */
    file_header hd;
} reader;

static rpiv_status truncated(const reader *r)
{
    return rpiv_fail(RPIV_EFORMAT, "%s: truncated checkpoint", r->path);
}

/* Open path and read its header and the caller's block (checked by `check`). */
static rpiv_status read_head(reader *r, const char *path, rpiv_ensemble_block_fn check, void *user)
{
    memset(r, 0, sizeof *r);
    r->path = path;
    r->io.h = HASH0;
    if (!(r->io.fp = fopen(path, "rb")))
        return rpiv_fail(RPIV_EIO, "%s: cannot open: %s", path, strerror(errno));
    file_header *hd = &r->hd;
    if (fseek(r->io.fp, 0, SEEK_END) != 0 || (r->size = ftell(r->io.fp)) < 0 ||
        fseek(r->io.fp, 0, SEEK_SET) != 0)
        return rpiv_fail(RPIV_EIO, "%s: cannot read: %s", path, strerror(errno));
    if (!get(&r->io, hd->magic, 8) ||
        (memcmp(hd->magic, "RPIVENS", 7) && memcmp(hd->magic, "RPIVCKP", 7)))
        return rpiv_fail(RPIV_EFORMAT, "%s: not an rpiv checkpoint", path);
    if (memcmp(hd->magic, MAGIC, 8) != 0)
        return rpiv_fail(RPIV_EFORMAT, "%s: checkpoint of an older rpiv format", path);
    if (!get(&r->io, (char *)hd + 8, sizeof *hd - 8))
        return truncated(r);
    if (hd->endian != ENDIAN)
        return rpiv_fail(RPIV_EFORMAT, "%s: checkpoint written on a machine of another byte order",
                         path);
    if (hd->length > (uint64_t)r->size || hd->nblock > (uint64_t)r->size)
        return truncated(r);
    if (hd->length < (uint64_t)r->size) /* junk appended (issue 20 item 13) */
        return rpiv_fail(
            RPIV_EFORMAT, "%s: %llu bytes after the checkpoint's end (byte %llu): refused", path,
            (unsigned long long)((uint64_t)r->size - hd->length), (unsigned long long)hd->length);
    void *block = malloc(hd->nblock ? (size_t)hd->nblock : 1);
    if (!block)
        return rpiv_fail(RPIV_ENOMEM, "%s: out of memory", path);
    rpiv_status st = RPIV_OK;
    if (!get(&r->io, block, (size_t)hd->nblock))
        st = truncated(r);
    else if (check)
        st = check(user, block, (size_t)hd->nblock);
    free(block);
    return st;
}

/* The header's pass and layout are those of `want` (the plan's). */
static rpiv_status check_layout(const reader *r, const file_header *want)
{
    const file_header *hd = &r->hd;
    if (hd->nsums != want->nsums &&
        hd->nsums - (uint64_t)hd->nx * (uint64_t)hd->ny * ENS_UNC_STRIDE == want->nsums)
        return rpiv_fail(RPIV_EFORMAT, "%s: sums made with piv.uncertainty on; this run has it off",
                         r->path);
    if (hd->nsums + (uint64_t)want->nx * (uint64_t)want->ny * ENS_UNC_STRIDE == want->nsums)
        return rpiv_fail(RPIV_EFORMAT, "%s: sums made with piv.uncertainty off; this run has it on",
                         r->path);
    if (hd->w != want->w || hd->h != want->h || hd->pass != want->pass || hd->ww != want->ww ||
        hd->wh != want->wh || hd->nx != want->nx || hd->ny != want->ny || hd->ox != want->ox ||
        hd->oy != want->oy || hd->nsums != want->nsums)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: sums of pass %d with %dx%d windows on a %dx%d grid of "
                         "%dx%d images; this run's pass %d has %dx%d windows on %dx%d of %dx%d",
                         r->path, hd->pass + 1, hd->ww, hd->wh, hd->nx, hd->ny, hd->w, hd->h,
                         want->pass + 1, want->ww, want->wh, want->nx, want->ny, want->w, want->h);
    return RPIV_OK;
}

/* Read the predictor, if the file has one, into a new field (*f NULL if none). */
static rpiv_status read_pred(reader *r, rpiv_field **f)
{
    *f = NULL;
    if (!r->hd.has_pred)
        return RPIV_OK;
    int32_t dims[2];
    double g[6];
    if (!get(&r->io, dims, sizeof dims) || !get(&r->io, g, sizeof g))
        return truncated(r);
    if (dims[0] < 1 || dims[1] < 1)
        return rpiv_fail(RPIV_EFORMAT, "%s: corrupt checkpoint (predictor grid)", r->path);
    if ((double)dims[0] * (double)dims[1] * 17 > (double)r->size) /* 4 floats and a flag */
        return truncated(r);
    if (rpiv_field_new(dims[0], dims[1], g[0], g[1], g[2], g[3], f))
        return rpiv_fail(RPIV_EFORMAT, "%s: corrupt checkpoint (predictor grid)", r->path);
    rpiv_field *p = *f;
    p->scale_mm_per_px = g[4];
    p->dt_s = g[5];
    size_t n = (size_t)dims[0] * (size_t)dims[1];
    if (get(&r->io, p->u, n * sizeof *p->u) && get(&r->io, p->v, n * sizeof *p->v) &&
        get(&r->io, p->peak_ratio, n * sizeof *p->peak_ratio) &&
        get(&r->io, p->corr, n * sizeof *p->corr) && get(&r->io, p->flag, n)) {
        if (!(r->hd.flags & CK_PRED_SIGMA))
            return RPIV_OK;
        float *su, *sv;
        rpiv_status st = unc_add(p, &su, &sv);
        if (!st && get(&r->io, su, n * sizeof *su) && get(&r->io, sv, n * sizeof *sv))
            return RPIV_OK;
        rpiv_field_free(p);
        *f = NULL;
        return st ? st : truncated(r);
    }
    rpiv_field_free(p);
    *f = NULL;
    return truncated(r);
}

/* Read the nsums sums into data, then the checksum, and compare it. */
static rpiv_status read_sums(reader *r, float *data)
{
    uint64_t want, sum;
    if (!get(&r->io, data, (size_t)r->hd.nsums * sizeof *data))
        return truncated(r);
    want = r->io.h;
    if (!get(&r->io, &sum, sizeof sum))
        return truncated(r);
    if (sum != want)
        return rpiv_fail(RPIV_EFORMAT, "%s: corrupt checkpoint (checksum mismatch)", r->path);
    long end = ftell(r->io.fp);
    if (end < 0 || (uint64_t)end != r->hd.length)
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: corrupt checkpoint (its parts end at byte %ld, its header says %llu)",
                         r->path, end, (unsigned long long)r->hd.length);
    return RPIV_OK;
}

rpiv_status rpiv_ensemble_load(rpiv_ensemble *e, const char *path)
{
    reader r;
    file_header want;
    rpiv_field *pred = NULL;
    float *buf = NULL;
    layout_of(e->pv, e->pass, &want);
    rpiv_status st = read_head(&r, path, NULL, NULL);
    if (!st && !(st = check_layout(&r, &want)) && r.hd.pred_hash != e->pred_hash)
        st = rpiv_fail(RPIV_EFORMAT, "%s: made with another predictor than this run's pass %d",
                       path, e->pass + 1);
    if (st || (st = read_pred(&r, &pred)))
        goto out_close;
    if (!(buf = malloc(e->n * sizeof *buf))) {
        st = rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory");
        goto out_close;
    }
    if ((st = read_sums(&r, buf)))
        goto out_close;
    memcpy(e->data, buf, e->n * sizeof *buf);
    e->npairs = (size_t)r.hd.npairs;
out_close:
    free(buf);
    rpiv_field_free(pred);
    if (r.io.fp)
        fclose(r.io.fp);
    return st;
}

rpiv_status rpiv_ensemble_load_new(rpiv_piv *pv, const char *path, rpiv_ensemble_block_fn check,
                                   void *user, rpiv_ensemble **out)
{
    reader r;
    file_header want;
    rpiv_field *pred = NULL;
    rpiv_ensemble *e = NULL;
    *out = NULL;
    rpiv_status st = read_head(&r, path, check, user);
    if (st)
        goto out_close;
    if (r.hd.pass < 0 || r.hd.pass >= pv->npass) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: corrupt checkpoint (pass %d of %d)", path, r.hd.pass + 1,
                       pv->npass);
        goto out_close;
    }
    layout_of(pv, r.hd.pass, &want);
    if ((st = check_layout(&r, &want)) || (st = read_pred(&r, &pred)) ||
        (st = rpiv_ensemble_new(pv, r.hd.pass, pred, &e)))
        goto out_close;
    if (e->pred_hash != r.hd.pred_hash) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: corrupt checkpoint (predictor)", path);
        goto out_close;
    }
    if ((st = read_sums(&r, e->data)))
        goto out_close;
    e->npairs = (size_t)r.hd.npairs;
    *out = e;
    e = NULL;
out_close:
    rpiv_ensemble_free(e);
    rpiv_field_free(pred);
    if (r.io.fp)
        fclose(r.io.fp);
    return st;
}
