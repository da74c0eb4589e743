/* bench_dataset.c - bcli_run_dataset (bench_cli.h): simulate one data set
 * into a FITS cube with its truth, and measure every configuration on it
 * in a forked child (bench_measure), scored against the cophased image.
 * Points already measured (same data set and configuration) are skipped. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <glib/gstdio.h>

#include "bench_ctx.h"
#include "pipeline/pipeline.h"

typedef bcli_config config;
typedef bcli_ctx ctx;

/* ---- data sets ---- */

/* The cached point-source reference (and cophased PSF) for a geometry. */
static const refset *get_ref(ctx *c, int w, int h, int n, double photons)
{
    for (guint i = 0; i < c->refs->len; i++) {
        refset *r = &g_array_index(c->refs, refset, i);
        if (r->w == w && r->h == h && r->n == n && r->photons == photons)
            return r;
    }
    refset r = {w, h, n, photons, NULL, NULL};
    r.cube = g_strdup_printf("%s/ref-%dx%d-%d-%g.fits", c->dir, w, h, n, photons);
    r.psf = g_strdup_printf("%s/psf-%dx%d-%d-%g.fits", c->dir, w, h, n, photons);
    bench_sim s;
    bench_sim_defaults(&s);
    s.scene = "point";
    s.width = w;
    s.height = h;
    s.nframes = n;
    s.photons = photons;
    s.seed = (uint64_t)c->a->seed + 1000;
    s.frame_interval_s = c->a->interval_ms * 1e-3;
    sl_err e = {0};
    fprintf(stderr, "bench: simulating the reference, %dx%d, %d frames, %g "
            "photons\n", w, h, n, photons);
    if (bench_sim_write(&s, r.cube, r.psf, &e) != SL_OK) {
        fprintf(stderr, "specklab bench: reference: %s\n", e.msg);
        g_free(r.cube);
        g_free(r.psf);
        return NULL;
    }
    g_array_append_val(c->refs, r);
    return &g_array_index(c->refs, refset, c->refs->len - 1);
}

static int same_point(const bcli_row *a, const bench_sim *d, const config *cf)
{
    return !strcmp(a->scene, d->scene) && a->width == d->width &&
           a->height == d->height && a->frames == d->nframes &&
           a->photons == d->photons && a->sep_lod == d->sep_lod &&
           a->dm_mag == d->dm_mag && a->method == cf->method &&
           a->ref == cf->ref && a->skips == cf->skips && a->target == cf->target &&
           a->inverse == cf->inverse &&
           a->inject == d->bad_frames && a->oversample == d->oversample &&
           (cf->method == PIPE_DIRECT ? a->r2 : a->nangles) == cf->param;
}

static void measure_one(ctx *c, const bench_sim *d, const char *cube,
                        const refset *ref, const bench_truth *truth,
                        const bench_score *mfloor, const config *cf, int block,
                        float *img)
{
    const bench_args *a = c->a;
    bcli_row r;
    memset(&r, 0, sizeof r);
    snprintf(r.scene, sizeof r.scene, "%s", d->scene);
    r.width = d->width;
    r.height = d->height;
    r.frames = d->nframes;
    r.photons = d->photons;
    r.sep_lod = d->sep_lod;
    r.pa_deg = d->pa_deg;
    r.dm_mag = d->dm_mag;
    r.method = cf->method;
    r.ref = cf->ref;
    r.skips = cf->skips;
    r.target = cf->target;
    r.inverse = cf->inverse;
    r.inject = d->bad_frames;
    r.oversample = d->oversample;
    r.repeat = a->repeat;
    r.threads = a->threads;
    r.block = block;
    r.floor = *mfloor;
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.method = cf->method;
    if (cf->method == PIPE_DIRECT)
        o.r2_px = r.r2 = cf->param;
    else
        o.nangles = r.nangles = cf->param;
    o.skips = cf->skips;
    o.target_error = cf->target;
    o.tsm_inverse = cf->inverse;
    o.nthreads = a->threads;
    o.fftw_measure = !a->estimate;
    o.closure_binary = block == 2; /* the paper binaries: closure fits too */
    if (cf->ref) {
        o.ref_path = ref->cube;
        o.target_path = ref->psf;
    }
    sl_err e = {0};
    r.status = bench_measure(cube, &o, a->repeat, img, d->width, d->height,
                             &r.t, &e);
    bench_score_init(&r.s);
    if (r.status == SL_OK)
        r.status = bench_score_image(img, truth, BENCH_HP_SIGMA_PX, &r.s, &e);
    if (r.status != SL_OK) {
        snprintf(r.msg, sizeof r.msg, "%s", e.msg);
        c->failures++;
    }
    bcli_print_row(&r);
    g_array_append_val(c->rows, r);
}

/* Simulate one data set and measure every configuration on it. */
int bcli_run_dataset(ctx *c, const bench_sim *d, const config *cf, int ncf,
                     int block)
{
    int need_ref = 0, todo = 0;
    for (int i = 0; i < ncf; i++) {
        int dup = 0;
        for (guint k = 0; k < c->rows->len && !dup; k++)
            dup = same_point(&g_array_index(c->rows, bcli_row, k), d, &cf[i]);
        todo += !dup;
        need_ref |= !dup && cf[i].ref;
    }
    if (!todo)
        return 0;
    const refset *ref = need_ref ? get_ref(c, d->width, d->height, d->nframes,
                                           d->photons) : NULL;
    if (need_ref && !ref)
        return 1;
    char *cube = g_strdup_printf("%s/data-%03d-%s.fits", c->dir, c->ndata++,
                                 d->scene);
    sl_err e = {0};
    bench_truth truth = {0};
    float *img = malloc(sizeof(float) * (size_t)d->width * (size_t)d->height);
    fprintf(stderr, "bench: simulating %s, %dx%d, %d frames, %g photons%s%s\n",
            d->scene, d->width, d->height, d->nframes, d->photons,
            d->bad_frames ? ", bad frames injected" : "",
            d->oversample > 1 ? ", oversampled" : "");
    bench_sim dt = *d;
    dt.frame_interval_s = c->a->interval_ms * 1e-3;
    int rc = !img ? sl_seterr(&e, SL_ENOMEM, "out of memory")
                  : bench_sim_write(&dt, cube, NULL, &e);
    bench_score mfloor;
    if (rc == SL_OK)
        rc = bench_truth_read(&truth, cube, &e);
    if (rc == SL_OK)
        rc = bench_score_image(truth.cophased, &truth, BENCH_HP_SIGMA_PX,
                               &mfloor, &e);
    if (rc == SL_OK && truth.binary)
        printf("# %s %g/%g %dx%d: metrics_binary on the cophased image itself "
               "(the metric's floor): dsep %+.3f px, dPA %+.2f deg, ddm %+.3f\n",
               d->scene, d->sep_lod, d->dm_mag, d->width, d->height,
               mfloor.sep_err_px, mfloor.pa_err_deg, mfloor.dm_err_mag);
    if (rc != SL_OK) {
        fprintf(stderr, "specklab bench: %s\n", e.msg);
        c->failures++;
    }
    for (int i = 0; i < ncf && rc == SL_OK; i++) {
        int dup = 0;
        for (guint k = 0; k < c->rows->len && !dup; k++)
            dup = same_point(&g_array_index(c->rows, bcli_row, k), d, &cf[i]);
        if (!dup)
            measure_one(c, d, cube, ref, &truth, &mfloor, &cf[i], block, img);
    }
    bench_truth_clear(&truth);
    free(img);
    if (!c->a->keep_data)
        g_unlink(cube);
    g_free(cube);
    return rc == SL_OK ? 0 : 1;
}

