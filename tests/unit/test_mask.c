/* test_mask.c - pupils and aperture masks: redundancy against a brute-force
 * count, generator constraints, file round trips and errors, rendering. */
#include "sim/mask.h"

#include "tcheck.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Independent count over all n(n-1) SIGNED baseline vectors c_j - c_i
 * (i != j): unordered pairs of them closer than d.  Relation to the
 * mask's redundancy R (unordered pairs of unsigned baselines {b_k, b_l}
 * with min(|b_k - b_l|, |b_k + b_l|) < d):
 *  - a pair with |b_k - b_l| < d shows up twice, as (b_k, b_l) and
 *    (-b_k, -b_l); one with |b_k + b_l| < d twice, as (b_k, -b_l) and
 *    (-b_k, b_l);
 *  - both cannot hold at once: |b_k - b_l| + |b_k + b_l| >= 2|b_k| >= 2d
 *    since holes do not overlap; for the same reason b and -b (distance
 *    2|b| >= 2d) never pair.
 * Hence brute == 2R exactly. */
static long brute_signed(const mask *m, double *min_self)
{
    int n = mask_nholes(m), nv = n * (n - 1);
    double d = mask_hole_diameter_m(m);
    double *vx = malloc((size_t)nv * sizeof *vx);
    double *vy = malloc((size_t)nv * sizeof *vy);
    if (!vx || !vy)
        abort();
    int k = 0;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            if (i == j)
                continue;
            double xi, yi, xj, yj;
            mask_hole(m, i, &xi, &yi);
            mask_hole(m, j, &xj, &yj);
            vx[k] = xj - xi;
            vy[k++] = yj - yi;
        }
    long c = 0;
    *min_self = INFINITY; /* shortest |v - (-v)|: the premise above */
    for (int s = 0; s < nv; s++) {
        double self = 2 * hypot(vx[s], vy[s]);
        *min_self = self < *min_self ? self : *min_self;
        for (int t = s + 1; t < nv; t++)
            c += hypot(vx[s] - vx[t], vy[s] - vy[t]) < d;
    }
    free(vx);
    free(vy);
    return c;
}

static mask *holes(const double *xy, int n, double d)
{
    double x[64], y[64];
    for (int i = 0; i < n; i++) {
        x[i] = xy[2 * i];
        y[i] = xy[2 * i + 1];
    }
    sl_err e;
    mask *m = mask_new_holes(x, y, n, d, &e);
    if (!m)
        fprintf(stderr, "mask_new_holes: %s\n", e.msg);
    return m;
}

/* n collinear holes spaced s > d: baselines m*s (m = 1..n-1) with
 * multiplicity n - m; only equal multiples overlap, so
 * R = sum_m C(n-m, 2) = C(n, 3). */
TEST(redundancy_collinear)
{
    for (int n = 3; n <= 6; n++) {
        double xy[12];
        for (int i = 0; i < n; i++) {
            xy[2 * i] = 0.2 * i - 0.5;
            xy[2 * i + 1] = 0.1;
        }
        mask *m = holes(xy, n, 0.1);
        CHECK(m, "collinear %d", n);
        long want = (long)n * (n - 1) * (n - 2) / 6, r = mask_redundancy(m);
        double ms;
        long b = brute_signed(m, &ms);
        mask_free(m);
        CHECK(r == want, "n=%d: redundancy %ld, C(n,3) = %ld", n, r, want);
        CHECK(b == 2 * r, "n=%d: brute %ld != 2 * %ld", n, b, r);
    }
}

/* A parallelogram has exactly two redundant pairs, its opposite sides; with
 * this hole order one is caught by |b_k - b_l| and one by |b_k + b_l|.  A
 * generic triangle has none. */
TEST(redundancy_parallelogram)
{
    static const double par[] = {0, 0, 0.3, 0, 0.6, 0.5, 0.3, 0.5};
    mask *m = holes(par, 4, 0.1);
    CHECK(m, "parallelogram");
    double ms;
    long r = mask_redundancy(m), b = brute_signed(m, &ms);
    mask_free(m);
    CHECK(r == 2, "parallelogram redundancy %ld, want 2", r);
    CHECK(b == 2 * r, "brute %ld != 2 * %ld", b, r);
    static const double tri[] = {0, 0, 0.37, 0.05, -0.1, 0.42};
    m = holes(tri, 3, 0.1);
    CHECK(m, "triangle");
    r = mask_redundancy(m);
    mask_free(m);
    CHECK(r == 0, "triangle redundancy %ld", r);
}

TEST(redundancy_nrm17_brute)
{
    mask *m;
    sl_err e;
    CHECK(mask_named(&m, "nrm17", &e) == SL_OK, "%s", e.msg);
    double min_self;
    long r = mask_redundancy(m), b = brute_signed(m, &min_self);
    double d = mask_hole_diameter_m(m);
    mask_free(m);
    CHECK(min_self >= 2 * d, "premise of brute == 2R: %g < 2d", min_self);
    CHECK(r >= 0, "redundancy %ld", r);
    CHECK(b == 2 * r, "brute-force signed count %ld != 2 * redundancy %ld",
          b, r);
}

/* Every constraint of the design, checked from the centres alone. */
static void check_design(tc *t, const mask *m, const mask_gen_opts *o)
{
    int n = mask_nholes(m);
    double rad = 0.5 * o->max_baseline_m, dmin = INFINITY, dmax = 0;
    CHECK(n == o->nholes, "nholes %d", n);
    CHECK(mask_hole_diameter_m(m) == o->hole_diameter_m, "d %g",
          mask_hole_diameter_m(m));
    for (int i = 0; i < n; i++) {
        double xi, yi;
        mask_hole(m, i, &xi, &yi);
        CHECK(hypot(xi, yi) <= rad * (1 + 1e-12), "hole %d at radius %g", i,
              hypot(xi, yi));
        for (int j = i + 1; j < n; j++) {
            double xj, yj;
            mask_hole(m, j, &xj, &yj);
            double dist = hypot(xj - xi, yj - yi);
            dmin = dist < dmin ? dist : dmin;
            dmax = dist > dmax ? dist : dmax;
        }
    }
    CHECK(dmin >= o->min_spacing_m * (1 - 1e-12), "spacing %g", dmin);
    CHECK(dmax <= o->max_baseline_m * (1 + 1e-12), "baseline %g", dmax);
    CHECK_NEAR(mask_min_spacing_m(m), dmin, 1e-12);
    CHECK_NEAR(mask_max_baseline_m(m), dmax, 1e-12);
    CHECK_NEAR(mask_extent_m(m), dmax + o->hole_diameter_m, 1e-12);
}

TEST(generate_constraints)
{
    mask_gen_opts o;
    mask_gen_defaults(&o);
    CHECK(o.nholes == 17 && o.hole_diameter_m == 0.10 &&
              o.max_baseline_m == 1.0 && o.min_spacing_m == 0.20 &&
              o.seed == 17,
          "defaults");
    mask *m;
    sl_err e;
    CHECK(mask_named(&m, "nrm17", &e) == SL_OK, "%s", e.msg);
    CHECK(strcmp(mask_name(m), "nrm17") == 0, "name %s", mask_name(m));
    CHECK(!mask_is_full(m), "holes");
    check_design(t, m, &o);
    mask_free(m);
    if (t->failed)
        return;
    o.iterations = 0; /* the raw random layout obeys them too */
    CHECK(mask_generate(&m, &o, &e) == SL_OK, "%s", e.msg);
    check_design(t, m, &o);
    mask_free(m);
}

static int same_holes(const mask *a, const mask *b)
{
    if (mask_nholes(a) != mask_nholes(b))
        return 0;
    for (int i = 0; i < mask_nholes(a); i++) {
        double xa, ya, xb, yb;
        mask_hole(a, i, &xa, &ya);
        mask_hole(b, i, &xb, &yb);
        if (xa != xb || ya != yb)
            return 0;
    }
    return 1;
}

TEST(generate_deterministic)
{
    mask_gen_opts o;
    mask_gen_defaults(&o);
    mask *a = NULL, *b = NULL, *c = NULL, *named = NULL;
    sl_err e;
    int ok = mask_generate(&a, &o, &e) == SL_OK &&
             mask_generate(&b, &o, &e) == SL_OK &&
             mask_named(&named, "nrm17", &e) == SL_OK;
    o.seed = 18;
    ok = ok && mask_generate(&c, &o, &e) == SL_OK;
    int same = ok && same_holes(a, b) && same_holes(a, named);
    int differ = ok && !same_holes(a, c);
    mask_free(a);
    mask_free(b);
    mask_free(c);
    mask_free(named);
    CHECK(ok, "%s", e.msg);
    CHECK(same, "seed 17 twice (and nrm17) gave different masks");
    CHECK(differ, "seeds 17 and 18 gave the same mask");
}

/* iterations = 0 returns the best of the same random starting layouts the
 * annealer begins from, so annealing can only improve on it. */
TEST(generate_improves)
{
    mask_gen_opts o;
    mask_gen_defaults(&o);
    mask *start, *best;
    sl_err e;
    o.iterations = 0;
    CHECK(mask_generate(&start, &o, &e) == SL_OK, "%s", e.msg);
    long r0 = mask_redundancy(start);
    mask_free(start);
    mask_gen_defaults(&o);
    CHECK(mask_generate(&best, &o, &e) == SL_OK, "%s", e.msg);
    long r = mask_redundancy(best);
    mask_free(best);
    CHECK(r <= r0, "annealed %ld worse than the start %ld", r, r0);
    CHECK(r < r0, "annealing did nothing (%ld)", r);
}

TEST(generate_bad_options)
{
    mask_gen_opts o;
    mask_gen_defaults(&o);
    static char sentinel;
    mask *m = (mask *)&sentinel; /* must be reset to NULL on failure */
    sl_err e;
    o.min_spacing_m = 0.5; /* 17 holes 0.5 m apart in a 1 m disk */
    CHECK(mask_generate(&m, &o, &e) == SL_ERANGE, "impossible layout");
    CHECK(m == NULL && strstr(e.msg, "cannot place"), "%s", e.msg);
    mask_gen_defaults(&o);
    o.min_spacing_m = 0.05; /* below the hole diameter: holes would overlap */
    CHECK(mask_generate(&m, &o, &e) == SL_EINVAL, "spacing < d");
    mask_gen_defaults(&o);
    o.nholes = 1;
    CHECK(mask_generate(&m, &o, &e) == SL_EINVAL, "one hole");
}

TEST(new_holes_errors)
{
    double x[3] = {0, 0.05, 0.4}, y[3] = {0, 0, 0};
    sl_err e;
    CHECK(!mask_new_holes(x, y, 3, 0.1, &e) && e.code == SL_EDATA &&
              strstr(e.msg, "holes 0 and 1"),
          "overlap: %s", e.msg);
    x[1] = 0.1; /* touching is allowed: distance == d */
    mask *m = mask_new_holes(x, y, 3, 0.1, &e);
    CHECK(m, "touching holes: %s", e.msg);
    mask_free(m);
    CHECK(!mask_new_holes(x, y, 1, 0.1, &e) && e.code == SL_EINVAL, "1");
    y[2] = NAN;
    CHECK(!mask_new_holes(x, y, 3, 0.1, &e) && e.code == SL_EDATA, "nan");
    y[2] = 0;
    CHECK(!mask_new_holes(x, y, 3, -0.1, &e) && e.code == SL_EDATA, "d<0");
    CHECK(!mask_new_full(0) && !mask_new_full(NAN), "full with D <= 0");
}

TEST(named)
{
    static char sentinel;
    mask *m = (mask *)&sentinel; /* must be reset to NULL on failure */
    sl_err e;
    CHECK(mask_named(&m, "golay9", &e) == SL_EINVAL && m == NULL, "unknown");
    CHECK(strstr(e.msg, "golay9") && strstr(e.msg, "nrm17") &&
              strstr(e.msg, "full"),
          "message should list the known names: %s", e.msg);
    CHECK(mask_named(&m, "full", &e) == SL_OK, "%s", e.msg);
    int ok = mask_is_full(m) && mask_nholes(m) == 0 &&
             mask_diameter_m(m) == 1.1 && mask_extent_m(m) == 1.1 &&
             mask_redundancy(m) == -1 && strcmp(mask_name(m), "full") == 0;
    mask_free(m);
    mask_free(NULL);
    CHECK(ok, "full aperture accessors");
}

/* ---- files ------------------------------------------------------------- */

typedef struct tmpdir {
    char dir[64];
    char path[128];
} tmpdir;

static int tmp_open(tmpdir *d)
{
    snprintf(d->dir, sizeof d->dir, "/tmp/test_mask.XXXXXX");
    return mkdtemp(d->dir) != NULL;
}

/* Write text to <dir>/name and leave its path in d->path. */
static int tmp_file(tmpdir *d, const char *name, const char *text)
{
    snprintf(d->path, sizeof d->path, "%s/%s", d->dir, name);
    FILE *f = fopen(d->path, "w");
    if (!f)
        return 0;
    int ok = fputs(text, f) >= 0;
    return fclose(f) == 0 && ok;
}

static void tmp_close(tmpdir *d, const char *const *names, int n)
{
    char p[160];
    for (int i = 0; i < n; i++) {
        snprintf(p, sizeof p, "%s/%s", d->dir, names[i]);
        remove(p);
    }
    rmdir(d->dir);
}

TEST(file_round_trip)
{
    mask *m, *back = NULL;
    sl_err e;
    CHECK(mask_named(&m, "nrm17", &e) == SL_OK, "%s", e.msg);
    tmpdir d;
    if (!tmp_open(&d)) {
        mask_free(m);
        CHECK(0, "mkdtemp");
    }
    snprintf(d.path, sizeof d.path, "%s/nrm17.txt", d.dir);
    int wrc = mask_write(m, d.path, &e);
    int rrc = wrc ? wrc : mask_read(&back, d.path, &e);
    int same = back && same_holes(m, back) &&
               mask_hole_diameter_m(back) == mask_hole_diameter_m(m) &&
               mask_redundancy(back) == mask_redundancy(m);
    mask_free(m);
    mask_free(back);
    static const char *const names[] = {"nrm17.txt"};
    tmp_close(&d, names, 1);
    CHECK(wrc == SL_OK && rrc == SL_OK, "%s", e.msg);
    CHECK(same, "holes changed in the round trip");
    mask *full = mask_new_full(1.0);
    CHECK(mask_write(full, "/nonexistent/x", &e) == SL_EINVAL,
          "a filled aperture has no file form");
    mask_free(full);
}

TEST(file_handwritten)
{
    tmpdir d;
    CHECK(tmp_open(&d), "mkdtemp");
    static const char text[] =
        "# a three-hole mask\r\n"
        "\n"
        "   hole_diameter_m   0.08   # metres\r\n"
        "# centres\n"
        "0.25 -0.1\n"
        "\t-0.3e0\t0.125  # west\n"
        "   \n"
        "0 0.4";                               /* no final newline */
    mask *m = NULL;
    sl_err e;
    int rc = tmp_file(&d, "hand.txt", text) ? mask_read(&m, d.path, &e) : -99;
    static const char *const names[] = {"hand.txt"};
    tmp_close(&d, names, 1);
    CHECK(rc == SL_OK, "rc %d: %s", rc, e.msg);
    double x[3], y[3];
    int n = mask_nholes(m);
    for (int i = 0; i < 3 && i < n; i++)
        mask_hole(m, i, &x[i], &y[i]);
    double hd = mask_hole_diameter_m(m);
    mask_free(m);
    CHECK(n == 3, "%d holes", n);
    CHECK(hd == 0.08, "d %g", hd);
    CHECK(x[0] == 0.25 && y[0] == -0.1 && x[1] == -0.3 && y[1] == 0.125 &&
              x[2] == 0 && y[2] == 0.4,
          "centres");
}

TEST(file_errors)
{
    static const struct {
        const char *text;
        int code;
        const char *where, *also; /* must appear in the message */
    } cases[] = {
        {"hole_diameter_m 0.1\n0 0\n0.3 abc\n", SL_EFORMAT, ":3:",
         "expected 'x_m y_m'"},
        {"hole_diameter_m 0.1\n0 0\n0.3 0.1 0.2\n", SL_EFORMAT, ":3:",
         "expected 'x_m y_m'"},
        {"hole_diameter_m 0.1\n0 0\n0.3\n", SL_EFORMAT, ":3:",
         "expected 'x_m y_m'"},
        {"hole_diameter_m\n0 0\n0.3 0\n", SL_EFORMAT, ":1:",
         "expected 'hole_diameter_m <metres>'"},
        {"# no diameter\n0 0\n0.3 0\n", SL_EFORMAT, ":2:",
         "before the required 'hole_diameter_m'"},
        {"# nothing\n\n", SL_EFORMAT, ":2:",
         "without the required 'hole_diameter_m'"},
        {"hole_diameter_m 0.1\n# one\n0 0\n", SL_EFORMAT, ":3:",
         "after 1 hole; a mask needs at least 2"},
        {"hole_diameter_m 0.1\n0 0\nhole_diameter_m 0.2\n", SL_EFORMAT,
         ":3:", "second"},
        {"hole_diameter_m 0.1\n0.5 0.5\n# c\n\n0.55 0.5\n", SL_EDATA,
         ":5:", "overlaps the hole at line 2"},
        {"hole_diameter_m 0.1\n0 0\nnan 0.3\n", SL_EDATA, ":3:",
         "not a finite"},
        {"hole_diameter_m 0.1\n0 0\n0.3 1e999\n", SL_EDATA, ":3:",
         "not a finite"},
        {"# x\nhole_diameter_m inf\n0 0\n0.3 0\n", SL_EDATA, ":2:",
         "not a finite"},
        {"hole_diameter_m -0.1\n0 0\n0.3 0\n", SL_EDATA, ":1:",
         "not a finite number > 0"},
    };
    static const char *const names[] = {"bad.txt"};
    tmpdir d;
    CHECK(tmp_open(&d), "mkdtemp");
    int ncase = (int)(sizeof cases / sizeof cases[0]), bad = -1, rc = 0;
    sl_err e = {0};
    for (int i = 0; i < ncase && bad < 0; i++) {
        mask *m = (mask *)&d; /* must be reset to NULL */
        rc = tmp_file(&d, "bad.txt", cases[i].text) ? mask_read(&m, d.path, &e)
                                                    : -99;
        if (rc != cases[i].code || m != NULL ||
            !strstr(e.msg, cases[i].where) || !strstr(e.msg, d.path) ||
            !strstr(e.msg, cases[i].also))
            bad = i;
        if (rc == SL_OK)
            mask_free(m);
    }
    tmp_close(&d, names, 1);
    CHECK(bad < 0,
          "case %d: rc %d (want %d), message '%s' should name the file, "
          "'%s' and '%s'",
          bad, rc, bad >= 0 ? cases[bad].code : 0, e.msg,
          bad >= 0 ? cases[bad].where : "", bad >= 0 ? cases[bad].also : "");
    mask *m;
    CHECK(mask_read(&m, "/nonexistent/mask.txt", &e) == SL_EIO &&
              strstr(e.msg, "/nonexistent/mask.txt"),
          "missing file: %s", e.msg);
}

/* ---- rendering --------------------------------------------------------- */

static double pupil_sum(const float *p, int n)
{
    double s = 0;
    for (int i = 0; i < n * n; i++)
        s += p[i];
    return s;
}

TEST(render_area)
{
    enum { N = 256 };
    const double dx = 0.005; /* 1.28 m grid, holes 20 px across */
    mask *m, *full;
    sl_err e;
    CHECK(mask_named(&m, "nrm17", &e) == SL_OK, "%s", e.msg);
    float *p = malloc(N * N * sizeof *p);
    int rc = p ? mask_render(m, p, N, dx, &e) : -99;
    double area = rc ? 0 : pupil_sum(p, N) * dx * dx;
    double want = mask_nholes(m) * M_PI * 0.05 * 0.05;
    double hx, hy;
    mask_hole(m, 0, &hx, &hy);
    float centre = 0, lo = 1, hi = 0;
    if (rc == SL_OK) {
        centre = p[(N / 2 + (int)lround(hy / dx)) * N + N / 2 +
                   (int)lround(hx / dx)];
        for (int i = 0; i < N * N; i++) {
            lo = p[i] < lo ? p[i] : lo;
            hi = p[i] > hi ? p[i] : hi;
        }
    }
    mask_free(m);
    full = mask_new_full(1.1);
    int rcf = rc ? rc : mask_render(full, p, N, dx, &e);
    double afull = rcf ? 0 : pupil_sum(p, N) * dx * dx;
    mask_free(full);
    free(p);
    CHECK(rc == SL_OK && rcf == SL_OK, "%s", e.msg);
    CHECK(fabs(area / want - 1) < 0.01, "holes: area %g, want %g", area,
          want);
    CHECK(fabs(afull / (M_PI * 1.1 * 1.1 / 4) - 1) < 0.01, "full: %g", afull);
    CHECK(centre == 1.0f && lo == 0.0f && hi == 1.0f,
          "hole centre %g, range [%g, %g]", centre, lo, hi);
}

/* Edge pixels carry their covered fraction: compare every pixel with a
 * 64x64-sample count made here; a binary or half-valued edge fails. */
TEST(render_coverage)
{
    enum { N = 64, S = 64 };
    const double dx = 0.01, d = 0.1; /* holes 10 px across */
    static const double xy[] = {0.1234, -0.0711, -0.1502, 0.1377};
    float p[N * N];
    mask *m = holes(xy, 2, d);
    sl_err e;
    int rc = m ? mask_render(m, p, N, dx, &e) : -99;
    mask_free(m);
    CHECK(rc == SL_OK, "%s", e.msg);
    double worst = 0;
    int partial = 0;
    for (int y = 0; y < N; y++)
        for (int x = 0; x < N; x++) {
            int hits = 0;
            for (int h = 0; h < 2; h++)
                for (int sy = 0; sy < S; sy++)
                    for (int sx = 0; sx < S; sx++) {
                        double u = (x - N / 2 + (sx + 0.5) / S - 0.5) * dx;
                        double v = (y - N / 2 + (sy + 0.5) / S - 0.5) * dx;
                        hits += hypot(u - xy[2 * h], v - xy[2 * h + 1]) <
                                d / 2;
                    }
            double ref = (double)hits / (S * S), got = p[y * N + x];
            worst = fabs(got - ref) > worst ? fabs(got - ref) : worst;
            partial += got > 0 && got < 1;
        }
    CHECK(partial > 40, "only %d fractional edge pixels", partial);
    CHECK(worst < 0.06, "edge coverage off by %g", worst);
}

/* Mirror-symmetric holes render bit-exactly mirrored about column n/2; the
 * render's centroid sits at (n/2, n/2) + mean centre / dx (the documented
 * orientation: +x_m is +column, +y_m is +row). */
TEST(render_symmetry)
{
    enum { N = 128 };
    const double dx = 1.0 / 100;
    static const double sym[] = {0.3,  0.1,   -0.3, 0.1,  0,     -0.25,
                                 0.13, 0.4,   -0.13, 0.4, 0.21, -0.37,
                                 -0.21, -0.37};
    float *p = malloc(N * N * sizeof *p);
    CHECK(p, "malloc");
    mask *m = holes(sym, 7, 0.09);
    sl_err e;
    int rc = m ? mask_render(m, p, N, dx, &e) : -99;
    int asym = 0;
    double sx = 0, sy = 0, s = 0, mx = 0, my = 0;
    for (int y = 0; y < N; y++)
        for (int x = 0; x < N; x++) {
            double v = p[y * N + x];
            if (x > 0 && v != p[y * N + (N - x)])
                asym++;
            sx += v * x;
            sy += v * y;
            s += v;
        }
    for (int i = 0; i < 7; i++) {
        mx += sym[2 * i] / 7;
        my += sym[2 * i + 1] / 7;
    }
    mask_free(m);
    free(p);
    CHECK(rc == SL_OK, "%s", e.msg);
    CHECK(asym == 0, "%d pixels differ from their mirror", asym);
    CHECK_NEAR(sx / s, N / 2 + mx / dx, 0.02);
    CHECK_NEAR(sy / s, N / 2 + my / dx, 0.02);
}

TEST(render_too_large)
{
    enum { N = 128 };
    const double dx = 1.0 / 128; /* exact: (n-1)*dx / dx == n-1 */
    float *p = malloc(N * N * sizeof *p);
    CHECK(p, "malloc");
    mask *nrm, *edge, *over;
    sl_err e, e1 = {0}, e2 = {0};
    CHECK(mask_named(&nrm, "nrm17", &e) == SL_OK, "%s", e.msg);
    int r1 = mask_render(nrm, p, N, 0.005, &e1); /* 0.64 m < 1.1 m */
    /* a centred disk fits when its radius reaches pixel centre n/2 - 1's
     * far edge, i.e. D = (n - 1) dx, and no further */
    edge = mask_new_full((N - 1) * dx);
    over = mask_new_full((N - 1) * dx * (1 + 1e-9));
    int r2 = mask_render(edge, p, N, dx, &e);
    int r3 = mask_render(over, p, N, dx, &e2);
    /* an off-centre pair whose extent (0.4 m) is under n*dx (1 m) but
     * which sits past the grid's edge */
    static const double off[][4] = {{0.2, 0, 0.5, 0}, {-0.2, 0, -0.5, 0},
                                     {0, 0.2, 0, 0.5}, {0, -0.2, 0, -0.5}};
    int r4 = SL_ERANGE;
    for (int i = 0; i < 4; i++) {
        mask *side = holes(off[i], 2, 0.1);
        int r = side ? mask_render(side, p, N, dx, &e) : -99;
        r4 = r != SL_ERANGE ? r : r4;
        mask_free(side);
    }
    mask_free(nrm);
    mask_free(edge);
    mask_free(over);
    free(p);
    CHECK(r1 == SL_ERANGE && strstr(e1.msg, "does not fit"), "%s", e1.msg);
    CHECK(r2 == SL_OK, "edge case should fit");
    CHECK(r3 == SL_ERANGE, "just over: %s", e2.msg);
    CHECK(r4 == SL_ERANGE, "off-centre pupil past an edge: %d", r4);
}

TC_MAIN(TC_CASE(redundancy_collinear), TC_CASE(redundancy_parallelogram),
        TC_CASE(redundancy_nrm17_brute), TC_CASE(generate_constraints),
        TC_CASE(generate_deterministic), TC_CASE(generate_improves),
        TC_CASE(generate_bad_options), TC_CASE(new_holes_errors),
        TC_CASE(named), TC_CASE(file_round_trip), TC_CASE(file_handwritten),
        TC_CASE(file_errors), TC_CASE(render_area), TC_CASE(render_coverage),
        TC_CASE(render_symmetry),
        TC_CASE(render_too_large))
