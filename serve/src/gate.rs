//! The door of `--auth FILE`: who may read the pages.
//!
//! - a browser logs in through the form of `/login` (POST, same origin
//!   only) and gets a session: a random 256-bit token in a cookie
//!   (`HttpOnly`, `SameSite=Strict`, `Secure` over TLS) that the server
//!   knows by its SHA-256 only; a session ends after [`Door::session_idle`]
//!   without a request (8 hours by default), [`SESSION_MAX`] after the login
//!   whatever its use, on `POST /logout`, or when the server stops;
//! - a program sends HTTP Basic credentials with each request (a name and
//!   password checked once are remembered, by a keyed digest, for
//!   [`BASIC_REMEMBERED`], so a program polling every second costs one
//!   argon2 check every few minutes);
//! - without either, `/api/...` is answered 401 with `WWW-Authenticate`, a
//!   page is a redirection to `/login?next=PATH`, and only `/login` answers;
//! - failed logins are counted per client address (an IPv6 address by its
//!   /64) and name: the first [`FREE_FAILURES`] cost nothing, each further
//!   one refuses that name from the address for 1 minute, doubling at each
//!   failure up to 1 hour ([`Failures::lock_for`]); a login that succeeds
//!   clears its own name's count only (one account's holder cannot clear
//!   what was guessed at another's). The address's failures over every
//!   name are counted too, never cleared by a success: beyond
//!   [`ADDRESS_FREE_FAILURES`] the whole address is refused on the same
//!   schedule (guessing many names). A refused login is answered 429 with
//!   `Retry-After` and its password is not even checked. Each failure is
//!   logged (warning) with the name tried and the address, never the
//!   password.

use super::auth::Users;
use super::{App, html_body};
use axum::body::Body;
use axum::extract::{Request, State};
use axum::http::{HeaderMap, HeaderValue, Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use base64::Engine as _;
use sha2::{Digest as _, Sha256};
use std::collections::HashMap;
use std::net::{IpAddr, Ipv6Addr, SocketAddr};
use std::sync::{Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};
use survey_report::page::{Running, document_under, escape};

/// The session cookie's name.
pub const COOKIE: &str = "survey_session";
/// A session ends this long after its login, however it is used.
pub const SESSION_MAX: Duration = Duration::from_secs(24 * 3600);
/// Sessions kept at most (beyond, the one idle longest ends).
const MAX_SESSIONS: usize = 10_000;
/// Failed logins as one name from one address that cost nothing.
pub const FREE_FAILURES: u32 = 4;
/// Failed logins from one address, over every name, that cost nothing.
pub const ADDRESS_FREE_FAILURES: u32 = 20;
/// How long Basic credentials checked once are remembered.
pub const BASIC_REMEMBERED: Duration = Duration::from_secs(300);
/// Addresses whose failures are counted at most (beyond, the one that failed longest ago is forgotten).
const MAX_ADDRESSES: usize = 10_000;
/// A count of failures is forgotten this long after its last failure.
const FAILURES_FORGOTTEN: Duration = Duration::from_secs(24 * 3600);

/// The policy of the login and logout pages: the pages' own, but their
/// form may post to this server.
const FORM_POLICY: &str = "default-src 'none'; style-src 'unsafe-inline'; img-src 'self' data:; base-uri 'none'; \
                           form-action 'self'; frame-ancestors 'none'";

/// What `--auth` sets up.
#[derive(Debug, Clone)]
pub struct Door {
    /// The users and their hashes.
    pub users: Users,
    /// A session ends after this long without a request.
    pub session_idle: Duration,
    /// The pages are served over TLS: the cookie is `Secure`.
    pub tls: bool,
}

/// The door's state while the server runs.
#[derive(Debug)]
pub(crate) struct Gate {
    door: Door,
    sessions: Mutex<Sessions>,
    failures: Mutex<Failures>,
    remembered: Mutex<HashMap<[u8; 32], Instant>>,
    /// The key of [`Gate::remembered`]'s digests (random, this process's only).
    key: [u8; 32],
    /// The threads that check passwords ([`Checkers`]).
    checkers: Checkers,
}

/// A password to check, and where to say whether it is right.
type Job = (String, String, tokio::sync::oneshot::Sender<bool>);

/// Argon2 checks on threads of their own, as many as there are cores (each
/// check takes 19 MiB and tens of milliseconds), each in memory it keeps
/// for its next check: the memory of logins is bounded by these threads
/// (about 19 MiB each), however many logins come. (Checked on the blocking
/// pool with the crate's own allocation, each failed login left about 20
/// MiB more resident: the allocator keeps freed memory per thread arena.)
#[derive(Debug)]
struct Checkers {
    jobs: Mutex<std::sync::mpsc::Sender<Job>>,
}

impl Checkers {
    fn start(users: &Users) -> Checkers {
        let (jobs, queue) = std::sync::mpsc::channel::<Job>();
        let queue = std::sync::Arc::new(Mutex::new(queue));
        let threads = std::thread::available_parallelism().map_or(2, |n| n.get());
        for i in 0..threads {
            let (users, queue) = (users.clone(), std::sync::Arc::clone(&queue));
            let spawned = std::thread::Builder::new().name(format!("login-{i}")).spawn(move || {
                let mut blocks = Vec::new();
                loop {
                    let job = lock(&queue).recv();
                    let Ok((name, password, answer)) = job else { return };
                    let _ = answer.send(users.check_in(&name, &password, &mut blocks));
                }
            });
            if let Err(e) = spawned {
                tracing::warn!("cannot start a thread to check passwords: {e}");
            }
        }
        Checkers { jobs: Mutex::new(jobs) }
    }

    /// Whether `password` is `name`'s (false when no thread can say).
    async fn check(&self, name: &str, password: &str) -> bool {
        let (answer, answered) = tokio::sync::oneshot::channel();
        if lock(&self.jobs).send((name.to_string(), password.to_string(), answer)).is_err() {
            return false;
        }
        answered.await.unwrap_or(false)
    }
}

/// The client's address, as the connection gave it ([`crate::doors`]).
#[derive(Debug, Clone, Copy)]
pub struct Peer(pub SocketAddr);

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

fn random_32() -> [u8; 32] {
    let mut bytes = [0u8; 32];
    getrandom::fill(&mut bytes).expect("random numbers from the system");
    bytes
}

/// What a login attempt came to.
#[derive(Debug, PartialEq)]
pub(crate) enum Checked {
    Ok,
    Wrong,
    /// The address is refused for this long.
    Refused(Duration),
}

impl Gate {
    pub(crate) fn new(door: Door) -> Gate {
        Gate {
            sessions: Mutex::new(Sessions::new(door.session_idle)),
            checkers: Checkers::start(&door.users),
            door,
            failures: Mutex::new(Failures::default()),
            remembered: Mutex::new(HashMap::new()),
            key: random_32(),
        }
    }

    fn digest(&self, name: &str, password: &str) -> [u8; 32] {
        let mut h = Sha256::new();
        h.update(self.key);
        h.update(name.as_bytes());
        h.update([0]);
        h.update(password.as_bytes());
        h.finalize().into()
    }

    /// Check `name` and `password` from `peer`, counting a failure against its address.
    pub(crate) async fn check(&self, peer: IpAddr, name: &str, password: &str, how: &str) -> Checked {
        let now = Instant::now();
        if let Some(wait) = lock(&self.failures).refused(peer, name, now) {
            tracing::warn!(user = ?clip(name), client = %peer, how, "a login refused: too many failed logins from this address");
            return Checked::Refused(wait);
        }
        let digest = self.digest(name, password);
        if lock(&self.remembered).get(&digest).is_some_and(|&until| now < until) {
            lock(&self.failures).succeeded(peer, name);
            return Checked::Ok;
        }
        let ok = self.checkers.check(name, password).await;
        let now = Instant::now();
        if ok {
            lock(&self.failures).succeeded(peer, name);
            let mut remembered = lock(&self.remembered);
            if remembered.len() >= 256 {
                remembered.retain(|_, &mut until| now < until);
                if remembered.len() >= 256 {
                    remembered.clear();
                }
            }
            remembered.insert(digest, now + BASIC_REMEMBERED);
            return Checked::Ok;
        }
        let (count, refused) = lock(&self.failures).failed(peer, name, now);
        tracing::warn!(user = ?clip(name), client = %peer, how, failures = count, "a failed login");
        if let Some(wait) = refused {
            tracing::warn!(user = ?clip(name), client = %peer, "failed logins: this address is refused for {} s", wait.as_secs());
        }
        Checked::Wrong
    }
}

/// A name as logged: at most 64 characters.
fn clip(name: &str) -> String {
    name.chars().take(64).collect()
}

/// The sessions, by the SHA-256 of their token.
#[derive(Debug)]
pub(crate) struct Sessions {
    by_digest: HashMap<[u8; 32], Session>,
    idle: Duration,
}

#[derive(Debug)]
struct Session {
    user: String,
    created: Instant,
    seen: Instant,
}

fn token_digest(token: &str) -> [u8; 32] {
    Sha256::digest(token.as_bytes()).into()
}

impl Sessions {
    pub(crate) fn new(idle: Duration) -> Sessions {
        Sessions { by_digest: HashMap::new(), idle }
    }

    fn alive(&self, s: &Session, now: Instant) -> bool {
        now.saturating_duration_since(s.seen) < self.idle && now.saturating_duration_since(s.created) < SESSION_MAX
    }

    /// A new session of `user`: its token.
    pub(crate) fn open(&mut self, user: &str, now: Instant) -> String {
        if self.by_digest.len() >= MAX_SESSIONS {
            let idle = self.idle;
            self.by_digest.retain(|_, s| now.saturating_duration_since(s.seen) < idle);
            if self.by_digest.len() >= MAX_SESSIONS
                && let Some(oldest) = self.by_digest.iter().min_by_key(|(_, s)| s.seen).map(|(&d, _)| d)
            {
                self.by_digest.remove(&oldest);
            }
        }
        let token = base64::engine::general_purpose::URL_SAFE_NO_PAD.encode(random_32());
        self.by_digest.insert(token_digest(&token), Session { user: user.to_string(), created: now, seen: now });
        token
    }

    /// The user of the session `token`, its use noted; `None` (and the
    /// session ended) once it has expired.
    pub(crate) fn touch(&mut self, token: &str, now: Instant) -> Option<String> {
        let digest = token_digest(token);
        let alive = self.alive(self.by_digest.get(&digest)?, now);
        if !alive {
            self.by_digest.remove(&digest);
            return None;
        }
        let s = self.by_digest.get_mut(&digest)?;
        s.seen = now;
        Some(s.user.clone())
    }

    pub(crate) fn end(&mut self, token: &str) {
        self.by_digest.remove(&token_digest(token));
    }
}

/// Failed logins by client address.
/// Failed logins: per address and name, and per address over every name.
#[derive(Debug, Default)]
pub(crate) struct Failures {
    by_account: Counts<(IpAddr, String)>,
    by_client: Counts<IpAddr>,
}

/// Failures counted by a key.
#[derive(Debug)]
struct Counts<K> {
    map: HashMap<K, Failed>,
}

impl<K> Default for Counts<K> {
    fn default() -> Self {
        Counts { map: HashMap::new() }
    }
}

#[derive(Debug)]
struct Failed {
    count: u32,
    last: Instant,
    refused_until: Option<Instant>,
}

/// An IPv6 client is counted by its /64 (one machine is given a /64).
fn client_of(ip: IpAddr) -> IpAddr {
    match ip {
        IpAddr::V6(v6) if v6.to_ipv4_mapped().is_none() => {
            let s = v6.segments();
            IpAddr::V6(Ipv6Addr::new(s[0], s[1], s[2], s[3], 0, 0, 0, 0))
        }
        IpAddr::V6(v6) => IpAddr::V4(v6.to_ipv4_mapped().unwrap_or(std::net::Ipv4Addr::UNSPECIFIED)),
        v4 => v4,
    }
}

impl<K: std::hash::Hash + Eq + Clone> Counts<K> {
    fn refused(&self, key: &K, now: Instant) -> Option<Duration> {
        let f = self.map.get(key)?;
        f.refused_until.filter(|&until| now < until).map(|until| until - now)
    }

    /// A failure of `key`: its count in a row, and how long it is now refused
    /// (none for the first `free`).
    fn failed(&mut self, key: K, now: Instant, free: u32) -> (u32, Option<Duration>) {
        if self.map.len() >= MAX_ADDRESSES && !self.map.contains_key(&key) {
            self.map.retain(|_, f| now.saturating_duration_since(f.last) < FAILURES_FORGOTTEN);
            if self.map.len() >= MAX_ADDRESSES
                && let Some(oldest) = self.map.iter().min_by_key(|(_, f)| f.last).map(|(c, _)| c.clone())
            {
                self.map.remove(&oldest);
            }
        }
        let f = self.map.entry(key).or_insert(Failed { count: 0, last: now, refused_until: None });
        if now.saturating_duration_since(f.last) >= FAILURES_FORGOTTEN {
            f.count = 0;
        }
        f.count += 1;
        f.last = now;
        let refused = f.count.checked_sub(free - FREE_FAILURES).and_then(Failures::lock_for);
        f.refused_until = refused.map(|d| now + d);
        (f.count, refused)
    }
}

impl Failures {
    /// How long an address is refused after its `count`th failure in a row:
    /// nothing for the first [`FREE_FAILURES`], then 1 minute doubling at
    /// each failure, at most 1 hour.
    pub(crate) fn lock_for(count: u32) -> Option<Duration> {
        let beyond = count.checked_sub(FREE_FAILURES + 1)?;
        Some(Duration::from_secs((60u64 << beyond.min(6)).min(3600)))
    }

    fn account(ip: IpAddr, name: &str) -> (IpAddr, String) {
        (client_of(ip), clip(name))
    }

    /// How much longer `name` from `ip` is refused, if it is (the address's
    /// own refusal included).
    pub(crate) fn refused(&mut self, ip: IpAddr, name: &str, now: Instant) -> Option<Duration> {
        let account = self.by_account.refused(&Failures::account(ip, name), now);
        account.max(self.by_client.refused(&client_of(ip), now))
    }

    /// A failure of `name` from `ip`: the name's count in a row from there,
    /// and how long it is now refused (the longer of the name's and the address's).
    pub(crate) fn failed(&mut self, ip: IpAddr, name: &str, now: Instant) -> (u32, Option<Duration>) {
        let (count, account) = self.by_account.failed(Failures::account(ip, name), now, FREE_FAILURES);
        let (_, address) = self.by_client.failed(client_of(ip), now, ADDRESS_FREE_FAILURES);
        (count, account.max(address))
    }

    /// A login of `name` from `ip` succeeded: its own count cleared (not
    /// another name's, nor the address's).
    pub(crate) fn succeeded(&mut self, ip: IpAddr, name: &str) {
        self.by_account.map.remove(&Failures::account(ip, name));
    }
}

/// The value of the cookie `name` in `headers`.
fn cookie<'h>(headers: &'h HeaderMap, name: &str) -> Option<&'h str> {
    headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(';'))
        .filter_map(|kv| kv.trim().split_once('='))
        .find(|(k, _)| *k == name)
        .map(|(_, v)| v)
}

/// HTTP Basic credentials in `headers`: the name and the password.
fn basic(headers: &HeaderMap) -> Option<(String, String)> {
    let value = headers.get(header::AUTHORIZATION)?.to_str().ok()?;
    let (scheme, encoded) = value.trim().split_once(' ')?;
    if !scheme.eq_ignore_ascii_case("basic") {
        return None;
    }
    let decoded = base64::engine::general_purpose::STANDARD.decode(encoded.trim()).ok()?;
    let text = String::from_utf8(decoded).ok()?;
    let (name, password) = text.split_once(':')?;
    Some((name.to_string(), password.to_string()))
}

fn peer_of(req: &Request) -> IpAddr {
    req.extensions().get::<Peer>().map_or(IpAddr::V4(std::net::Ipv4Addr::UNSPECIFIED), |p| p.0.ip())
}

fn is_api(path: &str) -> bool {
    path == "/api" || path.starts_with("/api/")
}

/// 401 with the Basic challenge (JSON under `/api/`, a page otherwise).
fn unauthorized(api: bool, why: &str) -> Response {
    let mut r = if api {
        (StatusCode::UNAUTHORIZED, super::json_body(&serde_json::json!({"error": why}))).into_response()
    } else {
        (StatusCode::UNAUTHORIZED, html_body(super::pages::failure(StatusCode::UNAUTHORIZED, why))).into_response()
    };
    r.headers_mut()
        .insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Basic realm=\"survey\", charset=\"UTF-8\""));
    r
}

/// 429 with `Retry-After`.
fn refused(wait: Duration, api: bool) -> Response {
    let why = format!("too many failed logins from this address: try again in {} s", wait.as_secs().max(1));
    let mut r = if api {
        (StatusCode::TOO_MANY_REQUESTS, super::json_body(&serde_json::json!({"error": why}))).into_response()
    } else {
        (StatusCode::TOO_MANY_REQUESTS, html_body(login_page("/", &why))).into_response()
    };
    r.headers_mut().insert(header::RETRY_AFTER, HeaderValue::from(wait.as_secs().max(1)));
    r
}

fn see_other(to: &str) -> Response {
    let mut r = StatusCode::SEE_OTHER.into_response();
    if let Ok(v) = HeaderValue::from_str(to) {
        r.headers_mut().insert(header::LOCATION, v);
    }
    r
}

/// Every request but `/login` and `/logout` when `--auth` is given: a live
/// session or Basic credentials, else 401 (`/api/`) or the login page.
pub(crate) async fn gate(State(app): State<App>, req: Request, next: Next) -> Response {
    let Some(gate) = app.gate.as_ref() else { return next.run(req).await };
    let path = req.uri().path();
    if path == "/login" || path == "/logout" {
        return next.run(req).await;
    }
    if let Some(token) = cookie(req.headers(), COOKIE)
        && lock(&gate.sessions).touch(token, Instant::now()).is_some()
    {
        return next.run(req).await;
    }
    let api = is_api(path);
    match basic(req.headers()) {
        Some((name, password)) => match gate.check(peer_of(&req), &name, &password, "basic").await {
            Checked::Ok => next.run(req).await,
            Checked::Wrong => unauthorized(api, "the name or the password is wrong"),
            Checked::Refused(wait) => refused(wait, api),
        },
        None if api => unauthorized(api, "log in: send HTTP Basic credentials of a user of the server's --auth file"),
        None => {
            let wanted = req.uri().path_and_query().map_or("/", |p| p.as_str());
            let next: String = form_urlencoded::Serializer::new(String::new()).append_pair("next", wanted).finish();
            see_other(&format!("/login?{next}"))
        }
    }
}

/// Where to go after the login: a path of this server only (never `//host`).
fn local_target(next: Option<&str>) -> String {
    match next {
        Some(n) if n.starts_with('/') && !n.starts_with("//") && !n.contains('\\') && !n.contains(['\r', '\n']) => {
            n.to_string()
        }
        _ => "/".into(),
    }
}

/// The login page, with `message` (empty: none).
fn login_page(next: &str, message: &str) -> String {
    let body = format!(
        "<h1>Log in</h1>\n<form id=\"login\" method=\"post\" action=\"/login\">\n\
         <input type=\"hidden\" name=\"next\" value=\"{next}\">\n\
         <p><label>Name <input name=\"name\" id=\"name\" autocomplete=\"username\" required autofocus></label></p>\n\
         <p><label>Password <input type=\"password\" name=\"password\" id=\"password\" \
         autocomplete=\"current-password\" required></label></p>\n\
         <p><button type=\"submit\" id=\"log-in\">Log in</button></p>\n</form>\n<p id=\"login-message\">{message}</p>\n",
        next = escape(next),
        message = escape(message),
    );
    document_under(FORM_POLICY, "Log in: the lab's surveys", &Running::default(), &body)
}

fn form_page(status: StatusCode, page: String) -> Response {
    let mut r = (status, html_body(page)).into_response();
    r.headers_mut().insert(header::CONTENT_SECURITY_POLICY, HeaderValue::from_static(FORM_POLICY));
    r
}

/// `GET /login?next=PATH`: the form.
pub(crate) async fn login_form(req: Request) -> Response {
    let next = req
        .uri()
        .query()
        .and_then(|q| form_urlencoded::parse(q.as_bytes()).find(|(k, _)| k == "next").map(|(_, v)| v.into_owned()));
    form_page(StatusCode::OK, login_page(&local_target(next.as_deref()), ""))
}

/// A POST from another site is refused: a browser says where a form came
/// from in `Sec-Fetch-Site` (its `Origin` is `null` under the pages'
/// `Referrer-Policy: no-referrer`); an older one by `Origin`; a program
/// sends neither.
fn same_origin(headers: &HeaderMap) -> bool {
    if let Some(site) = headers.get("sec-fetch-site") {
        return site == "same-origin";
    }
    let Some(origin) = headers.get(header::ORIGIN).and_then(|v| v.to_str().ok()) else { return true };
    let host = headers.get(header::HOST).and_then(|v| v.to_str().ok()).unwrap_or_default();
    origin.split_once("://").is_some_and(|(_, o)| !host.is_empty() && o == host)
}

/// `POST /login`: the form's name and password; a session and the page
/// asked for, or the form again saying why not.
pub(crate) async fn login(State(app): State<App>, req: Request) -> Response {
    let Some(gate) = app.gate.as_ref() else { return see_other("/") };
    if !same_origin(req.headers()) {
        return form_page(StatusCode::FORBIDDEN, login_page("/", "a login from another site is refused"));
    }
    let peer = peer_of(&req);
    let Ok(body) = axum::body::to_bytes(req.into_body(), 16 * 1024).await else {
        return form_page(StatusCode::PAYLOAD_TOO_LARGE, login_page("/", "the form is too long"));
    };
    let (mut name, mut password, mut next) = (String::new(), String::new(), None);
    for (k, v) in form_urlencoded::parse(&body) {
        match &*k {
            "name" => name = v.into_owned(),
            "password" => password = v.into_owned(),
            "next" => next = Some(v.into_owned()),
            _ => {}
        }
    }
    let next = local_target(next.as_deref());
    match gate.check(peer, &name, &password, "form").await {
        Checked::Ok => {
            let token = lock(&gate.sessions).open(&name, Instant::now());
            tracing::info!(user = ?clip(&name), client = %peer, "logged in");
            let mut r = see_other(&next);
            let secure = if gate.door.tls { "; Secure" } else { "" };
            let cookie = format!("{COOKIE}={token}; Path=/; HttpOnly; SameSite=Strict{secure}");
            r.headers_mut().insert(header::SET_COOKIE, HeaderValue::from_str(&cookie).expect("a cookie's characters"));
            r
        }
        Checked::Wrong => form_page(StatusCode::UNAUTHORIZED, login_page(&next, "The name or the password is wrong.")),
        Checked::Refused(wait) => {
            let mut r = refused(wait, false);
            r.headers_mut().insert(header::CONTENT_SECURITY_POLICY, HeaderValue::from_static(FORM_POLICY));
            r
        }
    }
}

/// `GET /logout`: a button that logs out.
pub(crate) async fn logout_form() -> Response {
    let body = "<h1>Log out</h1>\n<form id=\"logout\" method=\"post\" action=\"/logout\">\
                <p><button type=\"submit\" id=\"log-out\">Log out</button></p></form>\n";
    form_page(StatusCode::OK, document_under(FORM_POLICY, "Log out", &Running::default(), body))
}

/// `POST /logout`: the session ends; to the login page.
pub(crate) async fn logout(State(app): State<App>, req: Request<Body>) -> Response {
    if let (Some(gate), Some(token)) = (app.gate.as_ref(), cookie(req.headers(), COOKIE)) {
        lock(&gate.sessions).end(token);
    }
    let mut r = see_other("/login");
    let secure = app.gate.as_ref().is_some_and(|g| g.door.tls);
    let cookie =
        format!("{COOKIE}=; Path=/; HttpOnly; SameSite=Strict; Max-Age=0{}", if secure { "; Secure" } else { "" });
    r.headers_mut().insert(header::SET_COOKIE, HeaderValue::from_str(&cookie).expect("a cookie's characters"));
    r
}

/// The methods each path answers: GET and HEAD everywhere, POST at the
/// login and the logout when there is a door.
pub(crate) fn allowed(method: &Method, path: &str, door: bool) -> bool {
    method == Method::GET
        || method == Method::HEAD
        || (door && method == Method::POST && matches!(path, "/login" | "/logout"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_session_ends_when_idle_or_old_and_on_logout() {
        let t0 = Instant::now();
        let mut s = Sessions::new(Duration::from_secs(8 * 3600));
        let token = s.open("lab", t0);
        assert_eq!(token.len(), 43, "256 bits in base64");
        assert_eq!(s.touch(&token, t0 + Duration::from_secs(7 * 3600)).as_deref(), Some("lab"));
        // Used every 7 hours: still alive at 14 h, ended at 24 h whatever its use.
        assert!(s.touch(&token, t0 + Duration::from_secs(14 * 3600)).is_some());
        assert!(s.touch(&token, t0 + Duration::from_secs(21 * 3600)).is_some());
        assert!(s.touch(&token, t0 + SESSION_MAX).is_none());
        let idle = s.open("lab", t0);
        assert!(s.touch(&idle, t0 + Duration::from_secs(8 * 3600)).is_none(), "8 h without a request");
        assert!(s.touch(&idle, t0).is_none(), "an ended session stays ended");
        let out = s.open("lab", t0);
        s.end(&out);
        assert!(s.touch(&out, t0).is_none());
        assert!(s.touch("made-up", t0).is_none());
    }

    #[test]
    fn failures_refuse_an_address_for_longer_and_longer() {
        let secs = |n| Failures::lock_for(n).map(|d| d.as_secs());
        let schedule: Vec<_> = (1..=13).map(secs).collect();
        assert_eq!(
            schedule,
            [
                None,
                None,
                None,
                None,
                Some(60),
                Some(120),
                Some(240),
                Some(480),
                Some(960),
                Some(1920),
                Some(3600),
                Some(3600),
                Some(3600)
            ]
        );
        let (t0, a, b): (Instant, IpAddr, IpAddr) =
            (Instant::now(), "10.0.0.7".parse().unwrap(), "10.0.0.8".parse().unwrap());
        let mut f = Failures::default();
        for n in 1..=4 {
            assert_eq!(f.failed(a, "lab", t0), (n, None));
            assert_eq!(f.refused(a, "lab", t0), None);
        }
        assert_eq!(f.failed(a, "lab", t0), (5, Some(Duration::from_secs(60))));
        assert_eq!(f.refused(a, "lab", t0 + Duration::from_secs(59)), Some(Duration::from_secs(1)));
        assert_eq!(f.refused(b, "lab", t0), None, "another address is not refused");
        assert_eq!(f.refused(a, "lab", t0 + Duration::from_secs(60)), None);
        assert_eq!(f.failed(a, "lab", t0 + Duration::from_secs(61)).1, Some(Duration::from_secs(120)));
        f.succeeded(a, "lab");
        assert_eq!(f.failed(a, "lab", t0 + Duration::from_secs(62)), (1, None), "a success clears the count");
        // A day later, the count starts again.
        for _ in 0..5 {
            f.failed(b, "lab", t0);
        }
        assert_eq!(f.failed(b, "lab", t0 + FAILURES_FORGOTTEN), (1, None));
        // An IPv6 address by its /64.
        let (c, d): (IpAddr, IpAddr) = ("2001:db8:1:2::1".parse().unwrap(), "2001:db8:1:2::ffff".parse().unwrap());
        for _ in 0..5 {
            f.failed(c, "lab", t0);
        }
        assert!(f.refused(d, "lab", t0).is_some());
    }

    /// One account's holder cannot clear, by logging in, what was guessed
    /// at another account from the same address; guessing many names from
    /// one address refuses the address.
    #[test]
    fn failures_are_counted_per_address_and_name_and_a_success_clears_only_its_own() {
        let (t0, a): (Instant, IpAddr) = (Instant::now(), "10.0.0.7".parse().unwrap());
        let mut f = Failures::default();
        for n in 1..=4 {
            assert_eq!(f.failed(a, "admin", t0), (n, None));
        }
        // The guesser's own account, logged into, clears nothing of admin's.
        f.succeeded(a, "mallory");
        assert_eq!(f.failed(a, "admin", t0), (5, Some(Duration::from_secs(60))));
        assert!(f.refused(a, "admin", t0).is_some());
        assert_eq!(f.refused(a, "mallory", t0), None, "another name from the address is not refused yet");
        // Many names from one address: the address itself, beyond its free failures.
        let mut f = Failures::default();
        for n in 0..ADDRESS_FREE_FAILURES {
            assert_eq!(f.failed(a, &format!("user{n}"), t0).1, None, "{n}");
            f.succeeded(a, &format!("user{n}"));
        }
        assert_eq!(f.failed(a, "one more", t0), (1, Some(Duration::from_secs(60))));
        assert!(f.refused(a, "lab", t0).is_some(), "the whole address");
    }

    #[test]
    fn basic_credentials_and_cookies_are_read() {
        let mut h = HeaderMap::new();
        h.insert(header::AUTHORIZATION, HeaderValue::from_static("Basic bGFiOnNlYzpyZXQ="));
        h.insert(header::COOKIE, HeaderValue::from_static("a=1; survey_session=tok; b=2"));
        assert_eq!(basic(&h), Some(("lab".into(), "sec:ret".into())));
        assert_eq!(cookie(&h, COOKIE), Some("tok"));
        h.insert(header::AUTHORIZATION, HeaderValue::from_static("Bearer x"));
        assert_eq!(basic(&h), None);
    }

    #[test]
    fn after_the_login_only_a_path_of_this_server() {
        assert_eq!(local_target(Some("/assets/a?x=1")), "/assets/a?x=1");
        for bad in ["//evil.example/", "https://evil.example/", "/\\evil", "x", ""] {
            assert_eq!(local_target(Some(bad)), "/", "{bad}");
        }
        assert_eq!(local_target(None), "/");
    }
}
