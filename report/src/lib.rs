//! `survey report --out DIR`: the report a laboratory hands its customer, as
//! one self-contained HTML page (inline SVG, inline style, no script, nothing
//! fetched: its Content-Security-Policy forbids it) that prints as the
//! certificate (A4, one section a page, "page x of y" on every page), and,
//! with `--pdf`, that page printed by Chromium ([`pdf`]).
//!
//! [`gather`] reads what the report shows from the store: the survey, its
//! samples (with a tracker, around the axis fitted again from every SMR
//! position, as `survey process` does), the processing (computed, nothing
//! written), the verification survey of its table (or, for a verification,
//! the survey it verifies), and the model-gap steps when `--model` is given.
//! [`html`] lays it out, one module per section ([`html::BODY`] lists them);
//! [`dcc`] writes the same certificate as a Digital Calibration Certificate
//! (`dcc.xml`); [`conformity`] decides a tolerance's verdict; [`page`] is the skeleton and
//! the stylesheet, [`plot`] what every figure shares.
//!
//! Every error is shown in the unit chosen ([`units::Units`]), by
//! significance; angles along the axis stay in degrees.

pub mod certificate;
pub mod conformity;
pub mod dcc;
pub mod html;
pub mod issue;
pub mod page;
pub mod pdf;
pub mod plot;
pub mod rounding;
/// The units and numbers of the page (the processing's, shared with every command's text).
pub use survey_processing::units;

use anyhow::Context as _;
use certificate::CertificateFlags;
pub use html::verification::Verification;
use html::{drift, uncertainty};
use std::path::{Path, PathBuf};
use survey_bench::inputs::read_model;
use survey_lab::error::{bad_input, path_error};
use survey_lab::load::{Axis, Loaded, load};
use survey_lab::process::ProcessOptions;
use survey_modelgap::{ModelGap, ModelGapOptions};
use survey_processing::Sample;
use survey_store::Store;
use survey_store::survey::{SurveyRecord, SurveyRef, SurveySource};
use survey_tables::pipeline::{PipelineError, Processed};
pub use units::Units;

/// What the report is asked for, besides the survey.
#[derive(Debug, Clone, Default)]
pub struct ReportOptions {
    /// The unit of every error.
    pub units: Units,
    /// The header's fields given on the command line.
    pub flags: CertificateFlags,
    /// A model file whose `[design]` names the lines (as `survey process --design`).
    pub design: Option<PathBuf>,
    /// A recipe to replay (as `survey process --recipe`).
    pub recipe: Option<PathBuf>,
    /// Compare the survey with this model (model-gap) and show the steps.
    pub model: Option<PathBuf>,
    /// Say no processing notes on stderr (`survey serve`: a page view is not
    /// a command, and its notes are on the page).
    pub quiet: bool,
    /// Print the appendix (every target) too; the page always holds it, folded.
    pub appendix: bool,
}

/// Everything the page shows.
#[derive(Debug)]
pub struct ReportData {
    /// The survey.
    pub survey: SurveyRecord,
    /// Its samples, as processed (every figure of the page is of them, as
    /// `survey stats` and `survey process` give them).
    pub samples: Vec<Sample>,
    /// Which axis their actual angles were computed around.
    pub axis: survey_lab::refit::AxisUsed,
    /// The processing, or why there is none.
    pub processed: Result<Processed, String>,
    /// The verification pair, when there is one.
    pub verification: Option<Verification>,
    /// The model-gap steps and the model's name, with `--model`.
    pub model_gap: Option<(String, ModelGap)>,
    /// Re-measurements of a reference position over time (drift control).
    pub drift: Vec<drift::DriftPoint>,
    /// The table's uncertainty budget, when the processing gives one.
    pub uncertainty: Option<uncertainty::UncertaintyBudget>,
    /// The axis location's standard uncertainty (a tracker), degrees: a part of a measured figure's.
    pub axis_u_deg: Option<f64>,
    /// The reference's systematic standard uncertainty at an angle (a
    /// tracker's own error, from its MPE), degrees: a part of a measured figure's.
    pub reference_systematic_u_deg: Option<f64>,
    /// When the report was made (UTC, RFC 3339): the issue date of a certificate issued now.
    pub generated: String,
    /// The certificate's issue ([`issue`]), or why the page is a draft.
    pub issue: certificate::Issue,
    /// The asset's history up to this survey, when it has one.
    pub history: Option<survey_lab::life::history::History>,
    /// The air measured with the samples, or stated by the configuration.
    pub environment: survey_lab::environment::Environment,
    /// The air temperature against the samples' time, `(s, °C)`, when measured.
    pub temperature: Vec<(f64, f64)>,
    /// The axis's location and error motions (a tracker survey's).
    pub error_motions: Option<survey_motions::ErrorMotions>,
}

/// Read what the report of survey `id` (the latest when `None`) shows.
pub async fn gather(store: &Store, id: Option<SurveyRef>, opts: &ReportOptions) -> anyhow::Result<ReportData> {
    let loaded = load(store, id, Axis::Refitted).await?;
    if loaded.samples.is_empty() {
        return Err(bad_input(format!("survey {} holds no samples yet", loaded.survey.id)));
    }
    let verification = find_verification(store, &loaded).await?;
    // Its asset's history, up to this survey; a history that cannot be read
    // does not keep the report from being written.
    let history = survey_lab::life::history::history(store, &loaded.survey.asset, Some(loaded.survey.id)).await.ok();
    let (processed, model_gap, uncertainty) = analyse(&loaded, opts)?;
    let inputs = loaded.uncertainty_inputs();
    let (axis_u_deg, reference_systematic_u_deg) = (inputs.axis_u_deg, inputs.reference_systematic_u_deg);
    let environment = survey_lab::environment::Environment::of(store, &loaded.survey).await?;
    let temperature = store.temperature_series(loaded.survey.id).await?;
    let axis = loaded.axis_used();
    let Loaded { survey, samples, drift, refit, .. } = loaded;
    Ok(ReportData {
        survey,
        samples,
        axis,
        processed,
        verification,
        model_gap,
        drift: drift.iter().map(|p| (p.at_s, p.drift_deg)).collect(),
        uncertainty,
        axis_u_deg,
        reference_systematic_u_deg,
        generated: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
        issue: certificate::Issue::Draft(
            "no certificate is issued yet: `survey report` on the station's file issues it".into(),
        ),
        history,
        environment,
        temperature,
        error_motions: refit.and_then(|r| r.error_motions),
    })
}

/// The processing (or why there is none), the model-gap steps with
/// `--model`, and the table's uncertainty budget of `loaded`.
type Analysed = (Result<Processed, String>, Option<(String, ModelGap)>, Option<uncertainty::UncertaintyBudget>);

fn analyse(loaded: &Loaded, opts: &ReportOptions) -> anyhow::Result<Analysed> {
    let survey = &loaded.survey;
    // Corrected for the drift when the survey asked for it, as `survey process` does.
    let analysed = loaded.analysed();
    let process_opts = ProcessOptions {
        design: opts.design.clone(),
        recipe: opts.recipe.clone(),
        table_out: None,
        checks: loaded.checks_corrected(&loaded.checks),
        uncorrected_drift_deg: loaded.uncorrected_drift_deg(),
        quiet: opts.quiet,
        ..Default::default()
    };
    let processed = match survey_lab::process::compute(survey, &analysed, &process_opts) {
        Ok((p, _)) => Ok(p),
        Err(e) if e.downcast_ref::<PipelineError>().is_some() => Err(format!("{e:#}")),
        Err(e) => return Err(e),
    };
    let model_gap = match &opts.model {
        Some(path) => {
            let model = read_model(path)?;
            // As `survey model-gap` compares it: around the refitted axis, told the reference.
            let options = ModelGapOptions { reference: loaded.reference_info(), ..ModelGapOptions::default() };
            let gap = survey_modelgap::model_gap(&loaded.samples, &model, &options).with_context(|| {
                format!("survey {} cannot be compared with the model {}", survey.id, path.display())
            })?;
            Some((path.display().to_string(), gap))
        }
        None => None,
    };
    let mut inputs = loaded.uncertainty_inputs();
    // The reference's uncertainty the certificate states (`--reference-uncertainty` over the stored one).
    inputs.reference_u_deg = opts.flags.reference_uncertainty_deg.or(inputs.reference_u_deg);
    let uncertainty = processed.as_ref().ok().map(|p| {
        let u = survey_tables::uncertainty::uncertainty(p, &analysed, &inputs);
        uncertainty::UncertaintyBudget {
            k: u.k,
            table_u_deg: u.table_u_deg,
            combined_u_deg: u.combined_u_deg,
            budget: u
                .budget
                .into_iter()
                .map(|c| uncertainty::BudgetEntry { source: c.source, u_deg: c.u_deg })
                .collect(),
        }
    });
    Ok((processed, model_gap, uncertainty))
}

/// The verification pair of the survey of `loaded`: for a verification
/// survey, the survey it verifies; otherwise the latest verification of its
/// table. The native side is processed as the rest of the report is (around
/// the refitted axis of a tracker survey); the corrected side as stored. The
/// report's own samples are one side (see [`Verification`]); the other is
/// loaded here.
async fn find_verification(store: &Store, loaded: &Loaded) -> anyhow::Result<Option<Verification>> {
    let survey = &loaded.survey;
    let directional = |r: &SurveyRecord| {
        r.verification.as_ref().and_then(|v| v.correction.as_ref()).is_some_and(|t| t.is_directional())
    };
    if survey.source == SurveySource::Verification {
        let Some(of) = &survey.verification else { return Ok(None) };
        let native_loaded = load(store, Some(of.verifies_survey.into()), Axis::Refitted).await?;
        let plausible_max_cycles = survey_lab::verify::plausible_max(&native_loaded.survey);
        let native = native_loaded.samples;
        if native.is_empty() {
            return Ok(None);
        }
        // The corrected side as stored: the report's own samples, unless they were refitted.
        let corrected = match &loaded.refit {
            Some(_) => Some(store.samples(survey.id).await?),
            None => None,
        };
        return Ok(Some(Verification {
            native_id: of.verifies_survey,
            native: Some(native),
            verification_id: survey.id,
            corrected,
            directional: directional(survey),
            plausible_max_cycles,
        }));
    }
    // A verification is of its survey's asset: the asset's surveys, not the store's.
    let all = store.surveys_of_asset(&survey.asset).await?;
    let latest = all
        .iter()
        .filter(|r| r.verification.as_ref().is_some_and(|v| v.verifies_survey == survey.id) && r.sample_count > 0)
        .max_by_key(|r| r.id);
    let Some(v) = latest else { return Ok(None) };
    Ok(Some(Verification {
        native_id: survey.id,
        native: None,
        verification_id: v.id,
        corrected: Some(store.samples(v.id).await?),
        directional: directional(v),
        plausible_max_cycles: survey_lab::verify::plausible_max(survey),
    }))
}

/// Write `html` as `index.html` and `dcc` as `dcc.xml` into the folder `out`
/// (created if missing); returns the page's path.
pub fn write(out: &Path, html: &str, dcc: &str) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(out).map_err(|e| path_error(e, format!("cannot create the folder {}", out.display())))?;
    for (name, text) in [("dcc.xml", dcc), ("index.html", html)] {
        let path = out.join(name);
        std::fs::write(&path, text).map_err(|e| path_error(e, format!("cannot write {}", path.display())))?;
    }
    Ok(out.join("index.html"))
}
