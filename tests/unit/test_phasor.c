/* test_phasor.c - the direct method's phase recursion (phasor_recur.c)
 * through the bispec handle. */
#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "base/tpool.h"
#include "spectra/bispec.h"
#include "spectra/phasor_int.h"
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

/* One frame of three point sources (no turbulence): its bispectrum's
 * phases are the object's, up to the tilt (phi(1,0) = phi(0,1) = 0). */
static const struct { int x, y; double a; } PTS[3] = {{20, 30, 1.0}, {40, 25, 0.6}, {33, 44, 0.3}};

static double complex pts_ft(int n, int p, int q)
{
    double complex s = 0;
    for (int k = 0; k < 3; k++)
        s += PTS[k].a * cexp(-2 * M_PI * I * ((double)p * PTS[k].x + (double)q * PTS[k].y) / n);
    return s;
}

/* Phases of the points' frame with iters refinement passes within budget
 * bytes (0: none) on nthreads; *used the refinement's bytes. */
static int pts_phases(int n, size_t budget, int iters, int nthreads, double *ph,
                      unsigned char *kn, size_t *used, size_t *mem)
{
    float *fr = calloc((size_t)n * n, sizeof *fr);
    for (int k = 0; k < 3; k++)
        fr[PTS[k].y * n + PTS[k].x] = (float)PTS[k].a;
    bispec_opts o;
    bispec_opts_defaults(&o);
    o.r2_px = 8, o.rcut_px = n / 2 - 2, o.measure = 0, o.refine_iters = iters;
    o.nthreads = nthreads, o.budget_bytes = budget;
    bispec *b = bispec_new(n, n, &o, NULL);
    int rc = b ? bispec_add(b, fr) : SL_ENOMEM;
    if (rc == SL_OK)
        rc = bispec_phase(b, ph, kn);
    *used = bispec_refine_bytes(b), *mem = b ? bispec_memory_bytes(b) : 0;
    bispec_free(b);
    free(fr);
    return rc;
}

/* Worst phase error against the points where |O| > 1e-3 O(0). */
static double pts_error(int n, const double *ph, const unsigned char *kn, int *used)
{
    double a = carg(pts_ft(n, 1, 0)), c = carg(pts_ft(n, 0, 1)), worst = 0;
    *used = 0;
    for (int q = -(n / 2 - 3); q <= n / 2 - 3; q++)
        for (int p = -(n / 2 - 3); p <= n / 2 - 3; p++) {
            double complex O = pts_ft(n, p, q);
            size_t k = fidx(p, q, n);
            if (hypot(p, q) > n / 2 - 3 || cabs(O) < 1e-3 * 1.9 || !kn[k])
                continue;
            double e = fabs(remainder(ph[k] - (carg(O) - a * p - c * q), 2 * M_PI));
            worst = e > worst ? e : worst, (*used)++;
        }
    return worst;
}

/* The refinement within the handle's budget (phasor_refine.c): a bound it
 * does not reach changes no bit (on 1 thread against 2); a binding one is kept, the refinement
 * still runs and the phases stay the object's; one below the fixed part
 * skips the refinement (the recursion's phases, bit for bit). */
TEST(refine_within_budget)
{
    int n = 64;
    size_t npx = (size_t)n * n, used[5], mem;
    double *ph = calloc(5 * npx, sizeof *ph);
    unsigned char *kn = calloc(5 * npx, 1);
    CHECK(pts_phases(n, 0, 5, 2, ph, kn, &used[0], &mem) == SL_OK, "unbounded");
    CHECK(used[0] > 0, "the refinement did not run");
    CHECK(pts_phases(n, 1u << 30, 5, 1, ph + npx, kn + npx, &used[1], &mem) == SL_OK, "1 GB");
    CHECK(used[1] == used[0] && !memcmp(ph, ph + npx, npx * sizeof *ph),
          "a bound not reached, on 1 thread, changed the phases (%zu vs %zu bytes)", used[1],
          used[0]);
    /* refine_bytes = budget - mem when that is at least a quarter */
    size_t want = used[0] * 3 / 4, budget = want >= mem / 3 ? mem + want : 4 * want;
    CHECK(pts_phases(n, budget, 5, 2, ph + 2 * npx, kn + 2 * npx, &used[2], &mem) == SL_OK, "3/4");
    CHECK(used[2] > 0 && used[2] <= want, "bound %zu bytes: the refinement took %zu", want,
          used[2]);
    int cmp[2];
    double e0 = pts_error(n, ph, kn, &cmp[0]), e2 = pts_error(n, ph + 2 * npx, kn + 2 * npx, &cmp[1]);
    CHECK(cmp[0] > 500 && cmp[1] == cmp[0], "%d / %d frequencies compared", cmp[0], cmp[1]);
    CHECK(e0 < 1e-3 && e2 < 1e-3, "worst phase error %g rad unbounded, %g bounded", e0, e2);
    CHECK(pts_phases(n, 4096, 5, 2, ph + 3 * npx, kn + 3 * npx, &used[3], &mem) == SL_OK, "4 kB");
    CHECK(pts_phases(n, 0, 0, 2, ph + 4 * npx, kn + 4 * npx, &used[4], &mem) == SL_OK, "no refine");
    CHECK(used[3] == 0 && !memcmp(ph + 3 * npx, ph + 4 * npx, npx * sizeof *ph),
          "4 kB: the refinement took %zu bytes", used[3]);
    free(ph);
    free(kn);
}

static int cmp_desc(const void *x, const void *y)
{
    float a = *(const float *)x, b = *(const float *)y;
    return (a < b) - (a > b);
}

/* The refinement's cut (phasor_kth_largest) against a sort: arrays of
 * distinct values, of a few repeated ones and of one value, every k. */
TEST(kth_largest_matches_sort)
{
    rng r;
    rng_init(&r, 7, 0);
    float v[257], srt[257], tmp[257];
    for (int kind = 0; kind < 3; kind++)
        for (int m = 1; m <= 257; m += 16) {
            for (int i = 0; i < m; i++)
                v[i] = kind == 0 ? (float)rng_uniform(&r)
                     : kind == 1 ? (float)(int)(rng_uniform(&r) * 5) : 2.5f;
            memcpy(srt, v, sizeof *v * (size_t)m);
            qsort(srt, (size_t)m, sizeof *srt, cmp_desc);
            for (int k = 1; k <= m; k++) {
                memcpy(tmp, v, sizeof *v * (size_t)m);
                float got = phasor_kth_largest(tmp, m, k);
                CHECK(got == srt[k - 1], "kind %d, m %d, k %d: %g, sorted %g", kind, m, k,
                      (double)got, (double)srt[k - 1]);
            }
        }
}

/* phasor_halfspec is its definition to the bit on any pool: every known
 * half-plane frequency's mod tap exp(i (phi - 2 pi k.c)), the taper 1 up
 * to (1 - taper_frac) r_max and a raised cosine to 0 at r_max + 1 (r_max
 * the largest known hypot(p, q)), the p = 0 column's negative q
 * mirrored.  The code takes hypot only where the taper can need it. */
static void ref_halfspec(int nf, const int32_t *fp, const int32_t *fq, const double *phi,
                         const unsigned char *known, const double *mod, double taper, int w,
                         int h, double *cin)
{
    int wc = w / 2 + 1;
    double rmax = 0;
    for (int j = 0; j < nf; j++)
        if (known[j])
            rmax = fmax(rmax, hypot(fp[j], fq[j]));
    double r0 = rmax * (1.0 - taper), r1 = rmax + 1.0;
    memset(cin, 0, (size_t)h * wc * 2 * sizeof *cin);
    for (int j = 0; j < nf; j++) {
        if (!known[j])
            continue;
        int p = fp[j], q = fq[j];
        double r = hypot(p, q);
        double tap = r <= r0 ? 1.0 : 0.5 * (1.0 + cos(M_PI * (r - r0) / (r1 - r0)));
        double ph = phi[j] - 2.0 * M_PI * ((double)p * (w / 2) / w + (double)q * (h / 2) / h);
        double re = mod[j] * tap * cos(ph), im = mod[j] * tap * sin(ph);
        size_t k = (size_t)((q + h) % h) * wc + (size_t)p;
        cin[2 * k] = re, cin[2 * k + 1] = im;
        if (p == 0 && q > 0) {
            k = (size_t)(h - q) * wc;
            cin[2 * k] = re, cin[2 * k + 1] = -im;
        }
    }
}

TEST(halfspec_is_its_definition_on_any_pool)
{
    enum { WD = 48, HT = 40, R = 17 };
    int32_t fp[4 * R * R], fq[4 * R * R];
    double phi[4 * R * R], mod[4 * R * R];
    unsigned char known[4 * R * R];
    int nf = 0;
    rng r;
    rng_init(&r, 11, 0);
    for (int q = -R; q <= R; q++) /* the half plane within R, a few unknown */
        for (int p = 0; p <= R; p++)
            if ((p > 0 || q >= 0) && p * p + q * q <= R * R) {
                fp[nf] = p, fq[nf] = q, phi[nf] = 6 * rng_uniform(&r) - 3;
                mod[nf] = rng_uniform(&r), known[nf++] = rng_uniform(&r) > 0.1;
            }
    size_t nc = (size_t)HT * (WD / 2 + 1) * 2;
    double *want = malloc(nc * sizeof *want), *got = malloc(nc * sizeof *got);
    tpool *pool = tpool_new(3, NULL);
    CHECK(want && got && pool, "out of memory");
    for (int v = 0; want && got && pool && v < 3; v++) {
        double taper = v == 0 ? 0 : v == 1 ? 0.2 : 1;
        ref_halfspec(nf, fp, fq, phi, known, mod, taper, WD, HT, want);
        for (int pl = 0; pl < 2; pl++) {
            phasor_halfspec(pl ? pool : NULL, nf, fp, fq, phi, known, mod, taper, WD, HT, got);
            CHECK(memcmp(want, got, nc * sizeof *got) == 0, "taper %g, %s: not the definition",
                  taper, pl ? "pool of 3" : "no pool");
        }
    }
    tpool_free(pool);
    free(want), free(got);
}

TC_MAIN(TC_CASE(recursion_same_bits_any_threads), TC_CASE(refine_within_budget),
        TC_CASE(kth_largest_matches_sort), TC_CASE(halfspec_is_its_definition_on_any_pool))
