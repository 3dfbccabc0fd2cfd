//! The spectrum (the paper's Figures 4 and 5): amplitude against cycles per
//! revolution, every significant line labelled by its source, each alias drawn
//! where it was observed and, dashed, where it belongs, the frequency axis
//! sized to the lines (not to half the sampling rate), and the table of lines.

use super::{Page, Section, note};
use crate::page::{self, Key, escape, figure, legend};
use crate::plot::{self, BLUE, GREY, INK, ORANGE, PURPLE, VERMILLION, WIDTH, axes, hex, nice_ceil, render};
use crate::units::{Units, percent};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use survey_processing::analysis::{Line, Method};
use survey_tables::pipeline::Processed;
use survey_tables::recipe::{AliasOutcome, LineAction};

/// Canvas height: the top part is the lane the labels stand in.
const HEIGHT: u32 = 600;
/// The data use the lower part of the plot; the labels stand above.
const DATA_FRACTION: f64 = 0.55;
/// Labels longer than this are cut (they stand upright in the lane).
const LABEL_CHARS: usize = 30;
const LABEL_FONT: u32 = 15;
/// A label's foot stands this many pixels above its stem's top.
pub const LABEL_LIFT: i32 = 8;

/// A short name of a line's source for its label: `12:1 pinion ×2`,
/// `216-tooth gear ×2`, `ellipticity`, `216-tooth mesh -1×12:1 sideband`.
pub fn short_name(line: &Line) -> String {
    let kind = line.source.split(':').next().unwrap_or("").trim();
    let primary = line.explanation.split("; also").next().unwrap_or("").trim();
    let name = if kind == "eccentricity" || kind == "ellipticity" {
        kind.to_string()
    } else if primary.contains("matches no part of the design") {
        "unexplained".to_string()
    } else if let Some(rest) = primary.strip_prefix("sideband of the ") {
        match rest.split_once(" at ") {
            Some((mesh, tail)) => format!(
                "{} {} sideband",
                mesh.replace(" mesh", ""),
                tail.replace(" x the ", "×").replace(" gear pass", "")
            ),
            None => rest.to_string(),
        }
    } else {
        let base = if line.aliased { primary.split(" at ").next().unwrap_or(primary) } else { primary };
        let base = base.strip_suffix(", harmonic 1").unwrap_or(base);
        base.replace(", harmonic 1 (fundamental)", "").replace(", harmonic ", " ×")
    };
    cut(&name, LABEL_CHARS)
}

/// A line's source in words: the processing's `kind: explanation` with the
/// kind as a reader says it (`gear_pass: 20:1 pinion, harmonic 2` becomes
/// `gear pass: 20:1 pinion, harmonic 2`).
pub fn source_words(source: &str) -> String {
    let Some((kind, rest)) = source.split_once(": ") else { return source.to_string() };
    let word = match kind.trim() {
        "eccentricity" => "eccentricity (once a revolution)",
        "ellipticity" => "ellipticity (twice a revolution)",
        "gear_pass" => "gear pass",
        "tooth_mesh" => "tooth mesh",
        "harmonic" => "periodic error",
        _ => return source.to_string(),
    };
    format!("{word}: {rest}")
}

fn cut(s: &str, n: usize) -> String {
    if s.chars().count() <= n { s.to_string() } else { s.chars().take(n - 1).collect::<String>() + "…" }
}

fn num(v: f64) -> String {
    if (v - v.round()).abs() < 1e-9 { format!("{}", v.round() as i64) } else { format!("{v:.2}") }
}

/// One stem of the figure: where, how high, how drawn, what it says.
struct Stem {
    cycles: f64,
    amplitude_deg: f64,
    colour: RGBColor,
    dashed: bool,
    label: String,
}

/// The line's fate in the table.
fn fate(p: &Processed, line: &Line) -> Option<LineAction> {
    p.decisions.lines.iter().find(|d| (d.cycles_per_rev - line.cycles_per_rev).abs() < 1e-9).map(|d| d.action)
}

fn fate_word(a: Option<LineAction>) -> &'static str {
    match a {
        Some(LineAction::Kept) => "kept",
        Some(LineAction::Removed) => "removed",
        Some(LineAction::Relocated) => "relocated",
        Some(LineAction::Nulled) => "nulled",
        None => "-",
    }
}

/// The stems: every significant line, and each alias at its true frequency.
fn stems(p: &Processed) -> Vec<Stem> {
    let a = &p.analysis;
    let mut out: Vec<Stem> = a
        .lines
        .iter()
        .map(|l| {
            let mut label = format!("{} · {}", num(l.cycles_per_rev), short_name(l));
            if l.aliased {
                label =
                    cut(&format!("{} · alias of {}", num(l.cycles_per_rev), num(l.true_cycles_per_rev)), LABEL_CHARS);
            }
            Stem {
                cycles: l.cycles_per_rev,
                amplitude_deg: l.amplitude_deg,
                colour: if l.aliased {
                    PURPLE
                } else if l.repeatable {
                    BLUE
                } else {
                    ORANGE
                },
                dashed: false,
                label,
            }
        })
        .collect();
    for alias in &p.decisions.aliases {
        let seen = a.lines.iter().find(|l| (l.cycles_per_rev - alias.observed_cycles).abs() < 1e-9);
        let Some(seen) = seen else { continue };
        let what = match alias.action {
            AliasOutcome::Relocated => "relocated here",
            AliasOutcome::Nulled => "belongs here, nulled",
        };
        out.push(Stem {
            cycles: alias.true_cycles,
            amplitude_deg: seen.amplitude_deg,
            colour: if alias.action == AliasOutcome::Relocated { PURPLE } else { GREY },
            dashed: true,
            label: cut(&format!("{} · {what}", num(alias.true_cycles)), LABEL_CHARS),
        });
    }
    out
}

/// The frequency axis: past the highest line by a margin, to a round number.
pub fn x_max(stems_at: impl IntoIterator<Item = f64>) -> f64 {
    let top = stems_at.into_iter().fold(0.0f64, f64::max);
    if top <= 0.0 {
        return 10.0;
    }
    let tick = nice_ceil(top / 10.0);
    ((top * 1.04 + tick * 0.2) / tick).ceil() * tick
}

/// Labels at least `gap` pixels apart and inside `left..=right`, each as
/// near its stem as it can be (stems sorted by position; pushed right, then
/// the run pulled back left if it leaves the plot).
fn spread(xs: &[i32], gap: i32, left: i32, right: i32) -> Vec<i32> {
    let mut out: Vec<i32> = Vec::with_capacity(xs.len());
    for &x in xs {
        let want = out.last().map_or(x.max(left), |&p| x.max(p + gap));
        out.push(want);
    }
    let mut limit = right;
    for v in out.iter_mut().rev() {
        *v = (*v).min(limit);
        limit = *v - gap;
    }
    out
}

/// Where the band above half the sampling rate starts, when the figure
/// reaches it (a DFT whose lines, or aliases' true frequencies, lie past it).
fn shaded(p: &Processed) -> Option<f64> {
    let right = x_max(stems(p).iter().map(|s| s.cycles));
    let a = &p.analysis;
    (a.method == Method::Dft).then_some(a.points_per_rev / 2.0).filter(|ny| *ny < right)
}

fn svg(p: &Processed, units: Units) -> anyhow::Result<String> {
    let a = &p.analysis;
    let mut stems = stems(p);
    stems.sort_by(|x, y| x.cycles.total_cmp(&y.cycles));
    let right = x_max(stems.iter().map(|s| s.cycles));
    let bins: Vec<(f64, f64)> = a
        .spectra
        .as_ref()
        .map(|s| {
            s.mean
                .bins
                .iter()
                .filter(|b| b.cycles_per_rev > 0.0 && b.cycles_per_rev <= right)
                .map(|b| (b.cycles_per_rev, units.of(b.amplitude_deg)))
                .collect()
        })
        .unwrap_or_default();
    let threshold = units.of(a.noise.coherent_threshold_deg);
    let top = stems.iter().map(|s| units.of(s.amplitude_deg)).chain(bins.iter().map(|b| b.1)).fold(threshold, f64::max);
    let y_top = top / DATA_FRACTION;
    render((WIDTH, HEIGHT), |root| {
        let mut chart = axes(
            root,
            0.0..right,
            0.0..y_top,
            "cycles per revolution",
            &format!("amplitude of the mean error, {}", units.symbol()),
        )?;
        if let Some(ny) = shaded(p) {
            chart
                .draw_series(std::iter::once(Rectangle::new([(ny, 0.0), (right, y_top)], GREY.mix(0.10).filled())))
                .map_err(plot::plot_err)?;
        }
        chart
            .draw_series(bins.iter().map(|&(k, amp)| PathElement::new(vec![(k, 0.0), (k, amp)], GREY.stroke_width(1))))
            .map_err(plot::plot_err)?;
        chart
            .draw_series(DashedLineSeries::new(
                vec![(0.0, threshold), (right, threshold)],
                6,
                4,
                VERMILLION.stroke_width(2),
            ))
            .map_err(plot::plot_err)?;
        for s in &stems {
            let amp = units.of(s.amplitude_deg);
            let style = s.colour.stroke_width(3);
            if s.dashed {
                chart
                    .draw_series(DashedLineSeries::new(vec![(s.cycles, 0.0), (s.cycles, amp)], 6, 4, style))
                    .map_err(plot::plot_err)?;
            } else {
                chart
                    .draw_series(std::iter::once(PathElement::new(vec![(s.cycles, 0.0), (s.cycles, amp)], style)))
                    .map_err(plot::plot_err)?;
            }
        }
        // The aliases' arrows: from where each was observed to where it belongs.
        for alias in &p.decisions.aliases {
            if let Some(seen) = a.lines.iter().find(|l| (l.cycles_per_rev - alias.observed_cycles).abs() < 1e-9) {
                let y = units.of(seen.amplitude_deg);
                let pts = vec![(alias.observed_cycles, y), (alias.true_cycles, y)];
                chart
                    .draw_series(DashedLineSeries::new(pts, 3, 3, PURPLE.mix(0.6).stroke_width(1)))
                    .map_err(plot::plot_err)?;
            }
        }
        // Labels upright, each standing on its own stem's top (the lines
        // are tallest at 55 % of the plot, so the tallest label fits above),
        // spread apart sideways, with a short leader from the stem.
        let (plot_left, plot_right) = (chart.backend_coord(&(0.0, 0.0)).0, chart.backend_coord(&(right, 0.0)).0);
        let tops: Vec<(i32, i32)> =
            stems.iter().map(|s| chart.backend_coord(&(s.cycles, units.of(s.amplitude_deg)))).collect();
        let xs = spread(
            &tops.iter().map(|t| t.0).collect::<Vec<_>>(),
            LABEL_FONT as i32 + 3,
            plot_left + 10,
            plot_right - 4,
        );
        let font = ("sans-serif", LABEL_FONT).into_font().color(&INK).transform(FontTransform::Rotate270);
        for ((s, (tx, ty)), lx) in stems.iter().zip(&tops).zip(&xs) {
            let foot = ty - LABEL_LIFT;
            root.draw(&PathElement::new(vec![(*tx, *ty - 2), (*lx, foot + 2)], s.colour.mix(0.5).stroke_width(1)))
                .map_err(plot::plot_err)?;
            let style = font.clone().pos(Pos::new(HPos::Left, VPos::Center));
            root.draw(&Text::new(s.label.clone(), (*lx, foot), style)).map_err(plot::plot_err)?;
        }
        Ok(())
    })
}

/// The section: the figure, its legend and caption, and the table of lines.
pub fn section(p: &Processed, units: Units) -> anyhow::Result<String> {
    let a = &p.analysis;
    let mut html = String::new();
    let mut entries = vec![
        (hex(BLUE), Key::Line, "significant, repeatable line".to_string()),
        (hex(ORANGE), Key::Line, "significant, not repeatable".to_string()),
        (
            hex(VERMILLION),
            Key::Dashed,
            format!("significance threshold ({})", units.show(a.noise.coherent_threshold_deg)),
        ),
    ];
    if a.spectra.is_some() {
        entries.push((hex(GREY), Key::Thin, "every bin of the mean spectrum".to_string()));
    }
    if shaded(p).is_some() {
        entries.push((hex(GREY), Key::Band, "above half the sampling rate: seen only as an alias".to_string()));
    }
    if !p.decisions.aliases.is_empty() {
        entries.push((hex(PURPLE), Key::Line, "an alias, where it was observed".to_string()));
        entries.push((hex(PURPLE), Key::Dashed, "the same, where it belongs (relocated)".to_string()));
        entries.push((hex(GREY), Key::Dashed, "where it belongs (nulled: not in the table)".to_string()));
    }
    let method = match (a.method, &a.spectra) {
        (Method::Dft, _) => format!(
            "the DFT of the mean error over the runs ({} points per revolution{})",
            num(a.points_per_rev),
            if shaded(p).is_some() { "; shaded: above half of it, where a line is only seen as an alias" } else { "" }
        ),
        (Method::LeastSquares, Some(_)) => "the lines from a least-squares fit of sinusoids at the design's \
             frequencies (a partial range is not periodic); grey: the windowed DFT of the measured span, whose bins \
             are 360/span apart and leak into their neighbours"
            .to_string(),
        (Method::LeastSquares, None) => "the lines from a least-squares fit of sinusoids at the design's \
             frequencies (a partial range is not periodic)"
            .to_string(),
    };
    let caption = format!(
        "Spectrum of the readout error in cycles per revolution: {method}. Each significant line is labelled with \
         its frequency and the part of the design it comes from; the axis ends just past the highest line."
    );
    html += &figure("fig-spectrum", &svg(p, units)?, &legend(&entries), &escape(&caption));
    let rows: Vec<Vec<String>> = a
        .lines
        .iter()
        .map(|l| {
            vec![
                num(l.cycles_per_rev),
                num(l.true_cycles_per_rev),
                units.num(l.amplitude_deg),
                format!("{:.1}", l.phase_deg),
                if l.repeatable { "yes" } else { "no" }.to_string(),
                percent(l.share),
                fate_word(fate(p, l)).to_string(),
                escape(&units.text(&source_words(&l.source))),
            ]
        })
        .collect();
    html += "<h3>Significant lines</h3>\n";
    html += &page::table_left(
        "tbl-lines",
        &[
            "cycles/rev",
            "true cycles/rev",
            &format!("amplitude, {}", units.symbol()),
            "phase, deg",
            "repeatable",
            "share",
            "in the table",
            "source",
        ],
        &rows,
        &[7],
    );
    for alias in &p.decisions.aliases {
        let action = match alias.action {
            AliasOutcome::Relocated => "relocated to its true frequency",
            AliasOutcome::Nulled => "nulled",
        };
        html += &format!(
            "<p class=\"note\">Alias: {} at {} cycles/rev is seen at {}; {action}.</p>\n",
            escape(&units.text(&source_words(&alias.source))),
            num(alias.true_cycles),
            num(alias.observed_cycles),
        );
    }
    if let Some(n) = &a.points_needed {
        html += &format!("<p class=\"note\">{}</p>\n", escape(&units.text(&n.note)));
    }
    Ok(html)
}

/// The section, or why the survey could not be processed (which the
/// interpolation and the table then do not repeat).
pub fn show(p: &Page<'_>) -> anyhow::Result<Option<Section>> {
    match &p.d.processed {
        Ok(processed) => Ok(Section::page("spectrum", "Spectrum and error sources", section(processed, p.units)?)),
        Err(why) => Ok(Section::page(
            "spectrum",
            "Spectrum, interpolation and correction table",
            note(&format!("The survey cannot be processed: {why}.")),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_source_is_in_words() {
        assert_eq!(
            source_words("gear_pass: 12:1 pinion, harmonic 1 (fundamental)"),
            "gear pass: 12:1 pinion, harmonic 1 (fundamental)"
        );
        assert_eq!(source_words("tooth_mesh: 216-tooth gear, harmonic 3"), "tooth mesh: 216-tooth gear, harmonic 3");
        assert_eq!(
            source_words("harmonic: matches no part of the design"),
            "periodic error: matches no part of the design"
        );
        assert_eq!(source_words("no kind here"), "no kind here");
    }

    #[test]
    fn the_axis_ends_just_past_the_highest_line() {
        assert_eq!(x_max([1.0, 2.0, 6.0, 36.0, 72.0]), 80.0);
        assert_eq!(x_max([20.0, 40.0]), 45.0);
        assert_eq!(x_max([12.0, 288.0, 432.0, 648.0]), 700.0);
        assert_eq!(x_max([]), 10.0);
    }

    #[test]
    fn labels_are_spread_apart_and_kept_inside() {
        assert_eq!(spread(&[10, 12, 100], 18, 0, 500), vec![10, 28, 100]);
        assert_eq!(spread(&[490, 495], 18, 0, 500), vec![482, 500]);
        assert_eq!(spread(&[2, 3], 18, 10, 500), vec![10, 28]);
    }
}
