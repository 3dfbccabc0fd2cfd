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

/// Our SDO client against python-canopen's SDO server (`LocalNode`):
/// expedited and segmented, both ways, and the abort codes it sends. The
/// two hosts share one simulated CAN bus through two simulated SLCAN
/// adapters on two ptys.
#[tokio::test]
async fn our_sdo_client_against_python_canopens_local_node() {
    use std::time::Duration;
    use survey_drivers::error::ErrorKind;
    use survey_positioner_drivers::canopen::slcan::SlcanBus;
    use survey_positioner_drivers::canopen::{MemoryBus, SdoClient, SdoTimeouts};
    use survey_sim_servers::elcomat_server::pty_pair;
    use survey_sim_servers::slcan_adapter::serve_adapter;
    use tokio::io::{AsyncBufReadExt as _, AsyncWriteExt as _};

    if let Some(why) = python_canopen_missing() {
        eprintln!("skipped: {why}");
        return;
    }
    let bus = MemoryBus::new();
    let (python_master, python_slave) = pty_pair().unwrap();
    let (our_master, our_slave) = pty_pair().unwrap();
    let python_port = tokio_serial::SerialPort::name(&python_slave).unwrap();
    let our_port = tokio_serial::SerialPort::name(&our_slave).unwrap();
    tokio::spawn(serve_adapter(python_master, bus.endpoint()));
    tokio::spawn(serve_adapter(our_master, bus.endpoint()));
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/interop/canopen_local_node.py");
    let mut python = tokio::process::Command::new("python3")
        .arg(script)
        .arg(&python_port)
        .arg("9")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut lines = tokio::io::BufReader::new(python.stdout.take().unwrap()).lines();
    let ready = tokio::time::timeout(Duration::from_secs(30), lines.next_line()).await.unwrap().unwrap();
    assert_eq!(ready.as_deref(), Some("ready"));
    drop(python_slave);

    let mut can = SlcanBus::open_port(&our_port, 500_000, Duration::from_secs(2)).await.unwrap();
    drop(our_slave);
    let timeouts = SdoTimeouts { response: Duration::from_secs(2), resync_grace: Duration::from_millis(20) };
    let mut sdo = SdoClient::new(9, timeouts, "python LocalNode");
    // Expedited, both ways.
    assert_eq!(sdo.upload(&mut can, 0x2000, 0).await.unwrap(), 0x1234_5678u32.to_le_bytes());
    sdo.download(&mut can, 0x2000, 0, &0xCAFE_F00Du32.to_le_bytes()).await.unwrap();
    assert_eq!(sdo.upload(&mut can, 0x2000, 0).await.unwrap(), 0xCAFE_F00Du32.to_le_bytes());
    // Segmented, both ways.
    let text = sdo.upload(&mut can, 0x2001, 0).await.unwrap();
    assert_eq!(String::from_utf8(text).unwrap(), "survey: a segmented SDO transfer, 45 bytes..");
    let long = b"written by our SDO client in seven-byte segments";
    sdo.download(&mut can, 0x2001, 0, long).await.unwrap();
    assert_eq!(sdo.upload(&mut can, 0x2001, 0).await.unwrap(), long);
    // Its abort codes, with their text and our classification (an object
    // the dictionary does not have as expected is the device's, `abort_kind`).
    let e = sdo.download(&mut can, 0x2002, 0, &[1, 2]).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(0x0601_0002)), "{e}");
    assert!(e.message.contains("Attempt to write a read only object"), "{e}");
    let e = sdo.upload(&mut can, 0x3000, 0).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(0x0602_0000)), "object does not exist: {e}");
    assert_eq!(sdo.upload(&mut can, 0x2002, 0).await.unwrap(), 0xBEEFu16.to_le_bytes());

    // The server holds what we wrote.
    let mut stdin = python.stdin.take().unwrap();
    stdin.shutdown().await.unwrap();
    drop(stdin);
    let last = tokio::time::timeout(Duration::from_secs(10), lines.next_line()).await.unwrap().unwrap().unwrap();
    let held: serde_json::Value = serde_json::from_str(&last).unwrap();
    assert_eq!(held["0x2000"], 0xCAFE_F00Du32);
    assert_eq!(held["0x2001"], String::from_utf8_lossy(long).as_ref());
    let _ = python.wait().await;
}

/// A CiA 402 drive with the standard objects only, as python-canopen's
/// `LocalNode` holds them (nothing in 0x2000-0x5FFF: its SDO server answers
/// abort 0x06020000 there, as a real drive does), behind a simulated SLCAN
/// adapter: `survey check` passes and says what is unavailable without the
/// correction objects; our driver (its default configuration) enables the
/// drive, moves it and reads its status and position on the standard
/// objects alone, and refuses the correction table as bad usage without
/// sending it. Told the drive has the correction objects, the driver meets
/// the drive's abort.
#[tokio::test]
async fn our_driver_checks_enables_and_moves_a_drive_with_only_the_standard_objects() {
    use std::time::Duration;
    use survey_drivers::Positioner as _;
    use survey_drivers::error::ErrorKind;
    use survey_positioner_drivers::canopen::slcan::SlcanBus;
    use survey_positioner_drivers::canopen::{CanopenConfig, Cia402Positioner, MemoryBus};
    use survey_processing::table::CorrectionTable;
    use survey_sim_servers::elcomat_server::pty_pair;
    use survey_sim_servers::slcan_adapter::serve_adapter;
    use survey_store::config::SurveyConfig;
    use tokio::io::{AsyncBufReadExt as _, AsyncWriteExt as _};

    if let Some(why) = python_canopen_missing() {
        eprintln!("skipped: {why}");
        return;
    }
    let bus = MemoryBus::new();
    let (python_master, python_slave) = pty_pair().unwrap();
    let (our_master, our_slave) = pty_pair().unwrap();
    let python_port = tokio_serial::SerialPort::name(&python_slave).unwrap();
    let our_port = tokio_serial::SerialPort::name(&our_slave).unwrap();
    tokio::spawn(serve_adapter(python_master, bus.endpoint()));
    tokio::spawn(serve_adapter(our_master, bus.endpoint()));
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/interop/canopen_standard_drive.py");
    let mut python = tokio::process::Command::new("python3")
        .arg(script)
        .arg(&python_port)
        .arg("11")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut lines = tokio::io::BufReader::new(python.stdout.take().unwrap()).lines();
    let ready = tokio::time::timeout(Duration::from_secs(30), lines.next_line()).await.unwrap().unwrap();
    assert_eq!(ready.as_deref(), Some("ready"));
    drop(python_slave);

    // `survey check` of a configuration naming the drive (the tracker is
    // not there: its own line fails, the positioner's passes).
    let cfg = SurveyConfig::parse(
        &format!(
            "[positioner]\ndriver = \"canopen\"\ntransport = \"slcan\"\nport = \"{our_port}\"\nnode_id = 11\n\
             counts_per_degree = 10000.0\n[tracker]\ndriver = \"emscon\"\naddress = \"127.0.0.1:1\"\n\
             [timing]\ncall_timeout_s = 2.0\n"
        ),
        "standard.toml",
    )
    .unwrap();
    let checked = survey_bench::instruments::check(&cfg, &survey_drivers::SystemClock::new()).await;
    let positioner = &checked[0];
    assert!(positioner.ok, "{positioner:?}");
    assert!(positioner.detail.contains("in position"), "{positioner:?}");
    assert!(
        positioner.detail.contains("unavailable without correction_objects = true")
            && positioner.detail.contains("loading the correction table into the drive"),
        "{positioner:?}"
    );

    let can = SlcanBus::open_port(&our_port, 500_000, Duration::from_secs(2)).await.unwrap();
    drop(our_slave);
    let standard =
        CanopenConfig { node_id: 11, counts_per_degree: 10_000.0, sdo_timeout_ms: 2000, ..CanopenConfig::default() };
    let mut d = Cia402Positioner::connect(can, standard.clone()).await.unwrap();
    assert_eq!(d.device_name().await.unwrap(), "python-canopen standard CiA 402 drive");
    d.set_velocity(5.0).await.unwrap();
    d.move_to(12.5).await.unwrap();
    let s = d.status().await.unwrap();
    assert!(s.in_position && !s.moving && s.fault.is_none() && s.limit.is_none() && !s.correction_enabled, "{s:?}");
    assert_eq!(d.readout().await.unwrap(), 12.5);
    d.stop().await.unwrap();
    let table = CorrectionTable::new(vec![0.001; 8]).unwrap();
    let e = d.load_correction_table(&table).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Usage, "{e}");
    assert!(e.message.contains("correction_objects = true"), "{e}");
    // The same drive, the driver told it has the correction objects: the
    // status reads 0x2101, which the drive does not have.
    let mut told = Cia402Positioner::new(d.into_bus(), CanopenConfig { correction_objects: true, ..standard }).unwrap();
    let e = told.status().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(0x0602_0000)), "{e}");
    assert!(e.message.contains("0x2101"), "{e}");

    let mut stdin = python.stdin.take().unwrap();
    stdin.shutdown().await.unwrap();
    drop(stdin);
    let last = tokio::time::timeout(Duration::from_secs(10), lines.next_line()).await.unwrap().unwrap().unwrap();
    let held: serde_json::Value = serde_json::from_str(&last).unwrap();
    let written: Vec<&str> = held["written"].as_array().unwrap().iter().filter_map(|v| v.as_str()).collect();
    assert_eq!(written, ["0x6040", "0x6060", "0x607A", "0x6081"], "only standard objects were written");
    let _ = python.wait().await;
}
