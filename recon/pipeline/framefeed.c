/* framefeed.c - see framefeed.h: pipeline_int.h's stream, opened without
 * skips, for callers outside the pipeline. */
#include "framefeed.h"

#include <stdlib.h>

#include "pipeline_int.h"

struct framefeed {
    stream s;
};

int framefeed_open(framefeed **out, const char *const *paths, int npaths,
                   const pipeline_opts *o, sl_err *err)
{
    *out = calloc(1, sizeof **out);
    if (!*out)
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    int rc = stream_open(&(*out)->s, paths, npaths, o, err);
    if (rc != SL_OK) {
        free(*out);
        *out = NULL;
    }
    return rc;
}

void framefeed_free(framefeed *f)
{
    if (!f)
        return;
    stream_close(&f->s);
    free(f);
}

int framefeed_width(const framefeed *f) { return f->s.w; }
int framefeed_height(const framefeed *f) { return f->s.h; }
int framefeed_nframes(const framefeed *f) { return f->s.n; }

const cube_meta *framefeed_meta(const framefeed *f)
{
    return cube_reader_meta(f->s.rd);
}

static int flux_add(void *h, const float *frame)
{
    double *acc = h; /* {pixels, sum, frames} */
    for (size_t i = 0, n = (size_t)acc[0]; i < n; i++)
        acc[1] += frame[i];
    acc[2] += 1;
    return SL_OK;
}

int framefeed_photons_get(framefeed *f, const pipeline_opts *o,
                          framefeed_photons *ph, sl_err *err)
{
    double photons = 0, g = 0;
    int src = PHOT_NONE;
    int rc = stream_photon_stats(&f->s, o, &photons, &g, &src, err);
    if (rc != SL_OK)
        return rc;
    if (photons > 0 && !(g > 0)) {
        double acc[3] = {(double)f->s.w * f->s.h, 0, 0};
        if ((rc = stream_feed(&f->s, flux_add, acc, "mean flux", err)) != SL_OK)
            return rc;
        g = acc[2] > 0 && acc[1] > 0 ? acc[1] / acc[2] / photons : 0;
    }
    ph->photons = g > 0 ? photons : 0;
    ph->adu_per_photon = g > 0 ? g : 0;
    ph->read_noise_adu = g > 0 ? stream_read_noise_adu(&f->s, photons) : 0;
    ph->source = g > 0 ? src : PIPE_PHOT_NONE;
    return SL_OK;
}

int framefeed_run(framefeed *f, int (*add)(void *h, const float *frame),
                  void *h, const char *what, sl_err *err)
{
    return stream_feed(&f->s, add, h, what, err);
}

void framefeed_report(const framefeed *f, pipeline_report *r)
{
    stream_report(&f->s, r);
    r->nframes_in = f->s.n;
    r->scale = f->s.scale;
}
