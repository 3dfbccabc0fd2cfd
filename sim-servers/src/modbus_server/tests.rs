//! The Modbus driver against the simulated controller over real TCP (loopback)
//! and real RTU (a pty pair).

use super::*;
use crate::elcomat_server::pty_pair;
use crate::relay::{Ended, Framing, Relay, pty_relay, tcp_relay};
use std::time::{Duration, Instant};
use survey_drivers::VirtualClock;
use survey_drivers::clock::Clock;
use survey_drivers::error::ErrorKind;
use survey_drivers::traits::DeviceFault;
use survey_drivers::traits::{Positioner, PositionerStatus};
use survey_positioner_drivers::modbus::{Location, ModbusPositioner, ModbusTimeouts, PositionEncoding, WordOrder};
use survey_processing::Direction;
use survey_processing::table::CorrectionTable;
use survey_sims::positioner::{FAULT_FOLLOWING_ERROR, PositionerConfig, PositionerFaults};
use survey_sims::presets::{Preset, without_noise};
use tokio_modbus::client::{Reader as _, Writer as _};

/// Short deadlines: a dropped reply costs 200 ms.
const TIMEOUTS: ModbusTimeouts =
    ModbusTimeouts { connect: Duration::from_secs(2), request: Duration::from_millis(200) };
/// Longer than any move of these tests, clock time.
const SETTLE: Duration = Duration::from_secs(60);

/// Noise-free fig8 positioner with a travel of +/-170 degrees.
pub(super) fn config() -> PositionerConfig {
    let mut cfg = PositionerConfig::new(without_noise(&Preset::by_name("fig8").expect("fig8 preset").model));
    cfg.travel = Some((-170.0, 170.0));
    cfg
}

/// The controller behind a relay (its link faults); the driver talks to the relay.
struct Rig {
    clock: VirtualClock,
    device: ModbusDevice,
    /// Link faults (the relay's) and device faults (the controller's).
    faults: Faults,
    map: RegisterMap,
    drv: ModbusPositioner,
    /// The relay's address, over TCP.
    tcp: Option<SocketAddr>,
    rtu: Option<JoinHandle<RtuEnd>>,
    /// The serial line's path, over RTU.
    path: Option<String>,
    /// The serial relay's end.
    line: Option<JoinHandle<Ended>>,
    _tasks: Tasks,
}

/// Tasks aborted on drop.
struct Tasks(Vec<JoinHandle<()>>);

impl Drop for Tasks {
    fn drop(&mut self) {
        for t in &self.0 {
            t.abort();
        }
    }
}

/// The device fault "answer with exception `code`".
fn exception(code: ExceptionCode) -> Fault {
    Fault::Refuse(Some(DeviceFault { code: i64::from(u8::from(code)), text: String::new() }))
}

fn device(cfg: PositionerConfig, map: &RegisterMap) -> (VirtualClock, ModbusDevice) {
    let clock = VirtualClock::new();
    let sim = SimPositioner::new(cfg, Arc::new(clock.clone()));
    (clock, ModbusDevice::new(sim, map.clone()).expect("valid map"))
}

async fn tcp_rig(cfg: PositionerConfig, map: RegisterMap) -> Rig {
    let (clock, device) = device(cfg, &map);
    let faults = Faults::new();
    let (listener, addr, relay) = tcp_relay(Relay::armed(faults.clone(), Framing::ModbusTcp)).await;
    let (d, f) = (device.clone(), faults.clone());
    let server = tokio::spawn(async move {
        let _ = d.serve_tcp(listener, f).await;
    });
    let drv = ModbusPositioner::connect_tcp(addr, map.clone(), TIMEOUTS).await.expect("connect");
    Rig {
        clock,
        device,
        faults,
        map,
        drv,
        tcp: Some(addr),
        rtu: None,
        path: None,
        line: None,
        _tasks: Tasks(vec![server, relay]),
    }
}

async fn rtu_rig(cfg: PositionerConfig, map: RegisterMap) -> Rig {
    let (clock, device) = device(cfg, &map);
    let faults = Faults::new();
    let (slave, master, line) = pty_relay(Relay::armed(faults.clone(), Framing::ModbusRtu));
    let path = tokio_serial::SerialPort::name(&slave);
    let (d, f) = (device.clone(), faults.clone());
    let rtu = tokio::spawn(async move { d.serve_rtu(master, f).await });
    let drv = ModbusPositioner::attach_rtu(slave, map.clone(), TIMEOUTS).expect("attach").named("rtu-test");
    let line = Some(line);
    Rig { clock, device, faults, map, drv, tcp: None, rtu: Some(rtu), path, line, _tasks: Tasks(Vec::new()) }
}

impl Rig {
    /// A new TCP session (after a link fault closed the old one).
    async fn reconnect(&mut self) {
        let addr = self.tcp.expect("a TCP rig");
        self.drv = ModbusPositioner::connect_tcp(addr, self.map.clone(), TIMEOUTS).await.expect("reconnect");
    }

    /// A new driver on the RTU line (after a link fault closed the old
    /// one), as the reconnect layer opens it: by its path.
    fn reconnect_rtu(&mut self) {
        let path = self.path.clone().expect("an RTU rig");
        let port = tokio_serial::SerialPortBuilderExt::open_native_async(tokio_serial::new(&path, 115_200))
            .expect("the line opens again");
        self.drv = ModbusPositioner::attach_rtu(port, self.map.clone(), TIMEOUTS).expect("attach");
    }

    /// Let any move end and settle, then read the status.
    async fn settled(&mut self) -> PositionerStatus {
        self.clock.advance(SETTLE);
        self.drv.status().await.expect("status")
    }

    async fn actual_deg(&self) -> f64 {
        let now = self.clock.now();
        self.device.with_positioner(|p| p.truth().actual_deg(now)).await
    }
}

/// Move, status, readout, velocity and stop, checked against the sim and the
/// holding registers. `tol`: the encoding's resolution.
async fn full_cycle(rig: &mut Rig, tol: f64) {
    let s = rig.drv.status().await.unwrap();
    assert!(s.in_position && !s.moving && s.fault.is_none() && s.limit.is_none() && !s.correction_enabled, "{s:?}");
    let target = 45.12345;
    rig.drv.move_to(target).await.unwrap();
    let s = rig.drv.status().await.unwrap();
    assert!(s.moving && !s.in_position, "{s:?}");
    let mid = rig.drv.readout().await.unwrap();
    assert!((0.0..target).contains(&mid), "readout during the move {mid}");
    let s = rig.settled().await;
    assert!(s.in_position && !s.moving, "{s:?}");
    let r = rig.drv.readout().await.unwrap();
    assert!((r - target).abs() <= tol, "readout {r} vs target {target}");
    let (moves, raw) = rig.device.with_positioner(|p| (p.moves(), p.raw_readout_deg())).await;
    assert_eq!(moves, 1);
    assert!((raw - target).abs() <= tol, "the sim was commanded {raw}");
    let actual = rig.actual_deg().await;
    assert!((r - actual).abs() > 1e-4 && (r - actual).abs() < 0.1, "fig8 error {}", r - actual);
    let m = rig.map.clone();
    let cp = [
        rig.device.holding_register(m.command_position).await,
        rig.device.holding_register(m.command_position + 1).await,
    ];
    assert_eq!(cp, m.encode_position(target).unwrap());
    assert_eq!(rig.device.holding_register(m.command).await, m.command_codes.move_absolute);

    // Half the default velocity: a 10 degree move takes 10/5 + 5/20 = 2.25 s
    // (1.5 s at 10 deg/s), so it is still running at 1.9 s.
    rig.drv.set_velocity(5.0).await.unwrap();
    let v = [rig.device.holding_register(m.velocity).await, rig.device.holding_register(m.velocity + 1).await];
    assert_eq!(v, m.encode_velocity(5.0).unwrap());
    rig.drv.move_to(target - 10.0).await.unwrap();
    rig.clock.advance(Duration::from_millis(1900));
    assert!(rig.drv.status().await.unwrap().moving, "at 5 deg/s the move takes 2.25 s");
    rig.drv.stop().await.unwrap();
    assert_eq!(rig.device.holding_register(m.command).await, m.command_codes.stop);
    let stopped = rig.drv.readout().await.unwrap();
    assert!(stopped < target - 8.0 && stopped > target - 10.0, "stopped at {stopped}");
    let s = rig.settled().await;
    assert!(!s.moving && s.in_position, "{s:?}");
    assert_eq!(rig.drv.readout().await.unwrap(), stopped);
}

#[tokio::test]
async fn full_cycle_over_tcp_with_the_default_map() {
    let mut rig = tcp_rig(config(), RegisterMap::default()).await;
    full_cycle(&mut rig, 0.5e-5).await;
}

#[tokio::test]
async fn full_cycle_over_tcp_with_float32_low_word_first_in_holding_registers() {
    let map = RegisterMap {
        unit_id: 7,
        position_encoding: PositionEncoding::Float32,
        word_order: WordOrder::LowFirst,
        actual_position: Location::holding(20),
        status: Location::holding(22),
        fault_code: Location::holding(23),
        ..RegisterMap::default()
    };
    let mut rig = tcp_rig(config(), map).await;
    full_cycle(&mut rig, 45.2 * f64::from(f32::EPSILON)).await;
}

#[tokio::test]
async fn full_cycle_over_rtu_on_a_pty() {
    let mut rig = rtu_rig(config(), RegisterMap::default()).await;
    full_cycle(&mut rig, 0.5e-5).await;
    drop(rig.drv);
    let end = rig.rtu.take().unwrap().await.unwrap();
    assert!(matches!(end, RtuEnd::LinkError(_) | RtuEnd::PeerClosed), "{end:?}");
}

#[tokio::test]
async fn refused_values_are_usage_errors_with_the_exception_code() {
    let mut rig = tcp_rig(config(), RegisterMap::default()).await;
    for (what, e) in [
        ("target beyond the travel", rig.drv.move_to(200.0).await.unwrap_err()),
        ("zero velocity", rig.drv.set_velocity(0.0).await.unwrap_err()),
        ("negative velocity", rig.drv.set_velocity(-2.0).await.unwrap_err()),
        ("correction without a table", rig.drv.enable_correction(true).await.unwrap_err()),
    ] {
        assert_eq!((e.kind, e.code), (ErrorKind::Usage, Some(3)), "{what}: {e}");
        assert!(e.message.contains("illegal data value"), "{e}");
    }
    assert!(rig.drv.is_connected(), "exceptions leave the session open");
    rig.drv.move_to(-20.0).await.unwrap();
    assert!(rig.settled().await.in_position);
    assert!((rig.drv.readout().await.unwrap() + 20.0).abs() < 1e-9);
}

#[tokio::test]
async fn a_drive_fault_is_reported_refuses_moves_and_clears() {
    let mut cfg = config();
    cfg.faults = PositionerFaults { fault_on_move: Some(1), ..PositionerFaults::default() };
    let mut rig = tcp_rig(cfg, RegisterMap::default()).await;
    rig.drv.move_to(90.0).await.unwrap();
    let s = rig.settled().await;
    let fault = s.fault.clone().expect("the drive tripped");
    assert_eq!(fault.code, FAULT_FOLLOWING_ERROR);
    assert!(fault.text.contains("following error"), "{fault:?}");
    assert!(!s.in_position && !s.moving, "{s:?}");
    let e = rig.drv.move_to(10.0).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(4)), "{e}");
    rig.drv.clear_fault().await.unwrap();
    assert_eq!(rig.drv.status().await.unwrap().fault, None);
    rig.drv.move_to(10.0).await.unwrap();
    let s = rig.settled().await;
    assert!(s.in_position && s.fault.is_none(), "{s:?}");
}

fn f32_table(t: &CorrectionTable) -> CorrectionTable {
    let r = |c: &Vec<f64>| c.iter().map(|v| f64::from(*v as f32)).collect::<Vec<_>>();
    match &t.reverse {
        Some(rev) => CorrectionTable::directional(r(&t.forward), r(rev)).unwrap(),
        None => CorrectionTable::new(r(&t.forward)).unwrap(),
    }
}

fn sine_table(n: usize, directional: bool) -> CorrectionTable {
    let f: Vec<f64> = (0..n).map(|i| 0.02 * (3.0 * (i as f64 * 360.0 / n as f64).to_radians()).sin() + 0.005).collect();
    if directional {
        CorrectionTable::directional(f.clone(), f.iter().map(|v| v - 0.004).collect()).unwrap()
    } else {
        CorrectionTable::new(f).unwrap()
    }
}

/// The table loaded over the wire moves the true axis exactly as the same
/// table loaded into a SimPositioner directly, and by about the table's error
/// compared with no correction.
async fn correction_like_the_sims_own(rig: &mut Rig, table: CorrectionTable) {
    let e = rig.drv.enable_correction(true).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Usage, Some(3)), "no table yet: {e}");
    rig.drv.load_correction_table(&table).await.unwrap();
    assert!(!rig.drv.status().await.unwrap().correction_enabled, "loaded, not applied");
    assert_eq!(rig.drv.correction_state().await.unwrap(), Some(false), "read from the status register");
    rig.drv.enable_correction(true).await.unwrap();
    assert!(rig.drv.status().await.unwrap().correction_enabled);
    assert_eq!(rig.drv.correction_state().await.unwrap(), Some(true));

    let sent = f32_table(&table);
    let (clock_b, clock_c) = (VirtualClock::new(), VirtualClock::new());
    let mut b = SimPositioner::new(config(), Arc::new(clock_b.clone()));
    let mut c = SimPositioner::new(config(), Arc::new(clock_c.clone()));
    b.load_correction_table(&sent).await.unwrap();
    b.enable_correction(true).await.unwrap();
    let mut last = 0.0;
    for target in [30.5, 100.25, 50.75] {
        rig.drv.move_to(target).await.unwrap();
        b.move_to(target).await.unwrap();
        c.move_to(target).await.unwrap();
        assert!(rig.settled().await.in_position);
        clock_b.advance(SETTLE);
        clock_c.advance(SETTLE);
        assert!(
            (rig.drv.readout().await.unwrap() - target).abs() < 1e-9,
            "the servo holds the corrected readout at the target"
        );
        let a = rig.actual_deg().await;
        let want = b.truth().actual_deg(clock_b.now());
        assert!((a - want).abs() < 1e-9, "at {target}: wire {a} vs direct {want}");
        let dir = if target > last { Direction::Forward } else { Direction::Reverse };
        last = target;
        let shift = a - c.truth().actual_deg(clock_c.now());
        let err = sent.error_at(target, dir);
        assert!(err.abs() > 5e-3 && (shift - err).abs() < 1e-4, "at {target} {dir:?}: shift {shift} vs table {err}");
    }
    rig.drv.enable_correction(false).await.unwrap();
    assert!(!rig.drv.status().await.unwrap().correction_enabled);
    assert_eq!(rig.drv.correction_state().await.unwrap(), Some(false));
}

#[tokio::test]
async fn a_directional_table_over_tcp_corrects_like_the_sim() {
    let mut rig = tcp_rig(config(), RegisterMap::default()).await;
    correction_like_the_sims_own(&mut rig, sine_table(1000, true)).await;
}

#[tokio::test]
async fn a_single_column_table_over_rtu_corrects_like_the_sim() {
    let map = RegisterMap {
        table: survey_positioner_drivers::modbus::TableBlock { chunk_rows: 17, ..Default::default() },
        ..Default::default()
    };
    let mut rig = rtu_rig(config(), map).await;
    correction_like_the_sims_own(&mut rig, sine_table(360, false)).await;
}

#[tokio::test]
async fn a_lost_chunk_is_caught_by_the_checksum() {
    let mut rig = tcp_rig(config(), RegisterMap::default()).await;
    // Write 1 is the header, write 2 the first chunk.
    rig.faults.arm(Fault::LoseWrite(2));
    let e = rig.drv.load_correction_table(&sine_table(200, false)).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Garbled, "{e}");
    assert!(e.message.contains("checksum"), "{e}");
    rig.reconnect().await;
    let e = rig.drv.enable_correction(true).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Usage, "the table was never loaded: {e}");
    rig.drv.load_correction_table(&sine_table(200, false)).await.unwrap();
    rig.drv.enable_correction(true).await.unwrap();
}

#[tokio::test]
async fn tcp_a_dropped_reply_times_out_and_a_new_session_works() {
    let mut rig = tcp_rig(config(), RegisterMap::default()).await;
    rig.faults.arm(Fault::Drop);
    let t0 = Instant::now();
    let e = rig.drv.readout().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
    assert!(t0.elapsed() >= TIMEOUTS.request);
    assert!(!rig.drv.is_connected());
    let e = rig.drv.status().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    rig.reconnect().await;
    assert_eq!(rig.drv.readout().await.unwrap(), 0.0);
}

#[tokio::test]
async fn tcp_injected_exceptions_keep_their_codes() {
    let mut rig = tcp_rig(config(), RegisterMap::default()).await;
    rig.faults.arm(exception(ExceptionCode::ServerDeviceBusy));
    rig.faults.arm(exception(ExceptionCode::IllegalFunction));
    let e = rig.drv.stop().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(6)), "{e}");
    let e = rig.drv.status().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Usage, Some(1)), "{e}");
    assert!(rig.drv.is_connected());
    rig.drv.stop().await.unwrap();
    // A gateway that cannot reach the device is a link fault.
    rig.faults.arm(exception(ExceptionCode::GatewayTargetDevice));
    let e = rig.drv.readout().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Timeout, Some(11)), "{e}");
    assert!(!rig.drv.is_connected());
}

#[tokio::test]
async fn tcp_a_connection_closed_mid_reply_is_disconnected() {
    let mut rig = tcp_rig(config(), RegisterMap::default()).await;
    rig.drv.readout().await.unwrap();
    rig.faults.arm(Fault::Disconnect);
    let e = rig.drv.status().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    assert_eq!(rig.drv.readout().await.unwrap_err().kind, ErrorKind::Disconnected, "the session is closed");
    // The listener accepts a new connection. A write whose reply is cut was
    // executed (the commanded position is stored), but the move command was
    // never sent.
    rig.reconnect().await;
    rig.faults.arm(Fault::Disconnect);
    let e = rig.drv.move_to(1.0).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    assert_eq!(rig.device.holding_register(1).await, rig.map.encode_position(1.0).unwrap()[1]);
    assert_eq!(rig.device.with_positioner(|p| p.moves()).await, 0);
    assert_eq!(rig.device.requests(), 3);
    rig.reconnect().await;
    rig.drv.readout().await.unwrap();
}

#[tokio::test]
async fn tcp_a_reply_of_another_function_is_garbled() {
    let mut rig = tcp_rig(config(), RegisterMap::default()).await;
    rig.faults.arm(garbled(false));
    let e = rig.drv.readout().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Garbled, "{e}");
    assert!(!rig.drv.is_connected());
}

#[tokio::test]
async fn the_positioners_own_link_faults_reach_the_wire() {
    let mut cfg = config();
    // Call 2 times out, call 4 disconnects (calls of the simulated positioner).
    cfg.faults =
        PositionerFaults { timeout_on_call: Some(2), disconnect_on_call: Some(4), ..PositionerFaults::default() };
    let mut rig = tcp_rig(cfg, RegisterMap::default()).await;
    rig.drv.readout().await.unwrap();
    let e = rig.drv.readout().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
    rig.reconnect().await;
    rig.drv.status().await.unwrap();
    let e = rig.drv.status().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    rig.reconnect().await;
    rig.drv.status().await.unwrap();
}

#[tokio::test]
async fn rtu_a_dropped_reply_times_out() {
    let mut rig = rtu_rig(config(), RegisterMap::default()).await;
    rig.faults.arm(Fault::Drop);
    let e = rig.drv.readout().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
    assert_eq!(rig.drv.readout().await.unwrap_err().kind, ErrorKind::Disconnected);
}

#[tokio::test]
async fn rtu_exceptions_then_replies_that_answer_no_request() {
    let mut rig = rtu_rig(config(), RegisterMap::default()).await;
    rig.faults.arm(exception(ExceptionCode::ServerDeviceFailure));
    let e = rig.drv.readout().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(4)), "{e}");
    let e = rig.drv.move_to(500.0).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Usage, Some(3)), "{e}");
    assert_eq!(rig.drv.readout().await.unwrap(), 0.0);
    // A reply with a byte changed fails its CRC: tokio-modbus's framing
    // drops it byte by byte, never taking it, and the request times out.
    let flip = |frame: &[u8]| Some([&frame[..3], &[frame[3] ^ 0x5a], &frame[4..]].concat());
    rig.faults.arm(Fault::Garble(survey_sims::faults::Garble::edit("byte 3 flipped", flip)));
    let e = rig.drv.readout().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
    // A well-formed reply of another function answers no request of ours
    // (RTU has no transaction id: it could be a late reply): it is
    // discarded, never taken (it was once taken and failed as garbled), and
    // the request times out.
    rig.reconnect_rtu();
    rig.faults.arm(garbled(true));
    let e = rig.drv.set_velocity(3.0).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
    rig.reconnect_rtu();
    assert_eq!(rig.drv.readout().await.unwrap(), 0.0);
}

/// A reply held past the request's deadline on RTU (a stall) arrives while
/// the driver drains the line after the timeout: it is discarded, and the
/// next request on the line (a read of the same length, whose reply the
/// late one could pass for) gets its own reply.
#[tokio::test]
async fn rtu_a_late_reply_is_drained_not_taken_for_the_next_request() {
    let mut rig = rtu_rig(config(), RegisterMap::default()).await;
    assert_eq!(rig.drv.readout().await.unwrap(), 0.0);
    // Due at 250 ms: after the 200 ms deadline, within the 100 ms drain.
    rig.faults.arm(Fault::Stall(Duration::from_millis(250)));
    let t0 = Instant::now();
    let e = rig.drv.readout().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
    assert!(t0.elapsed() >= TIMEOUTS.request + TIMEOUTS.late_window(), "drained: {:?}", t0.elapsed());
    rig.reconnect_rtu();
    // Status and fault code: 2 registers, as the position's late reply.
    let s = rig.drv.status().await.unwrap();
    assert!(s.in_position && s.fault.is_none(), "{s:?}");
    assert_eq!(rig.drv.readout().await.unwrap(), 0.0);
}

/// A late reply of another request that comes after the drain, in the
/// middle of the next request, does not answer it: discarded by its
/// function code, and the next request's own reply is taken.
#[tokio::test]
async fn rtu_a_late_reply_of_another_function_is_discarded() {
    let mut rig = rtu_rig(config(), RegisterMap::default()).await;
    // Held 450 ms: past the 200 ms deadline and the 100 ms drain.
    rig.faults.arm(Fault::Stall(Duration::from_millis(450)));
    let e = rig.drv.set_velocity(3.0).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
    rig.reconnect_rtu();
    assert_eq!(rig.drv.readout().await.unwrap(), 0.0);
    let s = rig.drv.status().await.unwrap();
    assert!(s.in_position && s.fault.is_none(), "{s:?}");
}

#[tokio::test]
async fn rtu_a_port_closed_mid_transfer_is_disconnected() {
    let mut rig = rtu_rig(config(), RegisterMap::default()).await;
    rig.drv.readout().await.unwrap();
    rig.faults.arm(Fault::Disconnect);
    let e = rig.drv.status().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    assert_eq!(rig.line.take().unwrap().await.unwrap(), Ended::Disconnect, "the relay cut the line");
}

#[tokio::test]
async fn requests_to_another_unit_get_no_reply() {
    let mut rig = tcp_rig(config(), RegisterMap::default()).await;
    let other = RegisterMap { unit_id: 9, ..RegisterMap::default() };
    let addr = rig.tcp.unwrap();
    let mut drv = ModbusPositioner::connect_tcp(addr, other, TIMEOUTS).await.unwrap();
    assert_eq!(drv.readout().await.unwrap_err().kind, ErrorKind::Timeout);
    assert_eq!(rig.device.requests(), 0);
    rig.drv.readout().await.unwrap();
    assert_eq!(rig.device.requests(), 1);
}

#[tokio::test]
async fn connect_rtu_by_path() {
    let map = RegisterMap { unit_id: 17, ..RegisterMap::default() };
    let (_clock, device) = device(config(), &map);
    let (master, slave) = pty_pair().unwrap();
    let path = tokio_serial::SerialPort::name(&slave).expect("the slave pty has a path");
    // The pair's slave holds the port's exclusive lock: close it, open the
    // path, and only then start serving (the master reads EIO while no slave
    // is open).
    drop(slave);
    let mut drv = ModbusPositioner::connect_rtu(&path, 115_200, 17, RegisterMap::default(), TIMEOUTS).await.unwrap();
    tokio::spawn(async move { device.serve_rtu(master, Faults::new()).await });
    assert_eq!(drv.name(), format!("modbus-rtu {path}#17"));
    assert_eq!(drv.map().unit_id, 17);
    drv.move_to(2.5).await.unwrap();
    assert!(drv.status().await.unwrap().moving);
}

/// The register semantics, with a plain tokio-modbus client.
#[tokio::test]
async fn register_level_refusals_and_multi_item_writes() {
    use ExceptionCode::*;
    let map = RegisterMap::default();
    let (_clock, device) = device(config(), &map);
    let server = device.spawn_tcp(Faults::new()).await.unwrap();
    let mut ctx = tokio_modbus::client::tcp::connect_slave(server.addr, tokio_modbus::Slave(1)).await.unwrap();
    assert_eq!(ctx.write_single_register(0, 5).await.unwrap(), Err(IllegalDataAddress), "half a position");
    assert_eq!(ctx.write_multiple_registers(1, &[1, 2]).await.unwrap(), Err(IllegalDataAddress), "two halves");
    assert_eq!(ctx.read_holding_registers(5, 1).await.unwrap(), Err(IllegalDataAddress), "unmapped");
    assert_eq!(ctx.read_input_registers(0, 6).await.unwrap(), Err(IllegalDataAddress), "runs past the map");
    assert_eq!(ctx.write_single_register(4, 99).await.unwrap(), Err(IllegalDataValue), "unknown command");
    assert_eq!(ctx.write_multiple_registers(100, &[0, 0, 0, 0]).await.unwrap(), Err(IllegalDataValue), "no header");
    assert_eq!(ctx.write_multiple_registers(10, &[1, 1]).await.unwrap(), Err(IllegalDataValue), "1 row");
    assert_eq!(ctx.write_multiple_registers(10, &[4, 3]).await.unwrap(), Err(IllegalDataValue), "3 columns");
    assert_eq!(ctx.read_coils(0, 1).await.unwrap(), Err(IllegalFunction));
    ctx.write_multiple_registers(10, &[4, 1]).await.unwrap().unwrap();
    let one = map.encode_table_value(0.25).unwrap();
    assert_eq!(
        ctx.write_multiple_registers(100, &[1, 0, one[0], one[1]]).await.unwrap(),
        Err(IllegalDataValue),
        "column 1"
    );
    assert_eq!(
        ctx.write_multiple_registers(100, &[0, 3, 0, 0, 0, 0]).await.unwrap(),
        Err(IllegalDataValue),
        "rows 3..5 of 4"
    );
    assert_eq!(
        ctx.write_multiple_registers(101, &[0, 0, 0]).await.unwrap(),
        Err(IllegalDataAddress),
        "not at the window"
    );
    assert_eq!(ctx.write_multiple_registers(100, &[0, 0, 0x7FC0, 0]).await.unwrap(), Err(IllegalDataValue), "NaN");
    ctx.write_multiple_registers(100, &[0, 1, one[0], one[1]]).await.unwrap().unwrap();
    assert_eq!(ctx.write_single_register(4, 6).await.unwrap(), Err(IllegalDataValue), "load with rows missing");
    let ff = 0xFFFF;
    let want = survey_positioner_drivers::modbus::table_checksum(&[ff, ff, one[0], one[1], ff, ff, ff, ff]);
    assert_eq!(ctx.read_input_registers(4, 1).await.unwrap().unwrap(), vec![want]);
    // Position, velocity and the move command in one request.
    let mut words = map.encode_position(12.5).unwrap().to_vec();
    words.extend(map.encode_velocity(20.0).unwrap());
    words.push(map.command_codes.move_absolute);
    ctx.write_multiple_registers(0, &words).await.unwrap().unwrap();
    assert_eq!(device.with_positioner(|p| p.moves()).await, 1);
    assert_eq!(ctx.read_holding_registers(0, 5).await.unwrap().unwrap(), words);
    let inputs = ctx.read_input_registers(0, 5).await.unwrap().unwrap();
    assert_eq!(inputs[2] & 1, 1, "moving: {inputs:?}");
    assert_eq!(inputs[3], 0, "no fault");
}

#[tokio::test]
async fn the_controller_identifies_itself_and_one_without_the_function_has_nothing_to_say() {
    let mut rig = tcp_rig(config(), RegisterMap::default()).await;
    let id = rig.drv.identification().await.unwrap().expect("the simulator answers 0x2B / 0x0E");
    assert_eq!(
        id,
        "vendor survey-sims, product code SIM-MB-1, revision 1.0, product Modbus positioner controller \
         (simulated), model servo drive, register map of survey (simulated)"
    );
    // A device that does not serve the function (illegal function) or the object (illegal data address).
    for code in [ExceptionCode::IllegalFunction, ExceptionCode::IllegalDataAddress] {
        rig.faults.arm(exception(code));
        assert_eq!(rig.drv.identification().await.unwrap(), None);
    }
    // Any other refusal is the device's fault, said as such; a garbled reply a link fault.
    rig.faults.arm(exception(ExceptionCode::ServerDeviceBusy));
    assert_eq!(rig.drv.identification().await.unwrap_err().kind, ErrorKind::Device);
    rig.faults.arm(garbled(false));
    assert!(rig.drv.identification().await.unwrap_err().kind.is_link());
}
