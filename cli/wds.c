/* wds.c - see wds.h. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "base/utcdate.h"
#include "binmeas.h"
#include "cli.h"
#include "measure/metrics.h"
#include "wds.h"

int wds_measure_from(const pipeline_binary *v, double ps, const cube_meta *m,
                     int nframes, wds_measure *out, sl_err *err)
{
    memset(out, 0, sizeof *out);
    if (!(ps > 0) || !isfinite(ps))
        return sl_seterr(err, SL_EINVAL, "no plate scale (PLTSCALE): rho in arcsec "
                         "needs it");
    double mjd = 0;
    if (m->date_obs[0]) {
        sl_err de = {0};
        if (utcdate_mjd(m->date_obs, &mjd, &de) != SL_OK)
            return sl_seterr(err, SL_EINVAL, "DATE-OBS: %s", de.msg);
        out->has_date = 1;
        out->epoch = utcdate_besselian_year(mjd);
    }
    out->status = v->status;
    out->source = v->source;
    out->theta_deg = fmod(fmod(v->pa_deg, 360) + 360, 360);
    out->theta_err_deg = v->pa_err_deg;
    out->rho_arcsec = v->sep_px * ps;
    out->rho_err_arcsec = v->sep_err_px * ps;
    out->dm_mag = v->dm_mag;
    out->dm_err_mag = v->dm_err_mag;
    int numbers = v->status == PIPE_BIN_MEASURED || v->status == PIPE_BIN_AMBIGUOUS;
    size_t k = 0;
    if (numbers && nframes > 0)
        k = (size_t)snprintf(out->note, sizeof out->note, "%d frames", nframes);
    if (numbers && isfinite(m->wavelength_m) && k < sizeof out->note)
        k += (size_t)snprintf(out->note + k, sizeof out->note - k, "%s%.0f nm",
                              k ? ", " : "", m->wavelength_m * 1e9);
    if (v->why[0] && k < sizeof out->note)
        k += (size_t)snprintf(out->note + k, sizeof out->note - k, "%s%s", k ? "; " : "",
                              v->why);
    if (!out->has_date && k < sizeof out->note)
        snprintf(out->note + k, sizeof out->note - k, "%sno DATE-OBS", k ? "; " : "");
    return SL_OK;
}

void wds_format(const wds_measure *w, char *buf, size_t n)
{
    char date[16];
    if (w->has_date)
        snprintf(date, sizeof date, "%.4f", w->epoch);
    else
        snprintf(date, sizeof date, "nodate");
    if (w->status != PIPE_BIN_MEASURED && w->status != PIPE_BIN_AMBIGUOUS) {
        snprintf(buf, n, "%s  %s  speckle  %s", date,
                 pipeline_binary_status_name(w->status), w->note[0] ? w->note : "-");
        return;
    }
    snprintf(buf, n, "%s  %6.2f %.2f  %.4f %.4f  %.2f %.2f  %s  speckle/%s  %s", date,
             w->theta_deg, w->theta_err_deg, w->rho_arcsec, w->rho_err_arcsec, w->dm_mag,
             w->dm_err_mag, w->status == PIPE_BIN_AMBIGUOUS ? "Q" : "-",
             pipeline_binary_source_name(w->source), w->note[0] ? w->note : "-");
}

/* An image's verdict: the one recon --binary wrote, else the image fit. */
static int image_verdict(const char *path, const char *ext, pipeline_binary *v,
                         cube_meta *m, sl_err *e)
{
    seq *img = NULL;
    const char *paths[] = {path};
    cube_reader *r = NULL;
    int rc = cube_reader_open(&r, paths, 1, 0, e);
    if (rc == SL_OK)
        *m = *cube_reader_meta(r);
    cube_reader_free(r);
    if (rc == SL_OK)
        rc = ext ? cube_read_ext(&img, path, ext, e) : cube_read(&img, NULL, paths, 1, 0, e);
    if (rc != SL_OK)
        return rc;
    binmeas_from_header(m, v);
    binary_result b;
    if (v->status == PIPE_BIN_NONE) {
        if (metrics_binary(img->data, img->width, img->height, &b) == SL_OK) {
            v->status = b.pa_ambiguous ? PIPE_BIN_AMBIGUOUS : PIPE_BIN_MEASURED;
            v->source = PIPE_BIN_SRC_IMAGE;
            v->sep_px = b.sep_px, v->sep_err_px = b.sep_err_px;
            v->pa_deg = b.pa_deg, v->pa_err_deg = b.pa_err_deg;
            v->dm_mag = b.dm_mag, v->dm_err_mag = b.dm_err_mag;
        } else {
            v->status = PIPE_BIN_UNRESOLVED;
            snprintf(v->why, sizeof v->why, "no second component in the image");
        }
    }
    seq_free(img);
    return SL_OK;
}

static void print_json(const wds_measure *w, const char *line)
{
    JsonBuilder *jb = json_builder_new();
    json_builder_begin_object(jb);
    cli_json_str(jb, "wds", line);
    cli_json_str(jb, "status", pipeline_binary_status_name(w->status));
    cli_json_num(jb, "epoch_besselian", w->has_date ? w->epoch : NAN);
    if (w->status == PIPE_BIN_MEASURED || w->status == PIPE_BIN_AMBIGUOUS) {
        cli_json_num(jb, "theta_deg", w->theta_deg);
        cli_json_num(jb, "theta_err_deg", w->theta_err_deg);
        cli_json_num(jb, "rho_arcsec", w->rho_arcsec);
        cli_json_num(jb, "rho_err_arcsec", w->rho_err_arcsec);
        cli_json_num(jb, "dm_mag", w->dm_mag);
        cli_json_num(jb, "dm_err_mag", w->dm_err_mag);
        json_builder_set_member_name(jb, "quadrant_ambiguous");
        json_builder_add_boolean_value(jb, w->status == PIPE_BIN_AMBIGUOUS);
    }
    json_builder_end_object(jb);
    cli_print_json(jb);
    g_object_unref(jb);
}

int wds_binary(const char *path, const char *ext, int json)
{
    sl_err e = {0};
    const char *paths[] = {path};
    cube_reader *cr = NULL;
    if (cube_reader_open(&cr, paths, 1, 0, &e) != SL_OK) {
        fprintf(stderr, "specklab binary --wds: %s\n", e.msg);
        return 1;
    }
    /* rho needs the plate scale: say so before reconstructing */
    double ps0 = cube_reader_meta(cr)->plate_scale_arcsec;
    int nfr = ext ? 1 : cube_reader_nframes(cr);
    cube_reader_free(cr);
    if (!(ps0 > 0)) {
        fprintf(stderr, "specklab binary --wds: %s: no plate scale (PLTSCALE): rho in "
                "arcsec needs it\n", path);
        return 1;
    }
    pipeline_result r;
    memset(&r, 0, sizeof r);
    pipeline_binary v;
    cube_meta m;
    int rc;
    if (nfr > 1) { /* as `specklab binary CUBE`: direct, closure phases */
        pipeline_opts o;
        pipeline_opts_defaults(&o);
        o.method = PIPE_DIRECT;
        o.closure_binary = 1;
        if ((rc = pipeline_run(paths, 1, &o, &r, &e)) == SL_OK) {
            v = r.binary;
            m = r.meta;
            m.plate_scale_arcsec = r.plate_scale_arcsec;
            nfr = r.nframes;
        }
    } else {
        double n = 0;
        rc = image_verdict(path, ext, &v, &m, &e);
        nfr = rc == SL_OK && cube_meta_get_num(&m, "RECNFRM", &n) == SL_OK ? (int)n : 0;
    }
    wds_measure w;
    if (rc == SL_OK)
        rc = wds_measure_from(&v, m.plate_scale_arcsec, &m, nfr, &w, &e);
    pipeline_result_clear(&r);
    if (rc != SL_OK) {
        fprintf(stderr, "specklab binary --wds: %s: %s\n", path, e.msg);
        return 1;
    }
    char line[512];
    wds_format(&w, line, sizeof line);
    if (json)
        print_json(&w, line);
    else
        printf("%s\n", line);
    return w.status == PIPE_BIN_UNRESOLVED;
}
