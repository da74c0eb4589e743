/* test_camera_u3v.c - drivers/camera (Aravis backend) on a USB3 Vision
 * camera: bin/specklab-fake-u3v, a U3V device in a umockdev testbed that
 * Aravis's ArvUvDevice opens through libusb like a real one (GenCP
 * bootstrap, GenICam XML, leader/payload/trailer stream).
 *
 * The binary re-executes itself under libumockdev-preload.so.0; each test
 * runs in a forked child (fresh Aravis and libusb state) that starts its
 * own camera and points $UMOCKDEV_DIR at its testbed.  Synchronisation:
 * the camera's READY line and its answers to unplug/plug, each with a
 * deadline.
 *
 * Pixel truth: the camera renders through mocks/camsrc like the GigE fake
 * camera, so camtruth_fx.h re-renders every frame and the test compares
 * pixels exactly.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include "preload_fx.h"   /* glib before fakecam.h's mask type */
#include "camera.h"
#include "camtruth_fx.h"
#include "proc_fx.h"
#include "tcheck.h"
#include "u3v_fx.h"

#define LIMIT_S 60

/* The camera, our driver on it (Mono16, the ROI, fps), started. */
typedef struct session {
    fx_u3v u3v;
    camera *c;
    truth *tr;
    uint16_t *pix;
    char err[512];
} session;

static int session_open(session *s, size_t nslot, double fps)
{
    memset(s, 0, sizeof *s);
    s->u3v.p.pid = -1;
    s->u3v.in = -1;
    s->tr = calloc(1, sizeof *s->tr);
    s->pix = malloc(sizeof *s->pix * NPX * nslot);
    if (!s->tr || !s->pix)
        return snprintf(s->err, sizeof s->err, "out of memory"), -1;
    if (truth_new(s->tr, 3, 10000, 0, s->err, sizeof s->err) != 0)
        return -1;
    if (fx_u3v_start(&s->u3v, NULL) != 0)
        return snprintf(s->err, sizeof s->err, "bin/specklab-fake-u3v did not start "
                        "(run make)"), -1;
    return camtruth_open(&s->c, FX_U3V_ID, fps, 16, s->err, sizeof s->err);
}

static int session_pop(session *s, int timeout_ms, camera_frame *f, size_t k)
{
    return camtruth_pop(s->c, s->pix, timeout_ms, f, k, s->err, sizeof s->err);
}

static void session_close(session *s)
{
    camera_close(s->c);
    s->c = NULL;
    fx_u3v_stop(&s->u3v);
    if (s->tr)
        truth_free(s->tr);
    free(s->tr);
    free(s->pix);
}

/* SUCCESS frames in fr[0..n) whose pixels differ from the simulator's,
 * and jumps in their ids. */
static void check_frames(session *s, const camera_frame *fr, int n, int *good, int *bad_px,
                         int *jumps)
{
    *good = *bad_px = *jumps = 0;
    for (int i = 0; i < n; i++) {
        if (i > 0 && fr[i].frame_id != fr[i - 1].frame_id + 1)
            (*jumps)++;   /* U3V ids are 64-bit: no wrap */
        if (fr[i].status != CAMERA_FRAME_SUCCESS)
            continue;
        (*good)++;
        *bad_px += truth_diff(s->tr, fr[i].frame_id, fr[i].u16) != 0;
    }
}

/* ---- tests --------------------------------------------------------------- */

/* Listed by the backend as a USB3 Vision camera, opened by Aravis's
 * vendor-serial id, identified through its GenICam features. */
static void body_listed(tc *t)
{
    fx_u3v u;
    sl_err e = {0};
    CHECK(fx_u3v_start(&u, NULL) == 0, "bin/specklab-fake-u3v did not start (run make)");
    camera_info *v = NULL, info = {0};
    int n = 0, found = -1;
    int rc = camera_list("aravis", &v, &n, &e);
    for (int i = 0; rc == SL_OK && i < n; i++)
        if (strcmp(v[i].serial, FX_U3V_SERIAL) == 0)
            found = i;
    char proto[32] = "";
    if (found >= 0)
        snprintf(proto, sizeof proto, "%s", v[found].protocol);
    free(v);
    camera *c = NULL;
    int orc = camera_open(&c, "aravis", FX_U3V_ID, &e);
    if (orc == SL_OK)
        orc = camera_info_get(c, &info);
    camera_close(c);
    fx_u3v_stop(&u);
    CHECK(rc == SL_OK && found >= 0, "camera_list (%d cameras) lacks serial %s: %s", n,
          FX_U3V_SERIAL, e.msg);
    CHECK(strcmp(proto, "USB3Vision") == 0, "listed as '%s'", proto);
    CHECK(orc == SL_OK, "open %s: %s", FX_U3V_ID, e.msg);
    CHECK(strcmp(info.protocol, "USB3Vision") == 0 && strcmp(info.serial, FX_U3V_SERIAL) == 0,
          "info: protocol '%s', serial '%s'", info.protocol, info.serial);
}

/* 200 frames at 200 Hz: every id, every frame SUCCESS, pixels the sim's. */
static void body_frames(tc *t)
{
    enum { N = 200 };
    session s;
    camera_frame fr[N];
    int rc = session_open(&s, N, 200), n = 0;
    double t0 = fx_now();
    for (; rc == 0 && n < N; n++)
        rc = session_pop(&s, 2000, &fr[n], (size_t)n);
    double wall = fx_now() - t0;
    camera_stats st = {0};
    if (s.c)
        camera_stats_get(s.c, &st);
    int good = 0, bad_px = 0, jumps = 0;
    if (rc == 0)
        check_frames(&s, fr, N, &good, &bad_px, &jumps);
    session_close(&s);
    CHECK(rc == 0, "after %d frames: %s", n, s.err);
    printf("note: %d frames %dx%d Mono16 over U3V in %.2f s (%.0f fps wall, 200 Hz asked)\n",
           N, ROI_W, ROI_H, wall, N / wall);
    CHECK(good == N && st.completed == N && st.failed == 0, "%d of %d SUCCESS (stats %llu + %llu)",
          good, N, (unsigned long long)st.completed, (unsigned long long)st.failed);
    CHECK(jumps == 0 && st.id_gaps == 0, "%d jumps in the frame ids", jumps);
    CHECK(bad_px == 0, "%d frames differ from the simulator", bad_px);
}

/* Unplugged mid-stream: camera_pop says control lost (not a timeout
 * loop); plugged back: camera_reconnect re-opens it, re-applies the
 * settings, and frames are the simulator's again. */
static void body_unplug(tc *t)
{
    enum { N = 20 };
    session s;
    camera_frame fr[N];
    int rc = session_open(&s, N, 100), n = 0, lost_rc = 0, pops = 0;
    for (; rc == 0 && n < 10; n++)
        rc = session_pop(&s, 2000, &fr[n], (size_t)n);
    int unplugged = rc == 0 && fx_u3v_command(&s.u3v, "unplug", "UNPLUGGED") == 0;
    double t0 = fx_now();
    while (unplugged && pops++ < 50 && (lost_rc = session_pop(&s, 200, &fr[n], (size_t)n)) == SL_OK)
        ;
    double lost_s = fx_now() - t0;
    int plugged = unplugged && fx_u3v_command(&s.u3v, "plug", "PLUGGED") == 0;
    int rrc = plugged ? camera_reconnect(s.c, 10000) : -1;
    char rerr[512] = "";
    if (rrc != SL_OK && s.c)
        snprintf(rerr, sizeof rerr, "%s", camera_errmsg(s.c));
    int m = n;
    for (; rrc == SL_OK && m < N; m++)
        rrc = session_pop(&s, 2000, &fr[m], (size_t)m);
    int good = 0, bad_px = 0, jumps = 0;
    if (rrc == SL_OK)
        check_frames(&s, fr + n, N - n, &good, &bad_px, &jumps);
    session_close(&s);
    CHECK(rc == 0, "before the unplug: %s", s.err);
    CHECK(unplugged, "the camera did not answer 'unplug'");
    CHECK(lost_rc == CAMERA_ELOST, "after the unplug camera_pop gave %d (%s), not CAMERA_ELOST",
          lost_rc, sl_strstatus(lost_rc));
    printf("note: control lost %.2f s after the unplug\n", lost_s);
    CHECK(plugged, "the camera did not answer 'plug'");
    CHECK(rrc == SL_OK, "after the re-plug: %s", rerr[0] ? rerr : s.err);
    CHECK(good == N - n && bad_px == 0, "after the re-plug %d of %d SUCCESS, %d differ", good,
          N - n, bad_px);
}

TEST(u3v_listed_and_identified) { fx_in_child(t, body_listed, LIMIT_S); }
TEST(u3v_frames_match_simulator) { fx_in_child(t, body_frames, LIMIT_S); }
TEST(u3v_unplug_lost_and_replug) { fx_in_child(t, body_unplug, LIMIT_S); }

int main(int argc, char **argv)
{
    static const tc_case cases[] = {
        TC_CASE(u3v_listed_and_identified),
        TC_CASE(u3v_frames_match_simulator),
        TC_CASE(u3v_unplug_lost_and_replug),
    };
    fx_reexec_preloaded(argv, "SPECKLAB_TEST_U3V_REEXEC");
    if (!fx_preloaded()) {
        printf("skip test_camera_u3v: %s cannot be loaded (install umockdev)\n", PRELOAD_LIB);
        return tc_main(argv[0], argc, argv, cases, 0);
    }
    return tc_main(argv[0], argc, argv, cases, (int)(sizeof cases / sizeof cases[0]));
}
