//! Every shipped example configuration runs end to end against its simulated
//! instruments served over their real protocols by `survey sim` (another
//! process), as a lab would rehearse it: the example's addresses become
//! loopback ones (port 0: the ready line says which) and its serial ports
//! temporary paths, the plan is cut to 2 runs (and 12 targets for a tracker),
//! the engine's fixed dwell to 10 ms; everything else is the example's own.

use std::io::{BufRead as _, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Instant;

const BIN: &str = env!("CARGO_BIN_EXE_survey");

/// The example rewritten for a rehearsal in `dir`.
fn rehearsal(example: &str, dir: &Path) -> toml::Table {
    let mut cfg: toml::Table = example.parse().expect("the example parses");
    for (section, key) in [("positioner", "address"), ("tracker", "address")] {
        if let Some(t) = cfg.get_mut(section).and_then(|v| v.as_table_mut())
            && t.contains_key(key)
        {
            t.insert(key.into(), "127.0.0.1:0".into());
        }
    }
    for section in ["positioner", "autocollimator"] {
        if let Some(t) = cfg.get_mut(section).and_then(|v| v.as_table_mut())
            && t.contains_key("port")
        {
            t.insert("port".into(), dir.join(format!("{section}-port")).display().to_string().into());
        }
    }
    let timing = cfg.entry("timing").or_insert_with(|| toml::Value::Table(toml::Table::new()));
    timing.as_table_mut().unwrap().insert("dwell_s".into(), 0.01.into());
    cfg
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
        let mut cfg = rehearsal(&std::fs::read_to_string(&path).unwrap(), dir.path());
        let slcan = cfg["positioner"].get("transport").and_then(|t| t.as_str()) == Some("slcan");
        if cfg["positioner"]["driver"].as_str() == Some("canopen") && !slcan {
            let interface = cfg["positioner"]["interface"].as_str().unwrap_or("can0");
            if !Path::new("/sys/class/net").join(interface).exists() {
                eprintln!("{name}: skipped: no SocketCAN interface {interface} on this machine (no AF_CAN here)");
                continue;
            }
        }
        let sim_cfg = dir.path().join(format!("{name}.sim.toml"));
        std::fs::write(&sim_cfg, toml::to_string(&cfg).unwrap()).unwrap();
        let started = Instant::now();
        let (sim, ready) = start_sim(&sim_cfg);
        // The rehearsal's configuration names the addresses the sim took.
        for (instrument, section, key) in [("positioner", "positioner", "address"), ("tracker", "tracker", "address")] {
            if let (Some(at), Some(t)) =
                (ready["instruments"][instrument].as_str(), cfg.get_mut(section).and_then(|v| v.as_table_mut()))
                && t.contains_key(key)
            {
                t.insert(key.into(), at.into());
            }
        }
        let run_cfg = dir.path().join(format!("{name}.run.toml"));
        std::fs::write(&run_cfg, toml::to_string(&cfg).unwrap()).unwrap();
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
        for section in ["positioner", "autocollimator"] {
            assert!(!dir.path().join(format!("{section}-port")).exists(), "{name}: the sim removed its links");
        }
        eprintln!("{name}: {} samples in {:.1} s", doc["samples"], started.elapsed().as_secs_f64());
        ran += 1;
    }
    assert!(ran >= 4, "every example but the SocketCAN one runs here");
}

#[test]
fn survey_sim_serves_on_loopback_only_and_never_replaces_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("c.toml");
    let base = "[positioner]\ndriver = \"scpi-tcp\"\naddress = \"ADDRESS\"\n[tracker]\ndriver = \"emscon\"\naddress = \"127.0.0.1:0\"\n";
    std::fs::write(&cfg, base.replace("ADDRESS", "192.168.1.20:4000")).unwrap();
    let out = Command::new(BIN).args(["sim", "--config", cfg.to_str().unwrap()]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("loopback only") && err.contains("192.168.1.20:4000"), "{err}");

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
