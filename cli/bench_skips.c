/* bench_skips.c - `specklab bench --skips-report`: what each skip of
 * saves and costs, and where auto lands (bench_cli.h).
 *
 * Data sets (100 frames of 200^2, binary 6 lambda/D, dm 1, noiseless
 * unless noted), each chosen to exercise one skip:
 *   binary            crop and angles (the cloud is ~90 px across);
 *   binary bad        3 empty and 3 saturated frames injected: reject;
 *   binary os2        sampled 2x finer than Nyquist, so the support ends
 *                     at ~0.25 cycles/px: support;
 *   binary, 1000 ph   the lab's photon level: auto where noise decides.
 * On each: tsm-fourier 180 without and with each single skip, auto
 * (target 0.1) with every skip and with each one left out, and on the
 * first data set also the spatial tsm 180, direct without and with the
 * crop, and auto at targets 0.06 and 0.2 for the front.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "bench_cli.h"
#include "pipeline/pipeline.h"

enum { BLOCK_SKIPS = 4 };

static const int single[] = {PIPE_SKIP_REJECT, PIPE_SKIP_CROP,
                             PIPE_SKIP_SUPPORT, PIPE_SKIP_ANGLES};

int bcli_run_skips(bcli_ctx *c)
{
    bcli_config cf[24];
    int n = 0, rc = 0;
    for (int pass = 0; pass < 4 && !rc; pass++) {
        bench_sim d;
        bench_sim_defaults(&d);
        d.width = d.height = 200;
        d.nframes = 100;
        d.bad_frames = pass == 1 ? 3 : 0;
        d.oversample = pass == 2 ? 2 : 0;
        d.photons = pass == 3 ? 1000 : 0;
        n = 0;
        cf[n++] = (bcli_config){PIPE_TSM_FOURIER, 180, 0, 0, 0, 0};
        for (int k = 0; k < 4; k++)
            cf[n++] = (bcli_config){PIPE_TSM_FOURIER, 180, 0, single[k], 0, 0};
        cf[n++] = (bcli_config){PIPE_AUTO, 0, 0, PIPE_SKIP_ALL, 0.1, 0};
        for (int k = 0; k < 4; k++)
            cf[n++] = (bcli_config){PIPE_AUTO, 0, 0, PIPE_SKIP_ALL & ~single[k], 0.1, 0};
        if (pass == 0) {
            cf[n++] = (bcli_config){PIPE_TSM, 180, 0, 0, 0, 0};
            cf[n++] = (bcli_config){PIPE_DIRECT, 0, 0, 0, 0, 0};
            cf[n++] = (bcli_config){PIPE_DIRECT, 0, 0, PIPE_SKIP_CROP, 0, 0};
            cf[n++] = (bcli_config){PIPE_AUTO, 0, 0, PIPE_SKIP_ALL, 0.06, 0};
            cf[n++] = (bcli_config){PIPE_AUTO, 0, 0, PIPE_SKIP_ALL, 0.2, 0};
        }
        rc = bcli_run_dataset(c, &d, cf, n, BLOCK_SKIPS);
    }
    return rc;
}

static int same_data(const bcli_row *a, const bcli_row *b)
{
    return a->group == b->group;
}

static const bcli_row *find(GArray *rows, const bcli_row *data, int method,
                            int skips, double target)
{
    for (guint i = 0; i < rows->len; i++) {
        const bcli_row *r = &g_array_index(rows, bcli_row, i);
        if (r->block == BLOCK_SKIPS && same_data(r, data) && r->method == method &&
            r->skips == skips && (method != PIPE_AUTO || r->target == target) &&
            r->status == SL_OK)
            return r;
    }
    return NULL;
}

static void delta_row(const char *what, const bcli_row *off, const bcli_row *on)
{
    if (!off || !on)
        return;
    double dt = off->t.wall_s - on->t.wall_s, dc = off->t.cpu_s - on->t.cpu_s;
    printf("  %-34s %7.3f -> %7.3f s (CPU %6.3f -> %6.3f, saves %4.0f%%)  "
           "1-c %.4f -> %.4f (%+.4f)", what, off->t.wall_s, on->t.wall_s,
           off->t.cpu_s, on->t.cpu_s, 100 * dc / off->t.cpu_s, 1 - off->s.c,
           1 - on->s.c, off->s.c - on->s.c);
    if (isfinite(on->s.sep_err_px) && isfinite(off->s.sep_err_px))
        printf("  dsep %+.3f -> %+.3f, dPA %+.2f -> %+.2f", off->s.sep_err_px,
               on->s.sep_err_px, off->s.pa_err_deg, on->s.pa_err_deg);
    printf("%s\n", dt < 0 ? "  (slower)" : "");
}

static void versus(const bcli_row *a, const bcli_row *f, const char *name)
{
    if (!a || !f)
        return;
    printf("  auto vs %-16s time x1/%.1f (CPU x1/%.1f); 1-c %.4f vs %.4f; "
           "dsep %+.3f vs %+.3f px, dPA %+.2f vs %+.2f deg\n", name,
           f->t.wall_s / a->t.wall_s, f->t.cpu_s / a->t.cpu_s, 1 - a->s.c,
           1 - f->s.c, a->s.sep_err_px, f->s.sep_err_px, a->s.pa_err_deg,
           f->s.pa_err_deg);
}

void bcli_print_skips(GArray *rows)
{
    static const char *names[] = {"reject", "crop", "support", "angles"};
    int shown[64], ns = 0;
    printf("\n# Skips: each on/off, median wall and CPU time, "
           "error against the cophased image\n");
    for (guint i = 0; i < rows->len; i++) {
        const bcli_row *d = &g_array_index(rows, bcli_row, i);
        int seen = d->block != BLOCK_SKIPS;
        for (int k = 0; k < ns && !seen; k++)
            seen = shown[k] == d->group;
        if (seen || ns == 64)
            continue;
        shown[ns++] = d->group;
        printf("%s%s%s, %g photons:\n", d->inject ? "binary with 3 empty + 3 "
               "saturated frames" : "binary 6/1", d->oversample > 1 ?
               ", 2x oversampled" : "", "", d->photons);
        const bcli_row *base = find(rows, d, PIPE_TSM_FOURIER, 0, 0);
        for (int k = 0; k < 4; k++) {
            char what[64];
            snprintf(what, sizeof what, "tsm-fourier 180 + %s", names[k]);
            delta_row(what, base, find(rows, d, PIPE_TSM_FOURIER, single[k], 0));
        }
        delta_row("direct + crop", find(rows, d, PIPE_DIRECT, 0, 0),
                  find(rows, d, PIPE_DIRECT, PIPE_SKIP_CROP, 0));
        const bcli_row *au = find(rows, d, PIPE_AUTO, PIPE_SKIP_ALL, 0.1);
        for (int k = 0; k < 4; k++) {
            char what[64];
            snprintf(what, sizeof what, "auto 0.1, %s off -> on", names[k]);
            delta_row(what, find(rows, d, PIPE_AUTO, PIPE_SKIP_ALL & ~single[k], 0.1), au);
        }
        if (au) {
            printf("  auto 0.1 chose: %s; rejected %.0f frame(s)\n", au->t.chosen,
                   au->t.rejected);
            versus(au, base, "tsm-fourier 180");
            versus(au, find(rows, d, PIPE_TSM, 0, 0), "tsm 180");
            printf("  (the metric's own error on the cophased image: dsep %+.3f "
                   "px, dPA %+.2f deg)\n", au->floor.sep_err_px, au->floor.pa_err_deg);
        }
    }
}

void bcli_print_auto(GArray *rows)
{
    int header = 0;
    for (guint i = 0; i < rows->len; i++) {
        const bcli_row *a = &g_array_index(rows, bcli_row, i);
        if (a->method != PIPE_AUTO || a->status != SL_OK)
            continue;
        if (!header++)
            printf("\n# Where auto lands on its data set's Pareto front of "
                   "(wall time, 1 - c)\n");
        char cfg[80], dom[80] = "";
        bcli_config_label(a, cfg, sizeof cfg);
        const bcli_row *best = NULL;
        for (guint j = 0; j < rows->len && !a->front; j++) {
            const bcli_row *b = &g_array_index(rows, bcli_row, j);
            if (b->group != a->group || !b->front || b->status != SL_OK ||
                b->t.wall_s > a->t.wall_s || b->s.c < a->s.c)
                continue;
            if (!best || b->s.c > best->s.c)
                best = b;
        }
        if (best)
            bcli_config_label(best, dom, sizeof dom);
        printf("  %-34s %7.3f s  1-c %.4f (predicted %.3f, target %g): %s%s\n",
               cfg, a->t.wall_s, 1 - a->s.c, a->t.pred_error,
               a->target > 0 ? a->target : 0.1,
               a->front ? "ON the front" : "dominated by ", a->front ? "" : dom);
    }
}
