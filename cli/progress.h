/* progress.h - a one-line progress bar with ETA on a terminal.
 *
 * Drawn only when the stream is a terminal: piped or redirected output
 * (logs, CI, `2>file`) stays free of carriage returns.  Redraws are
 * limited to 10 per second, so callers may update on every event.  The
 * ETA assumes the remaining work goes at the average rate so far:
 * eta = elapsed * (total - done) / done.
 */
#ifndef SL_PROGRESS_H
#define SL_PROGRESS_H

#include <stddef.h>
#include <stdio.h>

typedef struct progress progress;

/* A bar of total units on f (stderr usually); never NULL. */
progress *progress_new(FILE *f, double total);
void progress_free(progress *p);
/* Nonzero when the bar is drawn (f is a terminal). */
int progress_active(const progress *p);
/* done of total units so far; label (may be NULL) names the current step.
 * The bar never goes back: a done below an earlier one is ignored. */
void progress_update(progress *p, double done, const char *label);
/* Print a message line above the bar (or plainly when quiet), e.g. a run
 * that failed; the bar is redrawn at the next update. */
void progress_note(progress *p, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* Erase the bar, leaving the line clean. */
void progress_finish(progress *p);

/* Seconds left at the average rate so far; negative when unknown (nothing
 * done yet). */
double progress_eta_s(double elapsed_s, double done, double total);
/* "1h02m", "3m05s", "42s" or "--" for a negative time, into buf. */
const char *progress_fmt_time(char *buf, size_t n, double s);

#endif
