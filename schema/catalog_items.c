/* catalog_items.c - see catalog.h: phase screens, masks, measured r0 and
 * its statistics, benchmarks.
 */
#include "catalog_int.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* 180 * 3600 / pi. */
#define ARCSEC_PER_RAD 206264.80624709636

/* The id of the row named `name` by statement `id` (CS_SCREEN_ID or
 * CS_MASK_ID); SL_EINVAL "no KIND named NAME" when absent. */
static int find_id(catalog *c, int id, const char *kind, const char *name,
                   int64_t *out)
{
    if (!name)
        return cat_seterr(c, SL_EINVAL, "catalogue %s: no %s name given",
                          c->path, kind);
    sqlite3_stmt *st = cat_stmt(c, id);
    cat_bind_text(st, 1, name);
    int rc = sqlite3_step(st), status = SL_OK;
    if (rc == SQLITE_ROW) {
        if (out)
            *out = cat_col_int64(st, 0);
    } else if (rc == SQLITE_DONE)
        status = cat_seterr(c, SL_EINVAL, "catalogue %s: no %s named '%.64s'",
                            c->path, kind, name);
    else
        status = cat_sqlerr(c, rc, "looking up a name");
    cat_done(st);
    return status;
}

/* Take `slot` away from any other row of the table (a slot holds one screen
 * and one mask), so that the upsert cannot trip the one-per-slot index. */
static int free_slot(catalog *c, int id, int slot, const char *name,
                     const char *what)
{
    if (slot < 0)
        return SL_OK;
    sqlite3_stmt *st = cat_stmt(c, id);
    sqlite3_bind_int(st, 1, slot);
    cat_bind_text(st, 2, name);
    return cat_run(c, st, what);
}

/* ---- screens ---- */

int catalog_screen_upsert(catalog *c, const char *name, int slot,
                          const char *description, int64_t *id_out)
{
    char what[128];
    if (!name || !*name)
        return cat_seterr(c, SL_EINVAL, "catalogue %s: a screen needs a name",
                          c->path);
    snprintf(what, sizeof what, "saving screen '%.64s'", name);
    int rc = cat_begin(c, what);
    if (rc != SL_OK)
        return rc;
    rc = free_slot(c, CS_SCREEN_CLEAR_SLOT, slot, name, what);
    if (rc == SL_OK) {
        sqlite3_stmt *st = cat_stmt(c, CS_SCREEN_UPSERT);
        cat_bind_text(st, 1, name);
        if (slot >= 0)
            sqlite3_bind_int(st, 2, slot);
        cat_bind_text(st, 3, description);
        sqlite3_bind_int64(st, 4, catalog_now_ms());
        rc = cat_run(c, st, what);
    }
    if (rc == SL_OK)
        rc = find_id(c, CS_SCREEN_ID, "screen", name, id_out);
    return cat_end(c, rc, what);
}

int catalog_screen_find(catalog *c, const char *name, int64_t *id_out)
{
    return find_id(c, CS_SCREEN_ID, "screen", name, id_out);
}

/* One row of the screen list, handed to the caller's fn. */
typedef struct screen_each { catalog_screen_fn fn; void *user; } screen_each;

static int screen_row(catalog *c, sqlite3_stmt *st, void *ctx)
{
    const screen_each *e = ctx;
    (void)c;
    catalog_screen s;
    s.id = cat_col_int64(st, 0);
    s.name = cat_col_text(st, 1);
    s.slot = sqlite3_column_type(st, 2) == SQLITE_NULL
                 ? -1
                 : sqlite3_column_int(st, 2);
    s.description = cat_col_text(st, 3);
    s.created_ms = cat_col_int64(st, 4);
    s.last_r0_m = cat_col_double(st, 5);
    s.last_r0_ms = cat_col_int64(st, 6);
    return e->fn(&s, e->user);
}

int catalog_screen_list(catalog *c, catalog_screen_fn fn, void *user)
{
    sqlite3_stmt *st = cat_stmt(c, CS_SCREEN_LIST);
    screen_each e = {fn, user};
    return cat_each(c, st, "listing screens", screen_row, &e);
}

/* ---- masks ---- */

static int mask_check(catalog *c, const catalog_mask *m)
{
    if (!m || !m->name || !*m->name)
        return cat_seterr(c, SL_EINVAL, "catalogue %s: a mask needs a name",
                          c->path);
    if (m->kind == CATALOG_MASK_FULL) {
        if (m->nholes != 0 || (!isnan(m->diameter_m) &&
                               !(isfinite(m->diameter_m) && m->diameter_m > 0)))
            return cat_seterr(c, SL_EINVAL, "catalogue %s: mask '%.64s': a "
                              "full aperture has no holes and a diameter > 0 "
                              "(or NaN)", c->path, m->name);
        return SL_OK;
    }
    if (m->kind != CATALOG_MASK_HOLES)
        return cat_seterr(c, SL_EINVAL, "catalogue %s: mask '%.64s': unknown "
                          "kind %d", c->path, m->name, (int)m->kind);
    if (m->nholes < 2 || m->nholes > CATALOG_MAX_HOLES || !m->x_m || !m->y_m)
        return cat_seterr(c, SL_EINVAL, "catalogue %s: mask '%.64s' has %d "
                          "holes (2..%d)", c->path, m->name, m->nholes,
                          CATALOG_MAX_HOLES);
    if (!(isfinite(m->diameter_m) && m->diameter_m > 0))
        return cat_seterr(c, SL_EINVAL, "catalogue %s: mask '%.64s': hole "
                          "diameter %g is not > 0", c->path, m->name,
                          m->diameter_m);
    for (int i = 0; i < m->nholes; i++)
        if (!isfinite(m->x_m[i]) || !isfinite(m->y_m[i]))
            return cat_seterr(c, SL_EINVAL, "catalogue %s: mask '%.64s': hole "
                              "%d has a non-finite centre", c->path, m->name,
                              i);
    return SL_OK;
}

int catalog_mask_upsert(catalog *c, const catalog_mask *m, int64_t *id_out)
{
    char what[128];
    int64_t id = 0;
    int rc = mask_check(c, m);
    if (rc != SL_OK)
        return rc;
    snprintf(what, sizeof what, "saving mask '%.64s'", m->name);
    rc = cat_begin(c, what);
    if (rc != SL_OK)
        return rc;
    rc = free_slot(c, CS_MASK_CLEAR_SLOT, m->slot, m->name, what);
    if (rc == SL_OK) {
        sqlite3_stmt *st = cat_stmt(c, CS_MASK_UPSERT);
        cat_bind_text(st, 1, m->name);
        if (m->slot >= 0)
            sqlite3_bind_int(st, 2, m->slot);
        cat_bind_text(st, 3, m->kind == CATALOG_MASK_FULL ? "full" : "holes");
        cat_bind_double(st, 4, m->diameter_m);
        cat_bind_text(st, 5, m->description);
        sqlite3_bind_int64(st, 6, catalog_now_ms());
        rc = cat_run(c, st, what);
    }
    if (rc == SL_OK)
        rc = find_id(c, CS_MASK_ID, "mask", m->name, &id);
    if (rc == SL_OK) { /* the holes are replaced as a whole */
        sqlite3_stmt *st = cat_stmt(c, CS_MASK_HOLES_DELETE);
        sqlite3_bind_int64(st, 1, id);
        rc = cat_run(c, st, what);
    }
    for (int i = 0; rc == SL_OK && i < m->nholes; i++) {
        sqlite3_stmt *st = cat_stmt(c, CS_MASK_HOLE_INSERT);
        sqlite3_bind_int64(st, 1, id);
        sqlite3_bind_int(st, 2, i);
        sqlite3_bind_double(st, 3, m->x_m[i]);
        sqlite3_bind_double(st, 4, m->y_m[i]);
        rc = cat_run(c, st, what);
    }
    rc = cat_end(c, rc, what);
    if (rc == SL_OK && id_out)
        *id_out = id;
    return rc;
}

int catalog_mask_find(catalog *c, const char *name, int64_t *id_out)
{
    return find_id(c, CS_MASK_ID, "mask", name, id_out);
}

int catalog_mask_list(catalog *c, catalog_mask_fn fn, void *user)
{
    /* 4 KiB on the stack instead of an allocation per mask. */
    double x[CATALOG_MAX_HOLES], y[CATALOG_MAX_HOLES];
    sqlite3_stmt *st = cat_stmt(c, CS_MASK_LIST);
    int rc, ret = SL_OK;
    while ((rc = sqlite3_step(st)) == SQLITE_ROW) {
        catalog_mask m;
        const char *kind = cat_col_text(st, 3);
        m.id = cat_col_int64(st, 0);
        m.name = cat_col_text(st, 1);
        m.slot = sqlite3_column_type(st, 2) == SQLITE_NULL
                     ? -1
                     : sqlite3_column_int(st, 2);
        m.kind = kind && strcmp(kind, "full") == 0 ? CATALOG_MASK_FULL
                                                  : CATALOG_MASK_HOLES;
        m.diameter_m = cat_col_double(st, 4);
        m.description = cat_col_text(st, 5);
        m.created_ms = cat_col_int64(st, 6);
        m.nholes = 0;
        m.x_m = x;
        m.y_m = y;
        sqlite3_stmt *h = cat_stmt(c, CS_MASK_HOLES);
        sqlite3_bind_int64(h, 1, m.id);
        int hrc;
        while ((hrc = sqlite3_step(h)) == SQLITE_ROW &&
               m.nholes < CATALOG_MAX_HOLES) {
            x[m.nholes] = sqlite3_column_double(h, 0);
            y[m.nholes] = sqlite3_column_double(h, 1);
            m.nholes++;
        }
        if (hrc != SQLITE_DONE)
            ret = hrc == SQLITE_ROW
                      ? cat_seterr(c, SL_ERANGE, "catalogue %s: mask '%s' "
                                   "has more than %d holes", c->path,
                                   m.name ? m.name : "", CATALOG_MAX_HOLES)
                      : cat_sqlerr(c, hrc, "reading mask holes");
        cat_done(h);
        if (ret == SL_OK)
            ret = fn(&m, user);
        if (ret != SL_OK)
            break;
    }
    if (rc != SQLITE_ROW && rc != SQLITE_DONE)
        ret = cat_sqlerr(c, rc, "listing masks");
    cat_done(st);
    return ret;
}

/* ---- measured r0 ---- */

void catalog_r0_init(catalog_r0 *r)
{
    memset(r, 0, sizeof *r);
    r->r0_m = r->seeing_arcsec = r->wavelength_m = r->r0_err_m = NAN;
}

int catalog_r0_add(catalog *c, const catalog_r0 *r, int64_t *id_out)
{
    char run[CATALOG_UUID_LEN + 1], what[128];
    int64_t screen = 0;
    int rc;
    if (!r || !r->method || !*r->method)
        return cat_seterr(c, SL_EINVAL, "catalogue %s: an r0 measurement "
                          "needs a method", c->path);
    if (!(isfinite(r->r0_m) && r->r0_m > 0) ||
        !(isfinite(r->wavelength_m) && r->wavelength_m > 0) ||
        !(isnan(r->seeing_arcsec) ||
          (isfinite(r->seeing_arcsec) && r->seeing_arcsec > 0)) ||
        !(isnan(r->r0_err_m) || (isfinite(r->r0_err_m) && r->r0_err_m >= 0)))
        return cat_seterr(c, SL_EINVAL, "catalogue %s: r0 %g m +- %g at %g m "
                          "(seeing %g arcsec): each must be finite and > 0 "
                          "(the error >= 0, or NaN: not stated)",
                          c->path, r->r0_m, r->r0_err_m, r->wavelength_m, r->seeing_arcsec);
    if (!r->screen_name && !r->run_uuid)
        return cat_seterr(c, SL_EINVAL, "catalogue %s: an r0 measurement "
                          "needs a screen or a run", c->path);
    if (r->run_uuid && (rc = cat_uuid_norm(c, r->run_uuid, run)) != SL_OK)
        return rc;
    /* Seeing FWHM of a Kolmogorov atmosphere: 0.98 lambda / r0. */
    double seeing = isnan(r->seeing_arcsec)
                        ? 0.98 * r->wavelength_m / r->r0_m * ARCSEC_PER_RAD
                        : r->seeing_arcsec;
    snprintf(what, sizeof what, "recording r0 of screen '%.64s'",
             r->screen_name ? r->screen_name : "(the run's)");
    rc = cat_begin(c, what);
    if (rc != SL_OK)
        return rc;
    if (r->screen_name)
        rc = find_id(c, CS_SCREEN_ID, "screen", r->screen_name, &screen);
    else {
        sqlite3_stmt *st = cat_stmt(c, CS_RUN_SCREEN);
        cat_bind_text(st, 1, run);
        int src = sqlite3_step(st);
        if (src == SQLITE_ROW)
            screen = cat_col_int64(st, 0);
        else if (src == SQLITE_DONE)
            rc = cat_seterr(c, SL_EINVAL, "catalogue %s: %s: no run %s in "
                            "the catalogue", c->path, what, run);
        else
            rc = cat_sqlerr(c, src, what);
        cat_done(st);
        if (rc == SL_OK && screen == 0)
            rc = cat_seterr(c, SL_EINVAL, "catalogue %s: run %s has no "
                            "screen to record r0 against", c->path, run);
    }
    if (rc == SL_OK) {
        sqlite3_stmt *st = cat_stmt(c, CS_R0_INSERT);
        sqlite3_bind_int64(st, 1, screen);
        cat_bind_text(st, 2, r->run_uuid ? run : NULL);
        sqlite3_bind_int64(st, 3, cat_time_or_now(r->measured_ms));
        sqlite3_bind_double(st, 4, r->r0_m);
        sqlite3_bind_double(st, 5, seeing);
        sqlite3_bind_double(st, 6, r->wavelength_m);
        cat_bind_text(st, 7, r->method);
        cat_bind_double(st, 8, r->r0_err_m);
        rc = cat_run(c, st, what);
        if (rc != SL_OK && c->last_rc == SQLITE_CONSTRAINT_FOREIGNKEY)
            rc = cat_seterr(c, SL_EINVAL, "catalogue %s: %s: run %s is not "
                            "in the catalogue", c->path, what, run);
    }
    rc = cat_end(c, rc, what);
    if (rc == SL_OK && id_out)
        *id_out = sqlite3_last_insert_rowid(c->db);
    return rc;
}

/* One row of the r0 list, handed to the caller's fn. */
typedef struct r0_each { catalog_r0_fn fn; void *user; } r0_each;

static int r0_row(catalog *c, sqlite3_stmt *st, void *ctx)
{
    const r0_each *e = ctx;
    (void)c;
    catalog_r0 r;
    r.id = cat_col_int64(st, 0);
    r.screen_name = cat_col_text(st, 1);
    r.run_uuid = cat_col_text(st, 2);
    r.measured_ms = cat_col_int64(st, 3);
    r.r0_m = cat_col_double(st, 4);
    r.seeing_arcsec = cat_col_double(st, 5);
    r.wavelength_m = cat_col_double(st, 6);
    r.method = cat_col_text(st, 7);
    r.r0_err_m = cat_col_double(st, 8);
    return e->fn(&r, e->user);
}

int catalog_r0_list(catalog *c, const char *screen_name, int64_t since_ms,
                    catalog_r0_fn fn, void *user)
{
    sqlite3_stmt *st = cat_stmt(c, CS_R0_LIST);
    cat_bind_text(st, 1, screen_name);
    sqlite3_bind_int64(st, 2, since_ms > 0 ? since_ms : INT64_MIN);
    r0_each e = {fn, user};
    return cat_each(c, st, "listing r0 measurements", r0_row, &e);
}

/* Bind the screen and time range shared by the CS_STATS_* statements. */
static sqlite3_stmt *stats_stmt(catalog *c, int id, int64_t screen,
                                int64_t lo, int64_t hi)
{
    sqlite3_stmt *st = cat_stmt(c, id);
    sqlite3_bind_int64(st, 1, screen);
    sqlite3_bind_int64(st, 2, lo);
    sqlite3_bind_int64(st, 3, hi);
    return st;
}

/* The three queries of catalog_screen_stats inside one read transaction,
 * so that a concurrent insert cannot make count, variance and median
 * disagree. */
static int stats_read(catalog *c, int64_t screen, int64_t lo, int64_t hi,
                      catalog_r0_stats *o)
{
    const char *what = "computing screen statistics";
    sqlite3_stmt *st = stats_stmt(c, CS_STATS_AGG, screen, lo, hi);
    int rc = sqlite3_step(st);
    if (rc != SQLITE_ROW) {
        rc = cat_sqlerr(c, rc == SQLITE_DONE ? SQLITE_ERROR : rc, what);
        cat_done(st);
        return rc;
    }
    o->n = sqlite3_column_int(st, 0);
    o->nruns = sqlite3_column_int(st, 1);
    o->r0_mean_m = cat_col_double(st, 2);
    o->r0_min_m = cat_col_double(st, 3);
    o->r0_max_m = cat_col_double(st, 4);
    o->seeing_mean_arcsec = cat_col_double(st, 5);
    o->wavelength_min_m = cat_col_double(st, 6);
    o->wavelength_max_m = cat_col_double(st, 7);
    o->first_ms = cat_col_int64(st, 8);
    o->last_ms = cat_col_int64(st, 9);
    cat_done(st);
    if (o->n >= 2) {
        st = stats_stmt(c, CS_STATS_SUMSQ, screen, lo, hi);
        sqlite3_bind_double(st, 4, o->r0_mean_m);
        rc = sqlite3_step(st);
        if (rc == SQLITE_ROW)
            o->r0_std_m = sqrt(sqlite3_column_double(st, 0) / (o->n - 1));
        rc = rc == SQLITE_ROW ? SL_OK : cat_sqlerr(c, rc, what);
        cat_done(st);
        if (rc != SL_OK)
            return rc;
    }
    if (o->n >= 1) { /* the middle one, or the mean of the middle two */
        st = stats_stmt(c, CS_STATS_MEDIAN, screen, lo, hi);
        sqlite3_bind_int(st, 4, (o->n - 1) / 2);
        sqlite3_bind_int(st, 5, 2 - o->n % 2);
        double sum = 0;
        int k = 0;
        while ((rc = sqlite3_step(st)) == SQLITE_ROW) {
            sum += sqlite3_column_double(st, 0);
            k++;
        }
        rc = rc == SQLITE_DONE ? SL_OK : cat_sqlerr(c, rc, what);
        cat_done(st);
        if (rc != SL_OK)
            return rc;
        o->r0_median_m = k ? sum / k : NAN;
    }
    return SL_OK;
}

int catalog_screen_stats(catalog *c, const char *screen_name, int64_t since_ms,
                         int64_t until_ms, catalog_r0_stats *out)
{
    catalog_r0_stats o;
    memset(&o, 0, sizeof o);
    o.r0_mean_m = o.r0_median_m = o.r0_min_m = o.r0_max_m = o.r0_std_m =
        o.seeing_mean_arcsec = o.wavelength_min_m = o.wavelength_max_m = NAN;
    int rc = find_id(c, CS_SCREEN_ID, "screen", screen_name, &o.screen_id);
    if (rc != SL_OK)
        return rc;
    int64_t lo = since_ms > 0 ? since_ms : INT64_MIN;
    int64_t hi = until_ms > 0 ? until_ms : INT64_MAX;
    rc = cat_run(c, cat_stmt(c, CS_BEGIN_READ), "computing screen statistics");
    if (rc != SL_OK)
        return rc;
    rc = cat_end(c, stats_read(c, o.screen_id, lo, hi, &o),
                 "computing screen statistics");
    if (rc == SL_OK)
        *out = o;
    return rc;
}

/* ---- benchmarks ---- */

void catalog_bench_init(catalog_bench *b)
{
    memset(b, 0, sizeof *b);
    b->photons = b->wall_s = b->cpu_s = b->peak_rss_mb = b->err_1mc =
        b->err_hp = b->sep_err_px = b->pa_err_deg = b->dm_err_mag = NAN;
}

int catalog_bench_insert(catalog *c, const catalog_bench *b, int64_t *id_out)
{
    const char *what = "inserting a benchmark";
    if (!b || !b->method || !*b->method)
        return cat_seterr(c, SL_EINVAL, "catalogue %s: a benchmark needs a "
                          "method", c->path);
    if (!(isfinite(b->wall_s) && b->wall_s >= 0))
        return cat_seterr(c, SL_EINVAL, "catalogue %s: benchmark wall_s %g "
                          "is not a time", c->path, b->wall_s);
    const double m[] = {b->photons, b->cpu_s, b->peak_rss_mb, b->err_1mc,
                        b->err_hp, b->sep_err_px, b->pa_err_deg,
                        b->dm_err_mag};
    int rc = SL_OK;
    for (int i = 0; rc == SL_OK && i < (int)(sizeof m / sizeof m[0]); i++)
        rc = cat_check_metric(c, "a benchmark figure", m[i]);
    if (rc != SL_OK)
        return rc;
    sqlite3_stmt *st = cat_stmt(c, CS_BENCH_INSERT);
    sqlite3_bind_int64(st, 1, cat_time_or_now(b->created_ms));
    cat_bind_text(st, 2, b->host);
    cat_bind_text(st, 3, b->git_rev);
    cat_bind_text(st, 4, b->method);
    cat_bind_text(st, 5, b->params_json);
    sqlite3_bind_int(st, 6, b->frames);
    sqlite3_bind_int(st, 7, b->width);
    sqlite3_bind_int(st, 8, b->height);
    cat_bind_double(st, 9, b->photons);
    cat_bind_text(st, 10, b->scene);
    sqlite3_bind_double(st, 11, b->wall_s);
    for (int i = 1; i < (int)(sizeof m / sizeof m[0]); i++)
        cat_bind_double(st, 11 + i, m[i]); /* cpu_s .. dm_err_mag: 12..18 */
    return cat_insert(c, st, what, id_out);
}

/* One row of the bench list, handed to the caller's fn. */
typedef struct bench_each { catalog_bench_fn fn; void *user; } bench_each;

static int bench_row(catalog *c, sqlite3_stmt *st, void *ctx)
{
    const bench_each *e = ctx;
    (void)c;
    catalog_bench b;
    b.id = cat_col_int64(st, 0);
    b.created_ms = cat_col_int64(st, 1);
    b.host = cat_col_text(st, 2);
    b.git_rev = cat_col_text(st, 3);
    b.method = cat_col_text(st, 4);
    b.params_json = cat_col_text(st, 5);
    b.frames = sqlite3_column_int(st, 6);
    b.width = sqlite3_column_int(st, 7);
    b.height = sqlite3_column_int(st, 8);
    b.photons = cat_col_double(st, 9);
    b.scene = cat_col_text(st, 10);
    b.wall_s = cat_col_double(st, 11);
    b.cpu_s = cat_col_double(st, 12);
    b.peak_rss_mb = cat_col_double(st, 13);
    b.err_1mc = cat_col_double(st, 14);
    b.err_hp = cat_col_double(st, 15);
    b.sep_err_px = cat_col_double(st, 16);
    b.pa_err_deg = cat_col_double(st, 17);
    b.dm_err_mag = cat_col_double(st, 18);
    return e->fn(&b, e->user);
}

int catalog_bench_list(catalog *c, const char *method, int64_t since_ms,
                       catalog_bench_fn fn, void *user)
{
    sqlite3_stmt *st = cat_stmt(c, CS_BENCH_LIST);
    cat_bind_text(st, 1, method);
    sqlite3_bind_int64(st, 2, since_ms > 0 ? since_ms : INT64_MIN);
    bench_each e = {fn, user};
    return cat_each(c, st, "listing benchmarks", bench_row, &e);
}
