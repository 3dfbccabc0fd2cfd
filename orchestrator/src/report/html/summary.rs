//! The summary: what a customer reads first.

use super::{Page, Section};
use crate::report::page;
use crate::report::page::escape;
use survey_processing::Sample;

/// The section: the figures a customer reads first.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    let (d, units) = (p.d, p.units);
    let mut rows: Vec<Vec<String>> = Vec::new();
    if let Ok(iso) = &p.iso {
        rows.push(vec!["ISO 230-2 accuracy A, as measured".into(), units.show(iso.a)]);
        rows.push(vec!["ISO 230-2 repeatability R".into(), units.show(iso.r)]);
    }
    if let Ok(p) = &d.processed {
        rows.push(vec!["native peak error ±".into(), units.show(p.prediction.native_peak_deg)]);
        rows.push(vec![
            "corrected peak error ±, predicted from this survey".into(),
            units.show(p.prediction.corrected_peak_deg),
        ]);
        if let Some(floor) = p.floor.deg {
            rows.push(vec![format!("floor: {}", escape(&units.text(&p.floor.what))), units.show(floor)]);
        }
    }
    if let Some(v) = &d.verification {
        let errors: Vec<f64> = v.corrected.iter().map(Sample::error_deg).collect();
        let peak = survey_processing::correction::ErrorFigures::of(&errors, None).peak_deg;
        rows.push(vec![format!("corrected peak error ±, measured (survey {})", v.verification_id), units.show(peak)]);
    }
    Ok(Some(Section {
        id: "summary",
        title: "Summary".into(),
        new_page: false,
        body: page::table("tbl-summary", &["figure", "value"], &rows),
    }))
}
