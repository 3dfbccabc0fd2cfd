-- Drift control's reference measurements (../0002_drift.sql).
CREATE TABLE drift_points (
    survey_id     BIGINT NOT NULL REFERENCES surveys (id),
    idx           BIGINT NOT NULL CHECK (idx >= 0),
    before_seq    BIGINT NOT NULL CHECK (before_seq >= 0),
    at_s          DOUBLE PRECISION NOT NULL,
    reference_deg DOUBLE PRECISION NOT NULL,
    readout_deg   DOUBLE PRECISION NOT NULL,
    actual_deg    DOUBLE PRECISION NOT NULL,
    PRIMARY KEY (survey_id, idx)
);
