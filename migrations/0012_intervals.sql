-- The control chart of every check (issue 53): what each check survey
-- measured of the table in force: the largest residual the calibration's
-- table leaves on the check's data and the U it was held to, the cells
-- where the error moved by more than U and the most that may while the
-- table holds; the chart plots cells_outside / (allowed_outside + 1), at 1
-- the table no longer holds. NULL for a check stored before this
-- migration, or one whose calibration's table could not be made. The intervals themselves are not stored: they are
-- reviewed from the history (dates, decisions, these figures, the
-- configuration each survey was made with) whenever they are asked for.
-- PostgreSQL's lab store has the same change (migrations/postgres/0012_intervals.sql).
ALTER TABLE checks ADD COLUMN residual_peak_deg REAL;
ALTER TABLE checks ADD COLUMN stated_u_deg REAL;
ALTER TABLE checks ADD COLUMN cells_outside INTEGER;
ALTER TABLE checks ADD COLUMN allowed_outside INTEGER;
