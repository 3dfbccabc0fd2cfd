//! ISO 230-2 statistics across runs.
//!
//! Targets `P_i`, runs `j`, positioning deviation `x_ij = actual - target` per
//! direction of approach (`up` is [`Direction::Forward`], `down` is
//! [`Direction::Reverse`]). Per target and direction: the mean deviation `x̄`,
//! the standard uncertainty `s` (denominator `n - 1`) and the unidirectional
//! repeatability `R = 4 s`. Per target, bidirectional: the reversal value
//! `B_i = x̄_up - x̄_down`, the repeatability
//! `R_i = max(2 s_up + 2 s_down + |B_i|, R_up_i, R_down_i)` and the mean
//! `x̄_i = (x̄_up + x̄_down) / 2`. Over the axis:
//!
//! | figure | definition |
//! |---|---|
//! | `R_up`, `R_down`, `R` | `max_i` of the per-target figure |
//! | `B`, `B_mean` | `max_i abs(B_i)`, `mean_i B_i` |
//! | `E_up`, `E_down` | `max_i x̄ - min_i x̄` in one direction |
//! | `E` | max of `x̄` over both directions minus min over both |
//! | `M` | `max_i x̄_i - min_i x̄_i` |
//! | `A_up`, `A_down` | `max_i (x̄ + 2s) - min_i (x̄ - 2s)` in one direction |
//! | `A` | `max(x̄_up + 2s_up, x̄_down + 2s_down) - min(x̄_up - 2s_up, x̄_down - 2s_down)` |
//!
//! A unidirectional survey (one direction only) is valid: the figures of the
//! missing direction and the bidirectional ones (`B`, `B_mean`, `M`, per-target
//! `B_i` and `x̄_i`) are `None`, and `A`, `R`, `E` equal the figures of the
//! direction that was measured.

use crate::types::{Direction, Sample};
use serde::Serialize;

/// Targets closer than this (degrees) are the same target.
pub const TARGET_TOLERANCE_DEG: f64 = 1e-9;

/// Statistics of one target in one direction of approach.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DirStats {
    /// Number of runs (samples) at this target in this direction.
    pub n: usize,
    /// Mean positioning deviation `x̄`, degrees.
    pub mean: f64,
    /// Standard uncertainty `s` (sample standard deviation, `n - 1`), degrees.
    pub s: f64,
    /// Unidirectional repeatability `4 s`, degrees.
    #[serde(rename = "R")]
    pub r: f64,
}

/// Statistics of one target.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TargetStats {
    /// The target position, degrees (the smallest of the targets grouped here).
    pub target_deg: f64,
    /// Forward approaches ("up"), if measured.
    pub up: Option<DirStats>,
    /// Reverse approaches ("down"), if measured.
    pub down: Option<DirStats>,
    /// Reversal value `B_i = x̄_up - x̄_down`; `None` in a unidirectional survey.
    #[serde(rename = "B")]
    pub b: Option<f64>,
    /// Repeatability `R_i`: bidirectional `max(2 s_up + 2 s_down + |B_i|, 4 s_up, 4 s_down)`,
    /// or `4 s` of the one direction in a unidirectional survey.
    #[serde(rename = "R")]
    pub r: f64,
    /// Mean bidirectional deviation `x̄_i = (x̄_up + x̄_down) / 2`; `None` in a
    /// unidirectional survey.
    pub mean_bi: Option<f64>,
}

/// ISO 230-2 figures of an axis, degrees. Serialises with the contract's keys
/// (`A`, `A_up`, `A_down`, `R`, `R_up`, `R_down`, `B`, `B_mean`, `E`, `E_up`,
/// `E_down`, `M`) plus `runs` and `targets`; absent figures are `null`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Iso230 {
    /// Accuracy `A` (both directions, or the one direction measured).
    #[serde(rename = "A")]
    pub a: f64,
    /// Unidirectional accuracy, forward.
    #[serde(rename = "A_up")]
    pub a_up: Option<f64>,
    /// Unidirectional accuracy, reverse.
    #[serde(rename = "A_down")]
    pub a_down: Option<f64>,
    /// Repeatability `R = max_i R_i`.
    #[serde(rename = "R")]
    pub r: f64,
    /// Unidirectional repeatability, forward: `max_i 4 s_up_i`.
    #[serde(rename = "R_up")]
    pub r_up: Option<f64>,
    /// Unidirectional repeatability, reverse: `max_i 4 s_down_i`.
    #[serde(rename = "R_down")]
    pub r_down: Option<f64>,
    /// Reversal value `B = max_i |B_i|`.
    #[serde(rename = "B")]
    pub b: Option<f64>,
    /// Mean reversal value `B_mean = mean_i B_i` (signed).
    #[serde(rename = "B_mean")]
    pub b_mean: Option<f64>,
    /// Systematic positional deviation `E`, over both directions.
    #[serde(rename = "E")]
    pub e: f64,
    /// Unidirectional systematic positional deviation, forward.
    #[serde(rename = "E_up")]
    pub e_up: Option<f64>,
    /// Unidirectional systematic positional deviation, reverse.
    #[serde(rename = "E_down")]
    pub e_down: Option<f64>,
    /// Mean positional deviation `M = max_i x̄_i - min_i x̄_i`.
    #[serde(rename = "M")]
    pub m: Option<f64>,
    /// The largest number of runs seen at any target and direction.
    pub runs: usize,
    /// Per-target statistics, targets in ascending order; empty when only
    /// the figures were kept ([`iso230_2_figures_grouped`]).
    pub targets: Vec<TargetStats>,
    /// How many targets the figures are of (`targets.len()` when they are kept).
    #[serde(skip)]
    pub target_count: usize,
}

/// Why ISO 230-2 statistics cannot be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StatsError {
    /// There is nothing to compute.
    #[error("no samples: ISO 230-2 statistics need at least 2 runs at every target")]
    NoSamples,
    /// A target has fewer than 2 runs in a direction, so `s` is undefined.
    #[error("target {target_deg} deg, {direction}: {runs} run{}; ISO 230-2 needs at least 2", if *runs == 1 { "" } else { "s" })]
    TooFewRuns {
        /// The target, degrees.
        target_deg: f64,
        /// The direction of approach that lacks runs.
        direction: Direction,
        /// How many runs there are (fewer than 2).
        runs: usize,
    },
    /// The survey is bidirectional but a target was approached from one side only.
    #[error(
        "target {target_deg} deg has no {missing} samples, but the survey is bidirectional; \
         ISO 230-2 needs both directions at every target"
    )]
    MissingDirection {
        /// The target, degrees.
        target_deg: f64,
        /// The direction with no samples at this target.
        missing: Direction,
    },
    /// The same run appears more than once at a target and direction.
    #[error(
        "target {target_deg} deg, {direction}: run {run} appears {count} times; each run gives one sample per target"
    )]
    DuplicateRun {
        /// The target, degrees.
        target_deg: f64,
        /// The direction of approach.
        direction: Direction,
        /// The run number that repeats.
        run: u32,
        /// How many samples carry it.
        count: usize,
    },
    /// A target or actual angle is NaN or infinite.
    #[error("sample {index} (run {run}, {direction}): {field} is {value}, not a finite number")]
    NonFinite {
        /// Position of the sample in the input slice (from 0).
        index: usize,
        /// Its run.
        run: u32,
        /// Its direction.
        direction: Direction,
        /// `target_deg` or `actual_deg`.
        field: &'static str,
        /// The offending value.
        value: f64,
    },
}

/// ISO 230-2 statistics of a survey.
///
/// Samples may come in any order; they are grouped by target (targets within
/// [`TARGET_TOLERANCE_DEG`] of each other are one target, reported in ascending
/// order) and direction, and each group is ordered by run, so the result does
/// not depend on the order of `samples`. Only `target_deg` and `actual_deg`
/// are used.
pub fn iso230_2(samples: &[Sample]) -> Result<Iso230, StatsError> {
    iso230_2_grouped(samples, &TargetGroups::of(samples))
}

/// [`iso230_2`] with the samples' grouping by target made already
/// ([`TargetGroups::of`] `samples`, or of samples with the same targets in
/// the same order).
pub fn iso230_2_grouped(samples: &[Sample], groups: &TargetGroups) -> Result<Iso230, StatsError> {
    iso230_2_with_actual(samples, groups, |i| samples[i].actual_deg)
}

/// [`iso230_2_grouped`]'s figures alone, `targets` left empty: the
/// per-target statistics (a hundred bytes a target) are folded into the
/// figures as they are made, to the same bits, and not kept.
pub fn iso230_2_figures_grouped(samples: &[Sample], groups: &TargetGroups) -> Result<Iso230, StatsError> {
    let mut fold = AxisFold::default();
    each_target(samples, groups, |i| samples[i].actual_deg, |t| fold.add(&t))?;
    Ok(fold.figures(Vec::new()))
}

/// [`iso230_2_figures_grouped`] and [`iso230_2_a_with_actual`] of
/// `actual` together, from one walk of the groups (each as the function
/// gives it alone, to the bit; either fails alone where the function does).
pub fn iso230_2_figures_and_a_with_actual(
    samples: &[Sample],
    groups: &TargetGroups,
    actual: impl Fn(usize) -> f64,
) -> (Result<Iso230, StatsError>, Result<f64, StatsError>) {
    let mut fold = AxisFold::default();
    let mut a = ABand::default();
    match each_target_of(
        samples,
        groups,
        |i| [samples[i].actual_deg, actual(i)],
        |[native, other]| {
            fold.add(&native);
            a.add(&other);
        },
    ) {
        Ok(()) => (Ok(fold.figures(Vec::new())), Ok(a.a())),
        // A value that is not finite is one set's: each is taken alone to
        // tell which (the errors of the grouping are both sets').
        Err(StatsError::NonFinite { .. }) => {
            (iso230_2_figures_grouped(samples, groups), iso230_2_a_with_actual(samples, groups, actual))
        }
        Err(e) => (Err(e.clone()), Err(e)),
    }
}

/// The bidirectional `A`'s largest `x̄ + 2s` and smallest `x̄ - 2s`, as
/// [`axis_figures`] finds them (a largest and a smallest: the same bits in
/// any order).
struct ABand {
    hi: f64,
    lo: f64,
}

impl Default for ABand {
    fn default() -> Self {
        ABand { hi: f64::NEG_INFINITY, lo: f64::INFINITY }
    }
}

impl ABand {
    fn add(&mut self, t: &TargetStats) {
        for d in [&t.up, &t.down].into_iter().flatten() {
            self.hi = self.hi.max(d.mean + 2.0 * d.s);
            self.lo = self.lo.min(d.mean - 2.0 * d.s);
        }
    }

    fn a(&self) -> f64 {
        self.hi - self.lo
    }
}

/// [`iso230_2_grouped`] of `samples` with the actual angle of sample `i`
/// replaced by `actual(i)` (corrected samples, without a copy of them).
fn iso230_2_with_actual(
    samples: &[Sample],
    groups: &TargetGroups,
    actual: impl Fn(usize) -> f64,
) -> Result<Iso230, StatsError> {
    let mut targets = Vec::with_capacity(groups.len());
    each_target(samples, groups, actual, |t| targets.push(t))?;
    Ok(axis_figures(targets))
}

/// The `A` of [`iso230_2_with_actual`] alone, without its per-target
/// statistics kept (a hundred bytes a target): the largest `x̄ + 2s` less the
/// smallest `x̄ - 2s` over every target and direction, as [`axis_figures`]
/// finds it (a largest and a smallest: the same bits in any order).
pub fn iso230_2_a_with_actual(
    samples: &[Sample],
    groups: &TargetGroups,
    actual: impl Fn(usize) -> f64,
) -> Result<f64, StatsError> {
    let mut band = ABand::default();
    each_target(samples, groups, actual, |t| band.add(&t))?;
    Ok(band.a())
}

/// Every target's statistics of `samples` (actual angle of sample `i`:
/// `actual(i)`), grouped by `groups`, to `each` in target order.
fn each_target(
    samples: &[Sample],
    groups: &TargetGroups,
    actual: impl Fn(usize) -> f64,
    mut each: impl FnMut(TargetStats),
) -> Result<(), StatsError> {
    each_target_of(samples, groups, |i| [actual(i)], |[t]| each(t))
}

/// [`each_target`] of `N` sets of actual angles at once (sample `i`'s:
/// `actual(i)`), each target's statistics of each set to `each` together:
/// one walk of the groups, one split of a target's samples by direction and
/// one check of their runs serve every set. The first value that is not
/// finite, of any set, is the error.
fn each_target_of<const N: usize>(
    samples: &[Sample],
    groups: &TargetGroups,
    actual: impl Fn(usize) -> [f64; N],
    mut each: impl FnMut([TargetStats; N]),
) -> Result<(), StatsError> {
    for (index, s) in samples.iter().enumerate() {
        if !s.target_deg.is_finite() {
            let value = s.target_deg;
            return Err(StatsError::NonFinite {
                index,
                run: s.run,
                direction: s.direction,
                field: "target_deg",
                value,
            });
        }
        if let Some(&value) = actual(index).iter().find(|v| !v.is_finite()) {
            return Err(StatsError::NonFinite {
                index,
                run: s.run,
                direction: s.direction,
                field: "actual_deg",
                value,
            });
        }
    }
    if samples.is_empty() {
        return Err(StatsError::NoSamples);
    }
    let any_up = samples.iter().any(|s| s.direction == Direction::Forward);
    let any_down = samples.iter().any(|s| s.direction == Direction::Reverse);
    let bidirectional = any_up && any_down;

    // One buffer each for a direction's (run, sample) and for each set's
    // deviations, reused by every target; a target's samples are split by
    // direction in one pass over them.
    let mut up_runs: Vec<(u32, usize)> = Vec::new();
    let mut down_runs: Vec<(u32, usize)> = Vec::new();
    let mut x: [Vec<f64>; N] = std::array::from_fn(|_| Vec::new());
    for group in groups.iter() {
        let target_deg = samples[group[0] as usize].target_deg;
        up_runs.clear();
        down_runs.clear();
        for &i in group {
            let s = &samples[i as usize];
            match s.direction {
                Direction::Forward => up_runs.push((s.run, i as usize)),
                Direction::Reverse => down_runs.push((s.run, i as usize)),
            }
        }
        let mut dir_stats = |direction: Direction| -> Result<Option<[DirStats; N]>, StatsError> {
            let g = if direction == Direction::Forward { &mut up_runs } else { &mut down_runs };
            if g.is_empty() {
                return Ok(None);
            }
            // In run order (a survey stores them so: no sort); equal runs
            // in the samples' order.
            if !g.is_sorted_by_key(|&(run, _)| run) {
                g.sort_by_key(|&(run, _)| run);
            }
            if let Some(w) = g.windows(2).find(|w| w[0].0 == w[1].0) {
                let run = w[0].0;
                let count = g.iter().filter(|&&(r, _)| r == run).count();
                return Err(StatsError::DuplicateRun { target_deg, direction, run, count });
            }
            if g.len() < 2 {
                return Err(StatsError::TooFewRuns { target_deg, direction, runs: g.len() });
            }
            x.iter_mut().for_each(Vec::clear);
            for &(_, i) in g.iter() {
                let (a, t) = (actual(i), samples[i].target_deg);
                for k in 0..N {
                    x[k].push(a[k] - t);
                }
            }
            Ok(Some(std::array::from_fn(|k| dir_stats_of(&x[k]))))
        };
        let up = dir_stats(Direction::Forward)?;
        let down = dir_stats(Direction::Reverse)?;
        if bidirectional && (up.is_none() || down.is_none()) {
            let missing = if up.is_none() { Direction::Forward } else { Direction::Reverse };
            return Err(StatsError::MissingDirection { target_deg, missing });
        }
        each(std::array::from_fn(|k| {
            target_stats(target_deg, up.as_ref().map(|u| u[k].clone()), down.as_ref().map(|d| d[k].clone()))
        }));
    }
    Ok(())
}

/// A target's statistics from its directions' (one at least).
fn target_stats(target_deg: f64, up: Option<DirStats>, down: Option<DirStats>) -> TargetStats {
    match (&up, &down) {
        (Some(u), Some(d)) => {
            let b = u.mean - d.mean;
            let r = (2.0 * u.s + 2.0 * d.s + b.abs()).max(u.r).max(d.r);
            TargetStats { target_deg, b: Some(b), r, mean_bi: Some((u.mean + d.mean) / 2.0), up, down }
        }
        (Some(one), None) | (None, Some(one)) => TargetStats { target_deg, b: None, r: one.r, mean_bi: None, up, down },
        (None, None) => unreachable!("every target group holds at least one sample"),
    }
}

/// Samples grouped by target, targets ascending; a group starts at its
/// smallest target and takes every target within [`TARGET_TOLERANCE_DEG`]
/// of it. Made once, it serves every statistic of samples with these
/// targets in this order (the survey's, its corrected errors').
#[derive(Debug, Clone)]
pub struct TargetGroups {
    /// The samples' indices sorted by target (`u32`: 4 bytes a sample for
    /// as long as the grouping is kept, a quarter of a `usize` with its key).
    sorted: Vec<u32>,
    /// Each group's range in `sorted`.
    ranges: Vec<std::ops::Range<usize>>,
}

impl TargetGroups {
    /// The grouping of `samples` by target.
    pub fn of(samples: &[Sample]) -> Self {
        // Sorted as (target, index) pairs, side by side in memory (not through a
        // reference each); the order of equal targets does not matter: a group
        // is ordered by run before anything is computed from it. A survey's
        // samples are a few sweeps, each ascending or descending in target: the
        // stable sort finds them and merges them (an unstable one partitions).
        if let Some(groups) = Self::of_sweeps(samples) {
            return groups;
        }
        Self::by_sort(samples)
    }

    /// [`TargetGroups::of`] by a stable sort of the samples' targets.
    fn by_sort(samples: &[Sample]) -> Self {
        let count = u32::try_from(samples.len()).expect("fewer than 2^32 samples");
        let mut keyed: Vec<(f64, u32)> = samples.iter().map(|s| s.target_deg).zip(0..count).collect();
        keyed.sort_by(|a, b| a.0.total_cmp(&b.0));
        let ranges = group_ranges(keyed.iter().map(|&(t, _)| t), 1);
        // A new vector (collected in place, it would keep the pairs' room).
        let sorted = keyed.iter().map(|&(_, i)| i).collect();
        TargetGroups { sorted, ranges }
    }

    /// The grouping of a survey's samples that are whole sweeps over the
    /// same targets (what a survey stores: each run forward, then reverse
    /// when bidirectional): the first sweep strictly ascending or
    /// descending, every other one the same targets (bit for bit) in the
    /// same or the reverse order. Their sorted order is then known without
    /// a sort: target by target, a sample from each sweep in the sweeps'
    /// order (the samples' order: what the stable sort gives, to the
    /// index). `None` for any other layout (repeated readings, a sweep cut
    /// short, a target missing): the sort takes those.
    fn of_sweeps(samples: &[Sample]) -> Option<Self> {
        let n = samples.len();
        let t = |i: usize| samples[i].target_deg;
        if n < 2 || u32::try_from(n).is_err() {
            return None;
        }
        // The first sweep: its length and its direction.
        let first = t(1).total_cmp(&t(0));
        if first == std::cmp::Ordering::Equal {
            return None;
        }
        let len = 1 + (1..n).take_while(|&i| t(i).total_cmp(&t(i - 1)) == first).count();
        if !n.is_multiple_of(len) {
            return None;
        }
        // The targets ascending, as the first sweep holds them.
        let ascending = first == std::cmp::Ordering::Greater;
        let target = |j: usize| if ascending { t(j) } else { t(len - 1 - j) };
        // Every sweep: its direction from its first target, then each of
        // its targets the same bits as the first sweep's.
        let sweeps = n / len;
        let mut up = Vec::with_capacity(sweeps);
        for s in 0..sweeps {
            let base = s * len;
            let bits = t(base).to_bits();
            let forward = if bits == target(0).to_bits() {
                true
            } else if bits == target(len - 1).to_bits() {
                false
            } else {
                return None;
            };
            let same = (0..len).all(|j| {
                let k = if forward { j } else { len - 1 - j };
                t(base + j).to_bits() == target(k).to_bits()
            });
            if !same {
                return None;
            }
            up.push(forward);
        }
        let mut sorted = Vec::with_capacity(n);
        for j in 0..len {
            for (s, &forward) in up.iter().enumerate() {
                let k = if forward { j } else { len - 1 - j };
                sorted.push((s * len + k) as u32);
            }
        }
        // The groups as the sorted targets make them (every sweep's sample
        // of a target has its bits).
        let ranges = group_ranges((0..len).map(target), sweeps);
        Some(TargetGroups { sorted, ranges })
    }

    /// How many targets.
    pub fn len(&self) -> usize {
        self.ranges.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.ranges.is_empty()
    }

    /// Each target's samples (indices), targets ascending, a target's
    /// samples in the order of their targets (equal ones in the samples'
    /// order).
    pub fn iter(&self) -> impl Iterator<Item = &[u32]> {
        self.ranges.iter().map(|r| &self.sorted[r.clone()])
    }
}

/// The groups of `targets` (ascending, each `places` places of the sorted
/// order): a group starts at its smallest target and takes every target
/// within [`TARGET_TOLERANCE_DEG`] of it.
fn group_ranges(targets: impl Iterator<Item = f64>, places: usize) -> Vec<std::ops::Range<usize>> {
    let mut ranges: Vec<std::ops::Range<usize>> = Vec::new();
    let mut start_target = f64::NAN;
    for (j, t) in targets.enumerate() {
        let (from, to) = (j * places, (j + 1) * places);
        match ranges.last_mut() {
            Some(g) if t - start_target <= TARGET_TOLERANCE_DEG => g.end = to,
            _ => {
                ranges.push(from..to);
                start_target = t;
            }
        }
    }
    ranges
}

fn dir_stats_of(x: &[f64]) -> DirStats {
    let n = x.len();
    let mean = x.iter().sum::<f64>() / n as f64;
    let ss: f64 = x.iter().map(|v| (v - mean) * (v - mean)).sum();
    let s = (ss / (n - 1) as f64).sqrt();
    DirStats { n, mean, s, r: 4.0 * s }
}

/// Axis figures of one direction: (A, R, E).
#[derive(Clone, Copy)]
struct DirFigures {
    a: f64,
    r: f64,
    e: f64,
    /// Largest `x̄ + 2s` and smallest `x̄ - 2s`, for the bidirectional `A`.
    hi_band: f64,
    lo_band: f64,
    /// Largest and smallest `x̄`, for the bidirectional `E`.
    hi_mean: f64,
    lo_mean: f64,
}

impl DirFigures {
    /// The figures so far (`None`: no target yet) with one more target's statistics.
    fn add(f: Option<DirFigures>, d: &DirStats) -> DirFigures {
        let (hi_band, lo_band) = (d.mean + 2.0 * d.s, d.mean - 2.0 * d.s);
        match f {
            None => DirFigures { a: 0.0, r: d.r, e: 0.0, hi_band, lo_band, hi_mean: d.mean, lo_mean: d.mean },
            Some(f) => DirFigures {
                r: f.r.max(d.r),
                hi_band: f.hi_band.max(hi_band),
                lo_band: f.lo_band.min(lo_band),
                hi_mean: f.hi_mean.max(d.mean),
                lo_mean: f.lo_mean.min(d.mean),
                ..f
            },
        }
    }

    fn finish(self) -> DirFigures {
        DirFigures { a: self.hi_band - self.lo_band, e: self.hi_mean - self.lo_mean, ..self }
    }
}

/// The axis figures, folded target by target in target order: what they
/// need of each target, and nothing kept a target.
struct AxisFold {
    up: Option<DirFigures>,
    down: Option<DirFigures>,
    runs: usize,
    r: f64,
    /// Largest `|B_i|`, and the sum (in target order) and count of the `B_i`.
    b_abs: f64,
    b_sum: Option<f64>,
    b_count: usize,
    /// Largest and smallest bidirectional mean `x̄_i`.
    hi_mean_bi: f64,
    lo_mean_bi: f64,
    targets: usize,
}

impl Default for AxisFold {
    fn default() -> Self {
        AxisFold {
            up: None,
            down: None,
            runs: 0,
            r: f64::NEG_INFINITY,
            b_abs: 0.0,
            b_sum: None,
            b_count: 0,
            hi_mean_bi: f64::NEG_INFINITY,
            lo_mean_bi: f64::INFINITY,
            targets: 0,
        }
    }
}

impl AxisFold {
    fn add(&mut self, t: &TargetStats) {
        if let Some(d) = &t.up {
            self.up = Some(DirFigures::add(self.up, d));
        }
        if let Some(d) = &t.down {
            self.down = Some(DirFigures::add(self.down, d));
        }
        self.runs = [&t.up, &t.down].into_iter().flatten().map(|d| d.n).fold(self.runs, usize::max);
        self.r = self.r.max(t.r);
        if let Some(b) = t.b {
            self.b_abs = self.b_abs.max(b.abs());
            // From the first term on: a sum from -0.0, as `Iterator::sum` makes it.
            self.b_sum = Some(self.b_sum.map_or(b, |sum| sum + b));
            self.b_count += 1;
        }
        if let Some(m) = t.mean_bi {
            self.hi_mean_bi = self.hi_mean_bi.max(m);
            self.lo_mean_bi = self.lo_mean_bi.min(m);
        }
        self.targets += 1;
    }

    /// The figures, with `targets` (the statistics folded, or none kept).
    fn figures(self, targets: Vec<TargetStats>) -> Iso230 {
        let (up, down) = (self.up.map(DirFigures::finish), self.down.map(DirFigures::finish));
        let (a, e, b, b_mean, m) = match (&up, &down) {
            (Some(u), Some(d)) => (
                u.hi_band.max(d.hi_band) - u.lo_band.min(d.lo_band),
                u.hi_mean.max(d.hi_mean) - u.lo_mean.min(d.lo_mean),
                Some(self.b_abs),
                Some(self.b_sum.unwrap_or(-0.0) / self.b_count as f64),
                Some(self.hi_mean_bi - self.lo_mean_bi),
            ),
            (Some(one), None) | (None, Some(one)) => (one.a, one.e, None, None, None),
            (None, None) => unreachable!("iso230_2 rejects an empty survey"),
        };
        Iso230 {
            a,
            a_up: up.as_ref().map(|f| f.a),
            a_down: down.as_ref().map(|f| f.a),
            r: self.r,
            r_up: up.as_ref().map(|f| f.r),
            r_down: down.as_ref().map(|f| f.r),
            b,
            b_mean,
            e,
            e_up: up.as_ref().map(|f| f.e),
            e_down: down.as_ref().map(|f| f.e),
            m,
            runs: self.runs,
            targets,
            target_count: self.targets,
        }
    }
}

fn axis_figures(targets: Vec<TargetStats>) -> Iso230 {
    let mut fold = AxisFold::default();
    targets.iter().for_each(|t| fold.add(t));
    fold.figures(targets)
}

#[cfg(test)]
mod tests;
