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
    /// Per-target statistics, targets in ascending order.
    pub targets: Vec<TargetStats>,
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

/// [`iso230_2_grouped`] of `samples` with the actual angle of sample `i`
/// replaced by `actual(i)` (corrected samples, without a copy of them).
pub(crate) fn iso230_2_with_actual(
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
pub(crate) fn iso230_2_a_with_actual(
    samples: &[Sample],
    groups: &TargetGroups,
    actual: impl Fn(usize) -> f64,
) -> Result<f64, StatsError> {
    let (mut hi, mut lo) = (f64::NEG_INFINITY, f64::INFINITY);
    each_target(samples, groups, actual, |t| {
        for d in [&t.up, &t.down].into_iter().flatten() {
            hi = hi.max(d.mean + 2.0 * d.s);
            lo = lo.min(d.mean - 2.0 * d.s);
        }
    })?;
    Ok(hi - lo)
}

/// Every target's statistics of `samples` (actual angle of sample `i`:
/// `actual(i)`), grouped by `groups`, to `each` in target order.
fn each_target(
    samples: &[Sample],
    groups: &TargetGroups,
    actual: impl Fn(usize) -> f64,
    mut each: impl FnMut(TargetStats),
) -> Result<(), StatsError> {
    for (index, s) in samples.iter().enumerate() {
        for (field, value) in [("target_deg", s.target_deg), ("actual_deg", actual(index))] {
            if !value.is_finite() {
                return Err(StatsError::NonFinite { index, run: s.run, direction: s.direction, field, value });
            }
        }
    }
    if samples.is_empty() {
        return Err(StatsError::NoSamples);
    }
    let any_up = samples.iter().any(|s| s.direction == Direction::Forward);
    let any_down = samples.iter().any(|s| s.direction == Direction::Reverse);
    let bidirectional = any_up && any_down;

    // One buffer each for a direction's samples and deviations, reused by every target.
    let (mut g, mut x): (Vec<usize>, Vec<f64>) = (Vec::new(), Vec::new());
    for group in groups.iter() {
        let target_deg = samples[group[0] as usize].target_deg;
        let mut dir_stats = |direction: Direction| -> Result<Option<DirStats>, StatsError> {
            g.clear();
            g.extend(group.iter().map(|&i| i as usize).filter(|&i| samples[i].direction == direction));
            if g.is_empty() {
                return Ok(None);
            }
            g.sort_by_key(|&i| samples[i].run);
            if let Some(w) = g.windows(2).find(|w| samples[w[0]].run == samples[w[1]].run) {
                let run = samples[w[0]].run;
                let count = g.iter().filter(|&&i| samples[i].run == run).count();
                return Err(StatsError::DuplicateRun { target_deg, direction, run, count });
            }
            if g.len() < 2 {
                return Err(StatsError::TooFewRuns { target_deg, direction, runs: g.len() });
            }
            x.clear();
            x.extend(g.iter().map(|&i| actual(i) - samples[i].target_deg));
            Ok(Some(dir_stats_of(&x)))
        };
        let up = dir_stats(Direction::Forward)?;
        let down = dir_stats(Direction::Reverse)?;
        let target = match (&up, &down) {
            (Some(u), Some(d)) => {
                let b = u.mean - d.mean;
                let r = (2.0 * u.s + 2.0 * d.s + b.abs()).max(u.r).max(d.r);
                TargetStats { target_deg, b: Some(b), r, mean_bi: Some((u.mean + d.mean) / 2.0), up, down }
            }
            (Some(one), None) | (None, Some(one)) => {
                if bidirectional {
                    let missing = if up.is_none() { Direction::Forward } else { Direction::Reverse };
                    return Err(StatsError::MissingDirection { target_deg, missing });
                }
                TargetStats { target_deg, b: None, r: one.r, mean_bi: None, up, down }
            }
            (None, None) => unreachable!("every target group holds at least one sample"),
        };
        each(target);
    }
    Ok(())
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
        let count = u32::try_from(samples.len()).expect("fewer than 2^32 samples");
        let mut keyed: Vec<(f64, u32)> = samples.iter().map(|s| s.target_deg).zip(0..count).collect();
        keyed.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut ranges: Vec<std::ops::Range<usize>> = Vec::new();
        for (i, &(t, _)) in keyed.iter().enumerate() {
            match ranges.last_mut() {
                Some(g) if t - keyed[g.start].0 <= TARGET_TOLERANCE_DEG => g.end = i + 1,
                _ => ranges.push(i..i + 1),
            }
        }
        // A new vector (collected in place, it would keep the pairs' room).
        let sorted = keyed.iter().map(|&(_, i)| i).collect();
        TargetGroups { sorted, ranges }
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

fn dir_stats_of(x: &[f64]) -> DirStats {
    let n = x.len();
    let mean = x.iter().sum::<f64>() / n as f64;
    let ss: f64 = x.iter().map(|v| (v - mean) * (v - mean)).sum();
    let s = (ss / (n - 1) as f64).sqrt();
    DirStats { n, mean, s, r: 4.0 * s }
}

/// Axis figures of one direction: (A, R, E).
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

fn dir_figures<'a>(stats: impl Iterator<Item = &'a DirStats>) -> Option<DirFigures> {
    let mut f: Option<DirFigures> = None;
    for d in stats {
        let (hi_band, lo_band) = (d.mean + 2.0 * d.s, d.mean - 2.0 * d.s);
        f = Some(match f {
            None => DirFigures { a: 0.0, r: d.r, e: 0.0, hi_band, lo_band, hi_mean: d.mean, lo_mean: d.mean },
            Some(f) => DirFigures {
                r: f.r.max(d.r),
                hi_band: f.hi_band.max(hi_band),
                lo_band: f.lo_band.min(lo_band),
                hi_mean: f.hi_mean.max(d.mean),
                lo_mean: f.lo_mean.min(d.mean),
                ..f
            },
        });
    }
    f.map(|f| DirFigures { a: f.hi_band - f.lo_band, e: f.hi_mean - f.lo_mean, ..f })
}

fn axis_figures(targets: Vec<TargetStats>) -> Iso230 {
    let up = dir_figures(targets.iter().filter_map(|t| t.up.as_ref()));
    let down = dir_figures(targets.iter().filter_map(|t| t.down.as_ref()));
    let runs = targets.iter().flat_map(|t| [&t.up, &t.down]).flatten().map(|d| d.n).max().unwrap_or(0);
    let r = targets.iter().map(|t| t.r).fold(f64::NEG_INFINITY, f64::max);
    let (a, e, b, b_mean, m) = match (&up, &down) {
        (Some(u), Some(d)) => {
            let bs: Vec<f64> = targets.iter().filter_map(|t| t.b).collect();
            let means: Vec<f64> = targets.iter().filter_map(|t| t.mean_bi).collect();
            let max = |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
            (
                u.hi_band.max(d.hi_band) - u.lo_band.min(d.lo_band),
                u.hi_mean.max(d.hi_mean) - u.lo_mean.min(d.lo_mean),
                Some(bs.iter().map(|b| b.abs()).fold(0.0, f64::max)),
                Some(bs.iter().sum::<f64>() / bs.len() as f64),
                Some(max(&means) - min(&means)),
            )
        }
        (Some(one), None) | (None, Some(one)) => (one.a, one.e, None, None, None),
        (None, None) => unreachable!("iso230_2 rejects an empty survey"),
    };
    Iso230 {
        a,
        a_up: up.as_ref().map(|f| f.a),
        a_down: down.as_ref().map(|f| f.a),
        r,
        r_up: up.as_ref().map(|f| f.r),
        r_down: down.as_ref().map(|f| f.r),
        b,
        b_mean,
        e,
        e_up: up.as_ref().map(|f| f.e),
        e_down: down.as_ref().map(|f| f.e),
        m,
        runs,
        targets,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::path::Path;

    fn sample(run: u32, direction: Direction, target_deg: f64, deviation: f64) -> Sample {
        Sample {
            run,
            direction,
            target_deg,
            readout_deg: target_deg,
            actual_deg: target_deg + deviation,
            timestamp_s: None,
        }
    }

    /// Samples at `target` in `direction`, one per run (runs from 1).
    fn runs(direction: Direction, target: f64, deviations: &[f64]) -> Vec<Sample> {
        deviations.iter().enumerate().map(|(j, &x)| sample(j as u32 + 1, direction, target, x)).collect()
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
    }

    #[track_caller]
    fn assert_close(name: &str, got: f64, want: f64) {
        assert!(close(got, want), "{name}: got {got}, want {want}");
    }

    #[track_caller]
    fn assert_some_close(name: &str, got: Option<f64>, want: f64) {
        match got {
            Some(g) => assert_close(name, g, want),
            None => panic!("{name}: got None, want {want}"),
        }
    }

    use Direction::{Forward as Up, Reverse as Down};

    /// Two targets x 3 runs, bidirectional, round numbers.
    ///
    /// ```text
    /// target 0:  up   x = 1, 2, 3       mean  2    s 1    4s 4
    ///            down x = -1, -0.5, 0   mean -0.5  s 0.5  4s 2
    ///            B = 2 - (-0.5) = 2.5;  R = max(2*1 + 2*0.5 + 2.5, 4, 2) = max(5.5, 4, 2) = 5.5
    ///            x̄ = (2 - 0.5)/2 = 0.75
    /// target 90: up   x = -2, 0, 2      mean  0    s 2    4s 8
    ///            down x = -4, -3, -2    mean -3    s 1    4s 4
    ///            B = 0 - (-3) = 3;      R = max(2*2 + 2*1 + 3, 8, 4) = max(9, 8, 4) = 9
    ///            x̄ = (0 - 3)/2 = -1.5
    /// R_up = max(4, 8) = 8;  R_down = max(2, 4) = 4;  R = max(5.5, 9) = 9 (bidirectional term wins, not 8)
    /// B = max(2.5, 3) = 3;   B_mean = (2.5 + 3)/2 = 2.75
    /// E_up = 2 - 0 = 2;  E_down = -0.5 - (-3) = 2.5;
    /// E = max(2, 0, -0.5, -3) - min(2, 0, -0.5, -3) = 2 - (-3) = 5 (not max(E_up, E_down) = 2.5)
    /// M = 0.75 - (-1.5) = 2.25
    /// A_up:   x̄+2s = 4, 4;      x̄-2s = 0, -4    -> 4 - (-4) = 8
    /// A_down: x̄+2s = 0.5, -1;   x̄-2s = -1.5, -5 -> 0.5 - (-5) = 5.5
    /// A = max(4, 0.5) - min(-4, -5) = 4 + 5 = 9
    /// ```
    fn case_one() -> Vec<Sample> {
        let mut s = Vec::new();
        // Interleave the groups so that grouping, not input order, does the work.
        s.extend(runs(Down, 90.0, &[-4.0, -3.0, -2.0]));
        s.extend(runs(Up, 0.0, &[1.0, 2.0, 3.0]));
        s.extend(runs(Up, 90.0, &[-2.0, 0.0, 2.0]));
        s.extend(runs(Down, 0.0, &[-1.0, -0.5, 0.0]));
        s.reverse();
        s
    }

    #[test]
    fn hand_computed_bidirectional_r_and_e_over_both_directions() {
        let st = iso230_2(&case_one()).unwrap();
        assert_eq!(st.runs, 3);
        assert_eq!(st.targets.len(), 2);
        let (t0, t1) = (&st.targets[0], &st.targets[1]);
        assert_eq!(t0.target_deg, 0.0);
        assert_eq!(t1.target_deg, 90.0);

        let u0 = t0.up.as_ref().unwrap();
        let d0 = t0.down.as_ref().unwrap();
        assert_eq!(u0.n, 3);
        assert_close("t0 up mean", u0.mean, 2.0);
        assert_close("t0 up s", u0.s, 1.0);
        assert_close("t0 up R", u0.r, 4.0);
        assert_close("t0 down mean", d0.mean, -0.5);
        assert_close("t0 down s", d0.s, 0.5);
        assert_close("t0 down R", d0.r, 2.0);
        assert_some_close("t0 B", t0.b, 2.5);
        assert_close("t0 R", t0.r, 5.5);
        assert_some_close("t0 mean", t0.mean_bi, 0.75);

        let u1 = t1.up.as_ref().unwrap();
        let d1 = t1.down.as_ref().unwrap();
        assert_close("t1 up mean", u1.mean, 0.0);
        assert_close("t1 up s", u1.s, 2.0);
        assert_close("t1 down mean", d1.mean, -3.0);
        assert_close("t1 down s", d1.s, 1.0);
        assert_some_close("t1 B", t1.b, 3.0);
        assert_close("t1 R", t1.r, 9.0);
        assert_some_close("t1 mean", t1.mean_bi, -1.5);

        assert_some_close("R_up", st.r_up, 8.0);
        assert_some_close("R_down", st.r_down, 4.0);
        assert_close("R", st.r, 9.0);
        assert_some_close("B", st.b, 3.0);
        assert_some_close("B_mean", st.b_mean, 2.75);
        assert_some_close("E_up", st.e_up, 2.0);
        assert_some_close("E_down", st.e_down, 2.5);
        assert_close("E", st.e, 5.0);
        assert_some_close("M", st.m, 2.25);
        assert_some_close("A_up", st.a_up, 8.0);
        assert_some_close("A_down", st.a_down, 5.5);
        assert_close("A", st.a, 9.0);
    }

    /// Two targets x 4 runs, where 4 s wins R and the targets jitter within the tolerance.
    ///
    /// ```text
    /// target -10: up   x = 0, 0, 0, 4            mean 1   dev -1,-1,-1,3: ss 12, s = sqrt(12/3) = 2, 4s 8
    ///             down x = 1, 1, 1, 1            mean 1   s 0
    ///             B = 0;  R = max(2*2 + 0 + 0, 8, 0) = 8 (4 s_up wins);  x̄ = 1
    /// target 20:  up   x = 2, 2, 2, 2            mean 2   s 0
    ///             down x = -2.5, -0.5, -0.5, -0.5 mean -1 dev -1.5,.5,.5,.5: ss 3, s 1, 4s 4
    ///             B = 3;  R = max(0 + 2 + 3, 0, 4) = 5;  x̄ = 0.5
    /// R_up = 8, R_down = 4, R = max(8, 5) = 8
    /// B = 3, B_mean = (0 + 3)/2 = 1.5
    /// E_up = 2 - 1 = 1;  E_down = 1 - (-1) = 2;  E = max(1, 2, 1, -1) - min(...) = 2 - (-1) = 3
    /// M = 1 - 0.5 = 0.5
    /// A_up:   x̄+2s = 5, 2;  x̄-2s = -3, 2   -> 5 - (-3) = 8
    /// A_down: x̄+2s = 1, 1;  x̄-2s = 1, -3   -> 1 - (-3) = 4
    /// A = max(5, 1) - min(-3, -3) = 8
    /// ```
    #[test]
    fn hand_computed_four_s_wins_and_targets_group_within_tolerance() {
        let mut s = Vec::new();
        s.extend(runs(Up, 20.0, &[2.0, 2.0, 2.0, 2.0]));
        s.extend(runs(Down, 20.0 + 5e-10, &[-2.5, -0.5, -0.5, -0.5]));
        s.extend(runs(Up, -10.0, &[0.0, 0.0, 0.0, 4.0]));
        s.extend(runs(Down, -10.0 - 4e-10, &[1.0, 1.0, 1.0, 1.0]));
        let st = iso230_2(&s).unwrap();
        assert_eq!(st.runs, 4);
        assert_eq!(st.targets.len(), 2, "targets within 1e-9 deg are one target");
        assert_eq!(st.targets[0].target_deg, -10.0 - 4e-10, "the smallest target of the group");
        assert_eq!(st.targets[1].target_deg, 20.0);
        let (t0, t1) = (&st.targets[0], &st.targets[1]);
        assert_close("t0 up s", t0.up.as_ref().unwrap().s, 2.0);
        assert_close("t0 down s", t0.down.as_ref().unwrap().s, 0.0);
        assert_some_close("t0 B", t0.b, 0.0);
        assert_close("t0 R", t0.r, 8.0);
        assert_close("t1 down s", t1.down.as_ref().unwrap().s, 1.0);
        assert_some_close("t1 B", t1.b, 3.0);
        assert_close("t1 R", t1.r, 5.0);

        assert_some_close("R_up", st.r_up, 8.0);
        assert_some_close("R_down", st.r_down, 4.0);
        assert_close("R", st.r, 8.0);
        assert_some_close("B", st.b, 3.0);
        assert_some_close("B_mean", st.b_mean, 1.5);
        assert_some_close("E_up", st.e_up, 1.0);
        assert_some_close("E_down", st.e_down, 2.0);
        assert_close("E", st.e, 3.0);
        assert_some_close("M", st.m, 0.5);
        assert_some_close("A_up", st.a_up, 8.0);
        assert_some_close("A_down", st.a_down, 4.0);
        assert_close("A", st.a, 8.0);
    }

    /// The forward half of `case_one`: A_up = 8, R_up = 8, E_up = 2 (see there).
    /// The reverse half: A_down = 5.5, R_down = 4, E_down = 2.5.
    #[test]
    fn unidirectional_surveys_report_one_direction() {
        let forward: Vec<Sample> = case_one().into_iter().filter(|s| s.direction == Up).collect();
        let st = iso230_2(&forward).unwrap();
        assert_close("A", st.a, 8.0);
        assert_close("R", st.r, 8.0);
        assert_close("E", st.e, 2.0);
        assert_eq!((st.a_up, st.r_up, st.e_up), (Some(st.a), Some(st.r), Some(st.e)));
        assert_eq!((st.a_down, st.r_down, st.e_down), (None, None, None));
        assert_eq!((st.b, st.b_mean, st.m), (None, None, None));
        assert_eq!(st.runs, 3);
        for t in &st.targets {
            assert!(t.up.is_some() && t.down.is_none() && t.b.is_none() && t.mean_bi.is_none());
            assert_eq!(t.r, t.up.as_ref().unwrap().r);
        }

        let reverse: Vec<Sample> = case_one().into_iter().filter(|s| s.direction == Down).collect();
        let st = iso230_2(&reverse).unwrap();
        assert_close("A", st.a, 5.5);
        assert_close("R", st.r, 4.0);
        assert_close("E", st.e, 2.5);
        assert_eq!((st.a_down, st.r_down, st.e_down), (Some(st.a), Some(st.r), Some(st.e)));
        assert_eq!((st.a_up, st.r_up, st.e_up), (None, None, None));
        assert_eq!((st.b, st.b_mean, st.m), (None, None, None));
    }

    #[test]
    fn serialises_with_the_contract_keys() {
        let st = iso230_2(&case_one()).unwrap();
        let v = serde_json::to_value(&st).unwrap();
        for key in ["A", "A_up", "A_down", "R", "R_up", "R_down", "B", "B_mean", "E", "E_up", "E_down", "M"] {
            assert!(v[key].is_f64(), "key {key} missing or not a number in {v}");
        }
        assert_eq!(v["R"], 9.0);
        assert_eq!(v["E"], 5.0);
        assert_eq!(v["runs"], 3);
        assert_eq!(v["targets"][1]["R"], 9.0);
        assert_eq!(v["targets"][1]["B"], 3.0);
        assert_eq!(v["targets"][1]["up"]["s"], 2.0);

        let forward: Vec<Sample> = case_one().into_iter().filter(|s| s.direction == Up).collect();
        let v = serde_json::to_value(iso230_2(&forward).unwrap()).unwrap();
        for key in ["A_down", "R_down", "B", "B_mean", "E_down", "M"] {
            assert!(v.get(key).is_some_and(|x| x.is_null()), "key {key} should be present and null in {v}");
        }
    }

    #[test]
    fn no_samples_is_an_error() {
        assert_eq!(iso230_2(&[]), Err(StatsError::NoSamples));
    }

    #[test]
    fn one_run_names_the_target_and_direction() {
        let mut s = case_one();
        s.retain(|x| !(x.direction == Down && x.target_deg == 0.0 && x.run > 1));
        let mut s2 = runs(Up, 12.5, &[0.1, 0.2]);
        s2.extend(runs(Down, 12.5, &[0.1]));
        let err = iso230_2(&s2).unwrap_err();
        assert_eq!(err, StatsError::TooFewRuns { target_deg: 12.5, direction: Down, runs: 1 });
        assert_eq!(err.to_string(), "target 12.5 deg, reverse: 1 run; ISO 230-2 needs at least 2");
        assert_eq!(iso230_2(&s).unwrap_err(), StatsError::TooFewRuns { target_deg: 0.0, direction: Down, runs: 1 });
    }

    #[test]
    fn a_bidirectional_survey_needs_both_directions_at_every_target() {
        let mut s = case_one();
        s.retain(|x| !(x.direction == Up && x.target_deg == 90.0));
        let err = iso230_2(&s).unwrap_err();
        assert_eq!(err, StatsError::MissingDirection { target_deg: 90.0, missing: Up });
        let msg = err.to_string();
        assert!(msg.contains("target 90 deg") && msg.contains("no forward samples"), "{msg}");
    }

    #[test]
    fn duplicate_runs_are_an_error() {
        let mut s = case_one();
        s.push(sample(2, Up, 90.0, 0.5));
        let err = iso230_2(&s).unwrap_err();
        assert_eq!(err, StatsError::DuplicateRun { target_deg: 90.0, direction: Up, run: 2, count: 2 });
        assert!(err.to_string().contains("run 2 appears 2 times"), "{err}");
    }

    #[test]
    fn non_finite_values_are_an_error() {
        let mut s = case_one();
        s[4].actual_deg = f64::NAN;
        let err = iso230_2(&s).unwrap_err();
        assert!(matches!(err, StatsError::NonFinite { index: 4, field: "actual_deg", .. }), "{err:?}");
        assert!(err.to_string().starts_with("sample 4 (run "), "{err}");
        let mut s = case_one();
        s[0].target_deg = f64::INFINITY;
        let err = iso230_2(&s).unwrap_err();
        assert!(matches!(err, StatsError::NonFinite { index: 0, field: "target_deg", .. }), "{err:?}");
        assert!(err.to_string().contains("target_deg is inf"), "{err}");
    }

    // ---- Real data: the PSI ecmc ISO 230-2 files (see shared/data/iso230-ecmc/README.md).

    fn ecmc_dir() -> &'static Path {
        Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/iso230-ecmc"))
    }

    /// Parses an ecmc `*_ISO230.dat` file into samples: target = readout = `TGT_DATA[i]`,
    /// actual = `REF_DATA_FWD[i,j]` / `REF_DATA_BWD[i,j]`, run = `j`.
    fn parse_ecmc_dat(text: &str) -> Vec<Sample> {
        let mut targets = std::collections::BTreeMap::new();
        let mut refs = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let Some((key, value)) = line.trim().split_once('=') else { continue };
            let Some((name, index)) = key.strip_suffix(']').and_then(|k| k.split_once('[')) else { continue };
            let parse = |v: &str| -> f64 {
                v.trim().parse().unwrap_or_else(|e| panic!("line {}: '{v}' is not a number: {e}", n + 1))
            };
            let parse_index =
                |v: &str| -> u32 { v.trim().parse().unwrap_or_else(|e| panic!("line {}: index '{v}': {e}", n + 1)) };
            match name {
                "TGT_DATA" => {
                    targets.insert(parse_index(index), parse(value));
                }
                "REF_DATA_FWD" | "REF_DATA_BWD" => {
                    let (i, j) = index.split_once(',').unwrap_or_else(|| panic!("line {}: bad index", n + 1));
                    let direction = if name == "REF_DATA_FWD" { Up } else { Down };
                    refs.push((parse_index(i), parse_index(j), direction, parse(value)));
                }
                _ => {}
            }
        }
        refs.into_iter()
            .map(|(i, j, direction, actual)| {
                let target = *targets.get(&i).unwrap_or_else(|| panic!("no TGT_DATA[{i}]"));
                Sample {
                    run: j,
                    direction,
                    target_deg: target,
                    readout_deg: target,
                    actual_deg: actual,
                    timestamp_s: None,
                }
            })
            .collect()
    }

    /// Compares every figure to the README's table, to 6 significant digits
    /// (relative 5e-6: half a unit in the sixth digit; no absolute floor, so the
    /// small figures such as B_mean = -5.4e-6 are checked as strictly as the large ones).
    fn check_ecmc(file: &str, want: [f64; 12]) {
        let path = ecmc_dir().join(file);
        if !path.exists() {
            eprintln!("skipped: {} is absent (the shared data sits beside the repository)", path.display());
            return;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let samples = parse_ecmc_dat(&text);
        assert_eq!(samples.len(), 50, "{file}: 5 targets x 5 runs x 2 directions");
        let st = iso230_2(&samples).unwrap();
        assert_eq!(st.runs, 5);
        assert_eq!(st.targets.len(), 5);
        let got = [
            Some(st.a),
            st.a_up,
            st.a_down,
            Some(st.r),
            st.r_up,
            st.r_down,
            st.b,
            st.b_mean,
            Some(st.e),
            st.e_up,
            st.e_down,
            st.m,
        ];
        let names = ["A", "A_up", "A_down", "R", "R_up", "R_down", "B", "B_mean", "E", "E_up", "E_down", "M"];
        for ((name, got), want) in names.iter().zip(got).zip(want) {
            let got = got.unwrap_or_else(|| panic!("{file}: {name} is None"));
            assert!((got - want).abs() <= 5e-6 * want.abs(), "{file}: {name} = {got:.6e}, README says {want:.6e}");
        }
    }

    #[test]
    fn ecmc_fat_sat_matches_the_readme() {
        check_ecmc(
            "fat_sat_ISO230.dat",
            [
                8.88072e-05,
                8.88072e-05,
                6.42824e-05,
                6.8815e-05,
                6.29031e-05,
                5.03269e-05,
                1.22e-05,
                -5.4e-06,
                3.68e-05,
                3.3e-05,
                2.46e-05,
                2.77e-05,
            ],
        );
    }

    #[test]
    fn ecmc_mcu1025_matches_the_readme() {
        check_ecmc(
            "mcu1025_ISO230.dat",
            [
                0.204759,
                0.204759,
                0.0892653,
                0.204759,
                0.204759,
                0.018297,
                0.0434594,
                -0.00718486,
                0.074772,
                0.0461161,
                0.074772,
                0.0480935,
            ],
        );
    }

    #[test]
    fn ecmc_parser_reads_leading_dot_numbers() {
        let s = parse_ecmc_dat("# comment\nUNIT=mm\nTGT_DATA[1]=0.24\nREF_DATA_FWD[1,2]=.2399139810\n");
        assert_eq!(s.len(), 1);
        assert_eq!((s[0].run, s[0].direction, s[0].target_deg), (2, Up, 0.24));
        assert_eq!(s[0].actual_deg, 0.2399139810);
    }

    // ---- Invariances.

    /// A random survey: 2-6 targets on a 30-degree grid, 2-5 runs, deviations within
    /// +-0.1 deg, bidirectional or one direction.
    fn survey() -> impl Strategy<Value = Vec<Sample>> {
        (2usize..=6, 2usize..=5, 0u8..3).prop_flat_map(|(targets, runs, dirs)| {
            let directions: Vec<Direction> = match dirs {
                0 => vec![Up, Down],
                1 => vec![Up],
                _ => vec![Down],
            };
            let n = targets * runs * directions.len();
            prop::collection::vec(-0.1f64..0.1, n).prop_map(move |x| {
                let mut s = Vec::with_capacity(n);
                let mut k = 0;
                for i in 0..targets {
                    for &d in &directions {
                        for j in 0..runs {
                            s.push(sample(j as u32 + 1, d, 30.0 * i as f64, x[k]));
                            k += 1;
                        }
                    }
                }
                s
            })
        })
    }

    /// Equal within 1e-12 relative; the 1e-12 deg floor covers the rounding of
    /// `actual = target + x + c` (targets up to 150 deg: about 3e-14 deg).
    fn near(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
    }

    fn near_opt(a: Option<f64>, b: Option<f64>) -> bool {
        match (a, b) {
            (Some(a), Some(b)) => near(a, b),
            (None, None) => true,
            _ => false,
        }
    }

    proptest! {
        #[test]
        fn the_a_alone_is_the_a_of_the_whole_statistics_bit_for_bit(s in survey(), c in -1e-3f64..1e-3) {
            let groups = TargetGroups::of(&s);
            let actual = |i: usize| s[i].actual_deg + c * (i as f64).sin();
            let whole = iso230_2_with_actual(&s, &groups, actual).map(|st| st.a.to_bits());
            prop_assert_eq!(iso230_2_a_with_actual(&s, &groups, actual).map(f64::to_bits), whole);
        }

        #[test]
        fn invariant_under_sample_order(
            (s, shuffled) in survey().prop_flat_map(|s| (Just(s.clone()), Just(s).prop_shuffle()))
        ) {
            // Groups are sorted by run before summing, so the result is bit-identical.
            prop_assert_eq!(iso230_2(&s).unwrap(), iso230_2(&shuffled).unwrap());
        }

        #[test]
        fn a_constant_shift_moves_only_the_means(s in survey(), c in -1.0f64..1.0) {
            let base = iso230_2(&s).unwrap();
            let moved: Vec<Sample> = s.iter().map(|x| Sample { actual_deg: x.actual_deg + c, ..*x }).collect();
            let st = iso230_2(&moved).unwrap();
            for (name, a, b) in [("A", base.a, st.a), ("R", base.r, st.r), ("E", base.e, st.e)] {
                prop_assert!(near(a, b), "{} {} vs {}", name, a, b);
            }
            for (name, a, b) in [
                ("A_up", base.a_up, st.a_up), ("A_down", base.a_down, st.a_down),
                ("R_up", base.r_up, st.r_up), ("R_down", base.r_down, st.r_down),
                ("B", base.b, st.b), ("B_mean", base.b_mean, st.b_mean),
                ("E_up", base.e_up, st.e_up), ("E_down", base.e_down, st.e_down), ("M", base.m, st.m),
            ] {
                prop_assert!(near_opt(a, b), "{} {:?} vs {:?}", name, a, b);
            }
            prop_assert_eq!(base.runs, st.runs);
            for (t0, t1) in base.targets.iter().zip(&st.targets) {
                prop_assert!(near(t0.r, t1.r));
                prop_assert!(near_opt(t0.b, t1.b));
                prop_assert!(near_opt(t0.mean_bi.map(|m| m + c), t1.mean_bi));
                for (d0, d1) in [(&t0.up, &t1.up), (&t0.down, &t1.down)] {
                    prop_assert_eq!(d0.is_some(), d1.is_some());
                    if let (Some(d0), Some(d1)) = (d0, d1) {
                        prop_assert!(near(d0.mean + c, d1.mean), "mean {} + {} vs {}", d0.mean, c, d1.mean);
                        prop_assert!(near(d0.s, d1.s), "s {} vs {}", d0.s, d1.s);
                    }
                }
            }
        }
    }
}
