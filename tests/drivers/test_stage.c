/* test_stage.c - drivers/stage against bin/specklab-fake-stage on loopback
 * (stage_fx.h): the register map, commands, refusals, faults, backends and
 * mbpoll.  The link's recovery (timeouts, drops, restarts) is in
 * test_stage_link.c.
 */
#include "stage_fx.h"

STAGE_TEST(home_move_status, "--step-ms", "40", "--slots-mask", "4",)
{
    stage *s = fx->s;
    stage_ident id;
    stage_wheel_status st;
    CHECK(stage_info(s, &id) == SL_OK, "%s", stage_errmsg(s));
    CHECK(id.magic == STAGE_MAGIC && id.version == 1 && id.nwheels == 2,
          "ident %x %u %u", id.magic, id.version, id.nwheels);
    CHECK(id.slots[0] == 6 && id.slots[1] == 4 && id.move_ms[0] == 40,
          "slots %d %d, step %d ms", id.slots[0], id.slots[1], id.move_ms[0]);
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    CHECK(!st.homed && st.position == -1 && !st.busy && !st.in_position,
          "power-up: homed %d position %d", st.homed, st.position);

    /* refused before homing */
    CHECK(stage_move(s, 0, 2) == SL_ERANGE, "unhomed move accepted");
    CHECK(HAS(stage_errmsg(s), "move of wheel 0 (screen) to slot 2 refused") &&
          HAS(stage_errmsg(s), "not homed"), "%s", stage_errmsg(s));

    CHECK(stage_home(s, STAGE_WHEEL_ALL) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_status(s, 1, &st) == SL_OK, "%s", stage_errmsg(s));
    CHECK(st.busy && !st.homed && st.position == -1, "homing: busy %d", st.busy);
    CHECK(stage_wait(s, STAGE_WHEEL_ALL, 0) == SL_OK, "%s", stage_errmsg(s));
    for (int w = 0; w < 2; w++) {
        CHECK(stage_status(s, w, &st) == SL_OK, "%s", stage_errmsg(s));
        CHECK(st.homed && st.in_position && !st.busy && st.position == 0,
              "wheel %d homed %d inpos %d position %d", w, st.homed,
              st.in_position, st.position);
    }

    /* a move takes time: busy and between slots right after the command */
    double t0 = now_s();
    CHECK(stage_move(s, 0, 3) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    CHECK(st.busy && st.position == -1 && st.target == 3 && !st.in_position,
          "moving: busy %d position %d target %d", st.busy, st.position,
          st.target);
    CHECK(stage_wait(s, 0, 0) == SL_OK, "%s", stage_errmsg(s));
    note("move of 3 steps of 40 ms, command to in-position", now_s() - t0);
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    CHECK(st.position == 3 && st.target == 3 && st.in_position && st.homed &&
          !st.busy && !st.faulted && st.fault == 0,
          "arrived: position %d status 0x%x", st.position, st.status);
    CHECK(st.status == (STAGE_ST_INPOS | STAGE_ST_HOMED), "status 0x%x",
          st.status);

    CHECK(stage_move_wait(s, 1, 3, 0) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_status(s, 1, &st) == SL_OK && st.position == 3,
          "mask position %d", st.position);
    /* the screen wheel did not move meanwhile */
    CHECK(stage_status(s, 0, &st) == SL_OK && st.position == 3,
          "screen position %d", st.position);

    /* a wait shorter than the move: bounded error, then a longer wait */
    CHECK(stage_move(s, 1, 0) == SL_OK, "%s", stage_errmsg(s));
    t0 = now_s();
    CHECK(stage_wait(s, 1, 50) == SL_EIO, "3 steps of 40 ms in 50 ms?");
    CHECK(now_s() - t0 < 0.05 + MARGIN_S, "took %.3f s", now_s() - t0);
    CHECK(HAS(stage_errmsg(s), "move of wheel 1 (mask) to slot 0 not in "
              "position after"), "%s", stage_errmsg(s));
    CHECK(stage_wait(s, 1, 0) == SL_OK, "%s", stage_errmsg(s));

    /* out of range: the message says which range */
    CHECK(stage_move(s, 0, 7) == SL_ERANGE, "slot 7 accepted");
    CHECK(HAS(stage_errmsg(s), "stage 127.0.0.1:") &&
          HAS(stage_errmsg(s), "move of wheel 0 (screen) to slot 7 refused: "
              "slot out of range 0..5"), "%s", stage_errmsg(s));
    CHECK(stage_move(s, 1, 4) == SL_ERANGE &&
          HAS(stage_errmsg(s), "out of range 0..3"), "%s", stage_errmsg(s));
    CHECK(stage_move(s, 0, -1) == SL_ERANGE, "slot -1 accepted");
    CHECK(stage_move(s, 2, 0) == SL_EINVAL, "wheel 2 accepted");

    /* stop: at rest on a slot between start and target */
    CHECK(stage_move(s, 0, 0) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_stop(s, 0) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    CHECK(!st.busy && st.in_position && st.position >= 0 && st.position <= 3,
          "stopped: busy %d position %d", st.busy, st.position);
    CHECK(stage_wait(s, 0, 500) == SL_OK, "%s", stage_errmsg(s));
}

/* The fake itself refuses per the map, seen by a plain Modbus client. */
STAGE_TEST(map_refusals, )
{
    modbus_t *c = modbus_new_tcp("127.0.0.1", fx->f.port);
    CHECK(c != NULL, "modbus_new_tcp");
    modbus_set_response_timeout(c, 1, 0);
    int ok = modbus_connect(c) == 0;
    int e_ro = 0, e_unhomed = 0, e_range = 0, e_cmd = 0;
    uint16_t v[2] = {STAGE_CMD_MOVE, 0};
    if (ok) {
        if (modbus_write_register(c, STAGE_REG_MAGIC, 1) < 0)
            e_ro = errno;
        if (modbus_write_registers(c, STAGE_REG_COMMAND, 2, v) < 0)
            e_unhomed = errno;
        uint16_t h[2] = {STAGE_CMD_HOME, STAGE_WHEEL_ALL};
        modbus_write_registers(c, STAGE_REG_COMMAND, 2, h);
        modbus_write_register(c, STAGE_REG_WHEEL_BASE(0) + STAGE_WREG_TARGET, 6);
        /* homing is still running (200 ms): unhomed again, then wait */
        if (stage_wait(fx->s, STAGE_WHEEL_ALL, 2000) == SL_OK &&
            modbus_write_registers(c, STAGE_REG_COMMAND, 2, v) < 0)
            e_range = errno;
        uint16_t bad[2] = {9, 0};
        if (modbus_write_registers(c, STAGE_REG_COMMAND, 2, bad) < 0)
            e_cmd = errno;
        modbus_close(c);
    }
    modbus_free(c);
    CHECK(ok, "connect to the fake failed");
    CHECK(e_ro == EMBXILADD, "write to MAGIC: %s", modbus_strerror(e_ro));
    CHECK(e_unhomed == EMBXILVAL, "unhomed MOVE: %s", modbus_strerror(e_unhomed));
    CHECK(e_range == EMBXILVAL, "MOVE to slot 6 of 6: %s",
          modbus_strerror(e_range));
    CHECK(e_cmd == EMBXILVAL, "command 9: %s", modbus_strerror(e_cmd));
}

STAGE_TEST(fault_busy, )
{
    stage *s = fx->s;
    stage_wheel_status st;
    CHECK(ctl(fx->f.port, FAKE_REG_BUSY_COUNT, 3) == 0, "ctl");
    double t0 = now_s();
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    double dt = now_s() - t0;
    note("status through 3 busy answers", dt);
    CHECK(dt < CALL_MS * 1e-3 + MARGIN_S, "took %.3f s", dt);
    CHECK(ctl(fx->f.port, FAKE_REG_BUSY_COUNT, -1) == 0,
          "busy answers not all consumed");
    CHECK(ctl(fx->f.port, FAKE_REG_BUSY_COUNT, 2) == 0, "ctl");
    CHECK(stage_home(s, 0) == SL_OK, "command through busy: %s",
          stage_errmsg(s));

    CHECK(ctl(fx->f.port, FAKE_REG_BUSY, 1) == 0, "ctl");
    t0 = now_s();
    int rc = stage_status(s, 1, &st);
    dt = now_s() - t0;
    note("status while always busy, to its error", dt);
    CHECK(rc == SL_EIO, "rc %d", rc);
    CHECK(HAS(stage_errmsg(s), "status of wheel 1 (mask)") &&
          HAS(stage_errmsg(s), "busy (exception 0x06)"), "%s", stage_errmsg(s));
    CHECK(dt < CALL_MS * 1e-3 + MARGIN_S, "took %.3f s", dt);
    CHECK(ctl(fx->f.port, FAKE_REG_BUSY, 0) == 0, "ctl");
    CHECK(stage_status(s, 1, &st) == SL_OK, "%s", stage_errmsg(s));
}

STAGE_TEST(fault_stall, "--step-ms", "20", "--stall-ms", "300",)
{
    stage *s = fx->s;
    stage_wheel_status st;
    CHECK(stage_home(s, 0) == SL_OK && stage_wait(s, 0, 0) == SL_OK, "%s",
          stage_errmsg(s));
    CHECK(ctl(fx->f.port, FAKE_REG_STALL, 1) == 0, "ctl");
    double t0 = now_s();
    int rc = stage_move_wait(s, 0, 2, 2500);
    double dt = now_s() - t0;
    note("stalled move, command to fault", dt);
    CHECK(rc == SL_EDATA, "rc %d: %s", rc, stage_errmsg(s));
    CHECK(HAS(stage_errmsg(s), "move of wheel 0 (screen) to slot 2 stalled "
              "(fault 1: stall) after"), "%s", stage_errmsg(s));
    CHECK(dt < 0.3 + MARGIN_S, "took %.3f s", dt);
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    CHECK(st.faulted && st.fault == STAGE_FAULT_STALL && st.position == -1 &&
          !st.busy && !strcmp(st.fault_text, "stall"),
          "fault %d (%s) position %d", st.fault, st.fault_text, st.position);
    CHECK(stage_move(s, 0, 3) == SL_ERANGE &&
          HAS(stage_errmsg(s), "in fault 1 (stall); reset it first"), "%s",
          stage_errmsg(s));
    CHECK(ctl(fx->f.port, FAKE_REG_STALL, 0) == 0, "ctl");
    CHECK(stage_reset(s, 0) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_status(s, 0, &st) == SL_OK && !st.faulted && st.fault == 0,
          "after reset: fault %d", st.fault);
    CHECK(stage_move_wait(s, 0, 4, 0) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_status(s, 0, &st) == SL_OK && st.position == 4,
          "position %d", st.position);
}

STAGE_TEST(fault_code, "--fault-screen", "4",)
{
    stage *s = fx->s;
    stage_wheel_status st;
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    CHECK(st.faulted && st.fault == STAGE_FAULT_LIMIT &&
          !strcmp(st.fault_text, "limit switch hit"), "flag: fault %d (%s)",
          st.fault, st.fault_text);
    CHECK(ctl(fx->f.port, FAKE_REG_FAULT_MASK, STAGE_FAULT_OVERTEMP) == 0, "ctl");
    CHECK(stage_status(s, 1, &st) == SL_OK, "%s", stage_errmsg(s));
    CHECK(st.faulted && st.fault == 3 && (st.status & STAGE_ST_FAULT),
          "register: fault %d", st.fault);
    double t0 = now_s();
    int rc = stage_wait(s, 1, 2000);
    double dt = now_s() - t0;
    CHECK(rc == SL_EDATA && HAS(stage_errmsg(s), "wheel 1 (mask) faulted "
          "(fault 3: driver over temperature)"), "rc %d: %s", rc,
          stage_errmsg(s));
    CHECK(dt < CALL_MS * 1e-3 + MARGIN_S, "took %.3f s", dt);
    CHECK(stage_home(s, 1) == SL_ERANGE &&
          HAS(stage_errmsg(s), "homing of wheel 1 (mask) refused: wheel 1 in "
              "fault 3 (driver over temperature); reset it first"), "%s",
          stage_errmsg(s));
    CHECK(stage_reset(s, STAGE_WHEEL_ALL) == SL_OK, "%s", stage_errmsg(s));
    for (int w = 0; w < 2; w++)
        CHECK(stage_status(s, w, &st) == SL_OK && !st.faulted && !st.fault,
              "wheel %d still faulted", w);
    CHECK(stage_home(s, 1) == SL_OK, "%s", stage_errmsg(s));
}

STAGE_TEST(wrong_device, "--magic", "0x1234",)
{
    stage *s = fx->s;
    stage_wheel_status st;
    double t0 = now_s();
    int rc = stage_status(s, 0, &st);
    double dt = now_s() - t0;
    CHECK(rc == SL_EFORMAT, "rc %d: %s", rc, stage_errmsg(s));
    CHECK(HAS(stage_errmsg(s), "not a specklab stage: register 0 reads 0x1234, "
              "expected 0x534C"), "%s", stage_errmsg(s));
    CHECK(dt < CALL_MS * 1e-3 + MARGIN_S, "took %.3f s", dt);
    CHECK(!stage_connected(s), "kept a connection to a wrong device");
}

TEST(backends)
{
    stage_config cfg;
    stage *s = NULL;
    sl_err e = {0};
    CHECK(!strcmp(stage_backend_name(0), "tcp") &&
          !strcmp(stage_backend_name(1), "rtu") && !stage_backend_name(2),
          "backend table");
    test_config(&cfg, 1502);
    cfg.backend = "can";
    CHECK(stage_new(&s, &cfg, &e) == SL_EINVAL && !s &&
          HAS(e.msg, "unknown backend 'can'"), "%s", e.msg);
    test_config(&cfg, 1502);
    cfg.host = "stage.local";
    CHECK(stage_new(&s, &cfg, &e) == SL_EINVAL && HAS(e.msg, "IPv4"), "%s",
          e.msg);
    test_config(&cfg, 1502);
    cfg.backend = "rtu";
    cfg.device = "/dev/ttyUSB0";
    cfg.parity = 'X';
    CHECK(stage_new(&s, &cfg, &e) == SL_EINVAL && HAS(e.msg, "parity"), "%s",
          e.msg);
    /* RTU: constructible without the port; the first call fails, bounded */
    cfg.parity = 'E';
    cfg.device = "/nonexistent/ttySPECKLAB";
    CHECK(stage_new(&s, &cfg, &e) == SL_OK, "%s", e.msg);
    CHECK(!strcmp(stage_label(s), cfg.device), "label %s", stage_label(s));
    double t0 = now_s();
    int rc = stage_home(s, 0);
    double dt = now_s() - t0;
    int msg_ok = HAS(stage_errmsg(s), "stage /nonexistent/ttySPECKLAB: homing "
                     "of wheel 0 (screen): not connected: cannot connect");
    char msg[SL_ERRMSG_MAX];
    snprintf(msg, sizeof msg, "%s", stage_errmsg(s));
    stage_free(s);
    stage_free(NULL);
    CHECK(rc == SL_EIO && msg_ok, "rc %d: %s", rc, msg);
    CHECK(dt < CALL_MS * 1e-3 + MARGIN_S, "took %.3f s", dt);
}

/* Run mbpoll with args, capture stdout (bounded 5 s); its exit status
 * (127: not installed), or -1. */
static int run_mbpoll(const char *const *args, char *out, size_t n)
{
    const char *argv[24] = {"mbpoll"};
    int k = 1, status = -1;
    pid_t pid;
    for (int i = 0; args[i] && k < 23; i++)
        argv[k++] = args[i];
    int fd = spawn(argv, 1, &pid);
    out[0] = '\0';
    if (fd < 0)
        return -1;
    read_bounded(fd, out, n, 0);
    kill(pid, SIGKILL); /* no-op when it has already exited */
    if (waitpid(pid, &status, 0) == pid && WIFEXITED(status))
        return WEXITSTATUS(status);
    return -1;
}

STAGE_TEST(mbpoll_map, "--step-ms", "30",)
{
    char port[16], out[4096];
    stage_wheel_status st;
    if (run_mbpoll((const char *const[]){"-V", NULL}, out, sizeof out) == 127)
        SKIP("mbpoll not installed (apt-get install mbpoll)");
    snprintf(port, sizeof port, "%d", fx->f.port);
#define MB(...) (const char *const[]){"-m", "tcp", "-a", "1", "-0", "-1",    \
                                      "-o", "1", "-p", port, __VA_ARGS__, NULL}
    /* -0: addresses as on the wire, so -r 0 is MAGIC */
    int rc = run_mbpoll(MB("-r", "0", "-c", "3", "127.0.0.1"), out, sizeof out);
    CHECK(rc == 0 && HAS(out, "[0]: \t21324") && HAS(out, "[1]: \t1") &&
          HAS(out, "[2]: \t2"), "mbpoll read (exit %d):\n%s", rc, out);
    /* HOME all wheels: COMMAND, CMD_WHEEL in one write */
    rc = run_mbpoll(MB("-r", "3", "127.0.0.1", "1", "65535"), out, sizeof out);
    CHECK(rc == 0, "mbpoll HOME (exit %d):\n%s", rc, out);
    CHECK(stage_wait(fx->s, STAGE_WHEEL_ALL, 2000) == SL_OK, "%s",
          stage_errmsg(fx->s));
    /* TARGET of wheel 0, then MOVE */
    rc = run_mbpoll(MB("-r", "17", "127.0.0.1", "4"), out, sizeof out);
    CHECK(rc == 0, "mbpoll TARGET (exit %d):\n%s", rc, out);
    rc = run_mbpoll(MB("-r", "3", "127.0.0.1", "2", "0"), out, sizeof out);
    CHECK(rc == 0, "mbpoll MOVE (exit %d):\n%s", rc, out);
    CHECK(stage_wait(fx->s, 0, 2000) == SL_OK, "%s", stage_errmsg(fx->s));
    CHECK(stage_status(fx->s, 0, &st) == SL_OK && st.position == 4 &&
          st.in_position, "position %d after the mbpoll move", st.position);
    rc = run_mbpoll(MB("-r", "16", "-c", "6", "127.0.0.1"), out, sizeof out);
    CHECK(rc == 0 && HAS(out, "[16]: \t6") && HAS(out, "[17]: \t4") &&
          HAS(out, "[18]: \t4") && HAS(out, "[19]: \t6") &&
          HAS(out, "[21]: \t30"), "mbpoll wheel block (exit %d):\n%s", rc, out);
    /* POSITION is read-only: the write is refused */
    rc = run_mbpoll(MB("-r", "18", "127.0.0.1", "1"), out, sizeof out);
    CHECK(rc != 0, "write to POSITION accepted:\n%s", out);
#undef MB
}

TC_MAIN(TC_CASE(home_move_status), TC_CASE(map_refusals), TC_CASE(fault_busy),
        TC_CASE(fault_stall), TC_CASE(fault_code), TC_CASE(wrong_device), TC_CASE(backends),
        TC_CASE(mbpoll_map))
