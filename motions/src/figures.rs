//! ISO 230-7's figures of one motion (a deviation at every sample), their
//! expanded uncertainties and the detection limit.
//!
//! Per direction, the samples grouped by target, each group one reading per
//! run: total = max - min of every reading; synchronous = max - min of the
//! groups' means; asynchronous = the largest max - min within a group. The
//! larger of the two directions' is reported.
//!
//! `U` (k = 2), stated as bounds that hold together at about 95 %:
//! - the tracker's systematic error: its transverse MPE `e_T` at the
//!   farthest SMR's distance (`TransverseMpe::at_um`) bounds what it adds to
//!   a total or synchronous figure (the same at a place of the circle every
//!   run, it cannot add to the asynchronous one);
//! - its random error, `sigma` per coordinate (the AT-class typical: 1.5
//!   urad of each angle at the distance, at least 1 um): every one of the `M`
//!   readings of a direction lies within `z sigma` of its truth at 95 % with
//!   `z` the two-sided normal quantile of `0.05 / M`, so the random part moves
//!   a peak-to-valley by at most `r = 2 z sigma`;
//! - the synchronous curve is a mean of the runs: what scatters from run to
//!   run (the tracker's noise and the axis's own asynchronous motion) moves
//!   it by at most `2 z s / sqrt(runs)`, `s` the larger of `sigma` and the
//!   scatter measured within the targets (pooled);
//! - total: `U = sqrt(e_T^2 + r^2)`; synchronous: `U = sqrt(e_T^2 + (2 z s /
//!   sqrt(runs))^2)`; asynchronous: `U = r`.
//!
//! The detection limit is the larger of `e_T` (the issue's "about its
//! transverse error at that distance") and `r`, what the tracker's random
//! error alone can make of a peak-to-valley: a figure below it is `None`,
//! "below the detection limit". A motion made of several SMRs' deviations,
//! `sum w_k d_k`, has its bounds scaled ([`Scale`]): the systematic one by
//! `sum |w_k|` (the tracker's error at the SMRs' places is not independent:
//! the bounds add), the random one by `sqrt(sum w_k^2)` (independent
//! readings). The tilt from two heights keeps its own scaling: every bound by
//! `sqrt(2) / dh`, the two SMRs' bounds added in quadrature.

use crate::direction_name;
use std::collections::BTreeMap;
use survey_processing::special::normal_two_sided_isf;
use survey_processing::tracker_errors::{TYPICAL_ANGLE_NOISE_URAD, TYPICAL_RANGE_NOISE_UM, TransverseMpe};
use survey_processing::{Direction, Sample};

/// The figures of one motion: `None` below the detection limit.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Block {
    pub total: Option<f64>,
    pub synchronous: Option<f64>,
    pub asynchronous: Option<f64>,
    /// The expanded uncertainty (k = 2) of any of the three: the largest of
    /// theirs.
    pub u: f64,
    /// Whether a figure is below the detection limit (then `None`).
    pub below_detection_limit: bool,
    /// Which figures are below it.
    pub below_limit: Vec<&'static str>,
    /// The detection limit in the block's unit.
    pub detection_limit: f64,
    /// Each figure's own `U` (k = 2).
    pub u_total: f64,
    pub u_synchronous: f64,
    pub u_asynchronous: f64,
}

/// The synchronous motions at one target in one direction.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PolarPoint {
    pub target_deg: f64,
    pub direction: &'static str,
    pub radial_um: f64,
    pub axial_um: f64,
    pub tilt_urad: Option<f64>,
    /// The tilt at 90 degrees to the first SMR's radial direction, urad.
    pub tilt_across_urad: Option<f64>,
    /// The axial motion on the axis (SMRs at several phases), um.
    pub axial_on_axis_um: Option<f64>,
}

/// How a motion's bounds scale from one SMR's deviation's (see the module
/// documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Scale {
    /// Of the tracker's systematic error (its MPE).
    pub systematic: f64,
    /// Of its random error.
    pub random: f64,
}

impl Scale {
    /// Both bounds scaled alike.
    pub(crate) fn both(s: f64) -> Self {
        Scale { systematic: s, random: s }
    }

    /// The scaling of `sum w_k d_k`.
    pub(crate) fn of_weights(w: &[f64]) -> Self {
        Scale { systematic: w.iter().map(|x| x.abs()).sum(), random: w.iter().map(|x| x * x).sum::<f64>().sqrt() }
    }
}

/// One target's sample indices (one a run), with the target.
type Target = (f64, Vec<usize>);

/// The samples grouped by direction and target, and the tracker's bounds.
#[derive(Debug)]
pub struct Figures {
    /// Per direction: each target's sample indices (one a run), in target order.
    groups: Vec<(Direction, Vec<Target>)>,
    runs: usize,
    e_t_um: f64,
    sigma_um: f64,
}

/// Peak-to-valley of `values` (0 for none).
fn spread(values: impl Iterator<Item = f64>) -> f64 {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if hi >= lo { hi - lo } else { 0.0 }
}

impl Figures {
    /// The groups of `samples`; the bounds of a tracker of `mpe` whose
    /// farthest SMR is `farthest_mm` away.
    pub(crate) fn new(samples: &[Sample], mpe: TransverseMpe, farthest_mm: f64) -> Self {
        let mut by: BTreeMap<(bool, i64), (f64, Vec<usize>)> = BTreeMap::new();
        for (i, s) in samples.iter().enumerate() {
            let key = (s.direction == Direction::Reverse, (s.target_deg * 1e6).round() as i64);
            by.entry(key).or_insert_with(|| (s.target_deg, Vec::new())).1.push(i);
        }
        let mut groups: Vec<(Direction, Vec<Target>)> = Vec::new();
        for ((reverse, _), g) in by {
            let d = if reverse { Direction::Reverse } else { Direction::Forward };
            match groups.last_mut() {
                Some((last, list)) if *last == d => list.push(g),
                _ => groups.push((d, vec![g])),
            }
        }
        let runs = samples.iter().map(|s| s.run).collect::<std::collections::BTreeSet<_>>().len();
        let sigma_um = (TYPICAL_ANGLE_NOISE_URAD * farthest_mm * 1e-3).max(TYPICAL_RANGE_NOISE_UM);
        Figures { groups, runs, e_t_um: mpe.at_um(farthest_mm), sigma_um }
    }

    /// The survey's runs.
    pub(crate) fn runs(&self) -> usize {
        self.runs
    }

    /// The tracker's systematic bound `e_T`, um.
    pub(crate) fn e_t_um(&self) -> f64 {
        self.e_t_um
    }

    /// The figures of `values` (one a sample), the bounds scaled by `scale`
    /// (1 for one SMR's um; `sqrt(2) / dh` for a tilt from two heights, urad).
    pub(crate) fn block(&self, values: &[f64], scale: Scale) -> Block {
        let (mut total, mut sync, mut asynchronous, mut readings) = (0.0f64, 0.0f64, None::<f64>, 0usize);
        let (mut squares, mut freedom) = (0.0f64, 0usize);
        for (_, list) in &self.groups {
            total = total.max(spread(list.iter().flat_map(|(_, ix)| ix.iter().map(|&i| values[i]))));
            let mean = |ix: &[usize]| ix.iter().map(|&i| values[i]).sum::<f64>() / ix.len() as f64;
            sync = sync.max(spread(list.iter().map(|(_, ix)| mean(ix))));
            for (_, ix) in list.iter().filter(|(_, ix)| ix.len() > 1) {
                asynchronous = Some(asynchronous.unwrap_or(0.0).max(spread(ix.iter().map(|&i| values[i]))));
                let m = mean(ix);
                squares += ix.iter().map(|&i| (values[i] - m).powi(2)).sum::<f64>();
                freedom += ix.len() - 1;
            }
            readings = readings.max(list.iter().map(|(_, ix)| ix.len()).sum());
        }
        let z = normal_two_sided_isf(0.05 / readings.max(1) as f64);
        let random = 2.0 * z * self.sigma_um * scale.random;
        let scatter = if freedom > 0 { (squares / freedom as f64).sqrt() } else { 0.0 };
        let of_means = 2.0 * z * (self.sigma_um * scale.random).max(scatter) / (self.runs.max(1) as f64).sqrt();
        let e_t = self.e_t_um * scale.systematic;
        let u_total = e_t.hypot(random);
        let u_synchronous = e_t.hypot(of_means);
        let u_asynchronous = random;
        let limit = e_t.max(random);
        let mut below_limit = Vec::new();
        let mut kept = |name: &'static str, v: Option<f64>| match v {
            Some(v) if v >= limit => Some(v),
            Some(_) => {
                below_limit.push(name);
                None
            }
            None => None,
        };
        let (total, synchronous, asynchronous) =
            (kept("total", Some(total)), kept("synchronous", Some(sync)), kept("asynchronous", asynchronous));
        Block {
            total,
            synchronous,
            asynchronous,
            u: u_total.max(u_synchronous).max(u_asynchronous),
            below_detection_limit: !below_limit.is_empty(),
            below_limit,
            detection_limit: limit,
            u_total,
            u_synchronous,
            u_asynchronous,
        }
    }

    /// The synchronous motions per target and direction, every n-th target
    /// beyond [`crate::POLAR_POINTS`] a direction.
    pub(crate) fn polar(
        &self,
        radial: &[f64],
        axial: &[f64],
        tilt: Option<&[f64]>,
        across: Option<&[f64]>,
        on_axis: Option<&[f64]>,
    ) -> Vec<PolarPoint> {
        let mean = |v: &[f64], ix: &[usize]| ix.iter().map(|&i| v[i]).sum::<f64>() / ix.len() as f64;
        let mut out = Vec::new();
        for (d, list) in &self.groups {
            let step = list.len().div_ceil(crate::POLAR_POINTS).max(1);
            for (target_deg, ix) in list.iter().step_by(step) {
                out.push(PolarPoint {
                    target_deg: *target_deg,
                    direction: direction_name(*d),
                    radial_um: mean(radial, ix),
                    axial_um: mean(axial, ix),
                    tilt_urad: tilt.map(|t| mean(t, ix)),
                    tilt_across_urad: across.map(|t| mean(t, ix)),
                    axial_on_axis_um: on_axis.map(|a| mean(a, ix)),
                });
            }
        }
        out
    }
}
