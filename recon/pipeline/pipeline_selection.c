/* pipeline_selection.c - the skips of pipeline.h: the scene
 * probe on the first frames, frame selection, the crop, its cache, and
 * putting the result back into a frame-sized image.  See pipeline_int.h.
 *
 * Why replay rather than a separate first pass: reading and cleaning a
 * 200^2 frame costs ~0.3 ms (prep's border median dominates), about as
 * much as a cropped TSM reconstruction of it, so the probe must not read
 * the sequence twice.  The probe keeps its frames; the estimator's first
 * pass takes them from memory and reads on from where the probe stopped.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline_int.h"

#define SKIP_CACHE_BYTES (128.0 * 1024 * 1024)

int skip_effective(const pipeline_opts *o)
{
    if (o->skips >= 0)
        return o->skips & PIPE_SKIP_ALL;
    return o->method == PIPE_AUTO ? PIPE_SKIP_ALL : 0;
}

int skip_apply(stream *s, int has_ref, const pipeline_opts *o, int skips,
               pipeline_opts *eo, autoconf_choice *ch, double *photons,
               sl_err *err)
{
    *eo = *o;
    memset(ch, 0, sizeof *ch);
    probe_opts po;
    probe_opts_defaults(&po);
    po.crop = (skips & PIPE_SKIP_CROP) && !has_ref;
    po.reject_mad = skips & PIPE_SKIP_REJECT ? 0 : -1;
    int tsm_skips = skips & (PIPE_SKIP_ANGLES | PIPE_SKIP_SUPPORT);
    int choose = o->method == PIPE_AUTO || (tsm_skips && o->method != PIPE_DIRECT);
    po.spectrum = choose; /* only the model reads it */
    if (!(s->pb = probe_new(s->w, s->h, s->n, &po, err)))
        return err ? err->code : SL_ENOMEM;
    cube_reader_rewind(s->rd);
    int rc = SL_OK;
    while (probe_wants(s->pb) > 0 &&
           (rc = stream_next(s)) == SL_OK) {
        prep_stats st;
        memset(&st, 0, sizeof st);
        if (s->pp)
            prep_frame(s->pp, s->frame, &st);
        if ((rc = probe_add(s->pb, s->frame, &st)) != SL_OK)
            return sl_seterr(err, rc, "scene probe: %s", probe_errmsg(s->pb));
    }
    if (rc != SL_OK && rc != SL_EEND)
        return sl_seterr(err, rc, "%s", cube_reader_errmsg(s->rd));
    if ((rc = probe_finish(s->pb, NULL)) != SL_OK)
        return sl_seterr(err, rc, "scene probe: %s", probe_errmsg(s->pb));
    const probe_scene *sc = probe_result(s->pb);
    if (choose) {
        /* frames the model expects to be kept: the probed proportion */
        int nk = (int)((double)s->n * sc->nprobed_kept / sc->nprobed + 0.5);
        /* A binary wanted: direct, whose closure phases measured it within
         * 0.15 px / 0.5 deg / 0.1 mag in 21 of 25 blind conditions where
         * tsm-fourier's raw ones, cheaper, met 16 (dm +0.10..+0.32 at 1e4
         * photons, with jitter, at 0.5x Nyquist). */
        int m = o->method == PIPE_AUTO && o->closure_binary ? PIPE_DIRECT : o->method;
        if (stream_leads(s))
            autoconf_choose(sc, nk, m, !!(skips & PIPE_SKIP_ANGLES),
                            o->nangles, !!(skips & PIPE_SKIP_SUPPORT),
                            !!(skips & PIPE_SKIP_CROP), o->target_error, ch);
        if ((rc = stream_agree(s, ch, sizeof *ch, err)) != SL_OK)
            return rc;
        if ((rc = probe_set_crop(s->pb, ch->crop_level)) != SL_OK)
            return sl_seterr(err, rc, "scene probe: %s", probe_errmsg(s->pb));
        eo->method = ch->method;
        eo->nangles = ch->nangles;
        if (ch->method != PIPE_DIRECT) {
            eo->tsm_inverse = o->tsm_inverse ? o->tsm_inverse : ch->inverse;
            eo->cutoff_cyc_px = o->cutoff_cyc_px > 0 ? o->cutoff_cyc_px
                                                     : ch->cutoff_cyc_px;
        }
    }
    s->fw = s->w, s->fh = s->h;
    s->w = sc->crop_w, s->h = sc->crop_h;
    size_t nc = (size_t)s->w * s->h;
    if (!(s->sel = malloc(nc * sizeof *s->sel)))
        return sl_seterr(err, SL_ENOMEM, "out of memory for a %dx%d crop",
                         s->w, s->h);
    /* The cache only pays for a second pass (direct); it is optional. */
    if ((double)nc * s->n * sizeof(float) <= SKIP_CACHE_BYTES &&
        eo->method == PIPE_DIRECT) {
        s->cache = malloc(nc * (size_t)s->n * sizeof *s->cache);
        s->ncache_max = s->cache ? s->n : 0;
    }
    if (*photons > 0)
        *photons *= sc->crop_flux_frac;
    probe_counts(s->pb, s->counts); /* the probed frames' verdicts */
    return stream_check_agreed(s, err);
}

/* Split over processes: the verdicts of every process's frames, once the
 * first pass has judged them (the probed ones, judged everywhere, once). */
static int skip_count_whole(stream *s, sl_err *err)
{
    if (!s->share)
        return SL_OK;
    int now[PROBE_NVERDICT];
    double v[PROBE_NVERDICT];
    probe_counts(s->pb, now);
    for (int i = 0; i < PROBE_NVERDICT; i++)
        v[i] = now[i] - s->counts[i];
    int rc = stream_share_doubles(s, v, PROBE_NVERDICT, err);
    for (int i = 0; rc == SL_OK && i < PROBE_NVERDICT; i++)
        s->counts[i] += (int)v[i];
    s->counts_whole = rc == SL_OK;
    return rc;
}

/* Judge frame k; feed its crop when kept (and cache it on pass 1). */
static int select_add(stream *s, int k, const float *f, const prep_stats *st,
                      add_fn add, void *h, int first, const char *what,
                      sl_err *err)
{
    if (probe_select(s->pb, k, f, st, s->sel) != PROBE_KEEP)
        return SL_OK;
    size_t nc = (size_t)s->w * s->h;
    if (first && s->cache && s->ncache < s->ncache_max)
        memcpy(s->cache + (size_t)s->ncache++ * nc, s->sel, nc * sizeof *s->sel);
    int rc = add ? add(h, s->sel) : SL_OK;
    return rc == SL_OK ? SL_OK : sl_seterr(err, rc, "frame %d: %s", k, what);
}

int skip_feed(stream *s, add_fn add, void *h, const char *what, sl_err *err)
{
    int first = s->passes++ == 0, rc = SL_OK, k = 0;
    size_t nc = (size_t)s->w * s->h;
    if (!first && s->cache) {
        for (int i = 0; i < s->ncache && add; i++)
            if ((rc = add(h, s->cache + (size_t)i * nc)) != SL_OK)
                return sl_seterr(err, rc, "kept frame %d: %s", i, what);
        return SL_OK;
    }
    k = s->k0;
    if (first) {
        for (; k < probe_nstored(s->pb) && k < s->k1; k++)
            if ((rc = select_add(s, k, probe_stored(s->pb, k), NULL, add, h,
                                 first, what, err)) != SL_OK)
                return rc;
    }
    prep_stats st;
    rc = cube_reader_seek(s->rd, k);
    while (rc == SL_OK && (rc = k < s->k1 ? stream_next(s) : SL_EEND) == SL_OK) {
        memset(&st, 0, sizeof st);
        if (s->pp)
            prep_frame(s->pp, s->frame, &st);
        if ((rc = select_add(s, k, s->frame, &st, add, h, first, what, err)) != SL_OK)
            return rc;
        k++;
    }
    if (rc != SL_EEND)
        return sl_seterr(err, rc, "%s", cube_reader_errmsg(s->rd));
    return first ? skip_count_whole(s, err) : SL_OK;
}

int skip_nkept(const stream *s)
{
    int c[PROBE_NVERDICT];
    probe_counts(s->pb, c);
    return s->counts_whole ? s->counts[PROBE_KEEP] : c[PROBE_KEEP];
}

void skip_report(const stream *s, const pipeline_opts *o, int skips,
                 const autoconf_choice *ch, pipeline_probe_report *r)
{
    memset(r, 0, sizeof *r);
    r->skips = skips;
    probe_report_fill(s->pb, r);
    for (int v = 0; s->counts_whole && v < PROBE_NVERDICT; v++)
        r->rejected[v] = s->counts[v];
    if (!ch->chosen)
        return;
    r->chosen = 1;
    r->target_error = o->target_error > 0 ? o->target_error : 0.1;
    r->pred_error = ch->pred_error;
    r->pred_cost_s = ch->pred_cost;
    autoconf_label(ch, r->chosen_label, sizeof r->chosen_label);
}

int skip_place(const stream *s, float **img, sl_err *err)
{
    if (s->w == s->fw && s->h == s->fh)
        return SL_OK;
    float *full = malloc(sizeof(float) * (size_t)s->fw * s->fh);
    if (!full)
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    probe_place(probe_result(s->pb), *img, full);
    free(*img);
    *img = full;
    return SL_OK;
}
