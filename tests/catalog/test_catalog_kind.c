/* test_catalog_kind.c - run kinds (003_run_kind.sql) and the calibration
 * lookup (catalog_run_find_calibration): the kind round-trips and filters,
 * the CHECK refuses an unknown kind written behind the API's back, a
 * version-2 catalogue's runs become science runs, and the lookup picks
 * exactly the run catalog.h promises (same camera, format, ROI, a dark's
 * exposure, a calibrator's screen and mask; done, with a file; nearest in
 * time) against a brute-force reading of the same rule; an r0's error
 * (004_r0_error.sql) round-trips, unknown as NULL, negative refused.
 */
#include "catalog_fx.h"

#include <glib.h>

typedef struct cal_run {
    catalog_kind kind;
    const char *serial;
    double exposure_us;
    const char *roi;      /* JSON text or NULL */
    int64_t created_ms;
    int done, has_file;
    int64_t screen_id, mask_id;
    char uuid[CATALOG_UUID_LEN + 1];
} cal_run;

static int add_run(catalog *c, cal_run *r)
{
    char settings[160];
    snprintf(settings, sizeof settings,
             "{\"exposure_us\":%.17g,\"pixel_format\":\"Mono16\"%s%s}",
             r->exposure_us, r->roi ? ",\"roi\":" : "", r->roi ? r->roi : "");
    catalog_run_spec spec = {.created_ms = r->created_ms, .camera_serial = r->serial,
                             .camera_settings_json = settings, .frames_requested = 10,
                             .kind = r->kind, .screen_id = r->screen_id,
                             .mask_id = r->mask_id};
    int rc = catalog_run_insert(c, &spec, r->uuid);
    static const catalog_state chain[] = {CATALOG_MOVING, CATALOG_ACQUIRING,
                                          CATALOG_STORED, CATALOG_DONE};
    for (int i = 0; rc == SL_OK && r->done && i < 4; i++)
        rc = catalog_run_set_state(c, r->uuid, chain[i], NULL);
    if (rc == SL_OK && r->has_file)
        rc = catalog_run_set_file(c, r->uuid, "runs/x.fits", NULL);
    return rc;
}

/* The rule of catalog.h, read independently of the SQL. */
static int matches(const cal_run *sci, const cal_run *cal, catalog_kind kind)
{
    if (cal == sci || cal->kind != kind || !cal->done || !cal->has_file)
        return 0;
    if (g_strcmp0(cal->serial, sci->serial) || g_strcmp0(cal->roi, sci->roi))
        return 0;
    if (kind == CATALOG_DARK && cal->exposure_us != sci->exposure_us)
        return 0;
    if (kind == CATALOG_CALIBRATOR &&
        (cal->screen_id != sci->screen_id || cal->mask_id != sci->mask_id))
        return 0;
    return 1;
}

static int64_t dist(int64_t a, int64_t b) { return a > b ? a - b : b - a; }

static int count(const catalog_run *r, void *u)
{
    (void)r;
    ++*(int *)u;
    return SL_OK;
}

FXTEST(kinds_round_trip_filter_and_are_checked)
{
    OPEN_OK(f);
    catalog_kind kinds[] = {CATALOG_KIND_ANY, CATALOG_SCIENCE, CATALOG_DARK,
                            CATALOG_FLAT, CATALOG_CALIBRATOR};
    char uuid[5][CATALOG_UUID_LEN + 1];
    for (int i = 0; i < 5; i++) {
        catalog_run_spec spec = {.frames_requested = 3, .kind = kinds[i]};
        CHECK(catalog_run_insert(f->c, &spec, uuid[i]) == SL_OK, "%s", catalog_errmsg(f->c));
    }
    for (int i = 0; i < 5; i++) {
        catalog_run r;
        CHECK(catalog_run_get(f->c, uuid[i], &r) == SL_OK, "%s", catalog_errmsg(f->c));
        catalog_kind want = kinds[i] ? kinds[i] : CATALOG_SCIENCE;
        CHECK(r.kind == want, "run %d kind %d, want %d", i, r.kind, want);
        catalog_run_clear(&r);
        catalog_kind back;
        CHECK(i == 0 || (catalog_kind_parse(catalog_kind_name(kinds[i]), &back) == SL_OK &&
                         back == kinds[i]), "name round trip %d", i);
    }
    catalog_kind k;
    CHECK(catalog_kind_parse("bias", &k) == SL_EINVAL, "bias is not a kind");
    catalog_run_spec bad = {.kind = (catalog_kind)42};
    CHECK(catalog_run_insert(f->c, &bad, NULL) == SL_EINVAL &&
          strstr(catalog_errmsg(f->c), "kind"), "%s", catalog_errmsg(f->c));
    CHECK(raw_exec(f->path, "UPDATE runs SET kind = 'bias'") != SQLITE_OK,
          "the CHECK let an unknown kind in");
    CHECK(raw_int(f->path, "SELECT count(*) FROM runs WHERE kind = 'bias'") == 0, "bias row");
    int n = 0;
    catalog_run_filter flt = {.kind = CATALOG_DARK};
    CHECK(catalog_run_list(f->c, &flt, count, &n) == SL_OK && n == 1, "%d dark runs", n);
    n = 0;
    flt.kind = CATALOG_SCIENCE;
    CHECK(catalog_run_list(f->c, &flt, count, &n) == SL_OK && n == 2, "%d science runs", n);
}

FXTEST(version_2_runs_become_science_runs)
{
    OPEN_OK(f);
    char uuid[CATALOG_UUID_LEN + 1];
    catalog_run_spec spec = {.frames_requested = 3};
    CHECK(catalog_run_insert(f->c, &spec, uuid) == SL_OK, "%s", catalog_errmsg(f->c));
    catalog_close(f->c);
    f->c = NULL;
    /* back to version 2 as an old daemon left it: no kind column */
    CHECK(raw_exec(f->path, "DROP INDEX runs_by_kind; ALTER TABLE runs DROP COLUMN kind; "
                            "ALTER TABLE screen_r0 DROP COLUMN r0_err_m; "
                            "PRAGMA user_version = 2") == SQLITE_OK, "downgrade");
    CHECK(raw_int(f->path, "SELECT count(*) FROM pragma_table_info('runs') "
                           "WHERE name = 'kind'") == 0, "kind still there");
    OPEN_OK(f);
    CHECK(catalog_schema_version(f->c) >= 3, "version %d", catalog_schema_version(f->c));
    catalog_run r;
    CHECK(catalog_run_get(f->c, uuid, &r) == SL_OK && r.kind == CATALOG_SCIENCE,
          "old run's kind %d", r.kind);
    catalog_run_clear(&r);
}

FXTEST(calibration_lookup_follows_the_rule)
{
    OPEN_OK(f);
    int64_t scr[2], msk[2];
    for (int i = 0; i < 2; i++) {
        char name[16];
        snprintf(name, sizeof name, "s%d", i);
        CHECK(catalog_screen_upsert(f->c, name, i, NULL, &scr[i]) == SL_OK, "%s",
              catalog_errmsg(f->c));
        catalog_mask m = {.name = name, .slot = i, .kind = CATALOG_MASK_FULL,
                          .diameter_m = NAN};
        CHECK(catalog_mask_upsert(f->c, &m, &msk[i]) == SL_OK, "%s", catalog_errmsg(f->c));
    }
    /* Random runs around a few science runs; every lookup is compared with
     * the brute-force answer (ties in time broken towards the newer). */
    enum { N = 60 };
    cal_run runs[N];
    const char *serials[] = {"A", "B"}, *rois[] = {NULL, "[0,0,64,64]"};
    const double exps[] = {1000, 2000};
    guint32 s = 11;
    for (int i = 0; i < N; i++) {
        s = s * 1664525u + 1013904223u;
        cal_run *r = &runs[i];
        memset(r, 0, sizeof *r);
        r->kind = i < 6 ? CATALOG_SCIENCE : (catalog_kind)(CATALOG_SCIENCE + 1 + (s >> 8) % 3);
        r->serial = serials[(s >> 11) & 1];
        r->roi = rois[(s >> 12) & 1];
        r->exposure_us = exps[(s >> 13) & 1];
        r->created_ms = 1700000000000 + (int64_t)((s >> 14) % 100000) * 1000 + i;
        r->done = i < 6 || ((s >> 4) & 3) != 0;
        r->has_file = i < 6 || ((s >> 6) & 7) != 0;
        r->screen_id = scr[(s >> 9) & 1];
        r->mask_id = msk[(s >> 10) & 1];
        CHECK(add_run(f->c, r) == SL_OK, "run %d: %s", i, catalog_errmsg(f->c));
    }
    int found = 0;
    for (int i = 0; i < 6; i++)
        for (catalog_kind k = CATALOG_DARK; k <= CATALOG_CALIBRATOR; k++) {
            const cal_run *best = NULL;
            for (int j = 0; j < N; j++) {
                const cal_run *c = &runs[j];
                if (!matches(&runs[i], c, k))
                    continue;
                int64_t d = dist(c->created_ms, runs[i].created_ms);
                int64_t db = best ? dist(best->created_ms, runs[i].created_ms) : 0;
                if (!best || d < db || (d == db && c->created_ms > best->created_ms))
                    best = c;
            }
            char got[CATALOG_UUID_LEN + 1] = "";
            int rc = catalog_run_find_calibration(f->c, runs[i].uuid, k, got);
            if (best) {
                found++;
                CHECK(rc == SL_OK && !strcmp(got, best->uuid), "run %d %s: got %s (%d), "
                      "want %s", i, catalog_kind_name(k), got, rc, best->uuid);
            } else {
                CHECK(rc == SL_EEND, "run %d %s: got %s (%d), want none", i,
                      catalog_kind_name(k), got, rc);
            }
        }
    CHECK(found >= 6, "only %d lookups had an answer: the test data is too thin", found);
    char got[CATALOG_UUID_LEN + 1];
    CHECK(catalog_run_find_calibration(f->c, runs[0].uuid, CATALOG_SCIENCE, got) == SL_EINVAL,
          "science is not a calibration kind");
    CHECK(catalog_run_find_calibration(f->c, "00000000-0000-4000-8000-000000000000",
                                       CATALOG_DARK, got) == SL_EINVAL &&
          strstr(catalog_errmsg(f->c), "no run"), "%s", catalog_errmsg(f->c));
}

static int last_r0(const catalog_r0 *r, void *user)
{
    *(catalog_r0 *)user = *r;   /* strings unused after the call */
    return SL_OK;
}

FXTEST(r0_error_round_trips)
{
    OPEN_OK(f);
    CHECK(catalog_screen_upsert(f->c, "s", 1, NULL, NULL) == SL_OK, "%s", catalog_errmsg(f->c));
    catalog_r0 m, got;
    catalog_r0_init(&m);
    m.screen_name = "s", m.method = "image-motion", m.r0_m = 0.2, m.wavelength_m = 633e-9;
    CHECK(catalog_r0_add(f->c, &m, NULL) == SL_OK, "%s", catalog_errmsg(f->c));
    CHECK(catalog_r0_list(f->c, "s", 0, last_r0, &got) == SL_OK && isnan(got.r0_err_m),
          "no error stated: %g", got.r0_err_m);
    CHECK(raw_int(f->path, "SELECT count(*) FROM screen_r0 WHERE r0_err_m IS NULL") == 1,
          "not NULL in the file");
    m.r0_err_m = 0.034;
    m.measured_ms = catalog_now_ms() + 1000;
    CHECK(catalog_r0_add(f->c, &m, NULL) == SL_OK, "%s", catalog_errmsg(f->c));
    CHECK(catalog_r0_list(f->c, "s", 0, last_r0, &got) == SL_OK && got.r0_err_m == 0.034,
          "error %g, stored 0.034", got.r0_err_m);
    m.r0_err_m = -0.01;
    CHECK(catalog_r0_add(f->c, &m, NULL) == SL_EINVAL && strstr(catalog_errmsg(f->c), "error"),
          "a negative error: %s", catalog_errmsg(f->c));
}

TC_MAIN(TC_CASE(kinds_round_trip_filter_and_are_checked), TC_CASE(r0_error_round_trips),
        TC_CASE(version_2_runs_become_science_runs),
        TC_CASE(calibration_lookup_follows_the_rule))
