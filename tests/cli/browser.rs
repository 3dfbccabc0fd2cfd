//! The report in a real browser: Debian's `chromium`, headless, opens the
//! page `survey report` wrote (a verified survey with a model-gap, so every
//! section is there) and the test asserts that every figure and table is
//! present and rendered, that the page fetched nothing and logged no error,
//! and keeps a screenshot and a printed PDF (their paths are printed).
//!
//! How errors are read, with nothing but the browser: the test copies the
//! page with a small collector script first in its `<head>` (and lets inline
//! script run in its Content-Security-Policy, which otherwise forbids every
//! script and fetch). The collector records uncaught errors, failed loads,
//! `console.error`, and every fetch the policy refused; after the load it
//! writes them, the ids on the page, each figure's rendered size and every
//! resource fetched into the DOM, which `--dump-dom` prints. The browser's
//! own log (stderr) is searched for uncaught errors and refusals too. A page
//! with a deliberate error proves the check fails on one.
//!
//! Where `chromium` is absent the tests say they skipped and why; CI
//! installs it (`.ci/run`). `SURVEY_CHROMIUM` names another binary.

use super::Bench;
use super::report::ALWAYS;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Flags that keep Chromium from reaching for the network or a display
/// (without them it hangs on a closed network).
const FLAGS: [&str; 9] = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--hide-scrollbars",
];

/// A generous bound on one browser run (it takes 1-3 s here).
const BROWSER_TIMEOUT: Duration = Duration::from_secs(120);

const COLLECTOR: &str = r#"<script>
window.__errors = [];
const __rec = (kind, msg) => window.__errors.push(kind + ': ' + msg);
window.addEventListener('error', e => {
  const t = e.target;
  if (t && t !== window && (t.src || t.href)) __rec('failed load', t.tagName + ' ' + (t.src || t.href));
  else __rec('uncaught error', e.message);
}, true);
window.addEventListener('unhandledrejection', e => __rec('unhandled rejection', String(e.reason)));
document.addEventListener('securitypolicyviolation', e => __rec('refused fetch', e.violatedDirective + ' ' + e.blockedURI));
const __ce = console.error.bind(console);
console.error = (...a) => { __rec('console.error', a.join(' ')); __ce(...a); };
window.addEventListener('load', () => setTimeout(() => {
  const out = document.createElement('pre');
  out.id = '__report_check';
  out.textContent = JSON.stringify({
    errors: window.__errors,
    ids: [...document.querySelectorAll('[id]')].map(e => e.id),
    figures: [...document.querySelectorAll('figure')].map(f => {
      const s = f.querySelector('svg.plot'); const r = s ? s.getBoundingClientRect() : {width: 0, height: 0};
      return {id: f.id, width: r.width, height: r.height};
    }),
    fetched: performance.getEntriesByType('resource').map(r => r.name),
  });
  document.body.appendChild(out);
}, 200));
</script>"#;

/// The print layout on screen: the page's print rules made the screen's,
/// the window as wide as an A4 page's content box (210 mm less 2 x 14 mm of
/// margin, at 96 px per inch), and every element's box measured against it.
const LAYOUT: &str = r#"<script>
window.addEventListener('load', () => setTimeout(() => {
  const width = document.documentElement.clientWidth;
  const wide = [...document.body.querySelectorAll('*')].filter(e => {
    const r = e.getBoundingClientRect();
    return r.width > 0 && (r.right > width + 0.5 || r.left < -0.5);
  }).map(e => e.tagName + (e.id ? '#' + e.id : '') + (e.className && e.className.baseVal === undefined ? '.' + e.className : '') + ' ' + Math.round(e.getBoundingClientRect().right));
  const tall = [...document.querySelectorAll('figure, tr, table.header, ul.legend')].filter(e =>
    getComputedStyle(e).display !== 'none' && e.getBoundingClientRect().height > PAGE_HEIGHT
  ).map(e => e.tagName + (e.id ? '#' + e.id : ''));
  const out = document.createElement('pre');
  out.id = '__layout_check';
  out.textContent = JSON.stringify({width, scroll_width: document.documentElement.scrollWidth, wide, tall});
  document.body.appendChild(out);
}, 100));
</script>"#;

/// An A4 page's content box, CSS px (96 per inch): 210 x 297 mm less the
/// margins of the page's `@page` rule (14 mm each side, 16 mm top, 15 mm bottom).
const PAGE_CONTENT_PX: (u32, u32) = (688, 1005);

/// What the layout check saw: elements wider than the page's content box
/// (or left of it), and unbreakable ones taller than a page.
fn layout(browser: &Path, work: &Path, html: &str) -> Value {
    let script = LAYOUT.replace("PAGE_HEIGHT", &PAGE_CONTENT_PX.1.to_string());
    let page = html
        .replacen("<head>", &format!("<head>{script}"), 1)
        .replacen("default-src 'none'", "default-src 'none'; script-src 'unsafe-inline'", 1)
        .replace("@media print{", "@media all{");
    let file = work.join("layout.html");
    std::fs::write(&file, page).expect("write the instrumented page");
    let profile = tempfile::tempdir().expect("a browser profile");
    let args = vec![
        "--dump-dom".to_string(),
        "--virtual-time-budget=3000".to_string(),
        format!("--window-size={},{}", PAGE_CONTENT_PX.0, PAGE_CONTENT_PX.1),
    ];
    let (dom, _) = run(browser, profile.path(), &args, &format!("file://{}", file.display()));
    let found = dom
        .split("<pre id=\"__layout_check\">")
        .nth(1)
        .and_then(|s| s.split("</pre>").next())
        .expect("the layout check wrote nothing: the page did not load");
    let text = found.replace("&lt;", "<").replace("&gt;", ">").replace("&quot;", "\"").replace("&amp;", "&");
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("the layout check's JSON: {e}\n{text}"))
}

/// No element of the printed page is wider than its page or taller than one page.
fn assert_fits_the_page(seen: &Value) {
    assert_eq!(seen["width"].as_u64(), Some(u64::from(PAGE_CONTENT_PX.0)), "the window is the content box: {seen}");
    assert!(seen["wide"].as_array().unwrap().is_empty(), "elements overflow the page's width: {seen:#}");
    assert!(seen["tall"].as_array().unwrap().is_empty(), "unbreakable elements taller than a page: {seen:#}");
    assert!(seen["scroll_width"].as_u64() <= seen["width"].as_u64(), "the page scrolls sideways: {seen}");
}

/// The browser, or why there is none.
fn chromium() -> Result<PathBuf, String> {
    if let Ok(path) = std::env::var("SURVEY_CHROMIUM") {
        return Ok(PathBuf::from(path));
    }
    for name in ["chromium", "chromium-browser"] {
        for dir in std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default()) {
            let candidate = dir.join(name);
            if candidate.is_file() {
                return Ok(candidate);
            }
        }
    }
    Err("no `chromium` on PATH (Debian: apt-get install chromium; CI installs it)".into())
}

/// Run the browser with `args` on `url` in a new empty profile; its stdout and stderr.
fn run(browser: &Path, profile: &Path, args: &[String], url: &str) -> (String, String) {
    let mut cmd = Command::new(browser);
    cmd.args(FLAGS).arg(format!("--user-data-dir={}", profile.display())).args(args).arg(url);
    cmd.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped());
    let child = cmd.spawn().unwrap_or_else(|e| panic!("start {}: {e}", browser.display()));
    let id = child.id();
    // The output is read on another thread so that a hung browser is killed
    // at the bound instead of blocking the test for ever.
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait_with_output());
    });
    let started = Instant::now();
    match rx.recv_timeout(BROWSER_TIMEOUT) {
        Ok(out) => {
            let out = out.expect("the browser ran");
            assert!(
                out.status.success(),
                "{} exited {:?}: {}",
                browser.display(),
                out.status,
                String::from_utf8_lossy(&out.stderr)
            );
            (String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
        }
        Err(_) => {
            let _ = Command::new("kill").arg("-9").arg(id.to_string()).status();
            panic!("{} did not finish within {:?} ({:?})", browser.display(), BROWSER_TIMEOUT, started.elapsed());
        }
    }
}

/// What the collector saw on the page at `html`, and the browser's log lines
/// that report an error.
fn check(browser: &Path, work: &Path, html: &str) -> (Value, Vec<String>) {
    let page = html.replacen("<head>", &format!("<head>{COLLECTOR}"), 1).replacen(
        "default-src 'none'",
        "default-src 'none'; script-src 'unsafe-inline'",
        1,
    );
    let file = work.join("checked.html");
    std::fs::write(&file, page).expect("write the instrumented page");
    let profile = tempfile::tempdir().expect("a browser profile");
    let args = vec![
        "--dump-dom".to_string(),
        "--virtual-time-budget=5000".to_string(),
        "--enable-logging=stderr".into(),
        "--v=0".into(),
    ];
    let (dom, log) = run(browser, profile.path(), &args, &format!("file://{}", file.display()));
    let found = dom
        .split("<pre id=\"__report_check\">")
        .nth(1)
        .and_then(|s| s.split("</pre>").next())
        .unwrap_or_else(|| panic!("the collector wrote nothing: the page did not load\n{log}"));
    let text = found.replace("&lt;", "<").replace("&gt;", ">").replace("&quot;", "\"").replace("&amp;", "&");
    let seen: Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("the collector's JSON: {e}\n{text}"));
    let logged = log
        .lines()
        .filter(|l| {
            l.contains("CONSOLE")
                && (l.contains("Uncaught") || l.contains("Refused to") || l.contains("Failed to load"))
        })
        .map(str::to_string)
        .collect();
    (seen, logged)
}

/// The errors of a check: the collector's and the log's.
fn errors(seen: &Value, logged: &[String]) -> Vec<String> {
    let mut all: Vec<String> =
        seen["errors"].as_array().unwrap().iter().map(|e| e.as_str().unwrap_or("").to_string()).collect();
    all.extend(seen["fetched"].as_array().unwrap().iter().map(|f| format!("fetched {f}")));
    all.extend(logged.iter().cloned());
    all
}

#[test]
fn the_report_opens_in_chromium_with_every_figure_and_no_error() {
    let browser = match chromium() {
        Ok(b) => b,
        Err(why) => {
            println!("skipped: {why}");
            return;
        }
    };
    let bench = Bench::new();
    bench.write("model.toml", super::CONTRACT_MODEL);
    bench.survey(&["run", "--points", "90", "--runs", "3", "--bidirectional", "--verify", "--json"]).success();
    bench
        .survey(&[
            "report",
            "--survey",
            "1",
            "--out",
            "r",
            "--model",
            "model.toml",
            "--units",
            "arcsec",
            "--certificate-number",
            "CAL-2026-0042",
            "--laboratory",
            "Metrology Lab North",
            "--tolerance",
            "0.05",
        ])
        .success();
    let html = bench.read("r/index.html");
    let artifacts = Path::new(env!("CARGO_TARGET_TMPDIR")).join("report-browser");
    std::fs::create_dir_all(&artifacts).unwrap();
    std::fs::write(artifacts.join("index.html"), &html).unwrap();

    let (seen, logged) = check(&browser, &artifacts, &html);
    let errs = errors(&seen, &logged);
    assert!(errs.is_empty(), "the page logged errors: {errs:#?}");
    let ids: Vec<&str> = seen["ids"].as_array().unwrap().iter().filter_map(|v| v.as_str()).collect();
    let expected = ALWAYS.iter().copied().chain([
        "fig-native",
        "fig-corrected",
        "tbl-verification",
        "fig-modelgap",
        "tbl-modelgap",
        // The certificate: its number on top, the verdict against the tolerance and its rule.
        "certificate-number",
        "verdict",
        "decision-rule",
    ]);
    for id in expected {
        assert!(ids.contains(&id), "the page in the browser lacks {id}: {ids:?}");
    }
    // The per-target table is an appendix, after every other section.
    let at = |id: &str| ids.iter().position(|i| *i == id).unwrap_or_else(|| panic!("{id}: {ids:?}"));
    for id in ["summary", "errors", "spectrum", "correction-table", "verification", "model-gap", "iso230"] {
        assert!(at(id) < at("iso230-targets"), "{id} comes before the appendix: {ids:?}");
    }
    assert!(html.contains(
        "<section id=\"iso230-targets\" class=\"appendix screen-only\">\n<h2>Appendix A: ISO 230-2 per target"
    ));
    assert!(html.contains("Rehearsal, not a calibration: certificate <b>CAL-2026-0042</b> · Metrology Lab North"));
    // Printed, nothing is wider than the page (every section of the certificate is here).
    assert_fits_the_page(&layout(&browser, &artifacts, &html));
    // Page x of y and the running head in print.
    assert!(html.contains("@bottom-right{content:\"page \" counter(page) \" of \" counter(pages)"));
    assert!(html.contains("@top-left{content:\"Rehearsal, not a calibration: certificate CAL-2026-0042\""));
    // Every figure is drawn at a readable size (not collapsed, not overflowing).
    let figures = seen["figures"].as_array().unwrap();
    assert!(figures.len() >= 8, "{figures:?}");
    for f in figures {
        let (w, h) = (f["width"].as_f64().unwrap(), f["height"].as_f64().unwrap());
        assert!(w > 600.0 && h > 200.0 && w <= 1040.0, "figure {} is {w} x {h} px", f["id"]);
    }

    // The artifacts: a screenshot of the page and the certificate printed to PDF.
    let profile = tempfile::tempdir().unwrap();
    let url = format!("file://{}", artifacts.join("index.html").display());
    let shot = artifacts.join("report.png");
    let pdf = artifacts.join("report.pdf");
    let _ = std::fs::remove_file(&shot);
    let _ = std::fs::remove_file(&pdf);
    run(
        &browser,
        profile.path(),
        &[format!("--screenshot={}", shot.display()), "--window-size=1100,2400".into()],
        &url,
    );
    let profile = tempfile::tempdir().unwrap();
    run(
        &browser,
        profile.path(),
        &[format!("--print-to-pdf={}", pdf.display()), "--no-pdf-header-footer".into()],
        &url,
    );
    let png = std::fs::read(&shot).expect("the screenshot");
    assert!(png.starts_with(b"\x89PNG") && png.len() > 50_000, "a screenshot of the page ({} bytes)", png.len());
    let printed = std::fs::read(&pdf).expect("the PDF");
    let pages = printed.windows(10).filter(|w| w == b"/Type /Pag").count();
    // A section a page: header, errors, hysteresis, spectrum, interpolation,
    // table, verification, model-gap, ISO, ISO per target.
    assert!(printed.starts_with(b"%PDF") && pages >= 10, "the printed report has {pages} page objects");
    println!("report in the browser: screenshot {}, printed {}", shot.display(), pdf.display());
}

#[test]
fn a_page_with_an_error_fails_the_check() {
    let browser = match chromium() {
        Ok(b) => b,
        Err(why) => {
            println!("skipped: {why}");
            return;
        }
    };
    let work = tempfile::tempdir().unwrap();
    let page = "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
        <meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; style-src 'unsafe-inline'\">\
        <title>broken</title></head><body><p>x</p><img alt=\"\" src=\"missing.png\">\
        <script>console.error('deliberate console error'); throw new Error('deliberate');</script></body></html>";
    let (seen, logged) = check(&browser, work.path(), page);
    let errs = errors(&seen, &logged).join("\n");
    println!("the deliberate errors, as caught:\n{errs}");
    assert!(errs.contains("deliberate console error"), "console.error is caught:\n{errs}");
    assert!(errs.contains("Error: deliberate") || errs.contains("Uncaught"), "an uncaught error is caught:\n{errs}");
    assert!(errs.contains("missing.png"), "a refused or failed load is caught:\n{errs}");
    // A table wider than the page and a figure taller than one are found.
    let page = "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
        <meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; style-src 'unsafe-inline'\">\
        <title>wide</title><style>@media print{td{white-space:nowrap}}</style></head><body>\
        <table id=\"too-wide\"><tr><td>WIDE WIDE WIDE WIDE WIDE WIDE WIDE WIDE WIDE WIDE WIDE WIDE WIDE WIDE WIDE \
        WIDE WIDE WIDE WIDE WIDE WIDE WIDE WIDE WIDE WIDE</td></tr></table>\
        <figure id=\"too-tall\" style=\"height:1200px\"></figure></body></html>";
    let seen = layout(&browser, work.path(), page);
    let found = |key: &str, id: &str| seen[key].as_array().unwrap().iter().any(|e| e.as_str().unwrap().contains(id));
    assert!(found("wide", "TABLE#too-wide") && found("tall", "FIGURE#too-tall"), "the overflow is found: {seen:#}");
}

/// `pdftotext`'s text of one page of `pdf`, or `None` without poppler-utils.
fn page_text(pdf: &Path, page: usize) -> Option<String> {
    let p = page.to_string();
    let out = Command::new("pdftotext").args(["-f", &p, "-l", &p, "-layout"]).arg(pdf).arg("-").output().ok()?;
    out.status.success().then(|| String::from_utf8_lossy(&out.stdout).into_owned())
}

/// The lines of a printed page's text that are not its running head or foot.
fn body_lines(text: &str) -> Vec<&str> {
    text.lines()
        .map(str::trim)
        .filter(|l| {
            !l.is_empty() && !l.starts_with("Rehearsal, not a calibration: certificate CAL-9") && !l.contains(" of ")
        })
        .collect()
}

/// Every page of `pdf` (of `pages`) says which it is, holds the number
/// `CAL-9` once and at least three lines of its own (never a page left
/// with one line, the last of a note: issue 50); `false` without pdftotext.
fn assert_pages_hold_lines(pdf: &Path, pages: usize) -> bool {
    if page_text(pdf, 1).is_none() {
        println!("pdftotext absent (Debian: poppler-utils): the pages' own text was not read");
        return false;
    }
    for page in 1..=pages {
        let text = page_text(pdf, page).unwrap();
        // Every page says which it is and how many there are, as the PDF has them.
        assert!(text.contains(&format!("page {page} of {pages}")), "page {page} of {pages}:\n{text}");
        assert_eq!(text.matches("CAL-9").count(), 1, "the number once on page {page}:\n{text}");
        assert!(body_lines(&text).len() >= 3, "page {page} is blank but for a line or two:\n{text}");
    }
    true
}

/// The number of pages of the PDF at `pdf`.
fn pdf_pages(pdf: &Path) -> usize {
    let printed = std::fs::read(pdf).expect("the PDF beside the page");
    assert!(printed.starts_with(b"%PDF"), "a PDF");
    let key = b"/Type /Page";
    printed.windows(key.len() + 1).filter(|w| w.starts_with(key) && w[key.len()] != b's').count()
}

/// Small surveys printed, none of their pages holding a line or two alone
/// (issue 50): 12 targets one way on the simulated bench (the hysteresis
/// section, a sentence, once had a page of its own), and 12 targets x 2
/// runs of the example configuration over `survey sim` (a page held only
/// "frequency)", the last line of the note under the spectrum's lines).
#[test]
fn small_surveys_print_no_page_with_a_line_or_two_alone() {
    let browser = match chromium() {
        Ok(b) => b,
        Err(why) => {
            println!("skipped: {why}");
            return;
        }
    };
    let one_way = Bench::new();
    one_way.survey(&["run", "--points", "12"]).success();
    let configured = Bench::new();
    let example = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/config/modbus-emscon.toml");
    let sim = super::walk::Sim::start(&configured, &["sim", "--config", example, "--time-scale", "1000"]);
    configured.survey(&["run", "--config", &sim.config, "--points", "12", "--runs", "2"]).success();
    drop(sim);
    for bench in [&one_way, &configured] {
        bench.survey(&["report", "--out", "r", "--pdf", "--certificate-number", "CAL-9"]).success();
        let pdf = bench.path("r/index.pdf");
        let pages = pdf_pages(&pdf);
        assert!((4..=12).contains(&pages), "{pages} pages");
        assert_fits_the_page(&layout(&browser, bench.path("r").as_path(), &bench.read("r/index.html")));
        assert_pages_hold_lines(&pdf, pages);
    }
}

/// The default survey (`survey run --points 1800 --bidirectional`) printed:
/// the certificate itself in at most 12 pages, none blank, its number once a
/// page, "page x of y" on each, nothing wider than a page; the appendix only
/// with `--appendix`. About 15 s in a debug build: the survey is the
/// default's, whose page count is the claim.
#[test]
fn report_pdf_prints_the_certificate_in_at_most_12_pages_with_page_x_of_y_on_every_page() {
    let browser = match chromium() {
        Ok(b) => b,
        Err(why) => {
            println!("skipped: {why}");
            return;
        }
    };
    let bench = Bench::new();
    bench.survey(&["run", "--points", "1800", "--bidirectional"]).success();
    let out = bench
        .survey(&["report", "--out", "r", "--pdf", "--certificate-number", "CAL-9", "--tolerance", "0.05"])
        .success();
    let pdf = bench.path("r/index.pdf");
    let pages = pdf_pages(&pdf);
    assert!(out.stdout.contains(&format!("r/index.pdf ({pages} pages)")), "it says how many pages: {out}");
    // The certificate, not its data: a section a page at most, the appendix left out.
    assert!((6..=12).contains(&pages), "{pages} pages");
    assert_fits_the_page(&layout(&browser, bench.path("r").as_path(), &bench.read("r/index.html")));
    if assert_pages_hold_lines(&pdf, pages) {
        let first = page_text(&pdf, 1).unwrap();
        assert!(first.contains("Rehearsal, not a calibration: certificate CAL-9"), "the title: {first}");
        let last = page_text(&pdf, pages).unwrap();
        assert!(last.contains("End of the certificate"), "the certificate ends on its last page:\n{last}");
        assert!(!last.contains("Appendix A"), "no appendix without --appendix");
    }
    // With --appendix the appendix is printed after the end of the certificate, open.
    // (The certificate is issued: printing its appendix too is an amendment.)
    bench.survey(&["report", "--out", "a", "--appendix", "--amend", "the appendix printed too"]).success();
    let html = bench.read("a/index.html");
    assert!(
        html.contains("<section id=\"iso230-targets\" class=\"page appendix\">") && html.contains("<details open>")
    );
    assert!(html.find("End of the certificate") < html.find("Appendix A"), "the appendix follows the end");
}

// ---------------------------------------------------------------------------
// `survey serve`'s pages, live
// ---------------------------------------------------------------------------

/// The DOM of `url` after `budget_ms` of the page's (virtual) time, and the
/// browser's console lines: on a served page every console message is an
/// error (the pages log nothing; a refused fetch, a failed load or an
/// uncaught error are logged as `CONSOLE` lines).
fn open_live(browser: &Path, url: &str, budget_ms: u64) -> (String, Vec<String>) {
    let profile = tempfile::tempdir().expect("a browser profile");
    let args = vec![
        "--dump-dom".to_string(),
        format!("--virtual-time-budget={budget_ms}"),
        "--enable-logging=stderr".into(),
        "--v=0".into(),
    ];
    let (dom, log) = run(browser, profile.path(), &args, url);
    (dom, log.lines().filter(|l| l.contains("CONSOLE")).map(str::to_string).collect())
}

/// The value of `attr` on the element of `id` in `dom`.
fn attribute(dom: &str, id: &str, attr: &str) -> Option<String> {
    let at = dom.find(&format!("id=\"{id}\""))?;
    let start = dom[..at].rfind('<')?;
    let end = at + dom[at..].find('>')?;
    let tag = &dom[start..end];
    Some(tag.split(&format!("{attr}=\"")).nth(1)?.split('"').next()?.to_string())
}

#[test]
fn the_lab_pages_open_in_chromium_with_their_elements_and_no_error() {
    let browser = match chromium() {
        Ok(b) => b,
        Err(why) => {
            println!("skipped: {why}");
            return;
        }
    };
    let bench = Bench::new();
    bench.survey(&["run", "--points", "36", "--runs", "2", "--bidirectional", "--json"]).success();
    bench.survey(&["run", "--points", "36", "--runs", "2", "--bidirectional", "--seed", "2", "--json"]).success();
    let uid = bench.survey(&["list", "--json"]).success().json()["surveys"][1]["uid"].as_str().unwrap().to_string();
    // A survey whose process died (like a power loss) stays stored `running`:
    // no process holds it, so no page shows it being acquired.
    let killed = bench.command(&["run", "--points", "36", "--runs", "2", "--sim-crash-after", "20"]).output().unwrap();
    assert!(!killed.status.success(), "the survey was killed");
    let server = super::serve::Server::on(&bench, "survey.db", &["--refresh", "0.5"]);

    let (dom, console) = open_live(&browser, &format!("{}/", server.url), 3000);
    assert!(console.is_empty(), "/ logged: {console:#?}");
    assert!(!dom.contains("class=\"live\""), "a survey no process holds is not live:\n{dom}");
    assert_eq!(attribute(&dom, "live-none", "hidden"), None, "'none being acquired' is shown:\n{dom}");
    for id in ["live", "live-list", "live-none", "live-status", "assets", "tbl-assets"] {
        assert!(dom.contains(&format!("id=\"{id}\"")), "/ in the browser lacks {id}");
    }
    assert!(dom.contains("<a href=\"/assets/sim-fig8\">sim-fig8</a>"));
    let refreshes: u64 = dom
        .split("data-refreshes=\"")
        .nth(1)
        .and_then(|s| s.split('"').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("the script refreshed nothing:\n{dom}"));
    assert!(refreshes >= 2, "{refreshes} refreshes in 3 s at 0.5 s");

    let (dom, console) = open_live(&browser, &format!("{}/assets/sim-fig8", server.url), 1000);
    assert!(console.is_empty(), "the asset's page logged: {console:#?}");
    for id in ["history", "fig-history-lines", "fig-history-a", "tbl-history"] {
        assert!(dom.contains(&format!("id=\"{id}\"")), "the asset's page lacks {id}");
    }
    assert!(dom.contains(&format!("href=\"/surveys/{uid}\"")));
    // The plots' time axis in UTC, never fractions of a day.
    assert!(dom.contains("time of day (UTC)") && !dom.contains("days since"), "the asset's page:\n{dom}");

    let (dom, console) = open_live(&browser, &format!("{}/surveys/{uid}", server.url), 1000);
    assert!(console.is_empty(), "the survey's page logged: {console:#?}");
    // The way back: home and the asset's history.
    assert!(dom.contains("<a href=\"/assets/sim-fig8\">sim-fig8</a>") && dom.contains("id=\"way-back\""), "{dom}");
    for id in ALWAYS {
        assert!(dom.contains(&format!("id=\"{id}\"")), "the survey's page lacks {id}");
    }

    // The check sees an error: a page whose inline script the policy refuses.
    let work = tempfile::tempdir().unwrap();
    let broken = work.path().join("broken.html");
    std::fs::write(
        &broken,
        "<!doctype html><html><head><meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'\">\
         </head><body><script>console.log('x')</script><img src=\"/missing.png\"></body></html>",
    )
    .unwrap();
    let (_, console) = open_live(&browser, &format!("file://{}", broken.display()), 500);
    assert!(!console.is_empty(), "a refused script is logged");
}

#[test]
fn a_survey_being_acquired_moves_on_the_open_page_without_a_reload() {
    use survey_acquire::{RawReading, RecordedSample};
    use survey_processing::{Direction, Sample};
    use survey_store::Store;
    use survey_store::survey::NewSurvey;

    let browser = match chromium() {
        Ok(b) => b,
        Err(why) => {
            println!("skipped: {why}");
            return;
        }
    };
    let bench = Bench::new();
    let db = bench.path("survey.db");
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    // A station acquiring: a survey of 10 targets both ways, 2 runs, written in steps.
    let sample = |seq: u64| {
        let (run, k) = (1 + (seq / 20) as u32, seq % 20);
        let (direction, target) =
            if k < 10 { (Direction::Forward, k as f64 * 36.0) } else { (Direction::Reverse, (19 - k) as f64 * 36.0) };
        RecordedSample {
            seq,
            others: Vec::new(),
            sample: Sample {
                run,
                direction,
                target_deg: target,
                readout_deg: target,
                actual_deg: target + 1e-3,
                timestamp_s: Some(seq as f64 * 2.0),
            },
            raw: RawReading::None,
        }
    };
    let (store, id) = rt.block_on(async {
        let store = Store::open(&db).await.unwrap();
        let new = NewSurvey {
            points: Some(10),
            runs: Some(2),
            bidirectional: true,
            planned_samples: Some(40),
            asset: "rig-9".into(),
            ..NewSurvey::default()
        };
        // Acquired by this process: its lock held to the end of the test
        // (a `running` survey no process holds is not live).
        let (id, lock) = store.create_acquired_survey(&new).await.unwrap();
        store.set_started(id, 0.0).await.unwrap();
        store.append(id, &(0..5).map(sample).collect::<Vec<_>>()).await.unwrap();
        (store, (id, lock))
    });
    let (id, _lock) = id;
    let mut cmd = bench.command(&["serve", "--listen", "127.0.0.1:0", "--refresh", "0.1"]);
    cmd.env("RUST_LOG", "warn,survey_serve=info");
    let server = super::serve::Server::start(cmd);
    let uid = super::serve::get(&server.url, "/api/live").json()["surveys"][0]["uid"].as_str().unwrap().to_string();

    // The browser opens `/` and keeps it open for 60 s of its time (every
    // fetch pauses that clock: 600 refreshes at least).
    let url = format!("{}/", server.url);
    let b = browser.clone();
    let opened = std::thread::spawn(move || open_live(&b, &url, 60_000));
    // Once `/` is served, the station stores 20 more samples; then wait for
    // the page to read /api/live after them.
    let deadline = Instant::now() + Duration::from_secs(60);
    let wait_for = |what: &str| loop {
        let line = server.log.recv_timeout(deadline.saturating_duration_since(Instant::now())).unwrap_or_else(|_| {
            panic!("no request for {what} within the deadline");
        });
        if line.contains("served") && line.contains(&format!("path={what} ")) {
            return;
        }
    };
    wait_for("/");
    rt.block_on(store.append(id, &(5..25).map(sample).collect::<Vec<_>>())).unwrap();
    wait_for("/api/live");
    let (dom, console) = opened.join().unwrap();
    assert!(console.is_empty(), "/ logged: {console:#?}");
    let shown = attribute(&dom, &format!("live-{uid}"), "data-samples");
    assert_eq!(shown.as_deref(), Some("25"), "the page shows the samples stored after it loaded");
    assert!(dom.contains("25 of 40 samples"), "{dom}");
    let served_pages = server.log.try_iter().filter(|l| l.contains("path=/ ")).count();
    assert_eq!(served_pages, 0, "the page was not loaded again");
    rt.block_on(store.close());
}

/// Chromium driven over the DevTools protocol on a pipe
/// (`--remote-debugging-pipe`: it reads commands on descriptor 3 and writes
/// answers on 4, JSON messages each ended by a NUL byte), the descriptors
/// given by a shell from two FIFOs: a browser that types into a form and
/// submits it, with nothing but the standard library.
struct Devtools {
    child: std::process::Child,
    to: std::fs::File,
    from: std::io::BufReader<std::fs::File>,
    next: u64,
    session: String,
    _profile: tempfile::TempDir,
}

impl Devtools {
    fn start(browser: &Path) -> Devtools {
        use nix::sys::stat::Mode;
        let profile = tempfile::tempdir().expect("a browser profile");
        let (fifo_in, fifo_out) = (profile.path().join("cdp-in"), profile.path().join("cdp-out"));
        for f in [&fifo_in, &fifo_out] {
            nix::unistd::mkfifo(f, Mode::S_IRUSR | Mode::S_IWUSR).expect("a FIFO");
        }
        let mut cmd = Command::new("sh");
        cmd.arg("-c").arg("exec \"$0\" \"$@\" 3<\"$CDP_IN\" 4>\"$CDP_OUT\"").arg(browser).args(FLAGS);
        cmd.arg(format!("--user-data-dir={}", profile.path().join("data").display()));
        cmd.args(["--remote-debugging-pipe", "about:blank"]).env("CDP_IN", &fifo_in).env("CDP_OUT", &fifo_out);
        let child = cmd.stdin(Stdio::null()).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
        // The same order as the shell's: its 3 (our writer), then its 4 (our reader).
        let to = std::fs::OpenOptions::new().write(true).open(&fifo_in).expect("the command pipe");
        let from = std::io::BufReader::new(std::fs::File::open(&fifo_out).expect("the answer pipe"));
        let mut tools = Devtools { child, to, from, next: 0, session: String::new(), _profile: profile };
        let target = tools.call("Target.createTarget", serde_json::json!({"url": "about:blank"}));
        let target = target["targetId"].as_str().unwrap().to_string();
        let attached = tools.call("Target.attachToTarget", serde_json::json!({"targetId": target, "flatten": true}));
        tools.session = attached["sessionId"].as_str().unwrap().to_string();
        tools
    }

    /// Send `method` (to the page once attached) and wait for its answer.
    fn call(&mut self, method: &str, params: Value) -> Value {
        match self.try_call(method, params) {
            Ok(result) => result,
            Err(answer) => panic!("{method}: {answer}"),
        }
    }

    /// [`Devtools::call`], the browser's error answer as the error.
    fn try_call(&mut self, method: &str, params: Value) -> Result<Value, Value> {
        use std::io::{BufRead as _, Write as _};
        self.next += 1;
        let mut message = serde_json::json!({"id": self.next, "method": method, "params": params});
        if !self.session.is_empty() {
            message["sessionId"] = Value::from(self.session.clone());
        }
        let mut bytes = message.to_string().into_bytes();
        bytes.push(0);
        self.to.write_all(&bytes).expect("a command to the browser");
        loop {
            let mut raw = Vec::new();
            let n = self.from.read_until(0, &mut raw).expect("an answer from the browser");
            assert!(n > 0, "the browser closed its pipe");
            raw.pop();
            let answer: Value = serde_json::from_slice(&raw).expect("JSON from the browser");
            if answer["id"].as_u64() == Some(self.next) {
                return match answer.get("error") {
                    None => Ok(answer["result"].clone()),
                    Some(_) => Err(answer),
                };
            }
        }
    }

    /// The value of `expression` in the page (`null` while it is loading,
    /// and when the page navigated away while it was evaluated: the
    /// browser answers "Inspected target navigated or closed").
    fn eval(&mut self, expression: &str) -> Value {
        let params = serde_json::json!({"expression": expression, "returnByValue": true});
        match self.try_call("Runtime.evaluate", params) {
            Ok(r) => r["result"]["value"].clone(),
            Err(answer) if answer.to_string().contains("navigated or closed") => Value::Null,
            Err(answer) => panic!("Runtime.evaluate: {answer}"),
        }
    }

    /// Wait until the page at `path` has loaded (the browser's own clock: at most 30 s).
    fn loaded(&mut self, path: &str) {
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let at = self.eval("document.readyState === 'complete' ? location.pathname : ''");
            if at.as_str() == Some(path) {
                return;
            }
            let html = self.eval("document.documentElement.outerHTML");
            assert!(Instant::now() < deadline, "never at {path}; at {at}:\n{html}");
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Devtools {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn behind_the_door_the_browser_sees_the_login_then_after_it_the_page() {
    let browser = match chromium() {
        Ok(b) => b,
        Err(why) => {
            println!("skipped: {why}");
            return;
        }
    };
    let bench = Bench::new();
    bench.write("valid.csv", super::VALID_CSV);
    bench.survey(&["import", "valid.csv", "--asset", "rig-1"]).success();
    let mut hashing = bench.command(&["serve", "--hash-password"]);
    let out = hashing.stdin(Stdio::piped()).stdout(Stdio::piped()).spawn().and_then(|mut c| {
        use std::io::Write as _;
        c.stdin.take().unwrap().write_all(b"open sesame\n")?;
        c.wait_with_output()
    });
    let hash = String::from_utf8(out.unwrap().stdout).unwrap();
    bench.write("auth.toml", format!("[[user]]\nname = \"lab\"\npassword_hash = \"{}\"\n", hash.trim()));
    let server = super::serve::Server::on(&bench, "survey.db", &["--auth", "auth.toml"]);
    let mut tools = Devtools::start(&browser);
    tools.call("Page.navigate", serde_json::json!({"url": format!("{}/assets/rig-1", server.url)}));
    // Without a session: the login form, nothing of the asset.
    tools.loaded("/login");
    let html = tools.eval("document.documentElement.outerHTML").as_str().unwrap().to_string();
    assert!(html.contains("id=\"login\"") && !html.contains("id=\"history\""), "{html}");
    let type_in = |password: &str| {
        format!(
            "document.getElementById('name').value = 'lab'; document.getElementById('password').value = '{password}'; \
             document.getElementById('login').requestSubmit(); true"
        )
    };
    tools.eval(&type_in("open sesam"));
    let deadline = Instant::now() + Duration::from_secs(30);
    while tools
        .eval("document.getElementById('login-message') ? document.getElementById('login-message').textContent : ''")
        != "The name or the password is wrong."
    {
        if Instant::now() > deadline {
            let html = tools.eval("location.href + ' ' + document.documentElement.outerHTML");
            panic!("no word of the wrong password: {html}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    tools.eval(&type_in("open sesame"));
    // The page asked for, after the login; the cookie out of the page's reach.
    tools.loaded("/assets/rig-1");
    let html = tools.eval("document.documentElement.outerHTML").as_str().unwrap().to_string();
    for id in ["history", "tbl-history"] {
        assert!(html.contains(&format!("id=\"{id}\"")), "the asset's page lacks {id}:\n{html}");
    }
    assert_eq!(tools.eval("document.cookie"), "", "the session cookie is HttpOnly");
    tools.call("Page.navigate", serde_json::json!({"url": format!("{}/", server.url)}));
    tools.loaded("/");
    assert_eq!(tools.eval("!!document.getElementById('assets')"), true);
    // Logged out by the pages' link and its button: the login again.
    tools.eval("document.getElementById('log-out').click(); true");
    tools.loaded("/logout");
    tools.eval("document.getElementById('logout').requestSubmit(); true");
    tools.loaded("/login");
    tools.call("Page.navigate", serde_json::json!({"url": format!("{}/assets/rig-1", server.url)}));
    let deadline = Instant::now() + Duration::from_secs(30);
    let next = "document.readyState === 'complete' && location.pathname === '/login' ? \
                document.querySelector('input[name=next]').value : ''";
    while tools.eval(next) != "/assets/rig-1" {
        assert!(Instant::now() < deadline, "the asset's page after the logout: not the login");
        std::thread::sleep(Duration::from_millis(50));
    }
    let _ = tools.call("Browser.close", Value::Null);
    let (code, log) = server.stop_and_log();
    assert_eq!(code, Some(0));
    assert_eq!(log.iter().filter(|l| l.contains("a failed login")).count(), 1, "{log:#?}");
}
