-- The air around every tracker measurement (issue 39): the temperature,
-- pressure and relative humidity the tracker's weather station reports
-- with it (emScon's dTemperature, dPressure, dHumidity). NULL where the
-- reference reports none (an autocollimator, a continuous scan's stream,
-- a survey acquired before this migration).
ALTER TABLE raw_readings ADD COLUMN air_temperature_c REAL;
ALTER TABLE raw_readings ADD COLUMN air_pressure_hpa REAL;
ALTER TABLE raw_readings ADD COLUMN air_humidity_pct REAL;
