//! The uncertainty budget of the correction table, when the processing
//! reports one (`uncertainty` in the processing summary: `{"k", "table_u_deg"
//! (the expanded uncertainty U), "combined_u_deg" (u), "budget": [{"source",
//! "u_deg"}]}`).

use super::{Page, Section};
use crate::page::{escape, table};
use crate::units::{Units, percent};
use serde::Deserialize;

/// One contribution: its source and its standard uncertainty, degrees.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct BudgetEntry {
    pub source: String,
    pub u_deg: f64,
}

/// The budget: the contributions, the expanded uncertainty of the table
/// (`table_u_deg`, U = k u), its combined standard uncertainty and the
/// coverage factor.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct UncertaintyBudget {
    pub k: f64,
    pub table_u_deg: f64,
    pub combined_u_deg: f64,
    pub budget: Vec<BudgetEntry>,
}

/// The section: the contributions, each one's share of the variance, the
/// combined and the expanded uncertainty.
pub fn section(b: &UncertaintyBudget, units: Units) -> String {
    let u = units.symbol();
    let total: f64 = b.budget.iter().map(|e| e.u_deg * e.u_deg).sum();
    let mut rows: Vec<Vec<String>> = b
        .budget
        .iter()
        .map(|e| {
            let share = if total > 0.0 { e.u_deg * e.u_deg / total } else { 0.0 };
            vec![escape(&units.text(&e.source)), units.num(e.u_deg), percent(share)]
        })
        .collect();
    rows.push(vec!["combined standard uncertainty u".into(), units.num(b.combined_u_deg), String::new()]);
    // U as every other place states it: two significant digits, rounded up (ILAC-P14).
    let u_stated = crate::rounding::num_u(units, b.table_u_deg);
    rows.push(vec![format!("expanded uncertainty U = k u (k = {})", b.k), u_stated, String::new()]);
    let mut html = table("tbl-uncertainty", &["source", &format!("standard uncertainty, {u}"), "share of u²"], &rows);
    html += "<p class=\"note\">Each contribution is a standard uncertainty (k = 1); the shares are of the sum of \
             their squares.</p>\n";
    html
}

/// The section, when the processing gives a budget.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    Ok(p.d
        .uncertainty
        .as_ref()
        .and_then(|b| Section::page("uncertainty", "Uncertainty of the table", section(b, p.units))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_budget_renders_with_its_shares_and_expanded_uncertainty() {
        let b: UncertaintyBudget = serde_json::from_str(
            r#"{"k": 2, "table_u_deg": 0.0010, "combined_u_deg": 0.0005, "budget": [{"source": "noise", "u_deg": 0.0003}, {"source": "axis", "u_deg": 0.0004}]}"#,
        )
        .unwrap();
        let html = section(&b, Units::Deg);
        assert!(html.contains("36.0 %") && html.contains("64.0 %"), "{html}");
        assert!(html.contains("0.00050"), "u = 0.0005: {html}");
        // U as the certificate states it everywhere: two significant digits (ILAC-P14).
        assert!(html.contains("(k = 2)</td><td>0.0010</td>"), "U = 2 x 0.0005: {html}");
    }
}
