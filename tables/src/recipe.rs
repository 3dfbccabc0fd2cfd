//! Processing recipes: every choice the processing of a survey makes, in a
//! TOML file, so that a recalibration replays them on new data (the paper:
//! "the steps used by the engineer are recovered from the parameter file and
//! processing occurs in the same way the factory calibration was performed,
//! but using the new survey data").
//!
//! # The file
//!
//! ```toml
//! version = 1
//!
//! [analysis]                  # survey_processing::analysis::AnalysisOptions, every key optional
//! false_alarm_rate = 0.01
//!
//! [lines]                     # true frequencies, cycles per revolution
//! keep = [1, 20, 40]          # kept in the table, significant in this survey or not
//! remove = [7]                # removed, repeatable in this survey or not
//! unlisted = "keep_repeatable"  # a line listed in neither: keep it when this
//!                             # survey finds it repeatable ("remove": drop it)
//! min_amplitude_deg = 0.0     # an unlisted line below this is dropped
//!
//! [[alias]]                   # an aliased line, by its true frequency
//! true_cycles = 432
//! action = "relocate"         # or "null", or "absent" (not there: its bin is
//!                             # left to the other frequency that lands on it)
//! observed_cycles = 288       # where it appeared when the recipe was made (for the record)
//!
//! [table]
//! dense_points = 131072       # the paper's "128k" resampling grid
//! rows = 16384                # rows of the correction table
//! directional = "auto"        # "on", "off", or "auto": directional when the
//! hysteresis_factor = 5.0     # largest |forward - reverse| of the mean maps exceeds
//!                             # this many standard deviations of its noise
//! remove_mean = false         # drop the mean error (the zero reference)
//! interpolation = "spectral"  # the method the report compares the others with (Figure 6)
//! # partial_method = { method = "least_squares", cycles = [6, 72], poly_degree = 3 }
//!
//! [export]                    # survey_controllers::export
//! linuxcnc = true             # <stem>.comp0 and <stem>.comp1 (COMP_FILE_TYPE 0 and 1)
//! linuxcnc_points = 256       # at most 256 (LinuxCNC's EMCMOT_COMP_SIZE)
//! sinumerik_840d = true       # <stem>.840d.ini
//! fanuc = true                # <stem>.fanuc.txt
//! generic = false             # <stem>.generic.csv
//! binary = true               # <stem>.bin for survey_controllers::corrector
//! binary_format = "f64"       # or "f32"
//! # start_deg = -720.0        # the controller tables' range (default 0..360,
//! # end_deg = 720.0           # or the measured range of a partial survey)
//! # interval_deg = 1.0        # or points = 361 (default: each format's)
//! directions = "auto"         # "combined" or "separate" forward/reverse values
//! # reference_deg = 0.0       # the reference point (default 0, or the point nearest it)
//! zero_at_reference = false   # zero the LinuxCNC and generic values there
//! sinumerik_absolute = false  # 840D: keep absolute values (default: zero at the reference, as K3 asks)
//! sign = "error"              # generic table: "error" (readout - actual) or "correction"
//! values = "absolute"         # generic table: or "incremental"
//! sinumerik_axis = "C1"       # 840D machine axis name
//! sinumerik_measuring_system = 0
//! fanuc_unit_deg = 0.001      # Fanuc detection unit
//! fanuc_magnification = 1     # parameter 3623
//! # fanuc_reference_number = 0  # parameter 3620
//! ```
//!
//! Every section and key is optional (the defaults above); unknown keys are
//! refused. The CSV table is always written.
//!
//! # What a recipe decides ([`Recipe::decide`])
//!
//! On a full circle of `N` points the decision is a [`SpectralEdit`] of the
//! survey's mean error spectrum:
//!
//! - a line in `lines.keep` is kept even when this survey's tests would not flag
//!   it; one in `lines.remove` is removed even when they would; a significant
//!   line listed in neither follows `lines.unlisted`. A kept line at or above
//!   `N/2` (this survey cannot resolve it) is relocated from its alias.
//! - an `[[alias]]` entry fixes what happens to that true frequency: `relocate`
//!   moves its alias bin to the true frequency, `null` empties the bin. When
//!   this survey resolves the frequency (`N > 2 f`), `relocate` keeps the line
//!   and `null` removes it. An aliased design harmonic the recipe does not name
//!   takes the analysis' recommendation when its bin holds a repeatable line
//!   (and `lines.unlisted` keeps lines), else its bin is nulled. An alias that
//!   lands on bin 0 cannot be told from the mean and is left alone; one on the
//!   Nyquist bin cannot be relocated (its phase is lost) and is nulled instead.
//! - everything else (noise) is removed: the table carries the kept lines only.
//!
//! Over a partial range the kept frequencies are fitted by least squares
//! ([`survey_processing::resample::PartialMethod`]); `table.partial_method`, when given, is
//! used as written, else the fit is a cubic polynomial plus the kept
//! frequencies that make at least half a cycle over the span, and cubic
//! interpolation of the map when that basis is degenerate.
//!
//! [`Recipe::from_analysis`] writes the recipe of a first processing: the
//! repeatable lines in `keep`, the significant non-repeatable ones in
//! `remove`, and one `[[alias]]` per aliased design harmonic whose bin holds a
//! line, with the analysis' recommendation (`null` when the line is not
//! repeatable); a full circle of more targets than `dense_points` raises it
//! to the next power of two that holds them. Deciding that recipe on the same
//! analysis gives the same table.
//!
//! # Errors
//!
//! A defect of the file is a [`RecipeError`] naming the file, the line and the
//! key (`recipe.toml:14: table.rows: must be at least 2, got 1`). A choice that
//! cannot be honoured on a given survey (a relocation this survey's sampling
//! makes impossible, a dense grid too small for it) is a [`ChoiceError`]
//! naming the key; [`RecipeError::of_choice`] adds the file and line.

mod build;
mod decide;
mod direction;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_direction;

pub use build::{BuiltTable, Hysteresis, TableMethod, hysteresis};
pub use decide::{AliasDecision, AliasOutcome, Decisions, LineAction, LineDecision};
pub use direction::DirectionModel;

use crate::correction::{CorrectionError, DEFAULT_DENSE_POINTS, DEFAULT_TABLE_ROWS};
use serde::{Deserialize, Serialize, Serializer};
use survey_processing::analysis::{Analysis, AnalysisOptions, Method as AnalysisMethod};
use survey_processing::errormap::Coverage;
use survey_processing::num::Num;
use survey_processing::resample::{Method as Interpolation, PartialMethod};

/// The recipe format version.
pub const RECIPE_VERSION: u32 = 1;
/// The most rows LinuxCNC's joint compensation holds (`EMCMOT_COMP_SIZE`).
pub const LINUXCNC_MAX_POINTS: usize = survey_controllers::linuxcnc::MAX_POINTS;
/// The largest dense grid or table a recipe may ask for (2^24 points).
pub const MAX_POINTS: usize = 1 << 24;

/// Every choice of a processing. See the module documentation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Recipe {
    /// Format version, 1.
    #[serde(default = "version_default")]
    pub version: u32,
    /// The spectral analysis' options.
    #[serde(default)]
    pub analysis: AnalysisOptions,
    /// Which lines the table keeps.
    #[serde(default)]
    pub lines: LineChoices,
    /// What to do with aliased lines, by true frequency (`[[alias]]`).
    #[serde(default, rename = "alias")]
    pub aliases: Vec<AliasChoice>,
    /// How the table is built.
    #[serde(default)]
    pub table: TableChoices,
    /// Which files are exported beside the CSV.
    #[serde(default)]
    pub export: ExportChoices,
}

fn version_default() -> u32 {
    RECIPE_VERSION
}

impl Default for Recipe {
    fn default() -> Self {
        Self {
            version: RECIPE_VERSION,
            analysis: AnalysisOptions::default(),
            lines: LineChoices::default(),
            aliases: Vec::new(),
            table: TableChoices::default(),
            export: ExportChoices::default(),
        }
    }
}

/// What happens to a significant line the recipe does not list.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Unlisted {
    /// Keep it when this survey finds it repeatable (and at least `min_amplitude_deg`).
    #[default]
    KeepRepeatable,
    /// Remove it: the table holds the listed lines only.
    Remove,
}

/// The `[lines]` section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LineChoices {
    /// True frequencies kept, cycles per revolution.
    #[serde(serialize_with = "ser_cycles")]
    pub keep: Vec<f64>,
    /// True frequencies removed, cycles per revolution.
    #[serde(serialize_with = "ser_cycles")]
    pub remove: Vec<f64>,
    /// The rule for lines listed in neither.
    pub unlisted: Unlisted,
    /// Unlisted lines below this amplitude are dropped, degrees.
    pub min_amplitude_deg: f64,
}

impl Default for LineChoices {
    fn default() -> Self {
        Self { keep: Vec::new(), remove: Vec::new(), unlisted: Unlisted::KeepRepeatable, min_amplitude_deg: 0.0 }
    }
}

/// Whole numbers are written as integers (`[1, 20, 40]`, not `[1.0, 20.0, 40.0]`).
fn ser_cycles<S: Serializer>(v: &[f64], s: S) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeSeq;
    let mut seq = s.serialize_seq(Some(v.len()))?;
    for &x in v {
        if x.fract() == 0.0 && x.abs() < 9e15 {
            seq.serialize_element(&(x as i64))?;
        } else {
            seq.serialize_element(&x)?;
        }
    }
    seq.end()
}

/// Relocate or null an aliased line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AliasChoiceAction {
    /// Move it from its alias bin to its true frequency.
    Relocate,
    /// Empty its alias bin.
    Null,
    /// It is not there (check points measured between the targets showed
    /// it): its alias bin is left to the other frequency that lands there.
    Absent,
}

/// One `[[alias]]` entry.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AliasChoice {
    /// The true frequency, cycles per revolution.
    pub true_cycles: usize,
    /// What to do with it.
    pub action: AliasChoiceAction,
    /// Where it appeared in the survey the recipe was made from (informative).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub observed_cycles: Option<usize>,
    /// The design part it comes from (informative).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
}

/// Whether the table has separate forward and reverse columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Directional {
    /// Directional when the hysteresis stands out of its noise (see [`TableChoices::hysteresis_factor`]).
    #[default]
    Auto,
    /// Always directional (when the survey measured both directions).
    On,
    /// One column for both directions.
    Off,
}

/// The `[table]` section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TableChoices {
    /// The resampling grid, points per revolution (default 131072).
    pub dense_points: usize,
    /// Rows of the table (default 16384).
    pub rows: usize,
    /// Directional table: `auto`, `on` or `off`.
    pub directional: Directional,
    /// `auto` makes the table directional when `max |forward - reverse|` exceeds
    /// this many standard deviations of the noise of the mean maps' difference
    /// (default 5: the largest of 1800 normal deviates is about 3.6).
    pub hysteresis_factor: f64,
    /// Drop the mean error (default false: the table holds the zero offset too).
    pub remove_mean: bool,
    /// The interpolation the report holds the others against (default `spectral`).
    pub interpolation: Interpolation,
    /// How a partial range is fitted (default: derived from the kept lines).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub partial_method: Option<PartialMethod>,
}

impl Default for TableChoices {
    fn default() -> Self {
        Self {
            dense_points: DEFAULT_DENSE_POINTS,
            rows: DEFAULT_TABLE_ROWS,
            directional: Directional::Auto,
            hysteresis_factor: 5.0,
            remove_mean: false,
            interpolation: Interpolation::Spectral,
            partial_method: None,
        }
    }
}

pub use survey_controllers::export::{ChoiceError, ExportChoices};

/// A defect of a recipe file: the file, the line (when known), the key and what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}{}: {}{message}", source_name, line.map(|l| format!(":{l}")).unwrap_or_default(), if key.is_empty() { String::new() } else { format!("{key}: ") })]
pub struct RecipeError {
    /// The file.
    pub source_name: String,
    /// The 1-based line, when known.
    pub line: Option<usize>,
    /// The key (empty when the defect is not at a key).
    pub key: String,
    /// What is wrong.
    pub message: String,
}

impl RecipeError {
    /// `e` as a defect of the recipe file `source_name` whose text is
    /// `text` (the line is found from the key).
    pub fn of_choice(e: ChoiceError, text: &str, source_name: &str) -> RecipeError {
        RecipeError { source_name: source_name.to_string(), line: locate(text, &e.key), key: e.key, message: e.message }
    }
}

impl Recipe {
    /// Parse and validate recipe text; `source_name` names it in errors.
    pub fn parse(text: &str, source_name: &str) -> Result<Self, RecipeError> {
        let recipe: Recipe = toml::from_str(text).map_err(|e| {
            let (line, key) = match e.span() {
                Some(span) => (Some(line_of(text, span.start)), key_at(text, span.start)),
                None => (None, String::new()),
            };
            RecipeError { source_name: source_name.to_string(), line, key, message: e.message().trim().to_string() }
        })?;
        recipe.validate().map_err(|e| RecipeError::of_choice(e, text, source_name))?;
        Ok(recipe)
    }

    /// The recipe as a TOML file that [`Recipe::parse`] reads back, after a
    /// comment header.
    pub fn to_toml(&self) -> String {
        let body = toml::to_string(self).expect("a recipe serialises to TOML");
        format!(
            "# survey processing recipe (format {RECIPE_VERSION}): every choice of `survey process`.\n\
             # Replay it on a new survey with `survey process --recipe FILE`. Frequencies are cycles\n\
             # per revolution (true frequencies); `[[alias]]` entries say what happens to aliased lines.\n\n{body}"
        )
    }

    /// Check every value that does not depend on a survey.
    pub fn validate(&self) -> Result<(), ChoiceError> {
        let bad = |key: &str, message: String| Err(ChoiceError::new(key, message));
        if self.version != RECIPE_VERSION {
            return bad(
                "version",
                format!("recipe format {} is not known (this program reads {RECIPE_VERSION})", self.version),
            );
        }
        // The analysis' own ranges (analysis::AnalysisOptions checks the same
        // when it runs; checked here so the key and line can be named).
        let a = &self.analysis;
        if !(a.false_alarm_rate > 0.0 && a.false_alarm_rate.is_finite()) {
            return bad(
                "analysis.false_alarm_rate",
                format!("must be a positive number, got {}", Num(a.false_alarm_rate)),
            );
        }
        if let Some(c) = a.min_coherence
            && !(0.0..=1.0).contains(&c)
        {
            return bad("analysis.min_coherence", format!("must be from 0 to 1, got {}", Num(c)));
        }
        for (key, v) in [
            ("analysis.gear_harmonics", a.gear_harmonics),
            ("analysis.tooth_harmonics", a.tooth_harmonics),
            ("analysis.sideband_orders", a.sideband_orders),
            ("analysis.sideband_tooth_harmonics", a.sideband_tooth_harmonics),
        ] {
            if v > 1000 {
                return bad(key, format!("must be at most 1000, got {v}"));
            }
        }
        for (key, list) in [("lines.keep", &self.lines.keep), ("lines.remove", &self.lines.remove)] {
            if let Some(f) = list.iter().find(|f| !(f.is_finite() && **f > 0.0)) {
                return bad(
                    key,
                    format!("{} is not a positive frequency (the mean, 0, is table.remove_mean)", Num(*f)),
                );
            }
        }
        if let Some(f) = self.lines.keep.iter().find(|f| self.lines.remove.contains(f)) {
            return bad("lines.remove", format!("{} cycles/rev is both kept and removed", Num(*f)));
        }
        let m = self.lines.min_amplitude_deg;
        if !(m.is_finite() && m >= 0.0) {
            return bad(
                "lines.min_amplitude_deg",
                format!("must be a finite, non-negative number of degrees, got {}", Num(m)),
            );
        }
        for (i, a) in self.aliases.iter().enumerate() {
            let key = |k: &str| format!("alias[{}].{k}", i + 1);
            if a.true_cycles == 0 {
                return bad(&key("true_cycles"), "must be at least 1".into());
            }
            if self.aliases[..i].iter().any(|b| b.true_cycles == a.true_cycles) {
                return bad(
                    &key("true_cycles"),
                    format!("{} cycles/rev has more than one [[alias]] entry", a.true_cycles),
                );
            }
            let f = a.true_cycles as f64;
            if self.lines.keep.contains(&f) || self.lines.remove.contains(&f) {
                return bad(&key("true_cycles"), format!("{f} cycles/rev is also in [lines]; give it one place"));
            }
        }
        let t = &self.table;
        if !(2..=MAX_POINTS).contains(&t.rows) {
            return bad("table.rows", format!("must be from 2 to {MAX_POINTS}, got {}", t.rows));
        }
        if !(2..=MAX_POINTS).contains(&t.dense_points) {
            return bad("table.dense_points", format!("must be from 2 to {MAX_POINTS}, got {}", t.dense_points));
        }
        if !(t.hysteresis_factor.is_finite() && t.hysteresis_factor > 0.0) {
            return bad(
                "table.hysteresis_factor",
                format!("must be a positive number, got {}", Num(t.hysteresis_factor)),
            );
        }
        if let Some(PartialMethod::LeastSquares { cycles, poly_degree }) = &t.partial_method {
            if let Some(c) = cycles.iter().find(|c| !(c.is_finite() && **c > 0.0)) {
                return bad("table.partial_method", format!("frequency {} must be positive", Num(*c)));
            }
            if *poly_degree > 20 {
                return bad("table.partial_method", format!("poly_degree {poly_degree} is above 20"));
            }
        }
        self.export.validate()
    }

    /// The recipe of a first processing: `defaults` (its analysis options
    /// should be the ones `analysis` was made with) with the lines and aliases
    /// the analysis found. See the module documentation.
    pub fn from_analysis(analysis: &Analysis, defaults: &Recipe) -> Recipe {
        let mut r = defaults.clone();
        r.analysis.series = analysis.series;
        r.lines.keep.clear();
        r.lines.remove.clear();
        r.aliases.clear();
        let full = analysis.method == AnalysisMethod::Dft;
        let bin_of = |c: f64| c.round() as usize;
        for line in &analysis.lines {
            // On a full circle an aliased line is the [[alias]] entries' business.
            if full && line.aliased {
                continue;
            }
            let f = if full { line.cycles_per_rev.round() } else { line.true_cycles_per_rev };
            let list = if line.repeatable { &mut r.lines.keep } else { &mut r.lines.remove };
            if !list.contains(&f) {
                list.push(f);
            }
        }
        if full {
            for a in analysis.aliases.iter().filter(|a| a.significant) {
                if a.true_cycles.fract() != 0.0 || r.aliases.iter().any(|b| b.true_cycles as f64 == a.true_cycles) {
                    continue;
                }
                let repeatable = analysis
                    .lines
                    .iter()
                    .any(|l| bin_of(l.cycles_per_rev) == bin_of(a.observed_cycles) && l.repeatable);
                let action = match a.action {
                    survey_processing::analysis::AliasAction::Relocate if repeatable => AliasChoiceAction::Relocate,
                    _ => AliasChoiceAction::Null,
                };
                let f = a.true_cycles;
                r.lines.keep.retain(|&k| k != f);
                r.lines.remove.retain(|&k| k != f);
                r.aliases.push(AliasChoice {
                    true_cycles: f as usize,
                    action,
                    observed_cycles: Some(bin_of(a.observed_cycles)),
                    source: Some(a.source.clone()),
                });
            }
        }
        r.lines.keep.sort_by(f64::total_cmp);
        r.lines.remove.sort_by(f64::total_cmp);
        r.aliases.sort_by_key(|a| a.true_cycles);
        // A full circle of more targets than the default grid resamples
        // through the next power of two that holds them all.
        if let Coverage::FullCircle { n } = analysis.error_map.coverage
            && n > r.table.dense_points
        {
            r.table.dense_points = n.next_power_of_two().min(MAX_POINTS);
        }
        r
    }
}

/// Why a recipe cannot be applied to a survey.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ApplyError {
    /// A choice of the recipe cannot be honoured on this survey.
    #[error(transparent)]
    Choice(#[from] ChoiceError),
    /// The survey's data cannot make a table.
    #[error(transparent)]
    Table(#[from] CorrectionError),
    /// The survey's targets cannot make a table.
    #[error("{0}")]
    Targets(String),
}

fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

/// The line's key (`rows` in `rows = 1`) and its section (`[table]`), dotted.
fn key_at(text: &str, offset: usize) -> String {
    let offset = offset.min(text.len());
    let start = text[..offset].rfind('\n').map_or(0, |i| i + 1);
    let line = text[start..].lines().next().unwrap_or("");
    let key = line.split_once('=').map(|(k, _)| k.trim().trim_matches('"').to_string()).unwrap_or_default();
    let mut section = String::new();
    let mut count = std::collections::HashMap::<String, usize>::new();
    for l in text[..start].lines() {
        let l = l.trim();
        if let Some(name) = l.strip_prefix("[[").and_then(|s| s.split_once("]]")).map(|(n, _)| n.trim().to_string()) {
            let n = count.entry(name.clone()).or_default();
            *n += 1;
            section = format!("{name}[{n}]");
        } else if let Some(name) =
            l.strip_prefix('[').and_then(|s| s.split_once(']')).map(|(n, _)| n.trim().to_string())
        {
            section = name;
        }
    }
    match (section.is_empty(), key.is_empty()) {
        (_, true) => section,
        (true, false) => key,
        (false, false) => format!("{section}.{key}"),
    }
}

/// The line of a dotted key (`table.rows`, `alias[2].action`, `version`) in
/// recipe text: the key's own line, else its section's header.
pub fn locate(text: &str, key: &str) -> Option<usize> {
    let (section, leaf) = match key.rsplit_once('.') {
        Some((s, l)) => (s, l),
        None => ("", key),
    };
    let (name, index) = match section.split_once('[') {
        Some((n, rest)) => (n, rest.trim_end_matches(']').parse::<usize>().ok()),
        None => (section, None),
    };
    let lines: Vec<&str> = text.lines().collect();
    let is_header = |l: &str| l.trim_start().starts_with('[');
    let header_name = |l: &str| l.trim().trim_start_matches('[').split(']').next().unwrap_or("").trim().to_string();
    let mut start = 0;
    let mut header = None;
    if !section.is_empty() {
        let mut seen = 0;
        let found = lines.iter().position(|l| {
            if !is_header(l) || header_name(l) != name {
                return false;
            }
            seen += 1;
            index.is_none_or(|i| i == seen)
        })?;
        header = Some(found + 1);
        start = found + 1;
    }
    for (i, l) in lines.iter().enumerate().skip(start) {
        if is_header(l) {
            break;
        }
        if let Some((k, _)) = l.split_once('=')
            && k.trim().trim_matches('"') == leaf
        {
            return Some(i + 1);
        }
    }
    header
}
