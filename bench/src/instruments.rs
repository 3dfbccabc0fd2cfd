//! Real instruments from a configuration: one connector per driver, every
//! driver behind [`Reconnecting`], and `survey check`.

use async_trait::async_trait;
use std::sync::Arc;
use std::time::Duration;
use survey_acquire::{Engine, Reference};
use survey_drivers::clock::with_timeout;
use survey_drivers::elcomat::ElcomatDriver;
use survey_drivers::emscon::EmsconConnector;
use survey_drivers::reconnect::{Connect, Reconnecting};
use survey_drivers::{Autocollimator, Clock, DriverError, ErrorKind, Positioner, Tracker};
use survey_positioner_drivers::canopen::frame::CanBus;
use survey_positioner_drivers::canopen::slcan::SlcanBus;
use survey_positioner_drivers::canopen::{CanopenConfig, Cia402Positioner, DriveMemory, SocketCanBus};
use survey_positioner_drivers::modbus::ModbusPositioner;
use survey_positioner_drivers::scpi::{Address, ScpiPositioner, ScpiTimeouts};
use survey_store::config::{AutocollimatorConfig, CanLink, PositionerConfig, SurveyConfig, TrackerConfig};

/// The SCPI driver's deadlines under the engine's call timeout: half of it
/// for a request, so the driver meets a late reply and drains it
/// ([`ScpiTimeouts::late_window`]) before the engine's deadline.
pub fn scpi_timeouts(call_timeout: Duration) -> ScpiTimeouts {
    ScpiTimeouts { request: call_timeout / 2, ..ScpiTimeouts::default() }
}

/// The ELCOMAT driver's timeout under the engine's measurement timeout:
/// half of it, so the driver meets a late reading and drains it (a quarter)
/// before the engine's deadline.
pub fn elcomat_timeout(measure_timeout: Duration) -> Duration {
    measure_timeout / 2
}

/// Opens the configured positioner controller.
#[derive(Debug, Clone)]
pub struct PositionerConnector {
    pub config: PositionerConfig,
    pub timeout: Duration,
    /// What the connections know of a CiA 402 drive: after its first full
    /// set-up a reconnect re-checks the statusword only.
    pub drive: Arc<DriveMemory>,
}

#[async_trait]
impl Connect<dyn Positioner> for PositionerConnector {
    async fn connect(&self) -> survey_drivers::Result<Box<dyn Positioner>> {
        let timeouts = scpi_timeouts(self.timeout);
        match &self.config {
            PositionerConfig::ScpiTcp {
                address,
                controller,
                axis,
                in_position_window_deg,
                error_query,
                unverified_commands,
            } => {
                let mut d = ScpiPositioner::connect_tcp(address.as_str(), timeouts).await?;
                let c = d.config_mut();
                (c.in_position_window_deg, c.error_query, c.unverified_commands) =
                    (*in_position_window_deg, *error_query, *unverified_commands);
                Ok(Box::new(d.with_address(Address { controller: *controller, axis: *axis })))
            }
            PositionerConfig::ScpiSerial {
                port,
                baud,
                controller,
                axis,
                in_position_window_deg,
                error_query,
                unverified_commands,
            } => {
                let mut d = ScpiPositioner::open_serial(port, *baud, timeouts)?;
                let c = d.config_mut();
                (c.in_position_window_deg, c.error_query, c.unverified_commands) =
                    (*in_position_window_deg, *error_query, *unverified_commands);
                Ok(Box::new(d.with_address(Address { controller: *controller, axis: *axis })))
            }
            PositionerConfig::ModbusTcp { address, map, timeouts } => {
                Ok(Box::new(ModbusPositioner::connect_tcp(address.as_str(), map.clone(), *timeouts).await?))
            }
            PositionerConfig::ModbusRtu { port, baud, slave, map, timeouts } => {
                Ok(Box::new(ModbusPositioner::connect_rtu(port, *baud, *slave, map.clone(), *timeouts).await?))
            }
            PositionerConfig::Canopen { drive, .. } => {
                let link = self.config.can_link().transpose().map_err(|e| DriverError::usage("canopen", e))?;
                match link {
                    Some(CanLink::Slcan { port, bitrate }) => {
                        // An adapter answers its commands at once: a quarter of
                        // the call's deadline each, so one asked again still fits.
                        let bus = SlcanBus::open_port(&port, bitrate, self.timeout / 4).await?;
                        self.cia402(bus, drive).await
                    }
                    Some(CanLink::SocketCan(interface)) => {
                        let bus = SocketCanBus::open(&interface)?;
                        self.cia402(bus, drive).await
                    }
                    None => unreachable!("a CANopen configuration has a CAN link"),
                }
            }
        }
    }
    fn describe(&self) -> String {
        match &self.config {
            PositionerConfig::ScpiTcp { address, .. } => format!("scpi-tcp {address}"),
            PositionerConfig::ScpiSerial { port, .. } => format!("scpi-serial {port}"),
            PositionerConfig::ModbusTcp { address, .. } => format!("modbus-tcp {address}"),
            PositionerConfig::ModbusRtu { port, slave, .. } => format!("modbus-rtu {port} slave {slave}"),
            PositionerConfig::Canopen { .. } => self.config.can_describe().unwrap_or_default(),
        }
    }
}

impl PositionerConnector {
    /// A CiA 402 drive on `bus`, set up (in full the first time, then by
    /// its statusword: [`Cia402Positioner::set_up`]), its errors naming it as every
    /// other call through the connector does (`canopen slcan PATH node N`),
    /// not by the bus (`canopen node N on slcan PATH`): the events of a
    /// survey name one instrument one way.
    async fn cia402<B: CanBus + 'static>(
        &self,
        bus: B,
        drive: &CanopenConfig,
    ) -> survey_drivers::Result<Box<dyn Positioner>> {
        let mut d = Cia402Positioner::new(bus, drive.clone())?.named(self.describe());
        d.set_up(&self.drive).await?;
        Ok(Box::new(d))
    }
}

/// Opens the configured tracking laser.
#[derive(Debug, Clone)]
pub struct TrackerConnector {
    pub config: TrackerConfig,
    pub timeout: Duration,
}

#[async_trait]
impl Connect<dyn Tracker> for TrackerConnector {
    async fn connect(&self) -> survey_drivers::Result<Box<dyn Tracker>> {
        match &self.config {
            TrackerConfig::Emscon { address, settings } => {
                EmsconConnector { addr: address.clone(), cfg: settings.clone() }.connect().await
            }
        }
    }
    fn describe(&self) -> String {
        match &self.config {
            TrackerConfig::Emscon { address, .. } => format!("emscon {address}"),
        }
    }
}

/// Opens the configured autocollimator.
#[derive(Debug, Clone)]
pub struct AutocollimatorConnector {
    pub config: AutocollimatorConfig,
    pub timeout: Duration,
}

#[async_trait]
impl Connect<dyn Autocollimator> for AutocollimatorConnector {
    async fn connect(&self) -> survey_drivers::Result<Box<dyn Autocollimator>> {
        match &self.config {
            AutocollimatorConfig::Elcomat { port, baud } => {
                Ok(Box::new(ElcomatDriver::open_serial(port, *baud)?.with_timeout(elcomat_timeout(self.timeout))))
            }
        }
    }
    fn describe(&self) -> String {
        match &self.config {
            AutocollimatorConfig::Elcomat { port, .. } => format!("elcomat {port}"),
        }
    }
}

/// The instruments a configuration names, each behind a reconnecting wrapper.
#[derive(Debug)]
pub struct Instruments {
    pub positioner: Reconnecting<dyn Positioner>,
    pub reference: ReferenceInstrument,
}

/// The reference instrument, not yet connected.
#[derive(Debug)]
pub enum ReferenceInstrument {
    Tracker(Reconnecting<dyn Tracker>),
    Autocollimator { instrument: Reconnecting<dyn Autocollimator>, faces: u32, certificate_arcsec: Vec<f64> },
}

impl Instruments {
    /// Build (without connecting) the instruments of a configuration.
    pub fn from_config(cfg: &SurveyConfig) -> Self {
        let timing = cfg.timing();
        let positioner = Reconnecting::new(Box::new(PositionerConnector {
            config: cfg.positioner.clone(),
            timeout: timing.call_timeout,
            drive: Arc::default(),
        }) as Box<dyn Connect<dyn Positioner>>);
        let reference = match cfg.reference() {
            survey_acquire::ReferenceKind::Tracker => {
                let tracker = cfg.tracker.clone().expect("checked when the configuration was read");
                ReferenceInstrument::Tracker(Reconnecting::new(Box::new(TrackerConnector {
                    config: tracker,
                    timeout: timing.measure_timeout,
                }) as Box<dyn Connect<dyn Tracker>>))
            }
            survey_acquire::ReferenceKind::Autocollimator => {
                let ac = cfg.autocollimator.clone().expect("checked when the configuration was read");
                let polygon = cfg.polygon.clone().expect("checked when the configuration was read");
                let certificate_arcsec = if polygon.certificate_arcsec.is_empty() {
                    vec![0.0; polygon.faces as usize]
                } else {
                    polygon.certificate_arcsec
                };
                ReferenceInstrument::Autocollimator {
                    instrument: Reconnecting::new(Box::new(AutocollimatorConnector {
                        config: ac,
                        timeout: timing.measure_timeout,
                    }) as Box<dyn Connect<dyn Autocollimator>>),
                    faces: polygon.faces,
                    certificate_arcsec,
                }
            }
        };
        Self { positioner, reference }
    }

    /// The survey engine on these instruments.
    pub fn into_engine(self, clock: Arc<dyn Clock>, cfg: &SurveyConfig) -> Engine {
        let reference = match self.reference {
            ReferenceInstrument::Tracker(t) => Reference::Tracker(Box::new(t)),
            ReferenceInstrument::Autocollimator { instrument, faces, certificate_arcsec } => {
                Reference::Autocollimator { instrument: Box::new(instrument), faces, certificate_arcsec }
            }
        };
        Engine::new(clock, Box::new(self.positioner), reference, cfg.timing())
    }
}

/// Whether a continuous scan (`--scan continuous`) is possible on the
/// configured instruments: how it would stream, or why not. From the
/// configuration alone, before anything is connected.
pub fn continuous_support(cfg: &SurveyConfig) -> Result<String, String> {
    let timing = cfg.timing();
    let scale = cfg.time_scale();
    if scale != 1.0 {
        return Err(format!(
            "the instruments run at {}x real time ([timing] time_scale: a simulator): a continuous scan pairs the \
             instruments' streams by their clocks, which needs them in real time",
            survey_processing::num::Num(scale)
        ));
    }
    let capture_ms = timing.scan.capture_period.as_secs_f64() * 1e3;
    let stream_ms = timing.scan.stream_period.as_secs_f64() * 1e3;
    let tracker = match (cfg.reference(), &cfg.tracker) {
        (survey_acquire::ReferenceKind::Autocollimator, _) => {
            return Err("the reference is an autocollimator (ELCOMAT), which reads a polygon face only while the \
                        axis rests on it; a continuous scan needs a tracker that measures while the axis turns"
                .into());
        }
        (_, Some(TrackerConfig::Emscon { .. })) => {
            format!("the emScon tracker measures in continuous time mode every {stream_ms} ms")
        }
        (_, None) => return Err("there is no [tracker] section".into()),
    };
    let positioner = match &cfg.positioner {
        PositionerConfig::ScpiTcp { unverified_commands, .. }
        | PositionerConfig::ScpiSerial { unverified_commands, .. } => {
            if !unverified_commands {
                return Err("the MI-4190-style controller's velocity command (VEL:COMM) is not in the public record, \
                            and a scan must set the velocity (two velocities calibrate the latency): set \
                            unverified_commands = true in [positioner] to send it. Its position-trigger output \
                            (STAT? bit 10) has no public set-up commands either, so the readout would be polled \
                            (POS:CURR?)"
                    .into());
            }
            format!(
                "the SCPI controller's readout is polled (POS:CURR?) every {capture_ms} ms and stamped by this computer"
            )
        }
        PositionerConfig::ModbusTcp { .. } | PositionerConfig::ModbusRtu { .. } => {
            format!("the Modbus drive's position register is read every {capture_ms} ms and stamped by this computer")
        }
        PositionerConfig::Canopen { .. } => format!(
            "the CiA 402 drive's position actual value (0x6064) is read by SDO every {capture_ms} ms and stamped by this computer"
        ),
    };
    Ok(format!("{tracker}; {positioner}"))
}

/// What `survey check` found about one instrument.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CheckLine {
    pub instrument: String,
    pub address: String,
    pub ok: bool,
    /// `ok`, `address unreachable`, `no reply`, `wrong protocol`, `device fault`, `bad usage`.
    pub verdict: String,
    pub detail: String,
}

fn verdict(e: &DriverError) -> &'static str {
    match e.kind {
        ErrorKind::Disconnected => "address unreachable",
        ErrorKind::Timeout => "no reply",
        ErrorKind::Garbled => "wrong protocol",
        ErrorKind::Device => "device fault",
        ErrorKind::Usage => "bad usage",
    }
}

fn line(instrument: &str, address: String, result: Result<String, DriverError>) -> CheckLine {
    match result {
        Ok(detail) => CheckLine { instrument: instrument.into(), address, ok: true, verdict: "ok".into(), detail },
        Err(e) => CheckLine {
            instrument: instrument.into(),
            address,
            ok: false,
            verdict: verdict(&e).into(),
            detail: e.to_string(),
        },
    }
}

/// What the configured positioner cannot do, for `survey check` (empty when
/// nothing): a CiA 402 drive without this project's correction objects
/// cannot take the correction table.
fn unavailable(positioner: &PositionerConfig) -> &'static str {
    match positioner {
        PositionerConfig::Canopen { drive, .. } if !drive.correction_objects => {
            "; unavailable without correction_objects = true (the drive has CiA 402's standard objects only): \
             loading the correction table into the drive (0x2100/0x2101, this project's own objects), so \
             survey run --verify cannot apply the table"
        }
        _ => "",
    }
}

/// What an instrument said it is, for a check line (nothing when it says nothing or cannot now).
fn identified(id: survey_drivers::Result<Option<String>>) -> String {
    match id.ok().flatten().as_deref().and_then(printable) {
        Some(text) => format!("; identifies itself as \"{text}\""),
        None => String::new(),
    }
}

/// The longest identification kept, characters (a certificate's line holds it).
pub const MAX_IDENTIFICATION_CHARS: usize = 200;

/// An instrument's identification as it is shown and kept: a control
/// character read as a space, at most [`MAX_IDENTIFICATION_CHARS`], trimmed;
/// `None` when nothing is left.
pub fn printable(text: &str) -> Option<String> {
    let clean: String =
        text.chars().map(|c| if c.is_control() { ' ' } else { c }).take(MAX_IDENTIFICATION_CHARS).collect();
    Some(clean.trim().to_string()).filter(|t| !t.is_empty())
}

/// Connect to every instrument and read its status, bounded by the
/// configuration's timeouts.
pub async fn check(cfg: &SurveyConfig, clock: &dyn Clock) -> Vec<CheckLine> {
    let timing = cfg.timing();
    let mut instruments = Instruments::from_config(cfg);
    let mut lines = Vec::new();
    let limit = timing.call_timeout * 3;
    let name = instruments.positioner.name().to_string();
    let p = &mut instruments.positioner;
    let result = async {
        with_timeout(clock, limit, &name, "connect", p.connect()).await?;
        let status = with_timeout(clock, timing.call_timeout, &name, "status", p.status()).await?;
        if let Some(f) = &status.fault {
            return Err(DriverError::device(name.clone(), f.code, f.text.clone()));
        }
        let readout = with_timeout(clock, timing.call_timeout, &name, "readout", p.readout()).await?;
        let id = with_timeout(clock, timing.call_timeout, &name, "identification", p.identification()).await;
        Ok(format!(
            "readout {readout} deg, {}{}{}{}",
            if status.moving {
                "moving"
            } else if status.in_position {
                "in position"
            } else {
                "at rest"
            },
            status.limit.map(|l| format!(", at the {l:?} limit")).unwrap_or_default(),
            unavailable(&cfg.positioner),
            identified(id)
        ))
    }
    .await;
    lines.push(line("positioner", name.clone(), result));
    match &mut instruments.reference {
        ReferenceInstrument::Tracker(t) => {
            let name = t.name().to_string();
            let result = async {
                with_timeout(clock, limit, &name, "connect", t.connect()).await?;
                let state = with_timeout(clock, timing.call_timeout, &name, "status", t.status()).await?;
                let id = with_timeout(clock, timing.call_timeout, &name, "identification", t.identification()).await;
                match state {
                    survey_drivers::TrackerState::TargetLocked => Ok(format!("target locked{}", identified(id))),
                    other => Err(DriverError::new(
                        ErrorKind::Device,
                        name.clone(),
                        format!("{other:?}: the SMR is not locked"),
                    )),
                }
            }
            .await;
            lines.push(line("tracker", name.clone(), result));
        }
        ReferenceInstrument::Autocollimator { instrument, .. } => {
            let name = instrument.name().to_string();
            let result = async {
                with_timeout(clock, limit, &name, "connect", instrument.connect()).await?;
                let state = with_timeout(clock, timing.measure_timeout, &name, "status", instrument.status()).await?;
                Ok(match state {
                    survey_drivers::AcState::InRange => "mirror in range".to_string(),
                    survey_drivers::AcState::NoReflection => "answers, but sees no mirror (turn to a face)".to_string(),
                })
            }
            .await;
            lines.push(line("autocollimator", name.clone(), result));
        }
    }
    lines
}
