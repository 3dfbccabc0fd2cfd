//! PyPI's `CESAPI` (an emScon client for Leica's AT4xx trackers that no one
//! here wrote) against the simulated tracker `survey sim` serves over TCP:
//! the client's set-up, a stationary measurement, and the positioning
//! commands a survey of several SMRs uses (`ES_C_GoPosition`,
//! `ES_C_FindReflector`), one of them where no reflector is. When python3 or
//! the package is missing the test says why and returns (CI installs
//! `CESAPI==1.1.3`).

use std::io::{BufRead as _, BufReader};
use std::process::{Command, Stdio};

const BIN: &str = env!("CARGO_BIN_EXE_survey");
const SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/interop/cesapi_client.py");

fn cesapi_missing() -> Option<String> {
    match Command::new("python3").args(["-c", "import CESAPI.command, CESAPI.connection"]).output() {
        Err(e) => Some(format!("python3 cannot be started ({e})")),
        Ok(out) if !out.status.success() => Some(format!(
            "CESAPI is not installed (`python3 -m pip install CESAPI==1.1.3`): {}",
            String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("")
        )),
        Ok(_) => None,
    }
}

fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt()
}

#[test]
fn cesapi_sets_up_measures_and_points_the_simulated_tracker() {
    if let Some(why) = cesapi_missing() {
        eprintln!("skipped: {why}");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("c.toml");
    std::fs::write(
        &cfg,
        "[positioner]\ndriver = \"modbus-tcp\"\naddress = \"127.0.0.1:0\"\n[positioner.map]\nunit_id = 1\n\
         position_encoding = { kind = \"counts\", counts_per_degree = 100000.0 }\n\
         [tracker]\ndriver = \"emscon\"\naddress = \"127.0.0.1:0\"\n",
    )
    .unwrap();
    let mut sim = Command::new(BIN)
        .args(["sim", "--config", cfg.to_str().unwrap(), "--time-scale", "50"])
        .env_remove("RUST_LOG")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut ready = String::new();
    BufReader::new(sim.stdout.as_mut().unwrap()).read_line(&mut ready).unwrap();
    let doc: serde_json::Value = serde_json::from_str(&ready).expect("the ready line");
    assert_eq!(doc["ready"], true, "{ready}");
    let tracker = doc["instruments"]["tracker"].as_str().expect("the tracker's address").to_string();
    let (host, port) = tracker.rsplit_once(':').unwrap();
    let out = Command::new("python3").arg(SCRIPT).args([host, port]).output().unwrap();
    let _ = nix::sys::signal::kill(nix::unistd::Pid::from_raw(sim.id() as i32), nix::sys::signal::Signal::SIGTERM);
    let _ = sim.wait();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let doc: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap_or_else(|e| {
        panic!("one JSON line from the client ({e}): {stdout}\n{}", String::from_utf8_lossy(&out.stderr))
    });
    assert_eq!(doc["status"], "ok", "{doc}");
    let xyz = |key: &str| -> Vec<f64> {
        doc[key].as_array().unwrap_or_else(|| panic!("{key}: {doc}")).iter().map(|v| v.as_f64().unwrap()).collect()
    };
    let (first, found) = (xyz("first"), xyz("found"));
    // The default arm's SMR, about 2.6 m away.
    let range = first.iter().map(|v| v * v).sum::<f64>().sqrt();
    assert!((1500.0..4000.0).contains(&range), "{first:?}");
    // Pointed beside it, the search found the same SMR (the table at rest):
    // the same place to the tracker's random part (micrometres).
    assert!(distance(&first, &found) < 0.05, "{first:?} against {found:?}");
    // Nowhere: cesapi raises on the search's failure status.
    let nowhere = doc["nowhere"].as_str().expect("the search where no reflector is failed");
    assert!(nowhere.starts_with("Command 63 failed with status"), "{nowhere}");
    // What it sent: GetSystemStatus, (Initialize), the set-up, the measurements, GoPosition and FindReflector.
    let sent: Vec<i64> = doc["commands"].as_array().unwrap().iter().map(|c| c.as_i64().unwrap()).collect();
    for c in [1, 5, 26, 24, 28, 49, 55, 63] {
        assert!(sent.contains(&c), "command {c} sent: {sent:?}");
    }
    assert_eq!(sent.iter().filter(|c| **c == 55).count(), 2, "{sent:?}");
    assert_eq!(doc["air"].as_array().map(Vec::len), Some(3), "the air each result carries: {doc}");
}
