//! The engine's own cost (issue 12): surveys on the simulated bench, whose
//! instruments run on a virtual clock (a move, a settle or a 1 s tracker
//! measurement takes no real time), so the wall time is what the engine,
//! the simulators' arithmetic and the sink cost; and SQLite's write rate.
//!
//! - `step`: the Figure 8 positioner and a tracker, 360 points x 2 runs,
//!   both directions (1440 samples and 12 locate points), into memory;
//! - `continuous`: the same plan scanned continuously (4 passes paired from
//!   their streams), into memory;
//! - `store`: 18000 samples (the default survey) written through
//!   [`StoreSink`] into a new SQLite database, in its batches.
//!
//! Each case prints the instrument time a sample costs on the simulated
//! instruments (their real speeds), so the overhead can be read as a
//! fraction of it. `cargo bench -p survey-lab --bench engine`

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use std::time::Duration;
use survey_acquire::ReferenceKind;
use survey_acquire::{MemorySink, RawReading, RecordedSample, SampleSink};
use survey_bench::{Bench, SimulatedRequest};
use survey_plan::ScanMode;
use survey_processing::{Direction, Sample};
use survey_store::survey::{NewSurvey, SurveySource, SurveyStatus};
use survey_store::{Store, StoreSink};

const POINTS: u32 = 360;
const RUNS: u32 = 2;

fn bench_of(scan: ScanMode) -> Bench {
    Bench::simulated(&SimulatedRequest {
        points: POINTS,
        runs: Some(RUNS),
        bidirectional: true,
        preset: "fig8".into(),
        model_file: None,
        reference: ReferenceKind::Tracker,
        seed: 1,
        scan,
        faults: None,
        smrs: 0,
        polygon_turns: Vec::new(),
    })
    .expect("the simulated bench")
}

/// One survey; its instrument time.
async fn survey(mut bench: Bench) -> Duration {
    let mut sink = MemorySink::default();
    let plan = bench.plan.clone();
    let outcome = bench.engine.run(&plan, 0, &mut sink, &mut |_| {}).await.expect("the survey runs");
    assert_eq!(sink.samples.len() as u64, plan.total_steps());
    outcome.instrument_time
}

/// `n` samples of a bidirectional survey with SMR readings.
fn samples(n: u64) -> Vec<RecordedSample> {
    let per_pass = 1800;
    (0..n)
        .map(|seq| {
            let pass = seq / per_pass;
            let direction = if pass % 2 == 0 { Direction::Forward } else { Direction::Reverse };
            let target = (seq % per_pass) as f64 * 0.2;
            let smr = survey_drivers::SmrMeasurement {
                x_mm: 1000.0 * target.to_radians().cos(),
                y_mm: 1000.0 * target.to_radians().sin(),
                z_mm: 12.5,
                std_dev_mm: [0.012; 3],
                measurement_time_s: 1.0,
                environment: None,
            };
            RecordedSample {
                seq,
                others: Vec::new(),
                sample: Sample {
                    run: (pass / 2 + 1) as u32,
                    direction,
                    target_deg: target,
                    readout_deg: target,
                    actual_deg: target - 0.004,
                    timestamp_s: Some(seq as f64 * 1.5),
                },
                raw: RawReading::Smr(smr),
            }
        })
        .collect()
}

async fn store_all(db: &std::path::Path, samples: Vec<RecordedSample>) {
    let store = Store::open(db).await.expect("the database opens");
    let id = store
        .create_survey(&NewSurvey {
            status: SurveyStatus::Running,
            source: SurveySource::Simulated,
            points: Some(1800),
            runs: Some(5),
            bidirectional: true,
            ..NewSurvey::default()
        })
        .await
        .expect("a survey");
    let mut sink = StoreSink::new(store.clone(), id);
    for s in samples {
        sink.record(s).await.expect("recorded");
    }
    sink.flush().await.expect("flushed");
    store.close().await;
}

fn bench(c: &mut Criterion) {
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().expect("a runtime");
    let n = u64::from(POINTS * RUNS * 2);
    let mut g = c.benchmark_group("engine");
    g.sample_size(10);
    g.throughput(Throughput::Elements(n));
    for (name, scan) in [("step", ScanMode::Step), ("continuous", ScanMode::Continuous)] {
        let t = rt.block_on(survey(bench_of(scan)));
        eprintln!(
            "{name}: {n} samples in {:.0} s of instrument time, {:.1} ms a sample",
            t.as_secs_f64(),
            t.as_secs_f64() / n as f64 * 1e3
        );
        g.bench_function(format!("{name} survey, {POINTS} points x {RUNS} runs x 2 directions, memory sink"), |b| {
            b.iter_batched(|| bench_of(scan), |bench| rt.block_on(survey(bench)), BatchSize::PerIteration)
        });
    }
    g.finish();

    let dir = tempfile::tempdir().expect("a temporary folder");
    let count = 18_000u64;
    let mut g = c.benchmark_group("store");
    g.sample_size(10);
    g.throughput(Throughput::Elements(count));
    let mut k = 0u32;
    g.bench_function(format!("{count} samples through StoreSink into a new database"), |b| {
        b.iter_batched(
            || {
                k += 1;
                (dir.path().join(format!("s{k}.db")), samples(count))
            },
            |(db, s)| rt.block_on(store_all(&db, s)),
            BatchSize::PerIteration,
        )
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
