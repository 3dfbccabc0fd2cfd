//! `survey report --out DIR`: a self-contained HTML page (inline SVG plots,
//! no scripts, no external files) with the survey's error map, its spectrum,
//! the named error sources and the ISO 230-2 figures.

use crate::error::{bad_input, path_error};
use crate::survey::SurveyRecord;
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use survey_processing::Sample;
use survey_processing::analysis::{Analysis, AnalysisOptions, analyse};
use survey_processing::errormap::ErrorMap;
use survey_processing::iso230::iso230_2;

/// The report of `survey` with its `samples`, as one HTML page.
pub fn html(survey: &SurveyRecord, samples: &[Sample]) -> anyhow::Result<String> {
    if samples.is_empty() {
        return Err(bad_input(format!("survey {} holds no samples yet", survey.id)));
    }
    let design = survey.model.as_ref().map(|m| m.design.clone()).unwrap_or_default();
    let map = ErrorMap::from_samples(samples).ok();
    let analysis = analyse(samples, &design, &AnalysisOptions::default()).ok();
    let mut html = String::new();
    let _ = write!(
        html,
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>Survey {id}</title>\n\
         <style>body{{font-family:sans-serif;max-width:1000px;margin:2em auto;color:#222}}\
         table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:3px 8px;text-align:right}}\
         th{{background:#f4f4f4}}td.l{{text-align:left}}</style></head><body>\n\
         <h1>Survey {id}</h1>\n<p>{source}, status {status}, created {created}; {n} samples, {points} targets x {runs} runs, {dir}.</p>\n",
        id = survey.id,
        source = escape(&survey.source.to_string()),
        status = survey.status,
        created = escape(&survey.created_at),
        n = samples.len(),
        points = survey.points.map(|p| p.to_string()).unwrap_or_else(|| "?".into()),
        runs = survey.runs.map(|p| p.to_string()).unwrap_or_else(|| "?".into()),
        dir = if survey.bidirectional { "bidirectional" } else { "unidirectional" },
    );
    html += "<h2>Error map</h2>\n<p>Readout error (readout - actual), mean over the runs per target and direction, degrees.</p>\n";
    match &map {
        Some(map) => html += &error_plot(map)?,
        None => html += "<p>The error map needs every run at every target.</p>\n",
    }
    html += "<h2>ISO 230-2</h2>\n";
    match iso230_2(samples) {
        Ok(iso) => {
            html += "<table><tr><th></th><th>axis</th><th>forward</th><th>reverse</th></tr>\n";
            let f = |v: Option<f64>| v.map(|x| format!("{x:.6}")).unwrap_or_else(|| "-".into());
            for (name, all, up, down) in [
                ("A accuracy", Some(iso.a), iso.a_up, iso.a_down),
                ("R repeatability", Some(iso.r), iso.r_up, iso.r_down),
                ("E systematic deviation", Some(iso.e), iso.e_up, iso.e_down),
                ("B reversal value", iso.b, None, None),
                ("B mean reversal", iso.b_mean, None, None),
                ("M mean bidirectional deviation", iso.m, None, None),
            ] {
                let _ = writeln!(
                    html,
                    "<tr><td class=\"l\">{name}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                    f(all),
                    f(up),
                    f(down)
                );
            }
            html += "</table>\n";
        }
        Err(e) => {
            let _ = writeln!(html, "<p>No ISO 230-2 figures: {}</p>", escape(&e.to_string()));
        }
    }
    html += "<h2>Spectrum and error sources</h2>\n";
    match &analysis {
        Some(a) => {
            html += &spectrum_plot(a)?;
            html += &lines_table(a);
        }
        None => html += "<p>No spectral analysis for this survey (it needs a complete error map).</p>\n",
    }
    html += "</body></html>\n";
    Ok(html)
}

/// Write `html` as `index.html` into the folder `out` (created if missing); returns the file's path.
pub fn write(out: &Path, html: &str) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(out).map_err(|e| path_error(e, format!("cannot create the folder {}", out.display())))?;
    let path = out.join("index.html");
    std::fs::write(&path, html).map_err(|e| path_error(e, format!("cannot write {}", path.display())))?;
    Ok(path)
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

fn plot_err(e: impl std::fmt::Display) -> anyhow::Error {
    anyhow::anyhow!("drawing the plot: {e}")
}

/// One named, coloured curve of a plot.
type Curve = (&'static str, RGBColor, Vec<(f64, f64)>);

/// Mean error per target, forward and reverse.
fn error_plot(map: &ErrorMap) -> anyhow::Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (960, 360)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let series: Vec<Curve> = [(&map.forward, "forward", BLUE), (&map.reverse, "reverse", RED)]
            .into_iter()
            .filter_map(|(d, name, colour)| {
                d.as_ref()
                    .map(|d| (name, colour, map.targets_deg.iter().copied().zip(d.mean_deg.iter().copied()).collect()))
            })
            .collect();
        let (lo, hi) = series
            .iter()
            .flat_map(|s| s.2.iter().map(|p| p.1))
            .fold((f64::MAX, f64::MIN), |(a, b), y| (a.min(y), b.max(y)));
        let pad = ((hi - lo) * 0.1).max(1e-6);
        let x0 = map.targets_deg.first().copied().unwrap_or(0.0);
        let x1 = map.targets_deg.last().copied().unwrap_or(360.0).max(x0 + 1e-9);
        let mut chart = ChartBuilder::on(&root)
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, (lo - pad)..(hi + pad))
            .map_err(plot_err)?;
        chart.configure_mesh().x_desc("target, deg").y_desc("error, deg").draw().map_err(plot_err)?;
        for (name, colour, points) in series {
            chart
                .draw_series(LineSeries::new(points, colour))
                .map_err(plot_err)?
                .label(name)
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], colour));
        }
        chart.configure_series_labels().border_style(BLACK).draw().map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg + "\n")
}

/// Amplitude of the mean spectrum against cycles per revolution.
fn spectrum_plot(a: &Analysis) -> anyhow::Result<String> {
    let Some(spectra) = &a.spectra else {
        return Ok(
            "<p>A partial-range axis has no FFT spectrum; the lines below come from a least-squares fit.</p>\n".into()
        );
    };
    let bins: Vec<(f64, f64)> = spectra
        .mean
        .bins
        .iter()
        .filter(|b| b.cycles_per_rev > 0.0)
        .map(|b| (b.cycles_per_rev, b.amplitude_deg))
        .collect();
    let top = bins.iter().map(|b| b.1).fold(0.0f64, f64::max).max(1e-9);
    let right = bins.last().map(|b| b.0).unwrap_or(1.0).max(1.0);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (960, 320)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let mut chart = ChartBuilder::on(&root)
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..right, 0.0..top * 1.1)
            .map_err(plot_err)?;
        chart.configure_mesh().x_desc("cycles per revolution").y_desc("amplitude, deg").draw().map_err(plot_err)?;
        chart
            .draw_series(bins.iter().map(|&(k, amp)| PathElement::new([(k, 0.0), (k, amp)], BLUE)))
            .map_err(plot_err)?;
        let floor = a.noise.coherent_threshold_deg;
        chart.draw_series(LineSeries::new([(0.0, floor), (right, floor)], RED)).map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg + "\n<p>Red: the level a line needs to be significant.</p>\n")
}

fn lines_table(a: &Analysis) -> String {
    let mut s = String::from(
        "<table><tr><th>cycles/rev</th><th>amplitude, deg</th><th>phase, deg</th><th>repeatable</th><th>share</th><th>source</th></tr>\n",
    );
    for l in &a.lines {
        let _ = writeln!(
            s,
            "<tr><td>{}</td><td>{:.6}</td><td>{:.1}</td><td>{}</td><td>{:.1} %</td><td class=\"l\">{}</td></tr>",
            l.cycles_per_rev,
            l.amplitude_deg,
            l.phase_deg,
            if l.repeatable { "yes" } else { "no" },
            l.share * 100.0,
            escape(&l.source)
        );
    }
    s += "</table>\n";
    for alias in &a.aliases {
        let _ = writeln!(
            s,
            "<p>Alias: {} cycles/rev is observed at {} ({:?}): {}</p>",
            alias.true_cycles,
            alias.observed_cycles,
            alias.action,
            escape(&alias.reason)
        );
    }
    s
}
