//! The positioner error model (the contract's model file, TOML).
//!
//! Pure data and arithmetic: the simulators generate readouts with it and the
//! processing explains measured data with it, so both agree by construction.
//!
//! A periodic effect contributes `amplitude_deg * sin(cycles_per_rev * theta + phase_deg)`
//! with `theta` the axis angle; backlash adds `+amplitude/2` on forward approaches
//! and `-amplitude/2` on reverse ones; drift adds `rate_deg_per_run` per run
//! elapsed; noise is a normal, non-repeatable error of `sigma_deg`.

pub use motions::{AxisMotions, MOTION_KINDS, MotionHarmonic, SmrPlace};

use crate::num::Num;
use crate::tracker_errors::{TrackerErrorSpec, TrackerErrors};
use crate::types::Direction;
use std::fmt::Write as _;

/// What the positioner is built from: the basis for naming spectral lines.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Design {
    /// Gear passes per axis revolution (a 12:1 pinion gives 12).
    pub gear_ratios: Vec<f64>,
    /// Tooth counts of gears that turn once per revolution.
    pub tooth_counts: Vec<u32>,
    /// Number of encoder heads (2 diametric heads cancel odd harmonics).
    pub encoder_heads: Option<u32>,
}

/// The kind of a periodic effect, named as in the model file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PeriodicKind {
    Eccentricity,
    Ellipticity,
    GearPass,
    ToothMesh,
    Harmonic,
}

impl PeriodicKind {
    pub fn as_str(self) -> &'static str {
        match self {
            PeriodicKind::Eccentricity => "eccentricity",
            PeriodicKind::Ellipticity => "ellipticity",
            PeriodicKind::GearPass => "gear_pass",
            PeriodicKind::ToothMesh => "tooth_mesh",
            PeriodicKind::Harmonic => "harmonic",
        }
    }

    /// The fixed frequency of the kind, if it has one.
    pub fn fixed_cycles(self) -> Option<f64> {
        match self {
            PeriodicKind::Eccentricity => Some(1.0),
            PeriodicKind::Ellipticity => Some(2.0),
            _ => None,
        }
    }
}

/// How a drift grows (the contract's `shape`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DriftShape {
    /// Linearly in time, `rate_deg_per_run` over one run's duration (the default).
    #[default]
    Ramp,
    /// Constant within a run, jumping by `rate_deg_per_run` between runs
    /// (re-homing, a reference set up again each run).
    Step,
}

impl DriftShape {
    /// `"ramp"` or `"step"`.
    pub fn as_str(self) -> &'static str {
        match self {
            DriftShape::Ramp => "ramp",
            DriftShape::Step => "step",
        }
    }

    /// The drift, in runs of `rate`, after `runs_elapsed` runs (fractional
    /// within a run): the time itself for a ramp, the runs completed for a step.
    pub fn runs(self, runs_elapsed: f64) -> f64 {
        self.runs_at(DriftTime::elapsed(runs_elapsed))
    }

    /// The drift, in runs of `rate`, at `t`: `t.runs_elapsed` for a ramp,
    /// `t.run_index` for a step.
    pub fn runs_at(self, t: DriftTime) -> f64 {
        match self {
            DriftShape::Ramp => t.runs_elapsed,
            DriftShape::Step => t.run_index,
        }
    }
}

/// When a sample was taken, as the drift sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriftTime {
    /// Runs elapsed since the first sample (fractional within a run): the time of a ramp.
    pub runs_elapsed: f64,
    /// Runs completed before this sample's run (0 in the first run): the time of a step.
    pub run_index: f64,
}

impl DriftTime {
    /// A time given in runs elapsed only: the run index is its whole part
    /// (the simulators' clock, where run `k` starts at exactly `k` runs).
    pub fn elapsed(runs_elapsed: f64) -> Self {
        Self { runs_elapsed, run_index: runs_elapsed.floor() }
    }
}

/// One error effect of the model file.
#[derive(Debug, Clone, PartialEq)]
pub enum Effect {
    Periodic { kind: PeriodicKind, cycles_per_rev: f64, amplitude_deg: f64, phase_deg: f64 },
    Backlash { amplitude_deg: f64 },
    Drift { rate_deg_per_run: f64, shape: DriftShape },
    Noise { sigma_deg: f64 },
}

impl Effect {
    /// The kind as written in the model file.
    pub fn kind_str(&self) -> &'static str {
        match self {
            Effect::Periodic { kind, .. } => kind.as_str(),
            Effect::Backlash { .. } => "backlash",
            Effect::Drift { .. } => "drift",
            Effect::Noise { .. } => "noise",
        }
    }

    /// The contribution of a periodic effect at axis angle `theta_deg`.
    pub fn periodic_at(&self, theta_deg: f64) -> f64 {
        match self {
            Effect::Periodic { cycles_per_rev, amplitude_deg, phase_deg, .. } => {
                amplitude_deg * (cycles_per_rev * theta_deg + phase_deg).to_radians().sin()
            }
            _ => 0.0,
        }
    }

    /// The contribution of a drift effect at `t`.
    pub fn drift_at(&self, t: DriftTime) -> f64 {
        match self {
            Effect::Drift { rate_deg_per_run, shape } => rate_deg_per_run * shape.runs_at(t),
            _ => 0.0,
        }
    }
}

/// A positioner error model: its design and its effects; and, for a
/// simulated bench, the reference instrument's own error (`[tracker_errors]`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Model {
    pub design: Design,
    pub effects: Vec<Effect>,
    /// The simulated tracker's own error ([`crate::tracker_errors`]); the
    /// processing of a survey never reads it.
    pub tracker_errors: TrackerErrorSpec,
    /// The SMRs on the simulated table (`[smrs]`), when given.
    pub smrs: Option<Vec<crate::smrs::SmrMount>>,
    /// The simulated polygon's true face errors and its certificate
    /// (`[polygon]`), when given.
    pub polygon: Option<PolygonTruth>,
    /// The simulated autocollimator's scale error, parts per million
    /// (`[autocollimator_errors] scale_ppm`; 0 when not given).
    pub autocollimator_scale_ppm: f64,
    /// The axis's error motions (ISO 230-7: [`motions`]), which move the
    /// simulated table's SMRs and leave the readout alone.
    pub motions: AxisMotions,
    /// The machine's frame in the simulated tracker's (`[machine_frame]`),
    /// when given: the axis's location is stated in it too.
    pub machine_frame: Option<crate::frame::MachineFrame>,
}

/// A simulated polygon: what its faces truly are and what its certificate
/// says (a certificate that is not the truth is a stale one).
#[derive(Debug, Clone, PartialEq)]
pub struct PolygonTruth {
    /// Each face's true deviation from its nominal angle, arcsec.
    pub face_errors_arcsec: Vec<f64>,
    /// What the certificate states, arcsec (`None`: the truth).
    pub certificate_arcsec: Option<Vec<f64>>,
}

impl PolygonTruth {
    /// What the certificate states.
    pub fn certificate(&self) -> &[f64] {
        self.certificate_arcsec.as_deref().unwrap_or(&self.face_errors_arcsec)
    }
}

/// A defect of a model file, naming where it is.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}{}: {message}", source_name, line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct ModelError {
    /// The file (or `<model>` for text without a file).
    pub source_name: String,
    /// The 1-based line, when it is known.
    pub line: Option<usize>,
    /// What is wrong, naming the key (`effect[3].sigma_deg`).
    pub message: String,
}

const KINDS: &str = "eccentricity, ellipticity, gear_pass, tooth_mesh, harmonic, backlash, drift, noise, \
                     radial_motion, axial_motion, tilt_motion, bearing_noise";

impl Model {
    /// Parse and validate model-file text; `source_name` names it in errors.
    pub fn parse(text: &str, source_name: &str) -> Result<Self, ModelError> {
        let err =
            |line: Option<usize>, message: String| ModelError { source_name: source_name.to_string(), line, message };
        let table: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            let line = e.span().map(|s| line_of_offset(text, s.start));
            err(line, format!("not valid TOML: {}", e.message()))
        })?;
        let locate = Locator { text };
        for key in table.keys() {
            if !["design", "effect", "tracker_errors", "smrs", "polygon", "autocollimator_errors", "machine_frame"]
                .contains(&key.as_str())
            {
                return Err(err(
                    locate.top_key(key),
                    format!(
                        "unknown top-level key '{key}' (expected [design], [[effect]], [tracker_errors], [smrs], \
                         [polygon], [autocollimator_errors] and [machine_frame])"
                    ),
                ));
            }
        }
        let design = match table.get("design") {
            None => Design::default(),
            Some(toml::Value::Table(t)) => parse_design(t, &locate).map_err(|(l, m)| err(l, m))?,
            Some(_) => return Err(err(locate.top_key("design"), "'design' must be a table".into())),
        };
        let mut effects = Vec::new();
        let mut motions = AxisMotions::default();
        match table.get("effect") {
            None => {}
            Some(toml::Value::Array(items)) => {
                for (i, item) in items.iter().enumerate() {
                    let toml::Value::Table(t) = item else {
                        return Err(err(None, format!("effect[{}] must be a table ([[effect]])", i + 1)));
                    };
                    match t.get("kind").and_then(|k| k.as_str()).filter(|k| MOTION_KINDS.contains(k)) {
                        Some(kind) => {
                            motions::parse_effect(t, kind, i, &locate, &mut motions).map_err(|(l, m)| err(l, m))?
                        }
                        None => effects.push(parse_effect(t, i, &locate).map_err(|(l, m)| err(l, m))?),
                    }
                }
            }
            Some(_) => {
                return Err(err(locate.top_key("effect"), "'effect' must be an array of tables ([[effect]])".into()));
            }
        }
        let tracker_errors = match table.get("tracker_errors") {
            None => TrackerErrorSpec::Typical,
            Some(toml::Value::Table(t)) => {
                let header = locate.section_header("tracker_errors");
                TrackerErrors::parse_spec(t, &|key| locate.key_in_table(header, key)).map_err(|(l, m)| err(l, m))?
            }
            Some(_) => return Err(err(locate.top_key("tracker_errors"), "'tracker_errors' must be a table".into())),
        };
        let smrs = match table.get("smrs") {
            None => None,
            Some(toml::Value::Table(t)) => {
                let header = locate.section_header("smrs");
                Some(
                    crate::smrs::parse_section(t, "smrs", &|key| locate.key_in_table(header, key))
                        .map_err(|(l, m)| err(l, m))?,
                )
            }
            Some(_) => return Err(err(locate.top_key("smrs"), "'smrs' must be a table".into())),
        };
        let machine_frame = match table.get("machine_frame") {
            None => None,
            Some(toml::Value::Table(t)) => {
                let header = locate.section_header("machine_frame");
                let at = |key: &str| locate.key_in_table(header, key);
                let f = crate::frame::parse_section(t, "machine_frame", &at);
                Some(f.map_err(|(l, m)| err(l.or(header), m))?)
            }
            Some(_) => return Err(err(locate.top_key("machine_frame"), "'machine_frame' must be a table".into())),
        };
        let polygon = match table.get("polygon") {
            None => None,
            Some(toml::Value::Table(t)) => {
                let header = locate.section_header("polygon");
                Some(parse_polygon(t, &|key| locate.key_in_table(header, key)).map_err(|(l, m)| err(l, m))?)
            }
            Some(_) => return Err(err(locate.top_key("polygon"), "'polygon' must be a table".into())),
        };
        let autocollimator_scale_ppm = match table.get("autocollimator_errors") {
            None => 0.0,
            Some(toml::Value::Table(t)) => {
                let header = locate.section_header("autocollimator_errors");
                let at = |key: &str| locate.key_in_table(header, key);
                if let Some(k) = t.keys().find(|k| *k != "scale_ppm") {
                    return Err(err(at(k), format!("autocollimator_errors: unknown key '{k}' (expected scale_ppm)")));
                }
                match t.get("scale_ppm").map(number) {
                    None => 0.0,
                    Some(Some(v)) if v.is_finite() && v.abs() <= 100_000.0 => v,
                    Some(_) => {
                        return Err(err(
                            at("scale_ppm"),
                            "autocollimator_errors.scale_ppm must be a number within +/-100000 (parts per million)"
                                .into(),
                        ));
                    }
                }
            }
            Some(_) => {
                return Err(err(
                    locate.top_key("autocollimator_errors"),
                    "'autocollimator_errors' must be a table".into(),
                ));
            }
        };
        Ok(Model { design, effects, tracker_errors, smrs, polygon, autocollimator_scale_ppm, motions, machine_frame })
    }

    /// The model as a model file (TOML), which [`Model::parse`] reads back.
    pub fn to_toml(&self) -> String {
        let mut s = String::from("[design]\n");
        let ratios: Vec<String> = self.design.gear_ratios.iter().map(|r| fmt_num(*r)).collect();
        let teeth: Vec<String> = self.design.tooth_counts.iter().map(|t| t.to_string()).collect();
        let _ = writeln!(s, "gear_ratios = [{}]", ratios.join(", "));
        let _ = writeln!(s, "tooth_counts = [{}]", teeth.join(", "));
        if let Some(h) = self.design.encoder_heads {
            let _ = writeln!(s, "encoder_heads = {h}");
        }
        for e in &self.effects {
            let _ = write!(s, "\n[[effect]]\nkind = \"{}\"\n", e.kind_str());
            match e {
                Effect::Periodic { cycles_per_rev, amplitude_deg, phase_deg, .. } => {
                    let _ = writeln!(s, "cycles_per_rev = {}", fmt_num(*cycles_per_rev));
                    let _ = writeln!(s, "amplitude_deg = {}", fmt_num(*amplitude_deg));
                    let _ = writeln!(s, "phase_deg = {}", fmt_num(*phase_deg));
                }
                Effect::Backlash { amplitude_deg } => {
                    let _ = writeln!(s, "amplitude_deg = {}", fmt_num(*amplitude_deg));
                }
                Effect::Drift { rate_deg_per_run, shape } => {
                    let _ = writeln!(s, "rate_deg_per_run = {}", fmt_num(*rate_deg_per_run));
                    if *shape == DriftShape::Step {
                        let _ = writeln!(s, "shape = \"step\"");
                    }
                }
                Effect::Noise { sigma_deg } => {
                    let _ = writeln!(s, "sigma_deg = {}", fmt_num(*sigma_deg));
                }
            }
        }
        s.push_str(&self.motions.to_toml());
        if let Some(smrs) = &self.smrs {
            s.push('\n');
            s.push_str(&crate::smrs::section_toml(smrs));
        }
        if let Some(f) = &self.machine_frame {
            s.push('\n');
            s.push_str(&f.section_toml());
        }
        if let Some(p) = &self.polygon {
            let list = |v: &[f64]| v.iter().map(|x| fmt_num(*x)).collect::<Vec<_>>().join(", ");
            let _ = write!(s, "\n[polygon]\nface_errors_arcsec = [{}]\n", list(&p.face_errors_arcsec));
            if let Some(c) = &p.certificate_arcsec {
                let _ = writeln!(s, "certificate_arcsec = [{}]", list(c));
            }
        }
        if self.autocollimator_scale_ppm != 0.0 {
            let _ = write!(s, "\n[autocollimator_errors]\nscale_ppm = {}\n", fmt_num(self.autocollimator_scale_ppm));
        }
        match &self.tracker_errors {
            TrackerErrorSpec::Typical => {}
            TrackerErrorSpec::None => s.push_str("\n[tracker_errors]\nnone = true\n"),
            TrackerErrorSpec::Given(e) => {
                s.push('\n');
                s.push_str(&e.to_toml());
            }
        }
        s
    }

    /// Sum of the periodic effects at axis angle `theta_deg`.
    pub fn periodic_error_deg(&self, theta_deg: f64) -> f64 {
        self.effects.iter().map(|e| e.periodic_at(theta_deg)).sum()
    }

    /// Total backlash (forward reads `+backlash/2`, reverse `-backlash/2`).
    pub fn backlash_deg(&self) -> f64 {
        self.effects.iter().map(|e| if let Effect::Backlash { amplitude_deg } = e { *amplitude_deg } else { 0.0 }).sum()
    }

    /// Drift per run.
    pub fn drift_deg_per_run(&self) -> f64 {
        self.effects
            .iter()
            .map(|e| if let Effect::Drift { rate_deg_per_run, .. } = e { *rate_deg_per_run } else { 0.0 })
            .sum()
    }

    /// Standard deviation of the non-repeatable noise (independent noises add in quadrature).
    pub fn noise_sigma_deg(&self) -> f64 {
        self.effects
            .iter()
            .map(|e| if let Effect::Noise { sigma_deg } = e { sigma_deg * sigma_deg } else { 0.0 })
            .sum::<f64>()
            .sqrt()
    }

    /// The repeatable part of the readout error at axis angle `theta_deg`,
    /// approached in `direction`: periodic effects plus backlash.
    pub fn repeatable_error_deg(&self, theta_deg: f64, direction: Direction) -> f64 {
        self.periodic_error_deg(theta_deg) + direction.sign() * self.backlash_deg() / 2.0
    }

    /// The systematic readout error (everything but noise) after `runs_elapsed`
    /// runs (0 during the first run; fractional values for drift within a run).
    pub fn systematic_error_deg(&self, theta_deg: f64, direction: Direction, runs_elapsed: f64) -> f64 {
        self.repeatable_error_deg(theta_deg, direction) + self.drift_deg(runs_elapsed)
    }

    /// The drift after `runs_elapsed` runs (fractional within a run), each
    /// drift effect by its shape.
    pub fn drift_deg(&self, runs_elapsed: f64) -> f64 {
        self.drift_deg_at(DriftTime::elapsed(runs_elapsed))
    }

    /// The drift at `t`, each drift effect by its shape.
    pub fn drift_deg_at(&self, t: DriftTime) -> f64 {
        self.effects.iter().map(|e| e.drift_at(t)).sum()
    }

    /// The systematic readout error at `t` (a ramp by the time, a step by
    /// the run): what model-gap compares with a survey whose run boundaries
    /// it knows.
    pub fn systematic_error_at(&self, theta_deg: f64, direction: Direction, t: DriftTime) -> f64 {
        self.repeatable_error_deg(theta_deg, direction) + self.drift_deg_at(t)
    }

    /// The model's systematic error made once to be taken at many samples
    /// ([`Systematic::at`]).
    pub fn systematic(&self) -> Systematic {
        let kept = |keep: fn(&Effect) -> bool| self.effects.iter().filter(|e| keep(e)).cloned().collect();
        Systematic {
            periodic: kept(|e| matches!(e, Effect::Periodic { .. })),
            half_backlash_deg: self.backlash_deg() / 2.0,
            drift: kept(|e| matches!(e, Effect::Drift { .. })),
        }
    }

    /// The periodic effects, in file order.
    pub fn periodic_effects(&self) -> impl Iterator<Item = &Effect> {
        self.effects.iter().filter(|e| matches!(e, Effect::Periodic { .. }))
    }
}

/// A model's systematic error ([`Model::systematic_error_at`]) with its
/// effects sorted out once: the periodic terms, half the backlash and the
/// drifts, each list in file order. [`Model::systematic_error_at`] walks
/// every effect three times for each of them; model-gap takes the error at
/// every sample of a survey several times over.
#[derive(Debug, Clone, PartialEq)]
pub struct Systematic {
    /// The periodic effects.
    periodic: Vec<Effect>,
    half_backlash_deg: f64,
    /// The drifts.
    drift: Vec<Effect>,
}

impl Systematic {
    /// [`Model::systematic_error_at`]: the same terms summed in the same
    /// order, the other effects' zeros left out (they could change only the
    /// sign of a zero).
    pub fn at(&self, theta_deg: f64, direction: Direction, t: DriftTime) -> f64 {
        let periodic = self.periodic.iter().map(|e| e.periodic_at(theta_deg)).sum::<f64>();
        let drift = self.drift.iter().map(|e| e.drift_at(t)).sum::<f64>();
        periodic + direction.sign() * self.half_backlash_deg + drift
    }
}

/// Formats a number so that TOML reads it back as the same `f64`.
fn fmt_num(v: f64) -> String {
    let s = format!("{v:?}");
    if s.contains('.') || s.contains('e') || s.contains("inf") || s.contains("NaN") { s } else { format!("{s}.0") }
}

/// A TOML value for a message: a float as [`Num`] shows it.
fn shown(v: &toml::Value) -> String {
    match v {
        toml::Value::Float(f) => Num(*f).to_string(),
        other => other.to_string(),
    }
}

fn line_of_offset(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

/// Finds the line of a key in the model text, for error messages.
struct Locator<'a> {
    text: &'a str,
}

impl Locator<'_> {
    fn lines(&self) -> impl Iterator<Item = (usize, &str)> {
        self.text.lines().enumerate().map(|(i, l)| (i + 1, l.trim()))
    }

    fn top_key(&self, key: &str) -> Option<usize> {
        self.lines()
            .find(|(_, l)| {
                l.starts_with(&format!("[{key}]")) || l.starts_with(&format!("[[{key}]]")) || is_key_line(l, key)
            })
            .map(|(n, _)| n)
    }

    /// The line of `[[effect]]` number `index` (0-based).
    fn effect_header(&self, index: usize) -> Option<usize> {
        self.lines().filter(|(_, l)| l.starts_with("[[effect]]")).nth(index).map(|(n, _)| n)
    }

    /// The line of `key` inside the table starting at `header`.
    fn key_in_table(&self, header: Option<usize>, key: &str) -> Option<usize> {
        let start = header?;
        self.lines()
            .skip(start)
            .take_while(|(_, l)| !l.starts_with('['))
            .find(|(_, l)| is_key_line(l, key))
            .map(|(n, _)| n)
            .or(Some(start))
    }

    fn design_header(&self) -> Option<usize> {
        self.section_header("design")
    }

    /// The line of `[name]`.
    fn section_header(&self, name: &str) -> Option<usize> {
        self.lines().find(|(_, l)| l.starts_with(&format!("[{name}]"))).map(|(n, _)| n)
    }
}

fn is_key_line(line: &str, key: &str) -> bool {
    line.strip_prefix(key).is_some_and(|rest| rest.trim_start().starts_with('='))
}

type Fail = (Option<usize>, String);

fn number(v: &toml::Value) -> Option<f64> {
    match v {
        toml::Value::Float(f) => Some(*f),
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

/// A `[polygon]` table: `face_errors_arcsec` (2 to 3600 faces, each within
/// +/-3600 arcsec) and optionally `certificate_arcsec`, one per face.
fn parse_polygon(t: &toml::Table, at: &dyn Fn(&str) -> Option<usize>) -> Result<PolygonTruth, Fail> {
    if let Some(k) = t.keys().find(|k| *k != "face_errors_arcsec" && *k != "certificate_arcsec") {
        return Err((at(k), format!("polygon: unknown key '{k}' (expected face_errors_arcsec, certificate_arcsec)")));
    }
    let list = |key: &str| -> Result<Option<Vec<f64>>, Fail> {
        let Some(v) = t.get(key) else { return Ok(None) };
        let arr = v.as_array().ok_or((at(key), format!("polygon.{key} must be an array of numbers (arcsec)")))?;
        arr.iter()
            .map(|x| match number(x) {
                Some(f) if f.is_finite() && f.abs() <= 3600.0 => Ok(f),
                _ => Err((at(key), format!("polygon.{key}: {} is not a face error within +/-3600 arcsec", shown(x)))),
            })
            .collect::<Result<Vec<f64>, _>>()
            .map(Some)
    };
    let truth = list("face_errors_arcsec")?
        .ok_or((at("face_errors_arcsec"), "polygon: missing key 'face_errors_arcsec' (one per face, arcsec)".into()))?;
    if !(2..=3600).contains(&truth.len()) {
        return Err((
            at("face_errors_arcsec"),
            format!("polygon.face_errors_arcsec: {} faces; a polygon has 2 to 3600", truth.len()),
        ));
    }
    let certificate = list("certificate_arcsec")?;
    if let Some(c) = &certificate
        && c.len() != truth.len()
    {
        return Err((
            at("certificate_arcsec"),
            format!("polygon.certificate_arcsec: {} values for {} faces (one per face)", c.len(), truth.len()),
        ));
    }
    Ok(PolygonTruth { face_errors_arcsec: truth, certificate_arcsec: certificate })
}

fn parse_design(t: &toml::Table, loc: &Locator) -> Result<Design, Fail> {
    let header = loc.design_header();
    let at = |key: &str| loc.key_in_table(header, key);
    let mut d = Design::default();
    for (key, value) in t {
        match key.as_str() {
            "gear_ratios" => {
                let arr = value.as_array().ok_or((at(key), "design.gear_ratios must be an array of numbers".into()))?;
                for v in arr {
                    match number(v) {
                        Some(r) if r > 0.0 && r <= 100_000.0 => d.gear_ratios.push(r),
                        _ => {
                            return Err((
                                at(key),
                                format!(
                                    "design.gear_ratios: {} is not a gear ratio (a number from above 0 to 100000)",
                                    shown(v)
                                ),
                            ));
                        }
                    }
                }
            }
            "tooth_counts" => {
                let arr =
                    value.as_array().ok_or((at(key), "design.tooth_counts must be an array of integers".into()))?;
                for v in arr {
                    match v.as_integer() {
                        Some(n) if (1..=100_000).contains(&n) => d.tooth_counts.push(n as u32),
                        _ => {
                            return Err((
                                at(key),
                                format!(
                                    "design.tooth_counts: {} is not a tooth count (an integer from 1 to 100000)",
                                    shown(v)
                                ),
                            ));
                        }
                    }
                }
            }
            "encoder_heads" => match value.as_integer() {
                Some(n) if (1..=64).contains(&n) => d.encoder_heads = Some(n as u32),
                _ => {
                    return Err((
                        at(key),
                        format!("design.encoder_heads must be an integer from 1 to 64, got {value}"),
                    ));
                }
            },
            other => {
                return Err((
                    at(other),
                    format!("design: unknown key '{other}' (expected gear_ratios, tooth_counts, encoder_heads)"),
                ));
            }
        }
    }
    Ok(d)
}

/// The range a model value must lie in to describe a positioner this
/// calibrates, and why: the paper's errors are hundredths of a degree, so an
/// amplitude of degrees is a unit or typing error (arcseconds, radians), not a
/// positioner. Signs are checked where they are parsed.
fn physical_range(key: &str) -> Option<(f64, f64, &'static str)> {
    const ANGLE: &str = "an error of a degree or more is not one a table corrects (the paper's are hundredths \
                         of a degree): is the value in arcseconds or radians?";
    match key {
        "amplitude_deg" | "sigma_deg" => Some((-1.0, 1.0, ANGLE)),
        "rate_deg_per_run" => Some((-1.0, 1.0, ANGLE)),
        "cycles_per_rev" => Some((0.0, 100_000.0, "no positioner error repeats more than 100000 times a turn")),
        "phase_deg" => Some((-1.0e6, 1.0e6, "a phase is an angle (it wraps at 360)")),
        _ => None,
    }
}

fn parse_effect(t: &toml::Table, index: usize, loc: &Locator) -> Result<Effect, Fail> {
    let header = loc.effect_header(index);
    let n = index + 1;
    let at = |key: &str| loc.key_in_table(header, key);
    let kind = match t.get("kind") {
        None => return Err((header, format!("effect[{n}]: missing key 'kind' (one of {KINDS})"))),
        Some(toml::Value::String(s)) => s.as_str(),
        Some(v) => return Err((at("kind"), format!("effect[{n}].kind must be a string, got {}", shown(v)))),
    };
    let allowed: &[&str] = match kind {
        "eccentricity" | "ellipticity" | "gear_pass" | "tooth_mesh" | "harmonic" => {
            &["kind", "cycles_per_rev", "amplitude_deg", "phase_deg"]
        }
        "backlash" => &["kind", "amplitude_deg"],
        "drift" => &["kind", "rate_deg_per_run", "shape"],
        "noise" => &["kind", "sigma_deg"],
        other => return Err((at("kind"), format!("effect[{n}]: unknown kind '{other}' (one of {KINDS})"))),
    };
    for key in t.keys() {
        if !allowed.contains(&key.as_str()) {
            return Err((
                at(key),
                format!("effect[{n}] ({kind}): unknown key '{key}' (expected {})", allowed[1..].join(", ")),
            ));
        }
    }
    let get = |key: &str| -> Result<f64, Fail> {
        let v = t.get(key).ok_or((header, format!("effect[{n}] ({kind}): missing key '{key}'")))?;
        match number(v) {
            Some(x) if x.is_finite() => match physical_range(key) {
                Some((lo, hi, why)) if !(lo..=hi).contains(&x) => Err((
                    at(key),
                    format!("effect[{n}] ({kind}).{key} = {} is outside {}..={}: {why}", Num(x), Num(lo), Num(hi)),
                )),
                _ => Ok(x),
            },
            _ => Err((at(key), format!("effect[{n}] ({kind}).{key} must be a finite number, got {}", shown(v)))),
        }
    };
    let non_negative = |key: &str, x: f64| -> Result<f64, Fail> {
        if x < 0.0 {
            Err((at(key), format!("effect[{n}] ({kind}).{key} must not be negative, got {}", Num(x))))
        } else {
            Ok(x)
        }
    };
    let periodic = |kind: PeriodicKind| -> Result<Effect, Fail> {
        let cycles = match (kind.fixed_cycles(), t.contains_key("cycles_per_rev")) {
            (Some(fixed), false) => fixed,
            _ => get("cycles_per_rev")?,
        };
        if let Some(fixed) = kind.fixed_cycles()
            && cycles != fixed
        {
            return Err((
                at("cycles_per_rev"),
                format!("effect[{n}] ({}).cycles_per_rev must be {fixed}, got {}", kind.as_str(), Num(cycles)),
            ));
        }
        if cycles <= 0.0 {
            return Err((
                at("cycles_per_rev"),
                format!("effect[{n}] ({}).cycles_per_rev must be positive, got {}", kind.as_str(), Num(cycles)),
            ));
        }
        let amplitude_deg = non_negative("amplitude_deg", get("amplitude_deg")?)?;
        let phase_deg = if t.contains_key("phase_deg") { get("phase_deg")? } else { 0.0 };
        Ok(Effect::Periodic { kind, cycles_per_rev: cycles, amplitude_deg, phase_deg })
    };
    match kind {
        "eccentricity" => periodic(PeriodicKind::Eccentricity),
        "ellipticity" => periodic(PeriodicKind::Ellipticity),
        "gear_pass" => periodic(PeriodicKind::GearPass),
        "tooth_mesh" => periodic(PeriodicKind::ToothMesh),
        "harmonic" => periodic(PeriodicKind::Harmonic),
        "backlash" => Ok(Effect::Backlash { amplitude_deg: non_negative("amplitude_deg", get("amplitude_deg")?)? }),
        "drift" => {
            let shape = match t.get("shape") {
                None => DriftShape::Ramp,
                Some(toml::Value::String(v)) if v == "ramp" => DriftShape::Ramp,
                Some(toml::Value::String(v)) if v == "step" => DriftShape::Step,
                Some(v) => {
                    return Err((
                        at("shape"),
                        format!("effect[{n}] (drift).shape must be \"ramp\" or \"step\", got {}", shown(v)),
                    ));
                }
            };
            Ok(Effect::Drift { rate_deg_per_run: get("rate_deg_per_run")?, shape })
        }
        "noise" => Ok(Effect::Noise { sigma_deg: non_negative("sigma_deg", get("sigma_deg")?)? }),
        _ => unreachable!("kind checked above"),
    }
}

mod motions;

#[cfg(test)]
mod tests {
    use super::*;

    const EXAMPLE: &str = r#"
[design]
gear_ratios = [12]
tooth_counts = [216]
encoder_heads = 2

[[effect]]
kind = "gear_pass"
cycles_per_rev = 12
amplitude_deg = 0.006
phase_deg = 30.0

[[effect]]
kind = "backlash"
amplitude_deg = 0.004

[[effect]]
kind = "drift"
rate_deg_per_run = 0.0002

[[effect]]
kind = "noise"
sigma_deg = 0.0005
"#;

    #[test]
    fn parses_the_contract_example_and_evaluates() {
        let m = Model::parse(EXAMPLE, "m.toml").unwrap();
        assert_eq!(m.design.gear_ratios, vec![12.0]);
        assert_eq!(m.design.tooth_counts, vec![216]);
        assert_eq!(m.design.encoder_heads, Some(2));
        assert_eq!(m.effects.len(), 4);
        // 12 * 2.5 deg + 30 deg = 60 deg.
        let expect = 0.006 * 60f64.to_radians().sin();
        assert!((m.periodic_error_deg(2.5) - expect).abs() < 1e-15);
        assert!((m.repeatable_error_deg(2.5, Direction::Forward) - (expect + 0.002)).abs() < 1e-15);
        assert!((m.repeatable_error_deg(2.5, Direction::Reverse) - (expect - 0.002)).abs() < 1e-15);
        assert!((m.systematic_error_deg(2.5, Direction::Reverse, 2.0) - (expect - 0.002 + 0.0004)).abs() < 1e-15);
        assert_eq!(m.noise_sigma_deg(), 0.0005);
    }

    #[test]
    fn round_trips_through_toml() {
        let m = Model::parse(EXAMPLE, "m.toml").unwrap();
        let again = Model::parse(&m.to_toml(), "again").unwrap();
        assert_eq!(m, again);
    }

    #[test]
    fn design_only_and_empty_files_are_valid() {
        assert_eq!(Model::parse("", "e").unwrap(), Model::default());
        let m = Model::parse("[design]\ngear_ratios = [20]\n", "d").unwrap();
        assert!(m.effects.is_empty());
    }

    fn error_of(text: &str) -> ModelError {
        Model::parse(text, "bad.toml").unwrap_err()
    }

    #[test]
    fn unknown_kind_names_line_and_kind() {
        let e = error_of("[design]\n\n[[effect]]\nkind = \"wobble\"\namplitude_deg = 1\n");
        assert_eq!(e.line, Some(4));
        assert!(e.to_string().starts_with("bad.toml:4: "), "{e}");
        assert!(e.message.contains("unknown kind 'wobble'"), "{e}");
    }

    #[test]
    fn missing_key_names_the_effect() {
        let e = error_of("[[effect]]\nkind = \"gear_pass\"\ncycles_per_rev = 12\nphase_deg = 0\n");
        assert_eq!(e.line, Some(1));
        assert!(e.message.contains("effect[1] (gear_pass): missing key 'amplitude_deg'"), "{e}");
    }

    #[test]
    fn negative_sigma_names_the_key_line() {
        let e = error_of(
            "[[effect]]\nkind = \"backlash\"\namplitude_deg = 0.001\n\n[[effect]]\nkind = \"noise\"\nsigma_deg = -0.1\n",
        );
        assert_eq!(e.line, Some(7));
        assert!(e.message.contains("effect[2] (noise).sigma_deg must not be negative"), "{e}");
    }

    #[test]
    fn other_defects_are_named() {
        assert!(error_of("[[effect]]\nkind = \"noise\"\nsigma = 1\n").message.contains("unknown key 'sigma'"));
        assert!(
            error_of("[[effect]]\nkind = \"eccentricity\"\ncycles_per_rev = 3\namplitude_deg = 1\n")
                .message
                .contains("must be 1")
        );
        assert!(error_of("[design]\ngear_ratio = [1]\n").message.contains("unknown key 'gear_ratio'"));
        assert!(error_of("[[effect]]\nkind = \"drift\"\nrate_deg_per_run = \"x\"\n").message.contains("finite number"));
        let syntax = error_of("[design\n");
        assert_eq!(syntax.line, Some(1));
        assert!(error_of("[[effect]]\namplitude_deg = 1\n").message.contains("missing key 'kind'"));
    }

    #[test]
    fn the_benchs_sections_parse_write_back_and_name_their_defects() {
        let text = "[design]\ngear_ratios = [20]\n\n[tracker_errors]\nnone = true\n\n[smrs]\nphases_deg = [10, 47, 141]\n\n\
                    [polygon]\nface_errors_arcsec = [0.5, -0.5, 0.25, 0.0]\ncertificate_arcsec = [0.4, -0.5, 0.25, 0.1]\n\n\
                    [autocollimator_errors]\nscale_ppm = 500\n";
        let m = Model::parse(text, "m.toml").unwrap();
        assert_eq!(m.tracker_errors, TrackerErrorSpec::None);
        let smrs = m.smrs.clone().unwrap();
        assert_eq!(smrs.iter().map(|s| s.phase_deg).collect::<Vec<_>>(), [0.0, 37.0, 131.0], "from the first's");
        let p = m.polygon.clone().unwrap();
        assert_eq!((p.face_errors_arcsec.len(), p.certificate()[0]), (4, 0.4));
        assert_eq!(m.autocollimator_scale_ppm, 500.0);
        assert_eq!(Model::parse(&m.to_toml(), "again").unwrap(), m);
        for (bad, line, says) in [
            ("[smrs]\nphases_deg = [0]\n", 2, "1 SMRs; a survey measures 2 to 12"),
            ("[smrs]\nphases_deg = [0, 360]\n", 2, "two SMRs at the same place"),
            ("[smrs]\nphases_deg = [0, 90]\nheights_mm = [1]\n", 3, "1 heights for 2 SMRs"),
            ("[polygon]\nface_errors_arcsec = [1, 2]\ncertificate_arcsec = [1]\n", 3, "1 values for 2 faces"),
            ("[polygon]\nface_errors_arcsec = [1, 4000]\n", 2, "4000 is not a face error"),
            ("[autocollimator_errors]\nscale = 3\n", 2, "unknown key 'scale'"),
            ("[turntable]\nx = 1\n", 1, "unknown top-level key 'turntable'"),
        ] {
            let e = Model::parse(bad, "bad.toml").unwrap_err();
            assert_eq!(e.line, Some(line), "{bad}: {e}");
            assert!(e.message.contains(says), "{bad}: {e}");
        }
    }

    #[test]
    fn drift_shapes_parse_write_back_and_evaluate() {
        let m =
            Model::parse("[[effect]]\nkind = \"drift\"\nrate_deg_per_run = 0.002\nshape = \"step\"\n", "d").unwrap();
        assert_eq!(m.effects, vec![Effect::Drift { rate_deg_per_run: 0.002, shape: DriftShape::Step }]);
        assert!(m.to_toml().contains("shape = \"step\""));
        assert_eq!(Model::parse(&m.to_toml(), "again").unwrap(), m);
        // A step holds within a run and jumps between runs; a ramp grows within one.
        assert_eq!(m.drift_deg(0.9), 0.0);
        assert_eq!(m.drift_deg(2.5), 0.004);
        let ramp = Model::parse("[[effect]]\nkind = \"drift\"\nrate_deg_per_run = 0.002\n", "d").unwrap();
        assert!((ramp.drift_deg(2.5) - 0.005).abs() < 1e-15);
        assert!(!ramp.to_toml().contains("shape"), "the default shape is not written");
        let e =
            Model::parse("[[effect]]\nkind = \"drift\"\nrate_deg_per_run = 0.1\nshape = \"saw\"\n", "d").unwrap_err();
        assert!(e.to_string().contains("must be \"ramp\" or \"step\""), "{e}");
    }

    fn any_effect() -> impl proptest::strategy::Strategy<Value = Effect> {
        use proptest::prelude::*;
        prop_oneof![
            (0.0f64..500.0, -0.05f64..0.05, -360.0f64..360.0).prop_map(|(cycles_per_rev, amplitude_deg, phase_deg)| {
                Effect::Periodic { kind: PeriodicKind::Harmonic, cycles_per_rev, amplitude_deg, phase_deg }
            }),
            (0.0f64..0.02).prop_map(|amplitude_deg| Effect::Backlash { amplitude_deg }),
            (-0.01f64..0.01, proptest::bool::ANY).prop_map(|(rate_deg_per_run, step)| Effect::Drift {
                rate_deg_per_run,
                shape: if step { DriftShape::Step } else { DriftShape::Ramp },
            }),
            (0.0f64..0.001).prop_map(|sigma_deg| Effect::Noise { sigma_deg }),
        ]
    }

    proptest::proptest! {
        /// The error sorted out once is the model's own, to the bit (a zero's
        /// sign aside), for any mix of effects in any order.
        #[test]
        fn the_systematic_error_made_once_is_the_models(
            effects in proptest::collection::vec(any_effect(), 0..8),
            theta_deg in -720.0f64..720.0,
            reverse in proptest::bool::ANY,
            runs_elapsed in 0.0f64..6.0,
        ) {
            let model = Model { design: Design::default(), effects, ..Model::default() };
            let direction = if reverse { Direction::Reverse } else { Direction::Forward };
            let t = DriftTime::elapsed(runs_elapsed);
            let made = model.systematic().at(theta_deg, direction, t);
            let walked = model.systematic_error_at(theta_deg, direction, t);
            proptest::prop_assert!(made == walked, "{made:e} against {walked:e}");
        }
    }
}
