//! The four views of the gap between model and data: in angle, in spatial
//! frequency, by direction and in time. See the documentation of
//! [`crate`] for the tests they make.

use super::ModelGapError;
use super::stats::{chi2_isf, least_squares, normal_two_sided_isf, t_two_sided_isf};
use super::survey::Survey;
use serde::Serialize;
use survey_processing::analysis::{Analysis, AnalysisOptions, Method, alias, analyse_map};
use survey_processing::errormap::ErrorMap;
use survey_processing::model::{Design, Effect, Model, PeriodicKind};

/// The gap seen four ways, for one model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Views {
    /// RMS of the residual (data minus model, zero reference fitted) over every sample, degrees.
    pub rms_deg: f64,
    /// In angle: the mean residual of each target against its band.
    pub angle: AngleView,
    /// In spatial frequency: the lines of the residual above the noise floor.
    pub frequency: FrequencyView,
    /// By direction: forward minus reverse (`None` for a one-way survey).
    pub direction: Option<DirectionView>,
    /// In time: the trend across runs (`None` with one run).
    pub time: Option<TimeView>,
}

/// The residual in angle.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AngleView {
    /// Half-width of the band the mean residual of every target stays inside
    /// when the model explains the data: `z * sigma / sqrt(runs * directions)`
    /// with `z` the two-sided normal point at `false_alarm_rate / targets`.
    pub band_deg: f64,
    /// RMS over targets of the mean residual (over runs and directions), degrees.
    pub mean_rms_deg: f64,
    /// The mean residual of largest magnitude (signed), degrees.
    pub mean_peak_deg: f64,
    /// Where it is, degrees.
    pub peak_at_deg: f64,
    /// Targets whose mean residual is outside the band.
    pub targets_outside: usize,
    /// Ranges of consecutive targets outside the band.
    pub ranges_total: usize,
    /// The (at most 20) ranges with the largest peaks, in angle order.
    pub ranges: Vec<AngleRange>,
}

/// Consecutive targets whose mean residual leaves the band.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AngleRange {
    /// First target of the range, degrees.
    pub start_deg: f64,
    /// Last target of the range, degrees (below `start_deg` when it wraps through 0).
    pub end_deg: f64,
    /// The mean residual of largest magnitude in the range (signed), degrees.
    pub peak_deg: f64,
    /// Where it is, degrees.
    pub at_deg: f64,
    /// Number of targets.
    pub targets: usize,
}

/// The residual in spatial frequency (the spectral analysis of the residual).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrequencyView {
    /// DFT of a full circle, or least squares at the design frequencies.
    pub method: Method,
    /// Points per revolution.
    pub points_per_rev: f64,
    /// Standard deviation of each quadrature component of a line in the mean
    /// spectrum of the residual, degrees (for a partial range: the typical one).
    pub line_noise_sd_deg: f64,
    /// A line is significant above this amplitude, degrees.
    pub threshold_deg: f64,
    /// The significant lines, largest first.
    pub lines: Vec<GapLine>,
}

/// A significant line of the residual, named from the design.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GapLine {
    /// Where it is seen, cycles/rev.
    pub observed_cycles_per_rev: f64,
    /// What it is, cycles/rev (the design harmonic it is an alias of, if aliased).
    pub cycles_per_rev: f64,
    /// Amplitude in the mean spectrum of the residual, degrees.
    pub amplitude_deg: f64,
    /// Phase at `cycles_per_rev`, degrees.
    pub phase_deg: f64,
    /// Its significance threshold, degrees.
    pub threshold_deg: f64,
    /// Passed the coherent test (the mean over runs is above the threshold).
    pub coherent: bool,
    /// Coherent and phase-consistent across runs (what a model effect can explain).
    pub repeatable: bool,
    /// The contract's kind word of its name.
    pub kind: String,
    /// What the design says it is.
    pub explanation: String,
    /// Whether it is an aliased design harmonic.
    pub aliased: bool,
    /// Remarks from the naming.
    pub notes: Vec<String>,
    /// The model effect (index in the model's effects) that sits at this line, if any.
    pub model_effect: Option<usize>,
    #[serde(skip)]
    pub(crate) periodic_kind: PeriodicKind,
    #[serde(skip)]
    pub(crate) part: Option<Part>,
}

/// The design part a line comes from: a harmonic of a gear pass or a tooth count.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Part {
    pub kind: PeriodicKind,
    pub base: f64,
    pub harmonic: u32,
    pub sideband: bool,
}

/// The residual by direction.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DirectionView {
    /// Mean over targets and runs of forward minus reverse, degrees.
    pub forward_minus_reverse_deg: f64,
    /// The backlash the model lacks (least squares with the offset and a
    /// drift of either shape), degrees: forward reads `+change/2`, reverse `-change/2`.
    pub backlash_change_deg: f64,
    /// Its standard error, degrees.
    pub standard_error_deg: f64,
    /// Significant above this magnitude, degrees.
    pub threshold_deg: f64,
    /// Whether the change is significant.
    pub significant: bool,
    /// RMS over targets of forward minus reverse about its mean, degrees: a
    /// direction-dependent error that no backlash explains shows here.
    pub hysteresis_spread_deg: f64,
}

/// How the trend across runs was tested.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TrendTest {
    /// Against the noise floor: the run means scatter as the noise predicts.
    NoiseFloor,
    /// Against the scatter of the run means about the trend (Student t,
    /// `runs - 2` degrees of freedom): the runs are offset from each other by
    /// more than the noise explains.
    RunScatter,
}

/// The mean residual of one run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunMean {
    /// The run number.
    pub run: u32,
    /// Mean residual, degrees.
    pub mean_deg: f64,
    /// Mean time of its samples, runs elapsed since the first sample.
    pub runs_elapsed: f64,
}

/// The residual in time.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TimeView {
    /// Each run's mean residual.
    pub run_means: Vec<RunMean>,
    /// The drift the model lacks, degrees per run (slope of the run means).
    pub drift_change_deg_per_run: f64,
    /// Its standard error.
    pub standard_error_deg_per_run: f64,
    /// Significant above this magnitude, degrees per run.
    pub threshold_deg_per_run: f64,
    /// Which test.
    pub test: TrendTest,
    /// Degrees of freedom of the run scatter (`runs - 2`), when used or measurable.
    pub dof: Option<usize>,
    /// Whether the run means scatter about the trend more than the noise explains.
    pub run_offsets: bool,
    /// Whether the drift change is significant.
    pub significant: bool,
}

/// What the views need besides the residual.
#[derive(Debug, Clone)]
pub(crate) struct Ctx<'a> {
    pub survey: &'a Survey<'a>,
    pub design: &'a Design,
    /// Analysis options, with the false-alarm rate of the spectral tests set.
    pub analysis: AnalysisOptions,
    /// Expected false effects per pass of all the tests.
    pub alpha: f64,
    /// The noise floor: standard deviation of one sample, degrees.
    pub sigma: f64,
}

/// Share of the false-alarm rate for the backlash test and for the drift test
/// (the spectral lines take the other half).
pub(crate) const SCALAR_SHARE: f64 = 0.25;

/// The spectral analysis of a residual: of the survey's samples with their
/// error replaced by it (`readout = residual`, `actual = 0`), grouped as the
/// survey's, with no copy of the samples made.
pub(crate) fn analyse_residual(ctx: &Ctx, residual: &[f64]) -> Result<Analysis, ModelGapError> {
    ctx.analysis.validate()?;
    let map = ErrorMap::from_grouped_errors(ctx.survey.samples, &ctx.survey.groups, residual)?;
    Ok(analyse_map(map, ctx.design, &ctx.analysis)?)
}

/// All four views of `residual` (data minus `model`, offset removed), and the
/// spectral analysis behind the frequency view.
pub(crate) fn views(ctx: &Ctx, model: &Model, residual: &[f64]) -> Result<(Views, Analysis), ModelGapError> {
    let analysis = analyse_residual(ctx, residual)?;
    let n = residual.len() as f64;
    let v = Views {
        rms_deg: (residual.iter().map(|r| r * r).sum::<f64>() / n).sqrt(),
        angle: angle_view(ctx, residual),
        frequency: frequency_view(&analysis, model),
        direction: direction_view(ctx, residual),
        time: time_view(ctx, residual),
    };
    Ok((v, analysis))
}

fn angle_view(ctx: &Ctx, residual: &[f64]) -> AngleView {
    let s = ctx.survey;
    let t = s.targets();
    let (mean, _) = s.target_means(residual);
    let per_target = (s.runs() * s.dirs.len()) as f64;
    let band = normal_two_sided_isf(ctx.alpha / t as f64) * ctx.sigma / per_target.sqrt();
    let targets = &s.map.targets_deg;
    let (peak_i, _) = mean
        .iter()
        .enumerate()
        .fold((0, 0.0f64), |(bi, bv), (i, v)| if v.abs() > bv { (i, v.abs()) } else { (bi, bv) });
    let outside: Vec<bool> = mean.iter().map(|m| m.abs() > band).collect();
    let mut ranges: Vec<(usize, usize)> = Vec::new();
    let mut i = 0;
    while i < t {
        if outside[i] {
            let start = i;
            while i + 1 < t && outside[i + 1] {
                i += 1;
            }
            ranges.push((start, i));
        }
        i += 1;
    }
    let full_circle = matches!(s.map.coverage, survey_processing::errormap::Coverage::FullCircle { .. });
    if full_circle && ranges.len() >= 2 && ranges[0].0 == 0 && ranges.last().is_some_and(|r| r.1 == t - 1) {
        let last = ranges.pop().expect("two ranges or more");
        ranges[0].0 = last.0;
    }
    let mut out: Vec<AngleRange> = ranges
        .iter()
        .map(|&(a, b)| {
            let idx: Vec<usize> = if a <= b { (a..=b).collect() } else { (a..t).chain(0..=b).collect() };
            let k = idx.iter().copied().fold(idx[0], |best, j| if mean[j].abs() > mean[best].abs() { j } else { best });
            AngleRange {
                start_deg: targets[a],
                end_deg: targets[b],
                peak_deg: mean[k],
                at_deg: targets[k],
                targets: idx.len(),
            }
        })
        .collect();
    let ranges_total = out.len();
    out.sort_by(|a, b| b.peak_deg.abs().total_cmp(&a.peak_deg.abs()));
    out.truncate(20);
    out.sort_by(|a, b| a.start_deg.total_cmp(&b.start_deg));
    AngleView {
        band_deg: band,
        mean_rms_deg: (mean.iter().map(|m| m * m).sum::<f64>() / t as f64).sqrt(),
        mean_peak_deg: mean[peak_i],
        peak_at_deg: targets[peak_i],
        targets_outside: outside.iter().filter(|o| **o).count(),
        ranges_total,
        ranges: out,
    }
}

/// The model's periodic effect seen at a line: one whose frequency lands on
/// the line's bin (full circle, aliases included), or equals it (partial
/// range). The one at the line's true frequency first.
pub(crate) fn effect_at(
    model: &Model,
    observed: f64,
    true_cycles: f64,
    points_per_rev: f64,
    full_circle: bool,
) -> Option<usize> {
    let lands = |f: f64| {
        if full_circle {
            (alias(f, points_per_rev).observed - observed).abs() <= 0.5
        } else {
            (f - observed).abs() <= 1e-9 * f.max(1.0)
        }
    };
    let periodic: Vec<(usize, f64)> = model
        .effects
        .iter()
        .enumerate()
        .filter_map(|(i, e)| match e {
            Effect::Periodic { cycles_per_rev, .. } => Some((i, *cycles_per_rev)),
            _ => None,
        })
        .filter(|(_, f)| lands(*f))
        .collect();
    periodic.iter().find(|(_, f)| (f - true_cycles).abs() <= 1e-9 * f.max(1.0)).or(periodic.first()).map(|(i, _)| *i)
}

fn frequency_view(a: &Analysis, model: &Model) -> FrequencyView {
    let full_circle = a.method == Method::Dft;
    let factor =
        if a.noise.line_sd_mean_deg > 0.0 { a.noise.coherent_threshold_deg / a.noise.line_sd_mean_deg } else { 0.0 };
    let mut lines: Vec<GapLine> = a
        .lines
        .iter()
        .map(|l| {
            let part = l
                .candidates
                .iter()
                .find(|c| c.kind == l.kind && (c.cycles_per_rev - l.true_cycles_per_rev).abs() <= 1e-9)
                .filter(|c| matches!(c.kind, PeriodicKind::GearPass | PeriodicKind::ToothMesh))
                .map(|c| Part {
                    kind: c.kind,
                    base: c.cycles_per_rev / c.harmonic.max(1) as f64,
                    harmonic: c.harmonic,
                    sideband: c.sideband.is_some(),
                });
            GapLine {
                observed_cycles_per_rev: l.cycles_per_rev,
                cycles_per_rev: l.true_cycles_per_rev,
                amplitude_deg: l.mean_amplitude_deg,
                phase_deg: l.true_phase_deg,
                threshold_deg: factor * l.noise_sd_deg,
                coherent: l.coherent,
                repeatable: l.repeatable,
                kind: l.kind.as_str().to_string(),
                explanation: l.explanation.clone(),
                aliased: l.aliased,
                notes: l.notes.clone(),
                model_effect: effect_at(model, l.cycles_per_rev, l.true_cycles_per_rev, a.points_per_rev, full_circle),
                periodic_kind: l.kind,
                part,
            }
        })
        .collect();
    lines.sort_by(|x, y| y.amplitude_deg.total_cmp(&x.amplitude_deg));
    FrequencyView {
        method: a.method,
        points_per_rev: a.points_per_rev,
        line_noise_sd_deg: a.noise.line_sd_mean_deg,
        threshold_deg: a.noise.coherent_threshold_deg,
        lines,
    }
}

fn direction_view(ctx: &Ctx, residual: &[f64]) -> Option<DirectionView> {
    let s = ctx.survey;
    if !s.bidirectional() {
        return None;
    }
    let n = s.len();
    let half_sign: Vec<f64> = (0..n).map(|i| s.direction(i).sign() / 2.0).collect();
    let ones = vec![1.0; n];
    // A drift of either shape is a nuisance here: a ramp moves forward against
    // reverse within a run, and a step fitted as a ramp would too.
    let both = least_squares(&[&ones, &half_sign, &s.tau, &s.run_index], residual);
    let fit = both
        .or_else(|_| least_squares(&[&ones, &half_sign, &s.tau], residual))
        .or_else(|_| least_squares(&[&ones, &half_sign], residual))
        .ok()?;
    let se = ctx.sigma * fit.unit_var[1].sqrt();
    let threshold = normal_two_sided_isf(ctx.alpha * SCALAR_SHARE) * se;
    // Per target: forward mean minus reverse mean.
    let t = s.targets();
    let mut acc = vec![[0.0f64; 4]; t];
    for (i, r) in residual.iter().enumerate() {
        let k = if s.direction(i) == survey_processing::types::Direction::Forward { 0 } else { 2 };
        acc[s.target[i] as usize][k] += r;
        acc[s.target[i] as usize][k + 1] += 1.0;
    }
    let h: Vec<f64> = acc.iter().map(|a| a[0] / a[1] - a[2] / a[3]).collect();
    let mean = h.iter().sum::<f64>() / t as f64;
    let spread = (h.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / t as f64).sqrt();
    Some(DirectionView {
        forward_minus_reverse_deg: mean,
        backlash_change_deg: fit.coef[1],
        standard_error_deg: se,
        threshold_deg: threshold,
        significant: fit.coef[1].abs() > threshold,
        hysteresis_spread_deg: spread,
    })
}

fn time_view(ctx: &Ctx, residual: &[f64]) -> Option<TimeView> {
    let s = ctx.survey;
    let r = s.runs();
    if r < 2 {
        return None;
    }
    let mut acc = vec![[0.0f64; 3]; r];
    for (i, v) in residual.iter().enumerate() {
        let run = s.run[i] as usize;
        acc[run][0] += v;
        acc[run][1] += s.tau[i];
        acc[run][2] += 1.0;
    }
    let m: Vec<f64> = acc.iter().map(|a| a[0] / a[2]).collect();
    let x: Vec<f64> = acc.iter().map(|a| a[1] / a[2]).collect();
    let per_run = acc.iter().map(|a| a[2]).fold(f64::INFINITY, f64::min);
    let (mx, mm) = (x.iter().sum::<f64>() / r as f64, m.iter().sum::<f64>() / r as f64);
    let sxx: f64 = x.iter().map(|v| (v - mx).powi(2)).sum();
    if sxx.is_nan() || sxx <= 0.0 {
        return None;
    }
    let slope = x.iter().zip(&m).map(|(a, b)| (a - mx) * (b - mm)).sum::<f64>() / sxx;
    let white_var = ctx.sigma * ctx.sigma / per_run;
    let p = ctx.alpha * SCALAR_SHARE;
    let (dof, lack) = if r >= 3 {
        let ss: f64 = x.iter().zip(&m).map(|(a, b)| (b - mm - slope * (a - mx)).powi(2)).sum();
        (Some(r - 2), Some(ss / (r - 2) as f64))
    } else {
        (None, None)
    };
    // Pre-test (1 %): do the run means scatter about the trend more than the noise explains?
    let run_offsets = match (dof, lack) {
        (Some(d), Some(l)) => white_var > 0.0 && l * d as f64 / white_var > chi2_isf(0.01, d),
        _ => false,
    };
    let (test, se, crit) = if run_offsets {
        let d = dof.expect("run offsets need a dof");
        (TrendTest::RunScatter, (lack.expect("with dof") / sxx).sqrt(), t_two_sided_isf(p, d))
    } else {
        (TrendTest::NoiseFloor, (white_var / sxx).sqrt(), normal_two_sided_isf(p))
    };
    Some(TimeView {
        run_means: s
            .map
            .runs
            .iter()
            .zip(&m)
            .zip(&x)
            .map(|((run, mean), t)| RunMean { run: *run, mean_deg: *mean, runs_elapsed: *t })
            .collect(),
        drift_change_deg_per_run: slope,
        standard_error_deg_per_run: se,
        threshold_deg_per_run: crit * se,
        test,
        dof,
        run_offsets,
        significant: slope.abs() > crit * se,
    })
}
