//! `survey report --out DIR`: the report a laboratory hands its customer, as
//! one self-contained HTML page (inline SVG, inline style, no script, nothing
//! fetched: its Content-Security-Policy forbids it) that prints as the
//! certificate (A4, one section a page).
//!
//! [`gather`] reads what the report shows from the store: the survey, its
//! samples (with a tracker, around the axis fitted again from every SMR
//! position, as `survey process` does), the processing (computed, nothing
//! written), the verification survey of its table (or, for a verification,
//! the survey it verifies), and the model-gap steps when `--model` is given.
//! [`html`] lays it out, one module per section:
//!
//! - [`header`]: the certificate's header and where each field comes from;
//! - [`errors`]: error against angle, every run and direction, ±2 s band;
//! - [`hysteresis`]: forward minus reverse against angle;
//! - [`spectrum`]: the spectrum with its lines named and the aliases moved;
//! - [`interpolation`]: the paper's Figure 6;
//! - [`table`]: the correction table;
//! - [`verification`]: native against corrected on one scale;
//! - [`modelgap`], [`drift`], [`uncertainty`]: when there is such data;
//! - [`iso`]: ISO 230-2 and VDI/DGQ 3441, for the axis and per target.
//!
//! Every error is shown in the unit chosen ([`units::Units`]); angles along
//! the axis stay in degrees.

pub mod drift;
pub mod errors;
pub mod header;
pub mod hysteresis;
pub mod interpolation;
pub mod iso;
pub mod modelgap;
pub mod page;
pub mod plot;
pub mod spectrum;
pub mod table;
pub mod uncertainty;
pub mod units;
pub mod verification;

use crate::error::{bad_input, path_error};
use crate::process::ProcessOptions;
use crate::store::Store;
use crate::survey::{SurveyRecord, SurveySource};
use header::{Certificate, CertificateFlags};
use page::{escape, section};
use std::path::{Path, PathBuf};
use survey_processing::Sample;
use survey_processing::errormap::ErrorMap;
use survey_processing::iso230::iso230_2;
use survey_processing::model::Model;
use survey_processing::modelgap::{ModelGap, ModelGapOptions};
use survey_processing::pipeline::{PipelineError, Processed};
pub use units::Units;
pub use verification::Verification;

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
    pub axis: crate::refit::Axis,
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
    /// When the report was made (UTC, RFC 3339).
    pub generated: String,
}

/// Read what the report of survey `id` (the latest when `None`) shows.
pub async fn gather(store: &Store, id: Option<i64>, opts: &ReportOptions) -> anyhow::Result<ReportData> {
    let survey = store.resolve(id).await?;
    let stored = store.samples(survey.id).await?;
    if stored.is_empty() {
        return Err(bad_input(format!("survey {} holds no samples yet", survey.id)));
    }
    let refit = crate::refit::refit_survey(store, &survey).await?;
    let located = match &refit {
        Some(_) => None,
        None => crate::refit::located_axis_knowledge(store, &survey).await?,
    };
    let drift_points = store.drift_points(survey.id).await?;
    let (samples, refit) = match refit {
        Some((refitted, r)) => (refitted, Some(r)),
        None => (stored.clone(), None),
    };
    let axis = crate::refit::Axis::of(&survey, refit.as_ref());
    // Corrected for the drift when the survey asked for it, as `survey process` does.
    let analysed = crate::drift::for_analysis(&survey, samples.clone(), &drift_points);
    let verification = find_verification(store, &survey, &stored, &samples).await?;
    let process_opts = ProcessOptions {
        design: opts.design.clone(),
        recipe: opts.recipe.clone(),
        table_out: None,
        checks: crate::resolving::checks_of(store, &survey).await?,
        ..Default::default()
    };
    let processed = match crate::process::compute(&survey, &analysed, &process_opts) {
        Ok((p, _)) => Ok(p),
        Err(e) if e.downcast_ref::<PipelineError>().is_some() => Err(format!("{e:#}")),
        Err(e) => return Err(e),
    };
    let model_gap = match &opts.model {
        Some(path) => {
            let model = Model::from_file(path)?;
            // As `survey model-gap` compares it: around the refitted axis, told the reference.
            let reference = crate::refit::reference_info(&survey, refit.as_ref(), located.as_ref());
            let options = ModelGapOptions { reference, ..ModelGapOptions::default() };
            let gap = survey_processing::modelgap::model_gap(&samples, &model, &options).map_err(|e| {
                bad_input(format!("survey {} cannot be compared with the model {}: {e}", survey.id, path.display()))
            })?;
            Some((path.display().to_string(), gap))
        }
        None => None,
    };
    let inputs = crate::refit::uncertainty_inputs(&survey, refit.as_ref(), located.as_ref());
    let uncertainty = processed.as_ref().ok().map(|p| {
        let u = survey_processing::uncertainty::uncertainty(p, &analysed, &inputs);
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
    Ok(ReportData {
        survey,
        samples: analysed,
        axis,
        processed,
        verification,
        model_gap,
        drift: drift_points.iter().map(|p| (p.at_s, p.drift_deg)).collect(),
        uncertainty,
        generated: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
    })
}

/// The verification pair of `survey`: for a verification survey, the survey
/// it verifies; otherwise the latest verification of its table. The native
/// side is processed as the rest of the report is (around the refitted axis
/// of a tracker survey, `processed`); the corrected side as stored.
async fn find_verification(
    store: &Store,
    survey: &SurveyRecord,
    stored: &[Sample],
    processed: &[Sample],
) -> anyhow::Result<Option<Verification>> {
    let directional = |r: &SurveyRecord| {
        r.verification.as_ref().and_then(|v| v.correction.as_ref()).is_some_and(|t| t.is_directional())
    };
    if survey.source == SurveySource::Verification {
        let Some(of) = &survey.verification else { return Ok(None) };
        let native_record = store.survey(of.verifies_survey).await?;
        let native = match crate::refit::refit_survey(store, &native_record).await? {
            Some((refitted, _)) => refitted,
            None => store.samples(of.verifies_survey).await?,
        };
        if native.is_empty() {
            return Ok(None);
        }
        return Ok(Some(Verification {
            native_id: of.verifies_survey,
            native,
            verification_id: survey.id,
            corrected: stored.to_vec(),
            directional: directional(survey),
        }));
    }
    let all = store.list().await?;
    let latest = all
        .iter()
        .filter(|r| r.verification.as_ref().is_some_and(|v| v.verifies_survey == survey.id) && r.sample_count > 0)
        .max_by_key(|r| r.id);
    let Some(v) = latest else { return Ok(None) };
    Ok(Some(Verification {
        native_id: survey.id,
        native: processed.to_vec(),
        verification_id: v.id,
        corrected: store.samples(v.id).await?,
        directional: directional(v),
    }))
}

/// The summary: what a customer reads first.
fn summary(d: &ReportData, units: Units) -> String {
    let mut rows: Vec<Vec<String>> = Vec::new();
    if let Ok(iso) = iso230_2(&d.samples) {
        rows.push(vec!["ISO 230-2 accuracy A, as measured".into(), units.show(iso.a)]);
        rows.push(vec!["ISO 230-2 repeatability R".into(), units.show(iso.r)]);
        rows.push(vec!["the figures' axis".into(), escape(d.axis.text())]);
    }
    if let Ok(p) = &d.processed {
        rows.push(vec!["native peak error ±".into(), units.show(p.prediction.native_peak_deg)]);
        rows.push(vec![
            "corrected peak error ±, predicted from this survey".into(),
            units.show(p.prediction.corrected_peak_deg),
        ]);
        if let Some(floor) = p.floor.deg {
            rows.push(vec![format!("floor: {}", escape(&p.floor.what)), units.show(floor)]);
        }
        let u = d.uncertainty.as_ref().map(|b| b.table_u_deg);
        rows.extend(verification::verdict_rows(p, u, d.verification.as_ref(), d.survey.id, units));
    }
    if let Some(v) = &d.verification {
        let errors: Vec<f64> = v.corrected.iter().map(Sample::error_deg).collect();
        let peak = survey_processing::correction::ErrorFigures::of(&errors, None).peak_deg;
        rows.push(vec![format!("corrected peak error ±, measured (survey {})", v.verification_id), units.show(peak)]);
    }
    page::table("tbl-summary", &["figure", "value"], &rows)
}

/// The page of `d`.
pub fn html(d: &ReportData, opts: &ReportOptions) -> anyhow::Result<String> {
    let units = opts.units;
    let s = &d.survey;
    let cert = Certificate::of(s, &opts.flags);
    let name = cert.positioner_name(s);
    let title = match (&s.source, &s.verification) {
        (SurveySource::Verification, Some(v)) => {
            format!("{name}: verification (survey {}) of the table of survey {}", s.id, v.verifies_survey)
        }
        _ => format!("{name}: calibration survey {}", s.id),
    };
    let mut body = format!(
        "<h1>{}</h1>\n<p class=\"subtitle\">Readout error of the positioner, its sources, the correction table and \
         the accuracy figures of ISO 230-2 and VDI/DGQ 3441. Errors are readout − actual, in {}.</p>\n",
        escape(&title),
        units.symbol()
    );
    body +=
        &section("certificate", "Certificate", false, &header::render(s, &cert, d.samples.len(), units, &d.generated));
    body += &section("summary", "Summary", false, &summary(d, units));
    let map = ErrorMap::from_samples(&d.samples);
    let (errors_html, hysteresis_html) = match &map {
        Ok(m) => (errors::section(m, units)?, hysteresis::section(m, units)?),
        Err(e) => {
            let note = format!("<p class=\"note\">No error map: {}.</p>\n", escape(&e.to_string()));
            (note.clone(), note)
        }
    };
    body += &section("errors", "Error against angle", true, &errors_html);
    body += &section("hysteresis", "Hysteresis", true, &hysteresis_html);
    match &d.processed {
        Ok(p) => {
            body += &section("spectrum", "Spectrum and error sources", true, &spectrum::section(p, units)?);
            body += &section(
                "interpolation",
                "Interpolation between measured points",
                true,
                &interpolation::section(p, units)?,
            );
            body += &section("correction-table", "Correction table", true, &table::section(p, units)?);
        }
        Err(why) => {
            let note = format!("<p class=\"note\">The survey cannot be processed: {}.</p>\n", escape(why));
            body += &section("spectrum", "Spectrum, interpolation and correction table", true, &note);
        }
    }
    if let Some(v) = &d.verification {
        body += &section("verification", "Native and corrected accuracy", true, &verification::section(v, units)?);
    }
    if let Some((model, gap)) = &d.model_gap {
        body += &section("model-gap", "Model and measurement", true, &modelgap::section(gap, model, units)?);
    }
    if let Some(drift_html) = drift::section(&d.drift, units)? {
        body += &section("drift", "Drift over time", true, &drift_html);
    }
    if let Some(b) = &d.uncertainty {
        body += &section("uncertainty", "Uncertainty of the table", true, &uncertainty::section(b, units));
    }
    match iso230_2(&d.samples) {
        Ok(iso) => {
            body += &section("iso230", "ISO 230-2 and VDI/DGQ 3441", true, &iso::axis_section(&iso, units));
            body += &section("iso230-targets", "ISO 230-2 per target", true, &iso::targets_section(&iso, units));
        }
        Err(e) => {
            let note = format!("<p class=\"note\">No ISO 230-2 figures: {}.</p>\n", escape(&e.to_string()));
            body += &section("iso230", "ISO 230-2 and VDI/DGQ 3441", true, &note);
        }
    }
    if let Ok(p) = &d.processed
        && !p.notes.is_empty()
    {
        let items: String = p.notes.iter().map(|n| format!("<li>{}</li>", escape(n))).collect();
        body += &section("notes", "Processing notes", false, &format!("<ul class=\"note\">{items}</ul>\n"));
    }
    body += &format!(
        "<footer><p class=\"note\">survey {} — report made {}.</p></footer>\n",
        env!("CARGO_PKG_VERSION"),
        escape(&d.generated)
    );
    Ok(page::document(&title, &body))
}

/// Write `html` as `index.html` into the folder `out` (created if missing); returns the file's path.
pub fn write(out: &Path, html: &str) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(out).map_err(|e| path_error(e, format!("cannot create the folder {}", out.display())))?;
    let path = out.join("index.html");
    std::fs::write(&path, html).map_err(|e| path_error(e, format!("cannot write {}", path.display())))?;
    Ok(path)
}
