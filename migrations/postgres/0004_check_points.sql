-- Check points a survey measured between its targets (../0004_check_points.sql):
-- part of the survey, copied with it by `survey push`.
CREATE TABLE check_points (
    survey_id   BIGINT NOT NULL REFERENCES surveys (id),
    seq         BIGINT NOT NULL CHECK (seq >= 0),
    run         BIGINT NOT NULL CHECK (run >= 1),
    direction   TEXT NOT NULL CHECK (direction IN ('forward', 'reverse')),
    target_deg  DOUBLE PRECISION NOT NULL,
    readout_deg DOUBLE PRECISION NOT NULL,
    actual_deg  DOUBLE PRECISION NOT NULL,
    timestamp_s DOUBLE PRECISION,
    PRIMARY KEY (survey_id, seq)
);
