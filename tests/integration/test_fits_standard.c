/* test_fits_standard.c - the FITS files the project writes, as other
 * tools see them: fitsverify (no warning, no error) and astropy
 * (checksum=True; CHECKSUM and DATASUM of every HDU verify), the standard
 * header of recon/io/cube.h (DATE, CREATOR with SPECKLAB_VERSION, BUNIT,
 * HISTORY) and the WCS: astropy's pixel-to-world on the two stars of a
 * binary of known separation and position angle gives them in arcsec, PA
 * from north through east (east left).  The checks are in
 * tests/integration/fits_standard.py; the files come from:
 *   specklab sim (the cube with its TRUTH; a --blind cube, no WCS),
 *   specklab recon of that cube,
 *   specklab camera grab on the fake camera (cube and FRAMES table),
 *   specklabd's run (cube and FRAMES table) and its reconstruction,
 *   specklab export of that run (byte-identical copies).
 * Needs /usr/bin/python3 with astropy and fitsverify (scripts/install-deps).
 */
#include "daemon_fx.h"

#include "base/version.h"
#include "cli.h"
#include "cmd_daemon.h"

#define PY "/usr/bin/python3"
/* The fake camera's binary (test_daemon.c): 0.7 arcsec at PA 30. */
#define CAM_SEP_ARCSEC 0.7
#define CAM_PA_DEG 30.0

/* tests/integration/fits_standard.py beside this test's sources: from the
 * binary's place (BUILD/tests/test_x), else from the working directory. */
static void script_path(char *out, size_t n)
{
    char exe[PATH_MAX] = "";
    ssize_t len = readlink("/proc/self/exe", exe, sizeof exe - 1);
    exe[len > 0 ? len : 0] = 0;
    snprintf(out, n, "%s/tests/integration/fits_standard.py", dirname(dirname(dirname(exe))));
    if (access(out, R_OK) != 0)
        snprintf(out, n, "tests/integration/fits_standard.py");
}

/* Why the tools are missing, or NULL. */
static const char *tools_missing(void)
{
    char *argv[] = {PY, "-c", "import astropy.io.fits, astropy.wcs, numpy", NULL};
    char *fv[] = {"fitsverify", "-q", "/dev/null", NULL};
    gint st = -1;
    GError *ge = NULL;
    if (!g_spawn_sync(NULL, argv, NULL, G_SPAWN_STDOUT_TO_DEV_NULL | G_SPAWN_STDERR_TO_DEV_NULL,
                      NULL, NULL, NULL, NULL, &st, &ge) || !g_spawn_check_wait_status(st, NULL)) {
        g_clear_error(&ge);
        return PY " with astropy and numpy (python3-astropy)";
    }
    if (!g_spawn_sync(NULL, fv, NULL, G_SPAWN_SEARCH_PATH | G_SPAWN_STDOUT_TO_DEV_NULL |
                      G_SPAWN_STDERR_TO_DEV_NULL, NULL, NULL, NULL, NULL, &st, &ge)) {
        g_clear_error(&ge);
        return "fitsverify";
    }
    return NULL;
}

/* Run fits_standard.py with opts (a NULL-terminated list) on files (NULL-
 * terminated).  0 when every file passed; its report in out. */
static int fits_check(char *out, size_t n, const char *const *opts, const char *const *files)
{
    char script[PATH_MAX];
    const char *argv[48];
    int k = 0;
    script_path(script, sizeof script);
    argv[k++] = PY, argv[k++] = script, argv[k++] = "--version", argv[k++] = SPECKLAB_VERSION;
    for (int i = 0; opts[i] && k < 40; i++)
        argv[k++] = opts[i];
    for (int i = 0; files[i] && k < 47; i++)
        argv[k++] = files[i];
    argv[k] = NULL;
    gchar *so = NULL, *se = NULL;
    gint st = -1;
    GError *ge = NULL;
    int ok = g_spawn_sync(NULL, (gchar **)argv, NULL, 0, NULL, NULL, &so, &se, &st, &ge) &&
             g_spawn_check_wait_status(st, NULL);
    snprintf(out, n, "%s%s%s", so ? so : "", se ? se : "", ge ? ge->message : "");
    printf("%s", so ? so : "");
    g_clear_error(&ge);
    g_free(so);
    g_free(se);
    return ok ? 0 : -1;
}

/* Run a subcommand in-process (GOption reorders argv: pass a copy). */
static int run_cli(int (*cmd)(int, char **), const char *const *args)
{
    char *v[32];
    int n = 0;
    for (; args[n] && n < 31; n++)
        v[n] = (char *)args[n];
    v[n] = NULL;
    return cmd(n, v);
}

static int same_bytes(const char *a, const char *b)
{
    gchar *da = NULL, *db = NULL;
    gsize na = 0, nb = 0;
    int same = g_file_get_contents(a, &da, &na, NULL) && g_file_get_contents(b, &db, &nb, NULL) &&
               na == nb && memcmp(da, db, na) == 0;
    g_free(da);
    g_free(db);
    return same;
}

TEST(sim_and_recon)
{
    const char *why = tools_missing();
    CHECK(!why, "%s is missing: run scripts/install-deps", why);
    char dir[] = "/tmp/sl_fitsstd_XXXXXX", out[8192];
    CHECK(mkdtemp(dir), "mkdtemp");
    char *cube = g_strdup_printf("%s/binary.fits", dir), *rec = g_strdup_printf("%s/rec.fits", dir);
    char *blind = g_strdup_printf("%s/blind.fits", dir);
    char *side = g_strdup_printf("%s/blind-truth.fits", dir);
    const char *sim[] = {"specklab sim", "--size", "64", "--frames", "60", "--sep-arcsec", "0.5",
                         "--pa-deg", "30", "--photons", "2e4", "-q", "-o", cube, NULL};
    const char *recon[] = {"specklab recon", cube, "--method", "direct", "-q", "-o", rec, NULL};
    const char *sim_blind[] = {"specklab sim", "--size", "32", "--frames", "3", "--sep-arcsec",
                               "0.2", "--photons", "1e4", "--blind", "-q", "-o", blind, NULL};
    int rs = run_cli(cmd_sim, sim), rr = rs ? -1 : run_cli(cmd_recon, recon);
    int rb = run_cli(cmd_sim, sim_blind);
    /* the truth extension, located with the cube's WCS: exact */
    const char *o_cube[] = {"--wcs", "offset", "--bunit", "adu", "--binary", "0.5", "30",
                            "0.002", "0.1", "--truth", NULL};
    const char *o_rec[] = {"--wcs", "offset", "--bunit", "relative flux", "--binary", "0.5",
                           "30", "0.025", "2", NULL};
    const char *o_blind[] = {"--wcs", "none", "--bunit", "adu", NULL};
    const char *o_side[] = {"--wcs", "offset", "--binary", "0.2", "30", "0.002", "0.1", "--truth",
                            NULL};
    const char *f_cube[] = {cube, NULL}, *f_rec[] = {rec, NULL}, *f_blind[] = {blind, NULL};
    const char *f_side[] = {side, NULL};
    int ok = rs == 0 && rr == 0 && rb == 0;
    int c1 = ok ? fits_check(out, sizeof out, o_cube, f_cube) : -1;
    if (c1 == 0)
        c1 = fits_check(out, sizeof out, o_rec, f_rec);
    if (c1 == 0)
        c1 = fits_check(out, sizeof out, o_blind, f_blind);
    int c4 = c1 == 0 ? fits_check(out, sizeof out, o_side, f_side) : -1;
    char *rm = g_strdup_printf("rm -rf '%s'", dir);
    if (system(rm) != 0)
        fprintf(stderr, "could not remove %s\n", dir);
    g_free(rm);
    g_free(cube), g_free(rec), g_free(blind), g_free(side);
    CHECK(ok, "sim %d, recon %d, sim --blind %d", rs, rr, rb);
    CHECK(c1 == 0, "%s", out);
    CHECK(c4 == 0, "the --blind sidecar: %s", out);
}

/* `specklab camera grab` on the fake camera: no plate scale, no WCS. */
static void grab_body(tc *t)
{
    bench b;
    char out[8192], cli[PATH_MAX], line[64];
    const char *why = tools_missing();
    CHECK(!why, "%s is missing: run scripts/install-deps", why);
    CHECK(bench_init(&b) == 0, "bench_init");
    b.cam_gige = 1;   /* the CLI opens the GigE camera itself */
    CHECK(bench_start_stage(&b, NULL) == 0 && bench_start_camera(&b) == 0,
          "the fake stage and camera did not start");
    char *path = g_strdup_printf("%s/grab.fits", b.dir);
    fx_bin(cli, sizeof cli, "specklab");
    char *argv[] = {cli, "camera", "grab", "--camera", "127.0.0.1", "--frames", "12", "-o",
                    path, NULL};
    fx_proc p;
    int st = -1;
    if (fx_spawn(&p, argv, FX_STDERR, NULL, NULL) == 0) {
        waitpid(p.pid, &st, 0);
        close(p.out);
    }
    snprintf(line, sizeof line, "grab exit %d", WIFEXITED(st) ? WEXITSTATUS(st) : -1);
    const char *opts[] = {"--wcs", "none", "--bunit", "adu", NULL}, *files[] = {path, NULL};
    int c = WIFEXITED(st) && WEXITSTATUS(st) == 0 ? fits_check(out, sizeof out, opts, files) : -1;
    g_free(path);
    bench_down(&b, 0);
    CHECK(WIFEXITED(st) && WEXITSTATUS(st) == 0, "%s", line);
    CHECK(c == 0, "%s", out);
}

TEST(camera_grab) { fx_in_netns(t, grab_body, 90); }

/* specklabd's cube and reconstruction, then `specklab export`. */
BENCH_TEST(daemon_run_and_export, 150, NULL, NULL)
{
    char out[8192];
    const char *why = tools_missing();
    CHECK(!why, "%s is missing: run scripts/install-deps", why);
    dc *c = bench_client(b);
    CHECK(c && bench_wait_camera(b, c, 20) == 0, "no camera in the daemon");
    JsonNode *r = keep(b, dc_call(c, "subscribe", NULL, 5));
    r = keep(b, dc_call(c, "start-run", "{\"screen\": 1, \"mask\": \"full\", \"frames\": 40, "
                        "\"object\": \"laser binary\", \"reconstruct\": \"direct\"}", 5));
    CHECK(jok(r), "start-run: %s", jtext(r));
    char uuid[40];
    snprintf(uuid, sizeof uuid, "%s", js(r, "result.run"));
    JsonNode *e = keep(b, dc_wait_state(c, uuid, "done,failed,aborted", 90, NULL, NULL));
    CHECK(e && !strcmp(js(e, "state"), "done"), "run ended %s", jtext(e));
    char args[128];
    snprintf(args, sizeof args, "{\"run\": \"%s\"}", uuid);
    r = keep(b, dc_call(c, "run", args, 5));
    const char *fc = js(r, "result.run.file"), *fr = js(r, "result.reconstructions.0.fits");
    CHECK(jok(r) && fc && fr, "run: %s", jtext(r));
    char cube[400], rec[400];
    snprintf(cube, sizeof cube, "%s", fc ? fc : "");
    snprintf(rec, sizeof rec, "%s", fr ? fr : "");
    char sep[32], tol[32];
    snprintf(sep, sizeof sep, "%g", CAM_SEP_ARCSEC);
    snprintf(tol, sizeof tol, "%g", 0.03 * CAM_SEP_ARCSEC);
    const char *o_cube[] = {"--wcs", "offset", "--bunit", "adu", NULL};
    const char *o_rec[] = {"--wcs", "offset", "--bunit", "relative flux", "--binary", sep,
                           "30", tol, "2", NULL};
    const char *f_cube[] = {cube, NULL}, *f_rec[] = {rec, NULL};
    CHECK(fits_check(out, sizeof out, o_cube, f_cube) == 0, "%s", out);
    CHECK(fits_check(out, sizeof out, o_rec, f_rec) == 0, "%s", out);

    char *dir = g_strdup_printf("%s/export", b->dir);
    const char *exp[] = {"specklab export", uuid, "-o", dir, "--socket", b->sock, NULL};
    int rc = run_cli(cmd_export, exp);
    char *ecube = g_build_filename(dir, strrchr(cube, '/') + 1, NULL);
    char *erec = g_build_filename(dir, strrchr(rec, '/') + 1, NULL);
    int same = rc == 0 && same_bytes(cube, ecube) && same_bytes(rec, erec);
    const char *f_ecube[] = {ecube, NULL}, *f_erec[] = {erec, NULL};
    int c1 = same ? fits_check(out, sizeof out, o_cube, f_ecube) : -1;
    if (c1 == 0)
        c1 = fits_check(out, sizeof out, o_rec, f_erec);
    g_free(dir);
    g_free(ecube);
    g_free(erec);
    CHECK(same, "export exit %d; copies %s", rc, same ? "identical" : "differ or are missing");
    CHECK(c1 == 0, "%s", out);
}

TC_MAIN(TC_CASE(sim_and_recon), TC_CASE(camera_grab), TC_CASE(daemon_run_and_export))
