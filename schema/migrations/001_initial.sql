-- 001_initial.sql - the specklab catalogue: screens and their measured r0,
-- masks and their holes, runs with their state machine, reconstructions,
-- benchmarks.
--
-- Conventions (schema/catalog.h repeats them for C callers):
--   * Every time is INTEGER unix milliseconds UTC, in a column named *_ms.
--     Integers sort and compare exactly, need no parsing, and SQLite formats
--     them for people with strftime('%Y-%m-%dT%H:%M:%fZ', t_ms/1000.0,
--     'unixepoch').
--   * Units are in column names (_m, _px, _deg, _mag, _arcsec, _s, _mb).
--   * A metric that is unknown is NULL (the C API maps NULL <-> NaN).
--   * *_json columns hold one JSON value, checked with json_valid().
--   * Every CHECK is named so that a violation says which rule failed.
--
-- This file runs inside the transaction catalog_open opens for it and must
-- end by setting user_version to its own number: that is how the version
-- moves without the C code ever formatting SQL.

PRAGMA application_id = 1397508931; -- 0x534C4B43 "SLKC": a specklab catalogue

CREATE TABLE screens (
    id          INTEGER PRIMARY KEY,
    name        TEXT    NOT NULL UNIQUE
                CONSTRAINT screen_name_nonempty CHECK (length(name) > 0),
    slot        INTEGER CONSTRAINT screen_slot_nonnegative
                CHECK (slot IS NULL OR slot >= 0),  -- NULL: not on the wheel
    description TEXT    NOT NULL DEFAULT '',
    created_ms  INTEGER NOT NULL
);

CREATE TABLE masks (
    id              INTEGER PRIMARY KEY,
    name            TEXT    NOT NULL UNIQUE
                    CONSTRAINT mask_name_nonempty CHECK (length(name) > 0),
    slot            INTEGER CONSTRAINT mask_slot_nonnegative
                    CHECK (slot IS NULL OR slot >= 0),
    kind            TEXT    NOT NULL
                    CONSTRAINT mask_kind_known CHECK (kind IN ('full', 'holes')),
    -- full: the aperture diameter (NULL when unknown); holes: the diameter
    -- of every hole (required).
    diameter_m      REAL    CONSTRAINT mask_diameter_positive
                    CHECK (diameter_m IS NULL OR diameter_m > 0),
    description     TEXT    NOT NULL DEFAULT '',
    created_ms      INTEGER NOT NULL,
    CONSTRAINT mask_holes_have_diameter
        CHECK (kind = 'full' OR diameter_m IS NOT NULL)
);

-- A wheel slot holds one screen and one mask at a time.
CREATE UNIQUE INDEX screens_one_per_slot ON screens (slot)
    WHERE slot IS NOT NULL;
CREATE UNIQUE INDEX masks_one_per_slot ON masks (slot)
    WHERE slot IS NOT NULL;

-- Hole centres in pupil metres (+x east, +y north, as recon/mask.h), in the
-- order the mask file gives them.
CREATE TABLE mask_holes (
    mask_id INTEGER NOT NULL REFERENCES masks(id) ON DELETE CASCADE,
    idx     INTEGER NOT NULL CONSTRAINT hole_idx_nonnegative CHECK (idx >= 0),
    x_m     REAL    NOT NULL,
    y_m     REAL    NOT NULL,
    PRIMARY KEY (mask_id, idx)
) WITHOUT ROWID;

-- The run state machine as data: the C code and the trigger below both read
-- it, so a transition is legal in exactly one place.
CREATE TABLE run_states (
    name     TEXT    PRIMARY KEY,
    terminal INTEGER NOT NULL CHECK (terminal IN (0, 1))
) WITHOUT ROWID;
INSERT INTO run_states (name, terminal) VALUES
    ('queued', 0), ('moving', 0), ('acquiring', 0), ('stored', 0),
    ('reconstructing', 0),
    ('done', 1), ('failed', 1), ('aborted', 1), ('interrupted', 1);

CREATE TABLE run_transitions (
    from_state TEXT NOT NULL REFERENCES run_states(name),
    to_state   TEXT NOT NULL REFERENCES run_states(name),
    PRIMARY KEY (from_state, to_state)
) WITHOUT ROWID;
-- The forward chain; 'stored' may finish without reconstruction.
INSERT INTO run_transitions (from_state, to_state) VALUES
    ('queued', 'moving'), ('moving', 'acquiring'), ('acquiring', 'stored'),
    ('stored', 'reconstructing'), ('stored', 'done'),
    ('reconstructing', 'done');
-- Every non-terminal state may exit to failed, aborted or interrupted.
INSERT INTO run_transitions (from_state, to_state)
    SELECT s.name, x.name FROM run_states AS s, run_states AS x
    WHERE s.terminal = 0 AND x.name IN ('failed', 'aborted', 'interrupted');

CREATE TABLE runs (
    uuid        TEXT    PRIMARY KEY NOT NULL
                CONSTRAINT run_uuid_lowercase CHECK (
                    length(uuid) = 36 AND uuid NOT GLOB '*[^0-9a-f-]*' AND
                    substr(uuid, 9, 1) = '-' AND substr(uuid, 14, 1) = '-' AND
                    substr(uuid, 19, 1) = '-' AND substr(uuid, 24, 1) = '-' AND
                    length(replace(uuid, '-', '')) = 32),
    state       TEXT    NOT NULL DEFAULT 'queued'
                CONSTRAINT run_state_known CHECK (state IN (
                    'queued', 'moving', 'acquiring', 'stored',
                    'reconstructing', 'done', 'failed', 'aborted',
                    'interrupted')),
    exit_reason TEXT,
    created_ms  INTEGER NOT NULL,
    started_ms  INTEGER,           -- first left 'queued'
    ended_ms    INTEGER,           -- reached a terminal state
    updated_ms  INTEGER NOT NULL,  -- last state or progress change
    operator    TEXT    NOT NULL DEFAULT '',
    object      TEXT    NOT NULL DEFAULT '',
    screen_id   INTEGER REFERENCES screens(id) ON DELETE RESTRICT,
    mask_id     INTEGER REFERENCES masks(id) ON DELETE RESTRICT,
    camera_serial        TEXT,
    -- exposure_us, gain, roi, pixel_format, ... as the daemon applied them
    camera_settings_json TEXT CONSTRAINT camera_settings_is_json
                CHECK (camera_settings_json IS NULL OR
                       json_valid(camera_settings_json)),
    frames_requested INTEGER NOT NULL
                CONSTRAINT frames_requested_nonnegative
                CHECK (frames_requested >= 0),
    frames_acquired  INTEGER NOT NULL DEFAULT 0
                CONSTRAINT frames_acquired_in_range
                CHECK (frames_acquired BETWEEN 0 AND frames_requested),
    frames_failed    INTEGER NOT NULL DEFAULT 0
                CONSTRAINT frames_failed_nonnegative CHECK (frames_failed >= 0),
    packets_missing  INTEGER NOT NULL DEFAULT 0
                CONSTRAINT packets_missing_nonnegative
                CHECK (packets_missing >= 0),
    file_path   TEXT,
    file_sha256 TEXT CONSTRAINT file_sha256_hex CHECK (
                    file_sha256 IS NULL OR (length(file_sha256) = 64 AND
                    file_sha256 NOT GLOB '*[^0-9a-f]*')),
    CONSTRAINT run_exit_has_reason CHECK (
        state NOT IN ('failed', 'aborted', 'interrupted') OR
        (exit_reason IS NOT NULL AND length(exit_reason) > 0)),
    CONSTRAINT run_terminal_has_end CHECK (
        state NOT IN ('done', 'failed', 'aborted', 'interrupted') OR
        ended_ms IS NOT NULL)
);

-- The schema itself refuses an illegal state change, whoever writes.
CREATE TRIGGER runs_state_transition
BEFORE UPDATE OF state ON runs
WHEN NOT EXISTS (SELECT 1 FROM run_transitions
                 WHERE from_state = OLD.state AND to_state = NEW.state)
BEGIN
    SELECT RAISE(ABORT, 'illegal run state transition');
END;

-- r0 measured for a screen, usually from a run's own frames; the history
-- answers "how does screen 3 compare with screen 5 over the last month".
CREATE TABLE screen_r0 (
    id            INTEGER PRIMARY KEY,
    screen_id     INTEGER NOT NULL REFERENCES screens(id) ON DELETE CASCADE,
    run_uuid      TEXT    REFERENCES runs(uuid) ON DELETE SET NULL,
    measured_ms   INTEGER NOT NULL,
    r0_m          REAL    NOT NULL CONSTRAINT r0_positive CHECK (r0_m > 0),
    seeing_arcsec REAL    CONSTRAINT seeing_positive
                  CHECK (seeing_arcsec IS NULL OR seeing_arcsec > 0),
    wavelength_m  REAL    NOT NULL
                  CONSTRAINT wavelength_positive CHECK (wavelength_m > 0),
    method        TEXT    NOT NULL
                  CONSTRAINT r0_method_nonempty CHECK (length(method) > 0)
);
CREATE INDEX screen_r0_by_screen_time ON screen_r0 (screen_id, measured_ms);

CREATE TABLE reconstructions (
    id           INTEGER PRIMARY KEY,
    run_uuid     TEXT    NOT NULL REFERENCES runs(uuid) ON DELETE CASCADE,
    method       TEXT    NOT NULL
                 CONSTRAINT recon_method_nonempty CHECK (length(method) > 0),
    params_json  TEXT    CONSTRAINT recon_params_is_json
                 CHECK (params_json IS NULL OR json_valid(params_json)),
    started_ms   INTEGER NOT NULL,
    elapsed_s    REAL    CONSTRAINT recon_elapsed_nonnegative
                 CHECK (elapsed_s IS NULL OR elapsed_s >= 0),
    output_fits  TEXT,
    output_png   TEXT,
    sep_px       REAL,
    sep_err_px   REAL,
    pa_deg       REAL,
    pa_err_deg   REAL,
    dm_mag       REAL,
    dm_err_mag   REAL,
    sep_arcsec   REAL,
    c_cophased   REAL    CONSTRAINT c_cophased_in_range
                 CHECK (c_cophased IS NULL OR c_cophased BETWEEN -1 AND 1),
    quality_json TEXT    CONSTRAINT recon_quality_is_json
                 CHECK (quality_json IS NULL OR json_valid(quality_json))
);

CREATE TABLE benchmarks (
    id          INTEGER PRIMARY KEY,
    created_ms  INTEGER NOT NULL,
    host        TEXT    NOT NULL DEFAULT '',
    git_rev     TEXT    NOT NULL DEFAULT '',
    method      TEXT    NOT NULL
                CONSTRAINT bench_method_nonempty CHECK (length(method) > 0),
    params_json TEXT    CONSTRAINT bench_params_is_json
                CHECK (params_json IS NULL OR json_valid(params_json)),
    frames      INTEGER NOT NULL CONSTRAINT bench_frames_positive
                CHECK (frames > 0),
    width       INTEGER NOT NULL CONSTRAINT bench_width_positive
                CHECK (width > 0),
    height      INTEGER NOT NULL CONSTRAINT bench_height_positive
                CHECK (height > 0),
    photons     REAL,              -- per frame; NULL: noiseless
    scene       TEXT    NOT NULL DEFAULT '',
    wall_s      REAL    NOT NULL CONSTRAINT bench_wall_nonnegative
                CHECK (wall_s >= 0),
    cpu_s       REAL,
    peak_rss_mb REAL,
    err_1mc     REAL,              -- 1 - c against the cophased image
    err_hp      REAL,              -- 1 - c after a high-pass
    sep_err_px  REAL,
    pa_err_deg  REAL,
    dm_err_mag  REAL
);

PRAGMA user_version = 1;
