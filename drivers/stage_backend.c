/* stage_backend.c - the transports of drivers/stage (see
 * stage_backend.h). */
#include "stage_backend.h"

#include <arpa/inet.h>
#include <errno.h>
#include <math.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/file.h>
#include <fcntl.h>
#include <unistd.h>

#include "stage_modbus.h"

static modbus_t *tcp_create(const stage_config *cfg, char *label, size_t n,
                            sl_err *e)
{
    struct in_addr a;
    if (!cfg->host || inet_pton(AF_INET, cfg->host, &a) != 1) {
        sl_seterr(e, SL_EINVAL, "stage: tcp host '%s' is not an IPv4 address",
                  cfg->host ? cfg->host : "(null)");
        return NULL;
    }
    if (cfg->port < 1 || cfg->port > 65535) {
        sl_seterr(e, SL_EINVAL, "stage: tcp port %d outside 1..65535",
                  cfg->port);
        return NULL;
    }
    snprintf(label, n, "%s:%d", cfg->host, cfg->port);
    return modbus_new_tcp(cfg->host, cfg->port);
}

static void tcp_on_connect(modbus_t *ctx)
{
    (void)ctx; /* a fresh socket has nothing stale in it */
}

/* What waits on the descriptor: 0 nothing, else poll's revents (POLLNVAL
 * for no descriptor).  One poll, no traffic. */
static int pending(modbus_t *ctx)
{
    struct pollfd p = {modbus_get_socket(ctx), POLLIN, 0};
    if (p.fd < 0)
        return POLLNVAL;
    return poll(&p, 1, 0) == 0 ? 0 : p.revents | POLLIN;
}

/* Between requests nothing may be waiting on the socket: the peer's FIN
 * (the stage restarted or closed it: readable, end of stream), an error or
 * hang-up, or bytes no request asked for (a late reply). */
static const char *tcp_dead(modbus_t *ctx)
{
    return pending(ctx) ? "connection closed by the stage" : NULL;
}

static modbus_t *rtu_create(const stage_config *cfg, char *label, size_t n,
                            sl_err *e)
{
    if (!cfg->device || !cfg->device[0]) {
        sl_seterr(e, SL_EINVAL, "stage: rtu backend needs a serial device");
        return NULL;
    }
    if (cfg->baud <= 0 || !cfg->parity || !strchr("NEO", cfg->parity) ||
        cfg->data_bits < 5 || cfg->data_bits > 8 || cfg->stop_bits < 1 ||
        cfg->stop_bits > 2) {
        sl_seterr(e, SL_EINVAL, "stage %s: bad serial settings %d %d%c%d "
                  "(baud > 0, 5..8 data bits, parity N/E/O, 1..2 stop bits)",
                  cfg->device, cfg->baud, cfg->data_bits,
                  cfg->parity ? cfg->parity : '?', cfg->stop_bits);
        return NULL;
    }
    snprintf(label, n, "%s", cfg->device);
    return modbus_new_rtu(cfg->device, cfg->baud, cfg->parity, cfg->data_bits,
                          cfg->stop_bits);
}

static void rtu_on_connect(modbus_t *ctx)
{
    modbus_flush(ctx); /* drop bytes left on the line by an earlier exchange */
}

/* A serial line has no connection to lose, but its port can hang up (a
 * USB adapter unplugged, a pty's other side gone), and bytes waiting
 * between requests (a reply that came after its timeout) put it out of
 * step. */
static const char *rtu_dead(modbus_t *ctx)
{
    int ev = pending(ctx);
    if (ev & (POLLHUP | POLLERR | POLLNVAL))
        return "the serial port hung up (device gone?)";
    return ev ? "unasked-for bytes on the line between requests (a late "
                "reply?)" : NULL;
}

static const stage_backend backends[] = {
    {"tcp", tcp_create, tcp_on_connect, tcp_dead, 0},
    {"rtu", rtu_create, rtu_on_connect, rtu_dead, 1},
};
#define NBACKENDS ((int)(sizeof backends / sizeof backends[0]))

const char *stage_backend_name(int i)
{
    return i >= 0 && i < NBACKENDS ? backends[i].name : NULL;
}

const stage_backend *stage_backend_find(const char *name)
{
    for (int i = 0; i < NBACKENDS; i++)
        if (!strcmp(backends[i].name, name))
            return &backends[i];
    return NULL;
}

int stage_backend_byte_ms(const stage_backend *be, const stage_config *cfg)
{
    int ms = cfg->response_timeout_ms;
    if (!be->serial || cfg->baud <= 0)
        return ms;
    /* 11 bits a character at most (start, 8 data, parity, stop) */
    int four_chars_ms = (int)ceil(4 * 11 * 1000.0 / cfg->baud);
    int gap = four_chars_ms > RTU_GAP_MS ? four_chars_ms : RTU_GAP_MS;
    return gap < ms ? gap : ms;
}

void stage_port_opened(stage_port *p, const stage_backend *be, int fd)
{
    p->locked = 0;
    p->have_tios = be->serial && tcgetattr(fd, &p->tios) == 0;
}

static int same_settings(const struct termios *a, const struct termios *b)
{
    return a->c_iflag == b->c_iflag && a->c_oflag == b->c_oflag &&
           a->c_cflag == b->c_cflag && a->c_lflag == b->c_lflag &&
           cfgetispeed(a) == cfgetispeed(b) &&
           cfgetospeed(a) == cfgetospeed(b) &&
           !memcmp(a->c_cc, b->c_cc, sizeof a->c_cc);
}

/* With the lock: the settings this handle connected with, in force. */
static void keep_settings(stage_port *p, int fd)
{
    struct termios now;
    if (!p->have_tios || tcgetattr(fd, &now) < 0)
        return;
    if (!same_settings(&now, &p->tios)) {
        tcsetattr(fd, TCSANOW, &p->tios);
        tcflush(fd, TCIOFLUSH);
    }
}

int stage_port_take(stage_port *p, const stage_backend *be, int fd,
                    double deadline_s)
{
    if (!be->serial || p->locked || fd < 0)
        return 0;
    double wait_s = 0.002;
    while (flock(fd, LOCK_EX | LOCK_NB) < 0) {
        if (errno == EINTR)
            continue;
        if (errno != EWOULDBLOCK)
            break; /* no lock to be had here (not a local file): go on */
        double left = deadline_s - stage_now_s();
        if (left <= 0)
            return -1;
        stage_sleep_s(left < wait_s ? left : wait_s);
        wait_s = fmin(2 * wait_s, 0.02);
    }
    p->locked = 1;
    keep_settings(p, fd);
    return 0;
}

void stage_port_give(stage_port *p, int fd)
{
    if (!p->locked)
        return;
    if (fd >= 0)
        flock(fd, LOCK_UN);
    p->locked = 0;
}

int stage_port_nudge(const char *device)
{
    struct termios t;
    int fd = open(device, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0)
        return -1;
    int rc = -1;
    if (tcgetattr(fd, &t) == 0) {
        t.c_iflag ^= IXANY;
        rc = tcsetattr(fd, TCSANOW, &t);
    }
    close(fd);
    return rc;
}
