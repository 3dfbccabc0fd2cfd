//! Drift over time, when it was measured: re-measurements of a reference
//! position during the survey (drift control, `[drift_control]`), as
//! (instrument time, drift) points from the store.

use super::{Page, Section};
use crate::page::{Key, escape, figure, legend, table};
use crate::plot::{self, BLUE, HEIGHT, WIDTH, axes, extent, hex, padded, render};
use crate::units::Units;
use plotters::prelude::*;

/// One re-measurement: instrument time since the survey started, seconds,
/// and the reference's error minus its first value, degrees.
pub type DriftPoint = (f64, f64);

/// The section: drift against time, and its figures. `None` with no points.
pub fn section(points: &[DriftPoint], units: Units) -> anyhow::Result<Option<String>> {
    if points.is_empty() {
        return Ok(None);
    }
    let hours: Vec<(f64, f64)> = points.iter().map(|(t, d)| (t / 3600.0, units.of(*d))).collect();
    let (t0, t1) = extent(hours.iter().map(|p| p.0));
    let (lo, hi) = extent(hours.iter().map(|p| p.1).chain([0.0]));
    let svg = render((WIDTH, HEIGHT), |root| {
        let mut chart = axes(
            root,
            padded(t0, t1, 0.02),
            padded(lo, hi, 0.1),
            "instrument time, h",
            &format!("drift, {}", units.symbol()),
        )?;
        chart.draw_series(LineSeries::new(hours.clone(), BLUE.stroke_width(2))).map_err(plot::plot_err)?;
        chart.draw_series(hours.iter().map(|&p| Circle::new(p, 4, BLUE.filled()))).map_err(plot::plot_err)?;
        Ok(())
    })?;
    let (dlo, dhi) = extent(points.iter().map(|p| p.1));
    let caption = format!(
        "Drift over time: {} re-measurements of the reference position, relative to the first ({}).",
        points.len(),
        escape(units.symbol())
    );
    let mut html = figure(
        "fig-drift",
        &svg,
        &legend(&[(hex(BLUE), Key::Line, "drift of the reference position".into())]),
        &caption,
    );
    let rows = vec![
        vec!["range (max − min)".to_string(), units.num(dhi - dlo)],
        vec!["last".to_string(), units.num(points[points.len() - 1].1)],
    ];
    html += &table("tbl-drift", &["drift", &format!("value, {}", units.symbol())], &rows);
    Ok(Some(html))
}

/// The section, when drift was measured.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    Ok(section(&p.d.drift, p.units)?.and_then(|body| Section::page("drift", "Drift over time", body)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drift_points_render_and_none_render_nothing() {
        assert_eq!(section(&[], Units::Deg).unwrap(), None);
        let html = section(&[(0.0, 0.0), (3600.0, 0.0002), (7200.0, 0.0005)], Units::Arcsec).unwrap().unwrap();
        assert!(html.contains("id=\"fig-drift\"") && html.contains("<svg") && html.contains("1.80"), "{html}");
    }
}
