//! The asset's history, when the survey has one (other surveys of its
//! asset made before it, `survey_lab::life::history`): its main lines and its
//! ISO 230-2 accuracy `A` over time, and a table of the surveys with what
//! each check decided.

use super::{Page, Section};
use crate::page::{Key, escape, figure, legend, table_left};
use crate::plot::{
    self, BLUE, GREEN, HEIGHT, ORANGE, PURPLE, SKY, VERMILLION, WIDTH, extent, hex, padded, padded_time, render,
    time_axes,
};
use crate::units::Units;
use plotters::prelude::*;
use survey_lab::life::cache::Figures;
use survey_lab::life::history::History;

/// When each survey of the history was made: seconds since 1970 (UTC),
/// from `created_at` (RFC 3339); NaN where it does not parse.
fn times(h: &History) -> Vec<f64> {
    h.surveys
        .iter()
        .map(|m| {
            humantime::parse_rfc3339(&m.survey.created_at)
                .ok()
                .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                .map_or(f64::NAN, |d| d.as_secs_f64())
        })
        .collect()
}

/// The section of survey `this` (the last of `h`); `None` when it is the
/// asset's only survey.
pub fn section(h: &History, this: i64, units: Units) -> anyhow::Result<Option<String>> {
    if h.surveys.len() < 2 {
        return Ok(None);
    }
    figures(h, Some(this), units, false).map(Some)
}

/// The most lines the lines plot follows.
const MAX_LINES: usize = 5;

/// The main lines the calibrations found, the largest first (each by its
/// largest amplitude over the calibrations), at most [`MAX_LINES`].
fn main_cycles(h: &History) -> Vec<f64> {
    let mut largest: Vec<(f64, f64)> = Vec::new();
    for m in h.surveys.iter().filter(|m| m.kind() == "calibration") {
        for l in &m.summary.lines {
            match largest.iter_mut().find(|(k, _)| same_line(*k, l.cycles_per_rev)) {
                Some((_, a)) => *a = a.max(l.amplitude_deg),
                None => largest.push((l.cycles_per_rev, l.amplitude_deg)),
            }
        }
    }
    largest.sort_by(|a, b| b.1.total_cmp(&a.1));
    largest.into_iter().take(MAX_LINES).map(|(k, _)| k).collect()
}

fn same_line(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-6
}

/// The history's figures (the main lines, A and R over time, calibrations
/// and checks told apart) and its table, survey `this` marked; with `links`,
/// each survey links to its page (`/surveys/<uid>`, `survey serve`'s).
pub fn figures(h: &History, this: Option<i64>, units: Units, links: bool) -> anyhow::Result<String> {
    let t = times(h);
    let of_kind = |kind: &'static str| move |(m, _): &(&survey_lab::life::history::Entry, &f64)| m.kind() == kind;
    // The lines: every calibration's, each followed over time (a check's
    // fewer targets see its lines at other bins: they are not plotted here).
    let cycles = main_cycles(h);
    let colours = [BLUE, VERMILLION, GREEN, PURPLE, ORANGE];
    let series: Vec<(f64, Vec<(f64, f64)>)> = cycles
        .iter()
        .map(|&k| {
            let points = h
                .surveys
                .iter()
                .zip(&t)
                .filter(of_kind("calibration"))
                .filter_map(|(m, &d)| {
                    let l = m.summary.lines.iter().find(|l| same_line(l.cycles_per_rev, k))?;
                    Some((d, units.of(l.amplitude_deg)))
                })
                .collect();
            (k, points)
        })
        .collect();
    let x = padded_time(extent(t.iter().copied()).0, extent(t.iter().copied()).1);
    let (_, hi) = extent(series.iter().flat_map(|(_, p)| p.iter().map(|q| q.1)));
    let lines_svg = render((WIDTH, HEIGHT), |root| {
        let mut chart = time_axes(root, x.clone(), padded(0.0, hi, 0.08), &format!("amplitude, {}", units.symbol()))?;
        for ((_, points), colour) in series.iter().zip(colours) {
            chart.draw_series(LineSeries::new(points.clone(), colour.stroke_width(2))).map_err(plot::plot_err)?;
            chart.draw_series(points.iter().map(|&p| Circle::new(p, 4, colour.filled()))).map_err(plot::plot_err)?;
        }
        Ok(())
    })?;
    let entries: Vec<_> =
        series.iter().zip(colours).map(|((k, _), c)| (hex(c), Key::Line, format!("{k} cycles/rev"))).collect();
    let mut html = figure(
        "fig-history-lines",
        &lines_svg,
        &legend(&entries),
        &format!(
            "The main lines of the asset {} over time: the lines each calibration's table corrects ({}); a line \
             missing at a calibration was below its detection threshold there.",
            escape(&h.asset),
            escape(units.symbol())
        ),
    );
    let iso = |kind: &'static str, f: fn(&Figures) -> f64| -> Vec<(f64, f64)> {
        h.surveys
            .iter()
            .zip(&t)
            .filter(of_kind(kind))
            .filter_map(|(m, &d)| m.summary.iso.as_ref().map(|i| (d, units.of(f(i)))))
            .collect()
    };
    let (a, r) = (iso("calibration", |i| i.a), iso("calibration", |i| i.r));
    let (check_a, check_r) = (iso("check", |i| i.a), iso("check", |i| i.r));
    let (lo, hi) = extent(a.iter().chain(&r).chain(&check_a).chain(&check_r).map(|p| p.1));
    let a_svg = render((WIDTH, HEIGHT * 3 / 4), |root| {
        let mut chart =
            time_axes(root, x.clone(), padded(lo.min(0.0), hi, 0.08), &format!("A and R, {}", units.symbol()))?;
        for (points, colour) in [(&a, SKY), (&r, ORANGE)] {
            chart.draw_series(LineSeries::new(points.clone(), colour.stroke_width(2))).map_err(plot::plot_err)?;
            chart.draw_series(points.iter().map(|&p| Circle::new(p, 4, colour.filled()))).map_err(plot::plot_err)?;
        }
        for (points, colour) in [(&check_a, SKY), (&check_r, ORANGE)] {
            chart
                .draw_series(points.iter().map(|&p| TriangleMarker::new(p, 6, colour.stroke_width(2))))
                .map_err(plot::plot_err)?;
        }
        Ok(())
    })?;
    let mut keys = vec![
        (hex(SKY), Key::Line, "A of a calibration".to_string()),
        (hex(ORANGE), Key::Line, "R of a calibration".to_string()),
    ];
    if !check_a.is_empty() {
        keys.push((hex(SKY), Key::Ring, "A of a check (its own, fewer targets: not comparable)".to_string()));
        keys.push((hex(ORANGE), Key::Ring, "R of a check".to_string()));
    }
    html += &figure(
        "fig-history-a",
        &a_svg,
        &legend(&keys),
        &format!(
            "ISO 230-2 accuracy A and repeatability R of the asset's calibrations (joined) and checks (open \
             triangles) ({}).",
            escape(units.symbol())
        ),
    );
    let rows: Vec<Vec<String>> = h
        .surveys
        .iter()
        .map(|m| {
            let s = &m.survey;
            let mark = if Some(s.id) == this { " (this survey)" } else { "" };
            let id =
                if links { format!("<a href=\"/surveys/{}\">{}</a>", escape(&s.uid), s.id) } else { s.id.to_string() };
            let decided = h.checks.iter().find(|c| c.survey_id == s.id).map_or(String::new(), |c| {
                format!("{}{}", c.verdict, if c.recalibrate { ", recalibrate" } else { ", in tolerance" })
            });
            vec![
                format!("{id}{mark}"),
                escape(&s.created_at),
                m.kind().to_string(),
                units.opt(m.summary.iso.as_ref().map(|i| i.a)),
                units.opt(m.summary.iso.as_ref().map(|i| i.r)),
                // As the certificate states a U: two significant digits, rounded up.
                m.summary.table_u_deg.map_or_else(|| "-".into(), |u| crate::rounding::num_u(units, u)),
                escape(&decided),
            ]
        })
        .collect();
    let u = units.symbol();
    let (a, r, table_u) = (format!("A, {u}"), format!("R, {u}"), format!("table U, {u}"));
    let head = ["survey", "made (UTC)", "kind", &a, &r, &table_u, "check"];
    html += &table_left("tbl-history", &head, &rows, &[1, 2, 6]);
    for (a, b, c) in &h.changes {
        if c.verdict == survey_modelgap::compare::Verdict::Changed {
            html += &format!(
                "<p class=\"note\">From survey {} to survey {}: {}.</p>\n",
                h.surveys[*a].survey.id,
                h.surveys[*b].survey.id,
                escape(&c.reason)
            );
        }
    }
    Ok(html)
}

/// The section, when the survey's asset has a history.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    let Some(h) = &p.d.history else { return Ok(None) };
    Ok(section(h, p.d.survey.id, p.units)?.and_then(|body| Section::page("history", "The asset's history", body)))
}

/// The checks' control chart drawn as a control chart is (issue 53): each
/// check's statistic in the order the checks were made, the centre line and
/// the 3-sigma limits where the chart has a baseline, the line at 1 (the
/// table no longer holds), and a check out of control marked; `None`
/// before any check measured its statistic.
pub fn control_chart(h: &History) -> anyhow::Result<Option<String>> {
    let chart = h.control();
    let at = |i: usize| (i + 1) as f64;
    let points: Vec<(f64, f64)> =
        chart.iter().enumerate().filter_map(|(i, p)| p.statistic.map(|s| (at(i), s))).collect();
    if points.is_empty() {
        return Ok(None);
    }
    let line = |f: &dyn Fn(&survey_lab::life::control::Point) -> Option<f64>| -> Vec<(f64, f64)> {
        chart.iter().enumerate().filter_map(|(i, p)| f(p).map(|v| (at(i), v))).collect()
    };
    let (centre, upper, lower) = (line(&|p| p.centre), line(&|p| p.upper()), line(&|p| p.lower()));
    let out: Vec<(f64, f64)> = chart
        .iter()
        .enumerate()
        .filter_map(|(i, p)| p.statistic.filter(|_| p.out_of_control()).map(|s| (at(i), s)))
        .collect();
    let n = chart.len().max(2) as f64;
    let (_, hi) = extent(points.iter().chain(&upper).map(|p| p.1).chain([1.0]));
    let svg = render((WIDTH, HEIGHT), |root| {
        let mut c = plot::axes(
            root,
            padded(1.0, n, 0.05),
            padded(0.0, hi, 0.08),
            "check, in the order made",
            "cells beyond U / (allowed + 1)",
        )?;
        c.draw_series(LineSeries::new(vec![(1.0, 1.0), (n, 1.0)], RGBColor(128, 128, 128).stroke_width(1)))
            .map_err(plot::plot_err)?;
        for (limit, width) in [(&upper, 2), (&lower, 2)] {
            c.draw_series(DashedLineSeries::new(limit.clone(), 6, 4, VERMILLION.stroke_width(width)))
                .map_err(plot::plot_err)?;
        }
        c.draw_series(LineSeries::new(centre.clone(), GREEN.stroke_width(2))).map_err(plot::plot_err)?;
        c.draw_series(LineSeries::new(points.clone(), BLUE.stroke_width(2))).map_err(plot::plot_err)?;
        c.draw_series(points.iter().map(|&p| Circle::new(p, 4, BLUE.filled()))).map_err(plot::plot_err)?;
        c.draw_series(out.iter().map(|&p| Circle::new(p, 8, VERMILLION.stroke_width(3)))).map_err(plot::plot_err)?;
        Ok(())
    })?;
    let keys = legend(&[
        (hex(BLUE), Key::Line, "each check's statistic".into()),
        (hex(GREEN), Key::Line, "centre line (the checks in control before it)".into()),
        (hex(VERMILLION), Key::Dashed, "3-sigma control limits".into()),
        (hex(VERMILLION), Key::Ring, "out of control".into()),
        ("#808080".into(), Key::Thin, "1: the table in force no longer holds".into()),
    ]);
    Ok(Some(figure(
        "fig-control",
        &svg,
        &keys,
        "The asset's checks on their control chart: a check beyond a limit (or a run of them) is out of control and \
         recalibrates, even inside tolerance.",
    )))
}
