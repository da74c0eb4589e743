/* test_web.c - specklabd's live web page (daemon/web.h) on the simulated
 * bench (daemon_fx.h: fake stage, fake camera, daemon in a private
 * network namespace).
 *
 *   live_page      [web] on 127.0.0.1, a port the kernel picks (the
 *                  daemon's READY line names it).  During an acquisition:
 *                  /api/status says the run is acquiring with its counters
 *                  and the wheels' contents; / is the page, self-contained
 *                  (no http:// or https:// reference at all) with its CSP;
 *                  /api/frame.png and /api/powspec.png are PNGs of the
 *                  frame's size (decoded whole with libpng); unknown paths
 *                  404, other methods 405, a bad stretch 400.  The event
 *                  stream pushes at the rate asked (5 Hz, then 20 Hz),
 *                  lives past the 10 s request deadline, and turns away
 *                  another site's Origin.  Headless
 *                  Chromium loads the page twice: the frame counter it
 *                  shows (#acquired, filled by the page's own script)
 *                  increases; a screenshot is kept in
 *                  BUILD/tests/artefacts/web-page.png (its path printed).
 *                  Then abuse: an oversized header, garbage, requests cut
 *                  off mid-way, more connections than allowed (503): the
 *                  page and the control socket still answer, the run
 *                  still acquires and loses nothing.
 *   listen_policy  a non-loopback address without allow_remote stops the
 *                  daemon at start (exit 2, naming the key; also --web);
 *                  with port 0 the READY line gives the bound URL; bound
 *                  to 127.0.0.1 the page is not reachable on the host's
 *                  other address (10.11.12.13 added to lo); with
 *                  allow_remote = yes and 0.0.0.0 it is, and the log warns.
 *   view_fft       the view's power spectrum (daemon/webfft.c on FFTW,
 *                  compiled in here): a tilted cosine's power lands at its
 *                  frequency and its mirror, centred as the page draws it,
 *                  with the DC and tone levels |F|^2 predicts, on even and
 *                  odd frame sizes.
 * Chromium missing is a failure naming the package (scripts/install-deps
 * installs it), not a skip.
 */
#include "daemon_fx.h"
#include "web_fx.h"

#include "../../daemon/webfft.c"   /* no daemon library to link: the one file */

/* The page's port, from the daemon's READY line (" web=http://H:P/"). */
static int web_port(const bench *b)
{
    const char *u = strstr(b->ready, " web=http://127.0.0.1:");
    int port = 0;
    return u && sscanf(u + 22, "%d/", &port) == 1 ? port : -1;
}
#define CAM_SIZE 64

/* The #acquired counter of a DOM Chromium dumped; -1 when absent. */
static long dom_acquired(const char *dom)
{
    const char *p = dom ? strstr(dom, "id=\"acquired\">") : NULL;
    char *end = NULL;
    long v = p ? strtol(p + 14, &end, 10) : -1;
    return p && end != p + 14 ? v : -1;
}

static int has(const char *hay, const char *needle)
{
    return hay && needle && strstr(hay, needle) != NULL;
}

/* GET path until its status is not 503 (the view's first render), 5 s. */
static int get_ready(int port, const char *path, web_reply *r)
{
    double end = fx_now() + 5;
    for (;;) {
        web_reply_clear(r);
        web_get(port, path, r);
        if (r->status != 503 || fx_now() >= end)
            return r->status;
        fx_nap_ms(100);
    }
}

/* A PNG endpoint: 200, image/png, a whole PNG of the frame's size. */
static void check_png(tc *t, int port, const char *path)
{
    web_reply r = {0};
    char why[256] = "";
    int w = 0, h = 0;
    int st = get_ready(port, path, &r);
    int ok = st == 200 && has(r.type, "image/png") &&
             web_png_size(r.body->data, r.body->len, &w, &h, why, sizeof why) == 0;
    web_reply_clear(&r);
    CHECK(ok && w == CAM_SIZE && h == CAM_SIZE, "%s: status %d, %dx%d (%s%s)", path, st, w, h,
          why, r.why);
}

static void check_status_json(tc *t, bench *b, const char *uuid)
{
    web_reply r = {0};
    web_get(web_port(b), "/api/status", &r);
    JsonNode *s = keep(b, web_json(&r));
    int st = r.status;
    char type[128];
    snprintf(type, sizeof type, "%s", r.type);
    web_reply_clear(&r);
    CHECK(st == 200 && has(type, "application/json") && s, "/api/status: %d %s", st, type);
    CHECK(has(js(s, "run.uuid"), uuid) && has(js(s, "run.state"), "acquiring") &&
              ji(s, "run.frames_acquired") > 0 && ji(s, "run.frames_requested") == 2000 &&
              ji(s, "run.frames_failed") >= 0 && ji(s, "run.packets_missing") >= 0,
          "/api/status run: %s", jtext(jget(s, "run")));
    CHECK(has(js(s, "stage.wheels.0.holds"), "screen1") &&
              has(js(s, "stage.wheels.1.holds"), "full") &&
              has(js(s, "stage.wheels.1.slots.1.name"), "nrm17") &&
              has(js(s, "camera.serial"), "SPECKLE01"),
          "/api/status stage/camera: %s", jtext(jget(s, "stage")));
}

static void check_page_and_errors(tc *t, int port)
{
    web_reply r = {0};
    web_get(port, "/", &r);
    char *page = r.body ? g_strndup((const char *)r.body->data, r.body->len) : NULL;
    int st = r.status, csp = has(r.headers, "Content-Security-Policy: default-src 'none'");
    web_reply_clear(&r);
    int self = page && !has(page, "http://") && !has(page, "https://") && !has(page, "src=\"//");
    int ok = st == 200 && csp && has(page, "id=\"acquired\"") && self;
    g_free(page);
    CHECK(ok, "/: status %d, CSP %d, self-contained %d", st, csp, self);
    const struct {
        const char *method, *path;
        int status;
    } bad[] = {{"GET", "/nope", 404},        {"GET", "/api/status/x", 404},
               {"GET", "/api/../etc/passwd", 404}, {"POST", "/api/status", 405},
               {"DELETE", "/", 405},          {"GET", "/api/frame.png?stretch=x", 400}};
    /* another site's name for 127.0.0.1 (DNS rebinding) */
    int fd = web_connect("127.0.0.1", port, 5);
    const char *rebind = "GET /api/status HTTP/1.1\r\nHost: evil.example:8080\r\n\r\n";
    memset(&r, 0, sizeof r);
    if (fd >= 0 && web_send_all(fd, rebind, strlen(rebind)) == 0)
        web_read_reply(fd, &r, 10);
    if (fd >= 0)
        close(fd);
    st = r.status;
    web_reply_clear(&r);
    CHECK(st == 421, "Host: evil.example answered %d, expected 421", st);
    for (size_t i = 0; i < G_N_ELEMENTS(bad); i++) {
        web_request("127.0.0.1", port, bad[i].method, bad[i].path, &r);
        st = r.status;
        web_reply_clear(&r);
        CHECK(st == bad[i].status, "%s %s: %d, expected %d", bad[i].method, bad[i].path, st,
              bad[i].status);
    }
}

/* Twice the page's counter, then a screenshot kept as an artefact. */
static void check_chromium(tc *t, bench *b)
{
    char url[64], profile[300], why[256] = "", shot[PATH_MAX], arg[PATH_MAX + 16];
    snprintf(url, sizeof url, "http://127.0.0.1:%d/", web_port(b));
    snprintf(profile, sizeof profile, "%s/chromium", b->dir);
    CHECK(web_chromium(), "chromium is not installed: the web page test needs Debian's "
          "chromium package (scripts/install-deps installs it)");
    long seen[2];
    for (int i = 0; i < 2; i++) {
        GString *dom = g_string_new(NULL);
        int rc = web_run_chromium(profile, url, "--dump-dom", NULL, dom, 40, why, sizeof why);
        seen[i] = dom_acquired(dom->str);
        int acq = has(dom->str, "id=\"state\">acquiring<");
        g_string_free(dom, TRUE);
        CHECK(rc == 0 && seen[i] > 0 && acq, "chromium --dump-dom %d: %s; #acquired %ld, "
              "state acquiring %d", i + 1, why, seen[i], acq);
    }
    CHECK(seen[1] > seen[0], "the page's frame counter did not increase: %ld then %ld", seen[0],
          seen[1]);
    char exe[PATH_MAX] = "";
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    exe[n > 0 ? n : 0] = 0;
    snprintf(shot, sizeof shot, "%s/artefacts", dirname(exe));
    g_mkdir_with_parents(shot, 0755);
    strncat(shot, "/web-page.png", sizeof shot - strlen(shot) - 1);
    unlink(shot);
    snprintf(arg, sizeof arg, "--screenshot=%s", shot);
    int rc = web_run_chromium(profile, url, arg, "--window-size=1280,1100", NULL, 40, why,
                              sizeof why);
    gchar *png = NULL;
    gsize len = 0;
    int w = 0, h = 0;
    char pwhy[128] = "";
    int ok = rc == 0 && g_file_get_contents(shot, &png, &len, NULL) &&
             web_png_size((guint8 *)png, len, &w, &h, pwhy, sizeof pwhy) == 0;
    g_free(png);
    CHECK(ok && w == 1280, "screenshot %s: %s %s (%dx%d)", shot, why, pwhy, w, h);
    printf("test_web: page screenshot (artefact): %s; counter %ld then %ld\n", shot, seen[0],
           seen[1]);
    fflush(stdout);
}

/* The event stream: pushed at the viewer's rate; another site's page is
 * turned away.  Leaves the stream open in *ws (checked again at the end). */
static void check_events(tc *t, int port, const char *uuid, web_ws *ws)
{
    char why[200], *last = NULL;
    int closed = 0;
    web_ws evil = {-1, NULL};
    int n = web_ws_open(&evil, port, "/api/events?hz=5", "http://evil.example", why,
                        sizeof why) == 0 ? web_ws_read(&evil, 1, 2, NULL, &closed) : 0;
    int refused = evil.fd < 0 || (n == 0 && closed);
    web_ws_close(&evil);
    CHECK(refused, "a foreign Origin got %d updates", n);
    char origin[64];
    snprintf(origin, sizeof origin, "http://127.0.0.1:%d", port);
    CHECK(web_ws_open(ws, port, "/api/events?hz=5", origin, why, sizeof why) == 0,
          "/api/events: %s", why);
    double t0 = fx_now();
    closed = 0;
    n = web_ws_read(ws, 4, 3, &last, &closed);
    double dt = fx_now() - t0;
    JsonNode *s = last ? json_from_string(last, NULL) : NULL;
    int ok = n >= 4 && !closed && dt < 2 && has(js(s, "run.uuid"), uuid);
    if (s)
        json_node_unref(s);
    g_free(last);
    CHECK(ok, "%d updates in %.2f s (5 Hz asked), closed %d", n, dt, closed);
}

/* After the rest and past the 10 s request deadline (t_open + 11 s):
 * still open, and {"hz": 20} speeds it up. */
static void check_events_later(tc *t, web_ws *ws, double t_open)
{
    int closed = 0, n = 0;
    /* At least one read: the checks before may already have taken the
     * stream past its 11 s (a loaded machine, Chromium). */
    do
        n += web_ws_read(ws, 1000, 0.5, NULL, &closed);
    while (fx_now() < t_open + 11 && !closed);
    const char *hz = "{\"hz\": 20}";
    web_ws_send(ws, 1, hz, strlen(hz));
    for (double end = fx_now() + 1; fx_now() < end && !closed;)   /* drain at 5 Hz */
        web_ws_read(ws, 1000, 0.3, NULL, &closed);
    double t0 = fx_now();
    int m = closed ? 0 : web_ws_read(ws, 10, 3, NULL, &closed);
    double dt = fx_now() - t0;
    CHECK(n >= 1 && m >= 10 && dt < 1.2 && !closed, "event stream later: %d updates, then %d "
          "at 20 Hz in %.2f s (closed %d)", n, m, dt, closed);
}

/* Bad clients: none of them may hurt the page, the socket or the run. */
static void abuse(tc *t, int port)
{
    web_reply r = {0};
    /* a 200 KiB header line: libsoup refuses (400) or closes */
    GString *big = g_string_new("GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: ");
    for (int i = 0; i < 200 * 1024; i++)
        g_string_append_c(big, 'a');
    g_string_append(big, "\r\n\r\n");
    const char *sends[] = {big->str, "\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03garbage\r\n\r\n",
                           "GET / HTTP/9.9\r\n\r\n", "GET\r\n\r\n",
                           "POST /api/status HTTP/1.1\r\nHost: x\r\nContent-Length: 99999999\r\n\r\nabc"};
    for (size_t i = 0; i < G_N_ELEMENTS(sends); i++) {
        int fd = web_connect("127.0.0.1", port, 5);
        CHECK(fd >= 0, "connect: %s", strerror(errno));
        memset(&r, 0, sizeof r);
        web_send_all(fd, sends[i], strlen(sends[i]));
        shutdown(fd, SHUT_WR);
        web_read_reply(fd, &r, 15);
        close(fd);
        int st = r.status;
        web_reply_clear(&r);
        CHECK(st == 0 || (st >= 400 && st < 600), "bad request %zu answered %d", i, st);
    }
    g_string_free(big, TRUE);
    /* cut off mid-request and mid-reply */
    for (int i = 0; i < 20; i++) {
        int fd = web_connect("127.0.0.1", port, 5);
        CHECK(fd >= 0, "connect: %s", strerror(errno));
        const char *half = i % 2 ? "GET /api/powspec.png HTTP/1.1\r\nHo" : "GET / HTTP/1.1\r\n\r\n";
        web_send_all(fd, half, strlen(half));
        struct linger lg = {1, 0};   /* close with a reset */
        setsockopt(fd, SOL_SOCKET, SO_LINGER, &lg, sizeof lg);
        close(fd);
    }
    /* more idle connections than allowed (32): the surplus gets 503 */
    int fds[40], refused = 0;
    for (int i = 0; i < 40; i++)
        fds[i] = web_connect("127.0.0.1", port, 5);
    fx_nap_ms(300);
    for (int i = 0; i < 40; i++) {
        memset(&r, 0, sizeof r);
        struct pollfd pf = {fds[i], POLLIN, 0};
        if (fds[i] >= 0 && poll(&pf, 1, 0) == 1) {
            web_read_reply(fds[i], &r, 2);
            refused += r.status == 503;
        }
        web_reply_clear(&r);
    }
    for (int i = 0; i < 40; i++)
        if (fds[i] >= 0)
            close(fds[i]);
    CHECK(refused >= 5, "%d of 40 idle connections refused (limit 32)", refused);
    for (double end = fx_now() + 5; fx_now() < end;) {   /* the slots come back */
        web_get(port, "/api/status", &r);
        int st = r.status;
        web_reply_clear(&r);
        if (st == 200)
            return;
        fx_nap_ms(100);
    }
    CHECK(0, "/api/status does not answer after the abuse");
}

BENCH_TEST(live_page, 90, NULL, "[web]\nlisten=127.0.0.1:0\n")
{
    dc *c = bench_client(b);
    int port = web_port(b);
    CHECK(port > 0, "no web=http://127.0.0.1:PORT/ in READY: %s", b->ready);
    CHECK(c, "cannot connect to %s", b->sock);
    CHECK(bench_wait_camera(b, c, 20) == 0, "the daemon never reported the camera");
    JsonNode *r = keep(b, dc_call(c, "subscribe", NULL, 5));
    CHECK(jok(r), "subscribe: %s", jtext(r));
    r = keep(b, dc_call(c, "start-run", "{\"screen\": 1, \"mask\": \"full\", \"frames\": 2000, "
                        "\"reconstruct\": \"none\"}", 5));
    CHECK(jok(r), "start-run: %s", jtext(r));
    char uuid[40];
    snprintf(uuid, sizeof uuid, "%s", js(r, "result.run"));
    CHECK(dc_wait_progress(c, uuid, 30, 20) >= 30, "no progress to 30 frames");
    check_status_json(t, b, uuid);
    if (t->failed)
        return;
    web_ws ws = {-1, NULL};
    double t_open = fx_now();
    check_events(t, port, uuid, &ws);
    if (t->failed) {
        web_ws_close(&ws);
        return;
    }
    check_page_and_errors(t, port);
    if (t->failed)
        return;
    check_png(t, port, "/api/frame.png?stretch=log");
    if (!t->failed)
        check_png(t, port, "/api/powspec.png");
    if (!t->failed)
        check_chromium(t, b);
    if (!t->failed)
        abuse(t, port);
    if (!t->failed)
        check_events_later(t, &ws, t_open);
    web_ws_close(&ws);
    if (t->failed)
        return;
    check_status_json(t, b, uuid);   /* still acquiring, still answering */
    if (t->failed)
        return;
    r = keep(b, dc_call(c, "status", NULL, 5));
    CHECK(jok(r) && has(js(r, "result.current_state"), "acquiring"), "status after the abuse: %s",
          jtext(r));
    /* the control socket's status names the page (specklab daemon status) */
    char want[64];
    snprintf(want, sizeof want, "http://127.0.0.1:%d/", port);
    CHECK(!g_strcmp0(js(r, "result.web"), want), "status web %s, want %s", js(r, "result.web"),
          want);
    char args[80];
    snprintf(args, sizeof args, "{\"run\": \"%s\"}", uuid);
    r = keep(b, dc_call(c, "abort-run", args, 15));
    CHECK(jok(r), "abort-run: %s", jtext(r));
    catalog_run cr;
    char msg[512];
    CHECK(fx_catalog_run(b, uuid, &cr, msg, sizeof msg) == 0, "%s", msg);
    int failed = cr.frames_failed, acquired = cr.frames_acquired;
    catalog_run_clear(&cr);
    CHECK(failed == 0 && acquired > 100, "the run kept %d frames, %d damaged", acquired, failed);
    gchar *log = NULL;
    g_file_get_contents(b->dlog, &log, NULL, NULL);
    int clean = log && !strstr(log, "CRITICAL") && !strstr(log, "WARNING");
    char first[200] = "";
    const char *bad = log ? strstr(log, "CRITICAL") : NULL;
    bad = bad ? bad : log ? strstr(log, "WARNING") : NULL;
    if (bad)
        snprintf(first, sizeof first, "%.180s", bad);
    g_free(log);
    CHECK(clean, "the daemon's log has a GLib warning or critical: %s", first);
}

/* specklabd on conf (+ one more argument pair): READY's line, or the exit
 * status when it stopped before READY (ready 0). */
static int daemon_try(bench *b, const char *arg1, const char *arg2, char *line, size_t n,
                      int *ready)
{
    char bin[PATH_MAX];
    char *argv[] = {bin, "--config", b->conf, "--foreground", (char *)arg1, (char *)arg2, NULL};
    fx_bin(bin, sizeof bin, "specklabd");
    *ready = 0;
    line[0] = 0;
    if (fx_spawn(&b->daemon, argv, b->dlog, NULL, NULL) != 0)
        return -1;
    if (fx_wait_ready(&b->daemon, line, n, 20) == 0) {
        *ready = 1;
        return 0;
    }
    return fx_stop(&b->daemon, SIGTERM, 10);
}

static int write_conf(bench *b, const char *web)
{
    FILE *f = fopen(b->conf, "w");
    if (!f)
        return -1;
    fprintf(f, "[paths]\ndata_dir=%s\n[daemon]\nsocket=%s\n[web]\n%s\n", b->data, b->sock, web);
    truncate(b->dlog, 0);
    return fclose(f);
}

static int log_has(const bench *b, const char *needle)
{
    gchar *text = NULL;
    int hit = g_file_get_contents(b->dlog, &text, NULL, NULL) && strstr(text, needle);
    g_free(text);
    return hit;
}

/* Start with conf web, READY expected: the port of its web=URL. */
static int start_web(tc *t, bench *b, const char *web, const char *url_prefix)
{
    char line[512];
    int ready = 0;
    if (write_conf(b, web) != 0)
        return -1;
    daemon_try(b, NULL, NULL, line, sizeof line, &ready);
    const char *u = strstr(line, " web=");
    int port = 0;
    if (!ready || !u || !g_str_has_prefix(u + 5, url_prefix) ||
        sscanf(u + 5 + strlen(url_prefix), "%d/", &port) != 1 || port <= 0) {
        tc_note(t, 0, __FILE__, __LINE__, "READY web=", "'%s' gave READY '%s'", web, line);
        return -1;
    }
    return port;
}

static void listen_policy_run(tc *t)
{
    bench b_, *b = &b_;
    char line[512];
    int ready = 0;
    CHECK(bench_init(b) == 0, "bench_init");
    /* refused at start, naming what would allow it */
    int st = write_conf(b, "listen=0.0.0.0:8080") == 0
                 ? daemon_try(b, NULL, NULL, line, sizeof line, &ready) : -1;
    int named = log_has(b, "allow_remote");
    if (ready || st != 2 || !named)
        bench_down(b, 1);
    CHECK(!ready && st == 2 && named, "listen=0.0.0.0 without allow_remote: ready %d, exit %d, "
          "allow_remote named %d", ready, st, named);
    st = write_conf(b, "") == 0 ? daemon_try(b, "--web", "10.1.2.3:0", line, sizeof line, &ready)
                                : -1;
    named = log_has(b, "--web-allow-remote");
    if (ready || st != 2 || !named)
        bench_down(b, 1);
    CHECK(!ready && st == 2 && named, "--web 10.1.2.3:0: ready %d, exit %d, option named %d",
          ready, st, named);
    /* another address of this host, where a loopback page must not be */
    int ip = system("ip addr add 10.11.12.13/32 dev lo 2>/dev/null");
    int port = ip == 0 ? start_web(t, b, "listen=127.0.0.1:0", "http://127.0.0.1:") : -1;
    web_reply r = {0};
    int local = port > 0 && web_get(port, "/api/status", &r) == 0 && r.status == 200;
    web_reply_clear(&r);
    int fd = port > 0 ? web_connect("10.11.12.13", port, 2) : -1, e = errno;
    if (fd >= 0)
        close(fd);
    int stop = fx_stop(&b->daemon, SIGTERM, 20);
    if (t->failed || ip != 0 || !local || fd >= 0 || e != ECONNREFUSED || stop != 0)
        bench_down(b, 1);
    CHECK(!t->failed && ip == 0 && local && fd < 0 && e == ECONNREFUSED && stop == 0,
          "loopback page: ip addr %d, port %d, local %d, via 10.11.12.13: %s, exit %d", ip, port,
          local, fd >= 0 ? "connected" : strerror(e), stop);
    /* consented: reachable there, and the log says so */
    port = start_web(t, b, "listen=0.0.0.0:0\nallow_remote=yes", "http://0.0.0.0:");
    int remote = port > 0 && web_request("10.11.12.13", port, "GET", "/api/status", &r) == 0 &&
                 r.status == 200;
    web_reply_clear(&r);
    int warned = log_has(b, "non-loopback");
    stop = fx_stop(&b->daemon, SIGTERM, 20);
    bench_down(b, t->failed || !remote || !warned || stop != 0);
    CHECK(!t->failed && remote && warned && stop == 0, "allow_remote=yes on 0.0.0.0: port %d, "
          "reachable %d, warned %d, exit %d", port, remote, warned, stop);
}

TEST(listen_policy) { fx_in_netns(t, listen_policy_run, 90); }

/* cos(2 pi (3x/w + 5y/h)) on a w x h frame: power at (+-3, +-5) around
 * (w/2, h/2), DC (10 w h)^2, the tone (w h / 2)^2 each, elsewhere ~0. */
static int tone_lands(int w, int h, char *why, size_t n)
{
    float *img = g_new(float, w * h), *out = g_new(float, w * h);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            img[y * w + x] = (float)(10 + cos(2 * G_PI * (3.0 * x / w + 5.0 * y / h)));
    webps *ps = webps_new(w, h);
    webps_add(ps, img);
    webps_add(ps, img);
    int ok = ps && webps_count(ps) == 2 && webps_log_mean(ps, out);
    float zero = out[(h / 2) * w + w / 2], tone = out[(h / 2 + 5) * w + w / 2 + 3];
    float mirror = out[(h / 2 - 5) * w + w / 2 - 3], other = out[(h / 2 + 5) * w + w / 2 - 3];
    webps_free(ps);
    g_free(img);
    g_free(out);
    ok = ok && fabs(zero - 2 * log10(10.0 * w * h)) < 1e-4 &&
         fabs(tone - 2 * log10(w * h / 2.0)) < 1e-4 && fabs(mirror - tone) < 1e-4 &&
         other < tone - 10;
    snprintf(why, n, "%dx%d: log10 power DC %.4f, tone %.4f, mirror %.4f, elsewhere %.4f", w,
             h, zero, tone, mirror, other);
    return ok;
}

TEST(view_fft)
{
    char why[160];
    CHECK(tone_lands(48, 40, why, sizeof why), "%s", why);
    CHECK(tone_lands(33, 27, why, sizeof why), "%s", why);
    CHECK(!webps_new(1, 40) && !webps_new(40, 1), "a 1-pixel side was accepted");
}

TC_MAIN(TC_CASE(live_page), TC_CASE(listen_policy), TC_CASE(view_fft))
