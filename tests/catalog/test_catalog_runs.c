/* test_catalog_runs.c - properties of the catalogue's runs (round trips,
 * the state machine, restart recovery, progress and files), foreign keys,
 * reconstructions, r0 history and statistics, benchmarks and time.
 */
#include "catalog_fx.h"

#include <glib.h>

/* The state machine as the issue states it, written independently of the
 * schema's run_transitions table. */
static int is_final(catalog_state s)
{
    return s == CATALOG_DONE || s == CATALOG_FAILED || s == CATALOG_ABORTED ||
           s == CATALOG_INTERRUPTED;
}

static int legal(catalog_state from, catalog_state to)
{
    if (is_final(from))
        return 0;
    if (to == CATALOG_FAILED || to == CATALOG_ABORTED ||
        to == CATALOG_INTERRUPTED)
        return 1;
    return (from == CATALOG_QUEUED && to == CATALOG_MOVING) ||
           (from == CATALOG_MOVING && to == CATALOG_ACQUIRING) ||
           (from == CATALOG_ACQUIRING && to == CATALOG_STORED) ||
           (from == CATALOG_STORED &&
            (to == CATALOG_RECONSTRUCTING || to == CATALOG_DONE)) ||
           (from == CATALOG_RECONSTRUCTING && to == CATALOG_DONE);
}

/* Drive a queued run to `s` along the forward chain (exits straight from
 * queued).  Returns SL_OK or the failing status. */
static int drive(catalog *c, const char *uuid, catalog_state s)
{
    static const catalog_state chain[] = {
        CATALOG_MOVING, CATALOG_ACQUIRING, CATALOG_STORED,
        CATALOG_RECONSTRUCTING, CATALOG_DONE};
    if (s == CATALOG_QUEUED)
        return SL_OK;
    if (s == CATALOG_FAILED || s == CATALOG_ABORTED ||
        s == CATALOG_INTERRUPTED)
        return catalog_run_set_state(c, uuid, s, "test exit");
    for (int i = 0; i < 5; i++) {
        int rc = catalog_run_set_state(c, uuid, chain[i], NULL);
        if (rc != SL_OK || chain[i] == s)
            return rc;
    }
    return SL_EINVAL;
}

static int new_run(catalog *c, char uuid[CATALOG_UUID_LEN + 1])
{
    catalog_run_spec spec = {.frames_requested = 10};
    return catalog_run_insert(c, &spec, uuid);
}

/* ---- runs ---- */

typedef struct run_seen {
    int n;
    char uuid[16][CATALOG_UUID_LEN + 1];
} run_seen;

static int collect_run(const catalog_run *r, void *user)
{
    run_seen *v = user;
    if (v->n < 16)
        memcpy(v->uuid[v->n], r->uuid, sizeof r->uuid);
    v->n++;
    return 0;
}

static int stop_at_first(const catalog_run *r, void *user)
{
    (void)r;
    ++*(int *)user;
    return 7;
}

FXTEST(runs_round_trip_and_list)
{
    int64_t s3, s5, m;
    OPEN_OK(f);
    CHECK(catalog_screen_upsert(f->c, "s3", 3, NULL, &s3) == SL_OK &&
              catalog_screen_upsert(f->c, "s5", 5, NULL, &s5) == SL_OK,
          "screens");
    catalog_mask mk = {.name = "open", .slot = 0, .kind = CATALOG_MASK_FULL,
                       .diameter_m = 0.2};
    CHECK(catalog_mask_upsert(f->c, &mk, &m) == SL_OK, "mask");
    const char *given = "0A1B2C3D-4E5F-4a6b-8c7d-9e0f1a2b3c4d";
    catalog_run_spec spec = {
        .uuid = given, .created_ms = 1700000000123, .operator_name = "ana",
        .object = "laser binary", .screen_id = s3, .mask_id = m,
        .camera_serial = "FAKE-1",
        .camera_settings_json = "{\"exposure_us\":2000,\"gain\":1.5}",
        .frames_requested = 100};
    char uuid[CATALOG_UUID_LEN + 1];
    CHECK(catalog_run_insert(f->c, &spec, uuid) == SL_OK, "%s",
          catalog_errmsg(f->c));
    CHECK(!strcmp(uuid, "0a1b2c3d-4e5f-4a6b-8c7d-9e0f1a2b3c4d"), "uuid %s",
          uuid);
    catalog_run r;
    CHECK(catalog_run_get(f->c, given, &r) == SL_OK, "%s", /* any case */
          catalog_errmsg(f->c));
    int ok = r.state == CATALOG_QUEUED && r.created_ms == spec.created_ms &&
             r.updated_ms == spec.created_ms && r.started_ms == 0 &&
             r.ended_ms == 0 && same_str(r.operator_name, "ana") &&
             same_str(r.object, spec.object) && r.screen_id == s3 &&
             same_str(r.screen_name, "s3") && r.mask_id == m &&
             same_str(r.mask_name, "open") &&
             same_str(r.camera_serial, "FAKE-1") &&
             same_str(r.camera_settings_json, spec.camera_settings_json) &&
             r.frames_requested == 100 && r.frames_acquired == 0 &&
             r.frames_failed == 0 && r.packets_missing == 0 &&
             !r.exit_reason && !r.file_path && !r.file_sha256;
    catalog_run_clear(&r);
    CHECK(ok, "run fields differ");
    CHECK(catalog_run_insert(f->c, &spec, NULL) == SL_EINVAL, "dup uuid");
    /* The schema itself keeps uuids canonical, whoever writes. */
    CHECK(raw_exec(f->path, "INSERT INTO runs (uuid, created_ms, updated_ms, "
                            "frames_requested) VALUES ('0A1B2C3D-4E5F-4A6B-"
                            "8C7D-9E0F1A2B3C4D', 0, 0, 1)") ==
              SQLITE_CONSTRAINT, "upper-case uuid stored");
    CHECK(catalog_run_get(f->c, "not-a-uuid", &r) == SL_EINVAL, "bad uuid");
    CHECK(catalog_run_get(f->c, "11111111-2222-4333-8444-555555555555", &r) ==
              SL_EINVAL && strstr(catalog_errmsg(f->c), "no run"),
          "%s", catalog_errmsg(f->c));

    /* Ten generated runs alternating screens, one minute apart. */
    char ids[10][CATALOG_UUID_LEN + 1];
    for (int i = 0; i < 10; i++) {
        catalog_run_spec g = {.created_ms = 1700001000000 + i * 60000,
                              .screen_id = i % 2 ? s5 : s3,
                              .frames_requested = 5};
        CHECK(catalog_run_insert(f->c, &g, ids[i]) == SL_OK, "%s",
              catalog_errmsg(f->c));
        CHECK(g_uuid_string_is_valid(ids[i]), "generated uuid %s", ids[i]);
    }
    CHECK(catalog_run_set_state(f->c, ids[4], CATALOG_MOVING, NULL) == SL_OK,
          "move");
    run_seen v = {0};
    CHECK(catalog_run_list(f->c, NULL, collect_run, &v) == SL_OK && v.n == 11,
          "all: %d", v.n);
    CHECK(!strcmp(v.uuid[0], ids[9]) && !strcmp(v.uuid[10], uuid),
          "not newest first");
    catalog_run_filter fl = {.screen_id = s5};
    memset(&v, 0, sizeof v);
    CHECK(catalog_run_list(f->c, &fl, collect_run, &v) == SL_OK && v.n == 5,
          "screen 5: %d", v.n);
    fl = (catalog_run_filter){.since_ms = 1700001000000 + 7 * 60000};
    memset(&v, 0, sizeof v);
    CHECK(catalog_run_list(f->c, &fl, collect_run, &v) == SL_OK && v.n == 3,
          "since: %d", v.n);
    fl = (catalog_run_filter){.state = CATALOG_MOVING};
    memset(&v, 0, sizeof v);
    CHECK(catalog_run_list(f->c, &fl, collect_run, &v) == SL_OK && v.n == 1 &&
              !strcmp(v.uuid[0], ids[4]), "state: %d", v.n);
    fl = (catalog_run_filter){.limit = 4};
    memset(&v, 0, sizeof v);
    CHECK(catalog_run_list(f->c, &fl, collect_run, &v) == SL_OK && v.n == 4,
          "limit: %d", v.n);
    int calls = 0;
    CHECK(catalog_run_list(f->c, NULL, stop_at_first, &calls) == 7 &&
              calls == 1, "stop: %d calls", calls);
    /* Three queued in one millisecond: newest first by insertion order
     * (the daemon's start-run calls come that fast). */
    char same[3][CATALOG_UUID_LEN + 1];
    for (int i = 0; i < 3; i++) {
        catalog_run_spec g = {.created_ms = 1700002000000, .screen_id = s3,
                              .frames_requested = 5};
        CHECK(catalog_run_insert(f->c, &g, same[i]) == SL_OK, "%s", catalog_errmsg(f->c));
    }
    fl = (catalog_run_filter){.limit = 3};
    memset(&v, 0, sizeof v);
    CHECK(catalog_run_list(f->c, &fl, collect_run, &v) == SL_OK && v.n == 3 &&
              !strcmp(v.uuid[0], same[2]) && !strcmp(v.uuid[1], same[1]) &&
              !strcmp(v.uuid[2], same[0]),
          "same millisecond: not in the order inserted, newest first");

    char got[CATALOG_UUID_LEN + 1];
    CHECK(catalog_run_resolve(f->c, "0A1B2C", got) == SL_OK &&
              !strcmp(got, uuid), "resolve: %s", catalog_errmsg(f->c));
    CHECK(catalog_run_resolve(f->c, "ffff0000", got) == SL_EINVAL, "none");
    CHECK(catalog_run_resolve(f->c, "0a1%", got) == SL_EINVAL, "wildcard");
}

FXTEST(state_machine_allows_exactly_the_legal_transitions)
{
    OPEN_OK(f);
    int nlegal = 0;
    for (int from = CATALOG_QUEUED; from <= CATALOG_INTERRUPTED; from++)
        for (int to = CATALOG_QUEUED; to <= CATALOG_INTERRUPTED; to++) {
            char uuid[CATALOG_UUID_LEN + 1];
            catalog_run a, b;
            CHECK(new_run(f->c, uuid) == SL_OK, "insert");
            CHECK(drive(f->c, uuid, (catalog_state)from) == SL_OK,
                  "to %s: %s", catalog_state_name((catalog_state)from),
                  catalog_errmsg(f->c));
            CHECK(catalog_run_get(f->c, uuid, &a) == SL_OK, "get");
            int rc = catalog_run_set_state(f->c, uuid, (catalog_state)to,
                                           "why");
            int want = legal((catalog_state)from, (catalog_state)to);
            nlegal += want;
            CHECK(catalog_run_get(f->c, uuid, &b) == SL_OK, "get");
            int st_b = b.state, upd_a = a.updated_ms == b.updated_ms;
            int times = b.started_ms == 0 || b.ended_ms == 0 ||
                        b.started_ms <= b.ended_ms;
            int ended = is_final(b.state) == (b.ended_ms != 0);
            catalog_run_clear(&a);
            catalog_run_clear(&b);
            CHECK(times && ended, "times of %s", catalog_state_name(st_b));
            if (want) {
                CHECK(rc == SL_OK && st_b == to, "%s -> %s refused: %s",
                      catalog_state_name((catalog_state)from),
                      catalog_state_name((catalog_state)to),
                      catalog_errmsg(f->c));
            } else {
                char arrow[64];
                snprintf(arrow, sizeof arrow, "%s -> %s",
                         catalog_state_name((catalog_state)from),
                         catalog_state_name((catalog_state)to));
                CHECK(rc == SL_EINVAL && st_b == from && upd_a,
                      "%s allowed or changed the run", arrow);
                CHECK(strstr(catalog_errmsg(f->c), arrow) &&
                          strstr(catalog_errmsg(f->c), "illegal"),
                      "message: %s", catalog_errmsg(f->c));
            }
        }
    CHECK(nlegal == 5 * 3 + 6, "the spec above has %d legal moves", nlegal);
    /* Exits need a reason; the schema refuses what the API would. */
    char uuid[CATALOG_UUID_LEN + 1];
    CHECK(new_run(f->c, uuid) == SL_OK, "insert");
    CHECK(catalog_run_set_state(f->c, uuid, CATALOG_FAILED, NULL) ==
              SL_EINVAL, "failed without a reason");
    CHECK(catalog_run_set_state(f->c, uuid, CATALOG_FAILED, "") == SL_EINVAL,
          "failed with an empty reason");
    CHECK(drive(f->c, uuid, CATALOG_DONE) == SL_OK, "done");
    long long done = raw_int(f->path, "SELECT count(*) FROM runs WHERE "
                                      "state = 'done'");
    CHECK(done == 9 + 2 + 1, "%lld done runs", done); /* loop: 11 */
    CHECK(raw_exec(f->path, "UPDATE runs SET state = 'acquiring' "
                            "WHERE state = 'done'") == SQLITE_CONSTRAINT,
          "the trigger let done -> acquiring through");
    CHECK(raw_int(f->path, "SELECT count(*) FROM runs WHERE state = "
                           "'done'") == done, "a raw write changed a run");
}

FXTEST(mark_interrupted_flips_only_unfinished_runs)
{
    OPEN_OK(f);
    char ids[9][CATALOG_UUID_LEN + 1];
    catalog_run before[9];
    for (int s = CATALOG_QUEUED; s <= CATALOG_INTERRUPTED; s++) {
        CHECK(new_run(f->c, ids[s - 1]) == SL_OK, "insert");
        CHECK(drive(f->c, ids[s - 1], (catalog_state)s) == SL_OK, "drive");
    }
    for (int i = 0; i < 9; i++)
        CHECK(catalog_run_get(f->c, ids[i], &before[i]) == SL_OK, "get");
    int n = catalog_runs_mark_interrupted(f->c);
    int bad = -1;
    for (int i = 0; i < 9 && n == 5; i++) {
        catalog_run r;
        char want[64];
        if (catalog_run_get(f->c, ids[i], &r) != SL_OK) {
            bad = i;
            break;
        }
        snprintf(want, sizeof want, "daemon restarted while %s",
                 catalog_state_name(before[i].state));
        int good = is_final(before[i].state)
                       ? r.state == before[i].state &&
                             same_str(r.exit_reason, before[i].exit_reason) &&
                             r.ended_ms == before[i].ended_ms
                       : r.state == CATALOG_INTERRUPTED &&
                             same_str(r.exit_reason, want) && r.ended_ms > 0;
        catalog_run_clear(&r);
        if (!good && bad < 0)
            bad = i;
    }
    for (int i = 0; i < 9; i++)
        catalog_run_clear(&before[i]);
    CHECK(n == 5, "%d runs marked: %s", n, catalog_errmsg(f->c));
    CHECK(bad < 0, "run in state %d handled wrongly", bad + 1);
    CHECK(catalog_runs_mark_interrupted(f->c) == 0, "second call");
}

FXTEST(progress_and_file)
{
    OPEN_OK(f);
    char u[CATALOG_UUID_LEN + 1];
    catalog_run r;
    const char *sha =
        "9f86d081884c7d659a2feaa0c55ad015a3bf4f1b2b0b822cd15d6c15b0f00a08";
    CHECK(new_run(f->c, u) == SL_OK && drive(f->c, u, CATALOG_ACQUIRING) ==
              SL_OK, "setup");
    CHECK(catalog_run_update_progress(f->c, u, 7, 2, 31) == SL_OK, "%s",
          catalog_errmsg(f->c));
    CHECK(catalog_run_update_progress(f->c, u, 11, 0, 0) == SL_EINVAL &&
              strstr(catalog_errmsg(f->c), "frames_acquired_in_range"),
          "11 of 10 frames: %s", catalog_errmsg(f->c));
    CHECK(catalog_run_update_progress(f->c, u, 1, -1, 0) == SL_EINVAL, "neg");
    CHECK(catalog_run_set_file(f->c, u, "/data/a.fits", "XYZ") == SL_EINVAL &&
              strstr(catalog_errmsg(f->c), "file_sha256_hex"), "bad sha");
    CHECK(catalog_run_set_file(f->c, u, "/data/a.fits", NULL) == SL_OK, "%s",
          catalog_errmsg(f->c));
    CHECK(catalog_run_set_state(f->c, u, CATALOG_FAILED, "camera vanished") ==
              SL_OK, "fail");
    CHECK(catalog_run_update_progress(f->c, u, 8, 2, 31) == SL_EINVAL &&
              strstr(catalog_errmsg(f->c), "final"), "terminal progress");
    /* The partial cube of a failed run is still catalogued. */
    CHECK(catalog_run_set_file(f->c, u, "/data/a.fits", sha) == SL_OK, "%s",
          catalog_errmsg(f->c));
    CHECK(catalog_run_get(f->c, u, &r) == SL_OK, "get");
    int ok = r.frames_acquired == 7 && r.frames_failed == 2 &&
             r.packets_missing == 31 && same_str(r.file_path, "/data/a.fits") &&
             same_str(r.file_sha256, sha) && r.state == CATALOG_FAILED &&
             same_str(r.exit_reason, "camera vanished");
    catalog_run_clear(&r);
    CHECK(ok, "fields after progress, failure and file");
}

FXTEST(foreign_keys_are_enforced)
{
    OPEN_OK(f);
    const char *ghost = "12345678-1234-4234-8234-123456789abc";
    catalog_recon rc;
    catalog_recon_init(&rc);
    rc.run_uuid = ghost;
    rc.method = "tsm";
    CHECK(catalog_recon_insert(f->c, &rc, NULL) == SL_EINVAL &&
              strstr(catalog_errmsg(f->c), "not in the catalogue"),
          "%s", catalog_errmsg(f->c));
    catalog_run_spec spec = {.screen_id = 99, .frames_requested = 1};
    CHECK(catalog_run_insert(f->c, &spec, NULL) == SL_EINVAL &&
              strstr(catalog_errmsg(f->c), "not in the catalogue"),
          "%s", catalog_errmsg(f->c));
    CHECK(catalog_screen_upsert(f->c, "s", 1, NULL, NULL) == SL_OK, "screen");
    catalog_r0 r0;
    catalog_r0_init(&r0);
    r0.screen_name = "s";
    r0.run_uuid = ghost;
    r0.r0_m = 0.1;
    r0.wavelength_m = 633e-9;
    r0.method = "stf";
    CHECK(catalog_r0_add(f->c, &r0, NULL) == SL_EINVAL, "r0 of a ghost run");
    CHECK(raw_int(f->path, "SELECT (SELECT count(*) FROM reconstructions) + "
                           "(SELECT count(*) FROM runs) + "
                           "(SELECT count(*) FROM screen_r0)") == 0,
          "a refused insert left a row");
    CHECK(raw_int(f->path, "SELECT count(*) FROM pragma_foreign_key_check") ==
              0, "foreign_key_check");
}

/* ---- reconstructions ---- */

typedef struct recon_seen {
    int n;
    catalog_recon r[3];
    char method[3][16], params[3][64], fits[3][32];
} recon_seen;

static int collect_recon(const catalog_recon *r, void *user)
{
    recon_seen *v = user;
    if (v->n < 3) {
        v->r[v->n] = *r;
        snprintf(v->method[v->n], 16, "%s", r->method);
        snprintf(v->params[v->n], 64, "%s", r->params_json ? r->params_json
                                                           : "(null)");
        snprintf(v->fits[v->n], 32, "%s", r->output_fits ? r->output_fits
                                                         : "(null)");
    }
    v->n++;
    return 0;
}

FXTEST(reconstructions_round_trip)
{
    OPEN_OK(f);
    char u[CATALOG_UUID_LEN + 1];
    CHECK(new_run(f->c, u) == SL_OK, "run");
    catalog_recon a, b;
    catalog_recon_init(&a);
    CHECK(isnan(a.sep_px) && isnan(a.c_cophased), "init is not NaN");
    a.run_uuid = u;
    a.method = "tsm";
    a.params_json = "{\"projections\":180}";
    a.started_ms = 1700000000000;
    a.elapsed_s = 0.1875;
    a.output_fits = "/out/a.fits";
    a.sep_px = 12.345678901234567;
    a.sep_err_px = 0.01;
    a.pa_deg = -33.3;
    a.pa_err_deg = 0.25;
    a.dm_mag = 1.0;
    a.dm_err_mag = 0.05;
    a.sep_arcsec = 0.1234;
    a.quality_json = "{\"snr\": 41.5}";
    b = a;
    b.method = "direct";
    b.params_json = NULL;
    b.started_ms = a.started_ms + 1;
    b.c_cophased = 0.987;
    b.output_fits = NULL;
    int64_t ida, idb;
    CHECK(catalog_recon_insert(f->c, &a, &ida) == SL_OK, "%s",
          catalog_errmsg(f->c));
    CHECK(catalog_recon_insert(f->c, &b, &idb) == SL_OK && idb > ida, "%s",
          catalog_errmsg(f->c));
    recon_seen v = {0};
    CHECK(catalog_recon_list(f->c, u, collect_recon, &v) == SL_OK && v.n == 2,
          "%d reconstructions", v.n);
    const catalog_recon *x = &v.r[0], *y = &v.r[1];
    CHECK(x->id == ida && !strcmp(v.method[0], "tsm") &&
              !strcmp(v.params[0], a.params_json) &&
              !strcmp(v.fits[0], "/out/a.fits") &&
              x->started_ms == a.started_ms && same_dbl(x->elapsed_s,
              a.elapsed_s) && same_dbl(x->sep_px, a.sep_px) &&
              same_dbl(x->pa_deg, a.pa_deg) &&
              same_dbl(x->dm_err_mag, a.dm_err_mag) &&
              same_dbl(x->sep_arcsec, a.sep_arcsec) && isnan(x->c_cophased),
          "first reconstruction differs");
    CHECK(y->id == idb && !strcmp(v.method[1], "direct") &&
              !strcmp(v.params[1], "(null)") && !strcmp(v.fits[1], "(null)") &&
              same_dbl(y->c_cophased, 0.987), "second reconstruction differs");
    a.c_cophased = 1.5;
    CHECK(catalog_recon_insert(f->c, &a, NULL) == SL_EINVAL &&
              strstr(catalog_errmsg(f->c), "c_cophased_in_range"), "c > 1");
    a.c_cophased = NAN;
    a.sep_px = INFINITY;
    CHECK(catalog_recon_insert(f->c, &a, NULL) == SL_EINVAL, "Inf metric");
    a.sep_px = 1;
    a.params_json = "{not json";
    CHECK(catalog_recon_insert(f->c, &a, NULL) == SL_EINVAL, "bad JSON");
}

/* ---- r0 and screen statistics ---- */

typedef struct r0_seen {
    int n;
    double sum_seeing_err;
    int from_run;
} r0_seen;

static int check_r0(const catalog_r0 *r, void *user)
{
    r0_seen *v = user;
    double want = 0.98 * r->wavelength_m / r->r0_m * 206264.80624709636;
    v->sum_seeing_err += fabs(r->seeing_arcsec - want) / want;
    v->from_run += r->run_uuid != NULL;
    v->n++;
    return 0;
}

static int cmp_dbl(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

FXTEST(screen_statistics_match_the_measurements)
{
    enum { NA = 9, NB = 12 };
    const int64_t day = 86400000, t0 = 1700000000000;
    double ra[NA], rb[NB];
    uint64_t s = 99;
    OPEN_OK(f);
    CHECK(catalog_screen_upsert(f->c, "screen 3", 3, NULL, NULL) == SL_OK &&
              catalog_screen_upsert(f->c, "screen 5", 5, NULL, NULL) ==
                  SL_OK, "screens");
    int64_t s5;
    CHECK(catalog_screen_find(f->c, "screen 5", &s5) == SL_OK, "find");
    catalog_r0 r;
    catalog_r0_init(&r);
    r.wavelength_m = 633e-9;
    r.method = "stf";
    /* Screen 3: NA days of thin-screen r0; screen 5: NB of thicker, each
     * the 3rd one from a run of screen 5 (r0 recorded via the run). */
    for (int i = 0; i < NA + NB; i++) {
        s = s * 6364136223846793005ULL + 1442695040888963407ULL;
        double u = (double)(s >> 11) / 9007199254740992.0;
        int is_a = i < NA;
        r.screen_name = is_a ? "screen 3" : "screen 5";
        r.run_uuid = NULL;
        r.measured_ms = t0 + (is_a ? i : i - NA) * day;
        r.r0_m = is_a ? 0.15 + 0.05 * u : 0.05 + 0.02 * u;
        char u8[CATALOG_UUID_LEN + 1];
        if (!is_a && (i - NA) % 3 == 0) {
            catalog_run_spec sp = {.screen_id = s5, .frames_requested = 1};
            CHECK(catalog_run_insert(f->c, &sp, u8) == SL_OK, "run");
            r.screen_name = NULL;
            r.run_uuid = u8;
        }
        CHECK(catalog_r0_add(f->c, &r, NULL) == SL_OK, "%s",
              catalog_errmsg(f->c));
        if (is_a)
            ra[i] = r.r0_m;
        else
            rb[i - NA] = r.r0_m;
    }
    r0_seen v = {0};
    CHECK(catalog_r0_list(f->c, NULL, 0, check_r0, &v) == SL_OK &&
              v.n == NA + NB && v.from_run == 4, "list: %d %d", v.n,
          v.from_run);
    CHECK(v.sum_seeing_err < 1e-12, "seeing not 0.98 lambda / r0");

    /* Screen 5 over days 2..9 inclusive: 8 values, even count. */
    catalog_r0_stats st;
    CHECK(catalog_screen_stats(f->c, "screen 5", t0 + 2 * day, t0 + 9 * day,
                               &st) == SL_OK, "%s", catalog_errmsg(f->c));
    double w[NB], mean = 0, ss = 0;
    int n = 0;
    for (int i = 2; i <= 9; i++)
        mean += (w[n++] = rb[i]);
    mean /= n;
    for (int i = 0; i < n; i++)
        ss += (w[i] - mean) * (w[i] - mean);
    qsort(w, (size_t)n, sizeof w[0], cmp_dbl);
    /* Runs on days 3, 6 and 9. */
    CHECK(st.n == 8 && st.nruns == 3 && st.first_ms == t0 + 2 * day &&
              st.last_ms == t0 + 9 * day, "n %d runs %d", st.n, st.nruns);
    CHECK_NEAR(st.r0_mean_m, mean, 1e-15);
    CHECK_NEAR(st.r0_std_m, sqrt(ss / (n - 1)), 1e-15);
    CHECK_NEAR(st.r0_median_m, 0.5 * (w[3] + w[4]), 1e-15);
    CHECK(st.r0_min_m == w[0] && st.r0_max_m == w[n - 1], "min/max");
    CHECK(st.wavelength_min_m == 633e-9 && st.wavelength_max_m == 633e-9,
          "wavelengths");

    /* Screen 3, everything: odd count. */
    CHECK(catalog_screen_stats(f->c, "screen 3", 0, 0, &st) == SL_OK, "all");
    memcpy(w, ra, sizeof ra);
    qsort(w, NA, sizeof w[0], cmp_dbl);
    CHECK(st.n == NA && st.nruns == 0 && st.r0_median_m == w[NA / 2],
          "odd median %.17g vs %.17g", st.r0_median_m, w[NA / 2]);
    /* The question the catalogue must answer: 3 is better than 5. */
    catalog_r0_stats s5st;
    CHECK(catalog_screen_stats(f->c, "screen 5", 0, 0, &s5st) == SL_OK &&
              s5st.r0_mean_m < st.r0_mean_m &&
              s5st.seeing_mean_arcsec > st.seeing_mean_arcsec, "ordering");
    /* An empty window. */
    CHECK(catalog_screen_stats(f->c, "screen 3", t0 + 100 * day, 0, &st) ==
              SL_OK && st.n == 0 && isnan(st.r0_mean_m) &&
              isnan(st.r0_median_m) && isnan(st.r0_std_m) && st.first_ms == 0,
          "empty window");
    CHECK(catalog_screen_stats(f->c, "screen 4", 0, 0, &st) == SL_EINVAL,
          "unknown screen");
    r.screen_name = "screen 3";
    r.run_uuid = NULL;
    r.r0_m = -0.1;
    CHECK(catalog_r0_add(f->c, &r, NULL) == SL_EINVAL, "negative r0");
}

/* ---- benchmarks ---- */

typedef struct bench_seen {
    int n;
    catalog_bench b[2];
    char host[2][32];
} bench_seen;

static int collect_bench(const catalog_bench *b, void *user)
{
    bench_seen *v = user;
    if (v->n < 2) {
        v->b[v->n] = *b;
        snprintf(v->host[v->n], 32, "%s", b->host);
    }
    v->n++;
    return 0;
}

FXTEST(benchmarks_round_trip)
{
    OPEN_OK(f);
    catalog_bench b;
    catalog_bench_init(&b);
    b.created_ms = 1700000000000;
    b.host = "lab-pc";
    b.git_rev = "c824a14";
    b.method = "tsm";
    b.params_json = "{\"projections\":18}";
    b.frames = 100;
    b.width = b.height = 200;
    b.scene = "binary";
    b.wall_s = 0.0283;
    b.cpu_s = 0.051;
    b.peak_rss_mb = 61.5;
    b.err_1mc = 0.0123;
    b.sep_err_px = 0.04;
    catalog_bench d = b;
    d.method = "direct";
    d.photons = 1000;
    d.created_ms++;
    CHECK(catalog_bench_insert(f->c, &b, NULL) == SL_OK &&
              catalog_bench_insert(f->c, &d, NULL) == SL_OK, "%s",
          catalog_errmsg(f->c));
    bench_seen v = {0};
    CHECK(catalog_bench_list(f->c, "tsm", 0, collect_bench, &v) == SL_OK &&
              v.n == 1, "by method: %d", v.n);
    const catalog_bench *x = &v.b[0];
    CHECK(!strcmp(v.host[0], "lab-pc") && x->frames == 100 &&
              x->width == 200 && x->height == 200 && isnan(x->photons) &&
              same_dbl(x->wall_s, b.wall_s) && same_dbl(x->cpu_s, b.cpu_s) &&
              same_dbl(x->err_1mc, b.err_1mc) && isnan(x->err_hp) &&
              same_dbl(x->sep_err_px, 0.04) && x->created_ms == b.created_ms,
          "benchmark differs");
    memset(&v, 0, sizeof v);
    CHECK(catalog_bench_list(f->c, NULL, b.created_ms + 1, collect_bench,
                             &v) == SL_OK && v.n == 1 &&
              v.b[0].photons == 1000, "since: %d", v.n);
    d.frames = 0;
    CHECK(catalog_bench_insert(f->c, &d, NULL) == SL_EINVAL, "0 frames");
    CHECK(catalog_integrity_check(f->c) == SL_OK, "%s", catalog_errmsg(f->c));
}

/* ---- time ---- */

TEST(time_format_and_parse_are_inverse)
{
    char buf[CATALOG_TIME_MAX];
    int64_t tm;
    sl_err e;
    catalog_time_format(1714521600000, buf);
    CHECK(!strcmp(buf, "2024-05-01T00:00:00.000Z"), "%s", buf);
    catalog_time_format(-1, buf);
    CHECK(!strcmp(buf, "1969-12-31T23:59:59.999Z"), "%s", buf);
    CHECK(catalog_time_parse("2024-05-01", &tm, &e) == SL_OK &&
              tm == 1714521600000, "date");
    CHECK(catalog_time_parse("1714521600", &tm, &e) == SL_OK &&
              tm == 1714521600000, "unix seconds");
    CHECK(catalog_time_parse("2024-05-01T02:00:00+02:00", &tm, &e) == SL_OK &&
              tm == 1714521600000, "offset");
    uint64_t s = 7;
    for (int i = 0; i < 1000; i++) {
        s = s * 6364136223846793005ULL + 1442695040888963407ULL;
        int64_t want = (int64_t)(s >> 23); /* 0 .. ~2.2e12 ms: to 2039 */
        catalog_time_format(want, buf);
        CHECK(catalog_time_parse(buf, &tm, &e) == SL_OK && tm == want,
              "%lld -> %s -> %lld", (long long)want, buf, (long long)tm);
    }
    CHECK(catalog_time_parse("yesterday", &tm, &e) == SL_EINVAL &&
              strstr(e.msg, "yesterday"), "%s", e.msg);
    CHECK(catalog_time_parse("2024-13-01", &tm, &e) == SL_EINVAL, "month 13");
}

TC_MAIN(TC_CASE(runs_round_trip_and_list),
        TC_CASE(state_machine_allows_exactly_the_legal_transitions),
        TC_CASE(mark_interrupted_flips_only_unfinished_runs),
        TC_CASE(progress_and_file), TC_CASE(foreign_keys_are_enforced),
        TC_CASE(reconstructions_round_trip),
        TC_CASE(screen_statistics_match_the_measurements),
        TC_CASE(benchmarks_round_trip),
        TC_CASE(time_format_and_parse_are_inverse))
