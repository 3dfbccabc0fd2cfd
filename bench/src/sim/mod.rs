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
//! `beam_hold_s`). The relays are `survey_sim_servers::relay`'s, the one layer that
//! injects link faults; [`Served::injected`] counts every kind. A model that
//! drifts drifts by its rate per run of the configuration's plan at the
//! simulated hardware's pace ([`Served::drift_run_s`]; `points` required).

mod stand_in;

pub use stand_in::StandIns;

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;
use survey_drivers::{Clock, ScaledClock};
use survey_positioner_drivers::canopen::CanopenConfig;
use survey_processing::model::Model;
use survey_sim_servers::elcomat_server::{self, pty_pair};
use survey_sim_servers::emscon_server;
use survey_sim_servers::modbus_server::ModbusDevice;
use survey_sim_servers::relay::{Ended, Framing, Relay, relay, relay_tcp};
use survey_sim_servers::scpi_server;
use survey_sims::autocollimator::AutocollimatorConfig;
use survey_sims::faults::{FaultKind, FaultRates, Faults, Injected};
use survey_sims::tracker::ArmGeometry;
use survey_sims::{Preset, SimAutocollimator, SimBench, SimPositioner, SimTracker, derive_seed};
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

/// Serve the simulated instruments of `cfg`: the bench is built on the
/// scaled clock, then the positioner, the tracker and the autocollimator
/// configured are served, each behind the relay that injects its link
/// faults.
pub async fn serve(cfg: &SurveyConfig, opts: &SimOptions) -> anyhow::Result<Served> {
    if !(opts.time_scale.is_finite() && opts.time_scale > 0.0 && opts.time_scale <= 10_000.0) {
        return Err(bad_input(format!(
            "--time-scale must be above 0 and at most 10000, got {}",
            survey_processing::num::Num(opts.time_scale)
        )));
    }
    let (bench, drift_run) = simulated_bench(cfg, opts)?;
    let mut relays = Relays::new(cfg, opts);
    let mut served = Served {
        instruments: serde_json::Map::new(),
        drift_run_s: drift_run.map(|p| p.as_secs_f64()),
        faults: bench.injected.clone(),
        stand_ins: StandIns::new()?,
        tasks: Vec::new(),
        links: Vec::new(),
        _slaves: Vec::new(),
    };
    served.stand_ins.time_scale(opts.time_scale);
    served.stand_ins.rehearsal(format!(
        "survey sim {}, preset {}{}, seed {}, {}x real time",
        env!("CARGO_PKG_VERSION"),
        opts.preset,
        if opts.model.is_some() { " (a model file)" } else { "" },
        opts.seed,
        opts.time_scale
    ));
    if let Some(frame) = opts.model.as_ref().and_then(|m| m.machine_frame.as_ref()) {
        if cfg.reference() == survey_acquire::ReferenceKind::Tracker {
            served.stand_ins.machine_frame(frame, cfg.machine_frame.is_some());
        } else {
            served.stand_ins.moved.push(
                "machine_frame: the model file's is left out (it locates the axis for the tracker; the reference is \
                 the autocollimator)"
                    .into(),
            );
        }
    }
    served.positioner(cfg, bench.positioner, &mut relays).await?;
    // The reference instruments (both may be configured; each is served).
    if let Some(TrackerConfig::Emscon { address, .. }) = &cfg.tracker {
        served.tracker(address, bench.tracker, &mut relays).await?;
    }
    if let Some(AcConfig::Elcomat { port, .. }) = &cfg.autocollimator {
        served.autocollimator(port, bench.autocollimator, &mut relays)?;
    }
    Ok(served)
}

impl SimOptions {
    /// Whether the wire of `what` (`positioner`, `tracker`,
    /// `autocollimator`) meets faults ([`SimOptions::only`]).
    fn wired(&self, what: &str) -> bool {
        self.only.as_deref().is_none_or(|o| o == what)
    }
}

/// The simulated bench of `cfg` on a clock scaled by `--time-scale`: the
/// preset's positioner (or the model given) over the configured travel,
/// the configured arm and polygon, and the simulators' own device faults;
/// with the instrument time of one run when the model drifts
/// ([`drift_run_period`]).
fn simulated_bench(cfg: &SurveyConfig, opts: &SimOptions) -> anyhow::Result<(SimBench, Option<Duration>)> {
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
    // The configured SMRs on the simulated table (each where `[smrs]` puts it).
    if let Some(smrs) = &cfg.smrs {
        builder.tracker.arm.smrs = smrs.mounts();
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
    let blocked = if opts.wired("autocollimator") { opts.faults.device } else { 0.0 };
    builder = builder.fault_rates(&FaultRates {
        timeout: 0.0,
        garbled: 0.0,
        disconnect: 0.0,
        stall: 0.0,
        device: blocked,
        ..opts.faults
    });
    Ok((builder.build(), drift_run))
}

/// What the relays in front of the instruments are made of: the link and
/// device fault rates, the wires that meet them, how long each
/// instrument's stalled reply is held, and the seeds, one a relay in turn.
struct Relays<'a> {
    opts: &'a SimOptions,
    /// The positioner's stalled reply is held this long, real time.
    positioner_stall: Duration,
    /// The autocollimator's.
    elcomat_stall: Duration,
    /// The tracker's.
    tracker_stall: Duration,
    /// How many relays were asked for: the next one's seed is derived from it.
    asked: u64,
}

impl<'a> Relays<'a> {
    /// The relays of `cfg`'s instruments, at the rates and from the seed of
    /// `opts`. A stalled reply is held past its client's deadline (real
    /// time): every driver on a line without transaction id drains late
    /// replies after its own deadline, and its stalled reply comes a little
    /// past the deadline, a tenth into the drain (Modbus and CANopen name
    /// their deadline; SCPI's and the ELCOMAT's are half the engine's); the
    /// tracker's connection (TCP) is closed after a timeout: its stalled
    /// reply is held twice the longer of the engine's deadlines.
    fn new(cfg: &SurveyConfig, opts: &'a SimOptions) -> Self {
        let call_timeout = cfg.timing().call_timeout;
        let measure_timeout = cfg.timing().measure_timeout;
        let stall = |own: Duration, late: Duration| own + own / 20 + late / 10;
        let positioner_stall = match cfg.positioner.own_deadline() {
            Some((_, own, late)) => stall(own, late),
            None => {
                let scpi = crate::instruments::scpi_timeouts(call_timeout);
                stall(scpi.request, scpi.late_window())
            }
        };
        let elcomat = crate::instruments::elcomat_timeout(measure_timeout);
        Relays {
            opts,
            positioner_stall,
            elcomat_stall: stall(elcomat, elcomat / 2),
            tracker_stall: (call_timeout * 2).max(measure_timeout * 2),
            asked: 0,
        }
    }

    /// The relay in front of `what` (`None`: not on a wire of ours), sharing
    /// `faults` with its simulator; `device`: whether the relay arms the
    /// instrument's device faults (the autocollimator's are its own). Each
    /// call takes the next seed, whether or not it makes a relay.
    fn front_of(&mut self, what: &str, faults: &Faults, framing: Framing, device: bool) -> Option<Relay> {
        self.asked += 1;
        let seed = derive_seed(self.opts.seed, 100 + self.asked);
        if !self.opts.wired(what) {
            return None;
        }
        let f = &self.opts.faults;
        let rates = FaultRates {
            timeout: f.timeout,
            garbled: f.garbled,
            disconnect: f.disconnect,
            stall: f.stall,
            device: if device { f.device } else { 0.0 },
            ..FaultRates::default()
        };
        // Without fault rates the relay passes every reply as it is, and
        // counts it: `replies` says what was served.
        let stall_for = match what {
            "positioner" => self.positioner_stall,
            "autocollimator" => self.elcomat_stall,
            _ => self.tracker_stall,
        };
        Some(Relay { faults: faults.clone(), rates, stall_for, framing, seed })
    }
}

impl Served {
    /// The positioner, on a loopback listener (TCP) or a linked pty
    /// (serial), behind its relay; a CANopen drive as [`Served::canopen`]
    /// serves it.
    async fn positioner(
        &mut self,
        cfg: &SurveyConfig,
        positioner: SimPositioner,
        relays: &mut Relays<'_>,
    ) -> anyhow::Result<()> {
        let at = match &cfg.positioner {
            PositionerConfig::ScpiTcp { address, controller, axis, .. } => {
                let (listener, public) = self.listen("positioner", address).await?;
                let faults = Faults::counting(self.faults.clone());
                let relay = relays.front_of("positioner", &faults, Framing::Lines, true);
                let listener = self.front(listener, relay).await?;
                let at = (*controller, *axis);
                self.tasks.push(tokio::spawn(scpi_server::serve_tcp_at(listener, positioner, faults, at)));
                public
            }
            PositionerConfig::ScpiSerial { port, controller, axis, .. } => {
                let faults = Faults::counting(self.faults.clone());
                let relay = relays.front_of("positioner", &faults, Framing::Lines, true);
                let port = self.port("positioner", port);
                let device = self.serial("positioner", &port, relay)?;
                let at = (*controller, *axis);
                self.tasks.push(tokio::spawn(async move {
                    scpi_server::serve_stream(device, positioner, faults, at).await;
                }));
                port
            }
            PositionerConfig::ModbusTcp { address, map, .. } => {
                let (listener, public) = self.listen("positioner", address).await?;
                let server = ModbusDevice::new(positioner, map.clone())
                    .map_err(|e| bad_input(format!("positioner.map: {e}")))?;
                let faults = Faults::counting(self.faults.clone());
                let relay = relays.front_of("positioner", &faults, Framing::ModbusTcp, true);
                let listener = self.front(listener, relay).await?;
                self.tasks.push(tokio::spawn(async move {
                    if let Err(e) = server.serve_tcp(listener, faults).await {
                        tracing::error!(%e, "modbus simulator stopped");
                    }
                }));
                public
            }
            PositionerConfig::ModbusRtu { port, map, slave: address, .. } => {
                let faults = Faults::counting(self.faults.clone());
                let relay = relays.front_of("positioner", &faults, Framing::ModbusRtu, true);
                let port = self.port("positioner", port);
                let device = self.serial("positioner", &port, relay)?;
                // On a serial line the slave address is the unit (as the driver does).
                let map = survey_positioner_drivers::modbus::RegisterMap { unit_id: *address, ..map.clone() };
                let server =
                    ModbusDevice::new(positioner, map).map_err(|e| bad_input(format!("positioner.map: {e}")))?;
                self.tasks.push(tokio::spawn(async move {
                    server.serve_rtu(device, faults).await;
                }));
                port
            }
            PositionerConfig::Canopen { drive, .. } => return self.canopen(&cfg.positioner, drive, positioner, relays),
        };
        self.instruments.insert("positioner".into(), at.into());
        Ok(())
    }

    /// A CiA 402 drive: on the configured SocketCAN interface when this
    /// machine has it, else behind a simulated USB-CAN adapter on a pty
    /// (in the sim's folder for a missing interface, at the configured port
    /// for `slcan`).
    fn canopen(
        &mut self,
        cfg: &PositionerConfig,
        drive: &CanopenConfig,
        positioner: SimPositioner,
        relays: &mut Relays<'_>,
    ) -> anyhow::Result<()> {
        let mut node = survey_sim_servers::canopen_node::NodeConfig::new(drive.node_id);
        node.counts_per_degree = drive.counts_per_degree;
        // A drive with this project's own objects when the configuration
        // says so; else one with the standard objects only.
        node.correction_objects = drive.correction_objects;
        let faults = Faults::counting(self.faults.clone());
        match self.can_link(cfg)? {
            CanLink::Slcan { port, .. } => {
                // A CiA 402 drive behind a simulated USB-CAN adapter, on a
                // pty linked at the port (link faults on the serial line,
                // on the replies among the adapter's messages).
                let relay = relays.front_of("positioner", &faults, Framing::SlcanCanopen, true);
                let device = self.serial("positioner", &port, relay)?;
                let bus = survey_positioner_drivers::canopen::MemoryBus::new();
                let (drive_end, adapter_end) = (bus.endpoint(), bus.endpoint());
                self.tasks.push(tokio::spawn(async move {
                    survey_sim_servers::canopen_node::serve(drive_end, positioner, node, faults).await;
                }));
                self.tasks.push(tokio::spawn(async move {
                    survey_sim_servers::slcan_adapter::serve_adapter(device, adapter_end).await;
                    drop(bus);
                }));
                self.instruments.insert("positioner".into(), port.clone().into());
            }
            CanLink::SocketCan(interface) => {
                let bus = survey_positioner_drivers::canopen::SocketCanBus::open(&interface).map_err(|e| {
                    anyhow::anyhow!(
                        "positioner: cannot open the SocketCAN interface {interface} ({e}); survey sim serves a \
                         CANopen drive on an existing interface (ip link add dev {interface} type vcan; ip link \
                         set up {interface}), or behind a simulated USB-CAN adapter with transport = \"slcan\""
                    )
                })?;
                self.tasks.push(tokio::spawn(async move {
                    // No relay on the kernel's bus: link and armed device
                    // faults reach a CANopen drive on its SLCAN line only
                    // (its drive trips are the simulator's, here too).
                    survey_sim_servers::canopen_node::serve(bus, positioner, node, faults).await;
                }));
                self.instruments.insert("positioner".into(), format!("{interface} node {}", drive.node_id).into());
            }
        }
        Ok(())
    }

    /// Where a CANopen drive is served: its configured CAN link, but a
    /// SocketCAN interface this machine lacks becomes a simulated adapter's
    /// pty in the sim's folder, and an SLCAN port the path a pty is linked
    /// at (both said in the stand-ins).
    fn can_link(&mut self, cfg: &PositionerConfig) -> anyhow::Result<CanLink> {
        let link = match cfg.can_link() {
            Some(Ok(link)) => link,
            Some(Err(e)) => return Err(bad_input(e)),
            None => unreachable!("a CANopen configuration has a CAN link"),
        };
        Ok(match link {
            // No such interface here: the drive behind a simulated adapter.
            CanLink::SocketCan(interface) if !Path::new("/sys/class/net").join(&interface).exists() => {
                let port = self.stand_ins.dir().join("positioner").display().to_string();
                self.stand_ins.served("positioner", "transport", "socketcan", "slcan");
                self.stand_ins.served("positioner", "port", &interface, &port);
                self.stand_ins.removed("positioner", "interface");
                CanLink::Slcan { port, bitrate: DEFAULT_CAN_BITRATE }
            }
            CanLink::Slcan { port, bitrate } => CanLink::Slcan { port: self.port("positioner", &port), bitrate },
            link => link,
        })
    }

    /// The emScon tracker on a loopback listener standing in for `address`,
    /// behind its relay.
    async fn tracker(&mut self, address: &str, tracker: SimTracker, relays: &mut Relays<'_>) -> anyhow::Result<()> {
        let (listener, public) = self.listen("tracker", address).await?;
        let faults = Faults::counting(self.faults.clone());
        let relay = relays.front_of("tracker", &faults, Framing::Emscon, true);
        let listener = self.front(listener, relay).await?;
        self.tasks.push(tokio::spawn(emscon_server::serve_tcp(listener, tracker, faults)));
        self.instruments.insert("tracker".into(), public.into());
        Ok(())
    }

    /// The ELCOMAT on a pty linked at `port`, behind its relay. Its device
    /// fault is the simulated autocollimator's: a blocked view, answered
    /// "no reflection".
    fn autocollimator(
        &mut self,
        port: &str,
        instrument: SimAutocollimator,
        relays: &mut Relays<'_>,
    ) -> anyhow::Result<()> {
        let relay = relays.front_of("autocollimator", &Faults::counting(self.faults.clone()), Framing::Lines, false);
        let port = self.port("autocollimator", port);
        let device = self.serial("autocollimator", &port, relay)?;
        self.tasks.push(tokio::spawn(async move {
            elcomat_server::serve(device, instrument).await;
        }));
        self.instruments.insert("autocollimator".into(), port.into());
        Ok(())
    }
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
