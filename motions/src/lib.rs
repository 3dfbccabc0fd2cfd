//! A rotary axis's other errors from a tracker survey (issue 52): the
//! location of its axis average line (ISO 230-1: X0C, Y0C, A0C, B0C) and its
//! error motions (ISO 230-7: radial, axial and tilt; total, synchronous and
//! asynchronous), each with its expanded uncertainty and the detection limit
//! the tracker allows.
//!
//! Pure: the SMR positions of a survey in, the figures out. What is done:
//!
//! 1. Each SMR's positions are fitted with a plane and a circle
//!    (`survey_processing::geometry::fit_axis`). The first SMR's circle
//!    centre and plane normal are the axis average line's location in the
//!    tracker's frame, and in the machine's where the survey states it
//!    ([`Location`], with their `U`).
//! 2. Each position's radial deviation is its distance from the circle's
//!    centre, in the plane, less the radius; its axial deviation its distance
//!    from the plane. The least-squares circle's centre takes the
//!    once-per-revolution radial part out: that is the centring (the SMR's
//!    eccentricity to the axis, ISO 230-7's centring error), not a motion;
//!    the plane takes the once-per-revolution axial part out, the tilt of the
//!    axis average line (A0C, B0C), so a one-SMR axial motion is the face
//!    motion at the SMR's radius from 2 cycles per revolution up. The radial
//!    motion is in the SMR's radial direction, which turns with the table (a
//!    rotating sensitive direction).
//! 3. Tilt: two SMRs at one phase and different heights; the tilt motion is
//!    minus the difference of their radial motions over their separation
//!    (urad). With SMRs at opposite or spread phases ([`phases`]), the axial
//!    motion on the axis (E_ZC: the part of their axial motions common to
//!    them) and the tilt (from their difference over their separation); of
//!    the two tilts the one with the smaller `U` is reported, and says which.
//!    Three or more SMRs at spread phases also give the tilt at 90 degrees to
//!    the first SMR's radial direction (`tilt_across_urad`).
//! 4. Per target and direction, the synchronous motion is the mean over the
//!    runs; the asynchronous the spread across them. The figures, per
//!    direction (the larger of the two is reported): total = the largest
//!    minus the smallest deviation of every reading (the radial separation of
//!    two circles about the least-squares centre that enclose the total polar
//!    plot), synchronous = the same of the mean curve, asynchronous = the
//!    largest spread across runs at any target.
//! 5. Each figure's `U` (k = 2) and the detection limit, [`figures`].

mod deviations;
mod figures;
mod location;
mod phases;

pub use figures::{Block, Figures, PolarPoint};
pub use location::{Location, MachineLocation};

use deviations::{deviations, tilt_pair};
use figures::Scale;
use phases::separate;
use survey_processing::frame::MachineFrame;
use survey_processing::geometry::fit_axis;

use survey_processing::smrs::SmrMount;
use survey_processing::tracker_errors::TransverseMpe;
use survey_processing::{Direction, Sample};

/// One SMR's readings: its mount and its position at every sample (in the
/// samples' order).
#[derive(Debug, Clone, Copy)]
pub struct Track<'a> {
    pub mount: SmrMount,
    pub points_mm: &'a [[f64; 3]],
}

/// What the error motions are computed from.
#[derive(Debug, Clone)]
pub struct Input<'a> {
    /// The survey's samples (their run, direction and target; the readout
    /// orients each SMR's circle).
    pub samples: &'a [Sample],
    /// The first SMR's readings first, then the others'.
    pub tracks: Vec<Track<'a>>,
    /// The tracker's transverse maximum permissible error.
    pub mpe: TransverseMpe,
    /// The machine's frame in the tracker's, where the survey states one.
    pub frame: Option<MachineFrame>,
}

/// The contract's `error_motions`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ErrorMotions {
    /// The axis average line in the tracker's frame (ISO 230-1).
    pub location: Location,
    /// Radial error motion of the first SMR, um.
    pub radial_um: Block,
    /// Axial (face) error motion of the first SMR at its radius, um.
    pub axial_um: Block,
    /// Tilt error motion, urad, in the first SMR's radial direction: `None`
    /// without two SMRs at one phase and different heights or at phases
    /// that separate it ([`phases`]).
    pub tilt_urad: Option<Tilt>,
    /// Tilt error motion, urad, at 90 degrees to the first SMR's radial
    /// direction (toward increasing angle: `t2` of [`phases`]): `None`
    /// without three or more SMRs at phases spread in both directions.
    pub tilt_across_urad: Option<Tilt>,
    /// Axial error motion on the axis (E_ZC), um: `None` without SMRs at
    /// phases that separate it from the tilt ([`phases`]).
    pub axial_on_axis_um: Option<Block>,
    /// The smallest radial or axial motion the tracker can tell from its own
    /// error: its transverse MPE at the farthest SMR's distance, or what its
    /// random error can make of a peak-to-valley if larger, um.
    pub detection_limit_um: f64,
    /// The radius the radial and axial motions are measured at, mm.
    pub radius_mm: f64,
    /// Runs of the survey.
    pub runs: usize,
    /// How the figures were made, in words.
    pub method: &'static str,
    /// What the reader should know (no tilt, one run, ...).
    pub notes: Vec<String>,
    /// The synchronous motions per target and direction (at most
    /// [`POLAR_POINTS`] a direction: every n-th target beyond).
    pub polar: Vec<PolarPoint>,
}

/// The tilt error motion and how it was obtained.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Tilt {
    #[serde(flatten)]
    pub block: Block,
    /// `"heights"` (two SMRs at one phase: their radial motions) or
    /// `"phases"` (SMRs at opposite or spread phases: their axial motions).
    pub method: &'static str,
    /// The SMRs it was computed from.
    pub smrs: usize,
    /// Its value at every sample, urad.
    #[serde(skip)]
    pub series: Vec<f64>,
}

impl std::ops::Deref for Tilt {
    type Target = Block;
    fn deref(&self) -> &Block {
        &self.block
    }
}

/// The most points of the polar plot kept per direction.
pub const POLAR_POINTS: usize = 720;

/// The method, as `process --json` names it.
pub const METHOD: &str = "ISO 230-7 from the tracker's SMR positions: each SMR's least-squares plane and circle \
                          (centring and the axis's tilt removed), radial in the SMR's radial direction (rotating \
                          sensitive direction), axial as face motion at its radius, tilt from two SMRs at one phase \
                          and different heights or from SMRs at opposite or spread phases (then also the axial motion \
                          on the axis; at spread phases also the tilt across the first SMR's radial direction); \
                          synchronous = the mean over runs, asynchronous = the spread across runs, total = the \
                          peak-to-valley of every reading; U (k = 2) from the tracker's MPE and its random error";

/// The error motions of a survey; `None` when the first SMR's positions do
/// not locate an axis (fewer than 3, degenerate) or a track's length is not
/// the samples'.
pub fn error_motions(input: &Input) -> Option<ErrorMotions> {
    let samples = input.samples;
    if input.tracks.is_empty() || input.tracks.iter().any(|t| t.points_mm.len() != samples.len()) {
        return None;
    }
    let readouts: Vec<f64> = samples.iter().map(|s| s.readout_deg).collect();
    let first = deviations(input.tracks[0].points_mm, &readouts)?;
    let farthest_mm = input
        .tracks
        .iter()
        .flat_map(|t| t.points_mm.iter())
        .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
        .fold(0.0, f64::max);
    let figures = Figures::new(samples, input.mpe, farthest_mm);
    let radial = figures.block(&first.radial_um, Scale::both(1.0));
    let detection_limit_um = radial.detection_limit;
    let axial = figures.block(&first.axial_um, Scale::both(1.0));
    let mut notes = Vec::new();
    let by_heights = match tilt_pair(&input.tracks) {
        Some((i, j, dh)) => {
            let (lo, hi) =
                (deviations(input.tracks[i].points_mm, &readouts)?, deviations(input.tracks[j].points_mm, &readouts)?);
            // urad = um / m: minus the radial difference over the separation.
            let tilt: Vec<f64> = lo.radial_um.iter().zip(&hi.radial_um).map(|(a, b)| -(b - a) / (dh * 1e-3)).collect();
            let block = figures.block(&tilt, Scale::both(std::f64::consts::SQRT_2 / (dh * 1e-3)));
            Some(Tilt { block, method: "heights", smrs: 2, series: tilt })
        }
        None => None,
    };
    // Every SMR's fit, for the phases.
    let fits: Option<Vec<_>> = std::iter::once(Some(first.fit.clone()))
        .chain(input.tracks[1..].iter().map(|t| fit_axis(t.points_mm, &readouts).ok()))
        .collect();
    let points: Vec<&[[f64; 3]]> = input.tracks.iter().map(|t| t.points_mm).collect();
    let separated =
        fits.ok_or_else(|| "an SMR cannot be fitted".to_string()).and_then(|f| separate(&points, &f, &readouts));
    let (on_axis, by_phases, across) = match separated {
        Ok(s) => {
            let phases: Vec<String> = s.phases_deg.iter().map(|p| format!("{p:.1}")).collect();
            notes.push(format!(
                "the axial motion on the axis and the tilt from {} SMRs at {} deg (measured)",
                s.smrs,
                phases.join(", ")
            ));
            let on_axis = figures.block(&s.axial_um, s.axial);
            let tilt = Tilt {
                block: figures.block(&s.tilt_urad, s.tilt),
                method: "phases",
                smrs: s.smrs,
                series: s.tilt_urad,
            };
            let across = s.tilt_across.map(|(series, scale)| Tilt {
                block: figures.block(&series, scale),
                method: "phases",
                smrs: s.smrs,
                series,
            });
            if across.is_none() {
                notes.push(
                    "no tilt at 90 deg to the first SMR's radial direction: SMRs on one line (0 and 180 deg) cannot \
                     see it; three or more at spread phases (0, 120, 240 deg) measure it"
                        .into(),
                );
            }
            (Some((on_axis, s.axial_um)), Some(tilt), across)
        }
        Err(why) => {
            if input.tracks.len() > 1 {
                notes.push(format!("no axial motion on the axis: {why}"));
            }
            (None, None, None)
        }
    };
    // Of two ways to the tilt, the one with the smaller U.
    let tilt = match (by_heights, by_phases) {
        (Some(h), Some(p)) => Some(if p.block.u <= h.block.u { p } else { h }),
        (h, p) => h.or(p),
    };
    if tilt.is_none() {
        notes.push(
            "no tilt: it needs two SMRs at one phase and different heights, or at opposite or spread phases ([smrs] \
             phases_deg, heights_mm)"
                .into(),
        );
    }
    if figures.runs() < 2 {
        notes.push("one run: no asynchronous motion (it is the spread across runs)".into());
    }
    let location = Location::of(&first.fit, figures.e_t_um(), input.frame.as_ref());
    if location.machine.is_some_and(|m| m.u_xy_alignment_mm.is_none()) {
        notes.push(
            "the machine's frame is taken as stated: its alignment's uncertainty is not in the location's U ([machine_frame] \
             origin_u_mm, rotation_u_deg state it)"
                .into(),
        );
    }
    if input.frame.is_some() && location.machine.is_none() {
        notes.push(
            "no location in the machine's frame: the axis is more than 60 deg from its z axis ([machine_frame] \
             rotation_deg states the frame of a C axis, z along it)"
                .into(),
        );
    }
    let polar = figures.polar(
        &first.radial_um,
        &first.axial_um,
        tilt.as_ref().map(|t| t.series.as_slice()),
        across.as_ref().map(|t| t.series.as_slice()),
        on_axis.as_ref().map(|(_, a)| a.as_slice()),
    );
    Some(ErrorMotions {
        location,
        radial_um: radial,
        axial_um: axial,
        tilt_urad: tilt,
        tilt_across_urad: across,
        axial_on_axis_um: on_axis.map(|(b, _)| b),
        detection_limit_um,
        radius_mm: first.fit.radius_mm,
        runs: figures.runs(),
        method: METHOD,
        notes,
        polar,
    })
}

/// The direction's name in the documents.
fn direction_name(d: Direction) -> &'static str {
    match d {
        Direction::Forward => "forward",
        Direction::Reverse => "reverse",
    }
}

#[cfg(test)]
mod tests;
