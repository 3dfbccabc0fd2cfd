use super::*;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};
use survey_drivers::VirtualClock;
use survey_drivers::clock::Clock;
use survey_drivers::traits::{DeviceFault, PositionerStatus};
use survey_positioner_drivers::scpi::{Address, ScpiPositioner, ScpiTimeouts};
use survey_processing::Direction;
use survey_processing::model::Model;
use survey_sims::positioner::{PositionerConfig, PositionerFaults};
use survey_sims::presets::{Preset, without_noise};
use survey_sims::turntable::Turntable;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio::task::JoinHandle;

const TIMEOUTS: ScpiTimeouts = ScpiTimeouts {
    request: Duration::from_millis(200),
    connect: Duration::from_secs(2),
    resync_grace: Duration::from_millis(20),
};

type Wire = ScpiPositioner<TcpStream>;

fn fig8() -> Model {
    Preset::by_name("fig8").unwrap().model
}

/// A simulator on a loopback port; the server task is aborted on drop.
/// The simulator behind a relay (its link faults), both on loopback ports;
/// the tasks are aborted on drop.
struct Rig {
    clock: VirtualClock,
    truth: Turntable,
    /// Link faults (the relay's) and device faults (the controller's).
    faults: Faults,
    /// What `UNIT:POS?` answers.
    units: Arc<AtomicI64>,
    addr: SocketAddr,
    server: JoinHandle<()>,
    relay: JoinHandle<()>,
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.server.abort();
        self.relay.abort();
    }
}

/// A device fault of the controller: code and text.
fn fault(code: i64, text: &str) -> DeviceFault {
    DeviceFault { code, text: text.into() }
}

impl Rig {
    async fn new(cfg: PositionerConfig) -> Rig {
        let clock = VirtualClock::new();
        let sim = SimPositioner::new(cfg, Arc::new(clock.clone()));
        let truth = sim.truth();
        let faults = Faults::new();
        let (listener, addr, relay) =
            crate::relay::tcp_relay(crate::relay::Relay::armed(faults.clone(), crate::relay::Framing::Lines)).await;
        let controller = Controller::new(sim, faults.clone());
        let units = controller.position_units();
        let server = tokio::spawn(serve_controller(listener, controller));
        Rig { clock, truth, faults, units, addr, server, relay }
    }

    /// The driver with the commands the public record does not show
    /// enabled (`VEL:COMM`, `FAUL:CLE`, `CORR:`), which this simulator
    /// implements as the project's extension.
    async fn connect(&self) -> Wire {
        let mut p = ScpiPositioner::connect_tcp(self.addr, TIMEOUTS).await.unwrap();
        p.config_mut().unverified_commands = true;
        p
    }

    /// The driver as it talks to a real controller by default: only the
    /// commands the public record shows.
    async fn connect_verified(&self) -> Wire {
        ScpiPositioner::connect_tcp(self.addr, TIMEOUTS).await.unwrap()
    }

    fn actual(&self) -> f64 {
        self.truth.actual_deg(self.clock.now())
    }
}

/// Poll until in position or faulted, 250 ms of clock time between polls.
async fn settle(p: &mut impl Positioner, clock: &VirtualClock) -> PositionerStatus {
    for _ in 0..2_000 {
        let s = p.status().await.unwrap();
        if s.in_position || s.fault.is_some() {
            return s;
        }
        clock.advance(Duration::from_millis(250));
    }
    panic!("never settled");
}

#[tokio::test]
async fn move_poll_readout_stop_and_velocity() {
    let rig = Rig::new(PositionerConfig::new(fig8())).await;
    let mut p = rig.connect().await;
    assert!(p.name().starts_with("scpi-tcp 127.0.0.1:"), "{}", p.name());
    assert_eq!(p.identify().await.unwrap(), IDN);

    p.move_to(45.0).await.unwrap();
    assert_eq!(p.commanded_position().await.unwrap(), 45.0);
    let s = p.status().await.unwrap();
    assert!(s.moving && !s.in_position, "{s:?}");
    let s = settle(&mut p, &rig.clock).await;
    assert!(s.in_position && !s.moving && s.fault.is_none() && s.limit.is_none(), "{s:?}");
    assert_eq!(p.readout().await.unwrap(), 45.0, "readout at rest equals the target");

    // Velocity: accepted, and a move at 20 deg/s takes half the time.
    p.set_velocity(20.0).await.unwrap();
    let t0 = rig.clock.now();
    p.move_to(145.0).await.unwrap();
    settle(&mut p, &rig.clock).await;
    let took = (rig.clock.now() - t0).as_secs_f64();
    assert!(took < 100.0 / 20.0 + 2.0, "took {took} s");
    for bad in [-1.0, 0.0, 1e6] {
        let e = p.set_velocity(bad).await.unwrap_err();
        assert_eq!((e.kind, e.code), (ErrorKind::Usage, Some(-222)), "{bad}: {e}");
        assert!(e.message.contains("Data out of range"), "{e}");
    }
    let e = p.set_velocity(f64::NAN).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Usage, None));

    // Stop mid-move: the axis halts between start and target.
    p.set_velocity(10.0).await.unwrap();
    p.move_to(345.0).await.unwrap();
    rig.clock.advance(Duration::from_secs(5));
    assert!(p.status().await.unwrap().moving);
    p.stop().await.unwrap();
    let s = settle(&mut p, &rig.clock).await;
    assert!(!s.moving && s.in_position, "{s:?}");
    let r = p.readout().await.unwrap();
    assert!(r > 160.0 && r < 345.0, "stopped at {r}");
    assert!((r - rig.actual()).abs() < 0.1, "readout {r} vs actual {}", rig.actual());
    // Stopped: it stays put.
    rig.clock.advance(Duration::from_secs(10));
    assert_eq!(p.readout().await.unwrap(), r);
}

#[tokio::test]
async fn usage_errors_carry_the_controllers_code() {
    let cfg = PositionerConfig { travel: Some((-10.0, 90.0)), ..PositionerConfig::new(without_noise(&fig8())) };
    let rig = Rig::new(cfg).await;
    let mut p = rig.connect().await;
    let e = p.move_to(95.0).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Usage, Some(-222)), "{e}");
    assert!(e.message.contains("outside the travel -10..90 deg"), "{e}");
    // Nothing moved, and the commanded position is still the old one.
    assert_eq!(p.commanded_position().await.unwrap(), 0.0);
    let s = p.status().await.unwrap();
    assert!(!s.moving && s.in_position, "{s:?}");
    // Inside the travel it moves; at the end it reports the limit.
    p.move_to(90.0).await.unwrap();
    let s = settle(&mut p, &rig.clock).await;
    assert_eq!(s.limit, Some(Limit::Upper));
    // A correction table with nothing loaded: settings conflict.
    assert_eq!(p.correction_state().await.unwrap(), Some(false));
    let e = p.enable_correction(true).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Usage, Some(-221)), "{e}");
    // An axis the controller does not have (one client at a time: the
    // first one leaves).
    drop(p);
    let mut other = rig.connect().await.with_address(Address { controller: 1, axis: 2 });
    let e = other.move_to(10.0).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Usage, Some(-114)), "{e}");
}

#[tokio::test]
async fn correction_over_the_wire_moves_the_axis_as_the_simulators_own() {
    let cfg = PositionerConfig { seed: 7, ..PositionerConfig::new(fig8()) };
    let model = cfg.model.clone();
    let n = 360;
    let rows = |d| (0..n).map(|i| model.repeatable_error_deg(i as f64 * 360.0 / n as f64, d)).collect::<Vec<_>>();
    let table = CorrectionTable::directional(rows(Direction::Forward), rows(Direction::Reverse)).unwrap();

    let rig = Rig::new(cfg.clone()).await;
    let mut wire = rig.connect().await;
    let direct_clock = VirtualClock::new();
    let mut direct = SimPositioner::new(cfg, Arc::new(direct_clock.clone()));

    // Same moves on both, natively first.
    let target = 123.4;
    wire.move_to(target).await.unwrap();
    settle(&mut wire, &rig.clock).await;
    direct.move_to(target).await.unwrap();
    settle(&mut direct, &direct_clock).await;
    let native = rig.actual();
    assert_eq!(native, direct.truth().actual_deg(direct_clock.now()));

    // Load (12 chunks per column) and enable, on both.
    wire.load_correction_table(&table).await.unwrap();
    assert!(!wire.status().await.unwrap().correction_enabled, "loaded, not yet applied");
    assert_eq!(wire.correction_state().await.unwrap(), Some(false), "CORR:STAT? asked");
    wire.enable_correction(true).await.unwrap();
    assert!(wire.status().await.unwrap().correction_enabled);
    assert_eq!(wire.correction_state().await.unwrap(), Some(true));
    direct.load_correction_table(&table).await.unwrap();
    direct.enable_correction(true).await.unwrap();

    for t in [10.0, target, 300.25, 47.3] {
        wire.move_to(t).await.unwrap();
        settle(&mut wire, &rig.clock).await;
        direct.move_to(t).await.unwrap();
        settle(&mut direct, &direct_clock).await;
        assert_eq!(wire.readout().await.unwrap(), t);
        let (a, b) = (rig.actual(), direct.truth().actual_deg(direct_clock.now()));
        assert!((a - b).abs() < 1e-12, "at {t}: over the wire {a}, direct {b}");
        if t == target {
            assert!((a - native).abs() > 1e-3, "the table moved the axis: {a} vs native {native}");
            assert!((a - t).abs() < (native - t).abs(), "closer to the target: {a} vs native {native}");
        }
    }
    wire.enable_correction(false).await.unwrap();
    assert!(!wire.status().await.unwrap().correction_enabled);
    assert_eq!(wire.correction_state().await.unwrap(), Some(false));
}

/// Send raw lines, then `*IDN?`; the replies before the identification.
async fn raw(addr: SocketAddr, lines: &[&[u8]]) -> Vec<String> {
    let mut s = TcpStream::connect(addr).await.unwrap();
    let mut out = Vec::new();
    for l in lines {
        out.extend_from_slice(l);
        out.push(b'\n');
    }
    out.extend_from_slice(b"*IDN?\n");
    s.write_all(&out).await.unwrap();
    let mut d = Decoder::default();
    let mut buf = [0u8; 4096];
    let mut replies = Vec::new();
    loop {
        let n = s.read(&mut buf).await.unwrap();
        assert!(n > 0, "closed; got {replies:?}");
        d.push(&buf[..n]);
        while let Some(l) = d.next_line() {
            let l = l.unwrap();
            if l == IDN {
                return replies;
            }
            replies.push(l);
        }
    }
}

#[tokio::test]
async fn the_documented_protocol_on_a_raw_socket() {
    let rig = Rig::new(PositionerConfig::new(fig8())).await;
    let replies = raw(
        rig.addr,
        &[
            b"cont1:axis(1):pos:curr?",
            b"CONT1:AXIS(1):STAT?",
            b"CONTROLLER1:AXIS(1):POSITION:CURRENT?",
            b"SYST:ERR?",
            b"CONT1:AXIS(1):CORR:TABL 5,1.0",
            b"SYST:ERR?",
            b"CONT1:AXIS(1):CORR:TABL 0,1.0,x",
            b"SYST:ERR?",
            b"CONT1:AXIS(1):MOT:STAR 5",
            b"SYST:ERR?",
            b"CONT1:AXIS(1):POS:COMM",
            b"CONT1:AXIS(1):POS:COMM 1e999",
            b"\xffbad",
            b"CONT1:AXIS(1):CORR:TABL 0,0.5,0.25",
            b"CONT1:AXIS(1):CORR:TABL 1,0.125",
            b"CONT1:AXIS(1):CORR:TABL:POIN?",
            b"SYST:ERR?",
            b"SYST:ERR?",
            b"SYST:ERR?",
            b"SYST:ERR?",
        ],
    )
    .await;
    let expect_prefix = [
        "0",
        // Active, indexed, enabled: bits 8, 9, 5; nothing in the unused bits 13-15.
        "800",
        "-113,\"Undefined header",
        "-222,\"Data out of range;rows from 5",
        "-104,\"Data type error",
        "-108,\"Parameter not allowed",
        "2",
        "-109,\"Missing parameter",
        "-222,\"Data out of range",
        "-102,\"Syntax error;non-ASCII",
        "0,\"No error\"",
    ];
    assert_eq!(replies.len(), expect_prefix.len(), "{replies:#?}");
    for (r, e) in replies.iter().zip(expect_prefix) {
        assert!(r.starts_with(e), "{r:?} should start with {e:?}; all: {replies:#?}");
    }
    // The queue holds 16 entries; the newest becomes -350 on overflow.
    let mut lines: Vec<&[u8]> = vec![b"FOO"; 20];
    lines.extend([b"SYST:ERR?".as_slice(); 17]);
    let replies = raw(rig.addr, &lines).await;
    assert!(replies[..15].iter().all(|r| r.starts_with("-113,")), "{replies:#?}");
    assert_eq!(replies[15], "-350,\"Queue overflow\"");
    assert_eq!(replies[16], "0,\"No error\"");
}

#[tokio::test]
async fn dropped_reply_times_out_and_the_next_request_succeeds() {
    let rig = Rig::new(PositionerConfig::new(fig8())).await;
    let mut p = rig.connect().await;
    let r0 = p.readout().await.unwrap();
    rig.faults.arm(Fault::Drop);
    let t = Instant::now();
    let e = p.readout().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
    assert!(t.elapsed() >= TIMEOUTS.request, "{:?}", t.elapsed());
    assert_eq!(p.readout().await.unwrap(), r0);
    // A dropped SYST:ERR? after a command times out the command too.
    rig.faults.arm(Fault::Drop);
    assert_eq!(p.stop().await.unwrap_err().kind, ErrorKind::Timeout);
    p.stop().await.unwrap();
}

#[tokio::test]
async fn a_stale_line_is_never_taken_for_the_next_answer() {
    let rig = Rig::new(PositionerConfig::new(fig8())).await;
    let mut p = rig.connect().await;
    // "4865" would pass for a readout (and for a status word).
    rig.faults.arm(Fault::Trailing(b"4865\n".to_vec()));
    let s = p.status().await.unwrap();
    assert!(s.in_position, "{s:?}");
    assert_eq!(p.readout().await.unwrap(), 0.0);
}

#[tokio::test]
async fn garbled_reply_then_the_next_request_succeeds() {
    let rig = Rig::new(PositionerConfig::new(fig8())).await;
    let mut p = rig.connect().await;
    rig.faults.arm(garbled());
    let e = p.readout().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Garbled, "{e}");
    assert!(e.is_link());
    assert_eq!(p.readout().await.unwrap(), 0.0);
    rig.faults.arm(garbled());
    assert_eq!(p.status().await.unwrap_err().kind, ErrorKind::Garbled);
    assert!(p.status().await.unwrap().in_position);
}

#[tokio::test]
async fn closed_connection_is_disconnected_and_a_new_client_is_served() {
    let rig = Rig::new(PositionerConfig::new(fig8())).await;
    let mut p = rig.connect().await;
    p.move_to(30.0).await.unwrap();
    rig.faults.arm(Fault::Disconnect);
    let e = p.readout().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    assert!(!p.is_connected());
    // Every later call fails at once.
    let t = Instant::now();
    assert_eq!(p.status().await.unwrap_err().kind, ErrorKind::Disconnected);
    assert!(t.elapsed() < TIMEOUTS.request);
    drop(p);
    // The controller kept its state for the next client.
    let mut q = rig.connect().await;
    let s = settle(&mut q, &rig.clock).await;
    assert!(s.in_position);
    assert_eq!(q.readout().await.unwrap(), 30.0);
}

#[tokio::test]
async fn injected_device_fault_with_code_and_text() {
    let rig = Rig::new(PositionerConfig::new(fig8())).await;
    let mut p = rig.connect().await;
    let text = "PAU fault: amplifier over temperature";
    rig.faults.arm(Fault::Trip(fault(305, text)));
    let s = p.status().await.unwrap();
    let fault = s.fault.clone().expect("fault");
    assert_eq!((fault.code, fault.text.as_str()), (305, text));
    assert!(!s.in_position);
    // The queue gave the entry out once; the driver keeps it while the bit is set.
    assert_eq!(p.status().await.unwrap().fault, Some(fault.clone()));
    let e = p.move_to(10.0).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(305)), "{e}");
    assert!(e.message.contains(text), "{e}");
    p.clear_fault().await.unwrap();
    let s = p.status().await.unwrap();
    assert!(s.fault.is_none() && s.in_position, "{s:?}");
    p.move_to(10.0).await.unwrap();
    assert!(settle(&mut p, &rig.clock).await.in_position);
}

#[tokio::test]
async fn a_trip_of_the_simulated_drive_is_an_error_limit_fault() {
    let faults = PositionerFaults { fault_on_move: Some(1), ..PositionerFaults::default() };
    let rig = Rig::new(PositionerConfig { faults, ..PositionerConfig::new(fig8()) }).await;
    let mut p = rig.connect().await;
    p.move_to(90.0).await.unwrap();
    let s = settle(&mut p, &rig.clock).await;
    let fault = s.fault.expect("the drive tripped");
    assert_eq!(fault.code, FAULT_FOLLOWING_ERROR);
    assert!(fault.text.contains("following error"), "{}", fault.text);
    let e = p.move_to(0.0).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(FAULT_FOLLOWING_ERROR)), "{e}");
    p.clear_fault().await.unwrap();
    assert!(p.status().await.unwrap().fault.is_none());
    p.move_to(0.0).await.unwrap();
    assert!(settle(&mut p, &rig.clock).await.in_position);
}

#[tokio::test]
async fn a_rejected_command_carries_code_and_text() {
    let rig = Rig::new(PositionerConfig::new(fig8())).await;
    let mut p = rig.connect().await;
    rig.faults.arm(Fault::Refuse(Some(fault(-200, "Execution error;brake engaged"))));
    let e = p.move_to(20.0).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(-200)), "{e}");
    assert!(e.message.contains("brake engaged"), "{e}");
    rig.faults.arm(Fault::Refuse(Some(fault(-224, "Illegal parameter value"))));
    assert_eq!(p.stop().await.unwrap_err().kind, ErrorKind::Usage);
    p.move_to(20.0).await.unwrap();
    assert!(settle(&mut p, &rig.clock).await.in_position);
    assert_eq!(p.readout().await.unwrap(), 20.0);
}

/// The driver as it is sent to real controllers: only the commands the
/// public record shows. In position comes from bit 7 and `POS:CURR?`, faults
/// from `SYST:ERR:ALL?`, the units are checked, and the unverified commands
/// are refused with what to do instead.
#[tokio::test]
async fn the_driver_works_with_only_the_publicly_recorded_commands() {
    let rig = Rig::new(PositionerConfig::new(fig8())).await;
    let mut p = rig.connect_verified().await;
    p.move_to(30.0).await.unwrap();
    let s = settle(&mut p, &rig.clock).await;
    assert!(s.in_position && !s.moving, "{s:?}");
    assert_eq!(p.readout().await.unwrap(), 30.0);
    // A fault latched on the controller: read from SYST:ERR:ALL?.
    rig.faults.arm(Fault::Trip(fault(305, "PAU fault")));
    let s = p.status().await.unwrap();
    assert_eq!(s.fault.as_ref().map(|f| f.code), Some(305), "{s:?}");
    assert!(!s.in_position);
    // No public fault-clear command: only the queue is cleared, the fault
    // stays, and the clear says so and what to do (bad usage: the survey
    // stops at once, interrupted).
    let e = p.clear_fault().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Usage, "{e}");
    for says in [
        "PAU fault",
        "stays latched after *CLS",
        "clear it at the controller",
        "survey resume",
        "unverified_commands = true",
    ] {
        assert!(e.message.contains(says), "{says}: {e}");
    }
    assert!(p.status().await.unwrap().fault.is_some());
    // Without the unverified commands the state is unknown (nothing asked).
    assert_eq!(p.correction_state().await.unwrap(), None);
    for e in [
        p.load_correction_table(&CorrectionTable::new(vec![0.0; 4]).unwrap()).await.unwrap_err(),
        p.enable_correction(true).await.unwrap_err(),
        p.set_velocity(5.0).await.unwrap_err(),
    ] {
        assert_eq!(e.kind, ErrorKind::Usage, "{e}");
        assert!(e.message.contains("public record") && e.message.contains("unverified_commands"), "{e}");
    }
}

#[tokio::test]
async fn an_axis_in_other_units_is_refused_before_any_move() {
    let rig = Rig::new(PositionerConfig::new(fig8())).await;
    rig.units.store(7, Ordering::Relaxed);
    let mut p = rig.connect_verified().await;
    let e = p.move_to(10.0).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Usage, "{e}");
    assert!(e.message.contains("radians (UNIT:POS? = 7), not degrees"), "{e}");
    assert_eq!(p.commanded_position().await.unwrap(), 0.0, "nothing was commanded");
}

/// A unit code outside the public table is no answer to `UNIT:POS?` (a late
/// reply to an earlier query on the same line): a garbled exchange the
/// reconnect layer retries, never a unit refused as bad usage.
#[tokio::test]
async fn a_unit_code_outside_the_table_is_a_garbled_reply() {
    let rig = Rig::new(PositionerConfig::new(fig8())).await;
    rig.units.store(800, Ordering::Relaxed);
    let mut p = rig.connect_verified().await;
    let e = p.move_to(10.0).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Garbled, "{e}");
    assert!(e.message.contains("800"), "{e}");
    rig.units.store(6, Ordering::Relaxed);
    p.move_to(10.0).await.unwrap();
}

#[tokio::test]
async fn the_status_word_uses_only_the_documented_bits_and_the_queue_answers_all_at_once() {
    let rig = Rig::new(PositionerConfig::new(fig8())).await;
    let word = |r: &str| r.parse::<u16>().unwrap();
    let at_rest = raw(rig.addr, &[b"CONT1:AXIS(1):STAT?"]).await;
    let moving =
        raw(rig.addr, &[b"CONT1:AXIS(1):POS:COMM 90", b"CONT1:AXIS(1):MOT:STAR", b"CONT1:AXIS(1):STAT?"]).await;
    rig.faults.arm(Fault::Trip(fault(305, "PAU fault")));
    let faulted = raw(rig.addr, &[b"CONT1:AXIS(1):STAT?"]).await;
    for (what, w) in [("at rest", word(&at_rest[0])), ("moving", word(&moving[0])), ("faulted", word(&faulted[0]))] {
        assert_eq!(w & 0xE000, 0, "{what}: bits 13-15 are unused, got {w:#06x}");
    }
    assert_ne!(word(&moving[0]) & (1 << 7), 0, "bit 7: in motion");
    assert_ne!(word(&faulted[0]) & (1 << 4), 0, "bit 4: PAU fault");
    let replies = raw(rig.addr, &[b"FOO", b"BAR", b"SYST:ERR:COUN?", b"SYST:ERR:ALL?", b"SYST:ERR:ALL?"]).await;
    assert_eq!(replies[0], "3", "{replies:?}");
    assert_eq!(replies[1], "305,\"PAU fault\", -113,\"Undefined header;FOO\", -113,\"Undefined header;BAR\"");
    assert_eq!(replies[2], "0, \"No error\"");
}
