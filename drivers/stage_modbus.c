/* stage_modbus.c - the Modbus link of drivers/stage (see stage_modbus.h).
 *
 * Recovery policy, and why: libmodbus 3.1.6 has no notion of "this reply
 * belongs to an earlier request", so after a response timeout a late reply
 * answers the next request (EMBBADDATA, or worse, plausible data).  The only
 * safe resynchronisation is a new connection (TCP) or a flushed line
 * (RTU), so any timeout, garbled reply or socket error closes the link.
 * Connection attempts are spaced by an exponential backoff that persists
 * across calls, so a caller polling a dead stage does not hammer it, and
 * each call fails fast when its deadline falls before the next allowed
 * attempt.  MODBUS_ERROR_RECOVERY_LINK is never enabled: it reconnects
 * inside libmodbus with its own unbounded loop.
 *
 * Stale links: a stage that was restarted (power-cycled, its process
 * killed) leaves our end of the TCP connection open until something is
 * sent on it.  So before each request the socket is checked without a
 * byte on the wire (the peer's FIN or stray bytes: either way the link is
 * no longer ours to use) and a dead link is replaced before the request
 * goes out, a command included.  A link that drops while a request is in
 * flight is retried only for reads (READ_RETRIES times, within the call's
 * deadline): a read changes nothing at the stage, whereas a command may
 * or may not have been executed, so a failed write is reported and the
 * next call reconnects.
 *
 * RTU (a serial line, RS-485): the same policy, with what a line adds.
 * "Reconnecting" closes and reopens the port, and a reopened port is
 * flushed: what a late reply left on the line is dropped.  A reply that
 * arrives later still (after the flush) cannot pass for the answer to a
 * later request: every reconnection first reads the identity (3 registers
 * at 0) and the wheel blocks (22 registers), and the stage answers in
 * order, so a stale reply meets the identity read, whose byte count no
 * other request of this driver has (stage_info's identical read aside,
 * whose answer is the same), and is rejected there.  Between requests a
 * line holding unasked-for bytes is out of step and is reset before the
 * next request (the serial counterpart of the TCP check above).  A frame
 * damaged on the line - a byte corrupted (its CRC does not match) or lost
 * (the frame stops short: the byte timeout, RTU_GAP_MS or 4 characters,
 * ends it well before the response timeout) - is a line error: the link
 * is reset as after any bad reply, and the request is sent again within
 * its deadline (READ_RETRIES times), a write too: a reply means the
 * request arrived whole (the stage checks its CRC and answers nothing
 * else), so the stage acted on it or refused it, and every write of this
 * driver leaves the stage as it was after the first when repeated (the
 * same TARGET; HOME, MOVE to the same target, STOP, RESET:
 * stage_map.h), while a refusal is refused again, this time legibly.  A
 * request damaged on its way to the stage is not answered: a timeout, as
 * on TCP.  Each call holds the port's lock (stage_backend.h): a serial
 * line has one master at a time.
 */
#include "stage_modbus.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <modbus.h>

#include "stage_backend.h"

/* A read whose link dropped mid-request, or a request whose reply a
 * serial line damaged, is asked again this many times. */
#define READ_RETRIES 2

enum { AGAIN_NO, AGAIN_DROPPED, AGAIN_DAMAGED }; /* request()'s *again */

struct stage_link {
    const stage_backend *be;
    modbus_t *ctx;
    char label[160];
    int response_ms, backoff_min_ms, backoff_max_ms;
    int byte_ms;       /* longest silence inside a reply */
    unsigned rejected; /* damaged replies (CRC, cut short, mismatched) */
    int damaged;       /* the failure go_down handles is one of those */
    int connected;
    int outcome;       /* STAGE_LINK_*: how the last request ended */
    double next_try_s; /* no connection attempt before this */
    int backoff_ms;    /* delay scheduled after the next failure */
    char last[256];    /* why the link is down */
    stage_ident ident;
    stage_port port;   /* rtu: the shared port's lock */
};

double stage_now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

void stage_sleep_s(double d)
{
    if (d <= 0)
        return;
    struct timespec ts = {(time_t)d, (long)((d - (double)(time_t)d) * 1e9)};
    while (nanosleep(&ts, &ts) < 0 && errno == EINTR)
        ;
}

int stage_link_new(stage_link **out, const stage_config *cfg, sl_err *err)
{
    const char *name = cfg->backend ? cfg->backend : "tcp";
    const stage_backend *be = stage_backend_find(name);
    *out = NULL;
    sl_clearerr(err);
    if (!be)
        return sl_seterr(err, SL_EINVAL,
                         "stage: unknown backend '%s' (known: tcp, rtu)", name);
    if (cfg->unit_id < 0 || cfg->unit_id > 255 || cfg->response_timeout_ms < 1 ||
        cfg->backoff_min_ms < 1 || cfg->backoff_max_ms < cfg->backoff_min_ms)
        return sl_seterr(err, SL_EINVAL, "stage: bad unit id %d or timeouts "
                         "(response %d ms, backoff %d..%d ms)", cfg->unit_id,
                         cfg->response_timeout_ms, cfg->backoff_min_ms,
                         cfg->backoff_max_ms);
    stage_link *l = calloc(1, sizeof *l);
    if (!l)
        return sl_seterr(err, SL_ENOMEM, "stage: out of memory");
    l->be = be;
    l->response_ms = cfg->response_timeout_ms;
    l->backoff_min_ms = l->backoff_ms = cfg->backoff_min_ms;
    l->backoff_max_ms = cfg->backoff_max_ms;
    l->byte_ms = stage_backend_byte_ms(be, cfg);
    snprintf(l->last, sizeof l->last, "never connected");
    l->ctx = be->create(cfg, l->label, sizeof l->label, err);
    if (!l->ctx) {
        if (err && err->code == SL_OK) /* libmodbus refused the settings */
            sl_seterr(err, SL_EINVAL, "stage: %s backend: %s", be->name,
                      modbus_strerror(errno));
        goto free_link;
    }
    if (modbus_set_slave(l->ctx, cfg->unit_id) < 0) {
        sl_seterr(err, SL_EINVAL, "stage %s: unit id %d: %s", l->label,
                  cfg->unit_id, modbus_strerror(errno));
        goto free_ctx;
    }
    modbus_set_error_recovery(l->ctx, MODBUS_ERROR_RECOVERY_NONE);
    *out = l;
    return SL_OK;
free_ctx:
    modbus_free(l->ctx);
free_link:
    free(l);
    return err ? err->code : SL_EINVAL;
}

void stage_link_free(stage_link *l)
{
    if (!l)
        return;
    if (l->connected)
        modbus_close(l->ctx);
    modbus_free(l->ctx);
    free(l);
}

const char *stage_link_label(const stage_link *l)
{
    return l->label;
}

/* Close the connection (and so release the port's lock). */
static void close_link(stage_link *l)
{
    modbus_close(l->ctx);
    l->connected = 0;
    l->port.locked = 0;
}

static int take(stage_link *l, double deadline_s, sl_err *e)
{
    if (!l->connected ||
        stage_port_take(&l->port, l->be, modbus_get_socket(l->ctx),
                        deadline_s) == 0)
        return SL_OK;
    l->outcome = STAGE_LINK_LATE;
    return sl_seterr(e, SL_EIO, "the serial port was in use by another "
                     "handle until the call's deadline");
}

static void give(stage_link *l)
{
    stage_port_give(&l->port, modbus_get_socket(l->ctx));
}

/* A link found dead between requests: closed at once, and the next
 * attempt not delayed (the link failed on the stage's side, not on a
 * request of ours). */
static void drop_if_dead(stage_link *l)
{
    const char *why = l->connected ? l->be->dead(l->ctx) : NULL;
    if (!why)
        return;
    close_link(l);
    snprintf(l->last, sizeof l->last, "%s", why);
}

int stage_link_connected(stage_link *l)
{
    /* A shared port is looked at only while no other handle talks on it
     * (its reply in flight would pass for bytes nobody asked for). */
    if (l->connected && stage_port_take(&l->port, l->be,
                                        modbus_get_socket(l->ctx), 0) == 0) {
        drop_if_dead(l);
        give(l);
    }
    return l->connected;
}

int stage_link_outcome(const stage_link *l)
{
    return l->outcome;
}

const stage_ident *stage_link_ident(const stage_link *l)
{
    return &l->ident;
}

unsigned stage_link_rejected(const stage_link *l)
{
    return l->rejected;
}

/* Both libmodbus timeouts: the wait for the first byte of a reply (ms,
 * capped by the caller to the time left) and the gap between its bytes
 * (the link's byte_ms, within the same cap). */
static void set_timeouts(stage_link *l, int ms)
{
    ms = ms < 1 ? 1 : ms;
    int gap = l->byte_ms < ms ? l->byte_ms : ms;
    modbus_set_response_timeout(l->ctx, (uint32_t)(ms / 1000),
                                (uint32_t)(ms % 1000) * 1000u);
    modbus_set_byte_timeout(l->ctx, (uint32_t)(gap / 1000),
                            (uint32_t)(gap % 1000) * 1000u);
}

static int ms_left(const stage_link *l, double deadline_s)
{
    double left = (deadline_s - stage_now_s()) * 1e3;
    return left < l->response_ms ? (int)ceil(left) : l->response_ms;
}

enum { X_OK, X_LATE, X_BUSY, X_EXC, X_LINK };

/* How the last attempt of an exchange failed. */
typedef struct failure {
    int en;        /* errno */
    int to_ms;     /* its response timeout */
    double took_s; /* from sending to the failure */
} failure;

/* One request on an open link, re-sent while the stage answers "busy"
 * (the stage did not act on it, so repeating is safe) and time remains.
 * Returns an X_* class; *f says how the last attempt failed. */
static int exchange(stage_link *l, int write, int addr, int n, uint16_t *buf,
                    double deadline_s, failure *f)
{
    double busy_wait_s = 0.01;
    int busy = 0;
    for (;;) {
        int ms = ms_left(l, deadline_s);
        if (ms < 1)
            return busy ? X_BUSY : X_LATE;
        set_timeouts(l, ms);
        f->to_ms = ms;
        double t0 = stage_now_s();
        int rc;
        if (!write)
            rc = modbus_read_registers(l->ctx, addr, n, buf);
        else if (n == 1)
            rc = modbus_write_register(l->ctx, addr, buf[0]);
        else
            rc = modbus_write_registers(l->ctx, addr, n, buf);
        if (rc >= 0)
            return X_OK;
        f->en = errno;
        f->took_s = stage_now_s() - t0;
        if (f->en == EMBXSBUSY) {
            busy = 1;
            if (stage_now_s() + busy_wait_s >= deadline_s)
                return X_BUSY;
            stage_sleep_s(busy_wait_s);
            busy_wait_s = fmin(2 * busy_wait_s, 0.1);
            continue;
        }
        if (f->en > MODBUS_ENOBASE && f->en <= EMBXGTAR)
            return X_EXC;
        return X_LINK;
    }
}

/* Close the link, remember why (printf-style), schedule the next attempt
 * one backoff step later and double the step (after a reply the line
 * damaged: the shortest step, not doubled).  Returns code. */
static int go_down(stage_link *l, sl_err *e, int code, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static int go_down(stage_link *l, sl_err *e, int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(l->last, sizeof l->last, fmt, ap);
    va_end(ap);
    close_link(l);
    if (l->damaged) {
        /* the stage answered, the line garbled it: no reason to wait long */
        l->damaged = 0;
        l->next_try_s = stage_now_s() + l->backoff_min_ms * 1e-3;
        return sl_seterr(e, code, "%s", l->last);
    }
    l->next_try_s = stage_now_s() + l->backoff_ms * 1e-3;
    l->backoff_ms = l->backoff_ms * 2 > l->backoff_max_ms ? l->backoff_max_ms
                                                           : l->backoff_ms * 2;
    return sl_seterr(e, code, "%s", l->last);
}

/* A serial reply that stopped short: the byte timeout ended it well
 * before the response timeout would have (bytes had come). */
static int cut_short(const stage_link *l, const failure *f)
{
    return l->be->serial && f->en == ETIMEDOUT &&
           l->byte_ms < f->to_ms && f->took_s * 1e3 + l->byte_ms / 2.0 < f->to_ms;
}

static int bad_reply(int en)
{
    return en == EMBBADDATA || en == EMBBADCRC || en == EMBMDATA ||
           en == EMBBADEXC || en == EMBUNKEXC || en == EMBBADSLAVE;
}

/* A reply a serial line damaged: a byte corrupted (CRC), lost (cut
 * short), or a frame that does not fit the request. */
static int line_error(const stage_link *l, const failure *f)
{
    return l->be->serial && (bad_reply(f->en) || cut_short(l, f));
}

static const char *link_reason(const stage_link *l, const failure *f,
                               char *buf, size_t n)
{
    int en = f->en;
    if (cut_short(l, f))
        snprintf(buf, n, "reply cut short (no byte for %d ms: a byte lost on "
                 "the line?)", l->byte_ms);
    else if (en == ETIMEDOUT)
        snprintf(buf, n, "no reply within %d ms", f->to_ms);
    else if (en == ECONNRESET)
        snprintf(buf, n, "connection closed by the stage");
    else if (bad_reply(en))
        snprintf(buf, n, "bad reply (%s)", modbus_strerror(en));
    else
        snprintf(buf, n, "%s", modbus_strerror(en));
    return buf;
}

/* The reason of a failed exchange, counting a damaged reply. */
static const char *failed(stage_link *l, const failure *f, char *buf,
                          size_t n)
{
    if (line_error(l, f)) {
        l->rejected++;
        l->damaged = 1;
    }
    return link_reason(l, f, buf, n);
}

/* Verify a fresh connection is a specklab stage and read its wheels. */
static int handshake(stage_link *l, double deadline_s, sl_err *e)
{
    uint16_t id[3], wr[STAGE_REG_WHEEL_BASE(STAGE_NWHEELS - 1) +
                       STAGE_WHEEL_NREGS - STAGE_REG_WHEEL_BASE(0)];
    int nw = (int)(sizeof wr / sizeof wr[0]);
    failure f = {0, 0, 0};
    char why[128];
    int x = exchange(l, 0, STAGE_REG_MAGIC, 3, id, deadline_s, &f);
    if (x == X_OK)
        x = exchange(l, 0, STAGE_REG_WHEEL_BASE(0), nw, wr, deadline_s, &f);
    switch (x) {
    case X_OK: break;
    case X_LATE: return go_down(l, e, SL_EIO, "connected, but the call's "
                                "deadline came before the identity check");
    case X_BUSY: return go_down(l, e, SL_EIO, "connected, but the stage "
                                "answered busy (exception 0x06) until the "
                                "deadline");
    case X_EXC: return go_down(l, e, SL_EFORMAT, "identity registers refused "
                               "(%s): not a specklab stage?",
                               modbus_strerror(f.en));
    default: return go_down(l, e, SL_EIO, "connected, then %s during the "
                            "identity check",
                            failed(l, &f, why, sizeof why));
    }
    if (id[0] != STAGE_MAGIC)
        return go_down(l, e, SL_EFORMAT, "not a specklab stage: register 0 "
                       "reads 0x%04X, expected 0x%04X (wrong device, port or "
                       "unit id?)", id[0], STAGE_MAGIC);
    if (id[1] < 1 || id[1] > STAGE_MAP_VERSION || id[2] != STAGE_NWHEELS)
        return go_down(l, e, SL_EFORMAT, "unsupported stage: register map "
                       "version %u with %u wheels (this driver knows version "
                       "%d with %d)", id[1], id[2], STAGE_MAP_VERSION,
                       STAGE_NWHEELS);
    l->ident.magic = id[0];
    l->ident.version = id[1];
    l->ident.nwheels = id[2];
    for (int w = 0; w < STAGE_NWHEELS; w++) {
        /* Offset first: wr + BASE(1) alone would point past the end of
         * wr before the subtraction, which is undefined (UBSan, fuzzing). */
        const uint16_t *b =
            wr + (STAGE_REG_WHEEL_BASE(w) - STAGE_REG_WHEEL_BASE(0));
        l->ident.slots[w] = b[STAGE_WREG_SLOTS];
        l->ident.move_ms[w] = b[STAGE_WREG_MOVE_MS];
    }
    return SL_OK;
}

static int connect_once(stage_link *l, double deadline_s, sl_err *e)
{
    int ms = ms_left(l, deadline_s);
    if (ms < 1)
        return SL_EIO; /* the caller reports l->last */
    /* libmodbus bounds the TCP connect by the response timeout. */
    set_timeouts(l, ms);
    int rc = modbus_connect(l->ctx);
    if (rc < 0 && errno == EINVAL && l->be->serial &&
        stage_port_nudge(l->label) == 0) /* a pty set before (see there) */
        rc = modbus_connect(l->ctx);
    if (rc < 0) {
        int en = errno;
        /* libmodbus leaves EINPROGRESS when its connect wait ran out */
        if (en == EINPROGRESS || en == ETIMEDOUT)
            return go_down(l, e, SL_EIO, "cannot connect: no answer within "
                           "%d ms", ms);
        return go_down(l, e, SL_EIO, "cannot connect: %s", modbus_strerror(en));
    }
    int fd = modbus_get_socket(l->ctx);
    stage_port_opened(&l->port, l->be, fd);
    if (stage_port_take(&l->port, l->be, fd, deadline_s) < 0)
        return go_down(l, e, SL_EIO, "the serial port was in use by another "
                       "handle until the call's deadline");
    l->be->on_connect(l->ctx);
    rc = handshake(l, deadline_s, e);
    if (rc != SL_OK)
        return rc;
    l->connected = 1;
    l->backoff_ms = l->backoff_min_ms;
    return SL_OK;
}

/* stage_link_ensure with the port's lock held (when connected). */
static int ensure(stage_link *l, double deadline_s, sl_err *e)
{
    int attempts = 0;
    /* A serial attempt too short to see a frame's gap could only end in
     * "no reply", hiding why the earlier ones failed: not made. */
    double least_s = l->be->serial ? 2 * l->byte_ms * 1e-3 : 0;
    while (!l->connected) {
        double now = stage_now_s();
        if (l->next_try_s >= deadline_s)
            return sl_seterr(e, SL_EIO, "not connected: %s (%d attempt%s in "
                             "this call; next in %.0f ms, past its deadline)",
                             l->last, attempts, attempts == 1 ? "" : "s",
                             (l->next_try_s - now) * 1e3);
        if (attempts && l->next_try_s + least_s >= deadline_s)
            return sl_seterr(e, SL_EIO, "not connected: %s (%d attempts in "
                             "this call; too little time left for another)",
                             l->last, attempts);
        stage_sleep_s(l->next_try_s - now);
        attempts++;
        int rc = connect_once(l, deadline_s, e);
        if (rc == SL_EFORMAT)
            return rc;
        if (rc != SL_OK && stage_now_s() >= deadline_s)
            return sl_seterr(e, SL_EIO, "not connected: %s (%d attempt%s in "
                             "this call)", l->last, attempts,
                             attempts == 1 ? "" : "s");
    }
    return SL_OK;
}

int stage_link_ensure(stage_link *l, double deadline_s, sl_err *e)
{
    int rc = take(l, deadline_s, e);
    if (rc == SL_OK)
        rc = ensure(l, deadline_s, e);
    give(l);
    return rc;
}

/* request() with the port's lock held (when connected). */
static int request_locked(stage_link *l, int write, int addr, int n,
                          uint16_t *buf, double deadline_s, int *exc,
                          sl_err *e, int *again)
{
    failure f = {0, 0, 0};
    char why[160];
    drop_if_dead(l);
    int rc = ensure(l, deadline_s, e);
    if (rc != SL_OK)
        return rc;
    double t0 = stage_now_s();
    switch (exchange(l, write, addr, n, buf, deadline_s, &f)) {
    case X_OK:
        l->outcome = STAGE_LINK_DONE;
        return SL_OK;
    case X_LATE:
        l->outcome = STAGE_LINK_LATE;
        return sl_seterr(e, SL_EIO, "call deadline reached before the request");
    case X_BUSY:
        l->outcome = STAGE_LINK_BUSY;
        return sl_seterr(e, SL_EIO, "stage busy (exception 0x06) for %.1f s, "
                         "until the call's deadline", stage_now_s() - t0);
    case X_EXC:
        *exc = f.en - MODBUS_ENOBASE;
        return sl_seterr(e, SL_EIO, "exception 0x%02X (%s)", *exc,
                         modbus_strerror(f.en));
    default:
        if (line_error(l, &f))
            *again = AGAIN_DAMAGED;
        else if (f.en == ECONNRESET || f.en == EPIPE || f.en == ENOTCONN ||
                 f.en == ECONNABORTED)
            *again = AGAIN_DROPPED;
        return go_down(l, e, SL_EIO, "%s (reconnecting)",
                       failed(l, &f, why, sizeof why));
    }
}

/* One request, the port's traffic to itself; *again says why it may be
 * asked again (AGAIN_*): the link closed under it (a read), or a serial
 * line damaged its reply (any request). */
static int request(stage_link *l, int write, int addr, int n, uint16_t *buf,
                   double deadline_s, int *exc, sl_err *e, int *again)
{
    *exc = 0;
    *again = AGAIN_NO;
    l->outcome = STAGE_LINK_FAILED;
    int rc = take(l, deadline_s, e);
    if (rc == SL_OK)
        rc = request_locked(l, write, addr, n, buf, deadline_s, exc, e, again);
    give(l);
    return rc;
}

int stage_link_read(stage_link *l, int addr, int n, uint16_t *dst,
                    double deadline_s, int *exc, sl_err *e)
{
    int again = AGAIN_NO, rc;
    for (int attempt = 0;; attempt++) {
        rc = request(l, 0, addr, n, dst, deadline_s, exc, e, &again);
        if (rc == SL_OK || again == AGAIN_NO || attempt == READ_RETRIES ||
            stage_now_s() >= deadline_s)
            return rc;
    }
}

int stage_link_write(stage_link *l, int addr, int n, const uint16_t *src,
                     double deadline_s, int *exc, sl_err *e)
{
    uint16_t buf[MODBUS_MAX_WRITE_REGISTERS];
    if (n < 1 || n > MODBUS_MAX_WRITE_REGISTERS)
        return sl_seterr(e, SL_EINVAL, "write of %d registers", n);
    memcpy(buf, src, (size_t)n * sizeof *buf);
    int again = AGAIN_NO, rc;
    for (int attempt = 0;; attempt++) {
        rc = request(l, 1, addr, n, buf, deadline_s, exc, e, &again);
        if (rc == SL_OK || again != AGAIN_DAMAGED || attempt == READ_RETRIES ||
            stage_now_s() >= deadline_s)
            return rc;
    }
}
