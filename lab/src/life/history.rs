//! An asset's history (`survey history`, and the report's section): its
//! surveys in the order they were made, each with its ISO 230-2 `A`, `R`,
//! `B`, its table's `U` and main lines, a check survey with what it decided;
//! and what changed from each complete survey to the next (calibrations and
//! checks: the native measurements; a verification is measured with a table
//! applied, so it is listed but not compared).

use super::cache::{Change, Pair, Summary, made};
use serde_json::{Value, json};
use std::fmt::Write as _;
use survey_store::survey::SurveyRecord;
use survey_store::{CheckDecision, NotFound, Store};

/// One survey of a history: its record and its summary.
#[derive(Debug, Clone)]
pub struct Entry {
    /// The survey.
    pub survey: SurveyRecord,
    /// What measuring it gives (read from the history's cache, or measured).
    pub summary: Summary,
}

impl Entry {
    /// `calibration`, `check` or `verification`.
    pub fn kind(&self) -> &'static str {
        super::kind(&self.survey)
    }

    /// The history's entry of this survey (the contract's keys and more).
    pub fn json(&self) -> Value {
        let (s, m) = (&self.survey, &self.summary);
        json!({
            "id": s.id,
            "uid": s.uid,
            "created_at": s.created_at,
            "status": s.status.as_str(),
            "kind": self.kind(),
            "check_of": s.check_of,
            "samples": m.samples,
            "A_deg": m.iso.as_ref().map(|i| i.a),
            "R_deg": m.iso.as_ref().map(|i| i.r),
            "B_deg": m.iso.as_ref().and_then(|i| i.b),
            "table_u_deg": m.table_u_deg,
            "lines": m.lines,
            "error_motions": m.motions.as_ref().map(|t| t.json()),
        })
    }
}

/// An asset's history.
#[derive(Debug)]
pub struct History {
    /// The asset.
    pub asset: String,
    /// Its surveys, oldest first.
    pub surveys: Vec<Entry>,
    /// What changed from one complete survey to the next: indices into
    /// `surveys` and the change.
    pub changes: Vec<(usize, usize, Change)>,
    /// Pairs that could not be compared, and why.
    pub not_compared: Vec<String>,
    /// What the check surveys decided.
    pub checks: Vec<CheckDecision>,
    /// Read from the lab store: a check's table file is a path on the
    /// station that made it, not shown as one here.
    pub in_lab_store: bool,
}

/// The history of `asset` in `store`, up to and including survey `up_to`
/// when given (a report shows what was known when its survey was made):
/// read from the history's cache, what it lacks measured
/// ([`super::cache`]).
pub async fn history(store: &Store, asset: &str, up_to: Option<i64>) -> anyhow::Result<History> {
    let records = store.surveys_of_asset_uncounted(asset).await?;
    let last = up_to.and_then(|id| records.iter().position(|r| r.id == id));
    let mut records = records;
    records.truncate(last.map_or(records.len(), |i| i + 1));
    if records.is_empty() {
        return Err(NotFound(format!("no survey of the asset {asset} in {}", store.path().display())).into());
    }
    let made = made(store, &records).await?;
    let (mut changes, mut not_compared) = (Vec::new(), Vec::new());
    for (a, b, pair) in made.pairs {
        match pair {
            Ok(Pair::Compared(c)) => changes.push((a, b, c)),
            Ok(Pair::NotComparable(why)) => not_compared.push(Pair::not_compared(&why, &records[a], &records[b])),
            Err(message) => not_compared.push(message),
        }
    }
    let surveys = records.into_iter().zip(made.summaries).map(|(survey, summary)| Entry { survey, summary }).collect();
    let checks = store.checks_of_asset(asset).await?;
    let in_lab_store = survey_store::lab::url_of(store.path()).is_some();
    Ok(History { asset: asset.to_string(), surveys, changes, not_compared, checks, in_lab_store })
}

/// A check's point of the control chart, in words.
fn control_text(p: &super::control::Point) -> String {
    match (p.statistic, p.centre, p.lower(), p.upper()) {
        (None, ..) => "not measured (a check stored before the chart)".into(),
        (Some(x), Some(c), Some(lo), Some(hi)) => format!(
            "statistic {x:.3}, centre {c:.3}, limits {lo:.3} to {hi:.3}: {}",
            if p.out_of_control() { format!("OUT OF CONTROL ({})", p.rules.join(", ")) } else { "in control".into() }
        ),
        (Some(x), ..) => format!("statistic {x:.3} (no limits before {} checks in control)", super::control::BASELINE),
    }
}

impl History {
    /// The check decision of survey `id`, if it is a check.
    fn check(&self, id: i64) -> Option<&CheckDecision> {
        self.checks.iter().find(|c| c.survey_id == id)
    }

    /// The control chart of the checks, one point each, in their order.
    pub fn control(&self) -> Vec<super::control::Point> {
        let checks: Vec<super::control::Check> = self.checks.iter().map(super::control::Check::of).collect();
        super::control::chart(&checks)
    }

    /// `survey history --json` (the contract's keys and more): a check's
    /// decision carries its point of the control chart (`control`).
    pub fn json(&self) -> Value {
        let chart = self.control();
        let surveys: Vec<Value> = self
            .surveys
            .iter()
            .map(|m| {
                let mut doc = m.json();
                let at = self.checks.iter().position(|c| c.survey_id == m.survey.id);
                doc["check"] = match at {
                    Some(i) => {
                        let mut c = serde_json::to_value(&self.checks[i]).unwrap_or_default();
                        c["control"] = chart[i].json();
                        c
                    }
                    None => Value::Null,
                };
                doc
            })
            .collect();
        let changes: Vec<Value> =
            self.changes.iter().map(|(a, b, c)| c.json(&self.surveys[*a].survey, &self.surveys[*b].survey)).collect();
        json!({
            "asset": self.asset,
            "surveys": surveys,
            "changes": changes,
            "not_compared": self.not_compared,
        })
    }

    /// For people: one line per survey, then the changes.
    pub fn text(&self) -> String {
        let chart = self.control();
        let n = self.surveys.len();
        let mut s = format!("asset {}: {n} {}\n", self.asset, if n == 1 { "survey" } else { "surveys" });
        let _ = writeln!(
            s,
            "{:>4}  {:<20}  {:<12} {:<11} {:>9} {:>9} {:>9} {:>9}  main lines (cycles/rev: amplitude, deg)",
            "id", "created (UTC)", "kind", "status", "A, deg", "R, deg", "B, deg", "U, deg"
        );
        let num = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3e}"));
        for m in &self.surveys {
            let lines: Vec<String> = m
                .summary
                .lines
                .iter()
                .take(4)
                .map(|l| format!("{}: {:.2e}", l.cycles_per_rev, l.amplitude_deg))
                .collect();
            let _ = writeln!(
                s,
                "{:>4}  {:<20}  {:<12} {:<11} {:>9} {:>9} {:>9} {:>9}  {}",
                m.survey.id,
                m.survey.created_at,
                m.kind(),
                m.survey.status.as_str(),
                num(m.summary.iso.as_ref().map(|i| i.a)),
                num(m.summary.iso.as_ref().map(|i| i.r)),
                num(m.summary.iso.as_ref().and_then(|i| i.b)),
                num(m.summary.table_u_deg),
                if lines.is_empty() { "-".to_string() } else { lines.join(", ") }
            );
            if let Some(t) = &m.summary.motions {
                let total = |v: Option<f64>, u: f64| match v {
                    Some(v) => format!("{v:.1} um (U {u:.1})"),
                    None => format!("below the detection limit ({:.1} um)", t.limit_um),
                };
                let separated = |what: &str, x: Option<crate::life::Total>, unit: &str| match x {
                    Some(x) => match x.total {
                        Some(v) => format!(", {what} {v:.1} {unit} (U {:.1})", x.u),
                        None => format!(", {what} below the detection limit ({:.1} {unit})", x.limit),
                    },
                    None => String::new(),
                };
                let _ = writeln!(
                    s,
                    "      error motions (ISO 230-7, totals): radial {}, axial {}{}{}{}",
                    total(t.radial_um, t.u_radial_um),
                    total(t.axial_um, t.u_axial_um),
                    separated("axial on the axis", t.axial_on_axis_um, "um"),
                    separated("tilt", t.tilt_urad, "urad"),
                    separated("tilt across", t.tilt_across_urad, "urad")
                );
            }
            if let Some(c) = self.check(m.survey.id) {
                let _ = writeln!(
                    s,
                    "      check against {}: {}, the table {}; {}{}",
                    c.against_uid,
                    c.verdict,
                    if c.table_holds { "holds" } else { "does not hold" },
                    if c.recalibrate { "recalibrate" } else { "in tolerance" },
                    match (&c.recalibration_uid, &c.table_file) {
                        (Some(u), Some(_)) if self.in_lab_store => format!(
                            ": recalibrated by {u}, whose table is in force (in the lab store: `survey process --survey \
                             {u}` makes it)"
                        ),
                        (Some(u), Some(t)) => format!(": recalibrated by {u}, table {t} in force"),
                        (Some(u), None) => format!(": recalibrated by {u}"),
                        _ => String::new(),
                    }
                );
                if let Some(p) = self.checks.iter().position(|d| d.survey_id == c.survey_id).map(|i| &chart[i]) {
                    let _ = writeln!(s, "      control chart: {}", control_text(p));
                }
            }
        }
        if !self.changes.is_empty() {
            s += "changes:\n";
        }
        for (a, b, c) in &self.changes {
            let _ = writeln!(
                s,
                "  {} -> {}: {}{}",
                self.surveys[*a].survey.id,
                self.surveys[*b].survey.id,
                c.verdict.as_str(),
                if c.recalibrate { format!(": {}", c.reason) } else { String::new() }
            );
        }
        for n in &self.not_compared {
            let _ = writeln!(s, "  not compared: {n}");
        }
        s
    }
}
