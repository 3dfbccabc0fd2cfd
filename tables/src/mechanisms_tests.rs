//! Monte Carlo of the table's `U` and the verification's verdict against the
//! truth, by mechanism (issue 38): where `U` or the verdict could be
//! confident and wrong.
//!
//! In process and fast: a survey is simulated here as the simulated
//! positioner makes it (`sims/src/positioner.rs`: the encoder reads `raw =
//! actual + e(actual) + n`, `e` the model's systematic error with its drift
//! at the survey's place in its plan, `n` the rest noise drawn once a move;
//! the servo drives the displayed readout, `raw - table(raw)` when a table is
//! applied, to the target), through the model code the simulators run
//! ([`survey_processing::model::Model`]). Check points between the targets (a tracker)
//! are planned by [`crate::resolve::plan_checks`] and measured
//! the same way; a verification measures half a step from every target
//! (at the faces for an autocollimator) with the table applied.
//!
//! Each mechanism draws a **new model of its kind for every seed** (its
//! points, frequencies, amplitudes, phases and noise from the seed), so the
//! figures are over models as well as noise. Per survey: the share of the
//! circle (both directions, 2048 readouts each) where the table's true error
//! (`E(r) = r - theta`, `theta + e(theta) = r`, less the table, the mean over
//! the circle removed) is within `U`; `U` over the 95th percentile of that
//! error; the verdict of the verification where the mechanism has one.
//!
//! Required, per mechanism: every survey at least 90 % covered, 95 % on
//! average, `U` at most 4 times the true error's 95th percentile; a table
//! whose true error the verification shows beyond its prediction never
//! "confirmed"; one voice (a table predicted no better than native is never
//! "confirmed").
//!
//! CI runs two seeds of each (`every_mechanism_on_two_seeds`, about 6 s in
//! a debug build); `SURVEY_MECHANISM_SEEDS=N cargo test -p survey-processing
//! --lib mechanisms_monte_carlo -- --ignored --nocapture` runs `N` seeds of
//! each (default 20, from seed `SURVEY_MECHANISM_FIRST`, default 101: the
//! fixes were made on seeds 1 to 16) and prints the figures of
//! `docs/validation/uncertainty.md`; `SURVEY_MECHANISM=word` keeps the
//! mechanisms whose name holds it; `SURVEY_MECHANISM_BUDGET=1` prints every
//! survey's budget beside its truth.

use crate::pipeline::{Processed, process_with_checks};
use crate::resolve::plan_checks;
use crate::uncertainty::{Uncertainty, UncertaintyInputs, uncertainty};
use crate::verification::{Claim, Verdict, judge, peak_deg, predicted_for};
use survey_processing::analysis::testutil::Normal;
use survey_processing::model::{DriftTime, Model};
use survey_processing::table::CorrectionTable;
use survey_processing::types::{Direction, Sample};

/// How a survey is taken.
#[derive(Debug, Clone)]
struct Plan {
    points: usize,
    runs: u32,
    bidirectional: bool,
    /// A tracker: check points between the targets, a verification between them.
    tracker: bool,
    verify: bool,
    /// Each reading stamped (2 s a step): the survey measures its drift in
    /// time from its own readings and corrects it, as `survey` does
    /// (`crate::timedrift`, applied where the lab loads a survey).
    timed: bool,
}

/// One drawn case: the model simulated and how it is surveyed.
#[derive(Debug, Clone)]
struct Case {
    what: String,
    model: Model,
    /// The axis as the verification finds it, when it changed after the
    /// survey (a table made for `model` is then bad for it).
    changed: Option<Model>,
    plan: Plan,
}

/// What one survey of a case gave.
#[derive(Debug, Clone)]
struct Outcome {
    what: String,
    coverage: f64,
    p95: f64,
    u: f64,
    /// The survey's detection threshold `T`: the smallest line it could
    /// have missed, below which `U` cannot honestly go.
    t: f64,
    /// The verdict, when verified: (confirmed, the table's true peak error
    /// beyond the prediction plus U, not a result).
    verdict: Option<(bool, bool, bool)>,
    /// The axis changed before the verification: a table within its
    /// prediction plus `U` of the changed axis is neither good (the axis is
    /// not the one surveyed) nor bad; either verdict is right.
    changed: bool,
}

/// The positioner's sample at `target`: the servo at rest where the
/// displayed readout is the target, the reference measuring the true angle.
fn sample_at(
    model: &Model,
    target: f64,
    direction: Direction,
    run: u32,
    (t, stamp): (DriftTime, Option<f64>),
    table: Option<&CorrectionTable>,
    rng: &mut Normal,
) -> Sample {
    let n = model.noise_sigma_deg() * rng.sample();
    let raw = match table {
        Some(tb) => fixed_point(|raw| target + tb.error_at(raw, direction), target),
        None => target,
    };
    let actual = fixed_point(|a| raw - n - model.systematic_error_at(a, direction, t), raw - n);
    Sample { run, direction, target_deg: target, readout_deg: target, actual_deg: actual, timestamp_s: stamp }
}

fn fixed_point(f: impl Fn(f64) -> f64, start: f64) -> f64 {
    let mut x = start;
    for _ in 0..60 {
        let next = f(x);
        if (next - x).abs() < 1e-13 {
            return next;
        }
        x = next;
    }
    x
}

/// A survey of `targets`, `runs` runs (forward, then reverse when
/// bidirectional), its drift's time counted on from `runs_before`.
fn acquire(
    model: &Model,
    targets: &[f64],
    plan: &Plan,
    runs: u32,
    runs_before: f64,
    table: Option<&CorrectionTable>,
    rng: &mut Normal,
) -> Vec<Sample> {
    let dirs: &[Direction] =
        if plan.bidirectional { &[Direction::Forward, Direction::Reverse] } else { &[Direction::Forward] };
    let steps = (targets.len() * dirs.len()) as f64;
    let mut out = Vec::new();
    for run in 0..runs {
        let mut j = 0usize;
        for &d in dirs {
            let order: Vec<f64> = match d {
                Direction::Forward => targets.to_vec(),
                Direction::Reverse => targets.iter().rev().copied().collect(),
            };
            for t in order {
                let elapsed = runs_before + run as f64 + j as f64 / steps;
                let time = DriftTime { runs_elapsed: elapsed, run_index: runs_before + run as f64 };
                // The survey's clock: 2 s a step of its own plan, so the
                // drift's runs and the stamps keep one scale (check points too).
                let stamp = plan.timed.then_some(2.0 * (plan.points * dirs.len()) as f64 * elapsed);
                out.push(sample_at(model, t, d, run + 1, (time, stamp), table, rng));
                j += 1;
            }
        }
    }
    out
}

/// `E(r)`: the positioner's repeatable error at readout `r`.
fn true_error(model: &Model, r: f64, d: Direction) -> f64 {
    let theta = fixed_point(|th| r - model.repeatable_error_deg(th, d), r);
    r - theta
}

/// The table's true errors over the circle, in the directions surveyed
/// (both: a one-column table serves both), mean removed.
fn table_errors(model: &Model, table: &CorrectionTable, bidirectional: bool) -> Vec<f64> {
    let mut e = Vec::new();
    let dirs: &[Direction] =
        if bidirectional { &[Direction::Forward, Direction::Reverse] } else { &[Direction::Forward] };
    for &d in dirs {
        for i in 0..2048 {
            let r = 360.0 * (i as f64 + 0.5) / 2048.0;
            e.push(true_error(model, r, d) - table.error_at(r, d));
        }
    }
    let mean = e.iter().sum::<f64>() / e.len() as f64;
    e.iter().map(|x| x - mean).collect()
}

fn quantile(mut v: Vec<f64>, q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((q * v.len() as f64) as usize).min(v.len() - 1)]
}

/// Process a case's survey (with check points when a tracker has doubts):
/// the processing, its samples and its `U`.
fn survey(case: &Case, rng: &mut Normal) -> (Processed, Vec<Sample>, Uncertainty) {
    let p = &case.plan;
    let targets: Vec<f64> = (0..p.points).map(|k| 360.0 * k as f64 / p.points as f64).collect();
    let mut samples = acquire(&case.model, &targets, p, p.runs, 0.0, None, rng);
    // The drift in time, measured and corrected as the lab loads a survey.
    let measured = crate::timedrift::estimate(&samples);
    let drift_in_time_u_deg = measured.as_ref().map(|d| d.table_u_deg(&samples));
    let crooked = measured.as_ref().filter(|d| d.left_beyond_doubt).map(|d| d.left_deg);
    let drift = measured.filter(|d| d.corrected);
    if let Some(d) = &drift {
        samples = crate::timedrift::corrected(&samples, d);
    }
    let design = &case.model.design;
    let mut processed = process_with_checks(&samples, design, None, None, &[]).expect("processed");
    if p.tracker {
        let at = plan_checks(&processed.left, &targets);
        if !at.is_empty() {
            let mut checks = acquire(&case.model, &at, p, 2, p.runs as f64, None, rng);
            if let Some(d) = &drift {
                checks = crate::timedrift::corrected(&checks, d);
            }
            processed = process_with_checks(&samples, design, None, None, &checks).expect("processed with checks");
        }
    }
    // A drift no straight line takes makes the table not a result, as the
    // lab's processing says.
    processed.prediction.uncorrected_drift_deg = crooked;
    let u = uncertainty(&processed, &samples, &UncertaintyInputs { drift_in_time_u_deg, ..Default::default() });
    (processed, samples, u)
}

/// One survey of `case`, judged against the truth (and verified when the
/// case says so).
fn run(case: &Case, seed: u64) -> Outcome {
    let mut rng = Normal::new(seed.wrapping_mul(0x9E37_79B9) ^ 0xC0FFEE);
    let (processed, samples, u) = survey(case, &mut rng);
    let table = &processed.built.table;
    let e = table_errors(&case.model, table, case.plan.bidirectional);
    let coverage = e.iter().filter(|x| x.abs() <= u.table_u_deg).count() as f64 / e.len() as f64;
    let p95 = quantile(e.iter().map(|x| x.abs()).collect(), 0.95);
    // A standard uncertainty is a size ("-0.00e0 deg" was printed).
    assert!(u.budget.iter().all(|c| c.u_deg.is_sign_positive()), "{}: {:?}", case.what, u.budget);
    assert!(processed.left.second_order_deg.is_sign_positive(), "{}: {:?}", case.what, processed.left);
    // SURVEY_MECHANISM_BUDGET=1: every survey's budget beside its truth.
    if std::env::var_os("SURVEY_MECHANISM_BUDGET").is_some() {
        eprintln!(
            "    {}: U {:.2e}, p95 {:.2e}, T {:.2e}\n{}{}",
            case.what,
            u.table_u_deg,
            p95,
            processed.analysis.noise.coherent_threshold_deg,
            u.text(),
            processed.resolutions.iter().map(|r| format!("    {}\n", r.why)).collect::<String>()
        );
    }
    let verdict = case.plan.verify.then(|| {
        let p = &case.plan;
        let n = p.points as f64;
        let at: Vec<f64> = (0..p.points)
            .map(|k| if p.tracker { 360.0 * (k as f64 + 0.5) / n } else { 360.0 * k as f64 / n })
            .collect();
        let axis = case.changed.as_ref().unwrap_or(&case.model);
        let corrected = acquire(axis, &at, p, p.runs, p.runs as f64 + 2.0, Some(table), &mut rng);
        let predicted = predicted_for(&processed.prediction, corrected.len());
        let claim = Claim {
            predicted_deg: predicted,
            u_deg: u.table_u_deg,
            native_deg: peak_deg(&samples),
            not_a_result: processed.prediction.not_a_result(),
            shared_reference_u_deg: u.reference_systematic_u_deg().map(|s| s * u.k),
        };
        let j = judge(&claim, &corrected, &[]);
        // The table's true error on the axis verified.
        let e = match &case.changed {
            Some(m) => table_errors(m, table, case.plan.bidirectional),
            None => e.clone(),
        };
        let peak = e.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let bad = peak > processed.prediction.corrected_peak_deg + u.table_u_deg;
        (j.verdict == Verdict::Confirmed, bad, processed.prediction.not_a_result().is_some())
    });
    Outcome {
        what: case.what.clone(),
        coverage,
        p95,
        u: u.table_u_deg,
        t: processed.analysis.noise.coherent_threshold_deg,
        verdict,
        changed: case.changed.is_some(),
    }
}

/// A model file's text from its parts.
fn model(design: &str, lines: &[(&str, f64, f64, f64)], extra: &str) -> Model {
    let mut text = format!("[design]\n{design}\n");
    for (kind, f, a, ph) in lines {
        text +=
            &format!("[[effect]]\nkind = \"{kind}\"\ncycles_per_rev = {f}\namplitude_deg = {a}\nphase_deg = {ph}\n");
    }
    text += extra;
    Model::parse(&text, "drawn").unwrap_or_else(|e| panic!("{e}\n{text}"))
}

fn pick<T: Copy>(rng: &mut Normal, of: &[T]) -> T {
    of[((rng.uniform() * of.len() as f64) as usize).min(of.len() - 1)]
}

fn between(rng: &mut Normal, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.uniform()
}

/// The mechanisms of issue 38, each a drawing of cases from a seed.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Mechanism {
    Nyquist,
    BelowThreshold,
    NoiseOverLines,
    StepDrift,
    ManyFaces,
    SparseUnknown,
    Changed,
    RampDrift,
    Fold,
}

const MECHANISMS: [Mechanism; 9] = [
    Mechanism::Nyquist,
    Mechanism::BelowThreshold,
    Mechanism::NoiseOverLines,
    Mechanism::StepDrift,
    Mechanism::ManyFaces,
    Mechanism::SparseUnknown,
    Mechanism::Changed,
    Mechanism::RampDrift,
    Mechanism::Fold,
];

impl Mechanism {
    fn name(self) -> &'static str {
        match self {
            Mechanism::Nyquist => "a line on the Nyquist bin",
            Mechanism::BelowThreshold => "a line just below the detection threshold",
            Mechanism::NoiseOverLines => "noise much larger than the lines",
            Mechanism::StepDrift => "step drift between runs",
            Mechanism::ManyFaces => "many polygon faces",
            Mechanism::SparseUnknown => "an unknown design sparsely sampled",
            Mechanism::Changed => "an axis changed before the verification",
            Mechanism::RampDrift => "a ramp within the runs (thermal growth)",
            Mechanism::Fold => "lines the design does not name folded onto named bins",
        }
    }

    /// The case of `seed`: a new model of the kind.
    fn case(self, seed: u64) -> Case {
        let mut rng = Normal::new(seed ^ (self as u64 + 1).wrapping_mul(0xA5A5_5A5A_1234));
        let r = &mut rng;
        let gear = pick(r, &[5.0, 6.0, 8.0, 9.0, 12.0]);
        let base = |r: &mut Normal, scale: f64| {
            vec![
                ("gear_pass", gear, scale * between(r, 0.004, 0.009), between(r, 0.0, 360.0)),
                ("gear_pass", 2.0 * gear, scale * between(r, 0.001, 0.003), between(r, 0.0, 360.0)),
                ("eccentricity", 1.0, scale * between(r, 0.0005, 0.002), between(r, 0.0, 360.0)),
            ]
        };
        let noise = |sigma: f64| format!("[[effect]]\nkind = \"noise\"\nsigma_deg = {sigma}\n");
        let backlash = |b: f64| format!("[[effect]]\nkind = \"backlash\"\namplitude_deg = {b}\n");
        match self {
            Mechanism::Nyquist => {
                let points = pick(r, &[48usize, 72, 96, 120]);
                let mesh = points as f64 / 2.0;
                let mut lines = base(r, 1.0);
                // Named by the design (its harmonics alias to the bin: the
                // table nulls it) or not (the table keeps what it sees).
                let named = seed % 4 < 2;
                let kind = if named { "tooth_mesh" } else { "harmonic" };
                lines.push((kind, mesh, between(r, 0.001, 0.003), between(r, 0.0, 360.0)));
                let tracker = seed.is_multiple_of(2);
                let teeth = if named { format!("{mesh}") } else { String::new() };
                Case {
                    what: format!(
                        "{points} points, a {kind} line at {mesh}, {}",
                        if tracker { "tracker" } else { "autocollimator" }
                    ),
                    model: model(
                        &format!("gear_ratios = [{gear}]\ntooth_counts = [{teeth}]"),
                        &lines,
                        &(backlash(0.004) + &noise(between(r, 0.0002, 0.0004))),
                    ),
                    changed: None,
                    plan: Plan { points, runs: 3, bidirectional: true, tracker, verify: false, timed: false },
                }
            }
            Mechanism::BelowThreshold => {
                let points = pick(r, &[72usize, 120, 180]);
                let sigma = between(r, 0.0002, 0.0006);
                let runs = pick(r, &[3u32, 5]);
                // The threshold of the mean spectrum: about sqrt(2 ln(2 M /
                // alpha)) standard deviations of a component, M = points / 2.
                let per_component = sigma / ((2 * runs) as f64).sqrt() * (2.0 / points as f64).sqrt();
                let t = per_component * (2.0 * (points as f64 / 0.01).ln()).sqrt();
                let f = pick(r, &[3.0, 7.0, 11.0, 13.0]);
                let mut lines = base(r, 1.0);
                let share = between(r, 0.7, 1.0);
                lines.push(("harmonic", f, share * t, between(r, 0.0, 360.0)));
                Case {
                    what: format!("{points} points, {runs} runs, a line at {f} of {share:.2} T"),
                    model: model(&format!("gear_ratios = [{gear}]"), &lines, &(backlash(0.004) + &noise(sigma))),
                    changed: None,
                    plan: Plan { points, runs, bidirectional: true, tracker: true, verify: true, timed: false },
                }
            }
            Mechanism::NoiseOverLines => {
                let points = pick(r, &[36usize, 72, 120]);
                let sigma = between(r, 0.003, 0.008);
                let runs = pick(r, &[2u32, 3, 5]);
                let scale = between(r, 0.03, 0.1);
                let lines = base(r, scale);
                Case {
                    what: format!("{points} points, {runs} runs, noise {sigma:.4} deg"),
                    model: model(&format!("gear_ratios = [{gear}]"), &lines, &noise(sigma)),
                    changed: None,
                    plan: Plan {
                        points,
                        runs,
                        bidirectional: seed.is_multiple_of(2),
                        tracker: true,
                        verify: true,
                        timed: false,
                    },
                }
            }
            Mechanism::StepDrift => {
                // Enough points that no design harmonic aliases (that is another mechanism).
                let points = pick(r, &[128usize, 144, 180]);
                let runs = pick(r, &[3u32, 4, 5]);
                let rate = between(r, 0.001, 0.004) * if r.uniform() < 0.5 { -1.0 } else { 1.0 };
                let lines = base(r, 1.0);
                let drift = format!("[[effect]]\nkind = \"drift\"\nrate_deg_per_run = {rate}\nshape = \"step\"\n");
                Case {
                    what: format!("{points} points, {runs} runs, a step of {rate:.4} deg a run"),
                    model: model(
                        &format!("gear_ratios = [{gear}]"),
                        &lines,
                        &(drift + &backlash(0.004) + &noise(0.0003)),
                    ),
                    changed: None,
                    plan: Plan {
                        points,
                        runs,
                        bidirectional: seed.is_multiple_of(2),
                        tracker: true,
                        verify: false,
                        timed: false,
                    },
                }
            }
            Mechanism::ManyFaces => {
                let points = pick(r, &[60usize, 72, 90]);
                let lines = base(r, 1.0);
                Case {
                    what: format!("{points} faces"),
                    model: model(
                        &format!("gear_ratios = [{gear}]"),
                        &lines,
                        &(backlash(0.006) + &noise(between(r, 0.0002, 0.0005))),
                    ),
                    changed: None,
                    plan: Plan {
                        points,
                        runs: pick(r, &[3u32, 5]),
                        bidirectional: true,
                        tracker: false,
                        verify: true,
                        timed: false,
                    },
                }
            }
            Mechanism::SparseUnknown => {
                let points = pick(r, &[16usize, 20, 24, 30]);
                let seen = pick(r, &[1.0, 2.0, 3.0]);
                let n = points as f64;
                let f = pick(r, &[n - seen, n + seen]);
                let lines = vec![
                    ("harmonic", f, between(r, 0.003, 0.008), between(r, 0.0, 360.0)),
                    // Another line, not at the aliased one's bin (two real lines
                    // in one bin are a limit of their own, stated in the docs).
                    (
                        "harmonic",
                        if seen == 1.0 { 2.0 } else { 1.0 },
                        between(r, 0.0005, 0.002),
                        between(r, 0.0, 360.0),
                    ),
                ];
                Case {
                    what: format!("{points} points, a line at {f} seen at {seen}"),
                    model: model("", &lines, &(backlash(0.002) + &noise(0.0002))),
                    changed: None,
                    plan: Plan { points, runs: 2, bidirectional: true, tracker: false, verify: false, timed: false },
                }
            }
            // Issue 49: the error grows linearly in time within the runs as
            // between them; the survey measures it from its own readings.
            Mechanism::RampDrift => {
                let points = pick(r, &[120usize, 144, 180]);
                let runs = pick(r, &[3u32, 4, 5]);
                let rate = between(r, 0.0015, 0.004) * if r.uniform() < 0.5 { -1.0 } else { 1.0 };
                let lines = base(r, 1.0);
                let drift = format!("[[effect]]\nkind = \"drift\"\nrate_deg_per_run = {rate}\nshape = \"ramp\"\n");
                Case {
                    what: format!("{points} points, {runs} runs, a ramp of {rate:.4} deg a run"),
                    model: model(
                        &format!("gear_ratios = [{gear}]"),
                        &lines,
                        &(drift + &backlash(0.004) + &noise(0.0003)),
                    ),
                    changed: None,
                    plan: Plan { points, runs, bidirectional: true, tracker: true, verify: false, timed: true },
                }
            }
            // Issue 49: a tooth mesh at N = T, its once-per-revolution
            // sidebands T +/- 1 (the gear's runout modulating it: not named by
            // the design) folding onto bin 1 and the mesh onto bin 0; the
            // design's own sidebands T +/- g land on the gear pass's bin (the
            // table nulls it until check points decide it); and a harmonic
            // above Nyquist folding onto a named bin: a sideband of the
            // second mesh harmonic, at 2T + 1 (bin 1 again: a fold the
            // survey lists) or at 2T - 2g (the second gear harmonic's bin:
            // one it does not, which the check points' residual must show).
            Mechanism::Fold => {
                let teeth = pick(r, &[120usize, 144, 180]);
                let t = teeth as f64;
                let mut lines = base(r, 1.0);
                lines.push(("tooth_mesh", t, between(r, 0.001, 0.003), between(r, 0.0, 360.0)));
                lines.push(("harmonic", t - 1.0, between(r, 0.0005, 0.0015), between(r, 0.0, 360.0)));
                lines.push(("harmonic", t + 1.0, between(r, 0.0005, 0.0015), between(r, 0.0, 360.0)));
                let high = if seed.is_multiple_of(2) { 2.0 * t + 1.0 } else { 2.0 * t - 2.0 * gear };
                lines.push(("harmonic", high, between(r, 0.0003, 0.001), between(r, 0.0, 360.0)));
                let runs = pick(r, &[3u32, 5]);
                let extra = if r.uniform() < 0.5 { backlash(0.003) } else { String::new() };
                Case {
                    what: format!("{teeth} points, a {teeth}-tooth mesh with {} and {}, and {high}", t - 1.0, t + 1.0),
                    model: model(
                        &format!("gear_ratios = [{gear}]\ntooth_counts = [{teeth}]"),
                        &lines,
                        &(extra + &noise(between(r, 0.0002, 0.0003))),
                    ),
                    changed: None,
                    plan: Plan { points: teeth, runs, bidirectional: true, tracker: true, verify: true, timed: false },
                }
            }
            // A bad table for the verification to find: the axis changed
            // (a new line, worn or knocked) between the survey and it.
            Mechanism::Changed => {
                let points = pick(r, &[72usize, 96, 120]);
                let lines = base(r, 1.0);
                let extra = backlash(0.004) + &noise(between(r, 0.0002, 0.0004));
                let design = format!("gear_ratios = [{gear}]");
                let f = pick(r, &[3.0, 4.0, 7.0, 11.0]);
                let a = between(r, 0.0005, 0.004);
                let mut worn = lines.clone();
                worn.push(("harmonic", f, a, between(r, 0.0, 360.0)));
                Case {
                    what: format!("{points} points, a line of {a:.4} deg at {f} new at the verification"),
                    model: model(&design, &lines, &extra),
                    changed: Some(model(&design, &worn, &extra)),
                    plan: Plan { points, runs: 3, bidirectional: true, tracker: true, verify: true, timed: false },
                }
            }
        }
    }
}

/// The figures of one mechanism over `seeds`, printed; the failures named.
fn measure(m: Mechanism, seeds: impl Iterator<Item = u64>) -> Vec<String> {
    let outcomes: Vec<Outcome> = seeds.map(|s| run(&m.case(s), s)).collect();
    let mut failures = Vec::new();
    for o in &outcomes {
        let verdict = match o.verdict {
            Some((c, bad, nar)) => format!(
                ", {}{}{}",
                if c { "confirmed" } else { "not confirmed" },
                if bad { ", beyond P + U" } else { "" },
                if nar { ", NOT A RESULT" } else { "" }
            ),
            None => String::new(),
        };
        eprintln!(
            "  {}: {}: within U {:.1} %, U {:.2e}, p95 {:.2e}, U/p95 {:.2}{verdict}",
            m.name(),
            o.what,
            100.0 * o.coverage,
            o.u,
            o.p95,
            o.u / o.p95
        );
        if o.coverage < 0.90 {
            failures.push(format!("{}: {}: {:.1} % within U", m.name(), o.what, 100.0 * o.coverage));
        }
        if o.u > 4.0 * o.p95 {
            failures.push(format!("{}: {}: U {:.1} x p95", m.name(), o.what, o.u / o.p95));
        }
        if let Some((true, bad, nar)) = o.verdict
            && (bad || nar)
        {
            {
                failures.push(format!(
                    "{}: {}: confirmed (beyond P + U: {bad}, not a result: {nar})",
                    m.name(),
                    o.what
                ));
            }
        }
    }
    let mean = outcomes.iter().map(|o| o.coverage).sum::<f64>() / outcomes.len() as f64;
    let worst_ratio = outcomes.iter().map(|o| o.u / o.p95).fold(0.0, f64::max);
    // Where U is above 4 x the truth's p95: how far above the threshold, the
    // smallest line the survey could have missed (U cannot be below it).
    let inflated: Vec<&Outcome> = outcomes.iter().filter(|o| o.u > 4.0 * o.p95).collect();
    let inflated = match inflated.len() {
        0 => String::new(),
        n => format!(
            " ({n} above 4: their U at most {:.2} T, their p95 at most {:.2} T)",
            inflated.iter().map(|o| o.u / o.t).fold(0.0, f64::max),
            inflated.iter().map(|o| o.p95 / o.t).fold(0.0, f64::max)
        ),
    };
    let unchanged: Vec<&Outcome> = outcomes.iter().filter(|o| !o.changed).collect();
    let not_confirmed = unchanged.iter().filter(|o| matches!(o.verdict, Some((false, false, false)))).count();
    let good = unchanged.iter().filter(|o| matches!(o.verdict, Some((_, false, false)))).count();
    let bad = outcomes.iter().filter(|o| matches!(o.verdict, Some((_, true, _)))).count();
    let bad_caught = outcomes.iter().filter(|o| matches!(o.verdict, Some((false, true, _)))).count();
    eprintln!(
        "{}: {} surveys, within U {:.1} % on average (least {:.1} %), U/p95 at most {:.2}{inflated}{}",
        m.name(),
        outcomes.len(),
        100.0 * mean,
        100.0 * outcomes.iter().map(|o| o.coverage).fold(1.0, f64::min),
        worst_ratio,
        if good > 0 { format!(", good tables not confirmed {not_confirmed} of {good}") } else { String::new() }
            + &if bad > 0 { format!(", bad tables not confirmed {bad_caught} of {bad}") } else { String::new() }
    );
    if mean < 0.95 {
        failures.push(format!("{}: {:.1} % within U on average", m.name(), 100.0 * mean));
    }
    failures
}

/// The mechanisms whose `U` covers the truth so far (the rest are measured
/// and printed; every verdict is held to one voice all the same), and those
/// whose `U` also stays within 4 x the truth's p95 on the CI's seeds.
const COVERED: [Mechanism; 8] = [
    Mechanism::Fold,
    Mechanism::Changed,
    Mechanism::RampDrift,
    Mechanism::Nyquist,
    Mechanism::BelowThreshold,
    Mechanism::NoiseOverLines,
    Mechanism::StepDrift,
    Mechanism::SparseUnknown,
];
const NOT_INFLATED: [Mechanism; 5] =
    [Mechanism::BelowThreshold, Mechanism::StepDrift, Mechanism::SparseUnknown, Mechanism::RampDrift, Mechanism::Fold];

#[test]
fn every_mechanism_on_two_seeds() {
    let failures: Vec<String> = MECHANISMS
        .iter()
        .flat_map(|&m| {
            measure(m, 1..=2).into_iter().filter(move |f| {
                f.contains("confirmed (")
                    || (COVERED.contains(&m) && f.contains("within U"))
                    || (NOT_INFLATED.contains(&m) && f.contains("x p95"))
            })
        })
        .collect();
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
#[ignore = "Monte Carlo over many seeds: SURVEY_MECHANISM_SEEDS=N, figures for docs/validation/uncertainty.md"]
fn mechanisms_monte_carlo() {
    let n: u64 = std::env::var("SURVEY_MECHANISM_SEEDS").ok().and_then(|s| s.parse().ok()).unwrap_or(20);
    // Seeds from here (the figures of the docs are of seeds 101 on: models
    // and noise the fixes were not made on, which were seeds 1 to 16).
    let first: u64 = std::env::var("SURVEY_MECHANISM_FIRST").ok().and_then(|s| s.parse().ok()).unwrap_or(101);
    let only = std::env::var("SURVEY_MECHANISM").ok();
    let failures: Vec<String> = MECHANISMS
        .iter()
        .filter(|m| only.as_deref().is_none_or(|o| m.name().contains(o)))
        .flat_map(|&m| measure(m, first..first + n))
        .collect();
    assert!(failures.is_empty(), "{failures:#?}");
}

/// A kept line of no design part just above the threshold may be noise
/// selected for being large: `U` allows for the table carrying it wholly
/// wrongly (issue 38, noise much larger than the lines: a false line at 1.1 T
/// beside a true one under T left 75 % of the circle within `U`).
#[test]
fn a_kept_line_under_twice_the_threshold_is_counted_as_possibly_false() {
    let case = Case {
        what: "72 points, noise 0.005 deg, a harmonic at 9".into(),
        model: model(
            "gear_ratios = [5]",
            &[("harmonic", 9.0, 1.4e-3, 30.0)],
            "[[effect]]\nkind = \"noise\"\nsigma_deg = 0.005\n",
        ),
        changed: None,
        plan: Plan { points: 72, runs: 5, bidirectional: true, tracker: false, verify: false, timed: false },
    };
    let (p, _, u) = survey(&case, &mut Normal::new(3));
    let t = p.analysis.noise.coherent_threshold_deg;
    let line = p.analysis.lines.iter().find(|l| l.cycles_per_rev == 9.0).expect("the line is kept");
    assert!(line.amplitude_deg > t && line.amplitude_deg < 2.0 * t, "{} against T {t}", line.amplitude_deg);
    assert!(u.budget.iter().any(|c| c.source.contains("possible false alarms")), "{:?}", u.budget);
    assert!(
        u.table_u_deg > t + line.amplitude_deg * 0.9,
        "U {} against T {t} and the line {}",
        u.table_u_deg,
        line.amplitude_deg
    );
}

/// Issue 49: without check points (a reference that measures only at its
/// targets) a bin that folds the design does not name land on is in doubt
/// whole, and `U` counts it; the mesh on bin 0 is said to be unseen. With
/// them (a tracker) the folds are measured, the gear pass's bin decided
/// and corrected.
#[test]
fn folds_onto_a_named_bin_are_in_doubt_until_check_points_measure_them() {
    let fold = |tracker: bool| Case {
        what: "the issue's 180-tooth mesh at 180 points".into(),
        model: model(
            "gear_ratios = [20]\ntooth_counts = [180]",
            &[
                ("eccentricity", 1.0, 0.002, 40.0),
                ("gear_pass", 20.0, 0.006, 10.0),
                ("tooth_mesh", 180.0, 0.002, 70.0),
                ("harmonic", 179.0, 0.001, 20.0),
                ("harmonic", 181.0, 0.001, 150.0),
            ],
            "[[effect]]\nkind = \"noise\"\nsigma_deg = 0.0002\n",
        ),
        changed: None,
        plan: Plan { points: 180, runs: 3, bidirectional: true, tracker, verify: false, timed: false },
    };
    let (p, _, u) = survey(&fold(false), &mut Normal::new(7));
    let doubt = p.left.lines.iter().find(|l| l.kind == crate::left::LeftKind::MayFold).expect("bin 1 in doubt");
    assert_eq!((doubt.observed_cycles, doubt.candidates.clone()), (1.0, vec![1.0, 179.0, 181.0]));
    assert!(p.notes.iter().any(|n| n.contains("180 cycles/rev") && n.contains("lands on bin 0")), "{:?}", p.notes);
    assert!(u.budget.iter().any(|c| c.source.contains("bin 1 may hold a fold")), "{}", u.text());
    let (p, _, u) = survey(&fold(true), &mut Normal::new(7));
    assert!(p.decisions.kept_cycles.contains(&20.0), "bin 20 decided and corrected: {:?}", p.notes);
    let folded: Vec<f64> =
        p.left.lines.iter().filter(|l| l.kind == crate::left::LeftKind::Folded).map(|l| l.candidates[0]).collect();
    assert!(folded.contains(&179.0) && folded.contains(&181.0) && folded.contains(&180.0), "{folded:?}");
    let e = table_errors(&fold(true).model, &p.built.table, true);
    let within = e.iter().filter(|x| x.abs() <= u.table_u_deg).count() as f64 / e.len() as f64;
    assert!(within >= 0.9, "{within} within U {}", u.table_u_deg);
}
