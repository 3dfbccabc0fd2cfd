//! A laser tracker's own error: the geometric error model of laser trackers
//! (Muralikrishnan, Sawyer, Blackburn, Phillips, Borchardt, Estler, "ASME
//! B89.4.19 performance evaluation tests and geometric misalignments in laser
//! trackers", J. Res. NIST 114 (2009) 21-35; the same parameters in the NIST
//! model family's public code), in its first-order form for a tracker whose
//! beam leaves the rotating head directly (no steering mirror: the mirror
//! offset and tilt drop out), and the contract's `[tracker_errors]` section
//! of a model file.
//!
//! # The model
//!
//! In the tracker's own frame (origin at the tracker, `+z` its standing
//! axis), a point at range `R`, azimuth `H = atan2(y, x)` and zenith angle
//! `V = acos(z / R)` is measured at
//!
//! ```text
//! R_m = R + x2 sin V + x10 + s R                       + range noise
//! H_m = H + x1t / (R sin V) + x5t / sin V + x7 cot V + eH(H) + angle noise / sin V
//! V_m = V + x1n / R + x2 cos V / R + x4 - eE(90 deg - V)     + angle noise
//! ```
//!
//! `x2` the transit offset (`transit_offset_um`), `x1t` and `x1n` the beam
//! offsets along and across the transit axis (`beam_offset_um`,
//! `beam_offset_normal_um`), `x10` the range offset (`range_offset_um`, the
//! bird-bath constant), `s` the range scale (`range_scale_ppm`), `x4` the
//! vertical index offset (`vertical_index_urad`), `x5t` the horizontal beam
//! tilt (`beam_tilt_urad`), `x7` the transit-axis tilt (`transit_tilt_urad`),
//! `eH` and `eE` the azimuth and elevation encoders' errors as harmonics of
//! their own angle, `A sin(k angle + phase)` (`azimuth`, `elevation`: the
//! eccentricity is order 1, graduation errors higher ones). The reported
//! position is the ideal conversion of `(R_m, H_m, V_m)`, as a tracker
//! reports it. Each term is a residual of the maker's compensation: the
//! model's offsets are micrometres and its tilts microradians.
//!
//! The signs are this project's reading of the model (each parameter's
//! physical cause with a stated sign, checked against exact rotation
//! kinematics to second order): the public papers give the parameters and
//! their functional forms, not one sign convention for a simulator.
//!
//! The random part is one standard normal per coordinate of the reading:
//! `angle_noise_urad` on each angle (a transverse `R angle_noise` at range
//! `R`) and `range_noise_um` on the range.
//!
//! # The specification
//!
//! An AT-class tracker's transverse maximum permissible error is
//! `15 um + 6 um/m x distance` ([`transverse_mpe_um`]), typical errors about
//! half of it; most of it systematic (the parameters above), which repeats at
//! the same place in space every time and does not average away.

use crate::geometry::AxisFit;
use crate::num::Num;
use std::fmt::Write as _;

/// An AT-class tracker's transverse maximum permissible error at
/// `distance_mm` from it, micrometres: `15 um + 6 um/m x distance`.
pub fn transverse_mpe_um(distance_mm: f64) -> f64 {
    TransverseMpe::AT_CLASS.at_um(distance_mm)
}

/// A tracker's transverse maximum permissible error, `constant + per_m x
/// distance`, as its specification or its calibration states it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransverseMpe {
    /// The constant part, um.
    pub constant_um: f64,
    /// The part per metre of distance, um/m.
    pub per_m_um: f64,
}

impl Default for TransverseMpe {
    fn default() -> Self {
        Self::AT_CLASS
    }
}

impl TransverseMpe {
    /// The Leica AT-class specification: 15 um + 6 um/m.
    pub const AT_CLASS: TransverseMpe = TransverseMpe { constant_um: 15.0, per_m_um: 6.0 };

    /// The MPE at `distance_mm` from the tracker, um.
    pub fn at_um(&self, distance_mm: f64) -> f64 {
        self.constant_um + self.per_m_um * distance_mm / 1000.0
    }

    /// The standard uncertainty of an axis angle measured around `axis`
    /// with one SMR, from the tracker's systematic error as this
    /// specification bounds it, degrees: its rms over the axis angles `arc`
    /// (from, to; a full circle when they are 360 apart).
    ///
    /// A tracker's error repeats at the same place in space on every
    /// reading: it is the same for every run and every reading at an angle,
    /// and no number of readings divides it. The specification bounds its
    /// transverse part by the MPE at the SMR's distance and says nothing of
    /// its shape around the circle (which harmonics of the table's angle it
    /// lands on: low encoder orders move the circle and are mostly absorbed
    /// by its fit, high ones pass into the angles one to one), so each
    /// transverse component is taken as rectangular within +/-MPE (GUM 4.3.7,
    /// `u = MPE / sqrt 3`, as an MPE is evaluated as a Type B uncertainty),
    /// projected on the circle's tangent (the part of a displacement across
    /// the line of sight that moves the angle) and divided by the radius, at
    /// each angle: the survey's own geometry, the SMR's distance and
    /// direction from the tracker (at the origin of the frame the positions
    /// are in, the tracker's own) and the circle's radius. Nothing of it is
    /// taken as absorbed by the fit: a shape that survives the fit is within
    /// the specification. Only several SMRs separate it from the axis's error.
    pub fn systematic_angle_u_deg(&self, axis: &AxisFit, arc: (f64, f64)) -> f64 {
        const STEPS: usize = 360;
        let (from, to) = arc;
        let full = (to - from).abs() >= 360.0 - 1e-9;
        let count = if full { STEPS } else { STEPS + 1 };
        let mut sum2 = 0.0;
        for i in 0..count {
            let theta = from + (to - from) * i as f64 / STEPS as f64;
            let phi = (theta + axis.zero_offset_deg).to_radians();
            let (s, c) = phi.sin_cos();
            let p: [f64; 3] =
                std::array::from_fn(|k| axis.center_mm[k] + axis.radius_mm * (c * axis.u[k] + s * axis.v[k]));
            let tangent: [f64; 3] = std::array::from_fn(|k| -s * axis.u[k] + c * axis.v[k]);
            let d = p.iter().map(|x| x * x).sum::<f64>().sqrt();
            let along = tangent.iter().zip(p).map(|(t, x)| t * x / d).sum::<f64>();
            let across = (1.0 - along * along).max(0.0).sqrt();
            let u_mm = self.at_um(d) / 1000.0 / 3f64.sqrt() * across;
            sum2 += (u_mm / axis.radius_mm).powi(2);
        }
        (sum2 / count as f64).sqrt().to_degrees()
    }
}

/// One harmonic of an encoder's error, `amplitude sin(order angle + phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EncoderHarmonic {
    /// Cycles per turn of the encoder (1 is its eccentricity).
    pub order: u32,
    /// Microradians.
    pub amplitude_urad: f64,
    /// Degrees.
    pub phase_deg: f64,
}

impl EncoderHarmonic {
    /// Its value at encoder angle `angle_rad`, radians.
    fn at(&self, angle_rad: f64) -> f64 {
        self.amplitude_urad * 1e-6 * (self.order as f64 * angle_rad + self.phase_deg.to_radians()).sin()
    }
}

/// The typical random part of one stationary reading: each angle, urad.
pub const TYPICAL_ANGLE_NOISE_URAD: f64 = 1.5;
/// The typical random part of one stationary reading: the range, um.
pub const TYPICAL_RANGE_NOISE_UM: f64 = 1.0;

/// A tracker's error: the model's parameters (see the module documentation)
/// and the size of its random part.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerErrors {
    /// The azimuth encoder's harmonics.
    pub azimuth: Vec<EncoderHarmonic>,
    /// The elevation encoder's harmonics.
    pub elevation: Vec<EncoderHarmonic>,
    /// `x2`, um.
    pub transit_offset_um: f64,
    /// `x1t`, um.
    pub beam_offset_um: f64,
    /// `x1n`, um.
    pub beam_offset_normal_um: f64,
    /// `x10`, um.
    pub range_offset_um: f64,
    /// `s`, parts per million.
    pub range_scale_ppm: f64,
    /// `x4`, urad.
    pub vertical_index_urad: f64,
    /// `x5t`, urad.
    pub beam_tilt_urad: f64,
    /// `x7`, urad.
    pub transit_tilt_urad: f64,
    /// The random part of each angle of a reading, urad (one standard deviation).
    pub angle_noise_urad: f64,
    /// The random part of the range of a reading, um.
    pub range_noise_um: f64,
}

impl Default for TrackerErrors {
    /// The ideal tracker: no systematic error, the typical random part.
    fn default() -> Self {
        Self::ideal()
    }
}

/// The contract's `[tracker_errors]` of a model file.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum TrackerErrorSpec {
    /// Omitted: an AT-class tracker's typical error, drawn from the bench's seed.
    #[default]
    Typical,
    /// `none = true`: the ideal tracker (its random part only).
    None,
    /// The errors stated (keys not given are zero, the random part typical
    /// unless given).
    Given(TrackerErrors),
}

/// The keys of `[tracker_errors]` that are numbers, with their unit and the
/// largest magnitude accepted (a value beyond it is a unit error: a tracker
/// in its specification is off by micrometres and microradians).
const NUMBER_KEYS: [(&str, f64); 10] = [
    ("transit_offset_um", 1000.0),
    ("beam_offset_um", 1000.0),
    ("beam_offset_normal_um", 1000.0),
    ("range_offset_um", 1000.0),
    ("range_scale_ppm", 1000.0),
    ("vertical_index_urad", 1000.0),
    ("beam_tilt_urad", 1000.0),
    ("transit_tilt_urad", 1000.0),
    ("angle_noise_urad", 1000.0),
    ("range_noise_um", 1000.0),
];

impl TrackerErrors {
    /// No systematic error; the typical random part.
    pub fn ideal() -> Self {
        Self {
            azimuth: Vec::new(),
            elevation: Vec::new(),
            transit_offset_um: 0.0,
            beam_offset_um: 0.0,
            beam_offset_normal_um: 0.0,
            range_offset_um: 0.0,
            range_scale_ppm: 0.0,
            vertical_index_urad: 0.0,
            beam_tilt_urad: 0.0,
            transit_tilt_urad: 0.0,
            angle_noise_urad: TYPICAL_ANGLE_NOISE_URAD,
            range_noise_um: TYPICAL_RANGE_NOISE_UM,
        }
    }

    /// The same errors without their random part.
    pub fn without_noise(&self) -> Self {
        Self { angle_noise_urad: 0.0, range_noise_um: 0.0, ..self.clone() }
    }

    /// Whether it has no systematic part.
    pub fn is_ideal(&self) -> bool {
        self.without_noise() == Self { angle_noise_urad: 0.0, range_noise_um: 0.0, ..Self::ideal() }
    }

    fn number(&self, key: &str) -> f64 {
        match key {
            "transit_offset_um" => self.transit_offset_um,
            "beam_offset_um" => self.beam_offset_um,
            "beam_offset_normal_um" => self.beam_offset_normal_um,
            "range_offset_um" => self.range_offset_um,
            "range_scale_ppm" => self.range_scale_ppm,
            "vertical_index_urad" => self.vertical_index_urad,
            "beam_tilt_urad" => self.beam_tilt_urad,
            "transit_tilt_urad" => self.transit_tilt_urad,
            "angle_noise_urad" => self.angle_noise_urad,
            "range_noise_um" => self.range_noise_um,
            _ => unreachable!("a key of NUMBER_KEYS"),
        }
    }

    fn number_mut(&mut self, key: &str) -> &mut f64 {
        match key {
            "transit_offset_um" => &mut self.transit_offset_um,
            "beam_offset_um" => &mut self.beam_offset_um,
            "beam_offset_normal_um" => &mut self.beam_offset_normal_um,
            "range_offset_um" => &mut self.range_offset_um,
            "range_scale_ppm" => &mut self.range_scale_ppm,
            "vertical_index_urad" => &mut self.vertical_index_urad,
            "beam_tilt_urad" => &mut self.beam_tilt_urad,
            "transit_tilt_urad" => &mut self.transit_tilt_urad,
            "angle_noise_urad" => &mut self.angle_noise_urad,
            "range_noise_um" => &mut self.range_noise_um,
            _ => unreachable!("a key of NUMBER_KEYS"),
        }
    }

    /// The position a tracker with these errors reports for the true
    /// position `p_mm` (its own frame, mm), with the random part given as
    /// standard normals `z = [range, azimuth, elevation]` (zeros: the
    /// systematic part alone).
    pub fn measured(&self, p_mm: [f64; 3], z: [f64; 3]) -> [f64; 3] {
        let [x, y, zc] = p_mm;
        let r = (x * x + y * y + zc * zc).sqrt();
        if r == 0.0 {
            return p_mm;
        }
        let h = y.atan2(x);
        let v = (zc / r).clamp(-1.0, 1.0).acos();
        let (sv, cv) = v.sin_cos();
        let sv = if sv.abs() < 1e-9 { 1e-9_f64.copysign(sv) } else { sv };
        const UM: f64 = 1e-3;
        const URAD: f64 = 1e-6;
        let x2 = self.transit_offset_um * UM;
        let dr =
            x2 * sv + self.range_offset_um * UM + self.range_scale_ppm * 1e-6 * r + z[0] * self.range_noise_um * UM;
        let eh: f64 = self.azimuth.iter().map(|e| e.at(h)).sum();
        let dh = self.beam_offset_um * UM / (r * sv)
            + self.beam_tilt_urad * URAD / sv
            + self.transit_tilt_urad * URAD * cv / sv
            + eh
            + z[1] * self.angle_noise_urad * URAD / sv;
        let elevation = std::f64::consts::FRAC_PI_2 - v;
        let ee: f64 = self.elevation.iter().map(|e| e.at(elevation)).sum();
        let dv = self.beam_offset_normal_um * UM / r + x2 * cv / r + self.vertical_index_urad * URAD - ee
            + z[2] * self.angle_noise_urad * URAD;
        if dr == 0.0 && dh == 0.0 && dv == 0.0 {
            // The ideal tracker without noise: the position itself, to the bit.
            return p_mm;
        }
        let (rm, hm, vm) = (r + dr, h + dh, v + dv);
        let (svm, cvm) = vm.sin_cos();
        let (shm, chm) = hm.sin_cos();
        [rm * svm * chm, rm * svm * shm, rm * cvm]
    }

    /// The standard deviation of the random part of a reading at `p_mm`,
    /// per coordinate (the larger of the transverse and the range parts), mm.
    pub fn random_sd_mm(&self, p_mm: [f64; 3]) -> f64 {
        let r = p_mm.iter().map(|c| c * c).sum::<f64>().sqrt();
        (r * self.angle_noise_urad * 1e-6).max(self.range_noise_um * 1e-3)
    }

    /// Parse a `[tracker_errors]` table; `at(key)` is the line of a key.
    pub fn parse_spec(
        t: &toml::Table,
        at: &dyn Fn(&str) -> Option<usize>,
    ) -> Result<TrackerErrorSpec, (Option<usize>, String)> {
        if let Some(v) = t.get("none") {
            return match v.as_bool() {
                Some(true) if t.len() == 1 => Ok(TrackerErrorSpec::None),
                Some(true) => {
                    Err((at("none"), "tracker_errors: none = true is the ideal tracker: give no other key".into()))
                }
                Some(false) => {
                    Err((at("none"), "tracker_errors.none: only none = true has a meaning (omit the key)".into()))
                }
                None => Err((at("none"), format!("tracker_errors.none must be true, got {v}"))),
            };
        }
        let mut e = TrackerErrors::ideal();
        for (key, value) in t {
            match key.as_str() {
                "azimuth" | "elevation" => {
                    let list = harmonics(key, value).map_err(|m| (at(key), m))?;
                    if key == "azimuth" {
                        e.azimuth = list;
                    } else {
                        e.elevation = list;
                    }
                }
                k => {
                    let Some(&(_, limit)) = NUMBER_KEYS.iter().find(|(n, _)| *n == k) else {
                        let known: Vec<&str> = NUMBER_KEYS.iter().map(|(n, _)| *n).collect();
                        return Err((
                            at(k),
                            format!(
                                "tracker_errors: unknown key '{k}' (expected none, azimuth, elevation, {})",
                                known.join(", ")
                            ),
                        ));
                    };
                    let x = match value {
                        toml::Value::Float(f) => *f,
                        toml::Value::Integer(i) => *i as f64,
                        v => return Err((at(k), format!("tracker_errors.{k} must be a number, got {v}"))),
                    };
                    if !(x.is_finite() && x.abs() <= limit) {
                        return Err((
                            at(k),
                            format!(
                                "tracker_errors.{k}: {} is not within +/-{limit} (micrometres, microradians, ppm)",
                                Num(x)
                            ),
                        ));
                    }
                    if (k.ends_with("noise_urad") || k.ends_with("noise_um")) && x < 0.0 {
                        return Err((
                            at(k),
                            format!("tracker_errors.{k}: a standard deviation is not negative, got {}", Num(x)),
                        ));
                    }
                    *e.number_mut(k) = x;
                }
            }
        }
        Ok(TrackerErrorSpec::Given(e))
    }

    /// The `[tracker_errors]` section that [`TrackerErrors::parse_spec`] reads back.
    pub fn to_toml(&self) -> String {
        let mut s = String::from("[tracker_errors]\n");
        for (name, list) in [("azimuth", &self.azimuth), ("elevation", &self.elevation)] {
            if list.is_empty() {
                continue;
            }
            let items: Vec<String> = list
                .iter()
                .map(|h| {
                    format!(
                        "{{order = {}, amplitude_urad = {}, phase_deg = {}}}",
                        h.order,
                        Num(h.amplitude_urad),
                        Num(h.phase_deg)
                    )
                })
                .collect();
            let _ = writeln!(s, "{name} = [{}]", items.join(", "));
        }
        for (key, _) in NUMBER_KEYS {
            let _ = writeln!(s, "{key} = {}", Num(self.number(key)));
        }
        s
    }
}

/// An encoder's harmonics: `[{order, amplitude_urad, phase_deg}, ...]`.
fn harmonics(key: &str, value: &toml::Value) -> Result<Vec<EncoderHarmonic>, String> {
    let items = value
        .as_array()
        .ok_or(format!("tracker_errors.{key} must be an array of {{order, amplitude_urad, phase_deg}}"))?;
    let mut out = Vec::new();
    for (i, item) in items.iter().enumerate() {
        let name = format!("tracker_errors.{key}[{}]", i + 1);
        let t = item.as_table().ok_or(format!("{name} must be a table {{order, amplitude_urad, phase_deg}}"))?;
        for k in t.keys() {
            if !["order", "amplitude_urad", "phase_deg"].contains(&k.as_str()) {
                return Err(format!("{name}: unknown key '{k}' (expected order, amplitude_urad, phase_deg)"));
            }
        }
        let order = match t.get("order").and_then(toml::Value::as_integer) {
            Some(o) if (1..=1000).contains(&o) => o as u32,
            _ => {
                return Err(format!("{name}.order must be an integer from 1 to 1000 (cycles per turn of the encoder)"));
            }
        };
        let num = |k: &str| match t.get(k) {
            Some(toml::Value::Float(f)) => Some(*f),
            Some(toml::Value::Integer(i)) => Some(*i as f64),
            _ => None,
        };
        let amplitude_urad = match num("amplitude_urad") {
            Some(a) if a.is_finite() && (0.0..=1000.0).contains(&a) => a,
            _ => return Err(format!("{name}.amplitude_urad must be a number from 0 to 1000 (microradians)")),
        };
        let phase_deg = match t.get("phase_deg") {
            None => 0.0,
            Some(_) => match num("phase_deg") {
                Some(p) if p.is_finite() && p.abs() <= 1e6 => p,
                _ => return Err(format!("{name}.phase_deg must be a number (degrees)")),
            },
        };
        out.push(EncoderHarmonic { order, amplitude_urad, phase_deg });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
        a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt()
    }

    #[test]
    fn the_ideal_tracker_measures_the_true_position_without_noise() {
        let p = [2500.0, 800.0, -300.0];
        let m = TrackerErrors::ideal().measured(p, [0.0; 3]);
        assert!(dist(m, p) < 1e-9, "{m:?}");
        assert!(TrackerErrors::ideal().is_ideal());
    }

    #[test]
    fn each_term_moves_the_point_as_its_cause_does() {
        let p = [2500.0, 800.0, -300.0];
        let r = dist(p, [0.0; 3]);
        let zero = TrackerErrors::ideal().without_noise();
        // A range offset moves the point along the line of sight by itself.
        let m = TrackerErrors { range_offset_um: 10.0, ..zero.clone() }.measured(p, [0.0; 3]);
        assert!((dist(m, [0.0; 3]) - r - 0.010).abs() < 1e-9);
        // An azimuth error of 5 urad moves it sideways by R sin V x 5 urad.
        let harmonic =
            EncoderHarmonic { order: 1, amplitude_urad: 5.0, phase_deg: 90.0 - 800f64.atan2(2500.0).to_degrees() };
        let m = TrackerErrors { azimuth: vec![harmonic], ..zero.clone() }.measured(p, [0.0; 3]);
        let horizontal = (p[0] * p[0] + p[1] * p[1]).sqrt();
        assert!((dist(m, p) - horizontal * 5e-6).abs() < 1e-9, "{}", dist(m, p));
        assert!((dist(m, [0.0; 3]) - r).abs() < 1e-9, "an angle does not change the range");
        // A beam offset is a constant transverse displacement of its size.
        let m = TrackerErrors { beam_offset_um: 7.0, ..zero.clone() }.measured(p, [0.0; 3]);
        assert!((dist(m, p) - 0.007).abs() < 1e-7, "{}", dist(m, p));
        // Noise: one unit of the range's normal is its standard deviation.
        let m = TrackerErrors { range_noise_um: 2.0, ..zero }.measured(p, [1.0, 0.0, 0.0]);
        assert!((dist(m, [0.0; 3]) - r - 0.002).abs() < 1e-9);
    }

    #[test]
    fn the_section_parses_writes_back_and_names_its_defects() {
        let text = "azimuth = [{order = 1, amplitude_urad = 3.0, phase_deg = 20.0}, {order = 2, amplitude_urad = 2}]\n\
                    transit_offset_um = 5.0\nbeam_offset_um = 5\nrange_offset_um = 3.0\n";
        let t: toml::Table = text.parse().unwrap();
        let no_line = |_: &str| None;
        let TrackerErrorSpec::Given(e) = TrackerErrors::parse_spec(&t, &no_line).unwrap() else { panic!() };
        assert_eq!(e.azimuth.len(), 2);
        assert_eq!((e.transit_offset_um, e.beam_offset_um, e.range_offset_um), (5.0, 5.0, 3.0));
        assert_eq!(e.angle_noise_urad, TYPICAL_ANGLE_NOISE_URAD, "the random part typical unless given");
        let back: toml::Table = e.to_toml().parse().unwrap();
        let again = TrackerErrors::parse_spec(back["tracker_errors"].as_table().unwrap(), &no_line).unwrap();
        assert_eq!(again, TrackerErrorSpec::Given(e));
        let none: toml::Table = "none = true".parse().unwrap();
        assert_eq!(TrackerErrors::parse_spec(&none, &no_line).unwrap(), TrackerErrorSpec::None);
        for (bad, says) in [
            ("none = true\nbeam_offset_um = 1", "give no other key"),
            ("beam_offset = 1", "unknown key 'beam_offset'"),
            ("beam_offset_um = 0.5e6", "not within"),
            ("angle_noise_urad = -1", "not negative"),
            ("azimuth = [{order = 0, amplitude_urad = 1}]", "azimuth[1].order"),
            ("azimuth = [{order = 1, amplitude = 1}]", "unknown key 'amplitude'"),
            ("elevation = 3", "must be an array"),
        ] {
            let t: toml::Table = bad.parse().unwrap();
            let e = TrackerErrors::parse_spec(&t, &no_line).unwrap_err().1;
            assert!(e.contains(says), "{bad}: {e}");
        }
    }

    #[test]
    fn the_mpe_is_the_at_class_formula() {
        assert!((transverse_mpe_um(2600.0) - 30.6).abs() < 1e-12);
    }

    fn axis(center: [f64; 3], radius: f64) -> AxisFit {
        AxisFit {
            center_mm: center,
            normal: [0.0, 0.0, 1.0],
            u: [1.0, 0.0, 0.0],
            v: [0.0, 1.0, 0.0],
            radius_mm: radius,
            zero_offset_deg: 0.0,
            plane_rms_mm: 0.0,
            circle_rms_mm: 0.0,
            points: 100,
        }
    }

    #[test]
    fn the_systematic_part_is_the_mpe_across_the_radius_where_it_moves_the_angle() {
        let mpe = TransverseMpe::AT_CLASS;
        // A small circle far away seen from above its plane (the tracker on
        // the axis, 3 m below the table): every tangent is across the line of
        // sight, at 3 m: (15 + 18) / sqrt 3 um over 100 mm.
        let above = axis([0.0, 0.0, 3000.0], 100.0);
        let d = (3000f64.powi(2) + 100f64.powi(2)).sqrt();
        let want = (mpe.at_um(d) / 1000.0 / 3f64.sqrt() / 100.0).to_degrees();
        assert!((mpe.systematic_angle_u_deg(&above, (0.0, 360.0)) / want - 1.0).abs() < 1e-9);
        // Twice the radius, half the angle; a tracker twice as good, half the angle.
        let wide = axis([0.0, 0.0, 3000.0], 200.0);
        let u_wide = mpe.systematic_angle_u_deg(&wide, (0.0, 360.0));
        assert!((u_wide / want - 0.5).abs() < 0.01, "{u_wide}");
        let better = TransverseMpe { constant_um: 7.5, per_m_um: 3.0 };
        assert!((better.systematic_angle_u_deg(&above, (0.0, 360.0)) / want - 0.5).abs() < 1e-9);
        // Seen edge-on (the tracker in the circle's plane), the tangent runs
        // along the line of sight at two places: less than from above.
        let edge_on = axis([3000.0, 0.0, 0.0], 100.0);
        let u_edge = mpe.systematic_angle_u_deg(&edge_on, (0.0, 360.0));
        assert!(u_edge < 0.75 * want && u_edge > 0.6 * want, "{u_edge} against {want}");
        // Over the arc where the tangent is across the line of sight only
        // (about 3.1 m away: the MPE there).
        let across = mpe.systematic_angle_u_deg(&edge_on, (-10.0, 10.0));
        let there = (mpe.at_um(3100.0) / 1000.0 / 3f64.sqrt() / 100.0).to_degrees();
        assert!(across <= there && across > 0.98 * there, "{across} against {there}");
    }
}
