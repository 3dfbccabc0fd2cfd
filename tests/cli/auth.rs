//! `survey serve` behind its door (issue 51 item 7): with `--auth FILE`,
//! even on loopback, nothing but the login page answers without
//! credentials (`/api/` 401, a page a redirection to `/login`); HTTP Basic
//! for programs, the login form and its session cookie for browsers, the
//! session's end (logout, idle time), failed logins refused per address
//! and logged without the password; TLS on the server itself; an address
//! other than loopback refused without `--auth` or `--no-auth`.

use super::serve::{Response, Server, parse_response, send};
use super::{Bench, VALID_CSV};
use base64::Engine as _;
use std::io::{Read as _, Write as _};
use std::process::Stdio;
use std::sync::Arc;
use std::time::Duration;

const PASSWORD: &str = "correct horse battery";

/// A bench with one imported survey and `auth.toml` holding the user `lab`
/// (its hash made by `survey serve --hash-password`).
fn bench() -> Bench {
    let bench = Bench::new();
    bench.write("valid.csv", VALID_CSV);
    bench.survey(&["import", "valid.csv"]).success();
    let mut child = bench
        .command(&["serve", "--hash-password"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(format!("{PASSWORD}\n").as_bytes()).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let hash = String::from_utf8(out.stdout).unwrap();
    assert!(hash.starts_with("$argon2id$v=19$") && hash.ends_with('\n') && hash.lines().count() == 1, "{hash}");
    bench.write("auth.toml", format!("[[user]]\nname = \"lab\"\npassword_hash = \"{}\"\n", hash.trim_end()));
    bench
}

fn basic(name: &str, password: &str) -> String {
    format!("Basic {}", base64::engine::general_purpose::STANDARD.encode(format!("{name}:{password}")))
}

/// GET `path` with `headers`.
fn get_with(url: &str, path: &str, headers: &[(&str, &str)]) -> Response {
    send(url, "GET", path, headers, "")
}

/// POST the login form.
fn log_in(url: &str, name: &str, password: &str, next: &str) -> Response {
    let form = format!("name={name}&password={}&next={}", password.replace(' ', "+"), next.replace('/', "%2F"));
    send(url, "POST", "/login", &[("Content-Type", "application/x-www-form-urlencoded")], &form)
}

/// The session cookie a login set (`survey_session=...`), and its attributes.
fn session_cookie(r: &Response) -> (String, String) {
    let set = r.header("set-cookie").unwrap_or_else(|| panic!("a cookie: {r:?}"));
    let pair = set.split(';').next().unwrap().trim().to_string();
    (pair, set.to_string())
}

#[test]
fn without_credentials_only_the_login_answers_and_with_them_everything() {
    let bench = bench();
    let server = Server::on(&bench, "survey.db", &["--auth", "auth.toml"]);
    let url = server.url.clone();
    // Nothing but the login page without credentials, whatever the path.
    for path in ["/api/", "/api/surveys", "/api/live", "/api/nothing-here"] {
        let r = get_with(&url, path, &[]);
        assert_eq!(r.status, 401, "{path}: {r:?}");
        assert_eq!(r.header("www-authenticate"), Some("Basic realm=\"survey\", charset=\"UTF-8\""));
        assert!(r.json()["error"].as_str().unwrap().contains("log in"));
    }
    for (path, next) in
        [("/", "%2F"), ("/assets/unassigned", "%2Fassets%2Funassigned"), ("/surveys/1", "%2Fsurveys%2F1")]
    {
        let r = get_with(&url, path, &[]);
        assert_eq!((r.status, r.header("location")), (303, Some(format!("/login?next={next}").as_str())), "{path}");
        assert!(r.body.is_empty());
    }
    for path in ["/static/live.js", "/nothing-here", "/surveys/1/dcc.xml"] {
        assert_eq!(get_with(&url, path, &[]).status, 303, "{path}");
    }
    let form = get_with(&url, "/login?next=%2Fassets%2Funassigned", &[]);
    assert_eq!(form.status, 200);
    assert!(form.body.contains("<form id=\"login\" method=\"post\" action=\"/login\">"), "{}", form.body);
    assert!(form.body.contains("value=\"/assets/unassigned\""), "{}", form.body);
    assert!(form.header("content-security-policy").unwrap().contains("form-action 'self'"));

    // A program: HTTP Basic with each request.
    let good = basic("lab", PASSWORD);
    let r = get_with(&url, "/api/surveys", &[("Authorization", &good)]);
    assert_eq!(r.status, 200, "{r:?}");
    assert_eq!(r.json()["surveys"].as_array().unwrap().len(), 1);
    assert_eq!(get_with(&url, "/", &[("Authorization", &good)]).status, 200);
    for bad in [basic("lab", "wr0ng-pw"), basic("nobody", PASSWORD), "Bearer x".into()] {
        let r = get_with(&url, "/api/surveys", &[("Authorization", &bad)]);
        assert_eq!(r.status, 401, "{bad}: {r:?}");
    }

    // A browser: the form, then a session cookie.
    let wrong = log_in(&url, "lab", "wr0ng-pw", "/");
    assert_eq!(wrong.status, 401);
    assert!(wrong.body.contains("The name or the password is wrong."), "{}", wrong.body);
    assert!(wrong.header("set-cookie").is_none());
    let foreign = send(
        &url,
        "POST",
        "/login",
        &[("Origin", "http://evil.example"), ("Content-Type", "application/x-www-form-urlencoded")],
        &format!("name=lab&password={}", PASSWORD.replace(' ', "+")),
    );
    assert_eq!(foreign.status, 403, "a login posted from another site");
    let form = format!("name=lab&password={}", PASSWORD.replace(' ', "+"));
    let cross = send(&url, "POST", "/login", &[("Sec-Fetch-Site", "cross-site"), ("Origin", "null")], &form);
    assert_eq!(cross.status, 403, "a login a browser says came from another site");
    let ok = log_in(&url, "lab", PASSWORD, "/assets/unassigned");
    assert_eq!((ok.status, ok.header("location")), (303, Some("/assets/unassigned")), "{ok:?}");
    let (cookie, set) = session_cookie(&ok);
    assert!(set.contains("HttpOnly") && set.contains("SameSite=Strict") && !set.contains("Secure"), "{set}");
    assert_eq!(cookie.len(), "survey_session=".len() + 43, "256 random bits: {cookie}");
    for path in ["/", "/assets/unassigned", "/api/live", "/static/live.js", "/surveys/1"] {
        assert_eq!(get_with(&url, path, &[("Cookie", &cookie)]).status, 200, "{path}");
    }
    // A made-up session is none; to a foreign site after the login, never.
    assert_eq!(get_with(&url, "/api/live", &[("Cookie", "survey_session=AAAA")]).status, 401);
    assert_eq!(log_in(&url, "lab", PASSWORD, "//evil.example/").header("location"), Some("/"));
    // Logged out: the cookie opens nothing any more.
    let out = send(&url, "POST", "/logout", &[("Cookie", &cookie)], "");
    assert_eq!((out.status, out.header("location")), (303, Some("/login")));
    assert!(out.header("set-cookie").unwrap().contains("Max-Age=0"));
    assert_eq!(get_with(&url, "/api/live", &[("Cookie", &cookie)]).status, 401);
    assert_eq!(get_with(&url, "/", &[("Cookie", &cookie)]).status, 303);
    // Still read-only: no other POST.
    assert_eq!(send(&url, "POST", "/api/surveys", &[("Authorization", &good)], "").status, 405);

    // Failed logins: 4 cost nothing, the 5th refuses the address for a
    // minute, the right password included, form and Basic alike.
    for n in 1..=5 {
        assert_eq!(log_in(&url, "lab", &format!("guess {n}"), "/").status, 401, "failure {n}");
    }
    let refused = log_in(&url, "lab", PASSWORD, "/");
    assert_eq!(refused.status, 429, "{refused:?}");
    let wait: u64 = refused.header("retry-after").unwrap().parse().unwrap();
    assert!((1..=60).contains(&wait), "{wait}");
    assert!(refused.header("set-cookie").is_none());
    let r = get_with(&url, "/api/live", &[("Authorization", &good)]);
    assert_eq!(r.status, 429);
    assert!(r.json()["error"].as_str().unwrap().contains("too many failed logins"), "{}", r.body);

    let (code, log) = server.stop_and_log();
    assert_eq!(code, Some(0));
    let failed: Vec<&String> = log.iter().filter(|l| l.contains("a failed login")).collect();
    assert_eq!(failed.len(), 8, "each failure logged: {log:#?}");
    assert!(failed.iter().all(|l| l.contains("client=127.0.0.1")), "{failed:#?}");
    assert!(failed.iter().any(|l| l.contains("user=\"nobody\"")), "{failed:#?}");
    assert!(log.iter().any(|l| l.contains("refused for 60 s")), "{log:#?}");
    let all = log.join("\n");
    assert!(
        !all.contains(PASSWORD) && !all.contains("guess 3") && !all.contains("wr0ng-pw"),
        "a password logged:\n{all}"
    );
}

/// One HTTPS request over rustls to `url` (`https://127.0.0.1:PORT`),
/// trusting the certificate `ca` only.
fn tls_send(url: &str, ca: &[u8], method: &str, path: &str, headers: &[(&str, &str)], body: &str) -> Response {
    use rustls_pki_types::pem::PemObject as _;
    use rustls_pki_types::{CertificateDer, ServerName};
    let mut roots = rustls::RootCertStore::empty();
    roots.add(CertificateDer::from_pem_slice(ca).unwrap()).unwrap();
    let config = rustls::ClientConfig::builder_with_provider(Arc::new(rustls::crypto::ring::default_provider()))
        .with_safe_default_protocol_versions()
        .unwrap()
        .with_root_certificates(roots)
        .with_no_client_auth();
    let host = url.trim_start_matches("https://");
    let name = ServerName::try_from("127.0.0.1").unwrap().to_owned();
    let conn = rustls::ClientConnection::new(Arc::new(config), name).unwrap();
    let tcp = std::net::TcpStream::connect(host).unwrap();
    tcp.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let mut tls = rustls::StreamOwned::new(conn, tcp);
    let extra: String = headers.iter().map(|(k, v)| format!("{k}: {v}\r\n")).collect();
    write!(
        tls,
        "{method} {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n{extra}Content-Length: {}\r\n\r\n{body}",
        body.len()
    )
    .unwrap();
    let mut raw = Vec::new();
    match tls.read_to_end(&mut raw) {
        Ok(_) => {}
        // Hyper closes without a TLS close_notify: the response is whole.
        Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {}
        Err(e) => panic!("reading the response: {e}"),
    }
    parse_response(raw)
}

/// A self-signed certificate for 127.0.0.1 and its key, made by openssl
/// (CI installs it), or why there is none.
fn certificate(bench: &Bench) -> Result<(), String> {
    let made = std::process::Command::new("openssl")
        .args(["req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes", "-days", "2"])
        .args(["-subj", "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1"])
        .args(["-addext", "basicConstraints=critical,CA:FALSE", "-keyout", "key.pem", "-out", "cert.pem"])
        .current_dir(bench.path(""))
        .output()
        .map_err(|e| format!("no openssl: {e}"))?;
    if !made.status.success() {
        return Err(format!("openssl failed: {}", String::from_utf8_lossy(&made.stderr)));
    }
    Ok(())
}

#[test]
fn https_on_the_server_itself_with_a_secure_cookie_that_ends_when_idle() {
    let bench = bench();
    if let Err(why) = certificate(&bench) {
        println!("skipped: {why}");
        return;
    }
    // TLS files that cannot be used: named, exit 2.
    bench.write("not.pem", "not a certificate\n");
    let tls = ["serve", "--listen", "127.0.0.1:0", "--auth", "auth.toml"];
    let with = |cert: &str, key: &str| {
        let mut args = tls.to_vec();
        args.extend(["--tls-cert", cert, "--tls-key", key]);
        bench.survey(&args)
    };
    with("missing.pem", "key.pem").bad_input(&["missing.pem: no such file"]);
    with("not.pem", "key.pem").bad_input(&["not.pem: holds no PEM certificate"]);
    with("cert.pem", "not.pem").bad_input(&["not.pem: holds no PEM private key"]);
    with("key.pem", "key.pem").bad_input(&["key.pem: holds no PEM certificate"]);

    let mut args = tls.to_vec();
    args.extend(["--tls-cert", "cert.pem", "--tls-key", "key.pem", "--session-idle", "1", "--header-timeout", "1"]);
    let server = Server::start(bench.command(&args));
    assert!(server.url.starts_with("https://127.0.0.1:"), "{}", server.url);
    let url = server.url.clone();
    let ca = std::fs::read(bench.path("cert.pem")).unwrap();
    let r = tls_send(&url, &ca, "GET", "/api/live", &[], "");
    assert_eq!(r.status, 401);
    let good = basic("lab", PASSWORD);
    assert_eq!(tls_send(&url, &ca, "GET", "/api/surveys", &[("Authorization", &good)], "").status, 200);
    let form = format!("name=lab&password={}&next=%2F", PASSWORD.replace(' ', "+"));
    let ok = tls_send(&url, &ca, "POST", "/login", &[("Content-Type", "application/x-www-form-urlencoded")], &form);
    assert_eq!(ok.status, 303, "{ok:?}");
    let (cookie, set) = session_cookie(&ok);
    assert!(set.contains("; Secure"), "{set}");
    assert_eq!(tls_send(&url, &ca, "GET", "/", &[("Cookie", &cookie)], "").status, 200);
    // Plain HTTP to the TLS port gets no page.
    let mut plain = std::net::TcpStream::connect(url.trim_start_matches("https://")).unwrap();
    plain.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    plain.write_all(b"GET /api/live HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
    let mut raw = Vec::new();
    let _ = plain.read_to_end(&mut raw);
    assert!(!String::from_utf8_lossy(&raw).contains("HTTP/1.1 200"));
    // A connection that never begins its handshake is closed after the header timeout.
    let mut idle = std::net::TcpStream::connect(url.trim_start_matches("https://")).unwrap();
    idle.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let start = std::time::Instant::now();
    let closed = idle.read(&mut [0u8; 16]);
    assert!(matches!(closed, Ok(0)) || closed.is_err(), "{closed:?}");
    assert!(start.elapsed() < Duration::from_secs(5), "an idle handshake held {:?}", start.elapsed());
    // The session ends after 1 s without a request (the server's clock
    // cannot run short: waiting longer can only find it ended).
    std::thread::sleep(Duration::from_millis(1300));
    let r = tls_send(&url, &ca, "GET", "/", &[("Cookie", &cookie)], "");
    assert_eq!((r.status, r.header("location")), (303, Some("/login?next=%2F")), "{r:?}");
    assert_eq!(server.stop(), Some(0));
}

#[test]
fn an_address_other_than_loopback_needs_auth_or_no_auth_and_a_bad_auth_file_is_refused() {
    let bench = bench();
    for listen in ["0.0.0.0:0", "[::]:0"] {
        bench.survey(&["serve", "--listen", listen]).bad_input(&[
            "not loopback",
            "--auth FILE",
            "--no-auth",
            "survey serve --hash-password",
        ]);
    }
    let server = Server::start(bench.command(&["serve", "--listen", "0.0.0.0:0", "--no-auth"]));
    assert!(server.url.starts_with("http://0.0.0.0:"), "{}", server.url);
    let (code, log) = server.stop_and_log();
    assert_eq!(code, Some(0));
    assert!(log.iter().any(|l| l.contains("without authentication (--no-auth)")), "{log:#?}");
    bench.survey(&["serve", "--auth", "auth.toml", "--no-auth"]).bad_input(&["--no-auth"]);
    bench.survey(&["serve", "--auth", "missing.toml"]).bad_input(&["missing.toml: cannot read the auth file"]);
    let hash = "$argon2id$v=19$m=19456,t=2,p=1$aw9UfmWy8Ff1VZ3IHDfEOw$9gY8jIA0xJsDhWaJK7xX7aXc4y9YlxHfzCRIVOLh6ZU";
    for (text, said) in [
        (format!("[[user]]\nname = \"lab\"\npasword_hash = \"{hash}\"\n"), "bad.toml:3: pasword_hash: unknown field"),
        (
            "[[user]]\nname = \"lab\"\npassword_hash = \"hunter2\"\n".into(),
            "bad.toml:3: user.password_hash: not an argon2id",
        ),
        ("".into(), "bad.toml: user: no [[user]]"),
    ] {
        bench.write("bad.toml", &text);
        let out = bench.survey(&["serve", "--auth", "bad.toml"]).bad_input(&[said]);
        assert!(!out.stderr.contains("aw9UfmWy8") && !out.stderr.contains("hunter2"), "{out}");
    }
    let out = bench.command(&["serve", "--hash-password"]).stdin(Stdio::null()).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "no password on stdin");
}

#[test]
fn no_local_path_in_any_page_or_api_answer() {
    let bench = Bench::new();
    let folder = bench.path("").canonicalize().unwrap().display().to_string();
    bench.write("m.toml", "[design]\ngear_ratios = [12]\n\n[[effect]]\nkind = \"gear_pass\"\ncycles_per_rev = 12\namplitude_deg = 0.006\nphase_deg = 30.0\n");
    let (db, model) = (format!("{folder}/survey.db"), format!("{folder}/m.toml"));
    let run = ["--db", &db, "run", "--points", "24", "--runs", "2", "--bidirectional", "--model", &model, "--json"];
    bench.survey(&run).success();
    bench.survey(&["--db", &db, "report", "--out", &format!("{folder}/rep")]).success();
    let server = Server::on(&bench, &db, &[]);
    let paths = [
        "/",
        "/api/",
        "/api/surveys",
        "/api/surveys/1",
        "/api/surveys/1/stats",
        "/api/history/sim-fig8",
        "/api/assets",
        "/api/due",
        "/api/live",
        "/assets/sim-fig8",
        "/surveys/1",
        "/surveys/1/dcc.xml",
        "/surveys/1/certificate.html",
        "/api/surveys/9",
        "/surveys/9",
        "/api/compare/1/9",
        "/nothing",
    ];
    for path in paths {
        let r = super::serve::get(&server.url, path);
        assert!(!r.body.contains(&folder), "{path} ({}) shows {folder}:\n{}", r.status, r.body);
    }
    assert_eq!(super::serve::get(&server.url, "/api/surveys").json()["db"], "survey.db");
    assert_eq!(server.stop(), Some(0));
    // A store that cannot be read: the reason, without its folder.
    let missing = format!("{folder}/missing/none.db");
    let server = Server::on(&bench, &missing, &[]);
    for path in ["/", "/api/surveys"] {
        let r = super::serve::get(&server.url, path);
        assert_eq!(r.status, 503);
        assert!(r.body.contains("none.db") && !r.body.contains(&folder), "{path}: {}", r.body);
    }
    assert_eq!(server.stop(), Some(0));
}

/// A survey on configured instruments (a Modbus RTU positioner on the pty
/// `survey sim` serves, its path under the temporary folder), interrupted
/// where nothing answered and resumed with an absolute `--config` path: no
/// local path (the device's, the configuration's, the store's) in any page
/// or `/api/` answer; `survey show`, the operator's own view, keeps them.
#[test]
fn no_device_path_in_any_page_or_api_answer_of_a_configured_survey() {
    let b = Bench::new();
    let folder = b.path("").canonicalize().unwrap().display().to_string();
    let config = |port: &str, tracker: &str| {
        format!(
            "[survey]\npoints = 4\nruns = 2\nreference = \"tracker\"\n\
             [positioner]\ndriver = \"modbus-rtu\"\nport = \"{port}\"\n\
             [tracker]\ndriver = \"emscon\"\naddress = \"{tracker}\"\n\
             [timing]\ndwell_s = 0.01\nlocate_points = 4\nmax_retries = 1\nretry_backoff_s = 0.01\n"
        )
    };
    // Begun where nothing answers: stored, interrupted, its events naming the device.
    b.write("gone.toml", config(&format!("{folder}/gone"), "127.0.0.1:2"));
    assert_eq!(b.survey(&["run", "--config", "gone.toml"]).code, 1);
    b.write("sim.toml", config(&format!("{folder}/rtu"), "127.0.0.1:0"));
    let (sim, ready) = super::drift::Sim::serve(&b, &["--config", "sim.toml", "--time-scale", "500"]);
    let at = |k: &str| ready["instruments"][k].as_str().unwrap().to_string();
    b.write("moved.toml", config(&at("positioner"), &at("tracker")));
    let moved = format!("{folder}/moved.toml");
    let out = b.survey(&["resume", "--config", &moved]);
    drop(sim);
    assert_eq!(out.code, 0, "{out}");
    let show = b.survey(&["show", "--json"]).success().stdout;
    assert!(show.contains(&format!("{folder}/rtu")), "survey show keeps the device's path: {show}");
    assert!(show.contains("resumed on new addresses from moved.toml:"), "the file by its name: {show}");
    b.survey(&["report", "--out", &format!("{folder}/rep")]).success();
    let server = Server::on(&b, &format!("{folder}/survey.db"), &[]);
    let paths = [
        "/",
        "/api/surveys",
        "/api/surveys/1",
        "/api/surveys/1/stats",
        "/api/history/unassigned",
        "/api/assets",
        "/api/due",
        "/api/live",
        "/assets/unassigned",
        "/surveys/1",
        "/surveys/1/dcc.xml",
        "/surveys/1/certificate.html",
    ];
    for path in paths {
        let r = super::serve::get(&server.url, path);
        assert_eq!(r.status, 200, "{path}: {}", r.body);
        for local in [folder.as_str(), "/tmp/", "/dev/"] {
            assert!(!r.body.contains(local), "{path} shows {local}:\n{}", r.body);
        }
    }
    let page = super::serve::get(&server.url, "/surveys/1").body;
    assert!(page.contains("modbus-rtu (serial port)"), "the positioner by driver and transport: {page}");
    let api = super::serve::get(&server.url, "/api/surveys/1").json();
    assert_eq!(api["instruments"]["positioner"], "modbus-rtu (serial port) slave 1", "{api}");
    assert_eq!(server.stop(), Some(0));
}
