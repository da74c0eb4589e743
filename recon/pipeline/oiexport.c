/* oiexport.c - see oiexport.h. */
#include "oiexport.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/utcdate.h"

#define RAD_ARCSEC (180.0 * 3600.0 / M_PI)

void oiexport_opts_defaults(oiexport_opts *o)
{
    memset(o, 0, sizeof *o);
    pipeline_opts_defaults(&o->clean);
    o->clean.skips = 0;
    o->wavelength_m = NAN;
    o->plate_scale_arcsec = NAN;
}

void oiexport_result_clear(oiexport_result *r)
{
    maskobs_result_clear(&r->obs);
    free(r->sta);
    free(r->vis2);
    free(r->t3);
    memset(r, 0, sizeof *r);
}

/* The option, else the header's value; SL_EINVAL naming the keyword. */
static int pick(double opt, double hdr, const char *key, const char *what,
                const char *path, double *out, sl_err *err)
{
    *out = isfinite(opt) ? opt : hdr;
    if (!(*out > 0) || !isfinite(*out))
        return sl_seterr(err, SL_EINVAL, "%s: no %s (%s is %s): give it as an "
                         "option", path, what, key, isfinite(hdr) ? "not > 0" : "absent");
    return SL_OK;
}

static int add_frame(void *h, const float *frame)
{
    return maskobs_add(h, frame);
}

/* Measure: the observables of every cleaned frame into r->obs. */
static int measure(framefeed *ff, const oiexport_mask *mk, const oiexport_opts *o,
                   oiexport_result *r, sl_err *err)
{
    maskobs_opts mo;
    maskobs_opts_defaults(&mo);
    mo.wavelength_m = r->wavelength_m;
    mo.plate_scale_arcsec = r->plate_scale_arcsec;
    mo.adu_per_photon = r->photons.adu_per_photon;
    mo.read_noise_adu = r->photons.read_noise_adu;
    mo.block_frames = o->block_frames;
    mo.measure = o->clean.fftw_measure;
    maskobs *m = maskobs_new(mk->x_m, mk->y_m, mk->nholes, mk->hole_diameter_m,
                             framefeed_width(ff), framefeed_height(ff), &mo, err);
    if (!m)
        return err ? err->code : SL_ENOMEM;
    int rc = framefeed_run(ff, add_frame, m, "mask observables", err);
    if (rc == SL_OK && (rc = maskobs_result_get(m, &r->obs)) != SL_OK)
        sl_seterr(err, rc, "%s", maskobs_errmsg(m));
    maskobs_free(m);
    return rc;
}

static void hist(oiexport_result *r, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
static void hist(oiexport_result *r, const char *fmt, ...)
{
    size_t n = strlen(r->history);
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(r->history + n, sizeof r->history - n, fmt, ap);
    va_end(ap);
    n = strlen(r->history);
    if (n + 1 < sizeof r->history)
        r->history[n] = '\n', r->history[n + 1] = 0;
}

static void history(oiexport_result *r, const char *const *paths, int npaths,
                    const oiexport_mask *mk, int have_pos)
{
    const maskobs_result *b = &r->obs;
    hist(r, "specklab oifits: %s%s", paths[0], npaths > 1 ? " and more" : "");
    hist(r, "frames: %d used, %d without flux; cleaned as specklab recon", b->nframes,
         b->nskipped);
    hist(r, "mask %s: %d holes of %.3g m; %d of %d baselines and %d of %d triangles "
         "redundant (no clean pixel): not written", mk->name, mk->nholes,
         mk->hole_diameter_m, b->nvis2_lost, b->nvis2 + b->nvis2_lost, b->nt3_lost,
         b->nt3 + b->nt3_lost);
    hist(r, "lambda %.6g m, plate scale %.6g arcsec/px; one FFT pixel per baseline",
         r->wavelength_m, r->plate_scale_arcsec);
    hist(r, "photon bias: %s (%.4g photons/frame)", r->photons.adu_per_photon > 0
         ? pipeline_photon_source_name(r->photons.source) : "not removed",
         r->photons.photons);
    hist(r, "errors: frame scatter x correlation factor V2 %.2f, phase %.2f, amp %.2f "
         "(%d blocks)", sqrt(b->corr_vis2), sqrt(b->corr_phi), sqrt(b->corr_amp),
         b->nblocks);
    hist(r, "VIS2DATA, T3AMP raw: divided by the mask's transfer, not calibrated");
    hist(r, "UCOORD east, VCOORD north; STAXYZ = (-x, y) of the mask's holes");
    if (!have_pos)
        hist(r, "RAEP0, DECEP0 0: the position is not known (no RA, DEC)");
}

static void fill_stations(oiexport_result *r, const oiexport_mask *mk)
{
    for (int i = 0; i < mk->nholes; i++) {
        oifits_station *s = &r->sta[i];
        snprintf(s->tel_name, sizeof s->tel_name, "H%d", i + 1);
        snprintf(s->sta_name, sizeof s->sta_name, "H%d", i + 1);
        s->diameter_m = mk->hole_diameter_m;
        s->xyz_m[0] = -mk->x_m[i];
        s->xyz_m[1] = mk->y_m[i];
        s->xyz_m[2] = 0;
        s->fov_arcsec = 1.22 * r->wavelength_m / mk->hole_diameter_m * RAD_ARCSEC;
    }
}

static void fill_rows(oiexport_result *r)
{
    for (int i = 0; i < r->obs.nvis2; i++) {
        const maskobs_vis2 *v = &r->obs.vis2[i];
        r->vis2[i] = (oifits_vis2){{v->sta[0], v->sta[1]}, v->u_m, v->v_m, v->vis2,
                                   v->vis2_err, 0};
    }
    for (int i = 0; i < r->obs.nt3; i++) {
        const maskobs_t3 *t = &r->obs.t3[i];
        r->t3[i] = (oifits_t3){{t->sta[0], t->sta[1], t->sta[2]}, t->u1_m, t->v1_m,
                               t->u2_m, t->v2_m, t->amp, t->amp_err, t->phi_deg,
                               t->phi_err_deg, 0};
    }
}

static void copy_str(char *dst, const char *src)
{
    snprintf(dst, OIFITS_NAME_MAX, "%.68s", src ? src : "");
}

/* The primary header's and the target's strings. */
static void fill_names(oiexport_result *r, const cube_meta *m, const oiexport_mask *mk,
                       const oiexport_opts *o, const char *date_obs)
{
    oifits_data *d = &r->oi;
    const char *s;
    copy_str(d->origin, "specklab");
    copy_str(d->instrume, m->instrume[0] ? m->instrume : "specklab");
    copy_str(d->telescop, cube_meta_get_str(m, "TELESCOP", &s) == SL_OK ? s : "");
    copy_str(d->observer, cube_meta_get_str(m, "OBSERVER", &s) == SL_OK ? s : "");
    snprintf(d->insmode, sizeof d->insmode, "NRM %.60s", mk->name);
    copy_str(d->obstech, "aperture masking, speckle frames");
    copy_str(d->procsoft, "specklab oifits");
    copy_str(d->date_obs, date_obs);
    copy_str(d->target, o->target ? o->target : m->object[0] ? m->object : "");
    copy_str(d->arrname, mk->name);
    snprintf(d->insname, sizeof d->insname, "%.30s/%.30s", d->instrume, mk->name);
}

/* Everything oifits_write needs, pointing into r. */
static int fill_oifits(oiexport_result *r, const char *const *paths, int npaths,
                       const cube_meta *m, const oiexport_mask *mk,
                       const oiexport_opts *o, const char *date_obs, sl_err *err)
{
    oifits_data *d = &r->oi;
    oifits_data_init(d);
    r->sta = calloc((size_t)mk->nholes, sizeof *r->sta);
    r->vis2 = calloc((size_t)(r->obs.nvis2 ? r->obs.nvis2 : 1), sizeof *r->vis2);
    r->t3 = calloc((size_t)(r->obs.nt3 ? r->obs.nt3 : 1), sizeof *r->t3);
    if (!r->sta || !r->vis2 || !r->t3)
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    fill_names(r, m, mk, o, date_obs);
    double mjd0 = 0, ra = 0, dec = 0;
    sl_err de = {0};
    if (utcdate_mjd(date_obs, &mjd0, &de) != SL_OK)
        return sl_seterr(err, de.code, "%s: DATE-OBS: %s", paths[0], de.msg);
    int have_pos = cube_meta_get_num(m, "RA", &ra) == SL_OK &&
                   cube_meta_get_num(m, "DEC", &dec) == SL_OK;
    d->ra_deg = have_pos ? ra : 0;
    d->dec_deg = have_pos ? dec : 0;
    d->int_time_s = isfinite(m->exptime_s) ? r->obs.nframes * m->exptime_s : 0;
    d->mjd = mjd0 + d->int_time_s / 2 / 86400.0;
    d->eff_wave_m = r->wavelength_m;
    d->eff_band_m = o->bandwidth_m;
    fill_stations(r, mk);
    fill_rows(r);
    d->sta = r->sta, d->nsta = mk->nholes;
    d->vis2 = r->vis2, d->nvis2 = r->obs.nvis2;
    d->t3 = r->t3, d->nt3 = r->obs.nt3;
    history(r, paths, npaths, mk, have_pos);
    d->history = r->history;
    return SL_OK;
}

int oiexport_run(const char *const *paths, int npaths, const oiexport_mask *mask,
                 const oiexport_opts *o, oiexport_result *out, sl_err *err)
{
    memset(out, 0, sizeof *out);
    framefeed *ff = NULL;
    int rc = framefeed_open(&ff, paths, npaths, &o->clean, err);
    if (rc != SL_OK)
        return rc;
    const cube_meta *m = framefeed_meta(ff);
    const char *date_obs = o->date_obs ? o->date_obs : m->date_obs;
    if ((rc = pick(o->wavelength_m, m->wavelength_m, "WAVELEN", "wavelength", paths[0],
                   &out->wavelength_m, err)) != SL_OK ||
        (rc = pick(o->plate_scale_arcsec, m->plate_scale_arcsec, "PLTSCALE", "plate scale",
                   paths[0], &out->plate_scale_arcsec, err)) != SL_OK)
        goto close_ff;
    if (!date_obs[0]) {
        rc = sl_seterr(err, SL_EINVAL, "%s: no DATE-OBS: OIFITS needs the date of the "
                       "observation (give it as an option)", paths[0]);
        goto close_ff;
    }
    if ((rc = framefeed_photons_get(ff, &o->clean, &out->photons, err)) == SL_OK &&
        (rc = measure(ff, mask, o, out, err)) == SL_OK)
        rc = fill_oifits(out, paths, npaths, m, mask, o, date_obs, err);
close_ff:
    if (rc != SL_OK)
        oiexport_result_clear(out);
    framefeed_free(ff);
    return rc;
}
