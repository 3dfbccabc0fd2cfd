//! The axis's error motions of a model file (ISO 230-7): `radial_motion`,
//! `axial_motion`, `tilt_motion` and `bearing_noise` effects (issue 52).
//!
//! The table is a rigid body turning about its axis. Its error motions
//! displace it, as functions of the true axis angle `theta`:
//!
//! - `radial_motion` (`cycles_per_rev = k`, `amplitude_um = A`, `phase_deg =
//!   phi`): the radial error motion in the first SMR's radial direction (a
//!   sensitive direction turning with the table) is `A sin(k theta + phi)`;
//!   at an SMR mounted `delta` from the first it is `A sin(k theta + phi +
//!   delta)`, and the SMR is also moved `A cos(k theta + phi + delta)`
//!   along its circle (the axis whirls at `k - 1` cycles per revolution in
//!   the tracker's frame). `k` is at least 2: a once-per-revolution radial
//!   motion is a fixed offset of the axis, its location (X0C, Y0C), which
//!   ISO 230-7 removes as the centring error.
//! - `axial_motion` (`k`, `A` um, `phi`): the table moves `A sin(k theta +
//!   phi)` along the axis. Seen by one SMR at one radius, its once-per-revolution
//!   part is a tilt of the fitted plane (the axis's A0C, B0C).
//! - `tilt_motion` (`k`, `amplitude_urad = T`, `phi`): the table tilts
//!   about a line through the axis's point of the tracker's frame
//!   (`axis_center_mm` of the simulated arm) so that an SMR at radius `R`
//!   and height `h` above that point, mounted `delta` from the first, rises
//!   `R T sin(k theta + phi + delta)` and moves `-h T sin(k theta + phi +
//!   delta)` radially (`-h T cos(...)` along its circle): two SMRs on one
//!   vertical line differ in radial motion by `-(h2 - h1) T sin(...)`.
//!   `k` is at least 2, as for the radial motion.
//! - `bearing_noise` (`sigma_um`): an asynchronous displacement of the table,
//!   normal, independent along each of the three axes, drawn anew at every
//!   reading of the tracker.

use super::{Fail, Locator, number, shown};
use crate::num::Num;
use std::fmt::Write as _;

/// The model file's kinds of error motion.
pub const MOTION_KINDS: [&str; 4] = ["radial_motion", "axial_motion", "tilt_motion", "bearing_noise"];

/// One harmonic of an error motion: `amplitude * sin(cycles_per_rev *
/// theta + phase_deg)`, um (radial, axial) or urad (tilt).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionHarmonic {
    pub cycles_per_rev: u32,
    pub amplitude: f64,
    pub phase_deg: f64,
}

impl MotionHarmonic {
    /// `amplitude * (sin, cos)(cycles_per_rev * theta + phase + delta)`.
    fn at(&self, theta_deg: f64, delta_deg: f64) -> (f64, f64) {
        let (s, c) = (f64::from(self.cycles_per_rev) * theta_deg + self.phase_deg + delta_deg).to_radians().sin_cos();
        (self.amplitude * s, self.amplitude * c)
    }
}

/// An SMR's place on the table as the error motions see it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmrPlace {
    /// Its angle from the first SMR's, degrees.
    pub phase_deg: f64,
    /// Its circle's radius, mm.
    pub radius_mm: f64,
    /// Its height above the point the table tilts about, mm.
    pub height_mm: f64,
}

/// The axis's error motions of a model file (see the module documentation).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AxisMotions {
    pub radial: Vec<MotionHarmonic>,
    pub axial: Vec<MotionHarmonic>,
    pub tilt: Vec<MotionHarmonic>,
    /// The asynchronous part, um, along each axis.
    pub bearing_sigma_um: f64,
}

fn sum(list: &[MotionHarmonic], theta_deg: f64, delta_deg: f64) -> (f64, f64) {
    list.iter().map(|h| h.at(theta_deg, delta_deg)).fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1))
}

impl AxisMotions {
    /// No error motion at all.
    pub fn is_none(&self) -> bool {
        self.radial.is_empty() && self.axial.is_empty() && self.tilt.is_empty() && self.bearing_sigma_um == 0.0
    }

    /// The synchronous displacement of an SMR at `place` at true axis angle
    /// `theta_deg`, um: `[radial, along its circle (increasing angle), axial]`.
    pub fn displacement_um(&self, theta_deg: f64, place: SmrPlace) -> [f64; 3] {
        let (rs, rc) = sum(&self.radial, theta_deg, place.phase_deg);
        let (ts, tc) = sum(&self.tilt, theta_deg, place.phase_deg);
        let (axial, _) = sum(&self.axial, theta_deg, 0.0);
        let h_m = place.height_mm * 1e-3;
        [rs - h_m * ts, rc - h_m * tc, axial + place.radius_mm * 1e-3 * ts]
    }

    /// The radial error motion at an SMR mounted `phase_deg` from the first,
    /// at the height of the tilt's pivot, um.
    pub fn radial_um(&self, theta_deg: f64, phase_deg: f64) -> f64 {
        sum(&self.radial, theta_deg, phase_deg).0
    }

    /// The axial error motion (on the axis), um.
    pub fn axial_um(&self, theta_deg: f64) -> f64 {
        sum(&self.axial, theta_deg, 0.0).0
    }

    /// The tilt error motion in the radial direction of an SMR mounted
    /// `phase_deg` from the first, urad.
    pub fn tilt_urad(&self, theta_deg: f64, phase_deg: f64) -> f64 {
        sum(&self.tilt, theta_deg, phase_deg).0
    }

    /// The effects as the model file writes them.
    pub fn to_toml(&self) -> String {
        let mut s = String::new();
        for (kind, unit, list) in [
            ("radial_motion", "um", &self.radial),
            ("axial_motion", "um", &self.axial),
            ("tilt_motion", "urad", &self.tilt),
        ] {
            for h in list {
                let _ = write!(
                    s,
                    "\n[[effect]]\nkind = \"{kind}\"\ncycles_per_rev = {}\namplitude_{unit} = {}\nphase_deg = {}\n",
                    h.cycles_per_rev,
                    super::fmt_num(h.amplitude),
                    super::fmt_num(h.phase_deg)
                );
            }
        }
        if self.bearing_sigma_um != 0.0 {
            let _ = write!(
                s,
                "\n[[effect]]\nkind = \"bearing_noise\"\nsigma_um = {}\n",
                super::fmt_num(self.bearing_sigma_um)
            );
        }
        s
    }
}

/// Parse one `[[effect]]` of a motion kind (number `index`, 0-based) into
/// `motions`.
pub(super) fn parse_effect(
    t: &toml::Table,
    kind: &str,
    index: usize,
    loc: &Locator,
    motions: &mut AxisMotions,
) -> Result<(), Fail> {
    let header = loc.effect_header(index);
    let n = index + 1;
    let at = |key: &str| loc.key_in_table(header, key);
    let (unit_key, limit, unit) = match kind {
        "tilt_motion" => ("amplitude_urad", 100_000.0, "urad"),
        "bearing_noise" => ("sigma_um", 10_000.0, "um"),
        _ => ("amplitude_um", 10_000.0, "um"),
    };
    let allowed: &[&str] = if kind == "bearing_noise" {
        &["kind", "sigma_um"]
    } else {
        &["kind", "cycles_per_rev", unit_key, "phase_deg"]
    };
    if let Some(key) = t.keys().find(|k| !allowed.contains(&k.as_str())) {
        return Err((
            at(key),
            format!("effect[{n}] ({kind}): unknown key '{key}' (expected {})", allowed[1..].join(", ")),
        ));
    }
    let get = |key: &str, lo: f64, hi: f64, why: &str| -> Result<f64, Fail> {
        let v = t.get(key).ok_or((header, format!("effect[{n}] ({kind}): missing key '{key}'")))?;
        match number(v) {
            Some(x) if x.is_finite() && (lo..=hi).contains(&x) => Ok(x),
            Some(x) if x.is_finite() => Err((
                at(key),
                format!("effect[{n}] ({kind}).{key} = {} is outside {}..={}: {why}", Num(x), Num(lo), Num(hi)),
            )),
            _ => Err((at(key), format!("effect[{n}] ({kind}).{key} must be a finite number, got {}", shown(v)))),
        }
    };
    let size = format!("a motion of {} {unit} or more is not an axis's error motion: is the unit right?", Num(limit));
    if kind == "bearing_noise" {
        motions.bearing_sigma_um += get("sigma_um", 0.0, limit, &size)?;
        return Ok(());
    }
    let cycles = get("cycles_per_rev", 1.0, 1000.0, "an error motion is a harmonic of the axis angle, 1 to 1000")?;
    if cycles.fract() != 0.0 {
        return Err((
            at("cycles_per_rev"),
            format!(
                "effect[{n}] ({kind}).cycles_per_rev must be a whole number (a harmonic of the turn), got {}",
                Num(cycles)
            ),
        ));
    }
    if cycles == 1.0 && kind != "axial_motion" {
        return Err((
            at("cycles_per_rev"),
            format!(
                "effect[{n}] ({kind}).cycles_per_rev = 1 is the axis's location, not its motion (a once-per-revolution \
                 {} is a fixed offset of the axis, which ISO 230-7 removes as the centring): use 2 or more",
                if kind == "tilt_motion" { "tilt" } else { "radial motion" }
            ),
        ));
    }
    let amplitude = get(unit_key, 0.0, limit, &size)?;
    let phase_deg =
        if t.contains_key("phase_deg") { get("phase_deg", -1.0e6, 1.0e6, "a phase is an angle")? } else { 0.0 };
    let h = MotionHarmonic { cycles_per_rev: cycles as u32, amplitude, phase_deg };
    match kind {
        "radial_motion" => motions.radial.push(h),
        "axial_motion" => motions.axial.push(h),
        _ => motions.tilt.push(h),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use crate::model::Model;

    const TEXT: &str = "[[effect]]\nkind = \"radial_motion\"\ncycles_per_rev = 2\namplitude_um = 8\nphase_deg = 30\n\n\
                        [[effect]]\nkind = \"axial_motion\"\ncycles_per_rev = 1\namplitude_um = 5\n\n\
                        [[effect]]\nkind = \"tilt_motion\"\ncycles_per_rev = 3\namplitude_urad = 10\nphase_deg = -20\n\n\
                        [[effect]]\nkind = \"bearing_noise\"\nsigma_um = 1.5\n";

    #[test]
    fn motions_parse_write_back_and_evaluate() {
        let m = Model::parse(TEXT, "m.toml").unwrap();
        assert!(m.effects.is_empty(), "no angular effect");
        let mo = &m.motions;
        assert_eq!((mo.radial.len(), mo.axial.len(), mo.tilt.len(), mo.bearing_sigma_um), (1, 1, 1, 1.5));
        assert_eq!(Model::parse(&m.to_toml(), "again").unwrap(), m);
        // At theta = 30: radial 8 sin(90) = 8 at the first SMR; at 90 deg from it, 8 sin(180) = 0.
        assert!((mo.radial_um(30.0, 0.0) - 8.0).abs() < 1e-12);
        assert!(mo.radial_um(30.0, 90.0).abs() < 1e-12);
        let place = super::SmrPlace { phase_deg: 0.0, radius_mm: 1000.0, height_mm: 100.0 };
        let d = mo.displacement_um(30.0, place);
        let tilt = 10.0 * (90.0f64 - 20.0).to_radians().sin();
        assert!((d[0] - (8.0 - 0.1 * tilt)).abs() < 1e-12, "{d:?}");
        assert!((d[2] - (5.0 * 30f64.to_radians().sin() + tilt)).abs() < 1e-12, "{d:?}");
    }

    #[test]
    fn bad_motions_are_named_with_their_line() {
        for (bad, line, says) in [
            (
                "[[effect]]\nkind = \"radial_motion\"\ncycles_per_rev = 1\namplitude_um = 3\n",
                3,
                "is the axis's location",
            ),
            ("[[effect]]\nkind = \"tilt_motion\"\ncycles_per_rev = 2.5\namplitude_urad = 3\n", 3, "whole number"),
            (
                "[[effect]]\nkind = \"axial_motion\"\ncycles_per_rev = 2\namplitude_um = -3\n",
                4,
                "amplitude_um = -3 is outside",
            ),
            (
                "[[effect]]\nkind = \"axial_motion\"\ncycles_per_rev = 2\namplitude_deg = 3\n",
                4,
                "unknown key 'amplitude_deg'",
            ),
            ("[[effect]]\nkind = \"bearing_noise\"\n", 1, "missing key 'sigma_um'"),
        ] {
            let e = Model::parse(bad, "bad.toml").unwrap_err();
            assert_eq!(e.line, Some(line), "{bad}: {e}");
            assert!(e.message.contains(says), "{bad}: {e}");
        }
    }
}
