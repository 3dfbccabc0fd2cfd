//! What the keys' own ranges cannot say ([`super::schema`] checks those):
//! the sections consistent with each other, each defect named at the key a
//! reader changes, citing the other keys involved with their lines.

use super::place::{Defect, Places};
use super::{CanTransport, PositionerConfig, SurveyConfig, derived};
use survey_acquire::ReferenceKind;
use survey_processing::num::Num;

/// The value of `key` as written, else `value` in exponent form where long.
fn shown(at: &Places, key: &str, value: f64) -> String {
    at.written(key).map_or_else(|| Num(value).to_string(), str::to_string)
}

/// `[asset]`'s interval within its bounds: `interval_min_days` <=
/// `interval_days` <= `interval_max_days` (defaults 7, 90, 365).
fn check_interval(a: &super::AssetSection, at: &Places) -> Result<(), Defect> {
    use super::AssetSection as A;
    let min = a.interval_min_days.unwrap_or(A::DEFAULT_MIN_DAYS);
    let max = a.interval_max_days.unwrap_or(A::DEFAULT_MAX_DAYS);
    let days = a.interval_days.unwrap_or(A::DEFAULT_INTERVAL_DAYS);
    let bound = |key: &str, default: f64| at.cite(key, &Num(default).to_string());
    if max < min {
        let text = format!(
            "{} is below {}: the longest interval cannot be shorter than the shortest",
            shown(at, "asset.interval_max_days", max),
            bound("asset.interval_min_days", A::DEFAULT_MIN_DAYS)
        );
        let key = if at.written("asset.interval_max_days").is_some() {
            "asset.interval_max_days"
        } else {
            "asset.interval_min_days"
        };
        return Err(at.defect(key, text));
    }
    if !(min..=max).contains(&days) {
        let (side, key, default) = if days < min {
            ("below", "asset.interval_min_days", A::DEFAULT_MIN_DAYS)
        } else {
            ("above", "asset.interval_max_days", A::DEFAULT_MAX_DAYS)
        };
        let text = format!(
            "{} days is {side} {}: the first interval lies within the bounds a review keeps to",
            shown(at, "asset.interval_days", days),
            bound(key, default)
        );
        let key = if at.written("asset.interval_days").is_some() { "asset.interval_days" } else { key };
        return Err(at.defect(key, text));
    }
    Ok(())
}

impl SurveyConfig {
    /// The sections consistent, in this order: the asset, the reference's
    /// instruments, the plan, the durations the timing makes, the arm, the
    /// positioner, the drift control.
    pub(super) fn check(&self, at: &Places) -> Result<(), Defect> {
        if let Some(a) = &self.asset {
            crate::asset::asset_id(&a.id).map_err(|e| at.defect("asset.id", e))?;
            check_interval(a, at)?;
        }
        self.check_reference(at)?;
        if let Some([lo, hi]) = self.survey.travel_deg
            && hi <= lo
        {
            let text = format!(
                "{} is not an increasing pair: it takes [low, high], low below high, in deg",
                shown(at, "survey.travel_deg", lo)
            );
            return Err(at.defect("survey.travel_deg", text));
        }
        derived::check(self, at)?;
        self.check_arm(at)?;
        self.check_smrs(at)?;
        if self.machine_frame.is_some() && self.reference() != ReferenceKind::Tracker {
            return Err(at.defect(
                "machine_frame.origin_mm",
                "the machine's frame states where the tracker measures the axis: it needs the tracker as the reference",
            ));
        }
        self.check_positioner(at)?;
        self.check_drift_control(at)
    }

    /// `[smrs]`: 2 to 12 SMRs, one height each when heights are given, no
    /// two at the same place, a tracker to point at them, a step scan.
    fn check_smrs(&self, at: &Places) -> Result<(), Defect> {
        let Some(s) = &self.smrs else { return Ok(()) };
        let max = survey_processing::smrs::MAX_SMRS;
        if !(2..=max).contains(&s.phases_deg.len()) {
            let text = format!("{} phases: a survey measures 2 to {max} reflectors at a target", s.phases_deg.len());
            return Err(at.defect("smrs.phases_deg", text));
        }
        if let Some(h) = &s.heights_mm
            && h.len() != s.phases_deg.len()
        {
            let text = format!(
                "{} heights for {} phases in {}: one height per reflector",
                h.len(),
                s.phases_deg.len(),
                at.cite("smrs.phases_deg", "required")
            );
            return Err(at.defect("smrs.heights_mm", text));
        }
        let mounts = s.mounts();
        for (i, a) in mounts.iter().enumerate() {
            if mounts[..i].iter().any(|b| {
                survey_processing::types::wrap_180(a.phase_deg - b.phase_deg).abs() < 1e-6
                    && (a.height_mm - b.height_mm).abs() < 1e-6
            }) {
                let text = format!("two reflectors at the same place ({} deg)", Num(s.phases_deg[i]));
                return Err(at.defect("smrs.phases_deg", text));
            }
        }
        if self.tracker.is_none() || self.survey.reference.is_some_and(|r| r == ReferenceKind::Autocollimator) {
            return Err(
                at.defect("smrs.phases_deg", "several reflectors need the tracker as the reference ([tracker])")
            );
        }
        if self.survey.scan == Some(survey_plan::ScanMode::Continuous) {
            return Err(at.defect(
                "smrs.phases_deg",
                "several reflectors are measured one after the other at rest: survey.scan must be \"step\"",
            ));
        }
        Ok(())
    }

    /// The reference's instruments are configured: the tracker's section,
    /// or the autocollimator's with a polygon of at least 2 faces whose
    /// certificate, when given, holds one value a face.
    fn check_reference(&self, at: &Places) -> Result<(), Defect> {
        let key = "survey.reference";
        let chosen = match at.written(key) {
            Some(w) => format!("{w} needs"),
            None => "not given, so the reference is the tracker, which needs".to_string(),
        };
        let lacks = |section: &str| {
            at.defect(key, format!("{chosen} a {section} section, and the file has none: add it or change {key}"))
        };
        match self.reference() {
            ReferenceKind::Tracker if self.tracker.is_none() => return Err(lacks("[tracker] (driver, address)")),
            ReferenceKind::Autocollimator => {
                if self.autocollimator.is_none() {
                    return Err(lacks("[autocollimator] (driver, port)"));
                }
                let Some(p) = &self.polygon else { return Err(lacks("[polygon] (faces, certificate_arcsec)")) };
                if p.faces < 2 {
                    let text = format!(
                        "{} is too few: the autocollimator reference needs a polygon of 2 to 3600 faces",
                        p.faces
                    );
                    return Err(at.defect("polygon.faces", text));
                }
                let n = p.certificate_arcsec.len();
                if n != 0 && n != p.faces as usize {
                    let text = format!(
                        "{n} values for {}: it takes one value a face (or none)",
                        at.cite("polygon.faces", "required")
                    );
                    return Err(at.defect("polygon.certificate_arcsec", text));
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// `[arm]`: the tolerance of the radius no larger than the radius. The
    /// radius is blamed unless the tolerance departs from its default.
    fn check_arm(&self, at: &Places) -> Result<(), Defect> {
        let Some(arm) = &self.arm else { return Ok(()) };
        if arm.radius_tolerance_mm <= arm.radius_mm {
            return Ok(());
        }
        let (radius, tolerance) = ("arm.radius_mm", "arm.radius_tolerance_mm");
        Err(if arm.radius_tolerance_mm != super::radius_tolerance() {
            let text = format!(
                "{} mm is more than the radius, {}: it takes a number above 0, at most the radius",
                shown(at, tolerance, arm.radius_tolerance_mm),
                at.cite(radius, "required")
            );
            at.defect(tolerance, text)
        } else {
            let text = format!(
                "{} mm is less than its tolerance, {}: the radius is at least the tolerance",
                shown(at, radius, arm.radius_mm),
                at.cite(tolerance, "5 mm")
            );
            at.defect(radius, text)
        })
    }

    /// `[positioner]`: the CAN link, and the engine's deadline of a call
    /// against the driver's own.
    fn check_positioner(&self, at: &Places) -> Result<(), Defect> {
        if let PositionerConfig::Canopen { transport, interface, port, bitrate, .. } = &self.positioner
            && let Some(Err(_)) = self.positioner.can_link()
        {
            let (key, text) = match (transport, interface, port) {
                (CanTransport::Socketcan, None, _) => (
                    "positioner.interface",
                    "missing: a CANopen drive on SocketCAN needs it, e.g. \"can0\"".to_string(),
                ),
                (CanTransport::Socketcan, Some(_), Some(_)) => (
                    "positioner.port",
                    "is for transport = \"slcan\": on SocketCAN name the interface only".to_string(),
                ),
                (CanTransport::Slcan, _, None) => (
                    "positioner.port",
                    "missing: transport = \"slcan\" needs the adapter's serial device, e.g. \"/dev/ttyACM0\""
                        .to_string(),
                ),
                (CanTransport::Slcan, Some(_), Some(_)) => (
                    "positioner.interface",
                    "is for SocketCAN: with transport = \"slcan\" name the port only".to_string(),
                ),
                _ => (
                    "positioner.bitrate",
                    format!(
                        "{} has no SLCAN command: it takes one of 10000, 20000, 50000, 100000, 125000, 250000, \
                         500000, 750000, 800000 or 1000000",
                        bitrate.map_or_else(String::new, |b| b.to_string())
                    ),
                ),
            };
            return Err(at.defect(key, text));
        }
        self.check_deadline(at)
    }

    /// The engine's deadline of a call must be longer than the driver's own
    /// (its deadline and the drain of late replies after it): a late reply
    /// is then met, drained and matched by the driver, never left on the
    /// line by a call the engine cancelled. The engine's key is blamed when
    /// the file sets it, else the driver's.
    fn check_deadline(&self, at: &Places) -> Result<(), Defect> {
        let Some((key, own, late)) = self.positioner.own_deadline() else { return Ok(()) };
        let call = self.timing().call_timeout;
        if call > own + late {
            return Ok(());
        }
        let engine = "timing.call_timeout_s";
        let drain = if late.is_zero() {
            String::new()
        } else {
            format!(" and the {} ms it then drains late replies", late.as_millis())
        };
        Err(if at.has(engine) || !at.has(key) {
            let text = format!(
                "{} s is not longer than the positioner's own deadline, {}{drain}: raise {engine} or lower {key}",
                shown(at, engine, call.as_secs_f64()),
                at.cite(key, &format!("{} ms", own.as_millis()))
            );
            at.defect(engine, text)
        } else {
            let text = format!(
                "{} ms{drain} is not shorter than the engine's deadline of a call, {}: lower {key} or raise {engine}",
                shown(at, key, own.as_millis() as f64),
                at.cite(engine, &format!("{} s", Num(call.as_secs_f64())))
            );
            at.defect(key, text)
        })
    }

    /// `[drift_control]`: a reference target within the travel of a
    /// partial-range axis.
    fn check_drift_control(&self, at: &Places) -> Result<(), Defect> {
        let Some(d) = &self.drift_control else { return Ok(()) };
        if let Some([lo, hi]) = self.survey.travel_deg
            && !(lo..=hi).contains(&d.reference_deg)
        {
            let key = "drift_control.reference_deg";
            let text = format!(
                "{} deg is outside the travel, {}: the reference target lies within it",
                shown(at, key, d.reference_deg),
                at.cite("survey.travel_deg", "a full turn")
            );
            return Err(at.defect(key, text));
        }
        Ok(())
    }
}
