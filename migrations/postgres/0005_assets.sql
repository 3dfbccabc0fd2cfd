-- Assets, uids and the checks' decisions (../0005_assets.sql). In the lab
-- store the uid is what `survey push` copies by: a survey is stored once.
ALTER TABLE surveys ADD COLUMN uid TEXT NOT NULL DEFAULT '';
ALTER TABLE surveys ADD COLUMN asset TEXT NOT NULL DEFAULT 'unassigned';
ALTER TABLE surveys ADD COLUMN check_of TEXT;

CREATE UNIQUE INDEX surveys_by_uid ON surveys (uid);
CREATE INDEX surveys_by_asset ON surveys (asset, id);

CREATE TABLE checks (
    survey_id         BIGINT PRIMARY KEY REFERENCES surveys (id),
    against_uid       TEXT NOT NULL,
    verdict           TEXT NOT NULL CHECK (verdict IN ('unchanged', 'changed')),
    table_holds       BOOLEAN NOT NULL,
    recalibrate       BOOLEAN NOT NULL,
    reason            TEXT NOT NULL,
    recalibration_uid TEXT,
    table_file        TEXT
);
