/* test_radon.c - properties of the Radon transforms and their inverses. */
#include <complex.h>
#include <fftw3.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "tsm/radon.h"
#include "tcheck.h"

/* Pearson correlation (the paper's c) without registration. */
static double corr(const float *a, const float *b, int n)
{
    double ma = 0, mb = 0, ab = 0, aa = 0, bb = 0;
    for (int i = 0; i < n; i++)
        ma += a[i], mb += b[i];
    ma /= n, mb /= n;
    for (int i = 0; i < n; i++) {
        ab += (a[i] - ma) * (b[i] - mb);
        aa += (a[i] - ma) * (a[i] - ma);
        bb += (b[i] - mb) * (b[i] - mb);
    }
    return ab / sqrt(aa * bb);
}

/* Sum of Gaussians (x, y relative to the centre, amplitude, sigma). */
static void gaussians(float *img, int w, int h, const double (*g)[4], int ng)
{
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double v = 0, X = x - w / 2, Y = y - h / 2;
            for (int k = 0; k < ng; k++) {
                double dx = X - g[k][0], dy = Y - g[k][1];
                v += g[k][2] * exp(-(dx * dx + dy * dy) / (2 * g[k][3] * g[k][3]));
            }
            img[(size_t)y * w + x] = (float)v;
        }
}

static const double phantom[][4] = {
    {0, 0, 1.0, 4.0}, {9.5, 6.2, 0.7, 2.0}, {-11.3, 3.1, 0.5, 1.5},
    {3.2, -12.4, 0.8, 2.5}, {-6.1, -7.7, 0.4, 1.5}, {14.0, -3.0, 0.6, 1.5}};
enum { NPH = sizeof phantom / sizeof phantom[0] };

static radon *make(int w, int h, int nang, int nproj)
{
    radon_opts o;
    radon_opts_defaults(&o);
    o.nproj = nproj;
    o.fftw_flags = FFTW_ESTIMATE;
    return radon_new(w, h, nang, &o, NULL);
}

/* Centroid of a projection, s = i - ns/2. */
static double proj_centroid(const float *p, int ns)
{
    double s0 = 0, s1 = 0;
    for (int i = 0; i < ns; i++)
        s0 += p[i], s1 += p[i] * (double)(i - ns / 2);
    return s1 / s0;
}

/* A point at (x0, y0) from the centre projects to s = x0 cos + y0 sin, on
 * both paths, and theta = 90 deg looks north (PA = theta - 90). */
TEST(point_projects_to_s)
{
    int n = 64, nang = 12;
    const double pt[1][4] = {{7.3, -4.6, 1.0, 1.2}};
    float *img = malloc(sizeof(float) * n * n);
    radon *r = make(n, n, nang, 0);
    CHECK(r, "radon_new");
    int ns = radon_nproj(r), nf = radon_nfreq(r);
    float *p = malloc(sizeof(float) * nang * ns);
    float complex *sp = malloc(sizeof(float complex) * nang * nf);
    gaussians(img, n, n, pt, 1);
    for (int path = 0; path < 2; path++) {
        if (path == 0)
            radon_project(r, img, p);
        else {
            radon_slices(r, img, sp);
            radon_spec_to_proj(r, sp, p);
        }
        for (int k = 0; k < nang; k++) {
            double th = radon_angle_rad(r, k);
            double want = pt[0][0] * cos(th) + pt[0][1] * sin(th);
            double got = proj_centroid(p + (size_t)k * ns, ns);
            CHECK(fabs(got - want) < 0.02, "path %d angle %d: s %.4f, want %.4f", path, k,
                  got, want);
        }
    }
    /* North of the centre (+y, PA 0) at theta = 90: positive s. */
    const double north[1][4] = {{0, 9, 1.0, 1.2}};
    gaussians(img, n, n, north, 1);
    radon_project(r, img, p);
    CHECK_NEAR(proj_centroid(p + (size_t)(nang / 2) * ns, ns), 9.0, 0.02);
    radon_free(r);
    free(p), free(sp), free(img);
}

/* The Fourier-slice samples are the exact DFT of the pixels at the polar
 * points, to the NUFFT's accuracy, for both default kernels. */
TEST(slices_match_direct_dft)
{
    int n = 32;
    float *img = malloc(sizeof(float) * n * n);
    unsigned s = 12345;
    for (int i = 0; i < n * n; i++) {
        s = s * 1103515245u + 12345u;
        img[i] = (float)((s >> 8) & 0xffff) / 65536.0f;
    }
    int nangs[2] = {12, 90};   /* grid 40 (sigma 1.25) kernel 8, sigma 2 kernel 4 */
    for (int t2 = 0; t2 < 2; t2++) {
        radon *r = make(n, n, nangs[t2], 0);
        CHECK(r, "radon_new");
        int nf = radon_nfreq(r), ns = radon_nproj(r), nang = nangs[t2];
        float complex *sp = malloc(sizeof(float complex) * nang * nf);
        radon_slices(r, img, sp);
        double f0 = 0, emax = 0;
        for (int i = 0; i < n * n; i++)
            f0 += img[i];
        for (int k = 0; k < nang; k += 5)
            for (int j = 0; j < nf; j += 2) {
                double th = radon_angle_rad(r, k), rho = (double)j / ns;
                double complex d = 0;
                for (int y = 0; y < n; y++)
                    for (int x = 0; x < n; x++)
                        d += img[y * n + x] *
                             cexp(-2 * M_PI * I * rho * ((x - n / 2) * cos(th) + (y - n / 2) * sin(th)));
                double e = cabs(d - sp[(size_t)k * nf + j]);
                emax = e > emax ? e : emax;
            }
        radon_free(r);
        free(sp);
        printf("    %d angles: max |slice - DFT| / F(0) = %.2g\n", nang, emax / f0);
        /* measured 1.5e-5 and 3.2e-4 at this size (1.4e-4 at 64^2) */
        CHECK(emax < 1e-3 * f0, "%d angles: max error %.3g of F(0) %.3g", nang, emax, f0);
    }
    free(img);
}

/* Fourier-slice theorem: the 1-D FFT of the spatial projection equals the
 * slice, up to the bilinear projector's interpolation error. */
TEST(slices_equal_fft_of_projection)
{
    int n = 64, nang = 36;
    float *img = malloc(sizeof(float) * n * n);
    gaussians(img, n, n, phantom, NPH);
    radon *r = make(n, n, nang, 0);
    CHECK(r, "radon_new");
    int nf = radon_nfreq(r), ns = radon_nproj(r);
    float complex *a = malloc(sizeof(float complex) * nang * nf);
    float complex *b = malloc(sizeof(float complex) * nang * nf);
    float *p = malloc(sizeof(float) * nang * ns);
    radon_slices(r, img, a);
    radon_project(r, img, p);
    radon_proj_to_spec(r, p, b);
    double emax = 0, f0 = cabsf(a[0]);
    for (int i = 0; i < nang * nf; i++)
        emax = fmax(emax, cabsf(a[i] - b[i]));
    radon_free(r);
    free(a), free(b), free(p), free(img);
    printf("    max |slice - FFT(projection)| / F(0) = %.2g\n", emax / f0);
    CHECK(emax < 0.01 * f0, "max |slice - FFT(projection)| %.3g of F(0) %.3g", emax, f0);
}

/* radon_slices_ws: two threads, each with its own scratch, give the same
 * bits as the handle's radon_slices, and the samples are the pixels' DFT
 * on an odd, non-square frame (the padded spectrum's wrap and mirror
 * copies, radon.c), for the few- and many-angle grids. */
typedef struct ws_job {
    const radon *r;
    radon_ws *ws;
    const float *img;
    float complex *sp;
} ws_job;

static void *ws_thread(void *arg)
{
    ws_job *j = arg;
    for (int rep = 0; rep < 3; rep++)
        radon_slices_ws(j->r, j->ws, j->img, j->sp);
    return NULL;
}

TEST(slices_ws_threads_and_odd_sizes)
{
    int w = 45, h = 37, nangs[2] = {7, 90};   /* odd: the row blocks differ */
    float *img[2] = {malloc(sizeof(float) * w * h), malloc(sizeof(float) * w * h)};
    unsigned s = 777;
    for (int k = 0; k < 2; k++)
        for (int i = 0; i < w * h; i++) {
            s = s * 1103515245u + 12345u;
            img[k][i] = (float)((s >> 8) & 0xffff) / 65536.0f;
        }
    for (int t2 = 0; t2 < 2; t2++) {
        int nang = nangs[t2];
        radon *r = make(w, h, nang, 0);
        CHECK(r, "radon_new");
        int nf = radon_nfreq(r), ns = radon_nproj(r);
        size_t n = (size_t)nang * nf;
        float complex *ref[2], *got[2];
        ws_job jobs[2];
        pthread_t th[2];
        for (int k = 0; k < 2; k++) {
            ref[k] = malloc(sizeof(float complex) * n);
            got[k] = malloc(sizeof(float complex) * n);
            radon_slices(r, img[k], ref[k]);
            jobs[k] = (ws_job){r, radon_ws_new(r, NULL), img[k], got[k]};
            CHECK(jobs[k].ws, "radon_ws_new");
        }
        for (int k = 0; k < 2; k++)
            pthread_create(&th[k], NULL, ws_thread, &jobs[k]);
        for (int k = 0; k < 2; k++)
            pthread_join(th[k], NULL);
        for (int k = 0; k < 2; k++)
            CHECK(memcmp(ref[k], got[k], n * sizeof *got[k]) == 0,
                  "%d angles, image %d: radon_slices_ws differs from radon_slices", nang, k);
        double f0 = 0, emax = 0;
        for (int i = 0; i < w * h; i++)
            f0 += img[0][i];
        for (int k = 0; k < nang; k += nang > 10 ? 11 : 1)
            for (int j = 0; j < nf; j += 3) {
                double th_k = radon_angle_rad(r, k), rho = (double)j / ns;
                double complex d = 0;
                for (int y = 0; y < h; y++)
                    for (int x = 0; x < w; x++) {
                        double s_px = (x - w / 2) * cos(th_k) + (y - h / 2) * sin(th_k);
                        d += img[0][y * w + x] * cexp(-2 * M_PI * I * rho * s_px);
                    }
                emax = fmax(emax, cabs(d - ref[0][(size_t)k * nf + j]));
            }
        printf("    %dx%d, %d angles: max |slice - DFT| / F(0) = %.2g\n", w, h, nang, emax / f0);
        CHECK(emax < 1e-3 * f0, "%d angles: max error %.3g of F(0) %.3g", nang, emax, f0);
        for (int k = 0; k < 2; k++) {
            radon_ws_free(jobs[k].ws);
            free(ref[k]), free(got[k]);
        }
        radon_free(r);
    }
    radon_ws_free(NULL);
    free(img[0]), free(img[1]);
}

/* Projection <-> spectrum is an exact round trip at nfreq = nproj/2 + 1. */
TEST(proj_spec_round_trip)
{
    int n = 40, nang = 5;
    radon *r = make(n, n, nang, 0);
    CHECK(r, "radon_new");
    int ns = radon_nproj(r), nf = radon_nfreq(r);
    float *p = malloc(sizeof(float) * nang * ns), *q = malloc(sizeof(float) * nang * ns);
    float complex *sp = malloc(sizeof(float complex) * nang * nf);
    for (int i = 0; i < nang * ns; i++)
        p[i] = (float)sin(0.37 * i) + 0.5f;
    radon_proj_to_spec(r, p, sp);
    radon_spec_to_proj(r, sp, q);
    double emax = 0;
    for (int i = 0; i < nang * ns; i++)
        emax = fmax(emax, fabs(p[i] - q[i]));
    radon_free(r);
    free(p), free(q), free(sp);
    CHECK(emax < 1e-5, "round trip error %.3g", emax);
}

/* Radon -> inverse round trips at 180 angles: every path returns the
 * phantom.  Measured c: spatial+FBP 0.9999, slices+gridding 0.99999. */
TEST(fbp_round_trip_180)
{
    int n = 64, nang = 180;
    float *img = malloc(sizeof(float) * n * n), *rec = malloc(sizeof(float) * n * n);
    gaussians(img, n, n, phantom, NPH);
    radon *r = make(n, n, nang, 0);
    CHECK(r, "radon_new");
    int ns = radon_nproj(r), nf = radon_nfreq(r);
    float *p = malloc(sizeof(float) * nang * ns);
    float complex *sp = malloc(sizeof(float complex) * nang * nf);
    radon_project(r, img, p);
    radon_fbp(r, p, rec);
    double c1 = corr(img, rec, n * n);
    radon_slices(r, img, sp);
    radon_fbp_slices(r, sp, rec);
    double c2 = corr(img, rec, n * n);
    double s0 = 0, s1 = 0;   /* FBP keeps the flux of an object in the disc */
    radon_spec_to_proj(r, sp, p);
    radon_fbp(r, p, rec);
    double c3 = corr(img, rec, n * n);
    for (int i = 0; i < n * n; i++)
        s0 += img[i], s1 += rec[i];
    radon_free(r);
    free(p), free(sp), free(img), free(rec);
    printf("    180 angles: spatial+FBP c = %.5f, gridding c = %.6f, slices+FBP c = %.6f, "
           "flux ratio %.4f\n", c1, c2, c3, s1 / s0);
    CHECK(c1 >= 0.995, "spatial projection + FBP: c = %.5f", c1);
    CHECK(c2 >= 0.999, "slices + gridding FBP: c = %.5f", c2);
    CHECK(c3 >= 0.999, "slices -> projections + FBP: c = %.5f", c3);
    CHECK(fabs(s1 / s0 - 1) < 0.02, "FBP flux ratio %.4f", s1 / s0);
}

/* FBP windows: all keep a smooth phantom (they only cut high frequencies). */
TEST(fbp_windows)
{
    int n = 48, nang = 90;
    float *img = malloc(sizeof(float) * n * n), *rec = malloc(sizeof(float) * n * n);
    gaussians(img, n, n, phantom, 1);
    for (int win = RADON_WIN_RAMLAK; win <= RADON_WIN_HANN; win++) {
        radon_opts o;
        radon_opts_defaults(&o);
        o.window = (radon_window)win;
        o.bp_interp = win & 1 ? RADON_INTERP_LINEAR : RADON_INTERP_CUBIC;
        o.fftw_flags = FFTW_ESTIMATE;
        radon *r = radon_new(n, n, nang, &o, NULL);
        CHECK(r, "radon_new window %d", win);
        float *p = malloc(sizeof(float) * nang * radon_nproj(r));
        radon_project(r, img, p);
        radon_fbp(r, p, rec);
        double c = corr(img, rec, n * n);
        radon_free(r);
        free(p);
        CHECK(c > 0.995, "window %d: c = %.5f", win, c);
    }
    free(img), free(rec);
}

/* The normal operator N = fbp_slices(slices(.)) that radon_invert_iter
 * descends on is symmetric: <x, N y> = <N x, y> (gridding is the exact
 * adjoint of the slice interpolation, up to the density weights). */
TEST(normal_operator_symmetric)
{
    int n = 40, nang = 24;
    radon *r = make(n, n, nang, 0);
    CHECK(r, "radon_new");
    int nf = radon_nfreq(r);
    float *x = calloc(n * n, sizeof(float)), *y = calloc(n * n, sizeof(float));
    float *nx = malloc(sizeof(float) * n * n), *ny = malloc(sizeof(float) * n * n);
    float complex *sp = malloc(sizeof(float complex) * nang * nf);
    for (int i = 0; i < n * n; i++) {
        int X = i % n - n / 2, Y = i / n - n / 2;
        if (X * X + Y * Y < 17 * 17) {
            x[i] = (float)sin(0.3 * i), y[i] = (float)cos(0.11 * i * i);
        }
    }
    radon_slices(r, x, sp);
    radon_fbp_slices(r, sp, nx);
    radon_slices(r, y, sp);
    radon_fbp_slices(r, sp, ny);
    double a = 0, b = 0, m = 0;
    for (int i = 0; i < n * n; i++)
        a += (double)x[i] * ny[i], b += (double)nx[i] * y[i], m += fabs((double)x[i] * ny[i]);
    radon_free(r);
    free(x), free(y), free(nx), free(ny), free(sp);
    CHECK(fabs(a - b) < 1e-5 * m, "<x,Ny> %.9g, <Nx,y> %.9g", a, b);
}

/* 18 angles: FBP streaks; the non-negative iterative inverse removes them
 * on a sparse star field (measured c 0.79 -> 0.99). */
TEST(iterative_beats_fbp_at_18_angles)
{
    int n = 64, nang = 18;
    const double stars[][4] = {{0, 0, 1, 1.0}, {8.2, 5.1, 0.6, 1.0}, {-6.4, 9.3, 0.5, 1.0},
                               {-10.1, -5.2, 0.8, 1.0}, {4.3, -12.2, 0.4, 1.0}};
    float *img = malloc(sizeof(float) * n * n), *rec = malloc(sizeof(float) * n * n);
    gaussians(img, n, n, stars, 5);
    radon *r = make(n, n, nang, 0);
    CHECK(r, "radon_new");
    float complex *sp = malloc(sizeof(float complex) * nang * radon_nfreq(r));
    radon_slices(r, img, sp);
    radon_fbp_slices(r, sp, rec);
    double cf = corr(img, rec, n * n);
    radon_invert_iter(r, sp, 40, 1, rec);
    double ci = corr(img, rec, n * n);
    float mn = 0;
    for (int i = 0; i < n * n; i++)
        mn = rec[i] < mn ? rec[i] : mn;
    radon_free(r);
    free(sp), free(img), free(rec);
    printf("    18 angles: FBP c = %.4f, iterative c = %.4f\n", cf, ci);
    CHECK(ci > cf + 0.1 && ci > 0.95, "FBP c %.4f, iterative c %.4f", cf, ci);
    CHECK(mn >= 0, "negative pixel %g with nonneg", mn);
}

/* A pool (radon_opts.pool) spreads one image's slices, gridding FBP,
 * iterative inverse and projections from spectra, and the tables at
 * radon_new, over its threads: the bits must be those of one thread, for
 * any pool size.  The sizes give
 * column and row chunks with tails (45 x 38: a 90 grid, 46 columns, 19 +
 * 19 rows), row blocks of two heights (45 x 37), blocks sharing their
 * plans (100 x 100) and samples that straddle chunks and reach kx = 0 and
 * ng/2. */
TEST(pool_same_bits_as_one_thread)
{
    const int sizes[][3] = {{45, 38, 7}, {45, 38, 90}, {45, 37, 90}, {100, 100, 180}};
    for (int c = 0; c < 4; c++) {
        int w = sizes[c][0], h = sizes[c][1], nang = sizes[c][2];
        float *img = malloc(sizeof(float) * w * h), *out[3], *prj[3];
        float complex *sp[3];
        size_t npr = 0;
        gaussians(img, w, h, phantom, NPH);
        size_t nsp = 0;
        for (int p = 0; p < 3; p++) {   /* no pool, 2 threads, 3 threads */
            tpool *pool = p ? tpool_new(p + 1, NULL) : NULL;
            radon_opts o;
            radon_opts_defaults(&o);
            o.spatial = 0, o.fftw_flags = FFTW_ESTIMATE, o.pool = pool;
            radon *r = radon_new(w, h, nang, &o, NULL);
            CHECK(r && (!p || pool), "radon_new (pool %d)", p);
            nsp = (size_t)nang * radon_nfreq(r);
            sp[p] = malloc(sizeof(float complex) * nsp);
            out[p] = malloc(sizeof(float) * 2 * w * h);
            CHECK(radon_slices(r, img, sp[p]) == SL_OK, "radon_slices");
            npr = (size_t)nang * radon_nproj(r);
            prj[p] = malloc(sizeof(float) * npr);
            CHECK(radon_spec_to_proj(r, sp[p], prj[p]) == SL_OK, "radon_spec_to_proj");
            CHECK(radon_fbp_slices(r, sp[p], out[p]) == SL_OK, "radon_fbp_slices");
            CHECK(radon_invert_iter(r, sp[p], 5, 1, out[p] + w * h) == SL_OK, "iterative");
            radon_free(r);
            tpool_free(pool);
        }
        for (int p = 1; p < 3; p++) {
            CHECK(memcmp(sp[0], sp[p], nsp * sizeof *sp[0]) == 0,
                  "%dx%d, %d angles: slices on %d threads differ from one", w, h, nang, p + 1);
            CHECK(memcmp(prj[0], prj[p], sizeof(float) * npr) == 0,
                  "%dx%d, %d angles: projections on %d threads differ", w, h, nang, p + 1);
            CHECK(memcmp(out[0], out[p], sizeof(float) * w * h) == 0,
                  "%dx%d, %d angles: FBP on %d threads differs from one", w, h, nang, p + 1);
            CHECK(memcmp(out[0] + w * h, out[p] + w * h, sizeof(float) * w * h) == 0,
                  "%dx%d, %d angles: iterative inverse on %d threads differs", w, h, nang,
                  p + 1);
        }
        double cf = corr(img, out[0], w * h);
        printf("    %dx%d, %d angles: pooled bits equal; FBP c = %.4f\n", w, h, nang, cf);
        CHECK(cf > (nang > 50 ? 0.99 : 0.5), "FBP c %.4f", cf);
        for (int p = 0; p < 3; p++)
            free(sp[p]), free(out[p]), free(prj[p]);
        free(img);
    }
}

TEST(bad_arguments)
{
    sl_err e = {0};
    CHECK(radon_new(0, 10, 10, NULL, &e) == NULL && e.code == SL_EINVAL, "w = 0 accepted");
    radon_opts o;
    radon_opts_defaults(&o);
    o.nfreq = 1000;
    CHECK(radon_new(32, 32, 4, &o, &e) == NULL && e.code == SL_EINVAL, "nfreq > nproj/2+1");
    radon_free(NULL);
}

TC_MAIN(TC_CASE(point_projects_to_s), TC_CASE(slices_match_direct_dft),
        TC_CASE(slices_equal_fft_of_projection), TC_CASE(slices_ws_threads_and_odd_sizes),
        TC_CASE(proj_spec_round_trip),
        TC_CASE(fbp_round_trip_180), TC_CASE(fbp_windows),
        TC_CASE(normal_operator_symmetric), TC_CASE(iterative_beats_fbp_at_18_angles),
        TC_CASE(pool_same_bits_as_one_thread), TC_CASE(bad_arguments))
