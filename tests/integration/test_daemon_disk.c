/* test_daemon_disk.c - the fault matrix's full disks: each case puts part
 * of the bench's data on a small tmpfs (bench_tmpfs: a private mount
 * namespace of the test child) and fills it, then checks the run's state
 * and reason in the catalogue, the cube against the catalogue, and its
 * FRAMES table against the cube.
 *   frames_past_cube_end  the cubes' disk fills mid-run (the catalogue is
 *                         elsewhere): the run fails, frames_acquired is
 *                         the cube's NAXIS3 and no FRAMES row names a
 *                         frame past the cube's end.
 */
#include "daemon_fx.h"
#include "matrix_fx.h"

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

TEST(frames_past_cube_end) { fx_in_netns(t, frames_past_cube_end_run, 120); }

TC_MAIN(TC_CASE(frames_past_cube_end))
