//! The axis's other errors (issue 52): the location of its axis average
//! line (ISO 230-1) and its error motions (ISO 230-7) as a table, each
//! figure with its U and the detection limit, and polar plots as ISO 230-7
//! draws them (the synchronous motion about a base circle, magnified, with
//! the two circles about the least-squares centre that enclose it).

use super::{Page, Section};
use crate::page::{Key, escape, figure, legend, table};
use crate::plot::{self, GREY, INK, SKY, VERMILLION, hex, render};
use plotters::prelude::*;
use survey_motions::{Block, ErrorMotions, PolarPoint};

/// The polar plots' canvas, pixels: a row of panels side by side.
const PANELS: (u32, u32) = (plot::WIDTH, 380);

/// A figure or "below the detection limit".
fn shown(v: Option<f64>, b: &Block) -> String {
    match v {
        Some(v) => format!("{v:.1}"),
        None if b.below_detection_limit => "below limit".into(),
        None => "–".into(),
    }
}

/// The table of the figures.
pub fn figures_table(m: &ErrorMotions) -> String {
    let mut rows = Vec::new();
    let mut row = |name: String, unit: &str, b: &Block| {
        rows.push(vec![
            escape(&name),
            shown(b.total, b),
            shown(b.synchronous, b),
            shown(b.asynchronous, b),
            format!("{:.1}", b.u),
            format!("{:.1}{unit}", b.detection_limit),
        ]);
    };
    row("radial, µm".into(), "", &m.radial_um);
    row(format!("axial at {:.0} mm, µm", m.radius_mm), "", &m.axial_um);
    if let Some(a) = &m.axial_on_axis_um {
        row("axial on the axis, µm".into(), "", a);
    }
    if let Some(t) = &m.tilt_urad {
        let how = if t.method == "phases" { "SMRs at several phases" } else { "SMRs at two heights" };
        row(format!("tilt ({how}), µrad"), "", t);
    }
    if let Some(t) = &m.tilt_across_urad {
        row("tilt across, at 90° to the first SMR's radial direction, µrad".into(), "", t);
    }
    let l = &m.location;
    let mut frames = vec![vec![
        "tracker frame".into(),
        format!("{:.3}", l.x0_mm),
        format!("{:.3}", l.y0_mm),
        format!("{:.1}", l.a0_urad),
        format!("{:.1}", l.b0_urad),
        format!("{:.3} mm, {:.1} µrad", l.u_xy_mm, l.u_ab_urad),
    ]];
    if let Some(m) = &l.machine {
        let terms = match (m.u_xy_alignment_mm, m.u_ab_alignment_urad) {
            (Some(xy), Some(ab)) => format!(
                " (the fit's {:.3} mm, {:.1} µrad; the alignment's {xy:.3} mm, {ab:.1} µrad)",
                m.u_xy_fit_mm, m.u_ab_fit_urad
            ),
            _ => " (the frame taken as stated)".into(),
        };
        frames.push(vec![
            "machine frame (X0C, Y0C at its z = 0)".into(),
            format!("{:.3}", m.x0_mm),
            format!("{:.3}", m.y0_mm),
            format!("{:.1}", m.a0_urad),
            format!("{:.1}", m.b0_urad),
            format!("{:.3} mm, {:.1} µrad{}", m.u_xy_mm, m.u_ab_urad, escape(&terms)),
        ]);
    }
    let location = table(
        "tbl-axis-location",
        &["axis average line (ISO 230-1)", "X0C, mm", "Y0C, mm", "A0C, µrad", "B0C, µrad", "U (k = 2)"],
        &frames,
    );
    let motions = table(
        "tbl-error-motions",
        &["error motion (ISO 230-7)", "total", "synchronous", "asynchronous", "U (k = 2)", "detection limit"],
        &rows,
    );
    location + &motions
}

/// What a polar plot shows of a point.
type Value = fn(&PolarPoint) -> Option<f64>;

/// One polar plot of `value` of every point in `area`, magnified about a
/// base circle, titled; the enclosing circles' separation.
fn polar(area: &plot::Area<'_>, points: &[PolarPoint], value: Value, title: &str) -> anyhow::Result<f64> {
    let values: Vec<(f64, f64, &str)> =
        points.iter().filter_map(|p| value(p).map(|v| (p.target_deg, v, p.direction))).collect();
    let (lo, hi) = plot::extent(values.iter().map(|v| v.1));
    // The base circle at radius 0.7; the motion's range drawn over 0.6.
    let scale = 0.6 / (hi - lo).max(1e-9);
    let at = |deg: f64, r: f64| {
        let (s, c) = deg.to_radians().sin_cos();
        (r * c, r * s)
    };
    let radius = |v: f64| 0.7 + scale * (v - lo);
    let mut chart = ChartBuilder::on(area)
        .margin(8)
        .caption(title, ("sans-serif", 18).into_font().color(&INK))
        .build_cartesian_2d(-1.5..1.5, -1.5..1.5)
        .map_err(plot::plot_err)?;
    let circle = |r: f64| (0..=360).map(move |d| at(d as f64, r));
    for r in [radius(lo), radius(hi)] {
        chart.draw_series(LineSeries::new(circle(r), INK.stroke_width(1))).map_err(plot::plot_err)?;
    }
    chart.draw_series(LineSeries::new(circle(1.4), GREY.stroke_width(1))).map_err(plot::plot_err)?;
    for d in (0..360).step_by(30) {
        let spoke = vec![at(d as f64, 0.0), at(d as f64, 1.4)];
        chart
            .draw_series(std::iter::once(PathElement::new(spoke, GREY.mix(0.4).stroke_width(1))))
            .map_err(plot::plot_err)?;
        if d % 90 == 0 {
            let (x, y) = at(d as f64, 1.25);
            let label = Text::new(format!("{d}°"), (x - 0.08, y + 0.05), ("sans-serif", 15).into_font().color(&INK));
            chart.draw_series(std::iter::once(label)).map_err(plot::plot_err)?;
        }
    }
    for (direction, colour) in [("forward", VERMILLION), ("reverse", SKY)] {
        let mut pts: Vec<(f64, f64)> =
            values.iter().filter(|v| v.2 == direction).map(|v| at(v.0, radius(v.1))).collect();
        if let Some(first) = pts.first().copied() {
            pts.push(first);
        }
        chart.draw_series(LineSeries::new(pts, colour.stroke_width(2))).map_err(plot::plot_err)?;
    }
    Ok(hi - lo)
}

/// The section's body.
pub fn body(m: &ErrorMotions) -> anyhow::Result<String> {
    let mut s = figures_table(m);
    let plots: Vec<(&str, &str, Value)> = [
        ("radial, µm", "µm", (|p: &PolarPoint| Some(p.radial_um)) as Value),
        ("axial (face), µm", "µm", |p: &PolarPoint| Some(p.axial_um)),
        ("axial on the axis, µm", "µm", |p: &PolarPoint| p.axial_on_axis_um),
        ("tilt, µrad", "µrad", |p: &PolarPoint| p.tilt_urad),
        ("tilt across, µrad", "µrad", |p: &PolarPoint| p.tilt_across_urad),
    ]
    .into_iter()
    .filter(|(_, _, value)| m.polar.iter().any(|p| value(p).is_some()))
    .collect();
    let mut spans = Vec::new();
    // Up to four panels side by side; five (the tilt across too) in two rows of three.
    let rows = if plots.len() > 4 { 2 } else { 1 };
    let columns = plots.len().div_ceil(rows).max(1);
    let svg = render((PANELS.0, PANELS.1 * rows as u32), |root| {
        for ((title, unit, value), area) in plots.iter().zip(root.split_evenly((rows, columns))) {
            spans.push(format!("{title}: {:.1} {unit}", polar(&area, &m.polar, *value, title)?));
        }
        Ok(())
    })?;
    let entries = [
        (hex(VERMILLION), Key::Line, "synchronous, forward".to_string()),
        (hex(SKY), Key::Line, "synchronous, reverse".to_string()),
        (hex(INK), Key::Thin, format!("the enclosing circles, apart by {}", spans.join("; "))),
    ];
    let caption = format!(
        "Error motions (ISO 230-7 polar plots): the mean over the runs at each target, plotted about a base circle \
         with the motion magnified; the least-squares centre is the circle fit's, so the centring (once per \
         revolution) is removed. A figure below the detection limit ({:.1} µm) cannot be told from the tracker's \
         own error.",
        m.detection_limit_um
    );
    // The polar plots and the method on the screen (and the lab's pages); printed, the
    // certificate keeps the tables (the DCC carries every figure).
    s += "<div class=\"screen-only\">\n";
    s += &figure("fig-error-motions", &svg, &legend(&entries), &escape(&caption));
    for n in &m.notes {
        s += &super::note(n);
    }
    s += &format!("<p class=\"note\">{}</p>\n</div>\n", escape(m.method));
    Ok(s)
}

/// The section, for a survey whose SMR positions give the error motions.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    let Some(m) = &p.d.error_motions else { return Ok(None) };
    Section::page("motions", "The axis's location and error motions (ISO 230-1, ISO 230-7)", body(m)?)
        .map_or(Ok(None), |s| Ok(Some(s)))
}
