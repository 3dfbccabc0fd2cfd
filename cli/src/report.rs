//! `survey report --out DIR`: the survey's report as one HTML page, and the
//! certificate as a DCC (`DIR/dcc.xml`).

use super::args::UnitsArg;
use super::support::{emit, open_read_only};
use clap::Args;
use std::path::{Path, PathBuf};
use survey_processing::num::Num;
use survey_report::ReportOptions;
use survey_report::certificate::CertificateFlags;

#[derive(Debug, Args)]
pub struct ReportArgs {
    /// Survey id or uid (default: the latest).
    #[arg(long, value_name = "ID", allow_negative_numbers = true)]
    pub survey: Option<survey_store::survey::SurveyRef>,
    /// The folder to write index.html into (created if missing).
    #[arg(long, value_name = "DIR", value_hint = clap::ValueHint::DirPath)]
    pub out: PathBuf,
    #[command(flatten)]
    pub units: UnitsArg,
    /// Positioner model file (TOML) whose [design] names the lines [default: the survey's stored model].
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath)]
    pub design: Option<PathBuf>,
    /// Replay this processing recipe (TOML), as `survey process --recipe` did.
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath)]
    pub recipe: Option<PathBuf>,
    /// Compare the survey with this positioner model (model-gap) and show the steps.
    #[arg(long, value_name = "FILE", value_hint = clap::ValueHint::FilePath)]
    pub model: Option<PathBuf>,
    /// The positioner calibrated (make, model, serial) [default: [certificate] of the configuration, or the bench].
    #[arg(long, value_name = "TEXT")]
    pub positioner: Option<String>,
    /// The reference instrument (make, model, serial) [default: [certificate], or the bench].
    #[arg(long, value_name = "TEXT")]
    pub reference_instrument: Option<String>,
    /// The reference's stated standard uncertainty of one angle, degrees [default: [certificate], or the simulated instrument's noise].
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub reference_uncertainty: Option<f64>,
    /// Who measured [default: [certificate] of the configuration].
    #[arg(long, value_name = "NAME")]
    pub operator: Option<String>,
    /// For whom [default: [certificate] of the configuration].
    #[arg(long, value_name = "NAME")]
    pub customer: Option<String>,
    /// The air temperature during the survey, degrees Celsius [default: [certificate] of the configuration].
    #[arg(long, value_name = "C", allow_negative_numbers = true)]
    pub temperature: Option<f64>,
    /// The certificate's number [default: [certificate] number, or made from the survey's date and id].
    #[arg(long, value_name = "TEXT")]
    pub certificate_number: Option<String>,
    /// The calibrating laboratory: name, address, accreditation [default: [certificate] laboratory].
    #[arg(long, value_name = "TEXT")]
    pub laboratory: Option<String>,
    /// The traceability statement: the reference's calibration, by whom, certificate, date [default: [certificate] traceability].
    #[arg(long, value_name = "TEXT")]
    pub traceability: Option<String>,
    /// Judge the ISO 230-2 accuracy A against this tolerance, degrees: pass, fail or not decidable within the uncertainty [default: [certificate] tolerance_deg].
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub tolerance: Option<f64>,
    /// Who authorises the certificate: name and function [default: [certificate] signatory].
    #[arg(long, value_name = "TEXT")]
    pub signatory: Option<String>,
    /// Where the calibration was performed [default: [certificate] location].
    #[arg(long, value_name = "TEXT")]
    pub location: Option<String>,
    /// The item's condition when received [default: [certificate] item_condition].
    #[arg(long, value_name = "TEXT")]
    pub item_condition: Option<String>,
    /// The date the item was received, YYYY-MM-DD [default: [certificate] received].
    #[arg(long, value_name = "DATE")]
    pub received: Option<String>,
    /// The laboratory's country, ISO 3166-1 alpha-2 (DE, GB) [default: [certificate] country].
    #[arg(long, value_name = "CODE")]
    pub country: Option<String>,
    /// Print the appendix (every target's figures) too; the HTML page always holds it, folded.
    #[arg(long)]
    pub appendix: bool,
    /// Print the page to DIR/index.pdf with Chromium, headless (SURVEY_CHROMIUM names the browser; else chromium on PATH).
    #[arg(long)]
    pub pdf: bool,
}

pub async fn report(db: &Path, args: ReportArgs) -> anyhow::Result<()> {
    if let Some(t) = args.temperature
        && !(t.is_finite() && (-50.0..=100.0).contains(&t))
    {
        return Err(survey_lab::error::bad_input(format!("--temperature {}: outside -50 to 100 °C", Num(t))));
    }
    if let Some(u) = args.reference_uncertainty
        && !(u.is_finite() && u > 0.0 && u <= 1.0)
    {
        return Err(survey_lab::error::bad_input(format!(
            "--reference-uncertainty {}: must be above 0 and at most 1 deg",
            Num(u)
        )));
    }
    if let Some(t) = args.tolerance
        && !(t.is_finite() && t > 0.0 && t <= 360.0)
    {
        return Err(survey_lab::error::bad_input(format!(
            "--tolerance {}: must be above 0 and at most 360 deg",
            Num(t)
        )));
    }
    for (flag, text) in [
        ("--certificate-number", &args.certificate_number),
        ("--laboratory", &args.laboratory),
        ("--traceability", &args.traceability),
        ("--signatory", &args.signatory),
        ("--location", &args.location),
        ("--item-condition", &args.item_condition),
    ] {
        if text.as_ref().is_some_and(|t| t.trim().is_empty()) {
            return Err(survey_lab::error::bad_input(format!("{flag}: empty")));
        }
    }
    if let Some(d) = &args.received {
        survey_store::config::check_date(d)
            .map_err(|e| survey_lab::error::bad_input(format!("--received {d}: {d} is {e}")))?;
    }
    if let Some(c) = &args.country {
        survey_store::config::check_country(c)
            .map_err(|e| survey_lab::error::bad_input(format!("--country {c}: {e}")))?;
    }
    // Checked before anything is written.
    let pdf_bound = if args.pdf { Some(survey_report::pdf::timeout()?) } else { None };
    let opts = ReportOptions {
        units: args.units.units(),
        flags: CertificateFlags {
            positioner: args.positioner,
            reference: args.reference_instrument,
            reference_uncertainty_deg: args.reference_uncertainty,
            operator: args.operator,
            customer: args.customer,
            temperature_c: args.temperature,
            number: args.certificate_number,
            laboratory: args.laboratory,
            traceability: args.traceability,
            tolerance_deg: args.tolerance,
            signatory: args.signatory,
            location: args.location,
            item_condition: args.item_condition,
            received: args.received,
            country: args.country,
            // The tracker's MPE is the survey's (its U at every command), not the report's to change.
            reference_mpe_um: None,
            reference_mpe_um_per_m: None,
        },
        design: args.design,
        recipe: args.recipe,
        model: args.model,
        quiet: false,
        appendix: args.appendix,
    };
    let progress = crate::progress::Progress::spinner("writing the report", crate::progress::visible(false));
    let store = open_read_only(db).await?;
    let data = survey_report::gather(&store, args.survey, &opts).await;
    store.close().await;
    let data = data?;
    let html = survey_report::html::render(&data, &opts)?;
    let dcc = survey_report::dcc::document(&survey_report::html::page(&data, &opts))?;
    let path = survey_report::write(&args.out, &html, &dcc)?;
    let printed = match pdf_bound {
        Some(bound) => {
            let pdf = path.with_extension("pdf");
            let pages = survey_report::pdf::print(&path, &pdf, bound).await?;
            format!("{} ({pages} pages)\n", pdf.display())
        }
        None => String::new(),
    };
    drop(progress);
    // Every file written: the page, the DCC beside it, the PDF.
    let dcc = path.with_file_name("dcc.xml");
    emit(&format!("{}\n{}\n{printed}", path.display(), dcc.display()));
    Ok(())
}
