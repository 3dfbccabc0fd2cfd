//! The air temperature against time, when the tracker measured it with the
//! samples (beside the drift: a change of temperature is a usual cause of
//! drift).

use super::{Page, Section};
use crate::page::{Key, escape, figure, legend};
use crate::plot::{self, HEIGHT, ORANGE, WIDTH, axes, extent, hex, padded, render};
use plotters::prelude::*;

/// At most this many points are drawn (the page width holds fewer).
const MAX_DRAWN: usize = 2000;

/// The figure of `(s, °C)` points; `None` without any.
pub fn section(points: &[(f64, f64)]) -> anyhow::Result<Option<String>> {
    if points.is_empty() {
        return Ok(None);
    }
    let stride = points.len().div_ceil(MAX_DRAWN).max(1);
    let hours: Vec<(f64, f64)> = points.iter().step_by(stride).map(|(t, c)| (t / 3600.0, *c)).collect();
    let (t0, t1) = extent(hours.iter().map(|p| p.0));
    let (lo, hi) = extent(points.iter().map(|p| p.1));
    let svg = render((WIDTH, HEIGHT * 3 / 4), |root| {
        let mut chart =
            axes(root, padded(t0, t1, 0.02), padded(lo, hi, 0.15), "instrument time, h", "air temperature, °C")?;
        chart.draw_series(LineSeries::new(hours.clone(), ORANGE.stroke_width(2))).map_err(plot::plot_err)?;
        Ok(())
    })?;
    let caption = format!(
        "Air temperature against time: measured by the tracker with each of the {} samples ({:.2} to {:.2} °C).",
        points.len(),
        lo,
        hi
    );
    Ok(Some(figure(
        "fig-environment",
        &svg,
        &legend(&[(hex(ORANGE), Key::Line, "air temperature at the tracker".into())]),
        &escape(&caption),
    )))
}

/// The section, when the air was measured.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    Ok(section(&p.d.temperature)?.map(|body| Section {
        id: "environment",
        title: "Air temperature".into(),
        new_page: false,
        body,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_temperature_is_drawn_and_nothing_without_it() {
        assert_eq!(section(&[]).unwrap(), None);
        let html = section(&[(0.0, 20.0), (3600.0, 20.1), (7200.0, 20.05)]).unwrap().unwrap();
        assert!(html.contains("id=\"fig-environment\"") && html.contains("<svg") && html.contains("20.00 to 20.10"));
    }
}
