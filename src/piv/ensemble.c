/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/ensemble.c - sum-of-correlation accumulators, their files, and the ensemble run. */
#include "rpiv/ensemble.h"

#include "piv_impl.h"

#include "base/hash.h"

#include <errno.h>
#include <omp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

struct rpiv_ensemble {
    rpiv_piv *pv;
    int pass;
    rpiv_field *predictor;  /* copy, NULL for none */
    rpiv_deform_pred *pred; /* its interpolant     */
    uint64_t pred_hash;
    size_t plane; /* floats per plane    */
    size_t nwin;
    size_t n;    /* floats in data      */
    float *data; /* planes, then energies */
    size_t npairs;
};

static uint64_t field_hash(const rpiv_field *f)
{
    uint64_t h = HASH0;
    if (!f)
        return h;
    size_t n = (size_t)f->nx * (size_t)f->ny;
    int dims[2] = {f->nx, f->ny};
    h = hash_bytes(h, dims, sizeof dims);
    h = hash_bytes(h, f->u, n * sizeof *f->u);
    h = hash_bytes(h, f->v, n * sizeof *f->v);
    return hash_bytes(h, f->flag, n);
}

void rpiv_ensemble_free(rpiv_ensemble *e)
{
    if (!e)
        return;
    rpiv_field_free(e->predictor);
    rpiv_deform_pred_free(e->pred);
    free(e->data);
    free(e);
}

rpiv_status rpiv_ensemble_new(rpiv_piv *pv, int pass, const rpiv_field *predictor,
                              rpiv_ensemble **out)
{
    *out = NULL;
    if (pass < 0 || pass >= pv->npass)
        return rpiv_fail(RPIV_EINVAL, "ensemble: pass %d outside 0..%d", pass, pv->npass - 1);
    const piv_pass *ps = &pv->pass[pass];
    size_t plane = (size_t)ps->ww * (size_t)ps->wh, n = ps->nwin * (plane + 2);
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
    if (predictor) {
        if ((st = rpiv_field_copy(predictor, &e->predictor)) ||
            (st = piv_pred_new(pv, predictor, piv_shift(pv, pass), &e->pred)))
            goto out_free;
    }
    e->pred_hash = field_hash(predictor);
    *out = e;
    return RPIV_OK;
out_free:
    rpiv_ensemble_free(e);
    return st;
}

static void add_plane(void *ctx, const float *plane, const float *colmax, size_t win, double ea,
                      double eb, double pu, double pv_)
{
    rpiv_ensemble *e = ctx;
    (void)colmax;
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
                   (double)energy[2 * win + 1], pu, pv_, f, win);
    }
    if ((st = piv_validate(pv, f))) {
        rpiv_field_free(f);
        return st;
    }
    *out = f;
    return RPIV_OK;
}

/* ---- files ----------------------------------------------------------------------------------- */

#define MAGIC "RPIVENS1"

typedef struct file_header {
    char magic[8];
    uint32_t endian; /* 0x01020304 as written */
    int32_t pass, ww, wh, nx, ny, ox, oy, w, h;
    uint64_t npairs, n, pred_hash, data_hash;
} file_header;

static void header_of(const rpiv_ensemble *e, file_header *hd)
{
    const piv_pass *ps = &e->pv->pass[e->pass];
    memset(hd, 0, sizeof *hd);
    memcpy(hd->magic, MAGIC, 8);
    hd->endian = 0x01020304u;
    hd->pass = e->pass;
    hd->ww = ps->ww;
    hd->wh = ps->wh;
    hd->nx = ps->nx;
    hd->ny = ps->ny;
    hd->ox = ps->ox;
    hd->oy = ps->oy;
    hd->w = e->pv->w;
    hd->h = e->pv->h;
    hd->npairs = e->npairs;
    hd->n = e->n;
    hd->pred_hash = e->pred_hash;
}

rpiv_status rpiv_ensemble_save(const rpiv_ensemble *e, const char *path)
{
    file_header hd;
    header_of(e, &hd);
    hd.data_hash = hash_bytes(HASH0, e->data, e->n * sizeof *e->data);
    size_t len = strlen(path);
    char *tmp = malloc(len + 16);
    if (!tmp)
        return rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory");
    snprintf(tmp, len + 16, "%s.tmp%ld", path, (long)getpid());
    rpiv_status st = RPIV_OK;
    FILE *fp = fopen(tmp, "wb");
    if (!fp) {
        st = rpiv_fail(RPIV_EIO, "%s: cannot write: %s", path, strerror(errno));
        goto out_free;
    }
    int bad =
        fwrite(&hd, sizeof hd, 1, fp) != 1 || fwrite(e->data, sizeof *e->data, e->n, fp) != e->n;
    bad |= fflush(fp) != 0 || fsync(fileno(fp)) != 0;
    bad |= fclose(fp) != 0;
    if (bad || rename(tmp, path) != 0) {
        st = rpiv_fail(RPIV_EIO, "%s: cannot write: %s", path, strerror(errno));
        remove(tmp);
    }
out_free:
    free(tmp);
    return st;
}

rpiv_status rpiv_ensemble_load(rpiv_ensemble *e, const char *path)
{
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return rpiv_fail(RPIV_EIO, "%s: cannot open: %s", path, strerror(errno));
    file_header hd, want;
    rpiv_status st = RPIV_OK;
    float *buf = NULL;
    header_of(e, &want);
    if (fread(&hd, sizeof hd, 1, fp) != 1 || memcmp(hd.magic, MAGIC, 8) != 0) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: not an rpiv ensemble checkpoint", path);
        goto out_close;
    }
    if (hd.endian != want.endian) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: written on a machine of another byte order", path);
        goto out_close;
    }
    if (hd.w != want.w || hd.h != want.h || hd.pass != want.pass || hd.ww != want.ww ||
        hd.wh != want.wh || hd.nx != want.nx || hd.ny != want.ny || hd.ox != want.ox ||
        hd.oy != want.oy || hd.n != want.n) {
        st = rpiv_fail(RPIV_EFORMAT,
                       "%s: sums of pass %d with %dx%d windows on a %dx%d grid of "
                       "%dx%d images; this run's pass %d has %dx%d windows on %dx%d of %dx%d",
                       path, hd.pass + 1, hd.ww, hd.wh, hd.nx, hd.ny, hd.w, hd.h, want.pass + 1,
                       want.ww, want.wh, want.nx, want.ny, want.w, want.h);
        goto out_close;
    }
    if (hd.pred_hash != want.pred_hash) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: made with another predictor than this run's pass %d",
                       path, want.pass + 1);
        goto out_close;
    }
    buf = malloc(e->n * sizeof *buf);
    if (!buf) {
        st = rpiv_fail(RPIV_ENOMEM, "ensemble: out of memory");
        goto out_close;
    }
    if (fread(buf, sizeof *buf, e->n, fp) != e->n) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: truncated", path);
        goto out_close;
    }
    if (hash_bytes(HASH0, buf, e->n * sizeof *buf) != hd.data_hash) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: corrupt (checksum mismatch)", path);
        goto out_close;
    }
    memcpy(e->data, buf, e->n * sizeof *buf);
    e->npairs = (size_t)hd.npairs;
out_close:
    free(buf);
    fclose(fp);
    return st;
}
