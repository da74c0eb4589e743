/* test_oifits_cli.c - `specklab oifits` end to end: a simulated nrm17
 * binary (specklab sim, in-process) exported, read back with cfitsio (the
 * tables, their units, finite values, V2 <= ~1, errors > 0), and a binary
 * fitted here to the exported T3PHI at the exported uv, OIFITS's way
 * (east = U, V(u) = 1 + r exp(-2 pi i u.alpha)), against the truth and
 * against the project's own closure-phase fit of the same cube
 * (pipeline_run, direct, closure_binary); a point source's closure
 * phases are 0 within their errors; the options' errors name what is
 * missing; the input and an existing output are never written over. */
#include <fitsio.h>
#include <stdlib.h>
#include <sys/stat.h>

#include "cmdrun_fx.h"
#include "io/cube.h"
#include "pipeline/pipeline.h"

#define RAD_ARCSEC (180.0 * 3600.0 / M_PI)
#define MAX_T3 1000

typedef struct t3set {
    int n;
    double lambda_m;
    double u1[MAX_T3], v1[MAX_T3], u2[MAX_T3], v2[MAX_T3], phi[MAX_T3], err[MAX_T3];
} t3set;

/* OI_T3's closure phases (rad) and uv (m), OI_WAVELENGTH's EFF_WAVE;
 * cfitsio's status. */
static int read_t3(const char *path, t3set *t)
{
    fitsfile *fp = NULL;
    int st = 0;
    long n = 0;
    double *cols[] = {t->phi, t->err, t->u1, t->v1, t->u2, t->v2};
    const char *names[] = {"T3PHI", "T3PHIERR", "U1COORD", "V1COORD", "U2COORD", "V2COORD"};
    if (fits_open_diskfile(&fp, path, READONLY, &st))
        return st;
    fits_movnam_hdu(fp, BINARY_TBL, "OI_WAVELENGTH", 0, &st);
    fits_read_col(fp, TDOUBLE, 1, 1, 1, 1, NULL, &t->lambda_m, NULL, &st);
    fits_movnam_hdu(fp, BINARY_TBL, "OI_T3", 0, &st);
    fits_get_num_rows(fp, &n, &st);
    t->n = n < MAX_T3 ? (int)n : MAX_T3;
    for (int k = 0; k < 6 && !st; k++) {
        int c = 0;
        fits_get_colnum(fp, CASEINSEN, (char *)names[k], &c, &st);
        fits_read_col(fp, TDOUBLE, c, 1, 1, t->n, NULL, cols[k], NULL, &st);
    }
    for (int i = 0; i < t->n; i++)
        t->phi[i] *= M_PI / 180, t->err[i] *= M_PI / 180;
    fits_close_file(fp, &st);
    return st;
}

/* chi^2 of the binary (east, north offset a [rad], flux ratio r) against
 * the closure phases: arg V(u1) + arg V(u2) - arg V(u1 + u2). */
static double chi2(const t3set *t, const double p[3])
{
    double s = 0;
    for (int i = 0; i < t->n; i++) {
        double u[3] = {t->u1[i], t->u2[i], t->u1[i] + t->u2[i]};
        double v[3] = {t->v1[i], t->v2[i], t->v1[i] + t->v2[i]}, m = 0;
        for (int k = 0; k < 3; k++) {
            double ph = -2 * M_PI * (u[k] * p[0] + v[k] * p[1]) / t->lambda_m;
            double a = atan2(p[2] * sin(ph), 1 + p[2] * cos(ph));
            m += k < 2 ? a : -a;
        }
        double e = remainder(t->phi[i] - m, 2 * M_PI) / t->err[i];
        s += e * e;
    }
    return s;
}

/* The binary by a grid over offsets within half_rad (step step_rad) and
 * four flux ratios, then pattern search down to 1e-4 of the step: p =
 * (east, north, r); the chi^2 back. */
static double fit_binary(const t3set *t, double half_rad, double step_rad, double p[3])
{
    double best = INFINITY, rs[] = {0.1, 0.25, 0.5, 0.8};
    for (double a = -half_rad; a <= half_rad; a += step_rad)
        for (double b = -half_rad; b <= half_rad; b += step_rad)
            for (int k = 0; k < 4; k++) {
                double q[3] = {a, b, rs[k]}, c = chi2(t, q);
                if (c < best)
                    best = c, memcpy(p, q, sizeof q);
            }
    double d[3] = {step_rad / 2, step_rad / 2, 0.05};
    while (d[0] > 1e-4 * step_rad) {
        int better = 0;
        for (int k = 0; k < 3; k++)
            for (int s = -1; s <= 1; s += 2) {
                double q[3] = {p[0], p[1], p[2]};
                q[k] += s * d[k];
                q[2] = fmin(fmax(q[2], 1e-3), 0.999);
                double c = chi2(t, q);
                if (c < best)
                    best = c, memcpy(p, q, sizeof q), better = 1;
            }
        if (!better)
            for (int k = 0; k < 3; k++)
                d[k] /= 2;
    }
    return best;
}

/* Sep [arcsec] and PA [deg] errors of the fit from the chi^2's curvature
 * in the offsets (numerical Hessian), scaled by chi^2/dof when above 1. */
static void fit_errors(const t3set *t, const double p[3], double c2, double *sep_err,
                       double *pa_err)
{
    double h = 2e-9, H[2][2];
    for (int i = 0; i < 2; i++)
        for (int j = 0; j < 2; j++) {
            double q[4][3];
            for (int k = 0; k < 4; k++)
                memcpy(q[k], p, sizeof q[k]);
            q[0][i] += h, q[0][j] += h;
            q[1][i] += h, q[1][j] -= h;
            q[2][i] -= h, q[2][j] += h;
            q[3][i] -= h, q[3][j] -= h;
            H[i][j] = (chi2(t, q[0]) - chi2(t, q[1]) - chi2(t, q[2]) + chi2(t, q[3])) /
                      (4 * h * h) / 2;
        }
    double det = H[0][0] * H[1][1] - H[0][1] * H[1][0], s2 = fmax(c2 / (t->n - 3), 1);
    double C[2][2] = {{H[1][1] / det * s2, -H[0][1] / det * s2},
                      {-H[1][0] / det * s2, H[0][0] / det * s2}};
    double sep = hypot(p[0], p[1]);
    double gs[2] = {p[0] / sep, p[1] / sep}, gp[2] = {p[1] / (sep * sep), -p[0] / (sep * sep)};
    double vs = 0, vp = 0;
    for (int i = 0; i < 2; i++)
        for (int j = 0; j < 2; j++)
            vs += gs[i] * C[i][j] * gs[j], vp += gp[i] * C[i][j] * gp[j];
    *sep_err = sqrt(fmax(vs, 0)) * RAD_ARCSEC;
    *pa_err = sqrt(fmax(vp, 0)) * 180 / M_PI;
}

/* OI_VIS2: rows, the largest V2, the smallest error, all finite; and the
 * units of UCOORD and T3PHI. */
static int read_vis2(const char *path, int *n, double *vmax, double *emin, int *finite,
                     char *ucoord_unit, char *t3phi_unit)
{
    fitsfile *fp = NULL;
    int st = 0, c = 0;
    long nr = 0;
    if (fits_open_diskfile(&fp, path, READONLY, &st))
        return st;
    fits_movnam_hdu(fp, BINARY_TBL, "OI_VIS2", 0, &st);
    fits_get_num_rows(fp, &nr, &st);
    double *v = calloc((size_t)nr + 1, sizeof *v), *e = calloc((size_t)nr + 1, sizeof *e);
    fits_read_col(fp, TDOUBLE, 5, 1, 1, nr, NULL, v, NULL, &st);
    fits_read_col(fp, TDOUBLE, 6, 1, 1, nr, NULL, e, NULL, &st);
    fits_get_colnum(fp, CASEINSEN, "UCOORD", &c, &st);
    char key[16];
    snprintf(key, sizeof key, "TUNIT%d", c);
    fits_read_key_str(fp, key, ucoord_unit, NULL, &st);
    fits_movnam_hdu(fp, BINARY_TBL, "OI_T3", 0, &st);
    fits_get_colnum(fp, CASEINSEN, "T3PHI", &c, &st);
    snprintf(key, sizeof key, "TUNIT%d", c);
    fits_read_key_str(fp, key, t3phi_unit, NULL, &st);
    *n = (int)nr, *vmax = -INFINITY, *emin = INFINITY, *finite = 1;
    for (long i = 0; i < nr; i++) {
        *vmax = fmax(*vmax, v[i]);
        *emin = fmin(*emin, e[i]);
        *finite &= isfinite(v[i]) && isfinite(e[i]);
    }
    free(v);
    free(e);
    fits_close_file(fp, &st);
    return st;
}

/* The project's closure-phase fit of the cube (what `specklab binary
 * CUBE` reports): direct, closure_binary. */
static int closure_fit(const char *cube, binary_result *b, sl_err *e)
{
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.method = PIPE_DIRECT;
    o.closure_binary = 1;
    o.fftw_measure = 0;
    pipeline_result r;
    int rc = pipeline_run(&cube, 1, &o, &r, e);
    if (rc != SL_OK)
        return rc;
    rc = r.binary.have_closure ? SL_OK : SL_EDATA;
    *b = r.binary.closure;
    pipeline_result_clear(&r);
    return rc;
}

TEST(binary_closure_phases_agree_with_the_closure_fit)
{
    fx f;
    CHECK(fx_start(&f) == 0, "mkdtemp");
    char *cube = path_in(&f, "bin.fits"), *oi = path_in(&f, "bin.oifits");
    int rs = run(&f, cmd_sim, "sim", "--scene", "binary", "--sep-arcsec", "0.2", "--pa-deg",
                 "30", "--size", "128", "--frames", "100", "--photons", "1e5", "-q", "-o",
                 cube, NULL);
    int ro = rs ? -1 : run(&f, cmd_oifits, "oifits", cube, "-o", oi, NULL);
    char msg[4096];
    snprintf(msg, sizeof msg, "%.2047s%.2047s", f.out, f.err);
    int nv = 0, finite = 0, st = -1, st3 = -1;
    double vmax = 0, emin = 0;
    char uu[FLEN_VALUE] = "", pu[FLEN_VALUE] = "";
    static t3set ts;
    if (ro == 0) {
        st = read_vis2(oi, &nv, &vmax, &emin, &finite, uu, pu);
        st3 = read_t3(oi, &ts);
    }
    cube_meta m;
    cube_meta_init(&m);
    cube_reader *cr = NULL;
    sl_err e = {0};
    if (cube_reader_open(&cr, (const char **)&cube, 1, 0, &e) == SL_OK)
        m = *cube_reader_meta(cr);
    cube_reader_free(cr);
    binary_result cf = {0};
    int rcf = ro == 0 ? closure_fit(cube, &cf, &e) : -1;
    g_free(cube);
    g_free(oi);
    fx_stop(&f);
    CHECK(rs == 0 && ro == 0, "sim %d, oifits %d: %s", rs, ro, msg);
    CHECK(st == 0 && st3 == 0, "reading the OIFITS: cfitsio %d %d", st, st3);
    CHECK(!strcmp(uu, "m") && !strcmp(pu, "deg"), "units UCOORD '%s', T3PHI '%s'", uu, pu);
    CHECK(nv >= 40 && ts.n >= 30 && finite, "%d V2 (finite %d), %d closure phases", nv,
          finite, ts.n);
    CHECK(vmax <= 1.2 && emin > 0, "V2 up to %.3f, errors from %.3g", vmax, emin);
    CHECK(rcf == SL_OK, "closure fit: %s", e.msg);
    double ps = m.plate_scale_arcsec, p[3];
    double c2 = fit_binary(&ts, 12 * ps / RAD_ARCSEC, 0.25 * ps / RAD_ARCSEC, p);
    double sep = hypot(p[0], p[1]) * RAD_ARCSEC, pa = atan2(p[0], p[1]) * 180 / M_PI;
    pa += pa < 0 ? 360 : 0;
    double sep_err, pa_err;
    fit_errors(&ts, p, c2, &sep_err, &pa_err);
    printf("  OIFITS T3PHI fit: sep %.4f +- %.4f\" PA %.2f +- %.2f deg dm %.3f (chi2/n "
           "%.2f, %d triangles); closure.c: sep %.4f\" PA %.2f deg dm %.3f; truth 0.2\" "
           "30 deg 1\n", sep, sep_err, pa, pa_err, -2.5 * log10(p[2]), c2 / ts.n, ts.n,
           cf.sep_px * ps, cf.pa_deg, cf.dm_mag);
    CHECK(fabs(sep - 0.2) < 3 * sep_err + 0.002 && fabs(pa - 30) < 3 * pa_err + 0.2,
          "truth 0.2\" 30 deg: %.4f +- %.4f, %.2f +- %.2f", sep, sep_err, pa, pa_err);
    CHECK(fabs(sep / ps - cf.sep_px) < 0.2 && fabs(remainder(pa - cf.pa_deg, 360)) < 1,
          "closure.c's %.3f px %.2f deg against %.3f px %.2f deg", cf.sep_px, cf.pa_deg,
          sep / ps, pa);
}

TEST(point_source_closes)
{
    fx f;
    CHECK(fx_start(&f) == 0, "mkdtemp");
    char *cube = path_in(&f, "pt.fits"), *oi = path_in(&f, "pt.oifits");
    int rs = run(&f, cmd_sim, "sim", "--scene", "point", "--size", "128", "--frames", "100",
                 "--photons", "1e5", "--seed", "3", "-q", "-o", cube, NULL);
    int ro = rs ? -1 : run(&f, cmd_oifits, "oifits", cube, "-o", oi, "--json", NULL);
    static t3set ts;
    int st = ro ? -1 : read_t3(oi, &ts);
    char out[4096];
    snprintf(out, sizeof out, "%.2047s%.2047s", f.out, f.err);
    g_free(cube);
    g_free(oi);
    fx_stop(&f);
    CHECK(rs == 0 && ro == 0 && st == 0, "sim %d oifits %d read %d: %s", rs, ro, st, out);
    CHECK(strstr(out, "\"t3\":") && strstr(out, "\"vis2_not_measured\":"), "JSON: %s", out);
    double c2 = 0, mean = 0;
    for (int i = 0; i < ts.n; i++) {
        c2 += (ts.phi[i] / ts.err[i]) * (ts.phi[i] / ts.err[i]);
        mean += ts.phi[i] / ts.n;
    }
    printf("  point source: %d closure phases, chi2/n %.2f, mean %.3f deg\n", ts.n, c2 / ts.n,
           mean * 180 / M_PI);
    CHECK(ts.n >= 30 && c2 / ts.n < 3, "chi2/n %.2f over %d", c2 / ts.n, ts.n);
}

TEST(options_and_files)
{
    fx f;
    CHECK(fx_start(&f) == 0, "mkdtemp");
    char *cube = path_in(&f, "c.fits"), *blind = path_in(&f, "blind.fits");
    char *oi = path_in(&f, "c.oifits");
    int rs = run(&f, cmd_sim, "sim", "--size", "64", "--frames", "4", "-q", "-o", cube, NULL);
    int rb = run(&f, cmd_sim, "sim", "--size", "64", "--frames", "4", "--blind", "-q", "-o",
                 blind, NULL);
    char e1[512], e2[512], e3[512], e4[512], e5[512];
    int r1 = run(&f, cmd_oifits, "oifits", blind, "-o", oi, NULL);
    snprintf(e1, sizeof e1, "%.511s", f.err);
    int r2 = run(&f, cmd_oifits, "oifits", blind, "--mask", "nrm17", "-o", oi, NULL);
    snprintf(e2, sizeof e2, "%.511s", f.err);
    int r3 = run(&f, cmd_oifits, "oifits", cube, "-o", cube, "--overwrite", NULL);
    snprintf(e3, sizeof e3, "%.511s", f.err);
    int r4 = run(&f, cmd_oifits, "oifits", cube, "--mask", "full", "-o", oi, NULL);
    snprintf(e4, sizeof e4, "%.511s", f.err);
    int r5 = run(&f, cmd_oifits, "oifits", cube, "-o", oi, "-q", NULL);
    struct stat s1 = {0}, s2 = {0};
    stat(oi, &s1);
    int r6 = run(&f, cmd_oifits, "oifits", cube, "-o", oi, NULL);
    snprintf(e5, sizeof e5, "%.511s", f.err);
    int r7 = run(&f, cmd_oifits, "oifits", cube, "-o", oi, "--overwrite", "--target", "HD 1",
                 "-q", NULL);
    stat(oi, &s2);
    struct stat sc = {0};
    stat(cube, &sc);
    g_free(cube);
    g_free(blind);
    g_free(oi);
    fx_stop(&f);
    CHECK(rs == 0 && rb == 0, "sim");
    CHECK(r1 == 1 && strstr(e1, "no mask: give --mask"), "blind, no mask: %d %s", r1, e1);
    CHECK(r2 == 1 && strstr(e2, "wavelength (WAVELEN), plate scale (PLTSCALE)") &&
          strstr(e2, "give --wavelength-nm, --plate-scale-arcsec"), "blind with a mask: %d %s",
          r2, e2);
    CHECK(r3 == 1 && strstr(e3, "is the input") && sc.st_size > 64 * 64 * 4 * 4,
          "output = input: %d %s (%lld bytes)", r3, e3, (long long)sc.st_size);
    CHECK(r4 == 1 && strstr(e4, "filled aperture"), "--mask full: %d %s", r4, e4);
    CHECK(r5 == 0 && s1.st_size > 0, "export: %d", r5);
    CHECK(r6 == 1 && strstr(e5, "--overwrite"), "existing output: %d %s", r6, e5);
    CHECK(r7 == 0 && s2.st_ino != s1.st_ino, "--overwrite: %d", r7);
}

TC_MAIN(TC_CASE(binary_closure_phases_agree_with_the_closure_fit),
        TC_CASE(point_source_closes), TC_CASE(options_and_files))
