//! The uncertainty of a correction table's values: a budget in the manner of
//! the GUM (JCGM 100: each source a standard uncertainty, combined as the
//! root sum of squares of independent contributions, expanded with a
//! coverage factor `k = 2`), its sources those ISO/TR 230-9 lists for a
//! machine-tool measurement (the reference instrument, its set-up, the
//! repeatability, the model of what is measured, the environment, here the
//! drift).
//!
//! What is stated: the standard uncertainty of the table's value at any
//! angle, as an error of the positioner, relative to its zero reference (a
//! constant common to the whole table is the zero reference's choice, not
//! an error of the table). It is the uncertainty of the table the
//! processing made, from this survey:
//!
//! - **reference instrument, random**: the reference's random error of one
//!   angle (`reference_u_deg`, stated by the bench or the configuration)
//!   through the fit: a table of `p` fitted terms (two per kept line of a
//!   full circle; the polynomial and the lines of a partial range) from `N`
//!   readings carries `p u^2 / N` of it at an angle, on average.
//! - **reference instrument, systematic**: the reference's own error that
//!   repeats at the same place on every reading (a tracker's encoder
//!   harmonics, offsets and tilts; `reference_systematic_u_deg`, from the
//!   instrument's specification through the survey's geometry:
//!   `survey_processing::tracker_errors::TransverseMpe::systematic_angle_u_deg`).
//!   The survey cannot tell it from the positioner's error: the table
//!   absorbs it whole, and no number of readings divides it.
//! - **repeatability over the runs**: what the survey's own scatter from run
//!   to run puts into the fitted terms (Type A: for a full circle, each kept
//!   line's quadrature components have the standard deviation the spread of
//!   the run spectra gives, `line_sd_mean`; `K` lines make `K line_sd_mean^2`
//!   at an angle), less the reference's share above (the scatter holds both).
//! - **axis location** (a tracker): the once-per-revolution error of the
//!   angles computed around the fitted axis, from the axis fit's own standard
//!   error over the measured arc.
//! - **direction model**: a directional table's forward - reverse part (the
//!   noise of the difference's mean and of its kept lines, halved in each
//!   column; a line of the difference kept at less than twice its threshold
//!   may be a false alarm, noise selected for being large, and then each
//!   column carries half of it wrongly: `A / (2 sqrt 2)` rms); a table of
//!   one column for a bidirectional survey carries half the mean hysteresis
//!   as an error of each direction.
//! - **table resolution and interpolation**: the table is read between its
//!   rows by linear interpolation: a line of amplitude `A` and angular
//!   frequency `w` (rad/deg) leaves `A w^2 h^2 / sqrt(240)` rms between rows
//!   `h` deg apart.
//! - **drift**: by what it leaves in the table, whatever its shape, as the
//!   runs' own tables show it: each kept line fitted to each run alone, the
//!   trend of its phasor over the runs beyond what their noise makes, the
//!   table (their mean) wrong by that trend over half the survey. A drift
//!   of the whole map (a step or a ramp of the zero between runs) changes no
//!   line and leaves nothing; one that changes the lines is counted by how
//!   much it does. (It was a ramp assumed from the run means' slope: a step
//!   drift, which leaves nothing, made `U` 20 to 55 times the true error.)
//! - **drift in time**: the slope of the drift measured from the survey's
//!   own readings (`crate::timedrift`) corrects every reading by
//!   `b (t - mid)`; its standard error leaves `se (t_cell - mid)` in each
//!   table cell, counted at its rms over the cells, corrected or not.
//!
//! - **a line below the detection threshold** (the model of the table): the
//!   table holds the lines the analysis found; one it could not find is at
//!   most about the threshold of its test (`coherent_threshold_deg`) and the
//!   table leaves it whole. Its size is one for every readout (systematic),
//!   so it is not averaged over the amplitudes it may have (`T / sqrt(6)`
//!   did, and a line just below `T` then left more than `U` allowed for):
//!   the budget covers a sinusoid of amplitude `T` at any phase, propagated
//!   as its distribution with the rest (below).
//!
//! - **what the table leaves** ([`crate::left`]): a repeatable
//!   line the survey saw and the table does not carry (nulled: two design
//!   harmonics alias to its bin; removed), at its measured size, and, when
//!   the design does not name a line and the spectrum reaches into the top
//!   half of what the sampling resolves, the risk that the line is the alias
//!   of a frequency above it (the table then errs by up to twice the line
//!   between the targets). A line of amplitude `A` left whole contributes
//!   `A / sqrt(2)` rms; a possible alias, the difference of two lines, `A`.
//!   Their sizes are known to the noise of each measured phasor (`u_A` per
//!   component): one size for every readout, a systematic error, so the
//!   lines are taken at the upper end of that interval, `A + k u_A`, not
//!   averaged over the readouts like noise. Beside them a normal term: their
//!   products with the error through the readout, which the table made
//!   through the true angle carries for the lines it keeps and not for
//!   these (second order, [`crate::left`]).
//!
//! # The coverage interval
//!
//! Without anything left, every source is about normal and `U = k u` with
//! `k = 2` (about 95 %: 95.45 % for a normal distribution). What the table
//! leaves is not normal: a sinusoid over the readouts has the arcsine
//! distribution (its 95th percentile `0.997 A`, its rms `0.707 A`), and the
//! lines of one part are harmonics of each other with fixed relative phases,
//! so neither quadrature nor an independent-phase convolution describes
//! their sum. So the distribution is propagated instead of its rms (the
//! method of GUM Supplement 1, JCGM 101, done exactly rather than by random
//! draws): what is left, `s(r)`, is evaluated as the function it is at 4096
//! readouts equidistributed over the table's range, for each hypothesis of
//! its lines' true frequencies; the normal part (every other source, in
//! quadrature, `u_n`) is added as a normal of that standard deviation, and
//! `U` solves `mean_r P(|s(r) + u_n Z| <= U) = 0.9545` (the probability
//! `k = 2` gives a normal distribution, so `U` is continuous with the normal
//! case), by bisection. The least favourable hypothesis (the largest `U`)
//! is stated. The budget keeps `k = 2` and `U = k u` (the contract's form):
//! what is left enters it as the effective standard uncertainty
//! `sqrt((U/2)^2 - u_n^2)`, the entry that expands to the coverage interval
//! of the distribution; its rms (what quadrature would have used: for a
//! sinusoid `0.707 A` against the interval's `0.997 A / 2`) is in `method`.
//!
//! Check points between the targets that no hypothesis explains (no single
//! candidate per line does: the bin may hold several lines, in part
//! cancelling at the targets, so its measured size understates what is
//! left) measure what the table leaves there directly: `U` is then at least
//! the coverage interval of `|d - mean d|` over them
//! ([`crate::resolve::measured_left_deg`]).
//!
//! What is not: more than one line missed; a reference whose own error
//! exceeds what its specification states.

use crate::left::{Left, LeftKind};
use crate::pipeline::Processed;
use serde::Serialize;
use survey_processing::errormap::{Coverage, Series};
use survey_processing::types::{Direction, Sample};

/// What the processing does not know from the samples.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct UncertaintyInputs {
    /// The reference instrument's standard uncertainty of one angle
    /// (random), degrees; `None` when not stated.
    pub reference_u_deg: Option<f64>,
    /// The reference instrument's systematic standard uncertainty at an
    /// angle of the table (the same on every reading there), degrees;
    /// `None` when not stated.
    pub reference_systematic_u_deg: Option<f64>,
    /// The axis location's once-per-revolution standard error over the
    /// measured arc (a tracker), degrees; `None` without a fitted axis.
    pub axis_u_deg: Option<f64>,
    /// What the drift in time's slope, measured from the survey's readings,
    /// leaves in the table through its own standard error, degrees
    /// (`crate::timedrift::TimeDrift::table_u_deg`); `None`
    /// when the survey could not measure it or drift control corrected it.
    pub drift_in_time_u_deg: Option<f64>,
    /// The axis's radial error motion as one SMR reads it along its circle,
    /// degrees: a translation of the axis moves the SMR across its radius
    /// as much as along it, and the along part is read as angle and
    /// corrected into the table; `None` where the motion is below the
    /// tracker's detection limit or SMRs at equal spacing cancel it.
    pub wobble_u_deg: Option<f64>,
}

/// One source and its standard uncertainty.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Contribution {
    /// The source, in words.
    pub source: String,
    /// Its standard uncertainty at an angle of the table, degrees.
    pub u_deg: f64,
}

/// The budget and the table's uncertainty.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Uncertainty {
    /// The coverage factor of the expanded uncertainty.
    pub k: f64,
    /// The expanded uncertainty of the table's values, `k combined_u_deg`,
    /// degrees: what a certificate states (about 95 % coverage).
    pub table_u_deg: f64,
    /// The combined standard uncertainty of the table's values, degrees.
    pub combined_u_deg: f64,
    /// The contributions.
    pub budget: Vec<Contribution>,
    /// How it was estimated, in words.
    pub method: String,
    /// The approaches `U` holds for: `"both directions"`, or a one-way
    /// survey's `"forward approaches only"` / `"reverse approaches only"`
    /// (from the other side the reversal, which it did not measure, adds).
    pub holds_for: String,
}

pub use survey_processing::coverage::{K, coverage_interval, coverage_probability};

/// The budget's entry of the reference's systematic part.
pub const REFERENCE_SYSTEMATIC: &str = "reference instrument, systematic";

impl Uncertainty {
    /// The reference's systematic standard uncertainty at an angle, when
    /// the budget has one: a verification with the same reference shares it.
    pub fn reference_systematic_u_deg(&self) -> Option<f64> {
        self.budget.iter().find(|c| c.source == REFERENCE_SYSTEMATIC).map(|c| c.u_deg)
    }
}

/// What drift leaves in the table, as the runs' own tables show it (a
/// variance, degrees squared): each kept line fitted to each run's series
/// (the table made from that run alone), its phasor's trend over the runs
/// (least squares, complex), when its noise would make it one time in
/// twenty at most (`|b|^2 / (2 se^2)` beyond the 95th percentile of
/// `F(2, 2 (R - 2))`, the noise estimated from the same runs), less what its
/// noise makes of a trend (`2 se^2` for the two components), and the table
/// (their mean) taken as wrong by that trend over half the survey at either
/// end: `|b|^2 ((R - 1) / 2)^2 / 2` a line. A drift that moves the whole error map (a ramp or a step of the
/// zero, the same in every run) changes no line of the runs' tables and
/// leaves nothing (the table's zero is its reference's choice); one that
/// changes the lines from run to run is counted by how much it changes them.
/// `None` with fewer than three runs.
fn drift_from_runs(a: &survey_processing::analysis::Analysis, kept: &[f64]) -> Option<f64> {
    let map = &a.error_map;
    let runs = map.run_series(a.series)?;
    let r = runs.len();
    if r < 3 || kept.is_empty() {
        return None;
    }
    // One basis for every run: the runs share their targets (its QR is the
    // cost; each run's fit is a solve).
    let basis = survey_processing::spectrum::SinusoidBasis::new(&map.targets_deg, kept).ok()?;
    let fits: Vec<survey_processing::spectrum::SinusoidFit> = runs.iter().filter_map(|y| basis.fit(y).ok()).collect();
    if fits.len() != r {
        return None;
    }
    let x: Vec<f64> = (0..r).map(|i| i as f64 - (r - 1) as f64 / 2.0).collect();
    let sxx: f64 = x.iter().map(|v| v * v).sum();
    let mut var = 0.0;
    for k in 0..kept.len() {
        let c: Vec<(f64, f64)> = fits
            .iter()
            .map(|f| {
                let t = &f.terms[k];
                let ph = t.phase_deg.to_radians();
                (t.amplitude_deg * ph.cos(), t.amplitude_deg * ph.sin())
            })
            .collect();
        let mean = |i: usize| c.iter().map(|v| if i == 0 { v.0 } else { v.1 }).sum::<f64>() / r as f64;
        let (m0, m1) = (mean(0), mean(1));
        let b0 = x.iter().zip(&c).map(|(x, v)| x * (v.0 - m0)).sum::<f64>() / sxx;
        let b1 = x.iter().zip(&c).map(|(x, v)| x * (v.1 - m1)).sum::<f64>() / sxx;
        let rss: f64 = x.iter().zip(&c).map(|(x, v)| (v.0 - m0 - b0 * x).powi(2) + (v.1 - m1 - b1 * x).powi(2)).sum();
        // Each component's residual variance over r - 2 degrees of freedom.
        let se2 = rss / (2.0 * (r as f64 - 2.0)) / sxx;
        // A trend its noise makes one time in twenty is counted, less what
        // noise makes. The noise is estimated from the same few runs, so the
        // test is F(2, nu), nu = 2 (r - 2), not a chi-square: its 95th
        // percentile `x = nu/2 (0.05^(-2/nu) - 1)` is 19 at three runs (a
        // chi-square's 3, i.e. `b^2 > 6 se^2`, alarmed one time in four
        // there and put a drift into U where there was none), 6.9 at four,
        // 5.1 at five, and tends to 3 with many.
        let nu = 2.0 * (r as f64 - 2.0);
        let x = nu / 2.0 * (0.05f64.powf(-2.0 / nu) - 1.0);
        let b2 = b0 * b0 + b1 * b1;
        let excess = if b2 > 2.0 * x * se2 { b2 - 2.0 * se2 } else { 0.0 };
        var += excess * ((r - 1) as f64 / 2.0).powi(2) / 2.0;
    }
    Some(var)
}

/// The budget of `processed`, the table made from `samples`.
pub fn uncertainty(processed: &Processed, samples: &[Sample], inputs: &UncertaintyInputs) -> Uncertainty {
    let a = &processed.analysis;
    let map = &a.error_map;
    let n = map.targets_deg.len().max(1);
    let runs = a.runs.max(1);
    let kept = &processed.decisions.kept_cycles;
    let (params, in_range) = match map.coverage {
        Coverage::FullCircle { .. } => (2 * kept.len(), kept.len()),
        Coverage::Partial { start, end, .. } => {
            let width = end - start;
            let lines = kept.iter().filter(|f| *f * width / 360.0 >= 0.5).count();
            (3 + 2 * lines, lines)
        }
    };
    let p = params as f64;
    // The analysed series: one value per target and run (the mean of the two
    // directions of a bidirectional survey), `sample_sd` each.
    let series_var = a.noise.sample_sd_deg.powi(2);
    let random_var = match map.coverage {
        Coverage::FullCircle { .. } => in_range as f64 * a.noise.line_sd_mean_deg.powi(2),
        Coverage::Partial { .. } => p * series_var / (n * runs) as f64,
    };
    let readings = samples.len().max(1) as f64;
    let reference_var = inputs.reference_u_deg.map(|u| p * u * u / readings);
    let mut budget = Vec::new();
    if let Some(v) = reference_var {
        budget.push(Contribution { source: "reference instrument, random".into(), u_deg: v.sqrt() });
    }
    if let Some(u) = inputs.reference_systematic_u_deg {
        budget.push(Contribution { source: REFERENCE_SYSTEMATIC.into(), u_deg: u });
    }
    budget.push(Contribution {
        source: "repeatability over the runs".into(),
        u_deg: (random_var - reference_var.unwrap_or(0.0)).max(0.0).sqrt(),
    });
    if let Some(u) = inputs.axis_u_deg {
        budget.push(Contribution { source: "axis location".into(), u_deg: u });
    }
    let bidirectional = map.forward.is_some() && map.reverse.is_some();
    let built = &processed.built;
    let direction_var = match (&built.direction_model, built.directional, &built.hysteresis) {
        (Some(dm), _, _) => {
            // A line kept at less than twice the threshold may be a false
            // alarm: noise selected for being large. Then each column carries
            // half of it wrongly, a sinusoid of rms `A / (2 sqrt 2)`.
            let doubtful: f64 = dm
                .lines
                .iter()
                .filter(|(_, a)| *a < 2.0 * dm.threshold_deg)
                .map(|(_, a)| (a / 2.0).powi(2) / 2.0)
                .sum();
            dm.noise_deg.powi(2) / (4.0 * dm.targets as f64) * (1.0 + 2.0 * dm.lines.len() as f64) + doubtful
        }
        // Each direction's terms fitted from its own half of the data.
        (None, true, _) => p * series_var / (n * runs) as f64,
        (None, false, Some(h)) if bidirectional && a.series == Series::Bidirectional => (h.mean_deg / 2.0).powi(2),
        _ => 0.0,
    };
    if bidirectional {
        budget.push(Contribution { source: "direction model".into(), u_deg: direction_var.sqrt() });
    }
    // Linear interpolation between rows `h` apart.
    let h = built.table.spacing_deg();
    let interp_var: f64 = a
        .lines
        .iter()
        .filter(|l| kept.iter().any(|k| (k - l.true_cycles_per_rev).abs() < 1e-9))
        .map(|l| {
            let w = (l.true_cycles_per_rev * std::f64::consts::TAU / 360.0).powi(2);
            (l.amplitude_deg * w * h * h).powi(2) / 240.0
        })
        .sum();
    budget.push(Contribution { source: "table resolution and interpolation".into(), u_deg: interp_var.sqrt() });
    let in_range_kept: Vec<f64> = match map.coverage {
        Coverage::FullCircle { .. } => kept.clone(),
        Coverage::Partial { start, end, .. } => {
            kept.iter().copied().filter(|f| f * (end - start) / 360.0 >= 0.5).collect()
        }
    };
    let drift_var = drift_from_runs(a, &in_range_kept).unwrap_or(0.0);
    budget.push(Contribution { source: "drift".into(), u_deg: drift_var.sqrt() });
    if let Some(u) = inputs.drift_in_time_u_deg {
        budget.push(Contribution { source: "drift in time (its measured slope's standard error)".into(), u_deg: u });
    }
    if let Some(u) = inputs.wobble_u_deg {
        budget.push(Contribution {
            source: "the axis's radial motion read as angle (its part along the SMR's circle)".into(),
            u_deg: u,
        });
    }
    // What check points fitted with the survey's folds leave unexplained
    // beyond their noise (a line no fold and no hypothesis holds): a normal
    // term of its rms (for a sinusoid, `k` times its rms is 1.41 times its
    // amplitude: the normal's interval holds it).
    if let Some(v) = processed.unexplained_deg {
        budget.push(Contribution {
            source: "what the check points leave unexplained beside the folds (its rms beyond their noise)".into(),
            u_deg: v,
        });
    }
    // A line below the detection threshold is left out of the table whole:
    // a sinusoid of any amplitude up to the threshold `T`, at any phase. Its
    // size is one for every readout (systematic), so it is not averaged
    // over amplitudes: it enters the distribution as a sinusoid of `T`.
    let threshold = a.noise.coherent_threshold_deg;
    // A kept line that matches no part of the design and stands less than
    // twice the threshold may be noise selected for being large (a false
    // alarm, about one survey in a hundred when noise dominates): the table
    // then carries it wholly wrongly, a sinusoid of its size.
    let doubtful: Vec<f64> = a
        .lines
        .iter()
        .filter(|l| {
            l.repeatable
                && l.kind == survey_processing::model::PeriodicKind::Harmonic
                && l.amplitude_deg < 2.0 * threshold
                && kept.iter().any(|k| (k - l.true_cycles_per_rev).abs() < 1e-9)
        })
        .map(|l| l.amplitude_deg)
        .collect();
    // A line the survey could have missed: below the threshold, or sharing a
    // bin the check points decided beyond what they exclude (a possible
    // line). At most one line is missed: the largest of them, one sinusoid
    // (the possible lines were each a sinusoid of their own, added together:
    // three decided bins of a 360-point survey of an unknown design made `U`
    // ten times the truth's p95).
    let possible = processed.left.lines.iter().filter(|l| l.kind == LeftKind::Possible);
    let missed = possible.map(|l| l.amplitude_deg).fold(threshold, f64::max);
    let unseen: Vec<f64> = std::iter::once(missed).chain(doubtful).collect();
    let normal_u = budget.iter().map(|c| c.u_deg * c.u_deg).sum::<f64>().sqrt();
    let method = format!(
        "GUM (JCGM 100) budget, ISO/TR 230-9 sources: independent standard uncertainties combined in quadrature, \
         expanded with k = {K}; the table's value at an angle relative to its zero reference, {} fitted terms from \
         {} readings{}",
        params,
        samples.len(),
        if samples.iter().any(|s| s.direction == Direction::Reverse) { ", both directions" } else { "" }
    );
    // A line on the Nyquist bin that no check point measured between the
    // targets is bounded as a whole line ([`Left::nyquist_bounded`]).
    let nyquist_measured = processed.measured_left_deg.is_some()
        && processed.resolutions.iter().any(|r| 2.0 * r.observed_cycles == processed.left.points as f64);
    let measured_left = Left {
        lines: processed.left.lines.iter().filter(|l| l.kind != LeftKind::Possible).cloned().collect(),
        ..processed.left.clone()
    };
    let left = if nyquist_measured { measured_left } else { measured_left.nyquist_bounded() };
    let method = if !nyquist_measured && (0..left.lines.len()).any(|i| left.on_nyquist(i)) {
        format!(
            "{method}; a line on the Nyquist bin that no check point measured between the targets is taken whole as \
             the part the targets see over sin(pi/40) (its phase against the targets is unknown: all but the 5 % of \
             phases nearest their zeros): check points between the targets (a tracker) or a survey at another count \
             measure it"
        )
    } else {
        method
    };
    let mut u = with_left(&left, threshold, &unseen, normal_u, budget, method);
    u.holds_for = holds_for(samples);
    match processed.measured_left_deg {
        Some(measured) if measured > u.table_u_deg => at_least_measured(u, measured),
        _ => u,
    }
}

/// `u` raised to what check points measured the table leaves between the
/// targets, when no hypothesis explains them (see the module documentation):
/// an entry makes the budget expand to it.
fn at_least_measured(mut u: Uncertainty, measured: f64) -> Uncertainty {
    let rest = u.budget.iter().map(|c| c.u_deg * c.u_deg).sum::<f64>();
    u.budget.push(Contribution {
        source: "left by the table between the targets, as the check points measured it (no hypothesis explains them)"
            .into(),
        u_deg: ((measured / K).powi(2) - rest).max(0.0).sqrt(),
    });
    u.method += &format!(
        "; no hypothesis explains the check points between the targets (a bin holds several lines, in part \
         cancelling at the targets): U is at least the coverage interval of what they measured the table leaves, \
         {measured:.2e} deg (their own noise removed in quadrature)"
    );
    u.table_u_deg = measured;
    u.combined_u_deg = measured / K;
    u
}

/// The values of sinusoids of `amplitudes` at phases independent of the
/// readout and of each other, paired with `count` readouts (a Weyl sequence
/// of its own each, so each one's values have the arcsine distribution and
/// are independent of another sequence's).
fn unseen_lines(amplitudes: &[f64], count: usize) -> Vec<f64> {
    const STEPS: [f64; 6] = [
        std::f64::consts::SQRT_2 - 1.0,
        1.732_050_807_568_877_2 - 1.0,
        2.645_751_311_064_590_6 - 2.0,
        3.316_624_790_355_4 - 3.0,
        3.605_551_275_463_989 - 3.0,
        4.123_105_625_617_66 - 4.0,
    ];
    (0..count)
        .map(|j| {
            amplitudes
                .iter()
                .zip(STEPS.iter().cycle())
                .map(|(a, step)| a * (std::f64::consts::TAU * ((j as f64 + 0.5) * step).fract()).sin())
                .sum()
        })
        .collect()
}

/// The budget with what the table leaves (the lines the survey saw and
/// `unseen`: first the line it could have missed, at least the detection
/// threshold `threshold`, then kept lines that may be false alarms), and
/// its coverage interval from the distribution (see the module
/// documentation): `U` solves the coverage of `|left + unseen line +
/// normal|`; the budget's entries for what is left and for the unseen line
/// are the effective standard uncertainties that expand with `k` to it.
fn with_left(
    left: &Left,
    threshold: f64,
    unseen: &[f64],
    normal_u: f64,
    mut budget: Vec<Contribution>,
    method: String,
) -> Uncertainty {
    let p = coverage_probability();
    let readouts = Left::readouts();
    let normal_u = if left.is_empty() {
        normal_u
    } else {
        budget.push(Contribution {
            source: "the lines left, through the readout (their products with the error, second order)".into(),
            u_deg: left.second_order_deg,
        });
        normal_u.hypot(left.second_order_deg)
    };
    // Their sizes at the upper end of what the survey allows (systematic: one
    // size for every readout).
    let upper = left.at_upper_size(K);
    let hypotheses = if left.is_empty() { vec![Vec::new()] } else { upper.hypotheses() };
    let sines = unseen_lines(unseen, readouts.len());
    let (table_u_deg, seen_u_deg, rms, hypothesis) = hypotheses
        .into_iter()
        .map(|h| {
            let s = if left.is_empty() { vec![0.0; readouts.len()] } else { upper.values(&h, &readouts) };
            let rms = (s.iter().map(|x| x * x).sum::<f64>() / s.len() as f64).sqrt();
            let with_unseen: Vec<f64> = s.iter().zip(&sines).map(|(a, b)| a + b).collect();
            (coverage_interval(&with_unseen, normal_u, p), coverage_interval(&s, normal_u, p), rms, h)
        })
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .expect("at least one hypothesis");
    // The entries that make the budget expand (k = 2, in quadrature) to the
    // coverage interval of the distribution: U / k less the normal part.
    let effective_seen = ((seen_u_deg / K).powi(2) - normal_u.powi(2)).max(0.0).sqrt();
    let effective_unseen = ((table_u_deg / K).powi(2) - (seen_u_deg / K).powi(2).max(normal_u.powi(2))).max(0.0).sqrt();
    let (missed, doubtful) = (unseen[0], &unseen[1..]);
    let false_alarms = match doubtful.len() {
        0 => String::new(),
        n => format!(", and {n} kept line(s) of no design part under twice it (possible false alarms, whole)"),
    };
    let (missed_line, amplitude) = if missed > threshold {
        (
            "a line the survey could have missed (the largest the check points could not exclude beside a line they \
             decided, above the detection threshold; one line, from its distribution)",
            "the largest line check points could not exclude sharing a bin they decided, above T: at most one line \
             is missed",
        )
    } else {
        ("a line below the detection threshold (a sinusoid up to the threshold, from its distribution)", "T")
    };
    budget.push(Contribution { source: format!("{missed_line}{false_alarms}"), u_deg: effective_unseen });
    let mut method = format!(
        "{method}; a line below the detection threshold T = {threshold:.2e} deg is left whole by the table: a \
         sinusoid of amplitude {missed:.2e} deg ({amplitude}) at a phase independent of the readout, its values \
         (arcsine-distributed) added to the rest{}, and U the coverage interval of the sum for {:.2} % (what k = \
         {K} gives a normal distribution) computed from that distribution (GUM Supplement 1, propagated exactly, not by its rms); its budget entry is \
         the effective standard uncertainty that expands with k = {K} to that interval",
        if doubtful.is_empty() {
            String::new()
        } else {
            format!(
                "; so is each kept line that matches no design part and stands under 2 T (noise selected for being \
                 large, which the table would carry wholly wrongly): {}",
                doubtful.iter().map(|a| format!("{a:.2e} deg")).collect::<Vec<_>>().join(", ")
            )
        },
        100.0 * p
    );
    if !left.is_empty() {
        let lines: Vec<String> = left
            .lines
            .iter()
            .zip(&hypothesis)
            .map(|(l, f)| match l.kind {
                LeftKind::NotCarried => format!("bin {} not carried (at {f} cycles/rev)", l.observed_cycles),
                LeftKind::MaybeAlias => format!("bin {} may be an alias (of {f} cycles/rev)", l.observed_cycles),
                LeftKind::Possible => format!("bin {} possibly shared (at {f} cycles/rev)", l.observed_cycles),
                LeftKind::MayFold => format!("bin {} may hold a fold (of {f} cycles/rev)", l.observed_cycles),
                LeftKind::Folded => format!("bin {} holds a fold measured (at {f} cycles/rev)", l.observed_cycles),
            })
            .collect();
        budget.push(Contribution {
            source: format!("left by the table, from its distribution: {}", lines.join("; ")),
            u_deg: effective_seen,
        });
        method += &format!(
            "; the table leaves {} line(s) the survey saw: evaluated as functions of the readout at {} readouts \
             over the table's range for each hypothesis of their true frequencies (sizes at A + {K} u_A), added to \
             the rest, the least favourable hypothesis stated (what is left has rms {:.2e} deg, {:.2e} deg in \
             quadrature with the rest)",
            left.lines.len(),
            readouts.len(),
            rms,
            normal_u.hypot(rms),
        );
    }
    // A standard uncertainty is a size: never a signed zero (an empty sum is
    // -0.0 in Rust, and `sqrt(-0.0)` printed "-0.00e0 deg").
    for c in &mut budget {
        c.u_deg = c.u_deg.abs();
    }
    Uncertainty { k: K, table_u_deg, combined_u_deg: table_u_deg / K, budget, method, holds_for: String::new() }
}

/// The approaches a table made from `samples` holds for (see
/// [`Uncertainty::holds_for`]).
fn holds_for(samples: &[Sample]) -> String {
    let forward = samples.iter().any(|s| s.direction == Direction::Forward);
    let reverse = samples.iter().any(|s| s.direction == Direction::Reverse);
    match (forward, reverse) {
        (true, false) => "forward approaches only",
        (false, true) => "reverse approaches only",
        _ => "both directions",
    }
    .to_string()
}

impl Uncertainty {
    /// Lines for people.
    pub fn text(&self) -> String {
        let one_way = if self.holds_for == "both directions" || self.holds_for.is_empty() {
            String::new()
        } else {
            format!(
                ", for {}: the survey measured one way, and from the other side the reversal it did not measure adds",
                self.holds_for
            )
        };
        let mut s = format!(
            "table uncertainty (GUM): u = {:.2e} deg, U = {:.2e} deg (k = {}){one_way}\n",
            self.combined_u_deg, self.table_u_deg, self.k
        );
        for c in &self.budget {
            s += &format!("  {:<38} {:.2e} deg\n", c.source, c.u_deg);
        }
        s
    }
}
