//! The recipe's `[export]` choices turned into controller files: which
//! controllers, over which range and spacing, which directions, zeroed at the
//! reference point or not; each file's text and the accuracy it is predicted to
//! give (the survey's samples corrected the way that controller applies its
//! table, on every turn the table covers).
//!
//! Defaults: LinuxCNC the finest spacing that keeps `linuxcnc_points` (256)
//! points over the range (a whole number of points per turn when one fits);
//! 840D, Fanuc and the generic table 1 deg. Range: a full circle 0..360 (so
//! 840D is modulo and Fanuc rotary type), a partial survey its measured range.
//! A choice that cannot be honoured is a [`ChoiceError`] naming the `export.`
//! key.

use crate::corrector::ValueFormat;
use crate::fanuc::{FanucOptions, FanucTable, MIN_UNIT_DEG};
use crate::generic::{GenericTable, Sign, Values};
use crate::layout::{DefaultSpacing, Directions, Grid, MAX_TABLE_DEG, RangeChoice, Reader, Span, resolve};
use crate::linuxcnc::LinuxCncTable;
use crate::sinumerik::{Sinumerik840d, SinumerikOptions};
use crate::{AppliedTable, predicted_peaks_deg};
use serde::{Deserialize, Serialize};
use survey_processing::num::Num;
use survey_processing::table::CorrectionTable;
use survey_processing::{Direction, Sample};

/// The `[export]` section (the CSV is always written). See
/// [`build`] for what each key does to the controller files.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ExportChoices {
    /// Write LinuxCNC `COMP_FILE`s (types 0 and 1).
    pub linuxcnc: bool,
    /// The most points of the LinuxCNC files (2 to 256), the limit of their default spacing.
    pub linuxcnc_points: usize,
    /// Write the Siemens 840D EEC file.
    pub sinumerik_840d: bool,
    /// Write the Fanuc pitch-error file.
    pub fanuc: bool,
    /// Write the generic table.
    pub generic: bool,
    /// Write the binary table of [`crate::corrector`].
    pub binary: bool,
    /// Values of the binary table: `f64` or `f32`.
    pub binary_format: ValueFormat,
    /// First position of the controller tables, degrees (default: 0, or the first measured target).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start_deg: Option<f64>,
    /// Last position, degrees (default: 360, or the last measured target).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub end_deg: Option<f64>,
    /// Spacing, degrees (or `points`; default: each format's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interval_deg: Option<f64>,
    /// Number of points (or `interval_deg`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub points: Option<usize>,
    /// `auto`, `combined` or `separate` forward and reverse values.
    pub directions: Directions,
    /// The reference point, degrees (default: 0, or the table's point nearest 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_deg: Option<f64>,
    /// Zero the LinuxCNC and generic values at the reference point (the 840D
    /// values are zero there unless `sinumerik_absolute`, Fanuc's always are).
    pub zero_at_reference: bool,
    /// Write the 840D values absolute instead of zero at the reference point
    /// (Siemens' K3 manual asks for zero there, the default).
    pub sinumerik_absolute: bool,
    /// The generic table's sign: `error` (readout - actual) or `correction`.
    pub sign: Sign,
    /// The generic table's values: `absolute` or `incremental`.
    pub values: Values,
    /// The 840D machine axis name.
    pub sinumerik_axis: String,
    /// The 840D measuring system, 0 or 1.
    pub sinumerik_measuring_system: u8,
    /// Fanuc detection unit, degrees.
    pub fanuc_unit_deg: f64,
    /// Fanuc magnification (parameter 3623).
    pub fanuc_magnification: u32,
    /// Fanuc reference point's compensation number (parameter 3620; default: see the writer).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fanuc_reference_number: Option<u32>,
}

impl Default for ExportChoices {
    fn default() -> Self {
        Self {
            linuxcnc: true,
            linuxcnc_points: crate::linuxcnc::MAX_POINTS,
            sinumerik_840d: true,
            fanuc: true,
            generic: false,
            binary: true,
            binary_format: ValueFormat::F64,
            start_deg: None,
            end_deg: None,
            interval_deg: None,
            points: None,
            directions: Directions::Auto,
            reference_deg: None,
            zero_at_reference: false,
            sinumerik_absolute: false,
            sign: Sign::Error,
            values: Values::Absolute,
            sinumerik_axis: crate::sinumerik::DEFAULT_AXIS.to_string(),
            sinumerik_measuring_system: 0,
            fanuc_unit_deg: 0.001,
            fanuc_magnification: 1,
            fanuc_reference_number: None,
        }
    }
}

/// A choice that is wrong in itself or cannot be honoured on a survey, naming
/// its key (`table.rows`, `alias[2].true_cycles`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{key}: {message}")]
pub struct ChoiceError {
    /// The key, dotted, with 1-based `[n]` for `[[alias]]` entries.
    pub key: String,
    /// What is wrong.
    pub message: String,
}

impl ChoiceError {
    pub fn new(key: impl Into<String>, message: impl Into<String>) -> Self {
        Self { key: key.into(), message: message.into() }
    }
}

impl ExportChoices {
    /// Check every value that does not depend on a survey.
    pub fn validate(&self) -> Result<(), ChoiceError> {
        let bad = |key: &str, message: String| Err(ChoiceError::new(key, message));
        let x = self;
        for (key, v) in [
            ("export.start_deg", x.start_deg),
            ("export.end_deg", x.end_deg),
            ("export.reference_deg", x.reference_deg),
        ] {
            if let Some(v) = v
                && !(v.is_finite() && v.abs() <= MAX_TABLE_DEG)
            {
                return bad(key, format!("must be an angle within +/-{MAX_TABLE_DEG} deg, got {}", Num(v)));
            }
        }
        if let (Some(a), Some(b)) = (x.start_deg, x.end_deg)
            && b <= a
        {
            return bad("export.end_deg", format!("must be above export.start_deg ({}), got {}", Num(a), Num(b)));
        }
        if let Some(d) = x.interval_deg
            && !(d.is_finite() && d > 0.0)
        {
            return bad("export.interval_deg", format!("must be a positive number of degrees, got {}", Num(d)));
        }
        if let Some(p) = x.points {
            if x.interval_deg.is_some() {
                return bad("export.points", "give export.interval_deg or export.points, not both".into());
            }
            if p < 2 {
                return bad("export.points", format!("must be at least 2, got {p}"));
            }
        }
        if let Err(e) = crate::sinumerik::check_axis(&x.sinumerik_axis) {
            return bad("export.sinumerik_axis", e.to_string());
        }
        if x.sinumerik_measuring_system > 1 {
            return bad(
                "export.sinumerik_measuring_system",
                format!("must be 0 or 1, got {}", x.sinumerik_measuring_system),
            );
        }
        if !(MIN_UNIT_DEG..=1.0).contains(&x.fanuc_unit_deg) {
            return bad(
                "export.fanuc_unit_deg",
                format!("must be a detection unit from {} to 1 deg, got {}", Num(MIN_UNIT_DEG), Num(x.fanuc_unit_deg)),
            );
        }
        if !(1..=100).contains(&x.fanuc_magnification) {
            return bad("export.fanuc_magnification", format!("must be from 1 to 100, got {}", x.fanuc_magnification));
        }
        if !(2..=crate::linuxcnc::MAX_POINTS).contains(&x.linuxcnc_points) {
            return bad(
                "export.linuxcnc_points",
                format!(
                    "must be from 2 to {} (LinuxCNC holds 256), got {}",
                    crate::linuxcnc::MAX_POINTS,
                    x.linuxcnc_points
                ),
            );
        }
        Ok(())
    }
}

/// A controller format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Controller {
    /// LinuxCNC `COMP_FILE` types 0 and 1 (`<stem>.comp0`, `<stem>.comp1`).
    #[serde(rename = "linuxcnc")]
    LinuxCnc,
    /// Siemens SINUMERIK 840D EEC (`<stem>.840d.ini`).
    #[serde(rename = "840d")]
    Sinumerik840d,
    /// Fanuc stored pitch-error compensation (`<stem>.fanuc.txt`).
    #[serde(rename = "fanuc")]
    Fanuc,
    /// The generic table (`<stem>.generic.csv`).
    #[serde(rename = "generic")]
    Generic,
}

impl Controller {
    /// Every format, in the order files are listed.
    pub const ALL: [Controller; 4] =
        [Controller::LinuxCnc, Controller::Sinumerik840d, Controller::Fanuc, Controller::Generic];

    /// The name used on the command line and in JSON.
    pub fn as_str(self) -> &'static str {
        match self {
            Controller::LinuxCnc => "linuxcnc",
            Controller::Sinumerik840d => "840d",
            Controller::Fanuc => "fanuc",
            Controller::Generic => "generic",
        }
    }
}

impl std::str::FromStr for Controller {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Controller::ALL.into_iter().find(|c| c.as_str().eq_ignore_ascii_case(s.trim())).ok_or_else(|| {
            format!("unknown controller '{s}' (expected {})", Controller::ALL.map(Controller::as_str).join(", "))
        })
    }
}

/// One file of a controller.
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerFile {
    /// What it is (`linuxcnc_type0`, `linuxcnc_type1`, `sinumerik_840d`, `fanuc`, `generic`).
    pub kind: &'static str,
    /// Appended to the table's stem (`.comp0`, `.840d.ini`).
    pub suffix: &'static str,
    /// The contents.
    pub text: String,
}

/// A controller's export: its files and what they hold.
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerExport {
    /// The format.
    pub controller: Controller,
    /// Its files.
    pub files: Vec<ControllerFile>,
    /// The points.
    pub grid: Grid,
    /// Whether forward and reverse values differ in the file.
    pub directional: bool,
    /// 840D modulo, Fanuc rotary type.
    pub modulo: bool,
    /// The reference point, degrees.
    pub reference_deg: f64,
    /// Whether the values are zero at the reference point.
    pub zero_at_reference: bool,
    /// The corrected peak error predicted on the survey, degrees (every turn covered; the worst).
    pub corrected_peak_deg: Option<f64>,
    /// Format parameters to set beside the file (Fanuc's 3620-3627): number, value, meaning.
    pub parameters: Vec<(String, String, String)>,
    /// Remarks (what the format cannot hold, limits exceeded).
    pub notes: Vec<String>,
}

fn choice(key: &str, message: impl Into<String>) -> ChoiceError {
    ChoiceError::new(format!("export.{key}"), message)
}

/// The default reference point on a grid: 0 when it is a point of it, else
/// the point nearest 0.
fn default_reference(grid: &Grid) -> f64 {
    let k = ((0.0 - grid.start_deg) / grid.interval_deg).round().clamp(0.0, (grid.points - 1) as f64);
    grid.position(k as usize)
}

/// The controllers `export` asks for, in [`Controller::ALL`] order.
pub fn chosen(export: &ExportChoices) -> Vec<Controller> {
    Controller::ALL
        .into_iter()
        .filter(|c| match c {
            Controller::LinuxCnc => export.linuxcnc,
            Controller::Sinumerik840d => export.sinumerik_840d,
            Controller::Fanuc => export.fanuc,
            Controller::Generic => export.generic,
        })
        .collect()
}

/// Every controller file `export` asks for, from `table` (full circle when
/// `full_circle`, else the measured range `measured`), with its predicted
/// accuracy on `samples`.
pub fn build(
    table: &CorrectionTable,
    full_circle: bool,
    measured: (f64, f64),
    samples: &[Sample],
    export: &ExportChoices,
) -> Result<Vec<ControllerExport>, ChoiceError> {
    let span = if full_circle { Span::FullCircle } else { Span::Measured { start: measured.0, end: measured.1 } };
    let range = RangeChoice {
        start_deg: export.start_deg,
        end_deg: export.end_deg,
        interval_deg: export.interval_deg,
        points: export.points,
    };
    let separate = match export.directions {
        Directions::Auto => table.is_directional(),
        Directions::Combined => false,
        Directions::Separate => true,
    };
    let source = Source { table, full_circle, export, separate, range, span };
    let mut out = Vec::new();
    // Each export's table whose accuracy is predicted (its place in `out`):
    // all of them from one pass over the samples, after the loop.
    let mut predicted: Vec<(usize, AppliedTable)> = Vec::new();
    for controller in chosen(export) {
        let (e, applied) = source.controller_export(controller)?;
        if let Some(t) = applied {
            predicted.push((out.len(), t));
        }
        out.push(e);
    }
    let (places, tables): (Vec<usize>, Vec<AppliedTable>) = predicted.into_iter().unzip();
    for (place, peak) in places.into_iter().zip(predicted_peaks_deg(samples, &tables, full_circle)) {
        out[place].corrected_peak_deg = peak;
    }
    Ok(out)
}

/// What every controller's file is made from: the correction table, what it
/// covers, and the `[export]` choices.
struct Source<'a> {
    table: &'a CorrectionTable,
    /// A full circle (else the measured range `span` holds).
    full_circle: bool,
    export: &'a ExportChoices,
    /// Forward and reverse values apart, in the formats that hold two.
    separate: bool,
    /// The range and spacing `export` asks for.
    range: RangeChoice,
    /// What the survey covers.
    span: Span,
}

impl Source<'_> {
    /// `controller`'s export (its grid, its reference point, zeroed there or
    /// not, its files), its predicted accuracy left to the caller, and the
    /// table whose accuracy is to be predicted (none for the generic table).
    fn controller_export(
        &self,
        controller: Controller,
    ) -> Result<(ControllerExport, Option<AppliedTable>), ChoiceError> {
        let export = self.export;
        let default = match controller {
            Controller::LinuxCnc => DefaultSpacing::FinestWithin(export.linuxcnc_points),
            _ => DefaultSpacing::Interval(1.0),
        };
        let grid = resolve(&self.range, self.span, default).map_err(|e| choice(e.key, e.message))?;
        // 840D EEC is one table for both directions (see its module).
        let one_table = controller == Controller::Sinumerik840d;
        let reader = Reader::new(self.table, self.full_circle, grid.interval_deg, self.separate && !one_table);
        let reference_deg = self.reference(&grid)?;
        // Fanuc's values are increments from the reference (zero there by
        // construction); the 840D's are zero there unless kept absolute (K3).
        let zeroed = match controller {
            Controller::Sinumerik840d => !export.sinumerik_absolute,
            _ => export.zero_at_reference,
        };
        let offset = if zeroed { reader.error_at(reference_deg, Direction::Forward) } else { 0.0 };
        let mut e = ControllerExport {
            controller,
            files: Vec::new(),
            grid,
            directional: reader.is_separate(),
            modulo: false,
            reference_deg,
            zero_at_reference: zeroed,
            corrected_peak_deg: None,
            parameters: Vec::new(),
            notes: Vec::new(),
        };
        let applied = match controller {
            Controller::LinuxCnc => Some(self.linuxcnc(&mut e, &reader, offset)?),
            Controller::Sinumerik840d => Some(self.sinumerik_840d(&mut e, &reader)?),
            Controller::Fanuc => Some(self.fanuc(&mut e, &reader)?),
            Controller::Generic => {
                let t = GenericTable::new(&reader, &grid, offset, export.sign, export.values);
                e.files = vec![ControllerFile { kind: "generic", suffix: ".generic.csv", text: t.text() }];
                None
            }
        };
        Ok((e, applied))
    }

    /// The reference point on `grid`: `reference_deg`, else the default. It
    /// must be an angle a table may hold and, over a partial range, a point of
    /// the table's range.
    fn reference(&self, grid: &Grid) -> Result<f64, ChoiceError> {
        let reference_deg = self.export.reference_deg.unwrap_or_else(|| default_reference(grid));
        if !(reference_deg.is_finite() && reference_deg.abs() <= MAX_TABLE_DEG) {
            return Err(choice(
                "reference_deg",
                format!("must be an angle within +/-{MAX_TABLE_DEG} deg, got {}", Num(reference_deg)),
            ));
        }
        if !self.full_circle && !(grid.start_deg - 1e-9..=grid.end_deg() + 1e-9).contains(&reference_deg) {
            return Err(choice(
                "reference_deg",
                format!(
                    "{} deg is outside the table's range {}..{} deg",
                    Num(reference_deg),
                    Num(grid.start_deg),
                    Num(grid.end_deg())
                ),
            ));
        }
        Ok(reference_deg)
    }

    /// LinuxCNC's two files into `e`, less `offset` (the error at the
    /// reference point, or 0); a note when a full circle's table does not go
    /// past one turn, since LinuxCNC never wraps.
    fn linuxcnc(&self, e: &mut ControllerExport, reader: &Reader, offset: f64) -> Result<AppliedTable, ChoiceError> {
        let grid = e.grid;
        let t = LinuxCncTable::new(reader, &grid, offset).map_err(|err| {
            choice(
                if self.export.interval_deg.is_some() { "interval_deg" } else { "points" },
                format!(
                    "{err} over {}..{} deg: give a coarser spacing (at least {:.6} deg), or leave LinuxCNC out of the controllers",
                    grid.start_deg,
                    grid.end_deg(),
                    grid.span_deg() / (crate::linuxcnc::MAX_POINTS - 1) as f64
                ),
            )
        })?;
        if self.full_circle && grid.span_deg() <= 360.0 + 1e-9 {
            e.notes.push(format!(
                "the LinuxCNC table covers {}..{} deg only: LinuxCNC holds the end values outside its table and never wraps a rotary joint, so give the joint's whole range (--table-start, --table-end)",
                grid.start_deg,
                grid.end_deg()
            ));
        }
        e.files = vec![
            ControllerFile { kind: "linuxcnc_type0", suffix: ".comp0", text: t.text(0) },
            ControllerFile { kind: "linuxcnc_type1", suffix: ".comp1", text: t.text(1) },
        ];
        Ok(AppliedTable::of(&t))
    }

    /// The 840D's file into `e` (zeroed at the reference point when
    /// `e.zero_at_reference`), whether it is modulo, and notes: directions
    /// merged, a full circle's table that is not modulo, the points MD38000
    /// must reserve.
    fn sinumerik_840d(&self, e: &mut ControllerExport, reader: &Reader) -> Result<AppliedTable, ChoiceError> {
        let grid = e.grid;
        let options = SinumerikOptions {
            axis: self.export.sinumerik_axis.clone(),
            measuring_system: self.export.sinumerik_measuring_system,
        };
        let t = Sinumerik840d::new(reader, &grid, e.zero_at_reference.then_some(e.reference_deg), options).map_err(
            |err| match err {
                crate::sinumerik::SinumerikError::BadAxis(_) => choice("sinumerik_axis", err.to_string()),
                crate::sinumerik::SinumerikError::BadMeasuringSystem(_) => {
                    choice("sinumerik_measuring_system", err.to_string())
                }
            },
        )?;
        if self.separate && self.table.is_directional() {
            e.notes.push(
                "840D measuring-system error compensation is one table for both directions: the mean of forward and reverse was written (set the reversal with the backlash compensation)".into(),
            );
        }
        if self.full_circle && !t.modulo {
            e.notes.push(format!(
                "the 840D table is not modulo (its range {}..{} deg is not 0..360): the end values hold outside it",
                grid.start_deg,
                grid.end_deg()
            ));
        }
        e.notes.push(format!(
            "MD38000 $MA_MM_ENC_COMP_MAX_POINTS must reserve at least {} points; load the file while MD32700 is 0",
            grid.points
        ));
        e.modulo = t.modulo;
        e.files = vec![ControllerFile { kind: "sinumerik_840d", suffix: ".840d.ini", text: t.text() }];
        Ok(AppliedTable::of(&t))
    }

    /// Fanuc's file into `e`, with the grid it holds, its rotary type, its
    /// parameters and its warnings; its values are increments from the
    /// reference point, so zero there.
    fn fanuc(&self, e: &mut ControllerExport, reader: &Reader) -> Result<AppliedTable, ChoiceError> {
        let options = FanucOptions {
            unit_deg: self.export.fanuc_unit_deg,
            magnification: self.export.fanuc_magnification,
            reference_number: self.export.fanuc_reference_number,
            reference_deg: e.reference_deg,
        };
        let t = FanucTable::new(reader, &e.grid, options).map_err(|err| choice(err.key, err.message))?;
        e.notes.extend(t.warnings.iter().cloned());
        e.grid = t.grid;
        e.modulo = t.rotary;
        e.zero_at_reference = true;
        e.parameters = t.parameters().into_iter().map(|(n, v, w)| (n.to_string(), v, w)).collect();
        e.files = vec![ControllerFile { kind: "fanuc", suffix: ".fanuc.txt", text: t.text() }];
        Ok(AppliedTable::of(&t))
    }
}
