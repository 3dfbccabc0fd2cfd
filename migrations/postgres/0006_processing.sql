-- 'processing': every sample stored, the outputs not all written yet
-- (../0006_processing.sql, which rebuilds the table: SQLite cannot change a
-- CHECK in place; PostgreSQL replaces the constraint).
ALTER TABLE surveys DROP CONSTRAINT surveys_status_check;
ALTER TABLE surveys ADD CONSTRAINT surveys_status_check
    CHECK (status IN ('running', 'interrupted', 'processing', 'complete', 'failed', 'imported'));
