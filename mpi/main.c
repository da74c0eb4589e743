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

/* --mpi-report (first after the command's name, for specklab bench
 * --mpi): rank 0 prints one line, the ranks, the bytes of sums reduced,
 * the wall time from the first barrier to the end and of it the tail
 * after the last sums were complete (0 with one rank: no reduction). */
static int run_reported(mpishare *m, int argc, char **argv)
{
    int report = argc >= 2 && !strcmp(argv[1], "--mpi-report");
    if (report) {
        memmove(argv + 1, argv + 2, (size_t)(argc - 2) * sizeof *argv);
        argv[--argc] = NULL;
    }
    MPI_Barrier(MPI_COMM_WORLD);
    double t0 = MPI_Wtime();
    int status = run(m, argc, argv);
    double t1 = MPI_Wtime(), last = mpishare_last_s(m);
    if (report && status == 0 && mpishare_rank(m) == 0)
        printf("specklab-mpi: ranks %d, sums reduced %.0f bytes, wall %.6f s, tail %.6f s\n",
               mpishare_size(m), mpishare_bytes(m), t1 - t0, last > 0 ? t1 - last : 0.0);
    return status;
}

int main(int argc, char **argv)
{
    MPI_Init(&argc, &argv);
    mpishare *m = mpishare_new();
    if (!m) {
        fprintf(stderr, "specklab-mpi: out of memory\n");
        MPI_Abort(MPI_COMM_WORLD, 1);
    }
    int status = run_reported(m, argc, argv);
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
