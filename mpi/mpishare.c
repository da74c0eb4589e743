/* mpishare.c - see mpishare.h. */
#include "mpishare.h"

#include <limits.h>
#include <mpi.h>
#include <stdlib.h>

#include "status.h"

/* MPI counts are int: buffers go in pieces of at most 2^27 doubles (1 GiB). */
#define PIECE ((size_t)1 << 27)

struct mpishare {
    int rank, size;
    double bytes;
    double last_s;        /* MPI_Wtime when the last sums were complete */
    pipeline_share hooks;
};

static int piece(size_t n, size_t off) { return (int)(n - off < PIECE ? n - off : PIECE); }

/* Rank 0: its sums plus every other rank's, in rank order. */
static int gather_in_order(double *sums, size_t n, int size)
{
    double *part = malloc((n < PIECE ? n : PIECE) * sizeof *part);
    if (!part)
        return SL_ENOMEM;
    for (int r = 1; r < size; r++)
        for (size_t off = 0; off < n; off += PIECE) {
            MPI_Recv(part, piece(n, off), MPI_DOUBLE, r, 0, MPI_COMM_WORLD,
                     MPI_STATUS_IGNORE);
            pipeline_sums_merge(sums + off, part, (size_t)piece(n, off));
        }
    free(part);
    return SL_OK;
}

static int reduce(void *ctx, double *sums, size_t n, int last)
{
    mpishare *m = ctx;
    int rc = SL_OK;
    m->bytes += (double)n * sizeof *sums;
    if (m->rank == 0)
        rc = gather_in_order(sums, n, m->size);
    else
        for (size_t off = 0; off < n; off += PIECE)
            MPI_Send(sums + off, piece(n, off), MPI_DOUBLE, 0, 0, MPI_COMM_WORLD);
    /* rank 0 out of memory: the others would wait for ever */
    if (rc != SL_OK)
        MPI_Abort(MPI_COMM_WORLD, 1);
    if (last) { /* only rank 0 goes on: the others' part is done */
        m->last_s = MPI_Wtime();
        return m->rank == 0 ? SL_OK : SL_EEND;
    }
    for (size_t off = 0; off < n; off += PIECE)
        MPI_Bcast(sums + off, piece(n, off), MPI_DOUBLE, 0, MPI_COMM_WORLD);
    return SL_OK;
}

static int agree(void *ctx, void *buf, size_t bytes)
{
    (void)ctx;
    if (bytes > INT_MAX)
        return SL_ERANGE;
    MPI_Bcast(buf, (int)bytes, MPI_BYTE, 0, MPI_COMM_WORLD);
    return SL_OK;
}

mpishare *mpishare_new(void)
{
    mpishare *m = calloc(1, sizeof *m);
    if (!m)
        return NULL;
    MPI_Comm_rank(MPI_COMM_WORLD, &m->rank);
    MPI_Comm_size(MPI_COMM_WORLD, &m->size);
    m->hooks = (pipeline_share){m->rank, m->size, reduce, agree, m};
    return m;
}

void mpishare_free(mpishare *m) { free(m); }
int mpishare_rank(const mpishare *m) { return m->rank; }
int mpishare_size(const mpishare *m) { return m->size; }
const pipeline_share *mpishare_pipeline(const mpishare *m) { return &m->hooks; }
double mpishare_bytes(const mpishare *m) { return m->bytes; }
double mpishare_last_s(const mpishare *m) { return m->last_s; }
