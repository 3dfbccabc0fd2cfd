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

/// The polar plot's canvas, pixels.
const SIZE: u32 = 520;

/// A figure or "below the detection limit".
fn shown(v: Option<f64>, b: &Block) -> String {
    match v {
        Some(v) => format!("{v:.1}"),
        None if b.below_detection_limit => "below the detection limit".into(),
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
            format!("{:.1}", b.detection_limit),
            unit.to_string(),
        ]);
    };
    row("radial (E_XC, E_YC in the SMR's radial direction)".into(), "µm", &m.radial_um);
    row(format!("axial, face motion at {:.0} mm (E_ZC)", m.radius_mm), "µm", &m.axial_um);
    if let Some(t) = &m.tilt_urad {
        row("tilt (E_AC, E_BC in the SMR's radial direction)".into(), "µrad", t);
    }
    let l = &m.location;
    let location = table(
        "tbl-axis-location",
        &["axis average line (ISO 230-1), tracker frame", "X0C, mm", "Y0C, mm", "A0C, µrad", "B0C, µrad"],
        &[vec![
            "the first SMR's circle centre and plane normal".into(),
            format!("{:.3}", l.x0_mm),
            format!("{:.3}", l.y0_mm),
            format!("{:.1}", l.a0_urad),
            format!("{:.1}", l.b0_urad),
        ]],
    );
    let motions = table(
        "tbl-error-motions",
        &["error motion (ISO 230-7)", "total", "synchronous", "asynchronous", "U (k = 2)", "detection limit", "unit"],
        &rows,
    );
    location + &motions
}

/// One polar plot of `value` of every point, magnified about a base circle.
fn polar(points: &[PolarPoint], value: impl Fn(&PolarPoint) -> Option<f64>, unit: &str) -> anyhow::Result<String> {
    let values: Vec<(f64, f64, &str)> =
        points.iter().filter_map(|p| value(p).map(|v| (p.target_deg, v, p.direction))).collect();
    let (lo, hi) = plot::extent(values.iter().map(|v| v.1));
    let span = (hi - lo).max(1e-9);
    // The base circle at radius 1; the motion's range drawn over 0.6 of it.
    let scale = 0.6 / span;
    let at = |deg: f64, r: f64| {
        let (s, c) = deg.to_radians().sin_cos();
        (r * c, r * s)
    };
    let radius = |v: f64| 0.7 + scale * (v - lo);
    let svg = render((SIZE, SIZE), |root| {
        let mut chart =
            ChartBuilder::on(root).margin(24).build_cartesian_2d(-1.45..1.45, -1.45..1.45).map_err(plot::plot_err)?;
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
            let (x, y) = at(d as f64, 1.33);
            let label = Text::new(format!("{d}°"), (x - 0.05, y + 0.03), ("sans-serif", 15).into_font().color(&INK));
            chart.draw_series(std::iter::once(label)).map_err(plot::plot_err)?;
        }
        for (direction, colour) in [("forward", VERMILLION), ("reverse", SKY)] {
            let mut pts: Vec<(f64, f64)> =
                values.iter().filter(|v| v.2 == direction).map(|v| at(v.0, radius(v.1))).collect();
            if let Some(first) = pts.first().copied() {
                pts.push(first);
            }
            chart.draw_series(LineSeries::new(pts, colour.stroke_width(2))).map_err(plot::plot_err)?;
        }
        Ok(())
    })?;
    let entries = [
        (hex(VERMILLION), Key::Line, "synchronous, forward".to_string()),
        (hex(SKY), Key::Line, "synchronous, reverse".to_string()),
        (hex(INK), Key::Thin, format!("the enclosing circles: {:.1} {unit} apart", hi - lo)),
    ];
    Ok(svg + &legend(&entries))
}

/// What a polar plot shows of a point.
type Value = fn(&PolarPoint) -> Option<f64>;

/// The section's body.
pub fn body(m: &ErrorMotions) -> anyhow::Result<String> {
    let mut s = figures_table(m);
    let plots: [(&str, &str, &str, Value); 3] = [
        ("fig-radial-motion", "Radial error motion", "µm", |p| Some(p.radial_um)),
        ("fig-axial-motion", "Axial (face) error motion", "µm", |p| Some(p.axial_um)),
        ("fig-tilt-motion", "Tilt error motion", "µrad", |p| p.tilt_urad),
    ];
    for (id, name, unit, value) in plots {
        if m.polar.iter().all(|p| value(p).is_none()) {
            continue;
        }
        let svg = polar(&m.polar, value, unit)?;
        let caption = format!(
            "{name} (ISO 230-7 polar plot, {unit}): the mean over the runs at each target, plotted about a base \
             circle with the motion magnified; the least-squares centre is the circle fit's, so the centring \
             (once per revolution) is removed. A figure below the detection limit ({:.1} µm) cannot be told \
             from the tracker's own error.",
            m.detection_limit_um
        );
        s += &figure(id, &svg, "", &escape(&caption));
    }
    for n in &m.notes {
        s += &super::note(n);
    }
    s += &format!("<p class=\"note\">{}</p>\n", escape(m.method));
    Ok(s)
}

/// The section, for a survey whose SMR positions give the error motions.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    let Some(m) = &p.d.error_motions else { return Ok(None) };
    Section::page("motions", "The axis's location and error motions (ISO 230-1, ISO 230-7)", body(m)?)
        .map_or(Ok(None), |s| Ok(Some(s)))
}
