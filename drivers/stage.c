/* stage.c - the stage API on top of the Modbus link (see stage.h).
 *
 * This file knows the register map's meaning (commands, status bits,
 * refusals) and words the errors; stage_modbus.c knows how to talk and
 * recover.  Every public call computes one absolute deadline and hands it
 * down, so connection, backoff, busy retries and polling share one bound.
 */
#include "stage.h"

#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <modbus.h>

#include "stage_modbus.h"

#define POLL_S 0.02         /* STATUS polling period while waiting */
#define START_GRACE_S 0.25  /* a move not yet busy after this has not started */

enum { OP_NONE, OP_HOME, OP_MOVE };

/* What this handle last asked a wheel to do: stage_wait's goal and the
 * start of the "after 2.0 s" in its messages. */
typedef struct wheel_op {
    int op;
    int slot;
    double t0_s;
} wheel_op;

struct stage {
    stage_link *link;
    int call_ms, move_ms;
    wheel_op last[STAGE_NWHEELS];
    sl_err err;
};

static const char *const fault_texts[] = {
    "none", "stall", "encoder error (position lost)",
    "driver over temperature", "limit switch hit"};

const char *stage_fault_text(int code)
{
    int n = (int)(sizeof fault_texts / sizeof fault_texts[0]);
    return code >= 0 && code < n ? fault_texts[code] : "unknown fault";
}

const char *stage_wheel_name(int wheel)
{
    switch (wheel) {
    case STAGE_WHEEL_SCREEN: return "screen";
    case STAGE_WHEEL_MASK: return "mask";
    case STAGE_WHEEL_ALL: return "all";
    default: return "?";
    }
}

int stage_wheel_parse(const char *text, int *wheel)
{
    if (!text)
        return SL_EINVAL;
    if (!strcmp(text, "screen") || !strcmp(text, "0"))
        *wheel = STAGE_WHEEL_SCREEN;
    else if (!strcmp(text, "mask") || !strcmp(text, "1"))
        *wheel = STAGE_WHEEL_MASK;
    else if (!strcmp(text, "all"))
        *wheel = STAGE_WHEEL_ALL;
    else
        return SL_EINVAL;
    return SL_OK;
}

void stage_config_defaults(stage_config *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    cfg->backend = "tcp";
    cfg->host = "127.0.0.1";
    cfg->port = 1502;
    cfg->baud = 19200;
    cfg->parity = 'E';
    cfg->data_bits = 8;
    cfg->stop_bits = 1;
    cfg->unit_id = 1;
    cfg->response_timeout_ms = 500;
    cfg->call_timeout_ms = 2000;
    cfg->move_timeout_ms = 10000;
    cfg->backoff_min_ms = 50;
    cfg->backoff_max_ms = 1000;
}

int stage_new(stage **out, const stage_config *cfg, sl_err *err)
{
    *out = NULL;
    if (cfg->call_timeout_ms < cfg->response_timeout_ms ||
        cfg->move_timeout_ms < 1)
        return sl_seterr(err, SL_EINVAL, "stage: call timeout %d ms must be "
                         ">= the response timeout %d ms, move timeout %d ms "
                         "> 0", cfg->call_timeout_ms,
                         cfg->response_timeout_ms, cfg->move_timeout_ms);
    stage *s = calloc(1, sizeof *s);
    if (!s)
        return sl_seterr(err, SL_ENOMEM, "stage: out of memory");
    int rc = stage_link_new(&s->link, cfg, err);
    if (rc != SL_OK) {
        free(s);
        return rc;
    }
    s->call_ms = cfg->call_timeout_ms;
    s->move_ms = cfg->move_timeout_ms;
    *out = s;
    return SL_OK;
}

void stage_free(stage *s)
{
    if (!s)
        return;
    stage_link_free(s->link);
    free(s);
}

const char *stage_errmsg(const stage *s)
{
    return s ? s->err.msg : "stage: no handle";
}

const char *stage_label(const stage *s)
{
    return stage_link_label(s->link);
}

unsigned stage_rejected_replies(const stage *s)
{
    return stage_link_rejected(s->link);
}

int stage_connected(stage *s)
{
    return stage_link_connected(s->link);
}

/* Record "stage LABEL: <message>" in the handle; returns code. */
static int fail(stage *s, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static int fail(stage *s, int code, const char *fmt, ...)
{
    char msg[SL_ERRMSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return sl_seterr(&s->err, code, "stage %s: %s", stage_label(s), msg);
}

static double call_deadline(const stage *s)
{
    return stage_now_s() + s->call_ms * 1e-3;
}

static const char *wheel_desc(int wheel, char *buf, size_t n)
{
    if (wheel == STAGE_WHEEL_ALL)
        snprintf(buf, n, "all wheels");
    else
        snprintf(buf, n, "wheel %d (%s)", wheel, stage_wheel_name(wheel));
    return buf;
}

static int check_wheel(stage *s, int wheel, int allow_all, const char *what)
{
    if (wheel == STAGE_WHEEL_SCREEN || wheel == STAGE_WHEEL_MASK ||
        (allow_all && wheel == STAGE_WHEEL_ALL))
        return SL_OK;
    return fail(s, SL_EINVAL, "%s: wheel %d: expected 0 (screen), 1 (mask)%s",
                what, wheel, allow_all ? " or all" : "");
}

static void decode(int wheel, const uint16_t *r, stage_wheel_status *st)
{
    st->wheel = wheel;
    st->slots = r[STAGE_WREG_SLOTS];
    st->target = r[STAGE_WREG_TARGET];
    st->position = r[STAGE_WREG_POSITION] == STAGE_POSITION_UNKNOWN
                       ? -1 : r[STAGE_WREG_POSITION];
    st->status = r[STAGE_WREG_STATUS];
    st->busy = (st->status & STAGE_ST_BUSY) != 0;
    st->in_position = (st->status & STAGE_ST_INPOS) != 0;
    st->homed = (st->status & STAGE_ST_HOMED) != 0;
    st->faulted = (st->status & STAGE_ST_FAULT) != 0;
    st->fault = r[STAGE_WREG_FAULT];
    st->fault_text = stage_fault_text(st->fault);
    st->move_ms = r[STAGE_WREG_MOVE_MS];
}

/* Read one wheel's block; the link's reason goes to e. */
static int read_wheel(stage *s, int wheel, stage_wheel_status *st,
                      double deadline_s, int *exc, sl_err *e)
{
    uint16_t r[STAGE_WHEEL_NREGS];
    int rc = stage_link_read(s->link, STAGE_REG_WHEEL_BASE(wheel),
                             STAGE_WHEEL_NREGS, r, deadline_s, exc, e);
    if (rc == SL_OK)
        decode(wheel, r, st);
    return rc;
}

int stage_status(stage *s, int wheel, stage_wheel_status *out)
{
    char wd[32];
    sl_err e = {0};
    int exc;
    int rc = check_wheel(s, wheel, 0, "status");
    if (rc != SL_OK)
        return rc;
    rc = read_wheel(s, wheel, out, call_deadline(s), &exc, &e);
    if (rc != SL_OK)
        return fail(s, rc, "status of %s: %s",
                    wheel_desc(wheel, wd, sizeof wd), e.msg);
    return SL_OK;
}

int stage_info(stage *s, stage_ident *out)
{
    uint16_t r[3];
    sl_err e = {0};
    int exc;
    /* One live read, so a dead link is noticed (and re-verified) now. */
    int rc = stage_link_read(s->link, STAGE_REG_MAGIC, 3, r, call_deadline(s),
                             &exc, &e);
    if (rc != SL_OK)
        return fail(s, rc, "identity: %s", e.msg);
    *out = *stage_link_ident(s->link);
    return SL_OK;
}

/* Word a refused command (Modbus exception) from the wheel's state. */
static int refused(stage *s, const char *what, int wheel, int slot, int exc,
                   double deadline_s)
{
    stage_wheel_status st;
    sl_err e = {0};
    int exc2;
    int w = wheel == STAGE_WHEEL_ALL ? STAGE_WHEEL_SCREEN : wheel;
    for (int i = w; i < STAGE_NWHEELS; i++) {
        if (read_wheel(s, i, &st, deadline_s, &exc2, &e) != SL_OK)
            break;
        if (st.faulted)
            return fail(s, SL_ERANGE, "%s refused: wheel %d in fault %d (%s); "
                        "reset it first", what, i, st.fault, st.fault_text);
        if (slot >= 0 && !st.homed)
            return fail(s, SL_ERANGE, "%s refused: wheel %d not homed (home "
                        "it first)", what, i);
        if (slot >= st.slots)
            return fail(s, SL_ERANGE, "%s refused: slot out of range 0..%d",
                        what, st.slots - 1);
        if (wheel != STAGE_WHEEL_ALL)
            break;
    }
    return fail(s, SL_ERANGE, "%s refused: exception 0x%02X (%s)%s", what,
                exc, modbus_strerror(MODBUS_ENOBASE + exc),
                e.msg[0] ? "; its status is unreadable" : "");
}

/* Write COMMAND and CMD_WHEEL in one request: the stage acts once both
 * have landed. */
static int command(stage *s, unsigned cmd, int wheel, int slot,
                   const char *what, double deadline_s)
{
    uint16_t v[2] = {(uint16_t)cmd, (uint16_t)wheel};
    sl_err e = {0};
    int exc;
    int rc = stage_link_write(s->link, STAGE_REG_COMMAND, 2, v, deadline_s,
                              &exc, &e);
    if (rc == SL_OK)
        return SL_OK;
    if (exc)
        return refused(s, what, wheel, slot, exc, deadline_s);
    return fail(s, rc, "%s: %s", what, e.msg);
}

static void record(stage *s, int wheel, int op, int slot)
{
    for (int i = 0; i < STAGE_NWHEELS; i++) {
        if (wheel != STAGE_WHEEL_ALL && wheel != i)
            continue;
        s->last[i].op = op;
        s->last[i].slot = slot;
        s->last[i].t0_s = stage_now_s();
    }
}

int stage_home(stage *s, int wheel)
{
    char what[64], wd[32];
    int rc = check_wheel(s, wheel, 1, "homing");
    if (rc != SL_OK)
        return rc;
    snprintf(what, sizeof what, "homing of %s", wheel_desc(wheel, wd, sizeof wd));
    rc = command(s, STAGE_CMD_HOME, wheel, -1, what, call_deadline(s));
    if (rc == SL_OK)
        record(s, wheel, OP_HOME, -1);
    return rc;
}

int stage_move(stage *s, int wheel, int slot)
{
    char what[96], wd[32];
    sl_err e = {0};
    int exc;
    double deadline = call_deadline(s);
    int rc = check_wheel(s, wheel, 0, "move");
    if (rc != SL_OK)
        return rc;
    snprintf(what, sizeof what, "move of %s to slot %d",
             wheel_desc(wheel, wd, sizeof wd), slot);
    /* The slot count comes with the connection's identity check. */
    rc = stage_link_ensure(s->link, deadline, &e);
    if (rc != SL_OK)
        return fail(s, rc, "%s: %s", what, e.msg);
    int slots = stage_link_ident(s->link)->slots[wheel];
    if (slot < 0 || slot >= slots)
        return fail(s, SL_ERANGE, "%s refused: slot out of range 0..%d", what,
                    slots - 1);
    uint16_t t = (uint16_t)slot;
    rc = stage_link_write(s->link, STAGE_REG_WHEEL_BASE(wheel) +
                          STAGE_WREG_TARGET, 1, &t, deadline, &exc, &e);
    if (rc != SL_OK)
        return exc ? refused(s, what, wheel, slot, exc, deadline)
                   : fail(s, rc, "%s: %s", what, e.msg);
    rc = command(s, STAGE_CMD_MOVE, wheel, slot, what, deadline);
    if (rc == SL_OK)
        record(s, wheel, OP_MOVE, slot);
    return rc;
}

int stage_stop(stage *s, int wheel)
{
    char what[64], wd[32];
    int rc = check_wheel(s, wheel, 1, "stop");
    if (rc != SL_OK)
        return rc;
    snprintf(what, sizeof what, "stop of %s", wheel_desc(wheel, wd, sizeof wd));
    rc = command(s, STAGE_CMD_STOP, wheel, -1, what, call_deadline(s));
    if (rc == SL_OK)
        record(s, wheel, OP_NONE, -1);
    return rc;
}

int stage_reset(stage *s, int wheel)
{
    char what[64], wd[32];
    int rc = check_wheel(s, wheel, 1, "reset");
    if (rc != SL_OK)
        return rc;
    snprintf(what, sizeof what, "reset of %s", wheel_desc(wheel, wd, sizeof wd));
    return command(s, STAGE_CMD_RESET, wheel, -1, what, call_deadline(s));
}

static const char *op_desc(const stage *s, int wheel, char *buf, size_t n)
{
    char wd[32];
    const wheel_op *o = &s->last[wheel];
    wheel_desc(wheel, wd, sizeof wd);
    if (o->op == OP_MOVE)
        snprintf(buf, n, "move of %s to slot %d", wd, o->slot);
    else if (o->op == OP_HOME)
        snprintf(buf, n, "homing of %s", wd);
    else
        snprintf(buf, n, "%s", wd);
    return buf;
}

static const char *where(const stage_wheel_status *st, char *buf, size_t n)
{
    if (st->position >= 0)
        snprintf(buf, n, "at slot %d", st->position);
    else
        snprintf(buf, n, "%s", st->homed ? "between slots" : "not homed");
    return buf;
}

static int arrived(const wheel_op *o, const stage_wheel_status *st)
{
    if (st->busy)
        return 0;
    if (o->op == OP_MOVE)
        return st->homed && st->in_position && st->position == o->slot;
    if (o->op == OP_HOME)
        return st->homed && st->in_position;
    return 1; /* nothing asked by this handle: at rest is enough */
}

static int wait_one(stage *s, int wheel, double deadline_s, double t_wait)
{
    const wheel_op *o = &s->last[wheel];
    double t0 = o->op != OP_NONE ? o->t0_s : t_wait, silent_since = -1;
    char what[96], pos[32], why[SL_ERRMSG_MAX] = "no status read yet";
    stage_wheel_status st;
    int seen_busy = 0, have = 0;
    op_desc(s, wheel, what, sizeof what);
    for (;;) {
        sl_err e = {0};
        int exc;
        /* One read is a call: bounded by the call timeout, not the move's,
         * and while the stage is silent by what is left of that. */
        double t_read = stage_now_s();
        double read_by = (silent_since < 0 ? t_read : silent_since) + s->call_ms * 1e-3;
        int rc = read_wheel(s, wheel, &st, read_by < deadline_s ? read_by : deadline_s, &exc,
                            &e);
        double now = stage_now_s();
        if (rc == SL_OK) {
            have = 1;
            silent_since = -1;
            if (st.faulted)
                return fail(s, SL_EDATA, "%s %s (fault %d: %s) after %.1f s",
                            what, st.fault == STAGE_FAULT_STALL ? "stalled"
                                                                : "faulted",
                            st.fault, st.fault_text, now - t0);
            if (arrived(o, &st))
                return SL_OK;
            if (st.busy)
                seen_busy = 1;
            else if (seen_busy || now - t_wait > START_GRACE_S)
                return fail(s, SL_EIO, "%s stopped (%s) after %.1f s", what,
                            where(&st, pos, sizeof pos), now - t0);
        } else if (exc || rc == SL_EFORMAT) {
            return fail(s, rc, "%s: status: %s", what, e.msg);
        } else if (stage_link_outcome(s->link) == STAGE_LINK_LATE) {
            /* No time left to ask: the last status stands. */
        } else if (stage_link_outcome(s->link) == STAGE_LINK_BUSY) {
            /* It answers, busy: the move's timeout bounds that. */
            snprintf(why, sizeof why, "%s", e.msg);
            have = 0;
            silent_since = -1;
        } else {
            /* Link trouble: the read is safe to repeat, so keep polling
             * (the link reconnects with backoff) - for one call timeout.
             * A stage silent for longer is gone or restarted (its move is
             * lost either way): waiting out the move's timeout would only
             * hold the caller. */
            snprintf(why, sizeof why, "%s", e.msg);
            have = 0;
            if (silent_since < 0)
                silent_since = t_read;
            if (now - silent_since >= s->call_ms * 1e-3)
                return fail(s, SL_EIO, "%s not confirmed: no answer from the stage for "
                            "%.1f s: %s", what, now - silent_since, why);
        }
        /* Stop a poll early rather than send one with no time to answer:
         * that would only replace the last status with "deadline". */
        if (now >= deadline_s - POLL_S / 4) {
            if (have)
                return fail(s, SL_EIO, "%s not in position after %.1f s "
                            "(%s, status 0x%X)", what, now - t0,
                            where(&st, pos, sizeof pos), st.status);
            return fail(s, SL_EIO, "%s not confirmed after %.1f s: %s", what,
                        now - t0, why);
        }
        double left = deadline_s - POLL_S / 4 - now;
        stage_sleep_s(left < POLL_S ? left : POLL_S);
    }
}

int stage_wait(stage *s, int wheel, int timeout_ms)
{
    int rc = check_wheel(s, wheel, 1, "wait");
    if (rc != SL_OK)
        return rc;
    double t_wait = stage_now_s();
    double deadline = t_wait + (timeout_ms > 0 ? timeout_ms : s->move_ms) * 1e-3;
    for (int i = 0; i < STAGE_NWHEELS && rc == SL_OK; i++)
        if (wheel == STAGE_WHEEL_ALL || wheel == i)
            rc = wait_one(s, i, deadline, t_wait);
    return rc;
}

int stage_move_wait(stage *s, int wheel, int slot, int timeout_ms)
{
    int rc = stage_move(s, wheel, slot);
    return rc != SL_OK ? rc : stage_wait(s, wheel, timeout_ms);
}
