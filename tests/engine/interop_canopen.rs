//! python-canopen (an implementation no one here wrote) against the
//! simulated CiA 402 drive that `survey sim` serves behind its simulated SLCAN
//! adapter: its `BaseNode402` client, through python-can's `slcan` interface
//! on the pty `survey sim` links at the configured port, enables the drive,
//! switches it to profile position, moves it and reads the position back.
//! When python3 or the packages are missing the test says why and returns
//! (CI installs `canopen==2.3.0 python-can==4.6.1 pyserial==3.5`).

use std::io::{BufRead as _, BufReader};
use std::process::{Command, Stdio};

const BIN: &str = env!("CARGO_BIN_EXE_survey");
const SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/interop/canopen_402.py");

fn python_canopen_missing() -> Option<String> {
    match Command::new("python3").args(["-c", "import canopen, can, serial"]).output() {
        Err(e) => Some(format!("python3 cannot be started ({e})")),
        Ok(out) if !out.status.success() => Some(format!(
            "python-canopen is not installed (`python3 -m pip install canopen==2.3.0 python-can==4.6.1 \
             pyserial==3.5`): {}",
            String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("")
        )),
        Ok(_) => None,
    }
}

#[test]
fn python_canopen_enables_moves_and_reads_the_simulated_drive_over_slcan() {
    if let Some(why) = python_canopen_missing() {
        eprintln!("skipped: {why}");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let port = dir.path().join("ttyCAN");
    let cfg = dir.path().join("c.toml");
    std::fs::write(
        &cfg,
        format!(
            "[positioner]\ndriver = \"canopen\"\ntransport = \"slcan\"\nport = \"{}\"\nbitrate = 500000\nnode_id = 7\n\
             counts_per_degree = 10000.0\n[tracker]\ndriver = \"emscon\"\naddress = \"127.0.0.1:0\"\n",
            port.display()
        ),
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
    assert!(ready.contains("\"ready\":true"), "{ready}");
    let out = Command::new("python3").arg(SCRIPT).arg(&port).args(["7", "25.5", "10000"]).output().unwrap();
    let _ = nix::sys::signal::kill(nix::unistd::Pid::from_raw(sim.id() as i32), nix::sys::signal::Signal::SIGTERM);
    let _ = sim.wait();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "python-canopen failed: {stderr}");
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON line");
    assert_eq!(doc["start_state"], "SWITCH ON DISABLED", "{doc}");
    assert_eq!(doc["op_mode"], "PROFILED POSITION", "{doc}");
    assert_eq!(doc["state"], "OPERATION ENABLED", "{doc}");
    // The simulated axis settles on the target (its readout at rest is the
    // commanded position), so the position read back is the target's counts.
    assert_eq!(doc["position_counts"], doc["target_counts"], "{doc}");
    assert_eq!(doc["target_counts"], 255_000);
}
