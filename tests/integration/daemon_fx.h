/* daemon_fx.h - the fixture of tests/integration/test_daemon*.c: a bench
 * (fake stage, fake camera, specklabd) and a small json-glib client of
 * daemon/PROTOCOL.md.
 *
 * Camera, two tiers.  By default the camera is Aravis's in-process fake
 * inside specklabd ([camera] backend=fake, address Fake_1), its pixels
 * from bin/specklab-fake-source.so ([camera] source: the simulator of
 * bin/specklab-fake-camera, following the fake stage's wheels); the stage
 * listens on a port the kernel picks and the socket is in the test's own
 * directory, so such a test needs no namespace and runs beside others.
 * BENCH_TEST runs the body in a forked child (fx_in_child).  The network
 * tier, BENCH_NET_TEST, puts bin/specklab-fake-camera (GigE Vision on
 * loopback: GVCP's port 3956 is fixed) or the U3V mock in a private
 * network namespace (fx_in_netns: CLONE_NEWNET, with CLONE_NEWUSER when
 * not root; everything started shares its loopback and dies with it):
 * the tests that kill, stall or restart the camera process, drop its
 * packets or its controller.
 *
 * Binaries: $SL_BIN_DIR (else $SL_BIN, else BUILD/../bin next to this test,
 * else ./bin) must hold specklabd, specklab-fake-stage,
 * specklab-fake-source.so and (network tier) specklab-fake-camera.  Every
 * start is synchronised on the program's READY line, with a deadline;
 * nothing sleeps as synchronisation.
 *
 * Static functions: include once per test binary.
 */
#ifndef SL_DAEMON_FX_H
#define SL_DAEMON_FX_H

#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <json-glib/json-glib.h>
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
#include <sys/mount.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <fitsio.h>

#include "catalog.h"
#include "tcheck.h"

#include "preload_fx.h"
#include "proc_fx.h"
#include "u3v_fx.h"

/* ---- the bench ----------------------------------------------------------------- */

typedef struct bench {
    char dir[128];
    char data[200], sock[200], conf[200], dlog[200], clog[200];
    char db[300];                 /* the catalogue: DATA/specklab.db unless moved */
    char cam_size[16];
    char cam_masks[64];           /* the fake camera's --mask-slots; "": its default */
    char cam_dm[16];              /* its --dm-mag; "": its default (15: the
                                   * companion laser off, a point source) */
    fx_proc stage, cam, daemon;
    int port;
    int stage_rtu;                /* 1: the daemon reaches the stage by Modbus RTU
                                   * on the fake's pty (stage_tty); its TCP port
                                   * still serves the camera and fault switches */
    char stage_tty[96];
    void (*daemon_pre)(void *);   /* e.g. limits, before exec */
    void *daemon_pre_arg;
    int cam_gige;                 /* 1: the camera is bin/specklab-fake-camera (GigE
                                   * Vision on loopback: network tier); 0 with
                                   * cam_u3v 0: the daemon's in-process fake */
    char cam_extra[128];          /* more simulator flags (in-process fake) */
    char ready[512];              /* the daemon's READY line */
    int cam_u3v;                  /* 1: the camera is bin/specklab-fake-u3v (seed 5,
                                   * screen slot 1 always in its beam) and the daemon runs
                                   * under the umockdev preload on its testbed */
    fx_u3v u3v;
    char preload[1024];           /* $LD_PRELOAD for the daemon with cam_u3v */
    GPtrArray *keep;              /* JsonNode*, released by bench_down */
    GPtrArray *clients;           /* dc*, closed by bench_down */
    char mnt[2][300];             /* tmpfs mounts (bench_tmpfs), unmounted by bench_down */
    int nmnt, private_mounts;
} bench;

static inline int fx_rm(const char *path, const struct stat *sb, int flag, struct FTW *ftw)
{
    (void)sb, (void)flag, (void)ftw;
    return remove(path);
}

static inline int bench_init(bench *b)
{
    const char *tmp = getenv("TMPDIR");
    memset(b, 0, sizeof *b);
    b->stage.pid = b->cam.pid = b->daemon.pid = b->u3v.p.pid = -1;
    b->u3v.in = -1;
    snprintf(b->dir, sizeof b->dir, "%s/sl_daemon.XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(b->dir))
        return -1;
    snprintf(b->data, sizeof b->data, "%s/var", b->dir);
    snprintf(b->db, sizeof b->db, "%s/specklab.db", b->data);
    snprintf(b->sock, sizeof b->sock, "%s/var/specklabd.sock", b->dir);
    snprintf(b->conf, sizeof b->conf, "%s/specklabd.conf", b->dir);
    snprintf(b->dlog, sizeof b->dlog, "%s/specklabd.log", b->dir);
    snprintf(b->clog, sizeof b->clog, "%s/camera.log", b->dir);
    snprintf(b->cam_size, sizeof b->cam_size, "64");
    b->keep = g_ptr_array_new_with_free_func((GDestroyNotify)json_node_unref);
    b->clients = g_ptr_array_new();
    return 0;
}

/* extra: further fake-stage flags, NULL-terminated. */
static inline int bench_start_stage(bench *b, const char *const *extra)
{
    char bin[PATH_MAX], line[192];
    char *argv[24] = {bin, "--port", "0", "--step-ms", "20"};
    int n = 5;
    if (b->stage_rtu)
        argv[n++] = "--rtu";
    for (int i = 0; extra && extra[i] && n < 22; i++)
        argv[n++] = (char *)extra[i];
    argv[n] = NULL;
    fx_bin(bin, sizeof bin, "specklab-fake-stage");
    if (fx_spawn(&b->stage, argv, NULL, NULL, NULL) != 0 ||
        fx_wait_ready(&b->stage, line, sizeof line, 10) != 0 ||
        sscanf(line, "READY port=%d", &b->port) != 1)
        return -1;
    if (b->stage_rtu && sscanf(line, "READY port=%*d rtu=%95s", b->stage_tty) != 1)
        return -1;
    return 0;
}

static inline void bench_preload_daemon(void *arg)
{
    setenv("LD_PRELOAD", arg, 1);
}

/* The U3V camera; the daemon will see its testbed ($UMOCKDEV_DIR is set
 * for everything started from now on) through the preload. */
static inline int bench_start_u3v(bench *b)
{
    char *pre = fx_preload_value();
    snprintf(b->preload, sizeof b->preload, "%s", pre);
    g_free(pre);
    b->daemon_pre = bench_preload_daemon;
    b->daemon_pre_arg = b->preload;
    const char *extra[] = {"--size", b->cam_size, "--seed", "5", "--screen-slot", "1", NULL};
    return fx_u3v_start(&b->u3v, extra);
}

/* The in-process fake needs no process: the daemon opens it (its
 * configuration, bench_write_config). */
static inline int bench_start_camera(bench *b)
{
    if (b->cam_u3v)
        return bench_start_u3v(b);
    if (!b->cam_gige)
        return 0;
    char bin[PATH_MAX], line[256], stage[64];
    snprintf(stage, sizeof stage, "127.0.0.1:%d", b->port);
    char *argv[] = {bin, "--size", b->cam_size, "--stage", stage, "--stage-poll-ms", "20",
                    "--seed", "5", "-q", NULL, NULL, NULL, NULL, NULL};
    int n = 10;
    if (b->cam_masks[0]) {
        argv[n++] = "--mask-slots";
        argv[n++] = b->cam_masks;
    }
    if (b->cam_dm[0]) {
        argv[n++] = "--dm-mag";
        argv[n++] = b->cam_dm;
    }
    fx_bin(bin, sizeof bin, "specklab-fake-camera");
    if (fx_spawn(&b->cam, argv, b->clog, NULL, NULL) != 0 ||
        fx_wait_ready(&b->cam, line, sizeof line, 20) != 0)
        return -1;
    return 0;
}

/* [camera] for the in-process fake: the simulator with the GigE mock's
 * flags of bench_start_camera, polling the bench's stage. */
static inline void bench_fake_camera_conf(const bench *b, char *out, size_t n)
{
    char lib[PATH_MAX];
    fx_bin(lib, sizeof lib, "specklab-fake-source.so");
    snprintf(out, n, "backend=fake\naddress=Fake_1\nsource=%s\nsource_args=--size %s "
             "--stage 127.0.0.1:%d --stage-poll-ms 20 --seed 5%s%s%s%s %s\n", lib, b->cam_size,
             b->port, b->cam_masks[0] ? " --mask-slots " : "", b->cam_masks,
             b->cam_dm[0] ? " --dm-mag " : "", b->cam_dm, b->cam_extra);
}

/* The configuration: the bench's camera and stage port, data under the
 * temporary directory, 100 fps, plus extra text (whole
 * "[group]\nkey=value" lines, later keys win). */
static inline int bench_write_config(bench *b, const char *extra)
{
    char cam[PATH_MAX + 512] = "";
    if (!b->cam_gige && !b->cam_u3v)
        bench_fake_camera_conf(b, cam, sizeof cam);
    FILE *f = fopen(b->conf, "w");
    if (!f)
        return -1;
    char stage[160];
    if (b->stage_rtu)
        snprintf(stage, sizeof stage, "backend=rtu\ndevice=%s\nbaud=19200\n", b->stage_tty);
    else
        snprintf(stage, sizeof stage, "address=127.0.0.1:%d\n", b->port);
    fprintf(f, "[camera]\n%sframe_rate_hz=100\nlost_timeout_s=2\n"
               "[stage]\n%ssettle_ms=100\nmove_timeout_ms=5000\n"
               "[paths]\ndata_dir=%s\n[daemon]\nsocket=%s\n%s\n",
            cam, stage, b->data, b->sock, extra ? extra : "");
    return fclose(f) == 0 ? 0 : -1;
}

/* The READY line is kept in b->ready (the web page's URL, if any). */
static inline int bench_start_daemon(bench *b)
{
    char bin[PATH_MAX];
    char *argv[] = {bin, "--config", b->conf, "--foreground", NULL};
    fx_bin(bin, sizeof bin, "specklabd");
    if (fx_spawn(&b->daemon, argv, b->dlog, b->daemon_pre, b->daemon_pre_arg) != 0 ||
        fx_wait_ready(&b->daemon, b->ready, sizeof b->ready, 20) != 0)
        return -1;
    return 0;
}

/* Stage, camera, config (extra), daemon; gige: the network tier's camera;
 * setup (may be NULL) chooses what the bench is made of, after that. */
static inline int bench_up(bench *b, int gige, void (*setup)(bench *),
                           const char *const *stage_extra, const char *conf_extra)
{
    if (bench_init(b) != 0)
        return -1;
    b->cam_gige = gige;
    if (setup)
        setup(b);
    return bench_start_stage(b, stage_extra) || bench_start_camera(b) ||
                   bench_write_config(b, conf_extra) || bench_start_daemon(b)
               ? -1
               : 0;
}

/* Print the daemon's log (on a failure, to see why). */
static inline void bench_dump_log(const bench *b)
{
    FILE *f = fopen(b->dlog, "r");
    char line[1024];
    fprintf(stderr, "---- %s\n", b->dlog);
    while (f && fgets(line, sizeof line, f))
        fputs(line, stderr);
    if (f)
        fclose(f);
}

/* A tmpfs of size_kb KiB at path (created), so a test can fill a disk:
 * mounted in a private mount namespace of the test child (the namespace
 * and the mount die with it; bench_down unmounts it first so that the
 * bench directory can be removed).  0, or -1 with the reason in why (no
 * mount namespace here: the caller skips). */
static inline int bench_tmpfs(bench *b, const char *path, long size_kb, char *why, size_t n)
{
    char opt[32];
    if (b->nmnt >= (int)G_N_ELEMENTS(b->mnt)) {
        snprintf(why, n, "more than %d tmpfs mounts", (int)G_N_ELEMENTS(b->mnt));
        return -1;
    }
    if (g_mkdir_with_parents(path, 0750) != 0) {
        snprintf(why, n, "mkdir %s: %s", path, strerror(errno));
        return -1;
    }
    /* Private: nothing mounted here may show in the host's namespace. */
    if (!b->private_mounts &&
        (unshare(CLONE_NEWNS) != 0 || mount(NULL, "/", NULL, MS_REC | MS_PRIVATE, NULL) != 0)) {
        snprintf(why, n, "no private mount namespace: %s", strerror(errno));
        return -1;
    }
    b->private_mounts = 1;
    snprintf(opt, sizeof opt, "size=%ldk,mode=0750", size_kb);
    if (mount("tmpfs", path, "tmpfs", MS_NOSUID | MS_NODEV, opt) != 0) {
        snprintf(why, n, "mount tmpfs (%s) on %.200s: %s", opt, path, strerror(errno));
        return -1;
    }
    snprintf(b->mnt[b->nmnt++], sizeof b->mnt[0], "%s", path);
    return 0;
}

static inline void fx_bench_release(bench *b);

static inline void bench_down(bench *b, int failed)
{
    if (failed)
        bench_dump_log(b);
    fx_stop(&b->daemon, SIGTERM, 10);
    fx_stop(&b->cam, SIGTERM, 5);
    fx_u3v_stop(&b->u3v);
    fx_stop(&b->stage, SIGTERM, 5);
    while (b->nmnt > 0)
        umount2(b->mnt[--b->nmnt], MNT_DETACH);
    fx_bench_release(b);
    if (b->dir[0] && !getenv("SL_KEEP_TMP"))
        nftw(b->dir, fx_rm, 16, FTW_DEPTH | FTW_PHYS);
}

/* ---- files and catalogue, checked independently of the daemon -------------- */

/* Open a cube as cfitsio sees it: NAXIS3, every pixel read (a truncated
 * file fails), and the FRAMES table's rows (-1 when absent). */
static inline int fx_fits(const char *path, long *naxis3, long *table_rows, char *err, size_t n)
{
    fitsfile *f = NULL;
    int s = 0, naxis = 0;
    long ax[3] = {0, 0, 0};
    *naxis3 = *table_rows = -1;
    fits_open_diskfile(&f, path, READONLY, &s);
    fits_get_img_dim(f, &naxis, &s);
    fits_get_img_size(f, 3, ax, &s);
    if (!s && naxis == 3) {
        *naxis3 = ax[2];
        long npx = ax[0] * ax[1] * ax[2];
        float *buf = g_new(float, npx > 0 ? npx : 1);
        int any = 0;
        if (npx > 0)
            fits_read_img(f, TFLOAT, 1, npx, NULL, buf, &any, &s);
        g_free(buf);
    }
    if (!s) {
        int s2 = 0;
        if (fits_movnam_hdu(f, BINARY_TBL, "FRAMES", 0, &s2) == 0)
            fits_get_num_rows(f, table_rows, &s2);
    }
    if (f) {
        int s2 = 0;
        fits_close_file(f, &s2);
    }
    if (s || naxis != 3) {
        char text[FLEN_STATUS] = "";
        fits_get_errstatus(s, text);
        snprintf(err, n, "%s: %s (naxis %d)", path, s ? text : "not a cube", naxis);
        return -1;
    }
    return 0;
}

static inline int fx_sha256(const char *path, char hex[65])
{
    gchar *data = NULL;
    gsize len = 0;
    if (!g_file_get_contents(path, &data, &len, NULL))
        return -1;
    gchar *h = g_compute_checksum_for_data(G_CHECKSUM_SHA256, (const guchar *)data, len);
    snprintf(hex, 65, "%s", h);
    g_free(h);
    g_free(data);
    return 0;
}

/* The run as the catalogue file says, through a handle of the test's own,
 * after PRAGMA integrity_check.  0 or -1 with err. */
static inline int fx_catalog_run(const bench *b, const char *uuid, catalog_run *out, char *err,
                          size_t n)
{
    catalog *c = NULL;
    sl_err e = {0};
    int rc = catalog_open(&c, b->db, &e);
    if (rc != SL_OK)
        snprintf(err, n, "catalog_open: %.400s", e.msg);
    else if ((rc = catalog_integrity_check(c)) != SL_OK)
        snprintf(err, n, "integrity: %s", catalog_errmsg(c));
    else if ((rc = catalog_run_get(c, uuid, out)) != SL_OK)
        snprintf(err, n, "%s", catalog_errmsg(c));
    catalog_close(c);
    return rc == SL_OK ? 0 : -1;
}

#include "daemon_client.h"

static inline void fx_bench_release(bench *b)
{
    for (guint i = 0; b->clients && i < b->clients->len; i++) {
        dc_close(b->clients->pdata[i]);
        g_free(b->clients->pdata[i]);
    }
    if (b->clients)
        g_ptr_array_free(b->clients, TRUE);
    if (b->keep)
        g_ptr_array_free(b->keep, TRUE);
    b->clients = b->keep = NULL;
}

/* Keep n until the bench goes down (so a failing CHECK leaks nothing). */
static inline JsonNode *keep(bench *b, JsonNode *n)
{
    if (n)
        g_ptr_array_add(b->keep, n);
    return n;
}

/* A connected client closed by bench_down; NULL when connect fails. */
static inline dc *bench_client(bench *b)
{
    dc *c = g_new0(dc, 1);
    if (dc_connect(c, b->sock) != 0) {
        g_free(c);
        return NULL;
    }
    g_ptr_array_add(b->clients, c);
    return c;
}

/* Poll status until the daemon reports the camera connected (it opens it
 * at start, in the background); 0 when it did within timeout_s. */
static inline int bench_wait_camera(bench *b, dc *c, double timeout_s)
{
    double end = fx_now() + timeout_s;
    while (fx_now() < end) {
        JsonNode *r = keep(b, dc_call(c, "status", NULL, 5));
        JsonNode *m = r ? jget(r, "result.camera.connected") : NULL;
        if (m && JSON_NODE_HOLDS_VALUE(m) && json_node_get_boolean(m))
            return 0;
        fx_nap_ms(50);
    }
    return -1;
}

/* A daemon still running must stop cleanly on SIGTERM: exit 0 (under
 * ASan, LeakSanitizer makes a leak a non-zero exit). */
static inline void bench_check_stop(tc *t, bench *b)
{
    if (b->daemon.pid <= 0)
        return;
    int st = fx_stop(&b->daemon, SIGTERM, 20);
    if (st != 0 && !t->failed)
        tc_note(t, 0, __FILE__, __LINE__, "daemon exit", "specklabd exited %d on SIGTERM "
                "(a crash or a leak: see its log)", st);
}

/* A test with a bench up (stage flags stage_extra, a NULL-terminated
 * string array or NULL; config text conf_extra), the in-process fake
 * camera, in a forked child; torn down whatever the body's CHECKs do; the
 * daemon's log is printed when the test fails. */
#define BENCH_TEST(name, limit_s, stage_extra, conf_extra)                    \
    BENCH_TEST_TIER(name, limit_s, 0, NULL, stage_extra, conf_extra)

/* The same on a bench that setup(bench *) changed after bench_init. */
#define BENCH_TEST_WITH(name, limit_s, setup, stage_extra, conf_extra)       \
    BENCH_TEST_TIER(name, limit_s, 0, setup, stage_extra, conf_extra)

/* The network tier: the GigE mock (or, by setup, the U3V mock) in a
 * private network namespace. */
#define BENCH_NET_TEST(name, limit_s, stage_extra, conf_extra)                \
    BENCH_TEST_TIER(name, limit_s, 1, NULL, stage_extra, conf_extra)
#define BENCH_NET_TEST_WITH(name, limit_s, setup, stage_extra, conf_extra)   \
    BENCH_TEST_TIER(name, limit_s, 1, setup, stage_extra, conf_extra)

#define BENCH_TEST_TIER(name, limit_s, gige, setup, stage_extra, conf_extra) \
    static void name##_body(tc *t, bench *b);                                 \
    static void name##_run(tc *t)                                             \
    {                                                                         \
        bench b_;                                                             \
        if (bench_up(&b_, gige, setup, stage_extra, conf_extra) != 0) {       \
            tc_note(t, 0, __FILE__, __LINE__, "bench_up", "bench did not start " \
                    "(stage, camera or daemon; SL_BIN_DIR?)");                \
            bench_down(&b_, 1);                                               \
            return;                                                           \
        }                                                                     \
        name##_body(t, &b_);                                                  \
        bench_check_stop(t, &b_);                                             \
        bench_down(&b_, t->failed);                                           \
    }                                                                         \
    TEST(name) { fx_run_child(t, name##_run, limit_s, gige); }                \
    static void name##_body(tc *t, bench *b)

#endif
