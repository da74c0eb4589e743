/* test_camera.c - drivers/camera (Aravis backend), the fake speckle
 * camera and `specklab camera grab`, against fake GigE Vision cameras on
 * loopback: bin/specklab-fake-camera (ours) and arv-fake-gv-camera-0.8.
 * The network tier: what needs the wire (packet loss, a killed camera,
 * discovery, the heartbeat); test_camera_fake checks the same frames on
 * the in-process fake without a network.
 *
 * Namespaces: GVCP's port 3956 is fixed, so every test runs in a forked
 * child with a private network namespace (unshare CLONE_NEWNET, with
 * CLONE_NEWUSER when not root) whose loopback is brought up by ioctl; the
 * fakes it starts inherit it and die with it (PR_SET_PDEATHSIG).  Without
 * namespace support the child says so and uses the host's namespace
 * (tests/run then runs binaries one at a time).  The parent reads the child's
 * verdict with a deadline.  Aravis/GLib start only in the children.
 *
 * Synchronisation: fakes are waited for by their READY line (the stock
 * camera, which has none, by its UDP port appearing in /proc/net/udp),
 * always with a deadline.
 *
 * Pixel truth: mocks/camsrc/fakecam.h defines every frame as a
 * function of (flags, frame id); the test builds the same simulator and
 * compares pixels exactly.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <fitsio.h>
#include <libgen.h>
#include <limits.h>
#include <modbus.h>
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
#include "io/cube.h"
#include "stage_map.h"
#include "proc_fx.h"
#include "tcheck.h"
#include "camtruth_fx.h"

/* Run to completion (its own timeouts bound it): the exit status. */
static int run_wait(char *const argv[], int quiet)
{
    fx_proc p;
    int st = 0;
    if (fx_spawn(&p, argv, quiet ? NULL : FX_STDERR, NULL, NULL) != 0)
        return -1;
    waitpid(p.pid, &st, 0);
    close(p.out);
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

static int start_fake(fx_proc *p, const char *extra1, const char *extra2, const char *extra3)
{
    static char bin[PATH_MAX];
    fx_bin(bin, sizeof bin, "specklab-fake-camera");
    char size[32], line[256];
    snprintf(size, sizeof size, "%dx%d", SENSOR_W, SENSOR_H);
    char *argv[] = {bin, "--size", size, "--seed", "11", "--screen-slot", "3", "-q",
                    (char *)extra1, (char *)extra2, (char *)extra3, NULL};
    if (access(bin, X_OK) != 0 || fx_spawn(p, argv, FX_STDERR, NULL, NULL) != 0)
        return -1;
    if (fx_wait_ready(p, line, sizeof line, 20) != 0) {
        fx_stop(p, SIGKILL, 5);
        return -1;
    }
    return 0;
}

/* One of our fake cameras (start_fake's flags plus x1..x3) and our camera
 * on it: Mono16, the ROI, fps, started with nbuf buffers; room for nslot
 * frames in pix; tr is the truth of screen slot `screen`. */
typedef struct session {
    fx_proc fake;
    camera *c;
    truth *tr;
    uint16_t *pix;
    camera_stats st;
    char err[512];
} session;

static int session_open(session *s, size_t nslot, int screen, double fps, int nbuf,
                        const char *x1, const char *x2, const char *x3)
{
    memset(s, 0, sizeof *s);
    s->fake.pid = -1;
    s->tr = calloc(1, sizeof *s->tr);
    s->pix = malloc(sizeof *s->pix * NPX * nslot);
    if (!s->tr || !s->pix)
        return snprintf(s->err, sizeof s->err, "out of memory"), -1;
    if (truth_new(s->tr, screen, 10000, 0, s->err, sizeof s->err) != 0)
        return -1;
    if (start_fake(&s->fake, x1, x2, x3) != 0)
        return snprintf(s->err, sizeof s->err, "bin/specklab-fake-camera did not start "
                        "(run make)"), -1;
    return camtruth_open(&s->c, "127.0.0.1", fps, nbuf, s->err, sizeof s->err);
}

/* Pop into frame slot k of pix; on error the message goes to s->err. */
static int session_pop(session *s, int timeout_ms, camera_frame *f, size_t k)
{
    return camtruth_pop(s->c, s->pix, timeout_ms, f, k, s->err, sizeof s->err);
}

/* Close the camera before the fake goes (closing talks to it). */
static void session_close(session *s)
{
    if (s->c)
        camera_stats_get(s->c, &s->st);
    camera_close(s->c);
    s->c = NULL;
    fx_stop(&s->fake, SIGTERM, 5);
    if (s->tr)
        truth_free(s->tr);
    free(s->tr);
    free(s->pix);
}

/* ---- tests --------------------------------------------------------------- */

/* 1000 frames at up to 500 Hz: every id arrives, pixels are the sim's.
 * (At 1 kHz a 64x64 frame also streams, but AUTO's one-payload socket
 * buffer then leaves ~2 ms of slack for a busy CI machine.) */
static void body_frames(tc *t)
{
    enum { N = 1000 };
    session s;
    camera_frame *fr = calloc(N, sizeof *fr);
    int rc = session_open(&s, N, 3, 500, 64, NULL, NULL, NULL), n = 0;
    if (!fr)
        rc = -1, snprintf(s.err, sizeof s.err, "out of memory");
    double t0 = fx_now();
    for (; rc == 0 && n < N; n++)
        rc = session_pop(&s, 2000, &fr[n], (size_t)n);
    double wall = fx_now() - t0;
    int good = 0, later_bad = 0, bad_px = 0, gaps = 0, first_good = -1;
    for (int i = 0; rc == 0 && i < N; i++) {
        if (i > 0 && fr[i].frame_id != (fr[i - 1].frame_id == 65535 ? 1 : fr[i - 1].frame_id + 1))
            gaps++;
        if (fr[i].status != CAMERA_FRAME_SUCCESS) {
            later_bad += i > 0;   /* the first frame may be MISSING_PACKETS */
            continue;
        }
        good++;
        first_good = first_good < 0 ? i : first_good;
        bad_px += truth_diff(s.tr, fr[i].frame_id, fr[i].u16) != 0;
    }
    uint16_t lo = 65535, hi = 0;
    for (size_t i = 0; first_good >= 0 && i < NPX; i++) {
        uint16_t v = fr[first_good].u16[i];
        lo = v < lo ? v : lo;
        hi = v > hi ? v : hi;
    }
    double span = rc == 0 ? (fr[N - 1].cam_ts_ns - fr[0].cam_ts_ns) * 1e-9 : 0;
    session_close(&s);
    free(fr);
    CHECK(rc == 0, "after %d frames: %s", n, s.err);
    printf("note: %d frames %dx%d Mono16 in %.2f s: %.0f fps (camera clock), %.0f fps "
           "(wall)\n", N, ROI_W, ROI_H, wall, (N - 1) / span, N / wall);
    CHECK(gaps == 0 && s.st.id_gaps == 0, "%d jumps in the frame ids (%llu ids lost)", gaps,
          (unsigned long long)s.st.id_gaps);
    CHECK(later_bad == 0 && good >= N - 1, "%d of %d frames SUCCESS", good, N);
    CHECK(s.st.completed == (uint64_t)good && s.st.completed + s.st.failed == N,
          "stats %llu + %llu", (unsigned long long)s.st.completed,
          (unsigned long long)s.st.failed);
    CHECK(bad_px == 0, "%d SUCCESS frames differ from the simulator", bad_px);
    /* Speckle, not a dark frame: far above bias + read noise. */
    CHECK(hi > 150 && lo < 150, "the first good frame is flat (%u..%u ADU, bias 100)", lo, hi);
}

/* How far id b is ahead of a on the GigE 1..65535 cycle (negative: behind). */
static long ring_ahead(uint64_t a, uint64_t b)
{
    long d = ((long)b - (long)a) % 65535;
    d += d < 0 ? 65535 : 0;
    return d > 32767 ? d - 65535 : d;
}

/* 5% of packets lost: damaged frames are counted and never SUCCESS. */
static void body_lossy(tc *t)
{
    enum { N = 300 };
    session s;
    int rc = session_open(&s, 1, 3, 500, 128, "--lost-ratio", "0.05", NULL), n = 0;
    int good = 0, wrong = 0, unknown = 0, known = 0;
    uint64_t first = 0, newest = 0;
    for (camera_frame f; rc == 0 && n < N; n++) {
        if ((rc = session_pop(&s, 2000, &f, 0)) != 0)
            break;
        /* Damaged frames may come back after later ones (keep the newest
         * id), or with id 0 when their leader packet was lost. */
        if (f.frame_id == 0) {
            unknown++;
            wrong += f.status == CAMERA_FRAME_SUCCESS;   /* good without an id */
        } else {
            first = known == 0 ? f.frame_id : first;
            newest = known++ == 0 || ring_ahead(newest, f.frame_id) > 0 ? f.frame_id : newest;
        }
        if (f.status == CAMERA_FRAME_SUCCESS)
            good++, wrong += truth_diff(s.tr, f.frame_id, s.pix) != 0;
    }
    session_close(&s);
    camera_stats st = s.st;
    CHECK(rc == 0, "after %d frames: %s", n, s.err);
    printf("note: lost ratio 0.05: %d good, %llu damaged (%d without id), %llu missing "
           "packets, %llu ids lost, %llu underruns\n", good, (unsigned long long)st.failed, unknown,
           (unsigned long long)st.missing_packets, (unsigned long long)st.id_gaps,
           (unsigned long long)st.underruns);
    CHECK(wrong == 0, "%d SUCCESS frames have wrong pixels", wrong);
    CHECK(st.failed > 0 && st.missing_packets > 0, "no damage seen at 5%% packet loss");
    CHECK(st.completed == (uint64_t)good && st.completed + st.failed == N,
          "popped %d: %llu completed + %llu failed", N, (unsigned long long)st.completed,
          (unsigned long long)st.failed);
    /* Every id the camera sent in the span was returned or counted lost. */
    long span = ring_ahead(first, newest) + 1;
    CHECK(known + (long)st.id_gaps == span, "ids %llu..%llu (%ld): %d popped with an id + %llu "
          "lost", (unsigned long long)first, (unsigned long long)newest, span, known,
          (unsigned long long)st.id_gaps);
}

/* Kill the camera mid-stream; errors come within a bound; it reconnects,
 * with the heartbeat timeout set before (the camera's register reads it
 * back, and the new camera gets it again). */
static void body_kill(tc *t)
{
    session s;
    camera_frame f;
    int beat0 = -1, beat1 = -1, beat_bad = SL_OK;
    int rc = session_open(&s, 1, 3, 200, 16, NULL, NULL, NULL);
    if (rc == 0 && (camera_set_heartbeat_ms(s.c, 4000) != SL_OK ||
                    camera_heartbeat_ms(s.c, &beat0) != SL_OK))
        rc = -1, snprintf(s.err, sizeof s.err, "%s", camera_errmsg(s.c));
    if (rc == 0)
        beat_bad = camera_set_heartbeat_ms(s.c, 50);
    for (int i = 0; rc == 0 && i < 20; i++)
        rc = session_pop(&s, 2000, &f, 0);
    fx_stop(&s.fake, SIGKILL, 5);
    double t_kill = fx_now(), t_first = -1, t_lost = -1;
    char lost_msg[SL_ERRMSG_MAX] = "";
    while (rc == 0 && t_lost < 0 && fx_now() - t_kill < 20) {
        int r = camera_pop(s.c, 500, &(camera_frame){.u16 = s.pix, .capacity_px = NPX});
        t_first = r != SL_OK && t_first < 0 ? fx_now() - t_kill : t_first;
        if (r == CAMERA_ELOST) {
            t_lost = fx_now() - t_kill;
            snprintf(lost_msg, sizeof lost_msg, "%s", camera_errmsg(s.c));
        }
    }
    int rc2 = -1, good = 0, wrong = 0;
    if (rc == 0 && t_lost >= 0 && start_fake(&s.fake, NULL, NULL, NULL) == 0) {
        double t0 = fx_now();
        if ((rc2 = camera_reconnect(s.c, 10000)) != SL_OK)
            snprintf(s.err, sizeof s.err, "%s", camera_errmsg(s.c));
        printf("note: kill -9: first error after %.2f s, control lost after %.2f s; "
               "reconnected in %.2f s\n", t_first, t_lost, fx_now() - t0);
        for (int i = 0; rc2 == SL_OK && i < 20; i++)
            if ((rc2 = session_pop(&s, 2000, &f, 0)) == SL_OK && f.status == CAMERA_FRAME_SUCCESS)
                good++, wrong += truth_diff(s.tr, f.frame_id, s.pix) != 0;
        if (rc2 == SL_OK)
            camera_heartbeat_ms(s.c, &beat1);
    }
    session_close(&s);
    CHECK(rc == 0, "before the kill: %s", s.err);
    CHECK(t_first >= 0 && t_first < 3, "no error within 3 s of the kill (%.2f)", t_first);
    CHECK(t_lost >= 0, "no CAMERA_ELOST within 20 s of the kill");
    CHECK(strstr(lost_msg, "camera 127.0.0.1") && strstr(lost_msg, "control lost"),
          "unclear message: %s", lost_msg);
    CHECK(rc2 == SL_OK, "after reconnect: %s", s.err);
    CHECK(good >= 19 && wrong == 0, "after reconnect %d good frames, %d wrong", good, wrong);
    CHECK(s.st.reconnects == 1, "reconnects %llu", (unsigned long long)s.st.reconnects);
    CHECK(beat0 == 4000 && beat1 == 4000 && beat_bad == SL_ERANGE,
          "heartbeat timeout %d ms set, %d after the reconnect; 50 ms: %d", beat0, beat1,
          beat_bad);
}

/* Discovery finds our camera; an absent one is a clear, bounded error. */
/* Discovery finds our camera; exposure and gain reach the rendering; an
 * absent camera is a clear, bounded error. */
static void body_list_absent(tc *t)
{
    session s;
    truth *bright = calloc(1, sizeof *bright);
    camera_info *v = NULL;
    camera_frame f;
    int n = 0, found = 0, good = 0, wrong = 0;
    sl_err e = {0};
    int rc = session_open(&s, 1, 3, 200, 16, "--serial", "LISTME", NULL);
    if (rc == 0 && camera_list("aravis", &v, &n, &e) != SL_OK)
        rc = -1, snprintf(s.err, sizeof s.err, "%s", e.msg);
    for (int i = 0; i < n; i++)
        found += !strcmp(v[i].serial, "LISTME") && !strcmp(v[i].address, "127.0.0.1") &&
                 !strcmp(v[i].protocol, "GigEVision");
    free(v);
    /* 20 ms and 6 dB: twice the photons at half the electrons per ADU. */
    if (rc == 0 && (!bright || truth_new(bright, 3, 20000, 6, s.err, sizeof s.err) != 0))
        rc = -1;
    if (rc == 0 && (camera_stop(s.c) != SL_OK || camera_set_exposure_us(s.c, 20000) != SL_OK ||
                    camera_set_gain_db(s.c, 6) != SL_OK || camera_start(s.c, 16) != SL_OK))
        rc = -1, snprintf(s.err, sizeof s.err, "%s", camera_errmsg(s.c));
    for (int i = 0; rc == 0 && i < 10; i++)
        if ((rc = session_pop(&s, 2000, &f, 0)) == 0 && f.status == CAMERA_FRAME_SUCCESS)
            good++, wrong += truth_diff(bright, f.frame_id, s.pix) != 0;
    /* Refusals name the problem: range, and geometry while streaming. */
    int r_exp = rc == 0 ? camera_set_exposure_us(s.c, 1e9) : 0;
    char m_exp[SL_ERRMSG_MAX];
    snprintf(m_exp, sizeof m_exp, "%s", rc == 0 ? camera_errmsg(s.c) : "");
    int r_roi = rc == 0 ? camera_set_roi(s.c, 0, 0, 32, 32) : 0;
    session_close(&s);
    if (bright)
        truth_free(bright);
    free(bright);
    CHECK(rc == 0, "%s", s.err);
    CHECK(found == 1, "camera_list: %d cameras, ours not among them", n);
    CHECK(good >= 9 && wrong == 0, "at 20 ms, 6 dB: %d good frames, %d not the simulator's",
          good, wrong);
    CHECK(r_exp == SL_ERANGE && strstr(m_exp, "outside the camera's range"), "exposure 1e9 us "
          "gave %d: %s", r_exp, m_exp);
    CHECK(r_roi == SL_EINVAL, "ROI change while acquiring gave %d", r_roi);
    CHECK(camera_open(&(camera *){NULL}, "nope", "127.0.0.1", &e) == SL_EINVAL &&
          strstr(e.msg, "unknown camera backend"), "unknown backend: %s", e.msg);
    camera *c = NULL;
    double t0 = fx_now();
    rc = camera_open(&c, "aravis", "127.0.0.1", &e);
    double dt = fx_now() - t0;
    camera_close(c);
    CHECK(rc == CAMERA_ENODEV, "open with nobody there gave %d (%s)", rc, e.msg);
    CHECK(strstr(e.msg, "camera 127.0.0.1:") && strstr(e.msg, "no reply"), "unclear: %s", e.msg);
    CHECK(dt < 10, "open took %.1f s to fail", dt);
}

static int udp_port_bound(int port)
{
    FILE *f = fopen("/proc/net/udp", "r");
    char line[512], want[16];
    int found = 0;
    snprintf(want, sizeof want, ":%04X ", port);
    while (f && !found && fgets(line, sizeof line, f))
        found = strstr(line, want) != NULL;
    if (f)
        fclose(f);
    return found;
}

/* `grab` against the stock Aravis fake: a readable cube, FRAMES table,
 * and pixels that are the stock diagonal ramp of their FRAME_ID. */
static void body_grab_stock(tc *t)
{
    enum { N = 25 };
    char *stock = "/usr/bin/arv-fake-gv-camera-0.8", cli[PATH_MAX], out[] = "/tmp/sl-grab-XXXXXX";
    if (access(stock, X_OK) != 0)
        SKIP("%s not installed", stock);
    int fd = mkstemp(out);
    CHECK(fd >= 0, "mkstemp: %s", strerror(errno));
    close(fd);
    fx_proc fake;
    char *fargv[] = {stock, "-i", "127.0.0.1", NULL};
    CHECK(fx_spawn(&fake, fargv, NULL, NULL, NULL) == 0, "cannot start %s", stock);
    double end = fx_now() + 10;
    while (!udp_port_bound(3956) && fx_now() < end)
        fx_nap_ms(10);
    fx_bin(cli, sizeof cli, "specklab");
    char *gargv[] = {cli, "camera", "grab", "--camera", "127.0.0.1", "--frames", "25",
                     "--roi", "0,0,64,48", "--frame-rate-hz", "200", "-o", out,
                     "--overwrite" /* mkstemp made it */, NULL};
    char *help[] = {cli, "camera", "--help", NULL};
    int via_bin = access(cli, X_OK) == 0 && run_wait(help, 1) == 0, status = -1;
    if (via_bin)
        status = run_wait(gargv, 0);
    fx_stop(&fake, SIGTERM, 5);
    CHECK(via_bin, "%s is missing or has no camera command (run make)", cli);
    seq *s = NULL;
    sl_err e = {0};
    const char *paths[] = {out};
    int rc = status == 0 ? cube_read(&s, NULL, paths, 1, 0, &e) : -1;
    fitsfile *f = NULL;
    int fs = 0, anynul = 0, ok_rows = 0, ramp_bad = 0;
    long nrows = 0;
    LONGLONG ids[4 * N];
    int idx[4 * N];
    if (rc == SL_OK) {
        fits_open_diskfile(&f, out, READONLY, &fs);
        fits_movnam_hdu(f, BINARY_TBL, "FRAMES", 0, &fs);
        fits_get_num_rows(f, &nrows, &fs);
        if (!fs && nrows > 4 * N)
            nrows = 4 * N;
        fits_read_col(f, TLONGLONG, 1, 1, 1, nrows, NULL, ids, &anynul, &fs);
        fits_read_col(f, TINT, 5, 1, 1, nrows, NULL, idx, &anynul, &fs);
        for (long r = 0; !fs && r < nrows; r++) {
            if (idx[r] < 0 || idx[r] >= s->nframes)
                continue;
            ok_rows++;
            const float *img = seq_frame(s, idx[r]);
            for (int y = 0; y < 48; y++)
                for (int x = 0; x < 64; x++)
                    ramp_bad += img[y * 64 + x] != (float)((x + y + ids[r]) % 255);
        }
        int s2 = 0;
        fits_close_file(f, fs ? &s2 : &fs);
    }
    unlink(out);
    CHECK(status == 0, "grab exited %d", status);
    CHECK(rc == SL_OK, "cube unreadable: %s", e.msg);
    int nf = s->nframes, w = s->width, h = s->height;
    seq_free(s);
    CHECK(nf == N && w == 64 && h == 48, "cube %dx%dx%d, expected 64x48x%d", w, h, nf, N);
    CHECK(fs == 0, "FRAMES table unreadable (cfitsio %d)", fs);
    CHECK(nrows >= N && ok_rows == N, "%ld rows, %d stored", nrows, ok_rows);
    CHECK(ramp_bad == 0, "%d pixels differ from the stock ramp of their FRAME_ID", ramp_bad);
}

/* The stage moves the screen wheel: the camera renders the new seeing. */
static int stage_cmd(modbus_t *m, int wheel, int cmd, int target)
{
    if (target >= 0 && modbus_write_register(m, STAGE_REG_WHEEL_BASE(wheel) + STAGE_WREG_TARGET,
                                             target) != 1)
        return -1;
    if (modbus_write_register(m, STAGE_REG_CMD_WHEEL, wheel) != 1)
        return -1;
    return modbus_write_register(m, STAGE_REG_COMMAND, cmd) == 1 ? 0 : -1;
}

static int stage_settled(modbus_t *m, int screen_slot, double limit_s)
{
    double end = fx_now() + limit_s;
    while (fx_now() < end) {
        uint16_t a[STAGE_WHEEL_NREGS], b[STAGE_WHEEL_NREGS];
        if (modbus_read_registers(m, STAGE_REG_WHEEL_BASE(0), STAGE_WHEEL_NREGS, a) ==
                STAGE_WHEEL_NREGS &&
            modbus_read_registers(m, STAGE_REG_WHEEL_BASE(1), STAGE_WHEEL_NREGS, b) ==
                STAGE_WHEEL_NREGS &&
            (a[STAGE_WREG_STATUS] & STAGE_ST_INPOS) && (b[STAGE_WREG_STATUS] & STAGE_ST_INPOS) &&
            a[STAGE_WREG_POSITION] == screen_slot)
            return 0;
        fx_nap_ms(10);
    }
    return -1;
}

/* Pop until a frame equals the rendering of tr (<= 5 s); its peak
 * fraction above bias is returned in *peak. */
static int see(camera *c, truth *tr, uint16_t *pix, double *peak)
{
    double end = fx_now() + 5;
    while (fx_now() < end) {
        camera_frame f = {.u16 = pix, .capacity_px = NPX};
        if (camera_pop(c, 1000, &f) != SL_OK || f.status != CAMERA_FRAME_SUCCESS ||
            truth_diff(tr, f.frame_id, pix) != 0)
            continue;
        double sum = 0, mx = 0;
        for (size_t i = 0; i < NPX; i++) {
            double v = pix[i] - tr->m.bias_adu;
            sum += v;
            mx = v > mx ? v : mx;
        }
        *peak = mx / sum;
        return 0;
    }
    return -1;
}

static void body_stage(tc *t)
{
    static const char *const steps[] = {"setup", "HOME", "MOVE screen to 1",
                                        "frames of slot 1", "MOVE screen to 5",
                                        "frames of slot 5", "done"};
    char bin[PATH_MAX], line[256], hp[64];
    fx_bin(bin, sizeof bin, "specklab-fake-stage");
    if (access(bin, X_OK) != 0)
        SKIP("%s not built: the stage-driven seeing is untested", bin);
    fx_proc stg;
    char *sargv[] = {bin, "--port", "0", "--step-ms", "20", NULL};
    int port = 0, step = 0;
    CHECK(fx_spawn(&stg, sargv, NULL, NULL, NULL) == 0 && fx_wait_ready(&stg, line, sizeof line, 10) == 0 &&
          sscanf(line, "READY port=%d", &port) == 1, "fake stage did not start");
    snprintf(hp, sizeof hp, "127.0.0.1:%d", port);
    session s;
    truth *fast = calloc(1, sizeof *fast);
    modbus_t *m = modbus_new_tcp("127.0.0.1", port);
    double peak_good = 0, peak_bad = 0;
    if (session_open(&s, 1, 1, 200, 32, "--stage", hp, "--stage-poll-ms=20") == 0 && fast &&
        truth_new(fast, 5, 10000, 0, s.err, sizeof s.err) == 0 && m && modbus_connect(m) == 0) {
        modbus_set_response_timeout(m, 1, 0);
        step = 1;
        /* Wheels start unhomed: HOME both, then move the screen wheel. */
        if (stage_cmd(m, STAGE_WHEEL_ALL, STAGE_CMD_HOME, -1) == 0 && stage_settled(m, 0, 5) == 0)
            step = 2;
        if (step == 2 && stage_cmd(m, 0, STAGE_CMD_MOVE, 1) == 0 && stage_settled(m, 1, 5) == 0)
            step = 3;
        if (step == 3 && see(s.c, s.tr, s.pix, &peak_good) == 0)
            step = 4;
        if (step == 4 && stage_cmd(m, 0, STAGE_CMD_MOVE, 5) == 0 && stage_settled(m, 5, 5) == 0)
            step = 5;
        if (step == 5 && see(s.c, fast, s.pix, &peak_bad) == 0)
            step = 6;
    }
    session_close(&s);
    fx_stop(&stg, SIGTERM, 5);
    if (m)
        modbus_close(m), modbus_free(m);
    if (fast)
        truth_free(fast);
    free(fast);
    CHECK(step == 6, "failed at: %s %s", steps[step], s.err);
    printf("note: peak flux fraction %.4f at r0 0.25 m, %.4f at r0 0.05 m\n", peak_good,
           peak_bad);
    CHECK(peak_good > 1.5 * peak_bad, "seeing did not worsen: peak %.4f -> %.4f", peak_good,
          peak_bad);
}

TEST(frames_match_simulator) { fx_in_netns(t, body_frames, 120); }
TEST(lost_packets_never_good) { fx_in_netns(t, body_lossy, 60); }
TEST(kill_and_reconnect) { fx_in_netns(t, body_kill, 90); }
TEST(list_exposure_absent) { fx_in_netns(t, body_list_absent, 60); }
TEST(grab_stock_fake_camera) { fx_in_netns(t, body_grab_stock, 60); }
TEST(stage_changes_seeing) { fx_in_netns(t, body_stage, 60); }

TC_MAIN(TC_CASE(frames_match_simulator), TC_CASE(lost_packets_never_good),
        TC_CASE(kill_and_reconnect), TC_CASE(list_exposure_absent),
        TC_CASE(grab_stock_fake_camera), TC_CASE(stage_changes_seeing))
