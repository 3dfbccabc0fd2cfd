//! Pairing two streams by time (pure: data in, data out): what a continuous
//! scan's passes are paired with.
//!
//! - [`ClockMap::fit`]: an instrument stamps its stream with its own clock.
//!   At every read the engine notes when the answer came (host clock) and
//!   the stamp of the newest item in it; the newest item was stamped at or
//!   before that moment, so the host time of a stamp `d` is at most the
//!   answer's time. The map is the highest line `host = a + b d` that stays
//!   at or below every such pair (the lower convex hull of the pairs,
//!   supporting at their mean stamp: what minimises the summed gap): the
//!   offset and the rate of the instrument's clock, up to the shortest delay
//!   seen, which stays in the residual latency the two-velocity calibration
//!   removes ([`latency`]).
//! - [`crossing_time`]: when the readout passed a target, by cubic (Catmull-Rom)
//!   interpolation of the readout against time, solved by bisection; the
//!   readout stream must have a reading on each side within `max_gap`.
//! - [`position_at`]: the SMR position at a time, by a least-squares
//!   quadratic in time through the tracker points within a half-width of it
//!   (at least four, at least one on each side within `max_gap`): velocity
//!   ripple bends the path between points, and a straight line through them
//!   would cut the bend.

pub mod latency;

pub use latency::Latency;

/// `host = offset + rate * device`, seconds.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClockMap {
    pub offset_s: f64,
    pub rate: f64,
}

impl ClockMap {
    /// The identity (stamps already on the host clock).
    pub const HOST: ClockMap = ClockMap { offset_s: 0.0, rate: 1.0 };

    /// The host time of device time `d`.
    pub fn host(&self, d: f64) -> f64 {
        self.offset_s + self.rate * d
    }

    /// Fit the map from `(device stamp of the newest item, host time of the
    /// answer)` pairs (see the module documentation). `None` with fewer
    /// than two pairs of distinct stamps.
    pub fn fit(pairs: &[(f64, f64)]) -> Option<ClockMap> {
        let mut pts: Vec<(f64, f64)> = pairs.iter().filter(|(d, h)| d.is_finite() && h.is_finite()).copied().collect();
        if pts.len() < 2 {
            return None;
        }
        // Work relative to the first stamp: absolute stamps of thousands of
        // seconds would cost digits in the slopes.
        let d0 = pts.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
        for p in &mut pts {
            *p = (p.0 - d0, p.1 - p.0);
        }
        pts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        pts.dedup_by(|b, a| a.0 == b.0); // keep the lowest for each stamp
        if pts.len() < 2 {
            return None;
        }
        // Lower convex hull (Andrew's monotone chain).
        let mut hull: Vec<(f64, f64)> = Vec::new();
        for p in pts.iter().copied() {
            while hull.len() >= 2 {
                let (a, b) = (hull[hull.len() - 2], hull[hull.len() - 1]);
                let cross = (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0);
                if cross <= 0.0 {
                    hull.pop();
                } else {
                    break;
                }
            }
            hull.push(p);
        }
        let mean = pts.iter().map(|p| p.0).sum::<f64>() / pts.len() as f64;
        let i = hull.windows(2).position(|w| w[0].0 <= mean && mean <= w[1].0).unwrap_or(0);
        let (a, b) = (hull[i], hull[(i + 1).min(hull.len() - 1)]);
        let slope = if b.0 > a.0 { (b.1 - a.1) / (b.0 - a.0) } else { 0.0 };
        // host - device = a.1 + slope (device - d0 - a.0)
        let intercept = a.1 - slope * (d0 + a.0);
        Some(ClockMap { offset_s: intercept, rate: 1.0 + slope })
    }
}

/// Why a target could not be paired.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PairError {
    #[error("the {stream} stream has too few reads to map its clock")]
    NoClock { stream: &'static str },
    #[error("the readout never passed {target_deg} deg")]
    NotPassed { target_deg: f64 },
    #[error("the readout stream has a gap of {gap_s:.4} s at {target_deg} deg (longest allowed {max_s:.4} s)")]
    ReadoutGap { target_deg: f64, gap_s: f64, max_s: f64 },
    #[error("the tracker stream has no point within {max_s:.4} s on both sides of {at_s:.4} s ({target_deg} deg)")]
    TrackerGap { target_deg: f64, at_s: f64, max_s: f64 },
}

/// When the readout passed `target` (ascending times in `t`, readouts in
/// `r`), seconds, or why not. `sign` is +1 for a forward pass, -1 reverse.
pub fn crossing_time(t: &[f64], r: &[f64], target: f64, sign: f64, max_gap: f64) -> Result<f64, PairError> {
    let n = t.len();
    // The first reading at or past the target, in the pass's direction.
    let k = r.partition_point(|x| (x - target) * sign < 0.0);
    if k == 0 || k >= n {
        return Err(PairError::NotPassed { target_deg: target });
    }
    let i = k - 1;
    let gap = t[i + 1] - t[i];
    if gap > max_gap {
        return Err(PairError::ReadoutGap { target_deg: target, gap_s: gap, max_s: max_gap });
    }
    // Catmull-Rom through (i-1, i, i+1, i+2), one-sided at the ends.
    let p = |j: isize| -> (f64, f64) {
        let j = j.clamp(0, n as isize - 1) as usize;
        (t[j], r[j])
    };
    let (p0, p1, p2, p3) = (p(i as isize - 1), p(i as isize), p(i as isize + 1), p(i as isize + 2));
    let h = p2.0 - p1.0;
    let slope = |a: (f64, f64), b: (f64, f64)| if b.0 > a.0 { (b.1 - a.1) / (b.0 - a.0) } else { 0.0 };
    let m1 = if p0.0 < p1.0 { slope(p0, p2) } else { slope(p1, p2) } * h;
    let m2 = if p3.0 > p2.0 { slope(p1, p3) } else { slope(p1, p2) } * h;
    let value = |u: f64| {
        let (u2, u3) = (u * u, u * u * u);
        (2.0 * u3 - 3.0 * u2 + 1.0) * p1.1 + (u3 - 2.0 * u2 + u) * m1 + (-2.0 * u3 + 3.0 * u2) * p2.1 + (u3 - u2) * m2
    };
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if (value(mid) - target) * sign < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(p1.0 + 0.5 * (lo + hi) * h)
}

/// The SMR position at time `at` from tracker points (ascending times `t`,
/// positions `xyz`), fitted over `half_width` seconds each side (see the
/// module documentation).
pub fn position_at(
    t: &[f64],
    xyz: &[[f64; 3]],
    at: f64,
    half_width: f64,
    max_gap: f64,
    target_deg: f64,
) -> Result<[f64; 3], PairError> {
    let gap = || PairError::TrackerGap { target_deg, at_s: at, max_s: max_gap };
    let k = t.partition_point(|x| *x < at);
    if k == 0 || k >= t.len() || at - t[k - 1] > max_gap || t[k] - at > max_gap {
        return Err(gap());
    }
    let mut lo = t.partition_point(|x| *x < at - half_width);
    let mut hi = t.partition_point(|x| *x <= at + half_width);
    // At least four points: widen by one on the nearer side until there are.
    while hi - lo < 4 {
        let left = (lo > 0).then(|| at - t[lo - 1]);
        let right = (hi < t.len()).then(|| t[hi] - at);
        match (left, right) {
            (Some(l), Some(r)) if l <= r => lo -= 1,
            (Some(_), Some(_)) | (None, Some(_)) => hi += 1,
            (Some(_), None) => lo -= 1,
            (None, None) => return Err(gap()),
        }
    }
    // Least squares of y = c0 + c1 u + c2 u^2, u = t - at: c0 is the value.
    let mut s = [0.0f64; 5];
    for &tj in &t[lo..hi] {
        let u = tj - at;
        let mut p = 1.0;
        for sk in &mut s {
            *sk += p;
            p *= u;
        }
    }
    let m = [[s[0], s[1], s[2]], [s[1], s[2], s[3]], [s[2], s[3], s[4]]];
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(m);
    let mut out = [0.0; 3];
    for (c, o) in out.iter_mut().enumerate() {
        let mut b = [0.0f64; 3];
        for (tj, p) in t[lo..hi].iter().zip(&xyz[lo..hi]) {
            let u = tj - at;
            b[0] += p[c];
            b[1] += p[c] * u;
            b[2] += p[c] * u * u;
        }
        // Cramer's rule for the constant term.
        let m0 = [[b[0], m[0][1], m[0][2]], [b[1], m[1][1], m[1][2]], [b[2], m[2][1], m[2][2]]];
        *o = if d.abs() > 0.0 { det(m0) / d } else { f64::NAN };
    }
    if out.iter().any(|v| !v.is_finite()) {
        return Err(gap());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_clock_map_finds_offset_and_rate_under_delays() {
        // Device clock 5000 s ahead and 20 ppm slow; answers come 0..5 ms
        // (varying) plus 2 ms after the newest item's moment.
        let truth = ClockMap { offset_s: -5000.0 / (1.0 - 20e-6), rate: 1.0 / (1.0 - 20e-6) };
        let pairs: Vec<(f64, f64)> = (0..1000)
            .map(|i| {
                let host_item = 10.0 + i as f64 * 0.05;
                let d = 5000.0 + (1.0 - 20e-6) * host_item;
                let delay = 0.002 + 0.005 * ((i * 7919) % 13) as f64 / 13.0;
                (d, host_item + delay)
            })
            .collect();
        let fit = ClockMap::fit(&pairs).unwrap();
        for d in [5010.0, 5020.0, 5050.0] {
            let err = fit.host(d) - truth.host(d);
            // The shortest delay (2 ms) stays; nothing else does.
            assert!((err - 0.002).abs() < 1e-7, "{err}");
        }
        assert!(ClockMap::fit(&pairs[..1]).is_none());
    }

    #[test]
    fn crossings_and_positions_follow_a_rippled_path_across_a_gap() {
        // 5 deg/s with 0.5 % ripple at 3 Hz, readout every 5 ms with three lost (a 20 ms gap).
        let path = |t: f64| {
            5.0 * t + 0.005 * 5.0 / (2.0 * std::f64::consts::PI * 3.0) * (6.0 * std::f64::consts::PI * t).sin()
        };
        let mut t: Vec<f64> = (0..400).map(|i| i as f64 * 0.005).collect();
        t.retain(|x| (x - 0.5).abs() > 0.006);
        let r: Vec<f64> = t.iter().map(|x| path(*x)).collect();
        for target in [0.37, 2.5, 4.99, 7.3] {
            let tc = crossing_time(&t, &r, target, 1.0, 0.025).unwrap();
            assert!((path(tc) - target).abs() < 2e-8, "{target}: {}", path(tc) - target);
        }
        assert!(matches!(crossing_time(&t, &r, 2.5, 1.0, 0.005), Err(PairError::ReadoutGap { .. })));
        assert!(matches!(crossing_time(&t, &r, 50.0, 1.0, 0.02), Err(PairError::NotPassed { .. })));
        // Reverse: the same readings backwards in angle.
        let rev: Vec<f64> = r.iter().map(|x| 10.0 - x).collect();
        let tc = crossing_time(&t, &rev, 7.0, -1.0, 0.02).unwrap();
        assert!((10.0 - path(tc) - 7.0).abs() < 2e-8);

        // Tracker points every 5 ms on a 1000 mm arm, one lost.
        let pos = |t: f64| {
            let a = path(t).to_radians();
            [1000.0 * a.cos(), 1000.0 * a.sin(), 3.0]
        };
        let mut tt: Vec<f64> = (0..400).map(|i| 0.0025 + i as f64 * 0.005).collect();
        tt.remove(200);
        let xyz: Vec<[f64; 3]> = tt.iter().map(|x| pos(*x)).collect();
        for at in [0.3, 1.0, 1.0025, 1.5] {
            let p = position_at(&tt, &xyz, at, 0.0125, 0.02, 0.0).unwrap();
            let want = pos(at);
            let err = ((p[0] - want[0]).powi(2) + (p[1] - want[1]).powi(2)).sqrt();
            // A quadratic over +/-12.5 ms of a 3 Hz ripple: well under 1e-5 deg (1.7e-4 mm).
            assert!(err < 2e-5, "{at}: {err} mm");
        }
        assert!(matches!(position_at(&tt, &xyz, 1.0, 0.0125, 0.004, 0.0), Err(PairError::TrackerGap { .. })));
        assert!(position_at(&tt, &xyz, 5.0, 0.0125, 0.02, 0.0).is_err());
    }
}
