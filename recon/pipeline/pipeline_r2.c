/* pipeline_r2.c - the direct method's default |u2| radius, bounded by the
 * bispectrum's memory (pipeline_int.h, pipe_direct_r2).
 *
 * Why.  The default R2 = 0.14 x the frame side keeps the same share of
 * the spectrum whatever the sampling, but the stored triples grow as
 * r_c^2 R2^2, i.e. as the side^4: 200^2 holds 15 M triples (268 MB),
 * 1024^2 took 14.7 GB and 43 s a frame.  The phase recursion needs small
 * u2 only; larger R2 buys redundancy (noise averaging), which a big
 * frame's many targets already give.  So the default R2 is the largest
 * <= 0.14 side whose bispectrum fits the budget; a user's --r2-px is
 * kept as given.
 *
 * Model (bispec.h, Memory): T(R2) = s^2 [(pi^2/4) r_c^2 R2^2 -
 * (pi/3) r_c R2^3 - 2 R2^4] for R2 <= r_c/2, r_c the measured cut-off
 * and s the support's fill of the disc of radius r_c (an aperture mask's
 * MTF: ~0.5); bytes = T (2 + A (1 + snr/2)), A = 8 (float
 * accumulators, direct_opts), plus 95 + 16 kb bytes per support
 * frequency (kb frames per batch, bispec_batch_frames).  The caller
 * checks bispec_memory_bytes afterwards and shrinks once more when the
 * model was short. */
#include "pipeline_int.h"

#include <math.h>

static double triples(double rc, double fill, double r2)
{
    double t = M_PI * M_PI / 4 * rc * rc * r2 * r2 - M_PI / 3 * rc * r2 * r2 * r2 -
               2 * r2 * r2 * r2 * r2;
    return fill * fill * fmax(t, 0);
}

int pipe_direct_r2(int w, int h, const unsigned char *support, double rcut_px,
                   int snr, double budget_mb, size_t batch_bytes, int *bounded)
{
    int side = w < h ? w : h;
    int r2 = (int)lround(0.14 * side);
    r2 = r2 > BISPEC_R2_MAX ? BISPEC_R2_MAX : r2 < 1 ? 1 : r2;
    *bounded = 0;
    if (!(budget_mb > 0) || !(rcut_px > 0) || !support)
        return r2;
    size_t n = (size_t)w * h, ns = 0;
    for (size_t i = 0; i < n; i++)
        ns += support[i] != 0;
    double fill = fmin(1, ns / (M_PI * rcut_px * rcut_px));
    /* per stored triple, and per support frequency (its tables and
     * phases, 95 bytes, and the batch of frames' spectra, 16 per frame:
     * bispec.h) */
    double per = 2 + 8 * (1 + (snr ? 0.5 : 0)), budget = budget_mb * 1048576.0;
    int nf = (int)(ns / 2 + 1);
    budget -= (95.0 + 16.0 * bispec_batch_frames(nf, batch_bytes)) * nf;
    int lo = r2;
    while (lo > 4 && triples(rcut_px, fill, fmin(lo, rcut_px / 2)) * per > budget)
        lo--;
    *bounded = lo < r2;
    return lo;
}

int pipe_direct_r2_shrink(int r2, size_t bytes, double budget_mb)
{
    double budget = budget_mb * 1048576.0;
    if (!(budget_mb > 0) || (double)bytes <= 1.25 * budget || r2 <= 4)
        return r2;
    int s = (int)floor(r2 * sqrt(budget / (double)bytes));
    return s < 4 ? 4 : s >= r2 ? r2 - 1 : s;
}
