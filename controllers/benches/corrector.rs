//! The real-time corrector: nanoseconds per correction.
//!
//! The paper's budget (section 5): a position update rate of 20 kHz, so one
//! correction must fit in 50 us, and any delay costs accuracy (at 6 deg/s a
//! 50 us delay is 0.0003 deg). One readout corrected again and again is the
//! cached case; a new random readout each time, and 4096 scattered ones,
//! meet the table's rows at random.
//! `cargo bench -p survey-processing --bench corrector`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use survey_controllers::corrector::{Corrector, DirectionTracker};
use survey_processing::Direction;
use survey_processing::table::CorrectionTable;

/// A 16384-row direction-aware table like the paper's dense hardware table.
fn table() -> CorrectionTable {
    let n = 16_384;
    let col = |offset: f64| -> Vec<f64> {
        (0..n)
            .map(|i| {
                let t = (i as f64 * 360.0 / n as f64).to_radians();
                0.0078 * (20.0 * t).sin() + 0.0025 * (40.0 * t + 1.0).sin() + 0.0015 * (t + 1.9).sin() + offset
            })
            .collect()
    };
    CorrectionTable::directional(col(0.004), col(-0.004)).expect("a valid table")
}

fn bench(c: &mut Criterion) {
    let t = table();
    let corrector = Corrector::new(&t);
    // Readouts spread over several turns, both signs, in an order the branch
    // predictor and the cache cannot learn.
    let readouts: Vec<f64> = (0..4096u64)
        .map(|i| {
            let h = i.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 11;
            (h as f64 / (1u64 << 53) as f64) * 1440.0 - 720.0
        })
        .collect();

    let mut g = c.benchmark_group("corrector");
    g.bench_function("one correction (16384 rows, directional)", |b| {
        b.iter(|| corrector.correct(black_box(123.456_789), black_box(Direction::Reverse)))
    });
    // The case above corrects the same readout every time: its rows stay in
    // the cache and the branch predictor learns the path (the cached case).
    // Here every correction gets a new readout (a multiplicative hash of a
    // counter, over several turns): the table's rows are met at random.
    let mut k = 0u64;
    g.bench_function("one correction, a new random readout each time", |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let h = k.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 11;
            let r = (h as f64 / (1u64 << 53) as f64) * 1440.0 - 720.0;
            let d = if k & 1 == 0 { Direction::Forward } else { Direction::Reverse };
            corrector.correct(black_box(r), d)
        })
    });
    g.throughput(Throughput::Elements(readouts.len() as u64));
    g.bench_function("4096 corrections, scattered readouts", |b| {
        b.iter(|| {
            let mut sum = 0.0;
            for (i, &r) in readouts.iter().enumerate() {
                let d = if i & 1 == 0 { Direction::Forward } else { Direction::Reverse };
                sum += corrector.correct(black_box(r), d);
            }
            sum
        })
    });
    g.bench_function("4096 corrections with direction tracking", |b| {
        b.iter(|| {
            let mut tracker = DirectionTracker::new(Direction::Forward, 1e-4);
            let mut sum = 0.0;
            for &r in &readouts {
                let d = tracker.update(black_box(r));
                sum += corrector.correct(r, d);
            }
            sum
        })
    });
    g.bench_function("4096 CorrectionTable::correct (reference)", |b| {
        b.iter(|| readouts.iter().map(|&r| t.correct(black_box(r), Direction::Forward)).sum::<f64>())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
