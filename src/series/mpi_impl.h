/* SPDX-License-Identifier: GPL-3.0-or-later */
/* src/series/mpi_impl.h - the collectives rpiv's series runs need, over a team (rpiv/mpi.h).
 *
 * Every function here is collective: all ranks of the team call it at the same point, in the
 * same order, whatever happened locally (a rank that failed still takes part, and the
 * outcome is agreed with rpiv_mpi_agree). With a team of one (or NULL) they do nothing.
 * Results are identical on every rank: sums are formed at rank 0 and broadcast. */
#ifndef RPIV_MPI_IMPL_H
#define RPIV_MPI_IMPL_H

#include "rpiv/field.h"
#include "rpiv/mpi.h"

#include <stddef.h>

/* data[i] = sum over ranks of data[i], summed in double (floats are converted exactly; the
 * sum of K floats is exact in double unless their exponents spread over more than 29
 * binary orders, so the order MPI chooses does not matter) and rounded once to float. */
RPIV_NODISCARD rpiv_status mpi_sum_floats(const rpiv_mpi *m, float *data, size_t n);
/* data[i] = sum over ranks, in double, formed at rank 0 and broadcast. */
RPIV_NODISCARD rpiv_status mpi_sum_doubles(const rpiv_mpi *m, double *data, size_t n);
/* data[i] = minimum over ranks (exact). */
RPIV_NODISCARD rpiv_status mpi_min_floats(const rpiv_mpi *m, float *data, size_t n);
/* data[i] = maximum over ranks. */
RPIV_NODISCARD rpiv_status mpi_max_bytes(const rpiv_mpi *m, unsigned char *data, size_t n);
/* *v = maximum (or sum) over ranks. */
RPIV_NODISCARD rpiv_status mpi_max_long(const rpiv_mpi *m, long *v);
RPIV_NODISCARD rpiv_status mpi_sum_size(const rpiv_mpi *m, size_t *v);

/* Rank `root`'s *f (a field) is copied to every other rank into a new *f (theirs must be
 * NULL on entry; they own the copy). */
RPIV_NODISCARD rpiv_status mpi_bcast_field(const rpiv_mpi *m, int root, rpiv_field **f);

/* Every rank passes its field `mine` (NULL: none this time) on the grid of `grid`; rank 0
 * receives all[r] = a new copy of rank r's field, or NULL (all has size() entries, filled
 * on rank 0 only; the caller frees them). */
RPIV_NODISCARD rpiv_status mpi_gather_fields(const rpiv_mpi *m, const rpiv_field *mine,
                                             const rpiv_field *grid, rpiv_field **all);

#endif /* RPIV_MPI_IMPL_H */
