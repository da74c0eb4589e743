/* webfft.h - the web view's running mean power spectrum of frames, on
 * FFTW (double precision: the display spans ten decades of power).
 *
 * FFTW's planner is process-global and the worker thread plans too (and
 * imports and exports DATA_DIR/fftw-wisdom): specklabd makes the planner
 * thread-safe at start-up (fftw_make_planner_thread_safe, main.c) before
 * any thread exists, so the view may plan from its own thread.  The plan
 * (FFTW_ESTIMATE: no timing, so no stall the first time a size is seen)
 * is made once per frame size, when the accumulator is made; webps_add
 * executes it without allocating.  A 128x128 frame costs ~0.1 ms.
 */
#ifndef SL_DAEMON_WEBFFT_H
#define SL_DAEMON_WEBFFT_H

/* Frames larger than this (pixels) get no power spectrum. */
#define WEBPS_MAX_PIXELS (4096 * 4096)

typedef struct webps webps;

/* An accumulator for w x h frames (2 <= w, h; w*h <= WEBPS_MAX_PIXELS);
 * NULL when out of range or out of memory. */
webps *webps_new(int w, int h);
void webps_free(webps *p);
void webps_reset(webps *p);
/* Add |FFT(frame)|^2 (frame: w*h floats, row y at frame + y*w). */
void webps_add(webps *p, const float *frame);
/* Frames added since the last reset. */
long webps_count(const webps *p);
/* log10 of the mean power, zero frequency moved to (w/2, h/2) (the image
 * centre's convention) into out (w*h floats).  0 when nothing added. */
int webps_log_mean(const webps *p, float *out);

#endif
