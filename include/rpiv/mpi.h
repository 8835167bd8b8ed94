/* SPDX-License-Identifier: GPL-3.0-or-later */
/* rpiv/mpi.h - a team of processes sharing a series of pairs: the MPI ranks of a job started
 * by mpirun or srun, or this process alone.
 *
 * Long runs over a series (rpiv/batch.h) deal the pairs out to the ranks of a team: rank r
 * takes pairs r, r + K, r + 2K, ... (K ranks, 0-based pair indices). Every rank reads its own
 * images; only sums, statuses and (for a single output file) finished fields travel between
 * ranks. A team handle does not expose MPI types, so this header compiles without <mpi.h>.
 *
 * MPI is joined only when the library was built with it (RPIV_MPI, rpiv_mpi_built) and the
 * process was started by an MPI launcher, recognised from the variables it sets:
 * OMPI_COMM_WORLD_SIZE (OpenMPI's mpirun/mpiexec), PMIX_RANK (PMIx: srun --mpi=pmix,
 * OpenMPI 5), PMI_SIZE / PMI_RANK (MPICH's hydra, srun --mpi=pmi2). A process run directly
 * is a team of one and never calls MPI_Init (a singleton MPI_Init costs time and, under
 * AddressSanitizer, leak reports). The environment variable RPIV_MPI=0 keeps a launched
 * process out of MPI (every rank then works alone), RPIV_MPI=1 joins MPI even without a
 * launcher. MPI is used from the calling thread only (MPI_THREAD_FUNNELED; OpenMP threads
 * inside a rank never call it).
 *
 * A NULL team is a team of one, for every function taking a team. */
#ifndef RPIV_MPI_H
#define RPIV_MPI_H

#include "rpiv/error.h"

#include <stddef.h>

typedef struct rpiv_mpi rpiv_mpi;

/* 1 if the library was built with MPI support, else 0. */
int rpiv_mpi_built(void);

/* Join the job's team (see above) or make a team of one. MPI_Init_thread is called here when
 * MPI is joined and was not yet initialised; argc/argv are passed to it and may be NULL.
 * On RPIV_OK *out owns the team (release with rpiv_mpi_free, which calls MPI_Finalize if
 * this call initialised MPI). Errors: RPIV_EIO (MPI could not be initialised), RPIV_ENOMEM.
 * Call once per process, from the main thread. */
RPIV_NODISCARD rpiv_status rpiv_mpi_new(int *argc, char ***argv, rpiv_mpi **out);
void rpiv_mpi_free(rpiv_mpi *m); /* NULL is a no-op */

int rpiv_mpi_rank(const rpiv_mpi *m); /* 0..size-1; 0 for NULL */
int rpiv_mpi_size(const rpiv_mpi *m); /* >= 1; 1 for NULL     */

/* 1 if pair `index` is this rank's (index % size == rank). */
int rpiv_mpi_mine(const rpiv_mpi *m, size_t index);

/* Agree on the outcome of a step every rank took: collective, each rank passes its own
 * status. Returns RPIV_OK on every rank if all passed RPIV_OK. Otherwise a rank that failed
 * returns its own status with its own message, and the others return the status of the
 * lowest failing rank with the message "rank R of K stopped: rank F failed (status)".
 * A team of one returns st unchanged. */
RPIV_NODISCARD rpiv_status rpiv_mpi_agree(const rpiv_mpi *m, rpiv_status st);

#endif /* RPIV_MPI_H */
