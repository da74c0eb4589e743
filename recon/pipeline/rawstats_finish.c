/* rawstats_finish.c - rawstats.h's verdicts from the sums rawstats.c
 * made: saturation, the long exposure and its noise, stuck, hot and dead
 * pixels, the sky, and the speckle cloud. */
#include "rawstats_int.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "base/stats.h"
#include "nbr8.h"

static int is_adc_max(double v, double quantum)
{
    double q = quantum >= 1 ? quantum : 1;
    for (int k = 8; k <= 16; k++) {
        double top = ldexp(1.0, k) - 1;
        if (v == top || v == top * q)
            return 1;
    }
    return 0;
}

static void find_saturation(rawstats *r)
{
    rawstats_result *s = &r->res;
    double v = r->gmax;
    if (!isfinite(v) || !(v > 0))
        return;
    if (r->code_max > 0 && v >= r->code_max)
        s->sat_level = r->code_max, s->sat_source = RAWSTATS_SAT_TYPE;
    else if (r->integer_valued && r->n_at_gmax >= 2 && is_adc_max(v, r->quantum))
        s->sat_level = v, s->sat_source = RAWSTATS_SAT_ADC;
    else if (r->integer_valued && r->nflat_at_gmax >= 2)
        s->sat_level = v, s->sat_source = RAWSTATS_SAT_FLAT;
}

/* Pixels [i0, i1)'s long exposure M and temporal rms S. */
static void moments(const rawstats *r, float *M, float *S, size_t i0, size_t i1)
{
    for (size_t i = i0; i < i1; i++) {
        double c = r->nfull + r->cnt[i];
        double m = c > 0 ? r->s1[i] / c : 0;
        M[i] = (float)m;
        S[i] = c > 0 ? (float)sqrt(fmax(r->s2[i] / c - m * m, 0)) : 0.0f;
    }
}

/* rawstats_finish's per-pixel passes, over the bands of rows: the long
 * exposure and rms (pass 0), then their neighbours' median and mean
 * (pass 1, which reads the rows either side of a band).  Serially they
 * were half of finish: 14 of 23 ms at 512^2. */
typedef struct finish_job {
    const rawstats *r;
    float *M, *S, *mloc, *sloc;
    int pass;
    atomic_int next;
} finish_job;

static void finish_run(void *ctx, int tid, int nthr)
{
    finish_job *j = ctx;
    const rawstats *r = j->r;
    (void)tid, (void)nthr;
    for (int b; (b = atomic_fetch_add(&j->next, 1)) < RS_BANDS;) {
        int y0 = band_row(r->h, b), y1 = band_row(r->h, b + 1);
        if (j->pass == 0) {
            moments(r, j->M, j->S, (size_t)y0 * r->w, (size_t)y1 * r->w);
        } else {
            nbr8_median(j->M, r->w, r->h, y0, y1, j->mloc);
            nbr8_mean(j->S, r->w, r->h, y0, y1, j->sloc);
        }
    }
}

/* The finish's per-pixel passes in bands of rows (rawstats_run_bands).
 * The medians among them are stats_median_where's, on the pool: its
 * radix passes over the selection in place of a serial copy and select
 * (3 medians and 2 more over ~0.25 M pixels were ~3 ms of one thread at
 * 512^2, the other threads idle). */
enum { CLOUD_BINS = 512 };
typedef struct band_job {
    rawstats *r;
    const float *M, *S, *mloc, *sloc;
    float *scratch;           /* per pixel: a value for a median, or NaN */
    double bg, sigma_t, thr;
    int nstuck[RS_BANDS], nhot[RS_BANDS], ndead[RS_BANDS];
    double part[RS_BANDS];     /* per band: the max (is_static), the flux (rings) */
    double cx, cy, scale, cut; /* find_cloud's */
    double (*acc)[CLOUD_BINS];
    atomic_int next;
} band_job;

/* tpool job: rows of the bands claimed marked sky (a pixel's own test,
 * the same on any thread). */
static void sky_run(void *ctx, int tid, int nthr)
{
    band_job *j = ctx;
    rawstats *r = j->r;
    int w = r->w, h = r->h;
    (void)tid, (void)nthr;
    for (int b; (b = atomic_fetch_add(&j->next, 1)) < RS_BANDS;)
        for (int y = band_row(h, b); y < band_row(h, b + 1); y++)
            for (int x = 0; x < w; x++) {
                double s = 0;
                int c = 0;
                for (int dy = -1; dy <= 1; dy++)
                    for (int dx = -1; dx <= 1; dx++) {
                        int xx = x + dx, yy = y + dy;
                        if (xx >= 0 && yy >= 0 && xx < w && yy < h)
                            s += j->M[(size_t)yy * w + xx], c++;
                    }
                size_t i = (size_t)y * w + x;
                r->sky[i] = !r->bad[i] && s / c <= j->thr;
                j->scratch[i] = r->sky[i] ? j->S[i] : NAN;
            }
}

/* Sky: pixels whose 3x3-smoothed long exposure is within the background's
 * noise; their mean level and temporal rms.  bg is the long exposure's
 * 25th percentile, sigma_t the temporal rms of the dimmer half. */
static void find_sky(rawstats *r, const float *M, const float *S, double bg,
                     double sigma_t, float *scratch)
{
    int K = r->nframes;
    size_t n = (size_t)r->w * r->h;
    band_job j = {.r = r, .M = M, .S = S, .scratch = scratch,
                  .thr = bg + 5 * sigma_t / sqrt(9.0 * K) + 0.5 * r->quantum};
    atomic_init(&j.next, 0);
    rawstats_run_bands(r, sky_run, &j);
    double sum = 0;   /* in pixel order, as before the marks were banded */
    int ns = 0;
    for (size_t i = 0; i < n; i++)
        if (r->sky[i])
            ns++, sum += M[i];
    r->res.nsky = ns;
    r->res.sky_level = ns ? sum / ns : bg;
    r->res.sky_rms = ns ? stats_median_where(r->pool, scratch, NULL, 0, n) : sigma_t;
}

/* 1 when no bright pixel fluctuates beyond the noise: the median, over
 * the pixels above 10 % of the brightest (as levels above background), of
 * rms / level is below 0.1 (speckle gives 0.3 to 1).  Pixels that never
 * change are left out, so that a stuck pixel never sets the scale. */
static void top_run(void *ctx, int tid, int nthr)
{
    band_job *j = ctx;
    const rawstats *r = j->r;
    (void)tid, (void)nthr;
    for (int b; (b = atomic_fetch_add(&j->next, 1)) < RS_BANDS;) {
        double top = -INFINITY;
        size_t i1 = (size_t)band_row(r->h, b + 1) * r->w;
        for (size_t i = (size_t)band_row(r->h, b) * r->w; i < i1; i++)
            if (r->vmin[i] != r->vmax[i])
                top = fmax(top, j->M[i]);
        j->part[b] = top;
    }
}

static void level_run(void *ctx, int tid, int nthr)
{
    band_job *j = ctx;
    const rawstats *r = j->r;
    const float *M = j->M;
    (void)tid, (void)nthr;
    for (int b; (b = atomic_fetch_add(&j->next, 1)) < RS_BANDS;) {
        size_t i1 = (size_t)band_row(r->h, b + 1) * r->w;
        for (size_t i = (size_t)band_row(r->h, b) * r->w; i < i1; i++)
            j->scratch[i] = r->vmin[i] != r->vmax[i] && M[i] > j->thr && M[i] > j->bg
                                ? (float)(j->S[i] / (M[i] - j->bg)) : NAN;
    }
}

static int is_static(const rawstats *r, const float *M, const float *S,
                     double bg, double sigma_t, float *scratch)
{
    size_t n = (size_t)r->w * r->h;
    band_job j = {.r = (rawstats *)r, .M = M, .S = S, .scratch = scratch, .bg = bg};
    atomic_init(&j.next, 0);
    rawstats_run_bands(r, top_run, &j);
    double top = -INFINITY;
    for (int b = 0; b < RS_BANDS; b++)
        top = fmax(top, j.part[b]);
    j.thr = bg + fmax(10 * sigma_t, 0.1 * (top - bg));
    atomic_store(&j.next, 0);
    rawstats_run_bands(r, level_run, &j);
    /* none selected: the median is 0, static as before */
    float m = stats_median_where(r->pool, scratch, NULL, 0, n);
    return isnan(m) ? -1 : m < 0.1f; /* NaN: no memory for the histograms */
}

/* Stuck, hot and dead pixels (see rawstats.h).  A pixel's residual from
 * its neighbours' median is judged against its own standard error,
 * sqrt(S^2 + sloc^2 / 8) / sqrt(K), so that a pixel of real, strongly
 * fluctuating signal is never an outlier merely for being bright; and a
 * hot pixel's dark current is a floor under every frame (its minimum
 * stands above the background by half its excess at least), while a
 * dead pixel's maximum stays below its neighbours' level.  A real image
 * moves: its bright pixels go dark and its dark ones bright.  These tests
 * need 20 frames: even a pixel no different from its neighbours lies on
 * one side of their median in all of K frames with probability 2^-K,
 * about one pixel of a 1024^2 frame at K = 20 (clipped or quantised
 * noise is far from Gaussian, so the standard errors alone do not say). */
static void bad_run(void *ctx, int tid, int nthr)
{
    band_job *j = ctx;
    rawstats *r = j->r;
    const float *M = j->M, *S = j->S, *mloc = j->mloc, *sloc = j->sloc;
    double bg = j->bg, sigma_t = j->sigma_t;
    int K = r->nframes, stat = r->res.static_scene;
    double qn = r->quantum / sqrt(12.0);
    (void)tid, (void)nthr;
    for (int b; (b = atomic_fetch_add(&j->next, 1)) < RS_BANDS;) {
        size_t i0 = (size_t)band_row(r->h, b) * r->w, i1 = (size_t)band_row(r->h, b + 1) * r->w;
        for (size_t i = i0; i < i1; i++) {
            double res = M[i] - mloc[i], local = fabs(mloc[i] - bg);
            double se = sqrt(((double)S[i] * S[i] + (double)sloc[i] * sloc[i] / 8 +
                              qn * qn + 1e-30) / K);
            int stuck = K >= 4 && r->vmin[i] == r->vmax[i] && sloc[i] > 0 &&
                        fabs(res) > fmax(fmax(5 * sigma_t, 2 * r->quantum), 0.1 * local);
            int odd = !stat && K >= 20 && fabs(res) > 8 * se && fabs(res) > 0.3 * local;
            int hot = odd && res > 0 && r->vmin[i] - bg > 0.5 * res;
            int dead = odd && res < 0 && r->vmax[i] < mloc[i] + 0.5 * res;
            if (stuck)
                j->nstuck[b]++;
            else if (hot)
                j->nhot[b]++;
            else if (dead)
                j->ndead[b]++;
            r->bad[i] = (uint8_t)(stuck || hot || dead);
        }
    }
}

/* Every pixel's own test, in bands on the pool; the counts summed. */
static void mark_bad(rawstats *r, const float *M, const float *S,
                     const float *mloc, const float *sloc, double bg,
                     double sigma_t)
{
    band_job j = {.r = r, .M = M, .S = S, .mloc = mloc, .sloc = sloc, .bg = bg,
                  .sigma_t = sigma_t};
    atomic_init(&j.next, 0);
    rawstats_run_bands(r, bad_run, &j);
    for (int b = 0; b < RS_BANDS; b++) {
        r->res.nstuck += j.nstuck[b];
        r->res.nhot += j.nhot[b];
        r->res.ndead += j.ndead[b];
    }
}

/* tpool job: each claimed band's flux above the cut in rings of
 * j->scale about the centroid (hypot per pixel: ~2 ms of one thread at
 * 512^2). */
static void ring_run(void *ctx, int tid, int nthr)
{
    band_job *j = ctx;
    const rawstats *r = j->r;
    (void)tid, (void)nthr;
    for (int b; (b = atomic_fetch_add(&j->next, 1)) < RS_BANDS;) {
        double *acc = j->acc[b], tot = 0;
        memset(acc, 0, sizeof j->acc[b]);
        for (int y = band_row(r->h, b); y < band_row(r->h, b + 1); y++)
            for (int x = 0; x < r->w; x++) {
                size_t i = (size_t)y * r->w + x;
                double v = j->M[i] - j->cut;
                if (v > 0 && !r->bad[i] && !r->sky[i]) {
                    acc[(int)(hypot(x - j->cx, y - j->cy) / j->scale)] += v;
                    tot += v;
                }
            }
        j->part[b] = tot;
    }
}

/* Centroid and radius of the long exposure above the sky (see .h): the
 * centroid in one pass in pixel order, the rings by bands on the pool,
 * added band after band (the same on any thread count).  SL_ENOMEM. */
static int find_cloud(rawstats *r, const float *M, double sigma_t)
{
    rawstats_result *s = &r->res;
    int w = r->w, h = r->h;
    double thr = s->sky_level + 5 * sigma_t / sqrt((double)r->nframes);
    double sw = 0, sx = 0, sy = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t i = (size_t)y * w + x;
            double v = M[i] - thr;
            if (v > 0 && !r->bad[i] && !r->sky[i])
                sw += v, sx += v * x, sy += v * y;
        }
    s->cx_px = sw > 0 ? sx / sw : w / 2.0;
    s->cy_px = sw > 0 ? sy / sw : h / 2.0;
    band_job j = {.r = r, .M = M, .cx = s->cx_px, .cy = s->cy_px, .cut = thr,
                  .scale = hypot(w, h) / (CLOUD_BINS - 1),
                  .acc = malloc(sizeof *j.acc * RS_BANDS)};
    if (!j.acc)
        return SL_ENOMEM;
    atomic_init(&j.next, 0);
    rawstats_run_bands(r, ring_run, &j);
    double acc[CLOUD_BINS] = {0}, tot = 0;
    for (int b = 0; b < RS_BANDS; b++) {
        tot += j.part[b];
        for (int k = 0; k < CLOUD_BINS; k++)
            acc[k] += j.acc[b][k];
    }
    free(j.acc);
    double c = 0, rad = 0;
    for (int k = 0; k < CLOUD_BINS && tot > 0; k++)
        if ((c += acc[k]) >= 0.95 * tot) {
            rad = (k + 1) * j.scale;
            break;
        }
    s->cloud_radius_px = fmax(1.5 * rad, 8);
    return SL_OK;
}

int rawstats_finish(rawstats *r, rawstats_result *out)
{
    if (r->finished) {
        if (out)
            *out = r->res;
        return SL_OK;
    }
    size_t n = (size_t)r->w * r->h;
    rawstats_result *s = &r->res;
    memset(s, 0, sizeof *s);
    s->nframes = r->nframes;
    s->integer_valued = r->integer_valued && r->nframes > 0;
    s->quantum = s->integer_valued ? (r->quantum > 0 ? r->quantum : 1) : 0;
    r->quantum = s->quantum;
    find_saturation(r);
    float *M = calloc(n, sizeof *M), *S = calloc(n, sizeof *S);
    float *mloc = malloc(n * sizeof *mloc);
    float *sloc = malloc(n * sizeof *sloc), *tmp = malloc(n * sizeof *tmp);
    int rc = SL_OK;
    if (!M || !S || !mloc || !sloc || !tmp)
        goto no_memory;
    if (r->nframes > 0) {
        finish_job fj = {.r = r, .M = M, .S = S, .mloc = mloc, .sloc = sloc};
        for (fj.pass = 0; fj.pass < 2; fj.pass++) {
            atomic_store(&fj.next, 0);
            rawstats_run_bands(r, finish_run, &fj);
        }
        double med = stats_median_where(r->pool, M, NULL, 0, n);
        double bg = stats_median_where(r->pool, M, M, med, n);      /* 25th percentile */
        double sigma_t = stats_median_where(r->pool, S, M, med, n);  /* dimmer half */
        /* M and S are finite: a NaN median means no memory */
        if (isnan(med) || isnan(bg) || isnan(sigma_t) ||
            (s->static_scene = is_static(r, M, S, bg, sigma_t, tmp)) < 0)
            goto no_memory;
        mark_bad(r, M, S, mloc, sloc, bg, sigma_t);
        find_sky(r, M, S, bg, sigma_t, tmp);
        if (isnan(s->sky_rms) || find_cloud(r, M, sigma_t) != SL_OK)
            goto no_memory;
    }
    r->finished = 1;
    if (out)
        *out = *s;
    goto free_all;
no_memory:
    rc = sl_seterr(&r->err, SL_ENOMEM, "rawstats: out of memory");
free_all:
    free(M);
    free(S);
    free(mloc);
    free(sloc);
    free(tmp);
    return rc;
}
