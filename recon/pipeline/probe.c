/* probe.c - see probe.h. */
#include "probe.h"
#include "probe_int.h"

#include <complex.h>
#include <fftw3.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "spectra/powspec.h"

#define PROBE_MAX_BYTES (64.0 * 1024 * 1024)

/* Cloud edges, x the peak of the long exposure's azimuthal mean profile.
 * Measured on the bench (binary, point, six-star, extended; 100 frames of
 * 200^2 and 48 of 128^2, 3 seeds): the profile's tail is shallow near
 * 1e-2 (the 10 cm holes' Airy rings), where the radius jumps by 6 px
 * between seeds; at 5e-3 it is steady (41-49 px, crops 96-108) and the
 * cropped reconstruction matches the uncropped one to c >= 0.999 (direct)
 * and 0.994-0.997 (tsm-fourier 180).  At 3e-2 (crops 60-72) direct still
 * matches to c >= 0.998 but TSM only to ~0.98 (the seeing pedestal TSM
 * reconstructs is cut): only autoconf's model takes the tight crop. */
static const double cloud_levels[PROBE_NCROP] = {5e-3, 3e-2};



void probe_opts_defaults(probe_opts *o)
{
    memset(o, 0, sizeof *o);
    o->crop = 1;
    o->window = POWSPEC_WIN_TUKEY;
    o->spectrum = 1;
}

const char *probe_errmsg(const probe *p) { return p ? p->err.msg : "no probe"; }
int probe_wants(const probe *p) { return p->finished ? 0 : p->want - p->n; }
int probe_nstored(const probe *p) { return p->n; }
const float *probe_stored(const probe *p, int i)
{
    return p->frames + (size_t)i * p->w * p->h;
}
const probe_scene *probe_result(const probe *p) { return &p->sc; }

static const char *verdict_names[] = {"kept", "empty", "saturated", "flux",
                                      "sharpness"};

const char *probe_verdict_name(int v)
{
    return v >= 0 && v < PROBE_NVERDICT ? verdict_names[v] : "unknown";
}

void probe_counts(const probe *p, int counts[PROBE_NVERDICT])
{
    memcpy(counts, p->counts, sizeof p->counts);
}

void probe_free(probe *p)
{
    if (!p)
        return;
    free(p->frames);
    free(p->flux);
    free(p->sharp);
    free(p->plateau);
    free(p->nsat);
    free(p->le);
    free(p->verdict);
    free(p);
}

probe *probe_new(int w, int h, int nframes_total, const probe_opts *o,
                 sl_err *err)
{
    probe_opts d;
    probe_opts_defaults(&d);
    if (o)
        d = *o;
    if (w < 8 || h < 8 || nframes_total < 1 || d.nframes < 0) {
        sl_seterr(err, SL_EINVAL, "probe_new: bad parameters (%dx%d, %d "
                  "frames, probe %d)", w, h, nframes_total, d.nframes);
        return NULL;
    }
    if (d.nframes == 0)
        d.nframes = 32;
    if (d.reject_mad == 0)
        d.reject_mad = 8;
    if (!(d.margin_px > 0))
        d.margin_px = 4;
    if (!(d.extent_level > 0))
        d.extent_level = 0.05;
    /* Stored frames stay under PROBE_MAX_BYTES, but at least 4 of them. */
    int cap = (int)(PROBE_MAX_BYTES / (4.0 * w * h));
    int want = d.nframes < cap ? d.nframes : cap < 4 ? 4 : cap;
    if (want > nframes_total)
        want = nframes_total;
    probe *p = calloc(1, sizeof *p);
    if (!p) {
        sl_seterr(err, SL_ENOMEM, "probe_new: out of memory");
        return NULL;
    }
    p->w = w, p->h = h, p->ntotal = nframes_total, p->want = want, p->o = d;
    p->frames = malloc(sizeof(float) * (size_t)want * w * h);
    p->flux = malloc(sizeof(double) * want);
    p->sharp = malloc(sizeof(double) * want);
    p->plateau = malloc(sizeof(double) * want);
    p->nsat = malloc(sizeof(int) * want);
    p->verdict = malloc((size_t)nframes_total);
    if (!p->frames || !p->flux || !p->sharp || !p->plateau || !p->nsat || !p->verdict) {
        sl_seterr(err, SL_ENOMEM, "probe_new: out of memory for %d frames "
                  "of %dx%d", want, w, h);
        probe_free(p);
        return NULL;
    }
    memset(p->verdict, -1, (size_t)nframes_total);
    return p;
}

/* Flux, sharpness and saturation plateau (pixels equal to the maximum:
 * clipped values stay equal through prep's sky subtraction) of a w x h
 * region of a frame with row pitch `pitch`, in one pass. */
static void frame_stats(const float *f, int w, int h, size_t pitch,
                        const prep_stats *st, double *flux, double *sharp,
                        double *plateau)
{
    double s = 0, s2 = 0;
    float mx = -INFINITY;
    int cnt = 0;
    for (int y = 0; y < h; y++) {
        const float *r = f + (size_t)y * pitch;
        for (int x = 0; x < w; x++) {
            float v = r[x];
            s += v;
            s2 += (double)v * v;
            if (v > mx)
                mx = v, cnt = 1;
            else if (v == mx)
                cnt++;
        }
    }
    int rep = st ? st->saturated : 0;
    *flux = mx > 0 ? s : 0;
    *sharp = s > 0 ? s2 / (s * s) : 0;
    *plateau = mx > 0 && cnt > rep ? cnt : rep;
}

int probe_add(probe *p, const float *frame, const prep_stats *st)
{
    if (p->finished || p->n >= p->want)
        return sl_seterr(&p->err, SL_EINVAL, "probe_add: probe is full");
    size_t n = (size_t)p->w * p->h;
    memcpy(p->frames + (size_t)p->n * n, frame, n * sizeof *frame);
    p->nsat[p->n] = st ? st->saturated : 0;
    p->n++;
    return SL_OK;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median and MAD of v[0..n) (n <= a few hundred: sorting is fine). */
static void med_mad(const double *v, int n, double *med, double *mad)
{
    double *s = malloc(sizeof(double) * (size_t)(n + 1));
    *med = *mad = 0;
    if (!s || n < 1) {
        free(s);
        return;
    }
    memcpy(s, v, sizeof(double) * n);
    qsort(s, (size_t)n, sizeof *s, cmp_double);
    *med = n % 2 ? s[n / 2] : 0.5 * (s[n / 2 - 1] + s[n / 2]);
    for (int i = 0; i < n; i++)
        s[i] = fabs(v[i] - *med);
    qsort(s, (size_t)n, sizeof *s, cmp_double);
    *mad = n % 2 ? s[n / 2] : 0.5 * (s[n / 2 - 1] + s[n / 2]);
    free(s);
}

static int judge(const probe *p, double flux, double sharp, double plateau)
{
    const probe_scene *sc = &p->sc;
    double k = p->o.reject_mad;
    if (k < 0)
        return PROBE_KEEP;
    if (!(flux > 0) || flux < 0.05 * sc->flux_med)
        return PROBE_EMPTY;
    if (plateau >= 4 && plateau > sc->plateau_med + k * fmax(sc->plateau_mad, 1))
        return PROBE_SATURATED;
    if (fabs(flux - sc->flux_med) > k * fmax(sc->flux_mad, 0.01 * fabs(sc->flux_med)))
        return PROBE_FLUX;
    if (fabs(sharp - sc->sharp_med) > k * fmax(sc->sharp_mad, 0.01 * sc->sharp_med))
        return PROBE_SHARP;
    return PROBE_KEEP;
}

/* Smallest even n >= m whose only prime factors are 2, 3 and 5 (FFTW's
 * fast sizes). */
static int good_size(int m)
{
    for (int n = m + (m & 1);; n += 2) {
        int r = n;
        while (r % 2 == 0) r /= 2;
        while (r % 3 == 0) r /= 3;
        while (r % 5 == 0) r /= 5;
        if (r == 1)
            return n;
    }
}

/* The long exposure of the probed frames (all of them: judging needs the
 * crop, and an outlier frame hardly moves a mean of the cloud's extent),
 * its centroid and the cloud radius at each level. */
static void find_cloud(probe *p)
{
    probe_scene *sc = &p->sc;
    int w = p->w, h = p->h;
    size_t n = (size_t)w * h;
    double *le = p->le;
    memset(le, 0, n * sizeof *le);
    for (int k = 0; k < p->n; k++) {
        const float *f = probe_stored(p, k);
        for (size_t i = 0; i < n; i++)
            le[i] += f[i];
    }
    for (size_t i = 0; i < n; i++)
        le[i] /= p->n;
    /* noise: mean and rms scatter of a border band (MAD is 0 for sparse
     * photon counts, so rms it is) */
    int b = w < h ? w / 16 : h / 16;
    b = b < 2 ? 2 : b;
    double s1 = 0, s2 = 0, nb = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            if (x < b || x >= w - b || y < b || y >= h - b) {
                double v = le[(size_t)y * w + x];
                s1 += v, s2 += v * v, nb++;
            }
    double mb = s1 / nb, sd = sqrt(fmax(s2 / nb - mb * mb, 0));
    /* centroid of what stands 5 sigma above the border */
    double sx = 0, sy = 0, sw = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double v = le[(size_t)y * w + x] - mb;
            if (v > 5 * sd)
                sx += v * x, sy += v * y, sw += v;
        }
    sc->cx_px = sw > 0 ? sx / sw : w / 2.0;
    sc->cy_px = sw > 0 ? sy / sw : h / 2.0;
    /* The azimuthal mean profile: single pixels of a mean of a few tens
     * of photon-counting frames are too noisy to threshold, annuli of
     * hundreds of pixels are not.  Cloud radius: the largest radius whose
     * annulus stands above the level x the profile's peak and 5 sigma of
     * its own noise.  The scratch is on the stack: radii < 2^15. */
    enum { NR = 1024 };
    double acc[NR], cnt[NR];
    memset(acc, 0, sizeof acc);
    memset(cnt, 0, sizeof cnt);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            int k = (int)(hypot(x - sc->cx_px, y - sc->cy_px) + 0.5);
            k = k < NR ? k : NR - 1;
            acc[k] += le[(size_t)y * w + x] - mb;
            cnt[k]++;
        }
    double peak = 0;
    for (int k = 0; k < NR; k++)
        if (cnt[k] > 0) {
            acc[k] /= cnt[k];
            peak = acc[k] > peak ? acc[k] : peak;
        }
    for (int l = 0; l < PROBE_NCROP; l++) {
        int r = 0;
        for (int k = NR - 1; k > 0 && !r; k--)
            if (cnt[k] > 0 && acc[k] > fmax(cloud_levels[l] * peak, 5 * sd / sqrt(cnt[k])))
                r = k;
        sc->cloud_radius_px[l] = r;
        int side = good_size((int)ceil(2 * (r + p->o.margin_px)));
        side = side < 16 ? 16 : side;
        int cw = side < w ? side : w, ch = side < h ? side : h;
        /* a crop must save at least a third of the pixels to pay */
        sc->crop_side[l] = p->o.crop && (double)cw * ch <= 2.0 / 3.0 * w * h ? side : 0;
    }
}

/* Crop geometry for crop_side[l] (0: the whole frame) and its flux. */
static void place_crop(probe *p, int l)
{
    probe_scene *sc = &p->sc;
    int w = p->w, h = p->h, side = sc->crop_side[l];
    int cw = side && side < w ? side : w, ch = side && side < h ? side : h;
    int x0 = (int)lround(sc->cx_px) - cw / 2, y0 = (int)lround(sc->cy_px) - ch / 2;
    x0 = x0 < 0 ? 0 : x0 > w - cw ? w - cw : x0;
    y0 = y0 < 0 ? 0 : y0 > h - ch ? h - ch : y0;
    sc->crop_level = l;
    sc->crop_x0 = x0, sc->crop_y0 = y0, sc->crop_w = cw, sc->crop_h = ch;
    double in = 0, tot = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double v = p->le[(size_t)y * w + x];
            v = v > 0 ? v : 0;
            tot += v;
            if (x >= x0 && x < x0 + cw && y >= y0 && y < y0 + ch)
                in += v;
        }
    sc->crop_flux_frac = tot > 0 ? in / tot : 1;
}

/* Quality of the probed frames on the crop: the reference (medians and
 * MADs), then their verdicts, counted afresh. */
static int judge_probed(probe *p)
{
    probe_scene *sc = &p->sc;
    for (int k = 0; k < p->n; k++) {
        prep_stats st = {0};
        st.saturated = p->nsat[k];
        frame_stats(probe_stored(p, k) + (size_t)sc->crop_y0 * p->w + sc->crop_x0,
                    sc->crop_w, sc->crop_h, (size_t)p->w, &st, &p->flux[k],
                    &p->sharp[k], &p->plateau[k]);
    }
    med_mad(p->flux, p->n, &sc->flux_med, &sc->flux_mad);
    med_mad(p->sharp, p->n, &sc->sharp_med, &sc->sharp_mad);
    med_mad(p->plateau, p->n, &sc->plateau_med, &sc->plateau_mad);
    memset(p->counts, 0, sizeof p->counts);
    sc->nprobed_kept = 0;
    for (int k = 0; k < p->n; k++) {
        int v = judge(p, p->flux[k], p->sharp[k], p->plateau[k]);
        p->verdict[k] = (signed char)v;
        p->counts[v]++;
        sc->nprobed_kept += v == PROBE_KEEP;
    }
    if (!sc->nprobed_kept)
        return sl_seterr(&p->err, SL_EDATA, "probe: all %d probed frames "
                         "rejected", p->n);
    return SL_OK;
}


int probe_finish(probe *p, probe_scene *out)
{
    probe_scene *sc = &p->sc;
    if (p->finished) {
        if (out)
            *out = *sc;
        return SL_OK;
    }
    if (p->n < 1)
        return sl_seterr(&p->err, SL_EDATA, "probe: no frames");
    memset(sc, 0, sizeof *sc);
    sc->width = p->w, sc->height = p->h, sc->nframes = p->ntotal;
    sc->nprobed = p->n;
    if (!(p->le = malloc(sizeof(double) * (size_t)p->w * p->h)))
        return sl_seterr(&p->err, SL_ENOMEM, "probe: out of memory");
    find_cloud(p);
    place_crop(p, 0);
    int rc = judge_probed(p);
    if (rc == SL_OK && p->o.spectrum)
        rc = probe_measure_spectrum(p);
    if (rc != SL_OK)
        return rc;
    p->finished = 1;
    if (out)
        *out = *sc;
    return SL_OK;
}

int probe_set_crop(probe *p, int level)
{
    if (!p->finished || level < 0 || level >= PROBE_NCROP)
        return sl_seterr(&p->err, SL_EINVAL, "probe_set_crop: level %d", level);
    if (level == p->sc.crop_level)
        return SL_OK;
    for (int k = p->n; k < p->ntotal; k++)
        if (p->verdict[k] >= 0)
            return sl_seterr(&p->err, SL_EINVAL, "probe_set_crop: frames "
                             "already selected");
    place_crop(p, level);
    return judge_probed(p);
}

int probe_select(probe *p, int k, const float *frame, const prep_stats *st,
                 float *out)
{
    int v;
    if (k >= 0 && k < p->ntotal && p->verdict[k] >= 0) {
        v = p->verdict[k];
    } else {
        const probe_scene *sc = &p->sc;
        double flux, sharp, plateau;
        frame_stats(frame + (size_t)sc->crop_y0 * p->w + sc->crop_x0, sc->crop_w,
                    sc->crop_h, (size_t)p->w, st, &flux, &sharp, &plateau);
        v = judge(p, flux, sharp, plateau);
        if (k >= 0 && k < p->ntotal)
            p->verdict[k] = (signed char)v;
        p->counts[v]++;
    }
    if (v == PROBE_KEEP && out)
        probe_crop_copy(&p->sc, p->w, frame, out);
    return v;
}

void probe_place(const probe_scene *sc, const float *crop, float *full)
{
    int w = sc->width, h = sc->height, cw = sc->crop_w, ch = sc->crop_h;
    memset(full, 0, sizeof(float) * (size_t)w * h);
    int ox = w / 2 - cw / 2, oy = h / 2 - ch / 2;
    for (int y = 0; y < ch; y++)
        memcpy(full + (size_t)(y + oy) * w + ox, crop + (size_t)y * cw,
               sizeof(float) * cw);
}

void probe_report_fill(const probe *p, pipeline_probe_report *r)
{
    const probe_scene *sc = &p->sc;
    r->probed = sc->nprobed;
    r->crop_x0 = sc->crop_x0, r->crop_y0 = sc->crop_y0;
    r->crop_w = sc->crop_w, r->crop_h = sc->crop_h;
    r->cloud_radius_px = sc->cloud_radius_px[sc->crop_level];
    r->cloud_level = cloud_levels[sc->crop_level];
    r->crop_flux_frac = sc->crop_flux_frac;
    r->spectrum = p->o.spectrum;
    r->support_cyc_px = sc->support_cyc_px;
    r->support_frac = sc->support_frac;
    r->extent_px = sc->extent_px;
    r->snr = sc->snr;
    for (int v = 0; v < PROBE_NVERDICT && v < 5; v++)
        r->rejected[v] = p->counts[v];
    r->reject_mad = p->o.reject_mad;
}
