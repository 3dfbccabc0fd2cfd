//! Sample packs (`sample_packs`, migration 7): a survey's samples with the
//! SMR position behind each, copied into a few blobs of fixed 72-byte records
//! once its acquisition is whole, so that a command reading the whole survey
//! decodes a blob instead of two SQLite rows a sample.
//!
//! The rows stay the record. A pack is written from them in a transaction
//! of its own right after the one that marks the acquisition whole
//! ([`Store::set_status`](super::Store::set_status) to `processing`,
//! `complete` or `imported`, and [`Store::import`](super::Store::import)),
//! under the write lock, so it holds the rows as they are then. Any later
//! insert, update or delete of a survey's samples or raw readings drops its
//! pack (triggers). A survey without a pack (a kill between the two
//! transactions, a full disk, a database from before migration 7), or with
//! one that does not decode or does not end at its last sample, is read from
//! its rows. The format is this project's own (no public document); its
//! layout is in the migration and in [`Record`].

use anyhow::{Context as _, bail};
use sqlx::sqlite::SqliteConnection;
use survey_processing::{Direction, Sample};

/// The SMR positions behind a survey's samples, what the axis refit fits:
/// the points the read was given first (the locate points), then the
/// position behind each sample that has one, in seq order.
#[derive(Debug, Clone, Default)]
pub struct SmrPositions {
    /// x, y, z in mm (NaN where the tracker gave NaN).
    pub xyz_mm: Vec<[f64; 3]>,
    /// The index in the samples of each position after the given points;
    /// empty while they are 0, 1, 2, ... (each sample so far has one, the
    /// tracker survey's case: 4 bytes a sample saved at the refit's peak).
    sample_index: Vec<u32>,
    /// How many positions follow the given points.
    added: usize,
}

impl SmrPositions {
    /// `before` first, room for `n` positions after.
    pub(super) fn after(before: Vec<[f64; 3]>, n: usize) -> Self {
        let mut xyz_mm = before;
        xyz_mm.reserve(n);
        SmrPositions { xyz_mm, sample_index: Vec::new(), added: 0 }
    }

    /// Add the position `xyz_mm` of the sample at `index`.
    pub(super) fn push(&mut self, index: usize, xyz_mm: [f64; 3]) -> anyhow::Result<()> {
        let index = u32::try_from(index).map_err(|_| anyhow::anyhow!("more than {} samples", u32::MAX))?;
        if !(self.sample_index.is_empty() && index as usize == self.added) {
            if self.sample_index.is_empty() {
                // The first sample without a position: the indices so far
                // are written out.
                self.sample_index = (0..self.added as u32).collect();
            }
            self.sample_index.push(index);
        }
        self.xyz_mm.push(xyz_mm);
        self.added += 1;
        Ok(())
    }

    /// Clear the positions added, keeping the `before` given.
    pub(super) fn truncate_to_given(&mut self) {
        self.xyz_mm.truncate(self.given());
        self.sample_index = Vec::new();
        self.added = 0;
    }

    /// How many points were given before the samples' positions.
    pub fn given(&self) -> usize {
        self.xyz_mm.len() - self.added
    }

    /// How many positions follow the given points when they are those of
    /// the first samples, one each in order (a tracker survey's case):
    /// `None` when some sample before the last one with a position has none.
    pub fn dense(&self) -> Option<usize> {
        self.sample_index.is_empty().then_some(self.added)
    }

    /// The index in the samples of each position after the given points.
    pub fn sample_indices(&self) -> impl Iterator<Item = usize> + '_ {
        let dense = self.sample_index.is_empty();
        (0..self.added).map(move |k| if dense { k } else { self.sample_index[k] as usize })
    }

    /// The positions after the given points: (sample index, x, y, z).
    pub fn of_samples(&self) -> impl Iterator<Item = (usize, [f64; 3])> + '_ {
        self.sample_indices().zip(&self.xyz_mm[self.given()..]).map(|(i, &p)| (i, p))
    }
}

/// The same positions, whether their indices are written out or not.
impl PartialEq for SmrPositions {
    fn eq(&self, other: &Self) -> bool {
        self.xyz_mm == other.xyz_mm && self.added == other.added && self.sample_indices().eq(other.sample_indices())
    }
}

/// The layout [`encode`] writes and [`decode`] reads.
pub(super) const FORMAT: i64 = 1;
/// Bytes a record.
const RECORD: usize = 72;
/// Records a blob at most (4.7 MB; SQLite's default limit on a blob is 1 GB).
const PER_BLOB: usize = 1 << 16;
const HAS_TIME: u8 = 1;
const HAS_SMR: u8 = 2;

/// One sample as a pack holds it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Record {
    pub seq: i64,
    pub sample: Sample,
    pub smr_mm: Option<[f64; 3]>,
}

fn put(out: &mut Vec<u8>, r: &Record) {
    let mut flags = 0u8;
    if r.sample.timestamp_s.is_some() {
        flags |= HAS_TIME;
    }
    if r.smr_mm.is_some() {
        flags |= HAS_SMR;
    }
    let direction = match r.sample.direction {
        Direction::Forward => 0u8,
        Direction::Reverse => 1,
    };
    out.extend_from_slice(&r.seq.to_le_bytes());
    out.extend_from_slice(&r.sample.run.to_le_bytes());
    out.extend_from_slice(&[direction, flags, 0, 0]);
    let s = &r.sample;
    let [x, y, z] = r.smr_mm.unwrap_or([0.0; 3]);
    for v in [s.target_deg, s.readout_deg, s.actual_deg, s.timestamp_s.unwrap_or(0.0), x, y, z] {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

/// `records` (in seq order) as the blobs of a pack: (first seq, count, data).
pub(super) fn encode(records: &[Record]) -> Vec<(i64, i64, Vec<u8>)> {
    records
        .chunks(PER_BLOB)
        .map(|chunk| {
            let mut data = Vec::with_capacity(chunk.len() * RECORD);
            for r in chunk {
                put(&mut data, r);
            }
            (chunk[0].seq, chunk.len() as i64, data)
        })
        .collect()
}

fn f64_at(b: &[u8], at: usize) -> f64 {
    f64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"))
}

/// Decode one blob of `count` records that should start at `first_seq` and
/// follow `last_seq` (the previous blob's last), appending the samples to
/// `samples` and, when `smr` is some, the SMR positions to it. Returns the
/// blob's last seq. A blob that does not hold what its row says is an error
/// naming it.
pub(super) fn decode(
    data: &[u8],
    first_seq: i64,
    count: i64,
    last_seq: Option<i64>,
    samples: &mut Vec<Sample>,
    mut smr: Option<&mut SmrPositions>,
) -> anyhow::Result<i64> {
    if usize::try_from(count).ok().and_then(|n| n.checked_mul(RECORD)) != Some(data.len()) || count == 0 {
        bail!("the pack from seq {first_seq} holds {} bytes, not {count} records of {RECORD}", data.len())
    }
    let mut last = last_seq;
    for (k, b) in data.chunks_exact(RECORD).enumerate() {
        let seq = i64::from_le_bytes(b[0..8].try_into().expect("8 bytes"));
        if (k == 0 && seq != first_seq) || last.is_some_and(|l| seq <= l) || seq < 0 {
            bail!("the pack from seq {first_seq}: record {k} has seq {seq}, out of order");
        }
        last = Some(seq);
        let run = u32::from_le_bytes(b[8..12].try_into().expect("4 bytes"));
        let direction = match b[12] {
            0 => Direction::Forward,
            1 => Direction::Reverse,
            other => bail!("the pack from seq {first_seq}: seq {seq} has direction {other}"),
        };
        let flags = b[13];
        if run == 0 || flags & !(HAS_TIME | HAS_SMR) != 0 {
            bail!("the pack from seq {first_seq}: seq {seq} is malformed (run {run}, flags {flags})");
        }
        if flags & HAS_SMR != 0
            && let Some(smr) = smr.as_deref_mut()
        {
            smr.push(samples.len(), [f64_at(b, 48), f64_at(b, 56), f64_at(b, 64)])?;
        }
        samples.push(Sample {
            run,
            direction,
            target_deg: f64_at(b, 16),
            readout_deg: f64_at(b, 24),
            actual_deg: f64_at(b, 32),
            timestamp_s: (flags & HAS_TIME != 0).then(|| f64_at(b, 40)),
        });
    }
    Ok(last.expect("a pack holds at least one record"))
}

/// Write the pack of survey `survey_id` from `records` (every sample it
/// has, in seq order) on `conn`, inside the caller's transaction; a pack it
/// had is replaced. Nothing is written for a survey without samples.
pub(super) async fn write(conn: &mut SqliteConnection, survey_id: i64, records: &[Record]) -> anyhow::Result<()> {
    sqlx::query("DELETE FROM sample_packs WHERE survey_id = ?").bind(survey_id).execute(&mut *conn).await?;
    for (first_seq, count, data) in encode(records) {
        sqlx::query("INSERT INTO sample_packs (survey_id, first_seq, count, format, data) VALUES (?, ?, ?, ?, ?)")
            .bind(survey_id)
            .bind(first_seq)
            .bind(count)
            .bind(FORMAT)
            .bind(data)
            .execute(&mut *conn)
            .await
            .with_context(|| format!("cannot write the sample pack of survey {survey_id} from seq {first_seq}"))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Store;
    use crate::survey::{NewSurvey, SurveyStatus};
    use survey_acquire::{RawReading, RecordedSample};
    use survey_drivers::SmrMeasurement;

    /// The indices stay implicit while every sample has a position, and
    /// are written out from the first one without: either way they read
    /// back the same, and compare equal to the same positions pushed.
    #[test]
    fn sample_indices_are_implicit_until_a_sample_has_no_position() {
        let mut dense = SmrPositions::after(vec![[1.0, 2.0, 3.0]], 4);
        for i in 0..3 {
            dense.push(i, [i as f64, 0.0, 0.0]).unwrap();
        }
        assert!(dense.sample_index.is_empty());
        assert_eq!(dense.given(), 1);
        assert_eq!(dense.sample_indices().collect::<Vec<_>>(), [0, 1, 2]);
        assert_eq!(dense.dense(), Some(3));
        let mut sparse = dense.clone();
        sparse.push(4, [4.0, 0.0, 0.0]).unwrap();
        sparse.push(5, [5.0, 0.0, 0.0]).unwrap();
        assert_eq!(sparse.sample_index, [0, 1, 2, 4, 5]);
        assert_eq!(sparse.dense(), None);
        assert_eq!(
            sparse.of_samples().map(|(i, p)| (i, p[0])).collect::<Vec<_>>(),
            [(0, 0.0), (1, 1.0), (2, 2.0), (4, 4.0), (5, 5.0)]
        );
        assert_ne!(sparse, dense);
        // The same positions with the indices written out from the start.
        let mut written = SmrPositions::after(vec![[1.0, 2.0, 3.0]], 0);
        written.sample_index = vec![0, 1, 2];
        written.xyz_mm.extend((0..3).map(|i| [i as f64, 0.0, 0.0]));
        written.added = 3;
        assert_eq!(written, dense);
        sparse.truncate_to_given();
        assert_eq!(sparse, SmrPositions::after(vec![[1.0, 2.0, 3.0]], 0));
        assert_eq!(sparse.sample_indices().count(), 0);
    }

    /// Sample `seq` of a tracker survey: an SMR position behind two of three
    /// (NaN where the tracker gave NaN), a timestamp on four of five.
    fn recorded(seq: u64) -> RecordedSample {
        let f = seq as f64;
        let raw = match seq % 3 {
            0 => RawReading::None,
            _ => RawReading::Smr(SmrMeasurement {
                x_mm: if seq % 7 == 1 { f64::NAN } else { 250.0 + f * 1e-3 },
                y_mm: -50.0 + f / 7.0,
                z_mm: 0.1 + 0.2,
                std_dev_mm: [1e-3; 3],
                measurement_time_s: 2.5,
                environment: None,
            }),
        };
        let sample = Sample {
            run: 1 + (seq / 100) as u32,
            direction: if seq.is_multiple_of(2) { Direction::Forward } else { Direction::Reverse },
            target_deg: f * 0.36,
            readout_deg: f * 0.36 + 1e-4 / (1.0 + f),
            actual_deg: -0.0 + f * 0.36 - 1.0 / 3.0 * 1e-5,
            timestamp_s: (!seq.is_multiple_of(5)).then_some(f * 1.25),
        };
        RecordedSample { seq, sample, raw, others: Vec::new() }
    }

    /// The samples and SMR positions as bits: compared bit for bit (NaN
    /// equal to NaN, -0 not 0).
    type Bits = (Vec<[u64; 6]>, Vec<[u64; 3]>, Vec<u32>);

    fn bits(samples: &[Sample], smr: &SmrPositions) -> Bits {
        let s = samples
            .iter()
            .map(|s| {
                [
                    u64::from(s.run) * 2 + u64::from(s.direction == Direction::Reverse),
                    s.target_deg.to_bits(),
                    s.readout_deg.to_bits(),
                    s.actual_deg.to_bits(),
                    s.timestamp_s.map_or(u64::MAX, f64::to_bits),
                    u64::from(s.timestamp_s.is_some()),
                ]
            })
            .collect();
        (s, smr.xyz_mm.iter().map(|p| p.map(f64::to_bits)).collect(), smr.sample_index.clone())
    }

    async fn store_with(n: u64) -> (tempfile::TempDir, Store, i64) {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(&dir.path().join("s.db")).await.unwrap();
        let new = NewSurvey { status: SurveyStatus::Running, ..NewSurvey::default() };
        let id = store.create_survey(&new).await.unwrap();
        let samples: Vec<RecordedSample> = (0..n).map(recorded).collect();
        store.append(id, &samples).await.unwrap();
        (dir, store, id)
    }

    async fn packed(store: &Store, id: i64) -> (i64, i64) {
        sqlx::query_as("SELECT COUNT(*), COALESCE(SUM(count), 0) FROM sample_packs WHERE survey_id = ?")
            .bind(id)
            .fetch_one(store.sqlite().unwrap())
            .await
            .unwrap()
    }

    /// The locate points a refit gives the read, to come first.
    const LOCATE: [[f64; 3]; 2] = [[1.0, 2.0, 3.0], [4.0, f64::NAN, -0.0]];

    async fn read(store: &Store, id: i64) -> Bits {
        let (samples, smr) = store.samples_with_smr(id, LOCATE.to_vec()).await.unwrap();
        assert_eq!(bits(&store.samples(id).await.unwrap(), &SmrPositions::default()).0, bits(&samples, &smr).0);
        let given: Vec<[u64; 3]> = LOCATE.iter().map(|p| p.map(f64::to_bits)).collect();
        assert_eq!(smr.xyz_mm.len(), smr.sample_index.len() + 2);
        assert_eq!(bits(&samples, &smr).1[..2], given);
        bits(&samples, &smr)
    }

    async fn exec(store: &Store, sql: &'static str) {
        sqlx::query(sql).execute(store.sqlite().unwrap()).await.unwrap();
    }

    #[tokio::test]
    async fn a_whole_survey_is_packed_and_read_from_its_pack_bit_for_bit_as_from_its_rows() {
        let (_dir, store, id) = store_with(600).await;
        assert_eq!(packed(&store, id).await, (0, 0), "not packed while it is acquired");
        let rows = read(&store, id).await;
        assert_eq!(rows.2.len(), 400);
        assert_eq!(rows.2[..3], [1, 2, 4], "the samples with a position");
        assert!(rows.1[2..].iter().any(|p| f64::from_bits(p[0]).is_nan()));
        store.set_status(id, SurveyStatus::Processing, None).await.unwrap();
        assert_eq!(packed(&store, id).await, (1, 600));
        assert_eq!(read(&store, id).await, rows);
        // What is read is the pack: with the trigger gone, a changed row is
        // not seen (this is what the triggers are for).
        exec(&store, "DROP TRIGGER samples_update_unpacks").await;
        exec(&store, "UPDATE samples SET actual_deg = 1.0 WHERE seq = 7").await;
        assert_eq!(read(&store, id).await, rows);
        // Marking it complete keeps the pack it has.
        store.set_status(id, SurveyStatus::Complete, None).await.unwrap();
        assert_eq!(packed(&store, id).await, (1, 600));
        store.close().await;
    }

    #[tokio::test]
    async fn any_change_to_a_survey_s_rows_drops_its_pack_and_the_rows_are_read() {
        let (_dir, store, id) = store_with(300).await;
        let new = NewSurvey { status: SurveyStatus::Running, ..NewSurvey::default() };
        let other = store.create_survey(&new).await.unwrap();
        store.append(other, &(0..10).map(recorded).collect::<Vec<_>>()).await.unwrap();
        store.set_status(other, SurveyStatus::Complete, None).await.unwrap();
        for change in [
            "UPDATE samples SET actual_deg = 1.0 WHERE seq = 7",
            "UPDATE raw_readings SET smr_y_mm = 3.0 WHERE seq = 8",
            "DELETE FROM raw_readings WHERE seq = 10",
            "DELETE FROM samples WHERE seq = 12",
        ] {
            store.set_status(id, SurveyStatus::Complete, None).await.unwrap();
            assert_eq!(packed(&store, id).await.0, 1, "{change}");
            let sql = change.replace("WHERE", &format!("WHERE survey_id = {id} AND"));
            sqlx::query(sqlx::AssertSqlSafe(sql)).execute(store.sqlite().unwrap()).await.unwrap();
            assert_eq!(packed(&store, id).await, (0, 0), "{change}");
            let from_rows = read(&store, id).await;
            store.set_status(id, SurveyStatus::Complete, None).await.unwrap();
            assert_eq!(read(&store, id).await, from_rows, "{change}: packed again");
        }
        let (samples, smr) = store.samples_with_smr(id, Vec::new()).await.unwrap();
        assert_eq!((samples.len(), samples[7].actual_deg), (299, 1.0));
        assert!(smr.of_samples().any(|(_, p)| p[1] == 3.0) && !smr.of_samples().any(|(i, _)| i == 10));
        // A new sample drops the pack too (a survey resumed).
        store.append(id, &[recorded(300)]).await.unwrap();
        assert_eq!(packed(&store, id).await, (0, 0));
        assert_eq!(store.samples(id).await.unwrap().len(), 300);
        // The other survey's pack was never touched.
        assert_eq!(packed(&store, other).await, (1, 10));
        store.close().await;
    }

    #[tokio::test]
    async fn a_pack_that_does_not_hold_the_survey_s_rows_is_not_read() {
        let (_dir, store, id) = store_with(200).await;
        let rows = read(&store, id).await;
        // A pack of the first 150 samples only (written behind the store's back).
        let records: Vec<Record> = (0..150)
            .map(recorded)
            .map(|r| Record {
                seq: r.seq as i64,
                sample: r.sample,
                smr_mm: match r.raw {
                    RawReading::Smr(m) => Some(m.xyz()),
                    _ => None,
                },
            })
            .collect();
        let mut conn = store.sqlite().unwrap().acquire().await.unwrap();
        write(&mut conn, id, &records).await.unwrap();
        drop(conn);
        assert_eq!(packed(&store, id).await, (1, 150));
        assert_eq!(read(&store, id).await, rows, "a pack that ends early");
        // A damaged blob.
        exec(&store, "UPDATE sample_packs SET count = 200, data = zeroblob(14400)").await;
        assert_eq!(read(&store, id).await, rows, "a damaged pack");
        exec(&store, "UPDATE sample_packs SET format = 2").await;
        assert_eq!(read(&store, id).await, rows, "a pack of another format");
        store.close().await;
    }

    #[tokio::test]
    async fn an_import_is_packed() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(&dir.path().join("s.db")).await.unwrap();
        let samples: Vec<Sample> = (0..50).map(|k| recorded(k).sample).collect();
        let new = NewSurvey { status: SurveyStatus::Imported, ..NewSurvey::default() };
        let id = store.import(&new, &samples).await.unwrap();
        assert_eq!(packed(&store, id).await, (1, 50));
        assert_eq!(store.samples(id).await.unwrap(), samples);
        assert_eq!(store.samples_with_smr(id, LOCATE[..1].to_vec()).await.unwrap().1.xyz_mm, LOCATE[..1]);
        store.close().await;
    }

    #[test]
    fn a_large_survey_packs_into_several_blobs_that_decode_in_order() {
        let records: Vec<Record> = (0..(PER_BLOB as u64 * 2 + 5))
            .map(|seq| {
                let r = recorded(seq);
                Record { seq: seq as i64, sample: r.sample, smr_mm: (seq % 2 == 0).then_some([seq as f64, 1.0, 2.0]) }
            })
            .collect();
        let blobs = encode(&records);
        assert_eq!(
            blobs.iter().map(|b| (b.0, b.1)).collect::<Vec<_>>(),
            [(0, PER_BLOB as i64), (PER_BLOB as i64, PER_BLOB as i64), (2 * PER_BLOB as i64, 5)]
        );
        let (mut samples, mut smr, mut last) = (Vec::new(), SmrPositions::default(), None);
        for (first, count, data) in &blobs {
            last = Some(decode(data, *first, *count, last, &mut samples, Some(&mut smr)).unwrap());
        }
        assert_eq!(last, Some(records.len() as i64 - 1));
        assert_eq!(samples, records.iter().map(|r| r.sample).collect::<Vec<_>>());
        assert_eq!(smr.sample_index.len(), PER_BLOB + 3);
        assert!(smr.of_samples().all(|(i, p)| p[0] == i as f64));
        // Out of order: the second blob after the third.
        let e = decode(&blobs[1].2, blobs[1].0, blobs[1].1, Some(2 * PER_BLOB as i64 + 4), &mut samples, None);
        assert!(format!("{:#}", e.unwrap_err()).contains("out of order"));
    }

    #[test]
    fn a_malformed_blob_is_an_error_naming_what_is_wrong() {
        let one = |edit: fn(&mut Vec<u8>)| {
            let mut data = encode(&[Record { seq: 3, sample: recorded(3).sample, smr_mm: None }]).remove(0).2;
            edit(&mut data);
            let count = (data.len() / RECORD).max(1) as i64;
            decode(&data, 3, count, None, &mut Vec::new(), None).map_err(|e| format!("{e:#}"))
        };
        assert_eq!(one(|_| ()), Ok(3));
        assert!(one(|d| d.truncate(70)).unwrap_err().contains("holds 70 bytes, not 1 records of 72"));
        assert!(one(|d| d[0] = 4).unwrap_err().contains("record 0 has seq 4"));
        assert!(one(|d| d[12] = 2).unwrap_err().contains("seq 3 has direction 2"));
        assert!(one(|d| d[8..12].copy_from_slice(&[0; 4])).unwrap_err().contains("malformed (run 0"));
        assert!(one(|d| d[13] = 4).unwrap_err().contains("flags 4"));
    }
}
