-- A positioner's life (issue 22): every survey belongs to an asset (the axis
-- it measured) and has a uid (a UUID, lower-case hex 8-4-4-4-12) that stays
-- with it wherever it is copied (`survey push`: exactly once by uid). A check
-- survey (`survey run --check`) names the calibration it was compared with;
-- `checks` keeps what the check decided.
--
-- Surveys stored before this migration get a new random uid, and the asset:
-- `sim-<preset>` for a simulated survey, `[asset] id` of a configuration that
-- had one, the verified survey's asset for a verification, and `unassigned`
-- for the others (imports, configurations without `[asset]`).
-- PostgreSQL's lab store has the same change (migrations/postgres/0005_assets.sql).

ALTER TABLE surveys ADD COLUMN uid TEXT NOT NULL DEFAULT '';
ALTER TABLE surveys ADD COLUMN asset TEXT NOT NULL DEFAULT 'unassigned';
-- the uid of the calibration survey a check survey was compared with
ALTER TABLE surveys ADD COLUMN check_of TEXT;

UPDATE surveys SET uid =
    lower(hex(randomblob(4))) || '-' || lower(hex(randomblob(2))) || '-4'
    || substr(lower(hex(randomblob(2))), 2) || '-'
    || substr('89ab', 1 + (abs(random()) % 4), 1) || substr(lower(hex(randomblob(2))), 2) || '-'
    || lower(hex(randomblob(6)));

UPDATE surveys SET asset = COALESCE(
    CASE source
        WHEN 'simulated' THEN 'sim-' || json_extract(config_json, '$.preset')
        WHEN 'instruments' THEN json_extract(config_json, '$.config.asset.id')
    END,
    'unassigned')
WHERE json_valid(config_json);

UPDATE surveys SET asset = COALESCE(
    (SELECT v.asset FROM surveys AS v WHERE v.id = json_extract(surveys.instruments_json, '$.verifies_survey')),
    'unassigned')
WHERE source = 'verification' AND json_valid(instruments_json);

CREATE UNIQUE INDEX surveys_by_uid ON surveys (uid);
CREATE INDEX surveys_by_asset ON surveys (asset, id);

-- What a check survey decided (one row per check survey): compared with the
-- calibration `against_uid`, whether the positioner changed beyond what the
-- two surveys' repeatability allows, whether that calibration's table still
-- holds on the check, and so whether to recalibrate; `recalibration_uid` is
-- the full survey made because of it, whose table is then the one in force
-- (`table` the table file written for it).
CREATE TABLE checks (
    survey_id         INTEGER PRIMARY KEY REFERENCES surveys (id),
    against_uid       TEXT NOT NULL,
    verdict           TEXT NOT NULL CHECK (verdict IN ('unchanged', 'changed')),
    table_holds       INTEGER NOT NULL CHECK (table_holds IN (0, 1)),
    recalibrate       INTEGER NOT NULL CHECK (recalibrate IN (0, 1)),
    reason            TEXT NOT NULL,
    recalibration_uid TEXT,
    table_file        TEXT
);
