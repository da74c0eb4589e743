/* cmd_experiment.c - `specklab experiment binary-bench`: one daemon run per
 * (screen, mask) configuration, followed to the end through the daemon's
 * events, then one table row (or JSON element) per run.
 *
 * The client subscribes BEFORE starting any run, so no state change can
 * slip between a start-run reply and the subscription.  Events are the
 * fast path; every POLL_S the unfinished runs are also asked for with
 * `run`, so a lost event costs seconds, not a hang.  The whole wait is
 * bounded by a timeout derived from the frame count (--timeout-s).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "catalog.h"
#include "cli.h"
#include "cmd_daemon.h"
#include "pipeline/pipeline.h"
#include "progress.h"

#define EVENT_WAIT_MS 500
#define POLL_S 5.0
/* Progress units: acquisition counts 1 per frame, reconstruction RECON_W
 * per frame (TSM of a 128x128 cube takes roughly a quarter of the frames'
 * acquisition time on the bench; only the ETA depends on it). */
#define RECON_W 0.25

typedef struct bench_run {
    char *screen, *mask;  /* as given on the command line */
    char *uuid;           /* NULL when start-run was refused */
    char *state;          /* latest known state */
    char *reason;         /* exit reason, or why start-run failed */
    gint64 acquired;
    int finished;         /* terminal, final record fetched */
    JsonObject *run;      /* final run record */
    JsonObject *recon;    /* the reconstruction reported, else the latest */
    double t0_s, t1_s;    /* client clock: started, finished */
} bench_run;

typedef struct bench_opts {
    char *screens, *masks, *object, *method, *kind;
    int frames, exposure_us, timeout_s;
} bench_opts;

static int is_terminal(const char *s)
{
    return s && (!strcmp(s, "done") || !strcmp(s, "failed") ||
                 !strcmp(s, "aborted") || !strcmp(s, "interrupted"));
}

static void set_str(char **dst, const char *s)
{
    if (s && *dst && !strcmp(*dst, s))
        return;
    g_free(*dst);
    *dst = g_strdup(s);
}

static void set_obj(JsonObject **dst, JsonObject *o)
{
    if (o)
        json_object_ref(o);
    if (*dst)
        json_object_unref(*dst);
    *dst = o;
}

/* The name or slot exists in the daemon's list (screens or masks). */
static int known(JsonArray *a, const char *want)
{
    for (guint i = 0; a && i < json_array_get_length(a); i++) {
        JsonObject *o = json_array_get_object_element(a, i);
        const char *n = dcmd_str(o, "name");
        char slot[32];
        snprintf(slot, sizeof slot, "%lld", (long long)dcmd_int(o, "slot", -1));
        if ((n && !strcmp(n, want)) || !strcmp(slot, want))
            return 1;
    }
    return 0;
}

/* Refuse unknown screens/masks before starting anything, so a typo in the
 * last name does not leave the first runs orphaned.  When the daemon cannot
 * list them, start-run's own check decides. */
static int check_names(client *c, const char *what, char **names)
{
    JsonObject *res = NULL;
    if (client_call(c, what, NULL, DCMD_QUERY_MS, &res) != SL_OK)
        return 0;
    JsonArray *a = dcmd_arr(res, what);
    int bad = 0;
    for (char **n = names; *n; n++) {
        if (a && !known(a, *n)) {
            GString *k = g_string_new("");
            for (guint i = 0; i < json_array_get_length(a); i++)
                g_string_append_printf(k, "%s%s", i ? ", " : "",
                    dcmd_str(json_array_get_object_element(a, i), "name"));
            fprintf(stderr, "specklab experiment: no %.*s '%s' (known: %s)\n",
                    (int)strlen(what) - 1, what, *n, k->str);
            g_string_free(k, TRUE);
            bad = 1;
        }
    }
    json_object_unref(res);
    return bad;
}

static void start_runs(client *c, const bench_opts *o, bench_run *runs, int n,
                       progress *pg)
{
    for (int i = 0; i < n; i++) {
        bench_run *r = &runs[i];
        JsonObject *args = json_object_new(), *res = NULL;
        dcmd_set_name_or_slot(args, "screen", r->screen);
        dcmd_set_name_or_slot(args, "mask", r->mask);
        json_object_set_int_member(args, "frames", o->frames);
        if (o->exposure_us > 0)
            json_object_set_int_member(args, "exposure_us", o->exposure_us);
        if (o->object)
            json_object_set_string_member(args, "object", o->object);
        json_object_set_string_member(args, "operator", g_get_user_name());
        if (o->method)
            json_object_set_string_member(args, "reconstruct", o->method);
        if (o->kind)
            json_object_set_string_member(args, "kind", o->kind);
        r->t0_s = cli_now_s();
        if (client_call(c, "start-run", args, DCMD_QUERY_MS, &res) != SL_OK) {
            set_str(&r->state, "not started");
            set_str(&r->reason, client_errmsg(c));
            r->finished = 1;
            progress_note(pg, "screen %s, mask %s: not started: %s", r->screen,
                          r->mask, client_errmsg(c));
        } else {
            set_str(&r->uuid, dcmd_str(res, "run"));
            set_str(&r->state, dcmd_str(res, "state") ? dcmd_str(res, "state") : "queued");
            gint64 pos = dcmd_int(res, "queue_position", 0);
            progress_note(pg, "run %.8s: screen %s, mask %s, %d frames%s", r->uuid
                          ? r->uuid : "?", r->screen, r->mask, o->frames,
                          pos > 0 ? " (queued behind the run in progress)" : "");
            if (!r->uuid) { /* a reply without a run id: cannot follow it */
                set_str(&r->reason, "start-run reply has no run id");
                r->finished = 1;
            }
            json_object_unref(res);
        }
        json_object_unref(args);
    }
}

static bench_run *find_run(bench_run *runs, int n, const char *uuid)
{
    for (int i = 0; uuid && i < n; i++)
        if (runs[i].uuid && !strcmp(runs[i].uuid, uuid))
            return &runs[i];
    return NULL;
}

/* Fetch the final record once the run is terminal.  The reconstruction
 * event may be lost or arrive after the state: the record's list decides
 * then, highest id (the newest) first. */
static void finish_run(client *c, bench_run *r, progress *pg)
{
    JsonObject *args = json_object_new(), *res = NULL;
    json_object_set_string_member(args, "run", r->uuid);
    if (client_call(c, "run", args, DCMD_QUERY_MS, &res) == SL_OK) {
        JsonObject *run = dcmd_obj(res, "run");
        set_obj(&r->run, run);
        if (dcmd_str(run, "state"))
            set_str(&r->state, dcmd_str(run, "state"));
        if (dcmd_str(run, "exit_reason"))
            set_str(&r->reason, dcmd_str(run, "exit_reason"));
        JsonArray *recs = dcmd_arr(res, "reconstructions");
        JsonObject *best = NULL;
        for (guint i = 0; recs && i < json_array_get_length(recs); i++) {
            JsonObject *x = json_array_get_object_element(recs, i);
            if (!best || dcmd_int(x, "id", 0) > dcmd_int(best, "id", 0))
                best = x;
        }
        if (!r->recon && best)
            set_obj(&r->recon, best);
        json_object_unref(res);
    } else if (!r->reason) {
        set_str(&r->reason, client_errmsg(c));
    }
    json_object_unref(args);
    r->finished = 1;
    r->t1_s = cli_now_s();
    if (strcmp(r->state, "done") != 0)
        progress_note(pg, "run %.8s (screen %s, mask %s) %s: %s", r->uuid, r->screen,
                      r->mask, r->state, r->reason ? r->reason : "no reason given");
}

static void on_event(bench_run *runs, int n, JsonObject *ev)
{
    bench_run *r = find_run(runs, n, dcmd_str(ev, "run"));
    const char *kind = dcmd_str(ev, "event");
    if (!r || r->finished || !kind)
        return; /* another client's run, or already settled */
    if (!strcmp(kind, "state")) {
        if (dcmd_str(ev, "state"))
            set_str(&r->state, dcmd_str(ev, "state"));
        if (dcmd_str(ev, "reason"))
            set_str(&r->reason, dcmd_str(ev, "reason"));
    } else if (!strcmp(kind, "progress")) {
        r->acquired = dcmd_int(ev, "frames_acquired", r->acquired);
    } else if (!strcmp(kind, "reconstruction")) {
        set_obj(&r->recon, dcmd_obj(ev, "reconstruction"));
    }
}

/* Refresh unfinished runs by asking (events may be lost). */
static void poll_runs(client *c, bench_run *runs, int n)
{
    for (int i = 0; i < n; i++) {
        bench_run *r = &runs[i];
        if (r->finished)
            continue;
        JsonObject *args = json_object_new(), *res = NULL;
        json_object_set_string_member(args, "run", r->uuid);
        if (client_call(c, "run", args, DCMD_QUERY_MS, &res) == SL_OK) {
            JsonObject *run = dcmd_obj(res, "run");
            if (dcmd_str(run, "state"))
                set_str(&r->state, dcmd_str(run, "state"));
            r->acquired = dcmd_int(run, "frames_acquired", r->acquired);
            json_object_unref(res);
        }
        json_object_unref(args);
    }
}

static void show_progress(progress *pg, const bench_run *runs, int n, int frames)
{
    double done = 0;
    const bench_run *cur = NULL;
    int k = 0;
    for (int i = 0; i < n; i++) {
        const bench_run *r = &runs[i];
        done += r->finished ? frames * (1 + RECON_W) : (double)r->acquired;
        if (!cur && !r->finished && r->state && strcmp(r->state, "queued") != 0)
            cur = r, k = i + 1;
    }
    char label[160] = "waiting";
    if (cur)
        snprintf(label, sizeof label, "run %d/%d screen %s %s: %s %lld/%d", k, n,
                 cur->screen, cur->mask, cur->state, (long long)cur->acquired, frames);
    progress_update(pg, done, label);
}

/* Follow the runs until each is finished, the deadline passes or the
 * connection fails; 0 when every run finished. */
static int wait_runs(client *c, bench_run *runs, int n, int frames, double timeout_s,
                     progress *pg)
{
    double t0 = cli_now_s(), last_poll = t0;
    for (;;) {
        int left = 0;
        for (int i = 0; i < n; i++) {
            if (!runs[i].finished && is_terminal(runs[i].state))
                finish_run(c, &runs[i], pg);
            left += !runs[i].finished;
        }
        show_progress(pg, runs, n, frames);
        if (!left)
            return 0;
        if (cli_now_s() - t0 > timeout_s) {
            progress_note(pg, "specklab experiment: %d run(s) not finished after %.0f s "
                          "(--timeout-s); they go on in the daemon: specklab runs list",
                          left, timeout_s);
            return 1;
        }
        JsonObject *ev = NULL;
        if (client_next_event(c, EVENT_WAIT_MS, &ev) != SL_OK) {
            progress_note(pg, "specklab experiment: %s; the runs go on in the daemon: "
                          "specklab runs list", client_errmsg(c));
            return 1;
        }
        if (ev) {
            on_event(runs, n, ev);
            json_object_unref(ev);
        }
        if (cli_now_s() - last_poll > POLL_S) {
            poll_runs(c, runs, n);
            last_poll = cli_now_s();
        }
    }
}

/* Wall time of the run in the daemon (started..ended), else as seen here. */
static double run_time_s(const bench_run *r)
{
    double t = dcmd_iso_s(dcmd_str(r->run, "ended")) - dcmd_iso_s(dcmd_str(r->run, "started"));
    if (isfinite(t) && t >= 0)
        return t;
    return r->t1_s > r->t0_s ? r->t1_s - r->t0_s : NAN;
}

static void num_member(JsonObject *o, const char *k, double v)
{
    if (isfinite(v))
        json_object_set_double_member(o, k, v);
    else
        json_object_set_null_member(o, k);
}

static void str_member(JsonObject *o, const char *k, const char *v)
{
    if (v)
        json_object_set_string_member(o, k, v);
    else
        json_object_set_null_member(o, k);
}

static void print_json(const bench_run *runs, int n, int frames)
{
    JsonArray *a = json_array_new();
    for (int i = 0; i < n; i++) {
        const bench_run *r = &runs[i];
        JsonObject *o = json_object_new();
        str_member(o, "run", r->uuid);
        str_member(o, "screen", dcmd_str(r->run, "screen") ? dcmd_str(r->run, "screen") : r->screen);
        str_member(o, "mask", dcmd_str(r->run, "mask") ? dcmd_str(r->run, "mask") : r->mask);
        str_member(o, "state", r->state);
        str_member(o, "exit_reason", r->reason);
        json_object_set_int_member(o, "frames_requested", frames);
        json_object_set_int_member(o, "frames_acquired",
                                   dcmd_int(r->run, "frames_acquired", r->acquired));
        num_member(o, "r0_m", dcmd_num(r->run, "r0_m"));
        num_member(o, "r0_err_m", dcmd_num(r->run, "r0_err_m"));
        num_member(o, "r0_wavelength_m", dcmd_num(r->run, "r0_wavelength_m"));
        num_member(o, "seeing_arcsec", dcmd_num(r->run, "seeing_arcsec"));
        static const char *keys[] = {"sep_arcsec", "sep_px", "sep_err_px", "pa_deg",
                                     "pa_err_deg", "dm_mag", "dm_err_mag", "c_cophased"};
        for (size_t k = 0; k < sizeof keys / sizeof keys[0]; k++)
            num_member(o, keys[k], dcmd_num(r->recon, keys[k]));
        num_member(o, "closure_rms_deg", dcmd_num(dcmd_obj(r->recon, "quality"),
                                                  "closure_rms_deg"));
        num_member(o, "time_s", run_time_s(r));
        str_member(o, "method", dcmd_str(r->recon, "method"));
        num_member(o, "recon_elapsed_s", dcmd_num(r->recon, "elapsed_s"));
        str_member(o, "file", dcmd_str(r->run, "file"));
        str_member(o, "recon_fits", dcmd_str(r->recon, "fits"));
        str_member(o, "png", dcmd_str(r->recon, "png"));
        json_array_add_object_element(a, o);
    }
    /* one object, like every other command's --json */
    JsonObject *top = json_object_new();
    json_object_set_array_member(top, "runs", a);
    int nfailed = 0;
    for (int i = 0; i < n; i++)
        nfailed += !runs[i].state || strcmp(runs[i].state, "done") != 0;
    json_object_set_int_member(top, "runs_not_done", nfailed);
    dcmd_print_object(top);
    json_object_unref(top);
    json_array_unref(a);
}

static void print_table(const bench_run *runs, int n)
{
    /* cp(deg): the closure phases' rms residual after the binary fit, the
     * quality a real run has without truth (PROTOCOL.md, quality) */
    printf("%-8s  %-10s %-8s %7s %9s %8s %8s %8s %7s %8s  %s\n", "RUN", "SCREEN", "MASK",
           "r0(m)", "sep(\")", "sep(px)", "PA(deg)", "dm(mag)", "cp(deg)", "time(s)", "STATE");
    for (int i = 0; i < n; i++) {
        const bench_run *r = &runs[i];
        char r0[32], sa[32], sp[32], pa[32], dm[32], c[32], t[32];
        const char *screen = dcmd_str(r->run, "screen");
        const char *mask = dcmd_str(r->run, "mask");
        printf("%-8.8s  %-10s %-8s %7s %9s %8s %8s %8s %7s %8s  %s\n",
               r->uuid ? r->uuid : "-", screen ? screen : r->screen, mask ? mask : r->mask,
               dcmd_fmt(r0, sizeof r0, "%.3f", dcmd_num(r->run, "r0_m")),
               dcmd_fmt(sa, sizeof sa, "%.4f", dcmd_num(r->recon, "sep_arcsec")),
               dcmd_fmt(sp, sizeof sp, "%.3f", dcmd_num(r->recon, "sep_px")),
               dcmd_fmt(pa, sizeof pa, "%.2f", dcmd_num(r->recon, "pa_deg")),
               dcmd_fmt(dm, sizeof dm, "%.3f", dcmd_num(r->recon, "dm_mag")),
               dcmd_fmt(c, sizeof c, "%.2f",
                        dcmd_num(dcmd_obj(r->recon, "quality"), "closure_rms_deg")),
               dcmd_fmt(t, sizeof t, "%.1f", run_time_s(r)), r->state ? r->state : "-");
    }
    /* r0 holds at a wavelength: say it once, with the runs' errors */
    for (int i = 0; i < n; i++) {
        double wl = dcmd_num(runs[i].run, "r0_wavelength_m");
        if (isfinite(wl)) {
            printf("r0: from image motion at %.0f nm; 1-sigma", wl * 1e9);
            for (int k = 0; k < n; k++) {
                char e[32];
                printf(" %s", dcmd_fmt(e, sizeof e, "%.3f", dcmd_num(runs[k].run, "r0_err_m")));
            }
            printf(" m\n");
            break;
        }
    }
    for (int i = 0; i < n; i++) {
        const bench_run *r = &runs[i];
        if (r->reason && strcmp(r->state ? r->state : "", "done") != 0)
            printf("  %.8s: %s\n", r->uuid ? r->uuid : r->screen, r->reason);
        else if (dcmd_str(r->recon, "png"))
            printf("  %.8s: %s\n", r->uuid, dcmd_str(r->recon, "png"));
    }
}

static int binary_bench(const dcmd_opts *d, const bench_opts *o)
{
    char **screens = g_strsplit(o->screens, ",", -1);
    char **masks = g_strsplit(o->masks, ",", -1);
    int ns = (int)g_strv_length(screens), nm = (int)g_strv_length(masks);
    int n = ns * nm, status = 1;
    bench_run *runs = g_new0(bench_run, n > 0 ? n : 1);
    for (int i = 0; i < ns; i++)
        for (int j = 0; j < nm; j++) {
            runs[i * nm + j].screen = g_strstrip(screens[i]);
            runs[i * nm + j].mask = g_strstrip(masks[j]);
        }
    progress *pg = progress_new(stderr, n * o->frames * (1 + RECON_W));
    JsonObject *sub = NULL;
    client *c = dcmd_connect(d, "specklab experiment");
    if (!c)
        goto free_runs;
    if (check_names(c, "screens", screens) | check_names(c, "masks", masks))
        goto free_client;
    if (dcmd_call(c, "specklab experiment", "subscribe", NULL, DCMD_QUERY_MS, &sub))
        goto free_client;
    json_object_unref(sub);
    start_runs(c, o, runs, n, pg);
    /* Generous: the fake bench needs ~2 s per 100-frame run; a real one
     * with slow wheels and a 512x512 TSM far less than this. */
    double timeout_s = o->timeout_s > 0 ? o->timeout_s : n * (60.0 + 0.5 * o->frames);
    wait_runs(c, runs, n, o->frames, timeout_s, pg);
    progress_finish(pg);
    if (d->json)
        print_json(runs, n, o->frames);
    else
        print_table(runs, n);
    status = 0;
    for (int i = 0; i < n; i++)
        if (!runs[i].state || strcmp(runs[i].state, "done") != 0)
            status = 1;
free_client:
    client_free(c);
free_runs:
    progress_free(pg);
    for (int i = 0; i < n; i++) {
        g_free(runs[i].uuid); g_free(runs[i].state); g_free(runs[i].reason);
        set_obj(&runs[i].run, NULL);
        set_obj(&runs[i].recon, NULL);
    }
    g_free(runs);
    g_strfreev(screens);
    g_strfreev(masks);
    return status;
}

int cmd_experiment(int argc, char **argv)
{
    dcmd_opts d = {0};
    bench_opts o = {0};
    o.frames = 100;
    GOptionEntry entries[] = {
        {"screens", 0, 0, G_OPTION_ARG_STRING, &o.screens, "phase screens, names or slots, comma-separated (required)", "LIST"},
        {"masks", 0, 0, G_OPTION_ARG_STRING, &o.masks, "masks, names or slots, comma-separated (default nrm17)", "LIST"},
        {"frames", 'n', 0, G_OPTION_ARG_INT, &o.frames, "frames per run (default 100)", "N"},
        {"exposure-us", 0, 0, G_OPTION_ARG_INT, &o.exposure_us, "exposure per frame (default: the daemon's)", "US"},
        {"object", 0, 0, G_OPTION_ARG_STRING, &o.object, "object name recorded with each run", "NAME"},
        {"method", 0, 0, G_OPTION_ARG_STRING, &o.method, "reconstruction auto|direct|tsm|tsm-fourier|none (default: the daemon's)", "M"},
        {"kind", 0, 0, G_OPTION_ARG_STRING, &o.kind, "what the runs are: science (default), dark (light blocked: a closed mask slot), flat (uniform light) or calibrator (a point source); darks and flats calibrate later reconstructions and are not reconstructed", "KIND"},
        {"timeout-s", 0, 0, G_OPTION_ARG_INT, &o.timeout_s, "give up waiting after S s (default runs x (60 + 0.5 x frames))", "S"},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("binary-bench - the laser binary through each screen and mask");
    g_option_context_add_main_entries(ctx, entries, NULL);
    dcmd_opts_add(&d, ctx);
    g_option_context_set_description(ctx,
        "For each (screen, mask) the daemon moves the stage, acquires, catalogues and\n"
        "reconstructs; runs queue one behind the other.  The table gives per run the\n"
        "measured r0, the binary's separation, PA and dm, c against the cophased\n"
        "reference when known, and the run's time.  Exit status 1 if any run failed.");
    int status = 2;
    if (!cli_parse(ctx, &argc, &argv))
        goto free_ctx;
    if (argc != 2 || strcmp(argv[1], "binary-bench") != 0) {
        fprintf(stderr, "specklab experiment: usage: specklab experiment binary-bench "
                        "--screens 1,2,3 [--masks nrm17] [--frames 100] (try --help)\n");
        goto free_ctx;
    }
    if (!o.screens || !*o.screens) {
        fprintf(stderr, "specklab experiment: --screens LIST is required (e.g. --screens 1,2,3)\n");
        goto free_ctx;
    }
    if (!o.masks)
        o.masks = g_strdup("nrm17");
    if (o.frames < 1 || o.frames > 100000 || o.exposure_us < 0 || o.timeout_s < 0) {
        fprintf(stderr, "specklab experiment: --frames must be 1..100000, "
                        "--exposure-us and --timeout-s positive\n");
        goto free_ctx;
    }
    int m;
    if (o.method && strcmp(o.method, "none") && pipeline_method_parse(o.method, &m) != SL_OK) {
        fprintf(stderr, "specklab experiment: unknown --method '%s' (auto, direct, tsm, "
                        "tsm-fourier, none)\n", o.method);
        goto free_ctx;
    }
    catalog_kind k;
    if (o.kind && catalog_kind_parse(o.kind, &k) != SL_OK) {
        fprintf(stderr, "specklab experiment: unknown --kind '%s' (science, dark, flat, "
                        "calibrator)\n", o.kind);
        goto free_ctx;
    }
    status = binary_bench(&d, &o);
free_ctx:
    g_option_context_free(ctx);
    dcmd_opts_clear(&d);
    g_free(o.screens); g_free(o.masks); g_free(o.object); g_free(o.method);
    g_free(o.kind);
    return status;
}
