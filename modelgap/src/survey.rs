//! The survey as model-gap sees it: per sample its target, run, direction and
//! time in runs, the measured error, and the noise floor.

use super::ModelGapError;
use serde::Serialize;
use survey_processing::errormap::ErrorMap;
use survey_processing::iso230::TargetGroups;
use survey_processing::model::{DriftTime, Model, Systematic};
use survey_processing::types::{Direction, Sample};

/// What the drift's time axis (`runs_elapsed`) is measured in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Timebase {
    /// The samples' timestamps, in units of the mean time from one run's first
    /// sample to the next run's (drift is a function of time, as in the simulator).
    Timestamps,
    /// The acquisition order: the k-th of the `n` samples of run index `r` is at
    /// `r + k / n` runs (the samples carry no timestamps).
    SampleOrder,
}

/// A prepared survey.
#[derive(Debug, Clone)]
pub(crate) struct Survey<'a> {
    /// The survey's samples (borrowed: a copy was 48 bytes a sample).
    pub samples: &'a [Sample],
    /// Their grouping by target, made once: the error map's, and every
    /// residual's (the same targets in the same order).
    pub groups: TargetGroups,
    pub map: ErrorMap,
    /// Per sample: index into `map.targets_deg` (`u32`, as the grouping's).
    pub target: Vec<u32>,
    /// Per sample: index into `map.runs`.
    pub run: Vec<u32>,
    /// Per sample: index into `dirs`.
    pub dir: Vec<u8>,
    /// The measured directions (forward first).
    pub dirs: Vec<Direction>,
    /// Per sample: runs elapsed since the first sample (the time of a ramp).
    pub tau: Vec<f64>,
    /// Per sample: the run's place among the survey's runs, from 0 (the time of a step).
    pub run_index: Vec<f64>,
    /// The reference's zero against the model's axis angle, degrees (see
    /// [`Survey::set_angle_shift`]): a sample's axis angle is its measured
    /// actual angle plus this ([`Survey::angle_at`]; made from the samples
    /// when asked, as the measured error is: [`Survey::y_at`]. Two vectors
    /// of them were 16 bytes a sample at model-gap's peak).
    pub angle_shift_deg: f64,
    pub timebase: Timebase,
    /// Mean run duration, seconds (with timestamps).
    pub run_duration_s: Option<f64>,
}

impl<'a> Survey<'a> {
    pub fn prepare(samples: &'a [Sample]) -> Result<Self, ModelGapError> {
        let groups = TargetGroups::of(samples);
        let map = ErrorMap::from_grouped(samples, &groups)?;
        let dirs: Vec<Direction> =
            [Direction::Forward, Direction::Reverse].into_iter().filter(|d| map.direction(*d).is_some()).collect();
        // A sample's target is its group's: the map's targets are the
        // groups' smallest, in the groups' order.
        let mut target = vec![0u32; samples.len()];
        for (t, group) in (0..).zip(groups.iter()) {
            group.iter().for_each(|&i| target[i as usize] = t);
        }
        let run: Vec<u32> =
            samples.iter().map(|s| map.runs.binary_search(&s.run).expect("every run is in the map") as u32).collect();
        let dir: Vec<u8> =
            samples.iter().map(|s| dirs.iter().position(|d| *d == s.direction).expect("measured") as u8).collect();
        let (tau, timebase, run_duration_s) = time_in_runs(samples, &run, map.runs.len());
        let run_index = run.iter().map(|&r| f64::from(r)).collect();
        Ok(Survey {
            samples,
            groups,
            map,
            target,
            run,
            dir,
            dirs,
            tau,
            run_index,
            angle_shift_deg: 0.0,
            timebase,
            run_duration_s,
        })
    }

    /// The zero reference is an angle as well as a constant: a reference whose
    /// zero sits `c` degrees from the positioner's own zero measures `actual =
    /// theta + c` and an error `y = e(theta) - c`, so the constant fitted
    /// between model and data (`offset = -c`) also says where the model's
    /// angle is: `theta = actual + offset`. The model is evaluated there.
    /// (With a tracker, the engine sets the zero so the mean error at the
    /// locate points is 0; they are all approached forward, so `c` is about
    /// half the backlash, 0.004 deg on the Figure 8 positioner: evaluated at
    /// the measured angle, its 20-cycle gear pass would show a false phase
    /// change of 20 x 0.004 deg, 1.1e-5 deg, which model-gap names on a survey
    /// of 36000 points.)
    pub fn set_angle_shift(&mut self, shift_deg: f64) {
        self.angle_shift_deg = shift_deg;
    }

    /// Sample `i`'s axis angle, the model's: its measured actual angle
    /// plus the shift of the zero reference, degrees.
    pub fn angle_at(&self, i: usize) -> f64 {
        self.samples[i].actual_deg + self.angle_shift_deg
    }

    /// Every sample's axis angle ([`Survey::angle_at`]), in order.
    pub fn angles(&self) -> impl Iterator<Item = f64> + '_ {
        self.samples.iter().map(|s| s.actual_deg + self.angle_shift_deg)
    }

    /// Sample `i`'s measured error `readout - actual`.
    pub fn y_at(&self, i: usize) -> f64 {
        self.samples[i].error_deg()
    }

    /// Every sample's measured error ([`Survey::y_at`]), in order.
    pub fn ys(&self) -> impl Iterator<Item = f64> + '_ {
        self.samples.iter().map(Sample::error_deg)
    }

    /// [`Survey::prepare`], with the zero reference's angle found against
    /// `model` (two passes: the second changes it by the model's slope times
    /// the first's change, far below anything measurable).
    pub fn prepare_for(samples: &'a [Sample], model: &Model) -> Result<Self, ModelGapError> {
        let mut s = Survey::prepare(samples)?;
        for _ in 0..2 {
            let offset = s.offset(model);
            s.set_angle_shift(offset);
        }
        Ok(s)
    }

    /// Sample `i`'s time for the drift.
    pub fn drift_time(&self, i: usize) -> DriftTime {
        DriftTime { runs_elapsed: self.tau[i], run_index: self.run_index[i] }
    }

    pub fn len(&self) -> usize {
        self.samples.len()
    }

    pub fn runs(&self) -> usize {
        self.map.runs.len()
    }

    pub fn targets(&self) -> usize {
        self.map.targets_deg.len()
    }

    /// The mean of `residual` (one value per sample) at each target, and how
    /// many samples each mean holds (a target without samples: NaN, 0).
    pub fn target_means(&self, residual: &[f64]) -> (Vec<f64>, Vec<usize>) {
        let t = self.targets();
        let mut sum = vec![0.0; t];
        let mut count = vec![0usize; t];
        for (i, r) in residual.iter().enumerate() {
            sum[self.target[i] as usize] += r;
            count[self.target[i] as usize] += 1;
        }
        let mean = sum.iter().zip(&count).map(|(a, c)| a / *c as f64).collect();
        (mean, count)
    }

    pub fn bidirectional(&self) -> bool {
        self.dirs.len() == 2
    }

    pub fn direction(&self, i: usize) -> Direction {
        self.dirs[usize::from(self.dir[i])]
    }

    /// The model's systematic error at every sample: at the axis angle (the
    /// simulators' convention `readout = actual + e(actual)`; the measured
    /// actual angle with the zero reference's shift), in the sample's
    /// direction, at its time (a ramp by `tau`, a step by the run).
    pub fn predict(&self, model: &Model) -> Vec<f64> {
        let model = model.systematic();
        (0..self.len()).map(|i| model.at(self.angle_at(i), self.direction(i), self.drift_time(i))).collect()
    }

    /// `y - model` at sample `i`.
    fn gap_at(&self, model: &Systematic, i: usize) -> f64 {
        self.y_at(i) - model.at(self.angle_at(i), self.direction(i), self.drift_time(i))
    }

    /// `y - model`, with the constant offset (zero reference) removed; returns the offset too.
    pub fn residual(&self, model: &Model) -> (Vec<f64>, f64) {
        let model = model.systematic();
        let mut r: Vec<f64> = (0..self.len()).map(|i| self.gap_at(&model, i)).collect();
        let offset = r.iter().sum::<f64>() / r.len() as f64;
        r.iter_mut().for_each(|v| *v -= offset);
        (r, offset)
    }

    /// The offset of [`Survey::residual`] alone (the same sum, to the bit),
    /// with no vector of the residual.
    pub fn offset(&self, model: &Model) -> f64 {
        let model = model.systematic();
        (0..self.len()).map(|i| self.gap_at(&model, i)).sum::<f64>() / self.len() as f64
    }

    /// The noise floor from the two-way layout runs x cells (cell = target and
    /// direction): the interaction residual `y - run mean - cell mean + grand
    /// mean`. Anything that is the same in every run (the repeatable error,
    /// whatever the model says) and anything that moves a whole run (offsets,
    /// and a drift linear in time when the runs follow the same schedule) is
    /// removed, so what is left is the non-repeatable random part.
    /// `None` with one run (or one cell).
    pub fn anova_noise(&self) -> Option<(f64, usize)> {
        let (r, c) = (self.runs(), self.targets() * self.dirs.len());
        if r < 2 || c < 2 {
            return None;
        }
        let mut cells = vec![0.0; r * c];
        for i in 0..self.len() {
            cells[self.run[i] as usize * c + self.target[i] as usize * self.dirs.len() + usize::from(self.dir[i])] =
                self.y_at(i);
        }
        let run_mean: Vec<f64> = (0..r).map(|k| cells[k * c..(k + 1) * c].iter().sum::<f64>() / c as f64).collect();
        let cell_mean: Vec<f64> = (0..c).map(|j| (0..r).map(|k| cells[k * c + j]).sum::<f64>() / r as f64).collect();
        let grand = run_mean.iter().sum::<f64>() / r as f64;
        let ss: f64 = (0..r)
            .flat_map(|k| (0..c).map(move |j| (k, j)))
            .map(|(k, j)| (cells[k * c + j] - run_mean[k] - cell_mean[j] + grand).powi(2))
            .sum();
        let dof = (r - 1) * (c - 1);
        Some(((ss / dof as f64).sqrt(), dof))
    }
}

/// Runs elapsed at every sample, from the timestamps when every sample has one
/// (and they span some time), else from the acquisition order.
fn time_in_runs(samples: &[Sample], run: &[u32], runs: usize) -> (Vec<f64>, Timebase, Option<f64>) {
    let stamps: Option<Vec<f64>> = samples.iter().map(|s| s.timestamp_s.filter(|t| t.is_finite())).collect();
    if let Some(t) = stamps {
        let t0 = t.iter().copied().fold(f64::INFINITY, f64::min);
        let t1 = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let duration = if runs >= 2 {
            let mut start = vec![f64::INFINITY; runs];
            for (i, &ti) in t.iter().enumerate() {
                start[run[i] as usize] = start[run[i] as usize].min(ti);
            }
            (start[runs - 1] - start[0]) / (runs - 1) as f64
        } else if samples.len() >= 2 {
            (t1 - t0) * samples.len() as f64 / (samples.len() - 1) as f64
        } else {
            0.0
        };
        if duration > 0.0 && duration.is_finite() {
            return (t.iter().map(|ti| (ti - t0) / duration).collect(), Timebase::Timestamps, Some(duration));
        }
    }
    let mut count = vec![0usize; runs];
    for &r in run {
        count[r as usize] += 1;
    }
    let mut seen = vec![0usize; runs];
    let tau = run
        .iter()
        .map(|&r| {
            let r = r as usize;
            let k = seen[r];
            seen[r] += 1;
            r as f64 + k as f64 / count[r] as f64
        })
        .collect();
    (tau, Timebase::SampleOrder, None)
}
