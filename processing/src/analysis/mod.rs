//! The paper's spectral analysis: which periodic errors are there, which are
//! repeatable, what part of the positioner makes them, and which are aliased.
//!
//! [`analyse`] takes the samples of a survey and the positioner's [`Design`],
//! builds the [`ErrorMap`], takes each run's error series (by default the mean of
//! its forward and reverse passes, so backlash cancels), and then:
//!
//! # Spectra and the noise floor
//!
//! On a uniform full circle of `N` targets, each run's series is transformed
//! ([`crate::spectrum`]: phasor `z_rk` at bin `k`, amplitude and phase in the
//! contract's convention) and the mean spectrum is `zbar_k = mean_r z_rk`. The
//! noise floor is the run-to-run scatter of the complex spectrum pooled over the
//! `K = floor((N-1)/2)` bins strictly between 0 and N/2:
//! `sigma1^2 = sum_k sum_r |z_rk - zbar_k|^2 / (2 K (R - 1))`, the variance of each
//! quadrature component of a line in one run's spectrum (noise of sd `sigma` per
//! sample gives `sigma1 = sigma sqrt(2/N)`); the mean spectrum has
//! `sigma_mean = sigma1 / sqrt(R)`. Bin 0 is left out, so run-to-run offsets and
//! drift are not noise. With one run there is no scatter: `sigma1^2` is taken as
//! `median_k |z_k|^2 / (2 ln 2)` (the median of an exponential), which holds while
//! lines occupy fewer than half the bins. A numerical floor on the sample noise
//! (the larger of `1e-12` of the series' RMS and 8 ulps of the largest target
//! angle, since each error is a difference of two such angles) keeps noise-free
//! data from making every rounding error a line.
//!
//! # Significance
//!
//! `M` frequencies are tested (`floor(N/2)` bins on a full circle). The thresholds
//! are set so that the expected number of false lines per spectrum in pure
//! Gaussian noise is at most `alpha` ([`AnalysisOptions::false_alarm_rate`],
//! default 0.01): with `R >= 2` two tests are made per frequency, each at
//! `p = alpha / (2M)` (one test at `alpha / M` with one run):
//! - coherent: `|zbar_k| > c sigma_mean`. In noise `|zbar|^2 / sigma_mean^2` is
//!   chi-square with 2 degrees of freedom, so with a known floor
//!   `c = sqrt(-2 ln p)` (4.73 for 720 points, 5 runs). The floor is estimated
//!   with `d` degrees of freedom, independently of the mean spectrum, so the
//!   exact test is `|zbar|^2 / (2 sigma_mean^2)` against the F(2, d) distribution,
//!   whose tail is `(1 + 2f/d)^(-d/2)`: `c` is a little larger (4.739 for
//!   `d = 2872`). At the Nyquist bin, one component of sd `sigma_mean / sqrt 2`,
//!   compared with the two-sided normal point.
//! - incoherent: `sum_r |z_rk|^2 / sigma1^2 > x` with `x / 2R` the upper `p` point
//!   of F(2R, d) (chi-square with `2R` degrees of freedom for a known floor; not
//!   made at the Nyquist bin). It finds a line whose phase changes from run to
//!   run, which averages out of the mean spectrum. (The bin's own scatter is part
//!   of both the statistic and the floor, a `2(R-1)/d` share: negligible.)
//!
//! A frequency passing either test is a line. The union bound makes `alpha` an
//! upper bound: the two tests overlap, so the false-line rate lies between
//! `alpha / 2` and `alpha`. Measured on 2000 noise-only surveys of 256 points and
//! 4 runs: 0.0105 false lines per spectrum at `alpha = 0.01` (21 lines), 0.078
//! at 0.1, 0.83 at 1 (the `noise_only_control` test checks 150 surveys).
//!
//! # Repeatable or random
//!
//! A line is repeatable when it is coherently significant (its amplitude in the
//! mean spectrum is well above the noise floor) AND its phase is consistent
//! across runs, measured by the coherence
//! `gamma = |zbar|^2 / mean_r |z_r|^2` (coherent over incoherent power, in [0, 1]):
//! 1 for a line that repeats exactly, about `1/R` for a line of random phase. The
//! default threshold is halfway, `(1 + 1/R) / 2` (0.6 for 5 runs);
//! [`AnalysisOptions::min_coherence`] overrides it. With one run nothing can be
//! called repeatable and every line is reported with `repeatable: false`.
//!
//! # Naming
//!
//! Each line is matched against the frequencies the design predicts
//! ([`design_candidates`]): 1 (eccentricity) and 2 (ellipticity) cycles/rev;
//! harmonics `h g` of each gear ratio `g` up to [`AnalysisOptions::gear_harmonics`];
//! harmonics `h t` of each tooth count up to [`AnalysisOptions::tooth_harmonics`];
//! sidebands `h t +/- m g` of the tooth mesh modulated by each gear pass. On a full
//! circle a candidate matches bin `k` when its alias `|f - N round(f/N)|` is within
//! half a bin of `k`. The primary name prefers an unaliased candidate, then
//! eccentricity, ellipticity, gear pass, tooth mesh, sideband, then the lower
//! harmonic; every other match is listed after "also". A line that matches nothing
//! is a `harmonic` with a hint. With `encoder_heads = 2` (or more), an
//! eccentricity or unexplained line at a frequency the heads should cancel gets a
//! note. `source` is the contract's kind word, a colon and the explanation.
//!
//! `share` is the fraction of the variance of the mean error curve (the
//! repeatable part of the error: the per-target mean over runs) that the line's
//! component in it carries (`|zbar|^2 / 2` over the sum over all bins but 0).
//!
//! # Aliasing
//!
//! Every design frequency at or above `N/2` is reported ([`AliasEntry`]) at its
//! observed bin. The recommended action is `relocate` when the observed bin is
//! reached by that true frequency only, and `null` when another design frequency
//! (aliased or not) lands there too, when it lands on bin 0 or N/2, or when it is
//! not a whole number of cycles per revolution. For Figure 4 at 720 points,
//! 432 -> 288 is `relocate` and 648 -> 72 is `null`, because 72 is also the 6th
//! harmonic of the 12:1 pinion (the paper: "other error sources also contribute
//! at 72 cycles"). The action is a recommendation: a processing recipe may
//! override it. [`PointsNeeded`] says how many points per revolution would have
//! resolved the highest design harmonic found.
//!
//! # Partial ranges
//!
//! When the targets do not cover a full circle uniformly, the lines are fitted by
//! least squares ([`crate::spectrum::fit_sinusoids`]) at the candidate frequencies
//! below the sampling limit `180 / step`, with an offset, for each run and for
//! the mean. The noise is the run-to-run scatter of the fit residuals (with
//! `(R - 1)(N - p)` degrees of freedom; with one run the residual itself), and the
//! per-line noise comes from `(A^T A)^-1` (the mean of its sine and cosine
//! variances). The same tests then apply with `M` = number of fitted
//! frequencies. Frequencies the design does not predict are not fitted; they stay
//! in the residual, reported in [`PartialFit`]. The display spectra use
//! [`AnalysisOptions::partial_window`] (default Hann).

mod detect;
mod naming;
#[cfg(test)]
mod tests;
/// Test support for this crate's tests and the crates built on it (the
/// `testutil` feature, their dev-dependency's).
#[cfg(any(test, feature = "testutil"))]
pub mod testutil;

pub use detect::{NoiseFloor, NoiseMethod, default_min_coherence};
pub use naming::{Alias, AliasAction, AliasEntry, Candidate, alias, design_candidates, unalias_phase_deg};

use crate::errormap::{Coverage, ErrorMap, ErrorMapError, Series};
use crate::iso230::TargetGroups;
use crate::model::{Design, PeriodicKind};
use crate::spectrum::{Phasor, Planner, SinusoidBasis, SinusoidFit, Spectrum, SpectrumError, Window};
use crate::types::Sample;
use detect::{Tested, Thresholds, Verdict};
use naming::{Frame, Naming, name_line, num, ser_kind};
use serde::{Deserialize, Serialize};

/// The choices of the analysis. Deserialises from a table with these keys, each
/// optional (a processing recipe can carry it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AnalysisOptions {
    /// Which series of each run to analyse (`bidirectional`, `forward`, `reverse`).
    pub series: Series,
    /// Harmonics of each gear ratio considered (default 6).
    pub gear_harmonics: u32,
    /// Harmonics of each tooth count considered (default 3).
    pub tooth_harmonics: u32,
    /// Sidebands `t h +/- m g` for `m` up to this (default 2; 0 for none).
    pub sideband_orders: u32,
    /// Tooth-mesh harmonics `h` that carry sidebands (default 1).
    pub sideband_tooth_harmonics: u32,
    /// Expected false lines per spectrum in pure noise (default 0.01).
    pub false_alarm_rate: f64,
    /// Coherence a repeatable line needs; default `(1 + 1/runs) / 2`.
    pub min_coherence: Option<f64>,
    /// Window of the display spectra of a partial range (default `hann`).
    pub partial_window: Window,
}

impl Default for AnalysisOptions {
    fn default() -> Self {
        AnalysisOptions {
            series: Series::Bidirectional,
            gear_harmonics: 6,
            tooth_harmonics: 3,
            sideband_orders: 2,
            sideband_tooth_harmonics: 1,
            false_alarm_rate: 0.01,
            min_coherence: None,
            partial_window: Window::Hann,
        }
    }
}

impl AnalysisOptions {
    pub fn validate(&self) -> Result<(), AnalysisError> {
        let bad = |option: &'static str, message: String| Err(AnalysisError::BadOption { option, message });
        if !(self.false_alarm_rate > 0.0 && self.false_alarm_rate.is_finite()) {
            return bad("false_alarm_rate", format!("must be a positive number, got {}", self.false_alarm_rate));
        }
        if let Some(c) = self.min_coherence
            && !(0.0..=1.0).contains(&c)
        {
            return bad("min_coherence", format!("must be from 0 to 1, got {c}"));
        }
        for (option, v) in [
            ("gear_harmonics", self.gear_harmonics),
            ("tooth_harmonics", self.tooth_harmonics),
            ("sideband_orders", self.sideband_orders),
            ("sideband_tooth_harmonics", self.sideband_tooth_harmonics),
        ] {
            if v > 1000 {
                return bad(option, format!("must be at most 1000, got {v}"));
            }
        }
        Ok(())
    }
}

/// How the lines were found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// DFT of a uniform full circle.
    Dft,
    /// Least-squares fit at the design frequencies (partial range or uneven spacing).
    LeastSquares,
}

/// A significant spectral line.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Line {
    /// Where it is seen, cycles/rev (the bin, or the fitted frequency).
    pub cycles_per_rev: f64,
    /// Amplitude, degrees: the mean-spectrum amplitude of a repeatable line (what a
    /// correction removes), the RMS over runs of the single-run amplitude otherwise.
    pub amplitude_deg: f64,
    /// Phase of the mean spectrum at `cycles_per_rev`, degrees in `[0, 360)`.
    pub phase_deg: f64,
    /// Coherently significant and phase-consistent across runs.
    pub repeatable: bool,
    /// The contract's kind word of the primary name.
    #[serde(serialize_with = "ser_kind")]
    pub kind: PeriodicKind,
    /// What the design says it is.
    pub explanation: String,
    /// `kind: explanation`.
    pub source: String,
    /// The primary name's true frequency (different from `cycles_per_rev` when aliased).
    pub true_cycles_per_rev: f64,
    /// The phase at the true frequency, degrees.
    pub true_phase_deg: f64,
    /// Whether the primary name is an aliased design harmonic.
    pub aliased: bool,
    /// Fraction of the variance of the mean error curve this line carries.
    pub share: f64,
    /// Amplitude in the mean spectrum, degrees.
    pub mean_amplitude_deg: f64,
    /// RMS over runs of the single-run amplitude, degrees.
    pub run_rms_amplitude_deg: f64,
    /// Coherent over incoherent power, `|zbar|^2 / mean_r |z_r|^2`.
    pub coherence: f64,
    /// Passed the coherent test (mean spectrum above the threshold).
    pub coherent: bool,
    /// Passed the incoherent test (single-run power above the threshold).
    pub incoherent: bool,
    /// Noise standard deviation of each quadrature component of this line in the
    /// mean spectrum, degrees (the amplitude's standard uncertainty).
    pub noise_sd_deg: f64,
    /// Run-to-run standard deviation of each quadrature component at this
    /// frequency, degrees (compare with the noise floor's `line_sd_run_deg`).
    pub run_scatter_deg: Option<f64>,
    /// Every design frequency that lands here.
    pub candidates: Vec<Candidate>,
    /// Remarks worth a look.
    pub notes: Vec<String>,
}

/// The spectrum of the mean series. (Each run's spectrum serves the tests
/// of the lines and is not kept: five of them were ten bytes a sample for
/// as long as the analysis was.)
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Spectra {
    /// Spectrum of the mean series.
    pub mean: Spectrum,
}

/// The least-squares fits of a partial range.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PartialFit {
    /// The fitted frequencies, cycles/rev.
    pub frequencies: Vec<f64>,
    /// Fit of the mean series (its residual is what the design does not explain).
    pub mean: SinusoidFit,
    /// Fit of each run.
    pub runs: Vec<SinusoidFit>,
}

/// How many points per revolution the survey needed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PointsNeeded {
    /// The highest design frequency among the significant lines, cycles/rev.
    pub highest_cycles: f64,
    /// The smallest number of points per revolution above twice that.
    pub nyquist_points: usize,
    /// The largest step that resolves it, degrees (`360 / nyquist_points`).
    pub max_step_deg: f64,
    /// The paper's rule for quadratic interpolation: 20 x the highest frequency.
    pub quadratic_interpolation_points: usize,
    /// Points per revolution measured (`360 / step` for a partial range).
    pub points_per_rev: f64,
    /// Whether the survey had enough points.
    pub sufficient: bool,
    /// The same in words.
    pub note: String,
}

/// Everything the analysis found. See the module documentation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Analysis {
    /// The error map.
    pub error_map: ErrorMap,
    /// Which series was analysed.
    pub series: Series,
    /// Number of runs.
    pub runs: usize,
    /// Points per revolution (`360 / step` for a partial range).
    pub points_per_rev: f64,
    /// DFT or least squares.
    pub method: Method,
    /// The mean series's spectrum (`None` for an unevenly spaced partial range).
    pub spectra: Option<Spectra>,
    /// The least-squares fits of a partial range.
    pub fit: Option<PartialFit>,
    /// The noise floor and the thresholds.
    pub noise: NoiseFloor,
    /// Significant lines, by frequency.
    pub lines: Vec<Line>,
    /// Aliased (or unresolvable) design frequencies.
    pub aliases: Vec<AliasEntry>,
    /// How many points would have been enough (`None` when no design line was found).
    pub points_needed: Option<PointsNeeded>,
    /// Sum of the shares of the repeatable lines.
    pub repeatable_share: f64,
    /// Remarks about the whole analysis.
    pub notes: Vec<String>,
}

/// Why the analysis cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnalysisError {
    /// The samples do not make a complete error map.
    #[error(transparent)]
    ErrorMap(#[from] ErrorMapError),
    /// A spectrum or fit failed.
    #[error(transparent)]
    Spectrum(#[from] SpectrumError),
    /// The series asked for was not measured.
    #[error("the {series:?} series was asked for, but that direction was not measured")]
    MissingDirection {
        /// The series asked for.
        series: Series,
    },
    /// Too few targets for a spectrum or a fit.
    #[error("{targets} targets: at least {min} are needed for this analysis ({why})")]
    TooFewTargets {
        /// Targets measured.
        targets: usize,
        /// Targets needed.
        min: usize,
        /// Why.
        why: &'static str,
    },
    /// An option is out of range.
    #[error("analysis option {option}: {message}")]
    BadOption {
        /// The option's key.
        option: &'static str,
        /// What is wrong.
        message: String,
    },
}

/// Analyse a survey. See the module documentation.
pub fn analyse(samples: &[Sample], design: &Design, options: &AnalysisOptions) -> Result<Analysis, AnalysisError> {
    analyse_grouped(samples, &TargetGroups::of(samples), design, options)
}

/// [`analyse`] with the samples' grouping by target made already
/// ([`TargetGroups::of`] `samples`).
pub fn analyse_grouped(
    samples: &[Sample],
    groups: &TargetGroups,
    design: &Design,
    options: &AnalysisOptions,
) -> Result<Analysis, AnalysisError> {
    options.validate()?;
    let map = ErrorMap::from_grouped(samples, groups)?;
    analyse_map(map, design, options)
}

/// Analyse an error map that is already built.
pub fn analyse_map(map: ErrorMap, design: &Design, options: &AnalysisOptions) -> Result<Analysis, AnalysisError> {
    options.validate()?;
    let rows = map.run_series(options.series).ok_or(AnalysisError::MissingDirection { series: options.series })?;
    let runs = rows.len();
    let min_coherence = options.min_coherence.unwrap_or_else(|| default_min_coherence(runs));
    let candidates = design_candidates(design, options);
    let heads = design.encoder_heads.unwrap_or(1);
    let mut notes = Vec::new();
    if runs == 1 {
        notes.push(
            "one run: repeatability cannot be tested, so no line is marked repeatable; measure 2 runs or more \
             (ISO 230-2 asks for 5)"
                .to_string(),
        );
    }
    if options.series == Series::Bidirectional && map.is_bidirectional() {
        notes.push("series: the mean of the forward and reverse pass of each run (backlash cancels)".to_string());
    }
    let numerical_floor = {
        let count: usize = rows.iter().map(Vec::len).sum();
        let ss: f64 = rows.iter().flatten().map(|v| v * v).sum();
        // The error is a difference of angles of the size of the targets: its
        // rounding is a few ulps of those.
        let angle = map.targets_deg.iter().fold(1.0f64, |m, t| m.max(t.abs()));
        (1e-12 * (ss / count.max(1) as f64).sqrt()).max(8.0 * f64::EPSILON * angle)
    };
    let core = match map.coverage {
        Coverage::FullCircle { n } => {
            let frame = Frame {
                points_per_rev: n as f64,
                full_circle: true,
                start_deg: map.targets_deg[0],
                encoder_heads: heads,
            };
            full_circle(&rows, &frame, &candidates, options, min_coherence, numerical_floor)?
        }
        Coverage::Partial { start, end, step } => {
            let partial = Partial { theta: &map.targets_deg, start, end, step, uniform: map.uniform_spacing };
            partial_range(&rows, &partial, heads, &candidates, options, min_coherence, numerical_floor, &mut notes)?
        }
    };
    let repeatable_share = core.lines.iter().filter(|l| l.repeatable).map(|l| l.share).sum();
    let points_needed = points_needed(&core.lines, core.points_per_rev);
    Ok(Analysis {
        error_map: map,
        series: options.series,
        runs,
        points_per_rev: core.points_per_rev,
        method: core.method,
        spectra: core.spectra,
        fit: core.fit,
        noise: core.noise,
        lines: core.lines,
        aliases: core.aliases,
        points_needed,
        repeatable_share,
        notes,
    })
}

/// What the full-circle and the partial-range paths produce.
struct Core {
    points_per_rev: f64,
    method: Method,
    spectra: Option<Spectra>,
    fit: Option<PartialFit>,
    noise: NoiseFloor,
    lines: Vec<Line>,
    aliases: Vec<AliasEntry>,
}

/// Builds a line from a verdict and a name. `power` is the line's variance in
/// the mean curve and `total` that of the whole mean curve.
fn make_line(observed: f64, mean: Phasor, v: &Verdict, naming: Naming, frame: &Frame, power: f64, total: f64) -> Line {
    let true_phase_deg = if naming.aliased {
        unalias_phase_deg(
            mean.phase_deg(),
            alias(naming.true_cycles, frame.points_per_rev),
            frame.points_per_rev,
            frame.start_deg,
        )
    } else {
        mean.phase_deg()
    };
    let explanation = naming.explanation;
    Line {
        cycles_per_rev: observed,
        amplitude_deg: if v.repeatable { mean.amplitude_deg() } else { v.run_rms_amplitude },
        phase_deg: mean.phase_deg(),
        repeatable: v.repeatable,
        kind: naming.kind,
        source: format!("{}: {explanation}", naming.kind.as_str()),
        explanation,
        true_cycles_per_rev: naming.true_cycles,
        true_phase_deg,
        aliased: naming.aliased,
        share: if total > 0.0 { power / total } else { 0.0 },
        mean_amplitude_deg: mean.amplitude_deg(),
        run_rms_amplitude_deg: v.run_rms_amplitude,
        coherence: v.coherence,
        coherent: v.coherent,
        incoherent: v.incoherent,
        noise_sd_deg: v.sd_mean,
        run_scatter_deg: v.scatter,
        candidates: naming.candidates,
        notes: naming.notes,
    }
}

fn full_circle(
    rows: &[Vec<f64>],
    frame: &Frame,
    candidates: &[Candidate],
    options: &AnalysisOptions,
    min_coherence: f64,
    numerical_floor: f64,
) -> Result<Core, AnalysisError> {
    let n = frame.points_per_rev as usize;
    if n < 3 {
        return Err(AnalysisError::TooFewTargets { targets: n, min: 3, why: "a spectrum of a full circle" });
    }
    let r = rows.len();
    let mut planner = Planner::new();
    // Each run's phasors (the line tests need no more of their spectra),
    // and the mean series's spectrum from their mean.
    let spectra = rows
        .iter()
        .map(|y| planner.phasors(y, frame.start_deg, 360.0, Window::Rectangular))
        .collect::<Result<Vec<_>, _>>()?;
    let mean = Spectrum::mean_of_phasors(rows[0].len(), frame.start_deg, 360.0, Window::Rectangular, &spectra);
    let regular = (n - 1) / 2;
    let nyquist = n.is_multiple_of(2);
    let (sd_run, method, dof) = if r >= 2 {
        let ss: f64 =
            (1..=regular).map(|k| spectra.iter().map(|s| (s[k] - mean.bins[k].phasor).norm_sqr()).sum::<f64>()).sum();
        let dof = 2 * regular * (r - 1);
        ((ss / dof as f64).sqrt(), NoiseMethod::SpectrumScatter, Some(dof))
    } else {
        let mut p: Vec<f64> = (1..=regular).map(|k| spectra[0][k].norm_sqr()).collect();
        let median = crate::special::median(&mut p);
        ((median / (2.0 * std::f64::consts::LN_2)).sqrt(), NoiseMethod::SpectrumMedian, None)
    };
    let sd_run = sd_run.max(numerical_floor * (2.0 / n as f64).sqrt());
    let tests = regular + usize::from(nyquist);
    let th = Thresholds::new(tests, r, options.false_alarm_rate, min_coherence, dof);
    let power_of = |k: usize, z: Phasor| if 2 * k == n { z.norm_sqr() } else { z.norm_sqr() / 2.0 };
    let total: f64 = (1..=n / 2).map(|k| power_of(k, mean.bins[k].phasor)).sum();
    let mut lines = Vec::new();
    let mut significant = Vec::new();
    for k in 1..=n / 2 {
        let one_dim = 2 * k == n;
        let tested = Tested {
            runs: spectra.iter().map(|s| s[k]).collect(),
            mean: mean.bins[k].phasor,
            sd_run: if one_dim { sd_run / std::f64::consts::SQRT_2 } else { sd_run },
            one_dim,
        };
        let v = th.judge(&tested);
        if v.coherent || v.incoherent {
            significant.push(k);
            let naming = name_line(k as f64, candidates, frame);
            lines.push(make_line(k as f64, tested.mean, &v, naming, frame, power_of(k, tested.mean), total));
        }
    }
    let aliases = naming::alias_report(candidates, frame, |bin| {
        mean.bins.get(bin).map(|b| (significant.contains(&bin), b.amplitude_deg, b.phase_deg))
    });
    let sd_mean = sd_run / (r as f64).sqrt();
    let noise = NoiseFloor {
        method,
        line_sd_run_deg: sd_run,
        line_sd_mean_deg: sd_mean,
        sample_sd_deg: sd_run * (n as f64 / 2.0).sqrt(),
        dof,
        tests,
        false_alarm_rate: options.false_alarm_rate,
        coherent_threshold_deg: th.coh_2d * sd_mean,
        incoherent_threshold_deg: th.inc.map(|x| sd_run * (x / r as f64).sqrt()),
        min_coherence,
    };
    Ok(Core {
        points_per_rev: n as f64,
        method: Method::Dft,
        spectra: Some(Spectra { mean }),
        fit: None,
        noise,
        lines,
        aliases,
    })
}

/// The geometry of a partial range.
struct Partial<'a> {
    theta: &'a [f64],
    start: f64,
    end: f64,
    step: f64,
    uniform: bool,
}

#[allow(clippy::too_many_arguments)]
fn partial_range(
    rows: &[Vec<f64>],
    g: &Partial,
    heads: u32,
    candidates: &[Candidate],
    options: &AnalysisOptions,
    min_coherence: f64,
    numerical_floor: f64,
    notes: &mut Vec<String>,
) -> Result<Core, AnalysisError> {
    let n = g.theta.len();
    if n < 4 || g.step <= 0.0 {
        return Err(AnalysisError::TooFewTargets {
            targets: n,
            min: 4,
            why: "a least-squares fit over a partial range",
        });
    }
    let points_per_rev = 360.0 / g.step;
    let frame = Frame { points_per_rev, full_circle: false, start_deg: g.start, encoder_heads: heads };
    let mut freqs: Vec<f64> =
        candidates.iter().map(|c| c.cycles_per_rev).filter(|&f| f < points_per_rev / 2.0 - 1e-9).collect();
    freqs.sort_by(f64::total_cmp);
    freqs.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * a.max(1.0));
    let p = 1 + 2 * freqs.len();
    if n <= p {
        return Err(AnalysisError::TooFewTargets {
            targets: n,
            min: p + 1,
            why: "fitting the design frequencies with a residual",
        });
    }
    let basis = SinusoidBasis::new(g.theta, &freqs)?;
    let fits = rows.iter().map(|y| basis.fit(y)).collect::<Result<Vec<_>, _>>()?;
    let r = rows.len();
    let mean_row: Vec<f64> = (0..n).map(|j| rows.iter().map(|y| y[j]).sum::<f64>() / r as f64).collect();
    let mean_fit = basis.fit(&mean_row)?;
    let predict = |fit: &SinusoidFit, t: f64| {
        fit.offset_deg + fit.terms.iter().map(|x| x.phasor.value_at(x.cycles_per_rev, t)).sum::<f64>()
    };
    let residuals: Vec<Vec<f64>> =
        rows.iter().zip(&fits).map(|(y, f)| y.iter().zip(g.theta).map(|(v, &t)| v - predict(f, t)).collect()).collect();
    let dof_fit = n - p;
    let (sample_sd, method, dof) = if r >= 2 {
        let ss: f64 = (0..n)
            .map(|j| {
                let m = residuals.iter().map(|e| e[j]).sum::<f64>() / r as f64;
                residuals.iter().map(|e| (e[j] - m).powi(2)).sum::<f64>()
            })
            .sum();
        let dof = (r - 1) * dof_fit;
        ((ss / dof as f64).sqrt(), NoiseMethod::ResidualScatter, Some(dof))
    } else {
        let ss: f64 = residuals[0].iter().map(|e| e * e).sum();
        ((ss / dof_fit as f64).sqrt(), NoiseMethod::Residual, Some(dof_fit))
    };
    let sample_sd = sample_sd.max(numerical_floor);
    let th = Thresholds::new(freqs.len(), r, options.false_alarm_rate, min_coherence, dof);
    let variance = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64
    };
    let total = variance(&mean_row);
    let mut lines = Vec::new();
    let mut sds = Vec::with_capacity(freqs.len());
    for (i, &f) in freqs.iter().enumerate() {
        let term = &mean_fit.terms[i];
        let sd_run = sample_sd * (0.5 * (term.sin_unit_var + term.cos_unit_var)).sqrt();
        sds.push(sd_run);
        let tested = Tested {
            runs: fits.iter().map(|x| x.terms[i].phasor).collect(),
            mean: term.phasor,
            sd_run,
            one_dim: false,
        };
        let v = th.judge(&tested);
        if v.coherent || v.incoherent {
            let component: Vec<f64> = g.theta.iter().map(|&t| term.phasor.value_at(f, t)).collect();
            let naming = name_line(f, candidates, &frame);
            lines.push(make_line(f, term.phasor, &v, naming, &frame, variance(&component), total));
        }
    }
    let aliases = naming::alias_report(candidates, &frame, |_| None);
    let spectra = if g.uniform {
        let mut planner = Planner::new();
        let span = n as f64 * g.step;
        let runs = rows
            .iter()
            .map(|y| planner.phasors(y, g.start, span, options.partial_window))
            .collect::<Result<Vec<_>, _>>()?;
        Some(Spectra { mean: Spectrum::mean_of_phasors(rows[0].len(), g.start, span, options.partial_window, &runs) })
    } else {
        None
    };
    notes.push(format!(
        "partial range {} to {} deg: lines fitted by least squares at the {} design frequencies below {} cycles/rev; \
         an error at any other frequency stays in the residual ({:.3e} deg RMS on the mean curve)",
        num(g.start),
        num(g.end),
        freqs.len(),
        num(points_per_rev / 2.0),
        mean_fit.residual_rms_deg
    ));
    // The typical frequency: the median (the slow terms of a short span are far
    // less certain than the rest and would dominate a mean).
    sds.sort_by(f64::total_cmp);
    let line_sd_run = if sds.is_empty() { sample_sd } else { sds[sds.len() / 2] };
    let sd_mean = line_sd_run / (r as f64).sqrt();
    let noise = NoiseFloor {
        method,
        line_sd_run_deg: line_sd_run,
        line_sd_mean_deg: sd_mean,
        sample_sd_deg: sample_sd,
        dof,
        tests: freqs.len(),
        false_alarm_rate: options.false_alarm_rate,
        coherent_threshold_deg: th.coh_2d * sd_mean,
        incoherent_threshold_deg: th.inc.map(|x| line_sd_run * (x / r as f64).sqrt()),
        min_coherence,
    };
    Ok(Core {
        points_per_rev,
        method: Method::LeastSquares,
        spectra,
        fit: Some(PartialFit { frequencies: freqs, mean: mean_fit, runs: fits }),
        noise,
        lines,
        aliases,
    })
}

fn points_needed(lines: &[Line], points_per_rev: f64) -> Option<PointsNeeded> {
    let highest = lines.iter().flat_map(|l| l.candidates.iter()).map(|c| c.cycles_per_rev).fold(f64::NAN, f64::max);
    if !highest.is_finite() {
        return None;
    }
    let nyquist_points = (2.0 * highest).floor() as usize + 1;
    let quadratic = (20.0 * highest).ceil() as usize;
    let sufficient = points_per_rev > 2.0 * highest;
    let head = if sufficient {
        format!(
            "{} points/rev resolve the highest design harmonic found, {} cycles/rev",
            num(points_per_rev),
            num(highest)
        )
    } else {
        format!(
            "{} points/rev resolve only up to {} cycles/rev; the highest design harmonic found, {} cycles/rev, needs {} points/rev \
             or more (steps of at most {:.4} deg)",
            num(points_per_rev),
            num(points_per_rev / 2.0),
            num(highest),
            nyquist_points,
            360.0 / nyquist_points as f64
        )
    };
    Some(PointsNeeded {
        highest_cycles: highest,
        nyquist_points,
        max_step_deg: 360.0 / nyquist_points as f64,
        quadratic_interpolation_points: quadratic,
        points_per_rev,
        sufficient,
        note: format!(
            "{head}; spectral resampling needs no more, while quadratic interpolation of the table needs about {quadratic} \
             points/rev (the paper's rule: 20 x the highest frequency)"
        ),
    })
}
