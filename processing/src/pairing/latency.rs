//! The latency between the two instruments' clocks, from passes at two
//! velocities (pure).
//!
//! After the clock maps ([`super::ClockMap`]) a constant time offset
//! `delta` is left between the two streams: the shortest delays the maps
//! could not see, the tracker's stamp latency, whatever part of its
//! integration the half-integration shift does not cover. A tracker point
//! taken for time `t` then shows the axis at `t - delta`, so a sample paired
//! with `delta = 0` has the error `e + v delta` (`v` the signed velocity):
//! a backlash proportional to the velocity. With the first run at one
//! velocity and the second at another, per target `k`,
//!
//! `d_f(k) = e_f1(k) - e_f2(k) = (v1 - v2) delta` (forward passes) and
//! `d_r(k) = e_r1(k) - e_r2(k) = -(v1 - v2) delta` (reverse passes),
//!
//! the positioner's own error cancelling target by target, so
//! `delta = (mean d_f - mean d_r) / (2 (v1 - v2))` (forward only:
//! `mean d_f / (v1 - v2)`), with the standard error from the scatter of
//! the `d`. A drift that is a constant per run cancels too; a drift that
//! ramps in time within the runs does not, and biases `delta` by the drift
//! between the passes over `2 (v1 - v2)`.

use serde::{Deserialize, Serialize};

/// The estimated latency and how well it is known.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Latency {
    /// Seconds the tracker's points lag the readout's (removed from every sample).
    pub delta_s: f64,
    /// Its standard error, seconds.
    pub se_s: f64,
}

/// One pass paired with no latency: its speed and each target's error.
#[derive(Debug, Clone, PartialEq)]
pub struct PassErrors {
    /// Unsigned velocity, deg/s.
    pub speed_deg_s: f64,
    /// `readout - actual` per target, in the plan's target order.
    pub errors: Vec<f64>,
}

/// The mean and the standard error of the mean of `a - b`, target by target.
fn mean_difference(a: &PassErrors, b: &PassErrors) -> Option<(f64, f64)> {
    let d: Vec<f64> = a.errors.iter().zip(&b.errors).map(|(x, y)| x - y).filter(|x| x.is_finite()).collect();
    if d.len() < 2 {
        return None;
    }
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    Some((mean, (var / n).sqrt()))
}

/// `delta` from the first run's passes (`forward1`, `reverse1`) and the
/// second's; `None` when the velocities are equal or a pass has no targets.
pub fn estimate(
    forward1: &PassErrors,
    forward2: &PassErrors,
    reverse: Option<(&PassErrors, &PassErrors)>,
) -> Option<Latency> {
    let dv = forward1.speed_deg_s - forward2.speed_deg_s;
    if dv.abs() < 1e-9 {
        return None;
    }
    let (mf, sf) = mean_difference(forward1, forward2)?;
    match reverse {
        Some((r1, r2)) => {
            let (mr, sr) = mean_difference(r1, r2)?;
            Some(Latency { delta_s: (mf - mr) / (2.0 * dv), se_s: (sf * sf + sr * sr).sqrt() / (2.0 * dv.abs()) })
        }
        None => Some(Latency { delta_s: mf / dv, se_s: sf / dv.abs() }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_latency_comes_out_of_the_velocity_dependent_backlash() {
        // A positioner error of its own, a backlash, a per-run offset and a
        // 4 ms latency at 10 and 5 deg/s: exactly 4 ms back.
        let e = |k: usize| 0.01 * (k as f64 * 0.3).sin();
        let pass = |v: f64, sign: f64, run_offset: f64| PassErrors {
            speed_deg_s: v,
            errors: (0..100).map(|k| e(k) + sign * 0.004 + run_offset + sign * v * 0.004).collect(),
        };
        let (f1, r1, f2, r2) =
            (pass(10.0, 1.0, 0.001), pass(10.0, -1.0, 0.001), pass(5.0, 1.0, -0.002), pass(5.0, -1.0, -0.002));
        let l = estimate(&f1, &f2, Some((&r1, &r2))).unwrap();
        assert!((l.delta_s - 0.004).abs() < 1e-12 && l.se_s < 1e-12, "{l:?}");
        // Forward only: the run offset is not separable and stays in.
        let l = estimate(&f1, &f2, None).unwrap();
        assert!((l.delta_s - (0.004 + 0.003 / 5.0)).abs() < 1e-12, "{l:?}");
        assert!(estimate(&f1, &f1, None).is_none());
    }
}
