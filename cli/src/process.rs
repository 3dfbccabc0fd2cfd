//! `survey process`: the paper's DSP processing of a stored survey.
//!
//! The samples are those every command uses ([`survey_lab::load`] with `Axis::Refitted`:
//! around the refitted axis of a tracker survey, unless `--located-axis`);
//! the output says which axis (`"axis"`) and carries the survey's ISO 230-2
//! figures of the same samples (`"iso230_2"`, as `survey stats` gives them).

use super::args::{UnitsArg, whole};
use super::support::emit;
use crate::progress::{self, Progress};
use clap::builder::{PossibleValue, TypedValueParser};
use clap::{Args, ValueEnum};
use std::borrow::Cow;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use survey_bench::output::{iso_figures_json, iso_text};
use survey_controllers::export::Controller;
use survey_controllers::generic::{Sign, Values};
use survey_controllers::layout::Directions;
use survey_lab::load::{Axis, load_read_only};
use survey_lab::overrides::ExportOverrides;
use survey_lab::process::{ProcessOptions, default_table_path, process_survey};

#[derive(Debug, Args)]
pub struct ProcessArgs {
    /// Survey id or uid (default: the latest).
    #[arg(long, value_name = "ID", allow_negative_numbers = true)]
    pub survey: Option<survey_store::survey::SurveyRef>,
    /// Positioner model file (TOML) whose [design] names the lines [default: the survey's stored model].
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath)]
    pub design: Option<PathBuf>,
    /// Replay this processing recipe (TOML) instead of deriving one from the survey.
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath)]
    pub recipe: Option<PathBuf>,
    /// The correction table CSV [default: survey-<ID>/table-<ID>.csv, the
    /// survey's folder; beside a database other than survey.db,
    /// <DB>.survey-<ID>/table-<ID>.csv]; the controller files
    /// (<stem>.comp0, <stem>.comp1, <stem>.840d.ini, <stem>.fanuc.txt), the binary
    /// table (<stem>.bin) and the recipe used (<stem>.recipe.toml) go beside it.
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath)]
    pub table_out: Option<PathBuf>,
    #[command(flatten)]
    pub tables: TableArgs,
    /// Process the actual angles as stored, around the axis located before the
    /// runs, instead of around the axis fitted again from every SMR position
    /// (tracker surveys; for comparison).
    #[arg(long)]
    pub located_axis: bool,
    #[command(flatten)]
    pub units: UnitsArg,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

/// The controller tables' choices (kept in the recipe written beside the
/// table, so a recalibration replaying it writes the same files).
#[derive(Debug, Args)]
#[command(next_help_heading = "Controller tables")]
pub struct TableArgs {
    /// Controller files to write, comma-separated: linuxcnc, 840d, fanuc, generic
    /// [default: the recipe's; a new recipe: linuxcnc,840d,fanuc].
    #[arg(long, value_name = "LIST", value_delimiter = ',', value_parser = ControllerNames)]
    pub controller: Option<Vec<Controller>>,
    /// First axis position the tables cover, deg [default: 0, or the first target of a
    /// partial survey]. LinuxCNC never wraps a rotary joint: give the joint's whole range.
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub table_start: Option<f64>,
    /// Last axis position the tables cover, deg [default: 360, or the last target].
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub table_end: Option<f64>,
    /// Spacing of the table points, deg [default: LinuxCNC the finest within 256
    /// points, the others 1 deg].
    #[arg(long, value_name = "DEG", conflicts_with = "table_points", allow_negative_numbers = true)]
    pub table_interval: Option<f64>,
    /// Number of table points over the range (instead of --table-interval).
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = whole::<2, usize>)]
    pub table_points: Option<usize>,
    /// Forward and reverse values: separate (direction-aware), combined (their mean),
    /// or auto (separate when the table is direction-aware) [default: auto].
    #[arg(long, value_enum, value_name = "HOW")]
    pub table_directions: Option<DirectionsArg>,
    /// The reference point, deg [default: 0, or the table point nearest 0].
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub table_reference: Option<f64>,
    /// Zero the LinuxCNC and generic values at the reference point (840D values
    /// are zero there unless --sinumerik-absolute; Fanuc values always are).
    #[arg(long)]
    pub table_zero_at_reference: bool,
    /// Generic table: error (readout - actual) or correction (actual - readout) [default: error].
    #[arg(long, value_enum, value_name = "SIGN")]
    pub table_sign: Option<SignArg>,
    /// Generic table: absolute values or increments [default: absolute].
    #[arg(long, value_enum, value_name = "HOW")]
    pub table_values: Option<ValuesArg>,
    /// Siemens 840D machine axis name [default: C1].
    #[arg(long, value_name = "NAME")]
    pub sinumerik_axis: Option<String>,
    /// Siemens 840D: write absolute values instead of zero at the reference
    /// point (the K3 manual asks for zero there, the default).
    #[arg(long)]
    pub sinumerik_absolute: bool,
    /// Fanuc detection unit, deg [default: 0.001].
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub fanuc_unit: Option<f64>,
    /// Fanuc magnification, parameter 3623 (1-100) [default: 1].
    #[arg(long, value_name = "M", allow_negative_numbers = true, value_parser = whole::<1, u32>)]
    pub fanuc_magnification: Option<u32>,
    /// Fanuc reference point's compensation number, parameter 3620 [default: 0 for
    /// one revolution; else the smallest that numbers every point from 0].
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = whole::<0, u32>)]
    pub fanuc_reference_number: Option<u32>,
}

/// `--controller`'s values: a controller's name (any case, as the recipe's),
/// which the shells' completions and the help list.
#[derive(Debug, Clone, Copy)]
struct ControllerNames;

impl TypedValueParser for ControllerNames {
    type Value = Controller;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &OsStr,
    ) -> Result<Controller, clap::Error> {
        let parse = |s: &str| s.parse::<Controller>();
        parse.parse_ref(cmd, arg, value)
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(Controller::ALL.into_iter().map(|c| PossibleValue::new(c.as_str()))))
    }
}

/// `--table-directions`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DirectionsArg {
    /// Separate when the table is direction-aware.
    Auto,
    /// One set of values: the mean of forward and reverse.
    Combined,
    /// Forward and reverse values.
    Separate,
}

/// `--table-sign`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SignArg {
    /// readout - actual.
    Error,
    /// actual - readout.
    Correction,
}

/// `--table-values`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ValuesArg {
    /// The value at each point.
    Absolute,
    /// The change from the point before (the first absolute).
    Incremental,
}

impl From<TableArgs> for ExportOverrides {
    fn from(a: TableArgs) -> Self {
        ExportOverrides {
            controllers: a.controller,
            start_deg: a.table_start,
            end_deg: a.table_end,
            interval_deg: a.table_interval,
            points: a.table_points,
            directions: a.table_directions.map(|d| match d {
                DirectionsArg::Auto => Directions::Auto,
                DirectionsArg::Combined => Directions::Combined,
                DirectionsArg::Separate => Directions::Separate,
            }),
            reference_deg: a.table_reference,
            zero_at_reference: a.table_zero_at_reference,
            sinumerik_absolute: a.sinumerik_absolute,
            sign: a.table_sign.map(|s| match s {
                SignArg::Error => Sign::Error,
                SignArg::Correction => Sign::Correction,
            }),
            values: a.table_values.map(|v| match v {
                ValuesArg::Absolute => Values::Absolute,
                ValuesArg::Incremental => Values::Incremental,
            }),
            sinumerik_axis: a.sinumerik_axis,
            fanuc_unit_deg: a.fanuc_unit,
            fanuc_magnification: a.fanuc_magnification,
            fanuc_reference_number: a.fanuc_reference_number,
        }
    }
}

pub async fn process(db: &Path, args: ProcessArgs) -> anyhow::Result<()> {
    let progress = Progress::spinner("loading the survey", progress::visible(args.json));
    let axis = if args.located_axis { Axis::Located } else { Axis::Refitted };
    let loaded = load_read_only(db, args.survey, axis).await?;
    let survey = &loaded.survey;
    let uncertainty = loaded.uncertainty_inputs();
    let make_folder = args.table_out.is_none();
    // Corrected for the drift when the survey asked for it.
    let to_process = loaded.analysed();
    let axis = loaded.axis_used();
    let table_out = args.table_out.unwrap_or_else(|| default_table_path(db, survey.id));
    let opts = ProcessOptions {
        design: args.design,
        recipe: args.recipe,
        table_out: Some(table_out),
        make_folder,
        export: args.tables.into(),
        uncertainty,
        crash_when_staged: false,
        checks: loaded.checks_corrected(&loaded.checks),
        quiet: false,
        uncorrected_drift_deg: loaded.uncorrected_drift_deg(),
    };
    progress.stage(format!("processing survey {} ({} samples) and writing its tables", survey.id, to_process.len()));
    let outcome = process_survey(survey, &to_process, opts)?;
    // The processing's own statistics are of the same samples unless it left
    // some out (a closed circle's last target): computed once.
    let iso = match &outcome.processed.iso {
        Some(iso) if outcome.processed.prediction.samples == to_process.len() => Some(Cow::Borrowed(iso)),
        _ => survey_processing::iso230::iso230_2(&to_process).ok().map(Cow::Owned),
    };
    drop(progress);
    let units = args.units.units();
    let out = if args.json {
        let mut doc = outcome.json();
        doc["axis"] = axis.as_str().into();
        if let Some(iso) = &iso {
            doc["iso230_2"] = iso_figures_json(iso);
        }
        if let Some(r) = &loaded.refit {
            doc["axis_refit"] = serde_json::to_value(r).unwrap_or_default();
        }
        if let Some(e) = loaded.reference_error() {
            doc["reference_error"] = serde_json::to_value(&e).unwrap_or_default();
        }
        doc["error_motions"] = loaded.refit.as_ref().map(|r| r.motions_json()).unwrap_or_default();
        if let Some(p) = &loaded.polygon {
            p.put_in(&mut doc);
        }
        doc["gross_readings"] = serde_json::to_value(&loaded.gross).unwrap_or_default();
        doc["drift_in_time"] = serde_json::to_value(&loaded.time_drift).unwrap_or_default();
        format!("{doc}\n")
    } else {
        let mut text = loaded.refit.as_ref().map(|r| units.text(&r.text()) + &r.motions_text()).unwrap_or_default();
        text += &loaded.polygon.as_ref().map(|p| p.text()).unwrap_or_default();
        text += &loaded.time_drift.as_ref().map(|d| d.text()).unwrap_or_default();
        for note in loaded.gross.notes() {
            text += &format!("{note}\n");
        }
        if let Some(iso) = &iso {
            text += &iso_text(survey.id, iso, units);
        }
        text += axis.text();
        text += "\n";
        text + &outcome.text(units)
    };
    emit(&out);
    Ok(())
}
