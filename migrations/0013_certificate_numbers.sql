-- The laboratory's certificate numbers (issue 50): the last number drawn in
-- each year, drawn by `survey report --lab URL` from the lab store (one
-- sequence for every station of the lab: YYYY-NNNNN). The table is in a
-- station's file too, to keep the two schemas in step; a station draws none.
-- PostgreSQL's lab store has the same change (migrations/postgres/0013_certificate_numbers.sql).
CREATE TABLE certificate_numbers (
    year INTEGER PRIMARY KEY,
    last INTEGER NOT NULL CHECK (last >= 1)
);
