//! The lab store over TLS (issue 42 item 7) and its failures said in words
//! (issue 41): a cluster that takes only TLS connections reached with
//! `sslmode=require` and with `verify-full` against the CA named by
//! `sslrootcert`, a plain connection refused with what to add to the URL; a
//! refused connection said at once; a server that closes the connection
//! said so; a role that may only read told what to grant. No message shows
//! a password.

use super::lab::{PASSWORD, server, small_surveys, tls_server};
use super::{Bench, Output};
use std::time::{Duration, Instant};

fn clean(out: &Output, secrets: &[&str]) {
    for s in secrets.iter().chain([&PASSWORD]) {
        assert!(!out.stdout.contains(s) && !out.stderr.contains(s), "a password shows\n{out}");
    }
    for internal in ["at line", "expected to read", "pool timed out", "Error {", "Io("] {
        assert!(!out.stderr.contains(internal), "the driver's words {internal:?}\n{out}");
    }
}

#[test]
fn the_lab_store_is_reached_over_tls_and_a_plain_connection_is_refused_in_words() {
    let Some(pg) = tls_server() else { return };
    let lab = pg.database("over_tls");
    let bench = Bench::new();
    small_surveys(&bench, 2, 1);
    // Plain: the server refuses it; the message says what to add to the URL.
    let out = bench.survey(&["push", "--to", &format!("{lab}?sslmode=disable")]);
    clean(&out, &[]);
    out.bad_input(&["refused the connection of survey", "only encrypted connections", "sslmode=require"]);
    // TLS without checking the certificate, then checked against the CA.
    let out = bench.survey(&["push", "--to", &format!("{lab}?sslmode=require"), "--survey", "1", "--json"]).success();
    clean(&out, &[]);
    assert_eq!(out.json()["pushed"].as_array().unwrap().len(), 1, "{out}");
    let ca = pg.dir.join("ca.crt");
    let verified = format!("{lab}?sslmode=verify-full&sslrootcert={}", ca.display());
    let out = bench.survey(&["push", "--to", &verified, "--all", "--json"]).success();
    assert_eq!(out.json()["pushed"].as_array().unwrap().len(), 1, "{out}");
    let listed = bench.survey(&["--db", &verified, "list", "--json"]).success().json();
    assert_eq!(listed["surveys"].as_array().unwrap().len(), 2);
    // Checked without the CA: the system's roots do not know it.
    let out = bench.survey(&["--db", &format!("{lab}?sslmode=verify-full"), "list"]);
    assert_eq!(out.code, 1, "{out}");
    clean(&out, &[]);
    out.stderr_mentions(&["127.0.0.1", "not signed by a known authority", "sslrootcert=PATH"]);
}

#[test]
fn a_refused_connection_is_said_at_once_and_a_closed_one_in_words() {
    let bench = Bench::new();
    small_surveys(&bench, 1, 1);
    // Nothing listens: refused, at once (not after the 10 s the pool would wait).
    let closed = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let url = format!("postgres://survey:{PASSWORD}@127.0.0.1:{closed}/x");
    let start = Instant::now();
    let out = bench.survey(&["push", "--to", &url]);
    assert!(start.elapsed() < Duration::from_secs(5), "{:?}", start.elapsed());
    assert_eq!(out.code, 1, "{out}");
    clean(&out, &[]);
    out.stderr_mentions(&[&format!("127.0.0.1:{closed}"), "connection was refused"]);
    // A server that closes every connection as soon as it is made.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    std::thread::spawn(move || {
        for s in listener.incoming() {
            drop(s);
        }
    });
    let url = format!("postgres://survey:{PASSWORD}@127.0.0.1:{port}/x");
    let out = bench.survey(&["--db", &url, "list"]);
    assert_eq!(out.code, 1, "{out}");
    clean(&out, &[]);
    let out = out.stderr_mentions(&[&format!("127.0.0.1:{port}"), "the server closed the connection"]);
    assert_eq!(out.stderr.matches("closed the connection").count(), 1, "said once\n{out}");
    // The same without TLS's request first.
    let out = bench.survey(&["push", "--to", &format!("{url}?sslmode=disable")]);
    assert_eq!(out.code, 1, "{out}");
    clean(&out, &[]);
    out.stderr_mentions(&[&format!("127.0.0.1:{port}"), "the server closed the connection"]);
}

#[test]
fn a_role_that_may_only_read_is_told_what_to_grant_and_pushes_once_granted() {
    let Some(pg) = server() else { return };
    let lab = pg.database("grants");
    let fresh = pg.database("grants_fresh");
    let bench = Bench::new();
    small_surveys(&bench, 2, 1);
    bench.survey(&["push", "--to", &lab, "--survey", "1"]).success();
    const READER_PW: &str = "reader-s3cret-9";
    pg.psql(
        "grants",
        &format!(
            "CREATE ROLE grants_reader LOGIN PASSWORD '{READER_PW}'; GRANT USAGE ON SCHEMA public TO grants_reader; \
             GRANT SELECT ON ALL TABLES IN SCHEMA public TO grants_reader"
        ),
    );
    let reader = |db: &str| {
        let url = lab.replace(&format!("survey:{PASSWORD}"), &format!("grants_reader:{READER_PW}"));
        format!("{}{db}", url.strip_suffix("/grants").unwrap())
    };
    // A role that may not even read: what to grant for that.
    pg.psql("grants", &format!("CREATE ROLE grants_none LOGIN PASSWORD '{READER_PW}'"));
    let none = reader("/grants").replace("grants_reader:", "grants_none:");
    let out = bench.survey(&["--db", &none, "list"]);
    clean(&out, &[READER_PW]);
    out.bad_input(&[
        "the role grants_none may not read the lab store at 127.0.0.1",
        "permission denied for",
        "GRANT SELECT ON ALL TABLES IN SCHEMA public TO grants_none",
    ]);
    // Reading: fine. Pushing into the store set up: the privilege missing, what to grant.
    bench.survey(&["--db", &reader("/grants"), "list", "--json"]).success();
    let out = bench.survey(&["push", "--to", &reader("/grants"), "--all"]);
    clean(&out, &[READER_PW]);
    out.bad_input(&[
        "the role grants_reader may not write the lab store at 127.0.0.1",
        "permission denied for table",
        "GRANT SELECT, INSERT, UPDATE ON ALL TABLES IN SCHEMA public TO grants_reader",
        "docs/lab.md",
    ]);
    // Setting a store up: the schema's privilege, and the owner to make.
    let out = bench.survey(&["push", "--to", &reader("/grants_fresh"), "--all"]);
    clean(&out, &[READER_PW]);
    out.bad_input(&["permission denied for schema public", "createdb --owner grants_reader"]);
    assert!(fresh.ends_with("/grants_fresh"));
    // Granted what docs/lab.md says: the push goes through.
    pg.psql(
        "grants",
        "GRANT SELECT, INSERT, UPDATE ON ALL TABLES IN SCHEMA public TO grants_reader; \
         GRANT USAGE ON ALL SEQUENCES IN SCHEMA public TO grants_reader",
    );
    let out = bench.survey(&["push", "--to", &reader("/grants"), "--all", "--json"]).success();
    clean(&out, &[READER_PW]);
    assert_eq!(out.json()["pushed"].as_array().unwrap().len(), 1, "{out}");
}
