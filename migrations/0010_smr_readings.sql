-- Several SMRs on the table (issue 48): at every target the tracker is
-- pointed at each SMR beside the first and measures it; the first SMR's
-- reading stays in raw_readings (it gives the sample's angle at
-- acquisition), the others' are here, `smr` the SMR's place in the arm's
-- order (1 for the second). A sample's readings are written with it, in one
-- transaction.
CREATE TABLE smr_readings (
    survey_id          INTEGER NOT NULL,
    seq                INTEGER NOT NULL,
    smr                INTEGER NOT NULL CHECK (smr >= 1),
    x_mm               REAL NOT NULL,
    y_mm               REAL NOT NULL,
    z_mm               REAL NOT NULL,
    sx_mm              REAL NOT NULL,
    sy_mm              REAL NOT NULL,
    sz_mm              REAL NOT NULL,
    measurement_time_s REAL NOT NULL,
    air_temperature_c  REAL,
    air_pressure_hpa   REAL,
    air_humidity_pct   REAL,
    PRIMARY KEY (survey_id, seq, smr),
    FOREIGN KEY (survey_id, seq) REFERENCES samples (survey_id, seq)
) WITHOUT ROWID;
