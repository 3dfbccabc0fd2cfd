//! The error map: readout error per target, direction and run.
//!
//! Built from paired samples, the map holds for each direction of approach a
//! matrix `runs x targets` of `error = readout - actual` (the contract's sign),
//! the per-target mean and standard deviation across runs, and, for a
//! bidirectional survey, the bidirectional mean `(forward + reverse) / 2` and the
//! hysteresis `forward mean - reverse mean` per target.
//!
//! Targets are grouped as in [`crate::iso230`]: targets within
//! [`crate::iso230::TARGET_TOLERANCE_DEG`] of each other are one target, reported at the
//! smallest of them, in ascending order. The map is complete (no NaN, no hole):
//! every direction that was measured must hold one sample for every run and
//! every target, where the runs are all the runs seen in the survey and the
//! targets all the targets seen in any direction. A missing or repeated sample
//! is an error that names its run, target and direction.
//!
//! [`Coverage`] says whether the targets sample a full revolution uniformly
//! (spacing `360 / N` within [`SPACING_TOLERANCE_DEG`]; the spectrum is then a
//! plain DFT in cycles per revolution) or a partial range such as an elevation
//! axis from -10 to 90 deg (analysed by least squares at the design frequencies).

use crate::iso230::TargetGroups;
use crate::types::{Direction, Sample};
use serde::Serialize;

/// Consecutive targets whose spacing is within this of `360 / N` (degrees)
/// are uniformly spaced.
pub const SPACING_TOLERANCE_DEG: f64 = 1e-6;

/// What part of a revolution the targets cover.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Coverage {
    /// `n` targets uniformly spaced by `360 / n` over a full revolution,
    /// starting at the first (smallest) target.
    FullCircle {
        /// Number of targets per revolution.
        n: usize,
    },
    /// Targets over a part of a revolution (or a full one sampled unevenly,
    /// or with both 0 and 360 as targets).
    Partial {
        /// The smallest target, degrees.
        start: f64,
        /// The largest target, degrees.
        end: f64,
        /// The mean spacing `(end - start) / (N - 1)`, degrees (0 for one target);
        /// [`ErrorMap::uniform_spacing`] says whether every spacing equals it.
        step: f64,
    },
}

impl Coverage {
    /// Classify sorted, distinct targets; also returns whether the spacing is
    /// uniform (within [`SPACING_TOLERANCE_DEG`]).
    pub fn of_targets(targets_deg: &[f64]) -> (Coverage, bool) {
        let n = targets_deg.len();
        if n < 2 {
            let t = targets_deg.first().copied().unwrap_or(0.0);
            return (Coverage::Partial { start: t, end: t, step: 0.0 }, true);
        }
        let (start, end) = (targets_deg[0], targets_deg[n - 1]);
        let step = (end - start) / (n - 1) as f64;
        let uniform_at =
            |spacing: f64| targets_deg.windows(2).all(|w| ((w[1] - w[0]) - spacing).abs() <= SPACING_TOLERANCE_DEG);
        if uniform_at(360.0 / n as f64) {
            (Coverage::FullCircle { n }, true)
        } else {
            (Coverage::Partial { start, end, step }, uniform_at(step))
        }
    }
}

/// The errors of one direction of approach.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DirectionErrors {
    /// The direction of approach.
    pub direction: Direction,
    /// `errors_deg[r][i]`: `readout - actual` of run `runs[r]` at target `targets_deg[i]`
    /// (the runs and targets of the [`ErrorMap`]).
    pub errors_deg: Vec<Vec<f64>>,
    /// Mean over runs, per target.
    pub mean_deg: Vec<f64>,
    /// Sample standard deviation over runs (`n - 1`), per target; `None` with one run.
    pub sd_deg: Option<Vec<f64>>,
}

/// Readout error per target, direction and run. See the module documentation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ErrorMap {
    /// Targets, ascending, degrees.
    pub targets_deg: Vec<f64>,
    /// Run numbers, ascending: the row order of every error matrix.
    pub runs: Vec<u32>,
    /// Full circle or partial range.
    pub coverage: Coverage,
    /// Whether consecutive targets are evenly spaced (always true for a full circle).
    pub uniform_spacing: bool,
    /// Forward approaches, if measured.
    pub forward: Option<DirectionErrors>,
    /// Reverse approaches, if measured.
    pub reverse: Option<DirectionErrors>,
    /// `(forward mean + reverse mean) / 2` per target; `None` unless bidirectional.
    pub bidirectional_mean_deg: Option<Vec<f64>>,
    /// Hysteresis `forward mean - reverse mean` per target; `None` unless bidirectional.
    pub hysteresis_deg: Option<Vec<f64>>,
}

/// Why an error map cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ErrorMapError {
    /// There is nothing to map.
    #[error("no samples: the error map needs at least one sample")]
    NoSamples,
    /// An angle of a sample is NaN or infinite.
    #[error("sample {index} (run {run}, {direction}): {field} is {value}, not a finite number")]
    NonFinite {
        /// Position of the sample in the input slice (from 0).
        index: usize,
        /// Its run.
        run: u32,
        /// Its direction.
        direction: Direction,
        /// `target_deg`, `readout_deg` or `actual_deg`.
        field: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A run has no sample at a target in a direction that was measured.
    #[error(
        "run {run}, target {target_deg} deg, {direction}: no sample (every run needs one sample per target in each measured direction)"
    )]
    MissingSample {
        /// The run without a sample.
        run: u32,
        /// The target, degrees.
        target_deg: f64,
        /// The direction.
        direction: Direction,
    },
    /// A run has more than one sample at a target in a direction.
    #[error("run {run}, target {target_deg} deg, {direction}: {count} samples (each run gives one sample per target)")]
    DuplicateSample {
        /// The run.
        run: u32,
        /// The target, degrees.
        target_deg: f64,
        /// The direction.
        direction: Direction,
        /// How many samples carry it.
        count: usize,
    },
}

/// The runs of `samples`, ascending: a few, inserted in order as they
/// first appear (a survey stores a run's samples together, so a sample's run
/// is almost always the last one's). Not a `BTreeSet` collected: that sorts
/// a vector of every sample's run first.
fn distinct_runs(samples: &[Sample]) -> Vec<u32> {
    let mut runs: Vec<u32> = Vec::new();
    let mut last = None;
    for s in samples {
        if last != Some(s.run) {
            last = Some(s.run);
            if let Err(place) = runs.binary_search(&s.run) {
                runs.insert(place, s.run);
            }
        }
    }
    runs
}

impl ErrorMap {
    /// Build the error map of a survey. Samples may come in any order.
    pub fn from_samples(samples: &[Sample]) -> Result<Self, ErrorMapError> {
        Self::from_grouped(samples, &TargetGroups::of(samples))
    }

    /// [`ErrorMap::from_samples`] with the samples' grouping by target made
    /// already ([`TargetGroups::of`] `samples`).
    pub fn from_grouped(samples: &[Sample], groups: &TargetGroups) -> Result<Self, ErrorMapError> {
        for (index, s) in samples.iter().enumerate() {
            for (field, value) in
                [("target_deg", s.target_deg), ("readout_deg", s.readout_deg), ("actual_deg", s.actual_deg)]
            {
                if !value.is_finite() {
                    return Err(ErrorMapError::NonFinite { index, run: s.run, direction: s.direction, field, value });
                }
            }
        }
        Self::of_errors(samples, groups, |i| samples[i].error_deg())
    }

    /// [`ErrorMap::from_grouped`] of `samples` with each error replaced by
    /// `errors[i]`: of the samples with `readout_deg = errors[i]` and
    /// `actual_deg = 0` (a residual), without a copy of them made.
    pub fn from_grouped_errors(
        samples: &[Sample],
        groups: &TargetGroups,
        errors: &[f64],
    ) -> Result<Self, ErrorMapError> {
        assert_eq!(samples.len(), errors.len(), "an error a sample");
        for (index, (s, &e)) in samples.iter().zip(errors).enumerate() {
            for (field, value) in [("target_deg", s.target_deg), ("readout_deg", e)] {
                if !value.is_finite() {
                    return Err(ErrorMapError::NonFinite { index, run: s.run, direction: s.direction, field, value });
                }
            }
        }
        // `e - 0.0` is `e` to the bit.
        Self::of_errors(samples, groups, |i| errors[i])
    }

    /// The map of `samples` (checked finite) with sample `i`'s error `error(i)`.
    fn of_errors(
        samples: &[Sample],
        groups: &TargetGroups,
        error: impl Fn(usize) -> f64,
    ) -> Result<Self, ErrorMapError> {
        if samples.is_empty() {
            return Err(ErrorMapError::NoSamples);
        }
        // A target is its group's smallest.
        let mut targets_deg: Vec<f64> = Vec::with_capacity(groups.len());
        let mut target_of = vec![0u32; samples.len()];
        for (t, group) in (0..).zip(groups.iter()) {
            targets_deg.push(samples[group[0] as usize].target_deg);
            group.iter().for_each(|&i| target_of[i as usize] = t);
        }
        let runs = distinct_runs(samples);
        // A run's row: looked up by its number while the runs are numbered
        // below a million (a survey's from 1: no search a sample), searched
        // for otherwise.
        let slot: Vec<u32> = match runs.last() {
            Some(&last) if last < 1 << 20 => {
                let mut slot = vec![u32::MAX; last as usize + 1];
                for (r, &run) in (0..).zip(&runs) {
                    slot[run as usize] = r;
                }
                slot
            }
            _ => Vec::new(),
        };
        let run_index = |run: u32| match slot.get(run as usize) {
            Some(&r) if r != u32::MAX => r as usize,
            _ => runs.binary_search(&run).expect("every run was collected"),
        };

        let build = |direction: Direction| -> Result<Option<DirectionErrors>, ErrorMapError> {
            if !samples.iter().any(|s| s.direction == direction) {
                return Ok(None);
            }
            // Each run's row of errors, filled in place, and how many samples
            // fell in each cell (saturating: an exact count is made again
            // for the error only). Not a cell of (count, value) each: that
            // was 24 bytes a target and run where a row takes 8.
            let targets = targets_deg.len();
            let mut errors_deg: Vec<Vec<f64>> = vec![vec![f64::NAN; targets]; runs.len()];
            let mut seen = vec![0u8; runs.len() * targets];
            for (i, s) in samples.iter().enumerate().filter(|(_, s)| s.direction == direction) {
                let (r, t) = (run_index(s.run), target_of[i] as usize);
                seen[r * targets + t] = seen[r * targets + t].saturating_add(1);
                errors_deg[r][t] = error(i);
            }
            if let Some(cell) = seen.iter().position(|&n| n != 1) {
                let (r, t) = (cell / targets, cell % targets);
                let (run, target_deg) = (runs[r], targets_deg[t]);
                if seen[cell] == 0 {
                    return Err(ErrorMapError::MissingSample { run, target_deg, direction });
                }
                let count = (0..samples.len())
                    .filter(|&i| {
                        let s = &samples[i];
                        s.direction == direction && s.run == run && target_of[i] as usize == t
                    })
                    .count();
                return Err(ErrorMapError::DuplicateSample { run, target_deg, direction, count });
            }
            Ok(Some(DirectionErrors::new(direction, errors_deg)))
        };
        let forward = build(Direction::Forward)?;
        let reverse = build(Direction::Reverse)?;
        let (bidirectional_mean_deg, hysteresis_deg) = match (&forward, &reverse) {
            (Some(f), Some(r)) => (
                Some(f.mean_deg.iter().zip(&r.mean_deg).map(|(a, b)| (a + b) / 2.0).collect()),
                Some(f.mean_deg.iter().zip(&r.mean_deg).map(|(a, b)| a - b).collect()),
            ),
            _ => (None, None),
        };
        let (coverage, uniform_spacing) = Coverage::of_targets(&targets_deg);
        Ok(ErrorMap {
            targets_deg,
            runs,
            coverage,
            uniform_spacing,
            forward,
            reverse,
            bidirectional_mean_deg,
            hysteresis_deg,
        })
    }

    /// The errors of one direction, if it was measured.
    pub fn direction(&self, direction: Direction) -> Option<&DirectionErrors> {
        match direction {
            Direction::Forward => self.forward.as_ref(),
            Direction::Reverse => self.reverse.as_ref(),
        }
    }

    /// Whether both directions were measured.
    pub fn is_bidirectional(&self) -> bool {
        self.forward.is_some() && self.reverse.is_some()
    }

    /// The error series of each run (rows in the order of [`ErrorMap::runs`]):
    /// the average of forward and reverse of that run for
    /// [`Series::Bidirectional`] (or the one direction measured), else the named
    /// direction. `None` when the named direction was not measured.
    pub fn run_series(&self, series: Series) -> Option<Vec<Vec<f64>>> {
        match series {
            Series::Forward => self.forward.as_ref().map(|d| d.errors_deg.clone()),
            Series::Reverse => self.reverse.as_ref().map(|d| d.errors_deg.clone()),
            Series::Bidirectional => match (&self.forward, &self.reverse) {
                (Some(f), Some(r)) => Some(
                    f.errors_deg
                        .iter()
                        .zip(&r.errors_deg)
                        .map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x + y) / 2.0).collect())
                        .collect(),
                ),
                (Some(one), None) | (None, Some(one)) => Some(one.errors_deg.clone()),
                (None, None) => None,
            },
        }
    }

    /// Pooled standard deviation across runs over every target and measured
    /// direction, degrees (`sqrt` of the mean per-target variance); `None` with one run.
    /// It includes run-to-run offsets and drift.
    pub fn pooled_sd_deg(&self) -> Option<f64> {
        let sds: Vec<&Vec<f64>> =
            [&self.forward, &self.reverse].into_iter().flatten().filter_map(|d| d.sd_deg.as_ref()).collect();
        let count: usize = sds.iter().map(|v| v.len()).sum();
        (count > 0).then(|| (sds.iter().flat_map(|v| v.iter()).map(|s| s * s).sum::<f64>() / count as f64).sqrt())
    }
}

/// Hysteresis run by run: forward minus reverse error per run (rows in the
/// order of [`ErrorMap::runs`]) and target, its mean over the runs and its
/// standard deviation over the runs (`None` with one run).
#[derive(Debug, Clone, PartialEq)]
pub struct RunHysteresis {
    pub runs_deg: Vec<Vec<f64>>,
    pub mean_deg: Vec<f64>,
    pub sd_deg: Option<Vec<f64>>,
}

impl ErrorMap {
    /// The hysteresis of every run; `None` unless both directions were measured.
    pub fn run_hysteresis(&self) -> Option<RunHysteresis> {
        let (f, r) = (self.forward.as_ref()?, self.reverse.as_ref()?);
        let runs: Vec<Vec<f64>> = f
            .errors_deg
            .iter()
            .zip(&r.errors_deg)
            .map(|(a, b)| a.iter().zip(b).map(|(x, y)| x - y).collect())
            .collect();
        let n = runs.len() as f64;
        let targets = self.targets_deg.len();
        let mean: Vec<f64> = (0..targets).map(|i| runs.iter().map(|run| run[i]).sum::<f64>() / n).collect();
        let sd = (runs.len() > 1).then(|| {
            (0..targets)
                .map(|i| (runs.iter().map(|run| (run[i] - mean[i]).powi(2)).sum::<f64>() / (n - 1.0)).sqrt())
                .collect()
        });
        Some(RunHysteresis { runs_deg: runs, mean_deg: mean, sd_deg: sd })
    }
}

/// Which error series of a run the spectral analysis reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Series {
    /// The average of the forward and reverse errors of each run (backlash and
    /// a drift linear in time cancel), or the one direction measured.
    #[default]
    Bidirectional,
    /// Forward approaches only.
    Forward,
    /// Reverse approaches only.
    Reverse,
}

impl DirectionErrors {
    fn new(direction: Direction, errors_deg: Vec<Vec<f64>>) -> Self {
        let runs = errors_deg.len();
        let targets = errors_deg.first().map_or(0, Vec::len);
        let mean_deg: Vec<f64> =
            (0..targets).map(|t| errors_deg.iter().map(|row| row[t]).sum::<f64>() / runs as f64).collect();
        let sd_deg = (runs >= 2).then(|| {
            (0..targets)
                .map(|t| {
                    let ss: f64 = errors_deg.iter().map(|row| (row[t] - mean_deg[t]).powi(2)).sum();
                    (ss / (runs - 1) as f64).sqrt()
                })
                .collect()
        });
        DirectionErrors { direction, errors_deg, mean_deg, sd_deg }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use Direction::{Forward, Reverse};

    fn s(run: u32, direction: Direction, target_deg: f64, error: f64) -> Sample {
        Sample {
            run,
            direction,
            target_deg,
            readout_deg: target_deg + 0.5 * error,
            actual_deg: target_deg - 0.5 * error,
            timestamp_s: None,
        }
    }

    /// 3 targets x 2 runs x 2 directions, hand-computed.
    ///
    /// ```text
    /// forward  run 1: 1, 2, 3   run 2: 3, 2, 1   mean 2, 2, 2   sd sqrt(2), 0, sqrt(2)
    /// reverse  run 1: 0, 0, 0   run 2: 2, 0, -2  mean 1, 0, -1  sd sqrt(2), 0, sqrt(2)
    /// bidirectional mean 1.5, 1, 0.5;  hysteresis 1, 2, 3
    /// ```
    fn case() -> Vec<Sample> {
        let mut v = Vec::new();
        for (run, fwd, rev) in [(1, [1.0, 2.0, 3.0], [0.0, 0.0, 0.0]), (2, [3.0, 2.0, 1.0], [2.0, 0.0, -2.0])] {
            for (i, t) in [0.0, 120.0, 240.0].into_iter().enumerate() {
                v.push(s(run, Forward, t, fwd[i]));
                // Reverse targets a hair off: still the same target.
                v.push(s(run, Reverse, t + 5e-10, rev[i]));
            }
        }
        v.reverse();
        v
    }

    #[test]
    fn run_hysteresis_is_forward_minus_reverse_run_by_run() {
        let m = ErrorMap::from_samples(&case()).unwrap();
        let h = m.run_hysteresis().unwrap();
        assert_eq!(h.runs_deg, vec![vec![1.0, 2.0, 3.0], vec![1.0, 2.0, 3.0]]);
        assert_eq!(h.mean_deg, vec![1.0, 2.0, 3.0]);
        assert_eq!(h.sd_deg, Some(vec![0.0, 0.0, 0.0]));
        let forward: Vec<Sample> = case().into_iter().filter(|s| s.direction == Forward).collect();
        assert_eq!(ErrorMap::from_samples(&forward).unwrap().run_hysteresis(), None);
        let one_run: Vec<Sample> = case().into_iter().filter(|s| s.run == 2).collect();
        let h = ErrorMap::from_samples(&one_run).unwrap().run_hysteresis().unwrap();
        assert_eq!((h.mean_deg, h.sd_deg), (vec![1.0, 2.0, 3.0], None));
    }

    /// Runs numbered beyond the lookup's reach are searched for: the same
    /// map as with small numbers, rows in run order.
    #[test]
    fn runs_of_any_number_find_their_rows() {
        let renumbered: Vec<Sample> =
            case().into_iter().map(|x| Sample { run: if x.run == 1 { 7 } else { 3_000_000_000 }, ..x }).collect();
        let (small, large) = (ErrorMap::from_samples(&case()).unwrap(), ErrorMap::from_samples(&renumbered).unwrap());
        assert_eq!(large.runs, vec![7, 3_000_000_000]);
        assert_eq!(large.forward, small.forward);
        assert_eq!(large.reverse, small.reverse);
    }

    #[test]
    fn hand_computed_map() {
        let m = ErrorMap::from_samples(&case()).unwrap();
        assert_eq!(m.targets_deg, vec![0.0, 120.0, 240.0]);
        assert_eq!(m.runs, vec![1, 2]);
        assert_eq!(m.coverage, Coverage::FullCircle { n: 3 });
        let f = m.forward.as_ref().unwrap();
        assert_eq!(f.errors_deg, vec![vec![1.0, 2.0, 3.0], vec![3.0, 2.0, 1.0]]);
        assert_eq!(f.mean_deg, vec![2.0, 2.0, 2.0]);
        let sd = f.sd_deg.as_ref().unwrap();
        assert!((sd[0] - 2f64.sqrt()).abs() < 1e-15 && sd[1] == 0.0 && (sd[2] - 2f64.sqrt()).abs() < 1e-15);
        let r = m.reverse.as_ref().unwrap();
        assert_eq!(r.mean_deg, vec![1.0, 0.0, -1.0]);
        assert_eq!(m.bidirectional_mean_deg, Some(vec![1.5, 1.0, 0.5]));
        assert_eq!(m.hysteresis_deg, Some(vec![1.0, 2.0, 3.0]));
        assert_eq!(m.run_series(Series::Bidirectional).unwrap(), vec![vec![0.5, 1.0, 1.5], vec![2.5, 1.0, -0.5]]);
        assert_eq!(m.run_series(Series::Reverse).unwrap()[1], vec![2.0, 0.0, -2.0]);
        // Pooled: variances 2, 0, 2 in both directions -> mean 4/3.
        assert!((m.pooled_sd_deg().unwrap() - (4.0f64 / 3.0).sqrt()).abs() < 1e-15);
    }

    #[test]
    fn unidirectional_single_run() {
        let v: Vec<Sample> = (0..4).map(|i| s(7, Reverse, 90.0 * i as f64 - 180.0, i as f64)).collect();
        let m = ErrorMap::from_samples(&v).unwrap();
        assert!(m.forward.is_none() && m.bidirectional_mean_deg.is_none() && m.hysteresis_deg.is_none());
        assert_eq!(m.coverage, Coverage::FullCircle { n: 4 });
        assert_eq!(m.reverse.as_ref().unwrap().sd_deg, None);
        assert_eq!(m.pooled_sd_deg(), None);
        assert_eq!(m.run_series(Series::Bidirectional).unwrap(), vec![vec![0.0, 1.0, 2.0, 3.0]]);
        assert_eq!(m.run_series(Series::Forward), None);
    }

    #[test]
    fn coverage_full_partial_and_uneven() {
        let full: Vec<f64> = (0..720).map(|k| k as f64 * 0.5).collect();
        assert_eq!(Coverage::of_targets(&full), (Coverage::FullCircle { n: 720 }, true));
        let elev: Vec<f64> = (0..=200).map(|k| -10.0 + k as f64 * 0.5).collect();
        let (c, uniform) = Coverage::of_targets(&elev);
        assert!(uniform);
        match c {
            Coverage::Partial { start, end, step } => {
                assert_eq!((start, end), (-10.0, 90.0));
                assert!((step - 0.5).abs() < 1e-12);
            }
            other => panic!("{other:?}"),
        }
        // 0..=360 inclusive is not a full circle of N points.
        let closed: Vec<f64> = (0..=8).map(|k| k as f64 * 45.0).collect();
        assert!(matches!(Coverage::of_targets(&closed).0, Coverage::Partial { .. }));
        let uneven = [0.0, 1.0, 3.0, 4.0];
        assert!(!Coverage::of_targets(&uneven).1);
        // Slightly off the grid but within 1e-6: still a full circle.
        let jitter: Vec<f64> = (0..8).map(|k| k as f64 * 45.0 + if k == 3 { 4e-7 } else { 0.0 }).collect();
        assert_eq!(Coverage::of_targets(&jitter).0, Coverage::FullCircle { n: 8 });
    }

    #[test]
    fn defects_are_named() {
        assert_eq!(ErrorMap::from_samples(&[]), Err(ErrorMapError::NoSamples));
        let mut v = case();
        v.retain(|x| !(x.run == 2 && x.direction == Reverse && x.target_deg > 200.0));
        let e = ErrorMap::from_samples(&v).unwrap_err();
        assert!(matches!(e, ErrorMapError::MissingSample { run: 2, direction: Reverse, .. }), "{e}");
        assert!(e.to_string().contains("run 2, target 240 deg, reverse: no sample"), "{e}");
        let mut v = case();
        v.push(s(1, Forward, 120.0, 9.0));
        let e = ErrorMap::from_samples(&v).unwrap_err();
        assert_eq!(e, ErrorMapError::DuplicateSample { run: 1, target_deg: 120.0, direction: Forward, count: 2 });
        let mut v = case();
        v[3].readout_deg = f64::NAN;
        let e = ErrorMap::from_samples(&v).unwrap_err();
        assert!(matches!(e, ErrorMapError::NonFinite { index: 3, field: "readout_deg", .. }), "{e}");
        // A run present in one direction only is missing from the other.
        let mut v = case();
        v.push(s(3, Forward, 0.0, 0.0));
        assert!(matches!(ErrorMap::from_samples(&v).unwrap_err(), ErrorMapError::MissingSample { run: 3, .. }));
    }

    proptest::proptest! {
        /// The runs found as they first appear are the set of them, in order,
        /// in whatever order the samples come.
        #[test]
        fn distinct_runs_are_the_set_of_runs(runs in proptest::collection::vec(0u32..12, 0..300)) {
            let samples: Vec<Sample> = runs.iter().map(|&run| s(run, Forward, 0.0, 0.0)).collect();
            let set: Vec<u32> = runs.iter().copied().collect::<std::collections::BTreeSet<u32>>().into_iter().collect();
            proptest::prop_assert_eq!(distinct_runs(&samples), set);
        }
    }
}
