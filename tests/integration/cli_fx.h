/* cli_fx.h - fixtures of test_cli.c: a stub specklabd in a thread, and
 * run_cmd, which runs a subcommand in-process with stdout and stderr
 * captured.
 *
 * The stub speaks daemon/PROTOCOL.md on a Unix socket and simulates the
 * run state machine on a 5 ms tick: queued -> moving -> acquiring (frames
 * in steps of 20, progress events) -> stored -> reconstructing -> done,
 * one run at a time in queue order, sending state/progress/reconstruction
 * events to subscribers.  A run through screen "bad" fails while
 * acquiring ("camera lost after 20 frames").  Each run writes a real FITS
 * stand-in file (for export: size and sha256 are checked).  Screens s1..s3
 * (slots 1..3) have r0 0.30, 0.18, 0.10 m; the binary is at 0.7", PA 30.
 * Everything is static: one test binary includes this header.
 */
#ifndef SL_CLI_FX_H
#define SL_CLI_FX_H

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include "cmd_daemon.h"

#define MAXRUN 16
#define MAXCONN 8
#define SEP_ARCSEC 0.7
#define PA_DEG 30.0

typedef struct srun {
    char uuid[40], screen[32], mask[32], state[16], reason[64];
    char kind[16];            /* start-run's kind, "" when not sent */
    int frames, acquired, nrecon;
    char file[200];
} srun;

typedef struct sd {
    char dir[64], path[96];
    int lfd, stop_pipe[2];
    pthread_t th;
    pthread_mutex_t mu;       /* guards the fields below against the test */
    srun runs[MAXRUN];
    int nruns;
    JsonObject *last_runs_args; /* args of the last `runs` request */
    int bad_sha;              /* report a sha256 that is not the file's */
} sd;

typedef struct conn {
    int fd, sub;
    GString *in;
} conn;

static void put(conn *c, JsonObject *o)
{
    if (c->fd < 0)
        return;
    JsonNode *n = json_node_init_object(json_node_alloc(), o);
    char *s = json_to_string(n, FALSE);
    json_node_unref(n);
    char *line = g_strconcat(s, "\n", NULL);
    size_t len = strlen(line), off = 0;
    while (off < len) {
        ssize_t w = send(c->fd, line + off, len - off, MSG_NOSIGNAL);
        if (w <= 0)
            break;
        off += (size_t)w;
    }
    g_free(s);
    g_free(line);
}

static const double r0_of[] = {INFINITY, 0.30, 0.18, 0.10};

static double screen_r0(const char *name)
{
    int k = name[0] == 's' ? atoi(name + 1) : 0;
    return k >= 1 && k <= 3 ? r0_of[k] : NAN;
}

static void num(JsonObject *o, const char *k, double v)
{
    if (isfinite(v))
        json_object_set_double_member(o, k, v);
    else
        json_object_set_null_member(o, k);
}

static JsonObject *recon_obj(const sd *s, const srun *r, int id, const char *method)
{
    JsonObject *x = json_object_new();
    json_object_set_int_member(x, "id", id);
    json_object_set_string_member(x, "method", method);
    json_object_set_double_member(x, "elapsed_s", 0.5);
    json_object_set_string_member(x, "started", "2024-05-01T12:00:05Z");
    char *f = g_strdup_printf("%s/%s-r%d.fits", s->dir, r->uuid, id);
    char *p = g_strdup_printf("%s/%s-r%d.png", s->dir, r->uuid, id);
    g_file_set_contents(f, "RECONFITS", -1, NULL);
    g_file_set_contents(p, "PNG", -1, NULL);
    json_object_set_string_member(x, "fits", f);
    json_object_set_string_member(x, "png", p);
    g_free(f);
    g_free(p);
    json_object_set_double_member(x, "sep_arcsec", SEP_ARCSEC);
    json_object_set_double_member(x, "sep_px", SEP_ARCSEC / 0.1);
    json_object_set_double_member(x, "pa_deg", PA_DEG);
    json_object_set_double_member(x, "dm_mag", 1.0);
    json_object_set_null_member(x, "c_cophased");
    return x;
}

static JsonObject *run_obj(const sd *s, const srun *r)
{
    JsonObject *o = json_object_new();
    json_object_set_string_member(o, "uuid", r->uuid);
    json_object_set_string_member(o, "state", r->state);
    if (r->reason[0])
        json_object_set_string_member(o, "exit_reason", r->reason);
    else
        json_object_set_null_member(o, "exit_reason");
    json_object_set_string_member(o, "created", "2024-05-01T12:00:00Z");
    json_object_set_string_member(o, "started", "2024-05-01T12:00:01Z");
    json_object_set_string_member(o, "ended", "2024-05-01T12:00:04Z");
    json_object_set_string_member(o, "screen", r->screen);
    json_object_set_string_member(o, "mask", r->mask);
    json_object_set_int_member(o, "frames_requested", r->frames);
    json_object_set_int_member(o, "frames_acquired", r->acquired);
    num(o, "r0_m", !strcmp(r->state, "done") ? screen_r0(r->screen) : NAN);
    if (r->file[0]) {
        json_object_set_string_member(o, "file", r->file);
        gchar *data = NULL;
        gsize len = 0;
        g_file_get_contents(r->file, &data, &len, NULL);
        gchar *sum = g_compute_checksum_for_data(G_CHECKSUM_SHA256, (guchar *)data, len);
        json_object_set_string_member(o, "sha256", s->bad_sha ? "00ff" : sum);
        g_free(sum);
        g_free(data);
    } else {
        json_object_set_null_member(o, "file");
    }
    return o;
}

static void broadcast(conn *cs, int n, JsonObject *ev)
{
    for (int i = 0; i < n; i++)
        if (cs[i].fd >= 0 && cs[i].sub)
            put(&cs[i], ev);
    json_object_unref(ev);
}

static JsonObject *state_ev(const srun *r)
{
    JsonObject *e = json_object_new();
    json_object_set_string_member(e, "event", "state");
    json_object_set_string_member(e, "run", r->uuid);
    json_object_set_string_member(e, "state", r->state);
    if (r->reason[0])
        json_object_set_string_member(e, "reason", r->reason);
    else
        json_object_set_null_member(e, "reason");
    return e;
}

/* One tick of the bench: advance the first unfinished run. */
static void tick(sd *s, conn *cs, int n)
{
    srun *r = NULL;
    for (int i = 0; i < s->nruns && !r; i++)
        if (strcmp(s->runs[i].state, "done") && strcmp(s->runs[i].state, "failed"))
            r = &s->runs[i];
    if (!r)
        return;
    const char *next = NULL;
    if (!strcmp(r->state, "queued"))
        next = "moving";
    else if (!strcmp(r->state, "moving"))
        next = "acquiring";
    else if (!strcmp(r->state, "acquiring")) {
        r->acquired += r->frames - r->acquired < 20 ? r->frames - r->acquired : 20;
        JsonObject *e = json_object_new();
        json_object_set_string_member(e, "event", "progress");
        json_object_set_string_member(e, "run", r->uuid);
        json_object_set_int_member(e, "frames_acquired", r->acquired);
        json_object_set_int_member(e, "frames_requested", r->frames);
        json_object_set_int_member(e, "frames_failed", 0);
        broadcast(cs, n, e);
        if (!strcmp(r->screen, "bad")) {
            snprintf(r->reason, sizeof r->reason, "camera lost after %d frames", r->acquired);
            next = "failed";
        } else if (r->acquired >= r->frames) {
            next = "stored";
        }
    } else if (!strcmp(r->state, "stored")) {
        next = "reconstructing";
    } else if (!strcmp(r->state, "reconstructing")) {
        JsonObject *e = json_object_new();
        json_object_set_string_member(e, "event", "reconstruction");
        json_object_set_string_member(e, "run", r->uuid);
        json_object_set_object_member(e, "reconstruction", recon_obj(s, r, ++r->nrecon, "tsm"));
        broadcast(cs, n, e);
        next = "done";
    }
    if (next) {
        if (!strcmp(next, "acquiring")) {
            snprintf(r->file, sizeof r->file, "%s/%s.fits", s->dir, r->uuid);
            g_file_set_contents(r->file, "SIMPLE  =                    T", -1, NULL);
        }
        snprintf(r->state, sizeof r->state, "%s", next);
        broadcast(cs, n, state_ev(r));
    }
}

static srun *find(sd *s, const char *id)
{
    srun *hit = NULL;
    for (int i = 0; id && *id && i < s->nruns; i++)
        if (!strncmp(s->runs[i].uuid, id, strlen(id))) {
            if (hit)
                return NULL; /* ambiguous prefix */
            hit = &s->runs[i];
        }
    return hit;
}

static const char *name_arg(JsonObject *a, const char *k, const char *prefix, char *buf, size_t n)
{
    JsonNode *v = a ? json_object_get_member(a, k) : NULL;
    if (v && json_node_get_value_type(v) == G_TYPE_INT64)
        snprintf(buf, n, "%s%lld", prefix, (long long)json_node_get_int(v));
    else if (v && json_node_get_value_type(v) == G_TYPE_STRING)
        snprintf(buf, n, "%s", json_node_get_string(v));
    else
        buf[0] = '\0';
    return buf;
}

static JsonArray *named_list(const char *const *names, int n)
{
    JsonArray *a = json_array_new();
    for (int i = 0; i < n; i++) {
        JsonObject *o = json_object_new();
        json_object_set_string_member(o, "name", names[i]);
        json_object_set_int_member(o, "slot", i);
        json_array_add_object_element(a, o);
    }
    return a;
}

/* Answer one request line; res or an error goes back with the id. */
static void handle(sd *s, conn *c, const char *line)
{
    JsonParser *p = json_parser_new();
    if (!json_parser_load_from_data(p, line, -1, NULL)) {
        g_object_unref(p);
        return;
    }
    JsonObject *req = json_node_get_object(json_parser_get_root(p));
    JsonObject *args = json_object_has_member(req, "args") ?
                       json_object_get_object_member(req, "args") : NULL;
    const char *cmd = json_object_get_string_member(req, "cmd");
    JsonObject *res = json_object_new(), *reply = json_object_new();
    const char *ecode = NULL;
    char emsg[128] = "", b1[32], b2[32];
    if (!strcmp(cmd, "subscribe")) {
        c->sub = 1;
        json_object_set_boolean_member(res, "subscribed", TRUE);
    } else if (!strcmp(cmd, "status")) {
        json_object_set_string_member(res, "version", "stub");
        json_object_set_string_member(res, "state", "idle");
        json_object_set_double_member(res, "uptime_s", 1);
    } else if (!strcmp(cmd, "screens")) {
        static const char *const names[] = {"open", "s1", "s2", "s3", "bad"};
        JsonArray *a = named_list(names, 5);
        for (guint i = 1; i < 4; i++) {
            JsonObject *st = json_object_new();
            json_object_set_int_member(st, "n", 1);
            json_object_set_double_member(st, "mean_r0_m", r0_of[i]);
            json_object_set_object_member(json_array_get_object_element(a, i), "stats", st);
        }
        json_object_set_array_member(res, "screens", a);
    } else if (!strcmp(cmd, "masks")) {
        static const char *const names[] = {"full", "nrm17"};
        json_object_set_array_member(res, "masks", named_list(names, 2));
    } else if (!strcmp(cmd, "start-run")) {
        srun *r = &s->runs[s->nruns++];
        memset(r, 0, sizeof *r);
        snprintf(r->uuid, sizeof r->uuid, "%08x-0000-4000-8000-%012d", 0xabc00000u + (unsigned)s->nruns, s->nruns);
        static const char *const sn[] = {"open", "s1", "s2", "s3", "bad"};
        name_arg(args, "screen", "", b1, sizeof b1);
        int slot = atoi(b1);
        snprintf(r->screen, sizeof r->screen, "%s", b1[0] >= '0' && b1[0] <= '9' && slot < 5 ? sn[slot] : b1);
        snprintf(r->mask, sizeof r->mask, "%s", name_arg(args, "mask", "m", b2, sizeof b2));
        r->frames = (int)json_object_get_int_member(args, "frames");
        if (json_object_has_member(args, "kind"))
            snprintf(r->kind, sizeof r->kind, "%s", json_object_get_string_member(args, "kind"));
        snprintf(r->state, sizeof r->state, "queued");
        json_object_set_string_member(res, "run", r->uuid);
        json_object_set_string_member(res, "state", "queued");
        json_object_set_int_member(res, "queue_position", s->nruns - 1);
    } else if (!strcmp(cmd, "run") || !strcmp(cmd, "reconstruct")) {
        srun *r = find(s, args ? json_object_get_string_member(args, "run") : NULL);
        if (!r) {
            ecode = "not-found";
            snprintf(emsg, sizeof emsg, "no run '%s'", args ? json_object_get_string_member(args, "run") : "");
        } else if (!strcmp(cmd, "run")) {
            json_object_set_object_member(res, "run", run_obj(s, r));
            JsonArray *a = json_array_new();
            for (int k = 1; k <= r->nrecon; k++)
                json_array_add_object_element(a, recon_obj(s, r, k, "tsm"));
            json_object_set_array_member(res, "reconstructions", a);
        } else {
            json_object_set_string_member(res, "run", r->uuid);
            const char *m = args && json_object_has_member(args, "method") ?
                            json_object_get_string_member(args, "method") : "tsm";
            json_object_set_object_member(res, "reconstruction", recon_obj(s, r, ++r->nrecon, m));
        }
    } else if (!strcmp(cmd, "runs")) {
        if (s->last_runs_args)
            json_object_unref(s->last_runs_args);
        s->last_runs_args = args ? json_object_ref(args) : json_object_new();
        JsonArray *a = json_array_new();
        for (int i = s->nruns - 1; i >= 0; i--)
            json_array_add_object_element(a, run_obj(s, &s->runs[i]));
        json_object_set_array_member(res, "runs", a);
    } else {
        ecode = "unknown-command";
        snprintf(emsg, sizeof emsg, "unknown command '%s'", cmd);
    }
    json_object_set_int_member(reply, "id", json_object_get_int_member(req, "id"));
    json_object_set_boolean_member(reply, "ok", ecode == NULL);
    if (ecode) {
        JsonObject *e = json_object_new();
        json_object_set_string_member(e, "code", ecode);
        json_object_set_string_member(e, "message", emsg);
        json_object_set_object_member(reply, "error", e);
        json_object_unref(res);
    } else {
        json_object_set_object_member(reply, "result", res);
    }
    put(c, reply);
    json_object_unref(reply);
    g_object_unref(p);
}

static void *serve(void *arg)
{
    sd *s = arg;
    conn cs[MAXCONN];
    for (int i = 0; i < MAXCONN; i++)
        cs[i] = (conn){-1, 0, NULL};
    for (;;) {
        struct pollfd pf[MAXCONN + 2] = {{s->lfd, POLLIN, 0}, {s->stop_pipe[0], POLLIN, 0}};
        for (int i = 0; i < MAXCONN; i++)
            pf[i + 2] = (struct pollfd){cs[i].fd, POLLIN, 0};
        int n = poll(pf, MAXCONN + 2, 5);
        if (n < 0 && errno != EINTR)
            break;
        if (pf[1].revents)
            break;
        pthread_mutex_lock(&s->mu);
        if (pf[0].revents & POLLIN) {
            int fd = accept(s->lfd, NULL, NULL);
            for (int i = 0; fd >= 0 && i < MAXCONN; i++)
                if (cs[i].fd < 0) {
                    cs[i] = (conn){fd, 0, g_string_new("")};
                    fd = -1;
                }
            if (fd >= 0)
                close(fd);
        }
        for (int i = 0; i < MAXCONN; i++) {
            if (cs[i].fd < 0 || !(pf[i + 2].revents & (POLLIN | POLLHUP)))
                continue;
            char buf[4096];
            ssize_t r = read(cs[i].fd, buf, sizeof buf);
            if (r <= 0) {
                close(cs[i].fd);
                g_string_free(cs[i].in, TRUE);
                cs[i] = (conn){-1, 0, NULL};
                continue;
            }
            g_string_append_len(cs[i].in, buf, r);
            char *nl;
            while (cs[i].fd >= 0 && (nl = memchr(cs[i].in->str, '\n', cs[i].in->len))) {
                char *line = g_strndup(cs[i].in->str, (gsize)(nl - cs[i].in->str));
                g_string_erase(cs[i].in, 0, nl - cs[i].in->str + 1);
                handle(s, &cs[i], line);
                g_free(line);
            }
        }
        tick(s, cs, MAXCONN);
        pthread_mutex_unlock(&s->mu);
    }
    for (int i = 0; i < MAXCONN; i++)
        if (cs[i].fd >= 0) {
            close(cs[i].fd);
            g_string_free(cs[i].in, TRUE);
        }
    return NULL;
}

static int sd_start(sd *s)
{
    memset(s, 0, sizeof *s);
    snprintf(s->dir, sizeof s->dir, "/tmp/test_cli.XXXXXX");
    if (!mkdtemp(s->dir) || pipe(s->stop_pipe) < 0)
        return -1;
    snprintf(s->path, sizeof s->path, "%.40s/specklabd.sock", s->dir);
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", s->path);
    s->lfd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (s->lfd < 0 || bind(s->lfd, (struct sockaddr *)&sa, sizeof sa) < 0 || listen(s->lfd, 8) < 0)
        return -1;
    pthread_mutex_init(&s->mu, NULL);
    return pthread_create(&s->th, NULL, serve, s) == 0 ? 0 : -1;
}

static void sd_stop(sd *s)
{
    if (write(s->stop_pipe[1], "x", 1) == 1)
        pthread_join(s->th, NULL);
    close(s->lfd);
    close(s->stop_pipe[0]);
    close(s->stop_pipe[1]);
    if (s->last_runs_args)
        json_object_unref(s->last_runs_args);
    char *cmd = g_strdup_printf("rm -rf '%s'", s->dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", s->dir);
    g_free(cmd);
}

/* Run fn(argv) with stdout and stderr in files; out and err (g_free) get
 * their text.  Returns fn's exit status. */
/* Run a command in-process with its output captured (in s->dir); sock:
 * append --socket s->path (the commands that talk to the daemon). */
static int run_cmdv(const sd *s, int sock, int (*fn)(int, char **), char **out,
                    char **err, va_list ap)
{
    char *v[32];
    int n = 0;
    for (const char *a; n < 30 && (a = va_arg(ap, const char *));)
        v[n++] = g_strdup(a);
    if (sock) {
        v[n++] = g_strdup("--socket");
        v[n++] = g_strdup(s->path);
    }
    v[n] = NULL;
    char *argv_copy[32];
    memcpy(argv_copy, v, sizeof v); /* GOption reorders argv */
    char *fo = g_strdup_printf("%s/out.txt", s->dir), *fe = g_strdup_printf("%s/err.txt", s->dir);
    fflush(stdout);
    fflush(stderr);
    int so = dup(1), se = dup(2);
    int fdo = open(fo, O_WRONLY | O_CREAT | O_TRUNC, 0644), fde = open(fe, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fdo, 1);
    dup2(fde, 2);
    int rc = fn(n, argv_copy);
    fflush(stdout);
    fflush(stderr);
    dup2(so, 1);
    dup2(se, 2);
    close(so); close(se); close(fdo); close(fde);
    g_file_get_contents(fo, out, NULL, NULL);
    g_file_get_contents(fe, err, NULL, NULL);
    for (int i = 0; i < n; i++)
        g_free(v[i]);
    g_free(fo);
    g_free(fe);
    return rc;
}

static int run_cmd(const sd *s, int (*fn)(int, char **), char **out, char **err, ...)
{
    va_list ap;
    va_start(ap, err);
    int rc = run_cmdv(s, 1, fn, out, err, ap);
    va_end(ap);
    return rc;
}

/* The same for the commands that need no daemon (sim, recon, binary). */
static int run_local(const sd *s, int (*fn)(int, char **), char **out, char **err, ...)
{
    va_list ap;
    va_start(ap, err);
    int rc = run_cmdv(s, 0, fn, out, err, ap);
    va_end(ap);
    return rc;
}

static JsonNode *parse(const char *text)
{
    JsonParser *p = json_parser_new();
    JsonNode *n = NULL;
    if (text && json_parser_load_from_data(p, text, -1, NULL))
        n = json_node_copy(json_parser_get_root(p));
    g_object_unref(p);
    return n;
}

#endif
