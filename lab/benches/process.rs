//! `survey process` and `survey model-gap` as the commands do them, store to
//! result: open the database, read the survey record, load its samples, process
//! them and write every file (process), or compare them with the model
//! (model-gap). Surveys of 360, 3600 and 36000 points x 5 runs x both
//! directions (3600, 36000 and 360000 samples) of the paper's Figure 8
//! positioner, stored once per size in a temporary database.
//!
//! Besides the times, each case prints the peak heap it allocated (the
//! `peakmem-alloc` counting allocator: the most bytes live during one call
//! above what was live before it, from the store's read to the last file
//! written). SQLite's own memory (its page cache) comes from the C allocator
//! and is not counted here; `scripts/compare_process.sh` gives the whole
//! binary's peak resident memory. The goals: 360000
//! samples under 150 MiB peak (target 100) and at least 5x faster than the
//! old loader (3.4 s, 890 MiB); `scripts/compare_process.sh` times the whole
//! binary against the numpy/scipy script.
//!
//! `cargo bench -p survey-lab --bench process`

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

/// `points` x 5 bidirectional runs of the Figure 8 positioner, with noise.
fn samples(model: &Model, points: u32) -> Vec<Sample> {
    let sigma = model.noise_sigma_deg();
    let mut rng = ChaCha8Rng::seed_from_u64(u64::from(points));
    let step = 360.0 / f64::from(points);
    let mut out = Vec::with_capacity(points as usize * 10);
    let mut t = 0.0;
    for run in 1..=5 {
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
async fn store(dir: &Path, model: &Model, points: u32) -> std::path::PathBuf {
    let db = dir.join(format!("s{points}.db"));
    let store = Store::open(&db).await.expect("the database opens");
    let new = NewSurvey {
        status: SurveyStatus::Complete,
        source: SurveySource::Simulated,
        points: Some(points),
        runs: Some(5),
        bidirectional: true,
        setup: Setup::Unrecorded,
        model: Some(model.clone()),
        planned_samples: Some(u64::from(points) * 10),
        ..NewSurvey::default()
    };
    store.import(&new, &samples(model, points)).await.expect("the survey is stored");
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
    for points in [360u32, 3600, 36000] {
        let db = rt.block_on(store(dir.path(), &model, points));
        let n = points * 10;
        eprintln!(
            "{n} samples: peak heap process {:.1} MiB, model-gap {:.1} MiB",
            peak_mib(&rt, process(&db, dir.path())),
            peak_mib(&rt, gap(&db, &model))
        );
        g.bench_function(format!("survey process, {n} samples"), |b| b.iter(|| rt.block_on(process(&db, dir.path()))));
        g.bench_function(format!("survey model-gap, {n} samples"), |b| b.iter(|| rt.block_on(gap(&db, &model))));
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
