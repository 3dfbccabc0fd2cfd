//! The location of the axis average line (ISO 230-1: X0C, Y0C, A0C, B0C)
//! in the tracker's frame, from the first SMR's circle and plane, and in the
//! machine's where the survey states its frame
//! (`survey_processing::frame::MachineFrame`).
//!
//! `U` (k = 2), as bounds: the tracker's systematic error, bounded by `e_T`
//! (its transverse MPE at the farthest SMR), moves the circle's centre and
//! tilts its plane by at most its once-per-revolution part, which for an
//! error bounded by `e_T` is at most `4 e_T / pi` (a square wave's): the
//! centre by that, the plane by that over the radius. Their statistical
//! part, from the fit's residuals over `N` points on a circle of radius `R`:
//! the centre's standard error `circle_rms sqrt(2 / N)`, the normal's
//! `plane_rms / (R sqrt(N / 2))`, each doubled. The two added in quadrature.
//! In the machine's frame the line's point is where it crosses the
//! machine's plane z = 0, a distance `L` along it from the circle's centre:
//! its `U` adds `L` times the direction's. Where the frame states its
//! alignment's uncertainty (`origin_u_mm`, `rotation_u_deg`: `U`, k = 2, of
//! each coordinate and each rotation), each of the six moves the line in the
//! machine's frame by what the location computed with that key `U` up and
//! down makes, half their difference; those are added in quadrature, the
//! larger of x0's and y0's (a0's and b0's) is the alignment's term, and it
//! is added in quadrature to the fit's. Without them the frame is taken as
//! stated.

use survey_processing::frame::MachineFrame;
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
    /// The frame of the figures above: always `"tracker"`.
    pub frame: &'static str,
    /// `U` (k = 2) of `x0_mm` and `y0_mm`, mm.
    pub u_xy_mm: f64,
    /// `U` (k = 2) of `a0_urad` and `b0_urad`, urad.
    pub u_ab_urad: f64,
    /// The same line in the machine's frame, where the survey states one
    /// (`null` otherwise).
    pub machine: Option<MachineLocation>,
}

/// The axis average line in the machine's frame: `x0_mm`, `y0_mm` where it
/// crosses the machine's plane z = 0 (X0C, Y0C: the offsets from the
/// machine's z axis, the nominal C axis); `a0_urad`, `b0_urad` its
/// direction's rotations about the machine's x and y axes (A0C, B0C), as in
/// the tracker's frame.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct MachineLocation {
    pub x0_mm: f64,
    pub y0_mm: f64,
    pub a0_urad: f64,
    pub b0_urad: f64,
    /// `U` (k = 2) of `x0_mm`, `y0_mm`: the fit's and the alignment's.
    pub u_xy_mm: f64,
    /// `U` (k = 2) of `a0_urad`, `b0_urad`: the fit's and the alignment's.
    pub u_ab_urad: f64,
    /// The fit's term of `u_xy_mm` (the tracker's and the residuals'), mm.
    pub u_xy_fit_mm: f64,
    /// The fit's term of `u_ab_urad`, urad.
    pub u_ab_fit_urad: f64,
    /// The alignment's term of `u_xy_mm`, mm: `None` where the frame states
    /// no uncertainty (then it is taken as stated).
    pub u_xy_alignment_mm: Option<f64>,
    /// The alignment's term of `u_ab_urad`, urad.
    pub u_ab_alignment_urad: Option<f64>,
    /// The frame as stated: the machine's origin in the tracker's frame, mm.
    pub origin_mm: [f64; 3],
    /// The frame as stated: fixed-XYZ rotations of the machine's axes, deg.
    pub rotation_deg: [f64; 3],
    /// The frame's stated `U` (k = 2) of each origin coordinate, mm.
    pub origin_u_mm: Option<f64>,
    /// The frame's stated `U` (k = 2) of each rotation, deg.
    pub rotation_u_deg: Option<f64>,
}

/// The line through `centre` along `n` (tracker frame) in `f`'s machine
/// frame: `[x0_mm, y0_mm, a0_urad, b0_urad]` where it crosses the machine's
/// z = 0, and the distance from `centre` to there along it, mm; `None` when
/// it is more than 60 degrees from the machine's z axis.
fn in_machine(f: &MachineFrame, centre: [f64; 3], n: [f64; 3]) -> Option<([f64; 4], f64)> {
    let (m, a0_urad, b0_urad) = angles_urad(f.direction(n));
    if m[2] < 0.5 {
        return None;
    }
    let c = f.point(centre);
    let along_mm = -c[2] / m[2];
    Some(([c[0] + along_mm * m[0], c[1] + along_mm * m[1], a0_urad, b0_urad], along_mm))
}

/// The alignment's terms of the location's `U` in `f` (see the module
/// documentation): `(xy mm, ab urad)`, `None` where `f` states no
/// uncertainty.
fn alignment_u(f: &MachineFrame, centre: [f64; 3], n: [f64; 3]) -> Option<(f64, f64)> {
    if f.origin_u_mm.is_none() && f.rotation_u_deg.is_none() {
        return None;
    }
    let mut squares = [0.0f64; 4];
    for key in 0..6 {
        let u = if key < 3 { f.origin_u_mm } else { f.rotation_u_deg }.unwrap_or(0.0);
        let moved = |sign: f64| {
            let mut g = *f;
            if key < 3 {
                g.origin_mm[key] += sign * u;
            } else {
                g.rotation_deg[key - 3] += sign * u;
            }
            in_machine(&g, centre, n)
        };
        if let (Some((up, _)), Some((down, _))) = (moved(1.0), moved(-1.0)) {
            squares.iter_mut().zip(up.iter().zip(&down)).for_each(|(s, (a, b))| *s += ((a - b) / 2.0).powi(2));
        }
    }
    Some((squares[0].max(squares[1]).sqrt(), squares[2].max(squares[3]).sqrt()))
}

/// `a0`, `b0` of a unit direction, urad, its z component made positive.
fn angles_urad(n: [f64; 3]) -> ([f64; 3], f64, f64) {
    let n = if n[2] < 0.0 { n.map(|x| -x) } else { n };
    (n, (-n[1]).atan2(n[2]) * 1e6, n[0].atan2(n[2]) * 1e6)
}

impl Location {
    /// The location of `fit`'s axis, the tracker's systematic error bounded
    /// by `e_t_um`; in `frame` too where one is stated. `None` in the
    /// machine's frame when the axis is more than 60 degrees from its z axis
    /// (then the frame is not a C axis's: no X0C, Y0C).
    pub fn of(fit: &AxisFit, e_t_um: f64, frame: Option<&MachineFrame>) -> Self {
        let (n, a0_urad, b0_urad) = angles_urad(fit.normal);
        let points = fit.points.max(3) as f64;
        let once_per_rev_mm = 4.0 / std::f64::consts::PI * e_t_um * 1e-3;
        let se_centre_mm = fit.circle_rms_mm * (2.0 / points).sqrt();
        let se_normal_rad = fit.plane_rms_mm / (fit.radius_mm * (points / 2.0).sqrt());
        let u_xy_mm = once_per_rev_mm.hypot(2.0 * se_centre_mm);
        let u_ab_urad = (once_per_rev_mm / fit.radius_mm).hypot(2.0 * se_normal_rad) * 1e6;
        let machine = frame.and_then(|f| {
            let ([x0_mm, y0_mm, a0_urad, b0_urad], along_mm) = in_machine(f, fit.center_mm, n)?;
            let u_xy_fit_mm = u_xy_mm.hypot(along_mm * u_ab_urad * 1e-6);
            let alignment = alignment_u(f, fit.center_mm, n);
            let (a_xy, a_ab) = alignment.unwrap_or((0.0, 0.0));
            Some(MachineLocation {
                x0_mm,
                y0_mm,
                a0_urad,
                b0_urad,
                u_xy_mm: u_xy_fit_mm.hypot(a_xy),
                u_ab_urad: u_ab_urad.hypot(a_ab),
                u_xy_fit_mm,
                u_ab_fit_urad: u_ab_urad,
                u_xy_alignment_mm: alignment.map(|a| a.0),
                u_ab_alignment_urad: alignment.map(|a| a.1),
                origin_mm: f.origin_mm,
                rotation_deg: f.rotation_deg,
                origin_u_mm: f.origin_u_mm,
                rotation_u_deg: f.rotation_u_deg,
            })
        });
        Location {
            x0_mm: fit.center_mm[0],
            y0_mm: fit.center_mm[1],
            z0_mm: fit.center_mm[2],
            a0_urad,
            b0_urad,
            frame: "tracker",
            u_xy_mm,
            u_ab_urad,
            machine,
        }
    }
}
