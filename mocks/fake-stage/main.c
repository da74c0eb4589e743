/* main.c - bin/specklab-fake-stage: a Modbus TCP server that behaves like
 * the bench stage of drivers/stage_map.h, with fault switches for tests.
 *
 * One thread, one pselect() loop over the listening socket and up to
 * MAX_CLIENTS connections; libmodbus decodes and answers the requests
 * (modbus_receive / modbus_reply on a shared context re-pointed at each
 * client socket), model.c adds the semantics: read-only registers,
 * commands, motion that takes time.  A slow reply is parked per client
 * (the client's later requests wait in its socket) so one slow client never
 * delays the others, nor the test's control connection.
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

#include "model.h"

#define MAX_CLIENTS 32
#define TICK_S 0.02 /* motion/stall resolution when nothing else wakes us */

typedef struct client {
    int fd;      /* -1 = free slot */
    int pending; /* a delayed ("slow") request waits in q */
    double due_s;
    int qlen;
    uint8_t q[MODBUS_TCP_MAX_ADU_LENGTH];
} client;

typedef struct server {
    modbus_t *ctx;
    int listen_fd;
    int hl; /* Modbus TCP header (MBAP) length: function code at q[hl] */
    fake_model model;
    client c[MAX_CLIENTS];
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

static void usage(FILE *f)
{
    fprintf(f,
        "usage: specklab-fake-stage [OPTIONS]\n"
        "A Modbus TCP fake of the specklab stage (drivers/stage_map.h): two\n"
        "wheels that start unhomed, move one slot per --step-ms, home in\n"
        "--home-ms, and fault switches (also registers 100..108 at run time).\n\n"
        "  --port N             TCP port (default 1502; 0 = pick a free one)\n"
        "  --bind ADDR          IPv4 address to listen on (default 127.0.0.1)\n"
        "  --slots-screen N     slots on wheel 0, the phase screens (default 6)\n"
        "  --slots-mask N       slots on wheel 1, the masks (default 6)\n"
        "  --step-ms N          ms per slot step (default 100)\n"
        "  --home-ms N          ms to home (default 2 * step)\n"
        "  --ready-fd FD        write \"READY port=N\\n\" to FD once listening\n"
        "  --magic N            answer this in register 0 (tests a client's check)\n"
        "fault switches (register):\n"
        "  --busy-count N       exception 0x06 for the next N requests (100)\n"
        "  --busy               exception 0x06 for every request (101)\n"
        "  --stall              HOME/MOVE never complete (102)\n"
        "  --stall-ms N         then FAULT=STALL after N ms (103, default 1000)\n"
        "  --slow-ms N          delay every reply by N ms (104)\n"
        "  --disconnect-after N close the connection of the N-th request (105)\n"
        "  --disconnect         close each connection at its first request (106)\n"
        "  --fault-screen CODE  start with FAULT=CODE on wheel 0 (107)\n"
        "  --fault-mask CODE    start with FAULT=CODE on wheel 1 (108)\n"
        "Requests that touch only registers >= 100 ignore the fault switches.\n"
        "Prints \"READY port=N\" on stdout; SIGINT/SIGTERM exit cleanly.\n");
}

static int parse_int(const char *opt, const char *text, long lo, long hi,
                     int *out)
{
    char *end = NULL;
    errno = 0;
    long v = strtol(text, &end, 0);
    if (errno || end == text || *end || v < lo || v > hi) {
        fprintf(stderr, "specklab-fake-stage: --%s '%s': expected an integer "
                "in %ld..%ld\n", opt, text, lo, hi);
        return -1;
    }
    *out = (int)v;
    return 0;
}

/* Returns 0 to run, 1 for --help, 2 on a usage error. */
static int parse_args(int argc, char **argv, fake_opts *o, int *port,
                      const char **bind_addr, int *ready_fd)
{
    enum { O_PORT = 256, O_BIND, O_SS, O_SM, O_STEP, O_HOME, O_READY,
           O_MAGIC, O_BUSYN, O_BUSY, O_STALL, O_STALLMS, O_SLOW, O_DISCN,
           O_DISC, O_FS, O_FM };
    static const struct option opts[] = {
        {"port", required_argument, NULL, O_PORT},
        {"bind", required_argument, NULL, O_BIND},
        {"slots-screen", required_argument, NULL, O_SS},
        {"slots-mask", required_argument, NULL, O_SM},
        {"step-ms", required_argument, NULL, O_STEP},
        {"home-ms", required_argument, NULL, O_HOME},
        {"ready-fd", required_argument, NULL, O_READY},
        {"magic", required_argument, NULL, O_MAGIC},
        {"busy-count", required_argument, NULL, O_BUSYN},
        {"busy", no_argument, NULL, O_BUSY},
        {"stall", no_argument, NULL, O_STALL},
        {"stall-ms", required_argument, NULL, O_STALLMS},
        {"slow-ms", required_argument, NULL, O_SLOW},
        {"disconnect-after", required_argument, NULL, O_DISCN},
        {"disconnect", no_argument, NULL, O_DISC},
        {"fault-screen", required_argument, NULL, O_FS},
        {"fault-mask", required_argument, NULL, O_FM},
        {"help", no_argument, NULL, 'h'},
        {NULL, 0, NULL, 0}};
    int c, bad = 0;
    while ((c = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
        const char *n = NULL;
        for (const struct option *p = opts; p->name; p++)
            if (p->val == c)
                n = p->name;
        switch (c) {
        case 'h': usage(stdout); return 1;
        case O_PORT: bad |= parse_int(n, optarg, 0, 65535, port); break;
        case O_BIND: *bind_addr = optarg; break;
        case O_SS: bad |= parse_int(n, optarg, 1, 64, &o->slots[0]); break;
        case O_SM: bad |= parse_int(n, optarg, 1, 64, &o->slots[1]); break;
        case O_STEP: bad |= parse_int(n, optarg, 0, 60000, &o->step_ms); break;
        case O_HOME: bad |= parse_int(n, optarg, 0, 60000, &o->home_ms); break;
        case O_READY: bad |= parse_int(n, optarg, 0, 1 << 20, ready_fd); break;
        case O_MAGIC: bad |= parse_int(n, optarg, 0, 65535, &o->magic); break;
        case O_BUSYN: bad |= parse_int(n, optarg, 0, 65535, &o->busy_count); break;
        case O_BUSY: o->busy = 1; break;
        case O_STALL: o->stall = 1; break;
        case O_STALLMS: bad |= parse_int(n, optarg, 0, 65535, &o->stall_ms); break;
        case O_SLOW: bad |= parse_int(n, optarg, 0, 65535, &o->slow_ms); break;
        case O_DISCN: bad |= parse_int(n, optarg, 0, 65535, &o->disconnect_after); break;
        case O_DISC: o->disconnect = 1; break;
        case O_FS: bad |= parse_int(n, optarg, 0, 65535, &o->fault[0]); break;
        case O_FM: bad |= parse_int(n, optarg, 0, 65535, &o->fault[1]); break;
        default: bad = 1; break;
        }
    }
    if (optind < argc) {
        fprintf(stderr, "specklab-fake-stage: unexpected argument '%s'\n",
                argv[optind]);
        bad = 1;
    }
    if (bad)
        fprintf(stderr, "specklab-fake-stage: try --help\n");
    return bad ? 2 : 0;
}

static void drop(client *c)
{
    close(c->fd);
    c->fd = -1;
    c->pending = 0;
}

static int rd16(const uint8_t *p)
{
    return p[0] << 8 | p[1];
}

/* Fault switches apply to "ordinary" requests; a request addressed only to
 * the reserved block (>= FAKE_REG_FIRST) is the test's control channel. */
static int is_control(const server *sv, const uint8_t *q, int len)
{
    int fc = q[sv->hl];
    return len >= sv->hl + 3 && (fc == 0x03 || fc == 0x06 || fc == 0x10) &&
           rd16(q + sv->hl + 1) >= FAKE_REG_FIRST;
}

/* A write (0x06/0x10) goes through the model's checks, is stored by
 * modbus_reply, then its command runs.  Returns modbus_reply's status. */
static int reply_write(server *sv, const uint8_t *q, int len, double now)
{
    fake_model *m = &sv->model;
    const uint8_t *pdu = q + sv->hl;
    uint16_t v[MODBUS_MAX_WRITE_REGISTERS];
    int addr = rd16(pdu + 1), n;
    if (pdu[0] == 0x06) {
        n = 1;
        v[0] = (uint16_t)rd16(pdu + 3);
    } else {
        n = rd16(pdu + 3);
        /* malformed counts: libmodbus answers them itself, storing nothing */
        if (n < 1 || n > MODBUS_MAX_WRITE_REGISTERS || pdu[5] != 2 * n ||
            len < sv->hl + 6 + 2 * n)
            return modbus_reply(sv->ctx, q, len, m->map);
        for (int i = 0; i < n; i++)
            v[i] = (uint16_t)rd16(pdu + 6 + 2 * i);
    }
    int exc = fake_model_check_write(m, addr, n, v, now);
    if (exc)
        return modbus_reply_exception(sv->ctx, q, (unsigned)exc);
    int rc = modbus_reply(sv->ctx, q, len, m->map);
    fake_model_apply_write(m, addr, n, now);
    return rc;
}

static void process(server *sv, client *c, const uint8_t *q, int len)
{
    uint16_t *r = sv->model.map->tab_registers;
    double now = now_s();
    int rc;
    modbus_set_socket(sv->ctx, c->fd);
    if (!is_control(sv, q, len)) {
        if (r[FAKE_REG_DISCONNECT] ||
            (r[FAKE_REG_DISCONNECT_AFTER] > 0 &&
             --r[FAKE_REG_DISCONNECT_AFTER] == 0)) {
            drop(c);
            return;
        }
        if (r[FAKE_REG_BUSY] || r[FAKE_REG_BUSY_COUNT] > 0) {
            if (r[FAKE_REG_BUSY_COUNT] > 0)
                r[FAKE_REG_BUSY_COUNT]--;
            if (modbus_reply_exception(sv->ctx, q,
                    MODBUS_EXCEPTION_SLAVE_OR_SERVER_BUSY) < 0)
                drop(c);
            return;
        }
    }
    fake_model_advance(&sv->model, now);
    switch (q[sv->hl]) {
    case 0x06:
    case 0x10:
        rc = reply_write(sv, q, len, now);
        break;
    case 0x16:
    case 0x17: /* would bypass the write checks: not offered */
        rc = modbus_reply_exception(sv->ctx, q,
                                    MODBUS_EXCEPTION_ILLEGAL_FUNCTION);
        break;
    default:
        rc = modbus_reply(sv->ctx, q, len, sv->model.map);
        break;
    }
    if (rc < 0) /* the peer went away meanwhile */
        drop(c);
}

static void on_readable(server *sv, client *c)
{
    uint8_t q[MODBUS_TCP_MAX_ADU_LENGTH];
    modbus_set_socket(sv->ctx, c->fd);
    int len = modbus_receive(sv->ctx, q);
    if (len < 0) {
        drop(c);
        return;
    }
    if (len == 0)
        return;
    unsigned slow_ms = sv->model.map->tab_registers[FAKE_REG_SLOW_MS];
    if (slow_ms && !is_control(sv, q, len)) {
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
            sv->c[i].pending = 0;
            return;
        }
    }
    close(fd); /* full: the client sees the connection closed */
}

static int serve(server *sv, const sigset_t *run_mask)
{
    while (!stop_signal) {
        fd_set rd;
        FD_ZERO(&rd);
        FD_SET(sv->listen_fd, &rd);
        int maxfd = sv->listen_fd;
        double now = now_s(), wake = now + TICK_S;
        for (int i = 0; i < MAX_CLIENTS; i++) {
            client *c = &sv->c[i];
            if (c->fd < 0)
                continue;
            if (c->pending) {
                wake = c->due_s < wake ? c->due_s : wake;
                continue; /* its next request waits until this reply */
            }
            FD_SET(c->fd, &rd);
            maxfd = c->fd > maxfd ? c->fd : maxfd;
        }
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
        for (int i = 0; i < MAX_CLIENTS; i++) {
            client *c = &sv->c[i];
            if (n > 0 && c->fd >= 0 && !c->pending && FD_ISSET(c->fd, &rd))
                on_readable(sv, c);
        }
        now = now_s();
        for (int i = 0; i < MAX_CLIENTS; i++) {
            client *c = &sv->c[i];
            if (c->fd >= 0 && c->pending && c->due_s <= now) {
                c->pending = 0;
                process(sv, c, c->q, c->qlen);
            }
        }
    }
    return 0;
}

static int announce(int port, int ready_fd)
{
    char line[64];
    int n = snprintf(line, sizeof line, "READY port=%d\n", port);
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

int main(int argc, char **argv)
{
    fake_opts o;
    int port = 1502, ready_fd = -1, status = 1;
    const char *bind_addr = "127.0.0.1";
    server sv;
    memset(&sv, 0, sizeof sv);
    sv.listen_fd = -1;
    for (int i = 0; i < MAX_CLIENTS; i++)
        sv.c[i].fd = -1;
    fake_opts_defaults(&o);
    int prc = parse_args(argc, argv, &o, &port, &bind_addr, &ready_fd);
    if (prc)
        return prc == 1 ? 0 : 2;

    /* Block the exit signals except inside pselect(): no lost wake-up. */
    sigset_t block, run_mask;
    sigemptyset(&block);
    sigaddset(&block, SIGINT);
    sigaddset(&block, SIGTERM);
    sigprocmask(SIG_BLOCK, &block, &run_mask);
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    signal(SIGPIPE, SIG_IGN); /* replies to vanished clients: EPIPE, not death */

    if (fake_model_init(&sv.model, &o) < 0) {
        perror("specklab-fake-stage: register map");
        return 1;
    }
    sv.ctx = modbus_new_tcp(bind_addr, port);
    if (!sv.ctx) {
        fprintf(stderr, "specklab-fake-stage: --bind %s: %s\n", bind_addr,
                modbus_strerror(errno));
        goto free_model;
    }
    sv.hl = modbus_get_header_length(sv.ctx);
    /* libmodbus sets SO_REUSEADDR, so a restarted fake can take the same
     * port back at once (tests kill and restart it). */
    sv.listen_fd = modbus_tcp_listen(sv.ctx, MAX_CLIENTS);
    if (sv.listen_fd < 0) {
        fprintf(stderr, "specklab-fake-stage: listen on %s:%d: %s\n",
                bind_addr, port, modbus_strerror(errno));
        goto free_ctx;
    }
    struct sockaddr_in sin;
    socklen_t slen = sizeof sin;
    if (getsockname(sv.listen_fd, (struct sockaddr *)&sin, &slen) < 0) {
        perror("specklab-fake-stage: getsockname");
        goto close_listen;
    }
    if (announce(ntohs(sin.sin_port), ready_fd) < 0)
        goto close_listen;
    status = serve(&sv, &run_mask);
close_listen:
    for (int i = 0; i < MAX_CLIENTS; i++)
        if (sv.c[i].fd >= 0)
            drop(&sv.c[i]);
    close(sv.listen_fd);
free_ctx:
    modbus_free(sv.ctx);
free_model:
    fake_model_fini(&sv.model);
    return status;
}
