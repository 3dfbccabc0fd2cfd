//! The location of the axis average line (ISO 230-1: X0C, Y0C, A0C, B0C)
//! in the tracker's frame, from the first SMR's circle and plane.

use survey_processing::geometry::AxisFit;

/// Where the axis average line is, tracker frame: `x0_mm`, `y0_mm` (and
/// `z0_mm`) the first SMR's circle centre, a point of the line; `a0_urad`
/// and `b0_urad` its direction's rotations about the tracker's x and y
/// axes from the tracker's z axis (`a0`: right-handed about x, so a line
/// leaning toward -y has a positive `a0`; `b0`: about y, a line leaning
/// toward +x positive). A line has no sense: the normal is taken with its
/// z component positive.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Location {
    pub x0_mm: f64,
    pub y0_mm: f64,
    pub z0_mm: f64,
    pub a0_urad: f64,
    pub b0_urad: f64,
    /// The frame: always `"tracker"` (a configuration states no machine frame yet).
    pub frame: &'static str,
}

impl Location {
    /// The location of `fit`'s axis.
    pub fn of(fit: &AxisFit) -> Self {
        let n = if fit.normal[2] < 0.0 { fit.normal.map(|x| -x) } else { fit.normal };
        Location {
            x0_mm: fit.center_mm[0],
            y0_mm: fit.center_mm[1],
            z0_mm: fit.center_mm[2],
            a0_urad: (-n[1]).atan2(n[2]) * 1e6,
            b0_urad: n[0].atan2(n[2]) * 1e6,
            frame: "tracker",
        }
    }
}
