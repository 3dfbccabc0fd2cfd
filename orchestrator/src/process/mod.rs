//! `survey process`: the paper's DSP processing of a stored survey, and the
//! correction table with its exports.
//!
//! [`process_survey`] reads the survey's samples, the positioner design
//! (`--design FILE`, a model file whose `[design]` is used; else the model the
//! survey was simulated with; else an empty design, said on stderr), and the
//! processing recipe (`--recipe FILE` replays one; else a new one is derived
//! from this survey's analysis, [`Recipe::from_analysis`]). Then, all pure
//! ([`pipeline`]): the spectral analysis, the recipe's decisions, the table,
//! the predicted accuracy (native and corrected peak, ISO 230-2 `A`, the
//! repeatability floor), the paper's Figure 6 interpolation comparison. Last,
//! the files ([`files`]): the table CSV (`--table-out`, default
//! `table-<id>.csv`), and beside it, named from its stem, the LinuxCNC
//! `COMP_FILE`s `<stem>.comp0` and `<stem>.comp1`, the binary table
//! `<stem>.bin` and the recipe used, `<stem>.recipe.toml`.
//!
//! A failure writes nothing: every check and every computation comes first,
//! the files are written to temporary names and renamed at the end. The
//! database is only read.
//!
//! `survey run` ends with the same processing: it calls [`process_survey`]
//! and prints [`ProcessOutcome::summary`] or embeds [`ProcessOutcome::json`].

pub mod files;
pub mod pipeline;
pub mod report;

use crate::cli::{Failure, ProcessArgs};
use crate::store::Store;
use anyhow::{Context as _, anyhow};
use pipeline::Processed;
use std::path::{Path, PathBuf};
use survey_processing::Sample;
use survey_processing::model::{Design, Model};
use survey_processing::recipe::Recipe;

/// What to process with; every field optional.
#[derive(Debug, Clone, Default)]
pub struct ProcessOptions {
    /// A model file whose `[design]` names the lines (default: the survey's stored model).
    pub design: Option<PathBuf>,
    /// A recipe to replay (default: derive one from this survey).
    pub recipe: Option<PathBuf>,
    /// The table CSV (default `table-<id>.csv` in the current folder); the
    /// other files go beside it.
    pub table_out: Option<PathBuf>,
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
    pub files: files::OutputPaths,
}

impl ProcessOutcome {
    /// The `survey process --json` document (the contract's keys and more).
    pub fn json(&self) -> serde_json::Value {
        report::json(self)
    }

    /// The human summary.
    pub fn summary(&self) -> String {
        report::text(self)
    }
}

/// `survey process`: process and print.
pub async fn command(db: &Path, args: ProcessArgs) -> Result<(), Failure> {
    let store = crate::commands::open_existing(db).await?;
    let survey = store.resolve(args.survey).await.map_err(crate::commands::classify)?;
    let opts = ProcessOptions { design: args.design, recipe: args.recipe, table_out: args.table_out };
    let outcome = process_survey(&store, survey.id, opts).await;
    store.close().await;
    let outcome = outcome?;
    if args.json {
        crate::cli::emit(&format!("{}\n", outcome.json()));
    } else {
        crate::cli::emit(&outcome.summary());
    }
    Ok(())
}

/// Process survey `id` of `store` and write its files (see the module
/// documentation). Notes (the design used, recipe entries that meant
/// something else on this survey) go to stderr. Bad input (a design or recipe
/// file, samples that cannot make a table, a path that cannot be created)
/// is [`Failure::Usage`]; a disk failure while writing is [`Failure::Runtime`].
pub async fn process_survey(store: &Store, id: i64, opts: ProcessOptions) -> Result<ProcessOutcome, Failure> {
    let survey = store.survey(id).await.map_err(crate::commands::classify)?;
    let (design, design_source) = match &opts.design {
        Some(path) => {
            let model = Model::from_file(path).map_err(Failure::usage)?;
            (model.design, format!("--design {}", path.display()))
        }
        None => match &survey.model_toml {
            Some(text) => {
                let model = Model::parse(text, &format!("survey {id}'s stored model"))
                    .map_err(|e| Failure::runtime(anyhow!("{e}")))?;
                (model.design, "the survey's stored model".to_string())
            }
            None => {
                eprintln!(
                    "note: survey {id} has no stored model and no --design was given: lines are named without a design \
                     (pass --design MODEL.toml to name gear and tooth harmonics)"
                );
                (Design::default(), "none".to_string())
            }
        },
    };
    let recipe = match &opts.recipe {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("{}: cannot read the recipe file", path.display()))
                .map_err(Failure::usage)?;
            let name = path.display().to_string();
            let recipe = Recipe::parse(&text, &name).map_err(Failure::usage)?;
            Some((recipe, text, name))
        }
        None => None,
    };
    let samples: Vec<Sample> =
        store.samples(id).await.map_err(Failure::runtime)?.into_iter().map(|r| r.sample).collect();
    let processed =
        pipeline::process(id, &samples, &design, recipe.as_ref().map(|(r, t, n)| (r, t.as_str(), n.as_str())))
            .map_err(Failure::usage)?;
    for n in &processed.notes {
        eprintln!("note: {n}");
    }
    let table_out = opts.table_out.clone().unwrap_or_else(|| PathBuf::from(format!("table-{id}.csv")));
    let paths = files::OutputPaths::beside(&table_out, &processed.recipe.export);
    files::write_all(&paths, &processed, id)?;
    let design = DesignSource {
        from: design_source,
        gear_ratios: design.gear_ratios.clone(),
        tooth_counts: design.tooth_counts.clone(),
        encoder_heads: design.encoder_heads,
    };
    Ok(ProcessOutcome { survey_id: id, processed, design, recipe_from: opts.recipe, files: paths })
}
