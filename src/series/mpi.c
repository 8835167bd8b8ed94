/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/series/mpi.c - the team of processes (rpiv/mpi.h) and its collectives (mpi_impl.h). Built
 * without MPI (RPIV_HAVE_MPI undefined) every team is a team of one and the collectives do
 * nothing. */
#include "mpi_impl.h"

#include <assert.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#ifdef RPIV_HAVE_MPI
#include <mpi.h>
#endif

struct rpiv_mpi {
    int rank, size;
    int active; /* MPI is in use (size may still be 1)   */
    int owner;  /* rpiv_mpi_new called MPI_Init: finalize */
};

int rpiv_mpi_built(void)
{
#ifdef RPIV_HAVE_MPI
    return 1;
#else
    return 0;
#endif
}

int rpiv_mpi_rank(const rpiv_mpi *m)
{
    return m ? m->rank : 0;
}

int rpiv_mpi_size(const rpiv_mpi *m)
{
    return m ? m->size : 1;
}

int rpiv_mpi_mine(const rpiv_mpi *m, size_t index)
{
    return index % (size_t)rpiv_mpi_size(m) == (size_t)rpiv_mpi_rank(m);
}

/* MPI is in use with more than one rank. */
static int team(const rpiv_mpi *m)
{
    return m && m->active && m->size > 1;
}

#ifdef RPIV_HAVE_MPI
/* Started by an MPI launcher (see rpiv/mpi.h), or told to join by RPIV_MPI. */
static int launched(void)
{
    static const char *const vars[] = {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_SIZE", "PMI_RANK"};
    const char *force = getenv("RPIV_MPI");
    if (force && *force)
        return strcmp(force, "0") != 0;
    for (size_t i = 0; i < sizeof vars / sizeof *vars; i++)
        if (getenv(vars[i]))
            return 1;
    return 0;
}
#endif

rpiv_status rpiv_mpi_new(int *argc, char ***argv, rpiv_mpi **out)
{
    *out = NULL;
    rpiv_mpi *m = calloc(1, sizeof *m);
    if (!m)
        return rpiv_fail(RPIV_ENOMEM, "mpi: out of memory");
    m->size = 1;
#ifdef RPIV_HAVE_MPI
    int ready = 0;
    MPI_Initialized(&ready);
    if (!ready && launched()) {
        int provided = 0;
        if (MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS) {
            free(m);
            return rpiv_fail(RPIV_EIO, "mpi: MPI_Init_thread failed");
        }
        m->owner = ready = 1;
    }
    if (ready) {
        m->active = 1;
        MPI_Comm_rank(MPI_COMM_WORLD, &m->rank);
        MPI_Comm_size(MPI_COMM_WORLD, &m->size);
    }
#else
    (void)argc;
    (void)argv;
#endif
    *out = m;
    return RPIV_OK;
}

void rpiv_mpi_free(rpiv_mpi *m)
{
    if (!m)
        return;
#ifdef RPIV_HAVE_MPI
    int done = 0;
    MPI_Finalized(&done);
    if (m->owner && !done)
        MPI_Finalize();
#endif
    free(m);
}

rpiv_status rpiv_mpi_agree(const rpiv_mpi *m, rpiv_status st)
{
    if (!team(m))
        return st;
#ifdef RPIV_HAVE_MPI
    int first = st ? m->rank : m->size, lowest = m->size, code = (int)st;
    MPI_Allreduce(&first, &lowest, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
    if (lowest == m->size)
        return RPIV_OK;
    MPI_Bcast(&code, 1, MPI_INT, lowest, MPI_COMM_WORLD);
    if (st)
        return st;
    return rpiv_fail((rpiv_status)code, "rank %d of %d stopped: rank %d failed (%s)", m->rank,
                     m->size, lowest, rpiv_strerror((rpiv_status)code));
#else
    return st;
#endif
}

/* ---- collectives ------------------------------------------------------------------------ */

#ifdef RPIV_HAVE_MPI
enum { CHUNK = 1 << 20 }; /* elements per MPI call: counts are int, buffers stay small */

static int chunk(size_t n, size_t off)
{
    return (int)(n - off < CHUNK ? n - off : CHUNK);
}

/* Agree on a local allocation (p NULL: it failed); frees nothing. */
static rpiv_status agree_alloc(const rpiv_mpi *m, const void *p)
{
    return rpiv_mpi_agree(m, p ? RPIV_OK : rpiv_fail(RPIV_ENOMEM, "mpi: out of memory"));
}
#endif

rpiv_status mpi_sum_doubles(const rpiv_mpi *m, double *data, size_t n)
{
    if (!team(m))
        return RPIV_OK;
#ifdef RPIV_HAVE_MPI
    double *sum = m->rank == 0 ? malloc((size_t)CHUNK * sizeof *sum) : NULL;
    rpiv_status st = agree_alloc(m, m->rank == 0 ? (const void *)sum : (const void *)m);
    for (size_t off = 0; !st && off < n; off += CHUNK) {
        int c = chunk(n, off);
        MPI_Reduce(data + off, sum, c, MPI_DOUBLE, MPI_SUM, 0, MPI_COMM_WORLD);
        if (m->rank == 0)
            memcpy(data + off, sum, (size_t)c * sizeof *sum);
        MPI_Bcast(data + off, c, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    }
    free(sum);
    return st;
#else
    (void)data;
    (void)n;
    return RPIV_OK;
#endif
}

rpiv_status mpi_sum_floats(const rpiv_mpi *m, float *data, size_t n)
{
    if (!team(m))
        return RPIV_OK;
#ifdef RPIV_HAVE_MPI
    double *buf = malloc(2 * (size_t)CHUNK * sizeof *buf);
    rpiv_status st = agree_alloc(m, buf);
    for (size_t off = 0; !st && off < n; off += CHUNK) {
        int c = chunk(n, off);
        double *mine = buf, *sum = buf + CHUNK;
        for (int i = 0; i < c; i++)
            mine[i] = (double)data[off + (size_t)i];
        MPI_Reduce(mine, sum, c, MPI_DOUBLE, MPI_SUM, 0, MPI_COMM_WORLD);
        if (m->rank == 0)
            for (int i = 0; i < c; i++)
                data[off + (size_t)i] = (float)sum[i];
        MPI_Bcast(data + off, c, MPI_FLOAT, 0, MPI_COMM_WORLD);
    }
    free(buf);
    return st;
#else
    (void)data;
    (void)n;
    return RPIV_OK;
#endif
}

rpiv_status mpi_min_floats(const rpiv_mpi *m, float *data, size_t n)
{
    if (!team(m))
        return RPIV_OK;
#ifdef RPIV_HAVE_MPI
    for (size_t off = 0; off < n; off += CHUNK)
        MPI_Allreduce(MPI_IN_PLACE, data + off, chunk(n, off), MPI_FLOAT, MPI_MIN, MPI_COMM_WORLD);
#else
    (void)data;
    (void)n;
#endif
    return RPIV_OK;
}

rpiv_status mpi_max_bytes(const rpiv_mpi *m, unsigned char *data, size_t n)
{
    if (!team(m))
        return RPIV_OK;
#ifdef RPIV_HAVE_MPI
    for (size_t off = 0; off < n; off += CHUNK)
        MPI_Allreduce(MPI_IN_PLACE, data + off, chunk(n, off), MPI_UNSIGNED_CHAR, MPI_MAX,
                      MPI_COMM_WORLD);
#else
    (void)data;
    (void)n;
#endif
    return RPIV_OK;
}

rpiv_status mpi_max_long(const rpiv_mpi *m, long *v)
{
    if (!team(m))
        return RPIV_OK;
#ifdef RPIV_HAVE_MPI
    MPI_Allreduce(MPI_IN_PLACE, v, 1, MPI_LONG, MPI_MAX, MPI_COMM_WORLD);
#else
    (void)v;
#endif
    return RPIV_OK;
}

rpiv_status mpi_sum_size(const rpiv_mpi *m, size_t *v)
{
    if (!team(m))
        return RPIV_OK;
#ifdef RPIV_HAVE_MPI
    uint64_t x = (uint64_t)*v;
    MPI_Allreduce(MPI_IN_PLACE, &x, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
    *v = (size_t)x;
#else
    (void)v;
#endif
    return RPIV_OK;
}

rpiv_status mpi_bcast_field(const rpiv_mpi *m, int root, rpiv_field **f)
{
    if (!team(m))
        return RPIV_OK;
#ifdef RPIV_HAVE_MPI
    int dims[2] = {0, 0};
    double g[6] = {0};
    int me = m->rank == root;
    if (me) {
        const rpiv_field *s = *f;
        dims[0] = s->nx;
        dims[1] = s->ny;
        double h[6] = {s->x0, s->y0, s->dx, s->dy, s->scale_mm_per_px, s->dt_s};
        memcpy(g, h, sizeof g);
    } else {
        assert(!*f);
    }
    MPI_Bcast(dims, 2, MPI_INT, root, MPI_COMM_WORLD);
    MPI_Bcast(g, 6, MPI_DOUBLE, root, MPI_COMM_WORLD);
    rpiv_status st = RPIV_OK;
    if (!me && !(st = rpiv_field_new(dims[0], dims[1], g[0], g[1], g[2], g[3], f))) {
        (*f)->scale_mm_per_px = g[4];
        (*f)->dt_s = g[5];
    }
    if ((st = rpiv_mpi_agree(m, st)))
        goto out_drop;
    rpiv_field *d = *f;
    int n = dims[0] * dims[1];
    float *arr[4] = {d->u, d->v, d->peak_ratio, d->corr};
    for (int k = 0; k < 4; k++)
        MPI_Bcast(arr[k], n, MPI_FLOAT, root, MPI_COMM_WORLD);
    MPI_Bcast(d->flag, n, MPI_UNSIGNED_CHAR, root, MPI_COMM_WORLD);
    return RPIV_OK;
out_drop:
    if (!me) {
        rpiv_field_free(*f);
        *f = NULL;
    }
    return st;
#else
    (void)root;
    (void)f;
    return RPIV_OK;
#endif
}

rpiv_status mpi_gather_fields(const rpiv_mpi *m, const rpiv_field *mine, const rpiv_field *grid,
                              rpiv_field **all)
{
    if (!team(m)) {
        rpiv_status st = RPIV_OK;
        all[0] = NULL;
        if (mine)
            st = rpiv_field_copy(mine, &all[0]);
        return st;
    }
#ifdef RPIV_HAVE_MPI
    size_t n = (size_t)grid->nx * (size_t)grid->ny, rec = 1 + n * (4 * sizeof(float) + 1);
    unsigned char *snd = calloc(1, rec), *rcv = NULL; /* rcv: rank 0 only */
    if (m->rank == 0)
        rcv = malloc(rec * (size_t)m->size);
    rpiv_status st = agree_alloc(m, snd && (rcv || m->rank) ? snd : NULL);
    if (st)
        goto out_free;
    if (mine) {
        assert(mine->nx == grid->nx && mine->ny == grid->ny);
        const float *arr[4] = {mine->u, mine->v, mine->peak_ratio, mine->corr};
        snd[0] = 1;
        for (int k = 0; k < 4; k++)
            memcpy(snd + 1 + (size_t)k * n * sizeof(float), arr[k], n * sizeof(float));
        memcpy(snd + 1 + 4 * n * sizeof(float), mine->flag, n);
    }
    MPI_Gather(snd, (int)rec, MPI_BYTE, rcv, (int)rec, MPI_BYTE, 0, MPI_COMM_WORLD);
    if (m->rank == 0) {
        for (int r = 0; r < m->size; r++)
            all[r] = NULL;
        for (int r = 0; r < m->size && !st; r++) {
            const unsigned char *p = rcv + (size_t)r * rec;
            if (!p[0] || (st = rpiv_field_copy(grid, &all[r])))
                continue;
            float *arr[4] = {all[r]->u, all[r]->v, all[r]->peak_ratio, all[r]->corr};
            for (int k = 0; k < 4; k++)
                memcpy(arr[k], p + 1 + (size_t)k * n * sizeof(float), n * sizeof(float));
            memcpy(all[r]->flag, p + 1 + 4 * n * sizeof(float), n);
        }
    }
out_free:
    free(rcv);
    free(snd);
    return st;
#else
    (void)grid;
    return RPIV_OK;
#endif
}
