//! `survey serve` keeps its doors (issue 42 item 6): a request's head must
//! arrive within the header timeout, connections beyond the bound cannot
//! make the server unreachable, pages beyond those being made and queued
//! are answered 503 with Retry-After, and SIGTERM ends the server within
//! its deadline whatever connections are open. Short limits through the
//! flags; the pages held longer through a test-only variable.

use super::serve::{Server, get};
use super::{Bench, VALID_CSV};
use std::io::{Read as _, Write as _};
use std::net::TcpStream;
use std::time::{Duration, Instant};

/// A station's file with one imported survey.
fn bench() -> Bench {
    let bench = Bench::new();
    bench.write("valid.csv", VALID_CSV);
    bench.survey(&["import", "valid.csv"]).success();
    bench
}

/// A connection to `url` that has sent `bytes`.
fn sent(url: &str, bytes: &str) -> TcpStream {
    let mut s = TcpStream::connect(url.trim_start_matches("http://")).unwrap();
    s.write_all(bytes.as_bytes()).unwrap();
    s
}

/// Read `s` until the server closes it (or `within` passes): what was read,
/// and how long until the close (`None`: still open).
fn until_closed(s: &mut TcpStream, within: Duration) -> (String, Option<Duration>) {
    let start = Instant::now();
    s.set_read_timeout(Some(within)).unwrap();
    let mut raw = Vec::new();
    let mut buf = [0u8; 4096];
    loop {
        match s.read(&mut buf) {
            Ok(0) => return (String::from_utf8_lossy(&raw).into(), Some(start.elapsed())),
            Ok(n) => raw.extend_from_slice(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => {
                return (String::from_utf8_lossy(&raw).into(), Some(start.elapsed()));
            }
            Err(_) => return (String::from_utf8_lossy(&raw).into(), None),
        }
        if start.elapsed() > within {
            return (String::from_utf8_lossy(&raw).into(), None);
        }
    }
}

#[test]
fn half_a_request_line_and_an_idle_kept_alive_connection_are_closed_after_the_header_timeout() {
    let bench = bench();
    let server = Server::on(&bench, "survey.db", &["--header-timeout", "0.5"]);
    let mut half = sent(&server.url, "GET /api/li");
    let (read, closed) = until_closed(&mut half, Duration::from_secs(5));
    let closed = closed.expect("half a request line is closed");
    assert!(closed >= Duration::from_millis(400) && closed < Duration::from_secs(3), "{closed:?}");
    // Hyper answers a head that never came whole with 408 or nothing at all.
    assert!(read.is_empty() || read.starts_with("HTTP/1.1 408"), "{read}");
    // A whole request kept alive: answered, then closed once idle as long.
    let host = server.url.trim_start_matches("http://").to_string();
    let mut kept = sent(&server.url, &format!("GET /api/live HTTP/1.1\r\nHost: {host}\r\n\r\n"));
    let (read, closed) = until_closed(&mut kept, Duration::from_secs(5));
    assert!(read.starts_with("HTTP/1.1 200"), "{read}");
    assert!(closed.expect("an idle kept-alive connection is closed") < Duration::from_secs(3));
    assert_eq!(server.stop(), Some(0));
}

#[test]
fn connections_beyond_the_bound_do_not_stop_api_live_answering() {
    let bench = bench();
    let server = Server::on(&bench, "survey.db", &["--max-connections", "8", "--header-timeout", "60"]);
    // Five times the bound, each sending half a request line and no more.
    let mut held: Vec<TcpStream> = (0..40).map(|_| sent(&server.url, "GET /api/li")).collect();
    for _ in 0..3 {
        let start = Instant::now();
        let live = get(&server.url, "/api/live");
        assert_eq!(live.status, 200, "{}", live.body);
        assert!(start.elapsed() < Duration::from_secs(5), "{:?}", start.elapsed());
    }
    // The oldest of them were closed to make room (at most the bound stay open).
    let open = held.iter_mut().map(|s| until_closed(s, Duration::from_millis(50)).1.is_none()).filter(|&o| o).count();
    assert!(open <= 8, "{open} of the 40 half-open connections still open");
    assert_eq!(server.stop(), Some(0));
}

#[test]
fn pages_beyond_those_made_and_queued_are_answered_503_with_retry_after() {
    let bench = bench();
    let mut cmd = bench.command(&[
        "--db",
        "survey.db",
        "serve",
        "--listen",
        "127.0.0.1:0",
        "--pages-at-once",
        "1",
        "--pages-queued",
        "1",
    ]);
    cmd.env("SURVEY_TEST_SERVE_HOLD_MS", "3000");
    let server = Server::start(cmd);
    let asked: Vec<_> = (0..3)
        .map(|_| {
            let url = server.url.clone();
            std::thread::spawn(move || get(&url, "/api/surveys"))
        })
        .collect();
    // The ones under way do not hold up what is not a page.
    std::thread::sleep(Duration::from_millis(300));
    let start = Instant::now();
    assert_eq!(get(&server.url, "/api/live").status, 200);
    assert!(start.elapsed() < Duration::from_secs(2), "held up by the pages: {:?}", start.elapsed());
    let answers: Vec<_> = asked.into_iter().map(|t| t.join().unwrap()).collect();
    let mut statuses: Vec<u16> = answers.iter().map(|r| r.status).collect();
    statuses.sort_unstable();
    assert_eq!(statuses, [200, 200, 503], "one made, one waited its turn, one refused");
    let refused = answers.iter().find(|r| r.status == 503).unwrap();
    assert_eq!(refused.header("retry-after"), Some("2"));
    assert!(refused.json()["error"].as_str().unwrap().contains("busy"), "{}", refused.body);
    // Once they are done, pages are made again.
    assert_eq!(get(&server.url, "/api/surveys").status, 200);
    assert_eq!(server.stop(), Some(0));
}

#[test]
fn sigterm_ends_the_server_within_its_deadline_whatever_connections_are_open() {
    let bench = bench();
    let server = Server::on(&bench, "survey.db", &["--stop-within", "1", "--header-timeout", "60"]);
    let host = server.url.trim_start_matches("http://").to_string();
    // One idle, one kept alive after a response, one sending half a request line.
    let _idle = sent(&server.url, "");
    let mut kept = sent(&server.url, &format!("GET /api/live HTTP/1.1\r\nHost: {host}\r\n\r\n"));
    let mut head = [0u8; 12];
    kept.read_exact(&mut head).unwrap();
    assert_eq!(&head, b"HTTP/1.1 200");
    let _half = sent(&server.url, "GET /api/li");
    std::thread::sleep(Duration::from_millis(100));
    let start = Instant::now();
    assert_eq!(server.stop(), Some(0));
    assert!(start.elapsed() < Duration::from_secs(4), "stopped after {:?}", start.elapsed());
}
