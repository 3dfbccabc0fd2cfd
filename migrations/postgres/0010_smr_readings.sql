-- Several SMRs on the table (issue 48), as in the station's file
-- (migrations/0010_smr_readings.sql): the readings of the SMRs beside the first.
CREATE TABLE smr_readings (
    survey_id          BIGINT NOT NULL,
    seq                BIGINT NOT NULL,
    smr                BIGINT NOT NULL CHECK (smr >= 1),
    x_mm               DOUBLE PRECISION NOT NULL,
    y_mm               DOUBLE PRECISION NOT NULL,
    z_mm               DOUBLE PRECISION NOT NULL,
    sx_mm              DOUBLE PRECISION NOT NULL,
    sy_mm              DOUBLE PRECISION NOT NULL,
    sz_mm              DOUBLE PRECISION NOT NULL,
    measurement_time_s DOUBLE PRECISION NOT NULL,
    air_temperature_c  DOUBLE PRECISION,
    air_pressure_hpa   DOUBLE PRECISION,
    air_humidity_pct   DOUBLE PRECISION,
    PRIMARY KEY (survey_id, seq, smr),
    FOREIGN KEY (survey_id, seq) REFERENCES samples (survey_id, seq)
);
