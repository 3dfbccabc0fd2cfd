//! The interpolation comparison (the paper's Figure 6): keep every other
//! measured point, predict the ones left out with each of the four methods
//! (a fixed value, linear, quadratic, spectral resampling), and show the
//! curves over the stretch where linear interpolation misses most, beside
//! the scores over the whole revolution.

use super::{Page, Section};
use crate::page::{Key, escape, figure, legend, table};
use crate::plot::{self, BLUE, GREEN, HEIGHT, INK, ORANGE, SKY, WIDTH, axes, extent, hex, padded, render};
use crate::units::{Units, angle};
use plotters::prelude::*;
use survey_processing::errormap::Coverage;
use survey_processing::resample::{Method, Resampler, upsample};
use survey_tables::pipeline::Processed;

/// Points drawn between two kept samples.
const FACTOR: usize = 16;
/// Kept samples shown in the window.
const WINDOW: usize = 12;

fn colour(m: Method) -> RGBColor {
    match m {
        Method::Fixed => ORANGE,
        Method::Linear => SKY,
        Method::Quadratic => GREEN,
        Method::Spectral => BLUE,
    }
}

/// The mean map the comparison was made on (as the pipeline makes it).
fn series(p: &Processed) -> Option<(&[f64], f64, f64)> {
    let m = &p.analysis.error_map;
    let Coverage::FullCircle { n } = m.coverage else { return None };
    let y = m
        .bidirectional_mean_deg
        .as_ref()
        .or(m.forward.as_ref().map(|d| &d.mean_deg))
        .or(m.reverse.as_ref().map(|d| &d.mean_deg))?;
    (n % 2 == 0 && n >= 2 * WINDOW).then(|| (y.as_slice(), m.targets_deg[0], 360.0 / n as f64))
}

fn svg(y: &[f64], start: f64, step: f64, units: Units) -> anyhow::Result<String> {
    let n = y.len();
    let kept: Vec<f64> = y.iter().step_by(2).copied().collect();
    // Where linear interpolation misses most: the window is centred there.
    let worst = (1..n)
        .step_by(2)
        .max_by(|&a, &b| {
            let miss = |j: usize| ((y[j - 1] + y[(j + 1) % n]) / 2.0 - y[j]).abs();
            miss(a).total_cmp(&miss(b))
        })
        .unwrap_or(1);
    let half = kept.len();
    let lo = (worst / 2).saturating_sub(WINDOW / 2).min(half - WINDOW);
    let hi = lo + WINDOW;
    let x_at = |i: usize| start + i as f64 * step;
    let mut rs = Resampler::new();
    let curves: Vec<(Method, Vec<(f64, f64)>)> = Method::ALL
        .iter()
        .map(|&m| {
            let up = upsample(m, &kept, FACTOR, &mut rs);
            let pts = (lo * FACTOR..=hi * FACTOR)
                .map(|i| (start + i as f64 * 2.0 * step / FACTOR as f64, units.of(up[i % up.len()])))
                .collect();
            (m, pts)
        })
        .collect();
    let measured: Vec<(usize, f64)> = (2 * lo..=2 * hi).map(|i| (i, units.of(y[i % n]))).collect();
    let (ylo, yhi) = extent(curves.iter().flat_map(|c| c.1.iter().map(|p| p.1)).chain(measured.iter().map(|m| m.1)));
    render((WIDTH, HEIGHT), |root| {
        let mut chart = axes(
            root,
            padded(x_at(2 * lo), x_at(2 * hi), 0.02),
            padded(ylo, yhi, 0.1),
            "target angle, deg",
            &format!("mean error, {}", units.symbol()),
        )?;
        for (m, pts) in &curves {
            let width = if *m == Method::Spectral { 3 } else { 2 };
            chart.draw_series(LineSeries::new(pts.clone(), colour(*m).stroke_width(width))).map_err(plot::plot_err)?;
        }
        for &(i, v) in &measured {
            let style = if i % 2 == 0 { INK.filled() } else { INK.stroke_width(2) };
            chart.draw_series(std::iter::once(Circle::new((x_at(i), v), 5, style))).map_err(plot::plot_err)?;
        }
        Ok(())
    })
}

/// The section: the figure (full circle only) and the scores.
pub fn section(p: &Processed, units: Units) -> anyhow::Result<String> {
    let mut html = String::new();
    match series(p) {
        Some((y, start, step)) => {
            let entries: Vec<_> = Method::ALL
                .iter()
                .map(|&m| (hex(colour(m)), Key::Line, format!("{} interpolation from the kept points", m.as_str())))
                .chain([
                    (hex(INK), Key::Dot, "measured, kept (every other point)".to_string()),
                    (hex(INK), Key::Ring, "measured, left out: what each method must predict".to_string()),
                ])
                .collect();
            let caption = format!(
                "Interpolation between measured points (the paper's Figure 6): every other point of the mean error \
                 ({} points per revolution) is kept and the ones between are predicted by each method. Shown: the \
                 {WINDOW} kept steps around the point linear interpolation misses most. Spectral resampling is what \
                 the table is made with.",
                y.len()
            );
            html += &figure("fig-interpolation", &svg(y, start, step, units)?, &legend(&entries), &escape(&caption));
        }
        None => {
            let why = match p.analysis.error_map.coverage {
                Coverage::Partial { start, end, .. } => format!(
                    "The survey measured a partial arc ({} to {} deg), so the comparison cannot be drawn: it keeps \
                     every other point of a periodic map over the whole revolution and resamples it spectrally. \
                     On a partial arc the table is a least-squares fit over the measured span instead (see the \
                     correction table).",
                    angle(start),
                    angle(end)
                ),
                Coverage::FullCircle { n } => format!(
                    "The comparison keeps every other one of an even number of evenly spaced targets; this survey \
                     has {n}, so it cannot be drawn."
                ),
            };
            html += &format!("<p id=\"fig-interpolation\" class=\"note\">{}</p>\n", escape(&why));
        }
    }
    match &p.interpolation {
        Ok(scores) => {
            let rows: Vec<Vec<String>> = scores
                .iter()
                .map(|s| vec![s.method.as_str().to_string(), units.num(s.rms_deg), units.num(s.peak_deg)])
                .collect();
            let u = units.symbol();
            html +=
                &table("tbl-interpolation", &["method", &format!("RMS miss, {u}"), &format!("peak miss, {u}")], &rows);
            html += "<p class=\"note\">Scores over the whole revolution: prediction minus measurement at every point \
                     left out (its noise included).</p>\n";
        }
        Err(why) => html += &format!("<p class=\"note\">No interpolation scores: {}.</p>\n", escape(why)),
    }
    Ok(html)
}

/// The section, when the survey was processed.
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    match p.processed() {
        Some(processed) => {
            Ok(Section::page("interpolation", "Interpolation between measured points", section(processed, p.units)?))
        }
        None => Ok(None),
    }
}
