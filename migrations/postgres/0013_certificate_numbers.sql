-- The laboratory's certificate numbers (issue 50), as in the station's file
-- (migrations/0013_certificate_numbers.sql): the last number drawn in each
-- year by `survey report --lab URL`, one sequence for every station.
CREATE TABLE certificate_numbers (
    year BIGINT PRIMARY KEY,
    last BIGINT NOT NULL CHECK (last >= 1)
);
