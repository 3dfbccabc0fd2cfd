-- Instrument time (issue 12): where each survey's time went, and the
-- continuous scans' passes with their raw streams.

-- Instrument time by component (`locate`, `move`, `settle`, `dwell`,
-- `measure`, `poll_lag`, `command_latency`, `scan`, `recovery`, `other`),
-- seconds, summed over the survey's acquisitions (an acquisition adds its
-- account when it ends; one killed adds nothing).
CREATE TABLE survey_time (
    survey_id INTEGER NOT NULL REFERENCES surveys (id),
    component TEXT NOT NULL,
    seconds   REAL NOT NULL,
    PRIMARY KEY (survey_id, component)
) WITHOUT ROWID;

-- One row per pass of a continuous scan that was stored (with its samples,
-- in the same transaction): how its streams were paired. A clock maps a
-- stream's stamps to instrument time: host = offset + rate * stamp (the
-- identity for readouts polled by the host). The latency (seconds the
-- tracker's points lag the readout) was removed from every sample.
CREATE TABLE scan_passes (
    survey_id          INTEGER NOT NULL REFERENCES surveys (id),
    pass               INTEGER NOT NULL CHECK (pass >= 0),
    run                INTEGER NOT NULL CHECK (run >= 1),
    direction          TEXT NOT NULL CHECK (direction IN ('forward', 'reverse')),
    velocity_deg_s     REAL NOT NULL,
    latency_s          REAL NOT NULL,
    latency_se_s       REAL,
    readout_captured   INTEGER NOT NULL CHECK (readout_captured IN (0, 1)),
    readout_offset_s   REAL NOT NULL,
    readout_rate       REAL NOT NULL,
    tracker_offset_s   REAL NOT NULL,
    tracker_rate       REAL NOT NULL,
    started_at_s       REAL,
    ended_at_s         REAL,
    PRIMARY KEY (survey_id, pass)
) WITHOUT ROWID;

-- The raw streams of a stored pass, in chunks of little-endian f64 records:
--   readout        [stamp, readout_deg]                  (16 bytes)
--   readout_reads  [stamp of the newest, host time]       (16 bytes)
--   tracker        [stamp, x_mm, y_mm, z_mm, status]      (40 bytes)
--   tracker_reads  [stamp of the newest, host time]       (16 bytes)
CREATE TABLE scan_streams (
    survey_id INTEGER NOT NULL,
    pass      INTEGER NOT NULL,
    stream    TEXT NOT NULL CHECK (stream IN ('readout', 'readout_reads', 'tracker', 'tracker_reads')),
    chunk     INTEGER NOT NULL CHECK (chunk >= 0),
    records   INTEGER NOT NULL CHECK (records >= 0),
    data      BLOB NOT NULL,
    PRIMARY KEY (survey_id, pass, stream, chunk),
    FOREIGN KEY (survey_id, pass) REFERENCES scan_passes (survey_id, pass)
) WITHOUT ROWID;
