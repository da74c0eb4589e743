/* web_fx.h - what test_web.c (and the web soak) need to look at
 * specklabd's web page (daemon/web.h) from outside: a plain HTTP/1.1
 * client on a socket (every read bounded by a deadline), PNGs decoded
 * with libpng, and headless Chromium (Debian's chromium) run with a
 * deadline.  Include after daemon_fx.h (proc_fx.h's fx_now, fx_spawn).
 */
#ifndef SL_WEB_FX_H
#define SL_WEB_FX_H

#include <arpa/inet.h>
#include <netinet/in.h>
#include <png.h>

/* One reply: status 0 when the connection ended without one (closed,
 * refused or timed out: why says which). */
typedef struct web_reply {
    int status;
    char type[128];
    char headers[4096];
    GByteArray *body;
    char why[160];
} web_reply;

static inline void web_reply_clear(web_reply *r)
{
    if (r->body)
        g_byte_array_free(r->body, TRUE);
    memset(r, 0, sizeof *r);
}

/* A TCP connection to ip:port (non-blocking connect, bounded); -1 with
 * errno set. */
static inline int web_connect(const char *ip, int port, double timeout_s)
{
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port)};
    if (inet_pton(AF_INET, ip, &a.sin_addr) != 1)
        return errno = EINVAL, -1;
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    if (fd < 0)
        return -1;
    if (connect(fd, (struct sockaddr *)&a, sizeof a) != 0 && errno != EINPROGRESS) {
        int e = errno;
        close(fd);
        return errno = e, -1;
    }
    struct pollfd pf = {fd, POLLOUT, 0};
    int err = 0;
    socklen_t len = sizeof err;
    if (poll(&pf, 1, (int)(timeout_s * 1000)) != 1 ||
        getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len) != 0 || err) {
        close(fd);
        return errno = err ? err : ETIMEDOUT, -1;
    }
    return fd;
}

static inline int web_send_all(int fd, const void *data, size_t n)
{
    const char *p = data;
    double end = fx_now() + 10;
    while (n > 0 && fx_now() < end) {
        ssize_t w = send(fd, p, n, MSG_NOSIGNAL);
        if (w < 0 && (errno == EAGAIN || errno == EINTR)) {
            struct pollfd pf = {fd, POLLOUT, 0};
            poll(&pf, 1, 100);
            continue;
        }
        if (w <= 0)
            return -1;
        p += w, n -= (size_t)w;
    }
    return n == 0 ? 0 : -1;
}

/* Read until the peer closes (or the deadline) and parse the reply. */
static inline void web_read_reply(int fd, web_reply *r, double timeout_s)
{
    GByteArray *in = g_byte_array_new();
    double end = fx_now() + timeout_s;
    char buf[16384];
    for (;;) {
        struct pollfd pf = {fd, POLLIN, 0};
        if (fx_now() >= end) {
            snprintf(r->why, sizeof r->why, "no end of reply within %.0f s", timeout_s);
            break;
        }
        if (poll(&pf, 1, 100) <= 0)
            continue;
        ssize_t n = recv(fd, buf, sizeof buf, 0);
        if (n < 0 && (errno == EAGAIN || errno == EINTR))
            continue;
        if (n <= 0) {
            if (n < 0)
                snprintf(r->why, sizeof r->why, "recv: %s", strerror(errno));
            break;
        }
        g_byte_array_append(in, (guint8 *)buf, (guint)n);
    }
    const char *data = (const char *)in->data;
    const char *sep = in->len ? g_strstr_len(data, in->len, "\r\n\r\n") : NULL;
    if (sep && sscanf(data, "HTTP/1.%*d %d", &r->status) == 1) {
        size_t hl = (size_t)(sep - data);
        snprintf(r->headers, sizeof r->headers, "%.*s", (int)MIN(hl, sizeof r->headers - 1), data);
        const char *ct = strcasestr(r->headers, "\r\nContent-Type: ");
        if (ct)
            sscanf(ct + 16, "%127[^\r]", r->type);
        r->body = g_byte_array_new();
        g_byte_array_append(r->body, (const guint8 *)sep + 4, (guint)(in->len - hl - 4));
    } else if (!r->why[0]) {
        snprintf(r->why, sizeof r->why, "%u bytes, no HTTP reply", in->len);
    }
    g_byte_array_free(in, TRUE);
}

/* METHOD path on ip:port with Connection: close. */
static inline int web_request(const char *ip, int port, const char *method, const char *path,
                              web_reply *r)
{
    memset(r, 0, sizeof *r);
    int fd = web_connect(ip, port, 5);
    if (fd < 0) {
        snprintf(r->why, sizeof r->why, "connect %s:%d: %s", ip, port, strerror(errno));
        return -1;
    }
    char req[1024];
    int n = snprintf(req, sizeof req, "%s %s HTTP/1.1\r\nHost: %s:%d\r\nConnection: close\r\n\r\n",
                     method, path, ip, port);
    if (web_send_all(fd, req, (size_t)n) == 0)
        web_read_reply(fd, r, 10);
    else
        snprintf(r->why, sizeof r->why, "send: %s", strerror(errno));
    close(fd);
    return r->status ? 0 : -1;
}

static inline int web_get(int port, const char *path, web_reply *r)
{
    return web_request("127.0.0.1", port, "GET", path, r);
}

/* The body as a JSON node (owned), NULL when it is not JSON. */
static inline JsonNode *web_json(const web_reply *r)
{
    if (!r->body)
        return NULL;
    char *text = g_strndup((const char *)r->body->data, r->body->len);
    JsonNode *n = json_from_string(text, NULL);
    g_free(text);
    return n;
}

/* Decode a whole PNG: 0 with its size, or -1 with libpng's reason. */
static inline int web_png_size(const guint8 *data, size_t n, int *w, int *h, char *why,
                               size_t nwhy)
{
    png_image im;
    memset(&im, 0, sizeof im);
    im.version = PNG_IMAGE_VERSION;
    *w = *h = 0;
    if (!png_image_begin_read_from_memory(&im, data, n)) {
        snprintf(why, nwhy, "libpng: %s", im.message);
        return -1;
    }
    im.format = PNG_FORMAT_GRAY;
    guint8 *px = g_malloc(PNG_IMAGE_SIZE(im));
    int ok = png_image_finish_read(&im, NULL, px, 0, NULL);
    if (!ok)
        snprintf(why, nwhy, "libpng: %s", im.message);
    *w = (int)im.width, *h = (int)im.height;
    g_free(px);
    png_image_free(&im);
    return ok ? 0 : -1;
}

/* ---- WebSocket (RFC 6455), enough for the event stream ---------------------- */

/* A client's end: the socket and what was read but not yet parsed. */
typedef struct web_ws {
    int fd;
    GByteArray *in;
} web_ws;

static inline void web_ws_close(web_ws *c)
{
    if (c->fd >= 0)
        close(c->fd);
    if (c->in)
        g_byte_array_free(c->in, TRUE);
    c->fd = -1;
    c->in = NULL;
}

/* Connect and upgrade path (origin NULL: no Origin header): 0, or -1
 * with the server's first line (or why) in why. */
static inline int web_ws_open(web_ws *c, int port, const char *path, const char *origin,
                              char *why, size_t nwhy)
{
    c->in = g_byte_array_new();
    c->fd = web_connect("127.0.0.1", port, 5);
    if (c->fd < 0) {
        snprintf(why, nwhy, "connect: %s", strerror(errno));
        web_ws_close(c);
        return -1;
    }
    char req[768], org[200] = "";
    if (origin)
        snprintf(org, sizeof org, "Origin: %s\r\n", origin);
    int n = snprintf(req, sizeof req, "GET %s HTTP/1.1\r\nHost: 127.0.0.1:%d\r\n"
                     "Upgrade: websocket\r\nConnection: Upgrade\r\n"
                     "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                     "Sec-WebSocket-Version: 13\r\n%s\r\n", path, port, org);
    GString *in = g_string_new(NULL);
    double end = fx_now() + 5;
    char ch;
    web_send_all(c->fd, req, (size_t)n);
    while (fx_now() < end && !g_str_has_suffix(in->str, "\r\n\r\n")) {
        struct pollfd pf = {c->fd, POLLIN, 0};
        if (poll(&pf, 1, 100) == 1 && recv(c->fd, &ch, 1, 0) == 1)
            g_string_append_c(in, ch);
        else if (pf.revents & (POLLHUP | POLLERR))
            break;
    }
    int ok = g_str_has_prefix(in->str, "HTTP/1.1 101");
    snprintf(why, nwhy, "%.*s", (int)strcspn(in->str, "\r"), in->str);
    g_string_free(in, TRUE);
    if (!ok)
        web_ws_close(c);
    return ok ? 0 : -1;
}

/* A masked client frame (payload up to 125 bytes). */
static inline int web_ws_send(web_ws *c, int opcode, const char *data, size_t n)
{
    guint8 hdr[6] = {(guint8)(0x80 | opcode), (guint8)(0x80 | n), 1, 2, 3, 4};
    if (n > 125)
        return -1;
    GByteArray *f = g_byte_array_new();
    g_byte_array_append(f, hdr, 6);
    for (size_t i = 0; i < n; i++) {
        guint8 b = (guint8)data[i] ^ hdr[2 + i % 4];
        g_byte_array_append(f, &b, 1);
    }
    int rc = web_send_all(c->fd, f->data, f->len);
    g_byte_array_free(f, TRUE);
    return rc;
}

/* Take the complete frames read so far: text messages counted (the last
 * kept in *last), pings answered, a close frame noted. */
static inline int web_ws_parse(web_ws *c, char **last, int *closed)
{
    int got = 0;
    while (c->in->len >= 2) {
        const guint8 *d = c->in->data;
        size_t len = d[1] & 127, off = 2;
        if (len == 126) {
            if (c->in->len < 4)
                break;
            len = (size_t)d[2] << 8 | d[3], off = 4;
        } else if (len == 127) {
            if (c->in->len < 10)
                break;
            for (len = 0; off < 10; off++)
                len = len << 8 | d[off];
        }
        if (c->in->len < off + len)
            break;
        int op = d[0] & 15;
        if (op == 1) {
            got++;
            if (last) {
                g_free(*last);
                *last = g_strndup((const char *)d + off, len);
            }
        } else if (op == 9) {
            web_ws_send(c, 10, (const char *)d + off, MIN(len, 125));
        } else if (op == 8) {
            *closed = 1;
        }
        g_byte_array_remove_range(c->in, 0, (guint)(off + len));
    }
    return got;
}

/* Read for up to timeout_s until at least `want` text messages came;
 * their count (all the complete ones read), *closed when the server
 * closed or the connection ended. */
static inline int web_ws_read(web_ws *c, int want, double timeout_s, char **last, int *closed)
{
    double end = fx_now() + timeout_s;
    int got = web_ws_parse(c, last, closed);
    while (got < want && !*closed && fx_now() < end) {
        struct pollfd pf = {c->fd, POLLIN, 0};
        guint8 buf[16384];
        if (poll(&pf, 1, 50) != 1)
            continue;
        ssize_t r = recv(c->fd, buf, sizeof buf, 0);
        if (r < 0 && (errno == EAGAIN || errno == EINTR))
            continue;
        if (r <= 0)
            *closed = 1;
        else
            g_byte_array_append(c->in, buf, (guint)r);
        got += web_ws_parse(c, last, closed);
    }
    return got;
}

/* ---- headless Chromium --------------------------------------------------------- */

/* Debian's chromium ($SL_CHROMIUM overrides); NULL when it is not there. */
static inline const char *web_chromium(void)
{
    static char path[PATH_MAX];
    const char *env = getenv("SL_CHROMIUM");
    if (env && *env)
        return access(env, X_OK) == 0 ? env : NULL;
    const char *dirs[] = {"/usr/bin", "/usr/local/bin", "/bin"};
    for (size_t i = 0; i < G_N_ELEMENTS(dirs); i++) {
        snprintf(path, sizeof path, "%s/chromium", dirs[i]);
        if (access(path, X_OK) == 0)
            return path;
    }
    return NULL;
}

/* Run chromium --headless on url with extra (e.g. "--dump-dom"), its
 * stdout into *out (may be NULL), within limit_s.  0 when it exited 0. */
static inline int web_run_chromium(const char *profile, const char *url, const char *extra1,
                                   const char *extra2, GString *out, double limit_s, char *why,
                                   size_t nwhy)
{
    const char *bin = web_chromium();
    char prof[PATH_MAX + 32];
    snprintf(prof, sizeof prof, "--user-data-dir=%s", profile);
    char *argv[] = {(char *)bin, "--headless", "--no-sandbox", "--disable-gpu",
                    "--no-first-run", "--disable-dev-shm-usage", prof,
                    "--virtual-time-budget=3000", (char *)extra1, (char *)extra2, NULL, NULL};
    int n = 8;
    if (extra1)
        n++;
    if (extra2)
        n++;
    argv[n] = (char *)url;
    fx_proc p;
    if (fx_spawn(&p, argv, NULL, NULL, NULL) != 0) {
        snprintf(why, nwhy, "cannot start %.200s", bin);
        return -1;
    }
    double end = fx_now() + limit_s;
    char buf[8192];
    for (;;) {
        struct pollfd pf = {p.out, POLLIN, 0};
        if (fx_now() >= end) {
            snprintf(why, nwhy, "%.200s did not finish within %.0f s", bin, limit_s);
            fx_stop(&p, SIGKILL, 5);
            return -1;
        }
        if (poll(&pf, 1, 100) <= 0)
            continue;
        ssize_t r = read(p.out, buf, sizeof buf);
        if (r <= 0)
            break;
        if (out)
            g_string_append_len(out, buf, r);
    }
    int st = 0;
    while (waitpid(p.pid, &st, WNOHANG) == 0 && fx_now() < end)
        fx_nap_ms(20);
    int rc = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    if (waitpid(p.pid, &st, WNOHANG) == 0)
        kill(p.pid, SIGKILL), waitpid(p.pid, &st, 0), rc = -1;
    close(p.out);
    if (rc != 0)
        snprintf(why, nwhy, "%.200s exited %d", bin, rc);
    return rc == 0 ? 0 : -1;
}

#endif
