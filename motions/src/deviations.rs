//! Each SMR's radial and axial deviations from its own least-squares circle
//! and plane, and the pair of SMRs that measures tilt.

use crate::Track;
use survey_processing::geometry::{AxisFit, fit_axis};

/// One SMR's deviations at every sample, um: radial and axial; and its fit.
pub(crate) struct Deviations {
    pub fit: AxisFit,
    pub radial_um: Vec<f64>,
    pub axial_um: Vec<f64>,
}

pub(crate) fn deviations(points: &[[f64; 3]], readouts: &[f64]) -> Option<Deviations> {
    let fit = fit_axis(points, readouts).ok()?;
    let (c, n) = (fit.center_mm, fit.normal);
    let mut radial_um = Vec::with_capacity(points.len());
    let mut axial_um = Vec::with_capacity(points.len());
    for p in points {
        let d = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
        let h = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
        let inplane = [d[0] - h * n[0], d[1] - h * n[1], d[2] - h * n[2]];
        let r = (inplane[0] * inplane[0] + inplane[1] * inplane[1] + inplane[2] * inplane[2]).sqrt();
        radial_um.push((r - fit.radius_mm) * 1000.0);
        axial_um.push(h * 1000.0);
    }
    Some(Deviations { fit, radial_um, axial_um })
}

/// The pair of SMRs that measures tilt: the two at one phase (within 1
/// degree) farthest apart in height (at least 10 mm), first index lower.
pub(crate) fn tilt_pair(tracks: &[Track]) -> Option<(usize, usize, f64)> {
    let mut best: Option<(usize, usize, f64)> = None;
    for i in 0..tracks.len() {
        for j in 0..tracks.len() {
            let (a, b) = (tracks[i].mount, tracks[j].mount);
            let phase = (a.phase_deg - b.phase_deg + 180.0).rem_euclid(360.0) - 180.0;
            let dh = b.height_mm - a.height_mm;
            if phase.abs() <= 1.0 && dh >= 10.0 && best.is_none_or(|(_, _, h)| dh > h) {
                best = Some((i, j, dh));
            }
        }
    }
    best
}
