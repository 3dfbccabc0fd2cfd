//! Hysteresis against angle: forward minus reverse error at each target,
//! per run and its mean with a ±2 s band. What a one-column table cannot
//! remove, and what a direction-aware table does.

use super::{Page, Section, note};
use crate::page::{Key, escape, figure, legend};
use crate::plot::{self, GREY, HEIGHT, INK, SKY, VERMILLION, WIDTH, axes, extent, hex, padded, render};
use crate::units::Units;
use plotters::prelude::*;
use survey_processing::errormap::{ErrorMap, RunHysteresis};

/// The section's figure, or a sentence when the survey went one way only.
pub fn section(map: &ErrorMap, units: Units) -> anyhow::Result<String> {
    let Some(RunHysteresis { runs_deg: runs, mean_deg: mean, sd_deg: sd }) = map.run_hysteresis() else {
        return Ok(
            "<p id=\"fig-hysteresis\" class=\"note\">The survey was measured in one direction: no hysteresis.</p>\n"
                .into(),
        );
    };
    let t = &map.targets_deg;
    let band: Vec<(f64, f64, f64)> = match &sd {
        Some(sd) => mean.iter().zip(sd).map(|(m, s)| (*m, m - 2.0 * s, m + 2.0 * s)).collect(),
        None => mean.iter().map(|m| (*m, *m, *m)).collect(),
    };
    let (lo, hi) = extent(runs.iter().flatten().copied().chain(band.iter().flat_map(|b| [b.1, b.2])));
    let overall = mean.iter().sum::<f64>() / mean.len() as f64;
    let y = padded(units.of(lo.min(0.0)), units.of(hi.max(0.0)), 0.08);
    let x = padded(t[0], *t.last().unwrap_or(&360.0), 0.01);
    let svg = render((WIDTH, HEIGHT), |root| {
        let mut chart =
            axes(root, x.clone(), y, "target angle, deg", &format!("forward − reverse error, {}", units.symbol()))?;
        let outline: Vec<(f64, f64)> = t
            .iter()
            .zip(&band)
            .map(|(x, b)| (*x, units.of(b.2)))
            .chain(t.iter().zip(&band).rev().map(|(x, b)| (*x, units.of(b.1))))
            .collect();
        chart.draw_series(std::iter::once(Polygon::new(outline, GREY.mix(0.3).filled()))).map_err(plot::plot_err)?;
        for run in &runs {
            let pts = t.iter().zip(run).map(|(x, h)| (*x, units.of(*h)));
            chart.draw_series(LineSeries::new(pts, SKY.stroke_width(1))).map_err(plot::plot_err)?;
        }
        let pts = t.iter().zip(&mean).map(|(x, h)| (*x, units.of(*h)));
        chart.draw_series(LineSeries::new(pts, VERMILLION.stroke_width(3))).map_err(plot::plot_err)?;
        let level = units.of(overall);
        chart
            .draw_series(std::iter::once(PathElement::new(vec![(x.start, level), (x.end, level)], INK.stroke_width(1))))
            .map_err(plot::plot_err)?;
        Ok(())
    })?;
    let mut entries = vec![
        // Each series its own colour: the mean, the runs, the band and the average told apart in print.
        (hex(VERMILLION), Key::Line, "mean over the runs".to_string()),
        (hex(SKY), Key::Line, "each run".to_string()),
        (hex(INK), Key::Thin, format!("average over the targets: {}", units.show(overall))),
    ];
    if sd.is_some() {
        entries.insert(2, (hex(GREY), Key::Band, "mean ± 2 s (over the runs)".to_string()));
    }
    let caption = format!(
        "Hysteresis: the forward error minus the reverse error at each target ({}), per run and averaged. \
         Backlash shows as a constant offset; ISO 230-2's reversal value B<sub>i</sub> = x̄↑ − x̄↓ is its \
         negative (the deviation x = actual − target has the opposite sign to the error).",
        escape(units.symbol())
    );
    Ok(figure("fig-hysteresis", &svg, &legend(&entries), &caption))
}

/// The section: the figure, or why there is none.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    let body = match &p.map {
        Ok(m) => section(m, p.units)?,
        Err(e) => note(&format!("No error map: {e}.")),
    };
    Ok(Section::page("hysteresis", "Hysteresis", body))
}
