-- Check points a survey measured between its targets, after its runs, to
-- decide the lines its analysis left in doubt (issue 20): part of the survey.
-- They are acquired to a plan of their own as a survey of source `resolving`
-- (so a kill leaves them resumable) and folded in here once complete, that
-- survey removed. Values without a declared type, as in `samples`.
CREATE TABLE check_points (
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
