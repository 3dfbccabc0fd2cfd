//! The page: one module per section, in the order [`BODY`] and [`APPENDIX`]
//! list them. A section is a function of what every section shares
//! ([`Page`]: the gathered data, the options, the certificate's fields, the
//! error map and the ISO 230-2 figures, computed once); it returns `None`
//! when it has nothing to show (no verification, no drift data), and
//! otherwise always a body: a section that cannot show its figure says what
//! it cannot show and why. Adding a section is a module and one line in a
//! list.
//!
//! - [`header`]: the certificate's fields and where each comes from;
//! - [`summary`]: the figures a customer reads first, each with its
//!   uncertainty, and the verdict against a tolerance;
//! - [`errors`]: error against angle, every run and direction, ±2 s band;
//! - [`hysteresis`]: forward minus reverse against angle;
//! - [`spectrum`]: the spectrum with its lines named and the aliases moved;
//! - [`interpolation`]: the paper's Figure 6;
//! - [`table`]: the correction table;
//! - [`verification`]: native against corrected on one scale;
//! - [`motions`]: the axis's location and error motions (ISO 230-1, 230-7), a tracker's;
//! - [`modelgap`], [`drift`], [`environment`], [`uncertainty`]: when there is such data;
//! - [`history`]: the asset's earlier surveys, when it has any;
//! - [`iso`]: ISO 230-2 and VDI/DGQ 3441 for the axis; per target in the appendix.

pub mod drift;
pub mod environment;
pub mod errors;
pub mod header;
pub mod history;
pub mod hysteresis;
pub mod interpolation;
pub mod iso;
pub mod modelgap;
pub mod motions;
pub mod spectrum;
pub mod summary;
pub mod table;
pub mod uncertainty;
pub mod verification;

use crate::certificate::Issue;
use crate::certificate::{Certificate, REHEARSAL, Stated};
use crate::page::{self, escape};
use crate::units::Units;
use crate::{ReportData, ReportOptions};
use survey_processing::errormap::ErrorMap;
use survey_processing::iso230::{Iso230, iso230_2};
use survey_store::survey::SurveySource;
use survey_tables::pipeline::Processed;

/// What every section reads.
#[derive(Debug)]
pub struct Page<'a> {
    /// What was gathered.
    pub d: &'a ReportData,
    /// What was asked.
    pub opts: &'a ReportOptions,
    /// The unit of every error.
    pub units: Units,
    /// The certificate's fields, flags over the configuration over the bench.
    pub cert: Certificate,
    /// The error map of the survey's samples, or why there is none.
    pub map: Result<ErrorMap, String>,
    /// ISO 230-2 of the survey's samples, or why there are none.
    pub iso: Result<Iso230, String>,
}

impl Page<'_> {
    /// The processing, or `None` when the survey could not be processed.
    pub fn processed(&self) -> Option<&Processed> {
        self.d.processed.as_ref().ok()
    }
}

/// One section of the page.
#[derive(Debug)]
pub struct Section {
    /// Its id (the page's index and the tests find it by it).
    pub id: &'static str,
    /// Its heading.
    pub title: String,
    /// Whether it starts a printed page (one with neither a figure nor a
    /// table, a sentence or two, follows the section before it instead:
    /// [`Section::starts_a_page`]).
    pub new_page: bool,
    /// Its body, HTML.
    pub body: String,
}

impl Section {
    /// Whether it starts a printed page: asked to, and more than words (a
    /// figure or a table); a printed page never holds a heading and a
    /// sentence alone ("measured in one direction: no hysteresis").
    pub fn starts_a_page(&self) -> bool {
        self.new_page && (self.body.contains("<figure") || self.body.contains("<table"))
    }

    /// A section that starts a printed page.
    pub fn page(id: &'static str, title: impl Into<String>, body: String) -> Option<Section> {
        Some(Section { id, title: title.into(), new_page: true, body })
    }
}

/// A section of the page, from what every section reads.
pub type Show = fn(&Page<'_>) -> anyhow::Result<Option<Section>>;

/// The sections of the certificate, in order.
pub const BODY: &[Show] = &[
    header::show,
    summary::show,
    errors::show,
    hysteresis::show,
    spectrum::show,
    interpolation::show,
    table::show,
    verification::show,
    modelgap::show,
    drift::show,
    environment::show,
    uncertainty::show,
    history::show,
    iso::show_axis,
    motions::show,
    notes,
    end,
];

/// The appendices, after the body, lettered A, B, ... in this order.
pub const APPENDIX: &[Show] = &[iso::show_targets, header::show_sources];

/// A note in place of what a section cannot show.
pub fn note(text: &str) -> String {
    format!("<p class=\"note\">{}</p>\n", escape(text))
}

/// The processing's notes and its direction model, when there are any.
fn notes(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    let Some(processed) = p.processed() else { return Ok(None) };
    let direction = processed.built.direction_model.as_ref().map(|dm| dm.text());
    let notes: Vec<&String> = processed.notes.iter().chain(&direction).collect();
    if notes.is_empty() {
        return Ok(None);
    }
    let items: String = notes.iter().map(|n| format!("<li>{}</li>", escape(&p.units.text(n)))).collect();
    Ok(Some(Section {
        id: "notes",
        title: "Processing notes".into(),
        new_page: false,
        body: format!("<ul class=\"note\">{items}</ul>\n"),
    }))
}

/// The statements every certificate closes with, the authorisation and
/// its signature line, and the end of the certificate (what follows is
/// the appendix).
fn end(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    let signatory = p.cert.signatory.as_ref().map_or("<i>not stated</i>".to_string(), |s| escape(&s.value));
    let body = format!(
        "<ul class=\"statements\">\n\
         <li>The results relate only to the item calibrated, as it was when calibrated (ISO/IEC 17025:2017, \
         7.8.2.1).</li>\n\
         <li>{}</li>\n\
         <li>This certificate may not be reproduced other than in full without the written approval of the \
         calibrating laboratory.</li>\n</ul>\n\
         <table class=\"header\" id=\"tbl-authorisation\"><tbody>\n\
         <tr><td>Authorised by (name, function)</td><td>{signatory}</td></tr>\n\
         <tr><td>Signature</td><td><span class=\"signature\"></span></td></tr>\n\
         <tr><td>Date</td><td><span class=\"signature\"></span></td></tr>\n\
         </tbody></table>\n<p class=\"end\" id=\"end-of-certificate\">End of the certificate{}</p>\n",
        escape(crate::rounding::COVERAGE),
        if APPENDIX.is_empty() { "" } else { " (the appendix that follows is its supporting data)" },
    );
    Ok(Some(Section { id: "authorisation", title: "Statements and authorisation".into(), new_page: false, body }))
}

/// Under the number: what this certificate replaces and why (an
/// amendment), or that the page is a draft and why.
fn issue_note(issue: &Issue) -> String {
    match issue {
        Issue::Issued { replaces: Some(r), .. } => format!(
            "<p class=\"verdict\" id=\"amendment\">This certificate replaces certificate <b>{}</b> issued {}, \
             which is withdrawn. Reason: {}</p>\n",
            escape(&r.number),
            escape(&r.issued_at),
            escape(&r.reason)
        ),
        Issue::Issued { .. } => String::new(),
        Issue::Draft(why) => {
            format!("<p class=\"verdict fail\" id=\"draft\"><b>Draft, not issued</b>: {}.</p>\n", escape(why))
        }
    }
}

/// The title of the page.
fn title(p: &Page<'_>) -> String {
    let s = &p.d.survey;
    let name = p.cert.positioner_name(s);
    match (&s.source, &s.verification, &p.cert.rehearsal) {
        (SurveySource::Verification, Some(v), None) => {
            format!("{name}: verification (survey {}) of the table of survey {}", s.id, v.verifies_survey)
        }
        (SurveySource::Verification, Some(v), Some(_)) => {
            format!(
                "{name}: verification (survey {}) of the table of survey {}, a {REHEARSAL}",
                s.id, v.verifies_survey
            )
        }
        (_, _, None) => format!("{name}: calibration survey {}", s.id),
        (_, _, Some(_)) => format!("{name}: {REHEARSAL} (survey {})", s.id),
    }
}

/// A rehearsal's banner under the number (its running foot says it on every printed page).
fn rehearsal_note(p: &Page<'_>) -> String {
    p.cert.rehearsal.as_ref().map_or(String::new(), |why| {
        format!(
            "<p class=\"verdict fail\" id=\"rehearsal\"><b>Rehearsal on simulated instruments, not a \
             calibration</b>: {}. Its figures show the method and this program at work; they certify no instrument \
             and are traceable to nothing.</p>\n",
            escape(why)
        )
    })
}

/// What every section (and the DCC) reads, of `d`.
pub fn page<'a>(d: &'a ReportData, opts: &'a ReportOptions) -> Page<'a> {
    let mut cert = Certificate::of(&d.survey, &opts.flags);
    cert.number = match &d.issue {
        Issue::Issued { number, .. } => Stated { value: number.clone(), from: cert.number.from },
        // A draft's number says what it is, on every page and in the DCC.
        Issue::Draft(_) => Stated { value: format!("DRAFT-{}", cert.number.value), from: cert.number.from },
    };
    Page {
        d,
        opts,
        units: opts.units,
        cert,
        map: ErrorMap::from_samples(&d.samples).map_err(|e| e.to_string()),
        iso: iso230_2(&d.samples).map_err(|e| e.to_string()),
    }
}

/// The page of `d`.
pub fn render(d: &ReportData, opts: &ReportOptions) -> anyhow::Result<String> {
    let p = page(d, opts);
    let title = title(&p);
    let number = &p.cert.number.value;
    let laboratory = p.cert.laboratory.as_ref().map(|l| l.value.clone()).unwrap_or_default();
    let origin = if laboratory.is_empty() { String::new() } else { format!(" · {}", escape(&laboratory)) };
    let kind = if p.cert.rehearsal.is_some() {
        "Rehearsal, not a calibration: certificate"
    } else {
        "Calibration certificate"
    };
    let mut body = format!(
        "<p class=\"subtitle\" id=\"certificate-number\">{} <b>{}</b>{}</p>\n{}{}<h1>{}</h1>\n\
         <p class=\"subtitle\">Readout error of the positioner, its sources, the correction table and the accuracy \
         figures of ISO 230-2 and VDI/DGQ 3441. Errors are readout − actual, in {}.</p>\n",
        kind,
        escape(number),
        origin,
        rehearsal_note(&p),
        issue_note(&d.issue),
        escape(&title),
        p.units.symbol()
    );
    for show in BODY {
        if let Some(s) = show(&p)? {
            body += &page::section(s.id, &s.title, if s.starts_a_page() { &["page"] } else { &[] }, &s.body);
        }
    }
    // The appendix: always in the page, folded; printed only when asked for (`--appendix`).
    let (classes, open): (&[&str], &str) =
        if opts.appendix { (&["page", "appendix"], " open") } else { (&["appendix", "screen-only"], "") };
    for (letter, s) in ('A'..='Z').zip(APPENDIX.iter().map(|show| show(&p)).filter_map(Result::transpose)) {
        let s = s?;
        let folded = format!("<details{open}><summary>the table (open to read it)</summary>\n{}</details>\n", s.body);
        body += &page::section(s.id, &format!("Appendix {letter}: {}", s.title), classes, &folded);
    }
    body += &format!(
        "<footer class=\"screen-only\"><p class=\"note\">survey {} — report made {}.</p></footer>\n",
        env!("CARGO_PKG_VERSION"),
        escape(&d.generated)
    );
    let running = page::Running {
        top_left: format!("{kind} {number}"),
        top_right: laboratory,
        bottom_left: match &p.cert.rehearsal {
            None => format!("{}: survey {}", p.cert.positioner_name(&d.survey), d.survey.id),
            Some(_) => format!("{}: survey {}", REHEARSAL.to_uppercase(), d.survey.id),
        },
    };
    Ok(page::document(&title, &running, &body))
}
