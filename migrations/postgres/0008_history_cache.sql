-- The history's cache (../0008_history_cache.sql): per survey its measured
-- summary, per consecutive pair of an asset's complete surveys the
-- comparison, each keyed by the program version that made it. `survey push`
-- copies a survey's rows with it and completes what the lab store lacks
-- (a pair of surveys pushed by two stations); read commands only read them.
-- (No migration 7 here: the station's sample packs are not pushed.)

CREATE TABLE survey_summaries (
    survey_id BIGINT NOT NULL REFERENCES surveys (id),
    version   TEXT NOT NULL,
    data      BYTEA NOT NULL,
    PRIMARY KEY (survey_id, version)
);

CREATE TABLE survey_changes (
    survey_id BIGINT NOT NULL REFERENCES surveys (id),
    from_uid  TEXT NOT NULL,
    version   TEXT NOT NULL,
    data      BYTEA NOT NULL,
    PRIMARY KEY (survey_id, from_uid, version)
);
