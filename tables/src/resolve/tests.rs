//! The sparse survey against the truth: 36 points, both directions,
//! 2 runs, of the Figure 8 positioner with no `[design]` (its 20 cycles/rev
//! gear pass seen at 16, its 40 at 4). Without check points the table keeps
//! the lines where they are seen and errs by up to twice them between the
//! targets; with the check points [`plan_checks`] chooses, the processing
//! decides 20 and 40 and the table's true residual comes down to the noise,
//! close to a dense survey's.

use super::*;
use crate::left::LeftLine;
use crate::pipeline::{process, process_with_checks};
use std::f64::consts::SQRT_2;
use survey_processing::model::{Design, Model};
use survey_processing::types::Direction;

/// The Figure 8 positioner with no `[design]` (these tests draw their own
/// noise, [`SIGMA`], not the file's).
const FIG8_NO_DESIGN: &str = include_str!("../../../tests/fixtures/fig8-no-design.toml");

/// The noise of one sample (the default bench's positioner and tracker together), degrees.
const SIGMA: f64 = 0.001;

/// `E(r)`, the true error at readout `r` in `dir`.
fn truth(m: &Model, r: f64, dir: Direction) -> f64 {
    let mut theta = r;
    for _ in 0..60 {
        theta = r - m.repeatable_error_deg(theta, dir);
    }
    m.repeatable_error_deg(theta, dir)
}

/// splitmix64 and Box-Muller: deterministic normal deviates.
struct Gauss(u64);
impl Gauss {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        (((z ^ (z >> 31)) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// A survey of `targets`, both directions, `runs` runs.
fn survey(m: &Model, targets: &[f64], runs: u32, rng: &mut Gauss) -> Vec<Sample> {
    let mut out = Vec::new();
    for run in 1..=runs {
        for dir in [Direction::Forward, Direction::Reverse] {
            for &t in targets {
                let e = truth(m, t, dir) + SIGMA * rng.normal();
                out.push(Sample {
                    run,
                    direction: dir,
                    target_deg: t,
                    readout_deg: t,
                    actual_deg: t - e,
                    timestamp_s: None,
                });
            }
        }
    }
    out
}

/// The table's true residual over the circle, both columns, mean removed: (rms, peak).
fn residual(m: &Model, table: &CorrectionTable) -> (f64, f64) {
    let mut v = Vec::new();
    for i in 0..3600 {
        let r = 0.1 * i as f64 + 0.037;
        for dir in [Direction::Forward, Direction::Reverse] {
            v.push(truth(m, r, dir) - table.error_at(r, dir));
        }
    }
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let rms = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64).sqrt();
    (rms, v.iter().fold(0.0f64, |p, x| p.max((x - mean).abs())))
}

#[test]
fn check_points_decide_the_unknown_designs_aliases_and_the_table_corrects_them() {
    let m = Model::parse(FIG8_NO_DESIGN, "fig8-no-design").unwrap();
    let design = Design::default();
    let targets: Vec<f64> = (0..36).map(|j| 10.0 * j as f64).collect();
    let mut rng = Gauss(20);
    let sparse = survey(&m, &targets, 2, &mut rng);
    let first = process(&sparse, &design, None).unwrap();
    // In doubt: the lines at 16 and 4, and (a design that names no part:
    // issue 38) the eccentricity at 1, which may be the alias of 35 or 37.
    let bins: Vec<f64> = first.left.lines.iter().map(|l| l.observed_cycles).collect();
    assert_eq!(bins, [16.0, 4.0, 1.0], "{:?}", first.left.lines);
    let (unresolved_rms, unresolved_peak) = residual(&m, &first.built.table);

    let checks_at = plan_checks(&first.left, &targets);
    assert_eq!(checks_at.len(), 36, "four per candidate (nine candidates): {checks_at:?}");
    assert!(checks_at.iter().all(|c| targets.iter().all(|t| crate::verification::circular_distance(*c, *t) >= 2.4)));
    let checks = survey(&m, &checks_at, 2, &mut rng);
    let resolved = process_with_checks(&sparse, &design, None, None, &checks).unwrap();
    let decided: Vec<Option<f64>> = resolved.resolutions.iter().map(|r| r.decided_cycles).collect();
    assert_eq!(decided, [Some(20.0), Some(40.0), Some(1.0)], "{:?}", resolved.resolutions);
    // Left: only what the check points cannot exclude beside each decided
    // line (sqrt 2 k sigma sqrt(2 / 96), 4.1e-4 deg), no possible alias.
    let rest = SQRT_2 * 2.0 * SIGMA * (2.0 / 96.0f64).sqrt();
    assert!(
        resolved.left.lines.iter().all(|l| l.kind == LeftKind::Possible && l.amplitude_deg < 1.5 * rest),
        "{:?}",
        resolved.left.lines
    );
    assert!(resolved.recipe.lines.keep.contains(&20.0) && resolved.recipe.lines.keep.contains(&40.0));
    let (rms, peak) = residual(&m, &resolved.built.table);

    // The dense survey of the same positioner (360 points, 2 runs).
    let dense_targets: Vec<f64> = (0..360).map(|j| j as f64).collect();
    let dense = process(&survey(&m, &dense_targets, 2, &mut rng), &design, None).unwrap();
    let (dense_rms, dense_peak) = residual(&m, &dense.built.table);
    eprintln!(
        "unresolved rms {unresolved_rms:.2e} peak {unresolved_peak:.2e}; resolved rms {rms:.2e} peak {peak:.2e}; \
         dense rms {dense_rms:.2e} peak {dense_peak:.2e}"
    );
    // Close to the dense survey's: the sparse table fits 4 lines (and the
    // direction's mean) from 144 samples where the dense one has 1440, so its
    // noise is about sqrt(10) larger: within 5 times the dense residual plus
    // the noise of one line's quadrature components (sigma sqrt(2 / (36 x 4))),
    // and far below what the unresolved table leaves.
    let line_noise = SIGMA * (2.0 / (36.0 * 4.0f64)).sqrt();
    assert!(rms <= 5.0 * dense_rms + 2.0 * line_noise, "{rms:e} against dense {dense_rms:e}");
    assert!(rms <= unresolved_rms / 20.0, "{rms:e} against unresolved {unresolved_rms:e}");
    // And the prediction and U now say so.
    assert!(resolved.prediction.corrected_peak_deg < resolved.prediction.native_peak_deg / 2.0);
    // The possible lines are lines the survey could have missed, like one
    // below the threshold: U counts one missed line, the largest of them and
    // the threshold's. Here they are under the threshold and add nothing.
    let u = crate::uncertainty::uncertainty(&resolved, &sparse, &Default::default());
    assert!(resolved.left.lines.iter().all(|l| l.amplitude_deg < resolved.analysis.noise.coherent_threshold_deg));
    let mut without = resolved;
    without.left.lines.retain(|l| l.kind != LeftKind::Possible);
    let u_without = crate::uncertainty::uncertainty(&without, &sparse, &Default::default());
    assert_eq!(u.table_u_deg, u_without.table_u_deg, "{}", u.text());
}

#[test]
fn two_lines_sharing_a_bin_are_not_forced_into_one_frequency() {
    // Figure 8's design at 30 points: 20 and 40 both at bin 10, nulled. Both
    // are real, so no single frequency explains the check points: nothing is
    // decided and the line stays left (in U), rather than relocated wrongly.
    let mut m = Model::parse(FIG8_NO_DESIGN, "fig8").unwrap();
    m.design = Design { gear_ratios: vec![20.0], ..Design::default() };
    let design = m.design.clone();
    let targets: Vec<f64> = (0..30).map(|j| 12.0 * j as f64).collect();
    let mut rng = Gauss(30);
    let first = process(&survey(&m, &targets, 2, &mut rng), &design, None).unwrap();
    assert!(first.left.lines.iter().any(|l| l.observed_cycles == 10.0 && l.candidates.len() > 1), "{:?}", first.left);
    let checks_at = plan_checks(&first.left, &targets);
    let checks = survey(&m, &checks_at, 2, &mut rng);
    let again = process_with_checks(&survey(&m, &targets, 2, &mut Gauss(30)), &design, None, None, &checks).unwrap();
    let at10 = again.resolutions.iter().find(|r| r.observed_cycles == 10.0).unwrap();
    assert_eq!(at10.decided_cycles, None, "{at10:?}");
    assert!(at10.why.contains("no candidate explains"), "{}", at10.why);
    assert!(again.left.lines.iter().any(|l| l.observed_cycles == 10.0));
}

/// A `Left` of `points` per revolution with `lines` (bin, candidates, kind).
fn left(points: usize, lines: &[(f64, &[f64], LeftKind)]) -> Left {
    Left {
        lines: lines
            .iter()
            .map(|&(bin, c, kind)| LeftLine {
                observed_cycles: bin,
                amplitude_deg: 0.01,
                phase_deg: 0.0,
                noise_sd_deg: 0.0,
                kind,
                candidates: c.to_vec(),
                carried_cycles: None,
                why: String::new(),
            })
            .collect(),
        points,
        start_deg: 0.0,
        worst: None,
        second_order_deg: 0.0,
        folds: Vec::new(),
    }
}

#[test]
fn a_second_orientation_says_what_twice_the_faces_resolve() {
    // 24 faces, Figure 8's design: bin 4 holds 20 and 100, bin 8 holds 40
    // and 80. At 48 points they land on 20, 4, 8 and 16: all resolved.
    let l = left(24, &[(4.0, &[20.0, 100.0], LeftKind::NotCarried), (8.0, &[40.0, 80.0], LeftKind::NotCarried)]);
    let t = second_orientation(&l).unwrap();
    assert!(t.contains("would resolve the line at bin 4") && t.contains("bin 8"), "{t}");
    assert!(!t.contains("not separate"), "{t}");
    // An unknown design at 36 faces: 16 may be 20 or 52, which land on one
    // bin (20) at 72 points too.
    let l = left(36, &[(16.0, &[16.0, 20.0, 52.0], LeftKind::MaybeAlias)]);
    let t = second_orientation(&l).unwrap();
    assert!(t.contains("would not separate the line at bin 16"), "{t}");
    assert_eq!(second_orientation(&left(24, &[])), None);
}

#[test]
fn of_the_lines_check_points_cannot_exclude_u_counts_one_the_largest() {
    // 360 points of the same positioner: every line of a design that names no
    // part is in doubt (N / 2 < 720), the check points decide each where it
    // is seen, and what they cannot exclude beside each (three possible
    // lines) is above the survey's threshold.
    let m = Model::parse(FIG8_NO_DESIGN, "fig8-no-design").unwrap();
    let design = Design::default();
    let targets: Vec<f64> = (0..360).map(|j| j as f64).collect();
    let mut rng = Gauss(36);
    let samples = survey(&m, &targets, 2, &mut rng);
    let first = process(&samples, &design, None).unwrap();
    let checks = survey(&m, &plan_checks(&first.left, &targets), 2, &mut rng);
    let resolved = process_with_checks(&samples, &design, None, None, &checks).unwrap();
    let t = resolved.analysis.noise.coherent_threshold_deg;
    let sizes: Vec<f64> =
        resolved.left.lines.iter().filter(|l| l.kind == LeftKind::Possible).map(|l| l.amplitude_deg).collect();
    let largest = sizes.iter().copied().fold(0.0, f64::max);
    assert!(sizes.len() >= 2 && largest > t, "possible lines {sizes:?} against T {t}");
    let u = crate::uncertainty::uncertainty(&resolved, &samples, &Default::default());
    // At least the largest (its coverage interval is about its size) ...
    assert!(u.table_u_deg >= 0.95 * largest, "U {} against {sizes:?}", u.table_u_deg);
    // ... but not every one at once (U was their sum and more: 8.3e-4 deg
    // against three of 3.4e-4).
    assert!(u.table_u_deg < 0.6 * sizes.iter().sum::<f64>(), "U {} against {sizes:?}", u.table_u_deg);
    assert!(u.budget.iter().any(|c| c.source.starts_with("a line the survey could have missed")), "{}", u.text());
}
