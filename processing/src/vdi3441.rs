//! VDI/DGQ 3441 positioning figures, computed from the same per-target
//! statistics as ISO 230-2 ([`crate::iso230`]).
//!
//! No public text of VDI/DGQ 3441 (1977) was found. The definitions used are
//! the ones usually reproduced from it (and written down in the project's
//! references), with `x̄↑_j`, `x̄↓_j` the mean positioning deviations
//! (`actual - target`) of target `j` approached forward and in reverse over
//! the runs, and `s↑_j`, `s↓_j` their sample standard deviations (`n - 1`):
//!
//! - `x̄_j = (x̄↑_j + x̄↓_j) / 2`, the mean position deviation of target `j`;
//! - `U_j = |x̄↑_j - x̄↓_j|`, the reversal span; `U = max_j U_j`;
//! - `Ps_j = 6 (s↑_j + s↓_j) / 2`, the positional scatter; `Ps = max_j Ps_j`;
//! - `Pa = max_j x̄_j - min_j x̄_j`, the position deviation;
//! - `P = max_j [x̄_j + (U_j + Ps_j) / 2] - min_j [x̄_j - (U_j + Ps_j) / 2]`,
//!   the positional uncertainty.
//!
//! For a survey measured in one direction there is no reversal: `U_j` is not
//! defined (the axis `U` is `None`), `x̄_j` is the one direction's mean,
//! `Ps_j = 6 s_j`, and `P` uses `U_j = 0`. Note the `6 s` (that is `±3 s`)
//! where ISO 230-2 since 1997 uses `4 s` (`±2 s`).

use crate::iso230::Iso230;
use serde::Serialize;

/// The VDI/DGQ 3441 figures of one target, degrees.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VdiTarget {
    /// The target, degrees.
    pub target_deg: f64,
    /// Mean position deviation `x̄_j`.
    pub mean_deg: f64,
    /// Reversal span `U_j` (`None` in a unidirectional survey).
    #[serde(rename = "U_deg")]
    pub u_deg: Option<f64>,
    /// Positional scatter `Ps_j`.
    #[serde(rename = "Ps_deg")]
    pub ps_deg: f64,
}

/// The VDI/DGQ 3441 figures of an axis, degrees. See the module documentation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Vdi3441 {
    /// Positional uncertainty `P`.
    #[serde(rename = "P_deg")]
    pub p_deg: f64,
    /// Position deviation `Pa`.
    #[serde(rename = "Pa_deg")]
    pub pa_deg: f64,
    /// Largest positional scatter `Ps = max Ps_j`.
    #[serde(rename = "Ps_deg")]
    pub ps_deg: f64,
    /// Largest reversal span `U = max U_j` (`None` in a unidirectional survey).
    #[serde(rename = "U_deg")]
    pub u_deg: Option<f64>,
    /// Mean reversal span `Ū = mean U_j` (`None` in a unidirectional survey).
    #[serde(rename = "U_mean_deg")]
    pub u_mean_deg: Option<f64>,
    /// Per target, ascending.
    pub targets: Vec<VdiTarget>,
}

/// The VDI/DGQ 3441 figures of the per-target statistics `iso` (see the
/// module documentation for the definitions).
pub fn vdi3441(iso: &Iso230) -> Vdi3441 {
    let targets: Vec<VdiTarget> = iso
        .targets
        .iter()
        .filter_map(|t| {
            let (mean_deg, u_deg, ps_deg) = match (&t.up, &t.down) {
                (Some(u), Some(d)) => ((u.mean + d.mean) / 2.0, Some((u.mean - d.mean).abs()), 3.0 * (u.s + d.s)),
                (Some(one), None) | (None, Some(one)) => (one.mean, None, 6.0 * one.s),
                (None, None) => return None,
            };
            Some(VdiTarget { target_deg: t.target_deg, mean_deg, u_deg, ps_deg })
        })
        .collect();
    let max = |it: &mut dyn Iterator<Item = f64>| it.fold(f64::NEG_INFINITY, f64::max);
    let min = |it: &mut dyn Iterator<Item = f64>| it.fold(f64::INFINITY, f64::min);
    let half_band = |t: &VdiTarget| (t.u_deg.unwrap_or(0.0) + t.ps_deg) / 2.0;
    let p_deg = max(&mut targets.iter().map(|t| t.mean_deg + half_band(t)))
        - min(&mut targets.iter().map(|t| t.mean_deg - half_band(t)));
    let pa_deg = max(&mut targets.iter().map(|t| t.mean_deg)) - min(&mut targets.iter().map(|t| t.mean_deg));
    let ps_deg = max(&mut targets.iter().map(|t| t.ps_deg));
    let spans: Vec<f64> = targets.iter().filter_map(|t| t.u_deg).collect();
    let (u_deg, u_mean_deg) = if spans.is_empty() || spans.len() != targets.len() {
        (None, None)
    } else {
        (Some(max(&mut spans.iter().copied())), Some(spans.iter().sum::<f64>() / spans.len() as f64))
    };
    Vdi3441 { p_deg, pa_deg, ps_deg, u_deg, u_mean_deg, targets }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::iso230::iso230_2;
    use crate::{Direction, Sample};

    fn sample(run: u32, direction: Direction, target: f64, deviation: f64) -> Sample {
        Sample {
            run,
            direction,
            target_deg: target,
            readout_deg: target,
            actual_deg: target + deviation,
            timestamp_s: None,
        }
    }

    /// Two targets, three runs each way, deviations chosen so every figure
    /// is worked out by hand below.
    ///
    /// Target 0: forward 1, 2, 3 (mean 2, s 1); reverse -1, 0, 1 (mean 0, s 1).
    /// Target 10: forward 4, 6, 8 (mean 6, s 2); reverse 2, 2, 2 (mean 2, s 0).
    ///
    /// x̄: 1 and 4. U: 2 and 4. Ps = 3 (s↑ + s↓): 6 and 6.
    /// Pa = 4 - 1 = 3. U = 4, Ū = 3. Ps = 6.
    /// P = max(1 + (2 + 6)/2, 4 + (4 + 6)/2) - min(1 - 4, 4 - 5) = 9 - (-3) = 12.
    #[test]
    fn a_hand_computed_bidirectional_case() {
        let (f, r) = (Direction::Forward, Direction::Reverse);
        let mut samples = Vec::new();
        for (run, (a, b, c, d)) in
            [(1.0, -1.0, 4.0, 2.0), (2.0, 0.0, 6.0, 2.0), (3.0, 1.0, 8.0, 2.0)].iter().enumerate()
        {
            let run = run as u32 + 1;
            samples.push(sample(run, f, 0.0, *a));
            samples.push(sample(run, r, 0.0, *b));
            samples.push(sample(run, f, 10.0, *c));
            samples.push(sample(run, r, 10.0, *d));
        }
        let v = vdi3441(&iso230_2(&samples).unwrap());
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        assert_eq!(v.targets.len(), 2);
        assert!(close(v.targets[0].mean_deg, 1.0) && close(v.targets[1].mean_deg, 4.0), "{v:?}");
        assert!(close(v.targets[0].u_deg.unwrap(), 2.0) && close(v.targets[1].u_deg.unwrap(), 4.0), "{v:?}");
        assert!(close(v.targets[0].ps_deg, 6.0) && close(v.targets[1].ps_deg, 6.0), "{v:?}");
        assert!(close(v.pa_deg, 3.0), "{v:?}");
        assert!(close(v.u_deg.unwrap(), 4.0) && close(v.u_mean_deg.unwrap(), 3.0), "{v:?}");
        assert!(close(v.ps_deg, 6.0), "{v:?}");
        assert!(close(v.p_deg, 12.0), "{v:?}");
    }

    /// One direction: no reversal span; Ps = 6 s; P = the widest ±3 s band.
    /// Target 0: 1, 2, 3 (mean 2, s 1); target 5: -2, 0, 2 (mean 0, s 2).
    /// Pa = 2; Ps = 12; P = max(2 + 3, 0 + 6) - min(2 - 3, 0 - 6) = 6 + 6 = 12.
    #[test]
    fn a_hand_computed_unidirectional_case() {
        let f = Direction::Forward;
        let samples: Vec<Sample> = [(1.0, -2.0), (2.0, 0.0), (3.0, 2.0)]
            .iter()
            .enumerate()
            .flat_map(|(i, (a, b))| [sample(i as u32 + 1, f, 0.0, *a), sample(i as u32 + 1, f, 5.0, *b)])
            .collect();
        let v = vdi3441(&iso230_2(&samples).unwrap());
        assert_eq!((v.u_deg, v.u_mean_deg), (None, None));
        assert!((v.pa_deg - 2.0).abs() < 1e-12 && (v.ps_deg - 12.0).abs() < 1e-12, "{v:?}");
        assert!((v.p_deg - 12.0).abs() < 1e-12, "{v:?}");
    }

    /// P always covers Pa, and with zero scatter and no reversal they are equal.
    #[test]
    fn p_covers_pa_and_equals_it_without_scatter() {
        let f = Direction::Forward;
        let samples: Vec<Sample> =
            (1..=3).flat_map(|run| [sample(run, f, 0.0, 0.5), sample(run, f, 90.0, -0.25)]).collect();
        let v = vdi3441(&iso230_2(&samples).unwrap());
        assert!((v.pa_deg - 0.75).abs() < 1e-12 && (v.p_deg - v.pa_deg).abs() < 1e-12, "{v:?}");
    }
}
