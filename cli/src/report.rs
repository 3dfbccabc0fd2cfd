//! `survey report --out DIR`: the survey's report as one HTML page, and the
//! certificate as a DCC (`DIR/dcc.xml`).

use super::args::UnitsArg;
use super::support::{emit, open_read_only};
use clap::Args;
use std::path::{Path, PathBuf};
use survey_processing::num::Num;
use survey_report::ReportOptions;
use survey_report::certificate::CertificateFlags;
use survey_report::issue::Written;

#[derive(Debug, Args)]
pub struct ReportArgs {
    /// Survey id or uid (default: the latest).
    #[arg(long, value_name = "ID", allow_negative_numbers = true)]
    pub survey: Option<survey_store::survey::SurveyRef>,
    /// The folder to write into (created if missing): index.html, the page; dcc.xml, the certificate as a DCC; index.pdf with --pdf.
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
    /// The certificate's number [default: [certificate] number, or made from the survey's date and uid].
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
    /// Issue a new certificate of the survey that replaces the one issued, saying why (ISO/IEC 17025 7.8.8): its own number (the first's with -A1, -A2, ... unless --certificate-number), the fields and flags given now.
    #[arg(long, value_name = "REASON")]
    pub amend: Option<String>,
    /// Print the page to DIR/index.pdf with Chromium, headless (SURVEY_CHROMIUM names the browser; else chromium on PATH).
    #[arg(long)]
    pub pdf: bool,
    /// Draw the number of the certificate issued now from the lab store's sequence (postgres://...): YYYY-NNNNN, one sequence for every station of the lab (SURVEY_LAB, as push reads it: where nothing is issued now, no number is drawn and the certificate issued is written again).
    #[arg(long, value_name = "URL", env = "SURVEY_LAB", hide_env_values = true)]
    pub lab: Option<String>,
    /// Whether `lab` came from the environment's SURVEY_LAB, not the flag
    /// (set by `crate::main` from clap's value source).
    #[arg(skip)]
    pub lab_from_env: bool,
}

/// Every text flag printed on the certificate: not empty, one line without
/// control characters, within what a field holds (as the configuration's
/// `[certificate]` keys).
fn check_texts(args: &ReportArgs) -> anyhow::Result<()> {
    use survey_store::config::{check_field, check_number};
    let number = ("--certificate-number", &args.certificate_number, check_number as fn(&str) -> Result<(), String>);
    let fields = [
        ("--positioner", &args.positioner),
        ("--reference-instrument", &args.reference_instrument),
        ("--operator", &args.operator),
        ("--customer", &args.customer),
        ("--laboratory", &args.laboratory),
        ("--traceability", &args.traceability),
        ("--signatory", &args.signatory),
        ("--location", &args.location),
        ("--item-condition", &args.item_condition),
    ];
    let fields = fields.into_iter().chain([("--amend", &args.amend)]);
    let all = std::iter::once(number).chain(fields.map(|(f, t)| (f, t, check_field as fn(&str) -> _)));
    for (flag, text, check) in all {
        if let Some(t) = text
            && let Err(why) = check(t)
        {
            return Err(survey_lab::error::bad_input(format!("{flag} {}: {why}", shown(t))));
        }
    }
    Ok(())
}

/// A flag's text as a message quotes it: escaped (a control character as
/// `\u{7}`), cut at 40 characters.
fn shown(text: &str) -> String {
    let cut: String = text.chars().take(40).collect();
    let more = if text.chars().count() > 40 { "..." } else { "" };
    format!("{:?}{more}", cut)
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
    check_texts(&args)?;
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
    let lab = LabNumber {
        url: args.lab.clone(),
        from_env: args.lab_from_env,
        survey: args.survey.clone(),
        number_given: args.certificate_number.is_some(),
        amend: args.amend.is_some(),
    };
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
            // Whose premises: the configuration's, else read from the location's words.
            performance_location: None,
            item_condition: args.item_condition,
            received: args.received,
            country: args.country,
            // The tracker's MPE is the survey's (its U at every command), not the report's to change.
            reference_mpe_um: None,
            reference_mpe_um_per_m: None,
            // Addresses and identifications are the configuration's (a table has no flag).
            laboratory_address: None,
            customer_address: None,
            item: None,
            reference_instrument: None,
        },
        design: args.design,
        recipe: args.recipe,
        model: args.model,
        quiet: false,
        appendix: args.appendix,
    };
    let changes = changes(&opts);
    // Where the files go, checked before a certificate is issued (an issued one is never left unwritten by a
    // folder that cannot be).
    check_out(&args.out)?;
    let progress = crate::progress::Progress::spinner("writing the report", crate::progress::visible(false));
    // Read as every reader does; a certificate issued is kept in the station's file, opened to write for that
    // alone. A file this process cannot write (read-only media, another's) and the lab store give a draft.
    let writable = std::fs::OpenOptions::new().write(true).open(db).is_ok();
    let writer = (writable && survey_store::lab::url_of(db).is_none()).then_some(db);
    let store = open_read_only(db).await?;
    let amend = args.amend.as_deref();
    let mut opts = opts;
    if let Some(url) = &lab.url {
        match draw_number(&store, url, writer.is_some(), &lab).await {
            Ok(Some((number, from))) => {
                eprintln!("certificate number {number} drawn from the lab store {from}");
                opts.flags.number = Some(number);
            }
            Ok(None) => {}
            Err(e) => {
                store.close().await;
                return Err(e);
            }
        }
    }
    let written = survey_report::issue::report(&store, writer, args.survey, &opts, amend, &changes).await;
    store.close().await;
    let (html, dcc, said) = match written? {
        Written::IssuedNow(c) => {
            let what = if c.replaces.is_some() { "issued (an amendment)" } else { "issued" };
            (c.page, c.dcc, format!("certificate {} of survey {} {what} {}", c.number, c.survey_id, c.issued_at))
        }
        Written::Reproduced(c) => (
            c.page,
            c.dcc,
            format!("certificate {} as issued {} (written again from the store)", c.number, c.issued_at),
        ),
        Written::Draft { page, dcc, why } => (page, dcc, format!("a draft, not issued: {why}")),
    };
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
    eprintln!("{said}");
    // Every file written: the page, the DCC beside it, the PDF.
    let dcc = path.with_file_name("dcc.xml");
    emit(&format!("{}\n{}\n{printed}", path.display(), dcc.display()));
    Ok(())
}

/// `--lab URL` (or `SURVEY_LAB`): the number of the certificate this report
/// issues, drawn from the lab store's sequence (`YYYY-NNNNN`, the year's
/// count across every station), and the store as it may be named. Where no
/// certificate is issued now ([`nothing_issued`]) nothing is drawn: the
/// flag is refused (bad input), the environment's URL left unused (`None`:
/// the report goes on, a certificate issued is written again), either said.
async fn draw_number(
    store: &survey_store::Store,
    url: &str,
    issues: bool,
    args: &LabNumber,
) -> anyhow::Result<Option<(String, String)>> {
    use survey_lab::error::bad_input;
    let name = if args.from_env { "SURVEY_LAB" } else { "--lab" };
    if survey_store::lab::url_of(Path::new(url)).is_none() {
        // Shown as given unless it may hold a password (user:password@).
        let given = if url.contains('@') { "(a URL with credentials)" } else { url };
        return Err(bad_input(format!("{name} {given}: not a lab store (a postgres:// URL); no number was drawn")));
    }
    let shown = survey_store::lab::redacted(url);
    if let Some(why) = nothing_issued(store, issues, args).await? {
        if args.from_env {
            eprintln!("{name} {shown}: no number drawn: {why}");
            return Ok(None);
        }
        return Err(bad_input(format!("{name} {shown}: {why}; no number was drawn")));
    }
    let year: i32 = humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string()[..4].parse()?;
    let lab = survey_store::lab::open(url, true).await?;
    let n = lab.draw_certificate_number(year).await;
    lab.close().await;
    Ok(Some((format!("{year}-{:05}", n?), shown)))
}

/// Why this report issues no certificate that a lab's number could go to,
/// if it issues none: a number given otherwise (the flag, the
/// configuration's `[certificate] number`), a file only read here, a survey
/// not complete, one issued before (but with `--amend`).
async fn nothing_issued(store: &survey_store::Store, issues: bool, args: &LabNumber) -> anyhow::Result<Option<String>> {
    if args.number_given {
        return Ok(Some("--certificate-number gives the number: give one of the two".into()));
    }
    if !issues {
        return Ok(Some(format!(
            "{} is only read here: a certificate is issued on the station's file",
            store.path().display()
        )));
    }
    let survey = store.resolve(args.survey.clone()).await?;
    if survey.status != survey_store::survey::SurveyStatus::Complete {
        return Ok(Some(format!(
            "survey {} is {}: a certificate is issued for a complete survey",
            survey.id, survey.status
        )));
    }
    if let Some(c) = store.certificates(survey.id).await?.last()
        && !args.amend
    {
        return Ok(Some(format!(
            "certificate {} of survey {} was issued: a number is drawn only for one issued now (--amend)",
            c.number, survey.id
        )));
    }
    if let survey_store::survey::Setup::Configured(c) = &survey.setup
        && let Some(n) = c.config.certificate.as_ref().and_then(|c| c.number.as_ref())
    {
        return Ok(Some(format!("the survey's [certificate] number states its number ({n})")));
    }
    Ok(None)
}

/// What `--lab` needs of the flags.
struct LabNumber {
    url: Option<String>,
    /// The URL is the environment's `SURVEY_LAB`, not the flag's.
    from_env: bool,
    survey: Option<survey_store::survey::SurveyRef>,
    number_given: bool,
    amend: bool,
}

/// `out` is a folder, or can be made: the nearest part of it that exists is a folder.
fn check_out(out: &Path) -> anyhow::Result<()> {
    let existing = out.ancestors().find(|a| !a.as_os_str().is_empty() && a.exists()).unwrap_or(Path::new("."));
    if existing.is_dir() {
        Ok(())
    } else {
        Err(survey_lab::error::bad_input(format!(
            "--out {}: {} is not a folder: the report's files cannot be written there",
            out.display(),
            existing.display()
        )))
    }
}

/// The flags given that would change what a certificate states (refused
/// once it is issued, but with `--amend`; `--units` and `--appendix` only
/// when they differ from the certificate as issued: `survey_report::issue`).
fn changes(opts: &ReportOptions) -> Vec<&'static str> {
    let f = &opts.flags;
    let given = [
        ("--positioner", f.positioner.is_some()),
        ("--reference-instrument", f.reference.is_some()),
        ("--reference-uncertainty", f.reference_uncertainty_deg.is_some()),
        ("--operator", f.operator.is_some()),
        ("--customer", f.customer.is_some()),
        ("--temperature", f.temperature_c.is_some()),
        ("--certificate-number", f.number.is_some()),
        ("--laboratory", f.laboratory.is_some()),
        ("--traceability", f.traceability.is_some()),
        ("--tolerance", f.tolerance_deg.is_some()),
        ("--signatory", f.signatory.is_some()),
        ("--location", f.location.is_some()),
        ("--item-condition", f.item_condition.is_some()),
        ("--received", f.received.is_some()),
        ("--country", f.country.is_some()),
        ("--design", opts.design.is_some()),
        ("--recipe", opts.recipe.is_some()),
        ("--model", opts.model.is_some()),
    ];
    given.into_iter().filter(|(_, g)| *g).map(|(flag, _)| flag).collect()
}
