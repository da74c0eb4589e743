/* matrix_fx.h - helpers of test_daemon_matrix.c over daemon_fx.h: a bench
 * whose camera takes extra flags, polling `status` for a state, checking a
 * run's catalogue row against its cube (and the cube's FRAMES table and
 * pixels against the fake camera's model), holding the catalogue's write
 * lock, and poking the fake stage's fault registers over Modbus.
 *
 * Static functions: include once, after daemon_fx.h.
 */
#ifndef SL_MATRIX_FX_H
#define SL_MATRIX_FX_H

#include <dirent.h>
#include <modbus.h>
#include <sqlite3.h>

#include "stage_map.h"

/* After GLib (recon's `mask` typedef and GLib's parameter names). */
#include "../../mocks/camsrc/fakecam.h"

static inline const char *mx_str(const char *s)
{
    return s ? s : "";
}

/* ---- a bench with camera flags ------------------------------------------------- */

/* The camera with extra flags: the in-process fake's simulator takes
 * them in its source_args (bench_write_config), the GigE mock (network
 * tier) on its command line. */
static inline int mx_start_camera(bench *b, const char *const *extra)
{
    if (!b->cam_gige) {
        size_t len = 0;
        for (int i = 0; extra && extra[i]; i++)
            len += (size_t)snprintf(b->cam_extra + len, len < sizeof b->cam_extra ?
                                    sizeof b->cam_extra - len : 0, " %s", extra[i]);
        return len < sizeof b->cam_extra ? 0 : -1;
    }
    char bin[PATH_MAX], line[256], stage[64];
    char *argv[24] = {bin, "--size", b->cam_size, "--stage", stage, "--stage-poll-ms", "20",
                      "--seed", "5", "-q"};
    int n = 10;
    for (int i = 0; extra && extra[i] && n < 22; i++)
        argv[n++] = (char *)extra[i];
    argv[n] = NULL;
    snprintf(stage, sizeof stage, "127.0.0.1:%d", b->port);
    fx_bin(bin, sizeof bin, "specklab-fake-camera");
    if (fx_spawn(&b->cam, argv, b->clog, NULL, NULL) != 0 ||
        fx_wait_ready(&b->cam, line, sizeof line, 20) != 0)
        return -1;
    return 0;
}

/* BENCH_TEST with flags for the fake camera too (in-process fake). */
#define MATRIX_TEST(name, limit_s, stage_extra, cam_extra, conf_extra)          \
    MATRIX_TEST_TIER(name, limit_s, 0, stage_extra, cam_extra, conf_extra)
/* The network tier: flags of the GigE mock (--lost-ratio). */
#define MATRIX_NET_TEST(name, limit_s, stage_extra, cam_extra, conf_extra)      \
    MATRIX_TEST_TIER(name, limit_s, 1, stage_extra, cam_extra, conf_extra)

#define MATRIX_TEST_TIER(name, limit_s, gige, stage_extra, cam_extra, conf_extra) \
    static void name##_body(tc *t, bench *b);                                 \
    static void name##_run(tc *t)                                             \
    {                                                                         \
        bench b_;                                                             \
        if (bench_init(&b_) || ((b_.cam_gige = gige), 0) ||                   \
            bench_start_stage(&b_, stage_extra) ||                            \
            mx_start_camera(&b_, cam_extra) || bench_write_config(&b_, conf_extra) || \
            bench_start_daemon(&b_)) {                                        \
            tc_note(t, 0, __FILE__, __LINE__, "bench", "bench did not start"); \
            bench_down(&b_, 1);                                               \
            return;                                                           \
        }                                                                     \
        name##_body(t, &b_);                                                  \
        bench_check_stop(t, &b_);                                             \
        bench_down(&b_, t->failed);                                           \
    }                                                                         \
    TEST(name) { fx_run_child(t, name##_run, limit_s, gige); }                \
    static void name##_body(tc *t, bench *b)

static inline int mx_kill_restart(bench *b)
{
    fx_stop(&b->daemon, SIGKILL, 5);
    return bench_start_daemon(b);
}

/* ---- requests, events, status ------------------------------------------------- */

static inline int mx_start(bench *b, dc *c, const char *args, char out[40])
{
    JsonNode *r = keep(b, dc_call(c, "start-run", args, 10));
    if (!jok(r))
        return -1;
    snprintf(out, 40, "%s", js(r, "result.run"));
    return 0;
}

typedef int (*mx_status_fn)(JsonNode *reply, const void *arg);

/* `status` every 10 ms until fn(reply, arg): that reply (kept), or NULL
 * when timeout_s passed first. */
static inline JsonNode *mx_poll_status(bench *b, dc *c, mx_status_fn fn, const void *arg,
                                double timeout_s)
{
    double end = fx_now() + timeout_s;
    while (fx_now() < end) {
        JsonNode *r = dc_call(c, "status", NULL, 5);
        if (r && jok(r) && fn(r, arg))
            return keep(b, r);
        if (r)
            json_node_unref(r);
        fx_nap_ms(10);
    }
    return NULL;
}

/* The run in hand is `run`, in `state`, with at least `frames` on disk. */
typedef struct mx_want {
    const char *run, *state;
    int frames;
} mx_want;

static inline int mx_is_current(JsonNode *r, const void *arg)
{
    const mx_want *w = arg;
    return !g_strcmp0(js(r, "result.current_run"), w->run) &&
           !g_strcmp0(js(r, "result.current_state"), w->state) &&
           ji(r, "result.frames_acquired") >= w->frames;
}

/* Events until a final state of run (kept and returned; NULL on timeout);
 * *last_failed (may be NULL) the frames_failed of its last progress. */
static inline JsonNode *mx_wait_end(bench *b, dc *c, const char *run, double timeout_s,
                             gint64 *last_failed)
{
    double end = fx_now() + timeout_s;
    for (;;) {
        JsonNode *e = dc_next_event(c, end - fx_now());
        if (!e)
            return NULL;
        const char *kind = js(e, "event"), *s = js(e, "state");
        if (g_strcmp0(js(e, "run"), run)) {
            json_node_unref(e);
            continue;
        }
        if (!g_strcmp0(kind, "progress") && last_failed)
            *last_failed = ji(e, "frames_failed");
        if (!g_strcmp0(kind, "state") && s &&
            (!strcmp(s, "done") || !strcmp(s, "failed") || !strcmp(s, "aborted") ||
             !strcmp(s, "interrupted")))
            return keep(b, e);
        json_node_unref(e);
    }
}

/* Collect run's state events (comma-separated into seen) until time end. */
static inline void mx_events_until(dc *c, const char *run, double end, GString *seen)
{
    double left;
    while ((left = end - fx_now()) > 0) {
        JsonNode *e = dc_next_event(c, left);
        if (!e)
            continue;
        if (!g_strcmp0(js(e, "run"), run) && !g_strcmp0(js(e, "event"), "state"))
            g_string_append_printf(seen, "%s%s", seen->len ? "," : "", mx_str(js(e, "state")));
        json_node_unref(e);
    }
}

/* A new short run on the bench ends done. */
static inline void mx_next_run_done(tc *t, bench *b, dc *c)
{
    char uuid[40];
    keep(b, dc_call(c, "subscribe", NULL, 5));
    CHECK(mx_start(b, c, "{\"screen\": 1, \"mask\": 0, \"frames\": 10, \"reconstruct\": \"none\"}",
                   uuid) == 0, "start-run of the next run");
    JsonNode *e = mx_wait_end(b, c, uuid, 60, NULL);
    CHECK(e && !g_strcmp0(js(e, "state"), "done"), "the next run: %s", jtext(e));
}

/* ---- the catalogue and the files, checked by the test itself ------------------- */

/* What the catalogue says of a run, and what its cube holds. */
typedef struct mx_seen {
    catalog_state state;
    int frames, failed;
    int64_t packets_missing;
    char file[400];
    long n3, rows;     /* cube frames, FRAMES rows; -1: none */
} mx_seen;

/* The run's row (through the test's own handle, after integrity_check)
 * must have state want and a reason containing `reason` (NULL: no
 * reason); its file, when it has one, must be on disk with the catalogued
 * SHA-256 and open as a cube of exactly frames_acquired frames; without a
 * file it has no frames.  0, or -1 with the failure noted. */
static inline int mx_check_run(tc *t, bench *b, const char *uuid, catalog_state want,
                               const char *reason, mx_seen *v)
{
    catalog_run cr;
    char msg[512] = "", hex[65] = "";
    memset(v, 0, sizeof *v);
    v->n3 = v->rows = -1;
    if (fx_catalog_run(b, uuid, &cr, msg, sizeof msg) != 0) {
        tc_note(t, 0, __FILE__, __LINE__, "catalogue", "run %s: %s", uuid, msg);
        return -1;
    }
    v->state = cr.state;
    v->frames = cr.frames_acquired;
    v->failed = cr.frames_failed;
    v->packets_missing = cr.packets_missing;
    snprintf(v->file, sizeof v->file, "%s", mx_str(cr.file_path));
    int ok = cr.state == want &&
             (reason ? cr.exit_reason && strstr(cr.exit_reason, reason) : !cr.exit_reason);
    if (ok && cr.file_path)
        ok = fx_sha256(cr.file_path, hex) == 0 && cr.file_sha256 &&
             !strcmp(hex, cr.file_sha256) &&
             fx_fits(cr.file_path, &v->n3, &v->rows, msg, sizeof msg) == 0 &&
             v->n3 == cr.frames_acquired;
    else if (ok)
        ok = cr.frames_acquired == 0;
    if (!ok)
        tc_note(t, 0, __FILE__, __LINE__, "catalogue vs disk",
                "run %s: state %s (want %s), reason '%s' (want '%s'), file '%s', sha256 %s on "
                "disk vs %s catalogued, cube %ld frames vs %d catalogued %s", uuid,
                catalog_state_name(cr.state), catalog_state_name(want), mx_str(cr.exit_reason),
                reason ? reason : "(none)", v->file, hex, mx_str(cr.file_sha256), v->n3,
                cr.frames_acquired, msg);
    catalog_run_clear(&cr);
    return ok ? 0 : -1;
}

static inline catalog_state mx_state(bench *b, const char *uuid)
{
    catalog_run cr;
    char msg[512];
    if (fx_catalog_run(b, uuid, &cr, msg, sizeof msg) != 0)
        return CATALOG_STATE_ANY;
    catalog_state s = cr.state;
    catalog_run_clear(&cr);
    return s;
}

static inline int mx_count(const catalog_recon *r, void *user)
{
    (void)r;
    ++*(int *)user;
    return 0;
}

/* Reconstruction rows of a run, -1 when the catalogue cannot be read. */
static inline int mx_recon_rows(bench *b, const char *uuid)
{
    catalog *c = NULL;
    sl_err e = {0};
    int n = 0;
    if (catalog_open(&c, b->db, &e) != SL_OK || catalog_recon_list(c, uuid, mx_count, &n) != SL_OK)
        n = -1;
    catalog_close(c);
    return n;
}

static inline int mx_runs_files(bench *b)
{
    char path[300];
    int n = 0;
    snprintf(path, sizeof path, "%s/runs", b->data);
    DIR *d = opendir(path);
    for (struct dirent *de; d && (de = readdir(d));)
        n += de->d_name[0] != '.';
    if (d)
        closedir(d);
    return n;
}

static inline int mx_log_has(bench *b, const char *needle)
{
    gchar *text = NULL;
    int has = g_file_get_contents(b->dlog, &text, NULL, NULL) && strstr(text, needle);
    g_free(text);
    return has;
}

/* ---- the FRAMES table and the pixels ----------------------------------------- */

/* The fake camera's rendering (bench_start_camera's flags: seed 5, the
 * bench's sensor size, whole-sensor ROI) of the beam the cube's header
 * names. */
typedef struct mx_truth {
    fakecam_model m;
    mask *msk;
    scene *sc;
    sim *s;
    float *sensor;
    unsigned char *packed;
} mx_truth;

static inline int mx_truth_new(mx_truth *tr, fitsfile *f, int w, int h, char *err, size_t n)
{
    int s = 0, screen = -1, mslot = -1;
    double exptime_s = NAN, gain_db = 0;
    sl_err e = {0};
    memset(tr, 0, sizeof *tr);
    fits_read_key(f, TINT, "SCRSLOT", &screen, NULL, &s);
    fits_read_key(f, TINT, "MSKSLOT", &mslot, NULL, &s);
    fits_read_key(f, TDOUBLE, "EXPTIME", &exptime_s, NULL, &s);
    int s2 = 0;
    fits_read_key(f, TDOUBLE, "GAINDB", &gain_db, NULL, &s2);   /* absent: 0 */
    if (s || screen < 0 || (mslot != 0 && mslot != 1)) {
        snprintf(err, n, "cube header: SCRSLOT %d MSKSLOT %d EXPTIME %g (cfitsio %d)", screen,
                 mslot, exptime_s, s);
        return -1;
    }
    fakecam_model_defaults(&tr->m);
    tr->m.sensor_w = w;
    tr->m.sensor_h = h;
    tr->m.seed = 5;
    sim_opts o;
    fakecam_sim_opts(&tr->m, screen, (uint32_t)lround(exptime_s * 1e6), (uint32_t)lround(gain_db),
                     &o);
    tr->sensor = g_new(float, (size_t)w * h);
    tr->packed = g_new(unsigned char, 2 * (size_t)w * h);
    if (fakecam_mask(mslot ? "nrm17" : "full", &tr->msk, &e) != SL_OK ||
        fakecam_scene(&tr->m, &tr->sc, &e) != SL_OK || sim_new(&tr->s, &o, tr->msk, tr->sc, &e)) {
        snprintf(err, n, "simulator: %.200s", e.msg);
        return -1;
    }
    return 0;
}

static inline void mx_truth_free(mx_truth *tr)
{
    sim_free(tr->s);
    mask_free(tr->msk);
    scene_free(tr->sc);
    g_free(tr->sensor);
    g_free(tr->packed);
}

/* Pixels of pix (w x h) that differ from the rendering of frame_id. */
static inline long mx_truth_diff(mx_truth *tr, uint64_t frame_id, const unsigned short *pix)
{
    int w = tr->m.sensor_w, h = tr->m.sensor_h;
    if (sim_frame(tr->s, fakecam_frame_index(frame_id), tr->sensor) != SL_OK)
        return -1;
    fakecam_readout(tr->sensor, w, h, 0, 0, w, h, 1, 1, 2, tr->packed);
    long bad = 0;
    for (size_t i = 0; i < (size_t)w * h; i++)
        bad += pix[i] != (tr->packed[2 * i] | tr->packed[2 * i + 1] << 8);
    return bad;
}

/* The FRAMES table of v->file lists every buffer: SUCCESS rows are the
 * cube's frames 0, 1, 2... in order, every other row has CUBE_IDX -1 and
 * their count is the catalogue's frames_failed; and every stored frame is
 * the fake camera's frame of that id, bit for bit.  0, or -1 noted. */
static inline int mx_check_frames(tc *t, bench *b, const mx_seen *v)
{
    (void)b;
    fitsfile *f = NULL;
    int s = 0, col_id = 0, col_st = 0, col_idx = 0, naxis = 0;
    long ax[3] = {0, 0, 0}, nrows = 0, good = 0, bad = 0, order_bad = 0, wrong = 0;
    char err[300] = "";
    mx_truth tr = {0};
    fits_open_diskfile(&f, v->file, READONLY, &s);
    fits_get_img_dim(f, &naxis, &s);
    fits_get_img_size(f, 3, ax, &s);
    int have_truth = !s && naxis == 3 && mx_truth_new(&tr, f, (int)ax[0], (int)ax[1], err,
                                                      sizeof err) == 0;
    size_t npx = (size_t)ax[0] * (size_t)ax[1];
    unsigned short *pix = g_new(unsigned short, npx ? npx : 1);
    fits_movnam_hdu(f, BINARY_TBL, "FRAMES", 0, &s);
    fits_get_num_rows(f, &nrows, &s);
    fits_get_colnum(f, CASEINSEN, "FRAME_ID", &col_id, &s);
    fits_get_colnum(f, CASEINSEN, "STATUS", &col_st, &s);
    fits_get_colnum(f, CASEINSEN, "CUBE_IDX", &col_idx, &s);
    for (long i = 1; i <= nrows && !s && have_truth; i++) {
        LONGLONG id = 0;
        int idx = 0, any = 0;
        char text[20] = "", *cell = text;
        fits_read_col(f, TLONGLONG, col_id, i, 1, 1, NULL, &id, &any, &s);
        fits_read_col(f, TSTRING, col_st, i, 1, 1, NULL, &cell, &any, &s);
        fits_read_col(f, TINT, col_idx, i, 1, 1, NULL, &idx, &any, &s);
        if (s)
            break;
        if (idx < 0) {
            bad++;
            order_bad += !strcmp(text, "SUCCESS");
            continue;
        }
        order_bad += idx != good || strcmp(text, "SUCCESS") != 0;
        good++;
        /* The pixels of cube frame idx, from the primary HDU. */
        int hdu = 0;
        fits_get_hdu_num(f, &hdu);
        fits_movabs_hdu(f, 1, NULL, &s);
        fits_read_img(f, TUSHORT, (LONGLONG)idx * (LONGLONG)npx + 1, (LONGLONG)npx, NULL, pix,
                      &any, &s);
        fits_movabs_hdu(f, hdu, NULL, &s);
        if (!s && mx_truth_diff(&tr, (uint64_t)id, pix) != 0)
            wrong++;
    }
    if (s) {
        char text[FLEN_STATUS] = "";
        fits_get_errstatus(s, text);
        snprintf(err, sizeof err, "%.200s: cfitsio: %.80s", v->file, text);
    }
    if (f) {
        int s2 = 0;
        fits_close_file(f, &s2);
    }
    g_free(pix);
    if (have_truth)
        mx_truth_free(&tr);
    int ok = !s && have_truth && good == v->n3 && good == v->frames && bad == v->failed &&
             order_bad == 0 && wrong == 0;
    if (!ok)
        tc_note(t, 0, __FILE__, __LINE__, "FRAMES", "%s: %ld good rows (cube %ld, catalogue "
                "%d), %ld damaged (catalogue %d), %ld out of order or mislabelled, %ld stored "
                "frames differ from the camera's model %s", v->file, good, v->n3, v->frames, bad,
                v->failed, order_bad, wrong, err);
    return ok ? 0 : -1;
}

/* The FRAMES table of v->file never names a frame the cube does not
 * hold: it exists, every CUBE_IDX is -1 or inside the cube (< NAXIS3),
 * the stored ones are 0, 1, 2... in order and there are NAXIS3 of them
 * (= the catalogue's frames_acquired), and no damaged buffer claims a
 * place.  *lost (may be NULL) gets the SUCCESS rows left out of the cube
 * (delivered by the camera, not on disk).  0, or -1 noted. */
static inline int mx_check_cube_idx(tc *t, const mx_seen *v, long *lost)
{
    fitsfile *f = NULL;
    int s = 0, col_st = 0, col_idx = 0;
    long nrows = 0, stored = 0, outside = 0, order_bad = 0, damaged_in = 0, gone = 0;
    fits_open_diskfile(&f, v->file, READONLY, &s);
    fits_movnam_hdu(f, BINARY_TBL, "FRAMES", 0, &s);
    fits_get_num_rows(f, &nrows, &s);
    fits_get_colnum(f, CASEINSEN, "STATUS", &col_st, &s);
    fits_get_colnum(f, CASEINSEN, "CUBE_IDX", &col_idx, &s);
    for (long i = 1; i <= nrows && !s; i++) {
        int idx = 0, any = 0;
        char text[20] = "", *cell = text;
        fits_read_col(f, TSTRING, col_st, i, 1, 1, NULL, &cell, &any, &s);
        fits_read_col(f, TINT, col_idx, i, 1, 1, NULL, &idx, &any, &s);
        int good = !strcmp(text, "SUCCESS");
        if (idx < 0) {
            gone += good;
            outside += idx != -1;
            continue;
        }
        outside += idx >= v->n3;
        order_bad += idx != stored;
        damaged_in += !good;
        stored++;
    }
    char err[FLEN_STATUS] = "";
    if (s)
        fits_get_errstatus(s, err);
    if (f) {
        int s2 = 0;
        fits_close_file(f, &s2);
    }
    if (lost)
        *lost = gone;
    int ok = !s && outside == 0 && order_bad == 0 && damaged_in == 0 && stored == v->n3 &&
             stored == v->frames;
    if (!ok)
        tc_note(t, 0, __FILE__, __LINE__, "CUBE_IDX", "%s: FRAMES %s%s: %ld rows, %ld with a "
                "CUBE_IDX (cube NAXIS3 %ld, catalogue %d), %ld outside the cube, %ld out of "
                "order, %ld damaged with a place", v->file, s ? "unreadable: " : "ok", err,
                nrows, stored, v->n3, v->frames, outside, order_bad, damaged_in);
    return ok ? 0 : -1;
}

/* ---- the catalogue's write lock, held by this process ------------------------- */

typedef struct mx_lock {
    sqlite3 *db;
} mx_lock;

/* BEGIN EXCLUSIVE on the daemon's catalogue (in WAL mode: the write lock;
 * readers go on).  Waits up to 10 s for a daemon write in progress. */
static inline int mx_lock_take(mx_lock *l, const bench *b, char *err, size_t n)
{
    const char *path = b->db;
    l->db = NULL;
    int rc = sqlite3_open_v2(path, &l->db, SQLITE_OPEN_READWRITE, NULL);
    if (rc == SQLITE_OK) {
        sqlite3_busy_timeout(l->db, 10000);
        rc = sqlite3_exec(l->db, "BEGIN EXCLUSIVE", NULL, NULL, NULL);
    }
    if (rc != SQLITE_OK) {
        snprintf(err, n, "%.200s: %.80s", path, l->db ? sqlite3_errmsg(l->db) : sqlite3_errstr(rc));
        sqlite3_close(l->db);
        l->db = NULL;
        return -1;
    }
    return 0;
}

static inline void mx_lock_drop(mx_lock *l)
{
    if (!l->db)
        return;
    sqlite3_exec(l->db, "ROLLBACK", NULL, NULL, NULL);
    sqlite3_close(l->db);
    l->db = NULL;
}

/* ---- the fake stage over Modbus: its wheels, its fault registers (100..108,
 * drivers/stage_map.h; requests only to those ignore the fault switches) -- */

static inline modbus_t *mx_stage_open(int port)
{
    modbus_t *m = modbus_new_tcp("127.0.0.1", port);
    if (m && (modbus_set_slave(m, 1) != 0 || modbus_set_response_timeout(m, 2, 0) != 0 ||
              modbus_connect(m) != 0)) {
        modbus_free(m);
        m = NULL;
    }
    return m;
}

static inline int mx_stage_poke(int port, int reg, int value)
{
    modbus_t *m = mx_stage_open(port);
    int rc = m && modbus_write_register(m, reg, (uint16_t)value) == 1 ? 0 : -1;
    if (m) {
        modbus_close(m);
        modbus_free(m);
    }
    return rc;
}

/* Poll the stage itself until the wheel's move to slot has been
 * commanded: TARGET is slot and STATUS busy (in motion) or, without busy,
 * busy or already there (POSITION slot, in position).  TARGET alone does
 * not say it: the driver writes it one request before the move command.
 * The daemon's `moving` state starts before its commands do.  0, or -1
 * after timeout_s. */
static inline int mx_wheel_wait(int port, int wheel, int slot, int busy, double timeout_s)
{
    modbus_t *m = mx_stage_open(port);
    double end = fx_now() + timeout_s;
    int rc = -1;
    while (m && rc != 0 && fx_now() < end) {
        uint16_t r[3];   /* TARGET, POSITION, STATUS */
        if (modbus_read_registers(m, STAGE_REG_WHEEL_BASE(wheel) + STAGE_WREG_TARGET, 3, r) == 3 &&
            r[0] == slot && ((r[2] & STAGE_ST_BUSY) ||
                             (!busy && r[1] == slot && (r[2] & STAGE_ST_INPOS))))
            rc = 0;
        else
            fx_nap_ms(10);
    }
    if (m) {
        modbus_close(m);
        modbus_free(m);
    }
    return rc;
}

/* 0 once the wheel moves towards slot (TARGET slot, STATUS busy). */
static inline int mx_wheel_moving(int port, int wheel, int slot, double timeout_s)
{
    return mx_wheel_wait(port, wheel, slot, 1, timeout_s);
}

/* The register's value, or -1. */
static inline int mx_stage_read(int port, int reg)
{
    modbus_t *m = mx_stage_open(port);
    uint16_t v = 0;
    int rc = m && modbus_read_registers(m, reg, 1, &v) == 1 ? v : -1;
    if (m) {
        modbus_close(m);
        modbus_free(m);
    }
    return rc;
}

#endif
