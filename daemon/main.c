/* main.c - specklabd: options, start-up, the main loop, shutdown.
 *
 *   specklabd [--config FILE] [--socket PATH] [--data-dir DIR]
 *             [--web HOST:PORT [--web-allow-remote]]
 *             [--foreground] [--quiet] [--print-defaults]
 *
 * Start-up, in this order (each step can refuse to start, exit 1):
 *   1. configuration (config.h); without --foreground the process forks
 *      here, before any thread exists, and the parent exits 0 only once
 *      the child is serving (or 1 when it failed);
 *   2. DATA_DIR, DATA_DIR/runs, DATA_DIR/recon (0750), and an exclusive
 *      flock on DATA_DIR/specklabd.lock: a second daemon on the same data
 *      must not "recover" the first one's live runs;
 *   3. the socket (server.h), so a live daemon on it is found early;
 *   4. the catalogue, with its reserve for ending runs on a full disk
 *      (reserve.h): configured screens and masks upserted; every run
 *      left non-terminal by a previous daemon gets its partial cube
 *      salvaged (cubefile_salvage: frames on disk counted) and its FRAMES
 *      table rebuilt from the rows it logged (framelog.h), is marked
 *      'interrupted', and its file re-checksummed;
 *   5. the worker and runner threads, the web page when configured
 *      ([web] listen or --web: web.h), signal sources, then "READY
 *      socket=PATH" (with " web=URL" when the page is served: the bound
 *      address, also with port 0) on stdout and the main loop.
 * SIGTERM/SIGINT: stop listening (socket and web page), abort the current run ("daemon
 * stopping": its cube is closed and kept), mark queued runs aborted, let
 * the worker finish its current reconstruction, deliver the last events,
 * close everything, remove the socket, exit 0.  SIGPIPE and SIGXFSZ are
 * ignored: a vanished client or a file-size limit must be an error
 * return, not the end of the daemon.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <fftw3.h>
#include <glib-unix.h>
#include <glib.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <systemd/sd-daemon.h>

#include "base/version.h"
#include "cubefile.h"
#include "dispatch.h"
#include "framelog.h"
#include "reserve.h"
#include "web.h"
#include "webconf.h"
/* After GLib: recon's `mask` typedef would clash with gutils.h parameters. */
#include "sim/mask.h"

typedef struct opts {
    char *config, *socket, *data_dir, *web;
    gboolean foreground, quiet, print_defaults, version, web_allow_remote;
} opts;

static int parse_opts(int argc, char **argv, opts *o)
{
    GOptionEntry entries[] = {
        {"config", 'c', 0, G_OPTION_ARG_FILENAME, &o->config, "configuration file", "FILE"},
        {"socket", 's', 0, G_OPTION_ARG_FILENAME, &o->socket, "control socket path", "PATH"},
        {"data-dir", 'd', 0, G_OPTION_ARG_FILENAME, &o->data_dir, "data directory", "DIR"},
        {"web", 0, 0, G_OPTION_ARG_STRING, &o->web,
         "serve the live web page on HOST:PORT (port 0: any free; \"\": none), over [web] listen",
         "HOST:PORT"},
        {"web-allow-remote", 0, 0, G_OPTION_ARG_NONE, &o->web_allow_remote,
         "let --web use a non-loopback address (the page has no authentication)", NULL},
        {"foreground", 'f', 0, G_OPTION_ARG_NONE, &o->foreground, "do not detach", NULL},
        {"quiet", 'q', 0, G_OPTION_ARG_NONE, &o->quiet, "log warnings only", NULL},
        {"print-defaults", 0, 0, G_OPTION_ARG_NONE, &o->print_defaults,
         "print the built-in configuration and exit", NULL},
        {"version", 0, 0, G_OPTION_ARG_NONE, &o->version, "print the version and exit", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("- the specklab bench daemon");
    GError *ge = NULL;
    g_option_context_add_main_entries(ctx, entries, NULL);
    g_option_context_set_description(ctx,
        "Serves daemon/PROTOCOL.md on a Unix socket (mode 0660, the daemon's group).\n"
        "Prints 'READY socket=PATH' once serving (followed by ' web=URL' when it\n"
        "serves the web page), and tells systemd (Type=notify) when started by it.\n"
        "SIGTERM/SIGINT stop it cleanly.");
    int ok = g_option_context_parse(ctx, &argc, &argv, &ge);
    if (!ok)
        fprintf(stderr, "specklabd: %s (try --help)\n", ge->message);
    else if (argc > 1)
        fprintf(stderr, "specklabd: unexpected argument '%s'\n", argv[1]), ok = 0;
    if (ge)
        g_error_free(ge);
    g_option_context_free(ctx);
    return ok ? 0 : 2;
}

/* ---- data directory and lock ------------------------------------------------ */

static int prepare_dirs(const config *cfg, int *lock_fd, sl_err *e)
{
    const char *sub[] = {"", "runs", "recon"};
    for (size_t i = 0; i < G_N_ELEMENTS(sub); i++) {
        char *p = g_build_filename(cfg->data_dir, sub[i], NULL);
        int rc = g_mkdir_with_parents(p, 0750);
        if (rc != 0)
            sl_seterr(e, SL_EIO, "%s: %s", p, g_strerror(errno));
        g_free(p);
        if (rc != 0)
            return SL_EIO;
    }
    char *lock = g_build_filename(cfg->data_dir, "specklabd.lock", NULL);
    *lock_fd = open(lock, O_RDWR | O_CREAT | O_CLOEXEC, 0640);
    int rc = SL_OK;
    if (*lock_fd < 0)
        rc = sl_seterr(e, SL_EIO, "%s: %s", lock, g_strerror(errno));
    else if (flock(*lock_fd, LOCK_EX | LOCK_NB) != 0)
        rc = sl_seterr(e, SL_EIO, "%s: another specklabd uses this data directory (%s)", lock,
                       g_strerror(errno));
    g_free(lock);
    return rc;
}

/* ---- catalogue at start ------------------------------------------------------ */

static int upsert_slots(const config *cfg, catalog *cat, sl_err *e)
{
    for (int i = 0; i < cfg->nscreens; i++)
        if (catalog_screen_upsert(cat, cfg->screens[i].name, cfg->screens[i].slot, NULL,
                                  NULL) != SL_OK)
            return sl_seterr(e, SL_EIO, "%s", catalog_errmsg(cat));
    for (int i = 0; i < cfg->nmasks; i++) {
        const config_slot *s = &cfg->masks[i];
        mask *m = NULL;
        int rc = s->file ? mask_read(&m, s->file, e) : mask_named(&m, s->name, e);
        if (rc != SL_OK)
            return sl_seterr(e, rc, "config [masks] %d=%s: %s", s->slot, s->name, e->msg);
        int n = mask_nholes(m);
        double *x = g_new(double, n > 0 ? n : 1), *y = g_new(double, n > 0 ? n : 1);
        for (int h = 0; h < n; h++)
            mask_hole(m, h, &x[h], &y[h]);
        catalog_mask cm = {
            .name = s->name, .slot = s->slot,
            .kind = mask_is_full(m) ? CATALOG_MASK_FULL : CATALOG_MASK_HOLES,
            .diameter_m = mask_is_full(m) ? mask_diameter_m(m) : mask_hole_diameter_m(m),
            .nholes = n, .x_m = x, .y_m = y, .description = NULL};
        rc = catalog_mask_upsert(cat, &cm, NULL);
        g_free(x);
        g_free(y);
        mask_free(m);
        if (rc != SL_OK)
            return sl_seterr(e, rc, "%s", catalog_errmsg(cat));
    }
    return SL_OK;
}

typedef struct orphan {
    char uuid[CATALOG_UUID_LEN + 1];
    char *file;
} orphan;

static int collect_orphan(const catalog_run *r, void *user)
{
    if (catalog_state_is_terminal(r->state))
        return 0;
    orphan o = {{0}, g_strdup(r->file_path)};
    /* Killed between the rename to .fits and the catalogue's new path. */
    if (o.file && g_str_has_suffix(o.file, ".part") && access(o.file, F_OK) != 0) {
        char *done = g_strndup(o.file, strlen(o.file) - 5);
        if (access(done, F_OK) == 0)
            g_free(o.file), o.file = done;
        else
            g_free(done);
    }
    memcpy(o.uuid, r->uuid, sizeof o.uuid);
    g_array_append_val((GArray *)user, o);
    return 0;
}

/* Runs a previous daemon left behind: count the frames their cube really
 * holds, mark them interrupted, checksum what is on disk. */
static int recover_runs(const config *cfg, catalog *cat, sl_err *e)
{
    GArray *v = g_array_new(FALSE, FALSE, sizeof(orphan));
    int rc = catalog_run_list(cat, NULL, collect_orphan, v);
    if (rc != SL_OK) {
        sl_seterr(e, rc, "%s", catalog_errmsg(cat));
        goto free_v;
    }
    for (guint i = 0; i < v->len; i++) {
        orphan *o = &g_array_index(v, orphan, i);
        catalog_run r;
        int n = 0;
        if (o->file && cubefile_under(cfg->data_dir, o->file) &&
            cubefile_salvage(o->file, &n, e) == SL_OK &&
            catalog_run_get(cat, o->uuid, &r) == SL_OK) {
            sl_err e2 = {0};
            /* The FRAMES rows logged while it acquired (framelog.h). */
            if (framelog_recover(o->file, n, &e2) != SL_OK)
                g_warning("run %s: no FRAMES table: %s", o->uuid, e2.msg);
            catalog_run_update_progress(cat, o->uuid, n, r.frames_failed, r.packets_missing);
            catalog_run_clear(&r);
        }
    }
    rc = catalog_runs_mark_interrupted(cat);
    if (rc < 0) {
        sl_seterr(e, rc, "%s", catalog_errmsg(cat));
        goto free_v;
    }
    if (rc > 0)
        g_message("%d run(s) left by the previous daemon marked interrupted", rc);
    rc = SL_OK;
    for (guint i = 0; i < v->len; i++) {
        orphan *o = &g_array_index(v, orphan, i);
        char hex[65];
        sl_err e2 = {0};
        if (o->file && cubefile_under(cfg->data_dir, o->file) &&
            cubefile_sha256(o->file, hex, &e2) == SL_OK)
            catalog_run_set_file(cat, o->uuid, o->file, hex);
    }
free_v:
    for (guint i = 0; i < v->len; i++)
        g_free(g_array_index(v, orphan, i).file);
    g_array_free(v, TRUE);
    return rc;
}

/* Open the catalogue, upsert the slots, recover the runs left behind.  On
 * a full disk these writes fail; the reserve a previous daemon left is
 * then released and they are tried once more (the runner makes the
 * reserve again before the next run). */
static int start_catalog(const config *cfg, const catalog_opts *co, catalog **cat, reserve *rs,
                         sl_err *e)
{
    for (int attempt = 0;; attempt++) {
        int rc = catalog_open_opts(cat, cfg->catalog, co, e);
        if (rc == SL_OK && (rc = upsert_slots(cfg, *cat, e)) == SL_OK &&
            (rc = recover_runs(cfg, *cat, e)) == SL_OK)
            return SL_OK;
        if (attempt > 0 || !reserve_release(rs))
            return rc;
        g_warning("%s; released the catalogue's reserve to start", e->msg);
        catalog_close(*cat);
        *cat = NULL;
        sl_clearerr(e);
    }
}

/* ---- signals, logging, detaching ---------------------------------------------- */

static gboolean on_signal(gpointer loop)
{
    g_message("stopping");
    g_main_loop_quit(loop);
    return G_SOURCE_REMOVE;
}

static void log_quiet(const gchar *domain, GLogLevelFlags level, const gchar *msg, gpointer u)
{
    (void)domain, (void)level, (void)msg, (void)u;
}

/* Fork; the parent waits for the child's readiness byte.  Returns the
 * write end for the child (-1 in the foreground). */
static int detach(void)
{
    int p[2];
    if (pipe2(p, O_CLOEXEC) != 0) {
        perror("specklabd: pipe");
        exit(1);
    }
    pid_t pid = fork();
    if (pid < 0) {
        perror("specklabd: fork");
        exit(1);
    }
    if (pid > 0) {
        char c = 0;
        close(p[1]);
        ssize_t n;
        while ((n = read(p[0], &c, 1)) < 0 && errno == EINTR)
            ;
        exit(n == 1 && c == 'R' ? 0 : 1);
    }
    close(p[0]);
    setsid();
    int nul = open("/dev/null", O_RDWR);
    if (nul >= 0) {
        dup2(nul, 0);
        dup2(nul, 1);
        if (nul > 2)
            close(nul);
    }
    return p[1];
}

/* The configuration, with --web over [web] listen. */
static int load_config(config *cfg, const opts *o, sl_err *e)
{
    if (config_load(cfg, o->config, o->socket, o->data_dir, e) != SL_OK)
        return SL_EINVAL;
    if (o->web && webconf_set(cfg, "--web", o->web, o->web_allow_remote,
                              "--web-allow-remote", e) != SL_OK) {
        config_clear(cfg);
        return SL_EINVAL;
    }
    return SL_OK;
}

/* Ready: the READY line (the tests and scripts/demo read it), systemd,
 * the log, the parent waiting on the readiness pipe. */
static void announce(const config *cfg, const web *wb, int *ready_fd)
{
    const char *url = wb ? web_url(wb) : "";
    if (*url)
        g_message("web page at %s", url);
    printf("READY socket=%s%s%s\n", cfg->socket, *url ? " web=" : "", url);
    fflush(stdout);
    /* systemd Type=notify: ready only now that the socket answers; a
     * no-op without NOTIFY_SOCKET (started by hand or by a test). */
    sd_notifyf(0, "READY=1\nSTATUS=serving %s%s%s", cfg->socket, *url ? ", web page " : "", url);
    g_message("serving %s; data %s; catalogue %s", cfg->socket, cfg->data_dir, cfg->catalog);
    if (*ready_fd >= 0) {
        if (write(*ready_fd, "R", 1) != 1)
            g_warning("readiness pipe: %s", g_strerror(errno));
        close(*ready_fd);
        *ready_fd = -1;
    }
}

/* Everything main started, stopped in order: listeners first (web page,
 * socket), then the threads, then what they used. */
static void shut_down(daemon_ctx *d, web *wb, const config *cfg)
{
    web_stop(wb);
    server_stop_listening(d->srv);
    runner_stop(d->run);
    worker_stop(d->wk);
    /* devices queries in flight end within the stage call timeout. */
    for (gint64 end = g_get_monotonic_time() + (cfg->call_timeout_ms + 1000) * 1000LL;
         d->pending_tasks > 0 && g_get_monotonic_time() < end;)
        g_main_context_iteration(NULL, TRUE);
    while (g_main_context_iteration(NULL, FALSE))
        ;   /* the threads' last events and replies, the web's last closes */
    web_free(wb);
    runner_free(d->run);
    worker_free(d->wk);
    if (d->pending_tasks > 0)   /* a stuck query still holds the server */
        g_warning("leaving with %d devices queries unanswered", d->pending_tasks);
    else
        server_free(d->srv);
    catalog_close(d->cat);
}

static int start_web(web **wb, const daemon_ctx *d, const config *cfg, sl_err *e)
{
    web_opts wo = {cfg, d->run, d->wk, d->started_us};
    *wb = NULL;
    return cfg->web_host ? web_new(wb, &wo, e) : SL_OK;
}

int main(int argc, char **argv)
{
    opts o = {0};
    config cfg;
    sl_err e = {0};
    int status = 1, lock_fd = -1, ready_fd = -1;
    daemon_ctx d = {0};
    reserve *rs = NULL;
    web *wb = NULL;
    /* The worker and the web view both plan FFTs: FFTW's planner (and its
     * wisdom) is process-global, so it is made thread-safe before any
     * thread exists (cost: a lock around each plan, none on execution). */
    fftw_make_planner_thread_safe();
    fftwf_make_planner_thread_safe();
    if ((status = parse_opts(argc, argv, &o)) != 0)
        goto free_opts;
    status = 1;
    if (o.version || o.print_defaults) {
        fputs(o.version ? "specklabd " SPECKLAB_VERSION "\n" : config_defaults_text(), stdout);
        status = 0;
        goto free_opts;
    }
    if (load_config(&cfg, &o, &e) != SL_OK) {
        fprintf(stderr, "specklabd: %s\n", e.msg);
        status = 2;
        goto free_opts;
    }
    if (o.quiet)
        g_log_set_handler(NULL, G_LOG_LEVEL_MESSAGE | G_LOG_LEVEL_INFO, log_quiet, NULL);
    signal(SIGPIPE, SIG_IGN);
    signal(SIGXFSZ, SIG_IGN);
    if (!o.foreground)
        ready_fd = detach();
    d.cfg = &cfg;
    d.started_us = g_get_monotonic_time();
    catalog_opts cat_opts = {cfg.catalog_busy_timeout_ms};
    GMainLoop *loop = g_main_loop_new(NULL, FALSE);
    /* The main thread owns the main context from here to the end, also
     * outside g_main_loop_run: g_main_context_invoke from the threads then
     * always queues (server_*_async) instead of running the callback on
     * the calling thread when nobody owns the context. */
    g_main_context_acquire(g_main_context_default());
    if (prepare_dirs(&cfg, &lock_fd, &e) != SL_OK ||
        server_new(&d.srv, cfg.socket, cfg.max_clients, cfg.client_idle_timeout_ms,
                   dispatch_request, &d, &e) != SL_OK ||
        (rs = reserve_new(cfg.catalog), start_catalog(&cfg, &cat_opts, &d.cat, rs, &e)) != SL_OK ||
        worker_new(&d.wk, &cfg, d.srv, rs, &e) != SL_OK ||
        runner_new(&d.run, &cfg, d.srv, d.wk, rs, &e) != SL_OK ||
        start_web(&wb, &d, &cfg, &e) != SL_OK) {
        fprintf(stderr, "specklabd: %s\n", e.msg);
        goto stop;
    }
    if (wb)   /* for status */
        snprintf(d.web_url, sizeof d.web_url, "%s", web_url(wb));
    g_unix_signal_add(SIGTERM, on_signal, loop);
    g_unix_signal_add(SIGINT, on_signal, loop);
    announce(&cfg, wb, &ready_fd);
    g_main_loop_run(loop);
    status = 0;
    sd_notify(0, "STOPPING=1\nSTATUS=stopping: the current run ends with its frames kept");
stop:
    shut_down(&d, wb, &cfg);
    g_main_context_release(g_main_context_default());
    g_main_loop_unref(loop);
    if (lock_fd >= 0)
        close(lock_fd);
    reserve_free(rs);
    config_clear(&cfg);
free_opts:
    g_free(o.config);
    g_free(o.socket);
    g_free(o.data_dir);
    g_free(o.web);
    return status;
}
