-- The certificates issued (issue 50): the first `survey report` of a survey
-- issues its certificate, and every later report reproduces it from here,
-- byte for byte (the page and the DCC as issued). An amendment is a new
-- certificate of the same survey, with its own number, naming the one it
-- replaces and why (ISO/IEC 17025 7.8.8). A number is issued once in a store.
CREATE TABLE certificates (
    number     TEXT PRIMARY KEY,
    survey_id  INTEGER NOT NULL REFERENCES surveys (id),
    seq        INTEGER NOT NULL CHECK (seq >= 1),
    issued_at  TEXT NOT NULL,
    replaces   TEXT REFERENCES certificates (number),
    reason     TEXT,
    page       TEXT NOT NULL,
    dcc        TEXT NOT NULL,
    CHECK ((seq = 1) = (replaces IS NULL) AND (replaces IS NULL) = (reason IS NULL))
);
CREATE UNIQUE INDEX certificates_survey_seq ON certificates (survey_id, seq);
