/* viewers.c - `make soak-web`: does watching the bench cost frames?
 *
 * The bench of the integration tests (daemon_fx.h: fake stage, fake
 * camera, specklabd with [web] in a private network namespace), 128x128
 * frames at 100 Hz.  Three acquisitions of WEB_SOAK_FRAMES (1000) frames:
 * one with nobody looking, one with WEB_SOAK_VIEWERS (10) viewers, one
 * with nobody again.  A viewer does what the page does at its chosen rate
 * WEB_SOAK_VIEWER_HZ (10): it holds the event stream (/api/events at that
 * rate) and fetches /api/frame.png and /api/powspec.png each period, and
 * /api/history every 2 s, each on a new connection; ten of them run as
 * threads of this program.
 *
 * Each run is judged from its cube and FRAMES table (cfitsio), never from
 * the daemon's word: frames stored (NAXIS3), damaged buffers, frame-id
 * gaps (frames the camera sent that never arrived), and the acquisition
 * rate = (good frames - 1) / (last - first SYS_TS_NS).  PASS: the watched
 * run lost nothing (all frames stored, no damaged buffer, no gap) and its
 * rate is within 5 % of the mean of the unwatched runs; once the viewers
 * are gone the daemon has the descriptors it had before them and at most
 * 8 MB more resident memory.  The CPU time of
 * the daemon, the fake camera and the viewers per run and the viewers'
 * request counts are printed with it.
 *
 * Everything shares the machine, the fake camera too (it renders each
 * frame with the simulator): other load during the watched run slows the
 * camera itself (fewer frames sent, none lost: no id gap), which a real
 * camera's rate would not be.  Run it on an otherwise idle machine.
 *
 * Environment: WEB_SOAK_FRAMES, WEB_SOAK_VIEWERS, WEB_SOAK_VIEWER_HZ,
 * WEB_SOAK_RATE_HZ (100), WEB_SOAK_SIZE (128); SL_KEEP_TMP=1 keeps the
 * bench directory.
 */
#include "daemon_fx.h"
#include "web_fx.h"

#include <pthread.h>

#define PORT 8080
#define MAX_VIEWERS 64

typedef struct facts {
    long stored, damaged, gaps;
    double rate_hz, cpu_s, cam_cpu_s, self_cpu_s;   /* daemon, camera, viewers */
} facts;

typedef struct viewer {
    int hz;
    volatile int *stop;
    long requests, failures, updates, bytes;
} viewer;

static int env_int(const char *name, int def, int lo, int hi)
{
    const char *v = getenv(name);
    int x = v && *v ? atoi(v) : def;
    return x < lo || x > hi ? def : x;
}

/* ---- one viewer --------------------------------------------------------------- */

static void fetch(viewer *v, const char *path)
{
    web_reply r = {0};
    web_get(PORT, path, &r);
    v->requests++;
    if (r.status != 200 && v->failures++ < 3)
        fprintf(stderr, "soak-web: GET %s: %d %s\n", path, r.status, r.why);
    else
        v->bytes += r.body ? r.body->len : 0;
    web_reply_clear(&r);
}

static void *viewer_main(void *p)
{
    viewer *v = p;
    char path[64], why[160];
    web_ws ws = {-1, NULL};
    snprintf(path, sizeof path, "/api/events?hz=%d", v->hz);
    if (web_ws_open(&ws, PORT, path, "http://127.0.0.1:8080", why, sizeof why) != 0)
        v->failures++;
    double next_hist = fx_now();
    while (!*v->stop) {
        double t0 = fx_now();
        int closed = 0;
        fetch(v, "/api/frame.png?stretch=asinh");
        fetch(v, "/api/powspec.png");
        if (t0 >= next_hist) {
            fetch(v, "/api/history");
            next_hist = t0 + 2;
        }
        double left = 1.0 / v->hz - (fx_now() - t0);
        if (ws.fd >= 0)
            v->updates += web_ws_read(&ws, 1000, left > 0 ? left : 0, NULL, &closed);
        else if (left > 0)
            fx_nap_ms((int)(left * 1000));
        if (closed)
            v->failures++, web_ws_close(&ws);
    }
    web_ws_close(&ws);
    return NULL;
}

/* ---- one run, judged from its files ----------------------------------------------- */

static double daemon_cpu_s(pid_t pid)
{
    char path[64], buf[1024];
    snprintf(path, sizeof path, "/proc/%d/stat", (int)pid);
    FILE *f = fopen(path, "r");
    unsigned long ut = 0, st = 0;
    if (f && fgets(buf, sizeof buf, f)) {
        const char *p = strrchr(buf, ')');
        if (p)
            sscanf(p + 2, "%*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %lu %lu", &ut, &st);
    }
    if (f)
        fclose(f);
    return (double)(ut + st) / (double)sysconf(_SC_CLK_TCK);
}

static int frames_table(const char *path, facts *fa, char *why, size_t n)
{
    fitsfile *f = NULL;
    int s = 0, cid = 0, cts = 0, cst = 0, any = 0;
    long rows = 0;
    fits_open_diskfile(&f, path, READONLY, &s);
    fits_movnam_hdu(f, BINARY_TBL, "FRAMES", 0, &s);
    fits_get_num_rows(f, &rows, &s);
    fits_get_colnum(f, CASEINSEN, "FRAME_ID", &cid, &s);
    fits_get_colnum(f, CASEINSEN, "SYS_TS_NS", &cts, &s);
    fits_get_colnum(f, CASEINSEN, "STATUS", &cst, &s);
    LONGLONG *ids = g_new0(LONGLONG, rows + 1), *ts = g_new0(LONGLONG, rows + 1);
    char **st = g_new0(char *, rows + 1);
    for (long i = 0; i < rows; i++)
        st[i] = g_malloc0(32);
    fits_read_col(f, TLONGLONG, cid, 1, 1, rows, NULL, ids, &any, &s);
    fits_read_col(f, TLONGLONG, cts, 1, 1, rows, NULL, ts, &any, &s);
    fits_read_col(f, TSTRING, cst, 1, 1, rows, NULL, st, &any, &s);
    LONGLONG t_first = 0, t_last = 0, last_id = 0;
    long good = 0;
    for (long i = 0; !s && i < rows; i++) {
        if (strcmp(st[i], "SUCCESS") != 0) {
            fa->damaged++;
            continue;
        }
        if (good++ == 0)
            t_first = ts[i];
        t_last = ts[i];
        if (last_id > 0 && ids[i] > 0) {   /* ids cycle 1..65535 */
            long d = (long)((ids[i] - last_id + 65535) % 65535);
            fa->gaps += d > 1 ? d - 1 : 0;
        }
        last_id = ids[i] > 0 ? ids[i] : last_id;
    }
    fa->rate_hz = good > 1 && t_last > t_first ? (good - 1) / ((t_last - t_first) * 1e-9) : 0;
    for (long i = 0; i < rows; i++)
        g_free(st[i]);
    g_free(st), g_free(ids), g_free(ts);
    int s2 = 0;
    if (f)
        fits_close_file(f, &s2);
    if (s)
        snprintf(why, n, "%s: FRAMES table unreadable (cfitsio %d)", path, s);
    return s ? -1 : 0;
}

static int run_once(bench *b, dc *c, int frames, facts *fa, char *why, size_t n)
{
    char args[160], uuid[40], path[400];
    memset(fa, 0, sizeof *fa);
    snprintf(args, sizeof args, "{\"screen\": 1, \"mask\": \"nrm17\", \"frames\": %d, "
             "\"reconstruct\": \"none\"}", frames);
    JsonNode *r = keep(b, dc_call(c, "start-run", args, 10));
    if (!jok(r)) {
        snprintf(why, n, "start-run: %.300s", jtext(r));
        return -1;
    }
    snprintf(uuid, sizeof uuid, "%s", js(r, "result.run"));
    double cpu0 = daemon_cpu_s(b->daemon.pid), cam0 = daemon_cpu_s(b->cam.pid);
    double self0 = daemon_cpu_s(getpid());
    JsonNode *e = keep(b, dc_wait_state(c, uuid, "stored,done,failed,aborted", frames / 20.0 + 60,
                                         NULL, NULL));
    fa->cpu_s = daemon_cpu_s(b->daemon.pid) - cpu0;
    fa->cam_cpu_s = daemon_cpu_s(b->cam.pid) - cam0;
    fa->self_cpu_s = daemon_cpu_s(getpid()) - self0;
    if (!e || !(!strcmp(js(e, "state"), "stored") || !strcmp(js(e, "state"), "done"))) {
        snprintf(why, n, "run %s ended %.300s", uuid, e ? jtext(e) : "(no state in time)");
        return -1;
    }
    long n3 = 0, rows = 0;
    snprintf(path, sizeof path, "%s/runs/%s.fits", b->data, uuid);
    if (fx_fits(path, &n3, &rows, why, n) != 0 || frames_table(path, fa, why, n) != 0)
        return -1;
    fa->stored = n3;
    return 0;
}

/* The daemon's resident memory [kB] and open descriptors. */
static void daemon_mem(pid_t pid, long *rss_kb, int *fds)
{
    char path[64], line[256];
    snprintf(path, sizeof path, "/proc/%d/status", (int)pid);
    FILE *f = fopen(path, "r");
    *rss_kb = -1, *fds = 0;
    while (f && fgets(line, sizeof line, f))
        sscanf(line, "VmRSS: %ld", rss_kb);
    if (f)
        fclose(f);
    snprintf(path, sizeof path, "/proc/%d/fd", (int)pid);
    GDir *d = g_dir_open(path, 0, NULL);
    while (d && g_dir_read_name(d))
        (*fds)++;
    if (d)
        g_dir_close(d);
}

/* ---- the measurement -------------------------------------------------------------- */

typedef struct plan {
    int frames, nviewers, viewer_hz, rate_hz;
    char size[16];
} plan;

static void print_facts(const char *what, const facts *f, int frames)
{
    printf("soak-web: %-16s %4ld/%d frames stored, %ld damaged, %ld id gaps, %.2f frames/s; "
           "CPU s: daemon %.2f, fake camera %.2f, viewers %.2f\n", what, f->stored, frames,
           f->damaged, f->gaps, f->rate_hz, f->cpu_s, f->cam_cpu_s, f->self_cpu_s);
    fflush(stdout);
}

static int start_bench(bench *b, const plan *pl, char *why, size_t n)
{
    char extra[256];
    snprintf(extra, sizeof extra, "[camera]\nframe_rate_hz=%d\nexposure_us=1000\n"
             "[web]\nlisten=127.0.0.1:%d\nmax_connections=64\n", pl->rate_hz, PORT);
    if (bench_init(b) != 0)
        return snprintf(why, n, "bench_init"), -1;
    b->cam_gige = 1;   /* the camera's CPU is measured: a process of its own */
    snprintf(b->cam_size, sizeof b->cam_size, "%s", pl->size);
    if (bench_start_stage(b, NULL) || bench_start_camera(b) || bench_write_config(b, extra) ||
        bench_start_daemon(b))
        return snprintf(why, n, "the bench did not start (SL_BIN_DIR?)"), -1;
    return 0;
}

/* Watched run between two unwatched ones; the verdict in t. */
static void measure(tc *t, bench *b, dc *c, const plan *pl)
{
    char why[512] = "";
    facts quiet[2], watched;
    viewer v[MAX_VIEWERS];
    pthread_t th[MAX_VIEWERS];
    volatile int stop = 0;
    long rss0, rss1;
    int fds0, fds1;
    CHECK(run_once(b, c, pl->frames, &quiet[0], why, sizeof why) == 0, "%s", why);
    print_facts("no viewer", &quiet[0], pl->frames);
    daemon_mem(b->daemon.pid, &rss0, &fds0);
    memset(v, 0, sizeof v);
    for (int i = 0; i < pl->nviewers; i++) {
        v[i].hz = pl->viewer_hz, v[i].stop = &stop;
        pthread_create(&th[i], NULL, viewer_main, &v[i]);
    }
    fx_nap_ms(1000);
    double t0 = fx_now();
    int rc = run_once(b, c, pl->frames, &watched, why, sizeof why);
    double dt = fx_now() - t0;
    stop = 1;
    long req = 0, fail = 0, upd = 0, bytes = 0;
    for (int i = 0; i < pl->nviewers; i++) {
        pthread_join(th[i], NULL);
        req += v[i].requests, fail += v[i].failures, upd += v[i].updates, bytes += v[i].bytes;
    }
    CHECK(rc == 0, "%s", why);
    char label[32];
    snprintf(label, sizeof label, "%d viewers", pl->nviewers);
    print_facts(label, &watched, pl->frames);
    printf("soak-web: viewers: %d at %d Hz: %ld requests (%.0f/s), %ld failed, %.1f MB, "
           "%ld status updates (%.0f/s)\n", pl->nviewers, pl->viewer_hz, req, req / dt, fail,
           bytes / 1e6, upd, upd / dt);
    CHECK(run_once(b, c, pl->frames, &quiet[1], why, sizeof why) == 0, "%s", why);
    print_facts("no viewer again", &quiet[1], pl->frames);
    daemon_mem(b->daemon.pid, &rss1, &fds1);
    printf("soak-web: daemon before and after the viewers: RSS %ld -> %ld kB, %d -> %d open "
           "descriptors\n", rss0, rss1, fds0, fds1);
    double base = (quiet[0].rate_hz + quiet[1].rate_hz) / 2, ratio = watched.rate_hz / base;
    printf("soak-web: watched rate / unwatched rate = %.2f / %.2f = %.4f (%+.2f %%)\n",
           watched.rate_hz, base, ratio, 100 * (ratio - 1));
    fflush(stdout);
    CHECK(watched.stored == pl->frames && watched.damaged == 0 && watched.gaps == 0,
          "the watched run lost frames: %ld stored, %ld damaged, %ld gaps", watched.stored,
          watched.damaged, watched.gaps);
    CHECK(fabs(ratio - 1) <= 0.05, "the watched rate is %.2f %% off", 100 * (ratio - 1));
    CHECK(fail == 0, "%ld viewer requests failed", fail);
    CHECK(fds1 == fds0 && rss1 - rss0 < 8192, "after the viewers: %d descriptors (were %d), "
          "RSS grew %ld kB", fds1, fds0, rss1 - rss0);
}

static void soak_web_run(tc *t)
{
    plan pl = {env_int("WEB_SOAK_FRAMES", 1000, 100, 1000000),
               env_int("WEB_SOAK_VIEWERS", 10, 1, MAX_VIEWERS),
               env_int("WEB_SOAK_VIEWER_HZ", 10, 1, 30), env_int("WEB_SOAK_RATE_HZ", 100, 1, 1000),
               ""};
    snprintf(pl.size, sizeof pl.size, "%d", env_int("WEB_SOAK_SIZE", 128, 16, 2048));
    bench b_, *b = &b_;
    char why[256];
    printf("soak-web: %s x %s frames at %d Hz, %d frames a run, %d viewers at %d Hz\n", pl.size,
           pl.size, pl.rate_hz, pl.frames, pl.nviewers, pl.viewer_hz);
    fflush(stdout);
    if (start_bench(b, &pl, why, sizeof why) != 0) {
        bench_down(b, 1);
        CHECK(0, "%s", why);
    }
    dc *c = bench_client(b);
    JsonNode *r = c ? keep(b, dc_call(c, "subscribe", NULL, 5)) : NULL;
    facts warm;
    int ok = c && bench_wait_camera(b, c, 20) == 0 && jok(r) &&
             run_once(b, c, 200, &warm, why, sizeof why) == 0;   /* homing, first streams */
    if (ok)
        measure(t, b, c, &pl);
    else
        tc_note(t, 0, __FILE__, __LINE__, "warm-up", "warm-up run: %s", why);
    bench_check_stop(t, b);
    bench_down(b, t->failed);
}

TEST(ten_viewers) { fx_in_netns(t, soak_web_run, 600); }

TC_MAIN(TC_CASE(ten_viewers))
