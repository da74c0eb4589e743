/* reprocess.h - `mpirun -n N specklab-mpi reprocess --catalog DB`: every
 * catalogued run with a cube (state done; --since: created at or after)
 * reconstructed again (--method, default auto), the runs handed out one
 * at a time to ranks 1..N-1 as they come free (rank 0 alone with N = 1).
 *
 * Rank 0 owns the catalogue: it lists the runs and writes every new
 * reconstruction row, one transaction per run as its result arrives, so
 * whatever stops the job leaves the catalogue consistent with each run
 * done so far recorded (and its image written before its row).  The other
 * ranks never open it: they read their run's cube, write the image into
 * the output directory and send rank 0 the numbers for the row.  A rank
 * that dies ends the job (Open MPI's mpirun stops the others and names
 * the rank); a run that fails is reported and the job ends non-zero after
 * the others.  With N > 1 rank 0 only hands out and records (its writes
 * are one at a time anyway).  The cube is reconstructed as `specklab
 * recon` would, with the binary measured: the calibration runs (darks,
 * flats, a calibrator) that specklabd's worker looks up are not applied. */
#ifndef SL_REPROCESS_H
#define SL_REPROCESS_H

#include "mpishare.h"

/* argv[0] = "specklab-mpi reprocess"; the exit status (0, 1 failure, 2
 * usage), the same on every rank for a usage error. */
int reprocess_main(const mpishare *m, int argc, char **argv);

#endif
