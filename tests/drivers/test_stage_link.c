/* test_stage_link.c - drivers/stage's link to the stage, against
 * bin/specklab-fake-stage on loopback (stage_fx.h): a reply too slow, a
 * connection dropped mid-request (a read is asked again, a command is
 * not), the stage gone and back on the same port, restarted between two
 * calls (the closed connection seen without a request), and gone during a
 * wait (bounded by the call timeout, not the move's).
 */
#include "stage_fx.h"

STAGE_TEST(fault_slow_reply, )
{
    stage *s = fx->s;
    stage_wheel_status st;
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    /* slow but within the response timeout: fine */
    CHECK(ctl(fx->f.port, FAKE_REG_SLOW_MS, RESP_MS / 3) == 0, "ctl");
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    CHECK(ctl(fx->f.port, FAKE_REG_SLOW_MS, RESP_MS + 400) == 0, "ctl");
    double t0 = now_s();
    int rc = stage_status(s, 0, &st);
    double dt = now_s() - t0;
    note("status with a too slow reply, to its error", dt);
    CHECK(rc == SL_EIO, "rc %d", rc);
    CHECK(HAS(stage_errmsg(s), "status of wheel 0 (screen): no reply within "
              "300 ms (reconnecting)"), "%s", stage_errmsg(s));
    CHECK(dt < RESP_MS * 1e-3 + MARGIN_S, "took %.3f s", dt);
    CHECK(!stage_connected(s), "still connected after a timeout");
    /* The late reply is still on its way: a reused connection would read
     * it as the answer to the next request.  The reconnect avoids that. */
    CHECK(ctl(fx->f.port, FAKE_REG_SLOW_MS, 0) == 0, "ctl");
    t0 = now_s();
    CHECK(stage_status(s, 1, &st) == SL_OK, "%s", stage_errmsg(s));
    note("next status, reconnect included", now_s() - t0);
    CHECK(st.wheel == 1 && st.slots == 6 && st.move_ms == 100 &&
          st.position == -1, "wrong answer: slots %d step %d", st.slots,
          st.move_ms);
    CHECK(stage_connected(s), "not reconnected");
}

STAGE_TEST(fault_disconnect, )
{
    stage *s = fx->s;
    stage_wheel_status st;
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    /* A read whose link drops is asked again on a new connection: it
     * changes nothing at the stage. */
    CHECK(ctl(fx->f.port, FAKE_REG_DISCONNECT_AFTER, 1) == 0, "ctl");
    double t0 = now_s();
    int rc = stage_status(s, 0, &st);
    double dt = now_s() - t0;
    CHECK(rc == SL_OK && st.wheel == 0 && st.slots == 6, "read through a dropped link: "
          "rc %d: %s", rc, stage_errmsg(s));
    CHECK(dt < CALL_MS * 1e-3 + MARGIN_S, "took %.3f s", dt);
    /* A command is not: it may have been executed. */
    CHECK(ctl(fx->f.port, FAKE_REG_DISCONNECT_AFTER, 1) == 0, "ctl");
    rc = stage_home(s, 0);
    CHECK(rc == SL_EIO && HAS(stage_errmsg(s), "homing of wheel 0 (screen): connection "
          "closed by the stage (reconnecting)"), "rc %d: %s", rc, stage_errmsg(s));
    CHECK(stage_status(s, 0, &st) == SL_OK, "no reconnect: %s",
          stage_errmsg(s));

    /* every connection dropped: the call gives up at its deadline */
    CHECK(ctl(fx->f.port, FAKE_REG_DISCONNECT, 1) == 0, "ctl");
    t0 = now_s();
    rc = stage_status(s, 0, &st);
    CHECK(rc == SL_EIO, "rc %d", rc);
    rc = stage_status(s, 0, &st);
    dt = now_s() - t0;
    note("two status calls on a stage that drops every connection", dt);
    CHECK(rc == SL_EIO && HAS(stage_errmsg(s), "not connected"), "%s",
          stage_errmsg(s));
    CHECK(dt < 2 * (CALL_MS * 1e-3 + MARGIN_S), "took %.3f s", dt);
    CHECK(ctl(fx->f.port, FAKE_REG_DISCONNECT, 0) == 0, "ctl");
    CHECK(stage_status(s, 0, &st) == SL_OK, "no reconnect: %s",
          stage_errmsg(s));
}

STAGE_TEST(server_restart, )
{
    stage *s = fx->s;
    stage_wheel_status st;
    char why[512];
    int port = fx->f.port;
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    fake_stop(&fx->f);
    double t0 = now_s();
    int rc1 = stage_status(s, 0, &st);
    int rc2 = stage_status(s, 0, &st);
    double dt = now_s() - t0;
    note("two status calls with the stage gone", dt);
    CHECK(rc1 == SL_EIO && rc2 == SL_EIO, "rc %d %d", rc1, rc2);
    CHECK(HAS(stage_errmsg(s), "not connected") &&
          HAS(stage_errmsg(s), "Connection refused"), "%s", stage_errmsg(s));
    CHECK(dt < 2 * (CALL_MS * 1e-3 + MARGIN_S), "took %.3f s", dt);
    /* same port again (the fake listens with SO_REUSEADDR) */
    CHECK(fake_start(&fx->f, port, NULL, why, sizeof why) == 0, "%s", why);
    t0 = now_s();
    rc1 = stage_status(s, 0, &st);
    dt = now_s() - t0;
    note("status after the restart, backoff included", dt);
    CHECK(rc1 == SL_OK, "after restart: %s", stage_errmsg(s));
    CHECK(dt < CALL_MS * 1e-3 + MARGIN_S, "took %.3f s", dt);
    CHECK(stage_home(s, 0) == SL_OK && stage_wait(s, 0, 0) == SL_OK, "%s",
          stage_errmsg(s));
}

/* The stage restarts between two calls (power-cycled): the handle sees
 * its connection closed without sending anything, and the next call,
 * a status read or a command, runs on a new connection. */
STAGE_TEST(restart_between_calls, )
{
    stage *s = fx->s;
    stage_wheel_status st;
    char why[512];
    int port = fx->f.port;
    CHECK(stage_status(s, 0, &st) == SL_OK && stage_connected(s), "%s", stage_errmsg(s));
    fake_stop(&fx->f);   /* reaped: its end of the connection is closed */
    CHECK(!stage_connected(s), "a connection the stage closed is reported connected");
    CHECK(fake_start(&fx->f, port, NULL, why, sizeof why) == 0, "%s", why);
    double t0 = now_s();
    int rc = stage_status(s, 0, &st);
    double dt = now_s() - t0;
    note("first status after the restart", dt);
    CHECK(rc == SL_OK && !st.homed, "first status after a restart: rc %d: %s", rc,
          stage_errmsg(s));
    CHECK(dt < CALL_MS * 1e-3 + MARGIN_S, "took %.3f s", dt);
    fake_stop(&fx->f);
    CHECK(fake_start(&fx->f, port, NULL, why, sizeof why) == 0, "%s", why);
    CHECK(stage_home(s, 0) == SL_OK && stage_wait(s, 0, 0) == SL_OK,
          "first command after a restart: %s", stage_errmsg(s));
}

/* The stage vanishes mid-move and refuses connections: the wait ends
 * after one call timeout of silence, not at the move's timeout. */
STAGE_TEST(wait_on_vanished_stage, "--step-ms", "200",)
{
    stage *s = fx->s;
    CHECK(stage_home(s, 0) == SL_OK && stage_wait(s, 0, 0) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_move(s, 0, 5) == SL_OK, "%s", stage_errmsg(s));
    fake_stop(&fx->f);
    double t0 = now_s();
    int rc = stage_wait(s, 0, 10000);
    double dt = now_s() - t0;
    note("wait on a vanished stage, to its error", dt);
    CHECK(rc == SL_EIO && HAS(stage_errmsg(s), "move of wheel 0 (screen) to slot 5 not "
          "confirmed: no answer from the stage for") &&
              HAS(stage_errmsg(s), "Connection refused"),
          "rc %d: %s", rc, stage_errmsg(s));
    CHECK(dt < CALL_MS * 1e-3 + MARGIN_S, "took %.3f s for a %d ms call bound", dt, CALL_MS);
}

TC_MAIN(TC_CASE(fault_slow_reply), TC_CASE(fault_disconnect), TC_CASE(server_restart),
        TC_CASE(restart_between_calls), TC_CASE(wait_on_vanished_stage))
