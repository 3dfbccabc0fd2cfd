//! Tests of the analysis on synthetic surveys made with the error model.

use super::testutil::{Normal, circle, fig1, fig4, survey};
use super::*;
use crate::model::Effect;
use crate::types::Direction::{Forward, Reverse};

/// The periodic effects of a model: (cycles, amplitude, phase).
fn periodic(m: &crate::model::Model) -> Vec<(f64, f64, f64)> {
    m.periodic_effects()
        .map(|e| match e {
            Effect::Periodic { cycles_per_rev, amplitude_deg, phase_deg, .. } => {
                (*cycles_per_rev, *amplitude_deg, *phase_deg)
            }
            _ => unreachable!(),
        })
        .collect()
}

fn line_at(a: &Analysis, cycles: f64) -> &Line {
    a.lines.iter().find(|l| l.cycles_per_rev == cycles).unwrap_or_else(|| {
        panic!("no line at {cycles}; lines at {:?}", a.lines.iter().map(|l| l.cycles_per_rev).collect::<Vec<_>>())
    })
}

/// The Figure 4 positioner at 720 points, 5 bidirectional runs, noise 0.0002 deg.
///
/// The analysed series is the mean of forward and reverse, so its noise per
/// sample is `sigma / sqrt 2`, each quadrature component of a single-run line
/// has sd `(sigma / sqrt 2) sqrt(2/N) = sigma / sqrt N = 7.45e-6` and of a
/// mean-spectrum line `sigma / sqrt(N R) = 3.33e-6`. Each line's phasor is
/// checked within 5 of the latter (`P(|dz| > 5 sd) = e^-12.5 = 4e-6` per line):
/// 1.7e-5 deg in amplitude, 1.7e-5 / a radians in phase.
#[test]
fn figure_4_at_720_points() {
    let model = fig4();
    let sigma = model.noise_sigma_deg();
    assert_eq!(sigma, 0.0002);
    let samples =
        survey(&circle(720, 0.0), 5, &[Forward, Reverse], sigma, 4, |_, d, t| model.repeatable_error_deg(t, d));
    let a = analyse(&samples, &model.design, &AnalysisOptions::default()).unwrap();
    assert_eq!((a.runs, a.points_per_rev, a.method), (5, 720.0, Method::Dft));
    let sd_mean = sigma / (720.0f64 * 5.0).sqrt();
    // Noise floor: estimated with 2 * 359 * 4 = 2872 degrees of freedom (1.3 % sd).
    assert_eq!(a.noise.method, NoiseMethod::SpectrumScatter);
    assert_eq!(a.noise.dof, Some(2872));
    assert!((a.noise.line_sd_mean_deg / sd_mean - 1.0).abs() < 0.05, "{:?}", a.noise);
    assert!((a.noise.sample_sd_deg / (sigma / 2f64.sqrt()) - 1.0).abs() < 0.05, "{:?}", a.noise);
    assert_eq!(a.noise.tests, 360);
    // The chi-square threshold, raised a little for the estimated floor (F(2, 2872)).
    let c = (-2.0 * (0.01f64 / 720.0).ln()).sqrt();
    assert!((c - 4.73).abs() < 0.01);
    let ratio = a.noise.coherent_threshold_deg / a.noise.line_sd_mean_deg;
    assert!(ratio > c && (ratio - 4.739).abs() < 0.001, "{ratio}");

    let tol = 5.0 * sd_mean;
    let effects = periodic(&model);
    assert_eq!(
        a.lines.len(),
        effects.len(),
        "{:#?}",
        a.lines.iter().map(|l| (l.cycles_per_rev, &l.source)).collect::<Vec<_>>()
    );
    for &(f, amp, phase) in &effects {
        let al = alias(f, 720.0);
        let seen_phase = if al.folded { 180.0 - phase } else { phase };
        let l = line_at(&a, al.observed);
        let want = Phasor::from_polar(amp, seen_phase);
        let got = Phasor::from_polar(l.mean_amplitude_deg, l.phase_deg);
        assert!((got - want).amplitude_deg() < tol, "{f} cycles: got {got:?}, want {want:?}");
        assert!((l.amplitude_deg - amp).abs() < tol);
        assert!(l.repeatable && l.coherent && l.coherence > 0.99, "{l:#?}");
        assert!((l.noise_sd_deg / sd_mean - 1.0).abs() < 0.05);
    }
    let source = |c: f64| line_at(&a, c).source.clone();
    assert_eq!(
        source(2.0),
        "ellipticity: twice per revolution: elliptical distortion of the encoder scale or the ring gear"
    );
    assert_eq!(source(12.0), "gear_pass: 12:1 pinion, harmonic 1 (fundamental)");
    assert_eq!(source(36.0), "gear_pass: 12:1 pinion, harmonic 3");
    assert_eq!(source(216.0), "tooth_mesh: 216-tooth gear, harmonic 1");
    assert_eq!(source(204.0), "tooth_mesh: sideband of the 216-tooth mesh at -1 x the 12:1 gear pass");
    assert_eq!(source(228.0), "tooth_mesh: sideband of the 216-tooth mesh at +1 x the 12:1 gear pass");
    assert_eq!(
        source(288.0),
        "tooth_mesh: 216-tooth gear, harmonic 2 at 432 cycles/rev, aliased to 288 by 720 points/rev"
    );
    assert_eq!(
        source(72.0),
        "gear_pass: 12:1 pinion, harmonic 6; also 216-tooth gear, harmonic 3 at 648 cycles/rev, aliased to 72 by 720 points/rev"
    );
    let l288 = line_at(&a, 288.0);
    assert!(l288.aliased && l288.true_cycles_per_rev == 432.0);
    assert!(crate::types::wrap_180(l288.true_phase_deg - 45.0).to_radians().abs() < tol / 0.0004);

    // Aliases: 432 -> 288 can be relocated; 648 -> 72 shares its bin with the
    // 12:1 pinion's 6th harmonic, so it is nulled.
    assert_eq!(a.aliases.len(), 2, "{:#?}", a.aliases);
    let (r432, r648) = (&a.aliases[0], &a.aliases[1]);
    assert_eq!((r432.observed_cycles, r432.true_cycles, r432.action), (288.0, 432.0, AliasAction::Relocate));
    assert_eq!((r648.observed_cycles, r648.true_cycles, r648.action), (72.0, 648.0, AliasAction::Null));
    assert!(r432.significant && r648.significant);
    assert!(crate::types::wrap_180(r648.true_phase_deg.unwrap() - 90.0).to_radians().abs() < tol / 0.00025);

    let need = a.points_needed.as_ref().unwrap();
    assert_eq!((need.highest_cycles, need.nyquist_points, need.quadratic_interpolation_points), (648.0, 1297, 12960));
    assert!(!need.sufficient);
    // Shares: the lines carry all but the noise of the mean curve.
    let total: f64 = a.lines.iter().map(|l| l.share).sum();
    assert!(a.repeatable_share > 0.999 && total <= 1.0 + 1e-12, "{total}");
    let l12 = line_at(&a, 12.0);
    let expect12 = 0.006f64.powi(2) / effects.iter().map(|e| e.1 * e.1).sum::<f64>();
    assert!((l12.share - expect12).abs() < 0.01);

    // The contract's keys are there.
    let json = serde_json::to_value(&a).unwrap();
    let first = &json["lines"][0];
    for key in ["cycles_per_rev", "amplitude_deg", "source", "repeatable"] {
        assert!(first.get(key).is_some(), "{key}");
    }
    assert_eq!(json["aliases"][0]["action"], "relocate");
    assert_eq!(json["aliases"][1]["action"], "null");
    assert_eq!(json["lines"][0]["kind"], "ellipticity");
    assert_eq!(json["error_map"]["coverage"]["kind"], "full_circle");
}

/// Noise-free data: every model line at its exact amplitude and phase, and
/// nothing else (the numerical floor keeps rounding errors from being lines).
#[test]
fn clean_figure_4_is_recovered_exactly() {
    let model = fig4();
    let samples = survey(&circle(720, 0.25), 2, &[Forward], 0.0, 0, |_, _, t| model.periodic_error_deg(t));
    let a = analyse(&samples, &model.design, &AnalysisOptions::default()).unwrap();
    let effects = periodic(&model);
    assert_eq!(a.lines.len(), effects.len());
    for &(f, amp, phase) in &effects {
        let l = line_at(&a, alias(f, 720.0).observed);
        assert!((l.amplitude_deg - amp).abs() < 1e-12, "{l:?}");
        // The true phase survives aliasing with samples that start at 0.25 deg
        // (648 is named as the unaliased 72: its phase is in the alias report).
        if f < 360.0 || l.aliased {
            assert!(crate::types::wrap_180(l.true_phase_deg - phase).abs() < 1e-6, "{f}: {l:?}");
        }
    }
    let r648 = &a.aliases[1];
    assert!(crate::types::wrap_180(r648.true_phase_deg.unwrap() - 90.0).abs() < 1e-6, "{r648:?}");
}

/// A sinusoid whose phase changes from run to run is found, but not repeatable.
#[test]
fn random_phase_line_is_not_repeatable() {
    let design = Design { gear_ratios: vec![12.0], tooth_counts: vec![], encoder_heads: None };
    let targets = circle(360, 0.0);
    // Phases spread evenly over 5 runs: the mean spectrum cancels exactly.
    let spread = survey(&targets, 5, &[Forward], 0.0002, 11, |run, _, t| {
        0.005 * (12.0 * t + 40.0f64).to_radians().sin() + 0.002 * (30.0 * t + 72.0 * run as f64).to_radians().sin()
    });
    let a = analyse(&spread, &design, &AnalysisOptions::default()).unwrap();
    assert_eq!(a.lines.len(), 2, "{:#?}", a.lines);
    assert!(line_at(&a, 12.0).repeatable);
    let l = line_at(&a, 30.0);
    assert!(!l.repeatable && !l.coherent && l.incoherent && l.coherence < 0.01, "{l:#?}");
    assert!((l.amplitude_deg - 0.002).abs() < 1e-4, "{l:?}");
    assert_eq!(l.kind, PeriodicKind::Harmonic);
    // Seeded random phases over 8 runs, several seeds: never repeatable.
    for seed in 0..6u64 {
        let mut g = Normal::new(100 + seed);
        let phases: Vec<f64> = (0..8).map(|_| 360.0 * g.uniform()).collect();
        let s = survey(&targets, 8, &[Forward], 0.0002, seed, |run, _, t| {
            0.005 * (12.0 * t).to_radians().sin() + 0.002 * (30.0 * t + phases[run as usize - 1]).to_radians().sin()
        });
        let a = analyse(&s, &design, &AnalysisOptions::default()).unwrap();
        let l = line_at(&a, 30.0);
        assert!(!l.repeatable && l.incoherent && l.coherence < 0.5625, "seed {seed}: {l:#?}");
        assert!(line_at(&a, 12.0).repeatable);
        assert_eq!(a.lines.len(), 2);
    }
}

/// Pure noise: nothing is named, and over many surveys the false lines come at
/// the stated rate (between alpha/2 and alpha per spectrum, see the module doc).
#[test]
fn noise_only_control() {
    let design = fig4().design;
    let targets = circle(256, 0.0);
    let analyse_noise = |seed: u64, alpha: f64| {
        let s = survey(&targets, 4, &[Forward], 0.0003, seed, |_, _, _| 0.0);
        let o = AnalysisOptions { false_alarm_rate: alpha, ..AnalysisOptions::default() };
        analyse(&s, &design, &o).unwrap()
    };
    let a = analyse_noise(1, 0.01);
    assert!(a.lines.is_empty(), "{:#?}", a.lines);
    assert!(a.points_needed.is_none());
    assert!((a.noise.sample_sd_deg / 0.0003 - 1.0).abs() < 0.1);
    // alpha = 1: between 0.5 and 1 false line per spectrum expected.
    let surveys = 150u64;
    let count: usize = (0..surveys).map(|seed| analyse_noise(1000 + seed, 1.0).lines.len()).sum();
    let (lo, hi) = (0.5 * surveys as f64, surveys as f64);
    assert!(
        (count as f64) > lo - 4.0 * lo.sqrt() && (count as f64) < hi + 4.0 * hi.sqrt(),
        "{count} false lines in {surveys} surveys"
    );
    // The default: at most 0.01 per spectrum, so a handful at most in 150.
    let count: usize = (0..surveys).map(|seed| analyse_noise(5000 + seed, 0.01).lines.len()).sum();
    assert!(count <= 6, "{count} false lines in {surveys} surveys at alpha 0.01");
}

/// One run: lines are found from the median noise estimate but none is repeatable.
#[test]
fn single_run() {
    let model = fig4();
    let s = survey(&circle(720, 0.0), 1, &[Forward], 0.0002, 3, |_, _, t| model.periodic_error_deg(t));
    let a = analyse(&s, &model.design, &AnalysisOptions::default()).unwrap();
    assert_eq!(a.noise.method, NoiseMethod::SpectrumMedian);
    assert!((a.noise.sample_sd_deg / 0.0002 - 1.0).abs() < 0.2, "{:?}", a.noise);
    assert!(a.lines.iter().all(|l| !l.repeatable));
    assert_eq!(a.lines.len(), periodic(&model).len());
    assert!(a.notes[0].starts_with("one run"));
}

/// The Figure 1 elevation axis over -10..90 deg: 6 and 72 cycles/rev are not
/// whole cycles per span (1.675 and 20.1), so the lines come from the
/// least-squares fit at the design frequencies; amplitudes within 5 standard
/// uncertainties (from `sigma^2 (A^T A)^-1`) of the model.
#[test]
fn partial_range_elevation() {
    let model = fig1();
    let targets: Vec<f64> = (0..=200).map(|j| -10.0 + 0.5 * j as f64).collect();
    let sigma = model.noise_sigma_deg();
    let s = survey(&targets, 5, &[Forward, Reverse], sigma, 8, |_, d, t| model.repeatable_error_deg(t, d));
    let a = analyse(&s, &model.design, &AnalysisOptions::default()).unwrap();
    assert_eq!(a.method, Method::LeastSquares);
    assert!((a.points_per_rev - 720.0).abs() < 1e-9);
    assert!(matches!(a.error_map.coverage, Coverage::Partial { .. }));
    let fit = a.fit.as_ref().unwrap();
    assert_eq!(fit.frequencies, vec![1.0, 2.0, 6.0, 12.0, 18.0, 24.0, 30.0, 36.0, 72.0, 144.0, 216.0, 288.0]);
    assert_eq!(a.noise.method, NoiseMethod::ResidualScatter);
    assert!((a.noise.sample_sd_deg / (sigma / 2f64.sqrt()) - 1.0).abs() < 0.1, "{:?}", a.noise);
    for (f, amp, phase) in periodic(&model) {
        let l = a.lines.iter().find(|l| l.cycles_per_rev == f);
        let l = match l {
            Some(l) => l,
            // A weak slow term may hide in the collinear columns; the big ones must not.
            None => {
                assert!(f < 6.0, "no line at {f}: {:#?}", a.lines);
                continue;
            }
        };
        let err =
            (Phasor::from_polar(l.mean_amplitude_deg, l.phase_deg) - Phasor::from_polar(amp, phase)).amplitude_deg();
        assert!(err < 5.0 * l.noise_sd_deg, "{f}: {err} vs sd {}", l.noise_sd_deg);
        assert!(l.repeatable);
    }
    // Nothing is found where the model has nothing.
    let model_freqs: Vec<f64> = periodic(&model).iter().map(|e| e.0).collect();
    assert!(a.lines.iter().all(|l| model_freqs.contains(&l.cycles_per_rev)), "{:#?}", a.lines);
    for f in [6.0, 12.0, 72.0] {
        let l = line_at(&a, f);
        assert_eq!(l.kind, PeriodicKind::GearPass);
        assert!(l.noise_sd_deg < 1e-4);
    }
    assert_eq!(line_at(&a, 72.0).source, "gear_pass: 72:1 pinion, harmonic 1 (fundamental)");
    // 360 (at the sampling limit) and 432 cannot be fitted: reported, nulled.
    let aliased: Vec<(f64, AliasAction)> = a.aliases.iter().map(|e| (e.true_cycles, e.action)).collect();
    assert_eq!(aliased, vec![(360.0, AliasAction::Null), (432.0, AliasAction::Null)]);
    // The Hann display spectrum is there, over a 100.5 deg span.
    let sp = a.spectra.as_ref().unwrap();
    assert_eq!((sp.mean.window, sp.mean.points), (Window::Hann, 201));
    assert!(a.notes.iter().any(|n| n.starts_with("partial range -10 to 90 deg")));
    // One run: the residual is the noise estimate.
    let one = survey(&targets, 1, &[Forward], sigma, 9, |_, d, t| model.repeatable_error_deg(t, d));
    let a1 = analyse(&one, &model.design, &AnalysisOptions::default()).unwrap();
    assert_eq!(a1.noise.method, NoiseMethod::Residual);
    assert!((line_at(&a1, 6.0).mean_amplitude_deg - 0.028).abs() < 5.0 * line_at(&a1, 6.0).noise_sd_deg);
}

#[test]
fn bad_input_is_named() {
    let model = fig4();
    let s = survey(&circle(36, 0.0), 2, &[Forward], 0.0, 0, |_, _, _| 0.0);
    let o = AnalysisOptions { series: Series::Reverse, ..AnalysisOptions::default() };
    assert_eq!(
        analyse(&s, &model.design, &o).unwrap_err(),
        AnalysisError::MissingDirection { series: Series::Reverse }
    );
    let o = AnalysisOptions { false_alarm_rate: 0.0, ..AnalysisOptions::default() };
    assert!(matches!(
        analyse(&s, &model.design, &o).unwrap_err(),
        AnalysisError::BadOption { option: "false_alarm_rate", .. }
    ));
    let o = AnalysisOptions { min_coherence: Some(1.5), ..AnalysisOptions::default() };
    assert!(analyse(&s, &model.design, &o).unwrap_err().to_string().contains("min_coherence"));
    let two = survey(&[0.0, 180.0], 2, &[Forward], 0.0, 0, |_, _, _| 0.0);
    assert!(matches!(
        analyse(&two, &model.design, &AnalysisOptions::default()).unwrap_err(),
        AnalysisError::TooFewTargets { .. }
    ));
    assert!(matches!(
        analyse(&[], &model.design, &AnalysisOptions::default()).unwrap_err(),
        AnalysisError::ErrorMap(_)
    ));
    // Options read from a recipe table; unknown keys are refused.
    let o: AnalysisOptions = toml::from_str("gear_harmonics = 4\nseries = \"forward\"\n").unwrap();
    assert_eq!((o.gear_harmonics, o.series, o.tooth_harmonics), (4, Series::Forward, 3));
    assert!(toml::from_str::<AnalysisOptions>("gear_harmonic = 4\n").is_err());
}
