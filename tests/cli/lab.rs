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
const PASSWORD: &str = "lab-s3cret-pw";

/// A PostgreSQL cluster of this test process.
struct Server {
    bin: PathBuf,
    port: u16,
}

static SERVER: OnceLock<Result<Server, String>> = OnceLock::new();

/// The cluster, started on first use; `None` (with the reason printed) where
/// PostgreSQL is not installed.
fn server() -> Option<&'static Server> {
    match SERVER.get_or_init(start) {
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

fn start() -> Result<Server, String> {
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
    // An ephemeral port: the kernel's choice, free again once the listener closes.
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let mut pg_ctl = as_server_user(&bin.join("pg_ctl"), root);
    pg_ctl.arg("-D").arg(&data).arg("-o").arg(format!(
        "-p {port} -k {} -c listen_addresses=127.0.0.1 -c fsync=off -c max_connections=40",
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
    Ok(Server { bin, port })
}

impl Server {
    /// The URL of `database` with the cluster's password.
    fn url(&self, database: &str) -> String {
        format!("postgres://survey:{PASSWORD}@127.0.0.1:{}/{database}", self.port)
    }

    /// `psql -At -c sql` on `database`: the rows, one a line, `|` between columns.
    fn psql(&self, database: &str, sql: &str) -> String {
        let out = Command::new(self.bin.join("psql"))
            .args(["-X", "-At", "-v", "ON_ERROR_STOP=1", "-d", &self.url(database), "-c", sql])
            .output()
            .expect("psql runs");
        assert!(out.status.success(), "psql {sql}: {}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8(out.stdout).unwrap()
    }

    /// A new, empty database for one test; its URL.
    fn database(&self, name: &str) -> String {
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
    bench.survey(&["run", "--points", "72", "--runs", "3", "--bidirectional", "--verify", "--json"]).success();
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
    // The verification names the lab's id of the survey it verifies; the report shows the pair.
    let v = on_lab(&bench, &lab, &["show", &uids[1], "--json"]).success().json();
    let native = on_lab(&bench, &lab, &["show", &uids[0], "--json"]).success().json();
    assert_eq!(v["verifies_survey"], native["id"]);
    on_lab(&bench, &lab, &["report", "--survey", &uids[0], "--out", "lab-report"]).success();
    let html = bench.read("lab-report/index.html");
    assert!(html.contains("id=\"verification\"") && html.contains("ISO 230-2"), "the lab's report");
}
