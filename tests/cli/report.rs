//! `survey report --out DIR`, from outside: the page's sections, figures and
//! tables, its units, its header and where the header's fields come from,
//! and bad input. `tests/cli/browser.rs` opens the page in a real browser.

use super::{Bench, CONTRACT_MODEL};

/// The ids of the figures and tables every processed survey's report holds.
pub const ALWAYS: [&str; 15] = [
    "tbl-header",
    "tbl-summary",
    "fig-error",
    "fig-hysteresis",
    "fig-spectrum",
    "tbl-lines",
    "fig-interpolation",
    "tbl-interpolation",
    "fig-table",
    "tbl-table",
    "tbl-iso-axis",
    "tbl-vdi",
    "vdi-definitions",
    "tbl-iso-targets",
    "iso230-targets",
];

/// No cell of any table is a row of zeros ("0.00000"): a value is shown by
/// significance, or is exactly 0.
pub fn assert_no_zeros(html: &str) {
    for cell in html.split("<td").skip(1).filter_map(|c| c.split_once('>')).map(|c| c.1.split('<').next().unwrap_or(""))
    {
        let digits = cell.trim().trim_start_matches('-');
        let zeros = digits.contains('.') && digits.chars().all(|c| c == '0' || c == '.');
        assert!(!zeros, "a cell shows {cell:?}: a value lost to its format");
    }
}

/// The spectrum's caption names the band above half the sampling rate
/// exactly when the figure draws it (`drawn`: whether it should).
fn assert_shading_as_drawn(html: &str, drawn: bool) {
    let figure = html.split("<figure id=\"fig-spectrum\">").nth(1).unwrap().split("</figure>").next().unwrap();
    let band = figure.contains("opacity=\"0.1\" fill=\"#969696\"");
    let caption = figure.split("<figcaption>").nth(1).unwrap();
    assert_eq!((band, caption.contains("shaded")), (drawn, drawn), "the band drawn and named: {caption}");
}

/// The spectrum's labels of the lines in the table of lines: (amplitude as
/// the table shows it, the label's foot in the figure's pixels).
fn spectrum_labels(html: &str) -> Vec<(f64, f64)> {
    let table = html.split("id=\"tbl-lines\"").nth(1).unwrap().split("</table>").next().unwrap();
    let amplitude: Vec<(String, f64)> = table
        .split("<tr>")
        .skip(2)
        .map(|row| {
            let cells: Vec<&str> =
                row.split("<td").skip(1).map(|c| c.split('>').nth(1).unwrap().split('<').next().unwrap()).collect();
            (cells[0].to_string(), cells[2].parse().unwrap())
        })
        .collect();
    let figure = html.split("<figure id=\"fig-spectrum\">").nth(1).unwrap().split("</svg>").next().unwrap();
    figure
        .split("<text ")
        .skip(1)
        .filter_map(|t| {
            let label = t.split('>').nth(1)?.split('<').next()?.trim();
            let (cycles, _) = label.split_once(" · ")?;
            let amp = amplitude.iter().find(|(c, _)| c == cycles)?.1;
            let y: f64 = t.split("y=\"").nth(1)?.split('"').next()?.parse().ok()?;
            Some((amp, y))
        })
        .collect()
}

#[test]
fn report_writes_a_self_contained_page_with_every_figure_and_table() {
    let bench = Bench::new();
    bench.survey(&["report", "--out", "r"]).bad_input(&["survey.db"]);
    assert!(!bench.exists("r/index.html"));
    bench.small_survey(true);
    let out = bench.survey(&["report", "--out", "r"]).success();
    // Every file it wrote, named.
    let lines: Vec<&str> = out.stdout.lines().collect();
    assert!(lines.len() == 2 && lines[0].ends_with("r/index.html") && lines[1].ends_with("r/dcc.xml"), "{out}");
    let html = bench.read("r/index.html");
    assert!(html.starts_with("<!doctype html>"));
    for id in ALWAYS {
        assert!(html.contains(&format!("id=\"{id}\"")), "the page should hold {id}");
    }
    // The table's uncertainty budget (issue 14), with the tracker's axis location in it.
    assert!(html.contains("id=\"tbl-uncertainty\""), "the page should hold the uncertainty budget");
    for source in [
        "reference instrument, random",
        "reference instrument, systematic",
        "axis location",
        "direction model",
        "expanded uncertainty U = k u (k = 2)",
    ] {
        assert!(html.contains(source), "the budget should name {source:?}");
    }
    // Nothing without a verification, a model or drift data.
    for id in ["fig-native", "fig-corrected", "fig-modelgap", "fig-drift"] {
        assert!(!html.contains(&format!("id=\"{id}\"")), "{id} has no data");
    }
    // The title names the positioner and the survey.
    assert!(
        html.contains(
            "<title>simulated fig8 positioner: rehearsal on simulated instruments, not a calibration (survey 1)</title>"
        ),
        "title"
    );
    // The simulated default's header: the preset, the tracker's random part (2.3e-4 deg).
    for words in ["simulated fig8 positioner: azimuth", "simulated laser tracker", "0.000227 deg", "survey 0.1.0"] {
        assert!(html.contains(words), "the header should say {words:?}");
    }
    // A certificate: its number (made from the survey when none was assigned), the
    // traceability a simulated reference has (none), page x of y in print.
    assert!(
        html.contains("id=\"certificate-number\">Rehearsal, not a calibration: certificate <b>20"),
        "the number on top"
    );
    // ISO/IEC 17025 7.8.2.1 and 7.8.4.1: every item, stated or said to be not stated.
    for row in [
        "Calibrating laboratory</td><td><i>not stated</i>",
        "Customer (name, address)</td><td><i>not stated</i>",
        "Item&#x27;s condition</td><td><i>not stated</i>",
        "Date received</td><td><i>not stated</i>",
        "Location of calibration</td><td><i>not stated</i>",
        "Method</td><td>ISO 230-2:2014",
        "Environment</td><td>air temperature ",
        "measurements by the simulated tracker's room (this program's own model",
        "Authorised by (name, function)</td><td><i>not stated</i>",
        "id=\"end-of-certificate\">End of the certificate",
        "The results relate only to the item calibrated",
        "coverage probability of about 95 %",
    ] {
        assert!(html.replace("Item's", "Item&#x27;s").contains(row), "the certificate should state {row:?}");
    }
    // The spectrum's sources in words; the table excerpt at an eighth of the shortest period
    // (the fig8 preset's 40 cycles/rev line: 9 deg, so every 1 deg), not every 10 deg.
    assert!(!html.contains("gear_pass:") && html.contains("gear pass: 20:1 pinion"), "sources in words");
    assert!(html.contains("The excerpt: every 1 deg, an eighth or less of the shortest significant period (9 deg"));
    // The hysteresis figure tells its series apart: the mean, each run and the band each in its own colour.
    let hysteresis = html.split("<figure id=\"fig-hysteresis\">").nth(1).unwrap().split("</figure>").next().unwrap();
    let legend = hysteresis.split("<ul class=\"legend\">").nth(1).unwrap();
    let colour = |label: &str| {
        let item = legend.split("<li>").find(|i| i.contains(label)).unwrap_or_else(|| panic!("{label} in {legend}"));
        item.split(['"']).find(|w| w.starts_with('#')).unwrap().to_string()
    };
    let colours = [colour("mean over the runs"), colour("each run"), colour("mean ± 2 s")];
    assert!(colours[0] != colours[1] && colours[1] != colours[2] && colours[0] != colours[2], "{colours:?}");
    // The appendix is in the page, folded, and not printed without --appendix.
    assert!(html.contains("class=\"appendix screen-only\">") && html.contains("<details><summary>"), "folded");
    assert!(
        html.contains("made from the survey&#x27;s date and uid")
            || html.contains("made from the survey's date and uid")
    );
    assert!(html.contains("Traceability</td><td>none: a rehearsal on simulated instruments"), "not traceable");
    // A rehearsal says so under its number, on every printed page (the running foot) and in its DCC.
    assert!(html.contains("id=\"rehearsal\"><b>Rehearsal on simulated instruments, not a calibration</b>"));
    assert!(html.contains("@bottom-left{content:\"REHEARSAL ON SIMULATED INSTRUMENTS, NOT A CALIBRATION: survey 1\""));
    let dcc = bench.read("r/dcc.xml");
    assert!(
        dcc.contains("refType=\"survey_rehearsal\"")
            && dcc.contains("Rehearsal on simulated instruments, not a calibration: Readout error")
    );
    assert!(html.contains("counter(page) \" of \" counter(pages)"), "page x of y in print");
    // The definitions the VDI figures use, without a remark about sources to a customer.
    assert!(!html.contains("No public text") && html.contains("with these definitions"));
    // Each line's label stands on its own stem: its height is linear in the line's
    // amplitude (not every label at the tallest's height).
    let labels = spectrum_labels(&html);
    assert!(labels.len() >= 2, "labelled lines: {labels:?}");
    let (lo, hi) = labels
        .iter()
        .fold((labels[0], labels[0]), |(l, h), p| (if p.0 < l.0 { *p } else { l }, if p.0 > h.0 { *p } else { h }));
    assert!(hi.0 > 1.5 * lo.0 && hi.1 < lo.1 - 20.0, "the taller line's label stands higher: {labels:?}");
    let slope = (hi.1 - lo.1) / (hi.0 - lo.0);
    for (amp, y) in &labels {
        assert!((lo.1 + slope * (amp - lo.0) - y).abs() < 2.0, "a label off its stem's height: {labels:?}");
    }
    // The caption names no region the figure does not draw.
    // 36 points see the 20 and 40 cycles/rev gear pass beyond 18: the band is drawn.
    assert_shading_as_drawn(&html, true);
    assert_no_zeros(&html);
    assert!(
        !html.contains("<script") && !html.contains("src=") && !html.contains("href="),
        "self-contained: no scripts, no links"
    );
    assert!(html.contains("default-src 'none'"), "the page forbids every fetch");
    // 180 points resolve every line: no band, and the caption names none.
    bench.survey(&["run", "--points", "180", "--runs", "2"]).success();
    bench.survey(&["report", "--out", "r180"]).success();
    assert_shading_as_drawn(&bench.read("r180/index.html"), false);
    bench.survey(&["report", "--out", "r", "--survey", "9"]).bad_input(&["9"]);
    bench.survey(&["report"]).bad_input(&["--out"]);
}

#[test]
fn units_flags_and_a_model_reach_the_page_and_bad_ones_write_nothing() {
    let bench = Bench::new();
    // An autocollimator survey: no axis to refit, so the report's figures are
    // the stored survey's exactly.
    bench
        .survey(&["run", "--points", "24", "--runs", "2", "--bidirectional", "--reference", "autocollimator"])
        .success();
    bench.write("model.toml", CONTRACT_MODEL);
    let a_deg = bench.stats_json(None)["iso230_2"]["A"].as_f64().unwrap();
    bench
        .survey(&[
            "report",
            "--out",
            "r",
            "--units",
            "arcsec",
            "--operator",
            "J. Smith",
            "--temperature",
            "20.5",
            "--positioner",
            "ACME AZ-200 <serial 7>",
            "--model",
            "model.toml",
            "--certificate-number",
            "CAL-2026-0042",
            "--laboratory",
            "Metrology Lab \"North\", Bay 3",
            "--traceability",
            "Polygon calibrated by PTB, certificate 12345, 2026-01",
            "--signatory",
            "A. Jones, head of the laboratory",
            "--location",
            "Bay 3",
            "--item-condition",
            "as received, no damage",
            "--received",
            "2026-11-20",
            "--country",
            "DE",
        ])
        .success();
    let html = bench.read("r/index.html").replace("Item's", "Item&#x27;s").replace("Laboratory's", "Laboratory&#x27;s");
    assert!(!html.contains("no air temperature was measured"), "a stated temperature is stated");
    // ISO A in the axis table, in arcsec, to the decimal place of its U (ILAC-P14), as in the summary.
    let shown = html.split("A, accuracy</td><td>").nth(1).and_then(|s| s.split('<').next()).expect("A");
    let value: f64 = shown.parse().expect("a number");
    let u = html.split("carry the expanded uncertainty U = ").nth(1).and_then(|s| s.split(' ').next()).expect("U");
    let places = |s: &str| s.split('.').nth(1).map_or(0, str::len);
    assert_eq!(places(shown), places(u), "A {shown} to the place of U {u}");
    assert!(html.contains(&format!("ISO 230-2 accuracy A, as measured</td><td>{shown} arcsec</td><td>{u} arcsec")));
    assert!((value - a_deg * 3600.0).abs() <= 5e-3 * a_deg * 3600.0, "A in arcsec {shown} against stats' {a_deg} deg");
    for words in [
        "error (readout − actual), arcsec",
        "J. Smith",
        "20.5 °C",
        "ACME AZ-200 &lt;serial 7&gt;",
        // Where each field came from: the appendix's, not the customer's pages.
        "<td class=\"l\">Operator</td><td class=\"l\">survey report flag</td>",
        "simulated autocollimator",
        "0.100 arcsec (standard uncertainty of one angle)",
        "Rehearsal, not a calibration: certificate <b>CAL-2026-0042</b> · Metrology Lab &quot;North&quot;, Bay 3",
        // A stated temperature is shown as stated, never as "not measured at all".
        "air temperature 20.5 °C, stated, not measured",
        "the air temperature was stated as 20.5 °C, not measured",
        "Authorised by (name, function)</td><td>A. Jones, head of the laboratory",
        "Location of calibration</td><td>Bay 3",
        "Item&#x27;s condition</td><td>as received, no damage",
        "Date received</td><td>2026-11-20",
        "Laboratory&#x27;s country</td><td>DE",
        // The running head and foot of every printed page.
        "@top-left{content:\"Rehearsal, not a calibration: certificate CAL-2026-0042\"",
        "@top-right{content:\"Metrology Lab \\\"North\\\", Bay 3\"",
    ] {
        assert!(html.contains(words), "the page should show {words:?}");
    }
    assert!(html.contains("<title>simulated, standing in for: ACME AZ-200 &lt;serial 7&gt;: rehearsal on simulated instruments, not a calibration (survey 1)</title>"));
    assert!(html.contains("id=\"fig-modelgap\""), "the model-gap section");
    assert!(!html.contains("(survey report flag)") && !html.contains("(the bench)"), "no provenance beside a field");
    // A rehearsal claims no traceability, whatever a flag states.
    assert!(
        !html.contains("Polygon calibrated by PTB") && html.contains("whatever the configuration or a flag states")
    );
    // 24 faces see the 20 cycles/rev gear pass at 4: its true frequency lies in the shaded band.
    assert_shading_as_drawn(&html, true);
    // The processing's sentences take the unit too: the table's caption says why it has two columns.
    let reason = html.split("Hysteresis max").nth(1).and_then(|s| s.split("(its noise)").next()).expect("the reason");
    assert!(reason.contains("arcsec") && !reason.contains("deg"), "the table's caption in arcsec: {reason}");
    assert_no_zeros(&html);
    // Bad input: exit 2, nothing written.
    for (args, words) in [
        (vec!["--units", "furlong"], vec!["furlong"]),
        (vec!["--temperature", "500"], vec!["--temperature"]),
        (vec!["--reference-uncertainty", "-1"], vec!["--reference-uncertainty"]),
        (vec!["--tolerance", "0"], vec!["--tolerance"]),
        (vec!["--tolerance", "-0.01"], vec!["--tolerance"]),
        (vec!["--certificate-number", " "], vec!["--certificate-number"]),
        // The certificate is issued: a flag that would change it is refused (an amendment says why).
        (vec!["--model", "missing.toml"], vec!["--model", "would change it", "--amend"]),
        (vec!["--received", "2026-02-30"], vec!["--received 2026-02-30: 2026-02-30 is not a date (no such day"]),
        (
            vec!["--received", "20.11.2026"],
            vec!["--received 20.11.2026: 20.11.2026 is not a date of the form YYYY-MM-DD"],
        ),
        (vec!["--country", "Germany"], vec!["--country Germany", "ISO 3166-1 alpha-2"]),
        (vec!["--country", "XK"], vec!["--country XK"]),
        (vec!["--signatory", ""], vec!["--signatory"]),
    ] {
        let mut all = vec!["report", "--out", "bad"];
        all.extend(args);
        bench.survey(&all).bad_input(&words);
        assert!(!bench.exists("bad/index.html"), "{all:?} wrote a page");
    }
}

#[test]
fn a_verified_survey_shows_native_and_corrected_on_one_scale() {
    let bench = Bench::new();
    bench.survey(&["run", "--points", "72", "--runs", "2", "--bidirectional", "--verify", "--json"]).success();
    let rehearsal = "rehearsal on simulated instruments, not a calibration";
    let verification = format!("verification (survey 2) of the table of survey 1, a {rehearsal}");
    for (id, title) in [("1", format!("{rehearsal} (survey 1)")), ("2", verification)] {
        let dir = format!("r{id}");
        bench.survey(&["report", "--survey", id, "--out", &dir]).success();
        let html = bench.read(&format!("{dir}/index.html"));
        assert!(html.contains(&format!("<title>simulated fig8 positioner: {title}</title>")), "{id}");
        for fig in ["fig-native", "fig-corrected", "tbl-verification"] {
            assert!(html.contains(&format!("id=\"{fig}\"")), "report of survey {id} should hold {fig}");
        }
        assert!(html.contains("Every verification target lies between the calibration targets"), "{id}");
        // One vertical scale: the two figures' y ticks are the same.
        let ticks = |fig: &str| {
            let part = html.split(&format!("<figure id=\"{fig}\">")).nth(1).unwrap().split("</figure>").next().unwrap();
            part.matches("<text").count()
        };
        assert_eq!(ticks("fig-native"), ticks("fig-corrected"), "{id}");
    }
}

/// The verdict of the report of survey 1 (verified by survey 2) against `tolerance` degrees.
fn verdict(bench: &Bench, tolerance: f64, extra: &[&str]) -> String {
    let t = tolerance.to_string();
    let mut args = vec!["report", "--survey", "1", "--out", "v", "--tolerance", &t];
    // The first report issues the certificate; another tolerance is an amendment.
    let amend = format!("judged against {t} deg");
    if bench.exists("v/index.html") {
        args.extend(["--amend", &amend]);
    }
    args.extend(extra);
    bench.survey(&args).success();
    let html = bench.read("v/index.html");
    assert!(
        html.contains("id=\"decision-rule\">Decision rule: ILAC-G8:09/2019 guarded acceptance and guarded rejection with a guard band w = U"),
        "the rule is stated"
    );
    html.split("id=\"verdict\">").nth(1).and_then(|s| s.split("</p>").next()).expect("a verdict").to_string()
}

#[test]
fn a_tolerance_gives_a_verdict_on_the_corrected_accuracy_by_the_decision_rule() {
    let bench = Bench::new();
    bench.survey(&["run", "--points", "72", "--runs", "2", "--bidirectional", "--verify", "--json"]).success();
    // The corrected A: ISO 230-2 of the verification survey as stored.
    let a = bench.stats_json(Some(2))["iso230_2"]["A"].as_f64().unwrap();
    // The simulated tracker's stated 0.000884 deg (and the axis) make U about 0.0018 deg.
    let pass = verdict(&bench, 10.0 * a, &[]);
    assert!(pass.starts_with("Verdict against the tolerance") && pass.contains(": PASS. A = "), "{pass}");
    assert!(pass.contains("the corrected accuracy A per ISO 230-2, measured by verification survey 2"), "{pass}");
    assert!(!pass.contains("survey report flag"), "no provenance on the customer's page: {pass}");
    let fail = verdict(&bench, a / 10.0, &[]);
    assert!(fail.contains(": FAIL. ") && fail.contains("A − U = "), "{fail}");
    let open = verdict(&bench, a, &[]);
    assert!(open.contains(": NOT DECIDABLE (WITHIN THE UNCERTAINTY). "), "{open}");
    // U follows the reference's stated uncertainty: twice A passes with the simulated
    // tracker's, and is within the uncertainty of a reference as uncertain as A itself.
    assert!(verdict(&bench, 2.0 * a, &[]).contains(": PASS. "));
    let a_text = a.to_string();
    let coarse = verdict(&bench, 2.0 * a, &["--reference-uncertainty", &a_text]);
    assert!(coarse.contains(": NOT DECIDABLE (WITHIN THE UNCERTAINTY). "), "{coarse}");
    // The figures carry their uncertainties: U beside A, the table's beside the prediction.
    let html = bench.read("v/index.html");
    let summary = html.split("id=\"tbl-summary\"").nth(1).unwrap().split("</table>").next().unwrap();
    assert!(
        summary.contains("expanded uncertainty U (k = 2, coverage probability about 95 %)")
            && summary.contains("(the table's)"),
        "{summary}"
    );
    assert!(summary.contains("ISO 230-2 accuracy A, corrected, measured (survey 2)"), "{summary}");
    let u_in_summary = summary.split("as measured</td><td>").nth(1).unwrap().split("</td><td>").nth(1).unwrap();
    let u_in_summary = u_in_summary.split('<').next().unwrap();
    assert!(
        html.contains(&format!(
            "The measured figures A, E and M carry the expanded uncertainty U = {u_in_summary} (k = 2)"
        )),
        "the ISO figures state the same U as the summary ({u_in_summary})"
    );
    // The stated reference uncertainty enters the table's budget too (as the header states it).
    let budget_u = |dir: &str| {
        let html = bench.read(&format!("{dir}/index.html"));
        let row = html
            .split("<td class=\"l\">reference instrument, random</td><td>")
            .nth(1)
            .expect("the budget's row")
            .to_string();
        row.split('<').next().unwrap().parse::<f64>().unwrap()
    };
    let coarse = ["--reference-uncertainty", "0.01", "--amend", "a coarser reference"];
    bench.survey(&[&["report", "--survey", "1", "--out", "coarse"][..], &coarse].concat()).success();
    bench.survey(&["report", "--survey", "1", "--out", "none", "--amend", "nothing stated"]).success();
    // The simulated tracker's random 0.000227 deg against 0.01 deg: about 44 times the contribution.
    let ratio = budget_u("coarse") / budget_u("none");
    assert!((ratio - 0.01 / 0.000_227).abs() < 0.5, "{ratio}");
    // Without a tolerance, no verdict.
    assert!(!bench.read("none/index.html").contains("id=\"verdict\""));
}

#[test]
fn without_a_stated_reference_uncertainty_nothing_is_decidable() {
    let bench = Bench::new();
    bench.small_survey(true);
    bench.survey(&["export", "--csv", "s.csv"]).success();
    let other = Bench::new();
    other.write("s.csv", bench.read("s.csv"));
    other.survey(&["import", "s.csv"]).success();
    other.survey(&["report", "--out", "v", "--tolerance", "10"]).success();
    let html = other.read("v/index.html");
    let verdict = html.split("id=\"verdict\">").nth(1).and_then(|s| s.split("</p>").next()).expect("a verdict");
    assert!(verdict.contains("NOT DECIDABLE") && verdict.contains("uncertainty is not known"), "{verdict}");
    assert!(verdict.contains("the native accuracy A per ISO 230-2 of this survey"), "{verdict}");
    assert!(html.contains("The reference's uncertainty is not stated: the figures' uncertainty is not known."));
}

/// The pixel x range of the figure's table curves (polylines 2 px wide) and of its measured means (dots).
fn x_ranges(figure: &str) -> ((f64, f64), (f64, f64)) {
    let range = |xs: Vec<f64>| xs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(*x), b.max(*x)));
    let attr =
        |e: &str, key: &str| e.split(&format!("{key}=\"")).nth(1).map(|v| v.split('"').next().unwrap().to_string());
    let curves = figure
        .split("<polyline")
        .filter(|e| e.contains("stroke-width=\"2\""))
        .filter_map(|e| attr(e, "points"))
        .flat_map(|p| {
            p.split_whitespace().map(|xy| xy.split(',').next().unwrap().parse().unwrap()).collect::<Vec<f64>>()
        })
        .collect();
    let dots = figure.split("<circle").skip(1).filter_map(|e| attr(e, "cx")).map(|x| x.parse().unwrap()).collect();
    (range(curves), range(dots))
}

#[test]
fn a_partial_arc_across_zero_shows_the_table_over_the_whole_arc_and_says_what_it_cannot_show() {
    let bench = Bench::new();
    // -30 to 90 deg, every 1 deg, 3 runs both ways: a once-per-revolution error and a 12 cycles/rev line.
    let mut csv = String::from("run,direction,target_deg,readout_deg,actual_deg\n");
    for run in 1..=3 {
        for (direction, sign) in [("forward", 1.0), ("reverse", -1.0)] {
            let mut targets: Vec<f64> = (0..=120).map(|i| -30.0 + i as f64).collect();
            if sign < 0.0 {
                targets.reverse();
            }
            for t in targets {
                let th = t.to_radians();
                let e = 0.004 * (th + 0.3).sin()
                    + 0.0015 * (12.0 * th + 1.0).sin()
                    + sign * 0.0005
                    + 1e-5 * ((run as f64) * 7.0 + t).sin();
                csv += &format!("{run},{direction},{t},{t},{}\n", t - e);
            }
        }
    }
    bench.write("arc.csv", csv);
    bench.survey(&["import", "arc.csv"]).success();
    bench.survey(&["report", "--out", "r"]).success();
    let html = bench.read("r/index.html");
    let figure = html.split("<figure id=\"fig-table\">").nth(1).unwrap().split("</svg>").next().unwrap();
    // The table's columns are drawn over every measured target, below 0 deg too.
    let (curves, measured) = x_ranges(figure);
    assert!(
        curves.0 <= measured.0 + 1.0 && curves.1 >= measured.1 - 1.0,
        "curves {curves:?} over the targets {measured:?}"
    );
    // What cannot be shown on a partial arc says why.
    assert!(html.contains("The survey measured a partial arc (-30 to 90 deg), so the comparison cannot be drawn"));
    for id in ["fig-error", "fig-hysteresis", "fig-spectrum", "fig-table", "tbl-iso-axis", "tbl-iso-targets"] {
        assert!(html.contains(&format!("id=\"{id}\"")), "{id} on a partial arc");
    }
    assert_no_zeros(&html);
}

#[test]
fn report_pdf_without_a_working_browser_exits_1_says_why_and_keeps_the_page() {
    let bench = Bench::new();
    bench.small_survey(true);
    bench.write("slow.sh", "#!/bin/sh\nsleep 30\n");
    let slow = bench.path("slow.sh");
    std::fs::set_permissions(&slow, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    let missing = bench.path("no-such-browser");
    for (browser, timeout, words) in [
        (missing.to_str().unwrap(), "120", vec!["SURVEY_CHROMIUM=", "no-such-browser", "names no file"]),
        ("/bin/false", "120", vec!["/bin/false exited with exit status: 1"]),
        (slow.to_str().unwrap(), "0.5", vec!["slow.sh did not finish within 500ms"]),
    ] {
        let _ = std::fs::remove_dir_all(bench.path("r"));
        let mut cmd = bench.command(&["report", "--out", "r", "--pdf"]);
        cmd.env("SURVEY_CHROMIUM", browser).env("SURVEY_PDF_TIMEOUT_S", timeout);
        let started = std::time::Instant::now();
        let out = Bench::output_of(&["report", "--pdf"], cmd);
        assert_eq!(out.code, 1, "a browser that cannot print is a run-time failure\n{out}");
        let out = out.stderr_mentions(&["cannot print", "to PDF (the HTML page is written)"]).stderr_mentions(&words);
        assert!(started.elapsed() < std::time::Duration::from_secs(20), "bounded: {:?}\n{out}", started.elapsed());
        assert!(bench.exists("r/index.html") && !bench.exists("r/index.pdf"), "{browser}");
    }
    // No browser at all: none named, none on PATH.
    let mut cmd = bench.command(&["report", "--out", "r", "--pdf"]);
    cmd.env_remove("SURVEY_CHROMIUM").env("PATH", bench.path("empty"));
    let out = Bench::output_of(&["report", "--pdf"], cmd);
    assert_eq!(out.code, 1, "{out}");
    out.stderr_mentions(&["no Chromium found", "apt-get install chromium", "SURVEY_CHROMIUM"]);
    bench
        .survey_with_env(&["report", "--out", "bad", "--pdf"], "SURVEY_PDF_TIMEOUT_S", "soon")
        .bad_input(&["SURVEY_PDF_TIMEOUT_S"]);
    assert!(!bench.exists("bad/index.html"), "bad input writes nothing");
}

/// The environment measured (issue 39): the simulated tracker reports the room
/// with every measurement; `run --json` and `show --json` give its ranges, the
/// certificate states them and plots the temperature against time, the DCC
/// carries them. An autocollimator reports none.
#[test]
fn the_air_the_tracker_measured_is_in_run_show_the_certificate_and_its_dcc() {
    let bench = Bench::new();
    let run = bench.survey(&["run", "--points", "72", "--runs", "2", "--bidirectional", "--json"]).success().json();
    let env = &run["environment"];
    assert_eq!(env["source"], "tracker", "{env}");
    assert_eq!(env["measurements"], 288, "one a sample: {env}");
    let t = &env["temperature_c"];
    let (lo, hi, mean) = (t["min"].as_f64().unwrap(), t["max"].as_f64().unwrap(), t["mean"].as_f64().unwrap());
    assert!(19.0 < lo && lo < mean && mean < hi && hi < 21.0, "a room near 20 °C that changes: {t}");
    for (key, low, high) in [("pressure_hpa", 1000.0, 1030.0), ("humidity_pct", 30.0, 60.0)] {
        let r = &env[key];
        assert!(r["min"].as_f64().unwrap() > low && r["max"].as_f64().unwrap() < high, "{key}: {r}");
    }
    assert_eq!(bench.survey(&["show", "--json"]).success().json()["environment"], *env, "show says the same");
    bench.survey(&["report", "--out", "r"]).success();
    let html = bench.read("r/index.html");
    assert!(html.contains("id=\"fig-environment\""), "the temperature against time");
    assert!(html.contains(&format!("air temperature {lo:.2} to {hi:.2} °C")), "the range measured");
    assert!(bench.read("r/dcc.xml").contains("refType=\"basic_temperatureMin\""), "the DCC's range");
    // An autocollimator measures no air: none, and the certificate says not measured.
    let ac = bench
        .survey(&["run", "--points", "24", "--runs", "2", "--reference", "autocollimator", "--json"])
        .success()
        .json();
    assert_eq!(ac["environment"]["source"], "none");
    bench.survey(&["report", "--out", "ac"]).success();
    assert!(bench.read("ac/index.html").contains("not measured: no air temperature was measured or stated"));
}

/// Issue 50: `report` reads `SURVEY_LAB` as `push` does: a survey to issue
/// draws its number from that lab store (here one nothing answers at, so the
/// report fails and issues nothing), a survey issued before is written again
/// as issued (not an error), a URL that is not a lab store is refused naming
/// SURVEY_LAB; the URL's password is never printed.
#[test]
fn report_reads_survey_lab_and_a_certificate_issued_is_written_again() {
    let b = Bench::new();
    b.survey(&["run", "--points", "24", "--runs", "2", "--json"]).success();
    let nowhere = "postgres://survey:pw-50-secret@127.0.0.1:1/lab";
    let failed = b.survey_with_env(&["report", "--out", "a"], "SURVEY_LAB", nowhere);
    assert_ne!(failed.code, 0, "the lab store's number could not be drawn: {failed}");
    assert!(!failed.stderr.contains("pw-50-secret") && !failed.stdout.contains("pw-50-secret"), "{failed}");
    assert!(!b.exists("a/dcc.xml"), "nothing issued without its number");
    let issued = b.survey(&["report", "--out", "b"]).success();
    assert!(issued.stderr.contains(" issued "), "{issued}");
    let again = b.survey_with_env(&["report", "--out", "c"], "SURVEY_LAB", nowhere).success();
    assert!(again.stderr.contains("SURVEY_LAB postgres://") && again.stderr.contains("no number drawn"), "{again}");
    assert!(again.stderr.contains("was issued") && !again.stderr.contains("pw-50-secret"), "{again}");
    assert_eq!(b.read("c/dcc.xml"), b.read("b/dcc.xml"), "the certificate as issued");
    assert_eq!(b.read("c/index.html"), b.read("b/index.html"));
    b.survey_with_env(&["report", "--out", "d"], "SURVEY_LAB", "lab.db")
        .bad_input(&["SURVEY_LAB lab.db: not a lab store"]);
    // The flag still refuses what the environment passes over.
    b.survey(&["report", "--out", "e", "--lab", nowhere]).bad_input(&["--lab postgres://", "was issued"]);
    let help = b.survey(&["report", "--help"]).success().stdout;
    assert!(help.contains("SURVEY_LAB"), "{help}");
}
