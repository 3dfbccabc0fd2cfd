//! Words: labels of effects, the explanations of what was added or adjusted,
//! the statement of the tests, and the closing remarks.

use super::views::{Ctx, Views};
use super::{AdjustedEffect, FoundEffect, NoiseFloor, Significance};
use survey_processing::analysis::Analysis;
use survey_processing::model::{DriftShape, Effect, Model, PeriodicKind};

/// A frequency or ratio: whole numbers without decimals.
pub(crate) fn num(v: f64) -> String {
    if (v - v.round()).abs() < 1e-9 {
        format!("{}", v.round() as i64)
    } else {
        format!("{}", (v * 1000.0).round() / 1000.0)
    }
}

/// `tooth_mesh 250 cycles/rev`, `backlash`, `drift`.
pub(crate) fn label(e: &Effect) -> String {
    match e {
        Effect::Periodic { kind, cycles_per_rev, .. } => {
            format!("{} {} cycles/rev", kind.as_str(), num(*cycles_per_rev))
        }
        other => other.kind_str().to_string(),
    }
}

/// The frequency of an effect (0 for backlash, drift and noise).
pub(crate) fn cycles(e: &Effect) -> f64 {
    match e {
        Effect::Periodic { cycles_per_rev, .. } => *cycles_per_rev,
        _ => 0.0,
    }
}

/// Amplitude (backlash, drift per run, noise sigma) and phase of an effect.
pub(crate) fn amplitude_phase(e: &Effect) -> (f64, Option<f64>) {
    match e {
        Effect::Periodic { amplitude_deg, phase_deg, .. } => (*amplitude_deg, Some(*phase_deg)),
        Effect::Backlash { amplitude_deg } => (*amplitude_deg, None),
        Effect::Drift { rate_deg_per_run, .. } => (*rate_deg_per_run, None),
        Effect::Noise { sigma_deg } => (*sigma_deg, None),
    }
}

fn se_of(touched: &[usize], se: &[f64], index: usize) -> f64 {
    touched.iter().position(|&i| i == index).map_or(0.0, |k| se[k])
}

/// Fill in the final values and the explanations.
pub(crate) fn finish(
    added: &mut [FoundEffect],
    adjusted: &mut [AdjustedEffect],
    model: &Model,
    touched: &[usize],
    se: &[f64],
    ctx: &Ctx,
) {
    let runs = ctx.survey.runs();
    let points = ctx.analysis_points_per_rev();
    let snapshot: Vec<FoundEffect> = added.to_vec();
    for f in added.iter_mut() {
        let e = &model.effects[f.index];
        let (a, p) = amplitude_phase(e);
        f.cycles_per_rev = cycles(e);
        f.amplitude_deg = a;
        f.phase_deg = p;
        f.standard_error_deg = se_of(touched, se, f.index);
        f.explanation = match (e, &f.line) {
            (Effect::Periodic { kind, cycles_per_rev, .. }, Some(line)) => {
                let mut s = if *kind == PeriodicKind::Harmonic {
                    line.explanation.clone()
                } else {
                    format!("{} cycles/rev: {}", num(*cycles_per_rev), line.explanation)
                };
                if let Some(part) = f.part.filter(|p| !p.sideband) {
                    let mut others: Vec<(u32, f64, Option<f64>)> = snapshot
                        .iter()
                        .filter(|o| o.index != f.index)
                        .filter_map(|o| {
                            o.part
                                .filter(|q| !q.sideband && q.kind == part.kind && (q.base - part.base).abs() < 1e-9)
                                .map(|q| (q, o))
                        })
                        .map(|(q, o)| {
                            let f_other = cycles(&model.effects[o.index]);
                            (q.harmonic, f_other, o.aliased.then(|| o.observed_cycles_per_rev.unwrap_or(f_other)))
                        })
                        .collect();
                    others.sort_by_key(|o| o.0);
                    let aliased = |f: f64, seen: f64| {
                        format!(
                            "{} cycles/rev, aliased to {} at {} points per revolution",
                            num(f),
                            num(seen),
                            num(points)
                        )
                    };
                    match others.as_slice() {
                        [] => {}
                        [(h, f_other, seen)] => {
                            let at = match seen {
                                Some(seen) => aliased(*f_other, *seen),
                                None => format!("{} cycles/rev", num(*f_other)),
                            };
                            s += &format!("; its harmonic {h} also shows ({at})");
                        }
                        many => {
                            let hs: Vec<String> = many.iter().map(|o| o.0.to_string()).collect();
                            let fs: Vec<String> = many.iter().map(|o| num(o.1)).collect();
                            s += &format!("; its harmonics {} also show ({} cycles/rev", hs.join(", "), fs.join(", "));
                            for (h, f_other, seen) in many {
                                if let Some(seen) = seen {
                                    s += &format!("; harmonic {h} at {}", aliased(*f_other, *seen));
                                }
                            }
                            s += ")";
                        }
                    }
                }
                for n in &line.notes {
                    s += &format!("; {n}");
                }
                s
            }
            (Effect::Backlash { amplitude_deg }, _) => format!(
                "forward and reverse approaches differ by {:.3e} deg that the model did not have: lost motion in the \
                 drive (gear backlash, coupling play or wind-up); forward reads +{:.3e} deg, reverse -{:.3e} deg",
                amplitude_deg,
                amplitude_deg / 2.0,
                amplitude_deg / 2.0
            ),
            (Effect::Drift { rate_deg_per_run, shape: DriftShape::Ramp }, _) => format!(
                "the error changes by {:+.3e} deg per run ({:+.3e} deg from the first run to the last of {runs}), \
                 steadily in time (a ramp): a thermal drift of the axis or of the reference; let both warm up before \
                 measuring, or measure the drift and recalibrate more often",
                rate_deg_per_run,
                rate_deg_per_run * (runs.max(1) - 1) as f64
            ),
            (Effect::Drift { rate_deg_per_run, shape: DriftShape::Step }, _) => format!(
                "the error jumps by {:+.3e} deg from one run to the next and holds within a run (a step; {:+.3e} deg \
                 from the first run to the last of {runs}): the axis re-homed, or the reference was set up again, \
                 between runs; keep the set-up between runs, or reference each run to a fixed target",
                rate_deg_per_run,
                rate_deg_per_run * (runs.max(1) - 1) as f64
            ),
            (e, _) => label(e),
        };
    }
    for f in adjusted.iter_mut() {
        let e = &model.effects[f.index];
        let (a, p) = amplitude_phase(e);
        f.cycles_per_rev = cycles(e);
        f.amplitude_deg = a;
        f.phase_deg = p;
        f.standard_error_deg = se_of(touched, se, f.index);
        let unit = if matches!(e, Effect::Drift { .. }) { "deg per run" } else { "deg" };
        // Each figure with its unit, so a sentence read in another unit converts both.
        let mut s = format!("{}: amplitude {:.3e} {unit} -> {:.3e} {unit}", label(e), f.amplitude_before_deg, a);
        if let (Some(p0), Some(p1)) = (f.phase_before_deg, p) {
            s += &format!(", phase {p0:.1} -> {p1:.1} deg");
        }
        if let Some(line) = &f.line {
            s += &format!(" ({})", line.explanation);
        }
        f.explanation = s;
    }
}

/// The tests in numbers and words.
pub(crate) fn significance(ctx: &Ctx, first: &Analysis, before: &Views, line_factor: f64) -> Significance {
    let alpha = ctx.alpha;
    let m = first.noise.tests;
    let per_line = if ctx.survey.runs() >= 2 {
        ctx.analysis.false_alarm_rate / (2 * m.max(1)) as f64
    } else {
        ctx.analysis.false_alarm_rate / m.max(1) as f64
    };
    let quarter = alpha * super::views::SCALAR_SHARE;
    let mut s = format!(
        "a disagreement is named only when a test rejects \"the model explains the data\"; on a survey the model \
         explains, the expected number of effects named is at most {alpha} per pass of the tests: {} for the lines \
         ({m} frequencies, each tested at {per_line:.2e}: the mean residual spectrum above {line_factor:.2} standard \
         deviations of a quadrature component, {:.2e} deg)",
        alpha / 2.0,
        first.noise.coherent_threshold_deg
    );
    match &before.direction {
        Some(d) => {
            s += &format!(
                ", {quarter} for the backlash (the fitted change above {:.2} standard errors, {:.2e} deg)",
                d.threshold_deg / d.standard_error_deg.max(f64::MIN_POSITIVE),
                d.threshold_deg
            )
        }
        None => s += ", none for the backlash (one direction measured)",
    }
    match &before.time {
        Some(t) => {
            s += &format!(
                ", {quarter} for the drift (the slope of the run means above {:.2} standard errors, {:.2e} deg per run, {})",
                t.threshold_deg_per_run / t.standard_error_deg_per_run.max(f64::MIN_POSITIVE),
                t.threshold_deg_per_run,
                match t.test {
                    super::TrendTest::NoiseFloor => "against the noise floor".to_string(),
                    super::TrendTest::RunScatter => format!(
                        "against the run-to-run scatter, Student t with {} degrees of freedom",
                        t.dof.unwrap_or(0)
                    ),
                }
            )
        }
        None => s += ", none for the drift (one run)",
    }
    Significance {
        false_alarm_rate: alpha,
        frequencies_tested: m,
        line_threshold_factor: line_factor,
        line_threshold_deg: first.noise.coherent_threshold_deg,
        backlash_threshold_deg: before.direction.as_ref().map(|d| d.threshold_deg),
        drift_threshold_deg_per_run: before.time.as_ref().map(|t| t.threshold_deg_per_run),
        statement: s,
    }
}

/// Remarks on what is left.
pub(crate) fn closing_notes(notes: &mut Vec<String>, after: &Views, noise: &NoiseFloor, sigma: f64, first: &Analysis) {
    for l in after.frequency.lines.iter().filter(|l| !l.repeatable && !l.coherent) {
        notes.push(format!(
            "a line at {} cycles/rev ({:.2e} deg) changes phase from run to run: it is not repeatable, and no effect \
             of the model file can hold it",
            num(l.observed_cycles_per_rev),
            l.amplitude_deg
        ));
    }
    if let Some(t) = after.time.as_ref().filter(|t| t.run_offsets) {
        let spread = {
            let m: Vec<f64> = t.run_means.iter().map(|r| r.mean_deg).collect();
            let mean = m.iter().sum::<f64>() / m.len() as f64;
            (m.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / m.len() as f64).sqrt()
        };
        notes.push(format!(
            "the runs are offset from each other by more than the noise explains ({spread:.2e} deg RMS): run-to-run \
             offsets are not drift, and no effect of the model file holds them"
        ));
    }
    if after.angle.targets_outside > 0 {
        notes.push(format!(
            "{} targets still leave the band of +/-{:.2e} deg in angle (largest {:+.2e} deg at {} deg): an error that \
             is not periodic over the range, or at a frequency that was not tested",
            after.angle.targets_outside,
            after.angle.band_deg,
            after.angle.mean_peak_deg,
            num(after.angle.peak_at_deg)
        ));
    }
    if first.method == survey_processing::analysis::Method::LeastSquares {
        notes.push(
            "partial range: only the design frequencies were tested; a periodic error at any other frequency stays in \
             the residual"
                .to_string(),
        );
    }
    if noise.model_noise_deg > 0.0 && !(0.8..=1.25).contains(&(sigma / noise.model_noise_deg)) {
        notes.push(format!(
            "the noise floor ({sigma:.2e} deg) differs from the model's noise ({:.2e} deg): the floor also holds the \
             reference instrument's noise; the model's noise effect is left as it is",
            noise.model_noise_deg
        ));
    }
}

/// With a tracker, an eccentricity found may be the reference's axis location.
pub(crate) fn reference_note(
    notes: &mut Vec<String>,
    added: &[FoundEffect],
    adjusted: &[AdjustedEffect],
    reference: &super::ReferenceInfo,
) {
    let found = added.iter().any(|e| e.kind == "eccentricity") || adjusted.iter().any(|e| e.kind == "eccentricity");
    let super::ReferenceInfo::Tracker { radius_mm, points, axis_se_deg, refitted } = reference else { return };
    if !found {
        return;
    }
    let how = if *refitted {
        format!("fitted again from {points} SMR positions")
    } else {
        format!("located from {points} SMR positions before the runs")
    };
    notes.push(format!(
        "the reference is a tracker whose axis was {how} ({radius_mm:.1} mm arm): an error in that location also reads \
         as a once-per-revolution error, {axis_se_deg:.1e} deg here (1 sigma); an eccentricity change not much larger \
         than that may be the reference's, not the positioner's"
    ));
}
