-- The control chart's figures of every check (issue 53), as in the
-- station's file (migrations/0012_intervals.sql): NULL where not measured.
ALTER TABLE checks ADD COLUMN residual_peak_deg DOUBLE PRECISION;
ALTER TABLE checks ADD COLUMN stated_u_deg DOUBLE PRECISION;
ALTER TABLE checks ADD COLUMN cells_outside BIGINT;
ALTER TABLE checks ADD COLUMN allowed_outside BIGINT;
