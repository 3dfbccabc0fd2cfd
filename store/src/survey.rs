//! Typed survey records: what a survey is, as every command sees it.
//!
//! The store keeps a survey's description in a few text columns (`source`,
//! `config_json`, `model_toml`, `axis_json`, `instruments_json`). They are
//! parsed here, once, when a survey is read ([`SurveyRecord::parse`]), with
//! one failure policy: a column that does not parse makes the survey
//! [`Damaged`] (a bad-input error naming the database, the survey and the
//! column), never a default silently taken. Commands match on enums, never on
//! strings.
//!
//! The text forms are those the store has always written, so databases made
//! by earlier versions read unchanged: `source` is `simulated`,
//! `instruments`, `verification`, `resolving` or `import:<file>`; `config_json` holds the
//! [`SimulatedSetup`] or [`ConfiguredSetup`] (a verification survey holds the
//! setup of the survey it verifies), `{"imported_from": ...}` for an import,
//! or `{}` when nothing was recorded.

use crate::asset::{UNASSIGNED, simulated_asset};
use crate::config::SurveyConfig;
use serde::{Deserialize, Serialize};
use std::fmt;
use survey_acquire::{ReferenceKind, Timing};
use survey_plan::SurveyPlan;
use survey_processing::geometry::AxisFit;
use survey_processing::model::Model;
use survey_processing::table::CorrectionTable;

/// Where a survey's samples came from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase", tag = "kind")]
pub enum SurveySource {
    /// Acquired on the built-in simulated instruments.
    Simulated,
    /// Acquired on the instruments of a configuration file.
    Instruments,
    /// Acquired with a correction table applied (`survey run --verify`).
    Verification,
    /// Check points between the targets of another survey, measured to
    /// decide the lines its analysis left in doubt (`survey run` with a
    /// tracker, `survey_lab::resolving`).
    Resolving,
    /// Imported from a CSV file.
    Import {
        /// The file, as it was named on the command line.
        file: String,
    },
}

impl SurveySource {
    /// The text stored in the `source` column.
    pub fn to_column(&self) -> String {
        match self {
            SurveySource::Simulated => "simulated".into(),
            SurveySource::Instruments => "instruments".into(),
            SurveySource::Verification => "verification".into(),
            SurveySource::Resolving => "resolving".into(),
            SurveySource::Import { file } => format!("import:{file}"),
        }
    }

    /// Parse the `source` column.
    pub fn from_column(text: &str) -> Option<Self> {
        match text {
            "simulated" => Some(SurveySource::Simulated),
            "instruments" => Some(SurveySource::Instruments),
            "verification" => Some(SurveySource::Verification),
            "resolving" => Some(SurveySource::Resolving),
            other => other.strip_prefix("import:").map(|f| SurveySource::Import { file: f.to_string() }),
        }
    }

    /// Whether the survey was acquired (and so can be resumed), not imported.
    pub fn is_acquired(&self) -> bool {
        !matches!(self, SurveySource::Import { .. })
    }
}

impl fmt::Display for SurveySource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SurveySource::Simulated => f.write_str("simulated instruments"),
            SurveySource::Instruments => f.write_str("instruments"),
            SurveySource::Verification => f.write_str("verification of a correction table"),
            SurveySource::Resolving => f.write_str("check points deciding another survey's lines"),
            SurveySource::Import { file } => write!(f, "imported from {file}"),
        }
    }
}

/// Everything a simulated survey was made from, stored with it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SimulatedSetup {
    /// The preset whose dynamics and arm the bench uses (`fig1`, `fig4`, `fig8`).
    pub preset: String,
    /// The model file given with `--model`, when one was.
    pub model_file: Option<String>,
    /// The reference instrument.
    pub reference: ReferenceKind,
    /// The seed of every random draw.
    pub seed: u64,
    /// What to measure.
    pub plan: SurveyPlan,
    /// The engine's deadlines and waits.
    pub timing: Timing,
    /// Instrument time of one run, which turns the model's drift per run into drift over time.
    pub run_period_s: f64,
    /// The faults the simulated instruments inject (`run --fault-rates`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub faults: Option<survey_sims::faults::FaultRates>,
    /// The SMRs on the table (`run --smrs`, a model file's `[smrs]`);
    /// empty: one.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub smrs: Vec<survey_processing::smrs::SmrMount>,
    /// The polygon on a stage, turned by these faces relative to the table
    /// in run 1, 2, … (repeated; `run --polygon-turns`): the polygon
    /// calibrated in place. Empty: on the table, never turned.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub polygon_turns: Vec<u32>,
    /// The machine's frame in the simulated tracker's (a model file's
    /// `[machine_frame]`), when given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub machine_frame: Option<survey_processing::frame::MachineFrame>,
    /// The asset's `[asset]` keys (its id and interval keys), when the
    /// bench was given them: a configuration states them for real
    /// instruments; the command line's simulated bench takes none (its
    /// surveys' intervals are the defaults), a test of the intervals on
    /// the simulated bench sets them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub asset: Option<crate::config::AssetSection>,
}

/// What a survey of real instruments was made from, stored with it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ConfiguredSetup {
    /// The configuration file's content.
    pub config: SurveyConfig,
    /// What to measure.
    pub plan: SurveyPlan,
}

/// How a survey was set up.
#[derive(Debug, Clone, PartialEq)]
#[allow(clippy::large_enum_variant, reason = "one record at a time: the size does not matter")]
pub enum Setup {
    /// On the simulated bench.
    Simulated(SimulatedSetup),
    /// On configured instruments.
    Configured(ConfiguredSetup),
    /// Imported from a file.
    Imported {
        /// The file, as it was named.
        file: String,
    },
    /// Nothing was recorded (`{}`).
    Unrecorded,
}

impl Setup {
    /// Why a survey of this setup is a rehearsal on simulated instruments,
    /// never a calibration, when it is: the built-in simulated bench; a
    /// configuration `survey sim` served (its `[rehearsal]`); instruments
    /// that ran faster than real time (`[timing] time_scale`: only a
    /// simulator does).
    pub fn rehearsal(&self) -> Option<String> {
        match self {
            Setup::Simulated(s) => {
                Some(format!("the built-in simulated instruments (preset {}, seed {})", s.preset, s.seed))
            }
            Setup::Configured(c) => match &c.config.rehearsal {
                Some(r) => Some(format!("instruments simulated by {}", r.simulator)),
                None if c.config.time_scale() != 1.0 => Some(format!(
                    "instruments that ran at {}x real time ([timing] time_scale): only a simulator does",
                    c.config.time_scale()
                )),
                None => None,
            },
            _ => None,
        }
    }

    /// How many times faster than real time the instruments ran: a
    /// configuration's `[timing] time_scale` (a rehearsal on `survey sim
    /// --time-scale X`); 1 for the simulated bench, whose virtual clock is
    /// its instruments' own.
    pub fn time_scale(&self) -> f64 {
        match self {
            Setup::Configured(c) => c.config.time_scale(),
            _ => 1.0,
        }
    }

    /// The plan, when the survey was acquired.
    pub fn plan(&self) -> Option<&SurveyPlan> {
        match self {
            Setup::Simulated(s) => Some(&s.plan),
            Setup::Configured(c) => Some(&c.plan),
            Setup::Imported { .. } | Setup::Unrecorded => None,
        }
    }

    /// The asset a survey of this setup belongs to unless told otherwise:
    /// `sim-<preset>` on the simulated bench, the configuration's `[asset]
    /// id`, else [`UNASSIGNED`].
    pub fn default_asset(&self) -> String {
        match self {
            Setup::Simulated(s) => s.asset.as_ref().map_or_else(|| simulated_asset(&s.preset), |a| a.id.clone()),
            Setup::Configured(c) => c.config.asset.as_ref().map_or(UNASSIGNED.to_string(), |a| a.id.clone()),
            Setup::Imported { .. } | Setup::Unrecorded => UNASSIGNED.to_string(),
        }
    }

    /// The text stored in `config_json`.
    pub fn to_column(&self) -> String {
        match self {
            Setup::Simulated(s) => serde_json::to_string(s),
            Setup::Configured(c) => serde_json::to_string(c),
            Setup::Imported { file } => serde_json::to_string(&serde_json::json!({ "imported_from": file })),
            Setup::Unrecorded => Ok("{}".to_string()),
        }
        .expect("a setup is plain data and serialises")
    }

    /// Parse `config_json` of a survey from `source`.
    fn from_column(source: &SurveySource, text: &str) -> Result<Self, String> {
        // `{}` (whitespace aside): nothing recorded.
        if text.chars().filter(|c| !c.is_whitespace()).eq("{}".chars()) {
            return Ok(Setup::Unrecorded);
        }
        // Parsed straight into the setup, not through a `Value` and its
        // clone: a simulated setup holds the plan's every target (180000 of
        // them in a 1.8 M-sample survey), and every command that reads the
        // survey parses it.
        let simulated = || serde_json::from_str::<SimulatedSetup>(text).map(Setup::Simulated);
        let configured = || serde_json::from_str::<ConfiguredSetup>(text).map(Setup::Configured);
        match source {
            SurveySource::Simulated => simulated().map_err(|e| e.to_string()),
            SurveySource::Instruments => configured().map_err(|e| e.to_string()),
            SurveySource::Verification | SurveySource::Resolving => simulated()
                .or_else(|_| configured())
                .map_err(|e| format!("neither a simulated nor a configured setup: {e}")),
            SurveySource::Import { file } => {
                let value: serde_json::Value = serde_json::from_str(text).map_err(|e| e.to_string())?;
                Ok(Setup::Imported {
                    file: value.get("imported_from").and_then(|f| f.as_str()).unwrap_or(file).to_string(),
                })
            }
        }
    }
}

/// What a verification survey verifies: the survey whose table it applied, and the table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VerificationOf {
    /// The survey the table was made from.
    pub verifies_survey: i64,
    /// The table file written by the processing.
    pub table: String,
    /// The table applied in the feedback path (absent in surveys stored by
    /// versions before 0.2: such a verification cannot be resumed).
    #[serde(default)]
    pub correction: Option<CorrectionTable>,
}

/// A stored survey column that does not parse: the database is damaged (or
/// was written by something else). A bad-input error (exit status 2).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{database}: survey {survey} is damaged: its {column} cannot be read ({detail})")]
pub struct Damaged {
    /// The database file.
    pub database: String,
    /// The survey id.
    pub survey: i64,
    /// Which part of it.
    pub column: &'static str,
    /// What the parser said.
    pub detail: String,
}

/// Where a survey stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SurveyStatus {
    /// Acquisition is under way (or the process died without saying otherwise:
    /// `survey resume` treats a `running` survey like an interrupted one).
    Running,
    /// Acquisition stopped before the plan was complete; `survey resume` continues it.
    Interrupted,
    /// Every planned sample is stored; the outputs (the correction table and
    /// the files beside it) are being written, or were not all written (a
    /// kill, a full disk): `survey resume` writes them.
    Processing,
    /// Every planned sample is stored, and the outputs are written.
    Complete,
    /// Acquisition gave up on an error.
    Failed,
    /// Data imported from a CSV file.
    Imported,
}

impl SurveyStatus {
    /// The name stored in the database and shown to users.
    pub fn as_str(self) -> &'static str {
        match self {
            SurveyStatus::Running => "running",
            SurveyStatus::Interrupted => "interrupted",
            SurveyStatus::Processing => "processing",
            SurveyStatus::Complete => "complete",
            SurveyStatus::Failed => "failed",
            SurveyStatus::Imported => "imported",
        }
    }

    /// Parse the stored name.
    pub fn from_column(s: &str) -> Option<Self> {
        Some(match s {
            "running" => SurveyStatus::Running,
            "interrupted" => SurveyStatus::Interrupted,
            "processing" => SurveyStatus::Processing,
            "complete" => SurveyStatus::Complete,
            "failed" => SurveyStatus::Failed,
            "imported" => SurveyStatus::Imported,
            _ => return None,
        })
    }
}

impl fmt::Display for SurveyStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// What [`crate::Store::create_survey`] and
/// [`crate::Store::import`] store about a new survey.
#[derive(Debug, Clone, PartialEq)]
pub struct NewSurvey {
    /// `Running` for an acquisition, `Imported` for an import.
    pub status: SurveyStatus,
    /// Where the samples come from.
    pub source: SurveySource,
    /// Target positions per revolution, when known.
    pub points: Option<u32>,
    /// Runs in the plan, when known.
    pub runs: Option<u32>,
    /// Runs go both ways (forward then reverse).
    pub bidirectional: bool,
    /// How the survey was set up.
    pub setup: Setup,
    /// The positioner model (simulated surveys: the one simulated).
    pub model: Option<Model>,
    /// The instruments, described for people (names, addresses).
    pub instruments: serde_json::Value,
    /// What a verification survey verifies.
    pub verification: Option<VerificationOf>,
    /// How many samples the plan holds, when known.
    pub planned_samples: Option<u64>,
    /// The asset (the axis measured): see [`asset_id`](crate::asset::asset_id).
    pub asset: String,
    /// For a check survey (`survey run --check`): the uid of the calibration it is compared with.
    pub check_of: Option<String>,
}

impl Default for NewSurvey {
    /// A running simulated survey with nothing recorded about its setup.
    fn default() -> Self {
        NewSurvey {
            status: SurveyStatus::Running,
            source: SurveySource::Simulated,
            points: None,
            runs: None,
            bidirectional: false,
            setup: Setup::Unrecorded,
            model: None,
            instruments: serde_json::json!({}),
            verification: None,
            planned_samples: None,
            asset: UNASSIGNED.to_string(),
            check_of: None,
        }
    }
}

impl NewSurvey {
    /// The `instruments_json` column: the description, with what a
    /// verification verifies merged in.
    pub(crate) fn instruments_column(&self) -> String {
        let mut doc = self.instruments.clone();
        if let (Some(v), Some(obj)) = (&self.verification, doc.as_object_mut())
            && let Ok(serde_json::Value::Object(extra)) = serde_json::to_value(v)
        {
            obj.extend(extra);
        }
        doc.to_string()
    }
}

/// A stored survey, typed: parsed once, when read.
#[derive(Debug, Clone, PartialEq)]
pub struct SurveyRecord {
    /// The survey id (`--survey ID`), this database's own.
    pub id: i64,
    /// The survey's UUID, the same in every store it is copied to.
    pub uid: String,
    /// The asset (the axis measured).
    pub asset: String,
    /// For a check survey: the uid of the calibration it was compared with.
    pub check_of: Option<String>,
    /// UTC ISO-8601, e.g. `2025-03-01T14:02:11Z`.
    pub created_at: String,
    /// UTC ISO-8601: the last change of status or axis.
    pub updated_at: String,
    /// Where the survey stands.
    pub status: SurveyStatus,
    /// Where its samples came from.
    pub source: SurveySource,
    /// Target positions per revolution, when known.
    pub points: Option<u32>,
    /// Runs in the plan, when known.
    pub runs: Option<u32>,
    /// Runs go both ways.
    pub bidirectional: bool,
    /// How it was set up (with its plan, for an acquired survey).
    pub setup: Setup,
    /// The positioner model stored with it (simulated surveys).
    pub model: Option<Model>,
    /// The axis located with the tracker, once located.
    pub axis: Option<AxisFit>,
    /// The instruments, as described when the survey was made.
    pub instruments: serde_json::Value,
    /// What a verification survey verifies.
    pub verification: Option<VerificationOf>,
    /// The survey whose doubts a resolving survey's check points decide.
    pub resolves: Option<i64>,
    /// Instrument time when acquisition started, seconds.
    pub started_at_s: Option<f64>,
    /// Instrument time when acquisition ended, seconds.
    pub ended_at_s: Option<f64>,
    /// How many samples the plan holds, when known.
    pub planned_samples: Option<u64>,
    /// Samples stored for this survey.
    pub sample_count: u64,
}

/// A survey's columns as stored, before parsing (a store's row; a test's
/// survey record).
#[derive(Debug, Clone)]
pub struct StoredColumns {
    pub id: i64,
    pub uid: String,
    pub asset: String,
    pub check_of: Option<String>,
    pub created_at: String,
    pub updated_at: String,
    pub status: String,
    pub source: String,
    pub points: Option<u32>,
    pub runs: Option<u32>,
    pub bidirectional: bool,
    pub config_json: String,
    pub model_toml: Option<String>,
    pub instruments_json: String,
    pub axis_json: Option<String>,
    pub started_at_s: Option<f64>,
    pub ended_at_s: Option<f64>,
    pub planned_samples: Option<u64>,
    pub sample_count: u64,
}

impl StoredColumns {
    /// The columns of a complete survey of `setup` as survey `id` would
    /// store them, with nothing measured yet (no axis, no samples): a
    /// record that reads a configuration as the commands read a stored
    /// survey's, without a store (the tests of what it says).
    pub fn configured(id: i64, setup: &ConfiguredSetup, instruments_json: &str) -> Self {
        StoredColumns {
            id,
            uid: format!("00000000-0000-4000-8000-{id:012}"),
            asset: UNASSIGNED.into(),
            check_of: None,
            created_at: "t".into(),
            updated_at: "t".into(),
            status: "complete".into(),
            source: "instruments".into(),
            points: Some(setup.plan.targets_deg.len() as u32),
            runs: Some(setup.plan.runs),
            bidirectional: setup.plan.bidirectional,
            config_json: serde_json::to_string(setup).expect("a configuration serialises"),
            model_toml: None,
            instruments_json: instruments_json.into(),
            axis_json: None,
            started_at_s: None,
            ended_at_s: None,
            planned_samples: None,
            sample_count: 0,
        }
    }
}

impl SurveyRecord {
    /// The SMRs on the table: the simulated bench's (`--smrs`, a model
    /// file's `[smrs]`) or the configuration's `[smrs]`; one otherwise.
    pub fn smrs(&self) -> Vec<survey_processing::smrs::SmrMount> {
        let smrs = match &self.setup {
            Setup::Simulated(s) => s.smrs.clone(),
            Setup::Configured(c) => c.config.smrs.as_ref().map(|s| s.mounts()).unwrap_or_default(),
            _ => Vec::new(),
        };
        if smrs.len() > 1 { smrs } else { vec![survey_processing::smrs::SmrMount::FIRST] }
    }

    /// The machine's frame in the tracker's, where the survey states one: the
    /// simulated bench's (a model file's `[machine_frame]`) or the
    /// configuration's.
    pub fn machine_frame(&self) -> Option<survey_processing::frame::MachineFrame> {
        match &self.setup {
            Setup::Simulated(s) => s.machine_frame,
            Setup::Configured(c) => c.config.machine_frame,
            _ => None,
        }
    }

    /// The reference instrument the survey was measured with, when recorded
    /// (a simulated or configured bench; not an imported survey).
    pub fn reference(&self) -> Option<ReferenceKind> {
        match &self.setup {
            Setup::Simulated(s) => Some(s.reference),
            Setup::Configured(c) => Some(c.config.reference()),
            _ => None,
        }
    }

    /// Parse the stored columns of a survey of `database` (see the module documentation).
    pub fn parse(c: StoredColumns, database: &str) -> Result<Self, Damaged> {
        let damaged = |column: &'static str, detail: String| Damaged {
            database: database.to_string(),
            survey: c.id,
            column,
            detail,
        };
        let status = SurveyStatus::from_column(&c.status)
            .ok_or_else(|| damaged("status", format!("'{}' is not a survey status", c.status)))?;
        let source = SurveySource::from_column(&c.source)
            .ok_or_else(|| damaged("source", format!("'{}' is not a survey source", c.source)))?;
        let setup = Setup::from_column(&source, &c.config_json).map_err(|e| damaged("stored setup", e))?;
        let model = c
            .model_toml
            .as_deref()
            .map(|text| Model::parse(text, "the stored model"))
            .transpose()
            .map_err(|e| damaged("model", e.to_string()))?;
        let axis = c
            .axis_json
            .as_deref()
            .map(serde_json::from_str::<AxisFit>)
            .transpose()
            .map_err(|e| damaged("located axis", e.to_string()))?;
        let instruments: serde_json::Value =
            serde_json::from_str(&c.instruments_json).map_err(|e| damaged("instruments", e.to_string()))?;
        let verification = match source {
            SurveySource::Verification => Some(
                serde_json::from_value::<VerificationOf>(instruments.clone())
                    .map_err(|e| damaged("verified table", e.to_string()))?,
            ),
            _ => None,
        };
        let resolves = match source {
            SurveySource::Resolving => Some(
                instruments["resolves_survey"]
                    .as_i64()
                    .ok_or_else(|| damaged("resolved survey", "no resolves_survey id".into()))?,
            ),
            _ => None,
        };
        Ok(SurveyRecord {
            id: c.id,
            uid: c.uid,
            asset: c.asset,
            check_of: c.check_of,
            created_at: c.created_at,
            updated_at: c.updated_at,
            status,
            source,
            points: c.points,
            runs: c.runs,
            bidirectional: c.bidirectional,
            setup,
            model,
            axis,
            instruments,
            verification,
            resolves,
            started_at_s: c.started_at_s,
            ended_at_s: c.ended_at_s,
            planned_samples: c.planned_samples,
            sample_count: c.sample_count,
        })
    }

    /// The plan, when the survey was acquired.
    pub fn plan(&self) -> Option<&SurveyPlan> {
        self.setup.plan()
    }

    /// Whether the survey is a whole measurement: acquired to its end, or imported.
    pub fn is_complete(&self) -> bool {
        matches!(self.status, SurveyStatus::Complete | SurveyStatus::Imported)
    }

    /// What instrument `role` (`positioner`, `reference`) said it is when
    /// the survey began (`instruments.identified`, survey_lab's identify).
    pub fn identified(&self, role: &str) -> Option<&str> {
        self.instruments.get("identified")?.get(role)?.as_str()
    }

    /// Why the survey is a rehearsal on simulated instruments, never a
    /// calibration, when it is: its setup says so ([`Setup::rehearsal`]), or
    /// an instrument identified itself as simulated (`survey sim`'s say
    /// "(simulated)": a configuration written by hand against it is one too).
    pub fn rehearsal(&self) -> Option<String> {
        self.setup.rehearsal().or_else(|| {
            ["positioner", "reference"].into_iter().find_map(|role| {
                let said = self.identified(role).filter(|s| s.contains("(simulated)"))?;
                Some(format!("instruments that said they are simulated (the {role} identified itself as \"{said}\")"))
            })
        })
    }

    /// Whether the survey is a calibration (neither a check nor a
    /// verification, nor a survey of the corrected axis kept on purpose).
    pub fn is_calibration(&self) -> bool {
        self.check_of.is_none() && self.source != SurveySource::Verification && !self.measured_corrected()
    }

    /// Whether the positioner's correction was kept on for this survey on
    /// purpose (`survey run --correction keep`): it measured the corrected
    /// axis, as a verification does.
    pub fn measured_corrected(&self) -> bool {
        self.instruments.get("correction").and_then(|v| v.as_str()) == Some("kept on")
    }
}

/// A survey as the command line names it: its id in this database, or its uid.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SurveyRef {
    /// The id (`3`).
    Id(i64),
    /// The UUID (`0b6c...-...`), lower or upper case.
    Uid(String),
}

impl From<i64> for SurveyRef {
    fn from(id: i64) -> Self {
        SurveyRef::Id(id)
    }
}

impl fmt::Display for SurveyRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SurveyRef::Id(id) => write!(f, "id {id}"),
            SurveyRef::Uid(uid) => write!(f, "uid {uid}"),
        }
    }
}

impl std::str::FromStr for SurveyRef {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if let Ok(id) = s.parse::<i64>() {
            return Ok(SurveyRef::Id(id));
        }
        if is_uid(s) {
            return Ok(SurveyRef::Uid(s.to_ascii_lowercase()));
        }
        Err(format!("'{s}' is neither a survey id (a number) nor a survey uid (a UUID like 0b6c1a52-...)"))
    }
}

/// Whether `s` has the shape of a UUID: 8-4-4-4-12 hexadecimal digits.
pub fn is_uid(s: &str) -> bool {
    let groups: Vec<&str> = s.split('-').collect();
    groups.len() == 5
        && groups.iter().zip([8, 4, 4, 4, 12]).all(|(g, n)| g.len() == n && g.chars().all(|c| c.is_ascii_hexdigit()))
}

/// A new random uid (UUID version 4, lower case), from the operating system's randomness.
pub fn new_uid() -> String {
    use rand::TryRngCore as _;
    let mut b = [0u8; 16];
    rand::rngs::OsRng.try_fill_bytes(&mut b).expect("the operating system gives random bytes");
    b[6] = (b[6] & 0x0f) | 0x40;
    b[8] = (b[8] & 0x3f) | 0x80;
    let hex: String = b.iter().map(|x| format!("{x:02x}")).collect();
    format!("{}-{}-{}-{}-{}", &hex[0..8], &hex[8..12], &hex[12..16], &hex[16..20], &hex[20..32])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn columns(source: &str, config: &str) -> StoredColumns {
        StoredColumns {
            id: 3,
            uid: "00000000-0000-4000-8000-000000000003".into(),
            asset: "sim-fig8".into(),
            check_of: None,
            created_at: "t".into(),
            updated_at: "t".into(),
            status: "running".into(),
            source: source.into(),
            points: None,
            runs: None,
            bidirectional: false,
            config_json: config.into(),
            model_toml: None,
            instruments_json: "{}".into(),
            axis_json: None,
            started_at_s: None,
            ended_at_s: None,
            planned_samples: None,
            sample_count: 0,
        }
    }

    #[test]
    fn sources_round_trip_through_their_column() {
        for s in [
            SurveySource::Simulated,
            SurveySource::Instruments,
            SurveySource::Verification,
            SurveySource::Import { file: "a:b.csv".into() },
        ] {
            assert_eq!(SurveySource::from_column(&s.to_column()), Some(s));
        }
        assert_eq!(SurveySource::from_column("telepathy"), None);
    }

    #[test]
    fn a_column_that_does_not_parse_makes_the_survey_damaged() {
        let e = SurveyRecord::parse(columns("simulated", r#"{"points": 3}"#), "x.db").unwrap_err();
        assert_eq!((e.survey, e.column), (3, "stored setup"));
        assert!(e.to_string().starts_with("x.db: survey 3 is damaged: its stored setup cannot be read"), "{e}");
        let e = SurveyRecord::parse(columns("warp", "{}"), "x.db").unwrap_err();
        assert_eq!(e.column, "source");
        let mut c = columns("import:a.csv", r#"{"imported_from": "a.csv"}"#);
        c.model_toml = Some("[design]\ngear_ratios = \"twelve\"\n".into());
        assert_eq!(SurveyRecord::parse(c, "x.db").unwrap_err().column, "model");
        let mut c = columns("import:a.csv", "{}");
        c.axis_json = Some("{".into());
        assert_eq!(SurveyRecord::parse(c, "x.db").unwrap_err().column, "located axis");
    }

    #[test]
    fn survey_references_are_checked() {
        assert_eq!("12".parse::<SurveyRef>(), Ok(SurveyRef::Id(12)));
        let uid = new_uid();
        assert!(is_uid(&uid) && uid.as_bytes()[14] == b'4' && "89ab".contains(uid.as_bytes()[19] as char), "{uid}");
        assert_eq!(uid.to_uppercase().parse::<SurveyRef>(), Ok(SurveyRef::Uid(uid.clone())));
        assert_ne!(new_uid(), uid);
        assert!("12a".parse::<SurveyRef>().unwrap_err().contains("neither a survey id"));
    }

    #[test]
    fn an_import_and_an_unrecorded_setup_parse() {
        let r = SurveyRecord::parse(columns("import:a.csv", r#"{"imported_from": "a.csv"}"#), "x.db").unwrap();
        assert_eq!(r.setup, Setup::Imported { file: "a.csv".into() });
        assert!(!r.source.is_acquired());
        let r = SurveyRecord::parse(columns("simulated", "{}"), "x.db").unwrap();
        assert_eq!((r.setup, r.source), (Setup::Unrecorded, SurveySource::Simulated));
    }
}
