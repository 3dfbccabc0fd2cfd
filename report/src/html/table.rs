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
use survey_tables::pipeline::Processed;

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

/// The excerpt's entries are laid out in this many blocks side by side.
const BLOCKS: usize = 3;
/// At most this many entries (a page beside the figure).
const MAX_ENTRIES: usize = 60;
/// The spacings an excerpt may take, degrees.
const NICE: [f64; 16] = [0.001, 0.002, 0.005, 0.01, 0.02, 0.025, 0.05, 0.1, 0.2, 0.25, 0.5, 1.0, 2.0, 2.5, 5.0, 10.0];

/// Which rows the excerpt shows, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Excerpt {
    pub from: f64,
    pub step: f64,
    pub count: usize,
    pub why: String,
}

/// The excerpt of the table: a spacing of at most an eighth of the shortest
/// significant period (so the values trace its shape instead of sampling it
/// at random phases), and at most [`MAX_ENTRIES`] rows from the start of the
/// span; without any line, 36 rows over the span.
pub fn excerpt(p: &Processed) -> Excerpt {
    let (lo, hi) = span(p);
    let shortest = p.analysis.lines.iter().map(|l| l.true_cycles_per_rev).filter(|c| *c > 0.0).fold(0.0, f64::max);
    let (step, reason) = if shortest > 0.0 {
        let period = 360.0 / shortest;
        let step = NICE.iter().copied().filter(|s| *s <= period / 8.0).fold(NICE[0], f64::max);
        (
            step,
            format!(
                "every {} deg, an eighth or less of the shortest significant period ({} deg, the {} cycles/rev line), \
                 so that the values show the error's shape",
                angle(step),
                angle(period),
                angle(shortest)
            ),
        )
    } else {
        let step = NICE.iter().copied().filter(|s| *s <= (hi - lo) / 36.0).fold(NICE[0], f64::max);
        (step, format!("every {} deg (no significant line)", angle(step)))
    };
    let whole = ((hi - lo) / step).round() as usize + usize::from(hi - lo < 360.0);
    let count = whole.min(MAX_ENTRIES);
    let covered = if count < whole {
        format!(
            "from {} to {} deg ({count} of the {whole} rows such a spacing gives; the figure above plots the whole \
             table)",
            angle(lo),
            angle(lo + (count - 1) as f64 * step)
        )
    } else {
        format!("over the whole span, {} to {} deg", angle(lo), angle(lo + (count - 1) as f64 * step))
    };
    Excerpt { from: lo, step, count, why: format!("The excerpt: {reason}, {covered}.") }
}

fn capitalised(s: &str) -> String {
    let mut c = s.chars();
    c.next().map_or(String::new(), |f| {
        f.to_uppercase().chain(c).collect::<String>() + if s.ends_with('.') { "" } else { "." }
    })
}

/// Why the table has its columns, in `units`: a largest hysteresis in it
/// (the largest |B<sub>i</sub>|, which is B) rounded as the certificate
/// rounds B, to the place of the measured figures' U `b_u_deg` (one rounding).
fn directional_reason(p: &Processed, units: Units, b_u_deg: Option<f64>) -> String {
    let reason = &p.built.directional_reason;
    match &p.built.hysteresis {
        Some(h) if *reason == h.auto_reason(&h.max_text()) => {
            units.text(&h.auto_reason(&crate::rounding::show(units, h.max_deg, b_u_deg).0))
        }
        _ => units.text(reason),
    }
}

/// The section: the figure and the excerpt, each value to the decimal
/// place of the table's U `u_deg` (ILAC-P14, as in the DCC); the
/// hysteresis named to the place of the measured figures' U `b_u_deg`, as B.
pub fn section(p: &Processed, units: Units, u_deg: Option<f64>, b_u_deg: Option<f64>) -> anyhow::Result<String> {
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
        escape(&capitalised(&directional_reason(p, units, b_u_deg))),
    );
    let mut html = figure("fig-table", &svg(p, units)?, &legend(&entries), &caption);
    let ex = excerpt(p);
    let u = units.symbol();
    let cols = columns(p);
    let mut head = vec![];
    for _ in 0..BLOCKS {
        head.push("readout, deg".to_string());
        for (d, _, _) in &cols {
            head.push(d.to_string());
        }
    }
    let per_block = ex.count.div_ceil(BLOCKS);
    let rows: Vec<Vec<String>> = (0..per_block)
        .map(|r| {
            let mut row = Vec::new();
            for block in 0..BLOCKS {
                let k = block * per_block + r;
                if k >= ex.count {
                    row.extend(std::iter::repeat_n(String::new(), 1 + cols.len()));
                    continue;
                }
                let x = ex.from + k as f64 * ex.step;
                row.push(angle(x));
                for (d, _, _) in &cols {
                    row.push(crate::rounding::num(units, t.error_at(x, *d), u_deg));
                }
            }
            row
        })
        .collect();
    let head: Vec<&str> = head.iter().map(String::as_str).collect();
    let at = u_deg.map_or(String::new(), |v| {
        format!(" (to the decimal place of the table's U = {})", crate::rounding::show_u(units, v))
    });
    html += &format!("<h3>Table values (excerpt): the error of each column, {u}{at}</h3>\n");
    html += &table("tbl-table", &head, &rows);
    html += &format!(
        "<p class=\"note\" id=\"table-excerpt\">{} The correction is the error with its sign changed (the value \
         added to the readout). Every row of the table is in the files `survey process` writes beside it (CSV, \
         controller files, the binary table).</p>\n",
        escape(&ex.why)
    );
    Ok(html)
}

/// The section, when the survey was processed.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    match p.processed() {
        Some(processed) => {
            let u = p.d.uncertainty.as_ref().map(|b| b.table_u_deg);
            let reference_u = p.cert.reference_uncertainty_deg.as_ref().map(|u| u.value);
            let b_u = crate::conformity::accuracy_u_deg(reference_u, p.d.reference_systematic_u_deg, p.d.axis_u_deg);
            let body = section(processed, p.units, u, b_u)?;
            Ok(Section::page("correction-table", "Correction table", body))
        }
        None => Ok(None),
    }
}
