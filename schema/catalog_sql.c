/* catalog_sql.c - every SQL statement of the catalogue, as literals.
 *
 * All values travel as bound parameters (?N).  RUN_COLS is pasted by the
 * compiler, so each entry is still one constant string: nothing here is
 * ever built at run time.  The column order of RUN_COLS is what
 * catalog_runs.c's run_from_row reads.
 */
#include "catalog_int.h"

#define RUN_COLS                                                              \
    "r.uuid, r.state, r.exit_reason, r.created_ms, r.started_ms, "           \
    "r.ended_ms, r.updated_ms, r.operator, r.object, r.screen_id, s.name, "  \
    "r.mask_id, m.name, r.camera_serial, r.camera_settings_json, "           \
    "r.frames_requested, r.frames_acquired, r.frames_failed, "               \
    "r.packets_missing, r.file_path, r.file_sha256, r.kind "                 \
    "FROM runs AS r LEFT JOIN screens AS s ON s.id = r.screen_id "           \
    "LEFT JOIN masks AS m ON m.id = r.mask_id "

#define R0_RANGE                                                              \
    "FROM screen_r0 WHERE screen_id = ?1 AND measured_ms BETWEEN ?2 AND ?3 "

const char *const cat_sql[CS_COUNT] = {
    [CS_BEGIN] = "BEGIN IMMEDIATE",
    /* A read snapshot (WAL): takes no lock that blocks a writer. */
    [CS_BEGIN_READ] = "BEGIN DEFERRED",
    [CS_COMMIT] = "COMMIT",
    [CS_ROLLBACK] = "ROLLBACK",
    [CS_USER_VERSION] = "PRAGMA user_version",
    [CS_APPLICATION_ID] = "PRAGMA application_id",
    [CS_OBJECT_COUNT] = "SELECT count(*) FROM sqlite_master",
    [CS_INTEGRITY] = "PRAGMA integrity_check",

    [CS_SCREEN_CLEAR_SLOT] =
        "UPDATE screens SET slot = NULL WHERE slot = ?1 AND name <> ?2",
    [CS_SCREEN_UPSERT] =
        "INSERT INTO screens (name, slot, description, created_ms) "
        "VALUES (?1, ?2, coalesce(?3, ''), ?4) "
        "ON CONFLICT (name) DO UPDATE SET slot = excluded.slot, "
        "description = coalesce(?3, screens.description)",
    [CS_SCREEN_ID] = "SELECT id FROM screens WHERE name = ?1",
    [CS_SCREEN_LIST] =
        "SELECT s.id, s.name, s.slot, s.description, s.created_ms, "
        "r.r0_m, r.measured_ms FROM screens AS s "
        "LEFT JOIN screen_r0 AS r ON r.id = (SELECT id FROM screen_r0 "
        "WHERE screen_id = s.id ORDER BY measured_ms DESC, id DESC LIMIT 1) "
        "ORDER BY s.slot IS NULL, s.slot, s.name",

    [CS_MASK_CLEAR_SLOT] =
        "UPDATE masks SET slot = NULL WHERE slot = ?1 AND name <> ?2",
    [CS_MASK_UPSERT] =
        "INSERT INTO masks (name, slot, kind, diameter_m, description, "
        "created_ms) VALUES (?1, ?2, ?3, ?4, coalesce(?5, ''), ?6) "
        "ON CONFLICT (name) DO UPDATE SET slot = excluded.slot, "
        "kind = excluded.kind, diameter_m = excluded.diameter_m, "
        "description = coalesce(?5, masks.description)",
    [CS_MASK_ID] = "SELECT id FROM masks WHERE name = ?1",
    [CS_MASK_HOLES_DELETE] = "DELETE FROM mask_holes WHERE mask_id = ?1",
    [CS_MASK_HOLE_INSERT] =
        "INSERT INTO mask_holes (mask_id, idx, x_m, y_m) "
        "VALUES (?1, ?2, ?3, ?4)",
    [CS_MASK_LIST] =
        "SELECT id, name, slot, kind, diameter_m, description, created_ms "
        "FROM masks ORDER BY slot IS NULL, slot, name",
    [CS_MASK_HOLES] =
        "SELECT x_m, y_m FROM mask_holes WHERE mask_id = ?1 ORDER BY idx",

    [CS_RUN_INSERT] =
        "INSERT INTO runs (uuid, created_ms, updated_ms, operator, object, "
        "screen_id, mask_id, camera_serial, camera_settings_json, "
        "frames_requested, kind) VALUES (?1, ?2, ?2, coalesce(?3, ''), "
        "coalesce(?4, ''), ?5, ?6, ?7, ?8, ?9, ?10)",
    [CS_RUN_EXISTS] = "SELECT 1 FROM runs WHERE uuid = ?1",
    [CS_RUN_STATE] = "SELECT state FROM runs WHERE uuid = ?1",
    [CS_TRANSITION_OK] =
        "SELECT 1 FROM run_transitions WHERE from_state = ?1 AND to_state = ?2",
    [CS_TRANSITIONS_FROM] =
        "SELECT to_state FROM run_transitions WHERE from_state = ?1 "
        "ORDER BY to_state",
    /* started_ms: the first move to a non-terminal state after 'queued';
     * ended_ms: the move to a terminal state. */
    [CS_RUN_SET_STATE] =
        "UPDATE runs SET state = ?2, exit_reason = ?3, updated_ms = ?4, "
        "started_ms = CASE WHEN started_ms IS NULL AND "
        "(SELECT terminal FROM run_states WHERE name = ?2) = 0 "
        "THEN ?4 ELSE started_ms END, "
        "ended_ms = CASE WHEN (SELECT terminal FROM run_states "
        "WHERE name = ?2) = 1 THEN ?4 ELSE ended_ms END "
        "WHERE uuid = ?1",
    [CS_RUN_PROGRESS] =
        "UPDATE runs SET frames_acquired = ?2, frames_failed = ?3, "
        "packets_missing = ?4, updated_ms = ?5 WHERE uuid = ?1",
    [CS_RUN_SET_FILE] =
        "UPDATE runs SET file_path = ?2, file_sha256 = ?3, updated_ms = ?4 "
        "WHERE uuid = ?1",
    [CS_RUN_GET] = "SELECT " RUN_COLS "WHERE r.uuid = ?1",
    [CS_RUN_LIST] =
        "SELECT " RUN_COLS "WHERE (?1 IS NULL OR r.state = ?1) "
        "AND (?2 IS NULL OR r.screen_id = ?2) AND r.created_ms >= ?3 "
        "AND (?5 IS NULL OR r.kind = ?5) "
        "ORDER BY r.created_ms DESC, r.rowid DESC LIMIT ?4",
    /* catalog.h says which run calibrates which: `IS` so that two unknown
     * (NULL) settings match; the ROI compares as JSON text, written by one
     * function (dispatch.c's settings_json). */
    [CS_RUN_CALIBRATION] =
        "SELECT c.uuid FROM runs AS s JOIN runs AS c ON c.kind = ?2 "
        "AND c.state = 'done' AND c.file_path IS NOT NULL AND c.uuid <> s.uuid "
        "AND c.camera_serial IS s.camera_serial "
        "AND json_extract(c.camera_settings_json, '$.pixel_format') IS "
        "json_extract(s.camera_settings_json, '$.pixel_format') "
        "AND json_extract(c.camera_settings_json, '$.roi') IS "
        "json_extract(s.camera_settings_json, '$.roi') "
        "AND (?2 <> 'dark' OR json_extract(c.camera_settings_json, "
        "'$.exposure_us') IS json_extract(s.camera_settings_json, '$.exposure_us')) "
        "AND (?2 <> 'calibrator' OR (c.screen_id IS s.screen_id AND "
        "c.mask_id IS s.mask_id)) "
        "WHERE s.uuid = ?1 "
        "ORDER BY abs(c.created_ms - s.created_ms), c.created_ms DESC LIMIT 1",
    /* ?1 is checked to be hex digits and dashes, so substr is exact. */
    [CS_RUN_RESOLVE] =
        "SELECT uuid FROM runs WHERE substr(uuid, 1, length(?1)) = ?1 "
        "ORDER BY uuid LIMIT 2",
    /* The right-hand `state` is the row's state before the update. */
    [CS_RUNS_INTERRUPT] =
        "UPDATE runs SET state = 'interrupted', exit_reason = ?1 || state, "
        "ended_ms = ?2, updated_ms = ?2 "
        "WHERE state IN (SELECT name FROM run_states WHERE terminal = 0)",
    [CS_RUN_SCREEN] = "SELECT screen_id FROM runs WHERE uuid = ?1",

    [CS_RECON_INSERT] =
        "INSERT INTO reconstructions (run_uuid, method, params_json, "
        "started_ms, elapsed_s, output_fits, output_png, sep_px, sep_err_px, "
        "pa_deg, pa_err_deg, dm_mag, dm_err_mag, sep_arcsec, c_cophased, "
        "quality_json) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, "
        "?12, ?13, ?14, ?15, ?16)",
    [CS_RECON_LIST] =
        "SELECT id, run_uuid, method, params_json, started_ms, elapsed_s, "
        "output_fits, output_png, sep_px, sep_err_px, pa_deg, pa_err_deg, "
        "dm_mag, dm_err_mag, sep_arcsec, c_cophased, quality_json "
        "FROM reconstructions WHERE run_uuid = ?1 ORDER BY started_ms, id",

    [CS_R0_INSERT] =
        "INSERT INTO screen_r0 (screen_id, run_uuid, measured_ms, r0_m, "
        "seeing_arcsec, wavelength_m, method, r0_err_m) "
        "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)",
    [CS_R0_LIST] =
        "SELECT r.id, s.name, r.run_uuid, r.measured_ms, r.r0_m, "
        "r.seeing_arcsec, r.wavelength_m, r.method, r.r0_err_m "
        "FROM screen_r0 AS r JOIN screens AS s ON s.id = r.screen_id "
        "WHERE (?1 IS NULL OR s.name = ?1) AND r.measured_ms >= ?2 "
        "ORDER BY r.measured_ms, r.id",
    [CS_STATS_AGG] =
        "SELECT count(*), count(DISTINCT run_uuid), avg(r0_m), min(r0_m), "
        "max(r0_m), avg(seeing_arcsec), min(wavelength_m), max(wavelength_m), "
        "min(measured_ms), max(measured_ms) " R0_RANGE,
    /* Two-pass variance: the mean from CS_STATS_AGG is bound as ?4, which
     * avoids the cancellation of sum(x^2) - n mean^2. */
    [CS_STATS_SUMSQ] = "SELECT sum((r0_m - ?4) * (r0_m - ?4)) " R0_RANGE,
    [CS_STATS_MEDIAN] =
        "SELECT r0_m " R0_RANGE "ORDER BY r0_m LIMIT ?5 OFFSET ?4",

    [CS_BENCH_INSERT] =
        "INSERT INTO benchmarks (created_ms, host, git_rev, method, "
        "params_json, frames, width, height, photons, scene, wall_s, cpu_s, "
        "peak_rss_mb, err_1mc, err_hp, sep_err_px, pa_err_deg, dm_err_mag) "
        "VALUES (?1, coalesce(?2, ''), coalesce(?3, ''), ?4, ?5, ?6, ?7, ?8, "
        "?9, coalesce(?10, ''), ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18)",
    [CS_BENCH_LIST] =
        "SELECT id, created_ms, host, git_rev, method, params_json, frames, "
        "width, height, photons, scene, wall_s, cpu_s, peak_rss_mb, err_1mc, "
        "err_hp, sep_err_px, pa_err_deg, dm_err_mag FROM benchmarks "
        "WHERE (?1 IS NULL OR method = ?1) AND created_ms >= ?2 "
        "ORDER BY created_ms, id",
};
