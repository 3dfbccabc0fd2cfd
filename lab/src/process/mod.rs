//! `survey process`: the paper's DSP processing of a stored survey, and the
//! correction table with its exports.
//!
//! [`process_survey`] reads the survey's samples, the positioner design
//! (`--design FILE`, a model file whose `[design]` is used; else the model the
//! survey was simulated with; else an empty design, said on stderr), and the
//! processing recipe (`--recipe FILE` replays one; else a new one is derived
//! from this survey's analysis, [`Recipe::from_analysis`]). Then, all pure
//! ([`survey_tables::pipeline`]): the spectral analysis, the recipe's decisions, the table,
//! the predicted accuracy (native and corrected peak, ISO 230-2 `A`, the
//! repeatability floor), the paper's Figure 6 interpolation comparison. Last,
//! the files ([`outputs`]): the table CSV (`--table-out`, default
//! `table-<id>.csv` in the survey's folder, [`default_table_path`]), and beside it, named from its stem, the controller
//! files the recipe's `[export]` asks for (with the command line's choices
//! laid over it, [`crate::overrides`]): LinuxCNC `<stem>.comp0` and `<stem>.comp1`,
//! Siemens 840D `<stem>.840d.ini`, Fanuc `<stem>.fanuc.txt`, the generic
//! `<stem>.generic.csv`; the binary table `<stem>.bin` and the recipe used,
//! `<stem>.recipe.toml`.
//!
//! A failure writes nothing: every check and every computation comes first,
//! the files are written to temporary names and renamed at the end. The
//! database is only read.
//!
//! `survey run` ends with the same processing: it calls [`process_survey`]
//! and prints [`ProcessOutcome::text`] or embeds [`ProcessOutcome::json`].

pub mod outputs;
mod summary;

use anyhow::Context as _;
use std::path::{Path, PathBuf};
use survey_processing::Sample;
use survey_processing::model::Design;
use survey_store::survey::SurveyRecord;
use survey_tables::pipeline::{PipelineError, Processed, Replay};
use survey_tables::recipe::Recipe;
use survey_tables::uncertainty::{Uncertainty, UncertaintyInputs};

/// The database `survey` uses when `--db` is not given.
pub const DEFAULT_DB: &str = "survey.db";

/// Where the table of survey `id` of the database `db` goes when
/// `--table-out` is not given: `table-<id>.csv` in the survey's own folder,
/// `survey-<id>/` in the current folder for the default database
/// (`survey.db`) and for a lab store's URL, else `<db>.survey-<id>/` beside
/// the database, so a survey's files stay together and surveys of different
/// databases never overwrite each other's tables. [`process_survey`] makes
/// the folder ([`ProcessOptions::make_folder`]).
pub fn default_table_path(db: &Path, id: i64) -> PathBuf {
    let folder = if db == Path::new(DEFAULT_DB) || survey_store::lab::url_of(db).is_some() {
        PathBuf::from(format!("survey-{id}"))
    } else {
        let mut s = db.as_os_str().to_os_string();
        s.push(format!(".survey-{id}"));
        PathBuf::from(s)
    };
    folder.join(format!("table-{id}.csv"))
}

/// What to process with; every field optional.
#[derive(Debug, Clone, Default)]
pub struct ProcessOptions {
    /// A model file whose `[design]` names the lines (default: the survey's stored model).
    pub design: Option<PathBuf>,
    /// A recipe to replay (default: derive one from this survey).
    pub recipe: Option<PathBuf>,
    /// The table CSV (default `survey-<id>/table-<id>.csv`); the other files
    /// go beside it.
    pub table_out: Option<PathBuf>,
    /// Make the table's folder when it is missing (the survey's own folder,
    /// [`default_table_path`]); a folder the user named must exist.
    pub make_folder: bool,
    /// Export choices laid over the recipe's `[export]` (the command line's).
    pub export: crate::overrides::ExportOverrides,
    /// What the uncertainty budget needs beyond the samples (the reference
    /// instrument's noise, the axis fit's standard error).
    pub uncertainty: UncertaintyInputs,
    /// For tests: abort the process (like a power loss) once every file is
    /// written to its temporary name, before any is renamed into place.
    pub crash_when_staged: bool,
    /// Check points measured between the targets to decide the lines in
    /// doubt ([`crate::resolving`]; empty when there are none).
    pub checks: Vec<Sample>,
    /// Print no notes: the caller says them once it has decided what stands
    /// ([`say_notes`]; a survey that measures check points next says the
    /// notes of its final processing only).
    pub quiet: bool,
    /// What a drift in time no straight line takes left in the survey's
    /// readings, degrees ([`crate::load::Loaded::uncorrected_drift_deg`]):
    /// the table carries it and is not a result.
    pub uncorrected_drift_deg: Option<f64>,
}

/// The notes of a processing on stderr, as [`compute`] says them unless
/// `quiet`: the missing design, then the processing's own.
pub fn say_notes(outcome: &ProcessOutcome) {
    if outcome.design.from == NO_DESIGN {
        survey_bench::say!("{}", no_design_note(outcome.survey_id));
    }
    for n in &outcome.processed.notes {
        survey_bench::say!("note: {n}");
    }
}

/// [`DesignSource::from`] when the survey has no model and none was given.
const NO_DESIGN: &str = "none";

fn no_design_note(id: i64) -> String {
    format!(
        "note: survey {id} has no stored model and no design was given: lines are named without a design (`survey \
         process --design MODEL.toml` or `survey report --design MODEL.toml` names gear and tooth harmonics)"
    )
}

/// Where the design came from.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DesignSource {
    /// In words: `--design fig4.toml`, `the survey's stored model`, `none`.
    pub from: String,
    /// Gear passes per revolution.
    pub gear_ratios: Vec<f64>,
    /// Tooth counts.
    pub tooth_counts: Vec<u32>,
    /// Encoder heads, when given.
    pub encoder_heads: Option<u32>,
}

/// Everything a processing produced.
#[derive(Debug)]
pub struct ProcessOutcome {
    /// The survey processed.
    pub survey_id: i64,
    /// The results.
    pub processed: Processed,
    /// The design used.
    pub design: DesignSource,
    /// The recipe file replayed, if any.
    pub recipe_from: Option<PathBuf>,
    /// The files written.
    pub files: outputs::OutputPaths,
    /// The table's uncertainty budget.
    pub uncertainty: Uncertainty,
}

impl ProcessOutcome {
    /// The `survey process --json` document (the contract's keys and more).
    pub fn json(&self) -> serde_json::Value {
        summary::json(self)
    }

    /// The summary for people, its errors in `units`.
    pub fn text(&self, units: survey_bench::output::Units) -> String {
        summary::text(self, units)
    }
}

/// Process `samples` of the survey `survey` and write its files (see the
/// module documentation). Notes (the design used, recipe entries that meant
/// something else on this survey) go to stderr. Bad input (a design or recipe
/// file, samples that cannot make a table, a path that cannot be created)
/// is a bad-input error; a disk failure while writing is a run-time failure.
pub fn process_survey(
    survey: &SurveyRecord,
    samples: &[Sample],
    opts: ProcessOptions,
) -> anyhow::Result<ProcessOutcome> {
    let id = survey.id;
    let (processed, design) = compute(survey, samples, &opts)?;
    let (table_out, make_folder) = match &opts.table_out {
        Some(path) => (path.clone(), opts.make_folder),
        None => (default_table_path(Path::new(DEFAULT_DB), id), true),
    };
    if let Some(folder) = table_out.parent().filter(|f| make_folder && !f.as_os_str().is_empty()) {
        std::fs::create_dir_all(folder)
            .map_err(|e| crate::error::path_error(e, format!("cannot create the folder {}", folder.display())))?;
    }
    let paths = outputs::OutputPaths::beside(&table_out, &processed.recipe.export);
    outputs::write_all(&paths, &processed, id, opts.crash_when_staged)?;
    let uncertainty = survey_tables::uncertainty::uncertainty(&processed, samples, &opts.uncertainty);
    Ok(ProcessOutcome { survey_id: id, processed, design, recipe_from: opts.recipe, files: paths, uncertainty })
}

/// The processing of `samples` of `survey` without writing anything: the
/// design and the recipe of `opts` resolved as [`process_survey`] resolves
/// them, then the pure pipeline (what `survey report` shows).
pub fn compute(
    survey: &SurveyRecord,
    samples: &[Sample],
    opts: &ProcessOptions,
) -> anyhow::Result<(Processed, DesignSource)> {
    let id = survey.id;
    let (design, design_source) = match &opts.design {
        Some(path) => (survey_bench::inputs::read_model(path)?.design, format!("--design {}", path.display())),
        None => match &survey.model {
            Some(model) => (model.design.clone(), "the survey's stored model".to_string()),
            None => {
                if !opts.quiet {
                    survey_bench::say!("{}", no_design_note(id));
                }
                (Design::default(), NO_DESIGN.to_string())
            }
        },
    };
    let recipe = match &opts.recipe {
        Some(path) => {
            let name = path.display().to_string();
            let text = std::fs::read_to_string(path)
                .map_err(|e| crate::error::path_error(e, format!("{name}: cannot read the recipe file")))?;
            Some((Recipe::parse(&text, &name)?, text, name))
        }
        None => None,
    };
    let replay = recipe.as_ref().map(|(recipe, text, name)| Replay { recipe, text, name });
    let export = if opts.export.is_empty() {
        None
    } else {
        let base = recipe.as_ref().map(|(r, _, _)| r.export.clone()).unwrap_or_default();
        Some(opts.export.resolve(&base)?)
    };
    let processed =
        match survey_tables::pipeline::process_with_checks(samples, &design, replay, export.as_ref(), &opts.checks) {
            Err(PipelineError::Export(e)) => return Err(crate::overrides::choice_error(&e)),
            other => other.with_context(|| format!("survey {id} cannot be processed"))?,
        };
    let mut processed = processed;
    processed.prediction.uncorrected_drift_deg = opts.uncorrected_drift_deg;
    if let Some(left) = opts.uncorrected_drift_deg {
        processed.notes.push(format!(
            "the survey drifted in time in a way no straight line takes (a pass keeps up to {left:.5} deg): the \
             table carries that drift and is not a result to load; survey again with the room settled, or with \
             [drift_control] (docs/acquisition.md)"
        ));
    }
    // An autocollimator's faces fix the sampling: say what a second
    // orientation of the polygon would resolve.
    if survey.reference() == Some(survey_acquire::ReferenceKind::Autocollimator)
        && let Some(t) = survey_tables::resolve::second_orientation(&processed.left)
    {
        processed.notes.push(t);
    }
    if !opts.quiet {
        for n in &processed.notes {
            survey_bench::say!("note: {n}");
        }
    }
    // How the table was made, not something to act on: under -v or RUST_LOG=info.
    if let Some(dm) = &processed.built.direction_model {
        tracing::info!("{}", dm.text());
    }
    let design = DesignSource {
        from: design_source,
        gear_ratios: design.gear_ratios.clone(),
        tooth_counts: design.tooth_counts.clone(),
        encoder_heads: design.encoder_heads,
    };
    Ok((processed, design))
}
