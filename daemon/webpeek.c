/* webpeek.c - a connection's request head, read (MSG_PEEK: left in the
 * socket) and checked before libsoup sees it.
 *
 * Why: libsoup 3.2 (Debian 12) leaks the request target of every request
 * whose body encoding it does not recognise (a Content-Length that is not
 * a number, two of them, an unknown Transfer-Encoding: found by
 * fuzz_http), up to its 100 KiB header limit each time, so a client could
 * grow the daemon's memory at will.  The page never takes a request body,
 * so a head that announces one is refused here: Content-Length other than
 * a single "0" (413), any Transfer-Encoding or folded header line (400).
 * Heads are limited to WEB_HEAD_MAX bytes (431).  What passes is handed to
 * libsoup untouched, still unread in the socket.
 *
 * Waiting: the first data is waited for on the socket; an incomplete head
 * is looked at again every PEEK_RETRY_MS (the data stays readable, so a
 * readiness source would spin) until it is complete or the connection's
 * request deadline (web.c) shuts the socket.
 */
#define _GNU_SOURCE
#include "webint.h"

#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>

#define PEEK_RETRY_MS 10

struct webpeek {
    web *w;
    GIOStream *io;        /* a reference while peeking */
    GSocket *s;
    GSource *src;         /* the first readiness */
    guint timer;          /* the retries */
};

static void peek_end(webpeek *p)
{
    if (p->src) {
        g_source_destroy(p->src);
        g_source_unref(p->src);
    }
    if (p->timer)
        g_source_remove(p->timer);
    g_object_unref(p->io);
    g_free(p);
}

static void refuse_head(webpeek *p, int code, const char *phrase, const char *why)
{
    char buf[256];
    int n = snprintf(buf, sizeof buf, "HTTP/1.1 %d %s\r\nContent-Type: text/plain\r\n"
                     "Content-Length: %zu\r\nConnection: close\r\n\r\n%s\n", code, phrase,
                     strlen(why) + 1, why);
    g_socket_send(p->s, buf, (gsize)n, NULL, NULL);
    g_io_stream_close(p->io, NULL, NULL);
}

/* One header line (no CR LF) of the head: 0 fine, else the status. */
static int check_line(const char *line, size_t n, int *lengths)
{
    const char *colon = memchr(line, ':', n);
    if (n > 0 && (line[0] == ' ' || line[0] == '\t'))
        return 400;   /* obsolete folding (RFC 9112: reject) */
    if (!colon)
        return 0;     /* libsoup's to refuse */
    size_t k = (size_t)(colon - line);
    while (k > 0 && (line[k - 1] == ' ' || line[k - 1] == '\t'))
        k--;
    const char *v = colon + 1, *end = line + n;
    while (v < end && (*v == ' ' || *v == '\t'))
        v++;
    while (end > v && (end[-1] == ' ' || end[-1] == '\t'))
        end--;
    if (k == 17 && !g_ascii_strncasecmp(line, "transfer-encoding", 17))
        return 400;
    if (k == 14 && !g_ascii_strncasecmp(line, "content-length", 14)) {
        if (++*lengths > 1 || end == v || strspn(v, "0123456789") < (size_t)(end - v))
            return 400;
        return strspn(v, "0") == (size_t)(end - v) ? 0 : 413;
    }
    return 0;
}

/* 1: a complete head that may go to libsoup; 0: incomplete; else the
 * status to refuse it with. */
static int check_head(const char *buf, size_t n)
{
    const char *line = buf, *end = buf + n;
    int lengths = 0, first = 1;
    while (line < end) {
        const char *nl = memchr(line, '\n', (size_t)(end - line));
        if (!nl)
            return n >= WEB_HEAD_MAX ? 431 : 0;
        size_t len = (size_t)(nl - line);
        if (len > 0 && line[len - 1] == '\r')
            len--;
        if (len == 0 && !first)
            return 1;             /* the blank line: the head is whole */
        int st = len == 0 || first ? 0 : check_line(line, len, &lengths);
        if (st)
            return st;
        if (len > 0)
            first = 0;            /* blank lines before the request line are skipped */
        line = nl + 1;
    }
    return n >= WEB_HEAD_MAX ? 431 : 0;
}

static gboolean examine(gpointer user);

static gboolean on_ready(GSocket *s, GIOCondition cond, gpointer user)
{
    webpeek *p = user;
    (void)s, (void)cond;
    g_source_unref(p->src);
    p->src = NULL;
    examine(p);
    return G_SOURCE_REMOVE;
}

static gboolean examine(gpointer user)
{
    webpeek *p = user;
    char buf[WEB_HEAD_MAX];
    p->timer = 0;
    ssize_t n = recv(g_socket_get_fd(p->s), buf, sizeof buf, MSG_PEEK | MSG_DONTWAIT);
    int st = n > 0 ? check_head(buf, (size_t)n) : -1;
    if (n < 0 && (errno == EAGAIN || errno == EINTR))
        st = 0;
    struct pollfd pf = {g_socket_get_fd(p->s), POLLRDHUP, 0};
    if (st == 0 && poll(&pf, 1, 0) == 1 && (pf.revents & (POLLRDHUP | POLLHUP | POLLERR)))
        st = n > 0 ? 400 : -1;     /* the client stopped sending: no head will come */
    if (st == 0) {                 /* more to come */
        p->timer = g_timeout_add(PEEK_RETRY_MS, examine, p);
        return G_SOURCE_REMOVE;
    }
    web_peek_done(p->w, p, p->io, st);
    if (st == 413)
        refuse_head(p, 413, "Payload Too Large", "the page takes no request body");
    else if (st == 431)
        refuse_head(p, 431, "Request Header Fields Too Large", "request head over 32 KiB");
    else if (st != 1 && st != -1)
        refuse_head(p, 400, "Bad Request", "a request body, or a folded header line");
    else if (st == -1)             /* gone before a head */
        g_io_stream_close(p->io, NULL, NULL);
    peek_end(p);
    return G_SOURCE_REMOVE;
}

webpeek *web_peek_start(web *w, GIOStream *io, GSocket *s)
{
    webpeek *p = g_new0(webpeek, 1);
    p->w = w;
    p->io = g_object_ref(io);
    p->s = s;
    p->src = g_socket_create_source(s, G_IO_IN | G_IO_HUP | G_IO_ERR, NULL);
    g_source_set_callback(p->src, G_SOURCE_FUNC(on_ready), p, NULL);
    g_source_attach(p->src, NULL);
    return p;
}

void web_peek_cancel(webpeek *p)
{
    g_io_stream_close(p->io, NULL, NULL);
    peek_end(p);
}
