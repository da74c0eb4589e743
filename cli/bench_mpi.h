/* bench_mpi.h - `specklab bench --mpi`: specklab-mpi recon timed on 1, 2
 * and 4 ranks (oversubscribed when the machine has fewer cores), its
 * parallel efficiency, and a model for N nodes from the bytes of sums each
 * run reduces against a network's bandwidth.  specklab itself does not
 * link MPI: it runs mpirun on the specklab-mpi beside it (or in PATH). */
#ifndef SL_BENCH_MPI_H
#define SL_BENCH_MPI_H

#include "bench_ctx.h"

/* The exit status: 0, or 1 when specklab-mpi or mpirun is missing or a
 * run fails (said on stderr). */
int bench_mpi_run(const bench_args *a);

#endif
