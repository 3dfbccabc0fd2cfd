//! A certificate is issued once (ISO/IEC 17025 7.8): the first `survey
//! report` of a complete survey issues it (its number, its issue date, the
//! page and the DCC as written) and the store keeps it; every later report
//! writes it again from the store, byte for byte, and refuses a flag that
//! would change what it states. `--amend "reason"` issues a new certificate
//! of the survey with its own number, which names the one it replaces, when
//! it was issued and why (7.8.8); the replaced one stays stored.
//!
//! The number: the one the laboratory assigns (`--certificate-number`, or
//! `[certificate] number`), refused when the store issued it before; else
//! made from the survey, `YYYYMMDD-` and the first 12 hexadecimal digits of
//! its uid (a UUID drawn at random when the survey was made, which stays
//! with it on every copy and in the lab store): two stations, or two
//! databases of one station, draw the same number only if they draw the same
//! 48 random bits on the same day (for 1000 certificates issued in a lab on
//! one day, a chance of 2e-9). An amendment's number is the first's with
//! `-A1`, `-A2`, ... unless one is given.
//!
//! A survey that is not complete (acquiring, interrupted, failed), or one
//! read from a store where nothing can be issued (the lab store, which
//! `survey push` alone writes; a file of an older schema read as it is), gets
//! a draft: the same page, marked "draft, not issued" and why, stored nowhere.

use crate::certificate::{Issue, Replaced};
use crate::{ReportData, ReportOptions};
use std::path::Path;
use survey_lab::error::bad_input;
use survey_store::survey::{SurveyRecord, SurveyRef, SurveyStatus};
use survey_store::{Issued, Store};

/// What `survey report` wrote: the certificate (issued now or before), or a draft.
#[derive(Debug)]
pub enum Written {
    /// Issued by this report.
    IssuedNow(Issued),
    /// Issued before: written again from the store.
    Reproduced(Issued),
    /// Not issued: the page and the DCC, and why.
    Draft { page: String, dcc: String, why: String },
}

/// Why survey `s` in `store` can get no certificate, if it cannot
/// (`writer`: the station's file to keep it in, when there is one).
fn not_issuable(store: &Store, s: &SurveyRecord, writer: Option<&Path>) -> Option<String> {
    if s.status != SurveyStatus::Complete {
        Some(format!("survey {} is {}: a certificate is issued for a complete survey", s.id, s.status))
    } else if writer.is_none() {
        Some(format!(
            "{} is only read here: a certificate is issued by `survey report` on the station's file (then pushed)",
            store.path().display()
        ))
    } else {
        None
    }
}

/// `survey report` of survey `r` (the latest when `None`): the certificate
/// issued before, or issued now, or a draft. `store` is read (opened
/// read-only: a report computes what it shows as a reader does, and writes
/// no cache); a certificate issued now is kept in `writer`, the station's
/// file opened to write for that alone (`None`: nothing can be issued, a
/// draft). `changes` names the flags given that would change what a
/// certificate states (refused once it is issued, but with `amend`).
pub async fn report(
    store: &Store,
    writer: Option<&Path>,
    r: Option<SurveyRef>,
    opts: &ReportOptions,
    amend: Option<&str>,
    changes: &[&str],
) -> anyhow::Result<Written> {
    let survey = store.resolve(r).await?;
    let survey = store.shown(survey).await?;
    let issued = store.certificates(survey.id).await?;
    let latest = issued.last();
    match (latest, amend) {
        (Some(c), None) => {
            let changes = with_presentation(changes, c, opts);
            if !changes.is_empty() {
                return Err(bad_input(format!(
                    "survey {}'s certificate {} was issued {}: what it states is fixed, and {} would change it; \
                     `survey report --amend \"reason\"` issues a new certificate that replaces it",
                    survey.id,
                    c.number,
                    c.issued_at,
                    changes.join(", ")
                )));
            }
            return Ok(Written::Reproduced(c.clone()));
        }
        (None, Some(_)) => {
            return Err(bad_input(format!(
                "--amend: survey {} has no certificate issued to amend; `survey report` without --amend issues it",
                survey.id
            )));
        }
        _ => {}
    }
    let mut data = crate::gather(store, Some(SurveyRef::Id(survey.id)), opts).await?;
    if let Some(why) = not_issuable(store, &survey, writer) {
        if amend.is_some() {
            return Err(bad_input(format!("--amend: {why}")));
        }
        data.issue = Issue::Draft(why.clone());
        let (page, dcc) = render(&data, opts)?;
        return Ok(Written::Draft { page, dcc, why });
    }
    let seq = issued.len() as i64 + 1;
    let assigned = crate::certificate::Certificate::of(&survey, &opts.flags).number;
    let number = match (latest, amend) {
        (None, _) => assigned.value,
        (Some(_), _) if opts.flags.number.is_some() => assigned.value,
        (Some(_), _) => format!("{}-A{}", issued[0].number, seq - 1),
    };
    if let Some(other) = store.certificate_number_issued(&number).await? {
        return Err(bad_input(format!(
            "certificate number {number} is issued already (to survey {other}): a number is issued once; give \
             another with --certificate-number"
        )));
    }
    let replaces = match (latest, amend) {
        (Some(c), Some(reason)) => Some(Replaced {
            number: c.number.clone(),
            issued_at: c.issued_at.clone(),
            reason: reason.to_string(),
            dcc_sha256: sha256_hex(c.dcc.as_bytes()),
        }),
        _ => None,
    };
    data.issue = Issue::Issued { number: number.clone(), issued_at: data.generated.clone(), seq, replaces };
    let (page, dcc) = render(&data, opts)?;
    let c = Issued {
        number,
        survey_id: survey.id,
        seq,
        issued_at: data.generated.clone(),
        replaces: latest.map(|c| c.number.clone()),
        reason: amend.map(str::to_string),
        page,
        dcc,
    };
    if let Some(path) = writer {
        let kept = Store::open_existing(path).await?;
        let issued = kept.issue(&c).await;
        kept.close().await;
        issued?;
    }
    Ok(Written::IssuedNow(c))
}

/// `changes` and what of the presentation asked for differs from the
/// certificate `c` as issued: its unit (`--units`, or `SURVEY_UNITS`), its
/// appendix printed (`--appendix`). Asking for what it was issued with is no change.
fn with_presentation<'a>(changes: &[&'a str], c: &Issued, opts: &ReportOptions) -> Vec<&'a str> {
    let mut all = changes.to_vec();
    if !c.page.contains(&format!("Errors are readout − actual, in {}.", opts.units.symbol())) {
        all.push("--units (or SURVEY_UNITS)");
    }
    if opts.appendix && !c.page.contains("<details open>") {
        all.push("--appendix");
    }
    all
}

/// The page and the DCC of `data`.
pub fn render(data: &ReportData, opts: &ReportOptions) -> anyhow::Result<(String, String)> {
    let page = crate::html::render(data, opts)?;
    let dcc = crate::dcc::document(&crate::html::page(data, opts))?;
    Ok((page, dcc))
}

/// SHA-256 of `bytes`, lower-case hexadecimal.
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest as _;
    sha2::Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_digest_is_sha_256() {
        assert_eq!(sha256_hex(b"abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    }
}
