//! The page around the figures: the HTML skeleton, the stylesheet (screen
//! and print), a figure with its caption and legend, and small helpers.
//!
//! The page loads nothing: its Content-Security-Policy forbids every fetch
//! (`default-src 'none'`), so a browser refuses, and reports, anything that
//! is not inline. Print: A4, one section a page, no figure or table row cut
//! across pages, no note cut either, nor parted from the table or figure it
//! follows (a page never holds a note's last line alone), no paragraph
//! leaving fewer than three lines on a page, SVG scaled to the page width, and on every page the
//! certificate's running head and "page x of y" (CSS paged media: `@page`
//! margin boxes with `counter(page)` and `counter(pages)`, which Chromium
//! prints from version 131 on). The first page leaves the running head's
//! number out: its title states it (the number once a page). What is
//! marked `screen-only` (the folded appendix without `--appendix`) is not
//! printed.

use std::fmt::Write as _;

/// The stylesheet, screen and print.
const STYLE: &str = "\
body{font-family:'DejaVu Sans',Arial,Helvetica,sans-serif;font-size:15px;line-height:1.45;max-width:1040px;\
margin:1.5em auto;padding:0 1em;color:#1a1a1a;background:#fff}\
h1{font-size:1.6em;margin:0 0 .2em}h2{font-size:1.25em;border-bottom:1px solid #999;padding-bottom:.15em;margin-top:1.8em}\
h3{font-size:1.05em;margin:1.2em 0 .3em}\
figure{margin:1em 0}figure svg.plot{width:100%;height:auto;display:block}\
figcaption{font-size:.92em;color:#333;margin-top:.3em}\
ul.legend{list-style:none;padding:0;margin:.4em 0 0;display:flex;flex-wrap:wrap;gap:.3em 1.4em;font-size:.92em}\
ul.legend svg{width:30px;height:12px;vertical-align:middle;margin-right:.35em}\
table{border-collapse:collapse;margin:.6em 0;font-size:.9em}td,th{border:1px solid #bbb;padding:2px 7px;text-align:right}\
th{background:#eee}td.l,th.l{text-align:left}td{white-space:nowrap}td.l{white-space:normal}\
table.header td{text-align:left;white-space:normal;border:none;padding:1px 12px 1px 0;vertical-align:top}table.header td:first-child{font-weight:bold;white-space:nowrap}\
p.note,ul.note{color:#444;font-size:.92em}.subtitle{color:#444;margin:0 0 1em}\
p.verdict{font-size:1.1em;padding:.4em .7em;border-left:5px solid #999;background:#f4f4f4}\
p.verdict.pass{border-color:#009e73}p.verdict.fail{border-color:#d55e00}\
section.appendix table{font-size:.82em}details>summary{cursor:pointer;color:#444}\
table#tbl-summary td{white-space:normal}table#tbl-summary td.l{min-width:15em}ul.statements{font-size:.92em;padding-left:1.2em}\
span.signature{display:inline-block;width:20em;border-bottom:1px solid #333;height:1.8em}\
p.end{font-weight:bold;text-align:center;margin-top:1.4em;border-top:1px solid #999;padding-top:.4em}\
@media print{body{max-width:none;margin:0;padding:0;font-size:10pt}.screen-only{display:none}\
section.page{break-before:page}figure,tr,table.header,ul.legend{break-inside:avoid}h2,h3{break-after:avoid}\
table#tbl-table{break-inside:avoid}p,li{orphans:3;widows:3}\
p.note,p.verdict,p.end{break-inside:avoid}table+p.note,figure+p.note{break-before:avoid}\
thead{display:table-header-group}}";

/// The print margins' own rule: A4, and the boxes' type.
const PAGE_STYLE: &str = "size:A4;margin:16mm 14mm 15mm;\
@bottom-right{content:\"page \" counter(page) \" of \" counter(pages);font:8pt 'DejaVu Sans',Arial,sans-serif;color:#444}";

/// What every printed page repeats in its margins besides "page x of y":
/// the top left and right (the certificate and the laboratory), the bottom
/// left (the survey).
#[derive(Debug, Clone, Default)]
pub struct Running {
    pub top_left: String,
    pub top_right: String,
    pub bottom_left: String,
}

/// `s` as a CSS string (quoted): quotes and backslashes escaped, a line
/// break as `\A`, and `<` as `\3C` so that no text ends the style element.
pub fn css_string(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' | '\\' => {
                out.push('\\');
                out.push(c);
            }
            '\n' => out += "\\A ",
            '<' => out += "\\3C ",
            c if c.is_control() => {}
            c => out.push(c),
        }
    }
    out + "\""
}

/// The `@page` rule with the running head and foot of `running`.
fn page_rule(running: &Running) -> String {
    let boxes =
        [("top-left", &running.top_left), ("top-right", &running.top_right), ("bottom-left", &running.bottom_left)];
    let mut rule = format!("@page{{{PAGE_STYLE}");
    for (place, text) in boxes.iter().filter(|(_, t)| !t.is_empty()) {
        let _ =
            write!(rule, "@{place}{{content:{};font:8pt 'DejaVu Sans',Arial,sans-serif;color:#444}}", css_string(text));
    }
    // Page 1 states the number in its title: its running head leaves it out (the number once a page).
    rule + "}@page :first{@top-left{content:none}}"
}

/// Escape text for HTML.
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The report's Content-Security-Policy: nothing is fetched, no script runs.
pub const POLICY: &str = "default-src 'none'; style-src 'unsafe-inline'";

/// The whole page: `title`, the margins of every printed page, then `body` (already HTML).
pub fn document(title: &str, running: &Running, body: &str) -> String {
    document_under(POLICY, title, running, body)
}

/// [`document`] under another Content-Security-Policy (`survey serve`'s
/// pages, which fetch their own JSON).
pub fn document_under(policy: &str, title: &str, running: &Running, body: &str) -> String {
    format!(
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n\
         <meta http-equiv=\"Content-Security-Policy\" content=\"{policy}\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>{}</title>\n<style>{STYLE}\n{}</style></head><body>\n{body}</body></html>\n",
        escape(title),
        page_rule(running)
    )
}

/// How a legend entry is drawn: a line (solid or dashed), a band or a marker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Key {
    Line,
    Thin,
    Dashed,
    Band,
    Dot,
    Ring,
}

/// One legend entry: colour (`#rrggbb`), how it is drawn, what it is.
pub type LegendEntry = (String, Key, String);

/// A legend below a figure (never over the data).
pub fn legend(entries: &[LegendEntry]) -> String {
    let mut s = String::from("<ul class=\"legend\">");
    for (colour, key, label) in entries {
        let mark = match key {
            Key::Line => format!("<line x1=\"1\" y1=\"6\" x2=\"29\" y2=\"6\" stroke=\"{colour}\" stroke-width=\"3\"/>"),
            Key::Thin => format!(
                "<line x1=\"1\" y1=\"6\" x2=\"29\" y2=\"6\" stroke=\"{colour}\" stroke-opacity=\"0.5\" stroke-width=\"1.5\"/>"
            ),
            Key::Dashed => format!(
                "<line x1=\"1\" y1=\"6\" x2=\"29\" y2=\"6\" stroke=\"{colour}\" stroke-width=\"2\" stroke-dasharray=\"5 3\"/>"
            ),
            Key::Band => {
                format!("<rect x=\"1\" y=\"1\" width=\"28\" height=\"10\" fill=\"{colour}\" fill-opacity=\"0.3\"/>")
            }
            Key::Dot => format!("<circle cx=\"15\" cy=\"6\" r=\"4\" fill=\"{colour}\"/>"),
            Key::Ring => {
                format!("<circle cx=\"15\" cy=\"6\" r=\"4\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.5\"/>")
            }
        };
        let _ = write!(s, "<li><svg viewBox=\"0 0 30 12\" aria-hidden=\"true\">{mark}</svg>{}</li>", escape(label));
    }
    s + "</ul>"
}

/// A figure: its SVG, legend and caption, with `id` for the page's index
/// (and the browser test).
pub fn figure(id: &str, svg: &str, legend_html: &str, caption: &str) -> String {
    let svg = svg.replacen("<svg ", "<svg class=\"plot\" role=\"img\" ", 1);
    format!("<figure id=\"{id}\">\n{svg}\n{legend_html}<figcaption>{caption}</figcaption></figure>\n")
}

/// A table with `id`: header cells (the first left-aligned) and rows of
/// cells already escaped or formatted.
pub fn table(id: &str, head: &[&str], rows: &[Vec<String>]) -> String {
    table_left(id, head, rows, &[])
}

/// [`table`] with the columns `left` (besides the first) aligned left (text).
pub fn table_left(id: &str, head: &[&str], rows: &[Vec<String>], left: &[usize]) -> String {
    let class = |i: usize| if i == 0 || left.contains(&i) { " class=\"l\"" } else { "" };
    let mut s = format!("<table id=\"{id}\"><thead><tr>");
    for (i, h) in head.iter().enumerate() {
        let _ = write!(s, "<th{}>{h}</th>", class(i));
    }
    s += "</tr></thead><tbody>\n";
    for row in rows {
        s += "<tr>";
        for (i, c) in row.iter().enumerate() {
            let _ = write!(s, "<td{}>{c}</td>", class(i));
        }
        s += "</tr>\n";
    }
    s + "</tbody></table>\n"
}

/// A section of the page with its classes (`page` starts it on a new printed page).
pub fn section(id: &str, title: &str, classes: &[&str], body: &str) -> String {
    let class = if classes.is_empty() { String::new() } else { format!(" class=\"{}\"", classes.join(" ")) };
    format!("<section id=\"{id}\"{class}>\n<h2>{}</h2>\n{body}</section>\n", escape(title))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_page_forbids_every_fetch_and_escapes_its_title() {
        let running = Running { top_left: "Certificate \"7\" </style>".into(), ..Running::default() };
        let page = document("a <b> & c", &running, "<p>x</p>");
        assert!(page.contains("default-src 'none'") && page.contains("<title>a &lt;b&gt; &amp; c</title>"));
        assert!(page.contains("@media print") && page.contains("break-before:page"));
        assert!(!page.contains("src=") && !page.contains("href="));
        assert!(page.contains("@bottom-right{content:\"page \" counter(page) \" of \" counter(pages)"), "page x of y");
        assert!(page.contains("@top-left{content:\"Certificate \\\"7\\\" \\3C /style>\""), "{page}");
        assert!(!page.contains("@top-right"), "an empty box is left out");
        assert_eq!(page.matches("</style>").count(), 1, "no text ends the style element");
    }

    #[test]
    fn a_legend_sits_outside_the_plot_and_a_figure_carries_its_id() {
        let l = legend(&[("#0072b2".into(), Key::Line, "forward <mean>".into())]);
        assert!(l.starts_with("<ul class=\"legend\">") && l.contains("forward &lt;mean&gt;"));
        let f = figure("fig-x", "<svg width=\"1\">", &l, "cap");
        assert!(f.contains("<figure id=\"fig-x\">") && f.contains("<svg class=\"plot\""));
    }
}
