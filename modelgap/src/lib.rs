//! Comparisons of a survey with something else: with a positioner model
//! (model-gap, this file) and with another survey of the same positioner
//! (`compare`: has it changed?). Pure, like `survey-processing`, on which it
//! builds.
//!
//! # Model-gap
//!
//! Model-gap: where a positioner model and a measured survey disagree, what
//! each disagreement is, and the model that closes the gap.
//!
//! [`model_gap`] simulates the model at the survey's samples with the model
//! code the simulators run ([`Model::systematic_error_deg`], its effects
//! sorted out once: [`survey_processing::model::Systematic`], the same sums; evaluated at
//! the measured actual angle because the simulators read `readout = actual +
//! e(actual)` with the servo holding the readout on target), fits the constant
//! offset between model and data (a matter of zero reference: always fitted,
//! never reported), and looks at the residual four ways ([`Views`]):
//!
//! - in angle: the mean residual of each target (over runs and directions)
//!   against the band `z sigma / sqrt(runs x directions)` it stays in when the
//!   model is right, `z` the two-sided normal point at `alpha / targets`; the
//!   ranges that leave it;
//! - in spatial frequency: the spectral analysis of the residual
//!   ([`survey_processing::analysis::analyse`], its tests, naming and alias handling: a line
//!   that is an alias of a design harmonic is named as that harmonic, at its
//!   true frequency);
//! - by direction: forward minus reverse, and the backlash change fitted by
//!   least squares together with an offset and a drift;
//! - in time: the slope of the run means against their time (the trend across
//!   runs).
//!
//! # The time axis of drift
//!
//! Drift is a function of time, as in the simulator (`runs_elapsed = t /
//! run period`). With timestamps on every sample, a sample is at
//! `(t - t_first) / D` runs, `D` the mean time from one run's first sample to
//! the next run's; without, at `r + k / n` for the k-th of the `n` samples of
//! the r-th run in the order given (the acquisition order).
//!
//! # The noise floor
//!
//! `noise_floor_deg` is the standard deviation of the random part of one
//! sample, from the two-way layout runs x cells (a cell is a target and a
//! direction): the interaction residual `y - run mean - cell mean + grand
//! mean`, with `(runs - 1)(cells - 1)` degrees of freedom. Whatever repeats in
//! every run (the whole repeatable error, modelled or not) and whatever moves a
//! whole run (run-to-run offsets, and a drift linear in time when the runs keep
//! the same schedule) is not in it. With one run it is the spectral analysis's
//! estimate (the median power of the residual spectrum, or the fit residual of
//! a partial range), scaled to one sample.
//!
//! # Significance
//!
//! A disagreement is named only when a test rejects "the model explains the
//! data". The tests share a false-alarm budget `alpha`
//! ([`ModelGapOptions::false_alarm_rate`], default 0.01): the expected number
//! of effects named, per pass of the tests, on a survey the model fully
//! explains is at most `alpha`:
//!
//! - spectral lines, `alpha / 2`: the coherent test of the analysis (the mean
//!   spectrum over runs of the residual against the run-to-run scatter, each of
//!   the `M` frequencies at `alpha / (2M)`; see [`survey_processing::analysis`]). A line is a
//!   candidate when it passes it and, with two runs or more, is also
//!   phase-consistent across runs (repeatable), since a model effect repeats.
//!   The analysis's incoherent test is reported but names nothing.
//! - backlash, `alpha / 4`: the fitted backlash change against its standard
//!   error at the noise floor, two-sided normal point.
//! - drift, `alpha / 4`: the slope of the run means against its standard
//!   error. With three runs or more the run means' scatter about the trend is
//!   compared with what the noise floor predicts (chi-square, 1 %); when they
//!   scatter more (run-to-run offsets, which are not drift), the slope is tested
//!   against that scatter (Student t, `runs - 2` degrees of freedom), else
//!   against the noise floor (normal).
//!
//! Each step re-runs the tests on the new residual, so a survey with `k`
//! missing effects makes `k + 1` passes and an extra false effect has a chance
//! of at most `(k + 1) alpha`. Measured on control surveys (the model exactly
//! right; 128 targets x 3 runs, both directions, a gear pass, backlash and
//! noise; release build, `MODELGAP_FALSE_ALARM_SURVEYS=4000` with the
//! `false_alarms_are_rare` test, which counts 100 in the normal suite): at
//! `alpha = 0.01`, 32 effects named in 4000 surveys (0.008 per survey); at
//! `alpha = 1`, 1261 in 1600 (0.79 per survey), so the bound holds and is
//! not loose.
//!
//! # Detection limits
//!
//! [`DetectionLimits`]: the threshold plus three standard errors, the size at
//! which an effect is found with probability about 99.9 % (its estimate is
//! normal about the truth with that standard error). For a periodic effect on
//! a full circle of `N` targets, `R` runs and `D` directions, the standard
//! error of each quadrature component is `sigma / sqrt(N R D / 2)` and the
//! threshold factor `c = sqrt(-2 ln(alpha / (2M)))` (4.73 for 720 points).
//!
//! # Closing the gap
//!
//! The most significant disagreement is taken first (a drift or backlash
//! before any line: a drift the model lacks makes a saw-tooth in a one-way
//! survey, whose harmonics would otherwise be named as lines). A line that
//! lands where an effect of the model is (its frequency or an alias of it on
//! the same bin) adjusts that effect; otherwise a new effect of the line's
//! kind at its true frequency is added. Every effect touched so far is then
//! fitted again, jointly, by least squares over all samples (periodic effects
//! as sine and cosine at the actual angles, backlash as `+-1/2`, drift as the
//! time in runs, plus the offset), the model is simulated again and the views
//! recomputed; the loop ends when no test names anything. An added effect
//! that the final joint fit no longer finds significant is removed again
//! (reported as a step). Effects the model file cannot hold are not added: a
//! negative backlash (forward reading lower than reverse), a line at the
//! Nyquist frequency (only one quadrature is seen) or a frequency that cannot
//! be resolved at the sample angles; they are reported in `notes`.
//!
//! A partial range (an elevation axis) is analysed at the design frequencies
//! only (see [`survey_processing::analysis`]): a periodic error that matches no part of the
//! design stays in the residual, and shows in angle, not in frequency.

pub mod compare;

mod explain;
mod fit;
pub(crate) mod stats;
mod survey;
#[cfg(test)]
pub(crate) mod tests;
#[cfg(test)]
mod tests_cases;
#[cfg(test)]
mod tests_verdict;
mod text;
mod verdict;
mod views;

pub use survey::Timebase;
pub use verdict::{ReferenceFinding, ReferenceInfo, RepeatableTest, Verdict};
pub use views::{AngleRange, AngleView, DirectionView, FrequencyView, GapLine, RunMean, TimeView, TrendTest, Views};

use serde::Serialize;
use stats::normal_two_sided_isf;
use survey::Survey;
use survey_processing::analysis::{AnalysisError, AnalysisOptions, Method};
use survey_processing::errormap::{Coverage, ErrorMapError};
use survey_processing::model::{DriftShape, Effect, Model};
use survey_processing::types::Sample;
use views::{Ctx, GapLine as Line, Part, SCALAR_SHARE};

/// The choices of model-gap.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelGapOptions {
    /// Expected number of effects named, per pass of the tests, when the model
    /// explains the data (default 0.01).
    pub false_alarm_rate: f64,
    /// At most this many steps (default 40).
    pub max_steps: usize,
    /// How lines are named from the design (harmonic orders, sidebands); its
    /// `false_alarm_rate` and `series` are set by model-gap.
    pub analysis: AnalysisOptions,
    /// The reference instrument, for what of the gap is its own (default: unknown).
    pub reference: ReferenceInfo,
}

impl Default for ModelGapOptions {
    fn default() -> Self {
        ModelGapOptions {
            false_alarm_rate: 0.01,
            max_steps: 40,
            analysis: AnalysisOptions::default(),
            reference: ReferenceInfo::default(),
        }
    }
}

/// Why model-gap cannot compare.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelGapError {
    /// The samples do not make a complete error map.
    #[error(transparent)]
    ErrorMap(#[from] ErrorMapError),
    /// The spectral analysis of the residual failed.
    #[error(transparent)]
    Analysis(#[from] AnalysisError),
    /// An option is out of range.
    #[error("model-gap option {option}: {message}")]
    BadOption {
        /// The option.
        option: &'static str,
        /// What is wrong.
        message: String,
    },
}

/// What a step did to the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Action {
    /// A new effect.
    Added,
    /// An effect of the model refitted.
    Adjusted,
    /// An added effect taken out again (not significant in the final fit).
    Removed,
}

/// One step of closing the gap.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Step {
    /// 1, 2, ...
    pub step: usize,
    /// What changed, e.g. `tooth_mesh 250 cycles/rev` or `adjusted gear_pass 20 cycles/rev`.
    pub added: String,
    /// Added, adjusted or removed.
    pub action: Action,
    /// The contract's kind word.
    pub kind: String,
    /// Frequency, cycles/rev (0 for backlash and drift).
    pub cycles_per_rev: f64,
    /// Amplitude (backlash, drift per run) right after this step's fit, degrees.
    pub amplitude_deg: f64,
    /// RMS of the residual after the step, degrees.
    pub rms_deg: f64,
    /// Largest mean residual of a target after the step, degrees.
    pub mean_peak_deg: f64,
    /// Significant residual lines left after the step.
    pub lines_left: usize,
}

/// An effect model-gap added.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FoundEffect {
    /// The contract's kind word.
    pub kind: String,
    /// Its true frequency, cycles/rev (0 for backlash and drift).
    pub cycles_per_rev: f64,
    /// Amplitude, degrees; the backlash, or the drift per run.
    pub amplitude_deg: f64,
    /// Phase, degrees (periodic effects).
    pub phase_deg: Option<f64>,
    /// What it is and where to look.
    pub explanation: String,
    /// Where its line was seen, cycles/rev (differs from `cycles_per_rev` when aliased).
    pub observed_cycles_per_rev: Option<f64>,
    /// Whether it was seen as an alias.
    pub aliased: bool,
    /// Standard error of the amplitude (per quadrature component) in the final fit, degrees.
    pub standard_error_deg: f64,
    /// The step that added it.
    pub step: usize,
    #[serde(skip)]
    index: usize,
    #[serde(skip)]
    part: Option<Part>,
    #[serde(skip)]
    line: Option<Line>,
}

/// An effect of the model that model-gap refitted.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AdjustedEffect {
    /// The contract's kind word.
    pub kind: String,
    /// Frequency, cycles/rev (0 for backlash and drift).
    pub cycles_per_rev: f64,
    /// Amplitude (backlash, drift per run) in the model given, degrees.
    pub amplitude_before_deg: f64,
    /// After the final fit.
    pub amplitude_deg: f64,
    /// Phase in the model given (periodic effects), degrees.
    pub phase_before_deg: Option<f64>,
    /// After the final fit.
    pub phase_deg: Option<f64>,
    /// What changed and what it is.
    pub explanation: String,
    /// Standard error of the amplitude in the final fit, degrees.
    pub standard_error_deg: f64,
    /// The step that adjusted it.
    pub step: usize,
    #[serde(skip)]
    index: usize,
    #[serde(skip)]
    line: Option<Line>,
}

/// The noise floor.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NoiseFloor {
    /// Standard deviation of the random part of one sample, degrees.
    pub sample_sd_deg: f64,
    /// `run_cell_interaction` (two runs or more) or `spectrum` (one run).
    pub method: &'static str,
    /// Degrees of freedom of the estimate, when known.
    pub dof: Option<usize>,
    /// The model's own noise (its `noise` effects), degrees.
    pub model_noise_deg: f64,
}

/// The tests and their thresholds (at the start).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Significance {
    /// Expected false effects per pass of the tests.
    pub false_alarm_rate: f64,
    /// Frequencies tested for a line.
    pub frequencies_tested: usize,
    /// A line is significant when its amplitude exceeds this many standard
    /// deviations of a quadrature component of the mean spectrum.
    pub line_threshold_factor: f64,
    /// The line threshold, degrees (for a partial range: the typical one).
    pub line_threshold_deg: f64,
    /// The backlash threshold, degrees (bidirectional surveys).
    pub backlash_threshold_deg: Option<f64>,
    /// The drift threshold, degrees per run (two runs or more).
    pub drift_threshold_deg_per_run: Option<f64>,
    /// The same in words.
    pub statement: String,
}

/// The smallest effects found with probability about 99.9 %: threshold plus
/// three standard errors.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DetectionLimits {
    /// Amplitude of a periodic effect, degrees (for a partial range: at the typical frequency).
    pub periodic_deg: f64,
    /// Backlash, degrees.
    pub backlash_deg: Option<f64>,
    /// Drift, degrees per run.
    pub drift_deg_per_run: Option<f64>,
}

/// The survey as compared.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SurveyShape {
    /// Samples compared.
    pub samples: usize,
    /// Distinct targets.
    pub targets: usize,
    /// Runs.
    pub runs: usize,
    /// Both directions measured.
    pub bidirectional: bool,
    /// A uniform full circle (else a partial range).
    pub full_circle: bool,
    /// Points per revolution (`360 / step` for a partial range).
    pub points_per_rev: f64,
    /// The time axis of drift.
    pub timebase: Timebase,
    /// Mean duration of one run, seconds (with timestamps).
    pub run_duration_s: Option<f64>,
}

/// Everything model-gap found. The contract's JSON keys are `effects_added`,
/// `steps`, `rms_before_deg`, `rms_after_deg` and `noise_floor_deg`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelGap {
    /// Effects added to the model (empty when it explains the data to the noise floor).
    pub effects_added: Vec<FoundEffect>,
    /// Effects of the model refitted.
    pub effects_adjusted: Vec<AdjustedEffect>,
    /// The steps, in order.
    pub steps: Vec<Step>,
    /// RMS of the residual with the model given (offset fitted), degrees.
    pub rms_before_deg: f64,
    /// RMS of the residual with the improved model, degrees.
    pub rms_after_deg: f64,
    /// Standard deviation of the random part of one sample, degrees.
    pub noise_floor_deg: f64,
    /// How the noise floor was measured.
    pub noise: NoiseFloor,
    /// The tests.
    pub significance: Significance,
    /// What is big enough to be found.
    pub detection_limits: DetectionLimits,
    /// The survey.
    pub survey: SurveyShape,
    /// The constant offset between the improved model and the data (zero reference), degrees.
    pub offset_deg: f64,
    /// The gap before, four ways.
    pub before: Views,
    /// The gap after, four ways.
    pub after: Views,
    /// Whether the improved model explains the data (stated tests), and what
    /// of the reference explains part of the gap.
    pub verdict: Verdict,
    /// Remarks: what could not be added, where the data and the model still differ.
    pub notes: Vec<String>,
    /// The improved model (the model given with the effects added and adjusted).
    #[serde(skip)]
    pub model: Model,
}

/// The model's systematic error at every sample, as model-gap simulates it
/// (before the offset is fitted). Samples in acquisition order.
pub fn simulated_errors(samples: &[Sample], model: &Model) -> Result<Vec<f64>, ModelGapError> {
    Ok(Survey::prepare_for(samples, model)?.predict(model))
}

/// What a candidate disagreement is.
#[derive(Debug, Clone)]
enum Candidate {
    Drift,
    Backlash,
    Line(Box<Line>),
}

/// What may not be tried again.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Key {
    Drift,
    Backlash,
    Bin(f64),
}

impl Candidate {
    fn key(&self) -> Key {
        match self {
            Candidate::Drift => Key::Drift,
            Candidate::Backlash => Key::Backlash,
            Candidate::Line(l) => Key::Bin(l.observed_cycles_per_rev),
        }
    }
}

/// The next disagreement to close: drift or backlash first (the larger
/// statistic over threshold), then the line most above its threshold.
fn next_candidate(v: &Views, blocked: &[Key], runs: usize) -> Option<Candidate> {
    let mut scalar: Vec<(f64, Candidate)> = Vec::new();
    if let Some(t) = v.time.as_ref().filter(|t| t.significant && !blocked.contains(&Key::Drift)) {
        scalar.push((t.drift_change_deg_per_run.abs() / t.threshold_deg_per_run, Candidate::Drift));
    }
    if let Some(d) = v.direction.as_ref().filter(|d| d.significant && !blocked.contains(&Key::Backlash)) {
        scalar.push((d.backlash_change_deg.abs() / d.threshold_deg, Candidate::Backlash));
    }
    if let Some((_, c)) = scalar.into_iter().max_by(|a, b| a.0.total_cmp(&b.0)) {
        return Some(c);
    }
    v.frequency
        .lines
        .iter()
        .filter(|l| l.coherent && (runs < 2 || l.repeatable) && l.threshold_deg > 0.0)
        .filter(|l| !blocked.contains(&Key::Bin(l.observed_cycles_per_rev)))
        .max_by(|a, b| (a.amplitude_deg / a.threshold_deg).total_cmp(&(b.amplitude_deg / b.threshold_deg)))
        .map(|l| Candidate::Line(Box::new(l.clone())))
}

fn validate(o: &ModelGapOptions) -> Result<(), ModelGapError> {
    if !(o.false_alarm_rate > 0.0 && o.false_alarm_rate < 4.0) {
        return Err(ModelGapError::BadOption {
            option: "false_alarm_rate",
            message: format!("must be above 0 and below 4, got {}", o.false_alarm_rate),
        });
    }
    if o.max_steps == 0 || o.max_steps > 1000 {
        return Err(ModelGapError::BadOption {
            option: "max_steps",
            message: format!("must be from 1 to 1000, got {}", o.max_steps),
        });
    }
    Ok(())
}

/// The state of the loop.
struct Gap<'a> {
    ctx: Ctx<'a>,
    model: Model,
    touched: Vec<usize>,
    blocked: Vec<Key>,
    added: Vec<FoundEffect>,
    adjusted: Vec<AdjustedEffect>,
    steps: Vec<Step>,
    notes: Vec<String>,
    offset: f64,
    se: Vec<f64>,
}

impl Gap<'_> {
    fn refit(&mut self) -> Result<(), usize> {
        let r = fit::refit(self.ctx.survey, &mut self.model, &self.touched, self.ctx.sigma)?;
        self.offset = r.offset_deg;
        self.se = r.standard_error;
        Ok(())
    }

    /// Sum of squared residuals of the data against the model and offset.
    fn rss(&self) -> f64 {
        let p = self.ctx.survey.predict(&self.model);
        self.ctx.survey.ys().zip(&p).map(|(y, p)| (y - p - self.offset).powi(2)).sum()
    }

    /// A drift just added as a ramp: fit it as a step too and keep the shape
    /// that leaves the smaller residual. A ramp moves the error forward
    /// against reverse within a run (their times differ); a step does not, so
    /// step data fitted as a ramp would leave a false backlash for the next
    /// step to "find".
    fn choose_drift_shape(&mut self, index: usize) {
        let ramp = (self.model.clone(), self.offset, self.se.clone(), self.rss());
        if let Effect::Drift { shape, .. } = &mut self.model.effects[index] {
            *shape = DriftShape::Step;
        }
        let better = self.refit().is_ok() && self.rss() < ramp.3;
        if !better {
            (self.model, self.offset, self.se) = (ramp.0, ramp.1, ramp.2);
        }
    }

    fn se_of(&self, index: usize) -> f64 {
        self.touched.iter().position(|&i| i == index).map_or(0.0, |k| self.se[k])
    }

    /// Apply one candidate: returns the step's action and effect index, or `None` when it was blocked.
    fn apply(&mut self, cand: &Candidate, step: usize) -> Option<(Action, usize)> {
        let before = self.model.clone();
        let find = |want: fn(&Effect) -> bool| self.model.effects.iter().position(want);
        let (action, index, line) = match cand {
            Candidate::Drift => match find(|e| matches!(e, Effect::Drift { .. })) {
                Some(i) => (Action::Adjusted, i, None),
                None => {
                    self.model.effects.push(Effect::Drift { rate_deg_per_run: 0.0, shape: DriftShape::Ramp });
                    (Action::Added, self.model.effects.len() - 1, None)
                }
            },
            Candidate::Backlash => match find(|e| matches!(e, Effect::Backlash { .. })) {
                Some(i) => (Action::Adjusted, i, None),
                None => {
                    self.model.effects.push(Effect::Backlash { amplitude_deg: 0.0 });
                    (Action::Added, self.model.effects.len() - 1, None)
                }
            },
            Candidate::Line(l) => {
                let f = self.ctx.analysis_points_per_rev();
                if self.ctx.full_circle() && (2.0 * l.observed_cycles_per_rev - f).abs() < 1e-9 {
                    self.notes.push(format!(
                        "a line at the Nyquist frequency ({} cycles/rev, {:.3e} deg) is not fitted: only its part in phase \
                         with the samples is seen; measure at more points per revolution to resolve it",
                        explain::num(l.observed_cycles_per_rev),
                        l.amplitude_deg
                    ));
                    return None;
                }
                match l.model_effect {
                    Some(i) if self.touched.contains(&i) => return None,
                    Some(i) => (Action::Adjusted, i, Some((**l).clone())),
                    None => {
                        self.model.effects.push(Effect::Periodic {
                            kind: l.periodic_kind,
                            cycles_per_rev: l.cycles_per_rev,
                            amplitude_deg: 0.0,
                            phase_deg: 0.0,
                        });
                        (Action::Added, self.model.effects.len() - 1, Some((**l).clone()))
                    }
                }
            }
        };
        self.touched.push(index);
        if self.refit().is_err() {
            self.notes.push(format!(
                "{} cannot be fitted at these sample angles (it cannot be told apart from the offset or the other \
                 effects): not {}",
                explain::label(&self.model.effects[index]),
                if action == Action::Added { "added" } else { "adjusted" }
            ));
            self.model = before;
            self.touched.pop();
            let _ = self.refit();
            return None;
        }
        if matches!(cand, Candidate::Drift) && action == Action::Added {
            self.choose_drift_shape(index);
        }
        if let Effect::Backlash { amplitude_deg } = self.model.effects[index]
            && amplitude_deg < 0.0
        {
            self.notes.push(format!(
                "forward approaches read {:.3e} deg lower than reverse ones, relative to the model: a negative backlash, \
                 which the model file cannot hold (backlash reads +amplitude/2 forward); check the sign of the \
                 reference or the preload of the drive",
                -amplitude_deg
            ));
            self.model = before;
            self.touched.pop();
            let _ = self.refit();
            return None;
        }
        let kind = self.model.effects[index].kind_str().to_string();
        match action {
            Action::Added => self.added.push(FoundEffect {
                kind,
                cycles_per_rev: 0.0,
                amplitude_deg: 0.0,
                phase_deg: None,
                explanation: String::new(),
                observed_cycles_per_rev: line.as_ref().map(|l| l.observed_cycles_per_rev),
                aliased: line.as_ref().is_some_and(|l| l.aliased),
                standard_error_deg: 0.0,
                step,
                index,
                part: line.as_ref().and_then(|l| l.part),
                line,
            }),
            _ => {
                let (a, p) = explain::amplitude_phase(&before.effects[index]);
                self.adjusted.push(AdjustedEffect {
                    kind,
                    cycles_per_rev: 0.0,
                    amplitude_before_deg: a,
                    amplitude_deg: 0.0,
                    phase_before_deg: p,
                    phase_deg: None,
                    explanation: String::new(),
                    standard_error_deg: 0.0,
                    step,
                    index,
                    line,
                })
            }
        }
        Some((action, index))
    }

    fn record(&mut self, action: Action, e: &Effect, views: &Views) {
        let label = explain::label(e);
        self.steps.push(Step {
            step: self.steps.len() + 1,
            added: match action {
                Action::Added => label,
                Action::Adjusted => format!("adjusted {label}"),
                Action::Removed => format!("removed {label}"),
            },
            action,
            kind: e.kind_str().to_string(),
            cycles_per_rev: explain::cycles(e),
            amplitude_deg: if action == Action::Removed { 0.0 } else { explain::amplitude_phase(e).0 },
            rms_deg: views.rms_deg,
            mean_peak_deg: views.angle.mean_peak_deg.abs(),
            lines_left: views.frequency.lines.iter().filter(|l| l.coherent).count(),
        });
    }

    /// Remove added effects the final joint fit does not find significant.
    fn prune(&mut self, line_factor: f64) -> Result<(), ModelGapError> {
        loop {
            let scalar = normal_two_sided_isf(self.ctx.alpha * SCALAR_SHARE);
            let weak = self.added.iter().position(|f| {
                let se = self.se_of(f.index);
                let (a, _) = explain::amplitude_phase(&self.model.effects[f.index]);
                let factor =
                    if matches!(self.model.effects[f.index], Effect::Periodic { .. }) { line_factor } else { scalar };
                se > 0.0 && a.abs() < factor * se
            });
            let Some(k) = weak else { return Ok(()) };
            let gone = self.added.remove(k);
            let label_effect = self.model.effects[gone.index].clone();
            self.model.effects.remove(gone.index);
            self.touched.retain(|&i| i != gone.index);
            for i in self.touched.iter_mut() {
                if *i > gone.index {
                    *i -= 1;
                }
            }
            for f in self.added.iter_mut() {
                if f.index > gone.index {
                    f.index -= 1;
                }
            }
            for f in self.adjusted.iter_mut() {
                if f.index > gone.index {
                    f.index -= 1;
                }
            }
            self.blocked.push(match &gone.line {
                Some(l) => Key::Bin(l.observed_cycles_per_rev),
                None if gone.kind == "drift" => Key::Drift,
                None => Key::Backlash,
            });
            let _ = self.refit();
            let (r, _) = self.ctx.survey.residual(&self.model);
            let (v, _) = views::views(&self.ctx, &self.model, &r)?;
            self.record(Action::Removed, &label_effect, &v);
        }
    }
}

impl Ctx<'_> {
    fn full_circle(&self) -> bool {
        matches!(self.survey.map.coverage, Coverage::FullCircle { .. })
    }

    fn analysis_points_per_rev(&self) -> f64 {
        match self.survey.map.coverage {
            Coverage::FullCircle { n } => n as f64,
            Coverage::Partial { step, .. } if step > 0.0 => 360.0 / step,
            Coverage::Partial { .. } => 0.0,
        }
    }
}

/// Compare `model` with the survey `samples` (in acquisition order), name
/// what the model lacks, and close the gap. See the module documentation.
pub fn model_gap(samples: &[Sample], model: &Model, options: &ModelGapOptions) -> Result<ModelGap, ModelGapError> {
    validate(options)?;
    let survey = Survey::prepare_for(samples, model)?;
    let runs = survey.runs();
    let spectral_alpha = if runs >= 2 { options.false_alarm_rate } else { options.false_alarm_rate / 2.0 };
    let analysis = AnalysisOptions {
        false_alarm_rate: spectral_alpha,
        series: survey_processing::errormap::Series::Bidirectional,
        ..options.analysis.clone()
    };
    let numerical_floor = {
        let angle = survey.samples.iter().fold(1.0f64, |m, s| m.max(s.actual_deg.abs()).max(s.target_deg.abs()));
        let rms = (survey.ys().map(|v| v * v).sum::<f64>() / survey.len() as f64).sqrt();
        (1e-12 * rms).max(8.0 * f64::EPSILON * angle)
    };
    let mut ctx = Ctx {
        survey: &survey,
        design: &model.design,
        analysis,
        alpha: options.false_alarm_rate,
        sigma: numerical_floor,
    };
    let (residual0, offset0) = survey.residual(model);
    let noise = match survey.anova_noise() {
        Some((sd, dof)) => NoiseFloor {
            sample_sd_deg: sd,
            method: "run_cell_interaction",
            dof: Some(dof),
            model_noise_deg: model.noise_sigma_deg(),
        },
        None => {
            let a = views::analyse_residual(&ctx, &residual0)?;
            let scale = if survey.bidirectional() { std::f64::consts::SQRT_2 } else { 1.0 };
            NoiseFloor {
                sample_sd_deg: a.noise.sample_sd_deg * scale,
                method: "spectrum",
                dof: a.noise.dof,
                model_noise_deg: model.noise_sigma_deg(),
            }
        }
    };
    ctx.sigma = noise.sample_sd_deg.max(numerical_floor);
    let (before, first) = views::views(&ctx, model, &residual0)?;
    let line_factor = if first.noise.line_sd_mean_deg > 0.0 {
        first.noise.coherent_threshold_deg / first.noise.line_sd_mean_deg
    } else {
        0.0
    };
    let mut gap = Gap {
        ctx: ctx.clone(),
        model: model.clone(),
        touched: Vec::new(),
        blocked: Vec::new(),
        added: Vec::new(),
        adjusted: Vec::new(),
        steps: Vec::new(),
        notes: Vec::new(),
        offset: offset0,
        se: Vec::new(),
    };
    let mut current = before.clone();
    let mut attempts = 0;
    while gap.steps.len() < options.max_steps && attempts < 4 * options.max_steps {
        attempts += 1;
        let Some(cand) = next_candidate(&current, &gap.blocked, runs) else { break };
        let step = gap.steps.len() + 1;
        let key = cand.key();
        match gap.apply(&cand, step) {
            None => gap.blocked.push(key),
            Some((action, index)) => {
                // Once fitted jointly, the same disagreement is not taken up again.
                gap.blocked.push(key);
                let (r, _) = survey.residual(&gap.model);
                current = views::views(&ctx, &gap.model, &r)?.0;
                let effect = gap.model.effects[index].clone();
                gap.record(action, &effect, &current);
            }
        }
    }
    if gap.steps.len() >= options.max_steps && next_candidate(&current, &gap.blocked, runs).is_some() {
        gap.notes.push(format!("stopped after {} steps with disagreements left", options.max_steps));
    }
    gap.prune(line_factor)?;
    // The model unchanged (nothing added, or all of it pruned again), its
    // residual is the first one: not evaluated again at every sample.
    let (residual_after, offset_after) =
        if gap.model == *model { (residual0, offset0) } else { survey.residual(&gap.model) };
    let after = if gap.steps.is_empty() {
        before.clone()
    } else {
        gap.offset = offset_after;
        views::views(&ctx, &gap.model, &residual_after)?.0
    };
    let verdict = verdict::verdict(&ctx, &residual_after, noise.dof, &options.reference);
    explain::finish(&mut gap.added, &mut gap.adjusted, &gap.model, &gap.touched, &gap.se, &ctx);
    let significance = explain::significance(&ctx, &first, &before, line_factor);
    let detection_limits = DetectionLimits {
        periodic_deg: (line_factor + 3.0) * first.noise.line_sd_mean_deg,
        backlash_deg: before.direction.as_ref().map(|d| d.threshold_deg + 3.0 * d.standard_error_deg),
        drift_deg_per_run: before.time.as_ref().map(|t| t.threshold_deg_per_run + 3.0 * t.standard_error_deg_per_run),
    };
    let mut notes = gap.notes;
    explain::closing_notes(&mut notes, &after, &noise, ctx.sigma, &first);
    explain::reference_note(&mut notes, &gap.added, &gap.adjusted, &options.reference);
    Ok(ModelGap {
        effects_added: gap.added,
        effects_adjusted: gap.adjusted,
        steps: gap.steps,
        rms_before_deg: before.rms_deg,
        rms_after_deg: after.rms_deg,
        noise_floor_deg: ctx.sigma,
        noise,
        significance,
        detection_limits,
        survey: SurveyShape {
            samples: survey.len(),
            targets: survey.targets(),
            runs,
            bidirectional: survey.bidirectional(),
            full_circle: first.method == Method::Dft,
            points_per_rev: first.points_per_rev,
            timebase: survey.timebase,
            run_duration_s: survey.run_duration_s,
        },
        offset_deg: gap.offset,
        before,
        after,
        verdict,
        notes,
        model: gap.model,
    })
}
