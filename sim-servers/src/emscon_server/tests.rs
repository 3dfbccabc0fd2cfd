//! Tests of the simulated emScon server: the real driver over TCP against it.

use super::*;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use survey_drivers::VirtualClock;
use survey_drivers::clock::Clock;
use survey_drivers::emscon::{EmsconConfig, EmsconTimeouts, EmsconTracker};
use survey_drivers::error::ErrorKind;
use survey_drivers::traits::DeviceFault;
use survey_sims::tracker::TrackerConfig;
use survey_sims::turntable::Turntable;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio::task::JoinHandle;

/// A measurement without its air (two measurements at different moments see different rooms).
fn dry(m: SmrMeasurement) -> SmrMeasurement {
    SmrMeasurement { environment: None, ..m }
}

const ANGLE: f64 = 30.0;

fn sim_cfg(seed: u64, break_on: Option<usize>) -> TrackerConfig {
    let measurement_time = Duration::from_millis(50);
    TrackerConfig { seed, break_on_measurement: break_on, measurement_time, ..TrackerConfig::default() }
}

fn driver_cfg() -> EmsconConfig {
    let timeouts = EmsconTimeouts {
        request_ms: 200,
        initialize_ms: 200,
        measurement_margin_ms: 150,
        reacquire_ms: 200,
        resync_grace_ms: 30,
        ..EmsconTimeouts::default()
    };
    EmsconConfig { measurement_time_ms: 50, timeouts, ..EmsconConfig::default() }
}

/// A server on 127.0.0.1:0, and a second tracker with the same seed and
/// angle measured directly.
/// The server is behind a relay (its link faults): `addr` is the relay's,
/// `server_addr` the server's own.
struct Rig {
    clock: VirtualClock,
    /// Link faults (the relay's) and device faults (the server's).
    faults: Faults,
    requests: Requests,
    addr: SocketAddr,
    server_addr: SocketAddr,
    server: JoinHandle<()>,
    relay: JoinHandle<()>,
    direct: SimTracker,
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.server.abort();
        self.relay.abort();
    }
}

/// A refusal with the result status `code`.
fn refusal(code: i32) -> DeviceFault {
    DeviceFault { code: i64::from(code), text: String::new() }
}

impl Rig {
    async fn new(cfg: TrackerConfig) -> Rig {
        let clock = VirtualClock::new();
        let sim = SimTracker::new(cfg.clone(), Arc::new(clock.clone()), Turntable::new(ANGLE));
        let direct = SimTracker::new(cfg, Arc::new(VirtualClock::new()), Turntable::new(ANGLE));
        let faults = Faults::new();
        let (listener, addr, relay) =
            crate::relay::tcp_relay(crate::relay::Relay::armed(faults.clone(), crate::relay::Framing::Emscon)).await;
        let server_addr = listener.local_addr().unwrap();
        let server = Server::new(sim, faults.clone());
        let requests = server.requests();
        let server = tokio::spawn(serve_server(listener, server));
        Rig { clock, faults, requests, addr, server_addr, server, relay, direct }
    }

    async fn connect(&self) -> EmsconTracker<TcpStream> {
        EmsconTracker::connect(self.addr, driver_cfg()).await.unwrap()
    }
}

#[tokio::test]
async fn connect_sets_up_and_measures_as_the_simulator_does() {
    let mut rig = Rig::new(sim_cfg(7, None)).await;
    let mut t = rig.connect().await;
    let params = StationaryModeData { meas_time_ms: 50, use_adm: false };
    let setup = vec![
        Request::Initialize,
        Request::SetUnits(SystemUnits::SURVEY),
        Request::SetCoordinateSystemType(coordinate_system::RHR),
        Request::SetMeasurementMode(meas_mode::STATIONARY),
        Request::SetStatisticMode { stationary: 0, continuous: 0 },
        Request::SetStationaryModeParams(params),
    ];
    assert_eq!(rig.requests.get(), setup);
    assert_eq!(t.status().await.unwrap(), TrackerState::TargetLocked);
    let s = t.system_status().await.unwrap();
    assert_eq!((s.tracker_serial_number, s.version), (SIM_SERIAL_NUMBER, [3, 6, 0]));
    let mut last_air = None;
    for _ in 0..3 {
        let t0 = rig.clock.now();
        let wire = t.measure().await.unwrap();
        assert_eq!(rig.clock.now() - t0, Duration::from_millis(50), "the sim's measurement time");
        // The room when the measurement ended, on the wire bit for bit.
        assert_eq!(wire.environment, Some(survey_sims::room::air_at(rig.clock.now().as_secs_f64())));
        last_air = wire.environment;
        // Same seed, same angle, mm on the wire: bit for bit the same (the room a moment later).
        assert_eq!(dry(wire), dry(rig.direct.measure().await.unwrap()));
    }
    let r = *t.last_result().unwrap();
    let air = last_air.expect("the room");
    assert_eq!((r.temperature, r.pressure, r.humidity), (air.temperature_c, air.pressure_hpa, air.humidity_pct));
    assert!((r.std_total - r.std[0] * 3f64.sqrt()).abs() < 1e-15);
}

/// A tracker left in extended statistic mode by other software answers
/// `SingleMeasResult2T` (204 bytes, type 9, the covariances after
/// `dStdTotal`: offsets from `ES_C_API_Def.h`); the driver decodes it, and
/// its set-up (`SetStatisticMode` standard) brings back `SingleMeasResultT`.
#[tokio::test]
async fn a_tracker_left_in_extended_statistic_mode() {
    let clock = VirtualClock::new();
    let cfg = sim_cfg(5, None);
    let sim = SimTracker::new(cfg, Arc::new(clock.clone()), Turntable::new(ANGLE));
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let server =
        tokio::spawn(serve_server(listener, Server::new(sim, Faults::new()).left_in_extended_statistic_mode()));
    let le = |w: &[i32]| w.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>();
    let mut s = TcpStream::connect(addr).await.unwrap();
    async fn ask(s: &mut TcpStream, bytes: &[u8]) -> Vec<u8> {
        s.write_all(bytes).await.unwrap();
        let mut size = [0u8; 4];
        s.read_exact(&mut size).await.unwrap();
        let mut rest = vec![0u8; i32::from_le_bytes(size) as usize - 4];
        s.read_exact(&mut rest).await.unwrap();
        [size.to_vec(), rest].concat()
    }
    assert_eq!(ask(&mut s, &le(&[12, 0, 7])).await, le(&[16, 0, 7, 0]));
    let m = ask(&mut s, &le(&[12, 0, 49])).await;
    assert_eq!((m.len(), &m[..8]), (204, &le(&[204, 9])[..]), "SingleMeasResult2T");
    let decoded = Reply::decode(&m).unwrap();
    assert!(matches!(decoded, Reply::SingleMeas2(r) if r.status == 0 && r.covar == [0.0; 3]), "{decoded:?}");
    // SetStatisticModeCT {stationary standard, continuous standard}: 20 bytes, command 80.
    assert_eq!(ask(&mut s, &le(&[20, 0, 80, 0, 0])).await, le(&[16, 0, 80, 0]));
    let m = ask(&mut s, &le(&[12, 0, 49])).await;
    assert_eq!((m.len(), &m[..8]), (156, &le(&[156, 2])[..]), "SingleMeasResultT again");
    // A mode outside the enum: ES_RS_WrongParameter1.
    assert_eq!(ask(&mut s, &le(&[20, 0, 80, 7, 0])).await, le(&[16, 0, 80, 4]));
    drop(s);
    server.abort();
}

/// Hand-built packets, offsets from the header, independent of the codec.
#[tokio::test]
async fn raw_packets_follow_the_header_layout() {
    let mut rig = Rig::new(sim_cfg(3, None)).await;
    let mut s = TcpStream::connect(rig.addr).await.unwrap();
    let le = |w: &[i32]| w.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>();
    async fn ask(s: &mut TcpStream, bytes: &[u8]) -> Vec<u8> {
        s.write_all(bytes).await.unwrap();
        let mut size = [0u8; 4];
        s.read_exact(&mut size).await.unwrap();
        let mut rest = vec![0u8; i32::from_le_bytes(size) as usize - 4];
        s.read_exact(&mut rest).await.unwrap();
        [size.to_vec(), rest].concat()
    }
    let f = |p: &[u8], at: usize| f64::from_le_bytes(p[at..at + 8].try_into().unwrap());
    // Not initialised yet: ES_RS_TrackerNotInitialized.
    assert_eq!(ask(&mut s, &le(&[12, 0, 49])).await, le(&[16, 0, 49, 39]));
    assert_eq!(ask(&mut s, &le(&[12, 0, 7])).await, le(&[16, 0, 7, 0]));
    // Metres until SetUnits.
    let m = ask(&mut s, &le(&[12, 0, 49])).await;
    assert_eq!((m.len(), &m[..20]), (156, &le(&[156, 2, 0, 0, 0])[..]));
    let direct = rig.direct.measure().await.unwrap();
    assert!((f(&m, 20) - direct.x_mm / 1000.0).abs() < 1e-12, "{} vs {}", f(&m, 20), direct.x_mm);
    assert!((f(&m, 44) - direct.std_dev_mm[0] / 1000.0).abs() < 1e-15);
    // mm, degree, Fahrenheit, psi, RH.
    assert_eq!(ask(&mut s, &le(&[32, 0, 5, 1, 1, 1, 4, 0])).await, le(&[16, 0, 5, 0]));
    let m = ask(&mut s, &le(&[12, 0, 49])).await;
    let direct = rig.direct.measure().await.unwrap();
    assert_eq!([f(&m, 20), f(&m, 28), f(&m, 36)], direct.xyz());
    // The simulated room (about 20 °C, 1013 hPa) in Fahrenheit and psi.
    assert!(((f(&m, 132) - 32.0) * 5.0 / 9.0 - 20.0).abs() < 0.5, "{}", f(&m, 132));
    assert!((f(&m, 140) - 14.6959).abs() < 0.03, "{}", f(&m, 140));
    // Undefined unit in field 4 (pressure): ES_RS_WrongParameter4.
    assert_eq!(ask(&mut s, &le(&[32, 0, 5, 1, 1, 0, 9, 0])).await, le(&[16, 0, 5, 7]));
    // A command not modelled, a packet that is no command, a wrong size.
    assert_eq!(ask(&mut s, &le(&[12, 0, 6])).await, le(&[16, 0, 6, 2]));
    assert_eq!(ask(&mut s, &le(&[12, 8, 25])).await, le(&[16, 1, 64, 3]));
    assert_eq!(ask(&mut s, &le(&[16, 0, 7, 0])).await, le(&[16, 0, 7, 3]));
    let info = ask(&mut s, &le(&[12, 0, 122])).await;
    assert_eq!(&info[..16], &le(&[24, 0, 122, 0])[..]);
    assert_eq!(i32::from_le_bytes(info[20..24].try_into().unwrap()) & (2048 | 65536), 2048 | 65536);
}

#[tokio::test]
async fn beam_break_is_a_device_error_and_reacquire_restores_measurements() {
    let mut rig = Rig::new(sim_cfg(11, Some(2))).await;
    let mut t = rig.connect().await;
    assert_eq!(dry(t.measure().await.unwrap()), dry(rig.direct.measure().await.unwrap()));
    let e = t.measure().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(i64::from(status::NO_STATIONARY_RESULT))), "{e}");
    assert!(e.message.contains("ES_RS_NoStationaryResult"), "{e}");
    assert_eq!(t.last_status_change(), Some(status_change::MEAS_STATUS_NOT_READY));
    assert_eq!(t.state(), TrackerState::BeamBroken);
    assert!(rig.direct.measure().await.is_err());
    assert_eq!(t.status().await.unwrap(), TrackerState::BeamBroken);
    let e = t.measure().await.unwrap_err();
    assert_eq!(e.code, Some(i64::from(status::MEASUREMENT_STATUS_NOT_READY)), "{e}");
    assert!(e.message.contains("ES_RS_MeasurementStatusNotReady"), "{e}");
    let before = rig.requests.get().len();
    let t0 = rig.clock.now();
    t.reacquire().await.unwrap();
    assert!(rig.clock.now() - t0 >= rig.direct.config().reacquire_time);
    let tail = rig.requests.get()[before..].to_vec();
    assert_eq!(tail, [Request::GoLastMeasuredPoint, Request::GetMeasurementStatusInfo]);
    assert_eq!(t.last_status_change(), Some(status_change::MEAS_STATUS_READY));
    assert_eq!(t.status().await.unwrap(), TrackerState::TargetLocked);
    rig.direct.reacquire().await.unwrap();
    assert_eq!(dry(t.measure().await.unwrap()), dry(rig.direct.measure().await.unwrap()));
}

#[tokio::test]
async fn reacquire_without_a_last_point_searches_for_the_reflector() {
    let rig = Rig::new(sim_cfg(5, Some(1))).await;
    let mut t = rig.connect().await;
    assert_eq!(t.measure().await.unwrap_err().code, Some(i64::from(status::NO_STATIONARY_RESULT)));
    let before = rig.requests.get().len();
    t.reacquire().await.unwrap();
    let tail = rig.requests.get()[before..].to_vec();
    let find = Request::FindReflector { approx_distance: 3000.0 };
    assert_eq!(tail, [Request::GoLastMeasuredPoint, find, Request::GetMeasurementStatusInfo]);
    t.measure().await.unwrap();
    assert_eq!(t.state(), TrackerState::TargetLocked);
}

/// A beam held blocked: both re-acquisition commands answer
/// `ES_RS_MeasurementStatusNotReady`, which the driver takes for a device
/// fault of a broken beam (the suspend path), never a link fault.
#[tokio::test]
async fn a_failed_reacquisition_answers_measurement_status_not_ready() {
    let cfg = TrackerConfig { beam_hold: Duration::from_secs(60), ..sim_cfg(13, Some(2)) };
    let rig = Rig::new(cfg).await;
    let mut t = rig.connect().await;
    t.measure().await.unwrap();
    assert_eq!(t.measure().await.unwrap_err().code, Some(i64::from(status::NO_STATIONARY_RESULT)));
    let before = rig.requests.get().len();
    let e = t.reacquire().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(i64::from(status::MEASUREMENT_STATUS_NOT_READY))), "{e}");
    assert!(e.message.contains("ES_RS_MeasurementStatusNotReady") && e.message.contains("FindReflector"), "{e}");
    let tail = rig.requests.get()[before..].to_vec();
    assert_eq!(tail[0], Request::GoLastMeasuredPoint);
    assert!(matches!(tail[1], Request::FindReflector { .. }), "{tail:?}");
    assert_eq!(t.state(), TrackerState::BeamBroken);
    assert_eq!(t.status().await.unwrap(), TrackerState::BeamBroken, "what the engine asks before suspending");
    // Once the hold is over, the same commands find it.
    rig.clock.sleep(Duration::from_secs(60)).await;
    t.reacquire().await.unwrap();
    assert_eq!(t.status().await.unwrap(), TrackerState::TargetLocked);
    t.measure().await.unwrap();
}

#[tokio::test]
async fn status_changes_before_an_answer_are_applied_not_taken_for_it() {
    let mut rig = Rig::new(sim_cfg(9, None)).await;
    let mut t = rig.connect().await;
    rig.faults.arm(Fault::Event(i64::from(status_change::MEAS_STATUS_NOT_READY)));
    assert_eq!(dry(t.measure().await.unwrap()), dry(rig.direct.measure().await.unwrap()));
    assert_eq!((t.last_status_change(), t.status_changes_seen()), (Some(25), 1));
    assert_eq!(t.state(), TrackerState::TargetLocked, "a result proves the lock");
    rig.faults.arm(Fault::Event(i64::from(status_change::LASER_WARMED_UP)));
    rig.faults.arm(Fault::Event(i64::from(status_change::MEAS_STATUS_BUSY)));
    assert_eq!(t.status().await.unwrap(), TrackerState::TargetLocked);
    assert_eq!((t.last_status_change(), t.status_changes_seen()), (Some(26), 3));
}

#[tokio::test]
async fn a_dropped_answer_times_out_and_the_next_request_succeeds() {
    let rig = Rig::new(sim_cfg(1, None)).await;
    let mut t = rig.connect().await;
    rig.faults.arm(Fault::Drop);
    let started = tokio::time::Instant::now();
    let e = t.status().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
    assert!(started.elapsed() >= Duration::from_millis(200));
    assert_eq!(t.status().await.unwrap(), TrackerState::TargetLocked);
    rig.faults.arm(Fault::Drop);
    let e = t.measure().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout, "{e}");
    assert!(e.message.contains("200ms"), "measurement time + margin: {e}");
    t.measure().await.unwrap();
}

#[tokio::test]
async fn garbled_answers_are_garbled_and_the_link_recovers() {
    let rig = Rig::new(sim_cfg(2, None)).await;
    let mut t = rig.connect().await;
    for (how, says) in [
        (Garble::UnknownType, "unknown packet type"),
        (Garble::WrongLength, "expected 156"),
        (Garble::AbsurdSize, "absurd packet size"),
    ] {
        rig.faults.arm(garbled(how));
        let e = t.measure().await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Garbled, "{how:?}: {e}");
        assert!(e.message.contains(says), "{how:?}: {e}");
        t.measure().await.unwrap();
        assert_eq!(t.status().await.unwrap(), TrackerState::TargetLocked);
    }
}

/// Issue 51: a garbled answer during the connection's set-up is asked again
/// on the same connection (the next request resynchronises); three in a row
/// are the set-up's fault.
#[tokio::test]
async fn a_garbled_answer_in_the_set_up_is_asked_again() {
    let rig = Rig::new(sim_cfg(2, None)).await;
    rig.faults.arm_n(garbled(Garble::UnknownType), 2);
    let mut t = EmsconTracker::connect(rig.addr, driver_cfg()).await.unwrap();
    t.measure().await.unwrap();
    drop(t);
    rig.faults.arm_n(garbled(Garble::UnknownType), 3);
    let e = EmsconTracker::connect(rig.addr, driver_cfg()).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Garbled, "{e}");
}

/// A result status changed into one the header does not define, in a
/// measurement result and in a command's answer: a garbled packet, not
/// the tracker's fault; the next requests are answered as before.
#[tokio::test]
async fn an_undefined_result_status_is_a_garbled_packet() {
    let rig = Rig::new(sim_cfg(3, None)).await;
    let mut t = rig.connect().await;
    rig.faults.arm(garbled(Garble::Status));
    let e = t.measure().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Garbled, None), "{e}");
    assert!(e.message.contains("ES_ResultStatus 23040 is no status of the emScon header"), "{e}");
    t.measure().await.unwrap();
    rig.faults.arm(garbled(Garble::Status));
    let e = t.status().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Garbled, None), "{e}");
    assert!(e.message.contains("ES_ResultStatus 23040") && e.message.contains("ES_C_GetSystemStatus"), "{e}");
    assert_eq!(t.status().await.unwrap(), TrackerState::TargetLocked);
    // A defined status refusing the command stays a device fault.
    rig.faults.arm(Fault::Refuse(Some(refusal(status::SENSOR_NOT_STABLE))));
    let e = t.measure().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(10_013)), "{e}");
}

#[tokio::test]
async fn a_truncated_answer_then_close_is_a_disconnection() {
    let rig = Rig::new(sim_cfg(4, None)).await;
    let mut t = rig.connect().await;
    rig.faults.arm(Fault::Disconnect);
    let e = t.measure().await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Disconnected, "{e}");
    assert!(e.message.contains("after 78 bytes of a packet"), "{e}");
    let started = tokio::time::Instant::now();
    assert_eq!(t.status().await.unwrap_err().kind, ErrorKind::Disconnected);
    assert!(started.elapsed() < Duration::from_millis(100), "fails at once");
    drop(t);
    let mut again = rig.connect().await;
    again.measure().await.unwrap();
}

#[tokio::test]
async fn error_statuses_carry_their_code_and_name() {
    let rig = Rig::new(sim_cfg(6, None)).await;
    rig.faults.arm(Fault::Refuse(Some(refusal(status::SENSOR_NOT_WARMED_UP))));
    let e = EmsconTracker::connect(rig.addr, driver_cfg()).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(10_012)), "{e}");
    assert!(e.message.contains("ES_RS_SensorNotWarmedUp (10012) in answer to ES_C_Initialize"), "{e}");
    let mut t = rig.connect().await;
    rig.faults.arm(Fault::Refuse(Some(refusal(status::SENSOR_NOT_WARMED_UP))));
    let e = t.measure().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(10_012)), "{e}");
    assert_eq!(t.state(), TrackerState::NotReady);
    rig.faults.arm(Fault::RefuseWithError(refusal(status::SYSTEM_NOT_READY_FOR_MEASUREMENT)));
    let e = t.status().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(10_014)), "{e}");
    assert!(e.message.contains("ES_RS_SystemNotReadyForMeasurement"), "{e}");
    t.measure().await.unwrap();
    assert_eq!(t.status().await.unwrap(), TrackerState::TargetLocked);
}

#[tokio::test]
async fn a_second_client_is_refused_while_the_first_is_served() {
    let rig = Rig::new(sim_cfg(8, None)).await;
    // The server's own port (the relay in front serves one client at a time).
    let mut first = EmsconTracker::connect(rig.server_addr, driver_cfg()).await.unwrap();
    let e = EmsconTracker::connect(rig.server_addr, driver_cfg()).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(10_011)), "{e}");
    assert!(e.message.contains("ES_RS_MultiConnectionsNotAllowed"), "{e}");
    first.measure().await.unwrap();
    drop(first);
    EmsconTracker::connect(rig.server_addr, driver_cfg()).await.unwrap().measure().await.unwrap();
}

#[tokio::test]
async fn pointed_at_another_smr_over_the_wire_it_measures_that_one() {
    use survey_processing::tracker_errors::TrackerErrorSpec;
    use survey_sims::tracker::{ArmGeometry, SmrMount};
    let arm = ArmGeometry { smrs: SmrMount::equal(2), ..ArmGeometry::default() };
    let cfg = TrackerConfig { arm: arm.clone(), errors: TrackerErrorSpec::None, noise_scale: 0.0, ..sim_cfg(3, None) };
    let rig = Rig::new(cfg).await;
    let mut t = rig.connect().await;
    assert!(t.can_point());
    let first = t.measure().await.unwrap().xyz();
    assert_eq!(first, arm.smr_position_of(0, ANGLE));
    let second = arm.smr_position_of(1, ANGLE);
    t.point_at(second).await.unwrap();
    assert_eq!(t.status().await.unwrap(), TrackerState::TargetLocked);
    assert_eq!(t.measure().await.unwrap().xyz(), second);
    // The requests on the wire: GoPosition with the position, FindReflector at its distance.
    let sent = rig.requests.get();
    let go = sent.iter().position(|r| matches!(r, Request::GoPosition { .. })).expect("a GoPosition");
    assert_eq!(sent[go], Request::GoPosition { position: second, use_adm: false });
    let distance = second.iter().map(|v| v * v).sum::<f64>().sqrt();
    assert_eq!(sent[go + 1], Request::FindReflector { approx_distance: distance });
    // Nothing there: a device fault, the tracker not locked, nothing measured.
    let e = t.point_at([100.0, 200.0, 300.0]).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Device, "{e}");
    assert!(e.to_string().contains("ES_C_FindReflector (pointing at (100.0, 200.0, 300.0) mm)"), "{e}");
    assert_eq!(t.status().await.unwrap(), TrackerState::BeamBroken);
    assert_eq!(t.measure().await.unwrap_err().kind, ErrorKind::Device);
    // Back on the first.
    t.point_at(first).await.unwrap();
    assert_eq!(t.measure().await.unwrap().xyz(), first);
}
