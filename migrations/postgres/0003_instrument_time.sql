-- Instrument time by component; a continuous scan's passes and raw streams
-- (../0003_instrument_time.sql).
CREATE TABLE survey_time (
    survey_id BIGINT NOT NULL REFERENCES surveys (id),
    component TEXT NOT NULL,
    seconds   DOUBLE PRECISION NOT NULL,
    PRIMARY KEY (survey_id, component)
);

CREATE TABLE scan_passes (
    survey_id          BIGINT NOT NULL REFERENCES surveys (id),
    pass               BIGINT NOT NULL CHECK (pass >= 0),
    run                BIGINT NOT NULL CHECK (run >= 1),
    direction          TEXT NOT NULL CHECK (direction IN ('forward', 'reverse')),
    velocity_deg_s     DOUBLE PRECISION NOT NULL,
    latency_s          DOUBLE PRECISION NOT NULL,
    latency_se_s       DOUBLE PRECISION,
    readout_captured   BOOLEAN NOT NULL,
    readout_offset_s   DOUBLE PRECISION NOT NULL,
    readout_rate       DOUBLE PRECISION NOT NULL,
    tracker_offset_s   DOUBLE PRECISION NOT NULL,
    tracker_rate       DOUBLE PRECISION NOT NULL,
    started_at_s       DOUBLE PRECISION,
    ended_at_s         DOUBLE PRECISION,
    PRIMARY KEY (survey_id, pass)
);

CREATE TABLE scan_streams (
    survey_id BIGINT NOT NULL,
    pass      BIGINT NOT NULL,
    stream    TEXT NOT NULL CHECK (stream IN ('readout', 'readout_reads', 'tracker', 'tracker_reads')),
    chunk     BIGINT NOT NULL CHECK (chunk >= 0),
    records   BIGINT NOT NULL CHECK (records >= 0),
    data      BYTEA NOT NULL,
    PRIMARY KEY (survey_id, pass, stream, chunk),
    FOREIGN KEY (survey_id, pass) REFERENCES scan_passes (survey_id, pass)
);
