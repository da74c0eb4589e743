/* test_sim_cli.c - `specklab sim` files as written: the --blind cube and
 * its truth sidecar, the BITPIX the detector asks for, headers that gain
 * keywords only for features in use, and the option errors.  cmd_sim runs
 * in-process (cmdrun_fx.h: stdout and stderr in files of the test's
 * directory); files are read back with cube.h (and cfitsio for the
 * BITPIX). */
#include <fitsio.h>
#include <stdlib.h>

#include "cmdrun_fx.h"
#include "io/cube.h"

/* Run `specklab sim ARGS... NULL` (cmdrun_fx.h); its exit status,
 * stderr in f->err. */
#define sim(f, ...) run((f), cmd_sim, "sim", __VA_ARGS__)

/* The equivalent BITPIX cfitsio sees (BYTE_IMG, USHORT_IMG, FLOAT_IMG). */
static int equiv_bitpix(const char *path)
{
    fitsfile *fp = NULL;
    int st = 0, type = 0;
    if (fits_open_diskfile(&fp, path, READONLY, &st) == 0)
        fits_get_img_equivtype(fp, &type, &st);
    if (fp) {
        int st2 = 0;
        fits_close_file(fp, &st2);
    }
    return st ? -1 : type;
}

/* Open path; its meta copied into *m and frame count; min/max of all
 * pixels.  SL_OK or the reader's error. */
static int read_cube(const char *path, cube_meta *m, int *n, float *lo, float *hi)
{
    cube_reader *r = NULL;
    sl_err e;
    int rc = cube_reader_open(&r, &path, 1, 0, &e);
    if (rc != SL_OK)
        return rc;
    *m = *cube_reader_meta(r);
    *n = cube_reader_nframes(r);
    size_t np = (size_t)cube_reader_width(r) * cube_reader_height(r);
    float *f = malloc(np * sizeof *f);
    *lo = INFINITY, *hi = -INFINITY;
    while (f && (rc = cube_reader_next(r, f)) == SL_OK)
        for (size_t i = 0; i < np; i++) {
            *lo = fminf(*lo, f[i]);
            *hi = fmaxf(*hi, f[i]);
        }
    free(f);
    cube_reader_free(r);
    return rc == SL_EEND ? SL_OK : rc;
}

static int has(const cube_meta *m, const char *key)
{
    double v;
    const char *s;
    return cube_meta_get_num(m, key, &v) == SL_OK || cube_meta_get_str(m, key, &s) == SL_OK;
}

/* A --blind cube says only what a camera says; the sidecar holds every
 * simulation keyword, the truth and the cophased image. */
TEST(blind_cube_and_its_sidecar)
{
    fx f;
    CHECK(fx_start(&f) == 0, "mkdtemp");
    char *cube = path_in(&f, "night1.fits"), *side = path_in(&f, "night1-truth.fits");
    int rc = sim(&f, "--size", "32", "--frames", "3", "--photons", "2e4", "--adc-bits", "12",
                 "--hot-pixels", "2", "--offset-px", "1.5,-0.5", "--object", "HD 1234",
                 "--blind", "-q", "-o", cube, NULL);
    cube_meta m, sm;
    int n = 0, nt = 0;
    float lo, hi, tlo, thi;
    int rr = rc ? -1 : read_cube(cube, &m, &n, &lo, &hi);
    int rs = rc ? -1 : read_cube(side, &sm, &nt, &tlo, &thi);
    int bp = equiv_bitpix(cube);
    seq *ext = NULL;
    sl_err e;
    int no_truth_in_cube = cube_read_ext(&ext, cube, "TRUTH", &e) != SL_OK;
    seq_free(ext);
    ext = NULL;
    int truth_ok = cube_read_ext(&ext, side, "TRUTH", &e) == SL_OK;
    seq_free(ext);
    ext = NULL;
    int cop_ok = cube_read_ext(&ext, side, "COPHASED", &e) == SL_OK;
    seq_free(ext);
    CHECK(rc == 0 && rr == SL_OK && rs == SL_OK, "exit %d, read %d %d: %s", rc, rr, rs, f.err);
    CHECK(n == 3 && bp == USHORT_IMG && lo >= 0 && hi == 4095, "cube: %d frames, type %d, "
          "range [%g, %g]", n, bp, lo, hi);
    CHECK(m.nextra == 0, "the blind cube has %d extra keywords, first %s", m.nextra,
          m.nextra ? m.extra[0].key : "");
    CHECK(!strcmp(m.object, "HD 1234") && m.instrume[0] && !strstr(m.instrume, "sim") &&
          m.date_obs[0] && isfinite(m.exptime_s) && isnan(m.plate_scale_arcsec) &&
          isnan(m.wavelength_m) && !strcmp(m.bunit, "adu"), "camera keywords: OBJECT '%s' "
          "INSTRUME '%s' PLTSCALE %g WAVELEN %g BUNIT '%s'", m.object, m.instrume,
          m.plate_scale_arcsec, m.wavelength_m, m.bunit);
    CHECK(no_truth_in_cube && truth_ok && cop_ok, "extensions: cube TRUTH %s, sidecar TRUTH "
          "%d COPHASED %d", no_truth_in_cube ? "absent" : "present", truth_ok, cop_ok);
    static const char *keys[] = {"SIMSCENE", "SIMMASK", "SIMSEED", "SIMPHOT", "SIMGAIN",
                                 "MASKEXT", "NYQUIST", "BINSEP", "BINPA", "SIMADC",
                                 "SIMNHOT", "SIMNDEAD", "SIMOFFX", "SIMOFFY", "SIMJITT",
                                 "SIMASPCT", "SIMPHMOD"};
    for (size_t i = 0; i < sizeof keys / sizeof keys[0]; i++)
        CHECK(has(&sm, keys[i]), "sidecar lacks %s", keys[i]);
    double adc = 0, offx = 0;
    cube_meta_get_num(&sm, "SIMADC", &adc);
    cube_meta_get_num(&sm, "SIMOFFX", &offx);
    CHECK(adc == 12 && offx == 1.5 && isfinite(sm.plate_scale_arcsec) &&
          isfinite(sm.wavelength_m) && nt == 1 && thi > 0, "sidecar: SIMADC %g SIMOFFX %g "
          "PLTSCALE %g, %d frame(s) peaking at %g", adc, offx, sm.plate_scale_arcsec, nt, thi);
    g_free(cube);
    g_free(side);
    /* --truth-out names the sidecar */
    cube = path_in(&f, "raw.fit");
    side = path_in(&f, "answers.fits");
    rc = sim(&f, "--size", "32", "--frames", "2", "--blind", "--truth-out", side, "-q", "-o",
             cube, NULL);
    rs = rc ? -1 : read_cube(side, &sm, &nt, &tlo, &thi);
    g_free(cube);
    g_free(side);
    fx_stop(&f);
    CHECK(rc == 0 && rs == SL_OK && has(&sm, "SIMSCENE"), "--truth-out: exit %d, read %d: %s",
          rc, rs, f.err);
}

/* Without --blind the new keywords appear only for features in use, and
 * the cube's type follows the converter. */
TEST(headers_and_bitpix_follow_the_features)
{
    fx f;
    CHECK(fx_start(&f) == 0, "mkdtemp");
    char *a = path_in(&f, "a.fits"), *b = path_in(&f, "b.fits"), *c = path_in(&f, "c.fits");
    int ra = sim(&f, "--size", "32", "--frames", "2", "-q", "-o", a, NULL);
    int rb = ra ? ra : sim(&f, "--size", "32", "--frames", "2", "--photons", "5000",
                           "--adc-bits", "8", "--jitter-px", "0.3", "-q", "-o", b, NULL);
    int rc = rb ? rb : sim(&f, "--size", "32", "--frames", "2", "--photons", "5000",
                           "--pixel-aspect", "1.25", "--mask", "full", "--aperture-m",
                           "0.35", "--obstruction", "0.3", "--plate-scale-arcsec", "0.2", "-q",
                           "-o", c, NULL);
    cube_meta ma, mb, mc;
    int n;
    float lo, hi, clo, chi;
    int ok = !ra && !rb && !rc && read_cube(a, &ma, &n, &lo, &hi) == SL_OK &&
             read_cube(b, &mb, &n, &lo, &hi) == SL_OK &&
             read_cube(c, &mc, &n, &clo, &chi) == SL_OK;
    int ta = equiv_bitpix(a), tb = equiv_bitpix(b), tcube = equiv_bitpix(c);
    g_free(a);
    g_free(b);
    g_free(c);
    fx_stop(&f);
    CHECK(ok, "exits %d %d %d: %s", ra, rb, rc, f.err);
    static const char *fresh[] = {"SIMADC", "SIMNHOT", "SIMNDEAD", "SIMOFFX", "SIMJITT",
                                  "SIMASPCT", "SIMPHMOD", "MASKOBS"};
    for (size_t i = 0; i < sizeof fresh / sizeof fresh[0]; i++)
        CHECK(!has(&ma, fresh[i]), "default header has %s", fresh[i]);
    CHECK(has(&ma, "SIMSCENE") && ta == FLOAT_IMG, "default: SIMSCENE, type %d", ta);
    CHECK(has(&mb, "SIMADC") && has(&mb, "SIMJITT") && !has(&mb, "SIMOFFX") &&
          !has(&mb, "SIMASPCT") && tb == BYTE_IMG && hi <= 255, "8-bit: type %d, max %g",
          tb, hi);
    CHECK(has(&mc, "SIMASPCT") && has(&mc, "MASKOBS") && !has(&mc, "SIMADC") &&
          tcube == FLOAT_IMG && chi > 0, "telescope: type %d, max %g", tcube, chi);
}

TEST(option_errors_are_named)
{
    fx f;
    CHECK(fx_start(&f) == 0, "mkdtemp");
    char *o = path_in(&f, "x.fits");
    static const char *const cases[][4] = {
        {"--aperture-m", "0.35", "aperture", NULL},
        {"--phase-model", "tilt", "phase-model", NULL},
        {"--offset-px", "3", "offset-px", NULL},
        {"--truth-out", "t.fits", "blind", NULL},
        {"--pixel-aspect", "3", "pixel aspect", NULL},
        {"--hot-pixels", "3", "photons", NULL},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        int rc = sim(&f, "--size", "16", "--frames", "1", cases[i][0], cases[i][1], "-q",
                     "-o", o, NULL);
        CHECK(rc != 0 && strstr(f.err, cases[i][2]), "%s %s: exit %d, '%s'", cases[i][0],
              cases[i][1], rc, f.err);
    }
    int rc = sim(&f, "--size", "16", "--frames", "1", "--mask", "full", "--phase-model",
                 "piston", "-q", "-o", o, NULL);
    g_free(o);
    fx_stop(&f);
    CHECK(rc != 0 && strstr(f.err, "piston") && strstr(f.err, "filled"), "exit %d, '%s'", rc,
          f.err);
}

TC_MAIN(TC_CASE(blind_cube_and_its_sidecar), TC_CASE(headers_and_bitpix_follow_the_features),
        TC_CASE(option_errors_are_named))
