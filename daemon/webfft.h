/* webfft.h - the web view's running mean power spectrum of frames.
 *
 * Why not FFTW, which recon/ uses: FFTW's planner and its wisdom are
 * process-global and not thread-safe, and the daemon's one planner is the
 * worker thread (worker.c imports and exports DATA_DIR/fftw-wisdom there,
 * unlocked).  Planning from the web view's thread could corrupt that
 * state mid-reconstruction.  So the view has its own small transform:
 * radix-2 for power-of-two lengths, Bluestein's chirp-z (through a
 * power-of-two transform) for any other, in double precision.  Its "plan"
 * (twiddles, bit reversal, the chirp and its transform) is made once per
 * frame size, when the accumulator is made.  A 128x128 frame costs about
 * 1 ms, 1024x1024 about 60 ms; the view computes at the viewers' rate at
 * most, at low priority.
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

/* The 1-D transform, exposed for its test: forward DFT of n complex
 * values (re, im interleaved) in place, X_k = sum x_j e^(-2 pi i jk/n). */
typedef struct webfft webfft;
webfft *webfft_new(int n);
void webfft_free(webfft *f);
void webfft_forward(webfft *f, double *re_im);

#endif
