//! The asset's history, when the survey has one (other surveys of its
//! asset made before it, `survey_lab::life::history`): its main lines and its
//! ISO 230-2 accuracy `A` over time, and a table of the surveys with what
//! each check decided.

use super::{Page, Section};
use crate::page::{Key, escape, figure, legend, table_left};
use crate::plot::{
    self, BLUE, GREEN, HEIGHT, ORANGE, PURPLE, SKY, VERMILLION, WIDTH, axes, extent, hex, padded, render,
};
use crate::units::Units;
use plotters::prelude::*;
use survey_lab::life::cache::Figures;
use survey_lab::life::history::History;

/// Days since the first survey of the history, from `created_at` (UTC, RFC 3339).
fn days(h: &History) -> Vec<f64> {
    let at: Vec<f64> = h
        .surveys
        .iter()
        .map(|m| {
            humantime::parse_rfc3339(&m.survey.created_at)
                .ok()
                .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                .map_or(f64::NAN, |d| d.as_secs_f64() / 86_400.0)
        })
        .collect();
    let first = at.iter().copied().find(|v| v.is_finite()).unwrap_or(0.0);
    at.iter().map(|t| t - first).collect()
}

/// The section of survey `this` (the last of `h`); `None` when it is the
/// asset's only survey.
pub fn section(h: &History, this: i64, units: Units) -> anyhow::Result<Option<String>> {
    if h.surveys.len() < 2 {
        return Ok(None);
    }
    figures(h, Some(this), units, false).map(Some)
}

/// The history's figures (the main lines, A and R over time) and its table,
/// survey `this` marked; with `links`, each survey links to its page
/// (`/surveys/<uid>`, `survey serve`'s).
pub fn figures(h: &History, this: Option<i64>, units: Units, links: bool) -> anyhow::Result<String> {
    let t = days(h);
    // The lines: the largest few of the surveys' main lines, each followed over time.
    let mut cycles: Vec<f64> = Vec::new();
    for m in h.surveys.iter().rev() {
        for l in &m.summary.lines {
            if cycles.len() < 5 && !cycles.contains(&l.cycles_per_rev) {
                cycles.push(l.cycles_per_rev);
            }
        }
    }
    let colours = [BLUE, VERMILLION, GREEN, PURPLE, ORANGE];
    let series: Vec<(f64, Vec<(f64, f64)>)> = cycles
        .iter()
        .map(|&k| {
            let points = h
                .surveys
                .iter()
                .zip(&t)
                .filter_map(|(m, &d)| {
                    let l = m.summary.lines.iter().find(|l| l.cycles_per_rev == k)?;
                    Some((d, units.of(l.amplitude_deg)))
                })
                .collect();
            (k, points)
        })
        .collect();
    let (t0, t1) = extent(t.iter().copied());
    let (_, hi) = extent(series.iter().flat_map(|(_, p)| p.iter().map(|q| q.1)));
    let x_desc = "days since the asset's first survey";
    let lines_svg = render((WIDTH, HEIGHT), |root| {
        let mut chart =
            axes(root, padded(t0, t1, 0.03), padded(0.0, hi, 0.08), x_desc, &format!("amplitude, {}", units.symbol()))?;
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
            "The main lines of the asset {} over time: each survey's lines that its table corrects ({}).",
            escape(&h.asset),
            escape(units.symbol())
        ),
    );
    let iso = |f: fn(&Figures) -> f64| -> Vec<(f64, f64)> {
        h.surveys.iter().zip(&t).filter_map(|(m, &d)| m.summary.iso.as_ref().map(|i| (d, units.of(f(i))))).collect()
    };
    let (a, r) = (iso(|i| i.a), iso(|i| i.r));
    let (lo, hi) = extent(a.iter().chain(&r).map(|p| p.1));
    let a_svg = render((WIDTH, HEIGHT * 3 / 4), |root| {
        let mut chart = axes(
            root,
            padded(t0, t1, 0.03),
            padded(lo.min(0.0), hi, 0.08),
            x_desc,
            &format!("A and R, {}", units.symbol()),
        )?;
        for (points, colour) in [(&a, SKY), (&r, ORANGE)] {
            chart.draw_series(LineSeries::new(points.clone(), colour.stroke_width(2))).map_err(plot::plot_err)?;
            chart.draw_series(points.iter().map(|&p| Circle::new(p, 4, colour.filled()))).map_err(plot::plot_err)?;
        }
        Ok(())
    })?;
    html += &figure(
        "fig-history-a",
        &a_svg,
        &legend(&[
            (hex(SKY), Key::Line, "ISO 230-2 accuracy A".into()),
            (hex(ORANGE), Key::Line, "ISO 230-2 repeatability R".into()),
        ]),
        &format!("ISO 230-2 accuracy A and repeatability R of each survey of the asset ({}).", escape(units.symbol())),
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
                units.opt(m.summary.table_u_deg),
                escape(&decided),
            ]
        })
        .collect();
    let head = ["survey", "made (UTC)", "kind", "A", "R", "table U", "check"];
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
