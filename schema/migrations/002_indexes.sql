-- 002_indexes.sql - the indexes the daemon's and the CLI's queries use.
-- A separate migration so that upgrading a version-1 catalogue is exercised
-- by the tests (the indexes must appear, in order, after 001's tables).

-- catalog_run_list: newest first, optionally by state or screen.
CREATE INDEX runs_by_created ON runs (created_ms);
CREATE INDEX runs_by_state ON runs (state, created_ms);
CREATE INDEX runs_by_screen ON runs (screen_id, created_ms);
-- Foreign-key children: without these, deleting a parent scans the child.
CREATE INDEX runs_by_mask ON runs (mask_id);
CREATE INDEX screen_r0_by_run ON screen_r0 (run_uuid);
CREATE INDEX reconstructions_by_run ON reconstructions (run_uuid, started_ms);
-- catalog_bench_list by method, newest first.
CREATE INDEX benchmarks_by_method ON benchmarks (method, created_ms);

PRAGMA user_version = 2;
