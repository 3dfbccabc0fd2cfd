//! Whether a verification could see the table fail: the calibration's own
//! aliases.
//!
//! A calibration at `N` targets per revolution sees a line of `f` cycles per
//! revolution at its alias, and its table corrects that alias as the line it
//! saw (at the frequency the processing gave it, `t`): a table line fitted
//! to the samples, so at the calibration's targets the two agree. Between
//! them they differ by up to twice the line. A verification whose targets
//! sample `f - (the table's line)` near its zeros sees nothing wrong: half a
//! step from every target of a full circle, a line `f = 2 k N +- t` (an even
//! band) shifts by whole turns there and the verification "confirms" a table
//! worse than native (issue 37).
//!
//! [`blind`] tries every plausible `f` that lands on a table line's bin at
//! the calibration's spacing (`k N +- b`, up to [`plausible_max_cycles`]),
//! each at several phases: the table's line is fitted to the line at the
//! calibration's targets (as the processing fits it), and the residual
//! evaluated at the verification's targets. The verification is blind to
//! `f` when, for some phase, the residual stays below half the line there.
//! [`second_spacing`] adds to the half-step targets a second, evenly spaced
//! set at a quarter of its own step (no fixed fraction of the calibration's
//! step), the fewest that leave no plausible line unseen.

use survey_processing::analysis::alias;

/// The highest line a positioner plausibly has without a design that says
/// more, cycles per revolution: the paper's Figure 4 positioner has lines up
/// to 648.
pub const PLAUSIBLE_MAX_CYCLES: f64 = 720.0;

/// The highest line to consider: [`PLAUSIBLE_MAX_CYCLES`], or the design's
/// highest line when it is higher.
pub fn plausible_max_cycles(design_max: Option<f64>) -> f64 {
    design_max.map_or(PLAUSIBLE_MAX_CYCLES, |d| d.max(PLAUSIBLE_MAX_CYCLES))
}

/// A plausible line a verification could not see the table miss.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Blind {
    /// The table's line, cycles per revolution.
    pub table_cycles: f64,
    /// The line it may really be, cycles per revolution.
    pub true_cycles: f64,
}

impl Blind {
    /// For people.
    pub fn text(&self) -> String {
        format!(
            "a line of {} cycles/rev, which the calibration's targets see where the table corrects {} cycles/rev, \
             would leave less than half its size at the verification's targets",
            self.true_cycles, self.table_cycles
        )
    }
}

/// The calibration's targets per revolution: `360 / step` of the smallest
/// step between distinct targets (a full circle's count, an arc's at its
/// spacing).
fn per_rev(targets_deg: &[f64]) -> Option<f64> {
    let mut t: Vec<f64> = targets_deg.to_vec();
    t.sort_by(f64::total_cmp);
    t.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    let step = t.windows(2).map(|w| w[1] - w[0]).fold(f64::INFINITY, f64::min);
    (step.is_finite() && step > 0.0).then(|| 360.0 / step)
}

/// The lines up to `f_max` other than `t` that land on `t`'s bin at `n` per revolution.
fn candidates(t: f64, n: f64, f_max: f64) -> Vec<f64> {
    let b = alias(t, n).observed;
    let mut out = Vec::new();
    let mut k = 0.0;
    while k * n - b <= f_max {
        for f in [k * n + b, k * n - b] {
            if f > 0.0 && f <= f_max && (f - t).abs() > 1e-9 && !out.iter().any(|g: &f64| (g - f).abs() < 1e-9) {
                out.push(f);
            }
        }
        k += 1.0;
    }
    out.sort_by(f64::total_cmp);
    out
}

/// The cosine and sine of a line at `t` fitted by least squares to `y` at
/// `theta` (radians); with the sine degenerate (the Nyquist bin), the cosine alone.
fn fit(t: f64, theta: &[f64], y: &[f64]) -> (f64, f64) {
    let (mut cc, mut ss, mut cs, mut cy, mut sy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (x, v) in theta.iter().zip(y) {
        let (s, c) = (t * x).sin_cos();
        cc += c * c;
        ss += s * s;
        cs += c * s;
        cy += c * v;
        sy += s * v;
    }
    let det = cc * ss - cs * cs;
    if det.abs() <= 1e-9 * (cc * ss).max(f64::MIN_POSITIVE) {
        return (if cc > 1e-9 { cy / cc } else { 0.0 }, 0.0);
    }
    ((ss * cy - cs * sy) / det, (cc * sy - cs * cy) / det)
}

/// Phases a line is tried at: enough that a residual vanishing at one of
/// them is found (a residual's size varies smoothly with the phase).
const PHASES: usize = 6;

/// Whether targets at `ver` (radians) see a table line at `t`, fitted at the
/// calibration's `cal`, miss a unit line at `f`: the smallest, over phases,
/// of the largest residual there.
fn seen(t: f64, f: f64, cal: &[f64], ver: &[f64]) -> f64 {
    (0..PHASES)
        .map(|p| {
            let phase = std::f64::consts::PI * p as f64 / PHASES as f64;
            let y: Vec<f64> = cal.iter().map(|x| (f * x + phase).sin()).collect();
            let (a, b) = fit(t, cal, &y);
            ver.iter()
                .map(|x| ((f * x + phase).sin() - a * (t * x).cos() - b * (t * x).sin()).abs())
                .fold(0.0, f64::max)
        })
        .fold(f64::INFINITY, f64::min)
}

/// The plausible lines (up to `f_max`) that a verification at `ver_deg`
/// could not see a table of `lines` (cycles/rev), made at `cal_deg`, miss
/// (see the module documentation); empty when every one shows.
pub fn blind(cal_deg: &[f64], ver_deg: &[f64], lines: &[f64], f_max: f64) -> Vec<Blind> {
    let Some(n) = per_rev(cal_deg) else { return Vec::new() };
    let rad = |d: &[f64]| -> Vec<f64> { d.iter().map(|x| x.to_radians()).collect() };
    let (cal, ver) = (rad(cal_deg), rad(ver_deg));
    let mut out = Vec::new();
    for &t in lines.iter().filter(|t| **t > 0.0) {
        for f in candidates(t, n, f_max) {
            if seen(t, f, &cal, &ver) < 0.5 {
                out.push(Blind { table_cycles: t, true_cycles: f });
            }
        }
    }
    out
}

/// A full circle's `p` targets at a quarter of their step from 0, degrees.
pub fn quarter_step_circle(p: usize) -> Vec<f64> {
    (0..p).map(|j| 360.0 * (j as f64 + 0.25) / p as f64).collect()
}

/// The fewest targets `p` (from half the calibration's count up to
/// `max_points`) of a second full-circle set at a quarter of its own step
/// that, with the half-step targets `half_deg`, leave no plausible line of
/// `lines` unseen, and the joined targets (sorted); `None` when the half-step
/// targets see them all already, or when no such set exists.
pub fn second_spacing(
    cal_deg: &[f64],
    half_deg: &[f64],
    lines: &[f64],
    f_max: f64,
    max_points: usize,
) -> Option<(usize, Vec<f64>)> {
    if blind(cal_deg, half_deg, lines, f_max).is_empty() {
        return None;
    }
    let near = |a: f64, b: f64| {
        let d = (a - b).rem_euclid(360.0);
        d.min(360.0 - d) < 1e-6
    };
    (cal_deg.len() / 2..=max_points).find_map(|p| {
        let second = quarter_step_circle(p);
        // None on a calibration target or on another verification target.
        if second.iter().any(|s| cal_deg.iter().chain(half_deg).any(|c| near(*s, *c))) {
            return None;
        }
        let mut joined: Vec<f64> = half_deg.iter().copied().chain(second).collect();
        joined.sort_by(f64::total_cmp);
        blind(cal_deg, &joined, lines, f_max).is_empty().then_some((p, joined))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle(n: usize, offset: f64) -> Vec<f64> {
        (0..n).map(|j| 360.0 * (j as f64 + offset) / n as f64).collect()
    }

    /// The case: 20 targets, a 43 cycles/rev line seen at bin 3.
    /// Half a step from every target the verification is blind to it (43 =
    /// 2 x 20 + 3, an even band); joined with a second spacing it is not.
    #[test]
    fn half_a_step_is_blind_to_an_even_band_and_a_second_spacing_sees_it() {
        let (cal, half) = (circle(20, 0.0), circle(20, 0.5));
        let b = blind(&cal, &half, &[3.0], 360.0);
        assert!(b.contains(&Blind { table_cycles: 3.0, true_cycles: 43.0 }), "{b:?}");
        // The odd band (23 = 20 + 3, 17 = 20 - 3) flips sign there: seen.
        assert!(!b.iter().any(|x| x.true_cycles == 23.0 || x.true_cycles == 17.0), "{b:?}");
        let (p, joined) = second_spacing(&cal, &half, &[3.0], 360.0, 40).expect("a second spacing");
        assert!(blind(&cal, &joined, &[3.0], 360.0).is_empty());
        assert_eq!(joined.len(), 20 + p);
        assert!(joined.iter().all(|t| cal.iter().all(|c| (t - c).abs() > 1e-6)));
    }

    #[test]
    fn a_dense_calibration_s_half_step_sees_every_plausible_line() {
        let (cal, half) = (circle(1800, 0.0), circle(1800, 0.5));
        assert!(blind(&cal, &half, &[1.0, 20.0, 40.0, 100.0], PLAUSIBLE_MAX_CYCLES).is_empty());
        assert_eq!(second_spacing(&cal, &half, &[1.0, 20.0, 40.0], PLAUSIBLE_MAX_CYCLES, 3600), None);
    }

    #[test]
    fn candidates_are_the_bands_around_multiples_of_the_count() {
        assert_eq!(candidates(3.0, 20.0, 45.0), vec![17.0, 23.0, 37.0, 43.0]);
        // A line above the count: the bin is its alias; the line itself is no candidate.
        assert_eq!(candidates(43.0, 20.0, 45.0), vec![3.0, 17.0, 23.0, 37.0]);
        assert_eq!(plausible_max_cycles(Some(1000.0)), 1000.0);
        assert_eq!(plausible_max_cycles(None), 720.0);
    }
}
