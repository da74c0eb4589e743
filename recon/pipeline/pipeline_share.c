/* pipeline_share.c - a run split over processes (pipeline.h,
 * pipeline_share; pipeline_int.h): each process's frame range, and the
 * accumulators' sums made whole through the caller's hooks.
 *
 * Why flat doubles: every sum (powers, bispectra, frame counts) adds
 * element-wise, so one merge (pipeline_sums_merge) serves every estimator
 * and the transport (MPI, or anything else) needs no knowledge of them.
 * Cost: one buffer the size of the sums per reduction, freed at once.
 */
#include <stdlib.h>
#include <string.h>

#include "pipeline_int.h"

void pipeline_sums_merge(double *acc, const double *part, size_t n)
{
    for (size_t i = 0; i < n; i++)
        acc[i] += part[i];
}

void stream_share_range(stream *s, const pipeline_share *share, int has_ref)
{
    s->has_ref = has_ref;
    s->share = share && share->nranks > 1 ? share : NULL;
    s->k0 = 0;
    s->k1 = s->n;
    if (s->share) {
        long n = s->n, r = share->rank, nr = share->nranks;
        s->k0 = (int)(n * r / nr);
        s->k1 = (int)(n * (r + 1) / nr);
    }
}

int stream_leads(const stream *s)
{
    return !s->share || s->share->rank == 0;
}

/* The hook; last as pipeline_share's reduce takes it. */
static int reduce(stream *s, double *v, size_t n, int last, sl_err *err)
{
    if (!s->share)
        return SL_OK;
    int rc = s->share->reduce(s->share->ctx, v, n, last);
    if (rc == SL_EEND && last)
        return sl_seterr(err, rc, "rank %d: its frames are in rank 0's sums",
                         s->share->rank);
    return rc == SL_OK ? SL_OK
                       : sl_seterr(err, rc, "rank %d: summing %zu values over %d "
                                   "ranks failed", s->share->rank, n, s->share->nranks);
}

int stream_share_doubles(stream *s, double *v, size_t n, sl_err *err)
{
    return reduce(s, v, n, 0, err);
}

int stream_agree(stream *s, void *buf, size_t bytes, sl_err *err)
{
    if (!s->share)
        return SL_OK;
    int rc = s->share->agree(s->share->ctx, buf, bytes);
    return rc == SL_OK ? SL_OK
                       : sl_seterr(err, rc, "rank %d: taking rank 0's decision "
                                   "failed", s->share->rank);
}

int stream_check_agreed(stream *s, sl_err *err)
{
    if (!s->share)
        return SL_OK;
    const rawstats_result *d = &s->det;
    double mine[16] = {s->scale, s->w, s->h, s->det_learnt, d->sat_level, d->sky_level,
                       d->sky_rms, d->cx_px, d->cy_px, d->nstuck + d->nhot + d->ndead},
           lead[16];
    size_t n = 10;
    if (s->pb) {
        const probe_scene *sc = probe_result(s->pb);
        const double more[] = {sc->crop_x0, sc->crop_y0, sc->nprobed_kept, sc->flux_med,
                               sc->sharp_med, sc->plateau_med};
        memcpy(mine + n, more, sizeof more);
        n += sizeof more / sizeof more[0];
    }
    memcpy(lead, mine, sizeof mine);
    int rc = stream_agree(s, lead, n * sizeof *lead, err);
    if (rc == SL_OK && memcmp(lead, mine, n * sizeof *lead) != 0)
        rc = sl_seterr(err, SL_EDATA, "rank %d: the scale, detector or scene probe "
                       "measured on the first frames differ from rank 0's",
                       s->share->rank);
    return rc;
}

/* Export, reduce, load back: get(h, NULL) is the count. */
typedef size_t (*sums_get)(void *h, double *buf);
typedef void (*sums_load)(void *h, const double *buf);

/* last: the estimator's sums with no reference sequence to follow, the
 * run's final ones. */
static int share_sums(stream *s, void *h, sums_get get, sums_load load,
                      const char *what, int last, sl_err *err)
{
    if (!s->share)
        return SL_OK;
    size_t n = get(h, NULL);
    double *buf = malloc(n * sizeof *buf);
    if (!buf)
        return sl_seterr(err, SL_ENOMEM, "out of memory for the %s's %zu sums",
                         what, n);
    get(h, buf);
    int rc = reduce(s, buf, n, last, err);
    if (rc == SL_OK)
        load(h, buf);
    free(buf);
    return rc;
}

static size_t ps_get(void *h, double *buf) { return powspec_partial(h, buf); }
static void ps_load(void *h, const double *buf) { powspec_partial_load(h, buf); }
static size_t bs_get(void *h, double *buf) { return bispec_partial(h, buf); }
static void bs_load(void *h, const double *buf) { bispec_partial_load(h, buf); }
static size_t tsm_get(void *h, double *buf) { return tsm_partial(h, buf); }
static void tsm_load(void *h, const double *buf) { tsm_partial_load(h, buf); }

int stream_share_powspec(stream *s, powspec *p, sl_err *err)
{
    return share_sums(s, p, ps_get, ps_load, "power spectrum", 0, err);
}

int stream_share_bispec(stream *s, bispec *b, sl_err *err)
{
    return share_sums(s, b, bs_get, bs_load, "bispectrum", !s->has_ref, err);
}

int stream_share_tsm(stream *s, tsm *t, sl_err *err)
{
    return share_sums(s, t, tsm_get, tsm_load, "projections", !s->has_ref, err);
}
