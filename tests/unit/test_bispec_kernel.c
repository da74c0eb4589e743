/* test_bispec_kernel.c - the direct bispectrum's accumulation (bispec_
 * kernel.c, bispec_graph.c): the same frames give the same bits on any
 * thread count, full batches and a partial one; and the float kernel's
 * sums stay within the bound bispec_kernel.c states, against the
 * definition summed in double from double-precision spectra. */
#include <complex.h>
#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "spectra/bispec.h"
#include "tcheck.h"

static float *random_frames(int n, int nfr, uint64_t seed)
{
    rng r;
    rng_init(&r, seed, 0);
    float *fr = malloc((size_t)nfr * n * n * sizeof *fr);
    for (size_t k = 0; k < (size_t)nfr * n * n; k++)
        fr[k] = (float)rng_uniform(&r);
    return fr;
}

/* The options every case here starts from: R2 9, a disk cut at 0.45 n,
 * ESTIMATE plans, nthr threads. */
static void test_opts(bispec_opts *o, int n, int nthr)
{
    bispec_opts_defaults(o);
    o->r2_px = 9;
    o->rcut_px = 0.45 * n;
    o->measure = 0;
    o->nthreads = nthr;
}

/* The flat sums (bispec_partial) of nfr frames on nthr threads, with
 * the kernel's instruction set simd and float accumulators or not. */
static double *sums_on(const float *fr, int n, int nfr, int nthr, int snr, int simd,
                       int accf, size_t *len, int *kb)
{
    bispec_opts o;
    test_opts(&o, n, nthr);
    o.weight = snr ? PHASOR_WEIGHT_SNR : PHASOR_WEIGHT_MOD;
    o.simd = simd;
    o.acc_float = accf;
    bispec *b = bispec_new(n, n, &o, NULL);
    if (!b)
        return NULL;
    for (int f = 0; f < nfr; f++)
        bispec_add(b, fr + (size_t)f * n * n);
    *len = bispec_partial(b, NULL);
    *kb = bispec_batch(b);
    double *buf = malloc(*len * sizeof *buf);
    bispec_partial(b, buf);
    bispec_free(b);
    return buf;
}

static double *sums(const float *fr, int n, int nfr, int nthr, int snr, size_t *len,
                    int *kb)
{
    return sums_on(fr, n, nfr, nthr, snr, BISPEC_SIMD_AUTO, 0, len, kb);
}

/* Every instruction set this CPU has (portable C with fmaf, AVX2 + FMA,
 * AVX-512) gives the same accumulators bit for bit, with and without the
 * second moment, in double and float accumulators, with a partial batch. */
TEST(bits_equal_on_every_simd_path)
{
    int n = 40, nfr = 45;
    float *fr = random_frames(n, nfr, 17);
    CHECK(bispec_simd_has(BISPEC_SIMD_PORTABLE), "the portable kernel must run anywhere");
    int paths = 0;
    for (int cfg = 0; cfg < 4; cfg++) {
        int snr = cfg & 1, accf = cfg >> 1, kb = 0;
        size_t len1 = 0;
        double *ref = sums_on(fr, n, nfr, 2, snr, BISPEC_SIMD_PORTABLE, accf, &len1, &kb);
        CHECK(ref, "bispec_new (portable) failed");
        for (int simd = BISPEC_SIMD_AVX2; simd <= BISPEC_SIMD_AVX512; simd++) {
            if (!bispec_simd_has(simd))
                continue;
            paths += cfg == 0;
            size_t len = 0;
            double *got = sums_on(fr, n, nfr, 2, snr, simd, accf, &len, &kb);
            CHECK(got && len == len1, "%s: %zu sums, portable %zu", bispec_simd_name(simd),
                  len, len1);
            size_t diff = 0;
            for (size_t k = 0; k < len; k++)
                diff += memcmp(&got[k], &ref[k], sizeof *got) != 0;
            free(got);
            CHECK(diff == 0, "%s (snr %d, float acc %d): %zu of %zu sums differ from "
                  "portable", bispec_simd_name(simd), snr, accf, diff, len);
        }
        free(ref);
    }
    /* A path the CPU lacks is refused by name, never run. */
    for (int simd = BISPEC_SIMD_AVX2; simd <= BISPEC_SIMD_AVX512; simd++)
        if (!bispec_simd_has(simd)) {
            bispec_opts o;
            bispec_opts_defaults(&o);
            o.simd = simd;
            sl_err e = {0};
            CHECK(!bispec_new(n, n, &o, &e) && strstr(e.msg, bispec_simd_name(simd)),
                  "a missing %s was not refused by name: %s", bispec_simd_name(simd), e.msg);
        }
    printf("# %d vector path(s) compared with the portable one\n", paths);
    free(fr);
}

/* 1, 2, 3 and 7 threads: every accumulator equal bit for bit (the triple
 * graph, the tiled ranges and the per-triple sums), for a frame count
 * that leaves a partial batch of an odd size, with and without the
 * second moment. */
TEST(bits_equal_on_any_thread_count)
{
    int n = 48, nfr = 83;
    float *fr = random_frames(n, nfr, 11);
    for (int snr = 0; snr < 2; snr++) {
        size_t len1 = 0;
        int kb = 0;
        double *ref = sums(fr, n, nfr, 1, snr, &len1, &kb);
        CHECK(ref, "bispec_new failed");
        CHECK(nfr % kb != 0, "%d frames fill whole batches of %d: no partial batch", nfr, kb);
        static const int thr[] = {2, 3, 7};
        for (int i = 0; i < 3; i++) {
            size_t len = 0;
            double *got = sums(fr, n, nfr, thr[i], snr, &len, &kb);
            CHECK(got && len == len1, "%d threads: %zu sums, 1 thread %zu", thr[i], len, len1);
            size_t diff = 0;
            for (size_t k = 0; k < len; k++)
                diff += memcmp(&got[k], &ref[k], sizeof *got) != 0;
            free(got);
            CHECK(diff == 0, "snr %d, %d threads: %zu of %zu sums differ from 1 thread", snr,
                  thr[i], diff, len);
        }
        free(ref);
    }
    free(fr);
}

/* The phases (recursion pipelined over threads, then the refinement)
 * equal bit for bit on 1, 2 and 5 threads: random frames, whose closure
 * misfit is large, so the refinement runs too. */
/* The phases of nfr random n x n frames on 1, 2 and 5 threads. */
static void phases_equal_at(tc *t, int n)
{
    int nfr = 40;
    float *fr = random_frames(n, nfr, 23);
    double *ref = NULL;
    static const int thr[] = {1, 2, 5};
    for (int i = 0; i < 3; i++) {
        bispec_opts o;
        test_opts(&o, n, thr[i]);
        o.refine_iters = 5;
        bispec *b = bispec_new(n, n, &o, NULL);
        CHECK(b, "bispec_new failed");
        for (int f = 0; f < nfr; f++)
            bispec_add(b, fr + (size_t)f * n * n);
        double *ph = malloc((size_t)n * n * sizeof *ph);
        CHECK(bispec_phase(b, ph, NULL) == SL_OK, "bispec_phase: %s", bispec_errmsg(b));
        bispec_free(b);
        if (!ref) {
            ref = ph;
            continue;
        }
        int same = memcmp(ph, ref, (size_t)n * n * sizeof *ph) == 0;
        free(ph);
        CHECK(same, "%dx%d, %d threads: phases differ from 1 thread", n, n, thr[i]);
    }
    free(ref);
    free(fr);
}

TEST(phases_equal_on_any_thread_count)
{
    for (int n = 48; n <= 96; n += 48) /* 3 and 11 of the recursion's blocks */
        phases_equal_at(t, n);
}
/* The float kernel against the definition in double: for every stored
 * triple, |acc - sum_f B_f| <= eps sum_f |B_f|.  The kernel's own share
 * (products and the batch's tree sum in float) is ~(log2 kb + 4) 2^-24 =
 * 6e-7 at kb 64, 6.6e-7 at 128; the float FFT's error on each of the three legs adds
 * ~3 x 2^-24 log2(n) = 1e-6 at 48 px.  2e-6 holds both.  Float
 * accumulators add one rounding per batch: nb 2^-24 more over nb
 * batches (3 here). */
TEST(float_sums_within_bound)
{
    int n = 48, nfr = 300;
    float *fr = random_frames(n, nfr, 5);
    fftw_complex *F = fftw_alloc_complex((size_t)nfr * n * n);
    for (size_t k = 0; k < (size_t)nfr * n * n; k++)
        F[k] = fr[k];
    for (int f = 0; f < nfr; f++) {
        fftw_plan p = fftw_plan_dft_2d(n, n, F + (size_t)f * n * n, F + (size_t)f * n * n,
                                       FFTW_FORWARD, FFTW_ESTIMATE);
        fftw_execute(p);
        fftw_destroy_plan(p);
    }
    for (int accf = 0; accf < 2; accf++) {
        bispec_opts o;
        test_opts(&o, n, 2);
        o.acc_float = accf;
        bispec *b = bispec_new(n, n, &o, NULL);
        CHECK(b, "bispec_new failed");
        for (int f = 0; f < nfr; f++)
            bispec_add(b, fr + (size_t)f * n * n);
        int nb = (nfr + bispec_batch(b) - 1) / bispec_batch(b);
        double worst = 0;
        for (size_t it = 0; it < bispec_ntriples(b); it++) {
            int u1[2], u2[2];
            double br, bi, wt;
            bispec_triple(b, it, u1, u2, &br, &bi, &wt);
            double complex s = 0;
            double mag = 0;
            for (int f = 0; f < nfr; f++) {
                const fftw_complex *G = F + (size_t)f * n * n;
#define AT(p, q) G[(((q) + n) % n) * n + ((p) + n) % n]
                double complex x = AT(u1[0], u1[1]) * AT(u2[0], u2[1]) *
                                   conj(AT(u1[0] + u2[0], u1[1] + u2[1]));
#undef AT
                s += x;
                mag += cabs(x);
            }
            double e = cabs((br + I * bi) * nfr - s) / mag;
            worst = e > worst ? e : worst;
        }
        bispec_free(b);
        double bound = 2e-6 + (accf ? nb * 0x1p-24 : 0);
        printf("# %s accumulators, %d batches: worst %.3g of sum |B_f| (bound %.3g)\n",
               accf ? "float" : "double", nb, worst, bound);
        CHECK(nb >= 3, "%d batches: too few to test the accumulators' share", nb);
        CHECK(worst < bound, "float kernel, %s accumulators: worst error %.3g of sum |B_f| "
              "(bound %.3g)", accf ? "float" : "double", worst, bound);
        CHECK(worst > 0, "no rounding at all: the kernel is not summing in float");
    }
    fftw_free(F);
    free(fr);
}

/* A frame with a NaN or an Inf is refused by frame and pixel and
 * changes nothing: the sums equal those of the good frames alone. */
TEST(non_finite_frame_refused_by_pixel)
{
    int n = 32, nfr = 20;
    float *fr = random_frames(n, nfr, 3);
    size_t len1 = 0, len2 = 0;
    int kb = 0;
    double *ref = sums(fr, n, nfr, 2, 0, &len1, &kb);
    bispec_opts o;
    test_opts(&o, n, 2);
    bispec *b = bispec_new(n, n, &o, NULL);
    CHECK(ref && b, "bispec_new failed");
    float *bad = malloc((size_t)n * n * sizeof *bad);
    for (int f = 0; f < nfr; f++) {
        CHECK(bispec_add(b, fr + (size_t)f * n * n) == SL_OK, "good frame %d", f);
        if (f != 9)
            continue;
        memcpy(bad, fr, (size_t)n * n * sizeof *bad);
        bad[333] = NAN;
        CHECK(bispec_add(b, bad) == SL_EDATA && strstr(bispec_errmsg(b), "frame 10 pixel 333"),
              "NaN: %s", bispec_errmsg(b));
        bad[333] = 0.5f;
        bad[1023] = INFINITY;
        CHECK(bispec_add(b, bad) == SL_EDATA && strstr(bispec_errmsg(b), "pixel 1023"),
              "Inf: %s", bispec_errmsg(b));
    }
    len2 = bispec_partial(b, NULL);
    double *got = malloc(len2 * sizeof *got);
    bispec_partial(b, got);
    CHECK(len2 == len1 && memcmp(got, ref, len1 * sizeof *got) == 0,
          "the refused frames changed the sums");
    free(got);
    free(bad);
    free(ref);
    bispec_free(b);
    free(fr);
}

TC_MAIN(TC_CASE(bits_equal_on_every_simd_path), TC_CASE(bits_equal_on_any_thread_count), TC_CASE(phases_equal_on_any_thread_count), TC_CASE(float_sums_within_bound), TC_CASE(non_finite_frame_refused_by_pixel))
