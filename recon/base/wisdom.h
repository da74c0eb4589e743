/* wisdom.h - FFTW wisdom kept on disk, so FFTW_MEASURE plans are measured
 * once per machine and size, not once per process.
 *
 * FFTW_MEASURE plans run ~8x faster than FFTW_ESTIMATE here, but measuring
 * costs ~1 s for the first 2-D size in a process.  Wisdom records what was
 * measured; importing it makes the next MEASURE planning of the same
 * transforms take milliseconds.  Both calls touch FFTW's global planner
 * state, so make them from the thread that plans, before/after planning
 * (the CLI: at start and at exit).  Both single (fftwf) and double (fftw)
 * wisdom are kept, in PATH.f and PATH.d.
 */
#ifndef SL_WISDOM_H
#define SL_WISDOM_H

#include "status.h"

/* Default location: $SPECKLAB_WISDOM, else $XDG_CACHE_HOME/specklab/fftw-
 * wisdom, else $HOME/.cache/specklab/fftw-wisdom; NULL when none. The
 * string is static storage. */
const char *wisdom_default_path(void);
/* Import; a missing file is not an error (returns SL_OK, *loaded = 0). */
int wisdom_load(const char *path, int *loaded, sl_err *err);
/* Export atomically (temp file + rename); creates the directory. */
int wisdom_save(const char *path, sl_err *err);

/* Bound FFTW_MEASURE's planning to seconds per plan (both precisions;
 * process-global, like the wisdom): FFTW keeps the best plan timed within
 * the bound.  At 0.01 s a size the wisdom does not hold costs ~0.07 s more
 * than a warm run (tsm-fourier and tsm at 200^2, where unbounded planning
 * cost 1.2 s), and the plans it keeps, saved as wisdom, run within ~10 %
 * of fully measured ones. */
#define WISDOM_PLAN_LIMIT_S 0.01
void wisdom_plan_limit(double seconds);

#endif
