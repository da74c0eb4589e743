/* test_daemon_u3v.c - specklabd with a USB3 Vision camera: the bench of
 * daemon_fx.h with bin/specklab-fake-u3v in place of the GigE fake camera
 * (cam_u3v), the daemon under umockdev's preload on the camera's
 * testbed, configured with the camera's Aravis id.  The checks are the
 * GigE runs' (matrix_fx.h): the catalogue against the cube, the cube's
 * FRAMES table against the catalogue's counters, every stored frame
 * against the simulator bit for bit.
 *
 * The U3V camera's beam is fixed (screen slot 1, mask slot 0): runs ask
 * for that configuration, so SCRSLOT/MSKSLOT name what it rendered.
 */
#include "daemon_fx.h"
#include "matrix_fx.h"

#define U3V_CONF "[camera]\naddress=" FX_U3V_ID "\nlost_timeout_s=3\n"

static void u3v_bench(bench *b)
{
    b->cam_u3v = 1;
}

/* 200 frames through the daemon: done, catalogue = cube = FRAMES, every
 * frame the simulator's, no id gap. */
BENCH_TEST_WITH(u3v_run_200, 120, u3v_bench, NULL, U3V_CONF)
{
    dc *c = bench_client(b);
    CHECK(c, "cannot connect to %s", b->sock);
    CHECK(bench_wait_camera(b, c, 20) == 0, "the daemon never reported the U3V camera");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    char uuid[40];
    CHECK(mx_start(b, c, "{\"screen\": 1, \"mask\": 0, \"frames\": 200, "
                   "\"reconstruct\": \"none\"}", uuid) == 0, "start-run refused");
    JsonNode *e = mx_wait_end(b, c, uuid, 90, NULL);
    CHECK(e && !g_strcmp0(js(e, "state"), "done"), "run ended %s", jtext(e));
    char args[80];
    snprintf(args, sizeof args, "{\"run\": \"%s\"}", uuid);
    JsonNode *r = keep(b, dc_call(c, "run", args, 5));
    CHECK(jok(r) && !g_strcmp0(js(r, "result.run.camera_serial"), FX_U3V_SERIAL),
          "run: %s", jtext(r));
    mx_seen v;
    if (mx_check_run(t, b, uuid, CATALOG_DONE, NULL, &v) != 0)
        return;
    CHECK(v.frames == 200 && v.n3 == 200 && v.failed == 0 && v.rows == 200,
          "catalogue %d frames (%d failed), cube %ld, FRAMES %ld rows", v.frames, v.failed, v.n3,
          v.rows);
    if (mx_check_frames(t, b, &v) != 0 || mx_check_cube_idx(t, &v, NULL) != 0)
        return;
}

int main(int argc, char **argv)
{
    static const tc_case cases[] = {
        TC_CASE(u3v_run_200),
    };
    return tc_main(argv[0], argc, argv, cases, (int)(sizeof cases / sizeof cases[0]));
}
