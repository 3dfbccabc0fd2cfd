//! The latency between the two instruments' clocks, from passes at two
//! velocities (pure).
//!
//! After the clock maps ([`super::ClockMap`]) a constant time offset
//! `delta` is left between the two streams: the shortest delays the maps
//! could not see, the tracker's stamp latency, whatever part of its
//! integration the half-integration shift does not cover. A tracker point
//! taken for time `t` then shows the axis at `t - delta`, so a sample paired
//! with `delta = 0` has the error `e + v delta` (`v` the signed velocity):
//! a backlash proportional to the velocity. With passes over the same
//! angles at one velocity (1) and at another (2) (the calibration passes
//! of [`crate::calibration_passes`]), per angle `k`,
//!
//! `d_f(k) = e_f1(k) - e_f2(k) = (v1 - v2) delta` (forward passes) and
//! `d_r(k) = e_r1(k) - e_r2(k) = -(v1 - v2) delta` (reverse passes),
//!
//! the positioner's own error cancelling angle by angle, so
//! `delta = (mean d_f - mean d_r) / (2 (v1 - v2))` (forward only:
//! `mean d_f / (v1 - v2)`). Its standard error is from the scatter of the
//! means of [`BLOCKS`] consecutive blocks of the `d`: pairing points closer
//! than a tracker fit's width, or than the positioner's noise correlation
//! along a move, share their errors, so the scatter of single differences
//! would understate it. A drift that is a constant per pass cancels between
//! the two directions; a drift that ramps in time within the passes does
//! not, and biases `delta` by the drift between the passes over
//! `2 (v1 - v2)`.

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

/// How many consecutive blocks the standard error is taken over (see the
/// module documentation).
const BLOCKS: usize = 20;

/// The mean and the standard error of the mean of `a - b`, target by
/// target (the standard error from the means of [`BLOCKS`] consecutive
/// blocks).
fn mean_difference(a: &PassErrors, b: &PassErrors) -> Option<(f64, f64)> {
    let d: Vec<f64> = a.errors.iter().zip(&b.errors).map(|(x, y)| x - y).filter(|x| x.is_finite()).collect();
    if d.len() < 2 {
        return None;
    }
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let size = d.len().div_ceil(BLOCKS);
    let blocks: Vec<f64> = d.chunks(size).map(|c| c.iter().sum::<f64>() / c.len() as f64).collect();
    let m = blocks.len() as f64;
    let var = blocks.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (m - 1.0);
    Some((mean, (var / m).sqrt()))
}

/// `delta` from passes over the same angles at one velocity (`forward1`,
/// and `reverse1` first in `reverse`) and at another (`forward2`,
/// `reverse2`); `None` when the velocities are equal or a pass has fewer
/// than two points.
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

    #[test]
    fn neighbours_that_share_their_errors_do_not_shrink_the_standard_error() {
        // 200 independent differences, then each read 8 times (as pairing
        // points closer than the fit's width read the same tracker points):
        // the same information, so the same standard error, where the
        // scatter of single differences would give sqrt(8) times less.
        // Uniform on (-0.5, 0.5): splitmix64's finaliser of the index.
        let noise = |k: u64| {
            let mut z = k.wrapping_add(1).wrapping_mul(0x9e37_79b9_7f4a_7c15);
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let pass = |v: f64, errors: Vec<f64>| PassErrors { speed_deg_s: v, errors };
        let zero = |n: usize| pass(5.0, vec![0.0; n]);
        let once: Vec<f64> = (0..200).map(noise).collect();
        let eight: Vec<f64> = once.iter().flat_map(|x| [*x; 8]).collect();
        let a = estimate(&pass(10.0, once.clone()), &zero(200), None).unwrap();
        let b = estimate(&pass(10.0, eight), &zero(1600), None).unwrap();
        assert!((a.delta_s - b.delta_s).abs() < 1e-12);
        assert!((b.se_s / a.se_s - 1.0).abs() < 0.3, "{a:?} {b:?}");
        // And it is the standard error of the mean: 1/sqrt(12) / sqrt(200) / 5.
        let expected = (1.0f64 / 12.0).sqrt() / 200f64.sqrt() / 5.0;
        assert!((a.se_s / expected - 1.0).abs() < 0.4, "{a:?} against {expected}");
    }
}
