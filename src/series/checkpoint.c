/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/series/checkpoint.c - the batch's checkpoints (rpiv/batch.h): what identifies a run,
 * the file of a rank's state, its atomic writing, and resuming from the ranks' files. */
#include "series_impl.h"

#include "base/hash.h"
#include "mpi_impl.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* ---- checkpoint files -------------------------------------------------------------------- */

#define CK_MAGIC "RPIVCKP1"

typedef struct ck_header {
    char magic[8];
    uint32_t endian, version;
    int32_t rank, nranks, pass, npass, has_pred, pad;
    uint64_t npairs, series_hash, plan_hash, nsums, nadded;
    char series[256], plan[768];
} ck_header;

void ck_ident_of(const rpiv_batch *b, const rpiv_piv *pv, ck_ident *id)
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
rpiv_status ck_save(const rpiv_batch *b, const ck_ident *id, int npass, int pass,
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
void ck_remove_stale(const char *path)
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
int ck_exists(const char *path)
{
    return access(path, F_OK) == 0;
}

/* A missing checkpoint: fine (*found = 0), unless the other team size's file is there. */
static rpiv_status ck_missing(const rpiv_batch *b, const char *user_path)
{
    char other[4200];
    if (rpiv_mpi_size(b->mpi) > 1) {
        if (ck_exists(user_path))
            return rpiv_fail(RPIV_EFORMAT,
                             "%s: checkpoint of a one-process run; this run has "
                             "%d ranks (resume it without mpirun)",
                             user_path, rpiv_mpi_size(b->mpi));
        return RPIV_OK;
    }
    snprintf(other, sizeof other, "%s.rank0", user_path);
    if (ck_exists(other))
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
rpiv_status ck_resume(rpiv_batch *b, rpiv_piv *pv, const ck_ident *id, const char *user_path,
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
    if ((st = mpi_sum_size(m, &done)) || (st = batch_sync_bad(b)))
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

/* A failed run keeps its checkpoint: save the state and say so after the message. */
rpiv_status ck_stop(const rpiv_batch *b, const ck_ident *id, int npass, int pass,
                    const rpiv_field *pred, rpiv_ensemble *e, rpiv_status st)
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
