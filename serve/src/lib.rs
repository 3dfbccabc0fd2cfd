//! `survey serve`: the lab's pages, read-only, over HTTP (axum).
//!
//! - `/`: every asset with its calibration in force and its state, and the
//!   surveys being acquired now with their progress, refreshed in place by a
//!   small same-origin script (`/static/live.js`) that reads `/api/live`;
//! - `/assets/<id>`: the asset's history (plots over time, each survey linked);
//! - `/surveys/<uid>` (or an id): the survey's report, the page `survey report` writes;
//! - `/api/...`: the commands' `--json` documents ([`api`]).
//!
//! Every request opens the store read-only and closes it again
//! ([`survey_store::Store::open_read_only`]: an SQLite reader in WAL mode
//! never blocks the station writing into the same file, and never takes its
//! lock), so what a page shows is what is stored at that moment. Only GET and
//! HEAD are served (anything else: 405); every response carries a
//! Content-Security-Policy that lets a page fetch nothing but its own
//! script and JSON. A path that names nothing is a 404 page (JSON under
//! `/api/`); a store that cannot be read, a 503 with the reason (a lab
//! store's URL shown without its password).

mod auth;
mod doors;
mod gate;
mod overview;
mod pages;

pub use auth::{AuthFileError, Users, hash_password};
pub use doors::{Limits, Tls, TlsFileError, connection_bound};
pub use gate::{BASIC_REMEMBERED, Door, FREE_FAILURES, SESSION_MAX};

use axum::Router;
use axum::extract::{Request, State};
use axum::http::{HeaderValue, StatusCode, Uri, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde_json::{Value, json};
use std::path::PathBuf;
use std::sync::Arc;
use survey_store::is_not_found;

/// The pages' policy, as a literal (for `concat!`).
macro_rules! policy {
    () => {
        "default-src 'none'; style-src 'unsafe-inline'; script-src 'self'; connect-src 'self'; img-src 'self' data:; \
         base-uri 'none'; form-action 'none'"
    };
}

/// The Content-Security-Policy of the pages (in their `<meta>`): styles
/// inline, the one same-origin script, JSON from this server only; nothing else.
pub const POLICY: &str = policy!();

/// The policy of every response's header: [`POLICY`], and no page may frame
/// these (a directive only a header carries).
const HEADER_POLICY: &str = concat!(policy!(), "; frame-ancestors 'none'");

/// What the server is told.
#[derive(Debug, Clone)]
pub struct ServeOptions {
    /// The station's SQLite file or the lab store's URL.
    pub db: PathBuf,
    /// A calibration older than this many days is due.
    pub due_after_days: f64,
    /// How often `/` refreshes the live surveys, milliseconds.
    pub refresh_ms: u64,
    /// The bounds on connections, on the work done at once, on shutdown.
    pub limits: Limits,
    /// Who may read the pages (`--auth`); `None`: whoever reaches the address.
    pub door: Option<Door>,
    /// HTTPS on the server itself (`--tls-cert`, `--tls-key`).
    pub tls: Option<Tls>,
}

/// The server's state: what it was told, and the bound on the work done off
/// the async workers.
#[derive(Debug)]
struct AppState {
    options: ServeOptions,
    /// The door's sessions and counts of failed logins (`options.door`).
    gate: Option<gate::Gate>,
    /// Pages and documents computed at once on blocking threads ([`offload`]).
    heavy: tokio::sync::Semaphore,
    /// Pages and documents computed or waiting their turn ([`offload`]).
    admitted: tokio::sync::Semaphore,
}

impl std::ops::Deref for AppState {
    type Target = ServeOptions;

    fn deref(&self) -> &ServeOptions {
        &self.options
    }
}

type App = Arc<AppState>;

/// Run `work` (a page's or a document's reads and computing: a history, a
/// report, plots) on a blocking thread, [`Limits::heavy_at_once`] at once
/// (as many as there are cores), up to [`Limits::heavy_queue`] more waiting
/// their turn, and beyond those a 503 with `Retry-After` at once: the async
/// workers stay free, so `/api/live` and the static script answer at once
/// whatever the pages cost, and a burst of requests costs the memory of a
/// few pages, not of all of them at once.
async fn offload<T: Send + 'static>(
    app: App,
    api: bool,
    work: impl Future<Output = Result<T, Failure>> + Send + 'static,
) -> Result<T, Failure> {
    let stopped = |why: String| Failure {
        status: StatusCode::SERVICE_UNAVAILABLE,
        reason: format!("the request's work stopped: {why}"),
        api,
    };
    let Ok(_admitted) = app.admitted.try_acquire() else {
        return Err(Failure::busy(&app.limits, api));
    };
    let _turn = app.heavy.acquire().await.map_err(|e| stopped(e.to_string()))?;
    let runtime = tokio::runtime::Handle::current();
    let hold = app.limits.hold;
    tokio::task::spawn_blocking(move || {
        let done = runtime.block_on(work);
        std::thread::sleep(hold);
        done
    })
    .await
    .map_err(|e| stopped(e.to_string()))?
}

/// What a 503 asks the client to wait, seconds.
const RETRY_AFTER_S: u64 = 2;

/// Why a request was not served.
#[derive(Debug)]
struct Failure {
    status: StatusCode,
    reason: String,
    /// Answer in JSON (an `/api/` path) rather than a page.
    api: bool,
}

impl Failure {
    /// The store could not be opened.
    fn unavailable(e: &anyhow::Error, api: bool) -> Failure {
        Failure {
            status: StatusCode::SERVICE_UNAVAILABLE,
            reason: format!("the survey database cannot be read: {e:#}"),
            api,
        }
    }

    /// What was asked for is not there (404), cannot be made from what is
    /// there (400), or the store failed while read (503).
    fn of(e: &anyhow::Error, api: bool) -> Failure {
        if is_not_found(e) {
            return Failure { status: StatusCode::NOT_FOUND, reason: format!("{e:#}"), api };
        }
        if survey_lab::error::exit_status(e) == 2 {
            return Failure { status: StatusCode::BAD_REQUEST, reason: format!("{e:#}"), api };
        }
        Failure::unavailable(e, api)
    }

    /// Too many pages and documents asked for at once: come back later.
    fn busy(limits: &Limits, api: bool) -> Failure {
        Failure {
            status: StatusCode::SERVICE_UNAVAILABLE,
            reason: format!(
                "busy: {} pages are being made and {} wait their turn; try again in {} s",
                limits.heavy_at_once, limits.heavy_queue, RETRY_AFTER_S
            ),
            api,
        }
    }

    fn not_found(what: String, api: bool) -> Failure {
        Failure { status: StatusCode::NOT_FOUND, reason: what, api }
    }
}

impl IntoResponse for Failure {
    fn into_response(self) -> Response {
        if self.status.is_server_error() {
            tracing::warn!(status = self.status.as_u16(), "{}", self.reason);
        }
        let mut response = if self.api {
            (self.status, json_body(&json!({"error": self.reason}))).into_response()
        } else {
            (self.status, html_body(pages::failure(self.status, &self.reason))).into_response()
        };
        if self.status == StatusCode::SERVICE_UNAVAILABLE {
            response.headers_mut().insert(header::RETRY_AFTER, HeaderValue::from(RETRY_AFTER_S));
        }
        response
    }
}

fn json_body(doc: &Value) -> ([(header::HeaderName, &'static str); 1], String) {
    ([(header::CONTENT_TYPE, "application/json")], format!("{doc}\n"))
}

fn html_body(page: String) -> ([(header::HeaderName, &'static str); 1], String) {
    ([(header::CONTENT_TYPE, "text/html; charset=utf-8")], page)
}

/// The store as the pages and documents name it: a lab store's URL without
/// its password, a station's SQLite file by its name alone (no local path
/// is shown to whoever reads the pages).
fn store_name(db: &std::path::Path) -> String {
    let shown = survey_store::lab::display(db);
    if shown.contains("://") {
        return shown;
    }
    db.file_name().map_or(shown, |n| n.to_string_lossy().into_owned())
}

/// `text` without the local paths of the store: the SQLite file's path (as
/// given, and absolute) by its name, the files beside it by theirs.
fn without_paths(text: &str, db: &std::path::Path) -> String {
    if survey_store::lab::display(db).contains("://") {
        return text.to_string();
    }
    let mut text = text.to_string();
    let absolute = std::path::absolute(db).ok();
    for path in [Some(db.to_path_buf()), absolute].into_iter().flatten() {
        if let Some(folder) = path.parent().map(|f| f.display().to_string()).filter(|f| !f.is_empty()) {
            text = text.replace(&format!("{folder}/"), "");
        }
    }
    text
}

/// `survey show --json` as `/api/` serves it: the instruments by driver and
/// transport, every other local path (in an event: a device's, a file's) said
/// as `(a local path)` (`survey show` itself, the operator's view, keeps them).
fn without_device_paths(mut doc: Value) -> Value {
    use survey_store::config::readdress::{instrument_words, without_local_paths};
    fn walk(v: &mut Value, f: &dyn Fn(&str) -> String) {
        match v {
            Value::String(s) => *s = f(s),
            Value::Array(items) => items.iter_mut().for_each(|i| walk(i, f)),
            Value::Object(map) => map.values_mut().for_each(|i| walk(i, f)),
            _ => {}
        }
    }
    for role in ["positioner", "reference"] {
        if let Some(v) = doc.get_mut("instruments").and_then(|i| i.get_mut(role)) {
            walk(v, &instrument_words);
        }
    }
    walk(&mut doc, &without_local_paths);
    doc
}

/// Open the store read-only, run `$body` with it bound to `$store`, close it;
/// the body's error mapped to its status.
macro_rules! read {
    ($app:expr, $api:expr, |$store:ident| $body:expr) => {{
        let $store = survey_store::Store::open_read_only(&$app.db).await.map_err(|e| Failure::unavailable(&e, $api))?;
        let result: anyhow::Result<_> = async { $body }.await;
        $store.close().await;
        // A lab store that went away: said in words, naming it.
        let result = result.map_err(|e| survey_store::lab::explained_at(&$app.db, e, "reading the lab store"));
        result.map_err(|e| Failure::of(&e, $api))?
    }};
}
use read;

/// A survey named in a path: an id or a uid (404 otherwise).
fn survey_ref(text: &str, api: bool) -> Result<survey_store::survey::SurveyRef, Failure> {
    text.parse().map_err(|e: String| Failure::not_found(e, api))
}

/// The server's routes, over the store `options.db`.
pub fn router(options: ServeOptions) -> Router {
    let app = Arc::new(AppState {
        heavy: tokio::sync::Semaphore::new(options.limits.heavy_at_once.max(1)),
        admitted: tokio::sync::Semaphore::new(options.limits.heavy_at_once.max(1) + options.limits.heavy_queue),
        gate: options.door.clone().map(gate::Gate::new),
        options,
    });
    let mut routes = Router::new();
    if app.gate.is_some() {
        routes = routes
            .route("/login", get(gate::login_form).post(gate::login))
            .route("/logout", get(gate::logout_form).post(gate::logout));
    }
    routes
        .route("/", get(pages::index))
        .route("/static/live.js", get(pages::script))
        .route("/assets/{*asset}", get(pages::asset))
        .route("/surveys/{survey}", get(pages::survey))
        .route("/surveys/{survey}/dcc.xml", get(pages::survey_dcc))
        .route("/surveys/{survey}/certificate.html", get(pages::survey_certificate))
        .route("/surveys/{survey}/certificate.pdf", get(pages::survey_pdf))
        // `/api/` and `/api` (the nest's own "/" would answer only the latter).
        .route("/api/", get(api::index))
        .route("/api", get(api::index))
        .nest("/api", api::routes())
        .fallback(not_found)
        .layer(middleware::from_fn_with_state(app.clone(), gate::gate))
        .layer(middleware::from_fn_with_state(app.clone(), guard))
        .with_state(app)
}

async fn not_found(uri: Uri) -> Failure {
    let api = uri.path().starts_with("/api/");
    Failure::not_found(format!("nothing at {}", uri.path()), api)
}

/// Every request: only GET and HEAD (and POST to log in and out); every
/// response: the policy (the login form's own, where it set one) and no caching.
async fn guard(State(app): State<App>, req: Request, next: Next) -> Response {
    let (method, path) = (req.method().clone(), req.uri().path().to_string());
    let mut response = if gate::allowed(&method, &path, app.gate.is_some()) {
        next.run(req).await
    } else {
        let mut r = (StatusCode::METHOD_NOT_ALLOWED, format!("{method} is not served: these pages are read-only\n"))
            .into_response();
        r.headers_mut().insert(header::ALLOW, HeaderValue::from_static("GET, HEAD"));
        r
    };
    if response.status().is_client_error() || response.status().is_server_error() {
        response = scrubbed(response, &app.db).await;
    }
    let h = response.headers_mut();
    h.entry(header::CONTENT_SECURITY_POLICY).or_insert(HeaderValue::from_static(HEADER_POLICY));
    h.insert(header::X_CONTENT_TYPE_OPTIONS, HeaderValue::from_static("nosniff"));
    h.insert(header::REFERRER_POLICY, HeaderValue::from_static("no-referrer"));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    tracing::info!(%method, path = %path, status = response.status().as_u16(), "served");
    response
}

/// An error's response without the store's local paths ([`without_paths`]).
async fn scrubbed(response: Response, db: &std::path::Path) -> Response {
    let (mut parts, body) = response.into_parts();
    let Ok(bytes) = axum::body::to_bytes(body, 1 << 20).await else {
        return (StatusCode::INTERNAL_SERVER_ERROR, "an error's answer too long to show\n").into_response();
    };
    let text = without_paths(&String::from_utf8_lossy(&bytes), db);
    parts.headers.remove(header::CONTENT_LENGTH);
    Response::from_parts(parts, axum::body::Body::from(text))
}

/// Serve `options.db` on `listener` until `shutdown` resolves; the requests
/// under way are answered first, within [`Limits::stop_within`] ([`doors`]).
pub async fn serve(
    listener: tokio::net::TcpListener,
    options: ServeOptions,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let (limits, tls) = (options.limits.clone(), options.tls.clone());
    doors::serve(listener, router(options), &limits, tls, shutdown).await
}

/// A future that resolves on SIGINT or SIGTERM, the handlers installed now
/// (before the ready line: a signal from then on ends the server gracefully).
pub fn on_signals() -> std::io::Result<impl Future<Output = ()> + Send + 'static> {
    use tokio::signal::unix::{SignalKind, signal};
    let (mut interrupt, mut terminate) = (signal(SignalKind::interrupt())?, signal(SignalKind::terminate())?);
    Ok(async move {
        tokio::select! {
            _ = interrupt.recv() => {}
            _ = terminate.recv() => {}
        }
    })
}

/// `/api/...`: the commands' `--json` documents, and `/`'s own (each but
/// `/api/live` made off the async workers: [`offload`]).
///
/// | path | document |
/// |---|---|
/// | `/api/surveys` | `survey list --json` |
/// | `/api/surveys/<id or uid>` | `survey show ID --json` |
/// | `/api/surveys/<id or uid>/stats` | `survey stats --survey ID --json` |
/// | `/api/history/<asset>` | `survey history --asset ID --json` |
/// | `/api/compare/<a>/<b>` | `survey compare A B --json` |
/// | `/api/assets` | the assets of `/`, each with its calibration in force and state |
/// | `/api/live` | the surveys being acquired now, with their progress |
/// | `/api/` | this list (`{"paths": [{"path", "document"}]}`) |
pub mod api {
    use super::{App, Failure, json_body, offload, survey_ref};
    use axum::Router;
    use axum::extract::{Path as UrlPath, State};
    use axum::response::IntoResponse;
    use axum::routing::get;
    use survey_lab::documents::{Stats, list_json, shown};
    use survey_lab::load::{Axis, load};

    /// What `/api/` serves: every path with its document (the table above), and the pages beside it.
    pub const INDEX: &[(&str, &str)] = &[
        ("/api/surveys", "survey list --json"),
        ("/api/surveys/<id or uid>", "survey show ID --json"),
        ("/api/surveys/<id or uid>/stats", "survey stats --survey ID --json"),
        ("/api/history/<asset>", "survey history --asset ID --json"),
        ("/api/compare/<a>/<b>", "survey compare A B --json"),
        ("/api/assets", "the assets of /, each with its calibration in force and state"),
        ("/api/due", "survey due --json, as of now"),
        ("/api/live", "the surveys being acquired now, with their progress"),
        ("/", "the assets and the surveys being acquired now, with their progress (a page)"),
        ("/assets/<asset>", "the asset's history: plots over time, every survey linked (a page)"),
        ("/surveys/<id or uid>", "the survey's certificate as issued (a page; its draft before)"),
        ("/surveys/<id or uid>/certificate.html", "the certificate's page as issued, byte for byte"),
        ("/surveys/<id or uid>/dcc.xml", "the certificate's DCC as issued, byte for byte"),
        ("/surveys/<id or uid>/certificate.pdf", "the certificate's page as issued, printed by Chromium"),
    ];

    pub(super) fn routes() -> Router<App> {
        Router::new()
            .route("/surveys", get(list))
            .route("/surveys/{survey}", get(show))
            .route("/surveys/{survey}/stats", get(stats))
            .route("/history/{*asset}", get(history))
            .route("/compare/{a}/{b}", get(compare))
            .route("/assets", get(assets))
            .route("/due", get(due))
            .route("/live", get(live))
    }

    /// `/api/due`: `survey due --json`, as of now.
    async fn due(State(app): State<App>) -> Result<impl IntoResponse, Failure> {
        let doc = offload(app.clone(), true, async move {
            let now = std::time::SystemTime::now();
            let all = read!(app, true, |store| survey_lab::life::due::due(&store, None, now).await);
            Ok(survey_lab::life::due::json(&all))
        });
        Ok(json_body(&doc.await?))
    }

    /// `/api/`: what it serves.
    pub(super) async fn index() -> impl IntoResponse {
        let paths: Vec<serde_json::Value> =
            INDEX.iter().map(|(path, what)| serde_json::json!({"path": path, "document": what})).collect();
        json_body(&serde_json::json!({ "paths": paths }))
    }

    async fn list(State(app): State<App>) -> Result<impl IntoResponse, Failure> {
        let doc = offload(app.clone(), true, async move {
            let surveys = read!(app, true, |store| store.list().await);
            Ok(list_json(&super::store_name(&app.db), &surveys))
        });
        Ok(json_body(&doc.await?))
    }

    async fn show(State(app): State<App>, UrlPath(survey): UrlPath<String>) -> Result<impl IntoResponse, Failure> {
        let r = survey_ref(&survey, true)?;
        let doc = offload(app.clone(), true, async move {
            let shown = read!(app, true, |store| shown(&store, Some(r)).await);
            Ok(super::without_device_paths(shown.json()))
        });
        Ok(json_body(&doc.await?))
    }

    async fn stats(State(app): State<App>, UrlPath(survey): UrlPath<String>) -> Result<impl IntoResponse, Failure> {
        let r = survey_ref(&survey, true)?;
        let doc = offload(app.clone(), true, async move {
            let loaded = read!(app, true, |store| load(&store, Some(r), Axis::Refitted).await);
            let stats = Stats::of(&loaded).map_err(|e| Failure::of(&e, true))?;
            Ok(stats.json(&loaded))
        });
        Ok(json_body(&doc.await?))
    }

    async fn history(State(app): State<App>, UrlPath(asset): UrlPath<String>) -> Result<impl IntoResponse, Failure> {
        let doc = offload(app.clone(), true, async move {
            let h = read!(app, true, |store| survey_lab::life::history::history(&store, &asset, None).await);
            Ok(h.json())
        });
        Ok(json_body(&doc.await?))
    }

    async fn compare(
        State(app): State<App>,
        UrlPath((a, b)): UrlPath<(String, String)>,
    ) -> Result<impl IntoResponse, Failure> {
        let (a, b) = (survey_ref(&a, true)?, survey_ref(&b, true)?);
        let doc = offload(app.clone(), true, async move {
            let (a, b) = read!(app, true, |store| {
                let a = survey_lab::life::measure(&store, a).await?;
                let b = survey_lab::life::measure(&store, b).await?;
                anyhow::Ok((a, b))
            });
            let c = survey_lab::life::compared(&a, &b).map_err(|e| Failure::of(&e, true))?;
            Ok(c.json(&a, &b))
        });
        Ok(json_body(&doc.await?))
    }

    async fn assets(State(app): State<App>) -> Result<impl IntoResponse, Failure> {
        let doc = offload(app.clone(), true, async move {
            let assets = read!(app, true, |store| super::overview::assets(&store, app.due_after_days).await);
            Ok(super::overview::assets_json(&assets))
        });
        Ok(json_body(&doc.await?))
    }

    async fn live(State(app): State<App>) -> Result<impl IntoResponse, Failure> {
        let live = read!(app, true, |store| super::overview::live(&store).await);
        Ok(json_body(&super::overview::live_json(&live)))
    }
}
