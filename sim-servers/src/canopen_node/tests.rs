//! The CiA 402 driver against the simulated node on the in-memory bus (and on
//! SocketCAN where the kernel has it). The positioner runs on a virtual
//! clock the tests advance; the driver's deadlines are real (200 ms), so a
//! dropped response costs 200 ms of real time. The node answers at once, so
//! no deadline is raced.

use super::*;
use rand::{Rng, SeedableRng};
use std::sync::Arc;
use std::time::Duration;
use survey_drivers::VirtualClock;
use survey_drivers::clock::Clock;
use survey_drivers::traits::DeviceFault;
use survey_positioner_drivers::canopen::objects::{
    DEVICE_TYPE_SERVO_DRIVE, DriveState, Statusword, decode_table, encode_table, index,
};
use survey_positioner_drivers::canopen::socketcan_bus::{SocketCanBus, is_can_unavailable};
use survey_positioner_drivers::canopen::{CW_OPERATE, CanopenConfig, Cia402Positioner, MemoryBus, MemoryEndpoint};
use survey_processing::Direction;
use survey_processing::model::Model;
use survey_processing::table::CorrectionTable;
use survey_sims::positioner::{FAULT_FOLLOWING_ERROR, PositionerConfig, PositionerFaults};
use survey_sims::presets::{Preset, without_noise};
use survey_sims::turntable::Turntable;
use tokio::task::JoinHandle;

const NODE: u8 = 5;
const CPD: f64 = DEFAULT_COUNTS_PER_DEGREE;

fn fig8() -> Model {
    without_noise(&Preset::by_name("fig8").unwrap().model)
}

/// The driver for a drive with this project's correction objects.
fn driver_cfg() -> CanopenConfig {
    CanopenConfig { node_id: NODE, sdo_timeout_ms: 200, correction_objects: true, ..CanopenConfig::default() }
}

/// A node with this project's own objects (0x2100-0x2102).
fn node_cfg() -> NodeConfig {
    NodeConfig { correction_objects: true, ..NodeConfig::new(NODE) }
}

type Driver = Cia402Positioner<MemoryEndpoint>;

/// The node on a bus of its own behind a relay (its link faults), the
/// driver and the monitor on the host's bus.
struct Rig {
    clock: VirtualClock,
    truth: Turntable,
    /// Link faults (the relay's) and device faults (the node's).
    faults: Faults,
    bus: MemoryBus,
    /// Sees every frame on the bus.
    monitor: MemoryEndpoint,
    node: Option<JoinHandle<NodeReport>>,
}

impl Drop for Rig {
    fn drop(&mut self) {
        if let Some(n) = &self.node {
            n.abort();
        }
    }
}

impl Rig {
    fn new(cfg: PositionerConfig) -> Rig {
        Rig::with_node(cfg, node_cfg())
    }

    /// A node that carries out a transition at once: for the tests of the
    /// state logic itself, step by step.
    fn instant() -> Rig {
        Rig::with_node(PositionerConfig::new(fig8()), NodeConfig { transition_time: Duration::ZERO, ..node_cfg() })
    }

    fn with_node(cfg: PositionerConfig, node_cfg: NodeConfig) -> Rig {
        let clock = VirtualClock::new();
        let sim = SimPositioner::new(cfg, Arc::new(clock.clone()));
        let truth = sim.truth();
        let bus = MemoryBus::new();
        let monitor = bus.endpoint();
        let faults = Faults::new();
        // When the host's bus goes down, the relay ends and takes the
        // node's bus down with it.
        let device_bus = MemoryBus::new();
        let (host, device, node_end) = (bus.endpoint(), device_bus.endpoint(), device_bus.endpoint());
        let relay = crate::relay::Relay::armed(faults.clone(), crate::relay::Framing::Chunks);
        tokio::spawn(async move {
            crate::relay::relay_can(host, device, &relay).await;
            device_bus.shut_down();
        });
        let node = tokio::spawn(serve(node_end, sim, node_cfg, faults.clone()));
        Rig { clock, truth, faults, bus, monitor, node: Some(node) }
    }

    fn fig8() -> Rig {
        Rig::new(PositionerConfig::new(fig8()))
    }

    /// A driver that has sent nothing yet.
    fn driver(&self) -> Driver {
        Cia402Positioner::new(self.bus.endpoint(), driver_cfg()).unwrap()
    }

    /// A driver with the node started and the drive in operation enabled.
    async fn connected(&self) -> Driver {
        Cia402Positioner::connect(self.bus.endpoint(), driver_cfg()).await.unwrap()
    }

    /// NMT and heartbeat frames the monitor saw since last asked, candump style.
    fn nmt_frames(&mut self) -> Vec<String> {
        std::iter::from_fn(|| self.monitor.try_recv().unwrap())
            .filter(|f| f.id() == 0 || f.id() == 0x700 + u16::from(NODE))
            .map(|f| f.to_string())
            .collect()
    }

    /// SDO downloads (index, value bytes) the monitor saw since last asked.
    fn downloads(&mut self) -> Vec<(u16, Vec<u8>)> {
        std::iter::from_fn(|| self.monitor.try_recv().unwrap())
            .filter(|f| f.id() == 0x600 + u16::from(NODE))
            .filter_map(|f| match SdoRequest::decode(f.data()) {
                Ok(SdoRequest::InitiateDownload { index, data: InitData::Expedited { data, .. }, .. }) => {
                    Some((index, data))
                }
                _ => None,
            })
            .collect()
    }
}

impl Rig {
    /// Abort codes the client sent since last asked.
    fn client_aborts(&mut self) -> Vec<u32> {
        std::iter::from_fn(|| self.monitor.try_recv().unwrap())
            .filter(|f| f.id() == 0x600 + u16::from(NODE))
            .filter_map(|f| match SdoRequest::decode(f.data()) {
                Ok(SdoRequest::Abort { code, .. }) => Some(code),
                _ => None,
            })
            .collect()
    }
}

/// Poll until in position or faulted, 100 ms of clock time between polls.
async fn settle<P: Positioner>(p: &mut P, clock: &VirtualClock) -> PositionerStatus {
    for _ in 0..2_000 {
        let s = p.status().await.unwrap();
        if s.in_position || s.fault.is_some() {
            return s;
        }
        clock.advance(Duration::from_millis(100));
    }
    panic!("never settled");
}

fn assert_error(r: survey_drivers::Result<impl std::fmt::Debug>, kind: ErrorKind, code: Option<u32>) -> DriverError {
    let e = r.unwrap_err();
    assert_eq!((e.kind, e.code), (kind, code.map(i64::from)), "{e}");
    e
}

#[tokio::test]
async fn nmt_start_stop_reset_and_heartbeats_on_the_wire() {
    let mut rig = Rig::instant();
    let mut d = rig.driver();
    // Pre-operational after boot-up: SDO works, enabling operation does not.
    assert_eq!(d.statusword().await.unwrap().state(), Some(DriveState::SwitchOnDisabled));
    assert_eq!(rig.nmt_frames(), ["705#00"]);
    d.write_controlword(0x06).await.unwrap();
    d.write_controlword(0x07).await.unwrap();
    let e = assert_error(d.write_controlword(0x0F).await, ErrorKind::Usage, Some(abort::DEVICE_STATE));
    assert!(e.message.contains("present device state"), "{e}");
    assert_eq!(d.statusword().await.unwrap().state(), Some(DriveState::SwitchedOn));
    // NMT start: 000#0105, answered by a heartbeat "operational".
    d.nmt(NmtCommand::Start).await.unwrap();
    d.write_controlword(0x0F).await.unwrap();
    assert_eq!(rig.nmt_frames(), ["000#0105", "705#05"]);
    assert_eq!(d.statusword().await.unwrap().state(), Some(DriveState::OperationEnabled));
    // Stopped: SDO is not served.
    d.nmt(NmtCommand::Stop).await.unwrap();
    assert_error(d.readout().await, ErrorKind::Timeout, None);
    d.nmt(NmtCommand::Start).await.unwrap();
    assert_eq!(d.readout().await.unwrap(), 0.0);
    assert_eq!(rig.nmt_frames(), ["000#0205", "705#04", "000#0105", "705#05"]);
    // Reset node: boot-up again, drive disabled; NMT to another node is ignored.
    d.bus_mut().send(nmt::encode_command(NmtCommand::Stop, NODE + 1)).await.unwrap();
    d.nmt(NmtCommand::ResetNode).await.unwrap();
    assert_eq!(d.statusword().await.unwrap().state(), Some(DriveState::SwitchOnDisabled));
    assert_eq!(rig.nmt_frames(), ["000#0206", "000#8105", "705#00"]);
    d.enable().await.unwrap();
    assert_eq!(d.statusword().await.unwrap().state(), Some(DriveState::OperationEnabled));
}

#[tokio::test]
async fn expedited_and_segmented_uploads() {
    let rig = Rig::fig8();
    let mut d = rig.connected().await;
    // 41 bytes: initiate + 6 segments.
    assert_eq!(d.device_name().await.unwrap(), DEVICE_NAME);
    assert_eq!(d.upload(index::DEVICE_TYPE, 0).await.unwrap(), DEVICE_TYPE_SERVO_DRIVE.to_le_bytes());
    assert_eq!(d.upload(index::MODES_OF_OPERATION_DISPLAY, 0).await.unwrap(), [1]);
    let w = d.statusword().await.unwrap();
    assert!(w.operation_enabled() && w.has(sw::REMOTE) && w.target_reached() && !w.fault(), "{w}");
    // No fault: an empty string, a segmented upload of size 0.
    assert_eq!(d.read_string(index::FAULT_TEXT).await.unwrap(), "");
    assert_eq!(d.upload(index::ERROR_CODE, 0).await.unwrap(), [0, 0]);
    assert_eq!(d.upload(index::ERROR_REGISTER, 0).await.unwrap(), [0]);
    assert_eq!(d.upload(index::PROFILE_VELOCITY, 0).await.unwrap(), 1_000_000u32.to_le_bytes());
    assert!(d.name().starts_with("canopen node 5 on memory bus"), "{}", d.name());
}

#[tokio::test]
async fn controlword_sequence_and_refused_set_points() {
    let rig = Rig::instant();
    let mut d = rig.driver();
    d.nmt(NmtCommand::Start).await.unwrap();
    let state = |w: Statusword| w.state().unwrap();
    assert_eq!(d.statusword().await.unwrap().0 & 0x4F, 0x40);
    d.write_controlword(cw::SHUTDOWN).await.unwrap();
    assert_eq!(state(d.statusword().await.unwrap()), DriveState::ReadyToSwitchOn);
    // A set-point outside operation enabled is refused and nothing changes.
    assert_error(d.write_controlword(0x17).await, ErrorKind::Usage, Some(abort::DEVICE_STATE));
    assert_eq!(state(d.statusword().await.unwrap()), DriveState::ReadyToSwitchOn);
    d.write_controlword(cw::SWITCH_ON_CMD).await.unwrap();
    assert_eq!(state(d.statusword().await.unwrap()), DriveState::SwitchedOn);
    // Modes of operation is still 0: enable + set-point is refused.
    assert_error(d.write_controlword(0x1F).await, ErrorKind::Usage, Some(abort::DEVICE_STATE));
    assert_error(d.download(index::MODES_OF_OPERATION, 0, &[3]).await, ErrorKind::Usage, Some(abort::VALUE_RANGE));
    d.download(index::MODES_OF_OPERATION, 0, &[1]).await.unwrap();
    d.write_controlword(cw::ENABLE_OPERATION_CMD).await.unwrap();
    assert_eq!(state(d.statusword().await.unwrap()), DriveState::OperationEnabled);
    // Quick stop and back (transition 16), disable voltage.
    d.write_controlword(cw::QUICK_STOP_CMD).await.unwrap();
    assert_eq!(state(d.statusword().await.unwrap()), DriveState::QuickStopActive);
    d.write_controlword(cw::ENABLE_OPERATION_CMD).await.unwrap();
    assert_eq!(state(d.statusword().await.unwrap()), DriveState::OperationEnabled);
    d.write_controlword(cw::DISABLE_VOLTAGE).await.unwrap();
    assert_eq!(state(d.statusword().await.unwrap()), DriveState::SwitchOnDisabled);
    // The trait's move enables the drive again by itself.
    d.move_to(1.0).await.unwrap();
    assert_eq!(state(d.statusword().await.unwrap()), DriveState::OperationEnabled);
}

#[tokio::test]
async fn a_move_with_new_set_point_until_target_reached() {
    let mut rig = Rig::fig8();
    let mut d = rig.connected().await;
    d.move_to(45.0).await.unwrap();
    let s = d.status().await.unwrap();
    assert!(s.moving && !s.in_position, "{s:?}");
    // The handshake left bit 4 low and the acknowledge with it.
    assert_eq!(d.upload(index::CONTROLWORD, 0).await.unwrap(), CW_OPERATE.to_le_bytes());
    assert!(!d.statusword().await.unwrap().set_point_acknowledged());
    let s = settle(&mut d, &rig.clock).await;
    assert!(s.in_position && !s.moving && s.fault.is_none() && s.limit.is_none(), "{s:?}");
    assert_eq!(d.readout().await.unwrap(), 45.0, "readout at rest equals the target");
    let actual = rig.truth.actual_deg(rig.clock.now());
    assert!((actual - 45.0).abs() < 0.05 && actual != 45.0, "true angle {actual}");
    // On the wire: target, then the rising edge of bit 4, then bit 4 low.
    rig.downloads();
    d.move_to(10.0).await.unwrap();
    assert_eq!(
        rig.downloads(),
        [
            (index::TARGET_POSITION, 1_000_000i32.to_le_bytes().to_vec()),
            (index::CONTROLWORD, 0x3Fu16.to_le_bytes().to_vec()),
            (index::CONTROLWORD, 0x2Fu16.to_le_bytes().to_vec()),
        ]
    );
    settle(&mut d, &rig.clock).await;
    assert_eq!(d.readout().await.unwrap(), 10.0);
    assert_eq!(d.position_counts().await.unwrap(), 1_000_000);
}

#[tokio::test]
async fn stop_halts_the_axis_where_it_is() {
    let rig = Rig::instant();
    let mut d = rig.connected().await;
    d.move_to(90.0).await.unwrap();
    rig.clock.advance(Duration::from_secs(3));
    d.stop().await.unwrap();
    assert_eq!(d.upload(index::CONTROLWORD, 0).await.unwrap(), (CW_OPERATE | cw::HALT).to_le_bytes());
    let s = settle(&mut d, &rig.clock).await;
    assert!(s.in_position && s.fault.is_none(), "{s:?}");
    let r = d.readout().await.unwrap();
    assert!(r > 5.0 && r < 85.0, "halted at {r}");
    assert!(!rig.truth.is_moving(rig.clock.now()));
    // Halt is cleared by the next set-point.
    d.move_to(100.0).await.unwrap();
    settle(&mut d, &rig.clock).await;
    assert_eq!(d.readout().await.unwrap(), 100.0);
    // Stop with the drive disabled sends nothing and succeeds.
    d.write_controlword(cw::DISABLE_VOLTAGE).await.unwrap();
    d.stop().await.unwrap();
    assert_eq!(d.upload(index::CONTROLWORD, 0).await.unwrap(), [0, 0]);
}

#[tokio::test]
async fn velocity_sets_the_move_time_and_out_of_range_is_usage() {
    let rig = Rig::fig8();
    let mut d = rig.connected().await;
    async fn timed(d: &mut Driver, clock: &VirtualClock, target: f64) -> Duration {
        let t0 = clock.now();
        d.move_to(target).await.unwrap();
        settle(d, clock).await;
        clock.now() - t0
    }
    let slow = timed(&mut d, &rig.clock, 40.0).await;
    d.set_velocity(20.0).await.unwrap();
    assert_eq!(d.upload(index::PROFILE_VELOCITY, 0).await.unwrap(), 2_000_000u32.to_le_bytes());
    let fast = timed(&mut d, &rig.clock, 0.0).await;
    assert!(slow > fast + Duration::from_secs(1), "slow {slow:?}, fast {fast:?}");
    let e = assert_error(d.set_velocity(1000.0).await, ErrorKind::Usage, Some(abort::VALUE_TOO_HIGH));
    assert!(e.message.contains("0x06090031"), "{e}");
    assert_error(
        d.download(index::PROFILE_VELOCITY, 0, &[0, 0, 0, 0]).await,
        ErrorKind::Usage,
        Some(abort::VALUE_TOO_LOW),
    );
    assert_error(d.set_velocity(0.0).await, ErrorKind::Usage, None);
    assert_error(d.set_velocity(f64::NAN).await, ErrorKind::Usage, None);
    assert_eq!(d.upload(index::PROFILE_VELOCITY, 0).await.unwrap(), 2_000_000u32.to_le_bytes());
}

#[tokio::test]
async fn travel_limits_out_of_range_targets_and_limit_switches() {
    let cfg = PositionerConfig { travel: Some((-10.0, 90.0)), ..PositionerConfig::new(fig8()) };
    let rig = Rig::new(cfg);
    let mut d = rig.connected().await;
    let e = assert_error(d.move_to(120.0).await, ErrorKind::Usage, Some(abort::VALUE_RANGE));
    assert!(e.message.contains("Value range of parameter exceeded") && e.message.contains("0x607A"), "{e}");
    assert_error(d.move_to(f64::INFINITY).await, ErrorKind::Usage, None);
    d.move_to(90.0).await.unwrap();
    assert_eq!(settle(&mut d, &rig.clock).await.limit, Some(Limit::Upper));
    assert_eq!(d.upload(index::DIGITAL_INPUTS, 0).await.unwrap(), di::POSITIVE_LIMIT.to_le_bytes());
    assert!(d.statusword().await.unwrap().internal_limit());
    d.move_to(-10.0).await.unwrap();
    assert_eq!(settle(&mut d, &rig.clock).await.limit, Some(Limit::Lower));
    d.move_to(45.0).await.unwrap();
    assert_eq!(settle(&mut d, &rig.clock).await.limit, None);
}

#[tokio::test]
async fn a_drive_fault_is_reported_with_its_code_and_cleared_by_fault_reset() {
    let faults = PositionerFaults { fault_on_move: Some(1), ..PositionerFaults::default() };
    let rig = Rig::new(PositionerConfig { faults, ..PositionerConfig::new(fig8()) });
    let mut d = rig.connected().await;
    d.move_to(60.0).await.unwrap();
    let s = settle(&mut d, &rig.clock).await;
    let f = s.fault.clone().expect("a fault");
    assert_eq!(f.code, survey_sims::positioner::FAULT_FOLLOWING_ERROR);
    assert!(f.text.contains("following error"), "{f:?}");
    assert!(!s.moving && !s.in_position, "{s:?}");
    assert_eq!(d.statusword().await.unwrap().state(), Some(DriveState::Fault));
    assert_eq!(d.upload(index::ERROR_REGISTER, 0).await.unwrap(), [1]);
    let e = assert_error(d.move_to(10.0).await, ErrorKind::Device, Some(0x8611));
    assert!(e.message.contains("following error"), "{e}");
    d.clear_fault().await.unwrap();
    let s = d.status().await.unwrap();
    assert!(s.fault.is_none(), "{s:?}");
    assert_eq!(d.statusword().await.unwrap().state(), Some(DriveState::OperationEnabled));
    d.move_to(10.0).await.unwrap();
    assert!(settle(&mut d, &rig.clock).await.in_position);
    assert_eq!(d.readout().await.unwrap(), 10.0);
    // Nothing latched: clear_fault is a no-op.
    d.clear_fault().await.unwrap();
}

#[tokio::test]
async fn the_fault_text_falls_back_to_the_standard_text_of_the_code() {
    let faults = PositionerFaults { fault_on_move: Some(1), ..PositionerFaults::default() };
    let rig = Rig::new(PositionerConfig { faults, ..PositionerConfig::new(fig8()) });
    let cfg = CanopenConfig { fault_text_index: Some(0x2999), ..driver_cfg() };
    let mut d = Cia402Positioner::connect(rig.bus.endpoint(), cfg).await.unwrap();
    d.move_to(60.0).await.unwrap();
    let f = settle(&mut d, &rig.clock).await.fault.unwrap();
    assert_eq!((f.code, f.text.as_str()), (0x8611, "Following error"));
}

#[tokio::test]
async fn correction_table_segmented_download_upload_and_effect() {
    let rig = Rig::fig8();
    let mut d = rig.connected().await;
    assert_error(d.enable_correction(true).await, ErrorKind::Usage, Some(abort::NO_DATA));
    assert_error(d.read_correction_table().await, ErrorKind::Usage, Some(abort::NO_DATA));
    let fwd: Vec<f64> = (0..720).map(|i| 0.01 * (i as f64 * 0.1).cos()).collect();
    let rev: Vec<f64> = fwd.iter().map(|v| v - 0.002).collect();
    let table = CorrectionTable::directional(fwd, rev).unwrap();
    d.load_correction_table(&table).await.unwrap();
    // What the node holds is the table rounded to f32.
    let held = d.read_correction_table().await.unwrap();
    assert_eq!(held, decode_table(&encode_table(&table).unwrap()).unwrap());
    assert!(held.is_directional() && held.len() == 720);
    assert!(!d.status().await.unwrap().correction_enabled);
    assert_eq!(d.correction_state().await.unwrap(), Some(false), "0x2101 read");
    d.enable_correction(true).await.unwrap();
    assert!(d.status().await.unwrap().correction_enabled);
    assert_eq!(d.correction_state().await.unwrap(), Some(true));
    // At rest at 0: the display is raw - error(raw), in counts.
    let want = counts_to_degrees(degrees_to_counts(-held.error_at(0.0, Direction::Forward), CPD).unwrap(), CPD);
    assert_eq!(d.readout().await.unwrap(), want);
    assert!((want + 0.01).abs() < 1e-6, "{want}");
    d.enable_correction(false).await.unwrap();
    assert_eq!(d.readout().await.unwrap(), 0.0);
    // Loading while moving is refused by the drive's state.
    d.move_to(30.0).await.unwrap();
    assert_error(d.load_correction_table(&table).await, ErrorKind::Usage, Some(abort::DEVICE_STATE));
    assert_error(d.download(index::CORRECTION_ENABLE, 0, &[2]).await, ErrorKind::Usage, Some(abort::VALUE_RANGE));
}

#[tokio::test]
async fn abort_codes_become_device_errors_with_code_and_text() {
    let rig = Rig::fig8();
    let mut d = rig.connected().await;
    let e = assert_error(d.upload(0x5555, 0).await, ErrorKind::Device, Some(abort::NO_OBJECT));
    assert!(e.message.contains("0x06020000 (Object does not exist") && e.message.contains("0x5555:00"), "{e}");
    assert!(!e.is_link());
    assert_error(d.upload(index::STATUSWORD, 1).await, ErrorKind::Device, Some(abort::NO_SUBINDEX));
    assert_error(d.download(index::DEVICE_NAME, 0, b"renamed drive").await, ErrorKind::Device, Some(abort::READ_ONLY));
    assert_error(d.download(index::STATUSWORD, 0, &[0, 0]).await, ErrorKind::Device, Some(abort::READ_ONLY));
    assert_error(d.download(index::TARGET_POSITION, 0, &[1, 2]).await, ErrorKind::Device, Some(abort::LENGTH_TOO_LOW));
    assert_error(d.download(index::CONTROLWORD, 0, &[1, 2, 3]).await, ErrorKind::Device, Some(abort::LENGTH_TOO_HIGH));
    assert_error(
        d.download(index::CORRECTION_TABLE, 0, &[2, 0, 0, 0, 1]).await,
        ErrorKind::Device,
        Some(abort::LENGTH_MISMATCH),
    );
    // An abort the node sends for its own reasons (injected), then all is well.
    rig.faults.arm(Fault::Refuse(Some(DeviceFault { code: 0x0606_0000, text: String::new() })));
    let e = assert_error(d.readout().await, ErrorKind::Device, Some(0x0606_0000));
    assert!(e.message.contains("hardware error"), "{e}");
    assert_eq!(d.readout().await.unwrap(), 0.0);
}

#[tokio::test]
async fn a_dropped_response_is_a_timeout_and_the_next_request_works() {
    let mut rig = Rig::fig8();
    let mut d = rig.connected().await;
    rig.client_aborts();
    rig.faults.arm(Fault::Drop);
    let t0 = tokio::time::Instant::now();
    let e = assert_error(d.readout().await, ErrorKind::Timeout, None);
    assert!(t0.elapsed() >= Duration::from_millis(200) && e.is_link(), "{e}");
    assert!(e.message.contains("0x6064:00"), "{e}");
    // The client told the node the transfer timed out.
    assert_eq!(rig.client_aborts(), [abort::TIMEOUT]);
    assert_eq!(d.readout().await.unwrap(), 0.0);
    // A dropped response to a write: the write happened, the driver timed out.
    rig.faults.arm(Fault::Drop);
    assert_error(d.set_velocity(5.0).await, ErrorKind::Timeout, None);
    assert_eq!(d.upload(index::PROFILE_VELOCITY, 0).await.unwrap(), 500_000u32.to_le_bytes());
}

#[tokio::test]
async fn garbled_responses_are_garbled_and_the_next_request_works() {
    let mut rig = Rig::fig8();
    let mut d = rig.connected().await;
    let table = CorrectionTable::new(vec![0.001; 16]).unwrap();
    rig.client_aborts();
    let cases: [(Garble, &str); 3] = [
        (Garble::Truncated, "4 data bytes"),
        (Garble::BadSpecifier, "unknown command specifier 7"),
        (Garble::FlipToggle, "toggle"),
    ];
    for (g, says) in cases {
        rig.faults.arm(garbled(g));
        let e = match g {
            Garble::FlipToggle => d.device_name().await.map(|_| ()),
            _ => d.readout().await.map(|_| ()),
        }
        .unwrap_err();
        assert_eq!(e.kind, ErrorKind::Garbled, "{g:?}: {e}");
        assert!(e.message.contains(says), "{g:?}: {e}");
        // The client aborted the transfer with the code for what went wrong.
        let code = if g == Garble::FlipToggle { abort::TOGGLE_BIT } else { abort::COMMAND_SPECIFIER };
        assert_eq!(rig.client_aborts(), [code], "{g:?}");
        assert_eq!(d.readout().await.unwrap(), 0.0);
        assert_eq!(d.device_name().await.unwrap(), DEVICE_NAME);
    }
    // A flipped toggle in a download segment response.
    rig.faults.arm(garbled(Garble::FlipToggle));
    assert_error(d.load_correction_table(&table).await, ErrorKind::Garbled, None);
    // A response echoing another object answers another transfer (a late
    // one): discarded, not taken (it was once taken and failed as garbled);
    // the transfer times out, and the client says so to the node.
    rig.client_aborts();
    rig.faults.arm(garbled(Garble::WrongIndex));
    assert_error(d.readout().await, ErrorKind::Timeout, None);
    assert_eq!(rig.client_aborts(), [abort::TIMEOUT]);
    rig.faults.arm(garbled(Garble::WrongIndex));
    assert_error(d.load_correction_table(&table).await, ErrorKind::Timeout, None);
    d.load_correction_table(&table).await.unwrap();
    assert_eq!(d.read_correction_table().await.unwrap().len(), 16);
}

#[tokio::test]
async fn silence_in_the_middle_of_a_segmented_transfer_times_out_and_recovers() {
    let mut rig = Rig::fig8();
    let mut d = rig.connected().await;
    // The initiate response and 2 segment responses, then silence.
    rig.faults.arm_n(Fault::Pass, 3);
    rig.faults.arm(Fault::Drop);
    let e = assert_error(d.device_name().await, ErrorKind::Timeout, None);
    assert!(e.message.contains("0x1008:00"), "{e}");
    assert_eq!(d.device_name().await.unwrap(), DEVICE_NAME);
    let table = CorrectionTable::new((0..100).map(|i| f64::from(i) * 1e-4).collect()).unwrap();
    rig.faults.arm_n(Fault::Pass, 6);
    rig.faults.arm(Fault::Drop);
    assert_error(d.load_correction_table(&table).await, ErrorKind::Timeout, None);
    assert_error(d.read_correction_table().await, ErrorKind::Usage, Some(abort::NO_DATA));
    d.load_correction_table(&table).await.unwrap();
    assert_eq!(d.read_correction_table().await.unwrap().len(), 100);
    drop(d);
    rig.bus.shut_down();
    let report = rig.node.take().unwrap().await.unwrap();
    // The client aborted both silent transfers (SDO protocol timed out).
    assert_eq!(report.client_aborts, 2, "{report:?}");
}

#[tokio::test]
async fn the_simulators_own_link_faults_show_on_the_bus() {
    // The first two sim calls (statusword reads of `connect`) time out and
    // drop: silence on the bus, the client aborts each transfer, and the
    // set-up asks each read again.
    let faults =
        PositionerFaults { timeout_on_call: Some(1), disconnect_on_call: Some(2), ..PositionerFaults::default() };
    let mut rig = Rig::new(PositionerConfig { faults, ..PositionerConfig::new(fig8()) });
    let mut d = Cia402Positioner::connect(rig.bus.endpoint(), driver_cfg()).await.unwrap();
    assert_eq!(rig.client_aborts(), [abort::TIMEOUT, abort::TIMEOUT]);
    assert_eq!(d.readout().await.unwrap(), 0.0);
    // Every sim call garbled: a garbled response.
    let faults = PositionerFaults { garbled_probability_per_call: 1.0, ..PositionerFaults::default() };
    let rig = Rig::new(PositionerConfig { faults, ..PositionerConfig::new(fig8()) });
    let mut d = rig.driver();
    assert_error(d.readout().await, ErrorKind::Garbled, None);
    // Objects that do not ask the sim still answer.
    assert_eq!(d.device_name().await.unwrap(), DEVICE_NAME);
}

#[tokio::test]
async fn a_stale_response_on_the_bus_is_not_taken_for_the_answer() {
    let mut rig = Rig::fig8();
    let mut d = rig.connected().await;
    let stale = SdoResponse::InitiateUpload {
        index: index::POSITION_ACTUAL,
        subindex: 0,
        data: InitData::Expedited { data: 999i32.to_le_bytes().to_vec(), size_indicated: true },
    };
    rig.monitor.send(CanFrame::full(0x580 + u16::from(NODE), stale.encode()).unwrap()).await.unwrap();
    // Another node's traffic is ignored too.
    rig.monitor.send(CanFrame::full(0x586, stale.encode()).unwrap()).await.unwrap();
    assert_eq!(d.readout().await.unwrap(), 0.0);
}

#[tokio::test]
async fn shutting_the_bus_down_is_a_disconnection() {
    let mut rig = Rig::fig8();
    let mut d = rig.connected().await;
    rig.bus.shut_down();
    let e = assert_error(d.readout().await, ErrorKind::Disconnected, None);
    assert!(e.is_link());
    let report = rig.node.take().unwrap().await.unwrap();
    assert!(report.sdo_requests > 5 && report.sdo_responses == report.sdo_requests, "{report:?}");
    assert_eq!(report.nmt_commands, 1);
}

#[tokio::test]
async fn random_frames_do_not_upset_the_node() {
    let mut rig = Rig::fig8();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(402);
    for _ in 0..1500 {
        let id = match rng.random_range(0..4) {
            0 => 0x000,
            1 => 0x600 + u16::from(NODE),
            2 => 0x580 + u16::from(NODE),
            _ => rng.random_range(0..=0x7FF),
        };
        let len = rng.random_range(0..=8);
        let data: Vec<u8> = (0..len).map(|_| rng.random()).collect();
        rig.monitor.send(CanFrame::new(id, &data).unwrap()).await.unwrap();
    }
    // Wait until the node has worked through them: start it and read 0x1000
    // with a request of our own; its answer comes after all the others.
    rig.monitor.send(nmt::encode_command(NmtCommand::Start, NODE)).await.unwrap();
    let marker = SdoRequest::InitiateUpload { index: index::DEVICE_TYPE, subindex: 0 };
    rig.monitor.send(CanFrame::full(0x600 + u16::from(NODE), marker.encode()).unwrap()).await.unwrap();
    let answered = async {
        loop {
            let f = rig.monitor.recv().await.unwrap();
            if f.id() == 0x580 + u16::from(NODE)
                && let Ok(SdoResponse::InitiateUpload { index: index::DEVICE_TYPE, .. }) = SdoResponse::decode(f.data())
            {
                return;
            }
        }
    };
    tokio::time::timeout(Duration::from_secs(10), answered).await.expect("the node answers after the barrage");
    let mut d = rig.driver();
    d.enable().await.unwrap();
    d.move_to(20.0).await.unwrap();
    settle(&mut d, &rig.clock).await;
    assert_eq!(d.readout().await.unwrap(), 20.0);
    assert_eq!(d.device_name().await.unwrap(), DEVICE_NAME);
}

/// The same exchange over SocketCAN on `vcan0`, where the kernel has CAN and
/// the interface exists; skipped with a printed reason otherwise.
#[tokio::test]
async fn the_driver_and_the_node_over_socketcan_vcan0() {
    let node_socket = match SocketCanBus::open_io("vcan0") {
        Ok(s) => s,
        Err(e) if is_can_unavailable(&e) => {
            println!("skipped: cannot open vcan0: {e} (this kernel has no AF_CAN, or there is no vcan0 interface)");
            return;
        }
        Err(e) => panic!("vcan0 exists but cannot be opened: {e}"),
    };
    let driver_socket = SocketCanBus::open("vcan0").unwrap();
    let clock = VirtualClock::new();
    let sim = SimPositioner::new(PositionerConfig::new(fig8()), Arc::new(clock.clone()));
    let node = tokio::spawn(serve(node_socket, sim, node_cfg(), Faults::new()));
    let mut d = Cia402Positioner::connect(driver_socket, driver_cfg()).await.unwrap();
    assert_eq!(d.device_name().await.unwrap(), DEVICE_NAME);
    d.move_to(12.5).await.unwrap();
    let s = settle(&mut d, &clock).await;
    assert!(s.in_position, "{s:?}");
    assert_eq!(d.readout().await.unwrap(), 12.5);
    node.abort();
}

/// The drive takes its time per transition (20 ms by default): a client that
/// reads the statusword a few times at once after each controlword, as the
/// driver once did, never sees operation enabled; the driver, which waits for
/// each transition (up to 0.5 s), does, and waits for 0x6061 to show the mode.
#[tokio::test]
async fn each_transition_takes_time_and_the_driver_waits_for_it() {
    let rig = Rig::fig8();
    let mut hasty = rig.driver();
    hasty.nmt(NmtCommand::Start).await.unwrap();
    hasty.download(index::MODES_OF_OPERATION, 0, &[1]).await.unwrap();
    assert_eq!(hasty.upload(index::MODES_OF_OPERATION_DISPLAY, 0).await.unwrap(), [0], "not yet shown");
    let mut state = hasty.statusword().await.unwrap().state();
    for _ in 0..6 {
        let c = match state {
            Some(DriveState::SwitchOnDisabled) => cw::SHUTDOWN,
            Some(DriveState::ReadyToSwitchOn) => cw::SWITCH_ON_CMD,
            _ => CW_OPERATE,
        };
        hasty.write_controlword(c).await.unwrap();
        state = hasty.statusword().await.unwrap().state();
    }
    assert_ne!(state, Some(DriveState::OperationEnabled), "six immediate polls are not enough");
    drop(hasty);

    let started = std::time::Instant::now();
    let mut d = rig.connected().await;
    assert!(d.statusword().await.unwrap().operation_enabled());
    assert_eq!(d.upload(index::MODES_OF_OPERATION_DISPLAY, 0).await.unwrap(), [1]);
    assert!(started.elapsed() >= 3 * crate::canopen_node::TRANSITION_TIME, "the driver waited for the transitions");
    d.move_to(20.0).await.unwrap();
    assert!(settle(&mut d, &rig.clock).await.in_position);
}

/// A drive too slow for the driver's transition timeout: a clear device
/// error naming the state it stayed in.
#[tokio::test]
async fn a_drive_slower_than_the_transition_timeout_is_a_clear_error() {
    let rig = Rig::with_node(
        PositionerConfig::new(fig8()),
        NodeConfig { transition_time: Duration::from_millis(300), ..node_cfg() },
    );
    let cfg = CanopenConfig { transition_timeout_ms: 50, ..driver_cfg() };
    let e = Cia402Positioner::connect(rig.bus.endpoint(), cfg).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Device, "{e}");
    assert!(e.message.contains("did not switch to profile position mode: 0x6061 shows 0"), "{e}");
}

/// A drive with the CiA 301/402 objects only (`NodeConfig::new`, the
/// driver's default configuration): enable, move, status, readout and its
/// fault work on the standard objects; this project's own objects are
/// absent (abort 0x06020000), so the driver neither reads them for the
/// status nor sends the table.
#[tokio::test]
async fn a_drive_with_only_the_standard_objects() {
    let faults = PositionerFaults { fault_on_move: Some(2), ..PositionerFaults::default() };
    let rig = Rig::with_node(PositionerConfig { faults, ..PositionerConfig::new(fig8()) }, NodeConfig::new(NODE));
    let standard = CanopenConfig { node_id: NODE, sdo_timeout_ms: 200, ..CanopenConfig::default() };
    let mut d = Cia402Positioner::connect(rig.bus.endpoint(), standard).await.unwrap();
    for object in [index::CORRECTION_TABLE, index::CORRECTION_ENABLE, index::FAULT_TEXT] {
        assert_error(d.upload(object, 0).await, ErrorKind::Device, Some(abort::NO_OBJECT));
    }
    d.move_to(20.0).await.unwrap();
    let s = settle(&mut d, &rig.clock).await;
    assert!(s.in_position && !s.correction_enabled && s.fault.is_none(), "{s:?}");
    assert_eq!(d.readout().await.unwrap(), 20.0);
    // The second move trips the drive: the fault's code, and the standard
    // text of 0x603F in place of 0x2102's.
    d.move_to(40.0).await.unwrap();
    let s = settle(&mut d, &rig.clock).await;
    let f = s.fault.expect("the drive tripped");
    assert_eq!(f.code, FAULT_FOLLOWING_ERROR);
    assert!(f.text.to_lowercase().contains("following error"), "{}", f.text);
    d.clear_fault().await.unwrap();
    let table = CorrectionTable::new(vec![0.001; 16]).unwrap();
    assert_error(d.load_correction_table(&table).await, ErrorKind::Usage, None);
    assert_error(d.enable_correction(true).await, ErrorKind::Usage, None);
    // The standard objects say nothing of a correction: unknown, not off.
    assert_eq!(d.correction_state().await.unwrap(), None);
}

/// A response held past the SDO deadline (a stall) and delivered after the
/// client's drain, in the middle of the next transfer, names its own object:
/// discarded, and the next transfer takes its own response. One held within
/// the drain is dropped there.
#[tokio::test]
async fn a_late_response_is_never_taken_for_the_next_transfer() {
    let rig = Rig::fig8();
    let mut d = rig.connected().await;
    // Within the drain (200 ms deadline, 100 ms drain).
    rig.faults.arm(Fault::Stall(Duration::from_millis(250)));
    let t0 = std::time::Instant::now();
    assert_error(d.readout().await, ErrorKind::Timeout, None);
    assert!(t0.elapsed() >= Duration::from_millis(300), "drained: {:?}", t0.elapsed());
    assert_eq!(d.device_name().await.unwrap(), DEVICE_NAME);
    // After the drain: it meets the next transfer.
    rig.faults.arm(Fault::Stall(Duration::from_millis(450)));
    assert_error(d.readout().await, ErrorKind::Timeout, None);
    assert_eq!(d.device_name().await.unwrap(), DEVICE_NAME);
    assert_eq!(d.readout().await.unwrap(), 0.0);
}
