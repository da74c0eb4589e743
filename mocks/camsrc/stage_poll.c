/* stage_poll.c - the fake camera learns what is in the beam the way any
 * client would: it reads the stage's registers over Modbus/TCP with
 * libmodbus (drivers/stage_map.h).  It never writes.
 *
 * libmodbus gets out of step after a response timeout (a late reply is
 * taken as the answer to the next request), so any failure other than a
 * "busy" exception closes the connection; the next attempt waits a
 * backoff of 100 ms doubling to 2 s, so a dead stage costs the main loop
 * at most one connect timeout (300 ms) per backoff period.
 */
#include <errno.h>
#include <modbus.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fakecam_app.h"
#include "stage_map.h"

#define STAGE_TIMEOUT_US 300000
#define BACKOFF_MIN_MS 100
#define BACKOFF_MAX_MS 2000

struct stage_poll {
    char host[256];
    int port, unit;
    modbus_t *ctx;          /* NULL while disconnected */
    gint64 next_try_us;     /* monotonic time of the next connect */
    int backoff_ms;
};

int stage_poll_new(stage_poll **out, const char *host_port, int unit, sl_err *err)
{
    *out = NULL;
    const char *colon = strrchr(host_port, ':');
    char *end = NULL;
    long port = colon ? strtol(colon + 1, &end, 10) : 0;
    if (!colon || colon == host_port || !end || *end || port < 1 || port > 65535 ||
        (size_t)(colon - host_port) >= sizeof ((stage_poll *)0)->host)
        return sl_seterr(err, SL_EINVAL, "--stage '%s': expected HOST:PORT", host_port);
    if (unit < 0 || unit > 247)
        return sl_seterr(err, SL_EINVAL, "--stage-unit %d: expected 0..247", unit);
    stage_poll *p = calloc(1, sizeof *p);
    if (!p)
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    memcpy(p->host, host_port, (size_t)(colon - host_port));
    p->port = (int)port;
    p->unit = unit;
    p->backoff_ms = BACKOFF_MIN_MS;
    *out = p;
    return SL_OK;
}

static void disconnect(stage_poll *p)
{
    if (!p->ctx)
        return;
    modbus_close(p->ctx);
    modbus_free(p->ctx);
    p->ctx = NULL;
    p->next_try_us = g_get_monotonic_time() + (gint64)p->backoff_ms * 1000;
    p->backoff_ms = p->backoff_ms * 2 > BACKOFF_MAX_MS ? BACKOFF_MAX_MS : p->backoff_ms * 2;
}

void stage_poll_free(stage_poll *p)
{
    if (!p)
        return;
    disconnect(p);
    free(p);
}

static int fail(stage_poll *p, sl_err *err, const char *doing, int e)
{
    sl_seterr(err, SL_EIO, "stage %s:%d: %s: %s", p->host, p->port, doing,
              modbus_strerror(e));
    disconnect(p);
    return SL_EIO;
}

static int connect_stage(stage_poll *p, sl_err *err)
{
    if (g_get_monotonic_time() < p->next_try_us)
        return sl_seterr(err, SL_EIO, "stage %s:%d: waiting to reconnect", p->host, p->port);
    p->ctx = modbus_new_tcp(p->host, p->port);
    if (!p->ctx) {
        p->next_try_us = g_get_monotonic_time() + (gint64)p->backoff_ms * 1000;
        return sl_seterr(err, SL_EIO, "stage %s:%d: %s", p->host, p->port,
                         modbus_strerror(errno));
    }
    modbus_set_slave(p->ctx, p->unit);
    modbus_set_response_timeout(p->ctx, 0, STAGE_TIMEOUT_US);
    if (modbus_connect(p->ctx) == -1)
        return fail(p, err, "connect", errno);
    uint16_t magic = 0;
    if (modbus_read_registers(p->ctx, STAGE_REG_MAGIC, 1, &magic) != 1)
        return fail(p, err, "read MAGIC", errno);
    if (magic != STAGE_MAGIC) {
        sl_seterr(err, SL_EIO, "stage %s:%d: register 0 is 0x%04X, not 0x%04X: not a "
                  "specklab stage", p->host, p->port, magic, STAGE_MAGIC);
        disconnect(p);
        return SL_EIO;
    }
    p->backoff_ms = BACKOFF_MIN_MS;
    return SL_OK;
}

/* A wheel holds a slot in the beam only when it is homed, in position,
 * not busy and not faulted; anything else blocks the beam. */
static int wheel_slot(const uint16_t *regs)
{
    unsigned st = regs[STAGE_WREG_STATUS];
    unsigned pos = regs[STAGE_WREG_POSITION];
    if (pos == STAGE_POSITION_UNKNOWN || !(st & STAGE_ST_INPOS) || !(st & STAGE_ST_HOMED) ||
        (st & (STAGE_ST_BUSY | STAGE_ST_FAULT)))
        return -1;
    return (int)pos;
}

int stage_poll_read(stage_poll *p, beam *out, sl_err *err)
{
    if (!p->ctx) {
        int rc = connect_stage(p, err);
        if (rc != SL_OK)
            return rc;
    }
    uint16_t w[STAGE_NWHEELS][STAGE_WHEEL_NREGS];
    for (int i = 0; i < STAGE_NWHEELS; i++) {
        if (modbus_read_registers(p->ctx, STAGE_REG_WHEEL_BASE(i), STAGE_WHEEL_NREGS,
                                  w[i]) != STAGE_WHEEL_NREGS) {
            int e = errno;
            if (e == EMBXSBUSY) /* the stage said busy: in step, ask later */
                return sl_seterr(err, SL_EIO, "stage %s:%d: busy", p->host, p->port);
            return fail(p, err, "read the wheels", e);
        }
    }
    int screen = wheel_slot(w[STAGE_WHEEL_SCREEN]);
    int msk = wheel_slot(w[STAGE_WHEEL_MASK]);
    out->known = 1;
    out->moving = screen < 0 || msk < 0;
    out->screen = screen;
    out->mask = msk;
    return SL_OK;
}
