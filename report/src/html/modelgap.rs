//! The model-gap steps (`survey report --model FILE` runs model-gap on the
//! survey): how far the residual falls as each missing effect is added,
//! against the noise floor, and what was added.

use super::{Page, Section};
use crate::page::{Key, escape, figure, legend, table};
use crate::plot::{self, BLUE, HEIGHT, INK, VERMILLION, WIDTH, axes, hex, render};
use crate::units::Units;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use survey_modelgap::ModelGap;

fn svg(gap: &ModelGap, units: Units) -> anyhow::Result<String> {
    let mut bars = vec![("model as given".to_string(), gap.rms_before_deg)];
    bars.extend(gap.steps.iter().map(|s| (format!("{}. {}", s.step, s.added), s.rms_deg)));
    let floor = gap.noise_floor_deg;
    let top = bars.iter().map(|b| b.1).fold(floor, f64::max);
    let n = bars.len() as f64;
    render((WIDTH, HEIGHT), |root| {
        let mut chart =
            axes(root, -0.6..n - 0.4, 0.0..units.of(top) * 1.12, "step", &format!("RMS residual, {}", units.symbol()))?;
        chart
            .draw_series(bars.iter().enumerate().map(|(i, b)| {
                let x = i as f64;
                Rectangle::new([(x - 0.32, 0.0), (x + 0.32, units.of(b.1))], BLUE.mix(0.75).filled())
            }))
            .map_err(plot::plot_err)?;
        chart
            .draw_series(DashedLineSeries::new(
                vec![(-0.6, units.of(floor)), (n - 0.4, units.of(floor))],
                6,
                4,
                VERMILLION.stroke_width(2),
            ))
            .map_err(plot::plot_err)?;
        let style = ("sans-serif", 15).into_font().color(&INK).pos(Pos::new(HPos::Center, VPos::Bottom));
        for (i, b) in bars.iter().enumerate() {
            chart
                .draw_series(std::iter::once(Text::new(
                    units.num(b.1),
                    (i as f64, units.of(b.1) + units.of(top) * 0.02),
                    style.clone(),
                )))
                .map_err(plot::plot_err)?;
        }
        Ok(())
    })
}

/// The section: the figure (when there are steps) and the table of steps.
pub fn section(gap: &ModelGap, model_name: &str, units: Units) -> anyhow::Result<String> {
    let mut html = String::new();
    if gap.steps.is_empty() {
        html += &format!(
            "<p id=\"fig-modelgap\" class=\"note\">The model {} explains the survey down to its noise floor ({}): \
             nothing was added.</p>\n",
            escape(model_name),
            units.show(gap.noise_floor_deg)
        );
        return Ok(html);
    }
    let entries = vec![
        (hex(BLUE), Key::Band, "RMS of (measured − model) after each step".to_string()),
        (hex(VERMILLION), Key::Dashed, format!("noise floor ({})", units.show(gap.noise_floor_deg))),
    ];
    let caption = format!(
        "Model-gap: the survey compared with the model {}; step 0 is the model as given, each step adds (or refits) \
         the effect named in the table below. RMS before {}, after {}.",
        escape(model_name),
        units.show(gap.rms_before_deg),
        units.show(gap.rms_after_deg)
    );
    html += &figure("fig-modelgap", &svg(gap, units)?, &legend(&entries), &caption);
    let u = units.symbol();
    let rows: Vec<Vec<String>> = gap
        .steps
        .iter()
        .map(|s| {
            vec![
                s.step.to_string(),
                escape(&units.text(&s.added)),
                format!("{:?}", s.action).to_lowercase(),
                if s.cycles_per_rev > 0.0 { format!("{}", s.cycles_per_rev) } else { "-".into() },
                units.num(s.amplitude_deg),
                units.num(s.rms_deg),
            ]
        })
        .collect();
    html += &table(
        "tbl-modelgap",
        &["step", "change", "action", "cycles/rev", &format!("amplitude, {u}"), &format!("RMS after, {u}")],
        &rows,
    );
    for e in &gap.effects_added {
        html += &format!("<p class=\"note\">{}: {}</p>\n", escape(&e.kind), escape(&units.text(&e.explanation)));
    }
    Ok(html)
}

/// The section, with `--model`.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    match &p.d.model_gap {
        Some((model, gap)) => Ok(Section::page("model-gap", "Model and measurement", section(gap, model, p.units)?)),
        None => Ok(None),
    }
}
