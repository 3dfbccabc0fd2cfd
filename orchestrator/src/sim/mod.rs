//! `survey sim`: the simulated instruments of a configuration file, served
//! over their real protocols on the configured addresses, so `survey run
//! --config` and `survey check --config` (or pymodbus, or an integrator's own
//! software) talk to them as to the hardware, from another process.
//!
//! - TCP instruments (`scpi-tcp`, `modbus-tcp`, `emscon`) listen on their
//!   configured address, which must be on loopback (port 0 takes a free port;
//!   the ready line says which).
//! - Serial instruments (`scpi-serial`, `modbus-rtu`, `elcomat`) get a
//!   pseudo-terminal whose slave is linked at the configured `port` path (a
//!   symbolic link made here and removed on exit; an existing file there is
//!   never replaced).
//! - CAN (`canopen`) is served on the configured SocketCAN interface, which
//!   must exist (a `vcan` interface on a machine with AF_CAN).
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
//! `beam_hold_s`). [`Served::injected`] counts every kind. A model that
//! drifts drifts by its rate per run of the configuration's plan at the
//! simulated hardware's pace ([`Served::drift_run_s`]; `points` required).

pub mod relay;

use crate::config::{AutocollimatorConfig as AcConfig, CanLink, PositionerConfig, SurveyConfig, TrackerConfig};
use crate::error::bad_input;
use relay::{Counts, DeviceArm, Framing, LinkFaults, relay_with};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use survey_drivers::{Clock, ScaledClock};
use survey_processing::model::Model;
use survey_sims::autocollimator::AutocollimatorConfig;
use survey_sims::elcomat_server::{self, ElcomatFaults, pty_pair};
use survey_sims::emscon_server::{self, EmsconFaults};
use survey_sims::faults::{FaultKind, FaultRates, Injected};
use survey_sims::modbus_server::{ModbusDevice, ModbusFaults};
use survey_sims::scpi_server::{self, ScpiFaults};
use survey_sims::tracker::ArmGeometry;
use survey_sims::{Preset, SimBench, derive_seed};
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
    /// What the link-fault relays did.
    pub counts: Arc<Counts>,
    /// What the simulated instruments injected themselves (moves tripped,
    /// beams broken, autocollimator reads blocked).
    pub sims: Injected,
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
    fn serial(
        &mut self,
        what: &str,
        port: &str,
        link: LinkFaults,
        arm: Option<DeviceArm>,
        seed: u64,
    ) -> anyhow::Result<tokio_serial::SerialStream> {
        let (master, slave) = pty_at(what, port)?;
        self.links.push(PathBuf::from(port));
        self._slaves.push(slave);
        if !link.any() && arm.is_none() {
            return Ok(master);
        }
        let (device_master, device_slave) = pty_pair()?;
        let counts = self.counts.clone();
        let port = PathBuf::from(port);
        self.tasks.push(tokio::spawn(serial_relay(master, device_slave, link, arm, seed, counts, port)));
        Ok(device_master)
    }

    /// Every fault injected so far, by kind (`timeout`, `garbled`,
    /// `disconnect`, `stall`, `device`, `move`, `beam`), and their total.
    pub fn injected(&self) -> (u64, serde_json::Map<String, serde_json::Value>) {
        let get = |c: &std::sync::atomic::AtomicU64| c.load(std::sync::atomic::Ordering::Relaxed);
        let c = &self.counts;
        let by_kind: Vec<(&str, u64)> = vec![
            ("timeout", get(&c.dropped)),
            ("garbled", get(&c.garbled)),
            ("disconnect", get(&c.disconnects)),
            ("stall", get(&c.stalls)),
            ("device", get(&c.device) + self.sims.get(FaultKind::Device)),
            ("move", self.sims.get(FaultKind::Move)),
            ("beam", self.sims.get(FaultKind::Beam)),
        ];
        let total = by_kind.iter().map(|(_, n)| n).sum();
        (total, by_kind.into_iter().map(|(k, n)| (k.to_string(), n.into())).collect())
    }

    /// What `survey sim` prints when it stops: requests relayed, faults
    /// injected by kind and in all (`{"replies", "injected", "by_kind", ...}`
    /// with the relays' own counts beside them).
    pub fn counts_json(&self) -> serde_json::Value {
        let (total, by_kind) = self.injected();
        let mut doc = self.counts.json();
        doc["injected"] = total.into();
        doc["by_kind"] = by_kind.into();
        doc
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

/// A loopback listener at `address` (`host:port`; port 0 takes a free one).
async fn listen(what: &str, address: &str) -> anyhow::Result<TcpListener> {
    let addr: SocketAddr = tokio::net::lookup_host(address)
        .await
        .ok()
        .and_then(|mut a| a.next())
        .ok_or_else(|| bad_input(format!("{what}: '{address}' is not a host:port address")))?;
    if !addr.ip().is_loopback() {
        return Err(bad_input(format!(
            "{what}: survey sim serves on loopback only, and {address} is not a loopback address \
             (use 127.0.0.1:PORT in the configuration you rehearse with)"
        )));
    }
    TcpListener::bind(addr)
        .await
        .map_err(|e| crate::error::path_error(e, format!("{what}: cannot listen on {address}")).context("survey sim"))
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
        .map_err(|e| crate::error::path_error(e, format!("{what}: cannot link {port} to {slave_path}")))?;
    Ok((master, slave))
}

/// Serve the simulated instruments of `cfg`.
pub async fn serve(cfg: &SurveyConfig, opts: &SimOptions) -> anyhow::Result<Served> {
    if !(opts.time_scale.is_finite() && opts.time_scale > 0.0 && opts.time_scale <= 10_000.0) {
        return Err(bad_input(format!("--time-scale must be above 0 and at most 10000, got {}", opts.time_scale)));
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
    // A stalled reply is held twice the client's call timeout (real time).
    let call_timeout = cfg.timing().call_timeout;
    let f = &opts.faults;
    let link_all = if f.any_link() {
        LinkFaults {
            drop: f.timeout,
            garble: f.garbled,
            disconnect: f.disconnect,
            stall: f.stall,
            stall_for: call_timeout * 2,
            framing: Framing::Chunks,
        }
    } else {
        LinkFaults::NONE
    };
    // A reference instrument's measurement is bounded by measure_timeout_s:
    // its stalled reply is held twice the longer of the two deadlines.
    let measure_timeout = cfg.timing().measure_timeout;
    let link = |what: &str| match (wired(what), what) {
        (false, _) => LinkFaults::NONE,
        (true, "positioner") => link_all,
        (true, _) => LinkFaults { stall_for: link_all.stall_for.max(measure_timeout * 2), ..link_all },
    };
    let arm = |what: &str, rate: f64, arm: Arc<dyn Fn() + Send + Sync>| {
        (rate > 0.0 && wired(what)).then_some(DeviceArm { rate, arm })
    };
    let counts = Arc::new(Counts::default());
    let mut served = Served {
        instruments: serde_json::Map::new(),
        drift_run_s: drift_run.map(|p| p.as_secs_f64()),
        counts: counts.clone(),
        sims: bench.injected.clone(),
        tasks: Vec::new(),
        links: Vec::new(),
        _slaves: Vec::new(),
    };
    let mut seeds = (1u64..).map(|k| derive_seed(opts.seed, 100 + k));

    // The positioner.
    match &cfg.positioner {
        PositionerConfig::ScpiTcp { address, controller, axis, .. } => {
            let listener = listen("positioner", address).await?;
            let public = listener.local_addr()?.to_string();
            let faults = ScpiFaults::new();
            let armed = arm("positioner", f.device, scpi_arm(&faults));
            let listener =
                front(listener, link("positioner"), armed, seeds.next().unwrap_or(1), &counts, &mut served).await?;
            let at = (*controller, *axis);
            served.tasks.push(tokio::spawn(scpi_server::serve_tcp_at(listener, bench.positioner, faults, at)));
            served.instruments.insert("positioner".into(), public.into());
        }
        PositionerConfig::ScpiSerial { port, controller, axis, .. } => {
            let faults = ScpiFaults::new();
            let armed = arm("positioner", f.device, scpi_arm(&faults));
            let device = served.serial("positioner", port, link("positioner"), armed, seeds.next().unwrap_or(1))?;
            let positioner = bench.positioner;
            let at = (*controller, *axis);
            served.tasks.push(tokio::spawn(async move {
                scpi_server::serve_stream(device, positioner, faults, at).await;
            }));
            served.instruments.insert("positioner".into(), port.clone().into());
        }
        PositionerConfig::ModbusTcp { address, map, .. } => {
            let listener = listen("positioner", address).await?;
            let public = listener.local_addr()?.to_string();
            let server = ModbusDevice::new(bench.positioner, map.clone())
                .map_err(|e| bad_input(format!("positioner.map: {e}")))?;
            let faults = ModbusFaults::new();
            let armed = arm("positioner", f.device, modbus_arm(&faults));
            let listener =
                front(listener, link("positioner"), armed, seeds.next().unwrap_or(1), &counts, &mut served).await?;
            served.tasks.push(tokio::spawn(async move {
                if let Err(e) = server.serve_tcp(listener, faults).await {
                    tracing::error!(%e, "modbus simulator stopped");
                }
            }));
            served.instruments.insert("positioner".into(), public.into());
        }
        PositionerConfig::ModbusRtu { port, map, slave: address, .. } => {
            let faults = ModbusFaults::new();
            let armed = arm("positioner", f.device, modbus_arm(&faults));
            let device = served.serial("positioner", port, link("positioner"), armed, seeds.next().unwrap_or(1))?;
            // On a serial line the slave address is the unit (as the driver does).
            let map = survey_drivers::modbus::RegisterMap { unit_id: *address, ..map.clone() };
            let server =
                ModbusDevice::new(bench.positioner, map).map_err(|e| bad_input(format!("positioner.map: {e}")))?;
            served.tasks.push(tokio::spawn(async move {
                server.serve_rtu(device, faults).await;
            }));
            served.instruments.insert("positioner".into(), port.clone().into());
        }
        PositionerConfig::Canopen { drive, .. } => {
            let mut node = survey_sims::canopen_node::NodeConfig::new(drive.node_id);
            node.counts_per_degree = drive.counts_per_degree;
            let positioner = bench.positioner;
            let faults = survey_sims::canopen_node::NodeFaults::new();
            let armed = arm("positioner", f.device, canopen_arm(&faults));
            match cfg.positioner.can_link() {
                Some(Ok(CanLink::Slcan { port, .. })) => {
                    // A CiA 402 drive behind a simulated USB-CAN adapter, on a
                    // pty linked at the port (link faults on the serial line,
                    // on the replies among the adapter's messages).
                    let link = LinkFaults { framing: Framing::SlcanCanopen, ..link("positioner") };
                    let device = served.serial("positioner", &port, link, armed, seeds.next().unwrap_or(1))?;
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
                Some(Ok(CanLink::SocketCan(interface))) => {
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
                Some(Err(e)) => return Err(bad_input(e)),
                None => unreachable!("a CANopen configuration has a CAN link"),
            }
        }
    }

    // The reference instruments (both may be configured; each is served).
    if let Some(TrackerConfig::Emscon { address, .. }) = &cfg.tracker {
        let listener = listen("tracker", address).await?;
        let public = listener.local_addr()?.to_string();
        let faults = EmsconFaults::new();
        let armed = arm("tracker", f.device, emscon_arm(&faults));
        let listener = front(listener, link("tracker"), armed, seeds.next().unwrap_or(1), &counts, &mut served).await?;
        served.tasks.push(tokio::spawn(emscon_server::serve_tcp(listener, bench.tracker, faults)));
        served.instruments.insert("tracker".into(), public.into());
    }
    if let Some(AcConfig::Elcomat { port, .. }) = &cfg.autocollimator {
        // Its device fault is the simulated autocollimator's: a blocked view,
        // answered "no reflection".
        let device = served.serial("autocollimator", port, link("autocollimator"), None, seeds.next().unwrap_or(1))?;
        let instrument = bench.autocollimator;
        served.tasks.push(tokio::spawn(async move {
            elcomat_server::serve(device, instrument, ElcomatFaults::default()).await;
        }));
        served.instruments.insert("autocollimator".into(), port.clone().into());
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
    let plan =
        crate::bench::configured_plan(cfg, crate::bench::PlanOverrides::default(), Path::new("the configuration"))?;
    let t = cfg.timing();
    let measure = match cfg.reference() {
        crate::acquire::ReferenceKind::Tracker => builder.tracker.measurement_time,
        crate::acquire::ReferenceKind::Autocollimator => builder.autocollimator.read_time,
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
    link: LinkFaults,
    arm: Option<DeviceArm>,
    seed: u64,
    counts: Arc<Counts>,
    port: PathBuf,
) {
    // The slave end of the current pty, kept open (see `Served::_slaves`).
    let mut _slave = None;
    for k in 0u64.. {
        let seed = if k == 0 { seed } else { derive_seed(seed, k) };
        if relay_with(master, &mut device, link, arm.clone(), seed, counts.clone()).await != relay::Ended::Disconnect {
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

/// For a TCP instrument: the listener the simulator serves on. Without
/// faults, the public one itself; with faults, an inner one on a free
/// loopback port, the public one relaying to it.
async fn front(
    public: TcpListener,
    link: LinkFaults,
    arm: Option<DeviceArm>,
    seed: u64,
    counts: &Arc<Counts>,
    served: &mut Served,
) -> anyhow::Result<TcpListener> {
    if link == LinkFaults::NONE && arm.is_none() {
        return Ok(public);
    }
    let inner = TcpListener::bind("127.0.0.1:0").await?;
    let inner_addr = inner.local_addr()?;
    served.tasks.push(tokio::spawn(relay_tcp(public, inner_addr, link, arm, seed, counts.clone())));
    Ok(inner)
}

/// The SCPI controller refuses the next axis command with -310 (a
/// device-specific error of SCPI-99's -300 class).
fn scpi_arm(faults: &ScpiFaults) -> Arc<dyn Fn() + Send + Sync> {
    let f = faults.clone();
    Arc::new(move || f.reject_next_command(-310, "System error; simulated device fault"))
}

/// The Modbus device answers the next request with exception 4 (server
/// device failure).
fn modbus_arm(faults: &ModbusFaults) -> Arc<dyn Fn() + Send + Sync> {
    let f = faults.clone();
    Arc::new(move || f.reject_next_request(survey_drivers::modbus::ExceptionCode::ServerDeviceFailure))
}

/// The CANopen drive aborts the next SDO request with 0x06060000 (CiA 301:
/// access failed due to a hardware error), the SDO counterpart of Modbus
/// exception 4. Not 0x08000022 (refused in the present device state): the
/// driver reads that as a wrong request (`Usage`), which is never retried.
fn canopen_arm(faults: &survey_sims::canopen_node::NodeFaults) -> Arc<dyn Fn() + Send + Sync> {
    let f = faults.clone();
    Arc::new(move || f.abort_next_request(0x0606_0000))
}

/// The emScon server refuses the next command with `ES_RS_SensorNotStable`.
fn emscon_arm(faults: &EmsconFaults) -> Arc<dyn Fn() + Send + Sync> {
    let f = faults.clone();
    Arc::new(move || {
        f.reject_next_command(
            survey_drivers::emscon::codes::status::SENSOR_NOT_STABLE,
            emscon_server::Refusal::CommandAnswer,
        )
    })
}

/// Accept clients on `listener` and relay each to the simulator at `inner`.
async fn relay_tcp(
    listener: TcpListener,
    inner: SocketAddr,
    link: LinkFaults,
    arm: Option<DeviceArm>,
    seed: u64,
    counts: Arc<Counts>,
) {
    let mut k = 0u64;
    loop {
        let Ok((client, _)) = listener.accept().await else {
            tokio::task::yield_now().await;
            continue;
        };
        client.set_nodelay(true).ok();
        let Ok(device) = tokio::net::TcpStream::connect(inner).await else { continue };
        device.set_nodelay(true).ok();
        k += 1;
        // One client at a time, like the instruments.
        relay_with(client, device, link, arm.clone(), derive_seed(seed, k), counts.clone()).await;
    }
}
