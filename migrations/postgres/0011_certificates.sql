-- The certificates issued (issue 50), as in the station's file
-- (migrations/0011_certificates.sql): a survey's issued certificate and its
-- amendments, each as issued (the page and the DCC), pushed with the survey.
CREATE TABLE certificates (
    number     TEXT PRIMARY KEY,
    survey_id  BIGINT NOT NULL REFERENCES surveys (id),
    seq        BIGINT NOT NULL CHECK (seq >= 1),
    issued_at  TEXT NOT NULL,
    replaces   TEXT REFERENCES certificates (number),
    reason     TEXT,
    page       TEXT NOT NULL,
    dcc        TEXT NOT NULL,
    CHECK ((seq = 1) = (replaces IS NULL) AND (replaces IS NULL) = (reason IS NULL))
);
CREATE UNIQUE INDEX certificates_survey_seq ON certificates (survey_id, seq);
