//! An asset's history (`survey history`, and the report's section): its
//! surveys in the order they were made, each with its ISO 230-2 `A`, `R`,
//! `B`, its table's `U` and main lines, a check survey with what it decided;
//! and what changed from each complete survey to the next (calibrations and
//! checks: the native measurements; a verification is measured with a table
//! applied, so it is listed but not compared).

use super::{Compared, Measured, compared, measure};
use serde_json::{Value, json};
use std::fmt::Write as _;
use survey_store::survey::SurveyRef;
use survey_store::{CheckDecision, NotFound, Store};

/// An asset's history.
#[derive(Debug)]
pub struct History {
    /// The asset.
    pub asset: String,
    /// Its surveys, oldest first.
    pub surveys: Vec<Measured>,
    /// What changed from one complete survey to the next: indices into
    /// `surveys` and the comparison.
    pub changes: Vec<(usize, usize, Compared)>,
    /// Pairs that could not be compared, and why.
    pub not_compared: Vec<String>,
    /// What the check surveys decided.
    pub checks: Vec<CheckDecision>,
}

/// The history of `asset` in `store`, up to and including survey `up_to`
/// when given (a report shows what was known when its survey was made).
pub async fn history(store: &Store, asset: &str, up_to: Option<i64>) -> anyhow::Result<History> {
    let records = store.surveys_of_asset(asset).await?;
    let last = up_to.and_then(|id| records.iter().position(|r| r.id == id));
    let records = &records[..last.map_or(records.len(), |i| i + 1)];
    if records.is_empty() {
        return Err(NotFound(format!("no survey of the asset {asset} in {}", store.path().display())).into());
    }
    let mut surveys = Vec::with_capacity(records.len());
    for r in records {
        surveys.push(measure(store, SurveyRef::Id(r.id)).await?);
    }
    let native: Vec<usize> =
        (0..surveys.len()).filter(|&i| surveys[i].survey.is_complete() && surveys[i].is_native()).collect();
    let (mut changes, mut not_compared) = (Vec::new(), Vec::new());
    for pair in native.windows(2) {
        let (a, b) = (&surveys[pair[0]], &surveys[pair[1]]);
        match compared(a, b) {
            Ok(c) => changes.push((pair[0], pair[1], c)),
            Err(e) => not_compared.push(format!("{e:#}")),
        }
    }
    let checks = store.checks_of_asset(asset).await?;
    Ok(History { asset: asset.to_string(), surveys, changes, not_compared, checks })
}

impl History {
    /// The check decision of survey `id`, if it is a check.
    fn check(&self, id: i64) -> Option<&CheckDecision> {
        self.checks.iter().find(|c| c.survey_id == id)
    }

    /// `survey history --json` (the contract's keys and more).
    pub fn json(&self) -> Value {
        let surveys: Vec<Value> = self
            .surveys
            .iter()
            .map(|m| {
                let mut doc = m.json();
                doc["check"] = serde_json::to_value(self.check(m.survey.id)).unwrap_or_default();
                doc
            })
            .collect();
        let changes: Vec<Value> =
            self.changes.iter().map(|(a, b, c)| c.change_json(&self.surveys[*a], &self.surveys[*b])).collect();
        json!({
            "asset": self.asset,
            "surveys": surveys,
            "changes": changes,
            "not_compared": self.not_compared,
        })
    }

    /// For people: one line per survey, then the changes.
    pub fn text(&self) -> String {
        let mut s = format!("asset {}: {} surveys\n", self.asset, self.surveys.len());
        let _ = writeln!(
            s,
            "{:>4}  {:<20}  {:<12} {:<11} {:>9} {:>9} {:>9} {:>9}  main lines (cycles/rev: amplitude, deg)",
            "id", "created (UTC)", "kind", "status", "A, deg", "R, deg", "B, deg", "U, deg"
        );
        let num = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3e}"));
        for m in &self.surveys {
            let lines: Vec<String> = m
                .main_lines()
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
                num(m.iso.as_ref().map(|i| i.a)),
                num(m.iso.as_ref().map(|i| i.r)),
                num(m.iso.as_ref().and_then(|i| i.b)),
                num(m.table_u_deg),
                if lines.is_empty() { "-".to_string() } else { lines.join(", ") }
            );
            if let Some(c) = self.check(m.survey.id) {
                let _ = writeln!(
                    s,
                    "      check against {}: {}, the table {}; {}{}",
                    c.against_uid,
                    c.verdict,
                    if c.table_holds { "holds" } else { "does not hold" },
                    if c.recalibrate { "recalibrate" } else { "in tolerance" },
                    match (&c.recalibration_uid, &c.table_file) {
                        (Some(u), Some(t)) => format!(": recalibrated by {u}, table {t} in force"),
                        (Some(u), None) => format!(": recalibrated by {u}"),
                        _ => String::new(),
                    }
                );
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
                c.comparison.verdict.as_str(),
                if c.decision.recalibrate { format!(": {}", c.decision.reason) } else { String::new() }
            );
        }
        for n in &self.not_compared {
            let _ = writeln!(s, "  not compared: {n}");
        }
        s
    }
}
