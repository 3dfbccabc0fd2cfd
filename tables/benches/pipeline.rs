//! The processing of a survey: an 1800-point, 5-run bidirectional survey end
//! to end (analysis, recipe, 131072-point resampling, 16384-row directional
//! table), and the spectral resampling 1800 -> 131072 alone (compare with
//! `scripts/resample_numpy.py`, scipy.signal.resample on the same sizes).
//! `cargo bench -p survey-processing --bench pipeline`.

use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;
use survey_processing::analysis::analyse;
use survey_processing::model::Model;
use survey_processing::resample::Resampler;
use survey_processing::{Direction, Sample};
use survey_tables::recipe::Recipe;

/// SplitMix64 and Box-Muller: seeded normal deviates without a dependency.
struct Normal(u64);

impl Normal {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        (((z ^ (z >> 31)) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn sample(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// The paper's Figure 8 positioner, 1800 points x 5 bidirectional runs.
fn survey() -> (Model, Vec<Sample>) {
    let model = Model::parse(include_str!("../../sims/presets/fig8.toml"), "fig8.toml").expect("the preset parses");
    let sigma = model.noise_sigma_deg();
    let mut rng = Normal(8);
    let mut out = Vec::new();
    for run in 1..=5 {
        for direction in [Direction::Forward, Direction::Reverse] {
            let mut targets: Vec<f64> = (0..1800).map(|j| j as f64 * 0.2).collect();
            if direction == Direction::Reverse {
                targets.reverse();
            }
            for t in targets {
                let e = model.repeatable_error_deg(t, direction) + sigma * rng.sample();
                out.push(Sample {
                    run,
                    direction,
                    target_deg: t,
                    readout_deg: t,
                    actual_deg: t - e,
                    timestamp_s: None,
                });
            }
        }
    }
    (model, out)
}

fn bench(c: &mut Criterion) {
    let (model, samples) = survey();
    let mut g = c.benchmark_group("processing");
    g.sample_size(20);
    g.bench_function("survey 1800 points x 5 runs bidirectional: analysis + table", |b| {
        b.iter(|| {
            let defaults = Recipe::default();
            let a = analyse(black_box(&samples), &model.design, &defaults.analysis).expect("analysis");
            let recipe = Recipe::from_analysis(&a, &defaults);
            let decisions = recipe.decide(&a).expect("decisions");
            recipe.build_table(&a, &decisions).expect("table")
        })
    });
    let y: Vec<f64> = (0..1800).map(|j| model.periodic_error_deg(j as f64 * 0.2)).collect();
    let mut out = vec![0.0; 131_072];
    let mut warm = Resampler::new();
    g.sample_size(50);
    g.bench_function("spectral resampling 1800 -> 131072 (plans reused)", |b| {
        b.iter(|| warm.resample_into(black_box(&y), &mut out))
    });
    g.bench_function("spectral resampling 1800 -> 131072 (planning included)", |b| {
        b.iter(|| Resampler::new().resample(black_box(&y), 131_072))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
