//! Test support for model-gap (a survey simulated the way the simulators make
//! one, with seeded noise) and tests of the pieces: the time axis, the noise
//! floor, the views, the refit and the report.

use super::*;
use survey_processing::analysis::testutil::Normal;
use survey_processing::model::{DriftShape, Effect, Model, PeriodicKind};
use survey_processing::types::{Direction, Sample};

/// A survey simulated as the simulators make one: in acquisition order (each
/// run forward over the targets, then, when `bidirectional`, reverse), the
/// positioner rests where `actual + e(actual) + n = target` with `e =
/// model.systematic_error_deg(actual, direction, runs elapsed)` and `n` its
/// noise (drawn once per sample), the readout is the target (the servo holds
/// it), and the reference reads the true angle plus normal noise of
/// `reference_sigma`. One run takes 1000 s of timestamps; `runs elapsed` is
/// time over that (the simulator's `drift_run_period`).
pub(crate) fn simulate(
    model: &Model,
    targets: &[f64],
    runs: u32,
    bidirectional: bool,
    reference_sigma: f64,
    seed: u64,
) -> Vec<Sample> {
    let mut rng = Normal::new(seed);
    let sigma = model.noise_sigma_deg();
    let per_run = targets.len() * if bidirectional { 2 } else { 1 };
    let dt = 1000.0 / per_run as f64;
    let mut out = Vec::with_capacity(per_run * runs as usize);
    for run in 1..=runs {
        let mut passes = vec![(Direction::Forward, targets.to_vec())];
        if bidirectional {
            passes.push((Direction::Reverse, targets.iter().rev().copied().collect()));
        }
        for (direction, order) in passes {
            for target in order {
                let t = out.len() as f64 * dt;
                let tau = t / 1000.0;
                let n = sigma * rng.sample();
                let mut actual = target;
                for _ in 0..100 {
                    let next = target - n - model.systematic_error_deg(actual, direction, tau);
                    let done = (next - actual).abs() < 1e-13;
                    actual = next;
                    if done {
                        break;
                    }
                }
                let measured = actual + reference_sigma * rng.sample();
                out.push(Sample {
                    run,
                    direction,
                    target_deg: target,
                    readout_deg: target,
                    actual_deg: measured,
                    timestamp_s: Some(t),
                });
            }
        }
    }
    out
}

/// `n` targets uniformly over a revolution from 0.
pub(crate) fn circle(n: usize) -> Vec<f64> {
    (0..n).map(|k| k as f64 * 360.0 / n as f64).collect()
}

pub(crate) fn periodic(kind: PeriodicKind, cycles: f64, amplitude: f64, phase: f64) -> Effect {
    Effect::Periodic { kind, cycles_per_rev: cycles, amplitude_deg: amplitude, phase_deg: phase }
}

/// A model from a design and effects.
pub(crate) fn model(gears: &[f64], teeth: &[u32], effects: Vec<Effect>) -> Model {
    Model {
        design: survey_processing::model::Design {
            gear_ratios: gears.to_vec(),
            tooth_counts: teeth.to_vec(),
            encoder_heads: None,
        },
        effects,
        ..Model::default()
    }
}

/// The model without the effects for which `drop` holds.
pub(super) fn lacking(m: &Model, drop: impl Fn(&Effect) -> bool) -> Model {
    Model { design: m.design.clone(), effects: m.effects.iter().filter(|e| !drop(e)).cloned().collect(), ..m.clone() }
}

/// The contract's JSON keys are there.
#[test]
fn the_contract_keys_serialise() {
    let m = model(
        &[20.0],
        &[],
        vec![periodic(PeriodicKind::GearPass, 20.0, 0.004, 10.0), Effect::Noise { sigma_deg: 0.0004 }],
    );
    let truth =
        Model { effects: [m.effects.clone(), vec![Effect::Backlash { amplitude_deg: 0.003 }]].concat(), ..m.clone() };
    let s = simulate(&truth, &circle(90), 3, true, 0.0, 1);
    let g = model_gap(&s, &m, &ModelGapOptions::default()).unwrap();
    let v = serde_json::to_value(&g).unwrap();
    for key in ["effects_added", "steps", "rms_before_deg", "rms_after_deg", "noise_floor_deg"] {
        assert!(v.get(key).is_some(), "{key} missing");
    }
    let e = &v["effects_added"][0];
    assert_eq!(e["kind"], "backlash");
    assert_eq!(e["cycles_per_rev"], 0.0);
    assert!(e["amplitude_deg"].as_f64().unwrap() > 0.0 && e["explanation"].as_str().unwrap().contains("lost motion"));
    assert_eq!(v["steps"][0]["added"], "backlash");
    assert!(v["steps"][0]["rms_deg"].as_f64().unwrap() < v["rms_before_deg"].as_f64().unwrap());
    let text = g.to_text();
    for want in [
        "the gap with the model given:",
        "in angle:",
        "in frequency:",
        "by direction:",
        "in time:",
        "steps",
        "backlash",
    ] {
        assert!(text.contains(want), "{want} not in\n{text}");
    }
}

/// Runs elapsed come from the timestamps (one run = 1000 s here) or, without
/// them, from the acquisition order; both give the same drift.
#[test]
fn the_time_axis_from_timestamps_and_from_the_order() {
    let m = model(
        &[],
        &[],
        vec![Effect::Drift { rate_deg_per_run: 0.001, shape: DriftShape::Ramp }, Effect::Noise { sigma_deg: 1e-5 }],
    );
    let s = simulate(&m, &circle(36), 4, true, 0.0, 2);
    let with = survey::Survey::prepare(&s).unwrap();
    assert_eq!(with.timebase, Timebase::Timestamps);
    assert!((with.run_duration_s.unwrap() - 1000.0).abs() < 1e-9);
    let no_stamps: Vec<Sample> = s.iter().map(|x| Sample { timestamp_s: None, ..*x }).collect();
    let without = survey::Survey::prepare(&no_stamps).unwrap();
    assert_eq!(without.timebase, Timebase::SampleOrder);
    for (a, b) in with.tau.iter().zip(&without.tau) {
        assert!((a - b).abs() < 1e-9, "{a} {b}");
    }
    let empty = lacking(&m, |e| matches!(e, Effect::Drift { .. }));
    for samples in [&s, &no_stamps] {
        let g = model_gap(samples, &empty, &ModelGapOptions::default()).unwrap();
        assert_eq!(g.effects_added.len(), 1, "{}", g.to_text());
        assert!((g.effects_added[0].amplitude_deg - 0.001).abs() < 5.0 * g.effects_added[0].standard_error_deg);
    }
}

/// The noise floor is the random part only: the repeatable error, run-to-run
/// offsets and a linear drift are not in it.
#[test]
fn the_noise_floor_leaves_out_repeatable_errors_offsets_and_drift() {
    let sigma = 0.0004;
    let m = model(
        &[12.0],
        &[],
        vec![
            periodic(PeriodicKind::GearPass, 12.0, 0.01, 0.0),
            Effect::Backlash { amplitude_deg: 0.005 },
            Effect::Drift { rate_deg_per_run: 0.002, shape: DriftShape::Ramp },
            Effect::Noise { sigma_deg: sigma },
        ],
    );
    let mut s = simulate(&m, &circle(180), 5, true, 0.0, 3);
    // Run-to-run offsets of the reference (a new zero each run).
    for x in s.iter_mut() {
        x.actual_deg += 0.003 * (x.run as f64 * 1.7).sin();
    }
    let prepared = survey::Survey::prepare(&s).unwrap();
    let (sd, dof) = prepared.anova_noise().unwrap();
    assert_eq!(dof, 4 * 359);
    // dof 1436: the estimate's relative sd is about 1/sqrt(2 dof) = 1.9 %; allow 4 of those.
    assert!((sd / sigma - 1.0).abs() < 0.075, "{sd}");
    // The model given is the truth but the offsets: the time view sees run
    // offsets, and nothing is named.
    let g = model_gap(&s, &m, &ModelGapOptions::default()).unwrap();
    assert!(g.effects_added.is_empty() && g.effects_adjusted.is_empty(), "{}", g.to_text());
    let t = g.before.time.as_ref().unwrap();
    assert!(t.run_offsets && t.test == TrendTest::RunScatter, "{t:?}");
    assert!(g.notes.iter().any(|n| n.contains("offset from each other")), "{:?}", g.notes);
}

/// A line at an effect the model has (here the alias of one) adjusts that
/// effect rather than adding one; an effect the model has at the wrong
/// amplitude and phase is reported as adjusted.
#[test]
fn an_effect_that_is_off_is_adjusted_not_added() {
    let truth = model(
        &[20.0],
        &[250],
        vec![
            periodic(PeriodicKind::GearPass, 20.0, 0.008, 10.0),
            periodic(PeriodicKind::ToothMesh, 500.0, 0.0008, 40.0),
            Effect::Noise { sigma_deg: 0.0003 },
        ],
    );
    let mut off = truth.clone();
    off.effects[0] = periodic(PeriodicKind::GearPass, 20.0, 0.0075, 14.0);
    off.effects[1] = periodic(PeriodicKind::ToothMesh, 500.0, 0.0004, 40.0);
    let s = simulate(&truth, &circle(720), 3, true, 0.0, 5);
    let g = model_gap(&s, &off, &ModelGapOptions::default()).unwrap();
    assert!(g.effects_added.is_empty(), "{}", g.to_text());
    assert_eq!(g.effects_adjusted.len(), 2, "{}", g.to_text());
    for (want_f, want_a, want_p) in [(20.0, 0.008, 10.0), (500.0, 0.0008, 40.0)] {
        let a = g.effects_adjusted.iter().find(|a| a.cycles_per_rev == want_f).expect("adjusted");
        let got = survey_processing::spectrum::Phasor::from_polar(a.amplitude_deg, a.phase_deg.unwrap());
        let err = (got - survey_processing::spectrum::Phasor::from_polar(want_a, want_p)).amplitude_deg();
        assert!(err < 5.0 * a.standard_error_deg, "{a:?}");
    }
    assert!(g.steps.iter().all(|s| s.action == Action::Adjusted && s.added.starts_with("adjusted ")));
    assert!(g.effects_adjusted[0].explanation.contains(" -> "), "{}", g.effects_adjusted[0].explanation);
}

/// Effects the model file cannot hold are not added: a negative backlash.
#[test]
fn a_negative_backlash_is_reported_not_added() {
    let m = model(
        &[20.0],
        &[],
        vec![periodic(PeriodicKind::GearPass, 20.0, 0.004, 0.0), Effect::Noise { sigma_deg: 0.0003 }],
    );
    let mut s = simulate(&m, &circle(120), 3, true, 0.0, 6);
    for x in s.iter_mut() {
        // Forward reads 0.002 lower than reverse.
        x.actual_deg += 0.001 * x.direction.sign();
    }
    let g = model_gap(&s, &m, &ModelGapOptions::default()).unwrap();
    assert!(g.effects_added.is_empty(), "{}", g.to_text());
    assert!(g.before.direction.as_ref().unwrap().significant);
    assert!(g.notes.iter().any(|n| n.contains("negative backlash")), "{:?}", g.notes);
}

/// Bad options and incomplete surveys are refused with a reason.
#[test]
fn bad_input_is_refused() {
    let m = model(&[], &[], vec![Effect::Noise { sigma_deg: 0.001 }]);
    let mut s = simulate(&m, &circle(16), 2, false, 0.0, 7);
    let o = ModelGapOptions { false_alarm_rate: 0.0, ..ModelGapOptions::default() };
    assert!(matches!(model_gap(&s, &m, &o), Err(ModelGapError::BadOption { option: "false_alarm_rate", .. })));
    s.pop();
    let e = model_gap(&s, &m, &ModelGapOptions::default()).unwrap_err();
    assert!(e.to_string().contains("no sample"), "{e}");
    assert!(matches!(model_gap(&[], &m, &ModelGapOptions::default()), Err(ModelGapError::ErrorMap(_))));
}

/// One run: the noise floor comes from the spectrum; drift is not tested.
#[test]
fn one_run_works() {
    let truth = model(
        &[20.0],
        &[],
        vec![
            periodic(PeriodicKind::GearPass, 20.0, 0.005, 0.0),
            periodic(PeriodicKind::Harmonic, 7.0, 0.001, 50.0),
            Effect::Noise { sigma_deg: 0.0002 },
        ],
    );
    let s = simulate(&truth, &circle(360), 1, true, 0.0, 8);
    let g = model_gap(
        &s,
        &lacking(&truth, |e| matches!(e, Effect::Periodic { kind: PeriodicKind::Harmonic, .. })),
        &ModelGapOptions::default(),
    )
    .unwrap();
    assert_eq!(g.noise.method, "spectrum");
    assert!((g.noise_floor_deg / 0.0002 - 1.0).abs() < 0.25, "{}", g.noise_floor_deg);
    assert!(g.before.time.is_none());
    assert_eq!(g.effects_added.len(), 1, "{}", g.to_text());
    assert_eq!((g.effects_added[0].kind.as_str(), g.effects_added[0].cycles_per_rev), ("harmonic", 7.0));
}

/// The report's text shows the steps as a table and the gap before and after.
#[test]
fn the_report_shows_the_gap_shrinking() {
    let truth = model(
        &[20.0],
        &[],
        vec![
            periodic(PeriodicKind::GearPass, 20.0, 0.006, 0.0),
            periodic(PeriodicKind::Eccentricity, 1.0, 0.001, 30.0),
            Effect::Noise { sigma_deg: 0.0003 },
        ],
    );
    let s = simulate(&truth, &circle(180), 3, true, 0.0, 9);
    let g = model_gap(
        &s,
        &lacking(&truth, |e| matches!(e, Effect::Periodic { kind: PeriodicKind::Eccentricity, .. })),
        &ModelGapOptions::default(),
    )
    .unwrap();
    let text = g.to_text();
    assert!(text.contains("     0  the model as given"), "{text}");
    assert!(text.contains("     1  eccentricity 1 cycles/rev"), "{text}");
    assert!(text.contains("effects added:\n  eccentricity 1 cycles/rev"), "{text}");
    assert!(text.contains("the gap with the improved model:"), "{text}");
    assert!(g.before.angle.targets_outside > 0 && g.after.angle.targets_outside == 0, "{text}");
    assert!(g.before.frequency.lines.iter().any(|l| l.cycles_per_rev == 1.0));
    assert!(g.after.frequency.lines.iter().all(|l| !l.coherent), "{text}");
}

/// Noise-free data: the numerical floor keeps rounding from being named, and
/// a missing effect is found to rounding.
#[test]
fn noise_free_data() {
    let truth = model(
        &[20.0],
        &[],
        vec![periodic(PeriodicKind::GearPass, 20.0, 0.008, 10.0), Effect::Backlash { amplitude_deg: 0.002 }],
    );
    let s = simulate(&truth, &circle(90), 2, true, 0.0, 10);
    let g = model_gap(&s, &truth, &ModelGapOptions::default()).unwrap();
    assert!(g.effects_added.is_empty() && g.effects_adjusted.is_empty(), "{}", g.to_text());
    let g =
        model_gap(&s, &lacking(&truth, |e| matches!(e, Effect::Backlash { .. })), &ModelGapOptions::default()).unwrap();
    assert_eq!(g.effects_added.len(), 1, "{}", g.to_text());
    assert!((g.effects_added[0].amplitude_deg - 0.002).abs() < 1e-10, "{}", g.to_text());
}
