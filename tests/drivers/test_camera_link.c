/* test_camera_link.c - camera_check and camera_probe (drivers/camera.h):
 * is this host still in control of the camera?  Against
 * bin/specklab-fake-camera on loopback, each case in a private network
 * namespace (GVCP's port is fixed; proc_fx.h):
 *   restart_seen_idle   the camera restarts under an open handle:
 *                       camera_check, sending nothing, says CAMERA_ELOST
 *                       within 3 s (the heartbeat reads a privilege of 0
 *                       from the new camera), and camera_probe agrees; a
 *                       new handle on it passes both;
 *   gone_seen_idle      the camera is killed: camera_check says so within
 *                       10 s (Aravis's heartbeat gives up after ~5 s);
 *   second_host         a second handle on a camera the first controls:
 *                       either it is refused at open or both calls say
 *                       it does not control the camera; the first still
 *                       does;
 *   control_taken_back  the camera drops this host mid-stream (SIGUSR1),
 *                       still acquiring: camera_pop says CAMERA_ELOST,
 *                       camera_reconnect takes it back and frames come
 *                       again, restarted by the reconnect and, the second
 *                       time, by a camera_start 300 ms after it (by then
 *                       the camera streams again, towards the dropped
 *                       stream's port: the start must stop it first).
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <limits.h>
#include <net/if.h>
#include <poll.h>
#include <sched.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "camera.h"
#include "proc_fx.h"
#include "tcheck.h"

static int start_fake(fx_proc *p)
{
    char bin[PATH_MAX], line[256];
    fx_bin(bin, sizeof bin, "specklab-fake-camera");
    char *argv[] = {bin, "--size", "64", "-q", NULL};
    if (fx_spawn(p, argv, FX_STDERR, NULL, NULL) != 0)
        return -1;
    if (fx_wait_ready(p, line, sizeof line, 20) != 0) {
        fx_stop(p, SIGKILL, 5);
        return -1;
    }
    return 0;
}

/* camera_check until it is not SL_OK, for up to limit_s: its code. */
static int check_until_lost(camera *c, double limit_s, double *took_s)
{
    double t0 = fx_now();
    int rc = SL_OK;
    while ((rc = camera_check(c)) == SL_OK && fx_now() - t0 < limit_s)
        fx_nap_ms(50);
    *took_s = fx_now() - t0;
    return rc;
}

static void body_restart(tc *t)
{
    fx_proc fk;
    camera *c = NULL, *c2 = NULL;
    sl_err e = {0};
    double took = -1;
    CHECK(start_fake(&fk) == 0, "bin/specklab-fake-camera did not start (run make)");
    CHECK(camera_open(&c, "aravis", "127.0.0.1", &e) == SL_OK, "%s", e.msg);
    int ok0 = camera_check(c), probe0 = camera_probe(c);
    fx_stop(&fk, SIGTERM, 5);
    CHECK(start_fake(&fk) == 0, "the fake camera did not restart");
    int lost = check_until_lost(c, 3, &took);
    char msg[SL_ERRMSG_MAX];
    snprintf(msg, sizeof msg, "%s", camera_errmsg(c));
    int probe1 = camera_probe(c);
    int open2 = camera_open(&c2, "aravis", "127.0.0.1", &e);
    int ok2 = open2 == SL_OK ? camera_check(c2) : -1, probe2 = open2 == SL_OK ? camera_probe(c2) : -1;
    camera_close(c2);
    camera_close(c);
    fx_stop(&fk, SIGTERM, 5);
    printf("note: a restart seen by camera_check after %.2f s\n", took);
    CHECK(ok0 == SL_OK && probe0 == SL_OK, "before: check %d, probe %d", ok0, probe0);
    CHECK(lost == CAMERA_ELOST && strstr(msg, "camera 127.0.0.1"),
          "camera_check %d after %.2f s: %s", lost, took, msg);
    CHECK(probe1 == CAMERA_ELOST, "camera_probe after the restart: %d", probe1);
    CHECK(open2 == SL_OK && ok2 == SL_OK && probe2 == SL_OK,
          "a new handle: open %d (%s), check %d, probe %d", open2, e.msg, ok2, probe2);
}

static void body_gone(tc *t)
{
    fx_proc fk;
    camera *c = NULL;
    sl_err e = {0};
    double took = -1;
    CHECK(start_fake(&fk) == 0, "bin/specklab-fake-camera did not start (run make)");
    CHECK(camera_open(&c, "aravis", "127.0.0.1", &e) == SL_OK, "%s", e.msg);
    fx_stop(&fk, SIGKILL, 5);
    int lost = check_until_lost(c, 10, &took);
    char msg[SL_ERRMSG_MAX];
    snprintf(msg, sizeof msg, "%s", camera_errmsg(c));
    camera_close(c);
    printf("note: a killed camera seen by camera_check after %.2f s\n", took);
    CHECK(lost == CAMERA_ELOST && strstr(msg, "control lost"),
          "camera_check %d after %.2f s: %s", lost, took, msg);
}

static void body_second(tc *t)
{
    fx_proc fk;
    camera *c = NULL, *c2 = NULL;
    sl_err e = {0}, e2 = {0};
    CHECK(start_fake(&fk) == 0, "bin/specklab-fake-camera did not start (run make)");
    CHECK(camera_open(&c, "aravis", "127.0.0.1", &e) == SL_OK, "%s", e.msg);
    int open2 = camera_open(&c2, "aravis", "127.0.0.1", &e2);
    int check2 = open2 == SL_OK ? camera_check(c2) : open2;
    int probe2 = open2 == SL_OK ? camera_probe(c2) : open2;
    char msg[SL_ERRMSG_MAX];
    snprintf(msg, sizeof msg, "%s", open2 == SL_OK ? camera_errmsg(c2) : e2.msg);
    camera_close(c2);
    int check1 = camera_check(c), probe1 = camera_probe(c);
    camera_close(c);
    fx_stop(&fk, SIGTERM, 5);
    CHECK(open2 != SL_OK || (check2 == CAMERA_ELOST && probe2 == CAMERA_ELOST &&
                             strstr(msg, "does not control")),
          "second handle: open %d, check %d, probe %d: %s", open2, check2, probe2, msg);
    printf("note: the second handle: %s\n", msg);
    CHECK(check1 == SL_OK && probe1 == SL_OK, "the first handle: check %d, probe %d", check1,
          probe1);
}

/* camera_pop for up to limit_s until it returns `until` (SL_OK: a frame,
 * whatever its status, came to this stream; or CAMERA_ELOST) or another
 * error: that code; CAMERA_ETIMEOUT when neither came. */
static int pop_until(camera *c, int until, double limit_s)
{
    uint16_t pix[64 * 64];
    double end = fx_now() + limit_s;
    while (fx_now() < end) {
        int rc = camera_pop(c, 200, &(camera_frame){.u16 = pix, .capacity_px = 64 * 64});
        if (rc == until || (rc != SL_OK && rc != CAMERA_ETIMEOUT))
            return rc;
    }
    return CAMERA_ETIMEOUT;
}

static void body_taken_back(tc *t)
{
    fx_proc fk;
    camera *c = NULL;
    sl_err e = {0};
    int first = -1, lost[2] = {-1, -1}, back[2] = {-1, -1}, again[2] = {-1, -1};
    CHECK(start_fake(&fk) == 0, "bin/specklab-fake-camera did not start (run make)");
    CHECK(camera_open(&c, "aravis", "127.0.0.1", &e) == SL_OK, "%s", e.msg);
    if (camera_start(c, 8) == SL_OK)
        first = pop_until(c, SL_OK, 5);
    for (int k = 0; k < 2 && first == SL_OK; k++) {
        if (kill(fk.pid, SIGUSR1) != 0 || (lost[k] = pop_until(c, CAMERA_ELOST, 10)) !=
                                              CAMERA_ELOST)
            break;
        if (k == 1)
            camera_stop(c);
        back[k] = camera_reconnect(c, 5000);
        if (k == 1 && back[k] == SL_OK) {
            /* Controlled again and still acquiring, the camera begins
             * streaming at its next 100 ms tick, to the port it holds. */
            fx_nap_ms(300);
            back[k] = camera_start(c, 8);
        }
        if (back[k] != SL_OK || (again[k] = pop_until(c, SL_OK, 3)) != SL_OK)
            break;
    }
    char msg[SL_ERRMSG_MAX];
    snprintf(msg, sizeof msg, "%s", camera_errmsg(c));
    camera_close(c);
    fx_stop(&fk, SIGTERM, 5);
    CHECK(first == SL_OK, "no frame before the drop: %d, %s", first, msg);
    for (int k = 0; k < 2; k++)
        CHECK(lost[k] == CAMERA_ELOST && back[k] == SL_OK && again[k] == SL_OK,
              "drop %d (%s): pop %d, reconnect %d, frames after %d (%s)", k + 1,
              k ? "started 300 ms after the reconnect" : "restarted by the reconnect",
              lost[k], back[k], again[k], msg);
}

TEST(restart_seen_idle) { fx_in_netns(t, body_restart, 60); }
TEST(gone_seen_idle) { fx_in_netns(t, body_gone, 60); }
TEST(second_host) { fx_in_netns(t, body_second, 60); }
TEST(control_taken_back) { fx_in_netns(t, body_taken_back, 60); }

TC_MAIN(TC_CASE(restart_seen_idle), TC_CASE(gone_seen_idle), TC_CASE(second_host),
        TC_CASE(control_taken_back))
