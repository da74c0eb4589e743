/* soak.c - `make soak`: specklabd under sustained load on the simulated
 * bench, checked for lost frames, memory growth, descriptor leaks and
 * catalogue/disk drift.  Not part of `make test` (it takes minutes).
 *
 * The bench is the integration tests' (daemon_fx.h): fake stage, fake
 * camera and specklabd in a private network namespace (GVCP's port 3956
 * is fixed), every start synchronised on a READY line.  The sequence:
 *   1. one long run (SOAK_LONG_FRAMES, 10000) on screen 1, reconstructed
 *      with the daemon's default method (auto; SOAK_LONG_RECON=none
 *      skips it, =tsm-fourier streams the 330 MB cube in ~10 s);
 *   2. SOAK_RUNS (50) short runs of SOAK_SHORT_FRAMES (100), each on
 *      another screen/mask slot pair (every stage move a screen swap),
 *      reconstructed with the daemon's default method.  Run k+1 is
 *      submitted as soon as run k is stored, so the stage moves and the
 *      camera streams while the worker reconstructs k (the daemon's real
 *      back-to-back pattern).  The first SOAK_WARM_RUNS (12: each of the
 *      6 x 2 slot pairs once) are the warm-up: FFTW plans and wisdom,
 *      SQLite's page cache, GLib's and malloc's pools reach their
 *      working size there.
 * The daemon's VmRSS and open descriptors (/proc/PID) are sampled every
 * second and after each run; "after warm-up" and "end" are taken with the
 * daemon idle (no run, no reconstruction), so they compare like with like.
 *
 * PASS needs, for every run: state done; catalogue frames_acquired =
 * frames requested = the cube's NAXIS3 = the FRAMES table's SUCCESS rows,
 * whose CUBE_IDX run 0..N-1 (no good frame missing from the cube: "lost"
 * counts the difference); frame-id gaps in the table equal to the
 * driver's NIDGAPS (every frame never delivered is accounted for); the
 * catalogued SHA-256 equal to the file's; the daemon's files under runs/
 * and recon/ exactly the catalogue's (each file a row, each row a file).
 * For the daemon: RSS growth end - after-warm-up < SOAK_RSS_BOUND_MB (8),
 * descriptors at the end = after warm-up, clean exit 0 on SIGTERM, no
 * GLib warning in its log.  Damaged buffers (a status other than SUCCESS,
 * never stored, counted in frames_failed) are reported, not failed: the
 * camera did not deliver them as good frames.
 *
 * Rate: 128x128 Mono16 frames at 200 Hz (5 ms).  The fake camera renders
 * each frame with the simulator, which is CPU-bound at ~150-190 frames/s
 * on the 2-core development machine, so it runs flat out; the daemon
 * needs ~0.7 ms of CPU per frame.
 *
 * Then the load phase (soak_load.c): SOAK_LOAD_FRAMES (1000) acquired
 * while the daemon and a separate `specklab recon` both reconstruct the
 * long run with TSM and SOAK_LOAD_HOGS (1) processes spin; the run is
 * checked like the others (no frame lost, every gap accounted for).
 *
 * Environment: SOAK_LONG_FRAMES, SOAK_RUNS, SOAK_SHORT_FRAMES,
 * SOAK_WARM_RUNS, SOAK_RATE_HZ (camera frame rate, default 200),
 * SOAK_EXPOSURE_US (1000), SOAK_SIZE (sensor, 128), SOAK_RSS_BOUND_MB,
 * SOAK_LONG_RECON, SOAK_LOAD_FRAMES (0: no load phase), SOAK_LOAD_HOGS,
 * SOAK_LOAD_PROJECTIONS, SOAK_BUFFERS (the daemon's [camera] buffers; default:
 * the daemon's), SOAK_CONF_EXTRA (more configuration lines, e.g.
 * $'[paths]\ncatalog=/elsewhere/x.db'); SL_KEEP_TMP=1 keeps the bench
 * directory.
 */
#include "daemon_fx.h"

#include <dirent.h>   /* after daemon_fx.h: it sets _GNU_SOURCE */
#include "soak.h"

#define SAMPLE_S 1.0        /* RSS/fd sampling period while waiting */
#define REPORT_S 15.0       /* progress line period */

static int env_int(const char *name, int def, int lo, int hi)
{
    const char *v = getenv(name);
    char *end = NULL;
    long x = v && *v ? strtol(v, &end, 10) : def;
    if (v && *v && (*end || x < lo || x > hi)) {
        fprintf(stderr, "soak: %s=%s: expected %d..%d; using %d\n", name, v, lo, hi, def);
        x = def;
    }
    return (int)x;
}

static double env_dbl(const char *name, double def)
{
    const char *v = getenv(name);
    char *end = NULL;
    double x = v && *v ? strtod(v, &end) : def;
    if (v && *v && (*end || !(x > 0))) {
        fprintf(stderr, "soak: %s=%s: expected a positive number; using %g\n", name, v, def);
        x = def;
    }
    return x;
}

static void opts_load(soak_opts *o)
{
    const char *v;
    o->long_frames = env_int("SOAK_LONG_FRAMES", 10000, 1, 100000);
    o->runs = env_int("SOAK_RUNS", 50, 0, SOAK_MAX_RUNS - 1);
    o->short_frames = env_int("SOAK_SHORT_FRAMES", 100, 1, 100000);
    o->warm_runs = env_int("SOAK_WARM_RUNS", 12, 0, SOAK_MAX_RUNS);
    o->buffers = env_int("SOAK_BUFFERS", 0, 0, 1024);
    if (o->warm_runs > o->runs)
        o->warm_runs = o->runs;
    o->rate_hz = env_dbl("SOAK_RATE_HZ", 200);
    o->exposure_us = env_dbl("SOAK_EXPOSURE_US", 1000);
    o->rss_bound_mb = env_dbl("SOAK_RSS_BOUND_MB", 8);
    v = getenv("SOAK_SIZE");
    snprintf(o->size, sizeof o->size, "%s", v && *v ? v : "128");
    v = getenv("SOAK_LONG_RECON");   /* "": the daemon's default */
    snprintf(o->long_method, sizeof o->long_method, "%s", v && *v ? v : "");
    o->load_frames = env_int("SOAK_LOAD_FRAMES", 1000, 0, 100000);
    o->load_hogs = env_int("SOAK_LOAD_HOGS", 1, 0, 64);
    /* 400: about the most a 128 px frame resolves (pi x 128 = 402; more is
     * refused), so the reconstructions last through the load phase */
    o->load_projections = env_int("SOAK_LOAD_PROJECTIONS", 400, 1, 4096);
}

/* ---- the daemon as /proc sees it ------------------------------------------ */

static int proc_sample_get(pid_t pid, proc_sample *out)
{
    char path[64], line[256];
    snprintf(path, sizeof path, "/proc/%d/status", (int)pid);
    FILE *f = fopen(path, "r");
    out->rss_kb = out->hwm_kb = -1;
    out->fds = -1;
    if (!f)
        return -1;
    while (fgets(line, sizeof line, f)) {
        sscanf(line, "VmRSS: %ld", &out->rss_kb);
        sscanf(line, "VmHWM: %ld", &out->hwm_kb);
    }
    fclose(f);
    /* utime and stime: fields 14 and 15, after the ")" that ends comm */
    snprintf(path, sizeof path, "/proc/%d/stat", (int)pid);
    f = fopen(path, "r");
    char stat[1024] = "";
    size_t got = f ? fread(stat, 1, sizeof stat - 1, f) : 0;
    if (f)
        fclose(f);
    stat[got] = 0;
    const char *p = strrchr(stat, ')');
    unsigned long ut = 0, stt = 0;
    if (p && sscanf(p + 2, "%*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %lu %lu", &ut, &stt) == 2)
        out->cpu_s = (double)(ut + stt) / (double)sysconf(_SC_CLK_TCK);
    snprintf(path, sizeof path, "/proc/%d/fd", (int)pid);
    DIR *d = opendir(path);
    if (!d)
        return -1;
    int n = 0;
    for (struct dirent *e; (e = readdir(d));)
        n += e->d_name[0] != '.';
    closedir(d);
    out->fds = n;
    return out->rss_kb >= 0 ? 0 : -1;
}

static void sample(soak *s, proc_sample *out)
{
    proc_sample p;
    if (proc_sample_get(s->b.daemon.pid, &p) != 0)
        return;
    s->t_sample = fx_now();
    if (p.rss_kb > s->peak.rss_kb)
        s->peak.rss_kb = p.rss_kb;
    if (p.fds > s->peak.fds)
        s->peak.fds = p.fds;
    s->peak.hwm_kb = p.hwm_kb;
    s->last_rss_kb = p.rss_kb;
    s->last_fds = p.fds;
    if (s->warm_done && p.rss_kb > s->peak_after_warm_kb)
        s->peak_after_warm_kb = p.rss_kb;
    if (out)
        *out = p;
}

/* Idle: no run in hand or queued, no reconstruction.  Then the descriptor
 * count, once two reads 100 ms apart agree (a worker may be closing the
 * files of the job it just finished: a leak stays, a transient does not). */
static int wait_idle(soak *s, proc_sample *out, double timeout_s)
{
    double end = fx_now() + timeout_s;
    while (fx_now() < end) {
        JsonNode *r = dc_call(s->c, "status", NULL, 5);
        int idle = jok(r) && !strcmp(js(r, "result.state") ? js(r, "result.state") : "", "idle") &&
                   jnull(r, "result.reconstructing") && ji(r, "result.reconstruct_queue") == 0;
        if (r)
            json_node_unref(r);
        if (idle)
            break;
        fx_nap_ms(100);
    }
    if (fx_now() >= end)
        return -1;
    proc_sample a = {0}, b = {0};
    sample(s, &a);
    for (int i = 0; i < 20; i++) {
        fx_nap_ms(100);
        sample(s, &b);
        if (b.fds == a.fds)
            break;
        a = b;
    }
    *out = b;
    return 0;
}

/* ---- events --------------------------------------------------------------- */

static soak_run *find_run(soak *s, const char *uuid)
{
    for (int i = 0; uuid && i < s->nruns; i++)
        if (!strcmp(s->runs[i].uuid, uuid))
            return &s->runs[i];
    return NULL;
}

static int terminal(const char *state)
{
    return !strcmp(state, "done") || !strcmp(state, "failed") || !strcmp(state, "aborted") ||
           !strcmp(state, "interrupted");
}

/* Take one event (or none within the time left), sampling the daemon every
 * SAMPLE_S and printing a progress line every REPORT_S.  State events
 * update the runs; a terminal one is followed by a sample ("after each
 * run").  0, or -1 when until passed. */
int soak_pump(soak *s, double until)
{
    double now = fx_now();
    if (now >= until)
        return -1;
    if (now - s->t_sample >= SAMPLE_S)
        sample(s, NULL);
    if (now - s->t_report >= REPORT_S) {
        s->t_report = now;
        printf("soak: %5.0f s  runs %d/%d done  frames %ld  RSS %.1f MB  fds %d\n",
               now - s->t0, s->ndone, s->nruns, s->frames_seen, s->last_rss_kb / 1024.0,
               s->last_fds);
        fflush(stdout);
    }
    double wait = MIN(until - now, SAMPLE_S);
    JsonNode *e = dc_next_event(s->c, wait);
    if (!e)
        return s->c->eof ? -1 : 0;
    soak_run *r = find_run(s, js(e, "run"));
    const char *kind = js(e, "event"), *st = js(e, "state");
    if (r && kind && !strcmp(kind, "progress")) {
        gint64 n = ji(e, "frames_acquired");
        s->frames_seen += n - r->progress;
        r->progress = n;
        if (n >= r->frames && r->t_full == 0) {   /* the frame loop is over */
            proc_sample p = {0};
            sample(s, &p);
            r->t_full = fx_now(), r->cpu_full = p.cpu_s;
        }
    } else if (r && st) {
        snprintf(r->state, sizeof r->state, "%s", st);
        proc_sample p = {0};
        if (!strcmp(st, "acquiring")) {
            sample(s, &p);
            r->t_acq = fx_now(), r->cpu_acq = p.cpu_s;
        }
        if ((!strcmp(st, "stored") || terminal(st)) && r->t_stored == 0)
            r->t_stored = fx_now();
        if (terminal(st)) {
            s->ndone++;
            sample(s, NULL);
            if (strcmp(st, "done") || !jnull(e, "reason"))
                soak_problem(s, "run %d (%.8s) ended %s: %s", (int)(r - s->runs), r->uuid, st,
                             js(e, "reason") ? js(e, "reason") : "-");
        }
    }
    json_node_unref(e);
    return 0;
}

int soak_submit(soak *s, int screen, int mask, int frames, const char *method)
{
    char args[256];
    int n = snprintf(args, sizeof args, "{\"screen\": %d, \"mask\": %d, \"frames\": %d, "
                     "\"exposure_us\": %g, \"object\": \"soak\", \"operator\": \"soak\"",
                     screen, mask, frames, s->o.exposure_us);
    if (method)
        n += snprintf(args + n, sizeof args - (size_t)n, ", \"reconstruct\": \"%s\"", method);
    snprintf(args + n, sizeof args - (size_t)n, "}");
    JsonNode *r = dc_call(s->c, "start-run", args, 10);
    if (!jok(r) || s->nruns >= SOAK_MAX_RUNS) {
        soak_problem(s, "start-run %s: %s", args, jtext(r));
        if (r)
            json_node_unref(r);
        return -1;
    }
    soak_run *run = &s->runs[s->nruns++];
    memset(run, 0, sizeof *run);
    snprintf(run->uuid, sizeof run->uuid, "%s", js(r, "result.run"));
    snprintf(run->state, sizeof run->state, "queued");
    run->frames = frames, run->screen = screen, run->mask = mask;
    run->reconstructs = !method || strcmp(method, "none");
    json_node_unref(r);
    return (int)(run - s->runs);
}

/* Pump until run i has left acquisition (stored or an end); -1 on time
 * (soak.h). */
int soak_wait_stored(soak *s, int i, double timeout_s)
{
    double until = fx_now() + timeout_s;
    while (!(s->runs[i].t_stored > 0))
        if (soak_pump(s, until) != 0)
            return -1;
    return 0;
}

static int wait_all_done(soak *s, double timeout_s)
{
    double until = fx_now() + timeout_s;
    while (s->ndone < s->nruns)
        if (soak_pump(s, until) != 0)
            return -1;
    return 0;
}

/* ---- the sequence ------------------------------------------------------- */

static int bench_start(soak *s)
{
    bench *b = &s->b;
    char extra[1024];
    const char *more = getenv("SOAK_CONF_EXTRA");
    if (bench_init(b) != 0)
        return -1;
    b->cam_gige = 1;   /* the bench as deployed: GigE on loopback */
    snprintf(b->cam_size, sizeof b->cam_size, "%s", s->o.size);
    /* Later keys win over the fixture's 100 Hz; a 5 s loss timeout stays
     * well clear of a loaded machine's scheduling stalls. */
    int n = snprintf(extra, sizeof extra, "[camera]\nframe_rate_hz=%g\nlost_timeout_s=5\n",
                     s->o.rate_hz);
    if (s->o.buffers > 0)
        n += snprintf(extra + n, sizeof extra - (size_t)n, "buffers=%d\n", s->o.buffers);
    snprintf(extra + n, sizeof extra - (size_t)n, "%s\n", more ? more : "");
    if (bench_start_stage(b, NULL) || bench_start_camera(b) || bench_write_config(b, extra) ||
        bench_start_daemon(b))
        return -1;
    sample(s, &s->start);
    s->c = bench_client(b);
    if (!s->c || bench_wait_camera(b, s->c, 30) != 0)
        return -1;
    JsonNode *r = dc_call(s->c, "subscribe", NULL, 5);
    int ok = jok(r);
    if (r)
        json_node_unref(r);
    return ok ? 0 : -1;
}

static void soak_sequence(soak *s)
{
    const soak_opts *o = &s->o;
    double per_frame_s = 1.0 / o->rate_hz;
    /* Bounds, not expectations: 4x the nominal acquisition plus a minute. */
    double long_limit = 60 + 4.0 * o->long_frames * per_frame_s;
    double short_limit = 60 + 4.0 * o->short_frames * per_frame_s;

    printf("soak: long run, %d frames of %s at %g Hz (reconstruct: %s)\n", o->long_frames,
           o->size, o->rate_hz, o->long_method[0] ? o->long_method : "the daemon's default");
    fflush(stdout);
    int i = soak_submit(s, 1, 0, o->long_frames, o->long_method[0] ? o->long_method : NULL);
    if (i < 0 || wait_all_done(s, long_limit + (s->runs[0].reconstructs ? 600 : 0)) != 0) {
        soak_problem(s, "the long run did not end within its bound (state %s)",
                     i < 0 ? "-" : s->runs[i].state);
        return;
    }
    printf("soak: %d short runs of %d frames, reconstructed (daemon default), "
           "%d of them warm-up\n", o->runs, o->short_frames, o->warm_runs);
    fflush(stdout);
    for (int k = 0; k < o->runs; k++) {
        if (k == o->warm_runs && o->warm_runs > 0) {
            if (wait_all_done(s, 600) != 0 || wait_idle(s, &s->base, 120) != 0) {
                soak_problem(s, "the warm-up runs did not end");
                return;
            }
            s->warm_done = 1;
            s->peak_after_warm_kb = s->base.rss_kb;
        }
        /* Consecutive runs never share a slot pair: the stage moves (a
         * screen swap) before every run; 6 screens x 2 masks cycle. */
        i = soak_submit(s, k % 6, (k / 6) % 2, o->short_frames, NULL);
        if (i < 0 || soak_wait_stored(s, i, short_limit) != 0) {
            soak_problem(s, "short run %d did not leave acquisition within %.0f s (state %s)",
                         k, short_limit, i < 0 ? "-" : s->runs[i].state);
            return;
        }
    }
    if (o->warm_runs == 0) {   /* no warm-up: compare with the start */
        s->base = s->start;
        s->warm_done = 1;
    }
    if (wait_all_done(s, 600) != 0 || wait_idle(s, &s->end, 120) != 0)
        soak_problem(s, "the short runs did not all end (%d of %d)", s->ndone, s->nruns);
    /* After the idle end point: the load does not blur the RSS and
     * descriptor comparison. */
    soak_load(s);
    if (wait_all_done(s, 600) != 0)
        soak_problem(s, "the load run did not end (%d of %d)", s->ndone, s->nruns);
}

/* The daemon's log lines of GLib warnings or worse: reported, and a
 * failure (the daemon logs a warning only for something that went wrong). */
static int log_warnings(const bench *b)
{
    FILE *f = fopen(b->dlog, "r");
    char line[1024];
    int n = 0;
    while (f && fgets(line, sizeof line, f))
        if (strstr(line, "WARNING") || strstr(line, "CRITICAL") || strstr(line, "ERROR")) {
            if (n++ < 5)
                printf("soak: daemon log: %s", line);
        }
    if (f)
        fclose(f);
    return n;
}

static void summary(soak *s, double elapsed_s, int daemon_exit)
{
    const soak_opts *o = &s->o;
    const soak_run *lr = s->nruns > 0 ? &s->runs[0] : NULL;
    /* Acquiring to the last frame's progress event: the frame loop only,
     * not the checksum and fsync that follow. */
    double acq_s = lr && lr->t_acq > 0 && lr->t_full > lr->t_acq ? lr->t_full - lr->t_acq : NAN;
    double growth_mb = (s->end.rss_kb - s->base.rss_kb) / 1024.0;
    printf("\n==== soak summary ====\n");
    int nload = s->load.run >= 0;
    printf("runs       %d (1 x %d frames + %d x %d frames%s), %d done\n", s->nruns,
           o->long_frames, s->nruns - 1 - nload, o->short_frames,
           nload ? " + the load run" : "", s->ndone);
    printf("frames     requested %ld, in cubes %ld, catalogued %ld, lost %ld; damaged %ld, "
           "id gaps %ld (accounted %s)\n", s->f.requested, s->f.naxis3, s->f.catalogued,
           s->f.lost, s->f.damaged, s->f.gaps, s->f.gaps_unaccounted ? "NO" : "yes");
    printf("rate       long run %d frames in %.1f s = %.1f frames/s (camera set to %g Hz, "
           "%s sensor); daemon CPU %.2f ms/frame\n", o->long_frames, acq_s,
           o->long_frames / acq_s, o->rate_hz, o->size,
           lr ? 1e3 * (lr->cpu_full - lr->cpu_acq) / o->long_frames : NAN);
    printf("RSS        start %.1f MB, after warm-up %.1f MB, peak %.1f MB (VmHWM %.1f MB), "
           "end %.1f MB\n", s->start.rss_kb / 1024.0, s->base.rss_kb / 1024.0,
           s->peak.rss_kb / 1024.0, s->peak.hwm_kb / 1024.0, s->end.rss_kb / 1024.0);
    printf("           growth after warm-up %+.2f MB (bound %g MB); peak after warm-up "
           "%.1f MB\n", growth_mb, o->rss_bound_mb, s->peak_after_warm_kb / 1024.0);
    printf("fds        start %d, after warm-up %d, peak %d, end %d\n", s->start.fds,
           s->base.fds, s->peak.fds, s->end.fds);
    printf("catalogue  %d run rows, %d reconstruction rows, %d files on disk: %s\n",
           s->disk.run_rows, s->disk.recon_rows, s->disk.files,
           s->disk.mismatches ? "MISMATCH" : "every file a row, every row a file, "
                                              "sha256 equal");
    printf("daemon     exit %d on SIGTERM; %d warning lines in its log\n", daemon_exit,
           s->log_warnings);
    if (s->load.run >= 0) {
        const soak_run *r = &s->runs[s->load.run];
        printf("load       %d frames in %.1f s while the daemon reconstructed the long run "
               "(tsm, %d angles; %s at the last frame; %s), `specklab recon` did too (%s at "
               "the last frame%s) and %d CPU hog%s spun: the machine's 1-min load average "
               "up to %.2f on %ld CPUs; run %s\n", r->frames, s->load.acq_s,
               o->load_projections, s->load.recon_spanned ? "still running" : "ENDED",
               s->load.recon_ok ? "done" : "FAILED",
               s->load.external_spanned ? "still running" : "ENDED",
               s->load.external_ok ? "" : ", FAILED", s->load.hogs, s->load.hogs == 1 ? "" : "s",
               s->load.loadavg_max, sysconf(_SC_NPROCESSORS_ONLN), r->state);
    }
    printf("elapsed    %.0f s (%.1f frames/s overall)\n", elapsed_s,
           s->f.naxis3 / elapsed_s);
    if (s->nproblems)
        printf("problems   %d:\n%s", s->nproblems, s->problems->str);
    printf("soak: %s\n", s->nproblems ? "FAIL" : "PASS");
}

int main(void)
{
    soak *s = g_new0(soak, 1);
    char why[256];
    opts_load(&s->o);
    /* Before any thread exists: unshare(CLONE_NEWUSER) refuses threaded
     * processes. */
    if (fx_enter_netns(why, sizeof why) != 0) {
        fprintf(stderr, "soak: no private network namespace: %s (needs unprivileged user "
                "namespaces, or root)\nsoak: FAIL\n", why);
        return 2;
    }
    s->problems = g_string_new(NULL);
    s->load.run = -1;
    s->peak.rss_kb = s->peak.fds = -1;
    s->t0 = s->t_report = fx_now();
    if (bench_start(s) != 0) {
        soak_problem(s, "the bench did not start (stage, camera or daemon; SL_BIN_DIR?)");
    } else {
        soak_sequence(s);
        if (s->warm_done && s->end.rss_kb > 0) {
            double growth_mb = (s->end.rss_kb - s->base.rss_kb) / 1024.0;
            if (growth_mb >= s->o.rss_bound_mb)
                soak_problem(s, "RSS grew %.2f MB after warm-up (bound %g MB)", growth_mb,
                             s->o.rss_bound_mb);
            if (s->end.fds != s->base.fds)
                soak_problem(s, "descriptors: %d after warm-up, %d at the end", s->base.fds,
                             s->end.fds);
        }
    }
    double elapsed = fx_now() - s->t0;
    int daemon_exit = -1;
    if (s->b.daemon.pid > 0) {
        daemon_exit = fx_stop(&s->b.daemon, SIGTERM, 30);
        if (daemon_exit != 0)
            soak_problem(s, "specklabd exited %d on SIGTERM", daemon_exit);
        /* After the daemon stopped: nothing can change the files under us. */
        soak_check_files(s);
        s->log_warnings = log_warnings(&s->b);
        if (s->log_warnings)
            soak_problem(s, "%d warning lines in the daemon's log (%s)", s->log_warnings,
                         s->b.dlog);
    }
    summary(s, elapsed, daemon_exit);
    int failed = s->nproblems > 0;
    if (failed && s->b.dir[0])
        printf("soak: the bench directory %s %s\n", s->b.dir,
               getenv("SL_KEEP_TMP") ? "is kept" : "is removed (SL_KEEP_TMP=1 keeps it)");
    bench_down(&s->b, 0);
    g_string_free(s->problems, TRUE);
    g_free(s);
    return failed ? 1 : 0;
}
