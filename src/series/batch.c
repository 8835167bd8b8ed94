/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/batch.c - long runs over a series (rpiv/batch.h): pairs dealt out to a team, skipped
 * when unreadable, and ensemble sums checkpointed so that a killed run resumes to the same
 * bits. The numerical work is rpiv_ensemble_add/_finish and rpiv_piv_run; this file decides
 * which pair goes where and when, and what is written to disk. */
#include "rpiv/batch.h"

#include "rpiv/ensemble.h"

#include "base/hash.h"
#include "mpi_impl.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

enum { DONE = 1, BAD = 2 }; /* per-pair state bits: added in this pass; unreadable */

struct rpiv_batch {
    const rpiv_pairs *pairs;
    const rpiv_mpi *mpi;
    rpiv_batch_params p;
    char *ckpt;           /* this rank's checkpoint path, NULL = none         */
    unsigned char *state; /* pairs->n entries                                 */
    size_t *skipped, nskipped;
    int resumed, resume_pass;
    size_t resume_done, npairs_last;
};

rpiv_batch_params rpiv_batch_params_default(void)
{
    return (rpiv_batch_params){.checkpoint = NULL, .checkpoint_every = 100};
}

rpiv_status rpiv_batch_params_check(const rpiv_batch_params *p)
{
    if (p->checkpoint && !p->checkpoint[0])
        return rpiv_fail(RPIV_EINVAL, "batch: empty checkpoint file name");
    if (p->resume && !p->checkpoint)
        return rpiv_fail(RPIV_EINVAL, "batch: resume needs a checkpoint file");
    return RPIV_OK;
}

void rpiv_batch_free(rpiv_batch *b)
{
    if (!b)
        return;
    free(b->ckpt);
    free(b->state);
    free(b->skipped);
    free(b);
}

rpiv_status rpiv_batch_new(const rpiv_pairs *pairs, const rpiv_batch_params *p, const rpiv_mpi *mpi,
                           rpiv_batch **out)
{
    *out = NULL;
    rpiv_batch_params def = rpiv_batch_params_default();
    if (!p)
        p = &def;
    rpiv_status st = rpiv_batch_params_check(p);
    if (st)
        return st;
    if (!pairs->n)
        return rpiv_fail(RPIV_EINVAL, "batch: no image pairs");
    rpiv_batch *b = calloc(1, sizeof *b);
    if (!b)
        return rpiv_fail(RPIV_ENOMEM, "batch: out of memory");
    b->pairs = pairs;
    b->mpi = mpi;
    b->p = *p;
    b->p.checkpoint = NULL; /* not kept: b->ckpt is the copy */
    b->state = calloc(pairs->n, 1);
    if (!b->state)
        goto out_nomem;
    if (p->checkpoint) {
        size_t len = strlen(p->checkpoint) + 32;
        if (!(b->ckpt = malloc(len)))
            goto out_nomem;
        if (rpiv_mpi_size(mpi) > 1)
            snprintf(b->ckpt, len, "%s.rank%d", p->checkpoint, rpiv_mpi_rank(mpi));
        else
            snprintf(b->ckpt, len, "%s", p->checkpoint);
    }
    *out = b;
    return RPIV_OK;
out_nomem:
    rpiv_batch_free(b);
    return rpiv_fail(RPIV_ENOMEM, "batch: out of memory");
}

size_t rpiv_batch_nskipped(const rpiv_batch *b)
{
    return b->nskipped;
}

size_t rpiv_batch_skipped(const rpiv_batch *b, size_t k)
{
    return b->skipped[k];
}

int rpiv_batch_resumed(const rpiv_batch *b, int *pass, size_t *done)
{
    if (pass)
        *pass = b->resume_pass;
    if (done)
        *done = b->resume_done;
    return b->resumed;
}

size_t rpiv_batch_npairs(const rpiv_batch *b)
{
    return b->npairs_last;
}

/* ---- unreadable pairs -------------------------------------------------------------------- */

static int unreadable(rpiv_status st)
{
    return st == RPIV_EIO || st == RPIV_EFORMAT || st == RPIV_ESIZE;
}

/* Pair i could not be read (the message is current): mark it and tell the caller. */
static void mark_bad(rpiv_batch *b, size_t i, int notify)
{
    b->state[i] |= BAD;
    if (notify && b->p.on_skip)
        b->p.on_skip(b->p.user, i, rpiv_errmsg());
}

/* Load pair i; frames of another size than w x h (w > 0) are an error naming the pair. */
static rpiv_status load_pair(const rpiv_batch *b, size_t i, int w, int h, rpiv_image **a,
                             rpiv_image **bb)
{
    rpiv_status st = rpiv_pairs_load(b->pairs, i, a, bb);
    if (!st && w > 0 && ((*a)->w != w || (*a)->h != h)) {
        st = rpiv_fail(RPIV_ESIZE, "pair %zu of %zu: %s: %dx%d frames, the series' are %dx%d",
                       i + 1, b->pairs->n, b->pairs->pair[i].path_a, (*a)->w, (*a)->h, w, h);
        rpiv_image_free(*a);
        rpiv_image_free(*bb);
        *a = *bb = NULL;
    }
    return st;
}

/* Merge the BAD marks of all ranks and rebuild the list of skipped pairs. Collective. */
static rpiv_status sync_bad(rpiv_batch *b)
{
    size_t n = b->pairs->n, k = 0;
    unsigned char *bad = malloc(n);
    rpiv_status st =
        rpiv_mpi_agree(b->mpi, bad ? RPIV_OK : rpiv_fail(RPIV_ENOMEM, "batch: out of memory"));
    if (st)
        goto out_free;
    for (size_t i = 0; i < n; i++)
        bad[i] = b->state[i] & BAD;
    if ((st = mpi_max_bytes(b->mpi, bad, n)))
        goto out_free;
    for (size_t i = 0; i < n; i++) {
        b->state[i] = (unsigned char)((b->state[i] & DONE) | bad[i]);
        k += bad[i] != 0;
    }
    size_t *list = k ? malloc(k * sizeof *list) : NULL;
    if ((st = rpiv_mpi_agree(b->mpi, k && !list ? rpiv_fail(RPIV_ENOMEM, "batch: out of memory")
                                                : RPIV_OK))) {
        free(list);
        goto out_free;
    }
    free(b->skipped);
    b->skipped = list;
    b->nskipped = k;
    for (size_t i = 0, j = 0; i < n; i++)
        if (bad[i])
            list[j++] = i;
out_free:
    free(bad);
    return st;
}

rpiv_status rpiv_batch_size(rpiv_batch *b, int *w, int *h)
{
    rpiv_status st = RPIV_OK;
    *w = *h = 0;
    for (size_t i = 0; i < b->pairs->n && !*w && !st; i++) {
        rpiv_image *a = NULL, *bb = NULL;
        if (b->state[i] & BAD)
            continue;
        if (!(st = rpiv_pairs_load(b->pairs, i, &a, &bb))) {
            *w = a->w;
            *h = a->h;
        } else if (b->p.skip_bad && unreadable(st)) {
            mark_bad(b, i, rpiv_mpi_mine(b->mpi, i));
            st = RPIV_OK;
        }
        rpiv_image_free(a);
        rpiv_image_free(bb);
    }
    if (!st && !*w)
        st = rpiv_fail(RPIV_EIO, "none of the %zu pairs can be read", b->pairs->n);
    st = rpiv_mpi_agree(b->mpi, st);
    rpiv_status ss = sync_bad(b);
    return st ? st : ss;
}

/* ---- background -------------------------------------------------------------------------- */

/* This rank's readable pairs as a list borrowing the paths of b->pairs (not to be freed with
 * rpiv_pairs_free), with their indices in idx. */
static rpiv_status share_of(const rpiv_batch *b, rpiv_pairs *view, size_t *idx)
{
    view->n = 0;
    for (size_t i = 0; i < b->pairs->n; i++)
        if (rpiv_mpi_mine(b->mpi, i) && !(b->state[i] & BAD)) {
            view->pair[view->n] = b->pairs->pair[i];
            idx[view->n++] = i;
        }
    return RPIV_OK;
}

/* After rpiv_series_background failed on a view with `st` (message current): find the first pair
 * of the view that cannot be read. Returns its position, or view->n if every pair reads (then
 * the original failure stands); *err is the pair's own failure (message current). */
static size_t find_bad(const rpiv_batch *b, const rpiv_pairs *view, const size_t *idx, int w, int h,
                       rpiv_status *err)
{
    char keep[1024];
    rpiv_status orig = *err;
    snprintf(keep, sizeof keep, "%s", rpiv_errmsg());
    for (size_t j = 0; j < view->n; j++) {
        rpiv_image *a = NULL, *bb = NULL;
        rpiv_status st = load_pair(b, idx[j], w, h, &a, &bb);
        rpiv_image_free(a);
        rpiv_image_free(bb);
        if (st) {
            *err = st;
            return j;
        }
    }
    *err = rpiv_fail(orig, "%s", keep);
    return view->n;
}

/* Combine the ranks' backgrounds of n_r pairs each (ga, gb: this rank's, NULL if n_r = 0). */
static rpiv_status combine_background(rpiv_batch *b, rpiv_background kind, int w, int h, size_t nr,
                                      rpiv_image **ga, rpiv_image **gb)
{
    size_t total = nr, n = (size_t)w * (size_t)h;
    rpiv_status st = mpi_sum_size(b->mpi, &total);
    if (!st && !total)
        st = rpiv_fail(RPIV_EIO, "piv.background: none of the %zu pairs can be read", b->pairs->n);
    if (st)
        return st;
    rpiv_image **g[2] = {ga, gb};
    double *sum = kind == RPIV_BACKGROUND_MEAN ? malloc(n * sizeof *sum) : NULL;
    for (int f = 0; f < 2 && !st; f++) /* a rank without pairs: the neutral element */
        if (!*g[f] && !(st = rpiv_image_new(w, h, g[f])) && kind == RPIV_BACKGROUND_MIN)
            for (size_t k = 0; k < n; k++)
                (*g[f])->px[k] = INFINITY;
    if (!st && kind == RPIV_BACKGROUND_MEAN && !sum)
        st = rpiv_fail(RPIV_ENOMEM, "piv.background: out of memory");
    if ((st = rpiv_mpi_agree(b->mpi, st)))
        goto out_free;
    for (int f = 0; f < 2 && !st; f++) {
        float *px = (*g[f])->px;
        if (kind == RPIV_BACKGROUND_MIN) {
            st = mpi_min_floats(b->mpi, px, n);
            continue;
        }
        for (size_t k = 0; k < n; k++)
            sum[k] = nr ? (double)px[k] * (double)nr : 0.0;
        if (!(st = mpi_sum_doubles(b->mpi, sum, n)))
            for (size_t k = 0; k < n; k++)
                px[k] = (float)(sum[k] / (double)total);
    }
out_free:
    free(sum);
    return st;
}

rpiv_status rpiv_batch_background(rpiv_batch *b, rpiv_background kind, int w, int h,
                                  const rpiv_progress *progress, rpiv_image **bg_a,
                                  rpiv_image **bg_b)
{
    *bg_a = *bg_b = NULL;
    rpiv_pairs view = {0};
    size_t *idx = malloc(b->pairs->n * sizeof *idx);
    view.pair = malloc(b->pairs->n * sizeof *view.pair);
    rpiv_image *ga = NULL, *gb = NULL;
    rpiv_status st = RPIV_OK;
    if (!idx || !view.pair) {
        st = rpiv_fail(RPIV_ENOMEM, "piv.background: out of memory");
        goto out_agree;
    }
    if ((st = share_of(b, &view, idx)))
        goto out_agree;
    while (view.n) {
        if (!(st = rpiv_series_background(&view, kind, progress, &ga, &gb)) || !unreadable(st))
            break;
        size_t j = find_bad(b, &view, idx, w, h, &st);
        if (j == view.n || !b->p.skip_bad)
            break;
        mark_bad(b, idx[j], 1);
        memmove(view.pair + j, view.pair + j + 1, (view.n - j - 1) * sizeof *view.pair);
        memmove(idx + j, idx + j + 1, (view.n - j - 1) * sizeof *idx);
        view.n--;
        st = RPIV_OK;
    }
    if (!st && rpiv_mpi_size(b->mpi) == 1 && !view.n)
        st = rpiv_fail(RPIV_EIO, "piv.background: none of the %zu pairs can be read", b->pairs->n);
out_agree:
    st = rpiv_mpi_agree(b->mpi, st);
    if (!st)
        st = sync_bad(b);
    if (!st && rpiv_mpi_size(b->mpi) > 1)
        st = combine_background(b, kind, w, h, view.n, &ga, &gb);
    free(idx);
    free(view.pair);
    if (st) {
        rpiv_image_free(ga);
        rpiv_image_free(gb);
        return st;
    }
    *bg_a = ga;
    *bg_b = gb;
    return RPIV_OK;
}

/* ---- checkpoint files -------------------------------------------------------------------- */

#define CK_MAGIC "RPIVCKP1"

/* What ties a checkpoint to its run: the series and the plan, as text (for messages) and as
 * a hash (the plan's also covers the mask and background frames). */
typedef struct ck_ident {
    char series[256], plan[768];
    uint64_t series_hash, plan_hash;
} ck_ident;

typedef struct ck_header {
    char magic[8];
    uint32_t endian, version;
    int32_t rank, nranks, pass, npass, has_pred, pad;
    uint64_t npairs, series_hash, plan_hash, nsums, nadded;
    char series[256], plan[768];
} ck_header;

static void ident_of(const rpiv_batch *b, const rpiv_piv *pv, ck_ident *id)
{
    static const char *const sub[] = {"gauss", "parabola", "centroid"};
    static const char *const bg[] = {"none", "min", "mean"};
    const rpiv_pairs *pp = b->pairs;
    const rpiv_piv_params *p = rpiv_piv_params_of(pv);
    int w, h_px;
    rpiv_piv_size(pv, &w, &h_px);
    memset(id, 0, sizeof *id);
    uint64_t h = hash_bytes(HASH0, &pp->n, sizeof pp->n);
    for (size_t i = 0; i < pp->n; i++) {
        h = hash_bytes(h, pp->pair[i].path_a, strlen(pp->pair[i].path_a) + 1);
        if (pp->pair[i].path_b)
            h = hash_bytes(h, pp->pair[i].path_b, strlen(pp->pair[i].path_b) + 1);
        h = hash_bytes(h, "|", 1);
    }
    id->series_hash = h;
    snprintf(id->series, sizeof id->series, "%zu pairs, %s ... %s", pp->n, pp->pair[0].path_a,
             pp->pair[pp->n - 1].path_a);
    char win[256] = "";
    for (int k = 0; k < p->npass; k++)
        snprintf(win + strlen(win), sizeof win - strlen(win), "%s%dx%d", k ? "," : "", p->win_w[k],
                 p->win_h[k]);
    snprintf(id->plan, sizeof id->plan,
             "%dx%d frames, windows %.100s, overlap %.15g, step %d px, subpixel %s, median %.15g "
             "(eps %.15g px), deform %d, background %s, roi %d,%d,%d,%d, mask %.300s",
             w, h_px, win, p->overlap, p->step_px, sub[p->subpixel], p->median_thr, p->median_eps,
             p->deform, bg[p->background], p->roi[0], p->roi[1], p->roi[2], p->roi[3],
             p->mask[0] ? p->mask : "none");
    double exact[3] = {p->overlap, p->median_thr, p->median_eps};
    h = hash_bytes(HASH0, id->plan, strlen(id->plan));
    h = hash_bytes(h, exact, sizeof exact);
    id->plan_hash = rpiv_piv_hash_frames(pv, h);
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

/* fsync the folder holding path, so that a rename in it is on disk. */
static int sync_dir(const char *path)
{
    char dir[4096];
    const char *slash = strrchr(path, '/');
    if (!slash)
        snprintf(dir, sizeof dir, ".");
    else
        snprintf(dir, sizeof dir, "%.*s", (int)(slash - path) + (slash == path), path);
    int fd = open(dir, O_RDONLY);
    if (fd < 0)
        return -1;
    int r = fsync(fd);
    close(fd);
    return r;
}

/* Write this rank's state in pass `pass`: predictor pred (NULL in pass 0), sums of e. */
static rpiv_status ck_save(const rpiv_batch *b, const ck_ident *id, int npass, int pass,
                           const rpiv_field *pred, rpiv_ensemble *e)
{
    ck_header hd;
    size_t nsums;
    float *sums = rpiv_ensemble_data(e, &nsums);
    memset(&hd, 0, sizeof hd);
    memcpy(hd.magic, CK_MAGIC, 8);
    hd.endian = 0x01020304u;
    hd.version = 1;
    hd.rank = rpiv_mpi_rank(b->mpi);
    hd.nranks = rpiv_mpi_size(b->mpi);
    hd.pass = pass;
    hd.npass = npass;
    hd.has_pred = pred != NULL;
    hd.npairs = b->pairs->n;
    hd.series_hash = id->series_hash;
    hd.plan_hash = id->plan_hash;
    hd.nsums = nsums;
    hd.nadded = rpiv_ensemble_npairs(e);
    memcpy(hd.series, id->series, sizeof hd.series);
    memcpy(hd.plan, id->plan, sizeof hd.plan);

    size_t len = strlen(b->ckpt) + 32;
    char *tmp = malloc(len);
    if (!tmp)
        return rpiv_fail(RPIV_ENOMEM, "checkpoint: out of memory");
    snprintf(tmp, len, "%s.tmp%ld", b->ckpt, (long)getpid());
    rpiv_status st = RPIV_OK;
    ck_io io = {fopen(tmp, "wb"), HASH0, 0};
    if (!io.fp) {
        st = rpiv_fail(RPIV_EIO, "%s: cannot write checkpoint: %s", b->ckpt, strerror(errno));
        goto out_free;
    }
    put(&io, &hd, sizeof hd);
    if (pred) {
        size_t n = (size_t)pred->nx * (size_t)pred->ny;
        int32_t dims[2] = {pred->nx, pred->ny};
        double g[6] = {pred->x0, pred->y0, pred->dx, pred->dy, pred->scale_mm_per_px, pred->dt_s};
        put(&io, dims, sizeof dims);
        put(&io, g, sizeof g);
        put(&io, pred->u, n * sizeof *pred->u);
        put(&io, pred->v, n * sizeof *pred->v);
        put(&io, pred->peak_ratio, n * sizeof *pred->peak_ratio);
        put(&io, pred->corr, n * sizeof *pred->corr);
        put(&io, pred->flag, n);
    }
    put(&io, b->state, b->pairs->n);
    put(&io, sums, nsums * sizeof *sums);
    uint64_t sum = io.h;
    put(&io, &sum, sizeof sum);
    int bad = io.bad || fflush(io.fp) != 0 || fsync(fileno(io.fp)) != 0;
    int err = errno;
    bad |= fclose(io.fp) != 0;
    if (bad || rename(tmp, b->ckpt) != 0) {
        st = rpiv_fail(RPIV_EIO, "%s: cannot write checkpoint: %s", b->ckpt,
                       strerror(bad && err ? err : errno));
        remove(tmp);
        goto out_free;
    }
    sync_dir(b->ckpt); /* best effort: the file itself is complete either way */
out_free:
    free(tmp);
    return st;
}

/* Remove the temporary files a killed run left next to path (path.tmp<pid>). */
static void remove_stale(const char *path)
{
    char dir[4096], name[4096];
    const char *slash = strrchr(path, '/'), *base = slash ? slash + 1 : path;
    if (!slash)
        snprintf(dir, sizeof dir, ".");
    else
        snprintf(dir, sizeof dir, "%.*s", (int)(slash - path) + (slash == path), path);
    size_t nb = strlen(base);
    DIR *d = opendir(dir);
    if (!d)
        return;
    for (struct dirent *de; (de = readdir(d));)
        if (!strncmp(de->d_name, base, nb) && !strncmp(de->d_name + nb, ".tmp", 4) &&
            snprintf(name, sizeof name, "%s/%s", dir, de->d_name) < (int)sizeof name)
            remove(name);
    closedir(d);
}

/* Is there a file at path? */
static int exists(const char *path)
{
    return access(path, F_OK) == 0;
}

/* A missing checkpoint: fine (*found = 0), unless the other team size's file is there. */
static rpiv_status ck_missing(const rpiv_batch *b, const char *user_path)
{
    char other[4200];
    if (rpiv_mpi_size(b->mpi) > 1) {
        if (exists(user_path))
            return rpiv_fail(RPIV_EFORMAT,
                             "%s: checkpoint of a one-process run; this run has "
                             "%d ranks (resume it without mpirun)",
                             user_path, rpiv_mpi_size(b->mpi));
        return RPIV_OK;
    }
    snprintf(other, sizeof other, "%s.rank0", user_path);
    if (exists(other))
        return rpiv_fail(RPIV_EFORMAT,
                         "%s: no such checkpoint, but %s is one of a run with "
                         "several MPI ranks (resume it with the same mpirun -np)",
                         user_path, other);
    return RPIV_OK;
}

/* Read this rank's checkpoint: *found = 0 if there is none; else its pass, predictor (NULL in
 * pass 0), an accumulator holding its sums, and the pair states. */
static rpiv_status ck_load(rpiv_batch *b, rpiv_piv *pv, const ck_ident *id, const char *user_path,
                           int *found, int *pass, rpiv_field **pred, rpiv_ensemble **e)
{
    *found = 0;
    *pred = NULL;
    *e = NULL;
    const char *path = b->ckpt;
    ck_io io = {fopen(path, "rb"), HASH0, 0};
    if (!io.fp)
        return errno == ENOENT ? ck_missing(b, user_path)
                               : rpiv_fail(RPIV_EIO, "%s: cannot open: %s", path, strerror(errno));
    ck_header hd;
    rpiv_status st = RPIV_OK;
    int K = rpiv_mpi_size(b->mpi), r = rpiv_mpi_rank(b->mpi);
    if (!get(&io, &hd, sizeof hd) || memcmp(hd.magic, CK_MAGIC, 8) != 0) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: not an rpiv checkpoint", path);
        goto out_fail;
    }
    hd.series[sizeof hd.series - 1] = hd.plan[sizeof hd.plan - 1] = '\0';
    if (hd.endian != 0x01020304u || hd.version != 1) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: checkpoint of another rpiv version or machine", path);
        goto out_fail;
    }
    if (hd.nranks != K || hd.rank != r) {
        st = rpiv_fail(RPIV_EFORMAT,
                       "%s: checkpoint of rank %d of a %d-rank run; this is rank "
                       "%d of %d (resume with mpirun -np %d)",
                       path, hd.rank, hd.nranks, r, K, hd.nranks);
        goto out_fail;
    }
    if (hd.npairs != b->pairs->n || hd.series_hash != id->series_hash) {
        st = rpiv_fail(RPIV_EFORMAT,
                       "%s: checkpoint of another series of pairs (%s); this "
                       "run has %s",
                       path, hd.series, id->series);
        goto out_fail;
    }
    if (hd.plan_hash != id->plan_hash || hd.npass != rpiv_piv_npass(pv)) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: checkpoint of another plan (%s); this run: %s%s", path,
                       hd.plan, id->plan,
                       strcmp(hd.plan, id->plan) ? "" : " (the mask or background frames differ)");
        goto out_fail;
    }
    if (hd.pass < 0 || hd.pass >= hd.npass || hd.has_pred != (hd.pass > 0)) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: corrupt checkpoint (pass %d of %d)", path, hd.pass + 1,
                       hd.npass);
        goto out_fail;
    }
    if (hd.has_pred) {
        int32_t dims[2];
        double g[6];
        if (!get(&io, dims, sizeof dims) || !get(&io, g, sizeof g))
            goto out_truncated;
        if ((st = rpiv_field_new(dims[0], dims[1], g[0], g[1], g[2], g[3], pred))) {
            st = rpiv_fail(RPIV_EFORMAT, "%s: corrupt checkpoint (predictor grid)", path);
            goto out_fail;
        }
        (*pred)->scale_mm_per_px = g[4];
        (*pred)->dt_s = g[5];
        size_t n = (size_t)dims[0] * (size_t)dims[1];
        rpiv_field *f = *pred;
        if (!get(&io, f->u, n * sizeof *f->u) || !get(&io, f->v, n * sizeof *f->v) ||
            !get(&io, f->peak_ratio, n * sizeof *f->peak_ratio) ||
            !get(&io, f->corr, n * sizeof *f->corr) || !get(&io, f->flag, n))
            goto out_truncated;
    }
    if (!get(&io, b->state, b->pairs->n))
        goto out_truncated;
    if ((st = rpiv_ensemble_new(pv, hd.pass, *pred, e)))
        goto out_fail;
    size_t nsums;
    float *sums = rpiv_ensemble_data(*e, &nsums);
    if (nsums != hd.nsums) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: corrupt checkpoint (%llu sums, the plan has %zu)", path,
                       (unsigned long long)hd.nsums, nsums);
        goto out_fail;
    }
    if (!get(&io, sums, nsums * sizeof *sums))
        goto out_truncated;
    uint64_t want = io.h, sum;
    if (!get(&io, &sum, sizeof sum))
        goto out_truncated;
    if (sum != want) {
        st = rpiv_fail(RPIV_EFORMAT, "%s: corrupt checkpoint (checksum mismatch)", path);
        goto out_fail;
    }
    rpiv_ensemble_set_npairs(*e, (size_t)hd.nadded);
    for (size_t i = 0; i < b->pairs->n; i++)
        b->state[i] &= DONE | BAD;
    fclose(io.fp);
    *found = 1;
    *pass = hd.pass;
    return RPIV_OK;
out_truncated:
    st = rpiv_fail(RPIV_EFORMAT, "%s: truncated checkpoint", path);
out_fail:
    fclose(io.fp);
    rpiv_ensemble_free(*e);
    rpiv_field_free(*pred);
    *e = NULL;
    *pred = NULL;
    memset(b->state, 0, b->pairs->n);
    return st;
}

/* Resume from the ranks' checkpoints (collective): *pass0 the pass to continue, *pred its
 * predictor and *e this rank's sums (NULL if this rank starts the pass afresh). */
static rpiv_status resume(rpiv_batch *b, rpiv_piv *pv, const ck_ident *id, const char *user_path,
                          int *pass0, rpiv_field **pred, rpiv_ensemble **e)
{
    const rpiv_mpi *m = b->mpi;
    int found = 0, pass = -1, r = rpiv_mpi_rank(m), K = rpiv_mpi_size(m);
    rpiv_status st = ck_load(b, pv, id, user_path, &found, &pass, pred, e);
    if ((st = rpiv_mpi_agree(m, st)))
        goto out_fail;
    long top = found ? pass : -1, holder;
    if ((st = mpi_max_long(m, &top)))
        goto out_fail;
    if (top < 0)
        return RPIV_OK; /* no checkpoint anywhere: begin */
    if (!found && top > 0)
        st = rpiv_fail(RPIV_EFORMAT,
                       "%s: missing, while the other ranks' checkpoints are in "
                       "pass %ld",
                       b->ckpt, top + 1);
    if ((st = rpiv_mpi_agree(m, st)))
        goto out_fail;
    /* a rank one pass behind (killed before it saved the new pass) starts that pass afresh
     * with the predictor of the lowest rank that has it */
    holder = found && pass == top ? -(long)r : -(long)K;
    if ((st = mpi_max_long(m, &holder)))
        goto out_fail;
    holder = -holder;
    if (found && pass < top) {
        rpiv_ensemble_free(*e);
        *e = NULL;
        for (size_t i = 0; i < b->pairs->n; i++)
            b->state[i] &= BAD;
    }
    if (r != holder) {
        rpiv_field_free(*pred);
        *pred = NULL;
    }
    if (top > 0 && (st = mpi_bcast_field(m, (int)holder, pred)))
        goto out_fail;
    size_t done = *e ? rpiv_ensemble_npairs(*e) : 0;
    if ((st = mpi_sum_size(m, &done)) || (st = sync_bad(b)))
        goto out_fail;
    b->resumed = 1;
    b->resume_pass = (int)top;
    b->resume_done = done;
    *pass0 = (int)top;
    return RPIV_OK;
out_fail:
    rpiv_ensemble_free(*e);
    rpiv_field_free(*pred);
    *e = NULL;
    *pred = NULL;
    return st;
}

/* ---- the ensemble run -------------------------------------------------------------------- */

/* Add pair i to e (plan pv): RPIV_OK when added or (skip_bad) skipped; else the error. */
static rpiv_status add_pair(rpiv_batch *b, const rpiv_piv *pv, rpiv_ensemble *e, size_t i,
                            int *added)
{
    rpiv_image *a = NULL, *bb = NULL;
    int w, h_px;
    rpiv_piv_size(pv, &w, &h_px);
    rpiv_status st = load_pair(b, i, w, h_px, &a, &bb);
    *added = 0;
    if (!st && (st = rpiv_ensemble_add(e, a, bb))) {
        char msg[768];
        snprintf(msg, sizeof msg, "%s", rpiv_errmsg());
        st = rpiv_fail(st, "pair %zu (%s): %s", i + 1, b->pairs->pair[i].path_a, msg);
    }
    rpiv_image_free(a);
    rpiv_image_free(bb);
    if (!st) {
        b->state[i] |= DONE;
        *added = 1;
    } else if (b->p.skip_bad && unreadable(st)) {
        mark_bad(b, i, 1);
        st = RPIV_OK;
    }
    return st;
}

/* A failed run keeps its checkpoint: save the state and say so after the message. */
static rpiv_status stop_with_checkpoint(const rpiv_batch *b, const ck_ident *id, int npass,
                                        int pass, const rpiv_field *pred, rpiv_ensemble *e,
                                        rpiv_status st)
{
    char msg[1024];
    snprintf(msg, sizeof msg, "%s", rpiv_errmsg());
    rpiv_status cs = ck_save(b, id, npass, pass, pred, e);
    if (cs) {
        char cmsg[512];
        snprintf(cmsg, sizeof cmsg, "%s", rpiv_errmsg());
        return rpiv_fail(st, "%s (and the checkpoint: %s)", msg, cmsg);
    }
    return rpiv_fail(st,
                     "%s; checkpoint %s saved (pass %d, %zu pair%s summed there by this "
                     "process)",
                     msg, b->ckpt, pass + 1, rpiv_ensemble_npairs(e),
                     rpiv_ensemble_npairs(e) == 1 ? "" : "s");
}

/* The pass is complete on every rank: combine the sums, locate the peaks. Collective. */
static rpiv_status finish_pass(rpiv_batch *b, rpiv_ensemble *e, int pass, rpiv_field **f)
{
    size_t n, np = rpiv_ensemble_npairs(e);
    float *data = rpiv_ensemble_data(e, &n);
    rpiv_status st;
    if ((st = sync_bad(b)) || (st = mpi_sum_floats(b->mpi, data, n)) ||
        (st = mpi_sum_size(b->mpi, &np)))
        return st;
    rpiv_ensemble_set_npairs(e, np);
    b->npairs_last = np;
    if (!np)
        return rpiv_fail(RPIV_EIO, "ensemble pass %d: none of the %zu pairs could be read",
                         pass + 1, b->pairs->n);
    return rpiv_mpi_agree(b->mpi, rpiv_ensemble_finish(e, f));
}

rpiv_status rpiv_batch_ensemble(rpiv_batch *b, rpiv_piv *pv, const rpiv_progress *progress,
                                rpiv_field **out)
{
    *out = NULL;
    const rpiv_mpi *m = b->mpi;
    size_t N = b->pairs->n, K = (size_t)rpiv_mpi_size(m), r = (size_t)rpiv_mpi_rank(m);
    int npass = rpiv_piv_npass(pv), pass0 = 0, saved_ok = 1;
    rpiv_field *pred = NULL;
    rpiv_ensemble *e = NULL;
    rpiv_status st = RPIV_OK;
    ck_ident id;
    char user_path[4096] = "";
    if (b->ckpt) {
        ident_of(b, pv, &id);
        snprintf(user_path, sizeof user_path, "%s", b->ckpt);
        if (K > 1)
            *strrchr(user_path, '.') = '\0';
    }
    for (size_t i = 0; i < N; i++)
        b->state[i] &= BAD;
    b->resumed = 0;
    if (b->ckpt) {
        remove_stale(b->ckpt);
        /* an interrupted run's checkpoint is not overwritten by a new run by mistake */
        if (!b->p.resume && exists(b->ckpt))
            st = rpiv_fail(RPIV_EINVAL,
                           "%s: a checkpoint is already there: continue it (rpiv piv "
                           "--resume) or remove it to start again",
                           b->ckpt);
        if ((st = rpiv_mpi_agree(m, st)))
            return st;
    }
    if (b->ckpt && b->p.resume && (st = resume(b, pv, &id, user_path, &pass0, &pred, &e)))
        return st;
    size_t nmine = 0, done = 0;
    for (size_t i = r; i < N; i += K) {
        nmine++;
        done += (b->state[i] & (DONE | BAD)) != 0;
    }
    size_t total = nmine * (size_t)npass;
    done += nmine * (size_t)pass0;
    for (int k = pass0; k < npass; k++) {
        if (!e) {
            for (size_t i = 0; i < N; i++)
                b->state[i] &= BAD;
            if (!(st = rpiv_ensemble_new(pv, k, pred, &e)) && b->ckpt)
                saved_ok = !(st = ck_save(b, &id, npass, k, pred, e));
        }
        if ((st = rpiv_mpi_agree(m, st)))
            break;
        size_t since = 0;
        for (size_t i = r; i < N && !st; i += K) {
            int added;
            if (b->state[i] & (DONE | BAD))
                continue;
            if ((st = add_pair(b, pv, e, i, &added)))
                break;
            since += (size_t)added;
            if (b->ckpt && b->p.checkpoint_every && since >= b->p.checkpoint_every) {
                saved_ok = !(st = ck_save(b, &id, npass, k, pred, e));
                since = 0;
            }
            if (!st && rpiv_progress_report(progress, ++done, total))
                st = rpiv_fail(RPIV_EINTR,
                               "ensemble: interrupted in pass %d after %zu of "
                               "%zu pairs",
                               k + 1, i / K + 1, nmine);
        }
        if ((st = rpiv_mpi_agree(m, st))) {
            if (b->ckpt && saved_ok)
                st = stop_with_checkpoint(b, &id, npass, k, pred, e, st);
            break;
        }
        rpiv_field *f = NULL;
        st = finish_pass(b, e, k, &f);
        rpiv_ensemble_free(e);
        e = NULL;
        rpiv_field_free(pred);
        pred = f;
        if (st)
            break;
    }
    rpiv_ensemble_free(e);
    if (st) {
        rpiv_field_free(pred);
        return st;
    }
    if (b->ckpt)
        remove(b->ckpt); /* the run is complete: nothing to resume */
    *out = pred;
    return RPIV_OK;
}

/* ---- per-pair fields --------------------------------------------------------------------- */

/* Process pair i: *f its field, NULL if skipped. */
static rpiv_status run_pair(rpiv_batch *b, rpiv_piv *pv, size_t i, rpiv_field **f)
{
    rpiv_image *a = NULL, *bb = NULL;
    int w, h_px;
    rpiv_piv_size(pv, &w, &h_px);
    rpiv_status st = load_pair(b, i, w, h_px, &a, &bb);
    if (!st && (st = rpiv_piv_run(pv, a, bb, f))) {
        char msg[768];
        snprintf(msg, sizeof msg, "%s", rpiv_errmsg());
        st = rpiv_fail(st, "pair %zu (%s): %s", i + 1, b->pairs->pair[i].path_a, msg);
    }
    rpiv_image_free(a);
    rpiv_image_free(bb);
    if (st && b->p.skip_bad && unreadable(st)) {
        mark_bad(b, i, 1);
        st = RPIV_OK;
    }
    return st;
}

rpiv_status rpiv_batch_series(rpiv_batch *b, rpiv_piv *pv, rpiv_series_sink local,
                              rpiv_series_sink root, void *user, const rpiv_progress *progress)
{
    const rpiv_mpi *m = b->mpi;
    size_t N = b->pairs->n, K = (size_t)rpiv_mpi_size(m), r = (size_t)rpiv_mpi_rank(m);
    size_t nmine = N / K + (r < N % K), done = 0;
    rpiv_field *grid = NULL, **all = calloc(K, sizeof *all);
    rpiv_status st = all ? RPIV_OK : rpiv_fail(RPIV_ENOMEM, "piv: out of memory");
    if (!st && root && K > 1)
        st = rpiv_piv_grid(pv, rpiv_piv_npass(pv) - 1, &grid);
    st = rpiv_mpi_agree(m, st);
    for (size_t j = 0; !st && j * K < N; j++) {
        size_t i = j * K + r;
        rpiv_field *f = NULL;
        if (i < N && !(b->state[i] & BAD)) {
            if (!(st = run_pair(b, pv, i, &f)) && f && local)
                st = local(user, i, f);
            if (!st && K == 1 && f && root)
                st = root(user, i, f);
        }
        if (!st && i < N && rpiv_progress_report(progress, ++done, nmine))
            st = rpiv_fail(RPIV_EINTR, "piv: interrupted after %zu of %zu pairs", done, nmine);
        st = rpiv_mpi_agree(m, st);
        if (!st && root && K > 1) {
            st = mpi_gather_fields(m, f, grid, all);
            for (size_t q = 0; q < K; q++) {
                if (!st && all[q])
                    st = root(user, j * K + q, all[q]);
                rpiv_field_free(all[q]);
                all[q] = NULL;
            }
            st = rpiv_mpi_agree(m, st);
        }
        rpiv_field_free(f);
    }
    rpiv_status ss = sync_bad(b);
    rpiv_field_free(grid);
    free(all);
    return st ? st : ss;
}
