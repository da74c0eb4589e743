/* worker.c - the reconstruction thread; see worker.h. */
#define _GNU_SOURCE
#include "worker.h"

#include <errno.h>
#include <fcntl.h>
#include <glib.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include "calib.h"
#include "catlock.h"
#include "recon_opts.h"
#include "runstate.h"
#include "cubefile.h"
#include "pipeline/pipeline.h"
#include "skyfig.h"
#include "base/version.h"
#include "base/wisdom.h"

typedef struct wjob {
    char uuid[CATALOG_UUID_LEN + 1];
    char method[16];
    int projections;
    char options[RECON_OPTS_MAX];   /* the client's, checked (recon_opts.h) */
    char calibrator[CATALOG_UUID_LEN + 1];   /* "": the nearest; "none"; a run */
    int automatic;
    proto_req req;
} wjob;

struct worker {
    const config *cfg;
    server *srv;
    catalog *cat;      /* the worker thread's own handle */
    catlock_ctx cl;    /* its writes: stop test, reserve */
    GThread *th;
    GMutex mu;         /* guards q, stopping, current */
    GCond cv;
    GQueue q;
    int stopping;
    char current[CATALOG_UUID_LEN + 1];
};

static int stopping(void *worker_arg)
{
    worker *w = worker_arg;
    g_mutex_lock(&w->mu);
    int s = w->stopping;
    g_mutex_unlock(&w->mu);
    return s;
}

/* Move the run to st (runstate.h: waiting out another process's lock). */
static void set_state(worker *w, const char *uuid, catalog_state st, const char *reason)
{
    runstate_set(w->cat, &w->cl, w->srv, uuid, st, reason, NULL, NULL);
}

/* DATA/recon/<uuid>-<method>[-N].fits, created empty (O_EXCL) so two jobs
 * never pick the same name; the .png shares the stem. */
static int output_paths(worker *w, const wjob *j, char **fits, char **png, sl_err *e)
{
    char *dir = g_build_filename(w->cfg->data_dir, "recon", NULL);
    int rc = SL_EIO;
    for (int n = 1; n < 10000 && rc != SL_OK; n++) {
        char *stem = n == 1 ? g_strdup_printf("%s-%s", j->uuid, j->method)
                            : g_strdup_printf("%s-%s-%d", j->uuid, j->method, n);
        char *f = g_strdup_printf("%s/%s.fits", dir, stem);
        int fd = open(f, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
        if (fd >= 0) {
            close(fd);
            *fits = f;
            *png = g_strdup_printf("%s/%s.png", dir, stem);
            rc = SL_OK;
        } else {
            g_free(f);
            if (errno != EEXIST) {
                sl_seterr(e, SL_EIO, "%s/%s.fits: %s", dir, stem, g_strerror(errno));
                g_free(stem);
                break;
            }
        }
        g_free(stem);
    }
    if (rc != SL_OK && !e->msg[0])
        sl_seterr(e, SL_EIO, "%s: no free output name for run %s", dir, j->uuid);
    g_free(dir);
    return rc;
}

static char *json_text(JsonBuilder *b)
{
    JsonNode *n = json_builder_get_root(b);
    g_object_unref(b);
    return proto_take_string(n);
}

/* Reconstruct, write, measure, catalogue.  On success *out holds the new
 * row (strings owned by the caller's buffers below). */
typedef struct outputs {
    char *fits, *png, *params, *quality;
} outputs;

static int insert_recon(catalog *c, void *catalog_recon_arg)
{
    catalog_recon *rec = catalog_recon_arg;
    return catalog_recon_insert(c, rec, &rec->id);
}

/* The reconstruction's figure, titled with OBJECT or, for a bench run
 * without one, the run and what was in the beam. */
static int write_figure(const wjob *j, const pipeline_result *res, const char *png,
                        sl_err *e)
{
    char name[96];
    const char *screen = NULL, *mask = NULL;
    cube_meta_get_str(&res->meta, "SCREEN", &screen);
    cube_meta_get_str(&res->meta, "MASK", &mask);
    if (screen && mask)
        snprintf(name, sizeof name, "run %.8s (%s, %s)", j->uuid, screen, mask);
    else
        snprintf(name, sizeof name, "run %.8s", j->uuid);
    skyfig_opts f;
    skyfig_opts_init(&f);
    skyfig_opts_from_result(&f, res, res->meta.object[0] ? NULL : name);
    return skyfig_write_png(png, res->image, res->width, res->height, &f, e);
}

static void job_opts(const worker *w, const wjob *j, pipeline_opts *po)
{
    pipeline_opts_defaults(po);
    pipeline_method_parse(j->method, &po->method);   /* checked by reconstruct */
    po->nangles = j->projections > 0 ? j->projections : w->cfg->projections;
    /* MEASURE plans run several times faster than ESTIMATE ones but cost
     * ~1 s per new size to time: the wisdom file (loaded when the thread
     * starts, saved after each job) pays that once per size and machine. */
    po->fftw_measure = w->cfg->fftw_measure;
    po->tsm_corrected_phases = w->cfg->tsm_corrected_phases;
    /* Camera frames carry read noise on every pixel; the crop to the
     * speckle cloud keeps it out (a dm 2 companion at 1e4 photons, 2 e-:
     * lost by TSM on the whole 200^2 frame, found on the crop). */
    po->skips = w->cfg->skips;
    /* The binary is measured by every fit and judged (pipeline.h,
     * pipeline_binary): the closure phases' fit met 0.1 px / 0.5 deg /
     * 0.1 mag on 8 of 8 seeds at 5 lambda/D, dm 2, where the image fits
     * met 3 of 8 (direct) and 0 of 4 (TSM-Fourier). */
    po->closure_binary = 1;
}

/* The verdict (recon/pipeline/pipeline_binary.c): the closure-phase fit,
 * else the image fit, else the power spectrum's fringes; catalogued as a
 * binary only when measured, or ambiguous (PA modulo 180 deg).  An
 * unresolved or inconsistent pair keeps no numbers, and says why.
 * Returns where the numbers came from ("none" when not found). */
static const char *verdict(const pipeline_binary *v, binary_result *br)
{
    int found = v->source != PIPE_BIN_SRC_NONE &&
                (v->status == PIPE_BIN_MEASURED || v->status == PIPE_BIN_AMBIGUOUS);
    memset(br, 0, sizeof *br);
    if (!found)
        return "none";
    const binary_result *fit = v->source == PIPE_BIN_SRC_CLOSURE ? &v->closure
                             : v->source == PIPE_BIN_SRC_IMAGE ? &v->image : NULL;
    if (fit)
        *br = *fit;
    br->sep_px = v->sep_px, br->sep_err_px = v->sep_err_px;
    br->pa_deg = v->pa_deg, br->pa_err_deg = v->pa_err_deg;
    br->dm_mag = v->dm_mag, br->dm_err_mag = v->dm_err_mag;
    return v->source == PIPE_BIN_SRC_CLOSURE ? "closure-phase"
                                             : pipeline_binary_source_name(v->source);
}

/* What ran, as the catalogue's params (PROTOCOL.md's recon object). */
static char *params_json(const wjob *j, const pipeline_opts *po, const pipeline_result *res,
                         const calib_set *cal, const char *binary_src)
{
    const pipeline_binary *v = &res->binary;
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    proto_add_str(b, "method", j->method);
    /* auto's choice, so that the catalogue says what ran */
    proto_add_str(b, "ran", pipeline_method_name(res->report.method));
    if (res->report.probe.chosen)
        proto_add_str(b, "chosen", res->report.probe.chosen_label);
    if (res->report.method != PIPE_DIRECT) {   /* pipeline.h: 0 means 180 */
        proto_add_int(b, "projections", res->report.nangles > 0 ? res->report.nangles
                                       : po->nangles > 0 ? po->nangles : 180);
        /* what ran: corrected needs the cube's photon statistics */
        proto_add_str(b, "tsm_phases", res->report.corrected_phases ? "corrected" : "raw");
    }
    proto_add_bool(b, "prep", po->prep);
    recon_opts_params(j->options, b);
    calib_json(cal, b);
    char skips[64];
    pipeline_skips_name(po->skips, skips, sizeof skips);
    proto_add_str(b, "skips", skips);
    proto_add_str(b, "fftw", po->fftw_measure ? "measure" : "estimate");
    proto_add_str(b, "binary", binary_src); /* where sep/PA/dm came from */
    proto_add_str(b, "binary_status", pipeline_binary_status_name(v->status));
    if (v->why[0])
        proto_add_str(b, "binary_why", v->why);
    json_builder_end_object(b);
    return json_text(b);
}

static char *quality_json(const pipeline_result *res, double scale, int found,
                          const binary_result *br)
{
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    proto_add_int(b, "nframes", res->nframes);
    proto_add_int(b, "width", res->width);
    proto_add_int(b, "height", res->height);
    proto_add_dbl(b, "plate_scale_arcsec", scale);
    proto_add_bool(b, "binary_found", found);
    /* Truth-free quality (the catalogue's c against a cophased image needs
     * the truth, which only a simulation has): the |B|-weighted rms of the
     * closure phases left after the binary fit, in degrees.  A point source
     * or a well-fitted binary leaves the noise; a scene the model does not
     * fit, or phases the data cannot support, leave more. */
    const pipeline_binary *v = &res->binary;
    if (v->have_closure) {
        proto_add_dbl(b, "closure_rms_deg", v->closure_info.rms_rad * 180.0 / G_PI);
        proto_add_int(b, "closure_triples", v->closure_info.ntriples);
    }
    if (found) {
        proto_add_dbl(b, "flux_ratio", br->flux_ratio);
        proto_add_dbl(b, "flux_ratio_err", br->flux_ratio_err);
        proto_add_dbl(b, "noise", br->noise);
    }
    json_builder_end_object(b);
    return json_text(b);
}

/* Write the image and its figure, then the catalogue row from them. */
static int record(worker *w, const wjob *j, pipeline_result *res, const char *params,
                  catalog_recon *rec, outputs *o, sl_err *e)
{
    int rc;
    if ((rc = output_paths(w, j, &o->fits, &o->png, e)) != SL_OK)
        return rc;
    seq img = {res->width, res->height, 1, res->image};
    snprintf(res->meta.creator, sizeof res->meta.creator, "specklabd %s", SPECKLAB_VERSION);
    if ((rc = cube_write(o->fits, &img, &res->meta, e)) != SL_OK ||
        (rc = write_figure(j, res, o->png, e)) != SL_OK)
        return rc;
    binary_result br;
    int found = strcmp(verdict(&res->binary, &br), "none") != 0;
    double scale = isfinite(res->plate_scale_arcsec) ? res->plate_scale_arcsec
                                                     : w->cfg->plate_scale_arcsec;
    if (found) {
        rec->sep_px = br.sep_px, rec->sep_err_px = br.sep_err_px;
        rec->pa_deg = br.pa_deg, rec->pa_err_deg = br.pa_err_deg;
        rec->dm_mag = br.dm_mag, rec->dm_err_mag = br.dm_err_mag;
        rec->sep_arcsec = br.sep_px * scale;
    }
    o->params = g_strdup(params);
    o->quality = quality_json(res, scale, found, &br);
    rec->run_uuid = j->uuid;
    rec->method = j->method;
    rec->params_json = o->params;
    rec->elapsed_s = res->elapsed_s;
    rec->output_fits = o->fits;
    rec->output_png = o->png;
    rec->quality_json = o->quality;
    char what[80];
    snprintf(what, sizeof what, "run %s: recording its reconstruction", j->uuid);
    if ((rc = catlock_write(w->cat, &w->cl, what, insert_recon, rec)) != SL_OK)
        sl_seterr(e, rc, "%s", catalog_errmsg(w->cat));
    return rc;
}

/* Reconstruct, write, measure, catalogue. */
static int reconstruct(worker *w, const wjob *j, const catalog_run *run, catalog_recon *rec,
                       outputs *o, sl_err *e)
{
    pipeline_opts po;
    pipeline_result res = {0};
    calib_set cal;
    char *params = NULL;
    int m;
    if (pipeline_method_parse(j->method, &m) != SL_OK)
        return sl_seterr(e, SL_EINVAL, "unknown method '%s'", j->method);
    job_opts(w, j, &po);
    int rc = recon_opts_apply(j->options, &po, e);
    const char *ref = j->calibrator[0] ? j->calibrator : NULL, *cube = run->file_path;
    if (rc != SL_OK ||
        (rc = calib_find(w->cat, w->cfg, j->uuid, run->kind, ref, &cal, e)) != SL_OK)
        return rc;
    calib_apply(&cal, &po);
    catalog_recon_init(rec);
    rec->started_ms = catalog_now_ms();
    if ((rc = pipeline_run(&cube, 1, &po, &res, e)) != SL_OK)
        goto clear_calib;
    binary_result br;
    params = params_json(j, &po, &res, &cal, verdict(&res.binary, &br));
    rc = record(w, j, &res, params, rec, o, e);
    if (rc != SL_OK && o->fits) {   /* no row: leave no orphan files */
        unlink(o->fits);
        unlink(o->png);
    }
    g_free(params);
    pipeline_result_clear(&res);
clear_calib:
    calib_clear(&cal);
    return rc;
}

static void run_job(worker *w, const wjob *j)
{
    catalog_run r;
    sl_err e = {0};
    outputs o = {0};
    catalog_recon rec;
    int rc = catalog_run_get(w->cat, j->uuid, &r);
    if (rc != SL_OK) {
        sl_seterr(&e, rc, "%s", catalog_errmsg(w->cat));
        goto reply;
    }
    if (j->automatic && !strcmp(j->method, "none")) {
        set_state(w, j->uuid, CATALOG_DONE, NULL);
        goto clear_run;
    }
    if (!r.file_path || !cubefile_under(w->cfg->data_dir, r.file_path)) {
        rc = sl_seterr(&e, SL_EINVAL, "run %s has no cube under the data directory %s",
                       j->uuid, w->cfg->data_dir);
    } else {
        if (j->automatic)
            set_state(w, j->uuid, CATALOG_RECONSTRUCTING, NULL);
        g_message("run %s: reconstructing (%s)", j->uuid, j->method);
        rc = reconstruct(w, j, &r, &rec, &o, &e);
    }
    if (rc == SL_OK) {
        server_event_async(w->srv, j->uuid, proto_event_recon(j->uuid, proto_recon_node(&rec)));
        g_message("run %s: %s done in %.2f s: sep %.3f px, PA %.2f deg, dm %.2f", j->uuid,
                  j->method, rec.elapsed_s, rec.sep_px, rec.pa_deg, rec.dm_mag);
    } else {
        g_warning("run %s: reconstruction failed: %s", j->uuid, e.msg);
    }
    if (j->automatic) {
        char *why = rc == SL_OK ? NULL : g_strdup_printf("reconstruction failed: %s", e.msg);
        set_state(w, j->uuid, CATALOG_DONE, why);
        g_free(why);
    }
clear_run:
    catalog_run_clear(&r);
reply:
    if (!j->automatic) {
        char *line;
        if (rc == SL_OK) {
            JsonBuilder *b = json_builder_new();
            json_builder_begin_object(b);
            proto_add_str(b, "run", j->uuid);
            json_builder_set_member_name(b, "reconstruction");
            json_builder_add_value(b, proto_recon_node(&rec));
            json_builder_end_object(b);
            JsonNode *n = json_builder_get_root(b);
            g_object_unref(b);
            line = proto_reply_ok(&j->req, n);
        } else {
            line = proto_reply_error(&j->req, "internal", "reconstruction of run %s failed: %s",
                                     j->uuid, e.msg);
        }
        server_complete_async(w->srv, j->req.tok, line);
    }
    g_free(o.fits);
    g_free(o.png);
    g_free(o.params);
    g_free(o.quality);
}

/* Reconstruction yields to acquisition: on a bench PC it shares the CPUs
 * with the run being acquired, whose frames are lost when the camera's
 * buffers are not emptied and stored in time, whereas a reconstruction
 * only ends later.  Nice 10 gives it about a tenth of a CPU's share beside
 * a nice-0 thread that wants the CPU, and all of it otherwise; the threads
 * it starts (the pipeline's team, FFTW's) inherit the value. */
#define WORKER_NICE 10

static void yield_to_acquisition(void)
{
    pid_t tid = (pid_t)syscall(SYS_gettid);
    if (setpriority(PRIO_PROCESS, (id_t)tid, WORKER_NICE) != 0)
        g_message("recon thread: cannot lower its priority: %s", g_strerror(errno));
}

/* DATA_DIR/fftw-wisdom: FFTW's planner state is global, so only this
 * thread (the daemon's one planner) imports and exports it. */
static void wisdom(worker *w, int save)
{
    sl_err e = {0};
    if (!w->cfg->fftw_measure)
        return;
    char *path = g_build_filename(w->cfg->data_dir, "fftw-wisdom", NULL);
    if (!save)
        wisdom_plan_limit(WISDOM_PLAN_LIMIT_S);
    if ((save ? wisdom_save(path, &e) : wisdom_load(path, NULL, &e)) != SL_OK)
        g_warning("%s", e.msg);
    g_free(path);
}

static gpointer thread_main(gpointer data)
{
    worker *w = data;
    yield_to_acquisition();
    wisdom(w, 0);
    for (;;) {
        g_mutex_lock(&w->mu);
        while (!w->stopping && g_queue_is_empty(&w->q))
            g_cond_wait(&w->cv, &w->mu);
        wjob *j = w->stopping ? NULL : g_queue_pop_head(&w->q);
        if (j)
            memcpy(w->current, j->uuid, sizeof w->current);
        g_mutex_unlock(&w->mu);
        if (!j)
            break;
        run_job(w, j);
        wisdom(w, 1);
        g_free(j);
        g_mutex_lock(&w->mu);
        w->current[0] = '\0';
        g_mutex_unlock(&w->mu);
    }
    /* Stopping: what is still queued is settled, not run. */
    wjob *j;
    while ((j = g_queue_pop_head(&w->q))) {
        if (j->automatic)
            set_state(w, j->uuid, CATALOG_DONE, "reconstruction not run: daemon stopping");
        else
            server_complete_async(w->srv, j->req.tok,
                                  proto_reply_error(&j->req, "internal",
                                                    "daemon stopping: reconstruction of "
                                                    "run %s not run", j->uuid));
        g_free(j);
    }
    return NULL;
}

int worker_new(worker **out, const config *cfg, server *srv, reserve *rs, sl_err *err)
{
    worker *w = g_new0(worker, 1);
    catalog_opts co = {cfg->catalog_busy_timeout_ms};
    int rc = catalog_open_opts(&w->cat, cfg->catalog, &co, err);
    if (rc != SL_OK) {
        g_free(w);
        *out = NULL;
        return rc;
    }
    w->cfg = cfg;
    w->srv = srv;
    w->cl = (catlock_ctx){stopping, w, rs};
    g_mutex_init(&w->mu);
    g_cond_init(&w->cv);
    g_queue_init(&w->q);
    w->th = g_thread_new("recon", thread_main, w);
    *out = w;
    return SL_OK;
}

int worker_submit(worker *w, const char *uuid, const char *method, int projections,
                  const worker_extra *extra, const proto_req *req)
{
    wjob *j = g_new0(wjob, 1);
    snprintf(j->uuid, sizeof j->uuid, "%s", uuid);
    snprintf(j->options, sizeof j->options, "%s", extra && extra->options ? extra->options : "");
    snprintf(j->calibrator, sizeof j->calibrator, "%s",
             extra && extra->calibrator ? extra->calibrator : "");
    snprintf(j->method, sizeof j->method, "%s", method);
    j->projections = projections;
    j->automatic = req == NULL;
    if (req)
        j->req = *req;
    g_mutex_lock(&w->mu);
    int ahead = (int)g_queue_get_length(&w->q) + (w->current[0] != '\0');
    g_queue_push_tail(&w->q, j);
    g_cond_signal(&w->cv);
    g_mutex_unlock(&w->mu);
    return ahead;
}

void worker_status(worker *w, char current[CATALOG_UUID_LEN + 1], int *queued)
{
    g_mutex_lock(&w->mu);
    memcpy(current, w->current, CATALOG_UUID_LEN + 1);
    *queued = (int)g_queue_get_length(&w->q);
    g_mutex_unlock(&w->mu);
}

void worker_stop(worker *w)
{
    if (!w || !w->th)
        return;
    g_mutex_lock(&w->mu);
    w->stopping = 1;
    g_cond_signal(&w->cv);
    g_mutex_unlock(&w->mu);
    g_thread_join(w->th);
    w->th = NULL;
}

void worker_free(worker *w)
{
    if (!w)
        return;
    worker_stop(w);
    catalog_close(w->cat);
    g_queue_clear(&w->q);
    g_mutex_clear(&w->mu);
    g_cond_clear(&w->cv);
    g_free(w);
}
