//! `survey serve` over HTTP, without a browser: every path and status, the
//! JSON documents equal to the commands' `--json`, the report equal to the
//! one `survey report` writes, the policy on every response, and a survey
//! acquired in another process into the same SQLite file seen moving on
//! `/api/live` and `/`.

use super::Bench;
use serde_json::Value;
use std::io::{BufRead as _, BufReader, Read as _, Write as _};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// A running `survey serve`, ended by SIGTERM when dropped.
pub struct Server {
    child: Child,
    /// `http://127.0.0.1:PORT`.
    pub url: String,
    /// Its stderr, line by line.
    pub log: mpsc::Receiver<String>,
}

impl Server {
    /// Start `cmd` (a `survey ... serve` command) and wait for its ready line.
    pub fn start(mut cmd: Command) -> Server {
        let mut child = cmd.stdout(Stdio::piped()).stderr(Stdio::piped()).stdin(Stdio::null()).spawn().unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        let ready: Value = serde_json::from_str(&line).unwrap_or_else(|e| panic!("the ready line {line:?}: {e}"));
        let url = ready["listening"].as_str().expect("{\"listening\": URL}").to_string();
        let (tx, log) = mpsc::channel();
        let stderr = child.stderr.take().unwrap();
        std::thread::spawn(move || {
            for l in BufReader::new(stderr).lines().map_while(Result::ok) {
                if tx.send(l).is_err() {
                    break;
                }
            }
        });
        Server { child, url, log }
    }

    /// `survey --db DB serve --listen 127.0.0.1:0` in `bench`'s folder.
    pub fn on(bench: &Bench, db: &str, extra: &[&str]) -> Server {
        let mut args = vec!["--db", db, "serve", "--listen", "127.0.0.1:0"];
        args.extend(extra);
        Server::start(bench.command(&args))
    }

    /// SIGTERM, the exit status, and every line it wrote on stderr.
    pub fn stop_and_log(mut self) -> (Option<i32>, Vec<String>) {
        let code = self.terminate();
        // The process is gone: its stderr ends, and with it the reader.
        (code, self.log.iter().collect())
    }

    /// SIGTERM, and the exit status.
    pub fn stop(mut self) -> Option<i32> {
        self.terminate()
    }

    fn terminate(&mut self) -> Option<i32> {
        let pid = nix::unistd::Pid::from_raw(self.child.id() as i32);
        nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).unwrap();
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                return status.code();
            }
            assert!(Instant::now() < deadline, "survey serve did not stop on SIGTERM");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// An HTTP response.
#[derive(Debug)]
pub struct Response {
    pub status: u16,
    pub headers: Vec<(String, String)>,
    pub body: String,
}

impl Response {
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find(|(k, _)| k.eq_ignore_ascii_case(name)).map(|(_, v)| v.as_str())
    }

    pub fn json(&self) -> Value {
        serde_json::from_str(&self.body).unwrap_or_else(|e| panic!("JSON: {e}\n{}", self.body))
    }
}

/// One HTTP/1.1 request to `url` (`http://host:port`) for `path`.
pub fn request(url: &str, method: &str, path: &str) -> Response {
    send(url, method, path, &[], "")
}

/// One HTTP/1.1 request to `url` for `path` with more `headers` and `body`.
pub fn send(url: &str, method: &str, path: &str, headers: &[(&str, &str)], body: &str) -> Response {
    let host = url.trim_start_matches("http://");
    let mut s = TcpStream::connect(host).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let extra: String = headers.iter().map(|(k, v)| format!("{k}: {v}\r\n")).collect();
    write!(
        s,
        "{method} {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n{extra}Content-Length: {}\r\n\r\n{body}",
        body.len()
    )
    .unwrap();
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).unwrap();
    parse_response(raw)
}

/// A whole HTTP/1.1 response as read from its connection.
pub fn parse_response(raw: Vec<u8>) -> Response {
    let text = String::from_utf8(raw).expect("UTF-8");
    let (head, body) = text.split_once("\r\n\r\n").expect("a header and a body");
    let mut lines = head.lines();
    let status = lines.next().unwrap().split(' ').nth(1).unwrap().parse().unwrap();
    let headers: Vec<(String, String)> = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect();
    assert!(
        !headers.iter().any(|(k, v)| k == "transfer-encoding" && v.contains("chunked")),
        "bodies are whole: {headers:?}"
    );
    Response { status, headers, body: body.to_string() }
}

/// GET `path`.
pub fn get(url: &str, path: &str) -> Response {
    request(url, "GET", path)
}

/// GET `path` whose body is bytes (a PDF): the status and the body.
fn get_bytes(url: &str, path: &str) -> (u16, Vec<u8>) {
    let host = url.trim_start_matches("http://");
    let mut s = TcpStream::connect(host).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(150))).unwrap();
    write!(s, "GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n").unwrap();
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).unwrap();
    let end = raw.windows(4).position(|w| w == b"\r\n\r\n").expect("a header and a body");
    let head = String::from_utf8_lossy(&raw[..end]).into_owned();
    let status = head.split(' ').nth(1).and_then(|s| s.parse().ok()).expect("a status");
    (status, raw[end + 4..].to_vec())
}

/// Whether `name` is on `PATH`.
fn which(name: &str) -> bool {
    std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default()).any(|d| d.join(name).is_file())
}

#[test]
fn every_path_answers_with_its_status_and_the_commands_documents() {
    let bench = Bench::new();
    bench.survey(&["run", "--points", "36", "--runs", "2", "--bidirectional", "--json"]).success();
    bench.survey(&["run", "--points", "36", "--runs", "2", "--bidirectional", "--seed", "2", "--json"]).success();
    let list = bench.survey(&["list", "--json"]).success().json();
    let uid = list["surveys"][1]["uid"].as_str().unwrap().to_string();
    let server = Server::on(&bench, "survey.db", &[]);
    let url = server.url.clone();
    assert!(url.starts_with("http://127.0.0.1:") && !url.ends_with(":0"), "the real port: {url}");

    // The commands' documents, equal.
    let same = |path: &str, args: &[&str]| {
        let r = get(&url, path);
        assert_eq!(r.status, 200, "{path}: {}", r.body);
        assert_eq!(r.header("content-type"), Some("application/json"), "{path}");
        assert_eq!(r.json(), bench.survey(args).success().json(), "{path} is `survey {}`", args.join(" "));
    };
    same("/api/surveys", &["list", "--json"]);
    same("/api/surveys/2", &["show", "2", "--json"]);
    same(&format!("/api/surveys/{uid}"), &["show", "2", "--json"]);
    same("/api/surveys/1/stats", &["stats", "--survey", "1", "--json"]);
    same(&format!("/api/surveys/{}/stats", uid.to_uppercase()), &["stats", "--survey", "2", "--json"]);
    same("/api/history/sim-fig8", &["history", "--asset", "sim-fig8", "--json"]);
    same("/api/compare/1/2", &["compare", "1", "2", "--json"]);
    same("/api/due", &["due", "--json"]);

    // `/`: the asset, its calibration in force (the last) and its state; nothing live.
    let home = get(&url, "/");
    assert_eq!(home.status, 200);
    assert!(home.header("content-type").unwrap().starts_with("text/html"));
    for part in [
        "id=\"tbl-assets\"",
        "<a href=\"/assets/sim-fig8\">sim-fig8</a>",
        &format!("<a href=\"/surveys/{uid}\">survey 2</a>"),
        // In force, never "in tolerance": no tolerance was stated.
        "data-state=\"in force\"",
        "<p id=\"live-none\">",
        "<script src=\"/static/live.js\"></script>",
    ] {
        assert!(home.body.contains(part), "/ lacks {part}:\n{}", home.body);
    }
    let assets = get(&url, "/api/assets").json();
    assert_eq!(assets["assets"][0]["asset"], "sim-fig8");
    assert_eq!(assets["assets"][0]["calibration"]["uid"], uid.as_str());
    assert_eq!(assets["assets"][0]["state"], "in force");
    assert!(!home.body.contains("in tolerance"), "no tolerance judged");
    assert_eq!(get(&url, "/api/live").json(), serde_json::json!({"surveys": []}));
    // `/api/` lists what it serves, each path answering.
    let index = get(&url, "/api/");
    assert_eq!(index.status, 200, "{}", index.body);
    let paths: Vec<String> =
        index.json()["paths"].as_array().unwrap().iter().map(|p| p["path"].as_str().unwrap().to_string()).collect();
    for path in ["/", "/assets/<asset>", "/api/surveys", "/api/assets", "/api/live", "/surveys/<id or uid>/dcc.xml"] {
        assert!(paths.iter().any(|p| p == path), "/api/ lists {path}: {paths:?}");
    }
    for path in paths.iter().filter(|p| !p.contains('<')) {
        assert_eq!(get(&url, path).status, 200, "{path}");
    }
    // Each path with its parameter too, this survey's and asset's (the pages as well as the JSON).
    for path in paths.iter().filter(|p| p.contains('<') && !p.contains("<a>") && !p.contains(".pdf")) {
        let path = path.replace("<id or uid>", &uid).replace("<asset>", "sim-fig8");
        assert_eq!(get(&url, &path).status, 200, "{path}");
    }
    // With an interval shorter than the calibration's age (0.000001 days: 0.09 s), it is due.
    let strict = Server::on(&bench, "survey.db", &["--due-after", "0.000001"]);
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(get(&strict.url, "/api/assets").json()["assets"][0]["state"], "due");
    drop(strict);

    // The asset's history: plotted, every survey linked.
    let page = get(&url, "/assets/sim-fig8");
    assert_eq!(page.status, 200);
    for part in [
        "id=\"fig-history-lines\"",
        "id=\"fig-history-a\"",
        "<svg",
        "repeatability R",
        "/surveys/",
        "<section id=\"due\">",
        "staircase",
        "<section id=\"control\">",
    ] {
        assert!(page.body.contains(part), "/assets/sim-fig8 lacks {part}");
    }
    for s in list["surveys"].as_array().unwrap() {
        assert!(page.body.contains(&format!("href=\"/surveys/{}\"", s["uid"].as_str().unwrap())));
    }

    // Before a certificate is issued the survey's page is its draft, and says so.
    let draft = get(&url, &format!("/surveys/{uid}"));
    assert!(draft.body.contains("id=\"draft\"><b>Draft, not issued</b>"), "{}", draft.body);
    // Once issued, the survey's page is the certificate `survey report` wrote, byte for byte.
    bench.survey(&["report", "--survey", &uid, "--out", "r"]).success();
    let report = get(&url, &format!("/surveys/{uid}"));
    assert_eq!(report.status, 200);
    // The certificate, with the way back at its top (home, the asset's history) and its files.
    let way_back = format!(
        "<nav class=\"subtitle\" id=\"way-back\"><a href=\"/\">All assets and live surveys</a> &middot; the \
         history of <a href=\"/assets/sim-fig8\">sim-fig8</a> &middot; this certificate as issued: <a \
         href=\"/surveys/{uid}/certificate.html\">the page</a>, <a href=\"/surveys/{uid}/dcc.xml\">its DCC \
         (dcc.xml)</a>, <a href=\"/surveys/{uid}/certificate.pdf\">printed (PDF)</a></nav>\n"
    );
    assert!(report.body.contains(&way_back), "{}", report.body);
    assert_eq!(report.body.replacen(&way_back, "", 1), bench.read("r/index.html"));
    for (path, file, kind) in [
        ("certificate.html", "r/index.html", "text/html; charset=utf-8"),
        ("dcc.xml", "r/dcc.xml", "application/xml; charset=utf-8"),
    ] {
        let got = get(&url, &format!("/surveys/{uid}/{path}"));
        assert_eq!((got.status, got.header("content-type")), (200, Some(kind)), "{path}");
        assert!(got.body == bench.read(file), "{path} is {file} byte for byte");
    }
    assert_eq!(get(&url, "/surveys/2").status, 200, "an id names it too");
    // The PDF: the page as issued, printed by Chromium (or a 503 saying what to do without one).
    let pdf = get_bytes(&url, &format!("/surveys/{uid}/certificate.pdf"));
    match (pdf.0, std::env::var_os("SURVEY_CHROMIUM").is_some() || which("chromium")) {
        (200, _) => {
            assert!(pdf.1.starts_with(b"%PDF-") && pdf.1.windows(10).filter(|w| w == b"/Type /Pag").count() >= 8);
        }
        (503, false) if std::env::var_os("CI").is_none() => {
            println!("skipped the PDF: no chromium here: {}", String::from_utf8_lossy(&pdf.1));
        }
        (status, _) => panic!("{status}: {}", String::from_utf8_lossy(&pdf.1)),
    }

    // The script, same-origin.
    let script = get(&url, "/static/live.js");
    assert_eq!((script.status, script.header("content-type")), (200, Some("text/javascript; charset=utf-8")));
    assert!(script.body.contains("/api/live"));

    // Every response carries the policy; nothing else is fetched.
    for r in [&home, &page, &report, &script] {
        let csp = r.header("content-security-policy").expect("a policy");
        assert!(csp.starts_with("default-src 'none'") && csp.contains("script-src 'self'"), "{csp}");
    }

    // 404: pages for pages, JSON under /api/.
    for path in [
        "/nothing",
        "/surveys/999",
        "/surveys/00000000-0000-4000-8000-000000000000",
        "/surveys/not-a-survey",
        "/assets/no-such-asset",
        "/assets/",
    ] {
        let r = get(&url, path);
        assert_eq!(r.status, 404, "{path}: {}", r.body);
        assert!(r.body.contains("<h1>404 Not Found</h1>"), "{path}: {}", r.body);
        assert!(r.header("content-security-policy").is_some());
    }
    for path in ["/api/nothing", "/api/surveys/999", "/api/surveys/999/stats", "/api/history/none", "/api/compare/1/9"]
    {
        let r = get(&url, path);
        assert_eq!(r.status, 404, "{path}: {}", r.body);
        assert!(r.json()["error"].as_str().is_some_and(|e| !e.is_empty()), "{path}: {}", r.body);
    }
    // 400: a comparison the store cannot make (surveys of two assets).
    bench.survey(&["run", "--points", "36", "--runs", "2", "--asset", "rig-2", "--json"]).success();
    let r = get(&url, "/api/compare/1/3");
    assert_eq!(r.status, 400, "{}", r.body);
    assert!(r.json()["error"].as_str().unwrap().contains("only surveys of one asset compare"));

    // No page can write: anything but GET and HEAD is 405.
    for (method, path) in [("POST", "/"), ("PUT", "/api/surveys/1"), ("DELETE", "/api/surveys/1"), ("PATCH", "/x")] {
        let r = request(&url, method, path);
        assert_eq!(r.status, 405, "{method} {path}");
        assert_eq!(r.header("allow"), Some("GET, HEAD"));
    }
    let head = request(&url, "HEAD", "/");
    assert_eq!((head.status, head.body.as_str()), (200, ""));
    assert_eq!(bench.survey(&["list", "--json"]).success().json()["surveys"].as_array().unwrap().len(), 3);

    // SIGINT/SIGTERM: a graceful end, status 0.
    assert_eq!(server.stop(), Some(0));
}

#[test]
fn a_database_it_cannot_read_is_a_503_with_the_reason_and_never_a_password() {
    let bench = Bench::new();
    let server = Server::on(&bench, "missing.db", &[]);
    for path in ["/", "/assets/a", "/surveys/1"] {
        let r = get(&server.url, path);
        assert_eq!(r.status, 503, "{path}");
        assert!(r.body.contains("missing.db") && r.body.contains("503 Service Unavailable"), "{}", r.body);
    }
    let r = get(&server.url, "/api/surveys");
    assert_eq!(r.status, 503);
    assert!(r.json()["error"].as_str().unwrap().contains("no survey database at missing.db"), "{}", r.body);
    // The file appears: served at once, nothing to restart.
    bench.survey(&["run", "--points", "36", "--runs", "2", "--json"]).success();
    std::fs::rename(bench.path("survey.db"), bench.path("missing.db")).unwrap();
    assert_eq!(get(&server.url, "/api/surveys").status, 200);
    drop(server);

    // A lab store that cannot be reached: the reason names the host, never the password.
    let server = Server::on(&bench, "postgres://viewer:s3cret-pw@127.0.0.1:1/surveys", &[]);
    for path in ["/", "/api/live"] {
        let r = get(&server.url, path);
        assert_eq!(r.status, 503, "{path}: {}", r.body);
        assert!(r.body.contains("127.0.0.1") && !r.body.contains("s3cret-pw"), "{}", r.body);
    }
    let log: Vec<String> = server.log.try_iter().collect();
    assert!(!log.join("\n").contains("s3cret-pw"), "{log:?}");
}

#[test]
fn it_binds_loopback_unless_told_otherwise_and_says_so() {
    let bench = Bench::new();
    let server = Server::on(&bench, "survey.db", &[]);
    assert!(server.url.starts_with("http://127.0.0.1:"));
    drop(server);
    // Any other address only with --auth or, on purpose, --no-auth (tests/cli/auth.rs).
    bench.command(&["serve", "--listen", "0.0.0.0:0"]).output().map(|o| assert_eq!(o.status.code(), Some(2))).unwrap();
    let server = Server::start(bench.command(&["serve", "--listen", "0.0.0.0:0", "--no-auth"]));
    let warned = server.log.recv_timeout(Duration::from_secs(30)).unwrap();
    assert!(warned.contains("without authentication") && warned.contains("reverse proxy"), "{warned}");
    assert_eq!(server.stop(), Some(0));
    bench.command(&["serve", "--listen", "nowhere"]).output().map(|o| assert_eq!(o.status.code(), Some(2))).unwrap();
}

/// A Modbus positioner and an emScon tracker, 12 targets both ways, 2 runs.
fn slow_config(positioner: &str, tracker: &str) -> String {
    format!(
        "[survey]\nreference = \"tracker\"\npoints = 12\nruns = 2\nbidirectional = true\n\
         [positioner]\ndriver = \"modbus-tcp\"\naddress = \"{positioner}\"\n\
         [tracker]\ndriver = \"emscon\"\naddress = \"{tracker}\"\n\
         [timing]\ndwell_s = 0.01\npoll_interval_s = 0.02\n"
    )
}

/// `survey sim` of [`slow_config`] at `scale` times real time, and the
/// configuration to run against it (written into `bench` as `run.toml`).
pub fn slow_bench(bench: &Bench, scale: f64) -> Child {
    bench.write("sim.toml", slow_config("127.0.0.1:0", "127.0.0.1:0"));
    let mut sim = bench
        .command(&["sim", "--config", "sim.toml", "--time-scale", &scale.to_string(), "--seed", "3"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(sim.stdout.as_mut().unwrap()).read_line(&mut line).unwrap();
    let ready: Value = serde_json::from_str(&line).expect("the simulator's ready line");
    let at = |k: &str| ready["instruments"][k].as_str().unwrap().to_string();
    bench.write("run.toml", slow_config(&at("positioner"), &at("tracker")));
    sim
}

#[test]
fn a_survey_acquired_in_another_process_is_seen_moving_on_the_live_paths() {
    let bench = Bench::new();
    let mut sim = slow_bench(&bench, 40.0);
    let run = bench
        .command(&["run", "--config", "run.toml", "--asset", "bay-1/az", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The survey is created when the run starts; serve it from then on.
    let deadline = Instant::now() + Duration::from_secs(60);
    while !bench.exists("survey.db") {
        assert!(Instant::now() < deadline, "the run made no database");
        std::thread::sleep(Duration::from_millis(20));
    }
    let server = Server::on(&bench, "survey.db", &[]);
    let mut seen: Vec<u64> = Vec::new();
    let mut page_seen = None;
    while Instant::now() < deadline {
        let live = get(&server.url, "/api/live");
        if live.status == 503 && seen.is_empty() {
            // The run is still setting its new database up.
            std::thread::sleep(Duration::from_millis(20));
            continue;
        }
        assert_eq!(live.status, 200, "{}", live.body);
        let live = live.json();
        let Some(s) = live["surveys"].as_array().unwrap().first().cloned() else {
            if seen.is_empty() {
                std::thread::sleep(Duration::from_millis(20));
                continue; // not started yet
            }
            break; // ended
        };
        assert_eq!((s["asset"].as_str(), s["planned_samples"].as_u64()), (Some("bay-1/az"), Some(48)), "{s}");
        let n = s["samples"].as_u64().unwrap();
        if seen.last() != Some(&n) {
            seen.push(n);
            if page_seen.is_none() && n > 0 {
                let home = get(&server.url, "/").body;
                let uid = s["uid"].as_str().unwrap();
                let at = home.find(&format!("id=\"live-{uid}\"")).expect("the live survey on /");
                let samples: u64 =
                    home[at..].split("data-samples=\"").nth(1).unwrap().split('"').next().unwrap().parse().unwrap();
                assert!(samples >= n, "/ shows {samples} samples, /api/live showed {n} before");
                assert!(home[at..].contains("time left: "), "{home}");
                page_seen = Some(samples);
            }
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let out = run.wait_with_output().unwrap();
    let _ = sim.kill();
    let _ = sim.wait();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let doc: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!((doc["status"].as_str(), doc["samples"].as_u64()), (Some("complete"), Some(48)));
    assert!(page_seen.is_some(), "the survey was seen on / while acquired");
    let moving: Vec<u64> = seen.iter().copied().filter(|&n| n > 0 && n < 48).collect();
    assert!(moving.len() >= 2 && moving.windows(2).all(|w| w[0] < w[1]), "the progress moved: {seen:?}");
    assert_eq!(get(&server.url, "/api/live").json()["surveys"], serde_json::json!([]), "ended: no longer live");
}

#[test]
fn the_lab_store_is_served_as_a_station_s_file_is() {
    let Some(pg) = super::lab::server() else { return };
    let lab = pg.database("served");
    let bench = Bench::new();
    super::lab::small_surveys(&bench, 2, 1);
    bench.survey(&["push", "--to", &lab, "--all", "--json"]).success();
    let uid = bench.survey(&["list", "--json"]).success().json()["surveys"][1]["uid"].as_str().unwrap().to_string();
    let server = Server::on(&bench, &lab, &[]);
    let on_lab = |args: &[&str]| {
        let mut all = vec!["--db", lab.as_str()];
        all.extend(args);
        bench.survey(&all).success().json()
    };
    let listed = get(&server.url, "/api/surveys");
    assert_eq!(listed.status, 200, "{}", listed.body);
    assert!(!listed.body.contains(super::lab::PASSWORD));
    assert_eq!(listed.json(), on_lab(&["list", "--json"]));
    assert_eq!(get(&server.url, "/api/history/sim-fig8").json(), on_lab(&["history", "--asset", "sim-fig8", "--json"]));
    let home = get(&server.url, "/");
    assert_eq!(home.status, 200);
    assert!(home.body.contains(&format!("/surveys/{uid}")) && !home.body.contains(super::lab::PASSWORD));
    for path in [format!("/surveys/{uid}"), "/assets/sim-fig8".to_string()] {
        assert_eq!(get(&server.url, &path).status, 200, "{path}");
    }
    assert_eq!(
        get(&server.url, "/api/live").json(),
        serde_json::json!({"surveys": []}),
        "push copies complete surveys"
    );
    assert_eq!(server.stop(), Some(0));
}

/// The figure with `id` of an HTML page.
fn figure_of<'a>(html: &'a str, id: &str) -> &'a str {
    let at = html.find(&format!("<figure id=\"{id}\">")).unwrap_or_else(|| panic!("no figure {id}"));
    let end = at + html[at..].find("</figure>").expect("the figure's end");
    &html[at..end]
}

/// Issue 41: an asset's page plots every calibration's lines on a time axis
/// in UTC dates (never fractions of a day since the first survey), tells its
/// checks from its calibrations, a survey's page leads back to its asset and
/// home, `unassigned` is not an asset in tolerance, and page views print no
/// processing notes on the server's stderr.
#[test]
fn the_asset_page_plots_every_calibration_on_a_date_axis_and_tells_checks_apart() {
    let bench = Bench::new();
    for seed in ["1", "2", "3"] {
        let args = ["run", "--asset", "lab/ax", "--points", "120", "--runs", "2", "--bidirectional", "--seed", seed];
        bench.survey(&args).success();
    }
    let check = bench.survey(&["run", "--check", "--asset", "lab/ax", "--seed", "4", "--json"]);
    assert_eq!(check.json()["check"]["to"], 4, "{check}");
    bench.export(Some(1), "one.csv");
    bench.import("one.csv");
    let uid = bench.survey(&["show", "3", "--json"]).success().json()["uid"].as_str().unwrap().to_string();
    let server = Server::on(&bench, "survey.db", &[]);
    let url = server.url.clone();

    let page = get(&url, "/assets/lab/ax");
    assert_eq!(page.status, 200, "{}", page.body);
    let lines = figure_of(&page.body, "fig-history-lines");
    // Made within a minute: the axis reads times of day, UTC.
    assert!(lines.contains("time of day (UTC)") && !page.body.contains("days since"), "{lines}");
    // ... on the date named beside it (a time is never without its date).
    assert!(lines.contains("time of day (UTC) on 20") || lines.contains("time of day (UTC) from 20"), "{lines}");
    assert!(page.body.contains("<th>A, deg</th><th>R, deg</th><th>table U, deg</th>"), "units in every column");
    // The table's U as the certificate states it (two significant digits, rounded up: issue 50).
    let dcc = get(&url, &format!("/surveys/{uid}/dcc.xml")).body;
    let stated = dcc.split("survey_correctedPeakPredicted\"").nth(1).and_then(|r| r.split("<si:uncertainty>").nth(1));
    let stated = stated.and_then(|r| r.split('<').next()).expect("the table's U in the DCC");
    let row = page.body.split(&format!("/surveys/{uid}\">3</a>")).nth(1).unwrap().split("</tr>").next().unwrap();
    let cells: Vec<&str> = row.split("<td>").skip(1).map(|c| c.split('<').next().unwrap()).collect();
    assert_eq!(cells.get(2).copied(), Some(stated), "survey 3's table U, A and R: {cells:?}");
    let is_time = |t: &str| {
        t.len() == 8
            && t.bytes().enumerate().all(|(i, b)| if i == 2 || i == 5 { b == b':' } else { b.is_ascii_digit() })
    };
    let ticks = lines.split('>').filter(|part| is_time(part.split('<').next().unwrap_or_default().trim())).count();
    assert!(ticks >= 2, "ticks in HH:MM:SS: {lines}");
    assert!(!lines.contains("-0.000"), "{lines}");
    // The 20 cycles/rev line (the largest, drawn first) of each of the three calibrations.
    assert!(lines.contains("20 cycles/rev"), "{lines}");
    assert_eq!(lines.matches("fill=\"#0072B2\"").count(), 3, "{lines}");
    let a = figure_of(&page.body, "fig-history-a");
    assert!(a.contains("A of a calibration") && a.contains("A of a check"), "{a}");
    // The checks on their control chart, drawn (issue 53): the one check's statistic, in order.
    let control = figure_of(&page.body, "fig-control");
    assert!(
        control.contains("cells beyond U / (allowed + 1)") && control.contains("check, in the order made"),
        "{control}"
    );
    assert!(control.contains("<circle") && control.contains("3-sigma control limits"), "{control}");

    let survey = get(&url, &format!("/surveys/{uid}"));
    assert!(survey.body.contains("id=\"way-back\"><a href=\"/\">"), "{}", survey.body);
    assert!(survey.body.contains("<a href=\"/assets/lab/ax\">lab/ax</a>"), "{}", survey.body);

    let assets = get(&url, "/api/assets").json();
    let unassigned = assets["assets"].as_array().unwrap().iter().find(|a| a["asset"] == "unassigned").unwrap();
    assert_eq!(unassigned["state"], "not an asset", "{assets:#}");
    let home = get(&url, "/");
    assert!(home.body.contains("data-state=\"not an asset\""), "{}", home.body);

    let (_, log) = server.stop_and_log();
    let notes: Vec<&String> = log.iter().filter(|l| l.starts_with("note:")).collect();
    assert!(notes.is_empty(), "page views print no processing notes: {notes:#?}");
}

/// Issue 41: while a survey's check points are measured (stored apart, as a
/// `resolving` survey, until they are folded into it), `/api/live` and `/`
/// show that survey, on its asset, measuring its check points: never a
/// survey of `unassigned` that `survey list` does not know.
#[test]
fn check_points_being_measured_are_shown_as_their_survey_s() {
    use survey_store::Store;
    use survey_store::survey::{NewSurvey, SurveySource};
    let bench = Bench::new();
    let db = bench.path("survey.db");
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    let (store, native, _lock) = rt.block_on(async {
        let store = Store::open(&db).await.unwrap();
        let native = NewSurvey { points: Some(24), runs: Some(2), asset: "rig-3".into(), ..NewSurvey::default() };
        let native = store.create_survey(&native).await.unwrap();
        let checks = NewSurvey {
            source: SurveySource::Resolving,
            instruments: serde_json::json!({"resolves_survey": native}),
            planned_samples: Some(96),
            ..NewSurvey::default()
        };
        // Acquired by this process: its lock held to the end of the test.
        let (_, lock) = store.create_acquired_survey(&checks).await.unwrap();
        (store, native, lock)
    });
    let uid =
        bench.survey(&["show", &native.to_string(), "--json"]).success().json()["uid"].as_str().unwrap().to_string();
    let server = Server::on(&bench, "survey.db", &[]);
    let live = get(&server.url, "/api/live").json();
    let shown = &live["surveys"][0];
    assert_eq!((shown["id"].as_i64(), shown["uid"].as_str()), (Some(native), Some(uid.as_str())), "{live:#}");
    assert_eq!((shown["asset"].as_str(), shown["check_points"].as_bool()), (Some("rig-3"), Some(true)), "{live:#}");
    let home = get(&server.url, "/");
    assert!(home.body.contains(&format!("survey {native}: its check points</a>")), "{}", home.body);
    assert!(!home.body.contains("unassigned"), "{}", home.body);
    rt.block_on(store.close());
}
