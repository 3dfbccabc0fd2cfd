-- The history of an asset computed once (issue 40): per complete survey its
-- measured summary (the history's entry: ISO 230-2 A, R and B, the table's
-- U and the main lines it corrects, the samples counted), and per pair of
-- consecutive complete surveys of an asset (calibrations and checks) the
-- comparison (the history's change document without the two surveys' ids,
-- or why the pair cannot be compared). Both are a cache: a copy of what the
-- surveys' own rows give, made by the program version `version` names
-- (`survey_lab::life::cache::VERSION`: the package version and a
-- fingerprint of the code that computes them), written when a survey
-- completes (`survey run`, `resume`, `import`, `push`) and read by
-- `survey history`, `survey run --check`, the report and `survey serve`. A
-- row of another version is never read; a survey without its row is
-- measured on read, as before this migration.
--
-- `data` is the encoding of `survey_lab::life::cache` (every f64 by its
-- bits). A change is keyed by its later survey and the earlier one's uid:
-- the pair, in either store (ids are a database's own, uids the surveys').
-- PostgreSQL's lab store has the same tables (migrations/postgres/0008_history_cache.sql).

CREATE TABLE survey_summaries (
    survey_id INTEGER NOT NULL REFERENCES surveys (id),
    version   TEXT NOT NULL,
    data      BLOB NOT NULL,
    PRIMARY KEY (survey_id, version)
);

CREATE TABLE survey_changes (
    survey_id INTEGER NOT NULL REFERENCES surveys (id),
    from_uid  TEXT NOT NULL,
    version   TEXT NOT NULL,
    data      BLOB NOT NULL,
    PRIMARY KEY (survey_id, from_uid, version)
);
