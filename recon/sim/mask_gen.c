/* mask_gen.c - mask_generate (mask.h): the least-redundant layout search
 * (simulated annealing), split from mask.c, which builds, reads, writes
 * and renders masks. */
#include "mask.h"
#include "mask_int.h"

#include "base/rng.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- generation -------------------------------------------------------- */

/* Annealing energy of one redundant pair: 1 (the count) plus weight x how
 * deep the overlap is (1 - q/d^2, in (0, 1]), so that moves which separate
 * patches without yet clearing them are rewarded and the search is not
 * blind on the integer count's plateaus.  The weight and the schedule were
 * tuned on seeds 17..32 (weights 0..5, T0 1.5..5, T1 0.03..0.5). */
#define GEN_DEPTH_WEIGHT 3.0
/* Schedule: temperature and Gaussian step size fall geometrically; a
 * fraction of moves jumps anywhere in the disk to escape local minima. */
#define GEN_T0 3.0
#define GEN_T1 0.3
#define GEN_JUMP_P 0.1
#define GEN_PLACE_TRIES 1000   /* per hole, before starting the layout over */
#define GEN_PLACE_LAYOUTS 200  /* layouts before declaring it impossible */

#define GEN_MAXB (MASK_GEN_MAX_HOLES * (MASK_GEN_MAX_HOLES - 1) / 2)

/* The search state, one ~40 KB allocation with room for the largest
 * layout; small enough that the O(n * nb) move scans stay in L1/L2. */
typedef struct gen {
    int n, nb;                          /* holes, baselines */
    double r, r2, s2, d2;               /* disk radius, squared limits */
    double x[MASK_GEN_MAX_HOLES], y[MASK_GEN_MAX_HOLES]; /* current */
    double bestx[MASK_GEN_MAX_HOLES], besty[MASK_GEN_MAX_HOLES];
    double ox[MASK_GEN_MAX_HOLES], oy[MASK_GEN_MAX_HOLES]; /* old and */
    double nx[MASK_GEN_MAX_HOLES], ny[MASK_GEN_MAX_HOLES]; /* moved ones */
    double bx[GEN_MAXB], by[GEN_MAXB];  /* baselines, pair order */
} gen;

/* Add the count and annealing energy of one baseline pair's test value. */
static inline void gen_pen(const gen *g, double q, long *count,
                           double *energy)
{
    if (q < g->d2) {
        ++*count;
        *energy += 1.0 + GEN_DEPTH_WEIGHT * (1.0 - q / g->d2);
    }
}

/* Index of baseline (i, j), i < j, in pair order. */
static inline int gen_pair(int n, int i, int j)
{
    return i * (2 * n - i - 1) / 2 + (j - i - 1);
}

/* May hole h move to (x, y)?  Checked against the first nset holes. */
static int gen_ok(const gen *g, int h, int nset, double x, double y)
{
    if (x * x + y * y > g->r2)
        return 0;
    for (int j = 0; j < nset; j++) {
        double dx = x - g->x[j], dy = y - g->y[j];
        if (j != h && dx * dx + dy * dy < g->s2)
            return 0;
    }
    return 1;
}

static void gen_uniform(const gen *g, rng *r, double *x, double *y)
{
    do { /* rejection from the square: no trig, exactly uniform */
        *x = (2 * rng_uniform(r) - 1) * g->r;
        *y = (2 * rng_uniform(r) - 1) * g->r;
    } while (*x * *x + *y * *y > g->r2);
}

/* Random sequential placement; -1 if GEN_PLACE_LAYOUTS attempts fail. */
static int gen_place(gen *g, rng *r)
{
    for (int layout = 0; layout < GEN_PLACE_LAYOUTS; layout++) {
        int h = 0;
        for (int tries = 0; h < g->n && tries < GEN_PLACE_TRIES; tries++) {
            double x, y;
            gen_uniform(g, r, &x, &y);
            if (gen_ok(g, h, h, x, y)) {
                g->x[h] = x;
                g->y[h] = y;
                h++;
                tries = -1;
            }
        }
        if (h == g->n)
            return 0;
    }
    return -1;
}

/* Keep the layout if it beats the best so far: by count, then energy. */
static void gen_keep(gen *g, long cur, double ecur, long *bc, double *be)
{
    if (cur < *bc || (cur == *bc && ecur < *be - 1e-9)) {
        memcpy(g->bestx, g->x, sizeof g->x);
        memcpy(g->besty, g->y, sizeof g->y);
        *bc = cur;
        *be = ecur;
    }
}

/* Anneal from the current layout for iters moves, keeping the best layout
 * seen in bestx/besty (count *bc, energy *be). */
static void gen_anneal(gen *g, rng *r, int iters, long *bc, double *be)
{
    int n = g->n, nb = g->nb;
    long cur = 0;
    double ecur = 0;
    baselines(g->x, g->y, n, g->bx, g->by);
    for (int k = 0; k < nb; k++)
        for (int l = k + 1; l < nb; l++)
            gen_pen(g, pair_q(g->bx[k], g->by[k], g->bx[l], g->by[l]), &cur,
                    &ecur);
    gen_keep(g, cur, ecur, bc, be);
    double sig0 = 0.2 * g->r, sig1 = 0.02 * sqrt(g->d2);
    for (int it = 0; it < iters && cur > 0; it++) {
        double f = (double)it / iters;
        double temp = GEN_T0 * pow(GEN_T1 / GEN_T0, f);
        double sig = sig0 * pow(sig1 / sig0, f);
        int h = (int)(rng_uniform(r) * n);
        double px, py;
        if (rng_uniform(r) < GEN_JUMP_P)
            gen_uniform(g, r, &px, &py);
        else {
            px = g->x[h] + sig * rng_normal(r);
            py = g->y[h] + sig * rng_normal(r);
        }
        if (!gen_ok(g, h, n, px, py))
            continue;
        /* The move changes only the n-1 baselines touching h (o -> n):
         * the energy change is theirs against the rest plus among
         * themselves, O(n * nb) instead of O(nb^2) for a recount. */
        long dco = 0, dcn = 0;
        double deo = 0, den = 0;
        for (int j = 0, c = 0; j < n; j++) {
            if (j == h)
                continue;
            int k = j < h ? gen_pair(n, j, h) : gen_pair(n, h, j);
            double sgn = j < h ? 1.0 : -1.0; /* b = c_later - c_earlier */
            g->ox[c] = g->bx[k];
            g->oy[c] = g->by[k];
            g->nx[c] = sgn * (px - g->x[j]);
            g->ny[c++] = sgn * (py - g->y[j]);
        }
        for (int i = 0, l = 0; i < n; i++)
            for (int j = i + 1; j < n; j++, l++) {
                if (i == h || j == h)
                    continue;
                for (int c = 0; c < n - 1; c++) {
                    gen_pen(g, pair_q(g->ox[c], g->oy[c], g->bx[l], g->by[l]),
                            &dco, &deo);
                    gen_pen(g, pair_q(g->nx[c], g->ny[c], g->bx[l], g->by[l]),
                            &dcn, &den);
                }
            }
        for (int c = 0; c < n - 1; c++)
            for (int c2 = c + 1; c2 < n - 1; c2++) {
                gen_pen(g, pair_q(g->ox[c], g->oy[c], g->ox[c2], g->oy[c2]),
                        &dco, &deo);
                gen_pen(g, pair_q(g->nx[c], g->ny[c], g->nx[c2], g->ny[c2]),
                        &dcn, &den);
            }
        double de = den - deo;
        if (de > 0 && rng_uniform(r) >= exp(-de / temp))
            continue;
        g->x[h] = px;
        g->y[h] = py;
        for (int j = 0, c = 0; j < n; j++)
            if (j != h) {
                int k = j < h ? gen_pair(n, j, h) : gen_pair(n, h, j);
                g->bx[k] = g->nx[c];
                g->by[k] = g->ny[c++];
            }
        cur += dcn - dco;
        ecur += de;
        gen_keep(g, cur, ecur, bc, be);
    }
}

void mask_gen_defaults(mask_gen_opts *o)
{
    o->nholes = 17;
    o->hole_diameter_m = 0.10;
    o->max_baseline_m = 1.0;
    o->min_spacing_m = 0.20;
    o->seed = 17;
    o->iterations = 3500;
}

int mask_generate(mask **out, const mask_gen_opts *o, sl_err *err)
{
    *out = NULL;
    if (o->nholes < 2 || o->nholes > MASK_GEN_MAX_HOLES || o->iterations < 0)
        return sl_seterr(err, SL_EINVAL,
                         "mask_generate: %d holes, %d iterations (need "
                         "2..%d holes, iterations >= 0)",
                         o->nholes, o->iterations, MASK_GEN_MAX_HOLES);
    if (!(isfinite(o->hole_diameter_m) && o->hole_diameter_m > 0 &&
          isfinite(o->max_baseline_m) &&
          o->min_spacing_m >= o->hole_diameter_m &&
          o->max_baseline_m >= o->min_spacing_m))
        return sl_seterr(err, SL_EINVAL,
                         "mask_generate: need 0 < hole diameter (%g m) <= "
                         "min spacing (%g m) <= max baseline (%g m)",
                         o->hole_diameter_m, o->min_spacing_m,
                         o->max_baseline_m);
    int n = o->nholes, rc = SL_OK;
    gen *g = malloc(sizeof *g);
    if (!g)
        return sl_seterr(err, SL_ENOMEM, "mask_generate: out of memory");
    g->n = n;
    g->nb = n * (n - 1) / 2;
    g->r = 0.5 * o->max_baseline_m;
    g->r2 = g->r * g->r;
    g->s2 = o->min_spacing_m * o->min_spacing_m;
    g->d2 = o->hole_diameter_m * o->hole_diameter_m;
    long best_c = LONG_MAX;
    double best_e = INFINITY;
    for (int rs = 0; rs < MASK_GEN_RESTARTS; rs++) {
        rng rp, ra; /* separate streams: placement does not depend on the
                     * iteration count, so iterations=0 shows the start */
        rng_init(&rp, o->seed, 2 * (uint64_t)rs);
        rng_init(&ra, o->seed, 2 * (uint64_t)rs + 1);
        if (gen_place(g, &rp)) {
            rc = sl_seterr(err, SL_ERANGE,
                           "mask_generate: cannot place %d holes %g m apart "
                           "with centres in a %g m disk",
                           n, o->min_spacing_m, o->max_baseline_m);
            goto done;
        }
        gen_anneal(g, &ra, o->iterations, &best_c, &best_e);
    }
    /* mask_new_holes recounts from scratch: the reported redundancy does not
     * rest on the annealer's incremental bookkeeping, which must agree. */
    *out = mask_new_holes(g->bestx, g->besty, n, o->hole_diameter_m, err);
    if (!*out)
        rc = err && err->code ? err->code : SL_ENOMEM;
    else if (mask_redundancy(*out) != best_c) {
        rc = sl_seterr(err, SL_EDATA,
                       "mask_generate: internal error: annealer counted %ld "
                       "redundant pairs, recount finds %ld",
                       best_c, mask_redundancy(*out));
        mask_free(*out);
        *out = NULL;
    }
done:
    free(g);
    return rc;
}
