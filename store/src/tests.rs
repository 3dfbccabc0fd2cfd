//! Tests of the store and of [`StoreSink`](super::StoreSink) on temporary
//! database files.

use std::time::Duration;

use survey_drivers::{AcReading, SmrMeasurement};
use survey_processing::geometry::AxisFit;
use survey_processing::{Direction, Sample};

use super::*;
use crate::survey::{NewSurvey, Setup, SurveySource, SurveyStatus};
use survey_acquire::{RawReading, RecordedSample, SampleSink};
use survey_processing::model::Model;

fn new_survey() -> NewSurvey {
    NewSurvey {
        status: SurveyStatus::Running,
        source: SurveySource::Simulated,
        points: Some(36),
        runs: Some(2),
        bidirectional: true,
        setup: Setup::Unrecorded,
        model: Some(Model::parse("[design]\ngear_ratios = [12]\n", "m.toml").unwrap()),
        instruments: serde_json::json!({"positioner": "sim-positioner", "reference": "sim-tracker"}),
        verification: None,
        planned_samples: Some(144),
        ..NewSurvey::default()
    }
}

fn recorded(seq: u64) -> RecordedSample {
    let f = seq as f64;
    let raw = match seq % 3 {
        0 => RawReading::None,
        1 => RawReading::Smr(SmrMeasurement {
            x_mm: 100.0 + f * 1e-3,
            y_mm: -50.0 + f / 7.0,
            z_mm: 0.1 + 0.2,
            std_dev_mm: [1e-3, 2e-3, f64::NAN],
            measurement_time_s: 2.5,
            environment: None,
        }),
        _ => RawReading::Autocollimator {
            face: (seq % 24) as u32,
            reading: AcReading { x_arcsec: f / 3.0, y_arcsec: -f / 11.0 },
        },
    };
    RecordedSample {
        seq,
        others: Vec::new(),
        sample: Sample {
            run: 1 + (seq / 1000) as u32,
            direction: if seq.is_multiple_of(2) { Direction::Forward } else { Direction::Reverse },
            target_deg: f * 0.36,
            readout_deg: f * 0.36 + 1e-4 / (1.0 + f),
            actual_deg: f * 0.36 - 1.0 / 3.0 * 1e-5,
            timestamp_s: if seq.is_multiple_of(5) { None } else { Some(f * 1.25) },
        },
        raw,
    }
}

fn axis_fit() -> AxisFit {
    AxisFit {
        center_mm: [0.0, 0.0, 0.0],
        normal: [0.0, 0.0, 1.0],
        u: [1.0, 0.0, 0.0],
        v: [0.0, 1.0, 0.0],
        radius_mm: 250.0,
        zero_offset_deg: 0.5,
        plane_rms_mm: 0.001,
        circle_rms_mm: 0.002,
        points: 3,
    }
}

/// Equal bit for bit (NaN equal to NaN).
fn assert_same(a: &[RecordedSample], b: &[RecordedSample]) {
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(b) {
        let (sx, sy) = (format!("{x:?}"), format!("{y:?}"));
        assert_eq!(sx, sy);
        assert_eq!(x.sample.readout_deg.to_bits(), y.sample.readout_deg.to_bits());
        assert_eq!(x.sample.actual_deg.to_bits(), y.sample.actual_deg.to_bits());
    }
}

async fn temp_store() -> (tempfile::TempDir, Store) {
    let dir = tempfile::tempdir().unwrap();
    let store = Store::open(&dir.path().join("survey.db")).await.unwrap();
    (dir, store)
}

#[tokio::test]
async fn wal_mode_and_reopen() {
    let (dir, store) = temp_store().await;
    assert_eq!(store.journal_mode().await.unwrap(), "wal");
    let sync: i64 = sqlx::query_scalar("PRAGMA synchronous").fetch_one(store.sqlite().unwrap()).await.unwrap();
    assert_eq!(sync, 2, "synchronous = FULL");
    let fk: i64 = sqlx::query_scalar("PRAGMA foreign_keys").fetch_one(store.sqlite().unwrap()).await.unwrap();
    assert_eq!(fk, 1);
    let id = store.create_survey(&new_survey()).await.unwrap();
    store.close().await;
    // reopening runs the (already applied) migrations again without harm
    let store = Store::open_existing(&dir.path().join("survey.db")).await.unwrap();
    assert_eq!(store.journal_mode().await.unwrap(), "wal");
    assert_eq!(store.latest_survey_id().await.unwrap(), Some(id));
    store.close().await;
}

#[tokio::test]
async fn append_in_chunks_and_read_back() {
    let (_dir, store) = temp_store().await;
    let id = store.create_survey(&new_survey()).await.unwrap();
    let samples: Vec<RecordedSample> = (0..5000).map(recorded).collect();
    // 5000 rows x 8 values = 40000 > 32766: must be chunked
    store.append(id, &samples[..4500]).await.unwrap();
    store.append(id, &samples[4500..]).await.unwrap();
    let back = store.recorded_samples(id).await.unwrap();
    assert_same(&back, &samples);
    // The compact load gives the same samples, bit for bit, in the same order.
    let compact = store.samples(id).await.unwrap();
    assert_eq!(compact.len(), samples.len());
    for (c, r) in compact.iter().zip(&samples) {
        let bits = |s: &Sample| {
            (
                s.run,
                s.direction,
                s.target_deg.to_bits(),
                s.readout_deg.to_bits(),
                s.actual_deg.to_bits(),
                s.timestamp_s.map(f64::to_bits),
            )
        };
        assert_eq!(bits(c), bits(&r.sample));
    }
    // The refit's read: the same samples, and each SMR position at its sample's index.
    let (with_smr, smr) = store.samples_with_smr(id, vec![[7.0, 8.0, 9.0]]).await.unwrap();
    assert_eq!(with_smr, compact);
    let mut expected = SmrPositions::after(vec![[7.0, 8.0, 9.0]], 0);
    for (index, r) in samples.iter().enumerate() {
        if let RawReading::Smr(m) = r.raw {
            expected.push(index, m.xyz()).unwrap();
        }
    }
    assert_eq!(expected.sample_indices().count(), 1667);
    assert_eq!(smr, expected);
    assert_eq!(smr.of_samples().map(|(i, _)| i).collect::<Vec<_>>(), expected.sample_indices().collect::<Vec<_>>());
    let latest = samples.iter().filter_map(|r| r.sample.timestamp_s).fold(f64::MIN, f64::max);
    assert_eq!(store.last_sample_time(id).await.unwrap(), Some(latest));
    assert_eq!(store.last_seq(id).await.unwrap(), Some(4999));
    assert_eq!(store.survey(id).await.unwrap().sample_count, 5000);
    // another survey is independent
    let other = store.create_survey(&new_survey()).await.unwrap();
    assert!(store.recorded_samples(other).await.unwrap().is_empty());
    assert!(store.samples(other).await.unwrap().is_empty());
    assert_eq!(store.last_seq(other).await.unwrap(), None);
    assert_eq!(store.last_sample_time(other).await.unwrap(), None);
    store.close().await;
}

#[tokio::test]
async fn duplicate_seq_fails_and_stores_nothing_of_the_batch() {
    let (_dir, store) = temp_store().await;
    let id = store.create_survey(&new_survey()).await.unwrap();
    let first: Vec<RecordedSample> = (0..10).map(recorded).collect();
    store.append(id, &first).await.unwrap();
    // seq 10..1010 then 5 again (in the third chunk)
    let mut batch: Vec<RecordedSample> = (10..1010).map(recorded).collect();
    let mut dup = recorded(5);
    dup.sample.readout_deg = 99.0;
    batch.push(dup);
    let e = store.append(id, &batch).await.unwrap_err();
    assert!(!is_not_found(&e));
    assert!(format!("{e:#}").contains("UNIQUE constraint failed"), "{e:#}");
    assert_same(&store.recorded_samples(id).await.unwrap(), &first);
    // unknown survey: a NotFound
    let e = store.append(999, &first).await.unwrap_err();
    assert!(is_not_found(&e), "{e:#}");
    store.close().await;
}

#[tokio::test]
async fn negative_zero_and_extremes_survive_the_database() {
    let (_dir, store) = temp_store().await;
    let id = store.create_survey(&new_survey()).await.unwrap();
    let mut s = recorded(1);
    s.sample.target_deg = -0.0;
    s.sample.readout_deg = 5e-324;
    s.sample.actual_deg = f64::MAX;
    s.sample.timestamp_s = Some(f64::MIN_POSITIVE);
    store.append(id, &[s.clone()]).await.unwrap();
    let back = store.recorded_samples(id).await.unwrap();
    assert_eq!(back[0].sample.target_deg.to_bits(), (-0.0f64).to_bits());
    assert_same(&back, &[s]);
    let mut nan = recorded(2);
    nan.sample.actual_deg = f64::NAN;
    let e = store.append(id, &[nan]).await.unwrap_err();
    assert!(format!("{e:#}").contains("actual_deg is NaN"), "{e:#}");
    store.close().await;
}

#[tokio::test]
async fn import_is_atomic() {
    let (_dir, store) = temp_store().await;
    let good: Vec<Sample> = (0..1000).map(|i| recorded(i).sample).collect();
    // a CHECK violation (run 0) at the end
    let mut bad = good.clone();
    bad[999].run = 0;
    let s = NewSurvey {
        status: SurveyStatus::Imported,
        source: SurveySource::Import { file: "data.csv".into() },
        setup: Setup::Imported { file: "data.csv".into() },
        ..NewSurvey::default()
    };
    assert!(store.import(&s, &bad).await.is_err());
    assert!(store.list().await.unwrap().is_empty());
    // a failure inside SQLite in the third chunk
    sqlx::query(
        "CREATE TEMP TRIGGER boom BEFORE INSERT ON samples WHEN NEW.seq = 900 \
         BEGIN SELECT RAISE(ABORT, 'boom'); END",
    )
    .execute(store.sqlite().unwrap())
    .await
    .unwrap();
    let e = store.import(&s, &good).await.unwrap_err();
    assert!(format!("{e:#}").contains("boom"), "{e:#}");
    assert!(store.list().await.unwrap().is_empty());
    let n: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM samples").fetch_one(store.sqlite().unwrap()).await.unwrap();
    assert_eq!(n, 0);
    // The failed write retired its connection (store::tx), and the temporary
    // trigger went with it: the next connection has none.
    sqlx::query("DROP TRIGGER IF EXISTS boom").execute(store.sqlite().unwrap()).await.unwrap();

    let id = store.import(&s, &good).await.unwrap();
    let row = store.survey(id).await.unwrap();
    assert_eq!(row.status, SurveyStatus::Imported);
    assert_eq!(row.source, SurveySource::Import { file: "data.csv".into() });
    assert_eq!(row.sample_count, 1000);
    assert_eq!(store.samples(id).await.unwrap(), good);
    assert!(store.recorded_samples(id).await.unwrap().iter().all(|r| r.raw == RawReading::None));
    store.close().await;
}

#[tokio::test]
async fn resolve_latest_and_not_found() {
    let (dir, store) = temp_store().await;
    let e = store.resolve(None).await.unwrap_err();
    assert!(is_not_found(&e));
    assert!(e.to_string().starts_with("no survey in "), "{e}");
    let a = store.create_survey(&new_survey()).await.unwrap();
    let b = store.create_survey(&new_survey()).await.unwrap();
    assert!(b > a);
    assert_eq!(store.resolve(None).await.unwrap().id, b);
    assert_eq!(store.resolve(Some(a.into())).await.unwrap().id, a);
    let e = store.resolve(Some(7.into())).await.unwrap_err();
    assert!(is_not_found(&e));
    assert!(e.downcast_ref::<NotFound>().is_some());
    assert_eq!(e.to_string(), format!("no survey with id 7 in {}", dir.path().join("survey.db").display()));
    assert!(is_not_found(&store.set_status(7, SurveyStatus::Failed, None).await.unwrap_err()));
    assert!(is_not_found(&store.set_axis(7, &axis_fit()).await.unwrap_err()));
    assert!(is_not_found(&store.log_event(7, 0.0, "info", "x").await.unwrap_err()));
    let list = store.list().await.unwrap();
    assert_eq!(list.iter().map(|r| r.id).collect::<Vec<_>>(), vec![a, b]);
    store.close().await;
}

#[tokio::test]
async fn survey_fields_status_axis_events_locate_points() {
    let (_dir, store) = temp_store().await;
    let (id, lock) = store.create_acquired_survey(&new_survey()).await.unwrap();
    let row = store.survey(id).await.unwrap();
    assert_eq!(row.status, SurveyStatus::Running, "its acquirer holds it");
    assert_eq!(row.points, Some(36));
    assert_eq!(row.runs, Some(2));
    assert!(row.bidirectional);
    assert_eq!(row.planned_samples, Some(144));
    assert_eq!(row.model.as_ref().map(|m| m.design.gear_ratios.clone()), Some(vec![12.0]));
    assert_eq!(row.axis, None);
    assert_eq!(row.ended_at_s, None);
    assert_eq!(row.sample_count, 0);
    assert!(row.created_at.ends_with('Z') && row.created_at.contains('T'), "{}", row.created_at);

    drop(lock);
    store.set_started(id, 0.5).await.unwrap();
    store.set_axis(id, &axis_fit()).await.unwrap();
    store.set_status(id, SurveyStatus::Interrupted, None).await.unwrap();
    store.set_status(id, SurveyStatus::Complete, Some(3600.25)).await.unwrap();
    let row = store.survey(id).await.unwrap();
    assert_eq!(row.status, SurveyStatus::Complete);
    assert_eq!(row.started_at_s, Some(0.5));
    assert_eq!(row.ended_at_s, Some(3600.25));
    assert_eq!(row.axis, Some(axis_fit()));

    store.log_event(id, 12.0, "warn", "beam broken, reacquired").await.unwrap();
    store.log_event(id, 13.0, "info", "resumed at seq 40").await.unwrap();
    let ev = store.events(id).await.unwrap();
    assert_eq!(ev.len(), 2);
    assert_eq!((ev[0].at_s, ev[0].level.as_str()), (12.0, "warn"));
    assert_eq!(ev[1].message, "resumed at seq 40");

    let m = |i: f64| SmrMeasurement {
        x_mm: i,
        y_mm: 2.0 * i,
        z_mm: -i,
        std_dev_mm: [0.001, 0.002, 0.003],
        measurement_time_s: 2.0,
        environment: None,
    };
    store.add_locate_points(id, &[(0.0, m(1.0)), (120.0, m(2.0))]).await.unwrap();
    store.add_locate_points(id, &[(240.0, m(3.0))]).await.unwrap();
    let pts = store.locate_points(id).await.unwrap();
    assert_eq!(pts, vec![(0.0, m(1.0)), (120.0, m(2.0)), (240.0, m(3.0))]);

    for st in [
        SurveyStatus::Running,
        SurveyStatus::Interrupted,
        SurveyStatus::Complete,
        SurveyStatus::Failed,
        SurveyStatus::Imported,
    ] {
        assert_eq!(SurveyStatus::from_column(st.as_str()), Some(st));
    }
    store.close().await;
}

/// A survey stored as `running` that no live process holds reads as
/// `interrupted` through every look-up, and is not among the live ones; its
/// stored row is left as it is (readers never write).
#[tokio::test]
async fn a_running_survey_no_process_holds_reads_as_interrupted_everywhere() {
    let (_dir, store) = temp_store().await;
    let stale = store.create_survey(&new_survey()).await.unwrap();
    let (live, lock) = store.create_acquired_survey(&new_survey()).await.unwrap();
    let uid_of = |id: i64| {
        let store = store.clone();
        async move { store.survey(id).await.unwrap().uid }
    };
    let (stale_uid, live_uid) = (uid_of(stale).await, uid_of(live).await);
    let asset = store.survey(stale).await.unwrap().asset;
    let check = |held: bool| {
        let store = store.clone();
        let (stale_uid, live_uid, asset) = (stale_uid.clone(), live_uid.clone(), asset.clone());
        async move {
            let live_status = if held { SurveyStatus::Running } else { SurveyStatus::Interrupted };
            assert_eq!(store.survey(stale).await.unwrap().status, SurveyStatus::Interrupted);
            assert_eq!(store.survey_by_uid(&stale_uid).await.unwrap().status, SurveyStatus::Interrupted);
            assert_eq!(store.survey(live).await.unwrap().status, live_status);
            assert_eq!(store.survey_by_uid(&live_uid).await.unwrap().status, live_status);
            let listed: Vec<_> = store.list().await.unwrap().iter().map(|r| r.status).collect();
            assert_eq!(listed, [SurveyStatus::Interrupted, live_status]);
            let of_asset: Vec<_> = store.surveys_of_asset_uncounted(&asset).await.unwrap();
            assert_eq!(of_asset.iter().map(|r| r.status).collect::<Vec<_>>(), [SurveyStatus::Interrupted, live_status]);
            let running: Vec<i64> = store.running().await.unwrap().iter().map(|r| r.id).collect();
            assert_eq!(running, if held { vec![live] } else { vec![] });
        }
    };
    check(true).await;
    drop(lock);
    check(false).await;
    let stored: Vec<String> =
        sqlx::query_scalar("SELECT status FROM surveys ORDER BY id").fetch_all(store.sqlite().unwrap()).await.unwrap();
    assert_eq!(stored, ["running", "running"], "a reader changes nothing stored");
    // An acquirer that takes the lock again (a resume) is live again.
    let again = AcquirerLock::acquire(store.path(), stale).unwrap();
    assert_eq!(store.survey(stale).await.unwrap().status, SurveyStatus::Running);
    drop(again);
    store.close().await;
}

#[tokio::test]
async fn open_existing_does_not_create() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nothing.db");
    let e = Store::open_existing(&path).await.unwrap_err();
    assert!(is_not_found(&e));
    assert_eq!(
        e.to_string(),
        format!("no survey database at {}: run `survey run` or `survey import` first", path.display())
    );
    assert!(!path.exists());
    // a file that is not a database is a user error too
    let junk = dir.path().join("notes.txt");
    std::fs::write(&junk, "this is not a database, just some text that is long enough to be a header ......................................................").unwrap();
    let e = Store::open_existing(&junk).await.unwrap_err();
    assert!(is_not_found(&e), "{e:#}");
    assert!(e.to_string().contains("notes.txt"), "{e:#}");
    // open() names the path when it cannot create the file
    let e = Store::open(&dir.path().join("no/such/dir/x.db")).await.unwrap_err();
    assert!(format!("{e:#}").contains("no/such/dir/x.db"), "{e:#}");
}

#[tokio::test]
async fn store_sink_flushes_by_batch_and_on_flush() {
    let (_dir, store) = temp_store().await;
    let id = store.create_survey(&new_survey()).await.unwrap();
    let mut sink = StoreSink::new(store.clone(), id).with_batch(10).with_max_age(Duration::from_secs(60));
    for seq in 0..9 {
        sink.record(recorded(seq)).await.unwrap();
    }
    assert_eq!(store.last_seq(id).await.unwrap(), None);
    assert_eq!(sink.pending(), 9);
    // The tenth fills the batch: it goes to a write beside the acquisition,
    // unacknowledged until a later call has waited for it.
    sink.record(recorded(9)).await.unwrap();
    assert_eq!(sink.pending(), 10);
    assert_eq!(sink.last_acknowledged(), None);
    for seq in 10..19 {
        sink.record(recorded(seq)).await.unwrap();
    }
    assert_eq!(sink.pending(), 19);
    // The second batch waits for the first, which is then on disk.
    sink.record(recorded(19)).await.unwrap();
    assert_eq!(sink.last_acknowledged(), Some(9));
    assert_eq!(sink.pending(), 10);
    assert!(store.last_seq(id).await.unwrap() >= Some(9));
    for seq in 20..23 {
        sink.record(recorded(seq)).await.unwrap();
    }
    sink.flush().await.unwrap();
    assert_eq!(store.last_seq(id).await.unwrap(), Some(22));
    assert_eq!(sink.pending(), 0);
    assert_eq!(sink.last_acknowledged(), Some(22));
    sink.flush().await.unwrap(); // nothing to write
    let expected: Vec<RecordedSample> = (0..23).map(recorded).collect();
    assert_same(&store.recorded_samples(id).await.unwrap(), &expected);
    store.close().await;
}

#[tokio::test]
async fn store_sink_flushes_by_age_and_keeps_failed_batches() {
    let (_dir, store) = temp_store().await;
    let id = store.create_survey(&new_survey()).await.unwrap();
    let mut sink = StoreSink::new(store.clone(), id).with_max_age(Duration::from_millis(300));
    sink.record(recorded(0)).await.unwrap();
    sink.record(recorded(1)).await.unwrap();
    assert_eq!(store.last_seq(id).await.unwrap(), None);
    tokio::time::sleep(Duration::from_millis(350)).await;
    // the oldest has waited more than max_age
    sink.record(recorded(2)).await.unwrap();
    assert_eq!(store.last_seq(id).await.unwrap(), Some(2));
    // slow samples (more than max_age apart) are written as they come
    tokio::time::sleep(Duration::from_millis(350)).await;
    sink.record(recorded(3)).await.unwrap();
    assert_eq!(store.last_seq(id).await.unwrap(), Some(3));

    // events and the located axis go straight to the store
    sink.event(4.5, "warn", "beam broken").await.unwrap();
    let m = SmrMeasurement {
        x_mm: 1.0,
        y_mm: 2.0,
        z_mm: 3.0,
        std_dev_mm: [0.01; 3],
        measurement_time_s: 2.0,
        environment: None,
    };
    let fit = axis_fit();
    let pts = [(0.0, m), (120.0, m), (240.0, m)];
    sink.axis_located(&pts, &fit).await.unwrap();
    assert_eq!(store.locate_points(id).await.unwrap(), pts.to_vec());
    assert_eq!(store.survey(id).await.unwrap().axis, Some(fit));
    assert_eq!(store.events(id).await.unwrap()[0].message, "beam broken");

    // a failing write keeps the samples for the next try
    sink.record(recorded(1)).await.unwrap(); // a duplicate seq, buffered
    sink.flush().await.unwrap_err();
    assert_eq!(sink.pending(), 1);
    assert_eq!(sink.last_acknowledged(), Some(3));
    store.close().await;
}

#[tokio::test]
async fn a_failed_write_beside_the_acquisition_gives_its_samples_back_in_order() {
    let (_dir, store) = temp_store().await;
    let id = store.create_survey(&new_survey()).await.unwrap();
    let mut sink = StoreSink::new(store.clone(), id).with_batch(2).with_max_age(Duration::from_secs(60));
    sink.record(recorded(0)).await.unwrap();
    sink.record(recorded(1)).await.unwrap(); // batch [0, 1] written beside
    sink.record(recorded(1)).await.unwrap(); // a duplicate seq
    sink.record(recorded(2)).await.unwrap(); // [0, 1] waited for; [1, 2] written beside, and fails
    assert_eq!(sink.last_acknowledged(), Some(1));
    sink.record(recorded(3)).await.unwrap();
    let e = sink.flush().await.unwrap_err();
    assert!(format!("{e:#}").contains("samples 1..=2"), "{e:#}");
    // Nothing of the failed batch is stored; it is back in front of the buffer.
    assert_eq!(store.last_seq(id).await.unwrap(), Some(1));
    assert_eq!(sink.pending(), 3);
    assert_eq!(sink.last_acknowledged(), Some(1));
    let e = sink.flush().await.unwrap_err();
    assert!(format!("{e:#}").contains("samples 1..=3"), "in order, the failed batch first: {e:#}");
    store.close().await;
}

/// What another process sees of a survey's samples (a fresh connection).
async fn on_disk(path: &std::path::Path, id: i64) -> u64 {
    let other = Store::open_existing(path).await.unwrap();
    let n = other.sample_count(id).await.unwrap();
    other.close().await;
    n
}

/// Fill the database until a write fails (the sink in batches of 100), then
/// check that every later write fails or is really stored, that the store
/// claims what is on disk, and that after space is freed the rest is written.
async fn fill_until_full(path: &std::path::Path, store: Store, free_space: impl FnOnce()) {
    let id = store.create_survey(&new_survey()).await.unwrap();
    let mut sink = StoreSink::new(store.clone(), id).with_batch(100);
    let mut failed_at = None;
    for seq in 0..1_000_000 {
        if let Err(e) = sink.record(recorded(seq)).await {
            assert!(format!("{e:#}").contains("full"), "{e:#}");
            // Said in words, once, without SQLite's codes (issue 51).
            let said = crate::error::said(&e);
            assert!(said.contains("the disk is full") && !said.contains("code: 13"), "{said}");
            failed_at = Some(seq);
            break;
        }
    }
    let failed_at = failed_at.expect("the database filled up");
    let acknowledged = sink.last_acknowledged().map_or(0, |s| s + 1);
    assert!(acknowledged > 0 && acknowledged <= failed_at, "{acknowledged} acknowledged of {failed_at}");
    assert_eq!(on_disk(path, id).await, acknowledged, "what another process sees is what was acknowledged");
    // Later writes: a batch either fails or is really stored (a small one may
    // fit in a page's free space); the store never claims what is not on disk.
    for _ in 0..3 {
        let flushed = sink.flush().await;
        let claim = store.sample_count(id).await;
        let disk = on_disk(path, id).await;
        if let Ok(claim) = claim {
            assert_eq!(claim, disk, "the store's claim after a flush that returned {flushed:?}");
        }
        let expected = sink.last_acknowledged().map_or(0, |s| s + 1);
        assert_eq!(disk, expected, "acknowledged means on disk (flush returned {flushed:?})");
    }
    // The other writes go through the same guarded transaction: an event too
    // big for the space left fails, and is nowhere, not even in a transaction
    // left open on a pooled connection that a later write would commit.
    let events_before = store.events(id).await.unwrap().len();
    let big = "x".repeat(512 * 1024);
    let e = store.log_event(id, 1.0, "warn", &big).await.unwrap_err();
    assert!(format!("{e:#}").contains("full") && format!("{e:#}").contains("event"), "{e:#}");
    for _ in 0..4 {
        // Each either fails or is stored; none commits the failed event.
        let _ = store.log_event(id, 2.0, "info", "small").await;
        let _ = store.set_status(id, SurveyStatus::Interrupted, Some(3.0)).await;
    }
    let other = Store::open_existing(path).await.unwrap();
    let seen = other.events(id).await.unwrap();
    other.close().await;
    assert!(seen.iter().all(|ev| ev.message != big), "the failed event is not stored");
    assert!(seen.len() >= events_before && seen.len() <= events_before + 4, "{} events", seen.len());
    let stored = on_disk(path, id).await;
    store.close().await;
    drop(sink);

    // Space is freed: what was not stored is written, each sample once.
    free_space();
    let store = Store::open(path).await.unwrap();
    let rest: Vec<RecordedSample> = (stored..failed_at + 1).map(recorded).collect();
    store.append(id, &rest).await.unwrap();
    assert_eq!(on_disk(path, id).await, failed_at + 1);
    store.log_event(id, 4.0, "info", "space freed").await.unwrap();
    assert_eq!(store.events(id).await.unwrap().last().unwrap().message, "space freed");
    store.close().await;
}

#[tokio::test]
async fn a_full_database_fails_every_write_and_claims_only_what_is_on_disk() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("full.db");
    // 64 pages of 4 KiB: the schema and a few batches fit, then SQLITE_FULL,
    // the error a full disk gives (at page allocation rather than at commit).
    fill_until_full(&path, Store::open_limited(&path, 64).await.unwrap(), || {}).await;
}

/// The same on a really full file system, where the failure comes when the
/// commit writes the WAL: set `SURVEY_TEST_SMALL_FS` to a folder on a small
/// file system (e.g. `mount -t tmpfs -o size=2M tmpfs /mnt/small`). Skipped,
/// saying so, when it is not set.
#[tokio::test]
async fn a_full_file_system_fails_every_write_and_claims_only_what_is_on_disk() {
    let Some(dir) = std::env::var_os("SURVEY_TEST_SMALL_FS") else {
        eprintln!("skipped: SURVEY_TEST_SMALL_FS names no folder on a small file system");
        return;
    };
    let path = std::path::Path::new(&dir).join(format!("full-{}.db", std::process::id()));
    // Ballast, deleted to free space once the database has filled the rest.
    let ballast = std::path::Path::new(&dir).join(format!("ballast-{}", std::process::id()));
    std::fs::write(&ballast, vec![1u8; 256 * 1024]).unwrap();
    fill_until_full(&path, Store::open(&path).await.unwrap(), || std::fs::remove_file(&ballast).unwrap()).await;
    for suffix in ["", "-wal", "-shm"] {
        let _ = std::fs::remove_file(format!("{}{suffix}", path.display()));
    }
    // In the same test: the two share the small file system.
    a_full_file_system_still_stores_the_status_and_resumes(std::path::Path::new(&dir)).await;
}

/// An acquisition whose disk fills up: every write fails, a status write
/// too, and yet the survey's status is stored as `interrupted` (the
/// reserve its lock file kept is given back for it); once space is freed, the
/// survey is resumed from its last stored sample to the end.
async fn a_full_file_system_still_stores_the_status_and_resumes(dir: &std::path::Path) {
    let path = dir.join(format!("full-status-{}.db", std::process::id()));
    let ballast = dir.join(format!("ballast-status-{}", std::process::id()));
    std::fs::write(&ballast, vec![1u8; 256 * 1024]).unwrap();
    let store = Store::open(&path).await.unwrap();
    let (id, lock) = store.create_acquired_survey(&new_survey()).await.unwrap();
    let mut sink = StoreSink::new(store.clone(), id).with_batch(100);
    let mut planned = None;
    for seq in 0..1_000_000 {
        if sink.record(recorded(seq)).await.is_err() {
            planned = Some(seq + 100);
            break;
        }
    }
    let planned = planned.expect("the disk filled up");
    // Whatever status write still fits (into the log's slack) is made, until
    // none does: the disk has no room left for the status.
    let mut refused = false;
    for n in 0..10_000 {
        if store.write_status(id, SurveyStatus::Running, Some(f64::from(n))).await.is_err() {
            refused = true;
            break;
        }
    }
    assert!(refused, "the disk is full");
    store.set_status(id, SurveyStatus::Interrupted, Some(7.0)).await.expect("the reserve holds the status");
    drop(sink);
    store.close().await;
    let stored = || async {
        let conn = rusqlite::Connection::open_with_flags(&path, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY).unwrap();
        conn.query_row("SELECT status FROM surveys WHERE id = ?1", [id], |r| r.get::<_, String>(0)).unwrap()
    };
    assert_eq!(stored().await, "interrupted", "the status on disk");
    drop(lock);

    // Space freed: a resume takes the lock (and its reserve) again and
    // stores the rest, each sample once.
    std::fs::remove_file(&ballast).unwrap();
    let lock = AcquirerLock::acquire(&path, id).unwrap();
    assert!(std::fs::metadata(lock.path()).unwrap().len() > RESERVE_BYTES, "the reserve is kept again");
    let store = Store::open_existing(&path).await.unwrap();
    let next = store.last_seq(id).await.unwrap().map_or(0, |s| s + 1);
    store.set_status(id, SurveyStatus::Running, None).await.unwrap();
    let rest: Vec<RecordedSample> = (next..planned).map(recorded).collect();
    store.append(id, &rest).await.unwrap();
    store.set_status(id, SurveyStatus::Complete, None).await.unwrap();
    assert_eq!(store.sample_count(id).await.unwrap(), planned);
    assert_eq!(store.survey(id).await.unwrap().status, SurveyStatus::Complete);
    store.close().await;
    drop(lock);
    assert_eq!(stored().await, "complete");
    for suffix in ["", "-wal", "-shm"] {
        let _ = std::fs::remove_file(format!("{}{suffix}", path.display()));
    }
}

#[tokio::test]
async fn another_writer_holding_the_lock_delays_a_write_but_never_fails_it_within_the_bounded_wait() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("busy.db");
    let limits = StoreLimits { busy_timeout: Duration::from_millis(50), max_pages: None };
    let store = Store::open_with(&path, limits).await.unwrap();
    let id = store.create_survey(&new_survey()).await.unwrap();

    // Another process's long write (an import): it holds the write lock for
    // 300 ms, six times this store's busy timeout.
    let hold = |ms: u64| {
        let other = rusqlite::Connection::open(&path).unwrap();
        other.execute_batch("BEGIN IMMEDIATE").unwrap();
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(ms));
            other.execute_batch("COMMIT").unwrap();
        })
    };
    let holder = hold(300);
    let mut sink = StoreSink::new(store.clone(), id).with_batch(1000);
    for seq in 0..10 {
        sink.record(recorded(seq)).await.unwrap();
    }
    sink.flush().await.expect("the write waits for the lock instead of failing");
    assert_eq!(store.sample_count(id).await.unwrap(), 10);
    holder.join().unwrap();

    // The wait is bounded: a sink allowed 100 ms gives up on a 500 ms lock, with
    // the busy error, and keeps its samples for the next try.
    let holder = hold(500);
    let mut impatient = StoreSink::new(store.clone(), id).with_batch(1000).with_busy_wait(Duration::from_millis(100));
    impatient.record(recorded(10)).await.unwrap();
    let e = impatient.flush().await.unwrap_err();
    assert!(is_busy(&e), "{e:#}");
    assert_eq!(impatient.pending(), 1);
    holder.join().unwrap();
    impatient.flush().await.unwrap();
    assert_eq!(store.sample_count(id).await.unwrap(), 11);
    store.close().await;
}

/// Processes that open a new database at the same moment (a `run` beside an
/// `import`) each find it without a schema: every one of them ends with the
/// schema set up once, none fails with "table surveys already exists".
#[test]
fn many_openers_of_a_new_database_set_its_schema_up_once() {
    crate::runtime::block_on_bounded(4, async {
        for round in 0..20 {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join(format!("race{round}.db"));
            let opens = (0..6).map(|_| {
                let path = path.clone();
                tokio::spawn(async move { Store::open(&path).await })
            });
            for open in futures_util::future::join_all(opens).await {
                let store = open.unwrap().unwrap_or_else(|e| panic!("round {round}: {e:#}"));
                store.close().await;
            }
            let store = Store::open_read_only(&path).await.unwrap();
            store.close().await;
        }
    })
    .expect("a runtime");
}

/// A database of schema 5 (before `processing`) with surveys, samples, raw
/// readings and events: migration 6 rebuilds `surveys` to allow the new
/// status, keeping every row as it was (ids, dates, every column), and every
/// foreign key still holds and is still enforced.
#[tokio::test]
async fn the_processing_migration_rebuilds_surveys_keeping_every_row_and_foreign_key() {
    use sqlx::migrate::{Migration, MigrationType, Migrator};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v5.db");
    let options = SqliteConnectOptions::new().filename(&path).create_if_missing(true).foreign_keys(true);
    let pool = single_connection_pool().connect_with(options).await.unwrap();
    let first_five = MIGRATIONS[..5]
        .iter()
        .map(|&(v, d, sql)| Migration::new(v, Cow::Borrowed(d), MigrationType::Simple, sql.into_sql_str(), false))
        .collect();
    Migrator::with_migrations(first_five).run(&pool).await.unwrap();
    sqlx::query(
        "INSERT INTO surveys (id, created_at, updated_at, status, source, points, runs, config_json, ended_at_s, uid, \
         asset, check_of) VALUES \
         (3, '2026-01-02T03:04:05Z', '2026-01-02T05:00:00Z', 'complete', 'simulated', 36, 2, '{}', 12.5, \
          '0b6c1a52-0000-4000-8000-000000000003', 'bay-2/az', NULL), \
         (7, '2026-02-03T04:05:06Z', '2026-02-03T04:05:06Z', 'interrupted', 'import:a.csv', NULL, NULL, '{}', NULL, \
          '0b6c1a52-0000-4000-8000-000000000007', 'bay-2/az', '0b6c1a52-0000-4000-8000-000000000003'); \
         INSERT INTO samples (survey_id, seq, run, direction, target_deg, readout_deg, actual_deg) VALUES \
         (3, 0, 1, 'forward', 0.0, 0.001, -0.0), (7, 0, 1, 'reverse', 10.0, 10.5, 10.25); \
         INSERT INTO raw_readings (survey_id, seq, kind, ac_face, ac_x_arcsec) VALUES (3, 0, 'autocollimator', 1, 0.5); \
         INSERT INTO events (survey_id, level, message) VALUES (3, 'info', 'kept'), (7, 'warn', 'also kept');",
    )
    .execute(&pool)
    .await
    .unwrap();
    pool.close().await;
    // Every row of every table, each value with its SQLite type.
    let dump = |path: &std::path::Path| {
        let c = rusqlite::Connection::open(path).unwrap();
        let mut all = Vec::new();
        for table in ["surveys", "samples", "raw_readings", "events"] {
            // The columns of migration 5 (migration 9 adds the air's, NULL for every row before it).
            let columns = match table {
                "raw_readings" => {
                    "survey_id, seq, kind, smr_x_mm, smr_y_mm, smr_z_mm, smr_sx_mm, smr_sy_mm, smr_sz_mm, \
                     measurement_time_s, ac_face, ac_x_arcsec, ac_y_arcsec"
                }
                _ => "*",
            };
            let mut stmt = c.prepare(&format!("SELECT {columns} FROM {table} ORDER BY 1, 2")).unwrap();
            let n = stmt.column_count();
            let rows = stmt
                .query_map([], |r| Ok((0..n).map(|i| format!("{:?}", r.get_ref(i).unwrap())).collect::<Vec<_>>()))
                .unwrap();
            all.extend(rows.map(|r| format!("{table}: {}", r.unwrap().join(", "))));
        }
        all
    };
    let before = dump(&path);
    assert_eq!(before.len(), 7);

    let store = Store::open(&path).await.unwrap();
    store.close().await;
    assert_eq!(dump(&path), before, "every row kept as it was");
    let store = Store::open(&path).await.unwrap();
    let version: i64 = sqlx::query_scalar("SELECT MAX(version) FROM _sqlx_migrations")
        .fetch_one(store.sqlite().unwrap())
        .await
        .unwrap();
    assert_eq!(version, MIGRATIONS.last().unwrap().0);
    // Migration 5's indexes are there again.
    let indexes: Vec<String> = sqlx::query_scalar(
        "SELECT name FROM sqlite_master WHERE type = 'index' AND tbl_name = 'surveys' ORDER BY name",
    )
    .fetch_all(store.sqlite().unwrap())
    .await
    .unwrap();
    assert_eq!(indexes, ["surveys_by_asset", "surveys_by_uid"]);
    let check: Vec<sqlx::sqlite::SqliteRow> =
        sqlx::query("PRAGMA foreign_key_check").fetch_all(store.sqlite().unwrap()).await.unwrap();
    assert!(check.is_empty(), "every sample, reading and event still has its survey");
    // The new status is allowed; foreign keys are enforced again.
    store.set_status(3, SurveyStatus::Processing, None).await.unwrap();
    assert_eq!(store.survey(3).await.unwrap().status, SurveyStatus::Processing);
    assert!(store.append(99, &[recorded(0)]).await.is_err(), "a sample of no survey is refused");
}

/// Check points (issue 20): acquired as a `resolving` survey, which "the
/// latest survey" skips (resume finds it), then folded into the survey they
/// resolve in one transaction, that survey removed with everything of it, so
/// the next survey takes its id again.
#[tokio::test]
async fn check_points_fold_into_their_survey_and_free_their_id() {
    let (_dir, store) = temp_store().await;
    let main = store.create_survey(&new_survey()).await.unwrap();
    let checks = store
        .create_survey(&NewSurvey {
            source: SurveySource::Resolving,
            instruments: serde_json::json!({"resolves_survey": main}),
            ..new_survey()
        })
        .await
        .unwrap();
    assert_eq!(store.resolve(None).await.unwrap().id, main, "the latest survey is not its check points");
    assert_eq!(store.resolve_any(None).await.unwrap().id, checks, "resume finds them");
    assert_eq!(store.survey(checks).await.unwrap().resolves, Some(main));
    let samples: Vec<RecordedSample> = (0..40).map(recorded).collect();
    store.append(checks, &samples).await.unwrap();
    store.log_event(checks, 1.0, "info", "measured").await.unwrap();
    assert_eq!(store.fold_check_points(checks, main).await.unwrap(), 40);
    let folded = store.check_points(main).await.unwrap();
    assert_eq!(folded.len(), 40);
    for (f, r) in folded.iter().zip(&samples) {
        assert_eq!(
            (f.target_deg.to_bits(), f.actual_deg.to_bits(), f.run),
            (r.sample.target_deg.to_bits(), r.sample.actual_deg.to_bits(), r.sample.run)
        );
    }
    assert!(is_not_found(&store.survey(checks).await.unwrap_err()), "the check-point survey is gone");
    assert!(store.events(checks).await.unwrap().is_empty());
    // Their events (the faults met measuring them) are the survey's, said to be theirs.
    let kept: Vec<String> = store.events(main).await.unwrap().into_iter().map(|e| e.message).collect();
    assert_eq!(kept, ["check points: measured"]);
    assert_eq!(store.create_survey(&new_survey()).await.unwrap(), checks, "its id is free again");
    assert!(store.check_points(checks).await.unwrap().is_empty());
    store.close().await;
}

#[tokio::test]
async fn the_air_of_every_tracker_measurement_is_kept_and_summarised() {
    let (_dir, store) = temp_store().await;
    let id = store.create_survey(&new_survey()).await.unwrap();
    assert_eq!(store.environment(id).await.unwrap(), None, "nothing measured yet");
    let air =
        |t: f64| survey_drivers::AirEnvironment { temperature_c: t, pressure_hpa: 1000.0 + t, humidity_pct: 40.0 };
    let batch: Vec<RecordedSample> = (0..6u64)
        .map(|seq| {
            let mut r = recorded(seq);
            if let RawReading::Smr(m) = &mut r.raw {
                m.environment = Some(air(20.0 + seq as f64 / 10.0));
            }
            r
        })
        .collect();
    store.append(id, &batch).await.unwrap();
    // Seqs 1 and 4 are tracker measurements (see `recorded`).
    let measured: Vec<f64> = batch
        .iter()
        .filter_map(|r| match &r.raw {
            RawReading::Smr(m) => m.environment.map(|a| a.temperature_c),
            _ => None,
        })
        .collect();
    let m = store.environment(id).await.unwrap().expect("the air measured");
    assert_eq!(m.count as usize, measured.len());
    let mean = measured.iter().sum::<f64>() / measured.len() as f64;
    assert_eq!((m.temperature_c.min, m.temperature_c.max), (measured[0], *measured.last().unwrap()));
    assert!((m.temperature_c.mean - mean).abs() < 1e-12 && (m.pressure_hpa.mean - 1000.0 - mean).abs() < 1e-9);
    assert_eq!(m.humidity_pct.max, 40.0);
    let series = store.temperature_series(id).await.unwrap();
    assert_eq!(series.iter().map(|p| p.1).collect::<Vec<_>>(), measured, "against time, in seq order");
}

#[tokio::test]
async fn the_other_smrs_readings_are_stored_with_their_sample_and_read_back_in_order() {
    let (_dir, store) = temp_store().await;
    let id = store.create_survey(&new_survey()).await.unwrap();
    assert!(store.other_smr_positions(id).await.unwrap().is_empty(), "one SMR: none");
    let smr = |x: f64| SmrMeasurement {
        x_mm: x,
        y_mm: 2.0 * x,
        z_mm: -x,
        std_dev_mm: [0.004; 3],
        measurement_time_s: 1.0,
        environment: None,
    };
    let samples: Vec<RecordedSample> = (0..5u64)
        .map(|seq| RecordedSample { others: vec![smr(seq as f64 + 0.5), smr(seq as f64 + 0.25)], ..recorded(seq) })
        .collect();
    store.append(id, &samples).await.unwrap();
    let back = store.other_smr_positions(id).await.unwrap();
    assert_eq!(back.len(), 10);
    assert_eq!(back[0], (0, 1, [0.5, 1.0, -0.5]));
    assert_eq!(back[1], (0, 2, [0.25, 0.5, -0.25]));
    assert_eq!(back[9], (4, 2, [4.25, 8.5, -4.25]));
    // A sample whose other SMR's reading cannot be stored is not stored either.
    let bad = RecordedSample { others: vec![smr(1.0)], ..recorded(5) };
    let dup = RecordedSample { seq: 6, others: vec![smr(1.0)], ..recorded(5) };
    store.append(id, &[bad, dup.clone()]).await.unwrap();
    let e = store.append(id, &[dup]).await.unwrap_err();
    assert!(format!("{e:#}").contains("UNIQUE constraint failed"), "{e:#}");
    assert_eq!(store.other_smr_positions(id).await.unwrap().len(), 12);
    store.close().await;
}

/// A configured survey's asset is its configuration's `[asset] id`, else
/// the unassigned one (the configuration's own checks are survey-config's).
#[test]
fn the_configured_asset_is_the_surveys() {
    use crate::config::SurveyConfig;
    use crate::survey::ConfiguredSetup;
    let bench =
        "[positioner]\ndriver = \"scpi-tcp\"\naddress = \"h:1\"\n[tracker]\ndriver = \"emscon\"\naddress = \"h:700\"\n";
    let plan = survey_plan::SurveyPlan::full_circle(36, 2, true).unwrap();
    let setup = |config| Setup::Configured(ConfiguredSetup { config, plan: plan.clone() });
    let cfg = SurveyConfig::parse(&format!("{bench}[asset]\nid = \"bay-2/az\"\n"), "c.toml").unwrap();
    assert_eq!(setup(cfg).default_asset(), "bay-2/az");
    let without = SurveyConfig::parse(bench, "c.toml").unwrap();
    assert_eq!(setup(without).default_asset(), crate::asset::UNASSIGNED);
}
