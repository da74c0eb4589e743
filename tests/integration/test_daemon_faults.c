/* test_daemon_faults.c - specklabd's robustness cases (issue 5, item 5),
 * each on its own simulated bench (daemon_fx.h):
 *   camera_vanishes   the fake camera is killed mid-run: the run fails
 *                     with "camera lost after N of M frames", exactly the
 *                     N frames are kept in a readable .part cube and
 *                     catalogued with its checksum, the daemon stays up,
 *                     and the next run works once the camera is back;
 *   stage_fault       a stalled wheel faults: the run fails before
 *                     acquiring (no cube), and so does the next run while
 *                     the wheel stays faulted;
 *   stage_timeout     a move that never ends, and a stage that is gone:
 *                     failed before acquiring, within the bound;
 *   sigkill_restart   the daemon is SIGKILLed mid-acquisition: after a
 *                     restart the run is 'interrupted', its cube opens
 *                     with at least every frame a progress event
 *                     announced, the catalogue counts exactly what is on
 *                     disk and passes PRAGMA integrity_check;
 *   disk_full         RLIMIT_FSIZE lowered on the running daemon: the run
 *                     fails cleanly, its cube holds the frames that fit,
 *                     the catalogue is consistent, and after the limit is
 *                     lifted the next run works;
 *   socket_access     a uid outside the daemon's group is refused
 *                     (EACCES) and one inside it is served.
 */
#include "daemon_fx.h"

#include <grp.h>
#include <sys/resource.h>

static int has(const char *hay, const char *needle)
{
    return hay && needle && strstr(hay, needle) != NULL;
}

/* Start a run and return its uuid in out (0), after subscribing. */
static int start(bench *b, dc *c, const char *args, char out[40])
{
    JsonNode *r = keep(b, dc_call(c, "start-run", args, 5));
    if (!jok(r))
        return -1;
    snprintf(out, 40, "%s", js(r, "result.run"));
    return 0;
}

/* The run's catalogue row must match its file: path, frames in the cube,
 * checksum; integrity_check ok.  The file is returned in file. */
static int run_matches_disk(tc *t, bench *b, const char *uuid, catalog_state want,
                            const char *reason, int *frames, char *file, size_t n)
{
    catalog_run cr;
    char msg[512], hex[65] = "";
    long n3 = -1, rows = -1;
    if (fx_catalog_run(b, uuid, &cr, msg, sizeof msg) != 0) {
        tc_note(t, 0, __FILE__, __LINE__, "catalogue", "%s", msg);
        return -1;
    }
    snprintf(file, n, "%s", cr.file_path ? cr.file_path : "");
    int ok = cr.state == want && has(cr.exit_reason, reason) && cr.file_path &&
             fx_sha256(cr.file_path, hex) == 0 && cr.file_sha256 &&
             !strcmp(hex, cr.file_sha256) &&
             fx_fits(cr.file_path, &n3, &rows, msg, sizeof msg) == 0 &&
             n3 == cr.frames_acquired;
    if (!ok)
        tc_note(t, 0, __FILE__, __LINE__, "catalogue vs disk",
                "run %s: state %s (want %s), reason '%s' (want '%s'), file %s, sha %s vs %s, "
                "cube %ld frames vs catalogue %d (%s)", uuid, catalog_state_name(cr.state),
                catalog_state_name(want), cr.exit_reason ? cr.exit_reason : "", reason, file,
                cr.file_sha256 ? cr.file_sha256 : "(none)", hex, n3, cr.frames_acquired,
                n3 < 0 ? msg : "");
    *frames = cr.frames_acquired;
    catalog_run_clear(&cr);
    return ok ? 0 : -1;
}

BENCH_NET_TEST(camera_vanishes, 120, NULL, NULL)
{
    dc *c = bench_client(b);
    char uuid[40], file[400];
    CHECK(c && bench_wait_camera(b, c, 20) == 0, "no daemon or no camera");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    CHECK(start(b, c, "{\"screen\": 2, \"mask\": 0, \"frames\": 3000}", uuid) == 0, "start-run");
    gint64 told = dc_wait_progress(c, uuid, 30, 30);
    CHECK(told >= 30, "no progress to 30 frames");
    fx_stop(&b->cam, SIGKILL, 5);
    double t0 = fx_now();
    JsonNode *e = keep(b, dc_wait_state(c, uuid, "failed,aborted,stored", 30, NULL, &told));
    CHECK(e && has(js(e, "state"), "failed"), "end: %s", jtext(e));
    const char *why = js(e, "reason");
    int n = -1, of = -1;
    CHECK(why && sscanf(why, "camera lost after %d of %d frames", &n, &of) == 2 && of == 3000,
          "reason: %s", why ? why : "(none)");
    CHECK(fx_now() - t0 < 15, "took %.1f s to notice", fx_now() - t0);
    int frames;
    if (run_matches_disk(t, b, uuid, CATALOG_FAILED, "camera lost", &frames, file,
                         sizeof file) != 0)
        return;
    CHECK(frames == n && n >= told && g_str_has_suffix(file, ".fits.part"),
          "reason says %d frames, catalogue %d, last progress %lld, file %s", n, frames,
          (long long)told, file);
    JsonNode *r = keep(b, dc_call(c, "status", NULL, 5));
    CHECK(jok(r) && has(js(r, "result.state"), "idle"), "status after the loss: %s", jtext(r));
    CHECK(bench_start_camera(b) == 0, "fake camera did not restart");
    CHECK(start(b, c, "{\"screen\": 1, \"mask\": 0, \"frames\": 20, \"reconstruct\": \"none\"}",
                uuid) == 0, "start-run after restart");
    e = keep(b, dc_wait_state(c, uuid, "done,failed,aborted", 60, NULL, NULL));
    CHECK(e && has(js(e, "state"), "done"), "run after the camera came back: %s", jtext(e));
}

static const char *const stall_short[] = {"--stall", "--stall-ms", "300", NULL};

BENCH_TEST(stage_fault, 60, stall_short, NULL)
{
    dc *c = bench_client(b);
    char uuid[40];
    CHECK(c, "cannot connect");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    for (int k = 0; k < 2; k++) {
        GString *seen = g_string_new(NULL);
        CHECK(start(b, c, "{\"screen\": 3, \"mask\": 1, \"frames\": 10}", uuid) == 0, "start-run");
        JsonNode *e = keep(b, dc_wait_state(c, uuid, "failed,aborted,stored,done", 30, seen, NULL));
        char states[200];
        snprintf(states, sizeof states, "%s", seen->str);
        g_string_free(seen, TRUE);
        CHECK(e && has(js(e, "state"), "failed") && !strcmp(states, "queued,moving,failed"),
              "run %d: states %s, end %s", k, states, jtext(e));
        /* First the stall itself, then the wheel it left faulted. */
        CHECK(has(js(e, "reason"), k == 0 ? "stall" : "faulted"), "run %d reason: %s", k,
              js(e, "reason"));
        char args[80];
        snprintf(args, sizeof args, "{\"run\": \"%s\"}", uuid);
        JsonNode *r = keep(b, dc_call(c, "run", args, 5));
        CHECK(jok(r) && jnull(r, "result.run.file") && ji(r, "result.run.frames_acquired") == 0,
              "a run that failed moving has a file: %s", jtext(r));
    }
    JsonNode *r = keep(b, dc_call(c, "devices", NULL, 10));
    CHECK(jok(r) && has(js(r, "result.stage.wheels.0.status"), "faulted"), "devices: %s",
          jtext(r));
}

static const char *const stall_long[] = {"--stall", "--stall-ms", "60000", NULL};

BENCH_TEST(stage_timeout, 60, stall_long, "[stage]\nmove_timeout_ms=800\n")
{
    dc *c = bench_client(b);
    char uuid[40];
    CHECK(c, "cannot connect");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    CHECK(start(b, c, "{\"screen\": 1, \"mask\": 0, \"frames\": 10}", uuid) == 0, "start-run");
    double t0 = fx_now();
    JsonNode *e = keep(b, dc_wait_state(c, uuid, "failed,aborted,stored,done", 30, NULL, NULL));
    CHECK(e && has(js(e, "state"), "failed") && has(js(e, "reason"), "stage"),
          "stalled move: %s", jtext(e));
    CHECK(fx_now() - t0 < 10, "the 0.8 s move bound took %.1f s", fx_now() - t0);
    /* The stage vanishes altogether. */
    fx_stop(&b->stage, SIGKILL, 5);
    CHECK(start(b, c, "{\"screen\": 2, \"mask\": 0, \"frames\": 10}", uuid) == 0, "start-run");
    GString *seen = g_string_new(NULL);
    e = keep(b, dc_wait_state(c, uuid, "failed,aborted,stored,done", 30, seen, NULL));
    char states[200];
    snprintf(states, sizeof states, "%s", seen->str);
    g_string_free(seen, TRUE);
    CHECK(e && has(js(e, "state"), "failed") && has(js(e, "reason"), "stage") &&
              !strcmp(states, "queued,moving,failed"),
          "stage gone: %s (states %s)", jtext(e), states);
}

BENCH_TEST(sigkill_restart, 120, NULL, NULL)
{
    dc *c = bench_client(b);
    char uuid[40], file[400];
    CHECK(c && bench_wait_camera(b, c, 20) == 0, "no daemon or no camera");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    CHECK(start(b, c, "{\"screen\": 4, \"mask\": 0, \"frames\": 3000}", uuid) == 0, "start-run");
    gint64 told = dc_wait_progress(c, uuid, 25, 30);
    CHECK(told >= 25, "no progress to 25 frames");
    fx_stop(&b->daemon, SIGKILL, 5);
    CHECK(bench_start_daemon(b) == 0, "the daemon did not restart");
    int frames;
    if (run_matches_disk(t, b, uuid, CATALOG_INTERRUPTED, "daemon restarted while acquiring",
                         &frames, file, sizeof file) != 0)
        return;
    CHECK(frames >= told && frames < 3000 && g_str_has_suffix(file, ".fits.part"),
          "%d frames on disk, %lld announced, file %s", frames, (long long)told, file);
    dc *c2 = bench_client(b);
    CHECK(c2, "cannot connect to the restarted daemon");
    char args[80];
    snprintf(args, sizeof args, "{\"run\": \"%s\"}", uuid);
    JsonNode *r = keep(b, dc_call(c2, "run", args, 5));
    CHECK(jok(r) && has(js(r, "result.run.state"), "interrupted") &&
              ji(r, "result.run.frames_acquired") == frames,
          "run after restart: %s", jtext(r));
    keep(b, dc_call(c2, "subscribe", NULL, 5));
    CHECK(start(b, c2, "{\"screen\": 1, \"mask\": 0, \"frames\": 20, \"reconstruct\": \"none\"}",
                uuid) == 0, "start-run after restart");
    JsonNode *e = keep(b, dc_wait_state(c2, uuid, "done,failed,aborted", 60, NULL, NULL));
    CHECK(e && has(js(e, "state"), "done"), "run after restart: %s", jtext(e));
}

static off_t file_size(const char *dir, const char *name)
{
    char p[400];
    struct stat st;
    snprintf(p, sizeof p, "%s/%s", dir, name);
    return stat(p, &st) == 0 ? st.st_size : 0;
}

static int set_fsize(pid_t pid, rlim_t soft)
{
    struct rlimit rl;
    if (prlimit(pid, RLIMIT_FSIZE, NULL, &rl) != 0)
        return -1;
    rl.rlim_cur = soft;
    return prlimit(pid, RLIMIT_FSIZE, &rl, NULL);
}

static void disk_full_body(tc *t, bench *b)
{
    dc *c = bench_client(b);
    char uuid[40], file[400];
    CHECK(c && bench_wait_camera(b, c, 20) == 0, "no daemon or no camera");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    /* A first run grows the catalogue's WAL to its working size, so the
     * limit below hits the cube, not SQLite. */
    CHECK(start(b, c, "{\"screen\": 1, \"mask\": 0, \"frames\": 10, \"reconstruct\": \"none\"}",
                uuid) == 0, "start-run");
    JsonNode *e = keep(b, dc_wait_state(c, uuid, "done,failed,aborted", 60, NULL, NULL));
    CHECK(e && has(js(e, "state"), "done"), "first run: %s", jtext(e));
    off_t db = file_size(b->data, "specklab.db"), wal = file_size(b->data, "specklab.db-wal");
    rlim_t limit = (rlim_t)(db > wal ? db : wal) + (512 << 10);
    long frame_bytes = 128L * 128 * 2, want = (long)limit / frame_bytes + 60;
    CHECK(set_fsize(b->daemon.pid, limit) == 0, "prlimit: %s", strerror(errno));
    char args[160];
    snprintf(args, sizeof args, "{\"screen\": 2, \"mask\": 0, \"frames\": %ld, "
             "\"reconstruct\": \"none\"}", want);
    CHECK(start(b, c, args, uuid) == 0, "start-run");
    e = keep(b, dc_wait_state(c, uuid, "failed,done,aborted,stored", 60, NULL, NULL));
    CHECK(e && has(js(e, "state"), "failed") && has(js(e, "reason"), "writing the cube failed"),
          "disk full: %s", jtext(e));
    int frames;
    if (run_matches_disk(t, b, uuid, CATALOG_FAILED, "writing the cube failed", &frames, file,
                         sizeof file) != 0)
        return;
    CHECK(frames > 0 && (rlim_t)frames * (rlim_t)frame_bytes <= limit,
          "%d frames of %ld bytes under a %lu-byte limit", frames, frame_bytes,
          (unsigned long)limit);
    CHECK(set_fsize(b->daemon.pid, RLIM_INFINITY) == 0, "prlimit: %s", strerror(errno));
    CHECK(start(b, c, "{\"screen\": 1, \"mask\": 0, \"frames\": 10, \"reconstruct\": \"none\"}",
                uuid) == 0, "start-run");
    e = keep(b, dc_wait_state(c, uuid, "done,failed,aborted", 60, NULL, NULL));
    CHECK(e && has(js(e, "state"), "done"), "run after space came back: %s", jtext(e));
}

/* 128x128 frames (32 KiB) so the limit is crossed within a short run. */
static void disk_full_run(tc *t)
{
    bench b;
    if (bench_init(&b) != 0) {
        tc_note(t, 0, __FILE__, __LINE__, "bench_init", "mkdtemp failed");
        return;
    }
    snprintf(b.cam_size, sizeof b.cam_size, "128");
    if (bench_start_stage(&b, NULL) || bench_start_camera(&b) || bench_write_config(&b, NULL) ||
        bench_start_daemon(&b))
        tc_note(t, 0, __FILE__, __LINE__, "bench", "bench did not start");
    else
        disk_full_body(t, &b);
    bench_check_stop(t, &b);
    bench_down(&b, t->failed);
}

TEST(disk_full) { fx_in_child(t, disk_full_run, 120); }

/* In a forked child: become uid 65534 with gid, connect, and (when
 * served) ask for status.  Exit 0 when connected and answered, else the
 * connect errno (or 100 for no answer). */
static int try_as(const char *sock, gid_t gid)
{
    pid_t pid = fork();
    if (pid == 0) {
        dc c;
        if (setgroups(0, NULL) != 0 || setgid(gid) != 0 || setuid(65534) != 0)
            _exit(101);
        int rc = dc_connect(&c, sock);
        if (rc != 0)
            _exit(-rc);
        JsonNode *r = dc_call(&c, "status", NULL, 5);
        _exit(jok(r) ? 0 : 100);
    }
    int st = 0;
    waitpid(pid, &st, 0);
    return WIFEXITED(st) ? WEXITSTATUS(st) : 102;
}

BENCH_TEST(socket_access, 60, NULL, NULL)
{
    struct stat st;
    if (geteuid() != 0 || getuid() != 0)
        SKIP("needs root to act as another uid (setuid 65534)");
    CHECK(stat(b->sock, &st) == 0 && S_ISSOCK(st.st_mode) && (st.st_mode & 0777) == 0660 &&
              st.st_uid == geteuid() && st.st_gid == getegid(),
          "socket mode %o uid %d gid %d", st.st_mode & 0777, (int)st.st_uid, (int)st.st_gid);
    /* Let anyone reach the socket's directory, so the socket's own mode is
     * what decides. */
    CHECK(chmod(b->dir, 0711) == 0 && chmod(b->data, 0711) == 0, "chmod: %s", strerror(errno));
    int outsider = try_as(b->sock, 65534);
    CHECK(outsider == EACCES, "uid/gid 65534 outside the group: got %d (%s), want EACCES",
          outsider, outsider < 100 ? strerror(outsider) : "see try_as");
    int member = try_as(b->sock, st.st_gid);
    CHECK(member == 0, "uid 65534 in the daemon's group %d: got %d", (int)st.st_gid, member);
}

TC_MAIN(TC_CASE(camera_vanishes), TC_CASE(stage_fault), TC_CASE(stage_timeout),
        TC_CASE(sigkill_restart), TC_CASE(disk_full), TC_CASE(socket_access))
