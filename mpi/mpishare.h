/* mpishare.h - pipeline.h's pipeline_share over MPI_COMM_WORLD: the sums
 * reduced in rank order, rank 0's decisions broadcast.
 *
 * The reduction: every rank > 0 sends its sums to rank 0, which adds them
 * to its own in rank order (pipeline_sums_merge), 1, 2, ..., N-1, however
 * the messages arrive, then broadcasts the total, except for the run's
 * last sums, which only rank 0 needs: there the others' part ends
 * (SL_EEND) and rank 0 alone recovers the phases and writes the image.  So
 * the image depends only on the ranks' frame ranges, never on timing.
 * Traffic per reduction of S bytes: (N - 1) S into rank 0, and for all
 * but the last a broadcast of S (Open MPI's tree: ~log2 N S on the
 * slowest link); rank 0 holds 2 S. */
#ifndef SL_MPISHARE_H
#define SL_MPISHARE_H

#include "pipeline/pipeline.h"

typedef struct mpishare mpishare;

/* After MPI_Init.  NULL when out of memory. */
mpishare *mpishare_new(void);
void mpishare_free(mpishare *m);
int mpishare_rank(const mpishare *m);
int mpishare_size(const mpishare *m);
/* The hooks for pipeline_opts.share. */
const pipeline_share *mpishare_pipeline(const mpishare *m);
/* Bytes of sums this rank has put into reductions so far (the size of
 * every reduced buffer, counted once per reduction). */
double mpishare_bytes(const mpishare *m);
/* MPI_Wtime when the run's last sums were complete (rank 0 then recovers
 * the phases alone: the serial tail); 0 before. */
double mpishare_last_s(const mpishare *m);

#endif
