-- A survey whose acquisition is whole but whose outputs (the correction table
-- and the files beside it) are not all written yet is 'processing': it becomes
-- 'complete' only once they are, and `survey resume` finishes a 'processing'
-- survey left by a kill or a full disk.
--
-- SQLite cannot change a CHECK in place: the table is rebuilt as SQLite
-- documents (https://www.sqlite.org/lang_altertable.html#otheralter, "making
-- other kinds of table schema changes"), keeping every row and id. The store
-- runs this migration on a connection with foreign keys off (step 1 of that
-- procedure) and checks them afterwards (`PRAGMA foreign_key_check`); the
-- table's indexes (migration 5's) are recreated after it.

CREATE TABLE surveys_new (
    id               INTEGER PRIMARY KEY,
    created_at       TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%SZ', 'now')),
    updated_at       TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%SZ', 'now')),
    status           TEXT NOT NULL
                     CHECK (status IN ('running', 'interrupted', 'processing', 'complete', 'failed', 'imported')),
    -- 'simulated', 'instruments', 'verification' or 'import:<file>'
    source           TEXT NOT NULL,
    points           INTEGER CHECK (points IS NULL OR points >= 0),
    runs             INTEGER CHECK (runs IS NULL OR runs >= 0),
    bidirectional    INTEGER NOT NULL DEFAULT 0 CHECK (bidirectional IN (0, 1)),
    -- the full survey configuration and plan, JSON
    config_json      TEXT NOT NULL DEFAULT '{}',
    -- the simulated positioner model (TOML), when simulated
    model_toml       TEXT,
    -- the names of the instrument drivers, JSON
    instruments_json TEXT NOT NULL DEFAULT '[]',
    -- the located axis, JSON, once located
    axis_json        TEXT,
    started_at_s     REAL,
    ended_at_s       REAL,
    planned_samples  INTEGER CHECK (planned_samples IS NULL OR planned_samples >= 0),
    -- migration 5: the asset, the uid, the calibration a check was compared with
    uid              TEXT NOT NULL DEFAULT '',
    asset            TEXT NOT NULL DEFAULT 'unassigned',
    check_of         TEXT
);

INSERT INTO surveys_new (id, created_at, updated_at, status, source, points, runs, bidirectional, config_json,
                         model_toml, instruments_json, axis_json, started_at_s, ended_at_s, planned_samples,
                         uid, asset, check_of)
SELECT id, created_at, updated_at, status, source, points, runs, bidirectional, config_json,
       model_toml, instruments_json, axis_json, started_at_s, ended_at_s, planned_samples,
       uid, asset, check_of
FROM surveys;

DROP TABLE surveys;

ALTER TABLE surveys_new RENAME TO surveys;

CREATE UNIQUE INDEX surveys_by_uid ON surveys (uid);
CREATE INDEX surveys_by_asset ON surveys (asset, id);
