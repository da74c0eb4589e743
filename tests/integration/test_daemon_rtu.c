/* test_daemon_rtu.c - the bench with its stage on RS-485: specklabd
 * reaches the fake stage by Modbus RTU on a pseudo-terminal (daemon_fx.h,
 * stage_rtu), the camera polls the same stage over TCP.
 *   binary_bench_over_rtu  two runs through two screens, with the line
 *                  corrupting 4 replies and cutting 4 short while they
 *                  move the wheels: both runs done, every damaged reply
 *                  used up (the driver saw and survived each), the frames
 *                  all in the cubes; `status` counts exactly the 8
 *                  rejected replies and `specklab daemon status` says so.
 */
#include "daemon_fx.h"
#include "matrix_fx.h"

#include "../../mocks/fake-stage/fake_regs.h"

static int has(const char *hay, const char *needle)
{
    return hay && needle && strstr(hay, needle) != NULL;
}

/* A fault register of the fake, read over its TCP port; -1 when it cannot. */
static int fault_left(bench *b, int reg)
{
    modbus_t *m = mx_stage_open(b->port);
    uint16_t v = 0;
    int ok = m && modbus_read_registers(m, reg, 1, &v) == 1;
    if (m) {
        modbus_close(m);
        modbus_free(m);
    }
    return ok ? (int)v : -1;
}

static void binary_bench_over_rtu_body(tc *t, bench *b)
{
    dc *c = bench_client(b);
    CHECK(c && bench_wait_camera(b, c, 20) == 0, "no daemon or no camera");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    CHECK(mx_stage_poke(b->port, FAKE_REG_LINE_NOISE, 4) == 0 &&
          mx_stage_poke(b->port, FAKE_REG_LINE_DROP, 4) == 0, "fault switches");
    for (int s = 1; s <= 2; s++) {
        char args[96], uuid[40];
        snprintf(args, sizeof args, "{\"screen\": %d, \"mask\": 1, \"frames\": 40}", s);
        JsonNode *r = keep(b, dc_call(c, "start-run", args, 5));
        CHECK(jok(r), "start-run %d: %s", s, jtext(r));
        snprintf(uuid, sizeof uuid, "%s", js(r, "result.run"));
        JsonNode *e = keep(b, dc_wait_state(c, uuid, "done,failed,aborted", 60, NULL, NULL));
        CHECK(e && has(js(e, "state"), "done"), "run %d over RTU: %s", s, jtext(e));
        catalog_run cr;
        char msg[600];
        long n3 = -1, rows = -1;
        CHECK(fx_catalog_run(b, uuid, &cr, msg, sizeof msg) == 0, "%s", msg);
        int frames_ok = fx_fits(cr.file_path, &n3, &rows, msg, sizeof msg) == 0 && n3 == 40 &&
                        cr.frames_acquired == 40;
        catalog_run_clear(&cr);
        CHECK(frames_ok, "run %d: %ld frames in the cube", s, n3);
    }
    int noise = fault_left(b, FAKE_REG_LINE_NOISE), drop = fault_left(b, FAKE_REG_LINE_DROP);
    CHECK(noise == 0 && drop == 0, "damaged replies left unused: %d corrupted, %d cut short",
          noise, drop);
    /* Each damaged reply was rejected once (a request the line damaged
     * would be a timeout, not a rejection: none here). */
    JsonNode *r = keep(b, dc_call(c, "status", NULL, 5));
    CHECK(jok(r) && ji(r, "result.stage.rejected_replies") == 8,
          "status's rejected replies (want the 8 the line damaged): %s", jtext(r));
    char bin[PATH_MAX], out[4096];
    fx_bin(bin, sizeof bin, "specklab");
    char *argv[] = {bin, "daemon", "status", "--socket", b->sock, NULL};
    int rc = fx_run(argv, NULL, NULL, NULL, out, sizeof out, 20);
    CHECK(rc == 0 && has(out, "line: 8 damaged replies rejected"),
          "specklab daemon status (exit %d):\n%s", rc, out);
}

static void binary_bench_over_rtu_run(tc *t)
{
    bench b;
    if (bench_init(&b) != 0)
        return;
    b.stage_rtu = 1;
    if (bench_start_stage(&b, NULL) || bench_start_camera(&b) ||
        bench_write_config(&b, "[daemon]\nreconstruct=none\n") || bench_start_daemon(&b)) {
        tc_note(t, 0, __FILE__, __LINE__, "bench", "the RTU bench did not start");
        bench_down(&b, 1);
        return;
    }
    binary_bench_over_rtu_body(t, &b);
    bench_check_stop(t, &b);
    bench_down(&b, t->failed);
}

TEST(binary_bench_over_rtu) { fx_in_child(t, binary_bench_over_rtu_run, 180); }

TC_MAIN(TC_CASE(binary_bench_over_rtu))
