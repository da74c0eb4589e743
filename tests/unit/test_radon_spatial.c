/* test_radon_spatial.c - the spatial projector (radon_spatial.c) against
 * its definition, and its bits across threads and code paths. */
#include <fftw3.h>
#include <stdlib.h>

#include "tsm/radon.h"
#include "tsm/radon_spatial.h"
#include "tcheck.h"

typedef struct geom {
    int w, h, nang, nproj;    /* nproj 0: radon's default */
} geom;

/* Odd and even sizes, non-square frames, odd angle counts (no 90-degree
 * partners), and projections shorter than the frame (wrapped). */
static const geom geoms[] = {
    {64, 64, 36, 0}, {63, 47, 17, 0}, {31, 64, 90, 20}, {40, 40, 2, 0}, {50, 80, 12, 40},
    {45, 45, 180, 44}};
enum { NGEOM = sizeof geoms / sizeof geoms[0] };

static void noise(float *img, int n, unsigned seed, int absval)
{
    for (int i = 0; i < n; i++) {
        seed = seed * 1103515245u + 12345u;
        float v = (float)((seed >> 8) & 0xffff) / 65536.0f - 0.3f;
        img[i] = absval ? fabsf(v) : v;
    }
}

/* The definition, ray by ray in double: ray sv of angle theta samples the
 * frame bilinearly (zero outside) at (w/2, h/2) + sv n + t m for every
 * integer t, n = (cos, sin), m = (-sin, cos); bin wrap(sv + ns/2). */
static void ref_project(const float *img, int w, int h, int nang, int ns, float *proj)
{
    int nd = (int)ceil(hypot(w, h)) + 4;
    nd += nd & 1;
    for (int k = 0; k < nang; k++) {
        double th = k * M_PI / nang, c = cos(th), s = sin(th);
        for (int i = 0; i < ns; i++)
            proj[(size_t)k * ns + i] = 0;
        for (int sv = -nd / 2; sv < nd / 2; sv++) {
            double acc = 0;
            for (int t = -nd / 2; t <= nd / 2; t++) {
                double x = w / 2 + sv * c - t * s, y = h / 2 + sv * s + t * c;
                int ix = (int)floor(x), iy = (int)floor(y);
                double fx = x - ix, fy = y - iy;
                for (int b = 0; b < 2; b++)
                    for (int a = 0; a < 2; a++) {
                        int X = ix + a, Y = iy + b;
                        if (X >= 0 && X < w && Y >= 0 && Y < h)
                            acc += (a ? fx : 1 - fx) * (b ? fy : 1 - fy) * img[(size_t)Y * w + X];
                    }
            }
            int bin = ((sv + ns / 2) % ns + ns) % ns;
            proj[(size_t)k * ns + bin] += (float)acc;
        }
    }
}

static radon *make(const geom *g, int threads)
{
    radon_opts o;
    radon_opts_defaults(&o);
    o.nproj = g->nproj;
    o.threads = threads;
    o.fftw_flags = FFTW_ESTIMATE;
    return radon_new(g->w, g->h, g->nang, &o, NULL);
}

/* Equal to the definition to float rounding: within 1e-5 of the largest
 * projection of |frame| (measured <= 1.2e-6; a wrong partner, bin or
 * weight is off by O(1)). */
TEST(projector_matches_ray_definition)
{
    for (int gi = 0; gi < NGEOM; gi++) {
        const geom *g = geoms + gi;
        radon *r = make(g, 1);
        CHECK(r, "radon_new %dx%d", g->w, g->h);
        int ns = radon_nproj(r), npix = g->w * g->h;
        size_t np = (size_t)g->nang * ns;
        float *img = malloc(npix * sizeof *img), *p = malloc(np * sizeof *p);
        float *ref = malloc(np * sizeof *ref);
        noise(img, npix, 17 + gi, 1);
        ref_project(img, g->w, g->h, g->nang, ns, ref);
        double scale = 0;
        for (size_t i = 0; i < np; i++)
            scale = fmax(scale, ref[i]);
        noise(img, npix, 17 + gi, 0);
        ref_project(img, g->w, g->h, g->nang, ns, ref);
        int st = radon_project(r, img, p);
        double emax = 0;
        for (size_t i = 0; i < np; i++)
            emax = fmax(emax, fabs((double)p[i] - ref[i]));
        radon_free(r);
        free(img), free(p), free(ref);
        CHECK(st == SL_OK, "radon_project: %d", st);
        printf("    %dx%d, %d angles, nproj %d: max |p - definition| = %.2g of %.3g\n", g->w,
               g->h, g->nang, ns, emax, scale);
        CHECK(emax <= 1e-5 * scale, "%dx%d %d angles: error %.3g of %.3g", g->w, g->h,
              g->nang, emax, scale);
    }
}

/* Each angle's projection is computed by one pass, whichever thread runs
 * it, and every code path sums in the same order: 1, 2 and 3 threads and
 * the portable, SSE2 and AVX2 loops give the same bits. */
TEST(projector_same_bits_any_threads_or_path)
{
    for (int gi = 0; gi < NGEOM; gi++) {
        const geom *g = geoms + gi;
        int npix = g->w * g->h;
        float *img = malloc(npix * sizeof *img), *p[3] = {NULL, NULL, NULL};
        noise(img, npix, 99 + gi, 0);
        size_t np = 0;
        for (int th = 1; th <= 3; th++) {
            radon *r = make(g, th);
            CHECK(r, "radon_new");
            np = (size_t)g->nang * radon_nproj(r);
            p[th - 1] = malloc(np * sizeof(float));
            radon_project(r, img, p[th - 1]);
            radon_free(r);
        }
        int same = !memcmp(p[0], p[1], np * sizeof(float)) &&
                   !memcmp(p[0], p[2], np * sizeof(float));
        CHECK(same, "%dx%d, %d angles: threads change the bits", g->w, g->h, g->nang);
        /* Code paths, on a handle of radon_spatial's own. */
        int ns = (int)(np / g->nang);
        double *cs = malloc(g->nang * sizeof *cs), *sn = malloc(g->nang * sizeof *sn);
        int *xlo = calloc(g->h, sizeof *xlo), *xhi = calloc(g->h, sizeof *xhi);
        for (int k = 0; k < g->nang; k++)
            cs[k] = cos(k * M_PI / g->nang), sn[k] = sin(k * M_PI / g->nang);
        radon_opts o;
        radon_opts_defaults(&o);
        o.fftw_flags = FFTW_ESTIMATE;
        radon_spatial *sp = radon_spatial_new(g->w, g->h, g->nang, ns, &o, cs, sn, xlo, xhi,
                                              NULL);
        CHECK(sp, "radon_spatial_new");
        int best = radon_spatial_set_simd(sp, -1), differ = -1;
        for (int lv = 0; lv <= best; lv++) {
            CHECK(radon_spatial_set_simd(sp, lv) == lv, "level %d", lv);
            radon_spatial_project(sp, img, p[lv]);
            if (lv && memcmp(p[0], p[lv], np * sizeof(float)))
                differ = lv;
        }
        if (gi == 0)
            printf("    code paths compared: portable..%s\n",
                   best == 2 ? "AVX2" : best == 1 ? "SSE2" : "portable");
        radon_spatial_free(sp);
        free(cs), free(sn), free(xlo), free(xhi), free(img);
        for (int i = 0; i < 3; i++)
            free(p[i]);
        CHECK(differ < 0, "%dx%d: path %d differs from the portable loop", g->w, g->h, differ);
    }
}

/* The back projection's rows are claimed by whichever thread is free, each
 * pixel summing the angles in order: 1, 2 and 3 threads give the same
 * bits (radon_backproject.c). */
TEST(fbp_same_bits_any_threads)
{
    for (int gi = 0; gi < NGEOM; gi++) {
        const geom *g = geoms + gi;
        int npix = g->w * g->h;
        float *img = malloc(npix * sizeof *img), *b[3] = {NULL, NULL, NULL}, *p = NULL;
        noise(img, npix, 7 + gi, 0);
        for (int th = 1; th <= 3; th++) {
            radon *r = make(g, th);
            CHECK(r, "radon_new");
            if (!p) {
                p = malloc((size_t)g->nang * radon_nproj(r) * sizeof *p);
                radon_project(r, img, p);
            }
            b[th - 1] = malloc(npix * sizeof(float));
            CHECK(radon_fbp(r, p, b[th - 1]) == SL_OK, "radon_fbp");
            radon_free(r);
        }
        double peak = 0;
        for (int i = 0; i < npix; i++)
            peak = fmax(peak, fabs(b[0][i]));
        int same = !memcmp(b[0], b[1], npix * sizeof(float)) &&
                   !memcmp(b[0], b[2], npix * sizeof(float));
        free(img), free(p);
        for (int i = 0; i < 3; i++)
            free(b[i]);
        CHECK(peak > 0, "%dx%d: empty back projection", g->w, g->h);
        CHECK(same, "%dx%d, %d angles: threads change the back projection's bits", g->w, g->h,
              g->nang);
    }
}

TEST(project_needs_spatial)
{
    radon_opts o;
    radon_opts_defaults(&o);
    o.spatial = 0;
    o.fftw_flags = FFTW_ESTIMATE;
    radon *r = radon_new(16, 16, 4, &o, NULL);
    CHECK(r, "radon_new");
    float img[256] = {0}, *p = malloc(4 * radon_nproj(r) * sizeof *p);
    int st = radon_project(r, img, p);
    radon_free(r);
    free(p);
    CHECK(st == SL_EINVAL, "radon_project without the projector: %d", st);
}

/* A handle made without the projector makes the FBP's filter at its first
 * radon_fbp: the same back projection, to the bit, as a full handle's. */
TEST(fbp_without_projector_is_the_same)
{
    radon_opts o;
    radon_opts_defaults(&o);
    o.fftw_flags = FFTW_ESTIMATE;
    int w = 24, h = 20, nang = 12;
    radon *full = radon_new(w, h, nang, &o, NULL);
    o.spatial = 0;
    radon *lazy = radon_new(w, h, nang, &o, NULL);
    CHECK(full && lazy, "radon_new");
    size_t npix = (size_t)w * h, np = (size_t)nang * radon_nproj(full);
    float *img = calloc(npix, sizeof *img), *p = malloc(np * sizeof *p);
    float *a = malloc(npix * sizeof *a), *b = malloc(npix * sizeof *b);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            img[y * w + x] = (x - 11) * (x - 11) + (y - 9) * (y - 9) < 30 ? 1.0f + 0.1f * x : 0;
    CHECK(radon_project(full, img, p) == SL_OK, "project");
    int sa = radon_fbp(full, p, a), sb = radon_fbp(lazy, p, b), sc = radon_fbp(lazy, p, b);
    double peak = 0;
    for (size_t i = 0; i < npix; i++)
        peak = a[i] > peak ? a[i] : peak;
    CHECK(sa == SL_OK && sb == SL_OK && sc == SL_OK, "radon_fbp: %d %d %d", sa, sb, sc);
    CHECK(peak > 0.5, "back projection peak %g", peak);
    CHECK(!memcmp(a, b, npix * sizeof *a), "the lazy filter changes the back projection");
    radon_free(full), radon_free(lazy);
    free(img), free(p), free(a), free(b);
}

/* A frame's projections and spectra on one thread with a radon_ws
 * (tsm_accum's workers) are the bits of radon_project then
 * radon_proj_to_spec; two workspaces on two frames do not mix; a
 * handle without the projector refuses the workspace. */
TEST(project_spec_ws_is_the_two_calls)
{
    radon_opts o;
    radon_opts_defaults(&o);
    o.fftw_flags = FFTW_ESTIMATE;
    o.threads = 2;
    int w = 30, h = 26, nang = 18;
    radon *r = radon_new(w, h, nang, &o, NULL);
    CHECK(r, "radon_new");
    size_t npix = (size_t)w * h, nsp = (size_t)nang * radon_nfreq(r);
    float *img = malloc(2 * npix * sizeof *img);
    float *p = malloc((size_t)nang * radon_nproj(r) * sizeof *p);
    float complex *want = malloc(2 * nsp * sizeof *want), *got = malloc(2 * nsp * sizeof *got);
    for (size_t i = 0; i < 2 * npix; i++)
        img[i] = (float)((i * 2654435761u) % 1000) / 100.0f;
    radon_ws *ws[2] = {radon_ws_new_projector(r, NULL), radon_ws_new_projector(r, NULL)};
    CHECK(ws[0] && ws[1], "radon_ws_new_projector");
    for (int f = 0; f < 2; f++) {
        CHECK(radon_project(r, img + f * npix, p) == SL_OK, "project");
        CHECK(radon_proj_to_spec(r, p, want + f * nsp) == SL_OK, "proj_to_spec");
    }
    CHECK(radon_project_spec_ws(r, ws[1], img + npix, got + nsp) == SL_OK &&
              radon_project_spec_ws(r, ws[0], img, got) == SL_OK, "radon_project_spec_ws");
    CHECK(!memcmp(want, got, 2 * nsp * sizeof *want), "the workspace path changes the spectra");
    o.spatial = 0;
    radon *f = radon_new(w, h, nang, &o, NULL);
    CHECK(f && !radon_ws_new_projector(f, NULL), "a workspace without the projector");
    radon_free(f);
    radon_ws_free(ws[0]), radon_ws_free(ws[1]);
    radon_free(r);
    free(img), free(p), free(want), free(got);
}

TC_MAIN(TC_CASE(projector_matches_ray_definition),
        TC_CASE(projector_same_bits_any_threads_or_path), TC_CASE(fbp_same_bits_any_threads),
        TC_CASE(project_needs_spatial), TC_CASE(fbp_without_projector_is_the_same),
        TC_CASE(project_spec_ws_is_the_two_calls))
