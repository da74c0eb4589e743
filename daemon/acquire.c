/* acquire.c - one run's acquisition on the runner thread: camera ready,
 * frames into the .part cube, then the cube finished on disk and
 * catalogued (see runner.h for the sequence and its guarantees).
 *
 * Costs per frame: one camera_pop (a copy of the pixels into floats), one
 * cube_writer_append (cfitsio buffered write, the only per-frame I/O),
 * one seeing_add (one pass over the pixels) and a 40-byte FRAMES row in
 * memory (4 MB at 100000 frames).  Flushing (header rewrite + fill) and
 * the progress event happen at most every 100 ms; the catalogue's
 * progress (one fsynced commit) at most every second, on a helper thread
 * (see progress_writer: never on the frame loop).
 */
#define _GNU_SOURCE
#include "runner_int.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "base/version.h"
#include "camlink.h"
#include "io/cube.h"
#include "cubefile.h"
#include "progress.h"
#include "framelog.h"
#include "measure/seeing.h"

#define POP_SLICE_MS 200        /* abort and loss are checked this often */
#define FLUSH_US 100000         /* cube flush + progress event period */
#define CATALOG_US 1000000      /* catalogue progress period */
/* Control lost mid-run is tried back this many times, each bounded. */
#define MAX_RECONNECTS 3
#define RECONNECT_MS 3000

struct acq {
    runner *r;
    const runner_spec *sp;
    camera_config cf;
    camera_info info;
    char *part, *final;
    cube_writer *w;
    GArray *rows;              /* cubefile_row */
    float *pix;
    seeing *see;
    int stored, failed;
    int64_t packets_missing;
    camera_stats base;         /* the handle's counters at the run's start */
    gint64 t_flush;
    int reconnects;            /* camera control taken back this run */
    progress_writer pw;        /* the catalogue's progress row */
    framelog *fl;              /* the rows on disk (framelog.h), NULL once closed */
    char *fl_path;
    guint fl_logged;           /* rows already in it */
};

/* This run's camera counters: the handle's totals carry over from run to
 * run (and across reconnects), so subtract those at the start. */
static uint64_t since(uint64_t now, uint64_t base)
{
    return now >= base ? now - base : 0;
}

static void run_stats(const acq *a, camera_stats *out)
{
    camera_stats n;
    const camera_stats *b = &a->base;
    camera_stats_get(a->r->cam, &n);
    out->completed = since(n.completed, b->completed);
    out->failed = since(n.failed, b->failed);
    for (int i = 0; i < CAMERA_FRAME_NSTATUS; i++)
        out->by_status[i] = since(n.by_status[i], b->by_status[i]);
    out->missing_packets = since(n.missing_packets, b->missing_packets);
    out->resent_packets = since(n.resent_packets, b->resent_packets);
    out->underruns = since(n.underruns, b->underruns);
    out->id_gaps = since(n.id_gaps, b->id_gaps);
    out->timeouts = since(n.timeouts, b->timeouts);
    out->reconnects = since(n.reconnects, b->reconnects);
}

static void fill_meta(acq *a, cube_meta *m)
{
    const runner_spec *sp = a->sp;
    const config *cfg = a->r->cfg;
    cube_meta_init(m);
    snprintf(m->instrume, sizeof m->instrume, "%.30s %.30s", a->info.vendor, a->info.model);
    g_strlcpy(m->object, sp->object, sizeof m->object);
    snprintf(m->bunit, sizeof m->bunit, "adu");
    m->exptime_s = a->cf.exposure_us * 1e-6;
    m->plate_scale_arcsec = cfg->plate_scale_arcsec;
    m->wavelength_m = cfg->wavelength_m;
    snprintf(m->creator, sizeof m->creator, "specklabd %s", SPECKLAB_VERSION);
    cube_meta_add_history(m, "specklabd run %s: %d frames asked through screen %s (slot %d) "
                          "and mask %s (slot %d)", sp->uuid, sp->frames, sp->screen,
                          sp->screen_slot, sp->mask, sp->mask_slot);
    cube_meta_set_str(m, "RUNUUID", sp->uuid, "specklab run");
    /* IRAF's values, which ds9, ccdproc and astropy's tools read */
    cube_meta_set_str(m, "IMAGETYP", sp->kind == CATALOG_DARK ? "dark"
                      : sp->kind == CATALOG_FLAT ? "flat" : "object",
                      catalog_kind_name(sp->kind ? sp->kind : CATALOG_SCIENCE));
    cube_meta_set_str(m, "SCREEN", sp->screen, "phase screen in the beam");
    cube_meta_set_num(m, "SCRSLOT", sp->screen_slot, "screen wheel slot");
    cube_meta_set_str(m, "MASK", sp->mask, "pupil mask in the beam");
    cube_meta_set_num(m, "MSKSLOT", sp->mask_slot, "mask wheel slot");
    cube_meta_set_str(m, "CAMSER", a->info.serial, "camera serial number");
    cube_meta_set_str(m, "CAMADDR", a->info.address, "camera address");
    cube_meta_set_str(m, "PIXFMT", camera_pixfmt_name(a->cf.pixel_format), "pixel format");
    cube_meta_set_num(m, "ROIX", a->cf.x, "[px] ROI offset x on the sensor");
    cube_meta_set_num(m, "ROIY", a->cf.y, "[px] ROI offset y on the sensor");
    cube_meta_set_num(m, "BINX", a->cf.bin_x, "binning x");
    cube_meta_set_num(m, "BINY", a->cf.bin_y, "binning y");
    if (isfinite(a->cf.gain_db))
        cube_meta_set_num(m, "GAINDB", a->cf.gain_db, "[dB] camera gain");
    if (isfinite(cfg->gain_e_per_adu)) {
        /* GenICam Gain amplifies: 20 log10 more ADU per electron */
        double g = cfg->gain_e_per_adu *
                   (isfinite(a->cf.gain_db) ? pow(10.0, -a->cf.gain_db / 20.0) : 1.0);
        cube_meta_set_num(m, "GAIN", g, "[e-/adu] detector gain");
    }
    if (isfinite(cfg->read_noise_e))
        cube_meta_set_num(m, "RDNOISE", cfg->read_noise_e, "[e-] read noise rms");
    if (isfinite(a->cf.frame_rate_hz))
        cube_meta_set_num(m, "FRATE", a->cf.frame_rate_hz, "[Hz] frame rate setting");
}

/* Damaged frames a run tolerates before it fails. */
static int max_failed(const runner *r, const runner_spec *sp)
{
    return r->cfg->max_failed_frames > 0 ? r->cfg->max_failed_frames : MAX(100, sp->frames);
}

/* Flush the cube, log the rows of the frames flushed (framelog.h), then
 * tell subscribers: a progress event never counts a frame that is not on
 * disk. */
static int flush_progress(acq *a, sl_err *e)
{
    if (cube_writer_flush(a->w) != SL_OK)
        return sl_seterr(e, SL_EIO, "%s", cube_writer_errmsg(a->w));
    a->t_flush = g_get_monotonic_time();
    if (a->fl) {
        sl_err le = {0};
        const cubefile_row *rows = (const cubefile_row *)(void *)a->rows->data;
        if (framelog_append(a->fl, rows + a->fl_logged, (long)(a->rows->len - a->fl_logged),
                            &le) == SL_OK) {
            a->fl_logged = a->rows->len;
        } else {   /* only a restart's rebuild of the table would miss them */
            g_warning("run %s: %s", a->sp->uuid, le.msg);
            framelog_close(a->fl);
            a->fl = NULL;
        }
    }
    runner_note_progress(a->r, a->stored, a->failed, -1);
    server_event_async(a->r->srv, a->sp->uuid,
                       proto_event_progress(a->sp->uuid, a->stored, a->sp->frames, a->failed));
    return SL_OK;
}

/* Control of the camera was lost mid-run: its heartbeat went unanswered
 * in time (the camera or this host too busy, a link blip), which does not
 * mean the camera is gone.  Take it again, bounded, and go on with the
 * run; frames it sent meanwhile are id gaps.  SL_OK when it is back. */
static int take_camera_back(acq *a)
{
    runner *r = a->r;
    gint64 t0 = g_get_monotonic_time();
    a->reconnects++;
    g_message("run %s: %s after %d frames; taking the camera back (%d of %d)", a->sp->uuid,
              camera_errmsg(r->cam), a->stored, a->reconnects, MAX_RECONNECTS);
    int rc = camera_reconnect(r->cam, RECONNECT_MS);
    if (rc == SL_OK)
        g_message("run %s: camera back after %.1f s", a->sp->uuid,
                  (g_get_monotonic_time() - t0) * 1e-6);
    else
        g_message("run %s: camera not back: %s", a->sp->uuid, camera_errmsg(r->cam));
    return rc;
}

/* The camera can go between camlink_ready and here (the cube's files come
 * first): a stream it refuses is taken back as mid-run, within the run's
 * MAX_RECONNECTS.  A refused setting (SL_EINVAL, SL_ERANGE) is not. */
static int start_stream(acq *a)
{
    camera *c = a->r->cam;
    int rc = camera_start(c, a->r->cfg->buffers);
    while (rc != SL_OK && rc != SL_EINVAL && rc != SL_ERANGE && a->reconnects < MAX_RECONNECTS &&
           take_camera_back(a) == SL_OK)
        rc = camera_start(c, a->r->cfg->buffers);
    return rc;
}

/* No frame this slice (rc CAMERA_ETIMEOUT or CAMERA_ELOST): 0 to go on
 * (a timeout within lost_timeout_s, or control taken back), 1 when the
 * run ends, with the reason.  An unplugged USB camera ends it at once. */
static int no_frame(acq *a, int rc, gint64 now, gint64 *t_frame, char *reason, size_t rlen)
{
    runner *r = a->r;
    char why[256];
    if (runner_camera_unplugged(r, rc == CAMERA_ELOST, why, sizeof why)) {
        snprintf(reason, rlen, "camera unplugged after %d of %d frames: %s", a->stored,
                 a->sp->frames, why);
    } else if (rc == CAMERA_ETIMEOUT && now - *t_frame <= r->cfg->lost_timeout_s * 1e6) {
        return 0;
    } else if (rc == CAMERA_ELOST && a->reconnects < MAX_RECONNECTS &&
               take_camera_back(a) == SL_OK) {
        *t_frame = g_get_monotonic_time();
        return 0;
    } else {
        snprintf(reason, rlen, "camera lost after %d of %d frames: %s", a->stored,
                 a->sp->frames, rc == CAMERA_ELOST ? camera_errmsg(r->cam) : "no frame for");
        if (rc == CAMERA_ETIMEOUT)
            snprintf(reason + strlen(reason), rlen - strlen(reason), " %.1f s",
                     (now - *t_frame) * 1e-6);
    }
    runner_note_camera(r, 0, NULL, reason);
    return 1;
}

/* The frame loop.  Returns how it ended, with the reason. */
static acq_end stream(acq *a, char *reason, size_t rlen)
{
    runner *r = a->r;
    const runner_spec *sp = a->sp;
    size_t npx = (size_t)a->cf.width * (size_t)a->cf.height;
    camera_frame fr = {.f32 = a->pix, .capacity_px = npx};
    int max_fail = max_failed(r, sp);
    gint64 t_frame = g_get_monotonic_time(), t_db = t_frame;
    sl_err e = {0};
    if (start_stream(a) != SL_OK) {
        snprintf(reason, rlen, "%s", camera_errmsg(r->cam));
        return ACQ_FAILED;
    }
    while (a->stored < sp->frames) {
        if (runner_aborting(r)) {
            runner_abort_reason(r, reason, rlen);
            return ACQ_ABORTED;
        }
        int rc = camera_pop(r->cam, POP_SLICE_MS, &fr);
        gint64 now = g_get_monotonic_time();
        if (rc == CAMERA_ETIMEOUT || rc == CAMERA_ELOST) {
            if (no_frame(a, rc, now, &t_frame, reason, rlen))
                return ACQ_FAILED;
            continue;
        }
        if (rc != SL_OK && rc != SL_ERANGE) {
            snprintf(reason, rlen, "camera failed after %d of %d frames: %s", a->stored,
                     sp->frames, camera_errmsg(r->cam));
            return ACQ_FAILED;
        }
        t_frame = now;
        cubefile_row row = {fr.frame_id, fr.cam_ts_ns, fr.sys_ts_ns, (int)fr.status, -1};
        if (rc == SL_OK && fr.status == CAMERA_FRAME_SUCCESS &&
            (fr.width != a->cf.width || fr.height != a->cf.height))
            row.status = CAMERA_FRAME_SIZE_MISMATCH;   /* not this run's geometry */
        if (rc == SL_OK && row.status == CAMERA_FRAME_SUCCESS) {
            if (cube_writer_append(a->w, a->pix) != SL_OK) {
                g_array_append_val(a->rows, row);
                snprintf(reason, rlen, "writing the cube failed after %d of %d frames: %s",
                         a->stored, sp->frames, cube_writer_errmsg(a->w));
                return ACQ_FAILED;
            }
            if (a->see)
                seeing_add(a->see, a->pix);
            webtap_offer(r->tap, sp->uuid, a->pix, fr.width, fr.height);   /* never waits */
            row.cube_idx = a->stored++;
        } else if (++a->failed > max_fail) {
            g_array_append_val(a->rows, row);
            snprintf(reason, rlen, "%d damaged frames (last %s) with %d of %d good: is the "
                     "link dropping packets?", a->failed,
                     camera_frame_status_name(row.status), a->stored, sp->frames);
            return ACQ_FAILED;
        }
        g_array_append_val(a->rows, row);
        if ((now - a->t_flush >= FLUSH_US || a->stored == sp->frames) &&
            flush_progress(a, &e) != SL_OK) {
            snprintf(reason, rlen, "writing the cube failed after %d of %d frames: %s",
                     a->stored, sp->frames, e.msg);
            return ACQ_FAILED;
        }
        if (now - t_db >= CATALOG_US) {
            camera_stats cs;
            run_stats(a, &cs);
            t_db = now;
            progress_post(&a->pw, r->cat, a->stored, a->failed, (int64_t)cs.missing_packets);
            runner_note_progress(r, a->stored, a->failed, (int64_t)cs.missing_packets);
        }
    }
    return ACQ_COMPLETE;
}

/* Close, salvage, table, fsync, rename, checksum, catalogue.  Any file
 * error turns a complete acquisition into a failed one, with the reason;
 * whatever frames are on disk stay there, catalogued. */
static acq_end finish(acq *a, acq_end end, char *reason, size_t rlen)
{
    runner *r = a->r;
    const char *uuid = a->sp->uuid;
    camera_stats cs = {0};
    sl_err e = {0};
    char hex[65];
    int on_disk = 0;
    if (r->cam) {
        if (camera_is_started(r->cam))
            camera_stop(r->cam);
        run_stats(a, &cs);
    }
    progress_stop(&a->pw);     /* before the final counts below */
    a->packets_missing = (int64_t)cs.missing_packets;
    if (cube_writer_close(a->w) != SL_OK && end == ACQ_COMPLETE) {
        snprintf(reason, rlen, "closing the cube failed after %d frames: %s", a->stored,
                 cube_writer_errmsg(a->w));
        end = ACQ_FAILED;
    }
    cube_writer_free(a->w);
    a->w = NULL;
    if (cubefile_salvage(a->part, &on_disk, &e) != SL_OK) {
        g_warning("run %s: %s", uuid, e.msg);
        if (end == ACQ_COMPLETE)
            snprintf(reason, rlen, "%s", e.msg), end = ACQ_FAILED;
    } else if (on_disk < a->stored) {
        g_warning("run %s: %d of %d frames reached the disk", uuid, on_disk, a->stored);
        if (end == ACQ_COMPLETE)
            snprintf(reason, rlen, "only %d of %d frames reached the disk", on_disk, a->stored),
                end = ACQ_FAILED;
        else   /* the reason counted the frames handed to the writer */
            snprintf(reason + strlen(reason), rlen - strlen(reason), " (%d of them on disk)",
                     on_disk);
    }
    framelog_close(a->fl);
    a->fl = NULL;
    if (framelog_table(a->part, a->fl_path, (cubefile_row *)(void *)a->rows->data,
                       (long)a->rows->len, on_disk, r->cam ? &cs : NULL, &e) != SL_OK) {
        g_warning("run %s: %s", uuid, e.msg);
        if (end == ACQ_COMPLETE)
            snprintf(reason, rlen, "%s", e.msg), end = ACQ_FAILED;
    }
    const char *path = a->part;
    if (cubefile_fsync(a->part, &e) != SL_OK && end == ACQ_COMPLETE)
        snprintf(reason, rlen, "%s", e.msg), end = ACQ_FAILED;
    if (end == ACQ_COMPLETE) {
        if (rename(a->part, a->final) == 0 && cubefile_fsync_dir(a->final, &e) == SL_OK) {
            path = a->final;
        } else {
            snprintf(reason, rlen, "%s: rename to .fits: %s", a->part,
                     e.msg[0] ? e.msg : g_strerror(errno));
            end = ACQ_FAILED;
            if (access(a->final, F_OK) == 0)
                path = a->final;
        }
    }
    int sha_ok = cubefile_sha256(path, hex, &e) == SL_OK;
    if (!sha_ok)
        g_warning("run %s: %s", uuid, e.msg);
    /* Counts first: a terminal run's progress can no longer change. */
    catlock_file cf = {uuid, path, sha_ok ? hex : NULL, 1, on_disk, a->failed,
                       a->packets_missing};
    char what[80];
    snprintf(what, sizeof what, "run %s: recording its cube", uuid);
    if (catlock_write(r->cat, &r->cl, what, catlock_set_file, &cf) != SL_OK)
        g_warning("run %s: %s", uuid, catalog_errmsg(r->cat));
    a->stored = on_disk;
    runner_note_progress(r, on_disk, a->failed, a->packets_missing);
    return end;
}

/* The rows' sidecar, then the cube, then the catalogue's record of it.
 * The sidecar first: it holds the room for the FRAMES table, and a run
 * that cannot have it fails before it writes anything.  The file is
 * catalogued before its first frame, so a crash at any point leaves a run
 * that names its partial cube. */
static int open_files(acq *a, sl_err *e)
{
    runner *r = a->r;
    const runner_spec *sp = a->sp;
    cube_meta meta;
    fill_meta(a, &meta);
    int bitpix = a->cf.pixel_format == CAMERA_PIX_MONO8 ? 8 : CUBE_BITPIX_U16;
    a->fl_path = framelog_path(a->part);
    int rc = framelog_create(&a->fl, a->fl_path, (long)sp->frames + max_failed(r, sp) + 2, e);
    if (rc == SL_OK)
        rc = cube_writer_open(&a->w, a->part, a->cf.width, a->cf.height, bitpix, &meta, e);
    if (rc == SL_OK && cube_writer_flush(a->w) != SL_OK)
        rc = sl_seterr(e, SL_EIO, "%s", cube_writer_errmsg(a->w));
    catlock_file cf = {sp->uuid, a->part, NULL, 0, 0, 0, 0};
    char what[80];
    snprintf(what, sizeof what, "run %s: recording its cube", sp->uuid);
    if (rc == SL_OK && catlock_write(r->cat, &r->cl, what, catlock_set_file, &cf) != SL_OK)
        rc = sl_seterr(e, SL_EIO, "%s", catalog_errmsg(r->cat));
    return rc;
}

/* The run's r0 from image motion into the catalogue; NAN when there is
 * none (no star in a dark or a flat) or it could not be recorded. */
static double record_r0(acq *a)
{
    const runner_spec *sp = a->sp;
    seeing_result sr;
    int starlit = sp->kind != CATALOG_DARK && sp->kind != CATALOG_FLAT;
    if (!starlit || !a->see || seeing_result_get(a->see, &sr) != SL_OK ||
        !isfinite(sr.r0_m) || !(sr.r0_m > 0))
        return NAN;
    catalog_r0 m;
    catalog_r0_init(&m);
    m.run_uuid = sp->uuid;   /* screen: the run's */
    m.r0_m = sr.r0_m;
    m.wavelength_m = a->r->cfg->wavelength_m;
    m.method = "image-motion";
    m.r0_err_m = sr.r0_err_m;
    if (catalog_r0_add(a->r->cat, &m, NULL) == SL_OK)
        return sr.r0_m;
    g_warning("run %s: recording r0: %s", sp->uuid, catalog_errmsg(a->r->cat));
    return NAN;
}

acq *acquire_open(runner *r, const runner_spec *sp, double pupil_m, char *reason,
                  size_t rlen, acq_end *end)
{
    acq *a = g_new0(acq, 1);
    a->r = r, a->sp = sp;
    sl_err e = {0};
    *end = ACQ_FAILED;
    if (camlink_ready(r, sp, &a->cf, &a->info, &e) != SL_OK) {
        snprintf(reason, rlen, "%s", e.msg);
        goto free_acq;
    }
    camera_stats_get(r->cam, &a->base);
    if (runner_aborting(r)) {
        runner_abort_reason(r, reason, rlen);
        *end = ACQ_ABORTED;
        goto free_acq;
    }
    a->part = g_strdup_printf("%s/runs/%s.fits.part", r->cfg->data_dir, sp->uuid);
    a->final = g_strdup_printf("%s/runs/%s.fits", r->cfg->data_dir, sp->uuid);
    a->rows = g_array_sized_new(FALSE, FALSE, sizeof(cubefile_row), (guint)sp->frames);
    a->pix = g_new(float, (size_t)a->cf.width * (size_t)a->cf.height);
    if (seeing_new(&a->see, a->cf.width, a->cf.height, r->cfg->plate_scale_arcsec,
                   r->cfg->wavelength_m, pupil_m, &e) != SL_OK) {
        g_warning("run %s: no seeing estimate: %s", sp->uuid, e.msg);
        a->see = NULL;
    }
    if (open_files(a, &e) != SL_OK) {
        snprintf(reason, rlen, "%s", e.msg);
        cube_writer_free(a->w);
        a->w = NULL;
        if (a->fl) {   /* no frame was taken: leave no file behind */
            framelog_close(a->fl);
            a->fl = NULL;
            unlink(a->fl_path);
        }
        goto free_acq;
    }
    a->t_flush = g_get_monotonic_time();
    return a;
free_acq:
    acquire_free(a);
    return NULL;
}

acq_end acquire_stream(acq *a, char *reason, size_t rlen, double *r0_m)
{
    runner *r = a->r;
    *r0_m = NAN;
    progress_start(&a->pw, r->cfg->catalog, r->cfg->catalog_busy_timeout_ms, a->sp->uuid);
    acq_end end = finish(a, stream(a, reason, rlen), reason, rlen);
    if (end == ACQ_COMPLETE)
        *r0_m = record_r0(a);
    return end;
}

void acquire_free(acq *a)
{
    if (!a)
        return;
    framelog_close(a->fl);
    g_free(a->fl_path);
    seeing_free(a->see);
    g_free(a->pix);
    if (a->rows)
        g_array_free(a->rows, TRUE);
    g_free(a->part);
    g_free(a->final);
    g_free(a);
}
