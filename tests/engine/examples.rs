//! Every shipped example configuration runs end to end against its simulated
//! instruments served over their real protocols by `survey sim` (another
//! process), as a lab would rehearse it: `survey sim` serves the example as it
//! is, its addresses on loopback ports and its serial devices in its own
//! folder, and writes the configuration to run against (the ready line's
//! `config`); the plan is cut to 2 runs (and 12 targets for a tracker), the
//! engine's fixed dwell to 10 ms; everything else is the example's own.

use std::io::{BufRead as _, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Instant;

const BIN: &str = env!("CARGO_BIN_EXE_survey");

/// The example with a 10 ms dwell (its addresses as they are).
fn rehearsal(example: &str) -> toml::Table {
    let mut cfg: toml::Table = example.parse().expect("the example parses");
    let timing = cfg.entry("timing").or_insert_with(|| toml::Value::Table(toml::Table::new()));
    timing.as_table_mut().unwrap().insert("dwell_s".into(), 0.01.into());
    cfg
}

/// Whether a configuration puts several SMRs on the table.
fn run_cfg_has_smrs(cfg: &toml::Table) -> bool {
    cfg.get("smrs").is_some()
}

/// The configuration `survey sim` wrote to run against (its ready line's `config`).
fn sim_config(ready: &serde_json::Value) -> (std::path::PathBuf, toml::Table) {
    let path = std::path::PathBuf::from(ready["config"].as_str().unwrap_or_else(|| panic!("no config: {ready}")));
    let cfg = std::fs::read_to_string(&path).unwrap().parse().expect("the written configuration parses");
    (path, cfg)
}

/// Start `survey sim` and read its ready line (bounded wait).
fn start_sim(config: &Path) -> (Child, serde_json::Value) {
    let mut child = Command::new(BIN)
        .args(["sim", "--config", config.to_str().unwrap(), "--time-scale", "100"])
        .env_remove("RUST_LOG")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.as_mut().unwrap()).read_line(&mut line).unwrap();
    let ready: serde_json::Value = match serde_json::from_str(&line) {
        Ok(v) => v,
        Err(e) => {
            let _ = child.kill();
            let out = child.wait_with_output().unwrap();
            panic!("no ready line ({e}): {line}\n{}", String::from_utf8_lossy(&out.stderr))
        }
    };
    assert_eq!(ready["ready"], true, "{ready}");
    (child, ready)
}

#[test]
fn every_example_configuration_runs_against_survey_sim() {
    let dir = tempfile::tempdir().unwrap();
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/config");
    let mut ran = 0;
    let mut names: Vec<_> = std::fs::read_dir(&examples).unwrap().map(|e| e.unwrap().path()).collect();
    names.sort();
    for path in names.into_iter().filter(|p| p.extension().is_some_and(|e| e == "toml")) {
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        let sim_cfg = dir.path().join(format!("{name}.toml"));
        std::fs::write(&sim_cfg, toml::to_string(&rehearsal(&std::fs::read_to_string(&path).unwrap())).unwrap())
            .unwrap();
        let started = Instant::now();
        let (sim, ready) = start_sim(&sim_cfg);
        // The configuration to run against names where each instrument is served.
        let (run_cfg, cfg) = sim_config(&ready);
        for (instrument, section, key) in [
            ("positioner", "positioner", "address"),
            ("positioner", "positioner", "port"),
            ("tracker", "tracker", "address"),
            ("autocollimator", "autocollimator", "port"),
        ] {
            if let Some(at) = cfg.get(section).and_then(|t| t.get(key)) {
                assert_eq!(ready["instruments"][instrument].as_str(), at.as_str(), "{name}: {section}.{key}");
                let at = at.as_str().unwrap();
                assert!(at.starts_with("127.0.0.1:") || at.starts_with(run_cfg.parent().unwrap().to_str().unwrap()));
            }
        }
        let db = dir.path().join(format!("{name}.db"));
        let mut args = vec!["--db", db.to_str().unwrap(), "run", "--config", run_cfg.to_str().unwrap(), "--runs", "2"];
        if cfg.get("polygon").is_none() {
            args.extend(["--points", "12"]);
        }
        args.push("--json");
        let out = Command::new(BIN).args(&args).env_remove("RUST_LOG").output().unwrap();
        nix::sys::signal::kill(nix::unistd::Pid::from_raw(sim.id() as i32), nix::sys::signal::Signal::SIGTERM).unwrap();
        let sim_out = sim.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{name}: survey run failed\n{stderr}");
        let doc: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON document");
        assert_eq!(doc["status"], "complete", "{name}: {stderr}");
        assert!(doc["samples"].as_u64().is_some_and(|n| n >= 2 * 2 * 9), "{name}: {}", doc["samples"]);
        assert_eq!(sim_out.status.code(), Some(0), "{name}: survey sim ends cleanly on SIGTERM");
        let last = String::from_utf8_lossy(&sim_out.stdout);
        assert!(last.lines().last().is_some_and(|l| l.contains("\"stopped\":true")), "{name}: {last}");
        assert!(!run_cfg.parent().unwrap().exists(), "{name}: the sim removed its folder, links and configuration");
        if run_cfg_has_smrs(&cfg) {
            // Three SMRs, each pointed at over the wire at every target:
            // the tracker's error separated from the axis's.
            let r = &doc["process"]["reference_error"];
            assert_eq!((r["separated"].as_bool(), r["smrs"].as_u64()), (Some(true), Some(3)), "{name}: {r}");
            assert_eq!(r["method"], "separation", "{name}: {r}");
        }
        eprintln!("{name}: {} samples in {:.1} s", doc["samples"], started.elapsed().as_secs_f64());
        ran += 1;
    }
    assert!(ran >= 7, "every example runs here (a SocketCAN drive behind a simulated adapter where no interface is)");
}

#[test]
fn the_help_example_serves_a_real_bench_and_refuses_a_continuous_scan_under_a_time_scale_at_once() {
    // `survey sim --help`'s own example, as it is: real addresses on the lab's network.
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/config/modbus-emscon.toml");
    let (sim, ready) = start_sim(&example);
    let (run_cfg, cfg) = sim_config(&ready);
    for section in ["positioner", "tracker"] {
        let at = ready["instruments"][section].as_str().unwrap();
        assert!(at.starts_with("127.0.0.1:") && !at.ends_with(":0"), "{ready}");
        assert_eq!(cfg[section]["address"].as_str(), Some(at));
    }
    assert_eq!(cfg["arm"]["radius_mm"].as_float(), Some(1000.0), "the rest of the example is kept");
    // A continuous scan cannot pair instruments 100 times faster than real time:
    // refused before the survey, saying why, nothing stored (before: minutes of
    // passes, then "the tracker stream has no point within 0.0300 s", exit 1).
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("s.db");
    let started = Instant::now();
    let out = Command::new(BIN)
        .args(["--db", db.to_str().unwrap(), "run", "--config", run_cfg.to_str().unwrap()])
        .args(["--points", "12", "--runs", "2", "--scan", "continuous"])
        .env_remove("RUST_LOG")
        .output()
        .unwrap();
    let took = started.elapsed();
    nix::sys::signal::kill(nix::unistd::Pid::from_raw(sim.id() as i32), nix::sys::signal::Signal::SIGTERM).unwrap();
    let sim_out = sim.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    // The configuration to run against says the instruments' time scale, so
    // the refusal comes from it, before anything is connected.
    assert!(err.contains("--scan continuous is not possible") && err.contains("100x real time"), "{err}");
    assert_eq!(cfg["timing"]["time_scale"].as_float(), Some(100.0), "{cfg}");
    assert!(took.as_secs() < 30, "refused after {took:?}");
    assert!(!db.exists(), "nothing stored");
    let sim_err = String::from_utf8_lossy(&sim_out.stderr);
    assert!(sim_err.contains(&format!("survey run --config {}", run_cfg.display())), "{sim_err}");
    assert!(sim_err.contains("positioner: 192.168.1.40:502 -> 127.0.0.1:"), "{sim_err}");
    assert!(sim_err.contains("at 100x real time a step scan works; a continuous scan needs"), "{sim_err}");
    assert!(!run_cfg.exists(), "the sim removed the configuration it wrote");
}

#[test]
fn a_continuous_survey_is_not_resumed_on_instruments_under_a_time_scale() {
    let dir = tempfile::tempdir().unwrap();
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/config/modbus-emscon.toml");
    let sim = |config: &Path, scale: &str| {
        let mut child = Command::new(BIN)
            .args(["sim", "--config", config.to_str().unwrap(), "--time-scale", scale])
            .env_remove("RUST_LOG")
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.as_mut().unwrap()).read_line(&mut line).unwrap();
        (child, serde_json::from_str::<serde_json::Value>(&line).unwrap_or_else(|e| panic!("{e}: {line}")))
    };
    let term = |child: &Child| {
        nix::sys::signal::kill(nix::unistd::Pid::from_raw(child.id() as i32), nix::sys::signal::Signal::SIGTERM)
            .unwrap()
    };
    // A continuous survey started in real time and stopped at once: interrupted.
    let (real_time, ready) = sim(&example, "1");
    let (written, _) = sim_config(&ready);
    let config = dir.path().join("bench.toml");
    std::fs::copy(&written, &config).unwrap();
    let db = dir.path().join("s.db");
    let db_arg = db.to_str().unwrap();
    let mut run = Command::new(BIN)
        .args(["--db", db_arg, "run", "--config", config.to_str().unwrap(), "--points", "12", "--scan", "continuous"])
        .env_remove("RUST_LOG")
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = BufReader::new(run.stderr.take().unwrap());
    let mut line = String::new();
    while !line.starts_with("survey 1:") {
        line.clear();
        assert!(stderr.read_line(&mut line).unwrap() > 0, "survey run ended before its survey began");
    }
    term(&run);
    run.wait().unwrap();
    term(&real_time);
    real_time.wait_with_output().unwrap();
    let status = || {
        let out = Command::new(BIN).args(["--db", db_arg, "list", "--json"]).output().unwrap();
        serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap()["surveys"][0]["status"].clone()
    };
    assert_eq!(status(), "interrupted");
    // The same addresses, 100 times faster: resume refuses, nothing changes.
    let (fast, _) = sim(&config, "100");
    let out = Command::new(BIN).args(["--db", db_arg, "resume"]).env_remove("RUST_LOG").output().unwrap();
    term(&fast);
    fast.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--scan continuous: emscon 127.0.0.1:") && pace(&err).is_some_and(|x| (90.0..110.0).contains(&x)),
        "{err}"
    );
    assert_eq!(status(), "interrupted");
}

#[test]
fn survey_sim_serves_on_loopback_only_and_never_replaces_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("c.toml");
    let base = "[positioner]\ndriver = \"scpi-tcp\"\naddress = \"ADDRESS\"\n[tracker]\ndriver = \"emscon\"\naddress = \"127.0.0.1:0\"\n";
    // A lab's address (or a host name of its own) is served on a loopback port.
    for address in ["192.168.1.20:4000", "positioner.lab.invalid:4000"] {
        std::fs::write(&cfg, base.replace("ADDRESS", address)).unwrap();
        let (sim, ready) = start_sim(&cfg);
        let _ = nix::sys::signal::kill(nix::unistd::Pid::from_raw(sim.id() as i32), nix::sys::signal::Signal::SIGTERM);
        let _ = sim.wait_with_output();
        let at = ready["instruments"]["positioner"].as_str().unwrap();
        assert!(at.starts_with("127.0.0.1:") && !at.ends_with(":0"), "{address}: {ready}");
    }
    std::fs::write(&cfg, base.replace("ADDRESS", "no-port")).unwrap();
    let out = Command::new(BIN).args(["sim", "--config", cfg.to_str().unwrap()]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("'no-port' is not a host:port address"), "{err}");

    let taken = dir.path().join("taken");
    std::fs::write(&taken, "mine").unwrap();
    let serial = format!(
        "[positioner]\ndriver = \"scpi-serial\"\nport = \"{}\"\n[tracker]\ndriver = \"emscon\"\naddress = \"127.0.0.1:0\"\n",
        taken.display()
    );
    std::fs::write(&cfg, serial).unwrap();
    let out = Command::new(BIN).args(["sim", "--config", cfg.to_str().unwrap()]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("never replaces a file"), "{err}");
    assert_eq!(std::fs::read_to_string(&taken).unwrap(), "mine");

    std::fs::write(&cfg, base.replace("ADDRESS", "127.0.0.1:0")).unwrap();
    for bad in [["--time-scale", "0"], ["--faults", "0.9"]] {
        let out = Command::new(BIN).args(["sim", "--config", cfg.to_str().unwrap()]).args(bad).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{bad:?}: {}", String::from_utf8_lossy(&out.stderr));
    }
}

/// The examples page's copy of each example: the fenced `toml` block under
/// each heading "## `examples/config/NAME`", by name.
fn shown_examples(page: &str) -> std::collections::BTreeMap<String, String> {
    let mut shown = std::collections::BTreeMap::new();
    let mut lines = page.lines();
    while let Some(line) = lines.next() {
        let Some(name) = line.strip_prefix("## `examples/config/").and_then(|l| l.strip_suffix('`')) else { continue };
        assert!(lines.by_ref().any(|l| l == "```toml"), "docs/examples.md: no ```toml block under {name}");
        let block: Vec<&str> = lines.by_ref().take_while(|l| *l != "```").collect();
        let previous = shown.insert(name.to_string(), block.iter().map(|l| format!("{l}\n")).collect());
        assert!(previous.is_none(), "docs/examples.md shows {name} twice");
    }
    shown
}

#[test]
fn the_examples_page_shows_every_example_verbatim() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let page = std::fs::read_to_string(root.join("docs/examples.md")).expect("docs/examples.md");
    let mut shown = shown_examples(&page);
    let mut files: Vec<_> =
        std::fs::read_dir(root.join("examples/config")).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    for path in &files {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let text = std::fs::read_to_string(path).unwrap();
        let copy =
            shown.remove(&name).unwrap_or_else(|| panic!("docs/examples.md does not show examples/config/{name}"));
        assert_eq!(copy, text, "docs/examples.md does not show examples/config/{name} as it is");
    }
    assert!(files.len() >= 5, "at least one example per driver");
    assert!(shown.is_empty(), "docs/examples.md shows files that examples/config/ does not hold: {:?}", shown.keys());
}

#[test]
fn the_examples_page_is_read_block_by_block_to_the_byte() {
    let page = "## `examples/config/a.toml`\n\nWords.\n\n```toml\n[survey]\n\npoints = 24\n```\n\n\
                ## `examples/config/b.toml`\n\n```toml\n# b\n```\n";
    let shown = shown_examples(page);
    assert_eq!(shown.len(), 2);
    assert_eq!(shown["a.toml"], "[survey]\n\npoints = 24\n");
    assert_eq!(shown["b.toml"], "# b\n");
}

/// How many times as fast as this computer the refusal says the tracker's clock runs.
fn pace(err: &str) -> Option<f64> {
    err.split("its clock runs ").nth(1)?.split(' ').next()?.parse().ok()
}
