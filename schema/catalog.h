/* catalog.h - the specklab catalogue: one SQLite database of phase screens
 * (with their measured r0 history), masks (with their holes), runs (with
 * their state machine), reconstructions and benchmarks.
 *
 * Storage.  WAL journal (readers never block the writer), foreign keys on,
 * synchronous=FULL: every commit is fsynced before it returns, so a run the
 * catalogue calls 'stored' or 'done' survives a power cut along with its
 * fsynced FITS file.  WAL+FULL costs one fsync per commit (about 1-10 ms on
 * a disk); commits here are state changes and progress updates, which the
 * daemon throttles to ~1 Hz, so durability is nearly free.  NORMAL would
 * only save that fsync at the price of losing the last commits on power
 * loss, which is the wrong trade for a record of hours of bench time.
 *
 * Migrations.  schema/migrations/NNN_name.sql, compiled in with GResource
 * and applied in NNN order at open, each in its own BEGIN IMMEDIATE
 * transaction that ends with the script's own `PRAGMA user_version = NNN`
 * (so no SQL is ever formatted in C).  Two processes opening a fresh file
 * at once are safe: the version is re-read inside the transaction.  A file
 * whose user_version is newer than the code's latest migration is refused.
 * Build (the Makefile's job):
 *   glib-compile-resources --generate-source --c-name catalog_res \
 *       --sourcedir=schema --target=$(BUILD)/schema/catalog_res.c \
 *       schema/catalog.gresource.xml
 *   (dependencies for make: the same with --generate-dependencies)
 * and link schema/catalog*.c, that catalog_res.c and common/status.c with
 *   $(pkg-config --cflags --libs sqlite3 gio-2.0 glib-2.0) -lm.
 *
 * SQL.  Every statement is a string literal (schema/catalog_sql.c; the
 * setup PRAGMAs in catalog.c), prepared once at open, with every value bound
 * as a parameter: no SQL is ever built from data.  The only unprepared SQL
 * is the compiled-in migration scripts, run with sqlite3_exec.
 *
 * Times are int64 unix milliseconds UTC (*_ms); 0 means "not yet / none" in
 * results, and an input time <= 0 means "now".  Units are in the names.
 * Unknown metrics are NaN in C and NULL in the database (use the *_init
 * functions, which set every metric to NaN, before filling a struct).
 *
 * Errors.  int status (SL_OK or negative SL_E*) with the message in the
 * handle (catalog_errmsg).  A key that is not in the catalogue (run uuid,
 * screen or mask name) is SL_EINVAL naming it; a violated rule is SL_EINVAL
 * naming the rule (e.g. "CHECK constraint failed: r0_positive"); a database
 * locked by another process for longer than the busy timeout is SL_EIO
 * "catalogue PATH is locked by another process (...)" - never a hang.
 * A failed call changes nothing (every write is one transaction).
 *
 * Threads.  A handle is not shared between threads: open one per thread
 * (WAL lets them read concurrently; writers queue on the busy timeout).
 *
 * Lists call fn(item, user) for each row; the item and its strings are
 * valid only during the call.  fn returns 0 to go on; a non-zero return
 * stops the list, which then returns that value.  fn may call other catalog
 * functions on the same handle, but not the same list function and no
 * writes (the list statement is still reading).
 */
#ifndef SL_CATALOG_H
#define SL_CATALOG_H

#include <stdint.h>

#include "status.h"

typedef struct catalog catalog;

#define CATALOG_UUID_LEN 36
#define CATALOG_BUSY_TIMEOUT_MS 5000
/* = MASK_MAX_HOLES in recon/sim/mask.h. */
#define CATALOG_MAX_HOLES 256
/* "2024-05-01T12:34:56.789Z" and its NUL, with room to spare. */
#define CATALOG_TIME_MAX 32

/* Run states.  Forward: queued -> moving -> acquiring -> stored ->
 * reconstructing -> done (stored -> done when no reconstruction is wanted).
 * Every non-terminal state may exit to failed, aborted or interrupted.
 * done, failed, aborted and interrupted are terminal: they never change.
 * CATALOG_STATE_ANY (0) is only a filter value. */
typedef enum catalog_state {
    CATALOG_STATE_ANY = 0,
    CATALOG_QUEUED,
    CATALOG_MOVING,
    CATALOG_ACQUIRING,
    CATALOG_STORED,
    CATALOG_RECONSTRUCTING,
    CATALOG_DONE,
    CATALOG_FAILED,
    CATALOG_ABORTED,
    CATALOG_INTERRUPTED
} catalog_state;

/* "queued", ...; NULL for CATALOG_STATE_ANY or out of range. */
const char *catalog_state_name(catalog_state s);
/* SL_OK, or SL_EINVAL for a name that is not a state. */
int catalog_state_parse(const char *name, catalog_state *out);
int catalog_state_is_terminal(catalog_state s);

/* ---- opening ---- */

typedef struct catalog_opts {
    int busy_timeout_ms; /* how long a write waits for another writer;
                          * 0: CATALOG_BUSY_TIMEOUT_MS */
} catalog_opts;

/* Open or create the catalogue at path and apply pending migrations.
 * SL_EIO (cannot open, locked, disk), SL_EFORMAT (not an SQLite file or not
 * a specklab catalogue), SL_ERANGE (schema newer than this program). */
int catalog_open(catalog **out, const char *path, sl_err *err);
int catalog_open_opts(catalog **out, const char *path,
                      const catalog_opts *opts, sl_err *err);
void catalog_close(catalog *c); /* NULL is a no-op */
const char *catalog_errmsg(const catalog *c);
/* 1 when the last error was the disk (or the catalogue's quota) running
 * out: SQLITE_FULL, or an I/O error whose OS error is ENOSPC.  The
 * message then says "disk full". */
int catalog_disk_full(const catalog *c);
/* The file's schema version (user_version), or a negative SL_E*. */
int catalog_schema_version(catalog *c);
/* The newest migration compiled in (>= 1), or a negative SL_E*. */
int catalog_schema_latest(void);
/* SL_OK iff PRAGMA integrity_check says "ok"; SL_EDATA with its first
 * complaint otherwise. */
int catalog_integrity_check(catalog *c);

/* ---- time ---- */

int64_t catalog_now_ms(void);
/* "2024-05-01T12:34:56.789Z". */
void catalog_time_format(int64_t t_ms, char buf[CATALOG_TIME_MAX]);
/* ISO-8601 ("2024-05-01T12:00:00Z", with any offset; no offset = UTC),
 * a date ("2024-05-01", midnight UTC) or integer unix seconds ("1714560000").
 * SL_EINVAL naming the text otherwise. */
int catalog_time_parse(const char *text, int64_t *t_ms, sl_err *err);

/* ---- phase screens ---- */

typedef struct catalog_screen {
    int64_t id;
    const char *name;
    int slot;                /* wheel slot, -1 when not on the wheel */
    const char *description;
    int64_t created_ms;
    double last_r0_m;        /* latest measurement, NaN if none */
    int64_t last_r0_ms;      /* its time, 0 if none */
} catalog_screen;
typedef int (*catalog_screen_fn)(const catalog_screen *s, void *user);

/* Create the screen or update its slot and description.  slot < 0: not on
 * the wheel.  description NULL: keep (or "" when new).  A screen that held
 * the slot before loses it (a slot holds one screen).  *id_out may be NULL. */
int catalog_screen_upsert(catalog *c, const char *name, int slot,
                          const char *description, int64_t *id_out);
/* SL_EINVAL "no screen named ..." when absent. */
int catalog_screen_find(catalog *c, const char *name, int64_t *id_out);
/* In slot order, then unslotted screens by name. */
int catalog_screen_list(catalog *c, catalog_screen_fn fn, void *user);

/* ---- masks ---- */

typedef enum catalog_mask_kind {
    CATALOG_MASK_FULL = 1, /* a filled aperture */
    CATALOG_MASK_HOLES     /* an aperture mask of equal circular holes */
} catalog_mask_kind;

typedef struct catalog_mask {
    int64_t id;              /* results only */
    const char *name;
    int slot;                /* -1: not on the wheel */
    catalog_mask_kind kind;
    double diameter_m;       /* FULL: aperture (NaN if unknown);
                              * HOLES: every hole's diameter (required) */
    int nholes;              /* FULL: 0; HOLES: 2..CATALOG_MAX_HOLES */
    const double *x_m;       /* hole centres, pupil metres, +x east */
    const double *y_m;       /* +y north */
    const char *description; /* NULL: keep (or "" when new) */
    int64_t created_ms;      /* results only */
} catalog_mask;
typedef int (*catalog_mask_fn)(const catalog_mask *m, void *user);

/* Create or replace (slot, kind, diameter, holes; description unless NULL)
 * the mask named m->name.  A mask that held the slot before loses it. */
int catalog_mask_upsert(catalog *c, const catalog_mask *m, int64_t *id_out);
int catalog_mask_find(catalog *c, const char *name, int64_t *id_out);
int catalog_mask_list(catalog *c, catalog_mask_fn fn, void *user);

/* ---- runs ---- */

/* What a run's frames are for (003_run_kind.sql says how each is used). */
typedef enum catalog_kind {
    CATALOG_KIND_ANY = 0,      /* only a filter value */
    CATALOG_SCIENCE,
    CATALOG_DARK,
    CATALOG_FLAT,
    CATALOG_CALIBRATOR
} catalog_kind;
/* "science", ...; NULL for CATALOG_KIND_ANY or out of range. */
const char *catalog_kind_name(catalog_kind k);
/* SL_OK, or SL_EINVAL for a name that is not a kind. */
int catalog_kind_parse(const char *name, catalog_kind *out);

typedef struct catalog_run_spec {
    const char *uuid;                 /* NULL: a random (v4) uuid */
    int64_t created_ms;               /* <= 0: now */
    const char *operator_name;        /* NULL: "" */
    const char *object;               /* NULL: "" */
    int64_t screen_id;                /* 0: none */
    int64_t mask_id;                  /* 0: none */
    const char *camera_serial;        /* NULL: unknown */
    const char *camera_settings_json; /* exposure_us, gain, roi, ...; NULL */
    int frames_requested;             /* >= 0 */
    catalog_kind kind;                /* CATALOG_KIND_ANY: science */
} catalog_run_spec;

typedef struct catalog_run {
    char uuid[CATALOG_UUID_LEN + 1];
    catalog_state state;
    char *exit_reason;                /* NULL: none */
    int64_t created_ms;
    int64_t started_ms;               /* left 'queued'; 0: not yet */
    int64_t ended_ms;                 /* reached a terminal state; 0: not */
    int64_t updated_ms;               /* last state or progress change */
    char *operator_name;
    char *object;
    int64_t screen_id;                /* 0: none */
    char *screen_name;                /* NULL: none */
    int64_t mask_id;
    char *mask_name;
    char *camera_serial;
    char *camera_settings_json;
    int frames_requested;
    int frames_acquired;
    int frames_failed;
    int64_t packets_missing;
    char *file_path;
    char *file_sha256;                /* 64 lowercase hex digits, or NULL */
    catalog_kind kind;
} catalog_run;
typedef int (*catalog_run_fn)(const catalog_run *r, void *user);

typedef struct catalog_run_filter {
    catalog_state state; /* CATALOG_STATE_ANY: every state */
    int64_t screen_id;   /* 0: every screen */
    int64_t since_ms;    /* created at or after; 0: ever */
    int limit;           /* 0: no limit */
    catalog_kind kind;   /* CATALOG_KIND_ANY: every kind */
} catalog_run_filter;

/* Insert a run in state 'queued'; uuid_out (may be NULL) receives its uuid
 * in lowercase.  SL_EINVAL for a malformed uuid, an existing uuid, an
 * unknown screen/mask id, invalid JSON or a negative frame count. */
int catalog_run_insert(catalog *c, const catalog_run_spec *spec,
                       char uuid_out[CATALOG_UUID_LEN + 1]);
/* Move the run to state `to` if run_transitions allows it; reason is
 * required for failed/aborted/interrupted, optional otherwise.  Sets
 * started_ms on first leaving queued, ended_ms on reaching a terminal state.
 * An illegal transition is SL_EINVAL naming both states and the legal ones,
 * and changes nothing. */
int catalog_run_set_state(catalog *c, const char *uuid, catalog_state to,
                          const char *reason);
/* Progress counters of a non-terminal run (SL_EINVAL once terminal: the
 * daemon writes its final counts before the final state). */
int catalog_run_update_progress(catalog *c, const char *uuid,
                                int frames_acquired, int frames_failed,
                                int64_t packets_missing);
/* Record the cube's path and SHA-256 (NULL: not known yet) in any state: a
 * partial cube of a failed or interrupted run is catalogued too. */
int catalog_run_set_file(catalog *c, const char *uuid, const char *path,
                         const char *sha256_hex);
/* Fill *out with owned copies; release with catalog_run_clear.  Uuids are
 * matched case-insensitively. */
int catalog_run_get(catalog *c, const char *uuid, catalog_run *out);
void catalog_run_clear(catalog_run *r);
/* The one run whose uuid starts with prefix (>= 4 hex digits and dashes).
 * SL_EINVAL when none or several match. */
int catalog_run_resolve(catalog *c, const char *prefix,
                        char uuid_out[CATALOG_UUID_LEN + 1]);
/* Newest first (by creation time, runs created in the same millisecond by
 * insertion order: three queued in one ms came out in uuid order); filter
 * NULL: every run. */
int catalog_run_list(catalog *c, const catalog_run_filter *filter,
                     catalog_run_fn fn, void *user);
/* The calibration run for run `uuid`: of kind `kind`, done, with a cube,
 * from the same camera (serial) with the same pixel format and region of
 * interest; for a dark the same exposure_us too, for a calibrator the same
 * screen and mask; of those the nearest in time (darks drift with
 * temperature, seeing with the hour).  SL_OK with its uuid in
 * uuid_out, SL_EEND when there is none (not an error: calibration is
 * optional), SL_EINVAL for an unknown run. */
int catalog_run_find_calibration(catalog *c, const char *uuid, catalog_kind kind,
                                 char uuid_out[CATALOG_UUID_LEN + 1]);
/* On daemon start: every run in a non-terminal state becomes 'interrupted'
 * with reason "daemon restarted while <state>".  Returns how many (>= 0) or
 * a negative SL_E*. */
int catalog_runs_mark_interrupted(catalog *c);

/* ---- reconstructions ---- */

typedef struct catalog_recon {
    int64_t id;              /* results only */
    const char *run_uuid;
    const char *method;      /* "tsm", "direct", ... */
    const char *params_json; /* NULL ok */
    int64_t started_ms;      /* <= 0: now */
    double elapsed_s;
    const char *output_fits;
    const char *output_png;
    double sep_px, sep_err_px;
    double pa_deg, pa_err_deg;
    double dm_mag, dm_err_mag;
    double sep_arcsec;
    double c_cophased;       /* NaN when there is no cophased reference */
    const char *quality_json;
} catalog_recon;
typedef int (*catalog_recon_fn)(const catalog_recon *r, void *user);

/* Zero everything and set every metric to NaN (unknown). */
void catalog_recon_init(catalog_recon *r);
/* SL_EINVAL "run ... is not in the catalogue" for an unknown run (the
 * foreign key refuses it). */
int catalog_recon_insert(catalog *c, const catalog_recon *r, int64_t *id_out);
/* Oldest first. */
int catalog_recon_list(catalog *c, const char *run_uuid, catalog_recon_fn fn,
                       void *user);

/* ---- measured r0 ---- */

typedef struct catalog_r0 {
    int64_t id;              /* results only */
    const char *screen_name; /* insert: NULL = the run's screen */
    const char *run_uuid;    /* NULL: not from a run */
    int64_t measured_ms;     /* <= 0: now */
    double r0_m;             /* at wavelength_m */
    double seeing_arcsec;    /* NaN on insert: 0.98 wavelength / r0 */
    double wavelength_m;
    const char *method;      /* "stf", "image-motion", ... */
    double r0_err_m;         /* 1-sigma, at wavelength_m; NaN: not stated */
} catalog_r0;
typedef int (*catalog_r0_fn)(const catalog_r0 *r, void *user);

void catalog_r0_init(catalog_r0 *r);
int catalog_r0_add(catalog *c, const catalog_r0 *r, int64_t *id_out);
/* Oldest first; screen_name NULL: every screen. */
int catalog_r0_list(catalog *c, const char *screen_name, int64_t since_ms,
                    catalog_r0_fn fn, void *user);

/* r0 statistics of one screen over [since_ms, until_ms] (until_ms 0: no
 * end).  r0 scales as wavelength^(6/5): the figures are of r0 as measured,
 * so compare screens at one wavelength (wavelength_min_m == _max_m). */
typedef struct catalog_r0_stats {
    int64_t screen_id;
    int n;                   /* measurements */
    int nruns;               /* distinct runs among them */
    double r0_mean_m, r0_median_m, r0_min_m, r0_max_m; /* NaN when n == 0 */
    double r0_std_m;         /* sample (n - 1) deviation; NaN when n < 2 */
    double seeing_mean_arcsec;
    double wavelength_min_m, wavelength_max_m;
    int64_t first_ms, last_ms; /* 0 when n == 0 */
} catalog_r0_stats;

int catalog_screen_stats(catalog *c, const char *screen_name, int64_t since_ms,
                         int64_t until_ms, catalog_r0_stats *out);

/* ---- benchmarks ---- */

typedef struct catalog_bench {
    int64_t id;              /* results only */
    int64_t created_ms;      /* <= 0: now */
    const char *host, *git_rev;
    const char *method;
    const char *params_json;
    int frames, width, height;
    double photons;          /* per frame; NaN: noiseless */
    const char *scene;
    double wall_s, cpu_s, peak_rss_mb;
    double err_1mc, err_hp;  /* 1 - c, plain and high-passed */
    double sep_err_px, pa_err_deg, dm_err_mag;
} catalog_bench;
typedef int (*catalog_bench_fn)(const catalog_bench *b, void *user);

void catalog_bench_init(catalog_bench *b);
int catalog_bench_insert(catalog *c, const catalog_bench *b, int64_t *id_out);
/* Oldest first; method NULL: every method. */
int catalog_bench_list(catalog *c, const char *method, int64_t since_ms,
                       catalog_bench_fn fn, void *user);

#endif
