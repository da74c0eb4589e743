/* cmd_camera.c - `specklab camera list|info|grab`: machine-vision cameras
 * through drivers/camera (GigE Vision / USB3 Vision via Aravis).
 *
 * grab streams frames to a FITS cube as they arrive (recon's cube writer,
 * unsigned 16-bit for Mono16, 8-bit for Mono8), storing only SUCCESS
 * frames, and flushes it every FLUSH_FRAMES frames so that an interrupted
 * grab leaves a valid cube.  After the cube is closed, a binary table
 * extension FRAMES is appended with one row per buffer the camera
 * delivered, good or damaged:
 *   FRAME_ID  K  camera block id
 *   CAM_TS_NS K  camera timestamp [ns]
 *   SYS_TS_NS K  host arrival time, CLOCK_REALTIME [ns]
 *   STATUS    16A SUCCESS, MISSING_PACKETS, TIMEOUT, SIZE_MISMATCH, ...
 *   CUBE_IDX  J  0-based frame index in the cube, -1 = not stored
 * Rows are kept in memory until then (40 bytes each).
 *
 * This file uses no other cli/ helper, so a test can compile it in and
 * call cmd_camera() directly.
 */
#include <fitsio.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "cli.h"
#include "outfile.h"
#include "progress.h"
#include "io/cube.h"

#define FLUSH_FRAMES 100

typedef struct grab_args {
    char *camera, *backend, *roi, *pixfmt, *out;
    int frames, timeout_ms, buffers, max_failed, binning, json, overwrite;
    double exposure_us, gain_db, frame_rate_hz;
} grab_args;

typedef struct frame_row {
    uint64_t id, cam_ts_ns, sys_ts_ns;
    int status, cube_idx;
} frame_row;

static gboolean parse(GOptionContext *ctx, int *argc, char ***argv)
{
    GError *e = NULL;
    if (!g_option_context_parse(ctx, argc, argv, &e)) {
        fprintf(stderr, "%s: %s (try --help)\n", (*argv)[0], e->message);
        g_error_free(e);
        return FALSE;
    }
    if (*argc > 1) {
        fprintf(stderr, "%s: unexpected argument '%s'\n", (*argv)[0], (*argv)[1]);
        return FALSE;
    }
    return TRUE;
}

/* ---- list --------------------------------------------------------------- */

static int run_list(int argc, char **argv)
{
    char *backend = NULL;
    int json = 0;
    GOptionEntry entries[] = {
        {"backend", 0, 0, G_OPTION_ARG_STRING, &backend, "camera backend (default aravis)", "NAME"},
        {"json", 0, 0, G_OPTION_ARG_NONE, &json, "print JSON", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("- list the cameras found (GigE discovery takes ~1 s)");
    g_option_context_add_main_entries(ctx, entries, NULL);
    int status = 2;
    if (!parse(ctx, &argc, &argv))
        goto free_ctx;
    camera_info *v = NULL;
    int n = 0;
    sl_err e = {0};
    status = 1;
    if (camera_list(backend, &v, &n, &e) != SL_OK) {
        fprintf(stderr, "%s: %s\n", argv[0], e.msg);
        goto free_ctx;
    }
    if (json) {
        JsonBuilder *b = json_builder_new();
        json_builder_begin_object(b);
        json_builder_set_member_name(b, "cameras");
        json_builder_begin_array(b);
        for (int i = 0; i < n; i++) {
            json_builder_begin_object(b);
            cli_json_str(b, "id", v[i].id);
            cli_json_str(b, "vendor", v[i].vendor);
            cli_json_str(b, "model", v[i].model);
            cli_json_str(b, "serial", v[i].serial);
            cli_json_str(b, "address", v[i].address);
            cli_json_str(b, "protocol", v[i].protocol);
            json_builder_end_object(b);
        }
        json_builder_end_array(b);
        json_builder_end_object(b);
        cli_print_json(b);
        g_object_unref(b);
    } else if (n == 0) {
        printf("no camera found (GigE cameras must answer discovery on a local "
               "interface; USB3 cameras need access to /dev/bus/usb)\n");
    } else {
        printf("%-28s %-12s %-16s %-12s %-16s %s\n", "ID", "VENDOR", "MODEL", "SERIAL",
               "ADDRESS", "PROTOCOL");
        for (int i = 0; i < n; i++)
            printf("%-28s %-12s %-16s %-12s %-16s %s\n", v[i].id, v[i].vendor, v[i].model,
                   v[i].serial, v[i].address, v[i].protocol);
    }
    free(v);
    status = 0;
free_ctx:
    g_option_context_free(ctx);
    g_free(backend);
    return status;
}

/* ---- info --------------------------------------------------------------- */

static int run_info(int argc, char **argv)
{
    char *id = NULL, *backend = NULL;
    int json = 0;
    GOptionEntry entries[] = {
        {"camera", 'c', 0, G_OPTION_ARG_STRING, &id, "camera id or IPv4 address (required)", "ID|ADDR"},
        {"backend", 0, 0, G_OPTION_ARG_STRING, &backend, "camera backend (default aravis)", "NAME"},
        {"json", 0, 0, G_OPTION_ARG_NONE, &json, "print JSON", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("- a camera's identity, capabilities and settings");
    g_option_context_add_main_entries(ctx, entries, NULL);
    int status = 2;
    camera *c = NULL;
    sl_err e = {0};
    camera_info in;
    camera_caps cp;
    camera_config cf;
    if (!parse(ctx, &argc, &argv))
        goto free_ctx;
    if (!id) {
        fprintf(stderr, "%s: --camera ID|ADDR is required\n", argv[0]);
        goto free_ctx;
    }
    status = 1;
    if (camera_open(&c, backend, id, &e) != SL_OK) {
        fprintf(stderr, "%s: %s\n", argv[0], e.msg);
        goto free_ctx;
    }
    if (camera_info_get(c, &in) != SL_OK || camera_caps_get(c, &cp) != SL_OK ||
        camera_config_get(c, &cf) != SL_OK) {
        fprintf(stderr, "%s: %s\n", argv[0], camera_errmsg(c));
        goto close_camera;
    }
    if (json) {
        JsonBuilder *b = json_builder_new();
        json_builder_begin_object(b);
        cli_json_str(b, "id", in.id), cli_json_str(b, "vendor", in.vendor), cli_json_str(b, "model", in.model);
        cli_json_str(b, "serial", in.serial), cli_json_str(b, "address", in.address);
        cli_json_str(b, "protocol", in.protocol);
        cli_json_int(b, "sensor_width", cp.sensor_width), cli_json_int(b, "sensor_height", cp.sensor_height);
        cli_json_int(b, "mono8", !!(cp.pixel_formats & CAMERA_PIXF(CAMERA_PIX_MONO8)));
        cli_json_int(b, "mono16", !!(cp.pixel_formats & CAMERA_PIXF(CAMERA_PIX_MONO16)));
        cli_json_num(b, "exposure_min_us", cp.exposure_min_us), cli_json_num(b, "exposure_max_us", cp.exposure_max_us);
        cli_json_num(b, "gain_min_db", cp.gain_min_db), cli_json_num(b, "gain_max_db", cp.gain_max_db);
        cli_json_num(b, "frame_rate_min_hz", cp.frame_rate_min_hz);
        cli_json_num(b, "frame_rate_max_hz", cp.frame_rate_max_hz);
        cli_json_int(b, "roi_x", cf.x), cli_json_int(b, "roi_y", cf.y);
        cli_json_int(b, "roi_width", cf.width), cli_json_int(b, "roi_height", cf.height);
        cli_json_str(b, "pixel_format", camera_pixfmt_name(cf.pixel_format));
        cli_json_num(b, "exposure_us", cf.exposure_us), cli_json_num(b, "gain_db", cf.gain_db);
        cli_json_num(b, "frame_rate_hz", cf.frame_rate_hz);
        cli_json_str(b, "trigger", camera_trigger_name(cf.trigger));
        json_builder_end_object(b);
        cli_print_json(b);
        g_object_unref(b);
    } else {
        printf("%s %s, serial %s, %s at %s (id %s)\n", in.vendor, in.model, in.serial,
               in.protocol, in.address, in.id);
        printf("sensor %dx%d, formats%s%s, exposure %g..%g us, gain %g..%g dB, "
               "frame rate %g..%g Hz, binning up to %d, software trigger %s\n",
               cp.sensor_width, cp.sensor_height,
               cp.pixel_formats & CAMERA_PIXF(CAMERA_PIX_MONO8) ? " Mono8" : "",
               cp.pixel_formats & CAMERA_PIXF(CAMERA_PIX_MONO16) ? " Mono16" : "",
               cp.exposure_min_us, cp.exposure_max_us, cp.gain_min_db, cp.gain_max_db,
               cp.frame_rate_min_hz, cp.frame_rate_max_hz, cp.binning_max,
               cp.software_trigger ? "yes" : "no");
        printf("now: ROI %d,%d,%dx%d, binning %dx%d, %s, exposure %g us, gain %g dB, "
               "%g Hz, trigger %s\n", cf.x, cf.y, cf.width, cf.height, cf.bin_x, cf.bin_y,
               camera_pixfmt_name(cf.pixel_format), cf.exposure_us, cf.gain_db,
               cf.frame_rate_hz, camera_trigger_name(cf.trigger));
    }
    status = 0;
close_camera:
    camera_close(c);
free_ctx:
    g_option_context_free(ctx);
    g_free(id);
    g_free(backend);
    return status;
}

/* ---- grab --------------------------------------------------------------- */

static int configure(camera *c, const grab_args *a, camera_config *cf, const char *prog)
{
    int x, y, w, h, rc = SL_OK;
    char tail;
    if (a->roi && sscanf(a->roi, "%d,%d,%d,%d%c", &x, &y, &w, &h, &tail) != 4) {
        fprintf(stderr, "%s: --roi '%s': expected X,Y,W,H\n", prog, a->roi);
        return 2;
    }
    camera_pixfmt f = CAMERA_PIX_UNKNOWN;
    if (a->pixfmt && (f = camera_pixfmt_parse(a->pixfmt)) != CAMERA_PIX_MONO8 &&
        f != CAMERA_PIX_MONO16) {
        fprintf(stderr, "%s: --pixel-format '%s': expected Mono8 or Mono16\n", prog, a->pixfmt);
        return 2;
    }
    if (f)
        rc = camera_set_pixel_format(c, f);
    if (rc == SL_OK && a->binning > 0)
        rc = camera_set_binning(c, a->binning, a->binning);
    if (rc == SL_OK && a->roi)
        rc = camera_set_roi(c, x, y, w, h);
    if (rc == SL_OK && a->exposure_us > 0)
        rc = camera_set_exposure_us(c, a->exposure_us);
    if (rc == SL_OK && !isnan(a->gain_db))
        rc = camera_set_gain_db(c, a->gain_db);
    if (rc == SL_OK && a->frame_rate_hz > 0)
        rc = camera_set_frame_rate_hz(c, a->frame_rate_hz);
    if (rc == SL_OK)
        rc = camera_config_get(c, cf);
    /* A camera left in a colour format by its last user: take Mono8. */
    if (rc == SL_OK && camera_pixfmt_bytes(cf->pixel_format) == 0 &&
        (rc = camera_set_pixel_format(c, CAMERA_PIX_MONO8)) == SL_OK)
        rc = camera_config_get(c, cf);
    if (rc != SL_OK) {
        fprintf(stderr, "%s: %s\n", prog, camera_errmsg(c));
        return 1;
    }
    return 0;
}

static void fill_meta(cube_meta *md, const camera_info *in, const camera_config *cf)
{
    cube_meta_init(md);
    snprintf(md->instrume, sizeof md->instrume, "%.30s %.30s", in->vendor, in->model);
    snprintf(md->bunit, sizeof md->bunit, "adu");
    md->exptime_s = cf->exposure_us * 1e-6;
    cube_meta_set_str(md, "CAMID", in->id, "camera device id");
    cube_meta_set_str(md, "CAMSER", in->serial, "camera serial number");
    cube_meta_set_str(md, "CAMADDR", in->address, "camera address");
    cube_meta_set_str(md, "CAMPROTO", in->protocol, "camera protocol");
    cube_meta_set_str(md, "PIXFMT", camera_pixfmt_name(cf->pixel_format), "pixel format");
    cube_meta_set_num(md, "ROIX", cf->x, "[px] ROI offset x on the sensor");
    cube_meta_set_num(md, "ROIY", cf->y, "[px] ROI offset y on the sensor");
    cube_meta_set_num(md, "BINX", cf->bin_x, "binning x");
    cube_meta_set_num(md, "BINY", cf->bin_y, "binning y");
    if (isfinite(cf->gain_db))
        cube_meta_set_num(md, "GAINDB", cf->gain_db, "[dB] camera gain");
    if (isfinite(cf->frame_rate_hz))
        cube_meta_set_num(md, "FRATE", cf->frame_rate_hz, "[Hz] frame rate setting");
}

/* Append the FRAMES table to the closed cube (cfitsio directly: the cube
 * writer has no table API). */
static int write_table(const char *path, const frame_row *rows, long n,
                       const camera_stats *st, char *msg, size_t msglen)
{
    char *ttype[] = {"FRAME_ID", "CAM_TS_NS", "SYS_TS_NS", "STATUS", "CUBE_IDX"};
    char *tform[] = {"1K", "1K", "1K", "16A", "1J"};
    char *tunit[] = {"", "ns", "ns", "", ""};
    fitsfile *f = NULL;
    int s = 0;
    LONGLONG *col = malloc(sizeof *col * (size_t)(n > 0 ? n : 1));
    char **names = malloc(sizeof *names * (size_t)(n > 0 ? n : 1));
    int *idx = malloc(sizeof *idx * (size_t)(n > 0 ? n : 1));
    if (!col || !names || !idx) {
        snprintf(msg, msglen, "%s: out of memory for the FRAMES table", path);
        s = MEMORY_ALLOCATION;
        goto free_cols;
    }
    fits_open_diskfile(&f, path, READWRITE, &s);
    fits_create_tbl(f, BINARY_TBL, 0, 5, ttype, tform, tunit, "FRAMES", &s);
    for (int c = 0; c < 3 && !s && n > 0; c++) {
        for (long i = 0; i < n; i++)
            col[i] = (LONGLONG)(c == 0 ? rows[i].id : c == 1 ? rows[i].cam_ts_ns
                                                              : rows[i].sys_ts_ns);
        fits_write_col(f, TLONGLONG, c + 1, 1, 1, n, col, &s);
    }
    for (long i = 0; i < n; i++) {
        names[i] = (char *)camera_frame_status_name(rows[i].status);
        idx[i] = rows[i].cube_idx;
    }
    if (n > 0) {
        fits_write_col(f, TSTRING, 4, 1, 1, n, names, &s);
        fits_write_col(f, TINT, 5, 1, 1, n, idx, &s);
    }
    fits_update_key_lng(f, "NSTORED", (LONGLONG)st->completed, "SUCCESS frames in the cube", &s);
    fits_update_key_lng(f, "NFAILED", (LONGLONG)st->failed, "damaged buffers, not stored", &s);
    fits_update_key_lng(f, "NMISSPKT", (LONGLONG)st->missing_packets, "GigE packets missing", &s);
    fits_update_key_lng(f, "NUNDERRN", (LONGLONG)st->underruns, "frames dropped: no buffer", &s);
    fits_update_key_lng(f, "NIDGAPS", (LONGLONG)st->id_gaps, "frame ids never delivered", &s);
    fits_write_chksum(f, &s);   /* last: after every row and keyword */
    if (f) {
        int s2 = 0;
        fits_close_file(f, s ? &s2 : &s);
    }
    if (s) {
        char text[FLEN_STATUS];
        fits_get_errstatus(s, text);
        snprintf(msg, msglen, "%s: writing the FRAMES table: %s", path, text);
    }
free_cols:
    free(col);
    free(names);
    free(idx);
    return s ? SL_EIO : SL_OK;
}

/* What a grab took: the rows of every buffer delivered, the frames
 * stored and damaged, the camera clock of the first and last stored. */
typedef struct grab_state {
    GArray *rows;
    int stored, failed;
    uint64_t t_first, t_last;
} grab_state;

/* Pop frames into the cube until a->frames are stored; 0, or 1 after a
 * message (the frames stored so far stay in the cube). */
static int grab_frames(const grab_args *a, const char *prog, camera *c,
                       const camera_config *cf, cube_writer *w, float *pix,
                       size_t npx, grab_state *g)
{
    camera_frame fr = {.f32 = pix, .capacity_px = npx};
    /* notes go to stderr plainly when it is not a terminal (--json) */
    progress *pg = progress_new(stderr, a->frames);
    int status = 1;
    while (g->stored < a->frames) {
        progress_update(pg, g->stored, "frames");
        int rc = camera_pop(c, a->timeout_ms, &fr);
        if (rc != SL_OK && rc != SL_ERANGE) {
            progress_note(pg, "%s: %s (after %d frames)", prog, camera_errmsg(c), g->stored);
            goto done;
        }
        frame_row r = {fr.frame_id, fr.cam_ts_ns, fr.sys_ts_ns, (int)fr.status, -1};
        /* A good frame of another size (ROI changed behind our back) is
         * not stored either. */
        if (fr.status == CAMERA_FRAME_SUCCESS && (fr.width != cf->width || fr.height != cf->height))
            r.status = CAMERA_FRAME_SIZE_MISMATCH;
        if (r.status == CAMERA_FRAME_SUCCESS) {
            if (cube_writer_append(w, pix) != SL_OK) {
                progress_note(pg, "%s: %s", prog, cube_writer_errmsg(w));
                goto done;
            }
            r.cube_idx = g->stored++;
            g->t_first = g->stored == 1 ? fr.cam_ts_ns : g->t_first;
            g->t_last = fr.cam_ts_ns;
            if (g->stored % FLUSH_FRAMES == 0)
                cube_writer_flush(w);
        } else if (++g->failed > a->max_failed) {
            g_array_append_val(g->rows, r);
            progress_note(pg, "%s: camera %s: %d damaged frames (last %s), more than "
                          "--max-failed %d: is the link dropping packets?", prog, a->camera,
                          g->failed, camera_frame_status_name(r.status), a->max_failed);
            goto done;
        }
        g_array_append_val(g->rows, r);
    }
    status = 0;
done:
    progress_free(pg);
    return status;
}

static void grab_report(const grab_args *a, const camera_config *cf, const grab_state *g,
                        const camera_stats *st, int status, double el)
{
    double fps = g->stored > 1 && g->t_last > g->t_first
                     ? (g->stored - 1) / ((g->t_last - g->t_first) * 1e-9) : NAN;
    if (a->json) {
        JsonBuilder *b = json_builder_new();
        json_builder_begin_object(b);
        cli_json_str(b, "output", a->out), cli_json_str(b, "camera", a->camera);
        cli_json_int(b, "stored", g->stored), cli_json_int(b, "failed", (gint64)st->failed);
        cli_json_int(b, "missing_packets", (gint64)st->missing_packets);
        cli_json_int(b, "underruns", (gint64)st->underruns), cli_json_int(b, "id_gaps", (gint64)st->id_gaps);
        cli_json_int(b, "width", cf->width), cli_json_int(b, "height", cf->height);
        cli_json_str(b, "pixel_format", camera_pixfmt_name(cf->pixel_format));
        cli_json_num(b, "fps", fps), cli_json_num(b, "elapsed_s", el);
        cli_json_int(b, "ok", status == 0);
        json_builder_end_object(b);
        cli_print_json(b);
        g_object_unref(b);
        return;
    }
    printf("%s %s: %d frames %dx%d %s stored, %llu failed, %llu missing packets, "
           "%llu underruns, %llu frame ids lost; %.1f fps (camera clock), %.2f s\n",
           status == 0 ? "wrote" : "partial", a->out, g->stored, cf->width, cf->height,
           camera_pixfmt_name(cf->pixel_format), (unsigned long long)st->failed,
           (unsigned long long)st->missing_packets, (unsigned long long)st->underruns,
           (unsigned long long)st->id_gaps, fps, el);
}

static int grab(const grab_args *a, const char *prog)
{
    sl_err e = {0};
    camera *c = NULL;
    cube_writer *w = NULL;
    camera_info in;
    camera_config cf;
    camera_stats st = {0};
    grab_state g = {g_array_new(FALSE, FALSE, sizeof(frame_row)), 0, 0, 0, 0};
    float *pix = NULL;
    int status = 1;
    gint64 t0 = g_get_monotonic_time();
    if (camera_open(&c, a->backend, a->camera, &e) != SL_OK) {
        fprintf(stderr, "%s: %s\n", prog, e.msg);
        goto free_rows;
    }
    if ((status = configure(c, a, &cf, prog)) != 0)
        goto close_camera;
    status = 1;
    if (camera_info_get(c, &in) != SL_OK) {
        fprintf(stderr, "%s: %s\n", prog, camera_errmsg(c));
        goto close_camera;
    }
    cube_meta md;
    fill_meta(&md, &in, &cf);
    cube_meta_add_history(&md, "specklab camera grab: %d frames asked of camera %s (%s)",
                          a->frames, a->camera, a->backend ? a->backend : "aravis");
    int bitpix = cf.pixel_format == CAMERA_PIX_MONO8 ? 8 : CUBE_BITPIX_U16;
    size_t npx = (size_t)cf.width * (size_t)cf.height;
    if (!(pix = malloc(npx * sizeof *pix))) {
        fprintf(stderr, "%s: out of memory\n", prog);
        goto close_camera;
    }
    if (cube_writer_open(&w, a->out, cf.width, cf.height, bitpix, &md, &e) != SL_OK) {
        fprintf(stderr, "%s: %s\n", prog, e.msg);
        goto close_camera;
    }
    if (camera_start(c, a->buffers) != SL_OK) {
        fprintf(stderr, "%s: %s\n", prog, camera_errmsg(c));
        goto close_cube;
    }
    status = grab_frames(a, prog, c, &cf, w, pix, npx, &g);
    camera_stop(c);
    camera_stats_get(c, &st);
close_cube:
    if (cube_writer_close(w) != SL_OK) {
        fprintf(stderr, "%s: %s\n", prog, cube_writer_errmsg(w));
        status = 1;
    } else {
        char msg[512];
        if (write_table(a->out, (const frame_row *)(void *)g.rows->data, (long)g.rows->len,
                        &st, msg, sizeof msg) != SL_OK) {
            fprintf(stderr, "%s: %s\n", prog, msg);
            status = 1;
        }
    }
    cube_writer_free(w);
    grab_report(a, &cf, &g, &st, status, (g_get_monotonic_time() - t0) * 1e-6);
close_camera:
    free(pix);
    camera_close(c);
free_rows:
    g_array_free(g.rows, TRUE);
    return status;
}

static int run_grab(int argc, char **argv)
{
    grab_args a = {0};
    a.frames = 100, a.timeout_ms = 2000, a.buffers = 32, a.max_failed = -1;
    a.gain_db = NAN;
    GOptionEntry entries[] = {
        {"camera", 'c', 0, G_OPTION_ARG_STRING, &a.camera, "camera id or IPv4 address (required)", "ID|ADDR"},
        {"frames", 'n', 0, G_OPTION_ARG_INT, &a.frames, "good frames to store (default 100)", "N"},
        {"roi", 0, 0, G_OPTION_ARG_STRING, &a.roi, "region of interest on the sensor", "X,Y,W,H"},
        {"binning", 0, 0, G_OPTION_ARG_INT, &a.binning, "binning N x N", "N"},
        {"pixel-format", 0, 0, G_OPTION_ARG_STRING, &a.pixfmt, "Mono8 or Mono16 (default: the camera's)", "FMT"},
        {"exposure-us", 0, 0, G_OPTION_ARG_DOUBLE, &a.exposure_us, "exposure time", "US"},
        {"gain-db", 0, 0, G_OPTION_ARG_DOUBLE, &a.gain_db, "camera gain", "DB"},
        {"frame-rate-hz", 0, 0, G_OPTION_ARG_DOUBLE, &a.frame_rate_hz, "frame rate", "HZ"},
        {"timeout-ms", 0, 0, G_OPTION_ARG_INT, &a.timeout_ms, "give up when no frame comes for this long (default 2000)", "MS"},
        {"buffers", 0, 0, G_OPTION_ARG_INT, &a.buffers, "stream buffer pool (default 32)", "N"},
        {"max-failed", 0, 0, G_OPTION_ARG_INT, &a.max_failed, "give up after more damaged frames (default: --frames)", "N"},
        {"backend", 0, 0, G_OPTION_ARG_STRING, &a.backend, "camera backend (default aravis)", "NAME"},
        {"output", 'o', 0, G_OPTION_ARG_FILENAME, &a.out, "output FITS cube (required)", "FILE"},
        {"overwrite", 0, 0, G_OPTION_ARG_NONE, &a.overwrite, "replace an existing output cube", NULL},
        {"json", 0, 0, G_OPTION_ARG_NONE, &a.json, "print a JSON summary", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("- grab frames into a FITS cube");
    g_option_context_add_main_entries(ctx, entries, NULL);
    g_option_context_set_description(ctx,
        "Only SUCCESS frames enter the cube; the FRAMES table extension lists every\n"
        "buffer delivered (FRAME_ID, CAM_TS_NS, SYS_TS_NS, STATUS, CUBE_IDX).");
    int status = 2;
    if (!parse(ctx, &argc, &argv))
        goto free_ctx;
    if (!a.camera || !a.out) {
        fprintf(stderr, "%s: --camera ID|ADDR and -o FILE are required\n", argv[0]);
        goto free_ctx;
    }
    if (a.frames < 1 || a.timeout_ms < 1) {
        fprintf(stderr, "%s: --frames and --timeout-ms must be >= 1\n", argv[0]);
        goto free_ctx;
    }
    if (a.max_failed < 0)
        a.max_failed = a.frames;
    /* written in place, not through a temporary: frames reach the disk as
     * they come, so an interrupted grab keeps them (outfile.h) */
    GError *ge = NULL;
    if (!outfile_check(a.out, a.overwrite, NULL, 0, &ge)) {
        fprintf(stderr, "%s: %s\n", argv[0], ge->message);
        g_error_free(ge);
        goto free_ctx;
    }
    status = grab(&a, argv[0]);
free_ctx:
    g_option_context_free(ctx);
    g_free(a.camera); g_free(a.roi); g_free(a.pixfmt); g_free(a.backend); g_free(a.out);
    return status;
}

int cmd_camera(int argc, char **argv)
{
    static const char usage[] =
        "usage: specklab camera list [--json]\n"
        "       specklab camera info --camera ID|ADDR [--json]\n"
        "       specklab camera grab --camera ID|ADDR --frames N [--roi X,Y,W,H]\n"
        "                            [--exposure-us US] [--pixel-format Mono16] -o CUBE.fits\n"
        "(specklab camera SUBCOMMAND --help for every option)\n";
    if (argc < 2) {
        fputs(usage, stderr);
        return 2;
    }
    const char *sub = argv[1];
    if (!strcmp(sub, "--help") || !strcmp(sub, "-h") || !strcmp(sub, "help")) {
        fputs(usage, stdout);
        return 0;
    }
    char name[64];
    snprintf(name, sizeof name, "%s %s", argv[0] ? argv[0] : "specklab camera", sub);
    argv[1] = name;
    if (!strcmp(sub, "list"))
        return run_list(argc - 1, argv + 1);
    if (!strcmp(sub, "info"))
        return run_info(argc - 1, argv + 1);
    if (!strcmp(sub, "grab"))
        return run_grab(argc - 1, argv + 1);
    fprintf(stderr, "%s: unknown subcommand '%s'\n%s", argv[0], sub, usage);
    return 2;
}
