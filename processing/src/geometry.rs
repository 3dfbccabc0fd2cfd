//! Locating a rotary axis from tracking-laser SMR positions.
//!
//! A tracking laser measures the 3-D position of a spherically mounted
//! retroreflector (SMR) on an arm fixed to the turntable, not an angle. Over
//! the travel the SMR describes a circle in a plane perpendicular to the axis;
//! the plane is tilted in the tracker frame and the circle is off the tracker's
//! origin. [`fit_axis`] finds that circle from positions measured at a spread
//! of readout angles:
//!
//! 1. plane: least squares, through the centroid, normal along the smallest
//!    eigenvector of the 3x3 covariance (a small Jacobi eigen-solver);
//! 2. circle: the points projected onto the plane, an algebraic (Kasa) fit as
//!    the start, then Gauss-Newton on the geometric distance;
//! 3. orientation: the normal's sign is chosen so that angles increase with the
//!    readouts (`u`, `v = normal x u`, `normal` form a right-handed frame);
//! 4. zero: the tracker has no angle zero, so the zero offset makes the mean
//!    readout error over the fit points zero.
//!
//! The angle of any later SMR position is then the direction of its projection
//! around the centre ([`AxisFit::angle_deg`]). A full revolution and a partial
//! arc (an elevation axis from -10 to 90 degrees) both work.

use crate::types::wrap_180;
use serde::{Deserialize, Serialize};

/// A located rotary axis: the circle an SMR describes about it, and the angle zero.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisFit {
    /// Centre of the circle, tracker frame, millimetres (a point on the axis).
    pub center_mm: [f64; 3],
    /// Unit axis direction; angles increase counter-clockwise about it
    /// (right-hand rule), which is the direction in which the readouts increase.
    pub normal: [f64; 3],
    /// Unit vector in the plane of the circle: the reference of the raw angle.
    pub u: [f64; 3],
    /// Unit vector in the plane, `normal x u`: raw angle 90 degrees.
    pub v: [f64; 3],
    /// Radius of the circle, millimetres.
    pub radius_mm: f64,
    /// Raw angle in the plane (from `u` towards `v`) of axis angle zero, degrees in `[-180, 180)`.
    pub zero_offset_deg: f64,
    /// RMS distance of the fit points from the plane, millimetres.
    pub plane_rms_mm: f64,
    /// RMS in-plane distance of the projected fit points from the circle, millimetres.
    pub circle_rms_mm: f64,
    /// Number of points fitted.
    pub points: usize,
}

/// Why an axis cannot be located.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GeometryError {
    /// A circle in space needs at least 3 points.
    #[error("locating an axis needs at least 3 SMR positions, got {0}")]
    TooFewPoints(usize),
    /// Every point needs its readout.
    #[error("{points} SMR positions but {readouts} readouts: each position needs the readout it was taken at")]
    LengthMismatch {
        /// Number of positions.
        points: usize,
        /// Number of readouts.
        readouts: usize,
    },
    /// A coordinate or readout is NaN or infinite.
    #[error("point {index}: {what} is {value}, not a finite number")]
    NonFinite {
        /// Position of the point in the input (from 0).
        index: usize,
        /// `x`, `y`, `z` or `readout`.
        what: &'static str,
        /// The offending value.
        value: f64,
    },
    /// The points do not define a circle (coincident, collinear) or the
    /// readouts do not define a direction of rotation.
    #[error("the SMR positions do not locate an axis: {0}")]
    Degenerate(String),
}

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: V3, b: V3) -> V3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn scale(a: V3, k: f64) -> V3 {
    [a[0] * k, a[1] * k, a[2] * k]
}

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn normalize(a: V3) -> V3 {
    scale(a, 1.0 / dot(a, a).sqrt())
}

/// Locate the axis from SMR positions `points_mm` taken at `readouts_deg`.
///
/// The readouts fix the direction of rotation and the angle zero only: the
/// geometry comes from the points alone. They may be in any order, and may
/// cover a full revolution or a partial arc.
pub fn fit_axis(points_mm: &[[f64; 3]], readouts_deg: &[f64]) -> Result<AxisFit, GeometryError> {
    fit_axis_with_angles(points_mm, || readouts_deg.iter().copied()).map(|(fit, _)| fit)
}

/// [`fit_axis`], and the raw angle of every point around the fitted axis
/// ([`AxisFit::raw_angle`] to rounding: from the circle fit's own
/// coordinates), in the order of `points_mm`. `readouts_deg` makes the
/// readouts anew for each pass over them.
fn fit_axis_with_angles<I: Iterator<Item = f64>>(
    points_mm: &[[f64; 3]],
    readouts_deg: impl Fn() -> I,
) -> Result<(AxisFit, Vec<f64>), GeometryError> {
    let n = points_mm.len();
    let readouts = readouts_deg().count();
    if n != readouts {
        return Err(GeometryError::LengthMismatch { points: n, readouts });
    }
    if n < 3 {
        return Err(GeometryError::TooFewPoints(n));
    }
    // 1. Plane: centroid and the smallest eigenvector of the covariance.
    // The sums of the coordinates and of the readouts are finite unless a
    // value is not (or they overflow): only then is each value looked at,
    // to name the first that is not finite.
    let nf = n as f64;
    let sum = points_mm.iter().fold([0.0; 3], |acc, &p| add(acc, p));
    if !(sum.iter().all(|v| v.is_finite()) && readouts_deg().sum::<f64>().is_finite()) {
        for (index, (p, r)) in points_mm.iter().zip(readouts_deg()).enumerate() {
            for (what, value) in [("x", p[0]), ("y", p[1]), ("z", p[2]), ("readout", r)] {
                if !value.is_finite() {
                    return Err(GeometryError::NonFinite { index, what, value });
                }
            }
        }
    }
    let centroid = scale(sum, 1.0 / nf);
    // The six distinct sums of the symmetric covariance, divided once.
    let mut sums = [0.0; 6];
    for &p in points_mm {
        let d = sub(p, centroid);
        for (s, (i, j)) in sums.iter_mut().zip([(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]) {
            *s += d[i] * d[j];
        }
    }
    let [xx, xy_, xz, yy, yz, zz] = sums.map(|s| s / nf);
    let cov = [[xx, xy_, xz], [xy_, yy, yz], [xz, yz, zz]];
    let (values, vectors) = sym_eigen3(cov);
    if values[2] <= 0.0 {
        return Err(GeometryError::Degenerate("all positions coincide".into()));
    }
    if values[1] <= 1e-12 * values[2] {
        return Err(GeometryError::Degenerate("the positions lie on a straight line".into()));
    }
    let mut normal = normalize(vectors[0]);
    let u = normalize(sub(vectors[2], scale(normal, dot(vectors[2], normal))));
    let mut v = cross(normal, u);

    // 2. Circle in the plane, in coordinates scaled to the spread of the points.
    let spread = (values[1] + values[2]).sqrt();
    // The projected points are made again on every pass over them (two dot
    // products with the basis scaled by the spread, no division) rather
    // than kept: a vector of them was 16 bytes a point at the refit's peak.
    let (us, vs) = (scale(u, 1.0 / spread), scale(v, 1.0 / spread));
    let project = |p: &[f64; 3]| {
        let d = sub(*p, centroid);
        [dot(d, us), dot(d, vs)]
    };
    let xy = || points_mm.iter().map(project);
    let (mut a, mut b, r, cost) = fit_circle(xy)
        .ok_or_else(|| GeometryError::Degenerate("the projected positions do not determine a circle".into()))?;
    let radius_mm = r * spread;
    if !radius_mm.is_finite() || !a.is_finite() || !b.is_finite() || radius_mm <= 1e-9 * spread {
        return Err(GeometryError::Degenerate(format!(
            "the fitted circle is degenerate (radius {radius_mm} mm over a spread of {spread} mm)"
        )));
    }
    let circle_rms_mm = spread * (cost / nf).sqrt();
    let plane_rms_mm = (points_mm.iter().map(|&p| dot(sub(p, centroid), normal).powi(2)).sum::<f64>() / nf).sqrt();

    // 3. Orientation. With theta the raw angles and r the readouts, the sum over
    // pairs of sin(theta_j - theta_i) sin(r_j - r_i) is positive when the angles
    // increase with the readouts; it equals (|sum e^{i(theta - r)}|^2 -
    // |sum e^{i(theta + r)}|^2) / 4, which needs no pairs and no unwrapping.
    // A position's e^{i theta} is its direction from the centre (a quotient,
    // not a sine and a cosine of its angle); e^{i r} is the readout's.
    // The raw angles around the fitted centre, radians, are taken in the
    // same pass: what `AxisFit::raw_angle` gives, to rounding, once `v` is
    // flipped with the normal (below) where it has to be (the refit hands
    // them on).
    //
    // The sums take every `stride`-th position, a few thousand of them
    // (every position up to 8191): they tell a direction and the zero's
    // circular mean, which the arithmetic mean over every position then
    // refines (step 4), and a readout's sine and cosine were a tenth of a
    // large survey's processing. A subset that does not tell the direction
    // clearly (its two squared resultants apart by less than half the square
    // of its count, which a clean full circle makes them: an arc, or
    // positions that alias with the sweeps) is not trusted: the sums are
    // taken again over every position, as they always are up to 8191.
    let stride = (n / ORIENTATION_POSITIONS).max(1);
    let mut raw: Vec<f64> = Vec::with_capacity(n);
    let mut sums = orientation_sums(xy().zip(readouts_deg()), stride, a, b, Some(&mut raw));
    let resultant = |(s, c): (f64, f64)| s * s + c * c;
    let told = |(minus, plus, m): ((f64, f64), (f64, f64), usize)| {
        (resultant(minus) - resultant(plus)).abs() >= (m as f64).powi(2) / 2.0
    };
    if stride > 1 && !told(sums) {
        sums = orientation_sums(xy().zip(readouts_deg()), 1, a, b, None);
    }
    let (minus, plus, taken) = sums;
    let orientation = (resultant(minus) - resultant(plus)) / 4.0;
    if orientation.abs() <= 1e-9 * (taken as f64).powi(2) {
        return Err(GeometryError::Degenerate(
            "the readouts do not vary enough to tell the direction of rotation".into(),
        ));
    }
    if orientation < 0.0 {
        normal = scale(normal, -1.0);
        v = scale(v, -1.0);
        b = -b;
        // `atan2` is odd in `y`, to the bit.
        raw.iter_mut().for_each(|t| *t = -*t);
    }

    // 4. Zero: the mean over the fit points of wrap_180(raw - zero - readout) is zero.
    // A circular mean first (robust to the wrap), then the arithmetic mean of the
    // wrapped differences around it. Flipped, e^{i(-theta - r)} is the
    // conjugate of e^{i(theta + r)}: the orientation's sums serve both ways.
    let (s, c) = if orientation < 0.0 { (-plus.0, plus.1) } else { minus };
    let z0 = s.atan2(c).to_degrees();
    let z = z0 + raw.iter().zip(readouts_deg()).map(|(t, r)| wrap_180(t.to_degrees() - r - z0)).sum::<f64>() / nf;

    a *= spread;
    b *= spread;
    let fit = AxisFit {
        center_mm: add(centroid, add(scale(u, a), scale(v, b))),
        normal,
        u,
        v,
        radius_mm,
        zero_offset_deg: wrap_180(z),
        plane_rms_mm,
        circle_rms_mm,
        points: n,
    };
    Ok((fit, raw))
}

/// Positions the orientation's sums take at least (every one below twice as many).
const ORIENTATION_POSITIONS: usize = 4096;

/// The orientation's sums over every `stride`-th of the positions `q` (in
/// the circle's plane, centre `(a, b)`) with their readouts `r`, degrees:
/// `sum e^{i(theta - r)}` and `sum e^{i(theta + r)}` as (sine, cosine)
/// parts, and how many positions they took; with `raw` some, the raw angle
/// `theta` of every position is pushed to it.
fn orientation_sums(
    points: impl Iterator<Item = ([f64; 2], f64)>,
    stride: usize,
    a: f64,
    b: f64,
    mut raw: Option<&mut Vec<f64>>,
) -> ((f64, f64), (f64, f64), usize) {
    let (mut minus, mut plus, mut taken) = ((0.0, 0.0), (0.0, 0.0), 0);
    // Positions until the next one taken (a count, not a remainder: a
    // division a position).
    let mut skip = 0;
    for (q, r) in points {
        let (x, y) = (q[0] - a, q[1] - b);
        let theta = libm::atan2(y, x);
        if let Some(raw) = raw.as_deref_mut() {
            raw.push(theta);
        }
        if skip > 0 {
            skip -= 1;
            continue;
        }
        skip = stride - 1;
        let rho = norm2(x, y);
        let (st, ct) = if rho > 0.0 { (y * (1.0 / rho), x * (1.0 / rho)) } else { theta.sin_cos() };
        let (sr, cr) = r.to_radians().sin_cos();
        minus = (minus.0 + (st * cr - ct * sr), minus.1 + (ct * cr + st * sr));
        plus = (plus.0 + (st * cr + ct * sr), plus.1 + (ct * cr - st * sr));
        taken += 1;
    }
    (minus, plus, taken)
}

/// `hypot(x, y)` by a plain square root where the squares can neither
/// overflow nor underflow (within a few ulps of `hypot`, and far quicker:
/// the refit takes several per sample), `hypot` itself elsewhere.
#[inline]
fn norm2(x: f64, y: f64) -> f64 {
    let q = (x * x + y * y).sqrt();
    if (1e-150..1e150).contains(&q) { q } else { x.hypot(y) }
}

/// The axis fitted again from a whole survey's SMR positions (see [`refit_axis`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Refit {
    /// The fit from every position kept.
    pub fit: AxisFit,
    /// Positions left out: farther from the fitted circle or plane than 5
    /// robust standard deviations (a glitch, a beam re-locked on a wrong point).
    pub dropped: usize,
    /// Covariance of the centre in the plane, mm², in the fit's `(u, v)`
    /// basis: `s² [(JᵀJ)⁻¹]` over the centre's two rows, `J` the Jacobian of
    /// the circle's residuals in (centre, radius) and `s` their standard
    /// deviation (`n - 3` degrees of freedom). On a full circle it is about
    /// `s² 2/n` in every direction; on a partial arc the direction of the
    /// arc's bisector is known far worse (it trades with the radius).
    pub center_cov_mm2: [[f64; 2]; 2],
    /// Standard error of the centre in its worst-known direction, mm (the
    /// square root of the covariance's larger eigenvalue).
    pub center_se_mm: f64,
    /// The once-per-revolution angle error that centre error makes, degrees
    /// (its standard error in the worst direction: `center_se_mm / radius`).
    pub once_per_rev_se_deg: f64,
    /// The arc the positions cover around the centre, degrees (360 less the
    /// largest gap between them).
    pub arc_deg: f64,
    /// What the centre's uncertainty costs over the measured arc, degrees: the
    /// largest standard deviation, over the arc, of the angle error a centre
    /// error makes there, its mean over the arc removed (a constant is the
    /// zero reference). On a full circle it equals `once_per_rev_se_deg`.
    pub over_arc_se_deg: f64,
}

/// Locate the axis again from many SMR positions (every sample of a survey
/// and the points that located it first). The SMR sits on the arm, so its
/// positions lie at the TRUE axis angles: the circle through them is not
/// biased by the positioner's angular error, and thousands of positions
/// know the centre far better than the dozen that located the axis before
/// the runs. The zero keeps the convention of [`fit_axis`] (the mean of
/// `angle - readout` over the positions is zero): a constant between two
/// fits is a matter of zero reference only.
///
/// Robust: a first fit, then positions whose distance from the circle or the
/// plane exceeds 5 robust standard deviations (1.4826 x the median absolute
/// residual) are dropped and the axis is fitted again from the rest.
///
/// How well the axis is known (see [`Refit`]): the centre's covariance from
/// the circle fit's Jacobian at its residual scatter. A centre error `dc`
/// turns the angle of a position at raw angle `phi` by `(dc_u sin phi - dc_v
/// cos phi) / radius`: a once-per-revolution error. The plane's own
/// uncertainty (a tilt of microradians) changes angles only at second order
/// and is left out.
pub fn refit_axis(points_mm: &[[f64; 3]], readouts_deg: &[f64]) -> Result<Refit, GeometryError> {
    refit_axis_with_angles(points_mm, || readouts_deg.iter().copied()).map(|(refit, _)| refit)
}

/// [`refit_axis`], and the raw angle of every position around the refitted
/// axis ([`AxisFit::raw_angle`], in the order of `points_mm`, the dropped
/// ones too): what the centre's uncertainty takes, and what
/// [`AxisFit::angle_of_raw`] turns into the positions' angles without a
/// second `atan2` each. `readouts_deg` makes the readouts anew for each
/// pass over them (a survey's are its samples': a copy of them was 8 bytes
/// a sample at the refit's peak).
pub fn refit_axis_with_angles<I: Iterator<Item = f64>>(
    points_mm: &[[f64; 3]],
    readouts_deg: impl Fn() -> I,
) -> Result<(Refit, Vec<f64>), GeometryError> {
    let (first, first_raw) = fit_axis_with_angles(points_mm, &readouts_deg)?;
    // Few or none: the points kept are the others.
    let beyond = beyond_limit(&first, points_mm);
    let dropped = beyond.len();
    let kept = points_mm.len() - dropped;
    let refitted = dropped != 0 && kept >= 3;
    let is_kept = |i: &usize| beyond.binary_search(i).is_err();
    let (fit, raw) = if refitted {
        drop(first_raw);
        let pts: Vec<[f64; 3]> = (0..points_mm.len()).filter(is_kept).map(|i| points_mm[i]).collect();
        let ro: Vec<f64> = readouts_deg().enumerate().filter(|(i, _)| is_kept(i)).map(|(_, r)| r).collect();
        let fit = fit_axis(&pts, &ro)?;
        let raw: Vec<f64> = points_mm.iter().map(|&p| fit.raw_angle(p)).collect();
        (fit, raw)
    } else {
        (first, first_raw)
    };
    let knowledge = if refitted {
        center_knowledge(&fit, || (0..points_mm.len()).filter(is_kept).map(|i| (points_mm[i], raw[i])))
    } else {
        center_knowledge(&fit, || points_mm.iter().copied().zip(raw.iter().copied()))
    };
    let refit = Refit {
        fit,
        dropped: if refitted { dropped } else { 0 },
        center_cov_mm2: knowledge.cov,
        center_se_mm: knowledge.worst_se_mm,
        once_per_rev_se_deg: knowledge.once_per_rev_se_deg,
        arc_deg: knowledge.arc_deg,
        over_arc_se_deg: knowledge.over_arc_se_deg,
    };
    Ok((refit, raw))
}

/// The indices of the points whose distance from the circle and plane of
/// `fit` (the norm of the in-plane and the out-of-plane distance) is beyond
/// 5 robust standard deviations (1.4826 x the median distance), ascending;
/// none when that median is 0.
///
/// The distances are compared in square (a square root a point fewer),
/// and each is made again on the second pass rather than kept (8 bytes a
/// point at the refit's peak): the vector the median is selected in is the
/// only one.
fn beyond_limit(fit: &AxisFit, points_mm: &[[f64; 3]]) -> Vec<usize> {
    let squared = |p: &[f64; 3]| {
        let d = sub(*p, fit.center_mm);
        let h = dot(d, fit.normal);
        let in_plane = sub(d, scale(fit.normal, h));
        (dot(in_plane, in_plane).sqrt() - fit.radius_mm).powi(2) + h * h
    };
    let mut squares: Vec<f64> = points_mm.iter().map(squared).collect();
    let mad = squares.select_nth_unstable_by(points_mm.len() / 2, f64::total_cmp).1.sqrt();
    drop(squares);
    let limit = 5.0 * 1.4826 * mad;
    if limit <= 0.0 {
        return Vec::new();
    }
    let limit2 = limit * limit;
    points_mm.iter().enumerate().filter(|(_, p)| squared(p) > limit2).map(|(i, _)| i).collect()
}

/// How well a fitted circle's centre is known from its points.
struct CenterKnowledge {
    cov: [[f64; 2]; 2],
    worst_se_mm: f64,
    once_per_rev_se_deg: f64,
    arc_deg: f64,
    over_arc_se_deg: f64,
}

/// From the points fitted and the raw angle of each ([`AxisFit::raw_angle`]),
/// which `points` makes anew for each pass over them (a copy of the angles
/// was 8 bytes a sample at the refit's peak).
fn center_knowledge<I: Iterator<Item = ([f64; 3], f64)>>(fit: &AxisFit, points: impl Fn() -> I) -> CenterKnowledge {
    let mut jtj = [[0.0; 3]; 3];
    let mut ss = 0.0;
    // The places (in `points`' order) of any point at the centre: it has no
    // direction, and its angle is left out with it.
    let mut at_centre = Vec::new();
    let mut count = 0usize;
    // A point's direction from the centre (the sine and the cosine of its
    // raw angle, as quotients), made again for each pass over the points
    // rather than kept: `None` at the centre.
    let direction = |p: [f64; 3]| {
        let d = sub(p, fit.center_mm);
        let (x, y) = (dot(d, fit.u), dot(d, fit.v));
        let dist = norm2(x, y);
        (dist != 0.0).then_some((x, y, dist))
    };
    // Sums of the sine and the cosine of the raw angles.
    let (mut sum_sin, mut sum_cos) = (0.0, 0.0);
    for (k, (p, _)) in points().enumerate() {
        let Some((x, y, dist)) = direction(p) else {
            at_centre.push(k);
            continue;
        };
        let (c, s) = (x * (1.0 / dist), y * (1.0 / dist));
        let jac = [-c, -s, -1.0];
        for i in 0..3 {
            for j in 0..3 {
                jtj[i][j] += jac[i] * jac[j];
            }
        }
        ss += (dist - fit.radius_mm).powi(2);
        sum_sin += s;
        sum_cos += c;
        count += 1;
    }
    let phi = || points().enumerate().filter(|(k, _)| at_centre.binary_search(k).is_err()).map(|(_, (_, raw))| raw);
    let s2 = ss / (count.saturating_sub(3)).max(1) as f64;
    let col = |k: usize| {
        let mut e = [0.0; 3];
        e[k] = 1.0;
        solve3(jtj, e)
    };
    let cov = match (col(0), col(1)) {
        (Some(c0), Some(c1)) => [[s2 * c0[0], s2 * c1[0]], [s2 * c0[1], s2 * c1[1]]],
        _ => [[f64::INFINITY, 0.0], [0.0, f64::INFINITY]],
    };
    // The larger eigenvalue of the symmetric 2x2.
    let (a, b, c) = (cov[0][0], 0.5 * (cov[0][1] + cov[1][0]), cov[1][1]);
    let worst = 0.5 * (a + c) + (0.25 * (a - c).powi(2) + b * b).sqrt();
    let worst_se_mm = worst.max(0.0).sqrt();
    // The angle error a centre error makes at phi, per unit of (dc_u, dc_v):
    // g(phi) = (sin phi, -cos phi) / R; its mean over the points removed.
    let r = fit.radius_mm;
    let m = count.max(1) as f64;
    let (gs, gc) = (sum_sin / m, sum_cos / m);
    let (mut over_arc, inv_r) = (0.0f64, 1.0 / r);
    for (x, y, dist) in points().filter_map(|(p, _)| direction(p)) {
        let inv = 1.0 / dist;
        let g = [(y * inv - gs) * inv_r, (-x * inv + gc) * inv_r];
        let var = g[0] * g[0] * a + 2.0 * g[0] * g[1] * b + g[1] * g[1] * c;
        over_arc = over_arc.max(var);
    }
    // The arc: 360 less the largest gap between the raw angles.
    let gap = largest_gap(phi, count);
    let arc_deg = (std::f64::consts::TAU - gap).to_degrees().max(0.0);
    CenterKnowledge {
        cov,
        worst_se_mm,
        once_per_rev_se_deg: (worst_se_mm / r).to_degrees(),
        arc_deg,
        over_arc_se_deg: over_arc.max(0.0).sqrt().to_degrees(),
    }
}

/// The largest gap between `count` angles (radians, within a turn) taken
/// in ascending order, the one across the turn's end (from the largest
/// round to the smallest) included: what sorting them gives, to the bit,
/// without sorting (a sort of every sample's angle was a twentieth of the
/// processing). `angles` makes them anew for each pass.
///
/// The angles fall into `count / 4` buckets of equal width between the
/// smallest and the largest; the bucket of an angle never decreases as the
/// angle grows (each step of its arithmetic is monotonic), so consecutive
/// angles are in one bucket or in consecutive non-empty ones. A gap between
/// buckets is the next one's least less the last one's largest; a gap
/// inside a bucket is at most its largest less its least. When the largest
/// gap between buckets is at least every bucket's span, it is the largest
/// gap; otherwise (angles spread evenly, no clusters) they are sorted.
fn largest_gap<I: Iterator<Item = f64>>(angles: impl Fn() -> I, count: usize) -> f64 {
    let (lo, hi) = angles().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), a| (lo.min(a), hi.max(a)));
    if count == 0 || lo > hi {
        return 0.0;
    }
    let wrap = lo + std::f64::consts::TAU - hi;
    let buckets = (count / 4).max(1);
    let scale = if hi > lo { buckets as f64 / (hi - lo) } else { 0.0 };
    let mut range = vec![(f64::INFINITY, f64::NEG_INFINITY); buckets];
    for a in angles() {
        let b = (((a - lo) * scale) as usize).min(buckets - 1);
        range[b] = (range[b].0.min(a), range[b].1.max(a));
    }
    let (mut best, mut span, mut last) = (wrap.max(0.0), 0.0f64, None::<f64>);
    for &(least, largest) in range.iter().filter(|r| r.0 <= r.1) {
        if let Some(previous) = last {
            best = best.max(least - previous);
        }
        span = span.max(largest - least);
        last = Some(largest);
    }
    if best >= span {
        return best;
    }
    drop(range);
    let mut sorted: Vec<f64> = angles().collect();
    sorted.sort_unstable_by(f64::total_cmp);
    sorted_largest_gap(&sorted)
}

/// [`largest_gap`] of angles sorted ascending.
fn sorted_largest_gap(sorted: &[f64]) -> f64 {
    sorted
        .windows(2)
        .map(|w| w[1] - w[0])
        .chain(sorted.first().zip(sorted.last()).map(|(f, l)| f + std::f64::consts::TAU - l))
        .fold(0.0, f64::max)
}

impl AxisFit {
    /// Angle of an SMR position, degrees, the representative closest to
    /// `near_deg` (so -10..90 elevation axes and angles past 360 work): the raw
    /// angle of its projection in the plane minus `zero_offset_deg`, unwrapped to
    /// within +-180 of `near_deg`.
    pub fn angle_deg(&self, p_mm: [f64; 3], near_deg: f64) -> f64 {
        self.angle_of_raw(self.raw_angle(p_mm), near_deg)
    }

    /// The raw angle of an SMR position, radians: the direction of its
    /// projection in the plane around the centre, from `u` towards `v`.
    pub fn raw_angle(&self, p_mm: [f64; 3]) -> f64 {
        let d = sub(p_mm, self.center_mm);
        dot(d, self.v).atan2(dot(d, self.u))
    }

    /// [`AxisFit::angle_deg`] of a position whose raw angle
    /// ([`AxisFit::raw_angle`]) is `raw_rad`.
    pub fn angle_of_raw(&self, raw_rad: f64, near_deg: f64) -> f64 {
        near_deg + wrap_180(raw_rad.to_degrees() - self.zero_offset_deg - near_deg)
    }
}

/// Circle through 2-D points: Kasa's algebraic fit, refined by Gauss-Newton on
/// the geometric distance. Returns `(centre x, centre y, radius)` and the sum
/// of the squared distances from the circle.
/// `xy` makes the points anew for each pass over them.
fn fit_circle<I: Iterator<Item = [f64; 2]>>(xy: impl Fn() -> I + Copy) -> Option<(f64, f64, f64, f64)> {
    // Kasa: x^2 + y^2 + D x + E y + F = 0, linear least squares in (D, E, F).
    let mut m = [[0.0; 3]; 3];
    let mut rhs = [0.0; 3];
    for q in xy() {
        let row = [q[0], q[1], 1.0];
        let w = q[0] * q[0] + q[1] * q[1];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += row[i] * row[j];
            }
            rhs[i] -= row[i] * w;
        }
    }
    let [d, e, f] = solve3(m, rhs)?;
    let (mut a, mut b) = (-d / 2.0, -e / 2.0);
    let r2 = a * a + b * b - f;
    if r2.is_nan() || r2 <= 0.0 {
        return None;
    }
    let mut r = r2.sqrt();

    // Gauss-Newton on r_k = |q_k - c| - r, halving a step that does not reduce
    // the cost. The cost at a point and the normal equations there take the
    // same distances: both come from one pass, so an accepted step's pass
    // also gives the next step's equations. A step within the convergence
    // tolerance ends the fit untaken (it moves the circle by less than
    // rounding, and taking it would cost a pass); a halved step reaching it
    // ends the fit whether it is taken or not: one that does not reduce the
    // cost is not halved further (at convergence the cost no longer falls
    // but by rounding, and twenty halvings cost twenty passes).
    let mut current = gauss_newton_pass(xy(), a, b, r);
    for _ in 0..50 {
        let Some(step) = solve3(current.jtj, current.jtr) else { break };
        let (norm, tolerance) = ((step[0].powi(2) + step[1].powi(2) + step[2].powi(2)).sqrt(), 1e-14 * (1.0 + r));
        if norm <= tolerance {
            break;
        }
        let mut k = 1.0;
        let mut accepted = false;
        for _ in 0..20 {
            let (na, nb, nr) = (a + k * step[0], b + k * step[1], r + k * step[2]);
            let next = gauss_newton_pass(xy(), na, nb, nr);
            if next.cost <= current.cost {
                (a, b, r, current) = (na, nb, nr, next);
                accepted = true;
                break;
            }
            if norm * k <= tolerance {
                break;
            }
            k /= 2.0;
        }
        if !accepted || norm * k <= 1e-14 * (1.0 + r) {
            break;
        }
    }
    let cost = if r >= 0.0 { current.cost } else { gauss_newton_pass(xy(), a, b, -r).cost };
    Some((a, b, r.abs(), cost))
}

/// The circle fit's sum of squared residuals `|q_k - c| - r` at centre
/// `(a, b)` and radius `r`, and the Gauss-Newton normal equations there
/// (`JᵀJ`, `-Jᵀr`; a point at the centre has no direction and is left out of
/// them).
struct GaussNewtonPass {
    cost: f64,
    jtj: [[f64; 3]; 3],
    jtr: [f64; 3],
}

fn gauss_newton_pass(xy: impl Iterator<Item = [f64; 2]>, a: f64, b: f64, r: f64) -> GaussNewtonPass {
    // The Jacobian's row is `(-dx / dist, -dy / dist, -1)`: the sums of
    // `JᵀJ`'s five distinct entries besides the count, and of `Jᵀr`.
    let (mut cost, mut count) = (0.0, 0.0);
    let (mut xx, mut xy_, mut yy, mut x, mut y) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut rx, mut ry, mut rr) = (0.0, 0.0, 0.0);
    for q in xy {
        let (dx, dy) = (q[0] - a, q[1] - b);
        let dist = norm2(dx, dy);
        let res = dist - r;
        cost += res * res;
        if dist == 0.0 {
            continue;
        }
        let inv = 1.0 / dist;
        let (jx, jy) = (-dx * inv, -dy * inv);
        xx += jx * jx;
        xy_ += jx * jy;
        yy += jy * jy;
        x += jx;
        y += jy;
        count += 1.0;
        rx += jx * res;
        ry += jy * res;
        rr += res;
    }
    GaussNewtonPass { cost, jtj: [[xx, xy_, -x], [xy_, yy, -y], [-x, -y, count]], jtr: [-rx, -ry, rr] }
}

/// Solves `m x = rhs` by Gaussian elimination with partial pivoting; `None`
/// when `m` is singular to working precision.
fn solve3(mut m: [[f64; 3]; 3], mut rhs: [f64; 3]) -> Option<[f64; 3]> {
    let biggest = m.iter().flatten().fold(0.0f64, |acc, x| acc.max(x.abs()));
    if biggest == 0.0 || !biggest.is_finite() {
        return None;
    }
    for col in 0..3 {
        let pivot = (col..3).max_by(|&i, &j| m[i][col].abs().total_cmp(&m[j][col].abs()))?;
        if m[pivot][col].abs() <= 1e-13 * biggest {
            return None;
        }
        m.swap(col, pivot);
        rhs.swap(col, pivot);
        for row in col + 1..3 {
            let k = m[row][col] / m[col][col];
            let pivot_row = m[col];
            for (x, p) in m[row][col..].iter_mut().zip(&pivot_row[col..]) {
                *x -= k * p;
            }
            rhs[row] -= k * rhs[col];
        }
    }
    let mut x = [0.0; 3];
    for row in (0..3).rev() {
        let tail: f64 = (row + 1..3).map(|c| m[row][c] * x[c]).sum();
        x[row] = (rhs[row] - tail) / m[row][row];
    }
    Some(x)
}

/// Eigen-decomposition of a symmetric 3x3 matrix by cyclic Jacobi rotations.
/// Returns the eigenvalues in ascending order and the matching unit
/// eigenvectors (`vectors[k]` belongs to `values[k]`).
fn sym_eigen3(m: [[f64; 3]; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let mut a = m;
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let norm2: f64 = a.iter().flatten().map(|x| x * x).sum();
    for _sweep in 0..64 {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        if off <= 1e-34 * norm2 || off == 0.0 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            // The rotation that zeroes a[p][q] (Numerical Recipes' form).
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = if theta.abs() > 1e150 {
                0.5 / theta
            } else {
                theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt())
            };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for row in a.iter_mut() {
                let (kp, kq) = (row[p], row[q]);
                row[p] = c * kp - s * kq;
                row[q] = s * kp + c * kq;
            }
            let (rp, rq) = (a[p], a[q]);
            a[p] = std::array::from_fn(|k| c * rp[k] - s * rq[k]);
            a[q] = std::array::from_fn(|k| s * rp[k] + c * rq[k]);
            for row in v.iter_mut() {
                let (kp, kq) = (row[p], row[q]);
                row[p] = c * kp - s * kq;
                row[q] = s * kp + c * kq;
            }
        }
    }
    let mut order = [0, 1, 2];
    order.sort_by(|&i, &j| a[i][i].total_cmp(&a[j][j]));
    let values = order.map(|k| a[k][k]);
    let vectors = order.map(|k| [v[0][k], v[1][k], v[2][k]]);
    (values, vectors)
}

#[cfg(test)]
mod tests;
