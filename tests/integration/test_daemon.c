/* test_daemon.c - specklabd end to end on a simulated bench (fake stage,
 * fake camera, daemon; daemon_fx.h): a full run, the queue and two
 * clients at once, bad requests, and a clean stop mid-run; a camera
 * source is refused on a backend of real cameras, and a missing one is
 * named in `status`.
 *
 * Truth: the fake camera renders a binary of separation 0.7 arcsec at PA
 * 30 deg, dm 1, at its default plate scale, which is also the daemon's
 * default PLTSCALE; the reconstruction must find it (the 2 % and
 * 1 deg), with the direct bispectrum (reliable on 64x64 frames; TSM runs
 * in the queue test).  Files are checked with cfitsio and GChecksum, the
 * catalogue through a handle of the test's own: never through the
 * daemon's own word alone.
 */
#include "daemon_fx.h"

#define SEP_ARCSEC 0.7
#define PA_DEG 30.0
#define DEFAULT_PLTSCALE 0.05934801016109636
#define SERVER_LINE_LIMIT 65536   /* PROTOCOL.md: longer lines are too-large */

static int has(const char *hay, const char *needle)
{
    return hay && needle && strstr(hay, needle) != NULL;
}

/* The fake camera's detector (its defaults): 1 e-/ADU, 2 e- read noise. */
BENCH_TEST(full_run, 120, NULL, "[camera]\ngain_e_per_adu=1\nread_noise_e=2\n")
{
    dc *c = bench_client(b);
    CHECK(c, "cannot connect to %s", b->sock);
    CHECK(bench_wait_camera(b, c, 20) == 0, "the daemon never reported the camera");
    JsonNode *r = keep(b, dc_call(c, "subscribe", NULL, 5));
    CHECK(jok(r), "subscribe: %s", jtext(r));
    r = keep(b, dc_call(c, "start-run", "{\"screen\": 1, \"mask\": \"full\", \"frames\": 60, "
                        "\"object\": \"laser binary\", \"operator\": \"test\", "
                        "\"reconstruct\": \"direct\"}", 5));
    CHECK(jok(r) && has(js(r, "result.state"), "queued") && ji(r, "result.queue_position") == 0 &&
              jnull(r, "result.queued_behind"),
          "start-run: %s", jtext(r));
    char uuid[40];
    snprintf(uuid, sizeof uuid, "%s", js(r, "result.run"));
    GString *seen = g_string_new(NULL);
    gint64 lastp = -1;
    JsonNode *e = keep(b, dc_wait_state(c, uuid, "done,failed,aborted", 90, seen, &lastp));
    char states[256];
    snprintf(states, sizeof states, "%s", seen->str);
    g_string_free(seen, TRUE);
    CHECK(e && has(js(e, "state"), "done") && jnull(e, "reason"), "run ended %s (states %s)",
          jtext(e), states);
    CHECK(!strcmp(states, "queued,moving,acquiring,stored,reconstructing,done"), "states %s",
          states);
    CHECK(lastp == 60, "last progress event said %lld frames", (long long)lastp);

    r = keep(b, dc_call(c, "run", NULL, 5));
    CHECK(!jok(r) && has(js(r, "error.code"), "bad-request") && has(js(r, "error.message"), "run"),
          "run without args: %s", jtext(r));
    char args[128];
    snprintf(args, sizeof args, "{\"run\": \"%.8s\"}", uuid);   /* a unique prefix */
    r = keep(b, dc_call(c, "run", args, 5));
    CHECK(jok(r), "run: %s", jtext(r));
    JsonNode *run = jget(r, "result.run");
    CHECK(has(js(run, "uuid"), uuid) && has(js(run, "state"), "done") &&
              ji(run, "frames_requested") == 60 && ji(run, "frames_acquired") == 60 &&
              has(js(run, "screen"), "screen1") && has(js(run, "mask"), "full") &&
              has(js(run, "object"), "laser binary") && has(js(run, "operator"), "test") &&
              has(js(run, "camera_serial"), "SPECKLE01") && js(run, "started") &&
              js(run, "ended"),
          "run: %s", jtext(run));
    char file[400], want[450], hex[65];
    snprintf(file, sizeof file, "%s", js(run, "file"));
    snprintf(want, sizeof want, "%s/runs/%s.fits", b->data, uuid);
    CHECK(!strcmp(file, want), "file %s, expected %s", file, want);
    CHECK(fx_sha256(file, hex) == 0 && has(js(run, "sha256"), hex) && strlen(hex) == 64,
          "sha256 %s in the catalogue, %s on disk", js(run, "sha256"), hex);
    double r0 = jd(run, "r0_m");
    CHECK(isfinite(r0) && r0 > 0, "r0_m of the run: %s", jtext(jget(run, "r0_m")));
    char msg[512];
    long n3, rows;
    CHECK(fx_fits(file, &n3, &rows, msg, sizeof msg) == 0, "%s", msg);
    CHECK(n3 == 60 && rows == 60 + ji(run, "frames_failed"), "cube %ld frames, FRAMES %ld rows",
          n3, rows);
    fitsfile *f = NULL;
    int s = 0;
    double scale = 0, gain = 0, rdn = 0;
    fits_open_diskfile(&f, file, READONLY, &s);
    fits_read_key(f, TDOUBLE, "PLTSCALE", &scale, NULL, &s);
    fits_read_key(f, TDOUBLE, "GAIN", &gain, NULL, &s);
    fits_read_key(f, TDOUBLE, "RDNOISE", &rdn, NULL, &s);
    if (f) {
        int s2 = 0;
        fits_close_file(f, &s2);
    }
    CHECK(s == 0 && fabs(scale - DEFAULT_PLTSCALE) < 1e-12, "PLTSCALE %g (cfitsio %d)", scale, s);
    /* the fake camera reports Gain 0 dB: GAIN is the configured value */
    CHECK(gain == 1 && rdn == 2, "GAIN %g, RDNOISE %g: configured 1, 2", gain, rdn);

    JsonNode *rec = jget(r, "result.reconstructions.0");
    CHECK(rec && has(js(rec, "method"), "direct") && !jget(r, "result.reconstructions.1"),
          "reconstructions: %s", jtext(jget(r, "result.reconstructions")));
    double sep = jd(rec, "sep_arcsec"), pa = jd(rec, "pa_deg");
    CHECK(fabs(sep - SEP_ARCSEC) <= 0.02 * SEP_ARCSEC, "separation %.4f arcsec, configured %.2f",
          sep, SEP_ARCSEC);
    CHECK(fabs(pa - PA_DEG) <= 1.0, "PA %.3f deg, configured %.1f", pa, PA_DEG);
    CHECK(fabs(jd(rec, "sep_px") * DEFAULT_PLTSCALE - sep) < 1e-9, "sep_px and sep_arcsec disagree");
    CHECK(has(js(rec, "params.skips"), "reject,crop,support"), "params %s",
          jtext(jget(rec, "params")));
    /* direct measures the binary on its bispectrum's closure phases */
    CHECK(has(js(rec, "params.binary"), "closure-phase"), "params %s",
          jtext(jget(rec, "params")));
    /* Photons from GAIN and the frames' flux: the fake renders 1000
     * photons per ms for the default 10 ms; the 64x64 sensor loses some
     * of the wings. */
    double phot = 0;
    char src[FLEN_VALUE] = "";
    s = 0;
    fits_open_diskfile(&f, js(rec, "fits"), READONLY, &s);
    fits_read_key(f, TDOUBLE, "RECPHOT", &phot, NULL, &s);
    fits_read_key(f, TSTRING, "RECPHSRC", src, NULL, &s);
    /* Every keyword the README promises for this configuration (skips
     * reject, crop and support; the closure-phase binary): the header is
     * written from the typed result in one place, and none may drop. */
    static const char *const promised[] = {
        "RECMETH", "RECTIME", "RECNFRM", "RECSKIPS", "RECREJ", "RECREJE", "RECREJS",
        "RECREJF", "RECREJQ", "RECREJK", "RECCROPX", "RECCROPY", "RECCROPW", "RECCROPH",
        "RECR2", "RECNTRI", "CPSTAT", "CPSEP", "CPSEPE", "CPPA", "CPPAE", "CPDM", "CPDME",
        "CPNTRI"};
    const char *missing = NULL;
    for (size_t i = 0; i < sizeof promised / sizeof promised[0] && !missing && s == 0; i++) {
        char card[FLEN_CARD];
        int ks = 0;
        if (fits_read_card(f, promised[i], card, &ks) != 0)
            missing = promised[i];
    }
    if (f) {
        int s2 = 0;
        fits_close_file(f, &s2);
    }
    CHECK(!missing, "keyword %s missing from the daemon's reconstruction", missing);
    CHECK(s == 0 && !strcmp(src, "GAIN") && phot > 6000 && phot < 10500,
          "RECPHOT %g from %s (cfitsio %d): expected 6000..10500 from GAIN", phot, src, s);
    CHECK(g_file_test(js(rec, "fits"), G_FILE_TEST_IS_REGULAR) &&
              g_file_test(js(rec, "png"), G_FILE_TEST_IS_REGULAR) &&
              g_str_has_prefix(js(rec, "fits"), b->data),
          "outputs %s %s", js(rec, "fits"), js(rec, "png"));

    catalog_run cr;
    CHECK(fx_catalog_run(b, uuid, &cr, msg, sizeof msg) == 0, "%s", msg);
    int same = cr.state == CATALOG_DONE && cr.file_sha256 && !strcmp(cr.file_sha256, hex) &&
               cr.frames_acquired == 60;
    catalog_run_clear(&cr);
    CHECK(same, "the catalogue file disagrees with the reply");

    r = keep(b, dc_call(c, "screens", NULL, 5));
    CHECK(jok(r) && has(js(r, "result.screens.1.name"), "screen1") &&
              ji(r, "result.screens.1.stats.n") == 1 &&
              fabs(jd(r, "result.screens.1.r0_m") - r0) < 1e-12,
          "screens: %s", jtext(r));
    r = keep(b, dc_call(c, "masks", NULL, 5));
    CHECK(jok(r) && has(js(r, "result.masks.1.name"), "nrm17") &&
              ji(r, "result.masks.1.nholes") == 17 && has(js(r, "result.masks.0.kind"), "full"),
          "masks: %s", jtext(r));
    r = keep(b, dc_call(c, "status", NULL, 5));
    CHECK(jok(r) && has(js(r, "result.state"), "idle") && jnull(r, "result.current_run") &&
              !jget(r, "result.queue.0") && has(js(r, "result.camera.serial"), "SPECKLE01"),
          "status: %s", jtext(r));
    r = keep(b, dc_call(c, "devices", NULL, 10));
    CHECK(jok(r) && ji(r, "result.stage.wheels.0.position") == 1 &&
              ji(r, "result.stage.wheels.1.position") == 0 &&
              has(js(r, "result.stage.wheels.0.status"), "in position"),
          "devices: %s", jtext(r));
    struct stat st;
    CHECK(stat(b->sock, &st) == 0 && S_ISSOCK(st.st_mode) && (st.st_mode & 0777) == 0660 &&
              st.st_uid == geteuid() && st.st_gid == getegid(),
          "socket mode %o uid %d gid %d", st.st_mode & 0777, (int)st.st_uid, (int)st.st_gid);
}

/* Every state event of every run, in order, as "uuid:state" entries. */
static void collect_states(dc *c, GPtrArray *log, const char *until_run, const char *until_state,
                           double timeout_s)
{
    double end = fx_now() + timeout_s;
    for (;;) {
        JsonNode *e = dc_next_event(c, end - fx_now());
        if (!e)
            return;
        const char *st = js(e, "state");
        int stop = 0;
        if (st) {
            g_ptr_array_add(log, g_strdup_printf("%s:%s", js(e, "run"), st));
            stop = !strcmp(js(e, "run"), until_run) && !strcmp(st, until_state);
        }
        json_node_unref(e);
        if (stop)
            return;
    }
}

static int find_entry(GPtrArray *log, const char *run, const char *state)
{
    char *want = g_strdup_printf("%s:%s", run, state);
    int at = -1;
    for (guint i = 0; i < log->len && at < 0; i++)
        if (!strcmp(log->pdata[i], want))
            at = (int)i;
    g_free(want);
    return at;
}

BENCH_TEST(queue_and_two_clients, 150, NULL, NULL)
{
    dc *a = bench_client(b), *c2 = bench_client(b);
    CHECK(a && c2, "cannot connect to %s", b->sock);
    CHECK(bench_wait_camera(b, a, 20) == 0, "the daemon never reported the camera");
    JsonNode *r = keep(b, dc_call(a, "subscribe", NULL, 5));
    CHECK(jok(r), "subscribe: %s", jtext(r));
    char ua[40], ub[40], uc[40];
    r = keep(b, dc_call(a, "start-run", "{\"screen\": \"screen2\", \"mask\": 0, \"frames\": 80, "
                        "\"reconstruct\": \"none\"}", 5));
    CHECK(jok(r) && ji(r, "result.queue_position") == 0, "A: %s", jtext(r));
    snprintf(ua, sizeof ua, "%s", js(r, "result.run"));
    r = keep(b, dc_call(c2, "start-run", "{\"screen\": 3, \"mask\": \"nrm17\", \"frames\": 20, "
                        "\"reconstruct\": \"none\"}", 5));
    CHECK(jok(r) && ji(r, "result.queue_position") == 1 &&
              has(js(r, "result.queued_behind"), ua),
          "B while A runs: %s", jtext(r));
    snprintf(ub, sizeof ub, "%s", js(r, "result.run"));
    r = keep(b, dc_call(c2, "start-run", "{\"screen\": 4, \"mask\": 0, \"frames\": 20}", 5));
    CHECK(jok(r) && ji(r, "result.queue_position") == 2 &&
              has(js(r, "result.queued_behind"), ub),
          "C: %s", jtext(r));
    snprintf(uc, sizeof uc, "%s", js(r, "result.run"));
    r = keep(b, dc_call(c2, "status", NULL, 5));
    /* C is queued whatever A and B are doing (B cannot end before C is
     * aborted below: it needs A's 80 frames and its own 20). */
    CHECK(jok(r) && has(js(r, "result.state"), "running") &&
              (has(js(r, "result.queue.1"), uc) || has(js(r, "result.queue.2"), uc)),
          "status: %s", jtext(r));
    char args[128];
    snprintf(args, sizeof args, "{\"run\": \"%s\"}", uc);
    r = keep(b, dc_call(c2, "abort-run", args, 5));
    CHECK(jok(r) && has(js(r, "result.state"), "aborted"), "abort of queued C: %s", jtext(r));
    r = keep(b, dc_call(c2, "abort-run", args, 5));
    CHECK(!jok(r) && has(js(r, "error.code"), "conflict"), "second abort of C: %s", jtext(r));

    GPtrArray *log = g_ptr_array_new_with_free_func(g_free);
    collect_states(a, log, ub, "done", 90);
    int a_stored = find_entry(log, ua, "stored"), b_moving = find_entry(log, ub, "moving");
    int b_done = find_entry(log, ub, "done"), c_moving = find_entry(log, uc, "moving");
    int c_aborted = find_entry(log, uc, "aborted");
    g_ptr_array_free(log, TRUE);
    CHECK(a_stored >= 0 && b_done >= 0 && b_moving > a_stored,
          "B must start after A's acquisition: A stored at %d, B moving at %d, done at %d",
          a_stored, b_moving, b_done);
    CHECK(c_moving < 0 && c_aborted >= 0, "aborted C moved (%d) or no abort event (%d)", c_moving,
          c_aborted);

    /* Pipelining: three requests in one write; the slow reconstruction's
     * reply comes first because replies keep request order. */
    snprintf(args, sizeof args, "{\"id\":1000,\"cmd\":\"reconstruct\",\"args\":{\"run\":\"%s\","
             "\"method\":\"tsm\"}}\n", ua);
    char *batch = g_strconcat(args, "{\"id\":1001,\"cmd\":\"status\"}\n",
                              "{\"id\":1002,\"cmd\":\"masks\"}\n", NULL);
    int sent = dc_send_raw(a, batch, strlen(batch));
    g_free(batch);
    CHECK(sent == 0, "send failed");
    /* The other client is served while that reconstruction runs. */
    snprintf(args, sizeof args, "{\"run\": \"%s\"}", ub);
    for (int i = 0; i < 3; i++) {
        r = keep(b, dc_call(c2, "run", args, 5));
        CHECK(jok(r) && has(js(r, "result.run.uuid"), ub) && has(js(r, "result.run.state"), "done"),
              "B's run from client 2: %s", jtext(r));
    }
    gint64 order[3];
    for (int i = 0; i < 3; i++) {
        r = keep(b, dc_wait_reply(a, -1, 60));
        order[i] = ji(r, "id");
        if (i == 0)
            CHECK(jok(r) && has(js(r, "result.reconstruction.method"), "tsm") &&
                      ji(r, "result.reconstruction.id") > 0,
                  "reconstruct: %s", jtext(r));
    }
    CHECK(order[0] == 1000 && order[1] == 1001 && order[2] == 1002, "reply order %lld %lld %lld",
          (long long)order[0], (long long)order[1], (long long)order[2]);
    snprintf(args, sizeof args, "{\"run\": \"%s\"}", ua);
    r = keep(b, dc_call(a, "run", args, 5));
    CHECK(jok(r) && has(js(r, "result.run.state"), "done") &&
              has(js(r, "result.reconstructions.0.method"), "tsm") &&
              !jget(r, "result.reconstructions.1"),
          "A after on-demand reconstruction: %s", jtext(r));
    /* [daemon] tsm_phases = corrected by default, but this bench's cubes
     * carry no GAIN: the phases that ran were raw, and params say so. */
    CHECK(has(js(r, "result.reconstructions.0.params.tsm_phases"), "raw"),
          "params without GAIN: %s", jtext(jget(r, "result.reconstructions.0.params")));
    r = keep(b, dc_call(a, "runs", "{\"state\": \"aborted\"}", 5));
    CHECK(jok(r) && has(js(r, "result.runs.0.uuid"), uc) && !jget(r, "result.runs.1") &&
              has(js(r, "result.runs.0.exit_reason"), "aborted by request"),
          "runs aborted: %s", jtext(r));
    /* Newest first: C, then B, the two last created (often in the same
     * millisecond as each other and as A: then in the order queued). */
    r = keep(b, dc_call(a, "runs", "{\"limit\": 2}", 5));
    const char *u0 = js(r, "result.runs.0.uuid"), *u1 = js(r, "result.runs.1.uuid");
    const char *t0 = js(r, "result.runs.0.created"), *t1 = js(r, "result.runs.1.created");
    CHECK(jok(r) && u0 && u1 && t0 && t1 && !jget(r, "result.runs.2") && has(u0, uc) &&
              has(u1, ub) && strcmp(t0, t1) >= 0,
          "runs newest first: %s (%s) then %s (%s); A %s, B %s, C %s", u0 ? u0 : "-",
          t0 ? t0 : "-", u1 ? u1 : "-", t1 ? t1 : "-", ua, ub, uc);
}

/* Each bad line gets its error; the connection stays usable. */
typedef struct bad_case {
    const char *line, *code, *says;
    int id;   /* echoed id, -1: null */
} bad_case;

BENCH_TEST(bad_requests, 60, NULL, "[daemon]\nmax_clients=3\n")
{
    static const bad_case cases[] = {
        {"this is not json", "bad-json", "JSON", -1},
        {"[1, 2, 3]", "bad-json", "object", -1},
        {"{\"id\": 5, \"cmd\": \"frobnicate\"}", "unknown-command", "start-run", 5},
        {"{\"id\": 6}", "bad-request", "cmd", 6},
        {"{\"id\": \"six\", \"cmd\": \"status\"}", "bad-request", "id", -1},
        {"{\"id\": 7, \"cmd\": \"status\", \"args\": [1]}", "bad-request", "args", 7},
        {"{\"id\": 8, \"cmd\": \"start-run\", \"args\": {\"screen\": 1, \"mask\": 0, \"frames\": 0}}",
         "bad-request", "frames", 8},
        {"{\"id\": 9, \"cmd\": \"start-run\", \"args\": {\"screen\": 1, \"mask\": 0, \"frames\": "
         "\"10\"}}", "bad-request", "frames", 9},
        {"{\"id\": 10, \"cmd\": \"start-run\", \"args\": {\"screen\": 1, \"mask\": 0}}",
         "bad-request", "frames", 10},
        {"{\"id\": 11, \"cmd\": \"start-run\", \"args\": {\"screen\": 1, \"mask\": 0, \"frames\": 5, "
         "\"colour\": \"red\"}}", "bad-request", "colour", 11},
        {"{\"id\": 12, \"cmd\": \"start-run\", \"args\": {\"screen\": \"nope\", \"mask\": 0, "
         "\"frames\": 5}}", "not-found", "screen1", 12},
        {"{\"id\": 13, \"cmd\": \"start-run\", \"args\": {\"screen\": 1, \"mask\": 9, \"frames\": 5}}",
         "not-found", "nrm17", 13},
        {"{\"id\": 14, \"cmd\": \"start-run\", \"args\": {\"screen\": 1, \"mask\": 0, \"frames\": 5, "
         "\"object\": \"../../etc/passwd\"}}", "bad-request", "object", 14},
        {"{\"id\": 15, \"cmd\": \"start-run\", \"args\": {\"screen\": 1, \"mask\": 0, \"frames\": 5, "
         "\"exposure_us\": -5}}", "bad-request", "exposure_us", 15},
        {"{\"id\": 16, \"cmd\": \"start-run\", \"args\": {\"screen\": 1, \"mask\": 0, \"frames\": 5, "
         "\"reconstruct\": \"magic\"}}", "bad-request", "reconstruct", 16},
        {"{\"id\": 17, \"cmd\": \"run\", \"args\": {\"run\": \"../../etc\"}}", "bad-request", "run", 17},
        {"{\"id\": 18, \"cmd\": \"run\", \"args\": {\"run\": \"abcd\"}}", "not-found", "abcd", 18},
        {"{\"id\": 19, \"cmd\": \"abort-run\", \"args\": {\"run\": \"0000-\"}}", "not-found", "0000", 19},
        {"{\"id\": 20, \"cmd\": \"runs\", \"args\": {\"state\": \"sleeping\"}}", "bad-request", "state", 20},
        {"{\"id\": 21, \"cmd\": \"reconstruct\", \"args\": {\"run\": \"ffff\", \"method\": \"x\"}}",
         "bad-request", "method", 21},
        {"{\"id\": 22, \"cmd\": \"runs\", \"args\": {\"since\": \"yesterday\"}}", "bad-request",
         "since", 22},
    };
    dc *c = bench_client(b);
    CHECK(c, "cannot connect to %s", b->sock);
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char *line = g_strconcat(cases[i].line, "\n", NULL);
        int sent = dc_send_raw(c, line, strlen(line));
        g_free(line);
        CHECK(sent == 0, "send failed");
        JsonNode *r = keep(b, dc_wait_reply(c, -1, 5));
        const char *code = js(r, "error.code"), *m = js(r, "error.message");
        CHECK(r && !jok(r) && has(code, cases[i].code) && has(m, cases[i].says),
              "%s -> %s (want %s naming %s)", cases[i].line, jtext(r), cases[i].code,
              cases[i].says);
        CHECK(cases[i].id < 0 ? jnull(r, "id") : ji(r, "id") == cases[i].id, "id echoed: %s",
              jtext(r));
    }
    /* A line of exactly the limit is a request... */
    char *big = g_malloc(SERVER_LINE_LIMIT + 2);
    memset(big, ' ', SERVER_LINE_LIMIT);
    memcpy(big, "{\"id\": 99, \"cmd\": \"status\"}", 27);
    big[SERVER_LINE_LIMIT] = '\n';
    int sent = dc_send_raw(c, big, SERVER_LINE_LIMIT + 1);
    JsonNode *r = keep(b, dc_wait_reply(c, 99, 5));
    CHECK(sent == 0 && jok(r), "a %d-byte line: %s", SERVER_LINE_LIMIT, jtext(r));
    /* ...one byte more is refused, and that connection is closed. */
    big[SERVER_LINE_LIMIT] = ' ';
    sent = dc_send_raw(c, big, SERVER_LINE_LIMIT + 1) || dc_send_raw(c, "\n", 1);
    g_free(big);
    r = keep(b, dc_wait_reply(c, -1, 5));
    CHECK(r && has(js(r, "error.code"), "too-large") && jnull(r, "id"), "oversized: %s", jtext(r));
    JsonNode *more = keep(b, dc_read(c, 5));
    CHECK(!more && c->eof, "connection still open after too-large: %s", jtext(more));
    /* Nothing changed, and the daemon still serves others, up to
     * max_clients at once: with every slot held by a subscriber (an idle
     * connection would make room: test_daemon_clients), one more is told
     * "busy" and let go. */
    dc *d2 = bench_client(b), *d3 = bench_client(b), *d4 = bench_client(b);
    CHECK(d2 && d3 && d4, "cannot connect after the bad requests");
    dc *subs[] = {d2, d3, d4};
    for (int i = 0; i < 3; i++)
        CHECK(jok(keep(b, dc_call(subs[i], "subscribe", NULL, 5))), "subscribe %d", i);
    r = keep(b, dc_call(d3, "status", NULL, 5));
    CHECK(jok(r) && ji(r, "result.clients") == 3, "status: %s", jtext(r));
    dc *d5 = bench_client(b);
    r = keep(b, d5 ? dc_wait_reply(d5, -1, 5) : NULL);
    CHECK(r && has(js(r, "error.code"), "busy") && !keep(b, dc_read(d5, 5)) && d5->eof,
          "a client beyond max_clients: %s", jtext(r));
    r = keep(b, dc_call(d2, "runs", NULL, 5));
    CHECK(jok(r) && !jget(r, "result.runs.0"), "runs after bad requests: %s", jtext(r));
    char runs[300];
    snprintf(runs, sizeof runs, "%s/runs", b->data);
    GDir *dir = g_dir_open(runs, 0, NULL);
    const char *name = dir ? g_dir_read_name(dir) : "no runs directory";
    char first[256];
    snprintf(first, sizeof first, "%s", name ? name : "");
    if (dir)
        g_dir_close(dir);
    CHECK(!first[0], "a file appeared under %s: %s", runs, first);
}

BENCH_TEST(sigterm_mid_run, 90, NULL, NULL)
{
    dc *c = bench_client(b);
    CHECK(c, "cannot connect to %s", b->sock);
    JsonNode *r = keep(b, dc_call(c, "subscribe", NULL, 5));
    r = keep(b, dc_call(c, "start-run", "{\"screen\": 2, \"mask\": 0, \"frames\": 2000}", 5));
    CHECK(jok(r), "start-run: %s", jtext(r));
    char uuid[40], msg[512];
    snprintf(uuid, sizeof uuid, "%s", js(r, "result.run"));
    gint64 told = dc_wait_progress(c, uuid, 20, 30);
    CHECK(told >= 20, "no progress to 20 frames");
    int status = fx_stop(&b->daemon, SIGTERM, 20);
    CHECK(status == 0, "daemon exit status %d after SIGTERM", status);
    CHECK(access(b->sock, F_OK) != 0, "socket %s left behind", b->sock);
    JsonNode *e = keep(b, dc_wait_state(c, uuid, "aborted,failed,done", 5, NULL, &told));
    CHECK(e && has(js(e, "reason"), "daemon stopping"), "last state event: %s", jtext(e));
    catalog_run cr;
    CHECK(fx_catalog_run(b, uuid, &cr, msg, sizeof msg) == 0, "%s", msg);
    char file[400], sha[65] = "", hex[65] = "";
    int acquired = cr.frames_acquired;
    catalog_state st = cr.state;
    snprintf(file, sizeof file, "%s", cr.file_path ? cr.file_path : "");
    snprintf(sha, sizeof sha, "%s", cr.file_sha256 ? cr.file_sha256 : "");
    int why = has(cr.exit_reason, "daemon stopping");
    catalog_run_clear(&cr);
    CHECK(st == CATALOG_ABORTED && why, "state %s", catalog_state_name(st));
    CHECK(g_str_has_suffix(file, ".fits.part"), "file %s", file);
    long n3, rows;
    CHECK(fx_fits(file, &n3, &rows, msg, sizeof msg) == 0, "%s", msg);
    CHECK(n3 == acquired && acquired >= told && acquired < 2000 && rows >= n3,
          "cube %ld frames, catalogue %d, last progress %lld, FRAMES rows %ld", n3, acquired,
          (long long)told, rows);
    CHECK(fx_sha256(file, hex) == 0 && !strcmp(hex, sha), "sha256 %s vs %s", sha, hex);
}

/* [camera] source on the aravis backend: the daemon does not start
 * (exit 2) and names the key; nothing is loaded into a real camera's
 * daemon. */
static void source_refused_run(tc *t)
{
    bench b;
    char bin[PATH_MAX], out[256];
    CHECK(bench_init(&b) == 0, "bench_init");
    FILE *f = fopen(b.conf, "w");
    if (f) {
        fprintf(f, "[camera]\nbackend=aravis\nsource=%s/x.so\n[paths]\ndata_dir=%s\n"
                   "[daemon]\nsocket=%s\n", b.dir, b.data, b.sock);
        fclose(f);
    }
    fx_bin(bin, sizeof bin, "specklabd");
    char *argv[] = {bin, "--config", b.conf, "--foreground", NULL};
    int st = f ? fx_run(argv, b.dlog, NULL, NULL, out, sizeof out, 20) : -1;
    gchar *log = NULL;
    g_file_get_contents(b.dlog, &log, NULL, NULL);
    int named = has(log, "[camera] source") && has(log, "only the fake backend");
    g_free(log);
    bench_down(&b, st != 2 || !named);
    CHECK(st == 2 && named, "source with backend=aravis: exit %d, named %d", st, named);
}

TEST(source_needs_the_fake_backend) { fx_in_child(t, source_refused_run, 30); }

/* The fake backend with a source that refuses its arguments: the daemon
 * runs, and `status` says the camera is not connected, with the source's
 * own message. */
static void no_source_file(bench *b)
{
    snprintf(b->cam_extra, sizeof b->cam_extra, "--size");   /* a flag without its value */
}

BENCH_TEST_WITH(source_errors_named, 60, no_source_file, NULL, NULL)
{
    dc *c = bench_client(b);
    CHECK(c, "cannot connect");
    JsonNode *r = NULL;
    double end = fx_now() + 10;
    while (fx_now() < end) {
        r = keep(b, dc_call(c, "status", NULL, 5));
        if (js(r, "result.camera.error"))
            break;
        fx_nap_ms(50);
    }
    const char *why = r ? js(r, "result.camera.error") : NULL;
    CHECK(has(why, "fake camera source") && has(why, "Missing argument for --size"),
          "status names no source error: %s", jtext(r));
}

TC_MAIN(TC_CASE(full_run), TC_CASE(queue_and_two_clients), TC_CASE(bad_requests),
        TC_CASE(sigterm_mid_run), TC_CASE(source_needs_the_fake_backend),
        TC_CASE(source_errors_named))
