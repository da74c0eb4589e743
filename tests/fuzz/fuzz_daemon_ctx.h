/* fuzz_daemon_ctx.h - the minimal specklabd that fuzz_dispatch drives.
 *
 * Real: the server (daemon/server.c, a Unix socket in a scratch
 * directory, served from the GLib main context), the dispatcher
 * (dispatch.c, query.c, proto.c), the configuration (config.c, read from
 * a file like the daemon's) and the catalogue (schema/, the SQLite file
 * DATA/specklab.db, migrated).  Absent: the devices and the two threads
 * that own them.  The runner and the worker are stand-ins defined here,
 * resolved at link time
 * (the target does not link runner.c, acquire.c or worker.c); they record
 * what the dispatcher hands them and answer deferred requests from an
 * idle source, as the real threads answer through the main context.  The
 * stage is configured as an RTU device that does not exist, so `devices`
 * runs its real thread and finds no stage at once (call timeout 50 ms =
 * the backoff: one failed open, no retry).
 *
 * The catalogue is seeded with a run in every interesting state (fixed
 * uuids below, used by the corpus): one queued in the stand-in runner's
 * queue, the run being acquired (its abort is deferred), a stored run
 * with a cube on disk (reconstruct reaches the worker), a done run with a
 * reconstruction and an r0 measurement and no cube, a failed run, a queued
 * run the runner does not hold, and two runs sharing the prefix "abcd".
 * A request that changes the catalogue or the queue (start-run, abort of
 * the queued run) marks the context dirty and it is restored before the
 * next input, so every input meets the same state: the harness's own
 * SQLite connection deletes the runs it did not seed and RUN_QUEUED is
 * inserted again if it was aborted (a fresh catalogue would cost ~20 ms
 * of migrations and seeding under ASan; this, well under one).  The
 * scratch directory is on /dev/shm when there is one: the catalogue's
 * fsyncs then cost nothing.
 *
 * Header-only, included once by fuzz_dispatch.c (FUZZ_NAME defined).
 */
#ifndef SL_FUZZ_DAEMON_CTX_H
#define SL_FUZZ_DAEMON_CTX_H

#include <errno.h>
#include <ftw.h>
#include <signal.h>
#include <glib.h>
#include <glib/gstdio.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <sqlite3.h>

#include "dispatch.h"
#include "proto.h"

#define RUN_QUEUED  "11111111-1111-4111-8111-111111111111"
#define RUN_CURRENT "22222222-2222-4222-8222-222222222222"
#define RUN_STORED  "33333333-3333-4333-8333-333333333333"
#define RUN_DONE    "44444444-4444-4444-8444-444444444444"
#define RUN_FAILED  "55555555-5555-4555-8555-555555555555"
#define RUN_ORPHAN  "66666666-6666-4666-8666-666666666666"
#define RUN_AMB1    "abcd0000-0000-4000-8000-000000000001"
#define RUN_AMB2    "abcd1111-0000-4000-8000-000000000002"

/* One deferred reply, sent from an idle source. */
typedef struct fz_later {
    server *srv;
    server_token tok;
    char *line;
} fz_later;

typedef struct fz_daemon {
    char root[96];            /* scratch directory (mkdtemp) */
    config cfg;
    daemon_ctx d;
    GPtrArray *queue;         /* the stand-in runner's queue: uuids */
    int dirty;                /* restore before the next input */
    sqlite3 *db;              /* the harness's own connection */
    int ntree;                /* entries under root after setup */
    /* What the dispatcher handed on during the current input. */
    GArray *enqueued;         /* runner_spec */
    GPtrArray *submitted;     /* "uuid method" */
} fz_daemon;

static fz_daemon FZ;

static void fz_die(const char *what, const char *msg)
{
    fprintf(stderr, "%s: setup: %s: %s\n", FUZZ_NAME, what, msg);
    abort();
}

/* ---- the stand-in runner and worker ---------------------------------------- */

static gboolean fz_send_later(gpointer p)
{
    fz_later *l = p;
    server_complete(l->srv, l->tok, l->line);
    g_free(l);
    return G_SOURCE_REMOVE;
}

static void fz_reply_later(server_token tok, char *line)
{
    fz_later *l = g_new(fz_later, 1);
    l->srv = FZ.d.srv, l->tok = tok, l->line = line;
    g_idle_add(fz_send_later, l);
}

void runner_enqueue(runner *r, const runner_spec *spec, int *ahead,
                    char behind[CATALOG_UUID_LEN + 1])
{
    (void)r;
    *ahead = 1 + (int)FZ.queue->len;   /* the current run, then the queue */
    snprintf(behind, CATALOG_UUID_LEN + 1, "%s",
             FZ.queue->len ? (char *)g_ptr_array_index(FZ.queue, FZ.queue->len - 1)
                           : RUN_CURRENT);
    g_ptr_array_add(FZ.queue, g_strdup(spec->uuid));
    g_array_append_val(FZ.enqueued, *spec);
    FZ.dirty = 1;
}

int runner_abort(runner *r, const char *uuid, const proto_req *req)
{
    (void)r;
    if (!strcmp(uuid, RUN_CURRENT)) {
        /* As runner.c: the reply once the run has stopped (here: later). */
        JsonBuilder *b = json_builder_new();
        json_builder_begin_object(b);
        proto_add_str(b, "run", uuid);
        proto_add_str(b, "state", "aborted");
        json_builder_end_object(b);
        JsonNode *n = json_builder_get_root(b);
        g_object_unref(b);
        fz_reply_later(req->tok, proto_reply_ok(req, n));
        return RUNNER_ABORTING;
    }
    for (guint i = 0; i < FZ.queue->len; i++)
        if (!strcmp(g_ptr_array_index(FZ.queue, i), uuid)) {
            g_ptr_array_remove_index(FZ.queue, i);
            FZ.dirty = 1;
            return RUNNER_DEQUEUED;
        }
    return RUNNER_NOT_HERE;
}

void runner_status_get(runner *r, runner_status *out)
{
    (void)r;
    memset(out, 0, sizeof *out);
    snprintf(out->current, sizeof out->current, "%s", RUN_CURRENT);
    out->state = CATALOG_ACQUIRING;
    out->frames_acquired = 3;
    out->frames_requested = 10;
    out->queue = g_new0(char *, FZ.queue->len + 1);
    for (guint i = 0; i < FZ.queue->len; i++)
        out->queue[i] = g_strdup(g_ptr_array_index(FZ.queue, i));
    snprintf(out->camera_error, sizeof out->camera_error,
             "camera %s: not connected (fuzz harness: no devices)", FZ.cfg.camera_address);
    snprintf(out->stage_error, sizeof out->stage_error,
             "stage %s: not connected (fuzz harness: no devices)", FZ.cfg.stage_device);
}

/* The real worker answers {"run", "reconstruction"} when done; the
 * stand-in answers at once (later) with what it was asked. */
int worker_submit(worker *w, const char *uuid, const char *method, int projections,
                  const worker_extra *extra, const proto_req *req)
{
    (void)w, (void)extra;
    g_ptr_array_add(FZ.submitted, g_strdup_printf("%s %s", uuid, method));
    if (req) {
        JsonBuilder *b = json_builder_new();
        json_builder_begin_object(b);
        proto_add_str(b, "run", uuid);
        proto_add_str(b, "method", method);
        proto_add_int(b, "projections", projections);
        json_builder_end_object(b);
        JsonNode *n = json_builder_get_root(b);
        g_object_unref(b);
        fz_reply_later(req->tok, proto_reply_ok(req, n));
    }
    return 0;
}

void worker_status(worker *w, char current[CATALOG_UUID_LEN + 1], int *queued)
{
    (void)w;
    current[0] = '\0';
    *queued = 0;
}

/* ---- the catalogue ------------------------------------------------------------ */

static void fz_cat(int rc, const char *what)
{
    if (rc != SL_OK)
        fz_die(what, catalog_errmsg(FZ.d.cat));
}

static void fz_run(const char *uuid, int64_t created_ms, const char *screen,
                   const char *mask, const catalog_state *path, int npath,
                   const char *reason)
{
    catalog *c = FZ.d.cat;
    int64_t sid = 0, mid = 0;
    fz_cat(catalog_screen_find(c, screen, &sid), screen);
    fz_cat(catalog_mask_find(c, mask, &mid), mask);
    catalog_run_spec spec = {
        .uuid = uuid, .created_ms = created_ms, .operator_name = "fuzz",
        .object = "HR 1234", .screen_id = sid, .mask_id = mid,
        .camera_settings_json = "{\"exposure_us\":10000,\"pixel_format\":\"Mono16\"}",
        .frames_requested = 10};
    fz_cat(catalog_run_insert(c, &spec, NULL), uuid);
    for (int i = 0; i < npath; i++)
        fz_cat(catalog_run_set_state(c, uuid, path[i], i == npath - 1 ? reason : NULL), uuid);
}

#define FZ_T0 1714560000000   /* 2024-05-01T10:40:00Z */

static void fz_sql(const char *sql)
{
    char *msg = NULL;
    if (sqlite3_exec(FZ.db, sql, NULL, NULL, &msg) != SQLITE_OK)
        fz_die(sql, msg ? msg : "?");
    sqlite3_free(msg);
}

/* The runs table, to see that a request changed nothing. */
static char *fz_fingerprint(void)
{
    sqlite3_stmt *st = NULL;
    char *fp = NULL;
    if (sqlite3_prepare_v2(FZ.db, "SELECT count(*) || ' ' || group_concat(uuid || state || "
                           "updated_ms || coalesce(file_path, ''), ',') FROM runs", -1, &st,
                           NULL) != SQLITE_OK ||
        sqlite3_step(st) != SQLITE_ROW)
        fz_die("fingerprint", sqlite3_errmsg(FZ.db));
    fp = g_strdup((const char *)sqlite3_column_text(st, 0));
    sqlite3_finalize(st);
    return fp;
}

/* Back to the seeded state: runs the input added deleted, RUN_QUEUED
 * queued again. */
static void fz_restore(void)
{
    catalog_run r;
    int requeue = 1;
    if (catalog_run_get(FZ.d.cat, RUN_QUEUED, &r) == SL_OK) {
        requeue = r.state != CATALOG_QUEUED;
        catalog_run_clear(&r);
    }
    fz_sql("DELETE FROM runs WHERE uuid NOT IN ('" RUN_QUEUED "', '" RUN_CURRENT "', '"
           RUN_STORED "', '" RUN_DONE "', '" RUN_FAILED "', '" RUN_ORPHAN "', '" RUN_AMB1
           "', '" RUN_AMB2 "')");
    if (requeue) {
        fz_sql("DELETE FROM runs WHERE uuid = '" RUN_QUEUED "'");
        fz_run(RUN_QUEUED, FZ_T0 + 7000, "screen1", "nrm17", NULL, 0, NULL);
    }
    g_ptr_array_set_size(FZ.queue, 0);
    g_ptr_array_add(FZ.queue, g_strdup(RUN_QUEUED));
    FZ.dirty = 0;
}

/* The catalogue, with the configured wheels and the runs described at
 * the top; the stand-in queue holds RUN_QUEUED. */
static void fz_seed(void)
{
    sl_err e = {0};
    if (catalog_open(&FZ.d.cat, FZ.cfg.catalog, &e) != SL_OK)
        fz_die("catalog_open", e.msg);
    if (sqlite3_open_v2(FZ.cfg.catalog, &FZ.db, SQLITE_OPEN_READWRITE, NULL) != SQLITE_OK)
        fz_die("sqlite3_open", FZ.cfg.catalog);
    sqlite3_busy_timeout(FZ.db, 5000);
    catalog *c = FZ.d.cat;
    for (int i = 0; i < FZ.cfg.nscreens; i++)
        fz_cat(catalog_screen_upsert(c, FZ.cfg.screens[i].name, FZ.cfg.screens[i].slot,
                                     NULL, NULL), "screen");
    static const double hx[3] = {-0.3, 0.1, 0.4}, hy[3] = {0.2, -0.35, 0.25};
    for (int i = 0; i < FZ.cfg.nmasks; i++) {
        int full = !strcmp(FZ.cfg.masks[i].name, "full");
        catalog_mask m = {.name = FZ.cfg.masks[i].name, .slot = FZ.cfg.masks[i].slot,
                          .kind = full ? CATALOG_MASK_FULL : CATALOG_MASK_HOLES,
                          .diameter_m = full ? 1.1 : 0.05, .nholes = full ? 0 : 3,
                          .x_m = full ? NULL : hx, .y_m = full ? NULL : hy};
        fz_cat(catalog_mask_upsert(c, &m, NULL), "mask");
    }
    const int64_t t0 = FZ_T0;
    const catalog_state to_acq[] = {CATALOG_MOVING, CATALOG_ACQUIRING};
    const catalog_state to_stored[] = {CATALOG_MOVING, CATALOG_ACQUIRING, CATALOG_STORED};
    const catalog_state to_done[] = {CATALOG_MOVING, CATALOG_ACQUIRING, CATALOG_STORED,
                                     CATALOG_DONE};
    const catalog_state to_failed[] = {CATALOG_MOVING, CATALOG_FAILED};
    fz_run(RUN_DONE, t0, "screen1", "nrm17", to_done, 4, NULL);
    fz_run(RUN_FAILED, t0 + 1000, "screen2", "full", to_failed, 2,
           "stage /dev/null: cannot connect");
    fz_run(RUN_STORED, t0 + 2000, "screen1", "full", to_stored, 3, NULL);
    fz_run(RUN_AMB1, t0 + 3000, "open", "full", NULL, 0, NULL);
    fz_run(RUN_AMB2, t0 + 4000, "open", "nrm17", to_failed, 2, "camera lost");
    fz_run(RUN_ORPHAN, t0 + 5000, "screen3", "full", NULL, 0, NULL);
    fz_run(RUN_CURRENT, t0 + 6000, "screen2", "nrm17", to_acq, 2, NULL);

    char *cube = g_strdup_printf("%s/runs/%s.fits", FZ.cfg.data_dir, RUN_STORED);
    char *gone = g_strdup_printf("%s/runs/%s.fits", FZ.cfg.data_dir, RUN_DONE);
    fz_cat(catalog_run_set_file(c, RUN_STORED, cube, NULL), "cube");
    fz_cat(catalog_run_set_file(c, RUN_DONE, gone, NULL), "cube");
    catalog_recon r;
    catalog_recon_init(&r);
    r.run_uuid = RUN_DONE, r.method = "tsm-fourier", r.params_json = "{\"projections\":180}";
    r.started_ms = t0 + 60000, r.elapsed_s = 1.5, r.sep_px = 7.5, r.pa_deg = 42;
    r.output_fits = "recon/" RUN_DONE "-tsm-fourier.fits";
    r.quality_json = "{\"nframes\":10,\"binary_found\":true}";
    fz_cat(catalog_recon_insert(c, &r, NULL), "recon");
    catalog_r0 q;
    catalog_r0_init(&q);
    q.screen_name = "screen1", q.run_uuid = RUN_DONE, q.measured_ms = t0 + 30000;
    q.r0_m = 0.12, q.wavelength_m = 633e-9, q.method = "image-motion";
    fz_cat(catalog_r0_add(c, &q, NULL), "r0");
    g_free(cube);
    g_free(gone);
    fz_restore();   /* adds RUN_QUEUED */
}

/* ---- the scratch directory ------------------------------------------------------ */

static int fz_nwalked;   /* nftw takes no user pointer */

static int fz_count_one(const char *p, const struct stat *st, int flag, struct FTW *f)
{
    (void)p, (void)st, (void)flag, (void)f;
    fz_nwalked++;
    return 0;
}

/* Entries under root (root included). */
static int fz_tree_size(void)
{
    fz_nwalked = 0;
    nftw(FZ.root, fz_count_one, 8, FTW_PHYS);
    return fz_nwalked;
}

static int fz_rm_one(const char *p, const struct stat *st, int flag, struct FTW *f)
{
    (void)st, (void)flag, (void)f;
    return remove(p);
}

static void fz_cleanup(void)
{
    if (FZ.root[0])
        nftw(FZ.root, fz_rm_one, 8, FTW_DEPTH | FTW_PHYS);
}

/* A crash (abort) skips atexit: remove the scratch directories of
 * harness processes that are gone (named after their pid), never those
 * of one still running. */
static void fz_remove_stale(const char *tmp)
{
    GDir *d = g_dir_open(tmp, 0, NULL);
    const char *name;
    while (d && (name = g_dir_read_name(d))) {
        long pid = 0;
        if (sscanf(name, "sl-fuzz-dispatch.%ld.", &pid) != 1 || pid <= 0 ||
            kill((pid_t)pid, 0) == 0 || errno != ESRCH)
            continue;
        char *p = g_build_filename(tmp, name, NULL);
        nftw(p, fz_rm_one, 8, FTW_DEPTH | FTW_PHYS);
        g_free(p);
    }
    if (d)
        g_dir_close(d);
}

/* Scratch directory, configuration file, server, catalogue. */
static void fz_setup(void)
{
    sl_err e = {0};
    const char *tmp = g_getenv("TMPDIR");
    if (g_file_test("/dev/shm", G_FILE_TEST_IS_DIR) && access("/dev/shm", W_OK) == 0)
        tmp = "/dev/shm";
    /* Short: the socket's path must fit sockaddr_un. */
    tmp = tmp && strlen(tmp) < 30 ? tmp : "/tmp";
    fz_remove_stale(tmp);
    snprintf(FZ.root, sizeof FZ.root, "%s/sl-fuzz-dispatch.%ld.XXXXXX", tmp, (long)getpid());
    if (!mkdtemp(FZ.root))
        fz_die("mkdtemp", FZ.root);
    atexit(fz_cleanup);
    char *runs = g_strdup_printf("%s/data/runs", FZ.root);
    char *recon = g_strdup_printf("%s/data/recon", FZ.root);
    char *cube = g_strdup_printf("%s/" RUN_STORED ".fits", runs);
    char *conf = g_strdup_printf("%s/specklabd.conf", FZ.root);
    char *text = g_strdup_printf(
        "[stage]\nbackend=rtu\ndevice=%s/no-such-stage\nresponse_timeout_ms=10\n"
        "call_timeout_ms=50\n[paths]\ndata_dir=%s/data\n[daemon]\nsocket=%s/s.sock\n"
        "fftw=estimate\nmax_clients=4\n", FZ.root, FZ.root, FZ.root);
    if (g_mkdir_with_parents(runs, 0750) || g_mkdir_with_parents(recon, 0750) ||
        !g_file_set_contents(cube, "SIMPLE", -1, NULL) ||
        !g_file_set_contents(conf, text, -1, NULL))
        fz_die("scratch directory", FZ.root);
    if (config_load(&FZ.cfg, conf, NULL, NULL, &e) != SL_OK)
        fz_die("config_load", e.msg);
    g_free(runs), g_free(recon), g_free(cube), g_free(conf), g_free(text);

    FZ.queue = g_ptr_array_new_with_free_func(g_free);
    FZ.enqueued = g_array_new(FALSE, FALSE, sizeof(runner_spec));
    FZ.submitted = g_ptr_array_new_with_free_func(g_free);
    FZ.d.cfg = &FZ.cfg;
    FZ.d.started_us = g_get_monotonic_time();
    /* As main.c: the main thread owns the default context throughout. */
    g_main_context_acquire(g_main_context_default());
    if (server_new(&FZ.d.srv, FZ.cfg.socket, FZ.cfg.max_clients,
                   FZ.cfg.client_idle_timeout_ms, dispatch_request, &FZ.d,
                   &e) != SL_OK)
        fz_die("server_new", e.msg);
    fz_seed();
    FZ.ntree = fz_tree_size();
}

#endif
