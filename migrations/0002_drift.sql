-- Drift control (issue 10): the reference target measured before step 0 and
-- every K-th step, in measurement order. The drift is the change of the
-- reference's readout error (readout_deg - actual_deg) since the first one.
-- Angles are degrees, `at_s` instrument time in seconds, as in 0001.
CREATE TABLE drift_points (
    survey_id     INTEGER NOT NULL REFERENCES surveys (id),
    idx           INTEGER NOT NULL CHECK (idx >= 0),
    before_seq    INTEGER NOT NULL CHECK (before_seq >= 0),
    at_s          REAL NOT NULL,
    reference_deg REAL NOT NULL,
    readout_deg   REAL NOT NULL,
    actual_deg    REAL NOT NULL,
    PRIMARY KEY (survey_id, idx)
) WITHOUT ROWID;
