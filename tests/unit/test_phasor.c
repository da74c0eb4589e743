/* test_phasor.c - the direct method's phase recursion (phasor_recur.c)
 * through the bispec handle. */
#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "spectra/bispec.h"
#include "tcheck.h"

/* The phase recursion, run with the next block's early sums on other
 * threads (phasor_recur.c), gives the same bits on 1, 2 and 3 threads,
 * and equals the recursion written out here: targets in storage order,
 * each the argument of sum_t w_t / |B_t| E(u1) E(u2) conj(B_t) over the
 * triples whose legs are known.  ~10 blocks of 32768 triples. */
static size_t fidx(int p, int q, int n) { return (size_t)((q + n) % n) * n + (size_t)((p + n) % n); }

static void ref_finish(double complex z, int p, int q, double *ph, unsigned char *kn, int n)
{
    if (kn[fidx(p, q, n)] || cabs(z) == 0)   /* a seed, or unreached */
        return;
    ph[fidx(p, q, n)] = carg(z), ph[fidx(-p, -q, n)] = -carg(z);
    kn[fidx(p, q, n)] = kn[fidx(-p, -q, n)] = 1;
}

static void ref_recursion(bispec *b, int n, double *ph, unsigned char *kn)
{
    int seeds[3][2] = {{0, 0}, {1, 0}, {0, 1}}, cur[2] = {0, 0};
    for (int s = 0; s < 3; s++)
        kn[fidx(seeds[s][0], seeds[s][1], n)] = kn[fidx(-seeds[s][0], -seeds[s][1], n)] = 1;
    double complex z = 0;
    for (size_t t = 0; t < bispec_ntriples(b); t++) {
        int u1[2], u2[2];
        double br, bi, w;
        bispec_triple(b, t, u1, u2, &br, &bi, &w);
        int p = u1[0] + u2[0], q = u1[1] + u2[1];
        if (t == 0 || p != cur[0] || q != cur[1]) {
            if (t > 0)
                ref_finish(z, cur[0], cur[1], ph, kn, n);
            cur[0] = p, cur[1] = q, z = 0;
        }
        size_t k1 = fidx(u1[0], u1[1], n), k2 = fidx(u2[0], u2[1], n);
        double mod = hypot(br, bi);
        if (w > 0 && mod > 0 && kn[k1] && kn[k2])
            z += w / mod * cexp(I * (ph[k1] + ph[k2])) * (br - I * bi);
    }
    ref_finish(z, cur[0], cur[1], ph, kn, n);
}

TEST(recursion_same_bits_any_threads)
{
    int n = 64, nfr = 4;
    size_t npx = (size_t)n * n;
    rng r;
    rng_init(&r, 11, 0);
    float *fr = malloc(nfr * npx * sizeof *fr);
    double *ph = calloc(4 * npx, sizeof *ph);
    unsigned char *kn = calloc(4 * npx, 1);
    for (size_t k = 0; k < nfr * npx; k++)
        fr[k] = (float)rng_uniform(&r);
    bispec *keep = NULL;
    for (int v = 0; v < 3; v++) {
        bispec_opts o;
        bispec_opts_defaults(&o);
        o.r2_px = 16, o.rcut_px = n / 2 - 2, o.measure = 0, o.refine_iters = 0;
        o.nthreads = v + 1;
        bispec *b = bispec_new(n, n, &o, NULL);
        CHECK(b, "bispec_new failed");
        for (int f = 0; f < nfr; f++)
            bispec_add(b, fr + f * npx);
        CHECK(bispec_phase(b, ph + v * npx, kn + v * npx) == SL_OK, "bispec_phase");
        if (v == 0)
            keep = b;
        else
            bispec_free(b);
    }
    CHECK(bispec_ntriples(keep) > 8 * 32768, "%zu triples", bispec_ntriples(keep));
    ref_recursion(keep, n, ph + 3 * npx, kn + 3 * npx);
    bispec_free(keep);
    for (int v = 1; v < 3; v++)
        CHECK(!memcmp(ph, ph + v * npx, npx * sizeof *ph) && !memcmp(kn, kn + v * npx, npx),
              "%d threads' phases differ from 1 thread's", v + 1);
    int used = 0;
    double worst = 0;
    for (size_t k = 0; k < npx; k++) {
        CHECK(kn[k] == kn[3 * npx + k], "frequency %zu: known %d, written-out recursion %d", k,
              kn[k], kn[3 * npx + k]);
        if (kn[k])
            worst = fmax(worst, fabs(remainder(ph[k] - ph[3 * npx + k], 2 * M_PI))), used++;
    }
    CHECK(used > 1000, "only %d frequencies known", used);
    CHECK(worst < 1e-9, "worst phase difference from the written-out recursion %g rad", worst);
    free(fr);
    free(ph);
    free(kn);
}

TC_MAIN(TC_CASE(recursion_same_bits_any_threads))
