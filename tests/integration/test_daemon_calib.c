/* test_daemon_calib.c - calibration frames through specklabd (daemon/
 * calib.h), on a simulated bench whose mask slot 0 is closed (the fake
 * camera renders only the bias there: the bench's darks):
 *   catalogued_dark   dark runs are catalogued as kind dark, never
 *                     reconstructed, carry IMAGETYP 'dark' and no r0; a
 *                     science run's reconstruction uses the dark of its
 *                     own exposure (not a nearer one of another exposure)
 *                     and says which in its params, and still measures
 *                     the binary; wrong kinds and reconstructing a dark
 *                     are refused by name;
 *   configured_files  [calibration] dark names a file that every
 *                     reconstruction uses instead of the catalogue's;
 *                     a missing file stops the daemon at start-up with
 *                     the key in the message;
 *   calibrator_reference  a calibrator run (the companion laser off: the
 *                     fake camera restarted with dm 15, its most: a 1e-6 companion) through screen 1 is
 *                     the reference of a later science run through the
 *                     same screen and mask, and the catalogue links them;
 *                     the result equals recon --ref on the same cubes; a
 *                     run through another screen gets none, nor does a
 *                     request with calibrator "none".
 */
#include "daemon_fx.h"

#include <glib.h>

#define SEP_ARCSEC 0.7   /* the fake camera's binary */
#define PA_DEG 30.0
#define BIAS_ADU 100.0

static int has(const char *hay, const char *needle)
{
    return hay && needle && strstr(hay, needle) != NULL;
}

/* A bench whose camera sees nothing through mask slot 0; conf as in
 * bench_write_config. */
static int calib_up(bench *b, const char *conf)
{
    if (bench_init(b) != 0)
        return -1;
    snprintf(b->cam_masks, sizeof b->cam_masks, "closed,nrm17");
    return bench_start_stage(b, NULL) || bench_start_camera(b) || bench_write_config(b, conf) ||
                   bench_start_daemon(b)
               ? -1
               : 0;
}

/* Run args to completion; its uuid into out.  0 when it ended done. */
static int run_done(bench *b, dc *c, const char *args, char out[40])
{
    JsonNode *r = keep(b, dc_call(c, "start-run", args, 5));
    if (!jok(r))
        return -1;
    snprintf(out, 40, "%s", js(r, "result.run"));
    JsonNode *e = keep(b, dc_wait_state(c, out, "done,failed,aborted", 90, NULL, NULL));
    return e && has(js(e, "state"), "done") ? 0 : -1;
}

/* The run object and its reconstructions ("result" of `run`). */
static JsonNode *run_info(bench *b, dc *c, const char *uuid)
{
    char args[96];
    snprintf(args, sizeof args, "{\"run\": \"%s\"}", uuid);
    JsonNode *r = keep(b, dc_call(c, "run", args, 5));
    return jok(r) ? jget(r, "result") : NULL;
}

/* Mean pixel and IMAGETYP of a cube. */
static int cube_facts(const char *path, double *mean, char type[FLEN_VALUE])
{
    fitsfile *f = NULL;
    int s = 0, anynul = 0;
    long nax[3] = {0, 0, 0};
    type[0] = 0;
    fits_open_diskfile(&f, path, READONLY, &s);
    fits_read_key(f, TSTRING, "IMAGETYP", type, NULL, &s);
    fits_get_img_size(f, 3, nax, &s);
    long n = nax[0] * nax[1] * (nax[2] > 0 ? nax[2] : 1);
    double *v = n > 0 ? g_new(double, n) : NULL;
    fits_read_img(f, TDOUBLE, 1, n, NULL, v, &anynul, &s);
    double sum = 0;
    for (long i = 0; s == 0 && i < n; i++)
        sum += v[i];
    *mean = n > 0 ? sum / n : NAN;
    g_free(v);
    if (f) {
        int s2 = 0;
        fits_close_file(f, &s2);
    }
    return s;
}

static void catalogued_dark_body(tc *t, bench *b)
{
    dc *c = bench_client(b);
    CHECK(c && bench_wait_camera(b, c, 20) == 0, "no daemon or no camera");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    JsonNode *r = keep(b, dc_call(c, "start-run", "{\"screen\": 1, \"mask\": 0, \"frames\": 5, "
                                  "\"kind\": \"dark\", \"reconstruct\": \"direct\"}", 5));
    CHECK(!jok(r) && has(js(r, "error.code"), "bad-request") &&
          has(js(r, "error.message"), "dark"), "a dark to reconstruct: %s", jtext(r));
    r = keep(b, dc_call(c, "start-run", "{\"screen\": 1, \"mask\": 0, \"frames\": 5, "
                        "\"kind\": \"bias\"}", 5));
    CHECK(!jok(r) && has(js(r, "error.message"), "kind"), "kind bias: %s", jtext(r));

    char dark_a[40], dark_b[40], sci[40];
    /* the matching dark first, then a nearer one of another exposure */
    CHECK(run_done(b, c, "{\"screen\": 1, \"mask\": 0, \"frames\": 10, \"kind\": \"dark\"}",
                   dark_a) == 0, "dark run at the default exposure");
    CHECK(run_done(b, c, "{\"screen\": 1, \"mask\": 0, \"frames\": 10, \"kind\": \"dark\", "
                   "\"exposure_us\": 5000}", dark_b) == 0, "dark run at 5 ms");
    JsonNode *d = run_info(b, c, dark_a);
    CHECK(d && has(js(d, "run.kind"), "dark") && !jget(d, "reconstructions.0") &&
          jnull(d, "run.r0_m"), "dark run: %s", jtext(d));
    double mean = NAN;
    char type[FLEN_VALUE];
    CHECK(cube_facts(js(d, "run.file"), &mean, type) == 0 && !strcmp(type, "dark") &&
          fabs(mean - BIAS_ADU) < 1, "dark cube: IMAGETYP '%s', mean %.2f ADU (bias %g)", type,
          mean, BIAS_ADU);

    CHECK(run_done(b, c, "{\"screen\": 1, \"mask\": 1, \"frames\": 60, "
                   "\"reconstruct\": \"direct\"}", sci) == 0, "science run");
    d = run_info(b, c, sci);
    JsonNode *rec = d ? jget(d, "reconstructions.0") : NULL;
    CHECK(rec && has(js(d, "run.kind"), "science"), "science run: %s", jtext(d));
    const char *used = js(rec, "params.dark.run");
    CHECK(used && !strcmp(used, dark_a), "dark used %s; want %s (same exposure), not %s",
          used ? used : "(none)", dark_a, dark_b);
    CHECK(has(js(rec, "params.dark.file"), dark_a) && !jget(rec, "params.flat"),
          "params %s", jtext(jget(rec, "params")));
    double sep = jd(rec, "sep_arcsec"), pa = jd(rec, "pa_deg");
    CHECK(fabs(sep - SEP_ARCSEC) <= 0.03 * SEP_ARCSEC && fabs(pa - PA_DEG) <= 1.5,
          "dark-subtracted binary: %.4f arcsec, PA %.2f (truth %.2f, %.1f)", sep, pa,
          SEP_ARCSEC, PA_DEG);

    r = keep(b, dc_call(c, "runs", "{\"kind\": \"dark\"}", 5));
    CHECK(jok(r) && jget(r, "result.runs.1") && !jget(r, "result.runs.2") &&
          has(js(r, "result.runs.0.kind"), "dark"), "runs of kind dark: %s", jtext(r));
    char args[96];
    snprintf(args, sizeof args, "{\"run\": \"%s\"}", dark_a);
    r = keep(b, dc_call(c, "reconstruct", args, 5));
    CHECK(!jok(r) && has(js(r, "error.message"), "dark"), "reconstruct a dark: %s", jtext(r));
}

static void catalogued_dark_run(tc *t)
{
    bench b;
    if (calib_up(&b, NULL) != 0) {
        tc_note(t, 0, __FILE__, __LINE__, "bench", "bench did not start");
        bench_down(&b, 1);
        return;
    }
    catalogued_dark_body(t, &b);
    bench_check_stop(t, &b);
    bench_down(&b, t->failed);
}

TEST(catalogued_dark) { fx_in_child(t, catalogued_dark_run, 240); }

/* A dark file of the bench's frames: bias only (64x64, the fixture's). */
static int write_dark(const char *path, double level)
{
    fitsfile *f = NULL;
    int s = 0;
    long nax[2] = {64, 64};
    float v[64 * 64];
    for (int i = 0; i < 64 * 64; i++)
        v[i] = (float)level;
    fits_create_diskfile(&f, path, &s);
    fits_create_img(f, FLOAT_IMG, 2, nax, &s);
    fits_write_img(f, TFLOAT, 1, 64 * 64, v, &s);
    fits_close_file(f, &s);
    return s;
}

static void configured_files_body(tc *t, bench *b, const char *dark)
{
    dc *c = bench_client(b);
    char dark_run[40], sci[40];
    CHECK(c && bench_wait_camera(b, c, 20) == 0, "no daemon or no camera");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    CHECK(run_done(b, c, "{\"screen\": 1, \"mask\": 0, \"frames\": 10, \"kind\": \"dark\"}",
                   dark_run) == 0, "dark run");
    CHECK(run_done(b, c, "{\"screen\": 1, \"mask\": 1, \"frames\": 40, "
                   "\"reconstruct\": \"tsm-fourier\"}", sci) == 0, "science run");
    JsonNode *d = run_info(b, c, sci);
    JsonNode *rec = d ? jget(d, "reconstructions.0") : NULL;
    CHECK(rec && has(js(rec, "params.dark.file"), dark) && !jget(rec, "params.dark.run"),
          "the configured file, not the dark run: %s", jtext(jget(rec, "params")));
}

static void configured_files_run(tc *t)
{
    bench b;
    char dark[300], conf[400], err[512] = "";
    if (bench_init(&b) != 0)
        return;
    snprintf(dark, sizeof dark, "%s/dark.fits", b.dir);
    snprintf(b.cam_masks, sizeof b.cam_masks, "closed,nrm17");
    snprintf(conf, sizeof conf, "[calibration]\ndark=%s/none.fits\n", b.dir);
    /* a missing file: the daemon refuses to start, naming the key */
    int bad_start = bench_start_stage(&b, NULL) || bench_start_camera(&b) ||
                    bench_write_config(&b, conf) || bench_start_daemon(&b);
    gchar *log = NULL;
    g_file_get_contents(b.dlog, &log, NULL, NULL);
    int named = has(log, "[calibration] dark") && has(log, "none.fits");
    g_free(log);
    fx_stop(&b.daemon, SIGKILL, 5);
    snprintf(conf, sizeof conf, "[calibration]\ndark=%s\n", dark);
    if (!bad_start || !named)
        snprintf(err, sizeof err, "a missing dark: started %d, named in the log %d", !bad_start,
                 named);
    else if (write_dark(dark, BIAS_ADU) != 0 || bench_write_config(&b, conf) ||
             bench_start_daemon(&b))
        snprintf(err, sizeof err, "the daemon did not start with dark=%s", dark);
    if (err[0])
        tc_note(t, 0, __FILE__, __LINE__, "start-up", "%s", err);
    else
        configured_files_body(t, &b, dark);
    bench_check_stop(t, &b);
    bench_down(&b, t->failed);
}

TEST(configured_files) { fx_in_child(t, configured_files_run, 240); }

/* Restart the fake camera with dm (a string; "" its default). */
static int camera_with_dm(bench *b, dc *c, const char *dm)
{
    fx_stop(&b->cam, SIGTERM, 5);
    snprintf(b->cam_dm, sizeof b->cam_dm, "%s", dm);
    return bench_start_camera(b) == 0 && bench_wait_camera(b, c, 20) == 0 ? 0 : -1;
}

/* sep_px, pa_deg, dm_mag of `specklab recon cube --ref ref ... --json`. */
static int cli_ref_binary(const char *cube, const char *ref, const char *dir, double m[3])
{
    char bin[PATH_MAX], out[400];
    fx_bin(bin, sizeof bin, "specklab");
    snprintf(out, sizeof out, "%s/cli-ref.fits", dir);
    char *argv[] = {bin, "recon", (char *)cube, "--ref", (char *)ref, "-m", "direct",
                    "--skips", "reject,crop,support", "--binary", "--overwrite", "-o", out,
                    "--json", NULL};
    char *text = NULL;
    int st = -1;
    g_spawn_sync(NULL, argv, NULL, G_SPAWN_STDERR_TO_DEV_NULL, NULL, NULL, &text, NULL, &st,
                 NULL);
    JsonNode *n = text ? json_from_string(text, NULL) : NULL;
    g_free(text);
    m[0] = n ? jd(n, "binary.sep_px") : NAN;
    m[1] = n ? jd(n, "binary.pa_deg") : NAN;
    m[2] = n ? jd(n, "binary.dm_mag") : NAN;
    if (n)
        json_node_unref(n);
    return isfinite(m[0]) ? 0 : -1;
}

BENCH_NET_TEST(calibrator_reference, 240, NULL, "[daemon]\nreconstruct=none\n")
{
    dc *c = bench_client(b);
    char cal[40], sci[40], other[40];
    CHECK(c && bench_wait_camera(b, c, 20) == 0, "no daemon or no camera");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    CHECK(camera_with_dm(b, c, "15") == 0, "the camera with the companion off");
    CHECK(run_done(b, c, "{\"screen\": 1, \"mask\": 1, \"frames\": 60, "
                   "\"kind\": \"calibrator\"}", cal) == 0, "calibrator run");
    CHECK(camera_with_dm(b, c, "") == 0, "the camera with the companion on");
    /* its automatic reconstruction after acquisition takes the calibrator */
    CHECK(run_done(b, c, "{\"screen\": 1, \"mask\": 1, \"frames\": 60, "
                   "\"reconstruct\": \"direct\"}", sci) == 0, "science run");
    JsonNode *auto_rec = run_info(b, c, sci);
    CHECK(auto_rec && has(js(auto_rec, "reconstructions.0.params.ref.run"), cal),
          "the automatic reconstruction's params: %s",
          jtext(jget(auto_rec, "reconstructions.0.params")));
    CHECK(run_done(b, c, "{\"screen\": 2, \"mask\": 1, \"frames\": 30}", other) == 0,
          "a run through screen 2");
    char args[200];
    snprintf(args, sizeof args, "{\"run\": \"%s\", \"method\": \"direct\", "
             "\"options\": {\"binary\": true}}", sci);
    JsonNode *r = keep(b, dc_call(c, "reconstruct", args, 120));
    JsonNode *x = jget(r, "result.reconstruction");
    CHECK(x && has(js(x, "params.ref.run"), cal), "the science run's reference: %s",
          jtext(jget(x, "params")));
    JsonNode *cr = run_info(b, c, cal), *sr = run_info(b, c, sci);
    CHECK(cr && sr && has(js(cr, "run.kind"), "calibrator"), "calibrator run %s", jtext(cr));
    double m[3];
    CHECK(cli_ref_binary(js(sr, "run.file"), js(cr, "run.file"), b->dir, m) == 0,
          "recon --ref on the same cubes measured nothing");
    double sep = jd(x, "sep_px"), pa = jd(x, "pa_deg"), dmag = jd(x, "dm_mag");
    CHECK(fabs(sep - m[0]) < 0.01 && fabs(pa - m[1]) < 0.05 && fabs(dmag - m[2]) < 0.01,
          "daemon %.4f px %.3f deg %.4f mag; recon --ref %.4f %.3f %.4f", sep, pa, dmag,
          m[0], m[1], m[2]);
    /* the calibrator is a point source: no companion measured in it */
    snprintf(args, sizeof args, "{\"run\": \"%s\", \"method\": \"direct\", "
             "\"options\": {\"binary\": true}}", cal);
    r = keep(b, dc_call(c, "reconstruct", args, 120));
    CHECK(jok(r) && !has(js(r, "result.reconstruction.params.binary_status"), "measured") &&
          !jget(r, "result.reconstruction.params.ref"), "the calibrator's own: %s", jtext(r));
    snprintf(args, sizeof args, "{\"run\": \"%s\", \"method\": \"direct\"}", other);
    r = keep(b, dc_call(c, "reconstruct", args, 120));
    CHECK(jok(r) && !jget(r, "result.reconstruction.params.ref"),
          "screen 2 took screen 1's calibrator: %s", jtext(r));
    snprintf(args, sizeof args, "{\"run\": \"%s\", \"method\": \"direct\", "
             "\"calibrator\": \"none\"}", sci);
    r = keep(b, dc_call(c, "reconstruct", args, 120));
    CHECK(jok(r) && !jget(r, "result.reconstruction.params.ref"),
          "calibrator none: %s", jtext(r));
}

TC_MAIN(TC_CASE(catalogued_dark), TC_CASE(configured_files), TC_CASE(calibrator_reference))
