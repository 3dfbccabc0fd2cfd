//! Error against angle, every run and direction, with the ±2 s band (the
//! paper's Figures 1, 2 and 8): what a metrologist reads first.

use super::{Page, Section, note};
use crate::page::{Key, LegendEntry, escape, figure, legend};
use crate::plot::{self, BLUE, HEIGHT, VERMILLION, WIDTH, axes, extent, hex, padded, render};
use crate::units::Units;
use plotters::prelude::*;
use std::ops::Range;
use survey_processing::Direction;
use survey_processing::errormap::{DirectionErrors, ErrorMap};

fn colour(d: Direction) -> RGBColor {
    match d {
        Direction::Forward => BLUE,
        Direction::Reverse => VERMILLION,
    }
}

fn directions(map: &ErrorMap) -> Vec<&DirectionErrors> {
    [&map.forward, &map.reverse].into_iter().flatten().collect()
}

/// The range of every run's error and of the ±2 s bands, in `units`.
pub fn y_extent(map: &ErrorMap, units: Units) -> (f64, f64) {
    let mut values = Vec::new();
    for d in directions(map) {
        values.extend(d.errors_deg.iter().flatten().copied());
        if let Some(sd) = &d.sd_deg {
            values.extend(d.mean_deg.iter().zip(sd).flat_map(|(m, s)| [m + 2.0 * s, m - 2.0 * s]));
        }
    }
    let (lo, hi) = extent(values);
    (units.of(lo), units.of(hi))
}

/// The SVG of `map` (runs thin, mean thick, ±2 s band) over the y range
/// `y` (in `units`; `None`: fitted to the data), and its legend.
pub fn svg(map: &ErrorMap, units: Units, y: Option<Range<f64>>) -> anyhow::Result<(String, String)> {
    let x = padded(map.targets_deg[0], *map.targets_deg.last().unwrap_or(&360.0), 0.01);
    let y = y.unwrap_or_else(|| {
        let (lo, hi) = y_extent(map, units);
        padded(lo, hi, 0.08)
    });
    let t = &map.targets_deg;
    let svg = render((WIDTH, HEIGHT), |root| {
        let mut chart =
            axes(root, x, y, "target angle, deg", &format!("error (readout − actual), {}", units.symbol()))?;
        for d in directions(map) {
            let c = colour(d.direction);
            if let Some(sd) = &d.sd_deg {
                let upper = t.iter().zip(&d.mean_deg).zip(sd).map(|((x, m), s)| (*x, units.of(m + 2.0 * s)));
                let lower = t.iter().zip(&d.mean_deg).zip(sd).rev().map(|((x, m), s)| (*x, units.of(m - 2.0 * s)));
                let outline: Vec<(f64, f64)> = upper.chain(lower).collect();
                chart
                    .draw_series(std::iter::once(Polygon::new(outline, c.mix(0.16).filled())))
                    .map_err(plot::plot_err)?;
            }
            for run in &d.errors_deg {
                let pts = t.iter().zip(run).map(|(x, e)| (*x, units.of(*e)));
                chart.draw_series(LineSeries::new(pts, c.mix(0.45).stroke_width(1))).map_err(plot::plot_err)?;
            }
            let mean = t.iter().zip(&d.mean_deg).map(|(x, e)| (*x, units.of(*e)));
            chart.draw_series(LineSeries::new(mean, c.stroke_width(3))).map_err(plot::plot_err)?;
        }
        Ok(())
    })?;
    let mut entries: Vec<LegendEntry> = Vec::new();
    for d in directions(map) {
        let (c, name) = (hex(colour(d.direction)), d.direction.to_string());
        entries.push((c.clone(), Key::Line, format!("{name}: mean over the runs")));
        entries.push((c.clone(), Key::Thin, format!("{name}: each run")));
        if d.sd_deg.is_some() {
            entries.push((c, Key::Band, format!("{name}: mean ± 2 s")));
        }
    }
    Ok((svg, legend(&entries)))
}

/// The section's figure.
pub fn section(map: &ErrorMap, units: Units) -> anyhow::Result<String> {
    let (svg, legend) = svg(map, units, None)?;
    let caption = format!(
        "Readout error (readout − actual, {}) at each of the {} targets, for each of the {} runs (thin lines) and \
         direction. The thick line is the mean over the runs; the band is that mean ± 2 s, s being the standard \
         deviation over the runs at the target (the bands of ISO 230-2's accuracy A). Forward approaches from below, \
         reverse from above.",
        escape(units.symbol()),
        map.targets_deg.len(),
        map.runs.len()
    );
    Ok(figure("fig-error", &svg, &legend, &caption))
}

/// The section: the figure, or why there is none.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    let body = match &p.map {
        Ok(m) => section(m, p.units)?,
        Err(e) => note(&format!("No error map: {e}.")),
    };
    Ok(Section::page("errors", "Error against angle", body))
}
