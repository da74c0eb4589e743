-- 003_run_kind.sql - what a run's frames are for.
--
--   science     the bench's object: reconstructed (the default, and what
--               every run before this migration was);
--   dark        the light blocked (a closed mask slot, the lasers off): the
--               detector's bias and dark current at the run's exposure,
--               subtracted from science frames of the same camera settings;
--   flat        uniform light: the pixels' relative response, divided out
--               (after its own dark) of science frames of the same camera;
--   calibrator  a point source through the same screen and mask: the
--               transfer function for reference-star calibration.
-- Dark and flat runs are never reconstructed.

ALTER TABLE runs ADD COLUMN kind TEXT NOT NULL DEFAULT 'science'
    CONSTRAINT run_kind_known
    CHECK (kind IN ('science', 'dark', 'flat', 'calibrator'));

-- The calibration lookup (catalog_run_find_calibration): by kind and state,
-- nearest in time.
CREATE INDEX runs_by_kind ON runs (kind, state, created_ms);

PRAGMA user_version = 3;
