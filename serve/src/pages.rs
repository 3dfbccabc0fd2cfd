//! The pages: `/`, `/assets/<id>`, `/surveys/<uid>`, the error pages, and
//! the refresh script. Server-rendered HTML in the report's style, plots
//! as inline SVG, no framework.

use super::overview::{self, Asset, Live};
use super::{App, Failure, POLICY, html_body, offload, read, survey_ref};
use axum::extract::{Path as UrlPath, State};
use axum::http::{StatusCode, header};
use axum::response::IntoResponse;
use survey_report::page::{Running, document_under, escape, section};
use survey_report::{ReportOptions, Units};

/// The refresh script of `/`.
const SCRIPT: &str = include_str!("live.js");

/// A link to an asset's page (its id may hold `/`, kept as it is).
fn asset_link(asset: &str) -> String {
    format!("<a href=\"/assets/{0}\">{0}</a>", escape(asset))
}

/// A page of `survey serve`: the report's look, under the server's policy
/// (behind a door, a way to log out).
fn page(title: &str, body: &str, door: bool) -> String {
    let out = if door { " &middot; <a href=\"/logout\" id=\"log-out\">log out</a>" } else { "" };
    let nav = format!("<p class=\"subtitle\"><a href=\"/\">All assets and live surveys</a>{out}</p>\n");
    document_under(POLICY, title, &Running::default(), &format!("{nav}{body}"))
}

/// The element of a survey being acquired (the script keeps it up to date).
fn live_element(l: &Live) -> String {
    let s = &l.survey;
    let planned = s.planned_samples.map_or(String::new(), |p| format!(" of {p}"));
    let bar = s.planned_samples.map_or("<progress></progress>".into(), |p| {
        format!("<progress max=\"{p}\" value=\"{}\"></progress>", s.sample_count)
    });
    let left = l.time_left_s.map_or("time left: not known yet".into(), |t| {
        let m = (t / 60.0).round();
        if m < 1.0 {
            format!("time left: {t:.0} s")
        } else if m < 120.0 {
            format!("time left: {m} min")
        } else {
            format!("time left: {:.1} h", m / 60.0)
        }
    });
    // A survey's check points are shown as that survey's (`/api/live` names it too).
    let named = l.check_points_of.as_ref().unwrap_or(s);
    format!(
        "<div class=\"live\" id=\"live-{uid}\" data-samples=\"{n}\"><a href=\"/surveys/{uid}\">survey {id}{what}</a> \
         <span class=\"asset\">{asset}</span> {bar} <span class=\"done\">{n}{planned} samples</span>, \
         <span class=\"left\">{left}</span>, <span class=\"faults\">{f} {fw} met</span></div>\n",
        uid = escape(&named.uid),
        id = named.id,
        what = if l.check_points_of.is_some() { ": its check points" } else { "" },
        n = s.sample_count,
        asset = escape(&named.asset),
        f = l.faults,
        fw = if l.faults == 1 { "fault" } else { "faults" },
    )
}

/// The assets' table.
fn assets_table(assets: &[Asset]) -> String {
    let units = Units::Deg;
    let rows: Vec<Vec<String>> = assets
        .iter()
        .map(|a| {
            let (cal, made, iso) = match &a.calibration {
                Some((r, iso)) => {
                    (format!("<a href=\"/surveys/{}\">survey {}</a>", escape(&r.uid), r.id), escape(&r.created_at), iso)
                }
                None => ("none".into(), "-".into(), &None),
            };
            vec![
                asset_link(&a.asset),
                a.surveys.to_string(),
                cal,
                made,
                units.opt(iso.as_ref().map(|i| i.a)),
                units.opt(iso.as_ref().map(|i| i.r)),
                format!(
                    "<span class=\"state\" data-state=\"{0}\">{0}</span>: {1}",
                    a.state.0.as_str(),
                    escape(&a.state.1)
                ),
            ]
        })
        .collect();
    let head = ["asset", "surveys", "calibration in force", "made (UTC)", "A, deg", "R, deg", "state"];
    survey_report::page::table_left("tbl-assets", &head, &rows, &[0, 2, 3, 6])
}

/// `/`.
pub(super) async fn index(State(app): State<App>) -> Result<impl IntoResponse, Failure> {
    Ok(html_body(offload(app.clone(), false, index_page(app)).await?))
}

/// `/`'s page.
async fn index_page(app: App) -> Result<String, Failure> {
    let (assets, live) = read!(app, false, |store| {
        let assets = overview::assets(&store, app.due_after_days).await?;
        let live = overview::live(&store).await?;
        anyhow::Ok((assets, live))
    });
    let db = super::store_name(&app.db);
    let live_html: String = live.iter().map(live_element).collect();
    let body = format!(
        "<h1>Surveys of {db}</h1>\n{live}{assets}<script src=\"/static/live.js\"></script>\n",
        db = escape(&db),
        live = section(
            "live",
            "Being acquired now",
            &[],
            &format!(
                "<div id=\"live-list\">{live_html}</div>\n<p id=\"live-none\"{hidden}>No survey is being acquired.</p>\n\
                 <p class=\"note\" id=\"live-status\">refreshed every {s} s</p>\n",
                hidden = if live.is_empty() { "" } else { " hidden" },
                s = app.refresh_ms as f64 / 1000.0,
            )
        ),
        assets = section(
            "assets",
            "Assets",
            &[],
            &if assets.is_empty() {
                "<p>The database holds no survey yet.</p>\n".to_string()
            } else {
                assets_table(&assets)
                    + &format!(
                        "<p class=\"note\">State: <b>due</b> when it has no calibration, the calibration is older than \
                         {} days, its interval says its next check is due (<code>survey due</code>), or a check called for a \
                         recalibration not made yet; <b>changed</b> when the last \
                         check found the positioner changed but its table still holding; otherwise <b>in \
                         force</b> (the calibration holds; no tolerance is judged here: a certificate judges \
                         against a stated one).</p>\n",
                        app.due_after_days
                    )
            }
        ),
    );
    Ok(page(&format!("Surveys of {db}"), &body, app.gate.is_some()).replacen(
        "<body>",
        &format!("<body data-refresh-ms=\"{}\">", app.refresh_ms),
        1,
    ))
}

/// `/static/live.js`.
pub(super) async fn script() -> impl IntoResponse {
    ([(header::CONTENT_TYPE, "text/javascript; charset=utf-8")], SCRIPT)
}

/// `/assets/<id>`: the asset's history.
pub(super) async fn asset(
    State(app): State<App>,
    UrlPath(asset): UrlPath<String>,
) -> Result<impl IntoResponse, Failure> {
    let html = offload(app.clone(), false, async move {
        let now = std::time::SystemTime::now();
        let (h, due) = read!(app, false, |store| {
            let h = survey_lab::life::history::history(&store, &asset, None).await?;
            let due = survey_lab::life::due::due(&store, Some(&asset), now).await?;
            anyhow::Ok((h, due))
        });
        let figures =
            survey_report::html::history::figures(&h, None, Units::Deg, true).map_err(|e| Failure::of(&e, false))?;
        let control =
            survey_report::html::history::control_chart(&h).map_err(|e| Failure::of(&e, false))?.unwrap_or_default();
        let body = format!(
            "<h1>Asset {a}</h1>\n<p class=\"subtitle\">{n} {noun}; the history as JSON: \
             <a href=\"/api/history/{a}\">/api/history/{a}</a></p>\n{d}{c}{s}",
            a = escape(&h.asset),
            n = h.surveys.len(),
            noun = if h.surveys.len() == 1 { "survey" } else { "surveys" },
            d = section("due", "When it is due", &[], &due_html(&due, now)),
            c = section("control", "Control chart of the checks", &[], &(control + &control_table(&h))),
            s = section("history", "History", &[], &figures),
        );
        Ok(page(&format!("Asset {}", h.asset), &body, app.gate.is_some()))
    });
    Ok(html_body(html.await?))
}

/// What is due for the asset: `survey due`'s text, as a paragraph each.
fn due_html(due: &[survey_lab::life::due::AssetDue], now: std::time::SystemTime) -> String {
    let text = survey_lab::life::due::text(due, now);
    let mut lines = text.lines().skip(1);
    let head = lines.next().unwrap_or_default();
    let state = if due.iter().any(|d| d.due.overdue) { "due" } else { "in force" };
    let rest: String = lines.map(|l| format!("<p>{}</p>\n", escape(l.trim()))).collect();
    format!("<p><span class=\"state\" data-state=\"{state}\">{}</span></p>\n{rest}", escape(head.trim()))
}

/// The checks' control chart: one row a check.
fn control_table(h: &survey_lab::life::history::History) -> String {
    let chart = h.control();
    if chart.is_empty() {
        return "<p>No check yet.</p>\n".into();
    }
    let num = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3}"));
    let rows: Vec<Vec<String>> = h
        .checks
        .iter()
        .zip(&chart)
        .map(|(c, p)| {
            let when = h.surveys.iter().find(|e| e.survey.id == c.survey_id).map(|e| e.survey.created_at.clone());
            vec![
                format!("survey {}", c.survey_id),
                escape(&when.unwrap_or_default()),
                num(p.statistic),
                num(p.centre),
                num(p.lower()),
                num(p.upper()),
                match p.out_of_control() {
                    true => format!("out of control: {}", escape(&p.rules.join(", "))),
                    false => "in control".into(),
                },
            ]
        })
        .collect();
    let head = ["check", "made (UTC)", "statistic", "centre", "lower", "upper", "state"];
    survey_report::page::table_left("tbl-control", &head, &rows, &[0, 1, 6])
        + "<p class=\"note\">The statistic: the check's cells where the error moved by more than the table's U, over \
           one more than the most that may while the table holds (at 1 it no longer holds); the centre and limits from \
           the asset's earlier checks in control (docs/lab.md).</p>\n"
}

/// `/surveys/<uid>` (or an id): the survey's report, as `survey report` writes it.
/// `/surveys/<uid>` (or an id): the survey's certificate as issued (the
/// page `survey report` wrote, byte for byte, under the way back and the
/// list of the certificates it replaced), or, before one is issued, the
/// draft `survey report` would write.
pub(super) async fn survey(
    State(app): State<App>,
    UrlPath(survey): UrlPath<String>,
) -> Result<impl IntoResponse, Failure> {
    let r = survey_ref(&survey, false)?;
    let html = offload(app.clone(), false, async move {
        let c = read!(app, false, |store| certificate(&store, r).await);
        Ok::<_, Failure>(with_way_back(c.page, &c.asset, &c.uid, &c.replaced))
    });
    Ok(html_body(html.await?))
}

/// `/surveys/<uid>/dcc.xml`: the DCC as issued (or the draft's).
pub(super) async fn survey_dcc(
    State(app): State<App>,
    UrlPath(survey): UrlPath<String>,
) -> Result<impl IntoResponse, Failure> {
    let r = survey_ref(&survey, false)?;
    let xml = offload(app.clone(), false, async move {
        let c = read!(app, false, |store| certificate(&store, r).await);
        Ok::<_, Failure>(c.dcc)
    });
    Ok(([(header::CONTENT_TYPE, "application/xml; charset=utf-8")], xml.await?))
}

/// `/surveys/<uid>/certificate.html`: the page as issued, byte for byte (or the draft's).
pub(super) async fn survey_certificate(
    State(app): State<App>,
    UrlPath(survey): UrlPath<String>,
) -> Result<impl IntoResponse, Failure> {
    let r = survey_ref(&survey, false)?;
    let html = offload(app.clone(), false, async move {
        let c = read!(app, false, |store| certificate(&store, r).await);
        Ok::<_, Failure>(c.page)
    });
    Ok(html_body(html.await?))
}

/// `/surveys/<uid>/certificate.pdf`: the page as issued, printed by Chromium
/// as `survey report --pdf` prints it (the browser `SURVEY_CHROMIUM` names,
/// else one on `PATH`; bounded as the report's print is). One print at a
/// time among the pages' heavy work; without a browser a 503 says what to do
/// (the page prints from any browser too).
pub(super) async fn survey_pdf(
    State(app): State<App>,
    UrlPath(survey): UrlPath<String>,
) -> Result<impl IntoResponse, Failure> {
    let r = survey_ref(&survey, false)?;
    let pdf = offload(app.clone(), false, async move {
        let c = read!(app, false, |store| certificate(&store, r).await);
        let cannot = |e: anyhow::Error| Failure {
            status: axum::http::StatusCode::SERVICE_UNAVAILABLE,
            reason: format!(
                "the certificate cannot be printed to PDF here: {e:#} (its page, /surveys/{}/certificate.html, \
                 prints from any browser)",
                c.uid
            ),
            api: false,
        };
        let bound = survey_report::pdf::timeout().map_err(cannot)?;
        let folder = tempfile::tempdir().map_err(|e| cannot(e.into()))?;
        let (html, pdf) = (folder.path().join("certificate.html"), folder.path().join("certificate.pdf"));
        std::fs::write(&html, &c.page).map_err(|e| cannot(e.into()))?;
        survey_report::pdf::print(&html, &pdf, bound).await.map_err(cannot)?;
        std::fs::read(&pdf).map_err(|e| cannot(e.into()))
    });
    Ok(([(header::CONTENT_TYPE, "application/pdf")], pdf.await?))
}

/// A survey's certificate: the page and the DCC as issued, or its draft's.
#[derive(Debug)]
pub(super) struct Shown {
    page: String,
    dcc: String,
    asset: String,
    uid: String,
    /// The certificates it replaced: number, issued, and the reason of the one after it.
    replaced: Vec<(String, String, String)>,
}

/// The current certificate of survey `r` in `store`, with those it replaced.
async fn certificate(store: &survey_store::Store, r: survey_store::survey::SurveyRef) -> anyhow::Result<Shown> {
    let s = store.resolve(Some(r)).await?;
    let issued = store.certificates(s.id).await?;
    if let Some((current, earlier)) = issued.split_last() {
        // Each replaced certificate with the reason the next one gave.
        let replaced = earlier
            .iter()
            .zip(&issued[1..])
            .map(|(c, next)| (c.number.clone(), c.issued_at.clone(), next.reason.clone().unwrap_or_default()))
            .collect();
        let shown =
            Shown { page: current.page.clone(), dcc: current.dcc.clone(), asset: s.asset, uid: s.uid, replaced };
        return Ok(shown);
    }
    let opts = ReportOptions { quiet: true, ..ReportOptions::default() };
    let data = survey_report::gather(store, Some(survey_store::survey::SurveyRef::Id(s.id)), &opts).await?;
    let (page, dcc) = survey_report::issue::render(&data, &opts)?;
    Ok(Shown { page, dcc, asset: s.asset, uid: s.uid, replaced: Vec::new() })
}

/// A survey's report with the way back at its top: home, and its asset's
/// history (the report itself is the certificate `survey report` writes,
/// which has no links).
fn with_way_back(html: String, asset: &str, uid: &str, replaced: &[(String, String, String)]) -> String {
    let mut nav = format!(
        "<nav class=\"subtitle\" id=\"way-back\"><a href=\"/\">All assets and live surveys</a> &middot; \
         the history of {} &middot; this certificate as issued: <a href=\"/surveys/{uid}/certificate.html\">the \
         page</a>, <a href=\"/surveys/{uid}/dcc.xml\">its DCC (dcc.xml)</a>, <a \
         href=\"/surveys/{uid}/certificate.pdf\">printed (PDF)</a></nav>\n",
        asset_link(asset),
        uid = escape(uid)
    );
    if !replaced.is_empty() {
        let items: String = replaced
            .iter()
            .map(|(number, issued, why)| {
                format!("<li>{} issued {}, replaced: {}</li>", escape(number), escape(issued), escape(why))
            })
            .collect();
        nav +=
            &format!("<div class=\"subtitle\" id=\"replaced\">Certificates this one replaced:<ul>{items}</ul></div>\n");
    }
    match html.find("<body").and_then(|at| html[at..].find('>').map(|end| at + end + 1)) {
        Some(at) => format!("{}{nav}{}", &html[..at], &html[at..]),
        None => format!("{nav}{html}"),
    }
}

/// An error page.
pub(super) fn failure(status: StatusCode, reason: &str) -> String {
    let title = format!("{} {}", status.as_u16(), status.canonical_reason().unwrap_or(""));
    page(&title, &format!("<h1>{}</h1>\n<p id=\"reason\">{}</p>\n", escape(&title), escape(reason)), false)
}
