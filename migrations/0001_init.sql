-- The survey store: one row per survey, its samples with the raw reference
-- readings behind them, the SMR positions that located the axis, and a log of
-- the events worth keeping (faults survived, resumes).
--
-- Angles are degrees. Times ending in `_s` are instrument time, seconds since
-- the survey started; `created_at`/`updated_at` are UTC ISO-8601 wall time.

CREATE TABLE surveys (
    id               INTEGER PRIMARY KEY,
    created_at       TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%SZ', 'now')),
    updated_at       TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%SZ', 'now')),
    status           TEXT NOT NULL
                     CHECK (status IN ('running', 'interrupted', 'complete', 'failed', 'imported')),
    -- 'simulated', 'instruments' or 'import:<file>'
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
    planned_samples  INTEGER CHECK (planned_samples IS NULL OR planned_samples >= 0)
);

-- One paired sample; `seq` is its place in the survey plan (0-based, dense).
-- Plain INSERTs: a duplicate seq is a primary key violation, never a silent replace.
--
-- The angle and time columns hold REAL values (the CHECKs say so) but are
-- declared without a type on purpose: a column of REAL affinity stores a real
-- with an integral value as an integer, which turns -0.0 into 0, and an export
-- must give back every imported value bit for bit. Without a declared type,
-- SQLite keeps the bound 8-byte double as it is.
CREATE TABLE samples (
    survey_id   INTEGER NOT NULL REFERENCES surveys (id),
    seq         INTEGER NOT NULL CHECK (seq >= 0),
    run         INTEGER NOT NULL CHECK (run >= 1),
    direction   TEXT NOT NULL CHECK (direction IN ('forward', 'reverse')),
    target_deg  NOT NULL CHECK (typeof(target_deg) = 'real'),
    readout_deg NOT NULL CHECK (typeof(readout_deg) = 'real'),
    actual_deg  NOT NULL CHECK (typeof(actual_deg) = 'real'),
    timestamp_s CHECK (timestamp_s IS NULL OR typeof(timestamp_s) = 'real'),
    PRIMARY KEY (survey_id, seq)
) WITHOUT ROWID;

-- The reference instrument's raw values behind a sample (none for imported
-- data). The columns of the other kind are NULL; a value column of the row's own
-- kind is NULL only when the instrument gave NaN (SQLite stores NaN as NULL).
CREATE TABLE raw_readings (
    survey_id          INTEGER NOT NULL,
    seq                INTEGER NOT NULL,
    kind               TEXT NOT NULL CHECK (kind IN ('smr', 'autocollimator')),
    smr_x_mm           REAL,
    smr_y_mm           REAL,
    smr_z_mm           REAL,
    smr_sx_mm          REAL,
    smr_sy_mm          REAL,
    smr_sz_mm          REAL,
    measurement_time_s REAL,
    ac_face            INTEGER CHECK (ac_face IS NULL OR ac_face >= 0),
    ac_x_arcsec        REAL,
    ac_y_arcsec        REAL,
    PRIMARY KEY (survey_id, seq),
    FOREIGN KEY (survey_id, seq) REFERENCES samples (survey_id, seq),
    CHECK (
        (kind = 'smr'
            AND ac_face IS NULL AND ac_x_arcsec IS NULL AND ac_y_arcsec IS NULL)
        OR (kind = 'autocollimator'
            AND ac_face IS NOT NULL
            AND smr_x_mm IS NULL AND smr_y_mm IS NULL AND smr_z_mm IS NULL
            AND smr_sx_mm IS NULL AND smr_sy_mm IS NULL AND smr_sz_mm IS NULL
            AND measurement_time_s IS NULL)
    )
) WITHOUT ROWID;

-- The SMR positions measured to locate the axis, in measurement order.
CREATE TABLE locate_points (
    survey_id          INTEGER NOT NULL REFERENCES surveys (id),
    idx                INTEGER NOT NULL CHECK (idx >= 0),
    readout_deg        REAL NOT NULL,
    x_mm               REAL,
    y_mm               REAL,
    z_mm               REAL,
    sx                 REAL,
    sy                 REAL,
    sz                 REAL,
    measurement_time_s REAL,
    PRIMARY KEY (survey_id, idx)
) WITHOUT ROWID;

-- What happened during a survey that is worth keeping: faults survived, resumes.
CREATE TABLE events (
    id        INTEGER PRIMARY KEY AUTOINCREMENT,
    survey_id INTEGER NOT NULL REFERENCES surveys (id),
    at_s      REAL,
    level     TEXT NOT NULL,
    message   TEXT NOT NULL
);

CREATE INDEX events_by_survey ON events (survey_id, id);
