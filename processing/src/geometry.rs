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
    let n = points_mm.len();
    if n != readouts_deg.len() {
        return Err(GeometryError::LengthMismatch { points: n, readouts: readouts_deg.len() });
    }
    if n < 3 {
        return Err(GeometryError::TooFewPoints(n));
    }
    for (index, (p, &r)) in points_mm.iter().zip(readouts_deg).enumerate() {
        for (what, value) in [("x", p[0]), ("y", p[1]), ("z", p[2]), ("readout", r)] {
            if !value.is_finite() {
                return Err(GeometryError::NonFinite { index, what, value });
            }
        }
    }

    // 1. Plane: centroid and the smallest eigenvector of the covariance.
    let nf = n as f64;
    let centroid = scale(points_mm.iter().fold([0.0; 3], |acc, &p| add(acc, p)), 1.0 / nf);
    let mut cov = [[0.0; 3]; 3];
    for &p in points_mm {
        let d = sub(p, centroid);
        for (i, row) in cov.iter_mut().enumerate() {
            for (j, c) in row.iter_mut().enumerate() {
                *c += d[i] * d[j] / nf;
            }
        }
    }
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
    let xy: Vec<[f64; 2]> = points_mm
        .iter()
        .map(|&p| {
            let d = sub(p, centroid);
            [dot(d, u) / spread, dot(d, v) / spread]
        })
        .collect();
    let (mut a, mut b, r) = fit_circle(&xy)
        .ok_or_else(|| GeometryError::Degenerate("the projected positions do not determine a circle".into()))?;
    let radius_mm = r * spread;
    if !radius_mm.is_finite() || !a.is_finite() || !b.is_finite() || radius_mm <= 1e-9 * spread {
        return Err(GeometryError::Degenerate(format!(
            "the fitted circle is degenerate (radius {radius_mm} mm over a spread of {spread} mm)"
        )));
    }
    let circle_rms_mm = spread * (xy.iter().map(|q| ((q[0] - a).hypot(q[1] - b) - r).powi(2)).sum::<f64>() / nf).sqrt();
    let plane_rms_mm = (points_mm.iter().map(|&p| dot(sub(p, centroid), normal).powi(2)).sum::<f64>() / nf).sqrt();

    // 3. Orientation. With theta the raw angles and r the readouts, the sum over
    // pairs of sin(theta_j - theta_i) sin(r_j - r_i) is positive when the angles
    // increase with the readouts; it equals (|sum e^{i(theta - r)}|^2 -
    // |sum e^{i(theta + r)}|^2) / 4, which needs no pairs and no unwrapping.
    let mut raw: Vec<f64> = xy.iter().map(|q| (q[1] - b).atan2(q[0] - a).to_degrees()).collect();
    let resultant = |sign: f64| {
        let (s, c) = raw.iter().zip(readouts_deg).fold((0.0, 0.0), |(s, c), (t, r)| {
            let x = (t + sign * r).to_radians();
            (s + x.sin(), c + x.cos())
        });
        s * s + c * c
    };
    let orientation = (resultant(-1.0) - resultant(1.0)) / 4.0;
    if orientation.abs() <= 1e-9 * nf * nf {
        return Err(GeometryError::Degenerate(
            "the readouts do not vary enough to tell the direction of rotation".into(),
        ));
    }
    if orientation < 0.0 {
        normal = scale(normal, -1.0);
        v = scale(v, -1.0);
        b = -b;
        raw.iter_mut().for_each(|t| *t = -*t);
    }

    // 4. Zero: the mean over the fit points of wrap_180(raw - zero - readout) is zero.
    // A circular mean first (robust to the wrap), then the arithmetic mean of the
    // wrapped differences around it.
    let diffs: Vec<f64> = raw.iter().zip(readouts_deg).map(|(t, r)| t - r).collect();
    let (s, c) = diffs.iter().fold((0.0, 0.0), |(s, c), d| (s + d.to_radians().sin(), c + d.to_radians().cos()));
    let z0 = s.atan2(c).to_degrees();
    let z = z0 + diffs.iter().map(|d| wrap_180(d - z0)).sum::<f64>() / nf;

    a *= spread;
    b *= spread;
    Ok(AxisFit {
        center_mm: add(centroid, add(scale(u, a), scale(v, b))),
        normal,
        u,
        v,
        radius_mm,
        zero_offset_deg: wrap_180(z),
        plane_rms_mm,
        circle_rms_mm,
        points: n,
    })
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
    let first = fit_axis(points_mm, readouts_deg)?;
    let residual = |f: &AxisFit, p: [f64; 3]| {
        let d = sub(p, f.center_mm);
        let h = dot(d, f.normal);
        let in_plane = sub(d, scale(f.normal, h));
        (dot(in_plane, in_plane).sqrt() - f.radius_mm).hypot(h)
    };
    let r: Vec<f64> = points_mm.iter().map(|&p| residual(&first, p)).collect();
    let mut sorted = r.clone();
    sorted.sort_by(f64::total_cmp);
    let mad = sorted[sorted.len() / 2];
    let limit = 5.0 * 1.4826 * mad;
    let keep: Vec<usize> = (0..points_mm.len()).filter(|&i| limit <= 0.0 || r[i] <= limit).collect();
    let dropped = points_mm.len() - keep.len();
    let (fit, kept) = if dropped == 0 || keep.len() < 3 {
        (first, points_mm.to_vec())
    } else {
        let pts: Vec<[f64; 3]> = keep.iter().map(|&i| points_mm[i]).collect();
        let ro: Vec<f64> = keep.iter().map(|&i| readouts_deg[i]).collect();
        (fit_axis(&pts, &ro)?, pts)
    };
    let knowledge = center_knowledge(&fit, &kept);
    Ok(Refit {
        fit,
        dropped: if dropped == 0 || keep.len() < 3 { 0 } else { dropped },
        center_cov_mm2: knowledge.cov,
        center_se_mm: knowledge.worst_se_mm,
        once_per_rev_se_deg: knowledge.once_per_rev_se_deg,
        arc_deg: knowledge.arc_deg,
        over_arc_se_deg: knowledge.over_arc_se_deg,
    })
}

/// How well a fitted circle's centre is known from its points.
struct CenterKnowledge {
    cov: [[f64; 2]; 2],
    worst_se_mm: f64,
    once_per_rev_se_deg: f64,
    arc_deg: f64,
    over_arc_se_deg: f64,
}

fn center_knowledge(fit: &AxisFit, points_mm: &[[f64; 3]]) -> CenterKnowledge {
    let n = points_mm.len();
    let mut jtj = [[0.0; 3]; 3];
    let mut ss = 0.0;
    let mut phi = Vec::with_capacity(n);
    for &p in points_mm {
        let d = sub(p, fit.center_mm);
        let (x, y) = (dot(d, fit.u), dot(d, fit.v));
        let dist = x.hypot(y);
        if dist == 0.0 {
            continue;
        }
        let jac = [-x / dist, -y / dist, -1.0];
        for i in 0..3 {
            for j in 0..3 {
                jtj[i][j] += jac[i] * jac[j];
            }
        }
        ss += (dist - fit.radius_mm).powi(2);
        phi.push(y.atan2(x));
    }
    let s2 = ss / (phi.len().saturating_sub(3)).max(1) as f64;
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
    // The arc: 360 less the largest gap between the sorted raw angles.
    let mut sorted = phi.clone();
    sorted.sort_by(f64::total_cmp);
    let gap = sorted
        .windows(2)
        .map(|w| w[1] - w[0])
        .chain(sorted.first().zip(sorted.last()).map(|(f, l)| f + std::f64::consts::TAU - l))
        .fold(0.0, f64::max);
    let arc_deg = (std::f64::consts::TAU - gap).to_degrees().max(0.0);
    // The angle error a centre error makes at phi, per unit of (dc_u, dc_v):
    // g(phi) = (sin phi, -cos phi) / R; its mean over the points removed.
    let r = fit.radius_mm;
    let m = phi.len().max(1) as f64;
    let (gs, gc) = phi.iter().fold((0.0, 0.0), |(s, c), p| (s + p.sin() / m, c + p.cos() / m));
    let mut over_arc = 0.0f64;
    for p in &phi {
        let g = [(p.sin() - gs) / r, (-p.cos() + gc) / r];
        let var = g[0] * g[0] * a + 2.0 * g[0] * g[1] * b + g[1] * g[1] * c;
        over_arc = over_arc.max(var);
    }
    CenterKnowledge {
        cov,
        worst_se_mm,
        once_per_rev_se_deg: (worst_se_mm / r).to_degrees(),
        arc_deg,
        over_arc_se_deg: over_arc.max(0.0).sqrt().to_degrees(),
    }
}

impl AxisFit {
    /// Angle of an SMR position, degrees, the representative closest to
    /// `near_deg` (so -10..90 elevation axes and angles past 360 work): the raw
    /// angle of its projection in the plane minus `zero_offset_deg`, unwrapped to
    /// within +-180 of `near_deg`.
    pub fn angle_deg(&self, p_mm: [f64; 3], near_deg: f64) -> f64 {
        let d = sub(p_mm, self.center_mm);
        let raw = dot(d, self.v).atan2(dot(d, self.u)).to_degrees();
        near_deg + wrap_180(raw - self.zero_offset_deg - near_deg)
    }
}

/// Circle through 2-D points: Kasa's algebraic fit, refined by Gauss-Newton on
/// the geometric distance. Returns `(centre x, centre y, radius)`.
fn fit_circle(xy: &[[f64; 2]]) -> Option<(f64, f64, f64)> {
    // Kasa: x^2 + y^2 + D x + E y + F = 0, linear least squares in (D, E, F).
    let mut m = [[0.0; 3]; 3];
    let mut rhs = [0.0; 3];
    for q in xy {
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

    // Gauss-Newton on r_k = |q_k - c| - r, halving a step that does not reduce the cost.
    let cost = |a: f64, b: f64, r: f64| xy.iter().map(|q| ((q[0] - a).hypot(q[1] - b) - r).powi(2)).sum::<f64>();
    let mut current = cost(a, b, r);
    for _ in 0..50 {
        let mut jtj = [[0.0; 3]; 3];
        let mut jtr = [0.0; 3];
        for q in xy {
            let dist = (q[0] - a).hypot(q[1] - b);
            if dist == 0.0 {
                continue;
            }
            let jac = [-(q[0] - a) / dist, -(q[1] - b) / dist, -1.0];
            let res = dist - r;
            for i in 0..3 {
                for j in 0..3 {
                    jtj[i][j] += jac[i] * jac[j];
                }
                jtr[i] -= jac[i] * res;
            }
        }
        let Some(step) = solve3(jtj, jtr) else { break };
        let mut k = 1.0;
        let mut accepted = false;
        for _ in 0..20 {
            let (na, nb, nr) = (a + k * step[0], b + k * step[1], r + k * step[2]);
            let c = cost(na, nb, nr);
            if c <= current {
                (a, b, r, current) = (na, nb, nr, c);
                accepted = true;
                break;
            }
            k /= 2.0;
        }
        let size = (step[0].powi(2) + step[1].powi(2) + step[2].powi(2)).sqrt() * k;
        if !accepted || size <= 1e-14 * (1.0 + r) {
            break;
        }
    }
    Some((a, b, r.abs()))
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
mod tests {
    use super::*;
    use crate::types::wrap_360;

    /// A seeded xorshift64* generator with Box-Muller normals (rand is not a
    /// dependency of this crate).
    struct Rng(u64);

    impl Rng {
        fn next_u64(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
        }

        /// Uniform in (0, 1].
        fn uniform(&mut self) -> f64 {
            ((self.next_u64() >> 11) + 1) as f64 / (1u64 << 53) as f64
        }

        fn normal(&mut self) -> f64 {
            let (u1, u2) = (self.uniform(), self.uniform());
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        }
    }

    /// Rotation matrix about unit `axis` by `deg` (Rodrigues).
    fn rotation(axis: V3, deg: f64) -> [[f64; 3]; 3] {
        let k = normalize(axis);
        let (s, c) = deg.to_radians().sin_cos();
        let mut r = [[0.0; 3]; 3];
        for (i, row) in r.iter_mut().enumerate() {
            for (j, x) in row.iter_mut().enumerate() {
                let kx = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]][i][j];
                *x = if i == j { c } else { 0.0 } + s * kx + (1.0 - c) * k[i] * k[j];
            }
        }
        r
    }

    fn column(m: [[f64; 3]; 3], j: usize) -> V3 {
        [m[0][j], m[1][j], m[2][j]]
    }

    fn angle_between_deg(a: V3, b: V3) -> f64 {
        (dot(a, b) / (dot(a, a) * dot(b, b)).sqrt()).clamp(-1.0, 1.0).acos().to_degrees()
    }

    /// The true geometry: an SMR on a 1000 mm arm about an axis through
    /// `center`, with the plane tilted by 0.5 deg and the arm mounted 37 deg
    /// from the frame's `u`.
    struct Truth {
        center: V3,
        u: V3,
        v: V3,
        n: V3,
        radius: f64,
        phase_deg: f64,
    }

    impl Truth {
        fn standard() -> Self {
            let r = rotation([0.6, 0.8, 0.0], 0.5);
            let (u, v) = (column(r, 0), column(r, 1));
            Truth { center: [2500.0, 800.0, -300.0], u, v, n: cross(u, v), radius: 1000.0, phase_deg: 37.0 }
        }

        /// The SMR position at axis angle `theta_deg`.
        fn point(&self, theta_deg: f64) -> V3 {
            let (s, c) = (theta_deg + self.phase_deg).to_radians().sin_cos();
            add(self.center, add(scale(self.u, self.radius * c), scale(self.v, self.radius * s)))
        }

        fn noisy(&self, theta_deg: f64, rng: &mut Rng, sigma: f64) -> V3 {
            add(self.point(theta_deg), [sigma * rng.normal(), sigma * rng.normal(), sigma * rng.normal()])
        }

        /// Standard errors predicted by linearised least squares for noise
        /// `sigma` per coordinate at axis angles `thetas`: (centre along u, along
        /// v, along n, radius, normal tilt in radians).
        fn predicted(&self, thetas: &[f64], sigma: f64) -> [f64; 5] {
            let inverse = |m: [[f64; 3]; 3]| -> [[f64; 3]; 3] {
                let cols = [0, 1, 2].map(|k| {
                    let mut e = [0.0; 3];
                    e[k] = 1.0;
                    solve3(m, e).unwrap()
                });
                [0, 1, 2].map(|i| [0, 1, 2].map(|j| cols[j][i]))
            };
            // Circle: residual derivatives [cos phi, sin phi, 1] for (centre u, centre v, radius).
            let mut jtj = [[0.0; 3]; 3];
            // Plane: height = h0 + t1 x + t2 y, rows [1, x, y] in the plane's frame about the centroid.
            let phis: Vec<f64> = thetas.iter().map(|t| (t + self.phase_deg).to_radians()).collect();
            let nf = phis.len() as f64;
            let xm = phis.iter().map(|p| self.radius * p.cos()).sum::<f64>() / nf;
            let ym = phis.iter().map(|p| self.radius * p.sin()).sum::<f64>() / nf;
            let mut xtx = [[0.0; 3]; 3];
            for p in &phis {
                let jr = [p.cos(), p.sin(), 1.0];
                let xr = [1.0, self.radius * p.cos() - xm, self.radius * p.sin() - ym];
                for i in 0..3 {
                    for j in 0..3 {
                        jtj[i][j] += jr[i] * jr[j];
                        xtx[i][j] += xr[i] * xr[j];
                    }
                }
            }
            let cc = inverse(jtj);
            let cp = inverse(xtx);
            // The centre's height error: the plane's height at the centre, (-xm, -ym) from the centroid.
            let g = [1.0, -xm, -ym];
            let h2: f64 = (0..3).flat_map(|i| (0..3).map(move |j| (i, j))).map(|(i, j)| g[i] * cp[i][j] * g[j]).sum();
            [
                sigma * cc[0][0].sqrt(),
                sigma * cc[1][1].sqrt(),
                sigma * h2.sqrt(),
                sigma * cc[2][2].sqrt(),
                sigma * (cp[1][1] + cp[2][2]).sqrt(),
            ]
        }
    }

    const SIGMA_MM: f64 = 0.016;

    /// Fits noisy points at `thetas` (readouts = true angles) and checks the
    /// centre, normal, radius, residuals and the angles of 360 further noisy
    /// points spread over `test_range`.
    fn check_geometry(thetas: &[f64], test_range: (f64, f64), seed: u64) {
        let truth = Truth::standard();
        let mut rng = Rng(seed);
        let points: Vec<V3> = thetas.iter().map(|&t| truth.noisy(t, &mut rng, SIGMA_MM)).collect();
        let fit = fit_axis(&points, thetas).unwrap();
        let [s_u, s_v, s_n, s_r, s_tilt] = truth.predicted(thetas, SIGMA_MM);
        let n = thetas.len() as f64;

        // Centre, per component of the true frame, within 5 predicted standard
        // errors (P(|z| > 5) = 6e-7). For n points evenly spread over a revolution
        // the prediction is sigma*sqrt(2/n) in the plane and sigma/sqrt(n) along
        // the axis; on a partial arc it is larger and comes from the same algebra.
        let dc = sub(fit.center_mm, truth.center);
        for (name, got, sd) in
            [("u", dot(dc, truth.u), s_u), ("v", dot(dc, truth.v), s_v), ("n", dot(dc, truth.n), s_n)]
        {
            assert!(got.abs() <= 5.0 * sd, "centre error along {name}: {got} mm > 5 x {sd} mm");
        }
        // Normal (sign included: readouts are the true angles, so the fit must
        // point along the true n), within 5 x the predicted tilt error.
        let tilt = angle_between_deg(fit.normal, truth.n);
        assert!(tilt <= 5.0 * s_tilt.to_degrees(), "normal off by {tilt} deg > 5 x {} deg", s_tilt.to_degrees());
        assert!((fit.radius_mm - truth.radius).abs() <= 5.0 * s_r, "radius {} mm, sd {s_r}", fit.radius_mm);
        // The frame is orthonormal and right-handed.
        assert!((dot(fit.u, fit.u) - 1.0).abs() < 1e-12 && dot(fit.u, fit.v).abs() < 1e-12);
        assert!(angle_between_deg(cross(fit.u, fit.v), fit.normal) < 1e-9);
        // Residual RMS estimate sigma with n - 3 degrees of freedom: E[rms^2] =
        // sigma^2 (n - 3) / n; 0.15 to 2 sigma holds for any plausible draw and
        // fails for residuals in wrong units or of a wrong fit.
        for (name, rms) in [("plane", fit.plane_rms_mm), ("circle", fit.circle_rms_mm)] {
            assert!((0.15 * SIGMA_MM..2.0 * SIGMA_MM).contains(&rms), "{name} rms {rms} mm");
        }
        assert_eq!(fit.points, thetas.len());

        // Angles. The readouts are the true angles, so the mean readout error at
        // the fit points is zero and the recovered angle should be the true one.
        // One point's transverse noise is sigma_deg = sigma / R in degrees; 4 of
        // those (360 draws: P(max > 4 sd) ~ 2 %) plus 5 x the fit's own angular
        // uncertainty: the centre's in-plane error over R, plus the zero
        // offset's error sigma_deg / sqrt(n).
        let sigma_deg = (SIGMA_MM / truth.radius).to_degrees();
        let fit_deg = (s_u.hypot(s_v) / truth.radius).to_degrees() + sigma_deg / n.sqrt();
        let tol = 4.0 * sigma_deg + 5.0 * fit_deg;
        let mut worst = 0.0f64;
        for k in 0..360 {
            let theta = test_range.0 + (test_range.1 - test_range.0) * k as f64 / 359.0;
            let p = truth.noisy(theta, &mut rng, SIGMA_MM);
            let got = fit.angle_deg(p, theta);
            worst = worst.max((got - theta).abs());
        }
        assert!(worst <= tol, "worst angle error {worst} deg > {tol} deg");
    }

    #[test]
    fn full_revolution_of_twelve_points() {
        let thetas: Vec<f64> = (0..12).map(|k| 30.0 * k as f64).collect();
        check_geometry(&thetas, (0.0, 360.0), 0x5eed_0001);
    }

    #[test]
    fn elevation_arc_of_nine_points_from_minus_10_to_90() {
        let thetas: Vec<f64> = (0..9).map(|k| -10.0 + 12.5 * k as f64).collect();
        check_geometry(&thetas, (-10.0, 90.0), 0x5eed_0002);
    }

    #[test]
    fn several_seeds_full_and_partial() {
        let full: Vec<f64> = (0..12).map(|k| 30.0 * k as f64).collect();
        let arc: Vec<f64> = (0..9).map(|k| -10.0 + 12.5 * k as f64).collect();
        for seed in 1..=20u64 {
            check_geometry(&full, (0.0, 360.0), seed * 7919);
            check_geometry(&arc, (-10.0, 90.0), seed * 104_729);
        }
    }

    /// The zero offset makes the mean readout error over the fit points zero.
    /// With contract sign `error = readout - actual`, the recovered angle is
    /// therefore `actual + mean(error at the fit points)`. With 12 points evenly
    /// spread, harmonics 1 and 3 average to zero and only the constant remains;
    /// harmonic 12 aliases onto the constant and does not cancel.
    #[test]
    fn zero_offset_cancels_harmonics_that_are_not_multiples_of_the_point_count() {
        let truth = Truth::standard();
        let thetas: Vec<f64> = (0..12).map(|k| 30.0 * k as f64 + 5.0).collect();
        let points: Vec<V3> = thetas.iter().map(|&t| truth.point(t)).collect();
        let cases: [(&dyn Fn(f64) -> f64, f64); 2] = [
            (&|t: f64| 0.05 + 0.02 * (t + 10.0).to_radians().sin() + 0.01 * (3.0 * t + 40.0).to_radians().sin(), 0.05),
            // 0.01 sin(12 (30 k + 5) + 30) = 0.01 sin(90 deg) at every point.
            (&|t: f64| 0.01 * (12.0 * t + 30.0).to_radians().sin(), 0.01),
        ];
        for (error, mean_error) in cases {
            let readouts: Vec<f64> = thetas.iter().map(|&t| t + error(t)).collect();
            let fit = fit_axis(&points, &readouts).unwrap();
            for k in 0..360 {
                let theta = k as f64;
                let got = fit.angle_deg(truth.point(theta), theta);
                // Noise-free points: only rounding remains (1e-9 deg is 2e-8 mm on the arm).
                assert!((got - (theta + mean_error)).abs() < 1e-9, "at {theta}: {got}, want {}", theta + mean_error);
            }
        }
    }

    #[test]
    fn readouts_in_decreasing_order_give_the_same_axis() {
        let truth = Truth::standard();
        let mut rng = Rng(77);
        let thetas: Vec<f64> = (0..12).map(|k| 30.0 * k as f64).collect();
        let points: Vec<V3> = thetas.iter().map(|&t| truth.noisy(t, &mut rng, SIGMA_MM)).collect();
        let fit = fit_axis(&points, &thetas).unwrap();
        let rev_points: Vec<V3> = points.iter().rev().copied().collect();
        let rev_thetas: Vec<f64> = thetas.iter().rev().copied().collect();
        let rev = fit_axis(&rev_points, &rev_thetas).unwrap();
        assert!(angle_between_deg(rev.normal, truth.n) < 0.01, "normal flipped: {:?}", rev.normal);
        // Same data in another order: equal up to rounding.
        assert!(sub(rev.center_mm, fit.center_mm).iter().all(|d| d.abs() < 1e-9));
        for k in 0..360 {
            let p = truth.point(k as f64);
            assert!((rev.angle_deg(p, k as f64) - fit.angle_deg(p, k as f64)).abs() < 1e-9);
        }
        // And a scrambled order, an arc swept downwards.
        let order = [5, 0, 11, 3, 8, 1, 10, 6, 2, 9, 4, 7];
        let sp: Vec<V3> = order.iter().map(|&i| points[i]).collect();
        let st: Vec<f64> = order.iter().map(|&i| thetas[i]).collect();
        let scrambled = fit_axis(&sp, &st).unwrap();
        assert!(angle_between_deg(scrambled.normal, truth.n) < 0.01);
        let arc: Vec<f64> = (0..9).rev().map(|k| -10.0 + 12.5 * k as f64).collect();
        let arc_points: Vec<V3> = arc.iter().map(|&t| truth.point(t)).collect();
        let down = fit_axis(&arc_points, &arc).unwrap();
        assert!(angle_between_deg(down.normal, truth.n) < 1e-6);
        assert!((down.angle_deg(truth.point(45.0), 0.0) - 45.0).abs() < 1e-9);
    }

    /// A mirrored tracker frame (x -> -x) turns the rotation clockwise about the
    /// mirrored normal: the fit must flip the normal so that angles still
    /// increase with the readouts. The normal for which they increase is
    /// `M u x M v = -M n`.
    #[test]
    fn a_mirrored_frame_still_gives_increasing_angles() {
        let truth = Truth::standard();
        let mirror = |p: V3| [-p[0], p[1], p[2]];
        let thetas: Vec<f64> = (0..12).map(|k| 30.0 * k as f64).collect();
        let mut rng = Rng(99);
        let points: Vec<V3> = thetas.iter().map(|&t| mirror(truth.noisy(t, &mut rng, SIGMA_MM))).collect();
        let fit = fit_axis(&points, &thetas).unwrap();
        let want_normal = scale(mirror(truth.n), -1.0);
        assert!(angle_between_deg(fit.normal, want_normal) < 0.01, "{:?} vs {:?}", fit.normal, want_normal);
        // Noise-free test points: only the fit's error remains, well under 0.01 deg.
        for k in 0..360 {
            let theta = k as f64;
            let got = fit.angle_deg(mirror(truth.point(theta)), theta);
            assert!((got - theta).abs() < 0.01, "at {theta}: {got}");
        }
    }

    #[test]
    fn angle_deg_unwraps_to_the_representative_near_the_hint() {
        let truth = Truth::standard();
        let thetas: Vec<f64> = (0..12).map(|k| 30.0 * k as f64).collect();
        let points: Vec<V3> = thetas.iter().map(|&t| truth.point(t)).collect();
        let fit = fit_axis(&points, &thetas).unwrap();
        let at = |theta: f64, near: f64| fit.angle_deg(truth.point(theta), near);
        for (theta, near, want) in [
            (359.9, 0.0, -0.1),
            (359.9, 360.0, 359.9),
            (359.9, 720.0, 719.9),
            (359.9, -300.0, -360.1),
            (0.1, 359.0, 360.1),
            (0.1, 0.0, 0.1),
            (-5.0, -10.0, -5.0),
            (-5.0, 90.0, -5.0),
            (-5.0, 45.0, -5.0),
            (-5.0, 270.0, 355.0),
            (185.0, 0.0, -175.0),
            (185.0, 100.0, 185.0),
        ] {
            let got = at(theta, near);
            assert!((got - want).abs() < 1e-9, "angle of {theta} near {near}: {got}, want {want}");
        }
        assert!((wrap_360(at(123.0, 0.0)) - 123.0).abs() < 1e-9);
    }

    #[test]
    fn three_points_give_the_exact_circle() {
        let truth = Truth::standard();
        let thetas = [0.0, 100.0, 250.0];
        let points: Vec<V3> = thetas.iter().map(|&t| truth.point(t)).collect();
        let fit = fit_axis(&points, &thetas).unwrap();
        assert!(sub(fit.center_mm, truth.center).iter().all(|d| d.abs() < 1e-8), "{:?}", fit.center_mm);
        assert!((fit.radius_mm - 1000.0).abs() < 1e-8);
        assert!(angle_between_deg(fit.normal, truth.n) < 1e-9);
        assert!(fit.plane_rms_mm < 1e-9 && fit.circle_rms_mm < 1e-9);
    }

    #[test]
    fn errors() {
        let truth = Truth::standard();
        let p: Vec<V3> = [0.0, 120.0, 240.0].iter().map(|&t| truth.point(t)).collect();
        assert_eq!(fit_axis(&p[..2], &[0.0, 120.0]), Err(GeometryError::TooFewPoints(2)));
        assert_eq!(fit_axis(&[], &[]), Err(GeometryError::TooFewPoints(0)));
        assert_eq!(fit_axis(&p, &[0.0, 120.0]), Err(GeometryError::LengthMismatch { points: 3, readouts: 2 }));
        let mut bad = p.clone();
        bad[1][2] = f64::NAN;
        let err = fit_axis(&bad, &[0.0, 120.0, 240.0]).unwrap_err();
        assert!(matches!(err, GeometryError::NonFinite { index: 1, what: "z", .. }), "{err:?}");
        assert_eq!(err.to_string(), "point 1: z is NaN, not a finite number");
        let err = fit_axis(&p, &[0.0, f64::INFINITY, 240.0]).unwrap_err();
        assert!(matches!(err, GeometryError::NonFinite { index: 1, what: "readout", .. }), "{err:?}");

        let line: Vec<V3> = (0..5).map(|k| [k as f64 * 10.0, 2.0 * k as f64, -3.0]).collect();
        let err = fit_axis(&line, &[0.0, 1.0, 2.0, 3.0, 4.0]).unwrap_err();
        assert!(matches!(err, GeometryError::Degenerate(ref m) if m.contains("straight line")), "{err}");
        let same = vec![[1.0, 2.0, 3.0]; 4];
        let err = fit_axis(&same, &[0.0, 1.0, 2.0, 3.0]).unwrap_err();
        assert!(matches!(err, GeometryError::Degenerate(ref m) if m.contains("coincide")), "{err}");
        let err = fit_axis(&p, &[10.0, 10.0, 10.0]).unwrap_err();
        assert!(matches!(err, GeometryError::Degenerate(ref m) if m.contains("direction of rotation")), "{err}");
    }

    #[test]
    fn jacobi_eigen_decomposes_symmetric_matrices() {
        let mut rng = Rng(2024);
        let mut cases = vec![
            [[3.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.0]],
            [[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 3.0]], // eigenvalues 1, 3, 3 (repeated)
            [[1e6, 1e3, 1.0], [1e3, 5e5, 2.0], [1.0, 2.0, 1e-4]], // widely spread, like a covariance
        ];
        for _ in 0..50 {
            let [a, b, c, d, e, f]: [f64; 6] = std::array::from_fn(|_| rng.normal());
            cases.push([[a, b, c], [b, d, e], [c, e, f]]);
        }
        for m in cases {
            let (values, vectors) = sym_eigen3(m);
            let norm = m.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
            assert!(values[0] <= values[1] && values[1] <= values[2], "{values:?}");
            for k in 0..3 {
                let mv = [0, 1, 2].map(|i| dot(m[i], vectors[k]));
                let residual = sub(mv, scale(vectors[k], values[k]));
                assert!(dot(residual, residual).sqrt() <= 1e-12 * norm, "{m:?}: pair {k} residual {residual:?}");
                for j in 0..3 {
                    let want = if j == k { 1.0 } else { 0.0 };
                    assert!((dot(vectors[k], vectors[j]) - want).abs() < 1e-12);
                }
            }
        }
        let (values, _) = sym_eigen3([[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 3.0]]);
        assert!((values[0] - 1.0).abs() < 1e-14 && (values[1] - 3.0).abs() < 1e-14 && (values[2] - 3.0).abs() < 1e-14);
    }

    #[test]
    fn axis_fit_round_trips_through_serde() {
        let truth = Truth::standard();
        let thetas = [0.0, 100.0, 250.0];
        let points: Vec<V3> = thetas.iter().map(|&t| truth.point(t)).collect();
        let fit = fit_axis(&points, &thetas).unwrap();
        let json = serde_json::to_string(&fit).unwrap();
        let back: AxisFit = serde_json::from_str(&json).unwrap();
        // serde_json without its `float_roundtrip` feature may miss the last bit
        // when reading a float back: equal to 1e-15 relative.
        let flat = |f: &AxisFit| {
            let mut v = [f.center_mm, f.normal, f.u, f.v].concat();
            v.extend([f.radius_mm, f.zero_offset_deg, f.plane_rms_mm, f.circle_rms_mm]);
            v
        };
        for (a, b) in flat(&fit).into_iter().zip(flat(&back)) {
            assert!((a - b).abs() <= 1e-15 * a.abs().max(b.abs()), "{a} vs {b}");
        }
        assert_eq!(back.points, fit.points);
        assert!(json.contains("\"center_mm\"") && json.contains("\"zero_offset_deg\""), "{json}");
    }

    /// Thousands of noisy positions with a few glitches: the glitches are
    /// left out, the centre is found within a few of its stated standard
    /// errors, and far better than from 12 positions.
    #[test]
    fn the_refit_from_a_whole_survey_is_robust_and_knows_its_uncertainty() {
        let center = [2500.0, 800.0, -300.0];
        let r_mm = 1000.0;
        let sigma = 0.01; // mm per coordinate
        let mut rng = Rng(0x5eed_1234);
        let point = |deg: f64, rng: &mut Rng| {
            let t = deg.to_radians();
            [
                center[0] + r_mm * t.cos() + sigma * rng.normal(),
                center[1] + r_mm * t.sin() + sigma * rng.normal(),
                center[2] + sigma * rng.normal(),
            ]
        };
        let readouts: Vec<f64> = (0..4000).map(|k| k as f64 * 0.09).collect();
        let mut points: Vec<[f64; 3]> = readouts.iter().map(|&d| point(d, &mut rng)).collect();
        for k in [7, 1500, 2222, 3900] {
            points[k][0] += 5.0; // glitches: 5 mm off
        }
        let refit = refit_axis(&points, &readouts).unwrap();
        assert_eq!(refit.dropped, 4);
        let off = (refit.fit.center_mm[0] - center[0]).hypot(refit.fit.center_mm[1] - center[1]);
        // sigma * sqrt(2 / n) = 2.2e-4 mm; within 4 standard errors.
        assert!((refit.center_se_mm - sigma * (2.0f64 / 3996.0).sqrt()).abs() < 0.2 * refit.center_se_mm, "{refit:?}");
        assert!(off < 4.0 * refit.center_se_mm, "centre off by {off} mm, se {}", refit.center_se_mm);
        let twelve: Vec<usize> = (0..12).map(|k| k * 333 + 1).collect();
        let few = fit_axis(
            &twelve.iter().map(|&k| points[k]).collect::<Vec<_>>(),
            &twelve.iter().map(|&k| readouts[k]).collect::<Vec<_>>(),
        )
        .unwrap();
        let few_off = (few.center_mm[0] - center[0]).hypot(few.center_mm[1] - center[1]);
        assert!(off < few_off, "{off} from 4000 positions against {few_off} from 12");
    }

    /// On a partial arc (100 deg, as an elevation axis) the centre is known
    /// far worse along the arc's bisector than across it; the refit says so,
    /// and its stated uncertainty is what repeated fits show: over 300
    /// surveys of 600 noisy positions, the spread of the centre along the
    /// worst direction and of the angle error it makes over the arc are within
    /// 15 % of the stated standard errors (the spread of 300 draws scatters by
    /// 1 / sqrt(600) = 4 %).
    #[test]
    fn on_a_partial_arc_the_refit_states_what_the_arc_allows() {
        let center = [2500.0, 800.0, -300.0];
        let (r_mm, sigma) = (1000.0, 0.01);
        let mut rng = Rng(0xa4c_0001);
        let readouts: Vec<f64> = (0..600).map(|k| -10.0 + 100.0 * k as f64 / 599.0).collect();
        let mut shifts = Vec::new();
        let mut stated = None;
        for _ in 0..300 {
            let points: Vec<[f64; 3]> = readouts
                .iter()
                .map(|d| {
                    let t = d.to_radians();
                    [
                        center[0] + r_mm * t.cos() + sigma * rng.normal(),
                        center[1] + r_mm * t.sin() + sigma * rng.normal(),
                        center[2] + sigma * rng.normal(),
                    ]
                })
                .collect();
            let refit = refit_axis(&points, &readouts).unwrap();
            shifts.push([refit.fit.center_mm[0] - center[0], refit.fit.center_mm[1] - center[1]]);
            stated.get_or_insert(refit);
        }
        let stated = stated.unwrap();
        assert!((stated.arc_deg - 100.0).abs() < 0.5, "{}", stated.arc_deg);
        // Full circle: sigma sqrt(2 / n) = 5.8e-4 mm; along the bisector of a
        // 100-degree arc the centre trades with the radius (6.4 times worse here).
        assert!(stated.center_se_mm > 4.0 * sigma * (2.0f64 / 600.0).sqrt(), "{stated:?}");
        // The worst direction is the bisector (40 deg): the spread along it.
        let b = 40f64.to_radians();
        let along: Vec<f64> = shifts.iter().map(|d| d[0] * b.cos() + d[1] * b.sin()).collect();
        let sd = |v: &[f64]| {
            let m = v.iter().sum::<f64>() / v.len() as f64;
            (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
        };
        let ratio = sd(&along) / stated.center_se_mm;
        assert!((ratio - 1.0).abs() < 0.15, "spread {} against stated {}", sd(&along), stated.center_se_mm);
        // The angle error over the arc, its mean removed, at the arc's ends
        // (where it is largest): spread against the stated figure.
        let ends: Vec<f64> = shifts
            .iter()
            .map(|d| {
                let err = |deg: f64| {
                    let p = deg.to_radians();
                    (d[0] * p.sin() - d[1] * p.cos()) / r_mm
                };
                let mean = readouts.iter().map(|&x| err(x)).sum::<f64>() / readouts.len() as f64;
                (err(90.0) - mean).to_degrees()
            })
            .collect();
        let ratio = sd(&ends) / stated.over_arc_se_deg;
        assert!((ratio - 1.0).abs() < 0.15, "spread {} against stated {}", sd(&ends), stated.over_arc_se_deg);
        assert!(stated.over_arc_se_deg < stated.once_per_rev_se_deg, "{stated:?}");
    }
}
