//! `survey process` and `survey model-gap` as the commands do them, store to
//! result: open the database, read the survey record, load its samples, process
//! them and write every file (process), or compare them with the model
//! (model-gap); and the floor under both, reading the samples and nothing
//! else. Surveys of 360, 3600 and 36000 points x 5 runs x both directions
//! (3600, 36000 and 360000 samples) and of 36000 points x 25 runs (1.8 M
//! samples) of the paper's Figure 8 positioner, stored once per size in a
//! temporary database.
//!
//! Besides the times, each case prints the peak heap it allocated (the
//! `peakmem-alloc` counting allocator: the most bytes live during one call
//! above what was live before it, from the store's read to the last file
//! written). SQLite's own memory (its page cache) comes from the C allocator
//! and is not counted here; `scripts/compare_process.sh` gives the whole
//! binary's peak resident memory and times the whole binary against the
//! numpy program.
//!
//! `cargo bench -p survey-lab --bench process` (`-- --save-baseline NAME`
//! and `-- --baseline NAME` compare two builds: a change beyond 5 % at 1 %
//! significance is reported as a regression or an improvement).

use criterion::{Criterion, criterion_group, criterion_main};
use peakmem_alloc::{INSTRUMENTED_SYSTEM, PeakMemAlloc, PeakMemAllocTrait};
use rand::{Rng as _, SeedableRng as _};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::alloc::System;
use std::path::Path;
use survey_lab::process::{ProcessOptions, process_survey};
use survey_modelgap::{ModelGapOptions, model_gap};
use survey_processing::model::Model;
use survey_processing::{Direction, Sample};
use survey_store::Store;
use survey_store::survey::{NewSurvey, Setup, SurveySource, SurveyStatus};

#[global_allocator]
static ALLOCATOR: &PeakMemAlloc<System> = &INSTRUMENTED_SYSTEM;

fn fig8() -> Model {
    Model::parse(include_str!("../../sims/presets/fig8.toml"), "fig8.toml").expect("the preset parses")
}

/// `points` x `runs` bidirectional runs of the Figure 8 positioner, with noise.
fn samples(model: &Model, points: u32, runs: u32) -> Vec<Sample> {
    let sigma = model.noise_sigma_deg();
    let mut rng = ChaCha8Rng::seed_from_u64(u64::from(points));
    let step = 360.0 / f64::from(points);
    let mut out = Vec::with_capacity(points as usize * runs as usize * 2);
    let mut t = 0.0;
    for run in 1..=runs {
        for direction in [Direction::Forward, Direction::Reverse] {
            for j in 0..points {
                let k = if direction == Direction::Forward { j } else { points - 1 - j };
                let target = f64::from(k) * step;
                let e = model.repeatable_error_deg(target, direction) + sigma * rng.sample::<f64, _>(StandardNormal);
                t += 2.0;
                out.push(Sample {
                    run,
                    direction,
                    target_deg: target,
                    readout_deg: target,
                    actual_deg: target - e,
                    timestamp_s: Some(t),
                });
            }
        }
    }
    out
}

/// One stored survey per size, in `dir`.
async fn store(dir: &Path, model: &Model, (points, runs): (u32, u32)) -> std::path::PathBuf {
    let db = dir.join(format!("s{points}x{runs}.db"));
    let store = Store::open(&db).await.expect("the database opens");
    let new = NewSurvey {
        status: SurveyStatus::Complete,
        source: SurveySource::Simulated,
        points: Some(points),
        runs: Some(runs),
        bidirectional: true,
        setup: Setup::Unrecorded,
        model: Some(model.clone()),
        planned_samples: Some(u64::from(points) * u64::from(runs) * 2),
        ..NewSurvey::default()
    };
    store.import(&new, &samples(model, points, runs)).await.expect("the survey is stored");
    store.close().await;
    db
}

/// `survey process`: open, read the record, load, process, write the files.
async fn process(db: &Path, out: &Path) {
    let store = Store::open_existing(db).await.expect("the database opens");
    let record = store.resolve(None).await.expect("the survey");
    let samples = store.samples(record.id).await.expect("the samples");
    let opts = ProcessOptions { table_out: Some(out.join("t.csv")), ..ProcessOptions::default() };
    process_survey(&record, &samples, opts).expect("processed");
    store.close().await;
}

/// The floor under `survey process`: open, read the record, load the
/// samples, and nothing else.
async fn read(db: &Path) {
    let store = Store::open_existing(db).await.expect("the database opens");
    let record = store.resolve(None).await.expect("the survey");
    let samples = store.samples(record.id).await.expect("the samples");
    assert!(!samples.is_empty());
    store.close().await;
}

/// `survey model-gap`: open, read the record, load, compare with the model.
async fn gap(db: &Path, model: &Model) {
    let store = Store::open_existing(db).await.expect("the database opens");
    let record = store.resolve(None).await.expect("the survey");
    let samples = store.samples(record.id).await.expect("the samples");
    model_gap(&samples, model, &ModelGapOptions::default()).expect("compared");
    store.close().await;
}

/// The peak heap of one call of `f` above what was live before it, in MiB.
fn peak_mib(rt: &tokio::runtime::Runtime, f: impl std::future::Future<Output = ()>) -> f64 {
    ALLOCATOR.reset_peak_memory();
    rt.block_on(f);
    ALLOCATOR.get_peak_memory() as f64 / (1024.0 * 1024.0)
}

fn bench(c: &mut Criterion) {
    let rt = tokio::runtime::Builder::new_multi_thread().enable_all().build().expect("a runtime");
    let dir = tempfile::tempdir().expect("a temporary folder");
    let model = fig8();
    let mut g = c.benchmark_group("command");
    g.sample_size(10);
    // 360 to 36000 points x 5 runs (3600 to 360000 samples), and 36000
    // points x 25 runs (1.8 M): issue 47's two sizes among them. Set
    // SURVEY_BENCH_LARGE=0 to leave out the 1.8 M case.
    let large = std::env::var("SURVEY_BENCH_LARGE").map_or(true, |v| v != "0");
    let sizes = [(360u32, 5u32), (3600, 5), (36000, 5), (36000, 25)];
    for (points, runs) in sizes.into_iter().filter(|(_, r)| large || *r == 5) {
        let db = rt.block_on(store(dir.path(), &model, (points, runs)));
        let n = points * runs * 2;
        eprintln!(
            "{n} samples: peak heap process {:.1} MiB, model-gap {:.1} MiB",
            peak_mib(&rt, process(&db, dir.path())),
            peak_mib(&rt, gap(&db, &model))
        );
        g.bench_function(format!("survey process, {n} samples"), |b| b.iter(|| rt.block_on(process(&db, dir.path()))));
        g.bench_function(format!("reading the samples, {n} samples"), |b| b.iter(|| rt.block_on(read(&db))));
        if runs == 5 {
            g.bench_function(format!("survey model-gap, {n} samples"), |b| b.iter(|| rt.block_on(gap(&db, &model))));
        }
    }
    g.finish();
}

// A change is reported only beyond 5 % and at 1 % significance: against a
// saved baseline (`-- --save-baseline main`, then `-- --baseline main`) a
// 20 % regression of `survey process` stands far out of the noise
// (docs/performance.md shows one).
criterion_group! {
    name = benches;
    config = Criterion::default().noise_threshold(0.05).significance_level(0.01);
    targets = bench
}
criterion_main!(benches);
