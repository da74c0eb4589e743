/* test_daemon_disk.c - the fault matrix's full disks: each case puts part
 * of the bench's data on a small tmpfs (bench_tmpfs: a private mount
 * namespace of the test child) and fills it, then checks the run's state
 * and reason in the catalogue, the cube against the catalogue, and its
 * FRAMES table against the cube.
 *   frames_past_cube_end  the cubes' disk fills mid-run (the catalogue is
 *                         elsewhere): the run fails, frames_acquired is
 *                         the cube's NAXIS3 and no FRAMES row names a
 *                         frame past the cube's end;
 *   catalog_on_full_disk  the catalogue shares the disk the cube fills:
 *                         the run's end is recorded and announced within
 *                         10 s with the disk-full reason, the run is no
 *                         longer in hand, and once there is room again the
 *                         daemon holds its reserve anew and runs work;
 *   catalog_disk_fills    the catalogue's own disk fills while a run
 *                         acquires (cubes elsewhere): the daemon releases
 *                         its reserve to record the run's end (done, all
 *                         frames), refuses the next run until there is
 *                         room again, saying why, then works.
 */
#include "daemon_fx.h"
#include "matrix_fx.h"

#include <sys/statvfs.h>

/* The bench with the cubes (DATA/runs) on a tmpfs of size_kb: stage,
 * camera, config (conf), tmpfs, daemon.  0; -1 noted or skipped. */
static int runs_on_tmpfs(tc *t, bench *b, long size_kb, const char *conf)
{
    char why[300], runs[256];
    if (bench_init(b) != 0) {
        tc_note(t, 0, __FILE__, __LINE__, "bench_init", "mkdtemp failed");
        return -1;
    }
    snprintf(runs, sizeof runs, "%s/runs", b->data);
    if (bench_tmpfs(b, runs, size_kb, why, sizeof why) != 0) {
        tc_note(t, 1, __FILE__, __LINE__, "", "%s", why);
        return -1;
    }
    if (bench_start_stage(b, NULL) || bench_start_camera(b) || bench_write_config(b, conf) ||
        bench_start_daemon(b)) {
        tc_note(t, 0, __FILE__, __LINE__, "bench", "bench did not start");
        return -1;
    }
    return 0;
}

/* The bench with the whole data directory (cubes and catalogue) on a
 * tmpfs of size_kb. */
static int data_on_tmpfs(tc *t, bench *b, long size_kb, const char *conf)
{
    char why[300];
    if (bench_init(b) != 0) {
        tc_note(t, 0, __FILE__, __LINE__, "bench_init", "mkdtemp failed");
        return -1;
    }
    if (bench_tmpfs(b, b->data, size_kb, why, sizeof why) != 0) {
        tc_note(t, 1, __FILE__, __LINE__, "", "%s", why);
        return -1;
    }
    if (bench_start_stage(b, NULL) || bench_start_camera(b) || bench_write_config(b, conf) ||
        bench_start_daemon(b)) {
        tc_note(t, 0, __FILE__, __LINE__, "bench", "bench did not start");
        return -1;
    }
    return 0;
}

/* Fill the filesystem of dir with path until leave_kb KiB are free. */
static int fill_disk(const char *dir, const char *path, long leave_kb)
{
    struct statvfs v;
    if (statvfs(dir, &v) != 0)
        return -1;
    long long room = (long long)v.f_bavail * (long long)v.f_frsize - leave_kb * 1024LL;
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    int rc = fd >= 0 && (room <= 0 || posix_fallocate(fd, 0, (off_t)room) == 0) ? 0 : -1;
    if (fd >= 0)
        close(fd);
    return rc;
}

/* ---- the cubes' disk fills ------------------------------------------------ */

/* 64x64 Mono16 frames (8 KiB) at 100 Hz: cfitsio holds about ten frames
 * between two flushes (its 40 buffers of 2880 bytes take 14), so the
 * disk runs out in a flush, with frames counted by the frame loop that
 * never reach the disk. */
static void past_end_body(tc *t, bench *b)
{
    dc *c = bench_client(b);
    char uuid[40];
    CHECK(c && bench_wait_camera(b, c, 20) == 0, "no daemon or no camera");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    CHECK(mx_start(b, c, "{\"screen\": 2, \"mask\": 0, \"frames\": 5000, \"reconstruct\": "
                   "\"none\"}", uuid) == 0, "start-run");
    JsonNode *e = mx_wait_end(b, c, uuid, 60, NULL);
    CHECK(e && !g_strcmp0(js(e, "state"), "failed") &&
              strstr(mx_str(js(e, "reason")), "writing the cube failed"),
          "end: %s", jtext(e));
    mx_seen v;
    long lost = -1;
    if (mx_check_run(t, b, uuid, CATALOG_FAILED, "writing the cube failed", &v) ||
        mx_check_cube_idx(t, &v, &lost))
        return;
    printf("note: %s: %d frames in the cube, %ld delivered but not on disk: %s\n", uuid,
           v.frames, lost, mx_str(js(e, "reason")));
    CHECK(v.frames > 0 && g_str_has_suffix(v.file, ".fits.part"), "%d frames in %s",
          v.frames, v.file);
}

static void frames_past_cube_end_run(tc *t)
{
    bench b;
    if (runs_on_tmpfs(t, &b, 1024, NULL) == 0)
        past_end_body(t, &b);
    bench_check_stop(t, &b);
    bench_down(&b, t->failed);
}

TEST(frames_past_cube_end) { fx_in_child(t, frames_past_cube_end_run, 120); }

/* ---- the catalogue's disk fills -------------------------------------------- */

static void catalog_full_body(tc *t, bench *b)
{
    dc *c = bench_client(b);
    char uuid[40], args[80], fill[300], res[300];
    struct stat st;
    CHECK(c && bench_wait_camera(b, c, 20) == 0, "no daemon or no camera");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    /* After a first run the catalogue's WAL keeps growing with every
     * transaction (it is checkpointed at 1000 pages), so once the disk is
     * full each catalogue write needs room there is not. */
    CHECK(mx_start(b, c, "{\"screen\": 1, \"mask\": 0, \"frames\": 20, \"reconstruct\": "
                   "\"none\"}", uuid) == 0, "start-run");
    JsonNode *e = mx_wait_end(b, c, uuid, 60, NULL);
    CHECK(e && !g_strcmp0(js(e, "state"), "done"), "first run: %s", jtext(e));
    snprintf(fill, sizeof fill, "%s/filler", b->data);
    CHECK(fill_disk(b->data, fill, 96) == 0, "filling %s: %s", b->data, strerror(errno));
    double t0 = fx_now();
    CHECK(mx_start(b, c, "{\"screen\": 2, \"mask\": 0, \"frames\": 30, \"reconstruct\": "
                   "\"none\"}", uuid) == 0, "start-run on the nearly full disk");
    e = mx_wait_end(b, c, uuid, 30, NULL);
    double dt = fx_now() - t0;
    CHECK(e && !g_strcmp0(js(e, "state"), "failed") &&
              strstr(mx_str(js(e, "reason")), "No space left on device"),
          "end on the full disk: %s", jtext(e));
    CHECK(dt < 10, "its end was announced after %.1f s", dt);
    mx_seen v;
    if (mx_check_run(t, b, uuid, CATALOG_FAILED, "No space left on device", &v) ||
        mx_check_cube_idx(t, &v, NULL))
        return;
    printf("note: %s: failed after %.1f s with %d frames: %s\n", uuid, dt, v.frames,
           mx_str(js(e, "reason")));
    JsonNode *r = keep(b, dc_call(c, "status", NULL, 5));
    CHECK(jok(r) && jnull(r, "result.current_run") && !g_strcmp0(js(r, "result.state"), "idle"),
          "status after: %s", jtext(r));
    snprintf(args, sizeof args, "{\"run\": \"%s\"}", uuid);
    r = keep(b, dc_call(c, "abort-run", args, 10));
    CHECK(!jok(r) && strstr(mx_str(js(r, "error.message")), "already failed"),
          "abort-run of the failed run: %s", jtext(r));
    /* Room again: the reserve is made anew and runs work. */
    CHECK(unlink(fill) == 0, "unlink %s: %s", fill, strerror(errno));
    mx_next_run_done(t, b, c);
    snprintf(res, sizeof res, "%s/specklab.db.reserve", b->data);
    CHECK(stat(res, &st) == 0 && st.st_size == 1 << 20, "the catalogue's reserve %s is not "
          "back", res);
}

static void catalog_on_full_disk_run(tc *t)
{
    bench b;
    if (data_on_tmpfs(t, &b, 8192, NULL) == 0)
        catalog_full_body(t, &b);
    bench_check_stop(t, &b);
    bench_down(&b, t->failed);
}

TEST(catalog_on_full_disk) { fx_in_child(t, catalog_on_full_disk_run, 150); }

/* The catalogue (and its reserve) on a tmpfs of its own, filled once the
 * run acquires: every catalogue write from there needs room. */
static void catalog_fills_body(tc *t, bench *b, const char *catdir)
{
    dc *c = bench_client(b), *q = bench_client(b);
    char uuid[40], fill[300];
    CHECK(c && q && bench_wait_camera(b, c, 20) == 0, "no daemon or no camera");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    CHECK(mx_start(b, c, "{\"screen\": 1, \"mask\": 0, \"frames\": 300, \"reconstruct\": "
                   "\"none\"}", uuid) == 0, "start-run");
    mx_want w = {.run = uuid, .state = "acquiring", .frames = 20};
    CHECK(mx_poll_status(b, q, mx_is_current, &w, 30), "status never showed %s acquiring", uuid);
    snprintf(fill, sizeof fill, "%s/filler", catdir);
    CHECK(fill_disk(catdir, fill, 0) == 0, "filling %s: %s", catdir, strerror(errno));
    JsonNode *e = mx_wait_end(b, c, uuid, 30, NULL);
    CHECK(e && !g_strcmp0(js(e, "state"), "done"), "end with the catalogue's disk full: %s",
          jtext(e));
    mx_seen v;
    if (mx_check_run(t, b, uuid, CATALOG_DONE, NULL, &v))
        return;
    CHECK(v.frames == 300 && g_str_has_suffix(v.file, ".fits") && v.rows >= 300,
          "%d frames in %s, %ld FRAMES rows", v.frames, v.file, v.rows);
    CHECK(mx_log_has(b, "released the catalogue's reserve"), "the log never says the "
          "reserve was used");
    /* The reserve is spent and cannot be made again: no run starts. */
    JsonNode *r = keep(b, dc_call(c, "start-run", "{\"screen\": 2, \"mask\": 0, \"frames\": "
                                  "10, \"reconstruct\": \"none\"}", 10));
    e = jok(r) ? mx_wait_end(b, c, js(r, "result.run"), 30, NULL) : NULL;
    CHECK(e && !g_strcmp0(js(e, "state"), "failed") &&
              strstr(mx_str(js(e, "reason")), "no room for the catalogue's"),
          "a run while the catalogue's disk is full: %s, %s", jtext(r), jtext(e));
    CHECK(unlink(fill) == 0, "unlink %s: %s", fill, strerror(errno));
    mx_next_run_done(t, b, c);
}

static void catalog_disk_fills_run(tc *t)
{
    bench b;
    char why[300], catdir[256], conf[400];
    if (bench_init(&b) != 0) {
        tc_note(t, 0, __FILE__, __LINE__, "bench_init", "mkdtemp failed");
        return;
    }
    snprintf(catdir, sizeof catdir, "%s/cat", b.dir);
    snprintf(b.db, sizeof b.db, "%s/specklab.db", catdir);
    snprintf(conf, sizeof conf, "[paths]\ncatalog=%s\n", b.db);
    if (bench_tmpfs(&b, catdir, 8192, why, sizeof why) != 0)
        tc_note(t, 1, __FILE__, __LINE__, "", "%s", why);
    else if (bench_start_stage(&b, NULL) || bench_start_camera(&b) ||
             bench_write_config(&b, conf) || bench_start_daemon(&b))
        tc_note(t, 0, __FILE__, __LINE__, "bench", "bench did not start");
    else
        catalog_fills_body(t, &b, catdir);
    bench_check_stop(t, &b);
    bench_down(&b, t->failed);
}

TEST(catalog_disk_fills) { fx_in_child(t, catalog_disk_fills_run, 150); }

TC_MAIN(TC_CASE(frames_past_cube_end), TC_CASE(catalog_on_full_disk),
        TC_CASE(catalog_disk_fills))
