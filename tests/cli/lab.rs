//! The lab store on PostgreSQL (issue 22 item 5), through the built binary
//! against a real server: Debian's `postgresql` package (`.ci/run` installs
//! it), one cluster for this test binary (started on first use in a
//! temporary folder on an ephemeral port, as `nobody` when the tests run as
//! root since the server refuses root, and stopped by a watchdog when the
//! test process ends), one database per test. Where the server's binaries
//! are absent, each test says it skipped.

use super::{Bench, Output, VALID_CSV};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;

/// The password of the cluster's user `survey`.
pub(super) const PASSWORD: &str = "lab-s3cret-pw";

/// A PostgreSQL cluster of this test process.
pub(super) struct Server {
    bin: PathBuf,
    port: u16,
    /// Its folder: the TLS cluster's CA certificate is `ca.crt` there.
    pub(super) dir: PathBuf,
    /// It takes only TLS connections.
    tls: bool,
}

static SERVER: OnceLock<Result<Server, String>> = OnceLock::new();
static TLS_SERVER: OnceLock<Result<Server, String>> = OnceLock::new();

/// The cluster, started on first use; `None` (with the reason printed) where
/// PostgreSQL is not installed.
pub(super) fn server() -> Option<&'static Server> {
    started(SERVER.get_or_init(|| start(false)))
}

/// A second cluster that takes only TLS connections (`hostssl`, plain ones
/// rejected by pg_hba.conf), its certificate signed by a CA made for it
/// (`ca.crt` in its folder, for `sslrootcert`), started on first use.
pub(super) fn tls_server() -> Option<&'static Server> {
    started(TLS_SERVER.get_or_init(|| start(true)))
}

fn started(server: &'static Result<Server, String>) -> Option<&'static Server> {
    match server {
        Ok(s) => Some(s),
        Err(why) => {
            eprintln!("skipped: {why}");
            None
        }
    }
}

/// Run `cmd` as `nobody` when this process is root (the server refuses root).
fn as_server_user(program: &Path, root: bool) -> Command {
    if root {
        let mut c = Command::new("runuser");
        c.args(["-u", "nobody", "--"]).arg(program);
        c
    } else {
        Command::new(program)
    }
}

/// A CA and a server certificate it signs for 127.0.0.1 in `dir` (`ca.crt`,
/// `server.crt`, `server.key`), by the `openssl` command.
fn certificates(dir: &Path) -> Result<(), String> {
    let openssl = |args: &[&str]| -> Result<(), String> {
        let out = Command::new("openssl").current_dir(dir).args(args).output().map_err(|e| format!("openssl: {e}"))?;
        if out.status.success() {
            Ok(())
        } else {
            Err(format!("openssl {args:?}: {}", String::from_utf8_lossy(&out.stderr)))
        }
    };
    let ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"];
    let mut ca =
        vec!["req", "-x509", "-days", "2", "-subj", "/CN=survey test CA", "-keyout", "ca.key", "-out", "ca.crt"];
    ca.extend(ec);
    ca.extend(["-addext", "basicConstraints=critical,CA:TRUE", "-addext", "keyUsage=critical,keyCertSign,cRLSign"]);
    openssl(&ca)?;
    let mut csr = vec!["req", "-subj", "/CN=127.0.0.1", "-keyout", "server.key", "-out", "server.csr"];
    csr.extend(ec);
    openssl(&csr)?;
    std::fs::write(dir.join("ext"), "subjectAltName=IP:127.0.0.1,DNS:localhost\nextendedKeyUsage=serverAuth\n")
        .map_err(|e| e.to_string())?;
    openssl(&[
        "x509",
        "-req",
        "-in",
        "server.csr",
        "-CA",
        "ca.crt",
        "-CAkey",
        "ca.key",
        "-CAcreateserial",
        "-days",
        "2",
        "-extfile",
        "ext",
        "-out",
        "server.crt",
    ])
}

fn start(tls: bool) -> Result<Server, String> {
    let bin = std::fs::read_dir("/usr/lib/postgresql")
        .map_err(|_| {
            "PostgreSQL is not installed (/usr/lib/postgresql is absent): the lab store tests skipped".to_string()
        })?
        .filter_map(|e| e.ok().map(|e| e.path().join("bin")))
        .filter(|b| b.join("initdb").exists() && b.join("pg_ctl").exists() && b.join("psql").exists())
        .max()
        .ok_or("no PostgreSQL server binaries (/usr/lib/postgresql/*/bin/initdb): the lab store tests skipped")?;
    let uid = |who: &[&str]| -> Option<u32> {
        let out = Command::new("id").arg("-u").args(who).output().ok()?;
        String::from_utf8(out.stdout).ok()?.trim().parse().ok()
    };
    let root = uid(&[]) == Some(0);
    let stamp = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_nanos();
    let dir = std::env::temp_dir().join(format!("survey-lab-{}-{stamp}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| format!("cannot make {}: {e}", dir.display()))?;
    std::fs::write(dir.join("pw"), PASSWORD).unwrap();
    if root {
        let nobody = uid(&["nobody"]).ok_or("no user nobody to run the server as")?;
        for p in [dir.clone(), dir.join("pw")] {
            std::os::unix::fs::chown(&p, Some(nobody), None).map_err(|e| format!("chown {}: {e}", p.display()))?;
        }
    }
    let data = dir.join("data");
    let run = |mut c: Command, what: &str| -> Result<(), String> {
        let out = c.output().map_err(|e| format!("{what}: {e}"))?;
        if out.status.success() {
            Ok(())
        } else {
            Err(format!(
                "{what} failed: {}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            ))
        }
    };
    let mut initdb = as_server_user(&bin.join("initdb"), root);
    initdb.arg("-D").arg(&data).args(["-U", "survey", "-A", "scram-sha-256", "--no-sync"]);
    initdb.arg(format!("--pwfile={}", dir.join("pw").display()));
    run(initdb, "initdb")?;
    let mut ssl = String::new();
    if tls {
        certificates(&dir)?;
        for f in ["server.crt", "server.key"] {
            std::fs::copy(dir.join(f), data.join(f)).map_err(|e| format!("{f}: {e}"))?;
        }
        use std::os::unix::fs::PermissionsExt as _;
        std::fs::set_permissions(data.join("server.key"), std::fs::Permissions::from_mode(0o600)).unwrap();
        if root {
            let nobody = uid(&["nobody"]).ok_or("no user nobody to run the server as")?;
            for f in ["server.crt", "server.key"] {
                std::os::unix::fs::chown(data.join(f), Some(nobody), None).map_err(|e| format!("chown {f}: {e}"))?;
            }
        }
        // TLS or nothing from the network; the socket in the folder for psql.
        std::fs::write(
            data.join("pg_hba.conf"),
            "local all all scram-sha-256\nhostssl all all 127.0.0.1/32 scram-sha-256\n\
             hostnossl all all 127.0.0.1/32 reject\n",
        )
        .map_err(|e| format!("pg_hba.conf: {e}"))?;
        ssl = " -c ssl=on".into();
    }
    // An ephemeral port: the kernel's choice, free again once the listener closes.
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let mut pg_ctl = as_server_user(&bin.join("pg_ctl"), root);
    pg_ctl.arg("-D").arg(&data).arg("-o").arg(format!(
        "-p {port} -k {} -c listen_addresses=127.0.0.1 -c fsync=off -c max_connections=40{ssl}",
        dir.display()
    ));
    pg_ctl.arg("-l").arg(dir.join("log")).args(["-w", "start"]);
    run(pg_ctl, "pg_ctl start")?;
    // The watchdog: when this test process ends, the cluster stops and its folder goes.
    let stop = format!(
        "while kill -0 {pid} 2>/dev/null; do sleep 0.2; done; {runuser}'{pg_ctl}' -D '{data}' -m immediate -w stop \
         >/dev/null 2>&1; rm -rf '{dir}'",
        pid = std::process::id(),
        runuser = if root { "runuser -u nobody -- " } else { "" },
        pg_ctl = bin.join("pg_ctl").display(),
        data = data.display(),
        dir = dir.display()
    );
    Command::new("sh")
        .args(["-c", &stop])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| format!("cannot start the watchdog: {e}"))?;
    Ok(Server { bin, port, dir, tls })
}

impl Server {
    /// The URL of `database` with the cluster's password.
    pub(super) fn url(&self, database: &str) -> String {
        format!("postgres://survey:{PASSWORD}@127.0.0.1:{}/{database}", self.port)
    }

    /// The URL psql connects with (TLS where the cluster takes nothing else).
    fn psql_url(&self, database: &str) -> String {
        let url = self.url(database);
        if self.tls { format!("{url}?sslmode=require") } else { url }
    }

    /// `psql -At -c sql` on `database`: the rows, one a line, `|` between columns.
    pub(super) fn psql(&self, database: &str, sql: &str) -> String {
        let out = Command::new(self.bin.join("psql"))
            .args(["-X", "-At", "-v", "ON_ERROR_STOP=1", "-d", &self.psql_url(database), "-c", sql])
            .output()
            .expect("psql runs");
        assert!(out.status.success(), "psql {sql}: {}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8(out.stdout).unwrap()
    }

    /// A new, empty database for one test; its URL.
    pub(super) fn database(&self, name: &str) -> String {
        self.psql("postgres", &format!("CREATE DATABASE {name}"));
        self.url(name)
    }
}

/// `args` on the lab store `url` (`--db URL`).
fn on_lab(bench: &Bench, url: &str, args: &[&str]) -> Output {
    let mut all = vec!["--db", url];
    all.extend_from_slice(args);
    bench.survey(&all)
}

/// Survey CSV rows whose values round-trip only if every bit is kept:
/// negative zero, subnormals, the largest and smallest normal doubles, 17 significant digits.
const EDGE_CSV: &str = "run,direction,target_deg,readout_deg,actual_deg,timestamp_s\n\
1,forward,0,-0,5e-324,0\n\
1,forward,180,180,180.00000000000003,-0\n\
1,reverse,180,179.99999999999997,2.2250738585072014e-308,999999999999.9999\n\
1,reverse,0,-2.225073858507201e-308,-0,4.9406564584124654e-324\n\
2,forward,0,1e-320,0.1,2\n\
2,forward,180,180.1,180.2,3\n\
2,reverse,180,180.3,179.9,4\n\
2,reverse,0,-0.30000000000000004,0.2,5\n";

/// `doc` without the keys that are a database's own numbering (ids) or
/// name: what must be equal between the station's file and the lab store.
fn without_ids(doc: &Value) -> Value {
    const OWN: [&str; 7] = ["id", "survey_id", "from", "to", "db", "verifies_survey", "path"];
    match doc {
        Value::Object(m) => Value::Object(
            m.iter().filter(|(k, _)| !OWN.contains(&k.as_str())).map(|(k, v)| (k.clone(), without_ids(v))).collect(),
        ),
        Value::Array(a) => Value::Array(a.iter().map(without_ids).collect()),
        other => other.clone(),
    }
}

#[test]
fn read_commands_give_the_same_answers_from_the_lab_store_as_from_the_station() {
    let Some(server) = server() else { return };
    let lab = server.database("same_answers");
    let bench = Bench::new();
    bench.write("fig8.toml", include_str!("../../sims/presets/fig8.toml"));
    bench.write("edge.csv", EDGE_CSV);
    // A calibration and its verification, a check, an import of edge values, a continuous scan.
    bench.survey(&["run", "--points", "90", "--runs", "3", "--bidirectional", "--verify", "--json"]).success();
    bench.survey(&["run", "--check", "--seed", "2", "--json"]).success();
    bench.survey(&["import", "edge.csv", "--asset", "edge"]).success();
    let scan = [
        "run",
        "--points",
        "36",
        "--runs",
        "2",
        "--bidirectional",
        "--scan",
        "continuous",
        "--asset",
        "scan",
        "--json",
    ];
    bench.survey(&scan).success();
    let station: Vec<Value> = bench.survey(&["list", "--json"]).success().json()["surveys"].as_array().unwrap().clone();
    let uids: Vec<String> = station.iter().map(|s| s["uid"].as_str().unwrap().to_string()).collect();
    assert_eq!(uids.len(), 5);

    // A certificate issued at the station goes with its survey.
    bench.survey(&["report", "--survey", &uids[0], "--out", "issued"]).success();
    let out = bench.survey(&["push", "--to", &lab, "--all", "--json"]).success();
    let doc = out.json();
    let pushed: Vec<&str> = doc["pushed"].as_array().unwrap().iter().map(|u| u.as_str().unwrap()).collect();
    assert_eq!(pushed, uids.iter().map(String::as_str).collect::<Vec<_>>(), "{out}");
    assert_eq!(doc["already"].as_array().map(Vec::len), Some(0));

    let listed = on_lab(&bench, &lab, &["list", "--json"]).success().json();
    let in_lab: Vec<Value> = listed["surveys"].as_array().unwrap().clone();
    assert_eq!(without_ids(&Value::Array(in_lab)), without_ids(&Value::Array(station.clone())));
    assert!(!listed["db"].as_str().unwrap().contains(PASSWORD), "{listed}");

    for uid in &uids {
        let both = |args: &[&str]| -> (Output, Output) {
            let mut a = args.to_vec();
            a.extend(["--survey", uid]);
            let station = bench.survey(&a);
            let mut l = vec!["--db", lab.as_str()];
            l.extend(a);
            (station, bench.survey(&l))
        };
        // Export bit for bit.
        let (s, l) = (format!("s-{uid}.csv"), format!("l-{uid}.csv"));
        bench.survey(&["export", "--csv", &s, "--survey", uid]).success();
        on_lab(&bench, &lab, &["export", "--csv", &l, "--survey", uid]).success();
        assert_eq!(bench.read(&s), bench.read(&l), "survey {uid} exported from the lab store");
        // Statistics, processing and model-gap equal.
        let (s, l) = both(&["stats", "--json"]);
        assert_eq!(without_ids(&s.success().json()), without_ids(&l.success().json()), "stats of {uid}");
        let show = |db: Option<&str>| {
            let mut a = vec!["show", uid.as_str(), "--json"];
            if let Some(db) = db {
                a.extend(["--db", db]);
            }
            without_ids(&bench.survey(&a).success().json())
        };
        assert_eq!(show(None), show(Some(&lab)), "show {uid}");
        if uid == &uids[3] {
            continue; // the import of edge values has too few targets to process
        }
        let (s, l) = both(&["process", "--json", "--table-out", "t.csv"]);
        let (s, l) = (s.success().json(), l.success().json());
        for key in ["peaks", "aliases", "predicted", "uncertainty", "noise"] {
            assert_eq!(s[key], l[key], "process {uid}: {key}");
        }
        let (s, l) = both(&["model-gap", "--model", "fig8.toml", "--json"]);
        let (s, l) = (without_ids(&s.success().json()), without_ids(&l.success().json()));
        assert_eq!(s, l, "model-gap of {uid}");
    }
    for asset in ["sim-fig8", "edge", "scan"] {
        let s = bench.survey(&["history", "--asset", asset, "--json"]).success().json();
        let l = on_lab(&bench, &lab, &["history", "--asset", asset, "--json"]).success().json();
        assert_eq!(without_ids(&s), without_ids(&l), "history of {asset}");
    }
    let s = bench.survey(&["compare", &uids[0], &uids[2], "--json"]).success().json();
    let l = on_lab(&bench, &lab, &["compare", &uids[0], &uids[2], "--json"]).success().json();
    assert_eq!(without_ids(&s), without_ids(&l));
    // What is due, from the dates, decisions and control figures pushed (the last survey: each store's own id).
    let due = |out: Output| {
        let mut doc = out.success().json();
        for a in doc["assets"].as_array_mut().unwrap() {
            a.as_object_mut().unwrap().remove("last_survey");
        }
        doc
    };
    let s = due(bench.survey(&["due", "--json"]));
    assert_eq!(s, due(on_lab(&bench, &lab, &["due", "--json"])), "due");
    assert_eq!(s["assets"][2]["asset"], "sim-fig8");
    assert_eq!(s["assets"][2]["reliability"]["checks"].as_u64(), Some(1), "{s}");
    // The verification names the lab's id of the survey it verifies; the report shows the pair.
    let v = on_lab(&bench, &lab, &["show", &uids[1], "--json"]).success().json();
    let native = on_lab(&bench, &lab, &["show", &uids[0], "--json"]).success().json();
    assert_eq!(v["verifies_survey"], native["id"]);
    on_lab(&bench, &lab, &["report", "--survey", &uids[0], "--out", "lab-report"]).success();
    let html = bench.read("lab-report/index.html");
    assert!(html.contains("id=\"verification\"") && html.contains("ISO 230-2"), "the lab's report");
    // The certificate as the station issued it, byte for byte; one amended after the push goes with the next.
    for file in ["index.html", "dcc.xml"] {
        assert!(bench.read(&format!("lab-report/{file}")) == bench.read(&format!("issued/{file}")), "{file}");
    }
    bench.survey(&["report", "--survey", &uids[0], "--out", "amended", "--amend", "a second look"]).success();
    bench.survey(&["push", "--to", &lab, "--all", "--json"]).success();
    on_lab(&bench, &lab, &["report", "--survey", &uids[0], "--out", "lab-amended"]).success();
    assert!(bench.read("lab-amended/dcc.xml") == bench.read("amended/dcc.xml"), "the amendment pushed");
    // Nothing is issued in the lab store: a survey without a certificate gets a draft there.
    let draft = on_lab(&bench, &lab, &["report", "--survey", &uids[3], "--out", "lab-draft"]).success();
    assert!(draft.stderr.contains("a draft, not issued"), "{draft}");
    assert!(bench.read("lab-draft/index.html").contains("<b>Draft, not issued</b>"));
}

/// A survey of more rows than a push writes with `INSERT`s goes by binary
/// `COPY`, a chunk at a time: every value the same bits in the lab store.
#[test]
fn a_large_survey_is_pushed_by_copy_bit_for_bit() {
    let Some(server) = server() else { return };
    let lab = server.database("large_copy");
    let bench = Bench::new();
    // 2 runs x 2 directions x 1100 targets = 4400 rows, with edge values.
    let edges = ["-0", "5e-324", "2.2250738585072014e-308", "0.30000000000000004", "1e-300"];
    let mut csv = String::from("run,direction,target_deg,readout_deg,actual_deg,timestamp_s\n");
    for run in 1..=2 {
        for direction in ["forward", "reverse"] {
            for k in 0..1100 {
                let target = f64::from(k) * 360.0 / 1100.0;
                let edge = edges[k as usize % edges.len()];
                csv += &format!("{run},{direction},{target},{target},{}, {edge}\n", target + 1e-3 / f64::from(k + 1));
            }
        }
    }
    bench.write("large.csv", csv);
    bench.survey(&["import", "large.csv", "--asset", "large"]).success();
    bench.survey(&["push", "--to", &lab, "--json"]).success();
    let rows: usize = server.psql("large_copy", "SELECT COUNT(*) FROM samples").trim().parse().unwrap();
    assert_eq!(rows, 4400);
    bench.survey(&["export", "--csv", "s.csv"]).success();
    on_lab(&bench, &lab, &["export", "--csv", "l.csv"]).success();
    assert_eq!(bench.read("s.csv"), bench.read("l.csv"));
    let s = bench.survey(&["history", "--asset", "large", "--json"]).success().json();
    let l = on_lab(&bench, &lab, &["history", "--asset", "large", "--json"]).success().json();
    assert_eq!(without_ids(&s), without_ids(&l));
}

/// The uids `push --json` listed under `key`.
fn uids(doc: &Value, key: &str) -> Vec<String> {
    doc[key].as_array().unwrap_or_else(|| panic!("{key} in {doc}")).iter().map(|u| u.as_str().unwrap().into()).collect()
}

/// `n` small simulated surveys in the bench's database (seeds from `seed`).
pub(super) fn small_surveys(bench: &Bench, n: u32, seed: u32) {
    for k in 0..n {
        let s = (seed + k).to_string();
        bench.survey(&["run", "--points", "36", "--runs", "2", "--bidirectional", "--seed", &s, "--json"]).success();
    }
}

#[test]
fn push_copies_each_complete_survey_exactly_once_again_from_several_stations_and_after_a_kill() {
    let Some(server) = server() else { return };
    let lab = server.database("exactly_once");
    let count = || -> usize { server.psql("exactly_once", "SELECT COUNT(*) FROM surveys").trim().parse().unwrap() };
    let distinct =
        || -> usize { server.psql("exactly_once", "SELECT COUNT(DISTINCT uid) FROM surveys").trim().parse().unwrap() };
    let (a, b, c) = (Bench::new(), Bench::new(), Bench::new());
    small_surveys(&a, 3, 1);
    // A survey killed during its acquisition: not complete, not pushed.
    let out = a.command(&["run", "--points", "36", "--runs", "2", "--sim-crash-after", "10"]).output().unwrap();
    assert!(!out.status.success());
    let running = a.survey(&["list", "--json"]).success().json()["surveys"][3]["uid"].as_str().unwrap().to_string();

    let first = a.survey(&["push", "--to", &lab, "--all", "--json"]).success().json();
    assert_eq!((uids(&first, "pushed").len(), uids(&first, "already").len()), (3, 0), "{first}");
    assert_eq!(uids(&first, "not_complete"), std::slice::from_ref(&running));
    // Again: nothing new.
    let again = a.survey(&["push", "--to", &lab, "--all", "--json"]).success().json();
    assert_eq!((uids(&again, "pushed").len(), uids(&again, "already")), (0, uids(&first, "pushed")), "{again}");
    // Two stations setting a new lab store up at the same moment: one schema, every survey once.
    let fresh = server.database("exactly_once_fresh");
    small_surveys(&b, 2, 10);
    let quiet = |mut c: Command| c.stdout(Stdio::null()).spawn().unwrap();
    let first_pushes = [&a, &b].map(|s| quiet(s.command(&["push", "--to", &fresh, "--all"])));
    for mut child in first_pushes {
        assert!(child.wait().unwrap().success());
    }
    let fresh_count = server.psql("exactly_once_fresh", "SELECT COUNT(DISTINCT uid) || ' ' || COUNT(*) FROM surveys");
    assert_eq!(fresh_count.trim(), "5 5");

    // One survey by its uid; one that is not complete: bad input (so is the
    // latest survey of this station, which is that one).
    let one = a.survey(&["push", "--to", &lab, "--survey", &uids(&first, "pushed")[1], "--json"]).success().json();
    assert_eq!(uids(&one, "already"), [uids(&first, "pushed")[1].clone()], "{one}");
    a.survey(&["push", "--to", &lab, "--survey", &running])
        .bad_input(&["is interrupted", "only complete surveys are pushed"]);
    a.survey(&["push", "--to", &lab]).bad_input(&["survey 4 of survey.db is interrupted"]);
    assert_eq!(count(), 3);

    // The latest survey by default.
    let latest = b.survey(&["push", "--to", &lab, "--json"]).success().json();
    let b_latest = b.survey(&["list", "--json"]).success().json()["surveys"][1]["uid"].clone();
    assert_eq!(latest["pushed"], serde_json::json!([b_latest]), "{latest}");
    assert_eq!(count(), 4);

    // Several stations at once, one of them twice: every survey stored once.
    let push = |bench: &Bench| quiet(bench.command(&["push", "--to", &lab, "--all", "--json"]));
    let children = [push(&a), push(&b), push(&b), push(&a)];
    for mut child in children {
        assert!(child.wait().unwrap().success());
    }
    assert_eq!((count(), distinct()), (5, 5));

    // A push killed midway (the second survey written, not committed): the
    // first is stored, nothing of the second; pushed again, all of them once.
    small_surveys(&c, 3, 20);
    let killed =
        c.command(&["push", "--to", &lab, "--all", "--json"]).env("SURVEY_TEST_PUSH_ABORT_AT", "2").output().unwrap();
    use std::os::unix::process::ExitStatusExt as _;
    assert_eq!(killed.status.signal(), Some(6), "the push aborted: {killed:?}");
    assert_eq!(count(), 6);
    let seq_rows: usize = server
        .psql("exactly_once", "SELECT COUNT(*) FROM samples WHERE survey_id NOT IN (SELECT id FROM surveys)")
        .trim()
        .parse()
        .unwrap();
    assert_eq!(seq_rows, 0);
    let rest = c.survey(&["push", "--to", &lab, "--all", "--json"]).success().json();
    assert_eq!((uids(&rest, "pushed").len(), uids(&rest, "already").len()), (2, 1), "{rest}");
    assert_eq!((count(), distinct()), (8, 8));
    // Every survey whole: its samples as many as the station's.
    let samples: usize = server.psql("exactly_once", "SELECT COUNT(*) FROM samples").trim().parse().unwrap();
    assert_eq!(samples, 8 * 144);
    // The lab store keeps the asset's whole history (issue 40): each
    // survey's summary copied with it, the pairs of surveys from two
    // stations made by the push; read from it, what computing it gives.
    let kept = |table: &str| server.psql("exactly_once", &format!("SELECT COUNT(*) FROM {table}")).trim().to_string();
    assert_eq!(kept("survey_summaries"), "8");
    // Every consecutive pair of the lab store's order (a station's own pair
    // whose first survey is not the one before it here is kept, unused).
    let pairs = "(SELECT p.id FROM (SELECT id, LAG(uid) OVER (ORDER BY created_at, id) AS prev FROM surveys) AS p \
                 JOIN survey_changes AS c ON c.survey_id = p.id AND c.from_uid = p.prev) AS kept";
    assert_eq!(kept(pairs), "7");
    let history = || on_lab(&c, &lab, &["history", "--asset", "sim-fig8", "--json"]).success().stdout;
    let read = history();
    server.psql("exactly_once", "DELETE FROM survey_changes; DELETE FROM survey_summaries");
    assert_eq!(history(), read, "computed on read");
    assert_eq!(kept("survey_summaries"), "0", "a read command writes nothing");
}

#[test]
fn a_password_never_shows_and_bad_urls_and_unreachable_servers_say_what_is_wrong() {
    let Some(server) = server() else { return };
    let lab = server.database("secrets");
    let bench = Bench::new();
    small_surveys(&bench, 1, 1);
    let loud = |args: &[&str]| {
        let mut cmd = bench.command(args);
        cmd.env("RUST_LOG", "trace");
        Bench::output_of(args, cmd)
    };
    let clean = |out: &Output| {
        assert!(!out.stdout.contains(PASSWORD) && !out.stderr.contains(PASSWORD), "the password shows\n{out}");
    };
    let out = loud(&["push", "--to", &lab, "--json"]).success();
    clean(&out);
    let out = loud(&["--db", &lab, "list", "--json"]).success();
    clean(&out);
    let out = loud(&["--db", &lab, "show"]).success();
    clean(&out);
    // Stored records hold no password.
    let dump = server.psql("secrets", "SELECT s::text FROM surveys AS s UNION ALL SELECT e::text FROM events AS e");
    assert!(!dump.is_empty() && !dump.contains(PASSWORD));
    // The environment's URL is not shown by --help.
    let out = bench.survey_with_env(&["--help"], "SURVEY_DB", &lab).success();
    clean(&out);

    // A wrong password: bad input naming the user and the host, never the password tried.
    let wrong = lab.replace(PASSWORD, "not-the-pw-42");
    let out = loud(&["--db", &wrong, "list"]);
    assert!(!out.stderr.contains("not-the-pw-42") && !out.stdout.contains("not-the-pw-42"), "{out}");
    let port = lab.rsplit(':').next().unwrap().split('/').next().unwrap().to_string();
    out.bad_input(&[
        "refused the connection of survey",
        &format!("127.0.0.1:{port}"),
        "password authentication failed",
    ]);
    // A URL that is not one: bad input naming it (without its password).
    let out = bench.survey(&["--db", "postgres://survey:pw-in-url@127.0.0.1:99999/x", "list"]);
    assert!(!out.stderr.contains("pw-in-url"), "{out}");
    out.bad_input(&["not a PostgreSQL URL", "postgres://survey@127.0.0.1:99999/x"]);
    bench.survey(&["push", "--to", "lab.db"]).bad_input(&["--to lab.db", "postgres:// URL"]);
    // No server there: a run-time failure naming the host.
    let closed = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let out = bench.survey(&["--db", &format!("postgres://survey:{PASSWORD}@127.0.0.1:{closed}/secrets"), "list"]);
    assert_eq!(out.code, 1, "{out}");
    let out = out.stderr_mentions(&[&format!("cannot reach the lab store at 127.0.0.1:{closed}")]);
    clean(&out);
    // A database without the survey tables, and acquisition into the lab store: bad input.
    let empty = server.database("secrets_empty");
    on_lab(&bench, &empty, &["list"]).bad_input(&["not a survey lab store yet", "survey push --to URL"]);
    let before = bench.stored();
    let out = on_lab(&bench, &lab, &["run", "--points", "36", "--runs", "2"]);
    let out = out.bad_input(&["written only by `survey push", "station's SQLite file"]);
    clean(&out);
    bench.write("valid.csv", VALID_CSV);
    on_lab(&bench, &lab, &["import", "valid.csv"]).bad_input(&["written only by `survey push"]);
    bench.assert_unchanged(&before, &out);
}

/// The SQLite schema of `db`: per table, its columns `(name, declared type,
/// not null, place in the primary key)`, its foreign keys `(column, table)`,
/// its indexes `(name, unique, columns)`, and the table's SQL.
type Schema = std::collections::BTreeMap<String, Table>;

#[derive(Debug, Default, PartialEq)]
struct Table {
    columns: Vec<(String, String, bool, usize)>,
    foreign: Vec<(String, String)>,
    indexes: Vec<(String, bool, String)>,
}

fn sqlite_schema(db: &Path) -> Schema {
    let conn = rusqlite::Connection::open(db).unwrap();
    let mut schema = Schema::new();
    let mut tables = conn
        // The sample packs are the station's copy of its rows for its own
        // reads (migration 7), not pushed: the lab store reads the rows.
        .prepare(
            "SELECT name, sql FROM sqlite_master WHERE type = 'table' AND name NOT LIKE 'sqlite_%' \
             AND name <> '_sqlx_migrations' AND name <> 'sample_packs'",
        )
        .unwrap();
    let tables: Vec<(String, String)> =
        tables.query_map([], |r| Ok((r.get(0)?, r.get(1)?))).unwrap().map(Result::unwrap).collect();
    for (name, sql) in tables {
        let mut t = Table::default();
        let mut cols = conn.prepare(&format!("PRAGMA table_info({name})")).unwrap();
        t.columns = cols
            .query_map([], |r| {
                let (col, ty, notnull, pk): (String, String, bool, i64) = (r.get(1)?, r.get(2)?, r.get(3)?, r.get(5)?);
                // The mapping of types: a 0/1 INTEGER is a boolean, a column of no declared type holds reals.
                let mapped = match ty.as_str() {
                    "INTEGER" if sql.contains(&format!("{col} IN (0, 1)")) => "boolean",
                    "INTEGER" => "bigint",
                    "REAL" | "" => "double precision",
                    "TEXT" => "text",
                    "BLOB" => "bytea",
                    other => panic!("{name}.{col}: type {other}"),
                };
                Ok((col, mapped.to_string(), notnull || pk > 0, pk as usize))
            })
            .unwrap()
            .map(Result::unwrap)
            .collect();
        let mut fks = conn.prepare(&format!("PRAGMA foreign_key_list({name})")).unwrap();
        t.foreign = fks.query_map([], |r| Ok((r.get(3)?, r.get(2)?))).unwrap().map(Result::unwrap).collect();
        let mut ix = conn.prepare(&format!("PRAGMA index_list({name})")).unwrap();
        let ix: Vec<(String, bool, String)> =
            ix.query_map([], |r| Ok((r.get(1)?, r.get(2)?, r.get(3)?))).unwrap().map(Result::unwrap).collect();
        for (ix_name, unique, _) in ix.into_iter().filter(|i| i.2 == "c") {
            let mut cols = conn.prepare(&format!("PRAGMA index_info({ix_name})")).unwrap();
            let cols: Vec<String> = cols.query_map([], |r| r.get(2)).unwrap().map(Result::unwrap).collect();
            t.indexes.push((ix_name, unique, cols.join(",")));
        }
        schema.insert(name, t);
    }
    schema
}

fn postgres_schema(server: &Server, database: &str) -> Schema {
    let rows = |sql: &str| -> Vec<Vec<String>> {
        server.psql(database, sql).lines().map(|l| l.split('|').map(str::to_string).collect()).collect()
    };
    let mut schema = Schema::new();
    for r in rows(
        "SELECT c.table_name, c.column_name, c.data_type, c.is_nullable, COALESCE(k.ordinal_position, 0) \
         FROM information_schema.columns AS c LEFT JOIN (SELECT kcu.table_name, kcu.column_name, kcu.ordinal_position \
         FROM information_schema.table_constraints AS tc JOIN information_schema.key_column_usage AS kcu \
         ON kcu.constraint_name = tc.constraint_name AND kcu.table_name = tc.table_name \
         WHERE tc.constraint_type = 'PRIMARY KEY' AND tc.table_schema = 'public') AS k \
         ON k.table_name = c.table_name AND k.column_name = c.column_name \
         WHERE c.table_schema = 'public' AND c.table_name <> '_sqlx_migrations' ORDER BY c.table_name, c.ordinal_position",
    ) {
        let t = schema.entry(r[0].clone()).or_default();
        t.columns.push((r[1].clone(), r[2].clone(), r[3] == "NO", r[4].parse().unwrap()));
    }
    for r in rows(
        "SELECT tc.table_name, kcu.column_name, ccu.table_name FROM information_schema.table_constraints AS tc \
         JOIN information_schema.key_column_usage AS kcu ON kcu.constraint_name = tc.constraint_name \
         JOIN (SELECT DISTINCT constraint_name, table_name FROM information_schema.constraint_column_usage) AS ccu \
         ON ccu.constraint_name = tc.constraint_name \
         WHERE tc.constraint_type = 'FOREIGN KEY' AND tc.table_schema = 'public' ORDER BY tc.table_name, kcu.ordinal_position",
    ) {
        schema.get_mut(&r[0]).unwrap().foreign.push((r[1].clone(), r[2].clone()));
    }
    for r in rows(
        "SELECT i.tablename, i.indexname, i.indexdef LIKE 'CREATE UNIQUE%', \
         regexp_replace(substring(i.indexdef from '\\((.*)\\)'), ' ', '', 'g') \
         FROM pg_indexes AS i WHERE i.schemaname = 'public' AND i.indexname NOT LIKE '%_pkey' \
         AND i.tablename <> '_sqlx_migrations'",
    ) {
        schema.get_mut(&r[0]).unwrap().indexes.push((r[1].clone(), r[2] == "t", r[3].clone()));
    }
    schema
}

#[test]
fn the_lab_store_s_schema_is_the_station_s_tables_columns_types_and_keys() {
    let Some(server) = server() else { return };
    let lab = server.database("schemas");
    let bench = Bench::new();
    bench.write("valid.csv", VALID_CSV);
    bench.import("valid.csv");
    bench.survey(&["push", "--to", &lab]).success();
    let (mut station, mut store) = (sqlite_schema(&bench.path("survey.db")), postgres_schema(server, "schemas"));
    for t in station.values_mut().chain(store.values_mut()) {
        t.foreign.sort();
        t.indexes.sort();
    }
    assert_eq!(station.keys().collect::<Vec<_>>(), store.keys().collect::<Vec<_>>());
    assert!(station.len() >= 10, "{:?}", station.keys());
    for (name, t) in &station {
        assert_eq!(t, &store[name], "table {name}: SQLite left, PostgreSQL right");
    }
}

/// Issue 51, item 4: the lab store's schema is checked as a station's
/// file's is. A column or a table dropped, an index gone: every read and
/// `push` exits 2 naming what is missing and the migration that makes it
/// (it gave raw sqlx text, exit 1); a table the role may not read: exit 2
/// with the grant to run.
#[test]
fn a_lab_store_missing_a_column_a_table_or_a_grant_is_refused_saying_what_to_run() {
    let Some(server) = server() else { return };
    let bench = Bench::new();
    small_surveys(&bench, 1, 3);
    let lab = server.database("damaged_lab");
    bench.survey(&["push", "--to", &lab]).success();
    server.psql("damaged_lab", "ALTER TABLE checks DROP COLUMN stated_u_deg; DROP INDEX surveys_by_asset");
    for args in [&["list"][..], &["stats"], &["history"]] {
        let out = on_lab(&bench, &lab, args).bad_input(&[
            "the lab store postgres://survey@127.0.0.1:",
            "is damaged: the table `checks` has no column `stated_u_deg` (made by migrations/postgres/0012_intervals.sql)",
            "the index `surveys_by_asset` is missing (made by migrations/postgres/0005_assets.sql)",
        ]);
        assert!(!out.stderr.contains(PASSWORD) && !out.stderr.contains("error returned from database"), "{out}");
    }
    bench.survey(&["push", "--to", &lab]).bad_input(&["is damaged", "stated_u_deg"]);
    server.psql("damaged_lab", "DROP TABLE events");
    on_lab(&bench, &lab, &["list"])
        .bad_input(&["the table `events` is missing (made by migrations/postgres/0001_init.sql)"]);
    // A role that may read the migrations' table and the surveys only.
    let sound = server.database("granted_lab");
    bench.survey(&["push", "--to", &sound]).success();
    server.psql(
        "granted_lab",
        "CREATE ROLE reader51 LOGIN PASSWORD 'reader-pw-51'; GRANT SELECT ON _sqlx_migrations, surveys TO reader51",
    );
    let reader = sound.replace(&format!("survey:{PASSWORD}"), "reader51:reader-pw-51");
    let out = on_lab(&bench, &reader, &["list"]).bad_input(&[
        "the role reader51 may not read the tables",
        "`events`",
        "GRANT SELECT ON",
    ]);
    assert!(!out.stderr.contains("reader-pw-51"), "{out}");
}

/// `survey report --lab URL`: every station's certificate numbered from the
/// lab store's one sequence (YYYY-NNNNN), two stations at once included; no
/// number drawn where no certificate is issued; the certificates pushed side
/// by side.
#[test]
fn certificate_numbers_are_drawn_from_the_lab_store_s_sequence_by_every_station() {
    let Some(server) = server() else { return };
    let lab = server.database("numbers");
    let (a, b) = (Bench::new(), Bench::new());
    small_surveys(&a, 2, 1);
    small_surveys(&b, 1, 5);
    let year = &survey_store_year();
    // Two stations at once: two numbers.
    let both = [(&a, "1"), (&b, "1")]
        .map(|(s, id)| s.command(&["report", "--survey", id, "--out", "r", "--lab", &lab]).output().unwrap());
    let mut numbers: Vec<String> = [&a, &b]
        .iter()
        .zip(&both)
        .map(|(s, out)| {
            assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
            let dcc = s.read("r/dcc.xml");
            let id = dcc.split("<dcc:uniqueIdentifier>").nth(1).and_then(|t| t.split('<').next()).unwrap().to_string();
            assert!(String::from_utf8_lossy(&out.stderr).contains(&format!("certificate number {id} drawn")));
            id
        })
        .collect();
    numbers.sort();
    assert_eq!(numbers, [format!("{year}-00001"), format!("{year}-00002")]);
    // The next: 3; none drawn for a certificate issued before, a given number or a survey not complete.
    a.survey(&["report", "--survey", "2", "--out", "r2", "--lab", &lab]).success();
    assert!(a.read("r2/dcc.xml").contains(&format!("<dcc:uniqueIdentifier>{year}-00003<")));
    a.survey(&["report", "--survey", "1", "--out", "again", "--lab", &lab])
        .bad_input(&["was issued", "no number was drawn"]);
    a.survey(&["report", "--survey", "2", "--out", "x", "--lab", &lab, "--certificate-number", "C-1"])
        .bad_input(&["--certificate-number gives the number"]);
    a.survey(&["report", "--out", "x", "--lab", "not-a-url.db"]).bad_input(&["--lab not-a-url.db: not a lab store"]);
    let hidden = a.survey(&["report", "--out", "x", "--lab", "mysql://u:secret@h/db"]);
    assert!(!hidden.stderr.contains("secret"), "{hidden}");
    // The environment's SURVEY_LAB (as push reads it): a certificate issued is written again, nothing drawn.
    let again = a.survey_with_env(&["report", "--survey", "1", "--out", "again-env"], "SURVEY_LAB", &lab).success();
    assert!(again.stderr.contains("no number drawn") && !again.stderr.contains(PASSWORD), "{again}");
    assert_eq!(a.read("again-env/dcc.xml"), a.read("r/dcc.xml"), "the certificate as issued");
    assert_eq!(server.psql("numbers", "SELECT last FROM certificate_numbers").trim(), "3", "nothing else drawn");
    // An amendment may draw its own.
    a.survey(&["report", "--survey", "1", "--out", "amended", "--amend", "a typo", "--lab", &lab]).success();
    assert!(a.read("amended/dcc.xml").contains(&format!("<dcc:uniqueIdentifier>{year}-00004<")));
    for s in [&a, &b] {
        s.survey(&["push", "--to", &lab, "--all"]).success();
    }
    assert_eq!(server.psql("numbers", "SELECT COUNT(DISTINCT number) FROM certificates").trim(), "4");
}

/// This year, as the report draws it (UTC).
fn survey_store_year() -> String {
    humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string()[..4].to_string()
}
