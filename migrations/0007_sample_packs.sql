-- A survey's samples with the SMR position behind each, packed into a few
-- blobs once its acquisition is whole: what the commands that read a whole
-- survey (process, stats, report, model-gap) read, in place of two rows a
-- sample (decoding them was most of `survey process`'s time). The rows of
-- `samples` and `raw_readings` stay the record: a pack is a copy of them,
-- written right after the transaction that marks the acquisition whole, and
-- dropped by any later change to them (the triggers below); a survey without
-- a pack is read from its rows.
--
-- `data` holds `count` records of 72 bytes, little-endian, in seq order (the
-- layout of `format` 1; orchestrator/src/store/pack.rs): seq (i64), run
-- (u32), direction (u8: 0 forward, 1 reverse), flags (u8: 1 a timestamp, 2 an
-- SMR position), two bytes of zero, target, readout, actual, timestamp (f64,
-- deg and s; 0 without a timestamp), the SMR x, y, z (f64, mm; 0 without a
-- position, NaN where the tracker gave NaN).
CREATE TABLE sample_packs (
    id        INTEGER PRIMARY KEY,
    survey_id INTEGER NOT NULL REFERENCES surveys (id),
    first_seq INTEGER NOT NULL CHECK (first_seq >= 0),
    count     INTEGER NOT NULL CHECK (count > 0),
    format    INTEGER NOT NULL,
    data      BLOB NOT NULL,
    UNIQUE (survey_id, first_seq)
);

CREATE TRIGGER samples_insert_unpacks AFTER INSERT ON samples
BEGIN
    DELETE FROM sample_packs WHERE survey_id = NEW.survey_id;
END;

CREATE TRIGGER samples_update_unpacks AFTER UPDATE ON samples
BEGIN
    DELETE FROM sample_packs WHERE survey_id IN (OLD.survey_id, NEW.survey_id);
END;

CREATE TRIGGER samples_delete_unpacks AFTER DELETE ON samples
BEGIN
    DELETE FROM sample_packs WHERE survey_id = OLD.survey_id;
END;

CREATE TRIGGER raw_readings_insert_unpacks AFTER INSERT ON raw_readings
BEGIN
    DELETE FROM sample_packs WHERE survey_id = NEW.survey_id;
END;

CREATE TRIGGER raw_readings_update_unpacks AFTER UPDATE ON raw_readings
BEGIN
    DELETE FROM sample_packs WHERE survey_id IN (OLD.survey_id, NEW.survey_id);
END;

CREATE TRIGGER raw_readings_delete_unpacks AFTER DELETE ON raw_readings
BEGIN
    DELETE FROM sample_packs WHERE survey_id = OLD.survey_id;
END;
