/* main.c - bin/specklab-fake-stage: a Modbus TCP server that behaves like
 * the bench stage of drivers/stage_map.h, with fault switches for tests;
 * with --rtu also a Modbus RTU stage on a serial line (a pty, line.h).
 *
 * One thread, one pselect() loop over the listening socket, up to
 * MAX_CLIENTS connections and the serial line; libmodbus decodes and
 * answers the requests (modbus_receive / modbus_reply on a shared TCP
 * context re-pointed at each client socket; the line has an RTU context
 * of its own), model.c adds the semantics: read-only registers,
 * commands, motion that takes time.  A slow reply is parked per client
 * (the client's later requests wait in its socket) so one slow client never
 * delays the others, nor the test's control connection.  With --rtu the
 * TCP port still serves the same stage: tests flip the fault switches
 * there while the line carries the traffic under test.
 */
#include <errno.h>
#include <getopt.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <modbus.h>

#include "args.h"
#include "line.h"
#include "model.h"

#define MAX_CLIENTS 32
#define LINE_SLOT MAX_CLIENTS /* c[LINE_SLOT]: the serial line (--rtu) */
#define TICK_S 0.02 /* motion/stall resolution when nothing else wakes us */
/* The stage's frame gap on the line: a frame with a byte missing is
 * dropped after this silence (bytes of one frame arrive together here). */
#define LINE_BYTE_TIMEOUT_US 50000

typedef struct client {
    int fd;      /* -1 = free slot */
    modbus_t *ctx;
    int hl;      /* header length: function code at q[hl] (TCP 7, RTU 1) */
    fake_line *line; /* the serial line's slot: never closed, replies relayed */
    int pending; /* a delayed ("slow") request waits in q */
    double due_s;
    int qlen;
    uint8_t q[MODBUS_TCP_MAX_ADU_LENGTH];
} client;

typedef struct server {
    modbus_t *ctx, *rtu_ctx;
    int listen_fd;
    int hl; /* Modbus TCP header (MBAP) length: function code at q[hl] */
    fake_model model;
    fake_line line;    /* line.master < 0 without --rtu */
    client c[MAX_CLIENTS + 1];
} server;

/* The one mutable global: a signal handler can only talk through static
 * storage.  SIGINT/SIGTERM are blocked outside pselect(), so the flag is
 * seen at once and never raced. */
static volatile sig_atomic_t stop_signal;

static void on_signal(int sig)
{
    stop_signal = sig;
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* Close a connection; the serial line has none to close: the request in
 * hand just goes unanswered. */
static void drop(client *c)
{
    c->pending = 0;
    if (c->line)
        return;
    close(c->fd);
    c->fd = -1;
}

static int rd16(const uint8_t *p)
{
    return p[0] << 8 | p[1];
}

/* Fault switches apply to "ordinary" requests; a request addressed only to
 * the reserved block (>= FAKE_REG_FIRST) is the test's control channel. */
static int is_control(const client *c, const uint8_t *q, int len)
{
    int fc = q[c->hl];
    return len >= c->hl + 3 && (fc == 0x03 || fc == 0x06 || fc == 0x10) &&
           rd16(q + c->hl + 1) >= FAKE_REG_FIRST;
}

/* A write (0x06/0x10) goes through the model's checks, is stored by
 * modbus_reply, then its command runs.  Returns modbus_reply's status. */
static int reply_write(server *sv, client *c, const uint8_t *q, int len,
                       double now)
{
    fake_model *m = &sv->model;
    const uint8_t *pdu = q + c->hl;
    uint16_t v[MODBUS_MAX_WRITE_REGISTERS];
    int addr = rd16(pdu + 1), n;
    if (pdu[0] == 0x06) {
        n = 1;
        v[0] = (uint16_t)rd16(pdu + 3);
    } else {
        n = rd16(pdu + 3);
        /* malformed counts: libmodbus answers them itself, storing nothing */
        if (n < 1 || n > MODBUS_MAX_WRITE_REGISTERS || pdu[5] != 2 * n ||
            len < c->hl + 6 + 2 * n)
            return modbus_reply(c->ctx, q, len, m->map);
        for (int i = 0; i < n; i++)
            v[i] = (uint16_t)rd16(pdu + 6 + 2 * i);
    }
    int exc = fake_model_check_write(m, addr, n, v, now);
    if (exc)
        return modbus_reply_exception(c->ctx, q, (unsigned)exc);
    int rc = modbus_reply(c->ctx, q, len, m->map);
    fake_model_apply_write(m, addr, n, now);
    return rc;
}

/* Answer one request as the model says; modbus_reply's status. */
static int answer(server *sv, client *c, const uint8_t *q, int len)
{
    double now = now_s();
    fake_model_advance(&sv->model, now);
    switch (q[c->hl]) {
    case 0x06:
    case 0x10:
        return reply_write(sv, c, q, len, now);
    case 0x16:
    case 0x17: /* would bypass the write checks: not offered */
        return modbus_reply_exception(c->ctx, q,
                                      MODBUS_EXCEPTION_ILLEGAL_FUNCTION);
    default:
        return modbus_reply(c->ctx, q, len, sv->model.map);
    }
}

static void process(server *sv, client *c, const uint8_t *q, int len)
{
    uint16_t *r = sv->model.map->tab_registers;
    int rc, control = is_control(c, q, len);
    modbus_set_socket(c->ctx, c->fd);
    if (!control && (r[FAKE_REG_DISCONNECT] ||
                     (r[FAKE_REG_DISCONNECT_AFTER] > 0 &&
                      --r[FAKE_REG_DISCONNECT_AFTER] == 0))) {
        drop(c);
        return;
    }
    /* on the line, an ordinary reply may be damaged on its way out */
    int fault = c->line && !control ? fake_line_reply_fault(r) : LINE_CLEAN;
    if (!control && (r[FAKE_REG_BUSY] || r[FAKE_REG_BUSY_COUNT] > 0)) {
        if (r[FAKE_REG_BUSY_COUNT] > 0)
            r[FAKE_REG_BUSY_COUNT]--;
        rc = modbus_reply_exception(c->ctx, q,
                                    MODBUS_EXCEPTION_SLAVE_OR_SERVER_BUSY);
    } else {
        rc = answer(sv, c, q, len);
    }
    if (c->line)
        fake_line_outbound(c->line, fault);
    else if (rc < 0) /* the peer went away meanwhile */
        drop(c);
}

static int rtu_ctx_new(server *sv, const fake_line *l, int unit, char parity);

/* libmodbus's RTU server, having ignored a request for another unit,
 * takes the next frame for that unit's reply (a bus with two stages) and
 * ignores it too.  This line has no other stage: a fresh context forgets. */
static void rtu_forget_unit(server *sv, client *c)
{
    int unit = modbus_get_slave(sv->rtu_ctx);
    char parity = c->line->parity;
    modbus_free(sv->rtu_ctx);
    sv->rtu_ctx = NULL;
    if (rtu_ctx_new(sv, c->line, unit, parity) < 0) {
        perror("specklab-fake-stage: RTU context");
        exit(1);
    }
    c->ctx = sv->rtu_ctx;
}

static void on_readable(server *sv, client *c)
{
    uint8_t q[MODBUS_TCP_MAX_ADU_LENGTH];
    modbus_set_socket(c->ctx, c->fd);
    int len = modbus_receive(c->ctx, q);
    if (len < 0 && c->line) {
        /* a frame with a bad CRC or cut short: ignored, as a stage does
         * (what is left of it is not the start of the next one) */
        fake_line_drain(c->line);
        return;
    }
    if (len < 0) {
        drop(c);
        return;
    }
    if (len == 0) { /* RTU: a frame for another unit */
        if (c->line)
            rtu_forget_unit(sv, c);
        return;
    }
    unsigned slow_ms = sv->model.map->tab_registers[FAKE_REG_SLOW_MS];
    if (slow_ms && !is_control(c, q, len)) {
        memcpy(c->q, q, (size_t)len);
        c->qlen = len;
        c->due_s = now_s() + slow_ms * 1e-3;
        c->pending = 1;
        return;
    }
    process(sv, c, q, len);
}

static void on_accept(server *sv)
{
    int fd = modbus_tcp_accept(sv->ctx, &sv->listen_fd);
    if (fd < 0)
        return;
    for (int i = 0; i < MAX_CLIENTS; i++) {
        if (sv->c[i].fd < 0) {
            sv->c[i].fd = fd;
            sv->c[i].ctx = sv->ctx;
            sv->c[i].hl = sv->hl;
            sv->c[i].pending = 0;
            return;
        }
    }
    close(fd); /* full: the client sees the connection closed */
}

#define NSLOTS (MAX_CLIENTS + 1) /* the connections and the line */

/* The descriptors to wait on; returns maxfd, *wake lowered to the first
 * parked reply's due time. */
static int wait_set(server *sv, fd_set *rd, double *wake)
{
    int maxfd = sv->listen_fd;
    FD_ZERO(rd);
    FD_SET(sv->listen_fd, rd);
    if (sv->line.master >= 0) {
        FD_SET(sv->line.master, rd);
        maxfd = sv->line.master > maxfd ? sv->line.master : maxfd;
    }
    for (int i = 0; i < NSLOTS; i++) {
        client *c = &sv->c[i];
        if (c->fd < 0)
            continue;
        if (c->pending) {
            *wake = c->due_s < *wake ? c->due_s : *wake;
            continue; /* its next request waits until this reply */
        }
        FD_SET(c->fd, rd);
        maxfd = c->fd > maxfd ? c->fd : maxfd;
    }
    return maxfd;
}

static int serve(server *sv, const sigset_t *run_mask)
{
    uint16_t *r = sv->model.map->tab_registers;
    while (!stop_signal) {
        fd_set rd;
        double now = now_s(), wake = now + TICK_S;
        int maxfd = wait_set(sv, &rd, &wake);
        double d = wake > now ? wake - now : 0;
        struct timespec ts = {(time_t)d, (long)((d - (time_t)d) * 1e9)};
        int n = pselect(maxfd + 1, &rd, NULL, NULL, &ts, run_mask);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            perror("specklab-fake-stage: pselect");
            return 1;
        }
        fake_model_advance(&sv->model, now_s());
        if (n > 0 && FD_ISSET(sv->listen_fd, &rd))
            on_accept(sv);
        if (n > 0 && sv->line.master >= 0 && FD_ISSET(sv->line.master, &rd))
            fake_line_inbound(&sv->line, r);
        for (int i = 0; i < NSLOTS; i++) {
            client *c = &sv->c[i];
            if (n > 0 && c->fd >= 0 && !c->pending && FD_ISSET(c->fd, &rd))
                on_readable(sv, c);
        }
        now = now_s();
        for (int i = 0; i < NSLOTS; i++) {
            client *c = &sv->c[i];
            if (c->fd >= 0 && c->pending && c->due_s <= now) {
                c->pending = 0;
                process(sv, c, c->q, c->qlen);
            }
        }
    }
    return 0;
}

static int announce(int port, const char *pts, int ready_fd)
{
    char line[128];
    int n = snprintf(line, sizeof line, "READY port=%d%s%s\n", port,
                     pts ? " rtu=" : "", pts ? pts : "");
    fputs(line, stdout);
    fflush(stdout);
    if (ready_fd < 0)
        return 0;
    for (int off = 0; off < n;) {
        ssize_t w = write(ready_fd, line + off, (size_t)(n - off));
        if (w < 0 && errno == EINTR)
            continue;
        if (w < 0) {
            perror("specklab-fake-stage: --ready-fd");
            return -1;
        }
        off += (int)w;
    }
    close(ready_fd);
    return 0;
}

/* libmodbus's RTU backend serving on the line's socket (the context is
 * never connected: it reads and writes that socket).  0 or -1, errno. */
static int rtu_ctx_new(server *sv, const fake_line *l, int unit, char parity)
{
    sv->rtu_ctx = modbus_new_rtu(l->pts, l->baud, parity ? parity : 'E', 8, 1);
    if (!sv->rtu_ctx)
        return -1;
    if (modbus_set_slave(sv->rtu_ctx, unit) < 0)
        return -1;
    modbus_set_socket(sv->rtu_ctx, l->near);
    modbus_set_byte_timeout(sv->rtu_ctx, 0, LINE_BYTE_TIMEOUT_US);
    modbus_set_error_recovery(sv->rtu_ctx, MODBUS_ERROR_RECOVERY_NONE);
    return 0;
}

/* --rtu: the pty and its server context. */
static int rtu_up(server *sv, const run_opts *ro)
{
    char why[600];
    if (fake_line_open(&sv->line, ro->rtu_link, ro->baud, ro->parity, why,
                       sizeof why) < 0) {
        fprintf(stderr, "specklab-fake-stage: --rtu: %s\n", why);
        return -1;
    }
    if (rtu_ctx_new(sv, &sv->line, ro->unit, ro->parity) < 0) {
        fprintf(stderr, "specklab-fake-stage: --rtu: %s\n",
                modbus_strerror(errno));
        return -1;
    }
    client *c = &sv->c[LINE_SLOT];
    c->fd = sv->line.near;
    c->ctx = sv->rtu_ctx;
    c->hl = modbus_get_header_length(sv->rtu_ctx);
    c->line = &sv->line;
    return 0;
}

static void install_signals(sigset_t *run_mask)
{
    /* Block the exit signals except inside pselect(): no lost wake-up. */
    sigset_t block;
    sigemptyset(&block);
    sigaddset(&block, SIGINT);
    sigaddset(&block, SIGTERM);
    sigprocmask(SIG_BLOCK, &block, run_mask);
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    signal(SIGPIPE, SIG_IGN); /* replies to vanished clients: EPIPE, not death */
}

/* Listen, announce, serve.  The exit status. */
static int run(server *sv, const run_opts *ro, const sigset_t *run_mask)
{
    int status = 1;
    sv->ctx = modbus_new_tcp(ro->bind_addr, ro->port);
    if (!sv->ctx) {
        fprintf(stderr, "specklab-fake-stage: --bind %s: %s\n", ro->bind_addr,
                modbus_strerror(errno));
        return 1;
    }
    sv->hl = modbus_get_header_length(sv->ctx);
    /* libmodbus sets SO_REUSEADDR, so a restarted fake can take the same
     * port back at once (tests kill and restart it). */
    sv->listen_fd = modbus_tcp_listen(sv->ctx, MAX_CLIENTS);
    if (sv->listen_fd < 0) {
        fprintf(stderr, "specklab-fake-stage: listen on %s:%d: %s\n",
                ro->bind_addr, ro->port, modbus_strerror(errno));
        return 1;
    }
    struct sockaddr_in sin;
    socklen_t slen = sizeof sin;
    if (getsockname(sv->listen_fd, (struct sockaddr *)&sin, &slen) < 0) {
        perror("specklab-fake-stage: getsockname");
        return 1;
    }
    if (ro->rtu && rtu_up(sv, ro) < 0)
        return 1;
    if (announce(ntohs(sin.sin_port), ro->rtu ? sv->line.pts : NULL,
                 ro->ready_fd) == 0)
        status = serve(sv, run_mask);
    return status;
}

int main(int argc, char **argv)
{
    fake_opts o;
    run_opts ro = {1502, -1, "127.0.0.1", 0, 1, 19200, 0, NULL};
    server sv;
    sigset_t run_mask;
    memset(&sv, 0, sizeof sv);
    sv.listen_fd = -1;
    sv.line.master = sv.line.hold = sv.line.near = sv.line.far = -1;
    for (int i = 0; i < NSLOTS; i++)
        sv.c[i].fd = -1;
    fake_opts_defaults(&o);
    int prc = parse_args(argc, argv, &o, &ro);
    if (prc)
        return prc == 1 ? 0 : 2;
    install_signals(&run_mask);
    if (fake_model_init(&sv.model, &o) < 0) {
        perror("specklab-fake-stage: register map");
        return 1;
    }
    int status = run(&sv, &ro, &run_mask);
    for (int i = 0; i < MAX_CLIENTS; i++)
        if (sv.c[i].fd >= 0)
            drop(&sv.c[i]);
    if (sv.listen_fd >= 0)
        close(sv.listen_fd);
    if (sv.rtu_ctx)
        modbus_free(sv.rtu_ctx); /* never modbus_close: the line closes its fds */
    fake_line_close(&sv.line);
    if (sv.ctx)
        modbus_free(sv.ctx);
    fake_model_fini(&sv.model);
    return status;
}
