//! Axial motion on the axis and tilt from SMRs at different phases.
//!
//! The table rises by its axial motion `Z` and tilts by `t = (t1, t2)`,
//! urad, in the turning frame of the first SMR (`t1` the tilt in its radial
//! direction, `t2` at 90 degrees, in the direction the readout increases). An
//! SMR at radius `R_k` (m), mounted `delta_k` from the first, rises by
//!
//! `a_k = Z + R_k (t1 cos delta_k + t2 sin delta_k)` um,
//!
//! whatever its height. Its axial deviation is read along one normal for
//! every SMR (the first SMR's plane's), from its own circle's centre: a
//! normal off the axis average line by a small angle adds to every `a_k`
//! exactly a once-per-revolution term of that form, so it leaves `Z` and
//! lands in the tilt's once-per-revolution part, which is the location of
//! the axis (A0C, B0C), not a motion, and is taken out of it. So `Z` keeps
//! its own once-per-revolution part (the fundamental axial error motion:
//! the axis's tilt cannot make one on the axis).
//!
//! At each sample `Z` and `t1` (and `t2`) are the least-squares solution of
//! the SMRs' equations: `Z = sum wz_k a_k`, `t1 = sum wt_k a_k`, the weights
//! the same at every sample (they depend on the SMRs' places only). The
//! normal's once-per-revolution term lands in `t2` as in `t1`, and is taken
//! out of it alike. Which equations:
//!
//! - the phases spread in the plane (three or more, the scatter of their
//!   directions at least 0.05 in every direction, e.g. 0/120/240 or
//!   0/90/270): `Z`, `t1`, `t2`;
//! - else every SMR within 2 degrees of the first's line (0 or 180), at
//!   least one on each side: `Z` and `t1` (for two opposite SMRs `Z` is the
//!   mean of their deviations, `t1` their difference over their
//!   separation). The tilt across that line is not measured: within 2
//!   degrees it moves `Z` by at most `sin 2 deg` (3.5 %) of the face motion it
//!   makes at the SMRs' radius.
//! - else (one phase, or two SMRs not opposite) nothing is separated.
//!
//! The SMRs' phases are measured (the mean angle between their positions
//! and the first's about the normal), not taken from the configuration.

use crate::figures::Scale;
use survey_processing::geometry::AxisFit;

/// The axial motion on the axis and the tilt in the first SMR's radial
/// direction at every sample, with their weights' scaling; the tilt at 90
/// degrees to it where the phases spread (three or more SMRs).
pub(crate) struct Separated {
    pub axial_um: Vec<f64>,
    pub tilt_urad: Vec<f64>,
    pub axial: Scale,
    pub tilt: Scale,
    /// `t2`, urad, and its scaling: `None` for SMRs on one line (0 and 180).
    pub tilt_across: Option<(Vec<f64>, Scale)>,
    /// How many SMRs took part.
    pub smrs: usize,
    /// The measured phases, degrees from the first's.
    pub phases_deg: Vec<f64>,
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `(X^T X)^-1 X^T` of the rows `x` (p columns, p <= 3); `None` when singular.
fn weights(x: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    let p = x.first()?.len();
    // [G | I], Gauss-Jordan with partial pivoting.
    let mut a: Vec<Vec<f64>> = (0..p)
        .map(|i| {
            let mut row: Vec<f64> = (0..p).map(|j| x.iter().map(|r| r[i] * r[j]).sum()).collect();
            row.extend((0..p).map(|j| if i == j { 1.0 } else { 0.0 }));
            row
        })
        .collect();
    let size = a.iter().map(|r| r[..p].iter().map(|v| v.abs()).fold(0.0, f64::max)).fold(0.0, f64::max);
    for c in 0..p {
        let pivot = (c..p).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[pivot][c].abs() <= 1e-9 * size {
            return None;
        }
        a.swap(c, pivot);
        let d = a[c][c];
        a[c].iter_mut().for_each(|v| *v /= d);
        for r in 0..p {
            if r != c {
                let f = a[r][c];
                let pivot_row = a[c].clone();
                a[r].iter_mut().zip(&pivot_row).for_each(|(v, q)| *v -= f * q);
            }
        }
    }
    Some((0..p).map(|i| x.iter().map(|row| (0..p).map(|j| a[i][p + j] * row[j]).sum()).collect()).collect())
}

/// `values` less their least-squares mean and once-per-revolution part in
/// the readout `theta` (degrees).
fn without_once_per_rev(values: &[f64], readouts: &[f64]) -> Vec<f64> {
    let rows: Vec<Vec<f64>> = readouts
        .iter()
        .map(|t| {
            let (s, c) = t.to_radians().sin_cos();
            vec![1.0, c, s]
        })
        .collect();
    let Some(w) = weights(&rows) else { return values.to_vec() };
    let coef: Vec<f64> = w.iter().map(|wi| wi.iter().zip(values).map(|(a, b)| a * b).sum()).collect();
    values.iter().zip(&rows).map(|(v, r)| v - r.iter().zip(&coef).map(|(a, b)| a * b).sum::<f64>()).collect()
}

/// Separate the axial motion on the axis and the tilt from the SMRs'
/// positions `points[k][sample]` and their fits; `Err` says why not.
pub(crate) fn separate(points: &[&[[f64; 3]]], fits: &[AxisFit], readouts: &[f64]) -> Result<Separated, String> {
    if points.len() < 2 || fits.len() != points.len() {
        return Err("one SMR: its axial motion is the face motion at its radius".into());
    }
    let n = fits[0].normal;
    // The measured phases: the circular mean of each SMR's angle from the first's about `n`.
    let phases: Vec<f64> = (0..points.len())
        .map(|k| {
            let (mut s, mut c) = (0.0, 0.0);
            for (p0, pk) in points[0].iter().zip(points[k]) {
                let (a, b) = (sub(*p0, fits[0].center_mm), sub(*pk, fits[k].center_mm));
                let (a, b) = (sub(a, n.map(|x| x * dot(a, n))), sub(b, n.map(|x| x * dot(b, n))));
                let angle = dot(cross(a, b), n).atan2(dot(a, b));
                s += angle.sin();
                c += angle.cos();
            }
            // In [0, 360), as the configuration writes them.
            let p = s.atan2(c).to_degrees().rem_euclid(360.0);
            if p >= 359.95 { 0.0 } else { p }
        })
        .collect();
    let dirs: Vec<(f64, f64)> = phases.iter().map(|p| (p.to_radians().cos(), p.to_radians().sin())).collect();
    let m = dirs.len() as f64;
    let (mx, my) = (dirs.iter().map(|d| d.0).sum::<f64>() / m, dirs.iter().map(|d| d.1).sum::<f64>() / m);
    let (sxx, syy, sxy) = dirs.iter().fold((0.0, 0.0, 0.0), |(a, b, c), d| {
        (a + (d.0 - mx).powi(2) / m, b + (d.1 - my).powi(2) / m, c + (d.0 - mx) * (d.1 - my) / m)
    });
    // The scatter's smaller eigenvalue: how far the directions spread across their main line.
    let least = 0.5 * (sxx + syy) - (0.25 * (sxx - syy).powi(2) + sxy * sxy).sqrt();
    let radius_m: Vec<f64> = fits.iter().map(|f| f.radius_mm * 1e-3).collect();
    let rows: Vec<Vec<f64>> = if points.len() >= 3 && least >= 0.05 {
        dirs.iter().zip(&radius_m).map(|(d, r)| vec![1.0, r * d.0, r * d.1]).collect()
    } else if dirs.iter().all(|d| d.1.abs() <= 2f64.to_radians().sin())
        && dirs.iter().any(|d| d.0 < 0.0)
        && dirs.iter().any(|d| d.0 > 0.0)
    {
        dirs.iter().zip(&radius_m).map(|(d, r)| vec![1.0, r * d.0]).collect()
    } else {
        let shown: Vec<String> = phases.iter().map(|p| format!("{p:.0}")).collect();
        return Err(format!(
            "the SMRs' phases ({} deg) do not separate the axial motion on the axis from the tilt: that needs two \
             opposite (0 and 180 deg) or three spread (0, 120, 240 deg)",
            shown.join(", ")
        ));
    };
    let w = weights(&rows).ok_or("the SMRs' places give a singular system")?;
    // Every SMR's axial deviation along `n`, from its own circle's centre, um.
    let axial: Vec<Vec<f64>> = points
        .iter()
        .zip(fits)
        .map(|(pts, f)| pts.iter().map(|p| dot(sub(*p, f.center_mm), n) * 1000.0).collect())
        .collect();
    let combine = |wk: &[f64]| -> Vec<f64> {
        (0..readouts.len()).map(|i| wk.iter().zip(&axial).map(|(w, a)| w * a[i]).sum()).collect()
    };
    let on_axis = combine(&w[0]);
    let tilt = without_once_per_rev(&combine(&w[1]), readouts);
    let tilt_across = w.get(2).map(|w2| (without_once_per_rev(&combine(w2), readouts), Scale::of_weights(w2)));
    Ok(Separated {
        axial_um: on_axis,
        tilt_urad: tilt,
        axial: Scale::of_weights(&w[0]),
        tilt: Scale::of_weights(&w[1]),
        tilt_across,
        smrs: points.len(),
        phases_deg: phases,
    })
}
