//! Interoperability with pymodbus, an implementation no one here wrote:
//! our driver against a pymodbus server, and a pymodbus client against our
//! simulator. The scripts are in `tests/interop/`; when python3 or pymodbus
//! is missing, the tests say why and return (CI installs pymodbus).

use super::*;
use std::collections::HashMap;
use std::io::{BufRead, BufReader, Lines};
use std::process::{Child, ChildStdout, Command, Stdio};
use std::time::Duration;
use survey_drivers::VirtualClock;
use survey_drivers::error::ErrorKind;
use survey_drivers::traits::{Limit, Positioner};
use survey_positioner_drivers::modbus::{Location, ModbusPositioner, ModbusTimeouts};
use survey_processing::table::CorrectionTable;

const SERVER_SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/interop/modbus_server.py");
const CLIENT_SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/interop/modbus_client.py");
const TIMEOUTS: ModbusTimeouts = ModbusTimeouts { connect: Duration::from_secs(5), request: Duration::from_secs(2) };
/// Longest a script may take (python start-up included).
const SCRIPT_LIMIT: Duration = Duration::from_secs(30);

/// Why the interop tests cannot run here, if they cannot.
fn pymodbus_missing() -> Option<String> {
    match Command::new("python3").args(["-c", "import pymodbus; print(pymodbus.__version__)"]).output() {
        Err(e) => Some(format!("python3 cannot be started ({e})")),
        Ok(out) if !out.status.success() => Some(format!(
            "pymodbus is not installed for python3 (`python3 -m pip install 'pymodbus==3.11.4'`): {}",
            String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("")
        )),
        Ok(_) => None,
    }
}

/// A JSON value of the flat objects the scripts print.
#[derive(Debug, Clone, PartialEq)]
enum Json {
    Num(f64),
    Bool(bool),
    Nums(Vec<f64>),
}

impl Json {
    fn num(&self) -> f64 {
        match self {
            Json::Num(v) => *v,
            other => panic!("expected a number, got {other:?}"),
        }
    }
    fn bool(&self) -> bool {
        match self {
            Json::Bool(b) => *b,
            other => panic!("expected a boolean, got {other:?}"),
        }
    }
    fn words(&self) -> Vec<u16> {
        match self {
            Json::Nums(v) => v.iter().map(|x| *x as u16).collect(),
            other => panic!("expected an array, got {other:?}"),
        }
    }
}

/// Parse a flat JSON object whose values are numbers, booleans or arrays of
/// numbers (what `json.dumps` prints for the scripts' output).
fn parse_flat_json(text: &str) -> Result<HashMap<String, Json>, String> {
    let body = text.trim().strip_prefix('{').and_then(|t| t.strip_suffix('}')).ok_or("not an object")?;
    let mut out = HashMap::new();
    let mut rest = body.trim();
    while !rest.is_empty() {
        let after_quote = rest.strip_prefix('"').ok_or_else(|| format!("expected a key at {rest:?}"))?;
        let end = after_quote.find('"').ok_or("unterminated key")?;
        let key = &after_quote[..end];
        rest = after_quote[end + 1..].trim_start().strip_prefix(':').ok_or("expected ':'")?.trim_start();
        let (value, tail) = if let Some(list) = rest.strip_prefix('[') {
            let end = list.find(']').ok_or("unterminated array")?;
            let items = list[..end].split(',').map(str::trim).filter(|s| !s.is_empty());
            let nums = items.map(|s| s.parse::<f64>().map_err(|e| format!("{s:?}: {e}"))).collect::<Result<_, _>>()?;
            (Json::Nums(nums), &list[end + 1..])
        } else {
            let end = rest.find(',').unwrap_or(rest.len());
            let v = rest[..end].trim();
            let value = match v {
                "true" => Json::Bool(true),
                "false" => Json::Bool(false),
                _ => Json::Num(v.parse().map_err(|e| format!("{v:?}: {e}"))?),
            };
            (value, &rest[end..])
        };
        out.insert(key.to_string(), value);
        rest = tail.trim_start();
        rest = rest.strip_prefix(',').unwrap_or(rest).trim_start();
    }
    Ok(out)
}

/// A child process killed (and reaped) when the test ends, however it ends.
struct Script(Child);

impl Drop for Script {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The next stdout line of a script, read off the runtime's threads, with a deadline.
async fn next_line(lines: Lines<BufReader<ChildStdout>>) -> (String, Lines<BufReader<ChildStdout>>) {
    let read = tokio::task::spawn_blocking(move || {
        let mut lines = lines;
        let line = lines.next();
        (line, lines)
    });
    let (line, lines) = tokio::time::timeout(SCRIPT_LIMIT, read).await.expect("the script answers").expect("reader");
    let line = line.expect("the script printed a line").expect("readable stdout");
    (line, lines)
}

#[tokio::test]
async fn our_driver_against_a_pymodbus_server() {
    if let Some(why) = pymodbus_missing() {
        println!("skipped: {why}");
        return;
    }
    // Status 53 = bits 0 (moving), 2 (fault), 4 (upper limit), 5 (correction
    // applied); fault code 0x8611 = 34321.
    let child = Command::new("python3")
        .arg(SERVER_SCRIPT)
        .args(["--actual-deg", "-123.45678", "--status", "53", "--fault-code", "34321"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("start the pymodbus server");
    let mut script = Script(child);
    let stdout = script.0.stdout.take().expect("stdout");
    let (line, lines) = next_line(BufReader::new(stdout).lines()).await;
    let port = parse_flat_json(&line).expect("the port line")["port"].num() as u16;
    let addr = format!("127.0.0.1:{port}");

    let mut drv = ModbusPositioner::connect_tcp(addr.clone(), RegisterMap::default(), TIMEOUTS).await.expect("connect");
    let r = drv.readout().await.unwrap();
    assert!((r + 123.45678).abs() < 1e-9, "readout {r}");
    // What pymodbus's server says it is, read as our driver reads it (0x2B / 0x0E, regular, stream).
    assert_eq!(
        drv.identification().await.unwrap().as_deref(),
        Some("vendor pymodbus interop, product code PM-1, revision 3.11, product interop server")
    );
    let s = drv.status().await.unwrap();
    assert!(s.moving && !s.in_position && s.correction_enabled, "{s:?}");
    assert_eq!(s.limit, Some(Limit::Upper));
    let fault = s.fault.expect("fault bit");
    assert_eq!(fault.code, 0x8611);
    assert!(fault.text.contains("following error"), "{fault:?}");
    drv.move_to(45.12345).await.unwrap();
    drv.set_velocity(7.5).await.unwrap();

    // pymodbus's own exception for an address outside its blocks.
    let far = RegisterMap { actual_position: Location::input(50), ..RegisterMap::default() };
    let mut other = ModbusPositioner::connect_tcp(addr, far, TIMEOUTS).await.expect("connect");
    let e = other.readout().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Usage, Some(2)), "{e}");

    // The table chunks are ordinary write-multiple requests pymodbus stores;
    // it computes no checksum (its input register 4 stays 0), so the driver
    // refuses to send the load command.
    let rows: Vec<f64> = (0..100).map(|i| f64::from(i) * 0.001).collect();
    let e = drv.load_correction_table(&CorrectionTable::new(rows).unwrap()).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Garbled, "{e}");
    assert!(e.message.contains("checksum 0x0000"), "{e}");

    drop(script.0.stdin.take());
    let (line, _) = next_line(lines).await;
    let holding = parse_flat_json(&line).expect("the holding line")["holding"].words();
    // 45.12345 deg = 4512345 counts = 0x0044DA59; 7.5 deg/s = 750000 counts/s
    // = 0x000B71B0; command 1 = move (the load command was never sent).
    assert_eq!(&holding[0..5], &[0x0044, 0xDA59, 0x000B, 0x71B0, 1]);
    // Table header: 100 rows, 1 column. The window holds the last chunk:
    // column 0 from row 60, whose value 0.06 is float32 0x3D75C28F.
    assert_eq!(&holding[10..12], &[100, 1]);
    assert_eq!(&holding[100..104], &[0, 60, 0x3D75, 0xC28F]);
}

#[tokio::test]
async fn a_pymodbus_client_against_our_simulator() {
    if let Some(why) = pymodbus_missing() {
        println!("skipped: {why}");
        return;
    }
    let mut cfg = super::tests::config();
    cfg.accel_deg_s2 = 1000.0;
    cfg.settle = Duration::from_millis(20);
    cfg.link_latency = Duration::from_millis(10);
    let sim = SimPositioner::new(cfg, Arc::new(VirtualClock::new()));
    let device = ModbusDevice::new(sim, RegisterMap::default()).unwrap();
    let server = device.spawn_tcp(survey_sims::faults::Faults::new()).await.unwrap();
    let port = server.addr.port().to_string();
    let run = tokio::task::spawn_blocking(move || {
        Command::new("python3").arg(CLIENT_SCRIPT).args([port.as_str(), "12.34567", "100", "200"]).output()
    });
    let out =
        tokio::time::timeout(SCRIPT_LIMIT, run).await.expect("the client finishes").unwrap().expect("python3 runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "client failed: {stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    let got = parse_flat_json(stdout.lines().last().unwrap_or("")).expect("one JSON line");
    assert_eq!(got["first_status"].num() as u16 & 0b11, 0b01, "moving right after the command: {got:?}");
    assert_eq!(got["final_status"].num() as u16 & 0b111, 0b010, "in position, no fault: {got:?}");
    assert!(got["polls"].num() < 2000.0, "{got:?}");
    assert_eq!(got["actual_counts"].num(), 1_234_567.0);
    assert_eq!(got["fault_code"].num(), 0.0);
    assert!(got["bad_move_is_error"].bool() && got["unmapped_is_error"].bool(), "{got:?}");
    assert_eq!(got["bad_move_exception"].num(), 3.0, "a target beyond the travel is illegal data value");
    assert_eq!(got["unmapped_exception"].num(), 2.0, "an unmapped register is illegal data address");
    // The identification as pymodbus reads it: objects 0, 1, 2, 4, 5, saying it is simulated.
    assert_eq!(got["identity_objects"].words(), [0, 1, 2, 4, 5], "{got:?}");
    assert!(got["identity_simulated"].bool() && got["identity_vendor_sims"].bool(), "{got:?}");
    assert_eq!(got["one_object"].words(), [4], "individual access: one object");
    assert_eq!(got["unknown_object_exception"].num(), 2.0, "an unknown object is illegal data address");
    let (moves, raw) = device.with_positioner(|p| (p.moves(), p.raw_readout_deg())).await;
    assert_eq!(moves, 1, "the refused move did not start");
    assert_eq!(raw, 12.34567);
    assert_eq!(device.holding_register(4).await, 1);
}

/// The same pymodbus client in Modbus RTU over a pty: our simulator's RTU
/// framing (CRC, timing-free framing by length) read by an implementation no
/// one here wrote.
#[tokio::test]
async fn a_pymodbus_rtu_client_against_our_simulator_on_a_pty() {
    if let Some(why) = pymodbus_missing() {
        println!("skipped: {why}");
        return;
    }
    let mut cfg = super::tests::config();
    cfg.accel_deg_s2 = 1000.0;
    cfg.settle = Duration::from_millis(20);
    cfg.link_latency = Duration::from_millis(10);
    let sim = SimPositioner::new(cfg, Arc::new(VirtualClock::new()));
    let device = ModbusDevice::new(sim, RegisterMap::default()).unwrap();
    let (master, slave) = crate::elcomat_server::pty_pair().unwrap();
    let path = tokio_serial::SerialPort::name(&slave).unwrap();
    let serving = device.clone();
    let server = tokio::spawn(async move { serving.serve_rtu(master, survey_sims::faults::Faults::new()).await });
    let target = format!("rtu:{path}");
    let run = tokio::task::spawn_blocking(move || {
        Command::new("python3").arg(CLIENT_SCRIPT).args([target.as_str(), "-7.25", "100", "200"]).output()
    });
    let out =
        tokio::time::timeout(SCRIPT_LIMIT, run).await.expect("the client finishes").unwrap().expect("python3 runs");
    drop(slave);
    server.abort();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "client failed: {stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    let got = parse_flat_json(stdout.lines().last().unwrap_or("")).expect("one JSON line");
    assert_eq!(got["final_status"].num() as u16 & 0b111, 0b010, "in position, no fault: {got:?}");
    assert_eq!(got["actual_counts"].num(), -725_000.0);
    assert_eq!(got["bad_move_exception"].num(), 3.0, "illegal data value over RTU too: {got:?}");
    assert_eq!(got["unmapped_exception"].num(), 2.0, "illegal data address over RTU too: {got:?}");
}

#[test]
fn the_flat_json_reader() {
    let j = parse_flat_json(r#"{"port": 4242, "x": -1.5e-3, "ok": true, "no": false, "h": [1, 2, 65535], "e": []}"#)
        .unwrap();
    assert_eq!(j["port"], Json::Num(4242.0));
    assert_eq!(j["x"], Json::Num(-1.5e-3));
    assert!(j["ok"].bool() && !j["no"].bool());
    assert_eq!(j["h"].words(), vec![1, 2, 65535]);
    assert_eq!(j["e"], Json::Nums(vec![]));
    assert!(parse_flat_json("[1]").is_err());
    assert!(parse_flat_json(r#"{"a": x}"#).is_err());
}
