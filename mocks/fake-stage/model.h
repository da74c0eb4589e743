/* model.h - the fake stage's wheels: motion in time, homing, commands,
 * faults, and the register image (drivers/stage_map.h + fake_regs.h).
 *
 * No sockets here: main.c feeds decoded requests in.  Motion is evaluated
 * lazily from the monotonic clock (fake_model_advance), so the model costs
 * nothing between requests and needs no thread.
 */
#ifndef SL_FAKE_MODEL_H
#define SL_FAKE_MODEL_H

#include <stdint.h>

#include <modbus.h>

#include "fake_regs.h"
#include "stage_map.h"

typedef struct fake_opts {
    int slots[STAGE_NWHEELS]; /* slots per wheel (default 6, 6) */
    int step_ms;              /* time per slot step (default 100) */
    int home_ms;              /* homing time (default 2 * step_ms) */
    int magic;                /* register 0 (default STAGE_MAGIC) */
    /* initial fault switches (the registers of fake_regs.h) */
    int busy_count, busy, stall, stall_ms, slow_ms;
    int disconnect_after, disconnect;
    int fault[STAGE_NWHEELS];
} fake_opts;

enum { FW_IDLE, FW_MOVING, FW_HOMING };

typedef struct fake_wheel {
    int slots, step_ms;
    int homed;
    double pos;    /* slot position, fractional between slots */
    int motion;    /* FW_* */
    double t0_s;   /* motion start */
    double from;   /* position at motion start */
    int target;    /* slot a MOVE goes to */
    int stalls;    /* this motion never completes */
    int fault;     /* STAGE_FAULT_* */
} fake_wheel;

typedef struct fake_model {
    fake_wheel w[STAGE_NWHEELS];
    int home_ms;
    modbus_mapping_t *map; /* FAKE_NREGS holding registers, owned */
} fake_model;

void fake_opts_defaults(fake_opts *o);
/* 0, or -1 with errno (allocation) */
int fake_model_init(fake_model *m, const fake_opts *o);
void fake_model_fini(fake_model *m);
/* Bring motion up to now_s and refresh the read-only registers. */
void fake_model_advance(fake_model *m, double now_s);
/* Check a write of n values at addr (before it is stored): 0 if it may
 * proceed, else the Modbus exception code to answer with. */
int fake_model_check_write(fake_model *m, int addr, int n,
                           const uint16_t *values, double now_s);
/* After the write was stored: run the command / fault triggers it holds. */
void fake_model_apply_write(fake_model *m, int addr, int n, double now_s);

#endif
