/* tsm_extent.c - the object's diameter from TSM's projection power, and
 * the angular average that diameter allows (see tsm.h, step 3).
 *
 * Why.  Step 3 averages each bispectrum element over the neighbouring
 * angles (tsm_phase_inputs, arc_bins): it buys SNR where the 1-D
 * recursion is starved of pairs.  But the object's spectrum is not the
 * same on neighbouring lines: moving a frequency u perpendicular to its
 * line by `arc` bins turns the phase of a feature at distance x from the
 * centre by 2 pi x arc / ns.  A binary's closure phases are periodic in
 * the angle with that rate, and averaging them over the arc low-passes
 * them: the companion's phase modulation shrinks and it reads faint.
 * Measured (200^2 bench binary, noiseless, 100 frames, tsm-fourier 180):
 * at 1.5 bins dm 1 reads 1.06 / 1.16 / 1.25 at 20 / 30 / 40 px
 * separation, dm 2 at 40 px reads 2.17; without the average 1.002 /
 * 1.002 / 1.002 and 1.99.  So the arc is capped at what the measured
 * diameter E allows: arc <= ARC_TURN ns / (2 pi E), a turn of at most
 * ARC_TURN radians at the arc's end for the farthest feature.
 *
 * The diameter.  Per angle, the autocorrelation of the projection is the
 * inverse transform of its bias-corrected mean power; its support is the
 * projected diameter (convolved with the speckle PSF's autocorrelation,
 * so E errs large: the cap errs small, towards less averaging).  E is
 * the largest lag where the autocorrelation exceeds `level` of its peak
 * at two adjacent lags (a lone ringing sample does not count), maximised
 * over the angles.  Cost: at most nangles x ns/2 x nf multiply-adds with a
 * cosine table of ns entries (1.8e6 at 180 angles, 200^2: 1.9 ms), no FFT
 * plan; lags below the extent already found are skipped (0.6 ms there),
 * on the pool's threads.
 */
#include "tsm.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>

/* Phase turn allowed at the arc's end, radians: 0.4 leaves a dm 1
 * companion at 40 px within ~0.02 mag (measured: 0.5 bins there, a turn
 * of 0.63 rad, reads +0.017). */
#define ARC_TURN 0.4

/* Autocorrelation of one angle's power p at lag x (ctab: cos 2 pi i / ns). */
static double lag(const double *p, int nf, int ns, const double *ctab, int x)
{
    double s = p[0];
    for (int u = 1, k = x; u < nf; u++) {   /* k = u x mod ns */
        s += 2.0 * p[u] * ctab[k];
        k += x;
        k -= k >= ns ? ns : 0;
    }
    return s;
}

/* The largest lag of angle a's autocorrelation above level x its peak,
 * if it is above e (else e): scanned from the longest lag down, and only
 * above e, since the maximum over angles needs no lag below it. */
static int angle_extent(const double *p, int nf, int ns, const double *ctab, double level,
                        int e)
{
    double a0 = lag(p, nf, ns, ctab, 0);
    if (!(a0 > 0))
        return e;
    double thr = level * a0, above = lag(p, nf, ns, ctab, ns / 2);
    for (int x = ns / 2; x > e; x--) {
        double below = lag(p, nf, ns, ctab, x - 1);
        if (above > thr && below > thr)
            return x;
        above = below;
    }
    return e;
}

/* Angles in tasks of EXTENT_TASK, claimed by the pool's threads, each
 * keeping its own maximum (and skipping below it); the result is the
 * maximum of theirs, the same number for any thread count or order.  It
 * was 8 ms of one thread alone at 512^2 (180 angles). */
enum { EXTENT_TASK = 8, EXTENT_THREADS = 64 };
typedef struct extent_job {
    const double *ps, *ctab;
    int nang, nf, ns;
    double level;
    atomic_int next;
    int e[EXTENT_THREADS];
} extent_job;

static void extent_run(void *ctx, int tid, int n)
{
    extent_job *j = ctx;
    int e = 0;
    (void)n;
    for (int a0; (a0 = atomic_fetch_add(&j->next, EXTENT_TASK)) < j->nang;)
        for (int a = a0; a < a0 + EXTENT_TASK && a < j->nang; a++)
            e = angle_extent(j->ps + (size_t)a * j->nf, j->nf, j->ns, j->ctab, j->level, e);
    j->e[tid] = e;
}

double tsm_extent_px(const double *ps, int nang, int nf, int ns, double level, tpool *pool)
{
    double *ctab = malloc((size_t)ns * sizeof *ctab);
    if (!ctab)
        return NAN;
    for (int i = 0; i < ns; i++)
        ctab[i] = cos(2.0 * M_PI * i / ns);
    extent_job j = {.ps = ps, .ctab = ctab, .nang = nang, .nf = nf, .ns = ns, .level = level};
    atomic_init(&j.next, 0);
    int nt = pool && tpool_size(pool) <= EXTENT_THREADS ? tpool_size(pool) : 1;
    if (nt > 1)
        tpool_run(pool, extent_run, &j);
    else
        extent_run(&j, 0, 1);
    int e = 0;
    for (int t = 0; t < nt; t++)
        e = j.e[t] > e ? j.e[t] : e;
    free(ctab);
    return e;
}

double tsm_arc_cap(double extent_px, int ns)
{
    return extent_px > 0 ? ARC_TURN * ns / (2.0 * M_PI * extent_px) : INFINITY;
}
