/* test_daemon_clients.c - the fault matrix's misbehaving clients, each on
 * its own simulated bench (daemon_fx.h):
 *   idle_clients      64 connections that never send a line, opened
 *                     while a run acquires: `status` and `abort-run` from
 *                     a new client still work (the idlest connection is
 *                     closed for it, and told why), the run ends aborted
 *                     with its frames kept;
 *   idle_limit        a connection that sends nothing, or only part of a
 *                     line, is closed after client_idle_timeout_ms with an
 *                     `idle` line; a subscriber is never closed for it;
 *   busy_reply        64 subscribers hold every slot: `specklab daemon
 *                     status` is refused and prints the daemon's busy
 *                     reply (not "Broken pipe");
 *   ids_out_of_range  ids (and any integer) of 2^63 or more, or below
 *                     -2^63, get bad-request (json-glib would read 2^64-1
 *                     as -1); the extremes of the range are served.
 * Waits are on the daemon's own signals: replies, events, the `idle` line
 * and the end of the stream of a closed connection.
 */
#include "daemon_fx.h"
#include "matrix_fx.h"

#define NIDLE 64   /* the default max_clients */

/* ---- idle connections -------------------------------------------------------- */

BENCH_TEST(idle_clients, 90, NULL, NULL)
{
    dc *c = bench_client(b), *idle[NIDLE];
    char uuid[40], args[80];
    CHECK(c && bench_wait_camera(b, c, 20) == 0, "no daemon or no camera");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    CHECK(mx_start(b, c, "{\"screen\": 2, \"mask\": 0, \"frames\": 3000, \"reconstruct\": "
                   "\"none\"}", uuid) == 0, "start-run");
    mx_want w = {.run = uuid, .state = "acquiring", .frames = 10};
    CHECK(mx_poll_status(b, c, mx_is_current, &w, 30), "status never showed %s acquiring", uuid);
    for (int i = 0; i < NIDLE; i++)
        CHECK((idle[i] = bench_client(b)) != NULL, "connect %d: %s", i, strerror(errno));
    /* A newcomer is served at once: its status, then the abort. */
    dc *q = bench_client(b);
    CHECK(q, "connect: %s", strerror(errno));
    JsonNode *r = keep(b, dc_call(q, "status", NULL, 5));
    CHECK(jok(r) && !g_strcmp0(js(r, "result.current_run"), uuid) &&
              ji(r, "result.clients") <= 64,
          "status beside %d idle connections: %s", NIDLE, jtext(r));
    snprintf(args, sizeof args, "{\"run\": \"%s\"}", uuid);
    r = keep(b, dc_call(q, "abort-run", args, 30));
    CHECK(jok(r) && !g_strcmp0(js(r, "result.state"), "aborted"), "abort-run: %s", jtext(r));
    JsonNode *e = mx_wait_end(b, c, uuid, 30, NULL);
    CHECK(e && !g_strcmp0(js(e, "state"), "aborted"), "end: %s", jtext(e));
    mx_seen v;
    if (mx_check_run(t, b, uuid, CATALOG_ABORTED, "aborted by request", &v))
        return;
    CHECK(v.frames >= 10, "%d frames kept", v.frames);
    /* The oldest idle connection made room, and was told so. */
    JsonNode *why = keep(b, dc_read(idle[0], 5));
    CHECK(why && !g_strcmp0(js(why, "error.code"), "idle") && jnull(why, "id") &&
              dc_read(idle[0], 5) == NULL && idle[0]->eof,
          "the idlest connection: %s, then %s", jtext(why),
          idle[0]->eof ? "closed" : "still open");
}

/* A short limit: 400 ms. */
BENCH_TEST(idle_limit, 60, NULL, "[daemon]\nclient_idle_timeout_ms=400\n")
{
    dc *quiet = bench_client(b), *slow = bench_client(b), *sub = bench_client(b);
    CHECK(quiet && slow && sub, "connect: %s", strerror(errno));
    JsonNode *r = keep(b, dc_call(sub, "subscribe", NULL, 5));
    CHECK(jok(r), "subscribe: %s", jtext(r));
    /* Part of a request, never finished: a trickling client is idle too. */
    CHECK(dc_send_raw(slow, "{\"id\": 1, \"cmd\": \"sta", 21) == 0, "send");
    double t0 = fx_now();
    JsonNode *a = keep(b, dc_read(quiet, 10)), *s = keep(b, dc_read(slow, 10));
    double dt = fx_now() - t0;
    CHECK(a && !g_strcmp0(js(a, "error.code"), "idle") && strstr(mx_str(js(a, "error.message")),
                                                                 "client_idle_timeout_ms"),
          "the quiet connection: %s", jtext(a));
    CHECK(s && !g_strcmp0(js(s, "error.code"), "idle"), "the trickling one: %s", jtext(s));
    CHECK(dc_read(quiet, 5) == NULL && quiet->eof && dc_read(slow, 5) == NULL && slow->eof,
          "not closed after the idle line");
    CHECK(dt < 5, "closed after %.1f s for a 0.4 s limit", dt);
    /* The subscriber outlived them (it waits for events) and is served. */
    r = keep(b, dc_call(sub, "status", NULL, 5));
    CHECK(jok(r) && ji(r, "result.clients") == 1, "the subscriber: %s", jtext(r));
}

/* ---- every slot taken --------------------------------------------------------- */

/* Run argv to its end within limit_s; its exit status (-1: killed), its
 * stderr in err (NUL-ended). */
static int run_cli(char *const argv[], const char *errlog, char *err, size_t n, double limit_s)
{
    fx_proc p;
    int st = 0;
    if (fx_spawn(&p, argv, errlog, NULL, NULL) != 0)
        return -1;
    double end = fx_now() + limit_s;
    pid_t w;
    while ((w = waitpid(p.pid, &st, WNOHANG)) == 0 && fx_now() < end)
        fx_nap_ms(10);
    if (w == 0) {
        kill(p.pid, SIGKILL);
        waitpid(p.pid, &st, 0);
    }
    close(p.out);
    gchar *text = NULL;
    g_file_get_contents(errlog, &text, NULL, NULL);
    snprintf(err, n, "%s", text ? text : "");
    g_free(text);
    return w > 0 && WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

BENCH_TEST(busy_reply, 60, NULL, NULL)
{
    char bin[PATH_MAX], errlog[300], err[2048];
    for (int i = 0; i < NIDLE; i++) {
        dc *s = bench_client(b);
        JsonNode *r = s ? keep(b, dc_call(s, "subscribe", NULL, 5)) : NULL;
        CHECK(jok(r), "subscriber %d: %s", i, jtext(r));
    }
    fx_bin(bin, sizeof bin, "specklab");
    snprintf(errlog, sizeof errlog, "%s/cli.err", b->dir);
    char *argv[] = {bin, "daemon", "status", "--socket", b->sock, NULL};
    int rc = run_cli(argv, errlog, err, sizeof err, 20);
    CHECK(rc > 0 && strstr(err, "too many clients (max_clients = 64)") &&
              !strstr(err, "Broken pipe"),
          "specklab daemon status with every slot taken: exit %d, stderr: %s", rc, err);
}

/* ---- ids ---------------------------------------------------------------------- */

/* Send line, read the reply (kept). */
static JsonNode *raw_call(bench *b, dc *c, const char *line)
{
    if (dc_send_raw(c, line, strlen(line)) != 0)
        return NULL;
    return keep(b, dc_wait_reply(c, -1, 5));
}

BENCH_TEST(ids_out_of_range, 60, NULL, NULL)
{
    dc *c = bench_client(b);
    CHECK(c, "connect");
    static const char *const refused[] = {
        "{\"id\": 18446744073709551615, \"cmd\": \"status\"}\n",
        "{\"id\": 9223372036854775808, \"cmd\": \"status\"}\n",
        "{ \"id\" : 36893488147419103232, \"cmd\": \"status\"}\n",
        "{\"cmd\": \"status\", \"id\": -9223372036854775809}\n"};
    for (size_t i = 0; i < G_N_ELEMENTS(refused); i++) {
        JsonNode *r = raw_call(b, c, refused[i]);
        CHECK(r && !jok(r) && !g_strcmp0(js(r, "error.code"), "bad-request") &&
                  jnull(r, "id") && strstr(mx_str(js(r, "error.message")), "id must be"),
              "%s -> %s", refused[i], jtext(r));
    }
    /* Any integer: an argument out of range is refused, its id echoed. */
    JsonNode *r = raw_call(b, c, "{\"id\": 5, \"cmd\": \"runs\", \"args\": {\"limit\": "
                                 "18446744073709551617}}\n");
    CHECK(r && !jok(r) && ji(r, "id") == 5 && !g_strcmp0(js(r, "error.code"), "bad-request") &&
              strstr(mx_str(js(r, "error.message")), "18446744073709551617"),
          "limit 2^64+1: %s", jtext(r));
    /* The range's ends are ids like any other; digits in a string or a
     * float are not integers. */
    r = raw_call(b, c, "{\"id\": 9223372036854775807, \"cmd\": \"status\"}\n");
    CHECK(jok(r) && ji(r, "id") == G_MAXINT64, "id 2^63-1: %s", jtext(r));
    r = raw_call(b, c, "{\"id\": -9223372036854775808, \"cmd\": \"status\"}\n");
    CHECK(jok(r) && ji(r, "id") == G_MININT64, "id -2^63: %s", jtext(r));
    r = raw_call(b, c, "{\"id\": 6, \"cmd\": \"runs\", \"args\": {\"state\": "
                       "\"18446744073709551615\", \"limit\": 3}}\n");
    CHECK(r && ji(r, "id") == 6 && !strstr(mx_str(js(r, "error.message")), "-2^63"),
          "digits in a string: %s", jtext(r));
}

TC_MAIN(TC_CASE(idle_clients), TC_CASE(idle_limit), TC_CASE(busy_reply),
        TC_CASE(ids_out_of_range))
