//! What every figure shares: the SVG canvas, axes with readable type and
//! labelled units, the palette, ranges. Drawn with plotters' SVG backend;
//! legends are HTML below the figure ([`super::page::legend`]), never over
//! the data.

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::ops::Range;

/// The canvas of a figure, pixels (the page scales it to its width).
pub const WIDTH: u32 = 1000;
/// The height of an ordinary figure.
pub const HEIGHT: u32 = 420;

/// Tick labels and axis titles, pixels at the canvas size (about 11 pt
/// printed on A4 at the page width).
const TICK_FONT: u32 = 17;
const DESC_FONT: u32 = 19;

/// The Okabe-Ito palette (told apart with every common colour-vision deficiency).
pub const BLUE: RGBColor = RGBColor(0, 114, 178);
pub const VERMILLION: RGBColor = RGBColor(213, 94, 0);
pub const GREEN: RGBColor = RGBColor(0, 158, 115);
pub const ORANGE: RGBColor = RGBColor(230, 159, 0);
pub const SKY: RGBColor = RGBColor(86, 180, 233);
pub const PURPLE: RGBColor = RGBColor(204, 121, 167);
pub const GREY: RGBColor = RGBColor(150, 150, 150);
pub const INK: RGBColor = RGBColor(26, 26, 26);

/// `#rrggbb` of a colour, for the HTML legend.
pub fn hex(c: RGBColor) -> String {
    format!("#{:02x}{:02x}{:02x}", c.0, c.1, c.2)
}

/// A chart with two linear axes.
pub type Chart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// The drawing area of a canvas.
pub type Area<'b> = DrawingArea<SVGBackend<'b>, Shift>;

/// A plotters failure (it draws into a string: this is a bug, not bad input).
pub fn plot_err(e: impl std::fmt::Debug) -> anyhow::Error {
    anyhow::anyhow!("drawing a figure: {e:?}")
}

/// Draw on a white canvas of `size` pixels and return the SVG.
pub fn render(size: (u32, u32), draw: impl FnOnce(&Area<'_>) -> anyhow::Result<()>) -> anyhow::Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        draw(&root)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

/// Decimals that tell ticks `span / 8` apart.
fn tick_decimals(span: f64) -> usize {
    let step = (span / 8.0).abs();
    if step >= 1.0 || step == 0.0 || !step.is_finite() { 0 } else { (-step.log10()).ceil() as usize }
}

/// Axes over `x` and `y` with their titles (units included), a light grid
/// and ticks printed with as many decimals as their spacing needs.
pub fn axes<'a, 'b>(
    area: &'a Area<'b>,
    x: Range<f64>,
    y: Range<f64>,
    x_desc: &str,
    y_desc: &str,
) -> anyhow::Result<Chart<'a, 'b>> {
    let xd = tick_decimals(x.end - x.start);
    let x_ticks = XTicks { labels: 10, margin_right: 24, format: &move |v: &f64| format!("{v:.xd$}") };
    framed(area, x, y, x_desc, y_desc, x_ticks)
}

/// Axes over a time `x` (seconds since 1970, UTC) and `y`: the x ticks are
/// UTC dates (and times when the span is short), never fractions of a day.
pub fn time_axes<'a, 'b>(
    area: &'a Area<'b>,
    x: Range<f64>,
    y: Range<f64>,
    y_desc: &str,
) -> anyhow::Result<Chart<'a, 'b>> {
    let span = x.end - x.start;
    let stamp = |v: f64| {
        let at = std::time::UNIX_EPOCH + std::time::Duration::from_secs_f64(v.max(0.0));
        humantime::format_rfc3339_seconds(at).to_string()
    };
    // YYYY-MM-DD over weeks, MM-DD HH:MM over days (the year named), HH:MM:SS within hours (the date named):
    // never a time without its date.
    let (first, last) = (stamp(x.start), stamp(x.end));
    let (from, to, x_desc) = if span > 7.0 * 86_400.0 {
        (0, 10, "date (UTC)".to_string())
    } else if span > 6.0 * 3_600.0 {
        (5, 16, format!("date and time (UTC), {}", &first[..4]))
    } else if first[..10] == last[..10] {
        (11, 19, format!("time of day (UTC) on {}", &first[..10]))
    } else {
        (11, 19, format!("time of day (UTC) from {} to {}", &first[..10], &last[..10]))
    };
    let x_fmt = move |v: &f64| {
        let text = stamp(*v);
        text.get(from..to).unwrap_or(&text).replace('T', " ")
    };
    // Fewer, wider labels, and room on the right for the last one.
    framed(area, x, y, &x_desc, y_desc, XTicks { labels: 5, margin_right: 48, format: &x_fmt })
}

/// How the x axis is labelled.
struct XTicks<'f> {
    labels: usize,
    margin_right: u32,
    format: &'f dyn Fn(&f64) -> String,
}

/// The chart every plot shares: margins, fonts, the light grid, and y ticks
/// with as many decimals as their spacing needs.
fn framed<'a, 'b>(
    area: &'a Area<'b>,
    x: Range<f64>,
    y: Range<f64>,
    x_desc: &str,
    y_desc: &str,
    x_ticks: XTicks<'_>,
) -> anyhow::Result<Chart<'a, 'b>> {
    let yd = tick_decimals(y.end - y.start);
    let y_fmt = move |v: &f64| format!("{v:.yd$}");
    let mut chart = ChartBuilder::on(area)
        .margin_top(14)
        .margin_right(x_ticks.margin_right)
        .margin_left(8)
        .x_label_area_size(58)
        .y_label_area_size(96)
        .build_cartesian_2d(x, y)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .label_style(("sans-serif", TICK_FONT).into_font().color(&INK))
        .axis_desc_style(("sans-serif", DESC_FONT).into_font().color(&INK))
        .light_line_style(WHITE)
        .bold_line_style(RGBColor(212, 212, 212))
        .axis_style(INK)
        .x_labels(x_ticks.labels)
        .y_labels(8)
        .x_label_formatter(x_ticks.format)
        .y_label_formatter(&y_fmt)
        .draw()
        .map_err(plot_err)?;
    Ok(chart)
}

/// A time range (seconds) with room each side: 5 % of its span, at least a
/// minute (surveys made within one second still get an axis).
pub fn padded_time(lo: f64, hi: f64) -> Range<f64> {
    let (lo, hi) = if lo.is_finite() && hi.is_finite() { (lo, hi) } else { (0.0, 86_400.0) };
    let pad = ((hi - lo) * 0.05).max(60.0);
    (lo - pad)..(hi + pad)
}

/// `lo..hi` widened by `pad` of its span each side (a flat range gets a
/// small span of its own, so the axis still has ticks).
pub fn padded(lo: f64, hi: f64, pad: f64) -> Range<f64> {
    let (lo, hi) = if lo.is_finite() && hi.is_finite() { (lo, hi) } else { (0.0, 1.0) };
    let span = hi - lo;
    if span <= 1e-15 * lo.abs().max(1.0) {
        let w = lo.abs().max(1e-9) * 0.1;
        return (lo - w)..(hi + w);
    }
    (lo - span * pad)..(hi + span * pad)
}

/// The smallest and largest of `values` (`(inf, -inf)` for none).
pub fn extent(values: impl IntoIterator<Item = f64>) -> (f64, f64) {
    values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)))
}

/// The first of 1, 2, 5 x 10^k at or above `x` (x > 0).
pub fn nice_ceil(x: f64) -> f64 {
    if !(x > 0.0 && x.is_finite()) {
        return 1.0;
    }
    let p = 10f64.powf(x.log10().floor());
    [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * p).find(|v| *v >= x * (1.0 - 1e-12)).unwrap_or(10.0 * p)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_and_ticks() {
        assert_eq!(nice_ceil(72.0), 100.0);
        assert_eq!(nice_ceil(0.0031), 0.005);
        assert_eq!(nice_ceil(20.0), 20.0);
        let r = padded(-1.0, 1.0, 0.1);
        assert!((r.start + 1.2).abs() < 1e-12 && (r.end - 1.2).abs() < 1e-12);
        let flat = padded(0.5, 0.5, 0.1);
        assert!(flat.start < 0.5 && flat.end > 0.5);
        assert_eq!(tick_decimals(0.04), 3);
        assert_eq!(tick_decimals(360.0), 0);
        assert_eq!(extent([3.0, f64::NAN, -1.0]), (-1.0, 3.0));
    }

    #[test]
    fn a_canvas_renders_to_svg_with_a_view_box() {
        let svg = render((200, 100), |root| {
            let _chart = axes(root, 0.0..1.0, 0.0..1.0, "x, deg", "y, deg")?;
            Ok(())
        })
        .unwrap();
        assert!(svg.contains("viewBox=\"0 0 200 100\"") && svg.contains("x, deg"), "{svg}");
    }
}
