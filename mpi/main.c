/* main.c - `mpirun -n N specklab-mpi recon CUBE ...`: specklab recon with
 * the frames split over MPI ranks (pipeline.h, pipeline_share; the sums
 * reduced in rank order, mpishare.h); `... reprocess --catalog DB`: the
 * catalogued runs spread over the ranks (reprocess.h).  Built only when Open MPI is
 * installed (the Makefile's MPI); the plain specklab never links MPI.
 *
 * A rank that fails ends the job (MPI_Abort) with its exit status, after
 * saying which rank it was: the others may be waiting for its sums. */
#include <mpi.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "jsonmode.h"
#include "mpishare.h"
#include "reprocess.h"

static void usage(FILE *f)
{
    fprintf(f, "Usage: mpirun -n N specklab-mpi recon CUBE.fits -o IMAGE.fits [OPTION]...\n"
               "       mpirun -n N specklab-mpi reprocess --catalog DB [--method M] [--since TIME]\n"
               "recon: specklab recon's options (specklab recon --help); each rank reads\n"
               "its own range of the frames, rank 0 writes the outputs.\n"
               "reprocess: every catalogued run again, one run per rank at a time;\n"
               "rank 0 writes the catalogue (specklab-mpi reprocess --help).\n");
}

static int run(mpishare *m, int argc, char **argv)
{
    int reproc = argc >= 2 && !strcmp(argv[1], "reprocess");
    if (argc < 2 || (strcmp(argv[1], "recon") != 0 && !reproc)) {
        if (mpishare_rank(m) == 0)
            usage(stderr);
        return 2;
    }
    if (reproc) {
        char rname[] = "specklab-mpi reprocess";
        argv[1] = rname;
        return reprocess_main(m, argc - 1, argv + 1);
    }
    char name[] = "specklab-mpi recon";
    argv[1] = name;
    jsonmode jm = {0};
    int lead = mpishare_rank(m) == 0;
    if (lead && jsonmode_wanted(argc - 1, argv + 1))
        jsonmode_begin(&jm);
    int status = cmd_recon_shared(argc - 1, argv + 1, mpishare_pipeline(m));
    return lead ? jsonmode_end(&jm, "recon", status) : status;
}

int main(int argc, char **argv)
{
    MPI_Init(&argc, &argv);
    mpishare *m = mpishare_new();
    if (!m) {
        fprintf(stderr, "specklab-mpi: out of memory\n");
        MPI_Abort(MPI_COMM_WORLD, 1);
    }
    int status = run(m, argc, argv);
    if (status != 0) {
        fprintf(stderr, "specklab-mpi: rank %d of %d failed (exit %d); ending the job\n",
                mpishare_rank(m), mpishare_size(m), status);
        fflush(NULL);
        MPI_Abort(MPI_COMM_WORLD, status);
    }
    mpishare_free(m);
    MPI_Finalize();
    return 0;
}
