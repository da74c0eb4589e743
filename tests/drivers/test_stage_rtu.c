/* test_stage_rtu.c - drivers/stage over Modbus RTU: bin/specklab-fake-stage
 * --rtu serves the stage on a pseudo-terminal (libmodbus's RTU backend on
 * the master side, through its line relay), the driver opens the slave
 * side as its serial port.  The same commands and fault switches as over
 * TCP (test_stage.c, test_stage_link.c), with the same bounds, plus what a
 * line adds: a corrupted byte (CRC) and a lost byte (a frame cut short) in
 * either direction, a stale reply after a timeout, the port's settings
 * (speed, parity, unit id) and the port vanishing and coming back.  The
 * fault switches are flipped over the fake's TCP port (stage_fx.h's ctl)
 * while the line carries the traffic under test.  specklabd on an RTU
 * stage: test_stage_rtu_daemon.c.
 */
#include "stage_fx.h"

#include <pthread.h>
#include <sys/stat.h>
#include <termios.h>

#define GAP_S 0.05 /* the driver's byte timeout at 19200 baud (RTU_GAP_MS) */

static void rtu_config(stage_config *cfg, const char *device)
{
    test_config(cfg, 1502);
    cfg->backend = "rtu";
    cfg->device = device;
    cfg->baud = 19200;
    cfg->parity = 'E';
}

/* The fake with --rtu and args, and an RTU handle on its pty. */
static int rtu_up(tc *t, fixture *fx, const char *const *args)
{
    char why[512];
    sl_err e = {0};
    memset(fx, 0, sizeof *fx);
    fx->f.pid = -1;
    if (fake_start(&fx->f, 0, args, why, sizeof why) < 0 || !fx->f.rtu[0]) {
        tc_note(t, 0, __FILE__, __LINE__, "fake_start --rtu", "%s",
                fx->f.pid < 0 ? why : "no rtu= on the READY line");
        return -1;
    }
    rtu_config(&fx->cfg, fx->f.rtu);
    if (stage_new(&fx->s, &fx->cfg, &e) != SL_OK) {
        tc_note(t, 0, __FILE__, __LINE__, "stage_new", "%s", e.msg);
        return -1;
    }
    return 0;
}

#define RTU_TEST(name, ...)                                                   \
    static void name##_body(tc *t, fixture *fx);                              \
    TEST(name)                                                                \
    {                                                                         \
        static const char *const args[] = {"--rtu", __VA_ARGS__ NULL};        \
        fixture fx;                                                           \
        if (rtu_up(t, &fx, args) == 0)                                        \
            name##_body(t, &fx);                                              \
        fixture_down(&fx);                                                    \
    }                                                                         \
    static void name##_body(tc *t, fixture *fx)

RTU_TEST(rtu_move_status, "--step-ms", "40", "--slots-mask", "4",)
{
    stage *s = fx->s;
    stage_ident id;
    stage_wheel_status st;
    CHECK(!strncmp(fx->f.rtu, "/dev/pts/", 9) &&
          !strcmp(stage_label(s), fx->f.rtu), "device %s, label %s",
          fx->f.rtu, stage_label(s));
    CHECK(stage_info(s, &id) == SL_OK, "%s", stage_errmsg(s));
    CHECK(id.magic == STAGE_MAGIC && id.version == 1 && id.slots[0] == 6 &&
          id.slots[1] == 4 && id.move_ms[0] == 40, "ident %x slots %d %d",
          id.magic, id.slots[0], id.slots[1]);
    CHECK(stage_connected(s), "not connected after the identity check");
    CHECK(stage_move(s, 0, 2) == SL_ERANGE &&
          HAS(stage_errmsg(s), "not homed"), "%s", stage_errmsg(s));
    double t0 = now_s();
    CHECK(stage_home(s, STAGE_WHEEL_ALL) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_wait(s, STAGE_WHEEL_ALL, 0) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_move(s, 0, 3) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_status(s, 0, &st) == SL_OK && st.busy && st.target == 3 &&
          st.position == -1, "moving: busy %d target %d position %d", st.busy,
          st.target, st.position);
    CHECK(stage_wait(s, 0, 0) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_move_wait(s, 1, 3, 0) == SL_OK, "%s", stage_errmsg(s));
    note("home both, move 3 steps, move 3 steps, over RTU", now_s() - t0);
    CHECK(stage_status(s, 0, &st) == SL_OK && st.position == 3 &&
          st.status == (STAGE_ST_INPOS | STAGE_ST_HOMED), "screen: position %d "
          "status 0x%x", st.position, st.status);
    CHECK(stage_status(s, 1, &st) == SL_OK && st.position == 3 &&
          st.slots == 4, "mask: position %d of %d", st.position, st.slots);
    char want[200];
    snprintf(want, sizeof want, "stage %s: move of wheel 1 (mask) to slot 4 "
             "refused: slot out of range 0..3", fx->f.rtu);
    CHECK(stage_move(s, 1, 4) == SL_ERANGE && HAS(stage_errmsg(s), want), "%s",
          stage_errmsg(s));
    CHECK(stage_reset(s, 0) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_rejected_replies(s) == 0, "%u damaged replies on a clean line",
          stage_rejected_replies(s));
    t0 = now_s();
    for (int i = 0; i < 50; i++)
        CHECK(stage_status(s, i & 1, &st) == SL_OK, "%s", stage_errmsg(s));
    note("50 status reads (request + 17-byte reply each)", now_s() - t0);
}

/* exception 0x06: retried within the call, then a bounded "busy" */
RTU_TEST(rtu_busy, )
{
    stage *s = fx->s;
    stage_wheel_status st;
    CHECK(ctl(fx->f.port, FAKE_REG_BUSY_COUNT, 3) == 0, "ctl");
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    CHECK(ctl(fx->f.port, FAKE_REG_BUSY_COUNT, -1) == 0, "busy answers not all "
          "consumed");
    CHECK(ctl(fx->f.port, FAKE_REG_BUSY, 1) == 0, "ctl");
    double t0 = now_s();
    int rc = stage_status(s, 1, &st);
    double dt = now_s() - t0;
    note("status while always busy, to its error", dt);
    CHECK(rc == SL_EIO && HAS(stage_errmsg(s), "status of wheel 1 (mask)") &&
          HAS(stage_errmsg(s), "busy (exception 0x06)"), "rc %d: %s", rc,
          stage_errmsg(s));
    CHECK(dt < CALL_MS * 1e-3 + MARGIN_S, "took %.3f s", dt);
    CHECK(ctl(fx->f.port, FAKE_REG_BUSY, 0) == 0, "ctl");
    CHECK(stage_status(s, 1, &st) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_rejected_replies(s) == 0, "%u", stage_rejected_replies(s));
}

/* A reply later than the response timeout: the call fails at the timeout;
 * the late reply then arrives on the line, and must not answer a later
 * request (wheel 0's block for wheel 1's: the wheels differ in slots). */
RTU_TEST(rtu_slow_reply, "--slots-mask", "4",)
{
    stage *s = fx->s;
    stage_wheel_status st;
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    CHECK(ctl(fx->f.port, FAKE_REG_SLOW_MS, RESP_MS / 3) == 0, "ctl");
    CHECK(stage_status(s, 0, &st) == SL_OK, "slow within the timeout: %s",
          stage_errmsg(s));
    CHECK(ctl(fx->f.port, FAKE_REG_SLOW_MS, RESP_MS + 400) == 0, "ctl");
    double t0 = now_s();
    int rc = stage_status(s, 0, &st);
    double dt = now_s() - t0;
    note("status with a too slow reply, to its error", dt);
    CHECK(rc == SL_EIO && HAS(stage_errmsg(s), "status of wheel 0 (screen): no "
          "reply within 300 ms (reconnecting)"), "rc %d: %s", rc, stage_errmsg(s));
    CHECK(dt < RESP_MS * 1e-3 + MARGIN_S, "took %.3f s", dt);
    CHECK(ctl(fx->f.port, FAKE_REG_SLOW_MS, 0) == 0, "ctl");
    t0 = now_s();
    rc = stage_status(s, 1, &st);
    dt = now_s() - t0;
    note("next status, the late reply on the line meanwhile", dt);
    CHECK(rc == SL_OK && st.wheel == 1 && st.slots == 4, "rc %d, slots %d: %s",
          rc, st.slots, stage_errmsg(s));
    CHECK(dt < CALL_MS * 1e-3 + MARGIN_S, "took %.3f s", dt);
    if (getenv("SL_VERBOSE"))
        fprintf(stderr, "  stale replies rejected on the way: %u\n",
                stage_rejected_replies(s));
    CHECK(stage_status(s, 0, &st) == SL_OK && st.slots == 6, "%s",
          stage_errmsg(s));
}

RTU_TEST(rtu_stall, "--step-ms", "20", "--stall-ms", "300",)
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
    CHECK(rc == SL_EDATA && HAS(stage_errmsg(s), "move of wheel 0 (screen) to "
          "slot 2 stalled (fault 1: stall) after"), "rc %d: %s", rc,
          stage_errmsg(s));
    CHECK(dt < 0.3 + MARGIN_S, "took %.3f s", dt);
    CHECK(stage_move(s, 0, 3) == SL_ERANGE &&
          HAS(stage_errmsg(s), "in fault 1 (stall); reset it first"), "%s",
          stage_errmsg(s));
    CHECK(ctl(fx->f.port, FAKE_REG_STALL, 0) == 0, "ctl");
    CHECK(stage_reset(s, 0) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_move_wait(s, 0, 4, 0) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_status(s, 0, &st) == SL_OK && st.position == 4 && !st.faulted,
          "position %d fault %d", st.position, st.fault);
}

/* A reply with a corrupted byte: rejected by its CRC (the data would
 * otherwise read wrong: the byte hit is the last data byte), the line
 * reset, the read asked again within the call. */
RTU_TEST(rtu_noise, "--step-ms", "20",)
{
    stage *s = fx->s;
    stage_wheel_status st;
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    CHECK(ctl(fx->f.port, FAKE_REG_LINE_NOISE, 1) == 0, "ctl");
    double t0 = now_s();
    int rc = stage_status(s, 0, &st);
    double dt = now_s() - t0;
    note("status through a corrupted reply (detect, reset, ask again)", dt);
    CHECK(rc == SL_OK && st.slots == 6 && st.move_ms == 20 && st.position == -1,
          "rc %d slots %d step %d: %s", rc, st.slots, st.move_ms, stage_errmsg(s));
    CHECK(ctl(fx->f.port, FAKE_REG_LINE_NOISE, -1) == 0, "noise not applied");
    CHECK(stage_rejected_replies(s) == 1, "%u rejected", stage_rejected_replies(s));
    CHECK(dt < RESP_MS * 1e-3, "took %.3f s: the CRC should tell at once", dt);
    /* two in a row: the second hits the reconnection's identity check */
    CHECK(ctl(fx->f.port, FAKE_REG_LINE_NOISE, 2) == 0, "ctl");
    CHECK(stage_status(s, 1, &st) == SL_OK && st.wheel == 1 && st.slots == 6,
          "%s", stage_errmsg(s));
    CHECK(stage_rejected_replies(s) == 3, "%u rejected", stage_rejected_replies(s));
    /* a command's reply: sent again (repeating a command of the map
     * changes nothing), and a refusal is still a refusal */
    CHECK(ctl(fx->f.port, FAKE_REG_LINE_NOISE, 1) == 0, "ctl");
    CHECK(stage_move(s, 0, 2) == SL_ERANGE && HAS(stage_errmsg(s), "not homed"),
          "%s", stage_errmsg(s));
    CHECK(stage_rejected_replies(s) == 4, "%u rejected", stage_rejected_replies(s));
    CHECK(ctl(fx->f.port, FAKE_REG_LINE_NOISE, 1) == 0, "ctl");
    CHECK(stage_home(s, 0) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_rejected_replies(s) == 5, "%u rejected", stage_rejected_replies(s));
    CHECK(stage_status(s, 0, &st) == SL_OK && st.busy, "not homing: busy %d homed "
          "%d", st.busy, st.homed);
    /* a line that stays noisy: the call fails within its bound */
    CHECK(ctl(fx->f.port, FAKE_REG_LINE_NOISE, 1000) == 0, "ctl");
    t0 = now_s();
    rc = stage_status(s, 0, &st);
    dt = now_s() - t0;
    note("status on a line that stays noisy, to its error", dt);
    CHECK(rc == SL_EIO && HAS(stage_errmsg(s), "bad reply (Invalid CRC)"),
          "rc %d: %s", rc, stage_errmsg(s));
    CHECK(dt < CALL_MS * 1e-3 + MARGIN_S, "took %.3f s", dt);
    CHECK(ctl(fx->f.port, FAKE_REG_LINE_NOISE, 0) == 0, "ctl");
    CHECK(stage_wait(s, 0, 0) == SL_OK, "after the noise: %s", stage_errmsg(s));
}

/* A burst of damaged replies (4 corrupted, then 4 cut short) under the
 * daemon's default timing (backoff 50..1000 ms, 2 s calls): the stage
 * answers, so the line is reset at the shortest backoff each time, not
 * an escalating one, and a status read gets through within its call. */
RTU_TEST(rtu_noise_burst, )
{
    stage_config cfg;
    stage *s = NULL;
    sl_err e = {0};
    stage_wheel_status st;
    stage_config_defaults(&cfg);
    cfg.backend = "rtu";
    cfg.device = fx->f.rtu;
    CHECK(stage_new(&s, &cfg, &e) == SL_OK, "%s", e.msg);
    int rc = stage_status(s, 0, &st);
    if (rc == SL_OK && (ctl(fx->f.port, FAKE_REG_LINE_NOISE, 4) < 0 ||
                        ctl(fx->f.port, FAKE_REG_LINE_DROP, 4) < 0))
        rc = -100;
    double t0 = now_s();
    if (rc == SL_OK)
        rc = stage_status(s, 1, &st);
    double dt = now_s() - t0;
    unsigned rej = stage_rejected_replies(s);
    char msg[SL_ERRMSG_MAX];
    snprintf(msg, sizeof msg, "%s", stage_errmsg(s));
    stage_free(s);
    note("status through 8 damaged replies in a row (default timing)", dt);
    CHECK(rc == SL_OK && st.wheel == 1 && st.slots == 6, "rc %d: %s", rc, msg);
    CHECK(rej == 8, "%u rejected", rej);
    CHECK(dt < cfg.call_timeout_ms * 1e-3, "took %.3f s", dt);
}

/* A reply with a byte lost: the frame stops short and the byte timeout
 * (GAP_S), not the response timeout, ends it. */
RTU_TEST(rtu_drop, )
{
    stage *s = fx->s;
    stage_wheel_status st;
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    CHECK(ctl(fx->f.port, FAKE_REG_LINE_DROP, 1) == 0, "ctl");
    double t0 = now_s();
    int rc = stage_status(s, 1, &st);
    double dt = now_s() - t0;
    note("status through a reply cut short (detect, reset, ask again)", dt);
    CHECK(rc == SL_OK && st.wheel == 1 && st.slots == 6 && st.move_ms == 100,
          "rc %d: %s", rc, stage_errmsg(s));
    CHECK(ctl(fx->f.port, FAKE_REG_LINE_DROP, -1) == 0, "drop not applied");
    CHECK(stage_rejected_replies(s) == 1, "%u rejected", stage_rejected_replies(s));
    CHECK(dt < RESP_MS * 1e-3, "took %.3f s: the gap should tell, not the %d ms "
          "response timeout", dt, RESP_MS);
    CHECK(dt >= GAP_S, "took %.3f s, less than the gap", dt);
    /* a command: sent again */
    CHECK(ctl(fx->f.port, FAKE_REG_LINE_DROP, 1) == 0, "ctl");
    CHECK(stage_home(s, 1) == SL_OK, "%s", stage_errmsg(s));
    CHECK(stage_rejected_replies(s) == 2, "%u rejected", stage_rejected_replies(s));
    CHECK(stage_wait(s, 1, 0) == SL_OK, "%s", stage_errmsg(s));
    /* every reply short: the call ends at its bound, naming the cause */
    CHECK(ctl(fx->f.port, FAKE_REG_LINE_DROP, 1000) == 0, "ctl");
    t0 = now_s();
    rc = stage_status(s, 0, &st);
    dt = now_s() - t0;
    note("status when every reply loses a byte, to its error", dt);
    CHECK(rc == SL_EIO && HAS(stage_errmsg(s), "reply cut short (no byte for 50 "
          "ms: a byte lost on the line?)"), "rc %d: %s", rc, stage_errmsg(s));
    CHECK(dt < CALL_MS * 1e-3 + MARGIN_S, "took %.3f s", dt);
    CHECK(ctl(fx->f.port, FAKE_REG_LINE_DROP, 0) == 0, "ctl");
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
}

/* A request damaged on its way to the stage: the stage's CRC check (or
 * its own byte timeout) drops it, nothing comes back: the response
 * timeout, as for a silent stage over TCP, and the next call is clean. */
RTU_TEST(rtu_request_damaged, )
{
    stage *s = fx->s;
    stage_wheel_status st;
    static const int regs[] = {FAKE_REG_LINE_NOISE_RX, FAKE_REG_LINE_DROP_RX};
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    for (int i = 0; i < 2; i++) {
        CHECK(ctl(fx->f.port, regs[i], 1) == 0, "ctl");
        double t0 = now_s();
        int rc = stage_status(s, 0, &st);
        double dt = now_s() - t0;
        note(i ? "status whose request lost a byte, to its error"
               : "status whose request was corrupted, to its error", dt);
        CHECK(rc == SL_EIO && HAS(stage_errmsg(s), "no reply within 300 ms "
              "(reconnecting)"), "register %d: rc %d: %s", regs[i], rc,
              stage_errmsg(s));
        CHECK(dt >= RESP_MS * 1e-3 && dt < RESP_MS * 1e-3 + MARGIN_S,
              "took %.3f s", dt);
        CHECK(ctl(fx->f.port, regs[i], -1) == 0, "register %d not consumed",
              regs[i]);
        t0 = now_s();
        CHECK(stage_status(s, 0, &st) == SL_OK && st.slots == 6, "%s",
              stage_errmsg(s));
        note("next status, reconnect included", now_s() - t0);
    }
    CHECK(stage_rejected_replies(s) == 0, "%u", stage_rejected_replies(s));
}

/* The port's settings reach the line: the fake answers unit 5 at 19200
 * baud, parity O only; a handle that differs in one of them gets no
 * reply, within its bound. */
TEST(rtu_settings)
{
    static const char *const args[] = {"--rtu", "--unit", "5", "--parity", "O",
                                       NULL};
    static const struct { int unit, baud; char parity; int ok; } cases[] = {
        {1, 19200, 'O', 0}, {5, 9600, 'O', 0}, {5, 19200, 'E', 0},
        {5, 19200, 'N', 0}, {5, 19200, 'O', 1}};
    char why[512];
    fake f;
    CHECK(fake_start(&f, 0, args, why, sizeof why) == 0, "%s", why);
    int bad = -1, rc = SL_OK;
    double worst = 0;
    char msg[SL_ERRMSG_MAX] = "";
    for (int i = 0; i < 5 && bad < 0; i++) {
        stage_config cfg;
        stage *s = NULL;
        sl_err e = {0};
        stage_wheel_status st;
        rtu_config(&cfg, f.rtu);
        cfg.unit_id = cases[i].unit;
        cfg.baud = cases[i].baud;
        cfg.parity = cases[i].parity;
        cfg.response_timeout_ms = 100;
        cfg.call_timeout_ms = 250;
        if (stage_new(&s, &cfg, &e) != SL_OK) {
            snprintf(msg, sizeof msg, "%s", e.msg);
            bad = i;
            break;
        }
        double t0 = now_s();
        rc = stage_status(s, 0, &st);
        double dt = now_s() - t0;
        worst = dt > worst ? dt : worst;
        snprintf(msg, sizeof msg, "%s", stage_errmsg(s));
        if ((rc == SL_OK) != cases[i].ok ||
            (!cases[i].ok && !HAS(msg, "no reply within 100 ms")))
            bad = i;
        stage_free(s);
    }
    fake_stop(&f);
    CHECK(bad < 0, "unit %d, %d baud, parity %c: rc %d: %s", cases[bad].unit,
          cases[bad].baud, cases[bad].parity, rc, msg);
    CHECK(worst < 0.25 + MARGIN_S, "a call took %.3f s for a 250 ms bound", worst);
}

/* The port vanishes (a USB adapter unplugged, the stage's process killed)
 * and comes back as another pty behind the same path: calls fail within
 * their bound meanwhile, and the handle reopens the path afterwards. */
TEST(rtu_port_gone_and_back)
{
    char dir[] = "/tmp/sl-rtu-XXXXXX", link[64], why[512];
    CHECK(mkdtemp(dir) != NULL, "mkdtemp: %s", strerror(errno));
    snprintf(link, sizeof link, "%s/ttySTAGE", dir);
    const char *const args[] = {"--rtu-link", link, NULL};
    fake f = {-1, 0, ""};
    stage_config cfg;
    stage *s = NULL;
    sl_err e = {0};
    stage_wheel_status st;
    int rc1 = -1, rc2 = -1, rc3 = -1, linked = 0, hung_up = 0;
    double dt_gone = 0, dt_back = 0;
    char msg[SL_ERRMSG_MAX] = "";
    rtu_config(&cfg, link);
    if (fake_start(&f, 0, args, why, sizeof why) == 0 &&
        stage_new(&s, &cfg, &e) == SL_OK) {
        struct stat lst;
        linked = lstat(link, &lst) == 0 && S_ISLNK(lst.st_mode);
        rc1 = stage_status(s, 0, &st);
        fake_stop(&f); /* the pty goes with it, and the link */
        hung_up = !stage_connected(s); /* seen without a request */
        double t0 = now_s();
        rc2 = stage_status(s, 0, &st);
        dt_gone = now_s() - t0;
        snprintf(msg, sizeof msg, "%s", stage_errmsg(s));
        if (fake_start(&f, 0, args, why, sizeof why) == 0) {
            t0 = now_s();
            rc3 = stage_status(s, 1, &st);
            dt_back = now_s() - t0;
        }
    }
    stage_free(s);
    fake_stop(&f);
    unlink(link);
    rmdir(dir);
    CHECK(linked && rc1 == SL_OK, "first status: rc %d (%s)", rc1, why);
    CHECK(hung_up, "a port that hung up is reported connected");
    note("status with the port gone, to its error", dt_gone);
    CHECK(rc2 == SL_EIO && HAS(msg, "No such file or directory"), "rc %d: %s",
          rc2, msg);
    CHECK(dt_gone < CALL_MS * 1e-3 + MARGIN_S, "took %.3f s", dt_gone);
    note("status with the port back, reopened", dt_back);
    CHECK(rc3 == SL_OK, "port back: rc %d: %s", rc3, why);
    CHECK(dt_back < CALL_MS * 1e-3 + MARGIN_S, "took %.3f s", dt_back);
}

/* Two handles on one port, as the daemon's runner and its device queries
 * are, talking at once from two threads: the port's lock makes one
 * master at a time, so no request meets another's reply. */
typedef struct hammer {
    stage *s;
    int wheel, n, fails;
    unsigned rejected;
    char msg[SL_ERRMSG_MAX];
} hammer;

static void *hammer_run(void *arg)
{
    hammer *h = arg;
    stage_wheel_status st;
    for (int i = 0; i < h->n && !h->fails; i++) {
        if (stage_status(h->s, h->wheel, &st) != SL_OK || st.wheel != h->wheel ||
            st.slots != (h->wheel ? 4 : 6)) {
            h->fails = i + 1;
            snprintf(h->msg, sizeof h->msg, "%s", stage_errmsg(h->s));
        }
    }
    h->rejected = stage_rejected_replies(h->s);
    return NULL;
}

RTU_TEST(rtu_shared_port, "--slots-mask", "4", "--parity", "E",)
{
    stage *s1 = NULL, *s2 = NULL;
    sl_err e = {0};
    /* Parity E: the second handle opens a pty already set as it wants,
     * less the parity bit a pty drops (stage_port_nudge) */
    CHECK(stage_new(&s1, &fx->cfg, &e) == SL_OK, "%s", e.msg);
    if (stage_new(&s2, &fx->cfg, &e) != SL_OK) {
        stage_free(s1);
        CHECK(0, "%s", e.msg);
    }
    hammer h[2] = {{s1, 0, 300, 0, 0, ""}, {s2, 1, 300, 0, 0, ""}};
    pthread_t th;
    double t0 = now_s();
    int started = pthread_create(&th, NULL, hammer_run, &h[1]) == 0;
    hammer_run(&h[0]);
    if (started)
        pthread_join(th, NULL);
    double dt = now_s() - t0;
    int connected = stage_connected(s1) && stage_connected(s2);
    stage_free(s1);
    stage_free(s2);
    note("2 handles x 300 status reads on one port, concurrently", dt);
    CHECK(started, "pthread_create");
    for (int i = 0; i < 2; i++)
        CHECK(h[i].fails == 0 && h[i].rejected == 0, "handle %d: read %d failed, "
              "%u rejected: %s", i, h[i].fails, h[i].rejected, h[i].msg);
    CHECK(connected, "a handle lost its connection");
}

/* Something else on the port changed its settings (libmodbus restores a
 * port's earlier settings when it closes it; another program may set
 * its own): the next call puts the handle's settings back first. */
RTU_TEST(rtu_settings_restored, )
{
    stage *s = fx->s;
    stage_wheel_status st;
    struct termios tio;
    CHECK(stage_status(s, 0, &st) == SL_OK, "%s", stage_errmsg(s));
    int fd = open(fx->f.rtu, O_RDWR | O_NOCTTY);
    CHECK(fd >= 0 && tcgetattr(fd, &tio) == 0, "%s: %s", fx->f.rtu, strerror(errno));
    /* a terminal's cooked mode: line editing, echo, CR to NL */
    tio.c_lflag |= ICANON | ECHO | ECHOE | ISIG;
    tio.c_iflag |= ICRNL | IXON;
    tio.c_oflag |= OPOST | ONLCR;
    cfsetispeed(&tio, B9600);
    cfsetospeed(&tio, B9600);
    int set = tcsetattr(fd, TCSANOW, &tio) == 0;
    close(fd);
    CHECK(set, "tcsetattr: %s", strerror(errno));
    for (int i = 0; i < 20; i++)
        CHECK(stage_status(s, i & 1, &st) == SL_OK && st.slots == 6, "read %d "
              "after the port was set cooked: %s", i, stage_errmsg(s));
    CHECK(stage_rejected_replies(s) == 0, "%u rejected", stage_rejected_replies(s));
}

TC_MAIN(TC_CASE(rtu_move_status), TC_CASE(rtu_busy), TC_CASE(rtu_slow_reply),
        TC_CASE(rtu_stall), TC_CASE(rtu_noise), TC_CASE(rtu_noise_burst),
        TC_CASE(rtu_drop),
        TC_CASE(rtu_request_damaged), TC_CASE(rtu_settings),
        TC_CASE(rtu_port_gone_and_back), TC_CASE(rtu_shared_port),
        TC_CASE(rtu_settings_restored))
