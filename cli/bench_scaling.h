/* bench_scaling.h - `specklab bench --scaling`: direct, tsm and
 * tsm-fourier on one simulated cube at 1, 2, 4 ... threads (up to the
 * cores), each run's wall time split by stage (pipeline_report.stage_s:
 * open, plan, read, frame, accum, solve, measure), the speedup, and the
 * parallel fraction of the run and of each stage (Amdahl), so that what
 * stays serial is visible.  --sizes, --frames, --methods, --repeat,
 * --estimate, --seed and --data-dir apply (first size and frame count;
 * default 200^2 x 100). */
#ifndef SL_BENCH_SCALING_H
#define SL_BENCH_SCALING_H

#include "bench_ctx.h"

/* The exit status: 0; 1 when a run fails, 2 for a bad option (said on
 * stderr). */
int bench_scaling_run(const bench_args *a);

#endif
