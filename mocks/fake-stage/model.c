/* model.c - see model.h. */
#include "model.h"

#include <math.h>
#include <string.h>

void fake_opts_defaults(fake_opts *o)
{
    memset(o, 0, sizeof *o);
    o->slots[STAGE_WHEEL_SCREEN] = 6;
    o->slots[STAGE_WHEEL_MASK] = 6;
    o->step_ms = 100;
    o->home_ms = -1; /* = 2 * step_ms */
    o->magic = STAGE_MAGIC;
    o->stall_ms = 1000;
}

static uint16_t *reg(fake_model *m, int addr)
{
    return &m->map->tab_registers[addr];
}

static int wreg(int w, int r)
{
    return STAGE_REG_WHEEL_BASE(w) + r;
}

/* A wheel sits on a slot when homed, at rest and at an integer position;
 * anywhere else POSITION reads STAGE_POSITION_UNKNOWN. */
static int position_reg(const fake_wheel *w)
{
    double r = floor(w->pos + 0.5);
    if (!w->homed || w->motion != FW_IDLE || fabs(w->pos - r) > 1e-6)
        return STAGE_POSITION_UNKNOWN;
    return (int)r;
}

static void sync_registers(fake_model *m)
{
    for (int i = 0; i < STAGE_NWHEELS; i++) {
        const fake_wheel *w = &m->w[i];
        int p = position_reg(w);
        unsigned st = 0;
        if (w->motion != FW_IDLE)
            st |= STAGE_ST_BUSY;
        if (p != STAGE_POSITION_UNKNOWN)
            st |= STAGE_ST_INPOS;
        if (w->homed)
            st |= STAGE_ST_HOMED;
        if (w->fault)
            st |= STAGE_ST_FAULT;
        *reg(m, wreg(i, STAGE_WREG_SLOTS)) = (uint16_t)w->slots;
        *reg(m, wreg(i, STAGE_WREG_POSITION)) = (uint16_t)p;
        *reg(m, wreg(i, STAGE_WREG_STATUS)) = (uint16_t)st;
        *reg(m, wreg(i, STAGE_WREG_FAULT)) = (uint16_t)w->fault;
        *reg(m, wreg(i, STAGE_WREG_MOVE_MS)) = (uint16_t)w->step_ms;
    }
}

int fake_model_init(fake_model *m, const fake_opts *o)
{
    memset(m, 0, sizeof *m);
    m->map = modbus_mapping_new(0, 0, FAKE_NREGS, 0);
    if (!m->map)
        return -1;
    m->home_ms = o->home_ms >= 0 ? o->home_ms : 2 * o->step_ms;
    for (int i = 0; i < STAGE_NWHEELS; i++) {
        fake_wheel *w = &m->w[i];
        w->slots = o->slots[i];
        w->step_ms = o->step_ms;
        w->fault = o->fault[i];
        /* Unhomed at power-up: moves are refused until HOME. */
        w->homed = 0;
        w->motion = FW_IDLE;
    }
    *reg(m, STAGE_REG_MAGIC) = (uint16_t)o->magic;
    *reg(m, STAGE_REG_VERSION) = STAGE_MAP_VERSION;
    *reg(m, STAGE_REG_NWHEELS) = STAGE_NWHEELS;
    *reg(m, FAKE_REG_BUSY_COUNT) = (uint16_t)o->busy_count;
    *reg(m, FAKE_REG_BUSY) = (uint16_t)o->busy;
    *reg(m, FAKE_REG_STALL) = (uint16_t)o->stall;
    *reg(m, FAKE_REG_STALL_MS) = (uint16_t)o->stall_ms;
    *reg(m, FAKE_REG_SLOW_MS) = (uint16_t)o->slow_ms;
    *reg(m, FAKE_REG_DISCONNECT_AFTER) = (uint16_t)o->disconnect_after;
    *reg(m, FAKE_REG_DISCONNECT) = (uint16_t)o->disconnect;
    sync_registers(m);
    return 0;
}

void fake_model_fini(fake_model *m)
{
    if (m->map)
        modbus_mapping_free(m->map);
    m->map = NULL;
}

void fake_model_advance(fake_model *m, double now_s)
{
    double stall_s = *reg(m, FAKE_REG_STALL_MS) * 1e-3;
    for (int i = 0; i < STAGE_NWHEELS; i++) {
        fake_wheel *w = &m->w[i];
        if (w->motion == FW_IDLE)
            continue;
        double el = now_s - w->t0_s;
        if (w->stalls) {
            /* Stuck where it started slipping: busy until the stall
             * detector gives up, then faulted and still off-slot. */
            if (el >= stall_s) {
                w->fault = STAGE_FAULT_STALL;
                w->motion = FW_IDLE;
            }
            continue;
        }
        if (w->motion == FW_MOVING) {
            double dur_s = fabs(w->target - w->from) * w->step_ms * 1e-3;
            if (el >= dur_s) {
                w->pos = w->target;
                w->motion = FW_IDLE;
            } else {
                w->pos = w->from + (w->target - w->from) * (el / dur_s);
            }
        } else if (el >= m->home_ms * 1e-3) {
            w->homed = 1;
            w->pos = 0;
            w->motion = FW_IDLE;
        }
    }
    sync_registers(m);
}

static int writable(int a)
{
    if (a == STAGE_REG_COMMAND || a == STAGE_REG_CMD_WHEEL)
        return 1;
    for (int w = 0; w < STAGE_NWHEELS; w++)
        if (a == wreg(w, STAGE_WREG_TARGET))
            return 1;
    return a >= FAKE_REG_FIRST && a <= FAKE_REG_LAST;
}

/* The value register a will hold once the write [addr, addr+n) lands. */
static unsigned proposed(fake_model *m, int a, int addr, int n,
                         const uint16_t *values)
{
    return a >= addr && a < addr + n ? values[a - addr] : *reg(m, a);
}

static int check_command(fake_model *m, unsigned cmd, unsigned wheel,
                         const unsigned *target)
{
    if (cmd == 0)
        return 0; /* writing 0 is a no-op */
    if (cmd < STAGE_CMD_HOME || cmd > STAGE_CMD_RESET)
        return MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE;
    if (wheel >= STAGE_NWHEELS && wheel != STAGE_WHEEL_ALL)
        return MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE;
    for (int i = 0; i < STAGE_NWHEELS; i++) {
        const fake_wheel *w = &m->w[i];
        if (wheel != STAGE_WHEEL_ALL && (int)wheel != i)
            continue;
        if (cmd == STAGE_CMD_HOME && w->fault)
            return MODBUS_EXCEPTION_SLAVE_OR_SERVER_FAILURE;
        if (cmd == STAGE_CMD_MOVE) {
            if (w->fault)
                return MODBUS_EXCEPTION_SLAVE_OR_SERVER_FAILURE;
            if (!w->homed || target[i] >= (unsigned)w->slots)
                return MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE;
        }
    }
    return 0;
}

int fake_model_check_write(fake_model *m, int addr, int n,
                           const uint16_t *values, double now_s)
{
    if (addr < 0 || n < 1 || addr + n > FAKE_NREGS)
        return MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS;
    for (int a = addr; a < addr + n; a++)
        if (!writable(a))
            return MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS;
    if (STAGE_REG_COMMAND < addr || STAGE_REG_COMMAND >= addr + n)
        return 0;
    fake_model_advance(m, now_s);
    unsigned target[STAGE_NWHEELS];
    for (int i = 0; i < STAGE_NWHEELS; i++)
        target[i] = proposed(m, wreg(i, STAGE_WREG_TARGET), addr, n, values);
    return check_command(m, proposed(m, STAGE_REG_COMMAND, addr, n, values),
                         proposed(m, STAGE_REG_CMD_WHEEL, addr, n, values),
                         target);
}

static void run_command(fake_model *m, fake_wheel *w, int i, unsigned cmd,
                        double now_s)
{
    int stall = *reg(m, FAKE_REG_STALL) != 0;
    switch (cmd) {
    case STAGE_CMD_HOME:
        w->homed = 0;
        w->motion = FW_HOMING;
        w->t0_s = now_s;
        w->stalls = stall;
        break;
    case STAGE_CMD_MOVE: {
        int target = *reg(m, wreg(i, STAGE_WREG_TARGET));
        double d = target - w->pos;
        w->from = w->pos;
        w->target = target;
        w->t0_s = now_s;
        w->stalls = stall && d != 0;
        w->motion = d != 0 ? FW_MOVING : FW_IDLE;
        if (w->stalls) /* slips half a step off the slot, then sticks */
            w->pos += d > 0 ? fmin(0.5, d) : fmax(-0.5, d);
        else if (d == 0)
            w->pos = target;
        break;
    }
    case STAGE_CMD_STOP:
        /* A running move settles on the nearest detent; a stalled one
         * stays where it stuck; homing is abandoned (still unhomed). */
        if (w->motion == FW_MOVING && !w->stalls)
            w->pos = floor(w->pos + 0.5);
        w->motion = FW_IDLE;
        break;
    case STAGE_CMD_RESET:
        w->fault = STAGE_FAULT_NONE;
        break;
    default:
        break;
    }
}

static void inject_fault(fake_wheel *w, int code)
{
    w->motion = FW_IDLE; /* the drive stops where it is */
    w->fault = code;
    if (code == STAGE_FAULT_ENCODER)
        w->homed = 0;
}

void fake_model_apply_write(fake_model *m, int addr, int n, double now_s)
{
    fake_model_advance(m, now_s);
    for (int i = 0; i < STAGE_NWHEELS; i++) {
        int a = FAKE_REG_FAULT_SCREEN + i;
        if (a >= addr && a < addr + n) {
            inject_fault(&m->w[i], *reg(m, a));
            *reg(m, a) = 0;
        }
    }
    if (STAGE_REG_COMMAND >= addr && STAGE_REG_COMMAND < addr + n) {
        unsigned cmd = *reg(m, STAGE_REG_COMMAND);
        unsigned wheel = *reg(m, STAGE_REG_CMD_WHEEL);
        for (int i = 0; i < STAGE_NWHEELS; i++)
            if (wheel == STAGE_WHEEL_ALL || (int)wheel == i)
                run_command(m, &m->w[i], i, cmd, now_s);
        *reg(m, STAGE_REG_COMMAND) = 0; /* write-only: reads 0 */
    }
    sync_registers(m);
}
