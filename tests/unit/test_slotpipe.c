/* test_slotpipe.c - the two-group pipeline: every frame filled is made
 * before it is taken, every take task and the done calls see the frames
 * once each, in the order they were filled, on pools of 1 to 3 threads,
 * for any group size and a last group left partial.  As in powspec and
 * bispec, take and done read what make wrote (made[]), not the slot the
 * caller may be filling again (frame[]). */
#include <stdlib.h>
#include <string.h>

#include "base/slotpipe.h"
#include "tcheck.h"

enum { MAXG = 8, NTAKE = 5, NFRAMES = 37 };

typedef struct log {
    int frame[2 * MAXG];  /* the frame each slot holds (set by the filler) */
    int made[2 * MAXG];   /* what make wrote from it: frame + 1000 */
    int taken[NTAKE][NFRAMES], ntaken[NTAKE];
    int done[NFRAMES], ndone, bad;
} log_t;

static void make(void *ctx, int slot)
{
    log_t *l = ctx;
    l->made[slot] = l->frame[slot] + 1000;
}

static void take(void *ctx, int task, int s0, int n)
{
    log_t *l = ctx;
    for (int s = s0; s < s0 + n; s++) {
        if (l->made[s] < 1000 || l->ntaken[task] >= NFRAMES)
            l->bad = 1; /* taken before made, or too often (one writer a task) */
        else
            l->taken[task][l->ntaken[task]++] = l->made[s] - 1000;
    }
}

static void done(void *ctx, int s0, int n)
{
    log_t *l = ctx;
    for (int s = s0; s < s0 + n && l->ndone < NFRAMES; s++)
        l->done[l->ndone++] = l->made[s] - 1000;
    l->bad |= n < 1;
}

/* 0..n-1 in order. */
static int in_order(const int *v, int n, int want)
{
    if (n != want)
        return 0;
    for (int i = 0; i < n; i++)
        if (v[i] != i)
            return 0;
    return 1;
}

TEST(frames_made_then_taken_in_order)
{
    static const slotpipe_ops ops = {make, take, done};
    for (int nt = 1; nt <= 3; nt++) {
        tpool *pool = tpool_new(nt, NULL);
        CHECK(pool, "pool of %d", nt);
        for (int g = 1; pool && g <= MAXG; g++) {
            log_t *l = calloc(1, sizeof *l);
            slotpipe *q = slotpipe_new(pool, g, NTAKE, &ops, l);
            CHECK(q, "slotpipe of %d", g);
            for (int k = 0; q && k < NFRAMES; k++) {
                int s = slotpipe_slot(q);
                CHECK(s >= 0 && s < 2 * g, "slot %d of %d", s, 2 * g);
                l->frame[s] = k;
                slotpipe_filled(q);
                if (k == NFRAMES / 2)
                    slotpipe_drain(q); /* a drain mid-way, as at a batch's end */
            }
            slotpipe_drain(q);
            slotpipe_free(q);
            CHECK(!l->bad, "%d threads, groups of %d: a slot taken before it was made", nt, g);
            for (int task = 0; task < NTAKE; task++)
                CHECK(in_order(l->taken[task], l->ntaken[task], NFRAMES), "%d threads, groups "
                      "of %d: take task %d saw %d frames, not 0..%d in order", nt, g, task,
                      l->ntaken[task], NFRAMES - 1);
            CHECK(in_order(l->done, l->ndone, NFRAMES), "%d threads, groups of %d: done saw %d "
                  "frames, not 0..%d in order", nt, g, l->ndone, NFRAMES - 1);
            free(l);
        }
        tpool_free(pool);
    }
    slotpipe_free(NULL);
    CHECK(!slotpipe_new(NULL, 4, 1, &ops, NULL), "a pipeline without a pool");
}

TC_MAIN(TC_CASE(frames_made_then_taken_in_order))
