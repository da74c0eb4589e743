/* test_cli.c - the daemon subcommands (cli/cmd_daemon.h) end to end.
 *
 * Against the stub daemon of cli_fx.h (always): the experiment's table
 * and JSON, a failed run, refusing unknown screens before starting
 * anything, filters passed on, prefixes, export with its sha256 check,
 * on-demand reconstruction, the daemon-not-running message.  The
 * subcommands run in-process with stdout/stderr redirected to files, so
 * the test checks what a user or script would see.
 *
 * The real_daemon_* tests run the same commands against the real daemon
 * ($SPECKLABD, else bin/specklabd; skipped when absent), started as a
 * child with its own data directory and socket, and devices that cannot
 * answer (stage on a closed port, camera on a TEST-NET address): queries,
 * errors and a run that fails at the stage are what they can check
 * without the fake bench (scripts/demo runs the full experiment).
 */
#include <signal.h>
#include <sys/wait.h>
#include <time.h>

#include "cli.h"
#include "cli_fx.h"
#include "tcheck.h"

TEST(binary_bench_json_one_row_per_run)
{
    sd s;
    CHECK(sd_start(&s) == 0, "stub daemon");
    char *out = NULL, *err = NULL;
    int rc = run_cmd(&s, cmd_experiment, &out, &err, "specklab experiment", "binary-bench",
                     "--screens", "1,2,3", "--masks", "nrm17", "--frames", "60", "--json", NULL);
    JsonNode *n = parse(out);
    JsonArray *a = n && JSON_NODE_HOLDS_OBJECT(n) ? dcmd_arr(json_node_get_object(n), "runs") : NULL;
    int len = a ? (int)json_array_get_length(a) : -1, good = len == 3 &&
        dcmd_int(json_node_get_object(n), "runs_not_done", -1) == 0;
    char why[200] = "";
    for (int i = 0; good && i < 3; i++) {
        JsonObject *o = json_array_get_object_element(a, i);
        char want[16];
        snprintf(want, sizeof want, "s%d", i + 1);
        good = !strcmp(dcmd_str(o, "screen"), want) && !strcmp(dcmd_str(o, "state"), "done") &&
               fabs(dcmd_num(o, "sep_arcsec") - SEP_ARCSEC) < 1e-12 &&
               fabs(dcmd_num(o, "pa_deg") - PA_DEG) < 1e-12 &&
               fabs(dcmd_num(o, "r0_m") - r0_of[i + 1]) < 1e-12 &&
               json_node_is_null(json_object_get_member(o, "c_cophased")) &&
               dcmd_int(o, "frames_acquired", 0) == 60 && fabs(dcmd_num(o, "time_s") - 3) < 1e-9 &&
               dcmd_str(o, "png") != NULL && !g_strcmp0(dcmd_str(o, "mask"), "nrm17");
        if (!good)
            snprintf(why, sizeof why, "row %d: screen %s state %s", i, dcmd_str(o, "screen"),
                     dcmd_str(o, "state"));
    }
    pthread_mutex_lock(&s.mu);
    int nruns = s.nruns;
    pthread_mutex_unlock(&s.mu);
    if (n)
        json_node_unref(n);
    sd_stop(&s);
    CHECK(rc == 0, "exit %d, stderr: %s", rc, err);
    CHECK(len == 3, "JSON array of %d rows: %s", len, out);
    CHECK(good, "%s", why);
    CHECK(nruns == 3, "%d runs started", nruns);
    g_free(out);
    g_free(err);
}

TEST(binary_bench_table_and_failed_run)
{
    sd s;
    CHECK(sd_start(&s) == 0, "stub daemon");
    char *out = NULL, *err = NULL;
    int rc = run_cmd(&s, cmd_experiment, &out, &err, "specklab experiment", "binary-bench",
                     "--screens", "s1,bad", "--frames", "40", NULL);
    int ok_row = out && strstr(out, "s1") && strstr(out, "0.7000") && strstr(out, "30.00");
    int failed = out && strstr(out, "failed") && strstr(out, "camera lost after 20 frames");
    int header = out && strstr(out, "r0(m)") && strstr(out, "sep(\")") && strstr(out, "PA(deg)");
    sd_stop(&s);
    CHECK(rc == 1, "exit %d with a failed run", rc);
    CHECK(header, "no table header:\n%s", out);
    CHECK(ok_row, "done run row missing:\n%s", out);
    CHECK(failed, "failed run and its reason missing:\n%s", out);
    g_free(out);
    g_free(err);
}

/* --kind reaches every start-run (calibrator runs for the screens'
 * references, darks, flats); an unknown kind starts nothing. */
TEST(binary_bench_kind_reaches_every_run)
{
    sd s;
    CHECK(sd_start(&s) == 0, "stub daemon");
    char *out = NULL, *err = NULL, *out2 = NULL, *err2 = NULL;
    int rc = run_cmd(&s, cmd_experiment, &out, &err, "specklab experiment", "binary-bench",
                     "--screens", "1,2", "--kind", "calibrator", NULL);
    int rc2 = run_cmd(&s, cmd_experiment, &out2, &err2, "specklab experiment", "binary-bench",
                      "--screens", "1", "--kind", "bias", NULL);
    pthread_mutex_lock(&s.mu);
    int nruns = s.nruns, all = nruns == 2;
    for (int i = 0; i < nruns; i++)
        all = all && !strcmp(s.runs[i].kind, "calibrator");
    pthread_mutex_unlock(&s.mu);
    sd_stop(&s);
    CHECK(rc == 0 && all, "exit %d, %d runs, kinds not all calibrator: %s", rc, nruns, err);
    CHECK(rc2 == 2 && err2 && strstr(err2, "--kind 'bias'"), "kind bias: exit %d: %s", rc2,
          err2);
    g_free(out), g_free(err), g_free(out2), g_free(err2);
}

TEST(binary_bench_unknown_screen_starts_nothing)
{
    sd s;
    CHECK(sd_start(&s) == 0, "stub daemon");
    char *out = NULL, *err = NULL;
    int rc = run_cmd(&s, cmd_experiment, &out, &err, "specklab experiment", "binary-bench",
                     "--screens", "1,9", NULL);
    pthread_mutex_lock(&s.mu);
    int nruns = s.nruns;
    pthread_mutex_unlock(&s.mu);
    sd_stop(&s);
    CHECK(rc == 1, "exit %d", rc);
    CHECK(nruns == 0, "%d runs started despite screen 9", nruns);
    CHECK(err && strstr(err, "no screen '9'") && strstr(err, "s1"), "stderr: %s", err);
    g_free(out);
    g_free(err);
}

TEST(runs_list_passes_filters)
{
    sd s;
    CHECK(sd_start(&s) == 0, "stub daemon");
    char *out = NULL, *err = NULL;
    int rc = run_cmd(&s, cmd_runs, &out, &err, "specklab runs", "list", "--state", "done",
                     "--screen", "s2", "--limit", "7", "--since", "2d", "--json", NULL);
    pthread_mutex_lock(&s.mu);
    JsonObject *a = s.last_runs_args ? json_object_ref(s.last_runs_args) : NULL;
    pthread_mutex_unlock(&s.mu);
    double since = a ? dcmd_iso_s(dcmd_str(a, "since")) : NAN;
    double age_d = ((double)time(NULL) - since) / 86400.0;
    int pass = a && !g_strcmp0(dcmd_str(a, "state"), "done") &&
               !g_strcmp0(dcmd_str(a, "screen"), "s2") && dcmd_int(a, "limit", 0) == 7;
    JsonNode *n = parse(out);
    int is_obj = n && JSON_NODE_HOLDS_OBJECT(n) && dcmd_arr(json_node_get_object(n), "runs");
    if (n)
        json_node_unref(n);
    if (a)
        json_object_unref(a);
    sd_stop(&s);
    CHECK(rc == 0, "exit %d: %s", rc, err);
    CHECK(pass, "filters not passed on");
    CHECK(fabs(age_d - 2) < 0.01, "--since 2d sent as %.4f days ago", age_d);
    CHECK(is_obj, "--json is not the daemon's result object: %s", out);
    g_free(out);
    g_free(err);
}

TEST(runs_show_prefix_and_not_found)
{
    sd s;
    CHECK(sd_start(&s) == 0, "stub daemon");
    char *out = NULL, *err = NULL, *o2 = NULL, *e2 = NULL, *o3 = NULL, *e3 = NULL;
    int rc1 = run_cmd(&s, cmd_experiment, &out, &err, "specklab experiment", "binary-bench",
                      "--screens", "1", "--frames", "20", "--json", NULL);
    int rc2 = run_cmd(&s, cmd_runs, &o2, &e2, "specklab runs", "show", "abc00001", NULL);
    int rc3 = run_cmd(&s, cmd_runs, &o3, &e3, "specklab runs", "show", "ffff", NULL);
    sd_stop(&s);
    CHECK(rc1 == 0, "experiment exit %d: %s", rc1, err);
    CHECK(rc2 == 0 && strstr(o2, "abc00001-0000") && strstr(o2, "reconstructions:"),
          "show by prefix: exit %d\n%s%s", rc2, o2, e2);
    CHECK(rc3 == 1 && strstr(e3, "no run 'ffff'"), "not found: exit %d, stderr %s", rc3, e3);
    g_free(out); g_free(err); g_free(o2); g_free(e2); g_free(o3); g_free(e3);
}

TEST(export_copies_files_and_sidecar)
{
    sd s;
    CHECK(sd_start(&s) == 0, "stub daemon");
    char *out = NULL, *err = NULL, *o2 = NULL, *e2 = NULL;
    int rc1 = run_cmd(&s, cmd_experiment, &out, &err, "specklab experiment", "binary-bench",
                      "--screens", "2", "--frames", "20", NULL);
    char *dir = g_strdup_printf("%s/export/sub", s.dir);
    int rc2 = run_cmd(&s, cmd_export, &o2, &e2, "specklab export", "abc00001", "-o", dir, NULL);
    char *fits = g_strdup_printf("%s/abc00001-0000-4000-8000-000000000001.fits", dir);
    char *png = g_strdup_printf("%s/abc00001-0000-4000-8000-000000000001-r1.png", dir);
    char *side = g_strdup_printf("%s/abc00001-0000-4000-8000-000000000001.json", dir);
    gchar *fdata = NULL, *sdata = NULL;
    g_file_get_contents(fits, &fdata, NULL, NULL);
    g_file_get_contents(side, &sdata, NULL, NULL);
    JsonNode *n = parse(sdata);
    JsonObject *so = n && JSON_NODE_HOLDS_OBJECT(n) ? json_node_get_object(n) : NULL;
    JsonObject *exp = dcmd_obj(so, "export");
    int verified = exp && json_object_get_boolean_member(exp, "sha256_verified");
    int has_run = so && !g_strcmp0(dcmd_str(dcmd_obj(so, "run"), "screen"), "s2") &&
                  dcmd_arr(so, "reconstructions") && json_array_get_length(dcmd_arr(so, "reconstructions")) == 1;
    int png_ok = g_file_test(png, G_FILE_TEST_IS_REGULAR);
    /* a copy that does not match the catalogue's checksum fails the export */
    pthread_mutex_lock(&s.mu);
    s.bad_sha = 1;
    pthread_mutex_unlock(&s.mu);
    char *o3 = NULL, *e3 = NULL, *dir2 = g_strdup_printf("%s/export2", s.dir);
    int rc3 = run_cmd(&s, cmd_export, &o3, &e3, "specklab export", "abc00001", "-o", dir2, NULL);
    int says = e3 && strstr(e3, "differs from the catalogue");
    g_free(o3); g_free(e3); g_free(dir2);
    if (n)
        json_node_unref(n);
    sd_stop(&s);
    CHECK(rc1 == 0, "experiment exit %d: %s", rc1, err);
    CHECK(rc2 == 0, "export exit %d: %s", rc2, e2);
    CHECK(fdata && !strcmp(fdata, "SIMPLE  =                    T"), "FITS copy differs");
    CHECK(png_ok, "no PNG at %s", png);
    CHECK(verified, "sidecar does not record a verified sha256: %s", sdata);
    CHECK(has_run, "sidecar lacks the run or its reconstruction");
    CHECK(rc3 == 1 && says, "checksum mismatch: exit %d", rc3);
    g_free(out); g_free(err); g_free(o2); g_free(e2); g_free(dir); g_free(fits);
    g_free(png); g_free(side); g_free(fdata); g_free(sdata);
}

TEST(recon_run_new_reconstruction_and_copy)
{
    sd s;
    CHECK(sd_start(&s) == 0, "stub daemon");
    char *out = NULL, *err = NULL, *o2 = NULL, *e2 = NULL;
    int rc1 = run_cmd(&s, cmd_experiment, &out, &err, "specklab experiment", "binary-bench",
                      "--screens", "3", "--frames", "20", NULL);
    char *dst = g_strdup_printf("%s/mine.fits", s.dir);
    int rc2 = run_cmd(&s, cmd_recon_run, &o2, &e2, "specklab recon", "abc00001",
                      "--method", "direct", "-o", dst, "--json", NULL);
    JsonNode *n = parse(o2);
    JsonObject *x = n ? dcmd_obj(json_node_get_object(n), "reconstruction") : NULL;
    int second = x && dcmd_int(x, "id", 0) == 2 && !g_strcmp0(dcmd_str(x, "method"), "direct");
    gchar *copied = NULL;
    g_file_get_contents(dst, &copied, NULL, NULL);
    if (n)
        json_node_unref(n);
    sd_stop(&s);
    CHECK(rc1 == 0 && rc2 == 0, "exit %d/%d: %s", rc1, rc2, e2);
    CHECK(second, "not a new direct reconstruction: %s", o2);
    CHECK(copied && !strcmp(copied, "RECONFITS"), "-o copy missing");
    g_free(out); g_free(err); g_free(o2); g_free(e2); g_free(dst); g_free(copied);
}

TEST(not_running_and_run_id_shape)
{
    sd s;
    CHECK(sd_start(&s) == 0, "stub daemon");
    sd_stop(&s); /* the socket path now names nothing */
    mkdir(s.dir, 0700); /* for run_cmd's output files */
    char *out = NULL, *err = NULL;
    int rc = run_cmd(&s, cmd_daemon, &out, &err, "specklab daemon", "status", NULL);
    char *rm = g_strdup_printf("rm -rf '%s'", s.dir);
    if (system(rm) != 0)
        fprintf(stderr, "could not remove %s\n", s.dir);
    g_free(rm);
    CHECK(rc == 1, "exit %d", rc);
    CHECK(err && strstr(err, "cannot reach specklabd at") && strstr(err, s.path) &&
          strstr(err, "start it with bin/specklabd"), "stderr: %s", err);
    CHECK(cmd_recon_is_run_id("abc00001") && cmd_recon_is_run_id("0f3c-9a"), "uuid prefixes");
    CHECK(!cmd_recon_is_run_id("cube.fits") && !cmd_recon_is_run_id("abc") &&
          !cmd_recon_is_run_id("/tmp") && !cmd_recon_is_run_id("----"), "non-ids");
    g_free(out);
    g_free(err);
}


/* ---- the real daemon ---- */

typedef struct rd {
    sd s;          /* only dir and path are used (run_cmd's files) */
    pid_t pid;
} rd;

static const char *daemon_bin(void)
{
    const char *b = getenv("SPECKLABD");
    return b && *b ? b : "bin/specklabd";
}

/* Start specklabd --foreground on a fresh dir; READY on its stdout (a
 * pipe) within 20 s, read with a bounded poll.  0, -1 (failed) or 1
 * (no daemon binary: skip). */
static int rd_start(rd *r)
{
    memset(r, 0, sizeof *r);
    if (access(daemon_bin(), X_OK) != 0)
        return 1;
    snprintf(r->s.dir, sizeof r->s.dir, "/tmp/test_cli_rd.XXXXXX");
    if (!mkdtemp(r->s.dir))
        return -1;
    snprintf(r->s.path, sizeof r->s.path, "%.40s/specklabd.sock", r->s.dir);
    char *conf = g_strdup_printf("%s/specklabd.conf", r->s.dir);
    char *text = g_strdup_printf(
        "[camera]\naddress=192.0.2.1\n"
        "[stage]\naddress=127.0.0.1:1\nmove_timeout_ms=1000\ncall_timeout_ms=500\n"
        "response_timeout_ms=200\n"
        "[paths]\ndata_dir=%s\n[daemon]\nsocket=%s\n", r->s.dir, r->s.path);
    int ok = g_file_set_contents(conf, text, -1, NULL);
    g_free(text);
    int p[2];
    if (!ok || pipe(p) < 0) {
        g_free(conf);
        return -1;
    }
    r->pid = fork();
    if (r->pid == 0) {
        dup2(p[1], 1);
        close(p[0]);
        close(p[1]);
        int nul = open("/dev/null", O_WRONLY);
        if (nul >= 0)
            dup2(nul, 2);
        execl(daemon_bin(), "specklabd", "--foreground", "--config", conf, (char *)NULL);
        _exit(127);
    }
    g_free(conf);
    close(p[1]);
    char buf[512];
    size_t have = 0;
    int ready = 0;
    for (int waited_ms = 0; r->pid > 0 && !ready && waited_ms < 20000; waited_ms += 100) {
        struct pollfd pf = {p[0], POLLIN, 0};
        if (poll(&pf, 1, 100) > 0) {
            ssize_t n = read(p[0], buf + have, sizeof buf - 1 - have);
            if (n <= 0)
                break; /* exited */
            have += (size_t)n;
            buf[have] = '\0';
            ready = strstr(buf, "READY") != NULL;
        }
    }
    close(p[0]); /* the daemon ignores SIGPIPE: later prints just fail */
    return ready ? 0 : -1;
}

static void rd_stop(rd *r)
{
    if (r->pid > 0) {
        kill(r->pid, SIGTERM);
        int st, k;
        for (k = 0; k < 150 && waitpid(r->pid, &st, WNOHANG) == 0; k++)
            poll(NULL, 0, 100); /* up to 15 s for a clean shutdown */
        if (k == 150) {
            kill(r->pid, SIGKILL);
            waitpid(r->pid, &st, 0);
        }
    }
    char *cmd = g_strdup_printf("rm -rf '%s'", r->s.dir);
    if (r->s.dir[0] && system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", r->s.dir);
    g_free(cmd);
}

TEST(real_daemon_queries_and_errors)
{
    rd r;
    int st = rd_start(&r);
    if (st == 1)
        SKIP("no daemon at %s (set SPECKLABD)", daemon_bin());
    if (st != 0) {
        rd_stop(&r);
        CHECK(0, "%s did not print READY within 20 s", daemon_bin());
    }
    char *o[7] = {0}, *e[7] = {0};
    int rc[7];
    rc[0] = run_cmd(&r.s, cmd_daemon, &o[0], &e[0], "specklab daemon", "status", NULL);
    rc[1] = run_cmd(&r.s, cmd_masks, &o[1], &e[1], "specklab masks", "list", "--json", NULL);
    rc[2] = run_cmd(&r.s, cmd_runs, &o[2], &e[2], "specklab runs", "list", "--since", "1d", NULL);
    rc[3] = run_cmd(&r.s, cmd_runs, &o[3], &e[3], "specklab runs", "show", "ffff", NULL);
    rc[4] = run_cmd(&r.s, cmd_export, &o[4], &e[4], "specklab export", "ffff", NULL);
    rc[5] = run_cmd(&r.s, cmd_experiment, &o[5], &e[5], "specklab experiment", "binary-bench",
                    "--screens", "nosuch", NULL);
    rc[6] = run_cmd(&r.s, cmd_screens, &o[6], &e[6], "specklab screens", "list", NULL);
    JsonNode *n = parse(o[1]);
    JsonArray *masks = n && JSON_NODE_HOLDS_OBJECT(n) ? dcmd_arr(json_node_get_object(n), "masks") : NULL;
    int nrm17 = 0;
    for (guint i = 0; masks && i < json_array_get_length(masks); i++) {
        JsonObject *m = json_array_get_object_element(masks, i);
        nrm17 |= !g_strcmp0(dcmd_str(m, "name"), "nrm17") && dcmd_int(m, "nholes", 0) == 17;
    }
    if (n)
        json_node_unref(n);
    rd_stop(&r);
    int good = rc[0] == 0 && strstr(o[0], "specklabd") && rc[1] == 0 && nrm17 && rc[2] == 0 &&
               strstr(o[2], "(no runs)") && rc[3] == 1 && e[3][0] && rc[4] == 1 && e[4][0] &&
               rc[5] == 1 && strstr(e[5], "no screen 'nosuch'") && rc[6] == 0 && strstr(o[6], "open");
    char msg[900];
    snprintf(msg, sizeof msg, "rc %d %d %d %d %d %d %d; status: %.120s; masks: %.120s; "
             "runs: %.80s; show: %.80s; experiment: %.120s", rc[0], rc[1], rc[2], rc[3], rc[4],
             rc[5], rc[6], o[0], o[1], o[2], e[3], e[5]);
    for (int i = 0; i < 7; i++) {
        g_free(o[i]);
        g_free(e[i]);
    }
    CHECK(good, "%s", msg);
}

TEST(real_daemon_failed_run_and_two_clients)
{
    rd r;
    int st = rd_start(&r);
    if (st == 1)
        SKIP("no daemon at %s (set SPECKLABD)", daemon_bin());
    if (st != 0) {
        rd_stop(&r);
        CHECK(0, "%s did not print READY within 20 s", daemon_bin());
    }
    /* Two connections, requests interleaved and pipelined: each reply
     * reaches the connection and the request it answers. */
    client *c1 = NULL, *c2 = NULL;
    sl_err err = {0};
    int routed = client_connect(&c1, r.s.path, 2000, &err) == SL_OK &&
                 client_connect(&c2, r.s.path, 2000, &err) == SL_OK;
    for (int k = 0; routed && k < 20; k++) {
        gint64 a = 0, b = 0, a2 = 0;
        JsonObject *ra = NULL, *rb = NULL, *ra2 = NULL;
        routed = client_send(c1, "masks", NULL, &a) == SL_OK &&
                 client_send(c2, "status", NULL, &b) == SL_OK &&
                 client_send(c1, "screens", NULL, &a2) == SL_OK &&
                 client_wait_reply(c2, b, 5000, &rb) == SL_OK &&
                 client_wait_reply(c1, a2, 5000, &ra2) == SL_OK &&
                 client_wait_reply(c1, a, 5000, &ra) == SL_OK &&
                 dcmd_arr(ra, "masks") && dcmd_str(rb, "version") && dcmd_arr(ra2, "screens");
        if (ra) json_object_unref(ra);
        if (rb) json_object_unref(rb);
        if (ra2) json_object_unref(ra2);
    }
    client_free(c1);
    client_free(c2);
    /* The stage cannot be reached: the run fails at the move, with the
     * reason, and the experiment says so in its exit status. */
    char *out = NULL, *e = NULL;
    int rc = run_cmd(&r.s, cmd_experiment, &out, &e, "specklab experiment", "binary-bench",
                     "--screens", "1", "--masks", "nrm17", "--frames", "5", "--timeout-s", "120",
                     "--json", NULL);
    rd_stop(&r);
    JsonNode *n = parse(out);
    JsonArray *a = n && JSON_NODE_HOLDS_OBJECT(n) ? dcmd_arr(json_node_get_object(n), "runs") : NULL;
    JsonObject *row = a && json_array_get_length(a) == 1 ? json_array_get_object_element(a, 0) : NULL;
    int failed = row && dcmd_int(json_node_get_object(n), "runs_not_done", -1) == 1 &&
                 !g_strcmp0(dcmd_str(row, "state"), "failed") &&
                 dcmd_str(row, "exit_reason") && strstr(dcmd_str(row, "exit_reason"), "stage");
    char msg[600];
    snprintf(msg, sizeof msg, "exit %d, stdout %.300s, stderr %.200s", rc, out, e);
    if (n)
        json_node_unref(n);
    g_free(out);
    g_free(e);
    CHECK(routed, "two clients: a reply went astray or failed: %s", err.msg);
    CHECK(rc == 1 && failed, "%s", msg);
}

/* `specklab binary` on a cube reconstructs it (direct, in memory) and
 * reports the image fit, the closure-phase fit and the verdict (measured,
 * from the closure phases); `recon -m direct --binary` leaves the same
 * fit and verdict in the image's header, which `binary` on that image
 * reports again.  Truth: the simulator's binary
 * (0.6", PA 140 deg, dm 1.5; the bounds are loose for 40 frames of 96^2). */
TEST(binary_of_a_cube_and_closure_keywords)
{
    sd s;
    CHECK(sd_start(&s) == 0, "stub daemon");
    char *cube = g_strdup_printf("%s/b.fits", s.dir), *img = g_strdup_printf("%s/r.fits", s.dir);
    char *out = NULL, *err = NULL, *out2 = NULL, *err2 = NULL;
    int rc = run_local(&s, cmd_sim, &out, &err, "specklab sim", "--scene", "binary",
                       "--sep-arcsec", "0.6", "--pa-deg", "140", "--dm-mag", "1.5", "--size", "96",
                       "--frames", "40", "-q", "-o", cube, NULL);
    g_free(out);
    g_free(err);
    out = err = NULL;
    int rc2 = rc ? rc : run_local(&s, cmd_binary, &out, &err, "specklab binary", cube, "--json", NULL);
    int rc3 = rc2 ? rc2 : run_local(&s, cmd_recon, &out2, &err2, "specklab recon", cube, "-m",
                                    "direct", "--binary", "-q", "-o", img, NULL);
    g_free(out2);
    g_free(err2);
    out2 = err2 = NULL;
    int rc4 = rc3 ? rc3 : run_local(&s, cmd_binary, &out2, &err2, "specklab binary", img, "--json", NULL);
    JsonNode *a = parse(out), *b = parse(out2);
    JsonObject *ca = NULL, *cb = NULL;
    if (a && JSON_NODE_HOLDS_OBJECT(a))
        ca = dcmd_obj(json_node_get_object(a), "closure_phase");
    if (b && JSON_NODE_HOLDS_OBJECT(b))
        cb = dcmd_obj(json_node_get_object(b), "closure_phase");
    double sep = ca ? dcmd_num(ca, "sep_arcsec") : NAN, pa = ca ? dcmd_num(ca, "pa_deg") : NAN;
    double dm = ca ? dcmd_num(ca, "dm_mag") : NAN;
    JsonObject *va = a && JSON_NODE_HOLDS_OBJECT(a) ? dcmd_obj(json_node_get_object(a), "binary") : NULL;
    JsonObject *vb = b && JSON_NODE_HOLDS_OBJECT(b) ? dcmd_obj(json_node_get_object(b), "binary") : NULL;
    int ok = ca && va && vb && !g_strcmp0(dcmd_str(va, "status"), "measured") &&
             !g_strcmp0(dcmd_str(va, "source"), "closure") &&
             !g_strcmp0(dcmd_str(vb, "status"), "measured");
    int same = ca && cb && fabs(dcmd_num(cb, "sep_px") - dcmd_num(ca, "sep_px")) < 1e-6 &&
               fabs(dcmd_num(cb, "dm_mag") - dcmd_num(ca, "dm_mag")) < 1e-6;
    char msg[700];
    snprintf(msg, sizeof msg, "exits %d %d %d %d; cube: %.300s %.100s; image: %.200s", rc, rc2,
             rc3, rc4, out, err, out2);
    if (a)
        json_node_unref(a);
    if (b)
        json_node_unref(b);
    g_free(out);
    g_free(err);
    g_free(out2);
    g_free(err2);
    unlink(cube);
    unlink(img);
    g_free(cube);
    g_free(img);
    sd_stop(&s);
    CHECK(rc == 0 && rc2 == 0 && rc3 == 0 && rc4 == 0 && ok, "%s", msg);
    CHECK(fabs(sep - 0.6) < 0.02 * 0.6 && fabs(pa - 140) < 1 && fabs(dm - 1.5) < 0.15,
          "closure: sep %.4f\" PA %.2f dm %.3f; %s", sep, pa, dm, msg);
    CHECK(same, "the image's CP* keywords differ from the cube's fit: %s", msg);
}

TC_MAIN(TC_CASE(binary_bench_json_one_row_per_run), TC_CASE(binary_bench_table_and_failed_run),
        TC_CASE(binary_bench_kind_reaches_every_run), TC_CASE(binary_bench_unknown_screen_starts_nothing), TC_CASE(runs_list_passes_filters),
        TC_CASE(runs_show_prefix_and_not_found), TC_CASE(export_copies_files_and_sidecar),
        TC_CASE(recon_run_new_reconstruction_and_copy), TC_CASE(not_running_and_run_id_shape),
        TC_CASE(real_daemon_queries_and_errors), TC_CASE(real_daemon_failed_run_and_two_clients),
        TC_CASE(binary_of_a_cube_and_closure_keywords))
