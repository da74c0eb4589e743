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
BENCH_NET_TEST_WITH(u3v_run_200, 120, u3v_bench, NULL, U3V_CONF)
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

/* `specklab devices --json ARGS` under the preload on the camera's
 * testbed: its JSON (kept), or NULL. */
static JsonNode *devices_json(bench *b, const char *a1, const char *a2)
{
    char bin[PATH_MAX], buf[65536];
    char *argv[] = {bin, "devices", "--json", "--no-stage", (char *)a1, (char *)a2, NULL};
    fx_proc p;
    size_t len = 0;
    ssize_t n;
    fx_bin(bin, sizeof bin, "specklab");
    if (fx_spawn(&p, argv, NULL, bench_preload_daemon, b->preload) != 0)
        return NULL;
    while (len + 1 < sizeof buf && (n = read(p.out, buf + len, sizeof buf - 1 - len)) > 0)
        len += (size_t)n;
    buf[len] = 0;
    fx_stop(&p, SIGKILL, 10);
    return keep(b, json_from_string(buf, NULL));
}

/* Cameras that `specklab devices` lists with the U3V mock's serial. */
static int devices_has_camera(bench *b)
{
    JsonNode *d = devices_json(b, NULL, NULL);
    JsonNode *cams = d ? jget(d, "cameras") : NULL;
    int n = 0;
    for (guint i = 0; cams && JSON_NODE_HOLDS_ARRAY(cams) &&
                      i < json_array_get_length(json_node_get_array(cams)); i++) {
        JsonObject *o = json_array_get_object_element(json_node_get_array(cams), i);
        n += !g_strcmp0(json_object_get_string_member_with_default(o, "serial", ""),
                        FX_U3V_SERIAL);
    }
    return d ? n : -1;
}

/* The camera unplugged mid-run: the run fails at once, its reason says
 * unplugged, every frame it had is kept (catalogue = cube = FRAMES, the
 * simulator's pixels); the daemon and `specklab devices` show it gone.
 * Plugged back: the daemon reopens it by itself and the next run is
 * done, without a restart. */
BENCH_NET_TEST_WITH(u3v_unplug_mid_run, 120, u3v_bench, NULL, U3V_CONF)
{
    dc *c = bench_client(b);
    CHECK(c, "cannot connect to %s", b->sock);
    CHECK(bench_wait_camera(b, c, 20) == 0, "the daemon never reported the U3V camera");
    CHECK(devices_has_camera(b) == 1, "specklab devices does not list the plugged camera");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    char uuid[40];
    CHECK(mx_start(b, c, "{\"screen\": 1, \"mask\": 0, \"frames\": 5000, "
                   "\"reconstruct\": \"none\"}", uuid) == 0, "start-run refused");
    mx_want w = {uuid, "acquiring", 50};
    CHECK(mx_poll_status(b, c, mx_is_current, &w, 30), "the run never reached 50 frames");
    CHECK(fx_u3v_command(&b->u3v, "unplug", "UNPLUGGED") == 0, "the camera did not unplug");
    JsonNode *e = mx_wait_end(b, c, uuid, 30, NULL);
    CHECK(e && !g_strcmp0(js(e, "state"), "failed") && strstr(mx_str(js(e, "reason")), "unplugged"),
          "after the unplug the run ended %s", jtext(e));
    mx_seen v;
    if (mx_check_run(t, b, uuid, CATALOG_FAILED, "unplugged", &v) != 0)
        return;
    CHECK(v.frames >= 50 && v.n3 == v.frames, "kept %d frames (cube %ld)", v.frames, v.n3);
    if (mx_check_frames(t, b, &v) != 0 || mx_check_cube_idx(t, &v, NULL) != 0)
        return;
    JsonNode *r = keep(b, dc_call(c, "devices", NULL, 10));
    CHECK(jok(r) && !jget(r, "result.camera.connected") == 0 &&
              !json_node_get_boolean(jget(r, "result.camera.connected")) &&
              strstr(mx_str(js(r, "result.camera.error")), "unplugged"),
          "daemon devices after the unplug: %s", jtext(r));
    CHECK(devices_has_camera(b) == 0, "specklab devices still lists the unplugged camera");

    CHECK(fx_u3v_command(&b->u3v, "plug", "PLUGGED") == 0, "the camera did not plug back");
    CHECK(bench_wait_camera(b, c, 20) == 0, "the daemon did not reopen the re-plugged camera");
    CHECK(devices_has_camera(b) == 1, "specklab devices does not list the re-plugged camera");
    mx_next_run_done(t, b, c);
}

int main(int argc, char **argv)
{
    static const tc_case cases[] = {
        TC_CASE(u3v_run_200),
        TC_CASE(u3v_unplug_mid_run),
    };
    return tc_main(argv[0], argc, argv, cases, (int)(sizeof cases / sizeof cases[0]));
}
