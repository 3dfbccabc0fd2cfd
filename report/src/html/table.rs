//! The correction table: its columns against the readout with the measured
//! means it was made from, and an excerpt of its values (error and
//! correction) every few degrees. The full table is in the files `survey
//! process` writes.

use super::{Page, Section};
use crate::page::{Key, escape, figure, legend, table};
use crate::plot::{self, BLUE, HEIGHT, INK, VERMILLION, WIDTH, axes, extent, hex, padded, render};
use crate::units::{Units, angle};
use plotters::prelude::*;
use survey_processing::Direction;
use survey_processing::errormap::Coverage;
use survey_processing::pipeline::Processed;

/// At most this many points of a column are drawn (the page width holds fewer).
const MAX_DRAWN: usize = 4000;

/// The readout span the table was measured over.
fn span(p: &Processed) -> (f64, f64) {
    match p.analysis.error_map.coverage {
        Coverage::FullCircle { .. } => (0.0, 360.0),
        Coverage::Partial { start, end, .. } => (start, end),
    }
}

fn columns(p: &Processed) -> Vec<(Direction, RGBColor, &'static str)> {
    if p.built.table.is_directional() {
        vec![(Direction::Forward, BLUE, "forward column"), (Direction::Reverse, VERMILLION, "reverse column")]
    } else {
        vec![(Direction::Forward, BLUE, "the one column (both directions)")]
    }
}

fn svg(p: &Processed, units: Units) -> anyhow::Result<String> {
    let t = &p.built.table;
    let (lo, hi) = span(p);
    // Rows over the measured span, which may start below 0 (the table wraps at 360).
    let h = t.spacing_deg();
    let (first, last) = ((lo / h).floor() as i64, (hi / h).ceil() as i64);
    let stride = (((last - first) as usize) / MAX_DRAWN).max(1);
    let map = &p.analysis.error_map;
    let curves: Vec<(RGBColor, Vec<(f64, f64)>)> = columns(p)
        .into_iter()
        .map(|(d, c, _)| {
            let pts = (first..=last)
                .step_by(stride)
                .map(|i| {
                    let x = i as f64 * h;
                    (x, units.of(t.error_at(x, d)))
                })
                .collect();
            (c, pts)
        })
        .collect();
    let means: Vec<(RGBColor, Vec<(f64, f64)>)> = [(&map.forward, BLUE), (&map.reverse, VERMILLION)]
        .into_iter()
        .filter_map(|(d, c)| d.as_ref().map(|d| (c, d)))
        .map(|(c, d)| (c, map.targets_deg.iter().zip(&d.mean_deg).map(|(x, e)| (*x, units.of(*e))).collect()))
        .collect();
    let (ylo, yhi) = extent(curves.iter().chain(&means).flat_map(|c| c.1.iter().map(|p| p.1)));
    render((WIDTH, HEIGHT), |root| {
        let mut chart = axes(
            root,
            padded(lo, hi, 0.01),
            padded(ylo, yhi, 0.08),
            "readout angle, deg",
            &format!("table error, {}", units.symbol()),
        )?;
        for (c, pts) in &means {
            chart
                .draw_series(pts.iter().map(|&(x, y)| Circle::new((x, y), 2, c.mix(0.35).filled())))
                .map_err(plot::plot_err)?;
        }
        for (c, pts) in &curves {
            chart.draw_series(LineSeries::new(pts.clone(), c.stroke_width(2))).map_err(plot::plot_err)?;
        }
        Ok(())
    })
}

fn capitalised(s: &str) -> String {
    let mut c = s.chars();
    c.next().map_or(String::new(), |f| {
        f.to_uppercase().chain(c).collect::<String>() + if s.ends_with('.') { "" } else { "." }
    })
}

/// The section: the figure and the excerpt.
pub fn section(p: &Processed, units: Units) -> anyhow::Result<String> {
    let t = &p.built.table;
    let mut entries: Vec<_> =
        columns(p).into_iter().map(|(_, c, name)| (hex(c), Key::Line, format!("table, {name}"))).collect();
    entries.push((hex(INK), Key::Dot, "measured mean error per target (forward blue, reverse red)".to_string()));
    let caption = format!(
        "The correction table: {} rows every {:.5} deg of readout{}, made by {}. The corrected angle is \
         readout − error(readout), read with linear interpolation between rows. {}",
        t.len(),
        t.spacing_deg(),
        if t.is_directional() { ", a forward and a reverse column" } else { ", one column" },
        escape(&units.text(&p.built.method.to_string())),
        escape(&capitalised(&units.text(&p.built.directional_reason))),
    );
    let mut html = figure("fig-table", &svg(p, units)?, &legend(&entries), &caption);
    let (lo, hi) = span(p);
    let step = if hi - lo >= 180.0 { 10.0 } else { ((hi - lo) / 10.0).max(1e-3) };
    let count = ((hi - lo) / step).round() as usize + usize::from(hi - lo < 360.0);
    let u = units.symbol();
    let mut head = vec!["readout, deg".to_string()];
    let cols = columns(p);
    for (d, _, _) in &cols {
        head.push(format!("error {d}, {u}"));
        head.push(format!("correction {d}, {u}"));
    }
    let rows: Vec<Vec<String>> = (0..count)
        .map(|k| {
            let x = lo + k as f64 * step;
            let mut row = vec![angle(x)];
            for (d, _, _) in &cols {
                let e = t.error_at(x, *d);
                row.push(units.num(e));
                row.push(units.num(-e));
            }
            row
        })
        .collect();
    let head: Vec<&str> = head.iter().map(String::as_str).collect();
    html += "<h3>Table values (excerpt)</h3>\n";
    html += &table("tbl-table", &head, &rows);
    html += "<p class=\"note\">Every row of the table is in the files `survey process` writes beside it (CSV, \
             controller files, the binary table); the correction is the value added to the readout.</p>\n";
    Ok(html)
}

/// The section, when the survey was processed.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    match p.processed() {
        Some(processed) => Ok(Section::page("correction-table", "Correction table", section(processed, p.units)?)),
        None => Ok(None),
    }
}
