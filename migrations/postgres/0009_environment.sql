-- The air around every tracker measurement (issue 39), as in the station's
-- file (migrations/0009_environment.sql): NULL where none was reported.
ALTER TABLE raw_readings ADD COLUMN air_temperature_c DOUBLE PRECISION;
ALTER TABLE raw_readings ADD COLUMN air_pressure_hpa DOUBLE PRECISION;
ALTER TABLE raw_readings ADD COLUMN air_humidity_pct DOUBLE PRECISION;
