//! `survey sim`: the simulated instruments of a configuration file, served
//! over their real protocols on the configured addresses, so `survey run
//! --config` and `survey check --config` (or pymodbus, or an integrator's own
//! software) talk to them as to the hardware, from another process.
//!
//! - TCP instruments (`scpi-tcp`, `modbus-tcp`, `emscon`) listen on their
//!   configured address when it is on loopback (port 0 takes a free port;
//!   the ready line says which), else on a free loopback port.
//! - Serial instruments (`scpi-serial`, `modbus-rtu`, `elcomat`) get a
//!   pseudo-terminal whose slave is linked at the configured `port` path (a
//!   symbolic link made here and removed on exit; an existing file there is
//!   never replaced), or in the sim's own folder for a device under `/dev/`.
//! - CAN (`canopen`) is served on the configured SocketCAN interface when this
//!   machine has it (a `vcan` interface on a machine with AF_CAN), else behind
//!   a simulated SLCAN adapter on a pseudo-terminal in the sim's folder.
//!
//! So a configuration written for the real bench is served as it is
//! ([`StandIns`]); [`Served::stand_ins`] writes the configuration to run
//! against, with the addresses served.
//!
//! The simulators run on a [`ScaledClock`]: `--time-scale X` makes every move,
//! settle and measurement X times faster than on the hardware. Faults at a
//! rate per kind ([`FaultRates`]; `--faults RATE` shares RATE among the link
//! kinds and gives it to each device kind): replies meet link faults
//! (dropped, garbled, cut, stalled past the client's timeout: [`relay`]),
//! requests are refused with the instrument's own code (armed in the
//! simulator by the relay: a Modbus exception 4, SDO abort 0x06060000, SCPI
//! error -310, emScon `ES_RS_SensorNotStable`; the ELCOMAT answers "no
//! reflection"), moves trip the drive and measurements break the beam (for
//! `beam_hold_s`). The relays are `survey_sims::relay`'s, the one layer that
//! injects link faults; [`Served::injected`] counts every kind. A model that
//! drifts drifts by its rate per run of the configuration's plan at the
//! simulated hardware's pace ([`Served::drift_run_s`]; `points` required).

mod stand_in;

pub use stand_in::StandIns;

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use survey_drivers::{Clock, ScaledClock};
use survey_processing::model::Model;
use survey_sims::autocollimator::AutocollimatorConfig;
use survey_sims::elcomat_server::{self, pty_pair};
use survey_sims::emscon_server;
use survey_sims::faults::{FaultKind, FaultRates, Faults, Injected};
use survey_sims::modbus_server::ModbusDevice;
use survey_sims::relay::{Ended, Framing, Relay, relay, relay_tcp};
use survey_sims::scpi_server;
use survey_sims::tracker::ArmGeometry;
use survey_sims::{Preset, SimBench, derive_seed};
use survey_store::config::{
    AutocollimatorConfig as AcConfig, CanLink, DEFAULT_CAN_BITRATE, PositionerConfig, SurveyConfig, TrackerConfig,
};
use survey_store::error::bad_input;
use tokio::net::TcpListener;
use tokio::task::JoinHandle;

/// How to serve.
#[derive(Debug, Clone)]
pub struct SimOptions {
    /// The positioner preset (`fig1`, `fig4`, `fig8`).
    pub preset: String,
    /// A model file instead of the preset's model.
    pub model: Option<Model>,
    /// Seed of every random draw.
    pub seed: u64,
    /// Faults per kind.
    pub faults: FaultRates,
    /// How many times faster than the hardware.
    pub time_scale: f64,
    /// Only this instrument's wire (`positioner`, `tracker`,
    /// `autocollimator`) meets link and device faults; `None`: every wire
    /// (what `survey sim` does). For tests that single out a wire.
    pub only: Option<String>,
}

/// The instruments being served; dropping it stops them and removes the links.
#[derive(Debug)]
pub struct Served {
    /// Where each instrument answers (`positioner`, `tracker`,
    /// `autocollimator`: an address or a path).
    pub instruments: serde_json::Map<String, serde_json::Value>,
    /// With a model that drifts: the simulator's time of one run, seconds
    /// (the drift grows by the model's rate per this much instrument time).
    pub drift_run_s: Option<f64>,
    /// Every fault injected, by kind: the relays' link faults, the device
    /// faults the simulators took, their own (moves tripped, beams broken,
    /// autocollimator reads blocked); and the replies relayed.
    pub faults: Injected,
    /// Where the instruments stand in for the configured ones, and the sim's folder.
    pub stand_ins: StandIns,
    tasks: Vec<JoinHandle<()>>,
    links: Vec<PathBuf>,
    /// The pty slave ends, kept open so the masters never read EIO while no
    /// client has the port open.
    _slaves: Vec<tokio_serial::SerialStream>,
}

impl Served {
    /// A serial instrument's line: a pty whose slave is linked at `port`;
    /// returns the stream the simulator serves on (the pty's master, or with
    /// faults the master of a second pty that a relay joins to it).
    fn serial(&mut self, what: &str, port: &str, relay: Option<Relay>) -> anyhow::Result<tokio_serial::SerialStream> {
        let (master, slave) = pty_at(what, port)?;
        self.links.push(PathBuf::from(port));
        self._slaves.push(slave);
        let Some(relay) = relay else { return Ok(master) };
        let (device_master, device_slave) = pty_pair()?;
        let port = PathBuf::from(port);
        self.tasks.push(tokio::spawn(serial_relay(master, device_slave, relay, port)));
        Ok(device_master)
    }

    /// For a TCP instrument: the listener the simulator serves on. Without a
    /// relay, the public one itself; with one, an inner one on a free
    /// loopback port, the public one relaying to it (one client at a time).
    async fn front(&mut self, public: TcpListener, relay: Option<Relay>) -> anyhow::Result<TcpListener> {
        let Some(relay) = relay else { return Ok(public) };
        let inner = TcpListener::bind("127.0.0.1:0").await?;
        let inner_addr = inner.local_addr()?;
        self.tasks.push(tokio::spawn(relay_tcp(public, inner_addr, relay)));
        Ok(inner)
    }

    /// Every fault injected so far, by kind (`timeout`, `garbled`,
    /// `disconnect`, `stall`, `device`, `move`, `beam`), and their total.
    pub fn injected(&self) -> (u64, serde_json::Map<String, serde_json::Value>) {
        let by_kind = self.faults.by_kind().into_iter().map(|(k, n)| (k.to_string(), n.into())).collect();
        (self.faults.total(), by_kind)
    }

    /// What `survey sim` prints when it stops: requests relayed, faults
    /// injected by kind and in all (`{"replies", "injected", "by_kind", ...}`
    /// with the relays' link faults and the device faults beside them).
    pub fn counts_json(&self) -> serde_json::Value {
        let (total, by_kind) = self.injected();
        let f = &self.faults;
        serde_json::json!({
            "replies": f.replies(),
            "dropped": f.get(FaultKind::Timeout),
            "garbled": f.get(FaultKind::Garbled),
            "disconnects": f.get(FaultKind::Disconnect),
            "stalls": f.get(FaultKind::Stall),
            "device": f.get(FaultKind::Device),
            "injected": total,
            "by_kind": by_kind,
        })
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        for t in &self.tasks {
            t.abort();
        }
        for l in &self.links {
            let _ = std::fs::remove_file(l);
        }
    }
}

impl Served {
    /// A loopback listener standing in for `section.key = address`; the
    /// address it listens on.
    async fn listen(&mut self, section: &'static str, address: &str) -> anyhow::Result<(TcpListener, String)> {
        let addr: SocketAddr = self.stand_ins.tcp(section, address)?;
        let listener = TcpListener::bind(addr).await.map_err(|e| {
            survey_store::error::path_error(e, format!("{section}: cannot listen on {addr}")).context("survey sim")
        })?;
        let public = listener.local_addr()?.to_string();
        self.stand_ins.served(section, "address", address, &public);
        Ok((listener, public))
    }

    /// The path a serial instrument of `section` is linked at for `port`.
    fn port(&mut self, section: &'static str, port: &str) -> String {
        let at = self.stand_ins.serial(section, port);
        self.stand_ins.served(section, "port", port, &at);
        at
    }
}

/// A pty whose slave is linked at `port`; returns the master and the slave.
fn pty_at(what: &str, port: &str) -> anyhow::Result<(tokio_serial::SerialStream, tokio_serial::SerialStream)> {
    let path = Path::new(port);
    if std::fs::symlink_metadata(path).is_ok() {
        return Err(bad_input(format!(
            "{what}: {port} exists; survey sim links its pseudo-terminal there and never replaces a file \
             (name a free path, e.g. /tmp/survey-{what}, in the configuration you rehearse with)"
        )));
    }
    let (master, slave) = pty_pair().map_err(|e| anyhow::anyhow!("{what}: cannot open a pseudo-terminal: {e}"))?;
    let slave_path = tokio_serial::SerialPort::name(&slave)
        .ok_or_else(|| anyhow::anyhow!("{what}: the pseudo-terminal has no path"))?;
    std::os::unix::fs::symlink(&slave_path, path)
        .map_err(|e| survey_store::error::path_error(e, format!("{what}: cannot link {port} to {slave_path}")))?;
    Ok((master, slave))
}

/// Serve the simulated instruments of `cfg`.
pub async fn serve(cfg: &SurveyConfig, opts: &SimOptions) -> anyhow::Result<Served> {
    if !(opts.time_scale.is_finite() && opts.time_scale > 0.0 && opts.time_scale <= 10_000.0) {
        return Err(bad_input(format!(
            "--time-scale must be above 0 and at most 10000, got {}",
            survey_processing::num::Num(opts.time_scale)
        )));
    }

    let preset = Preset::by_name(&opts.preset).ok_or_else(|| bad_input(format!("unknown preset '{}'", opts.preset)))?;
    let clock: Arc<dyn Clock> = Arc::new(ScaledClock::new(opts.time_scale));
    let mut builder = SimBench::builder(&preset, opts.seed, clock.clone())
        .travel(cfg.survey.travel_deg.map(|[lo, hi]| (lo, hi)).or(preset.travel));
    if let Some(model) = &opts.model {
        builder = builder.model(model.clone());
    }
    if let Some(arm) = &cfg.arm {
        builder = builder.arm(ArmGeometry { radius_mm: arm.radius_mm, ..ArmGeometry::default() });
    }
    let drift_run = drift_run_period(cfg, &preset, &builder)?;
    if let Some(period) = drift_run {
        builder = builder.drift_run_period(period);
    }
    if let Some(polygon) = &cfg.polygon {
        // The simulated polygon is the configured one: its faces and, when
        // given, its certificate (the engine corrects with the same).
        let mut ac = AutocollimatorConfig::seeded(polygon.faces, derive_seed(opts.seed, 3));
        if !polygon.certificate_arcsec.is_empty() {
            ac.certificate_arcsec = polygon.certificate_arcsec.clone();
        }
        builder = builder.autocollimator(ac);
    }
    // The link faults are the relays'; the simulators inject their own
    // device faults (drive trips, beam breaks, a blocked autocollimator),
    // set last so that no configuration above replaces them.
    let wired = |what: &str| opts.only.as_deref().is_none_or(|o| o == what);
    let blocked = if wired("autocollimator") { opts.faults.device } else { 0.0 };
    builder = builder.fault_rates(&FaultRates {
        timeout: 0.0,
        garbled: 0.0,
        disconnect: 0.0,
        stall: 0.0,
        device: blocked,
        ..opts.faults
    });
    let bench = builder.build();
    // A stalled reply is held past its client's deadline (real time): every
    // driver on a line without transaction id drains late replies after its
    // own deadline, and its stalled reply comes a little past the deadline,
    // a tenth into the drain (Modbus and CANopen name their deadline; SCPI's
    // and the ELCOMAT's are half the engine's); the tracker's connection
    // (TCP) is closed after a timeout: its stalled reply is held twice the
    // longer of the engine's deadlines.
    let call_timeout = cfg.timing().call_timeout;
    let measure_timeout = cfg.timing().measure_timeout;
    let stall = |own: std::time::Duration, late: std::time::Duration| own + own / 20 + late / 10;
    let positioner_stall = match cfg.positioner.own_deadline() {
        Some((_, own, late)) => stall(own, late),
        None => {
            let scpi = crate::instruments::scpi_timeouts(call_timeout);
            stall(scpi.request, scpi.late_window())
        }
    };
    let elcomat = crate::instruments::elcomat_timeout(measure_timeout);
    let elcomat_stall = stall(elcomat, elcomat / 2);
    let f = &opts.faults;
    let injected = bench.injected.clone();
    let mut seeds = (1u64..).map(|k| derive_seed(opts.seed, 100 + k));
    // The relay in front of an instrument (`None`: no fault reaches it),
    // sharing `faults` with its simulator; `device`: whether the relay arms
    // the instrument's device faults (the autocollimator's are its own).
    let mut relay_for = |what: &str, faults: &Faults, framing: Framing, device: bool| {
        let seed = seeds.next().unwrap_or(1);
        if !wired(what) {
            return None;
        }
        let rates = FaultRates {
            timeout: f.timeout,
            garbled: f.garbled,
            disconnect: f.disconnect,
            stall: f.stall,
            device: if device { f.device } else { 0.0 },
            ..FaultRates::default()
        };
        if !rates.any() {
            return None;
        }
        let stall_for = match what {
            "positioner" => positioner_stall,
            "autocollimator" => elcomat_stall,
            _ => (call_timeout * 2).max(measure_timeout * 2),
        };
        Some(Relay { faults: faults.clone(), rates, stall_for, framing, seed })
    };
    let mut served = Served {
        instruments: serde_json::Map::new(),
        drift_run_s: drift_run.map(|p| p.as_secs_f64()),
        faults: injected.clone(),
        stand_ins: StandIns::new()?,
        tasks: Vec::new(),
        links: Vec::new(),
        _slaves: Vec::new(),
    };

    // The positioner.
    match &cfg.positioner {
        PositionerConfig::ScpiTcp { address, controller, axis, .. } => {
            let (listener, public) = served.listen("positioner", address).await?;
            let faults = Faults::counting(injected.clone());
            let relay = relay_for("positioner", &faults, Framing::Lines, true);
            let listener = served.front(listener, relay).await?;
            let at = (*controller, *axis);
            served.tasks.push(tokio::spawn(scpi_server::serve_tcp_at(listener, bench.positioner, faults, at)));
            served.instruments.insert("positioner".into(), public.into());
        }
        PositionerConfig::ScpiSerial { port, controller, axis, .. } => {
            let faults = Faults::counting(injected.clone());
            let relay = relay_for("positioner", &faults, Framing::Lines, true);
            let port = served.port("positioner", port);
            let device = served.serial("positioner", &port, relay)?;
            let positioner = bench.positioner;
            let at = (*controller, *axis);
            served.tasks.push(tokio::spawn(async move {
                scpi_server::serve_stream(device, positioner, faults, at).await;
            }));
            served.instruments.insert("positioner".into(), port.into());
        }
        PositionerConfig::ModbusTcp { address, map, .. } => {
            let (listener, public) = served.listen("positioner", address).await?;
            let server = ModbusDevice::new(bench.positioner, map.clone())
                .map_err(|e| bad_input(format!("positioner.map: {e}")))?;
            let faults = Faults::counting(injected.clone());
            let relay = relay_for("positioner", &faults, Framing::ModbusTcp, true);
            let listener = served.front(listener, relay).await?;
            served.tasks.push(tokio::spawn(async move {
                if let Err(e) = server.serve_tcp(listener, faults).await {
                    tracing::error!(%e, "modbus simulator stopped");
                }
            }));
            served.instruments.insert("positioner".into(), public.into());
        }
        PositionerConfig::ModbusRtu { port, map, slave: address, .. } => {
            let faults = Faults::counting(injected.clone());
            let relay = relay_for("positioner", &faults, Framing::ModbusRtu, true);
            let port = served.port("positioner", port);
            let device = served.serial("positioner", &port, relay)?;
            // On a serial line the slave address is the unit (as the driver does).
            let map = survey_drivers::modbus::RegisterMap { unit_id: *address, ..map.clone() };
            let server =
                ModbusDevice::new(bench.positioner, map).map_err(|e| bad_input(format!("positioner.map: {e}")))?;
            served.tasks.push(tokio::spawn(async move {
                server.serve_rtu(device, faults).await;
            }));
            served.instruments.insert("positioner".into(), port.into());
        }
        PositionerConfig::Canopen { drive, .. } => {
            let mut node = survey_sims::canopen_node::NodeConfig::new(drive.node_id);
            node.counts_per_degree = drive.counts_per_degree;
            // A drive with this project's own objects when the configuration
            // says so; else one with the standard objects only.
            node.correction_objects = drive.correction_objects;
            let positioner = bench.positioner;
            let faults = Faults::counting(injected.clone());
            let link = match cfg.positioner.can_link() {
                Some(Ok(link)) => link,
                Some(Err(e)) => return Err(bad_input(e)),
                None => unreachable!("a CANopen configuration has a CAN link"),
            };
            let link = match link {
                // No such interface here: the drive behind a simulated adapter.
                CanLink::SocketCan(interface) if !Path::new("/sys/class/net").join(&interface).exists() => {
                    let port = served.stand_ins.dir().join("positioner").display().to_string();
                    served.stand_ins.served("positioner", "transport", "socketcan", "slcan");
                    served.stand_ins.served("positioner", "port", &interface, &port);
                    served.stand_ins.removed("positioner", "interface");
                    CanLink::Slcan { port, bitrate: DEFAULT_CAN_BITRATE }
                }
                CanLink::Slcan { port, bitrate } => CanLink::Slcan { port: served.port("positioner", &port), bitrate },
                link => link,
            };
            match link {
                CanLink::Slcan { port, .. } => {
                    // A CiA 402 drive behind a simulated USB-CAN adapter, on a
                    // pty linked at the port (link faults on the serial line,
                    // on the replies among the adapter's messages).
                    let relay = relay_for("positioner", &faults, Framing::SlcanCanopen, true);
                    let device = served.serial("positioner", &port, relay)?;
                    let bus = survey_drivers::canopen::MemoryBus::new();
                    let (drive_end, adapter_end) = (bus.endpoint(), bus.endpoint());
                    served.tasks.push(tokio::spawn(async move {
                        survey_sims::canopen_node::serve(drive_end, positioner, node, faults).await;
                    }));
                    served.tasks.push(tokio::spawn(async move {
                        survey_sims::slcan_adapter::serve_adapter(device, adapter_end).await;
                        drop(bus);
                    }));
                    served.instruments.insert("positioner".into(), port.clone().into());
                }
                CanLink::SocketCan(interface) => {
                    let bus = survey_drivers::canopen::SocketCanBus::open(&interface).map_err(|e| {
                        anyhow::anyhow!(
                            "positioner: cannot open the SocketCAN interface {interface} ({e}); survey sim serves a \
                             CANopen drive on an existing interface (ip link add dev {interface} type vcan; ip link \
                             set up {interface}), or behind a simulated USB-CAN adapter with transport = \"slcan\""
                        )
                    })?;
                    served.tasks.push(tokio::spawn(async move {
                        // No relay on the kernel's bus: link and armed device
                        // faults reach a CANopen drive on its SLCAN line only
                        // (its drive trips are the simulator's, here too).
                        survey_sims::canopen_node::serve(bus, positioner, node, faults).await;
                    }));
                    served
                        .instruments
                        .insert("positioner".into(), format!("{interface} node {}", drive.node_id).into());
                }
            }
        }
    }

    // The reference instruments (both may be configured; each is served).
    if let Some(TrackerConfig::Emscon { address, .. }) = &cfg.tracker {
        let (listener, public) = served.listen("tracker", address).await?;
        let faults = Faults::counting(injected.clone());
        let relay = relay_for("tracker", &faults, Framing::Emscon, true);
        let listener = served.front(listener, relay).await?;
        served.tasks.push(tokio::spawn(emscon_server::serve_tcp(listener, bench.tracker, faults)));
        served.instruments.insert("tracker".into(), public.into());
    }
    if let Some(AcConfig::Elcomat { port, .. }) = &cfg.autocollimator {
        // Its device fault is the simulated autocollimator's: a blocked view,
        // answered "no reflection".
        let relay = relay_for("autocollimator", &Faults::counting(injected.clone()), Framing::Lines, false);
        let port = served.port("autocollimator", port);
        let device = served.serial("autocollimator", &port, relay)?;
        let instrument = bench.autocollimator;
        served.tasks.push(tokio::spawn(async move {
            elcomat_server::serve(device, instrument).await;
        }));
        served.instruments.insert("autocollimator".into(), port.into());
    }
    Ok(served)
}

/// The instrument time of one run when the model drifts (the contract's
/// drift grows by its rate from one run to the next): the configuration's
/// plan at the simulated hardware's pace (the preset's moves and settle, the
/// configured dwell and poll, the reference's measurement), as the simulated
/// bench of `survey run` estimates it. `None` without a drift. Under
/// `--time-scale` a client's own waits (dwell, polling, round trips) are real
/// time, so a run then takes longer in the simulator's time than this.
fn drift_run_period(
    cfg: &SurveyConfig,
    preset: &Preset,
    builder: &survey_sims::SimBenchBuilder,
) -> anyhow::Result<Option<std::time::Duration>> {
    let rate = builder.positioner.model.drift_deg_per_run();
    if rate == 0.0 {
        return Ok(None);
    }
    if cfg.survey.points.is_none() {
        return Err(bad_input(format!(
            "the model drifts {rate} deg per run, and survey sim needs the length of a run: set `points` (and \
             `runs`) in the [survey] section of the configuration"
        )));
    }
    let plan = crate::configured_plan(cfg, crate::PlanOverrides::default(), Path::new("the configuration"))?;
    let t = cfg.timing();
    let measure = match cfg.reference() {
        survey_acquire::ReferenceKind::Tracker => builder.tracker.measurement_time,
        survey_acquire::ReferenceKind::Autocollimator => builder.autocollimator.read_time,
    };
    let per_target = preset.settle + t.dwell + measure + t.poll_interval;
    Ok(Some(plan.estimate_run_duration(preset.velocity_deg_s, preset.accel_deg_s2, per_target)))
}

/// A serial line's relay. A serial line has no connection to close, so an
/// injected disconnect is the line unplugged and plugged in again, as a USB
/// adapter is: the client's pty is closed (its reads fail: the port is gone)
/// and a new pty is linked at the same path, which the client's reconnect
/// opens. The simulator behind it keeps its own line. Our own design.
async fn serial_relay(
    mut master: tokio_serial::SerialStream,
    mut device: tokio_serial::SerialStream,
    relay_cfg: Relay,
    port: PathBuf,
) {
    // The slave end of the current pty, kept open (see `Served::_slaves`).
    let mut _slave = None;
    for k in 0u64.. {
        let cfg = if k == 0 { relay_cfg.clone() } else { relay_cfg.reseeded(derive_seed(relay_cfg.seed, k)) };
        if relay(master, &mut device, &cfg).await != Ended::Disconnect {
            return;
        }
        // Unplugged (the old master is closed); plugged in again.
        let Ok((m, s)) = pty_pair() else { return };
        let Some(path) = tokio_serial::SerialPort::name(&s) else { return };
        let _ = std::fs::remove_file(&port);
        if let Err(e) = std::os::unix::fs::symlink(&path, &port) {
            tracing::error!(%e, port = %port.display(), "sim: cannot link the serial line again");
            return;
        }
        tracing::info!(port = %port.display(), "sim: the serial line is back after a disconnect");
        master = m;
        _slave = Some(s);
    }
}
