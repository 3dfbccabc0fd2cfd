//! The survey configuration file (`survey run --config FILE`): which driver
//! and address for each instrument, the reference, the polygon or arm data,
//! travel limits and timing.
//!
//! ```toml
//! [survey]
//! points = 360
//! runs = 5
//! bidirectional = true
//! reference = "tracker"          # or "autocollimator"
//! travel_deg = [-10.0, 90.0]     # omit for continuous rotation
//!
//! [positioner]
//! driver = "scpi-tcp"
//! address = "192.168.1.20:4000"
//!
//! [tracker]
//! driver = "emscon"
//! address = "192.168.1.30:700"
//!
//! [timing]
//! dwell_s = 0.5
//! ```
//!
//! Unknown keys are errors, so a misspelt setting never silently falls back
//! to a default.
//!
//! Its own crate (`survey-config`, reached as `survey_store::config` too):
//! the file's schema, checks and messages, apart from the store that keeps
//! a survey's configuration with it. [`asset`]: an asset's id, as the
//! configuration and the store check it.

use serde::{Deserialize, Serialize};
use std::path::Path;
use std::time::Duration;
use survey_acquire::{ReferenceKind, SettleMode, SettleModel, SettleSpec, Timing, default_window_deg};
use survey_positioner_drivers::canopen::CanopenConfig;

pub mod asset;
mod consistency;
mod derived;
mod place;
pub mod readdress;
mod schema;
use place::{Defect, Places};
use survey_drivers::emscon::EmsconConfig;
use survey_positioner_drivers::modbus::{ModbusTimeouts, RegisterMap};
use survey_positioner_drivers::scpi::ErrorQueryForm;

/// A whole configuration file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurveyConfig {
    #[serde(default)]
    pub survey: SurveySection,
    pub positioner: PositionerConfig,
    #[serde(default)]
    pub tracker: Option<TrackerConfig>,
    #[serde(default)]
    pub autocollimator: Option<AutocollimatorConfig>,
    /// The SMR arm, used to check the located axis.
    #[serde(default)]
    pub arm: Option<ArmSection>,
    /// The polygon the autocollimator looks at.
    #[serde(default)]
    pub polygon: Option<PolygonSection>,
    #[serde(default)]
    pub timing: TimingSection,
    /// What the report's header states (`survey report` flags override it).
    #[serde(default)]
    pub certificate: Option<CertificateSection>,
    /// Drift control: a reference target re-measured every K steps (off by default).
    #[serde(default)]
    pub drift_control: Option<survey_plan::drift::DriftControl>,
    /// The asset (the axis this configuration measures): its surveys' history.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub asset: Option<AssetSection>,
    /// `[smrs]`: several SMRs on the table, each measured at every target.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub smrs: Option<SmrsSection>,
    /// `[machine_frame]`: the machine's frame in the tracker's, where the
    /// axis's location is stated too (`survey_processing::frame`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub machine_frame: Option<survey_processing::frame::MachineFrame>,
    /// `[rehearsal]`: the instruments are simulated (`survey sim` writes it
    /// into the configuration it serves): a survey of them is never a calibration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rehearsal: Option<RehearsalSection>,
}

/// `[rehearsal]`: what simulates the instruments.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RehearsalSection {
    /// The simulator, in words (`survey sim 0.1.0, preset fig8, seed 1, 1x real time`).
    pub simulator: String,
}

/// `[smrs]`: the SMRs on the table beside the arm's first (its phase and
/// height 0): each one's angle from the first's in the direction the readout
/// increases, and its height above it, mm (default all 0).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SmrsSection {
    pub phases_deg: Vec<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heights_mm: Option<Vec<f64>>,
}

impl SmrsSection {
    /// The mounts, each relative to the first SMR's.
    pub fn mounts(&self) -> Vec<survey_processing::smrs::SmrMount> {
        let heights = self.heights_mm.clone().unwrap_or_else(|| vec![0.0; self.phases_deg.len()]);
        let (p0, h0) = (self.phases_deg.first().copied().unwrap_or(0.0), heights.first().copied().unwrap_or(0.0));
        self.phases_deg
            .iter()
            .zip(heights.iter().chain(std::iter::repeat(&0.0)))
            .map(|(p, h)| survey_processing::smrs::SmrMount {
                phase_deg: (p - p0).rem_euclid(360.0),
                height_mm: h - h0,
            })
            .collect()
    }
}

/// `[asset]`: the axis measured, whose surveys make one history
/// (`survey history --asset ID`); `survey run --asset` overrides it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AssetSection {
    /// 1-64 characters of letters, digits and `-_./`.
    pub id: String,
    /// The first interval between checks, days (default
    /// [`AssetSection::DEFAULT_INTERVAL_DAYS`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interval_days: Option<f64>,
    /// How the interval is reviewed after each check or calibration:
    /// `staircase` (the default), `control-chart`, `in-use` or `fixed`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interval_method: Option<String>,
    /// The shortest interval a review may set, days (default 7).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interval_min_days: Option<f64>,
    /// The longest interval a review may set, days (default 365).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interval_max_days: Option<f64>,
    /// `in-use`: the revolutions of travel between checks (default 1000).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interval_revolutions: Option<f64>,
}

impl AssetSection {
    /// `interval_days` unless stated.
    pub const DEFAULT_INTERVAL_DAYS: f64 = 90.0;
    /// `interval_min_days` unless stated.
    pub const DEFAULT_MIN_DAYS: f64 = 7.0;
    /// `interval_max_days` unless stated.
    pub const DEFAULT_MAX_DAYS: f64 = 365.0;
    /// `interval_revolutions` unless stated.
    pub const DEFAULT_REVOLUTIONS: f64 = 1000.0;
    /// `interval_method` unless stated.
    pub const DEFAULT_METHOD: &str = "staircase";
}

/// `[certificate]`: what a calibration certificate states that no instrument
/// reports. Every key optional; stored with the survey, shown in the report's
/// header (the flags of `survey report` override each).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CertificateSection {
    /// The positioner calibrated: make, model, serial number.
    pub positioner: Option<String>,
    /// The reference instrument: make, model, serial number, its calibration.
    pub reference: Option<String>,
    /// The reference's stated standard uncertainty of one angle, degrees.
    pub reference_uncertainty_deg: Option<f64>,
    /// A tracker reference's transverse MPE, its constant part, um (default
    /// the AT-class 15): the bound of its systematic error.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_mpe_um: Option<f64>,
    /// A tracker reference's transverse MPE, its part per metre of
    /// distance, um/m (default the AT-class 6).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_mpe_um_per_m: Option<f64>,
    /// Who measured.
    pub operator: Option<String>,
    /// For whom.
    pub customer: Option<String>,
    /// The air temperature during the survey, degrees Celsius.
    pub temperature_c: Option<f64>,
    /// The certificate's number, as the laboratory assigns it.
    pub number: Option<String>,
    /// The calibrating laboratory: name, address, accreditation.
    pub laboratory: Option<String>,
    /// How the measurement is traceable to the SI: the reference's calibration (by whom, certificate, date).
    pub traceability: Option<String>,
    /// The tolerance the positioner's ISO 230-2 accuracy A is judged against, degrees.
    pub tolerance_deg: Option<f64>,
    /// Who authorises the certificate: name and function.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub signatory: Option<String>,
    /// Where the calibration was performed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub location: Option<String>,
    /// Whose premises `location` is, as the DCC says it (`laboratory`,
    /// `customer`, `laboratoryBranch`, `customerBranch`, `other`); not
    /// stated: read from `location`'s words.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub performance_location: Option<String>,
    /// The condition of the item when received (or calibrated).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub item_condition: Option<String>,
    /// The date the item was received, `YYYY-MM-DD`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub received: Option<String>,
    /// The laboratory's country, ISO 3166-1 alpha-2 (`DE`, `GB`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub country: Option<String>,
    /// The laboratory's postal address.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub laboratory_address: Option<Address>,
    /// The customer's postal address.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub customer_address: Option<Address>,
    /// The item calibrated: its identifications.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub item: Option<Equipment>,
    /// The reference instrument: its identifications and its calibration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_instrument: Option<Equipment>,
}

/// A postal address (`[certificate.laboratory_address]`, `[certificate.customer_address]`).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Address {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub street: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub street_no: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub post_code: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub city: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub state: Option<String>,
    /// ISO 3166-1 alpha-2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub country: Option<String>,
}

/// An instrument's identifications (`[certificate.item]`,
/// `[certificate.reference_instrument]`): who made it, its model, its
/// serial and inventory numbers, and, for a reference, the certificate of
/// its own calibration (number, by whom, when, when it is due again).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Equipment {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub manufacturer: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub serial: Option<String>,
    /// The owner's inventory number.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inventory: Option<String>,
    /// The number of the certificate of its own calibration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub certificate: Option<String>,
    /// Who calibrated it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibrated_by: Option<String>,
    /// When, `YYYY-MM-DD`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibrated: Option<String>,
    /// When its calibration is due again, `YYYY-MM-DD`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub due: Option<String>,
}

/// `[survey]`: the plan; command-line flags override these.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurveySection {
    pub points: Option<u32>,
    pub runs: Option<u32>,
    pub bidirectional: Option<bool>,
    /// The reference instrument (default: tracker).
    pub reference: Option<ReferenceKind>,
    /// Travel limits of a partial-range axis, degrees.
    pub travel_deg: Option<[f64; 2]>,
    /// Distance past a target before approaching it from the other side, degrees.
    pub overrun_deg: Option<f64>,
    /// `"step"` (default) or `"continuous"` (`--scan` overrides it).
    pub scan: Option<survey_plan::ScanMode>,
}

/// `[positioner]`: the controller and how to reach it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "driver", rename_all = "kebab-case", deny_unknown_fields)]
pub enum PositionerConfig {
    /// An MI-4190-style controller over TCP (SCPI-like text commands).
    ScpiTcp {
        /// `host:port`.
        address: String,
        #[serde(default = "one")]
        controller: u32,
        #[serde(default = "one")]
        axis: u32,
        /// At rest within this of the commanded position is in position, deg.
        #[serde(default = "in_position_window")]
        in_position_window_deg: f64,
        /// `"all"` (`SYST:ERR:ALL?`, default) or `"next"` (`SYST:ERR?`).
        #[serde(default)]
        error_query: ErrorQueryForm,
        /// Send `VEL:COMM`, `FAUL:CLE` and the `CORR:` subsystem, which the
        /// public record does not show (default false).
        #[serde(default)]
        unverified_commands: bool,
    },
    /// The same controller over a serial port.
    ScpiSerial {
        port: String,
        #[serde(default = "baud_9600")]
        baud: u32,
        #[serde(default = "one")]
        controller: u32,
        #[serde(default = "one")]
        axis: u32,
        #[serde(default = "in_position_window")]
        in_position_window_deg: f64,
        #[serde(default)]
        error_query: ErrorQueryForm,
        #[serde(default)]
        unverified_commands: bool,
    },
    /// A servo drive over Modbus TCP, with its register map.
    ModbusTcp {
        /// `host:port` (port 502 on most devices).
        address: String,
        #[serde(default)]
        map: RegisterMap,
        #[serde(default)]
        timeouts: ModbusTimeouts,
    },
    /// A servo drive over Modbus RTU on a serial port.
    ModbusRtu {
        port: String,
        #[serde(default = "baud_9600")]
        baud: u32,
        #[serde(default = "one_u8")]
        slave: u8,
        #[serde(default)]
        map: RegisterMap,
        #[serde(default)]
        timeouts: ModbusTimeouts,
    },
    /// A CiA 402 drive over CANopen, on a SocketCAN interface or through a
    /// USB-CAN adapter speaking SLCAN on a serial port.
    Canopen {
        /// `"socketcan"` (default) or `"slcan"`.
        #[serde(default)]
        transport: CanTransport,
        /// The SocketCAN interface (`can0`), with `transport = "socketcan"`.
        #[serde(default)]
        interface: Option<String>,
        /// The adapter's serial port (`/dev/ttyACM0`), with `transport = "slcan"`.
        #[serde(default)]
        port: Option<String>,
        /// The CAN bitrate, bit/s, with `transport = "slcan"` (default 500000).
        #[serde(default)]
        bitrate: Option<u32>,
        #[serde(flatten)]
        drive: CanopenConfig,
    },
}

/// How a CANopen drive is reached.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CanTransport {
    /// A SocketCAN interface (Linux).
    #[default]
    Socketcan,
    /// A serial-line CAN adapter (SLCAN / Lawicel: CANable, USBtin...).
    Slcan,
}

/// Where a CANopen drive is, resolved from the configuration.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CanLink {
    /// SocketCAN interface name.
    SocketCan(String),
    /// SLCAN adapter: serial port and bitrate.
    Slcan { port: String, bitrate: u32 },
}

/// Default SLCAN bitrate, bit/s (CANopen's most common).
pub const DEFAULT_CAN_BITRATE: u32 = 500_000;

impl PositionerConfig {
    /// The CAN link of a CANopen positioner (`None` for other drivers), or
    /// what is missing.
    pub fn can_link(&self) -> Option<Result<CanLink, String>> {
        let PositionerConfig::Canopen { transport, interface, port, bitrate, .. } = self else { return None };
        Some(match (transport, interface, port) {
            (CanTransport::Socketcan, Some(i), None) => Ok(CanLink::SocketCan(i.clone())),
            (CanTransport::Socketcan, None, _) => {
                Err("positioner: a CANopen drive on SocketCAN needs `interface` (e.g. \"can0\")".into())
            }
            (CanTransport::Socketcan, Some(_), Some(_)) => {
                Err("positioner: `port` is for transport = \"slcan\"; on SocketCAN name the `interface` only".into())
            }
            (CanTransport::Slcan, _, None) => Err(
                "positioner: transport = \"slcan\" needs `port`, the adapter's serial device (e.g. \"/dev/ttyACM0\")"
                    .into(),
            ),
            (CanTransport::Slcan, Some(_), Some(_)) => {
                Err("positioner: `interface` is for SocketCAN; with transport = \"slcan\" name the `port` only".into())
            }
            (CanTransport::Slcan, None, Some(p)) => {
                let bitrate = bitrate.unwrap_or(DEFAULT_CAN_BITRATE);
                match survey_positioner_drivers::canopen::slcan::bitrate_code(bitrate) {
                    Some(_) => Ok(CanLink::Slcan { port: p.clone(), bitrate }),
                    None => Err(format!(
                        "positioner.bitrate = {bitrate} has no SLCAN command (10000, 20000, 50000, 100000, 125000, \
                         250000, 500000, 750000, 800000 or 1000000)"
                    )),
                }
            }
        })
    }

    /// The positioner driver's own deadline of one request and how long it
    /// then drains late replies (a line without transaction id: Modbus RTU,
    /// CANopen SDO), with the key that sets the deadline; `None` for a
    /// driver whose deadline is the engine's (`scpi-*`).
    pub fn own_deadline(&self) -> Option<(&'static str, Duration, Duration)> {
        match self {
            PositionerConfig::ModbusTcp { timeouts, .. } => {
                Some(("positioner.timeouts.request_ms", timeouts.request, Duration::ZERO))
            }
            PositionerConfig::ModbusRtu { timeouts, .. } => {
                Some(("positioner.timeouts.request_ms", timeouts.request, timeouts.late_window()))
            }
            PositionerConfig::Canopen { drive, .. } => {
                let t = drive.sdo_timeouts();
                Some(("positioner.sdo_timeout_ms", t.response, t.late_window()))
            }
            PositionerConfig::ScpiTcp { .. } | PositionerConfig::ScpiSerial { .. } => None,
        }
    }

    /// A short description (`canopen slcan /dev/ttyACM0 node 5`).
    pub fn can_describe(&self) -> Option<String> {
        let PositionerConfig::Canopen { drive, .. } = self else { return None };
        Some(match self.can_link()? {
            Ok(CanLink::SocketCan(i)) => format!("canopen {i} node {}", drive.node_id),
            Ok(CanLink::Slcan { port, .. }) => format!("canopen slcan {port} node {}", drive.node_id),
            Err(_) => format!("canopen node {}", drive.node_id),
        })
    }
}

/// `[tracker]`: the tracking laser.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "driver", rename_all = "kebab-case", deny_unknown_fields)]
pub enum TrackerConfig {
    /// A Leica tracker through its emScon server (TPI over TCP, port 700).
    Emscon {
        /// `host:port`.
        address: String,
        #[serde(flatten)]
        settings: EmsconConfig,
    },
}

/// `[autocollimator]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "driver", rename_all = "kebab-case", deny_unknown_fields)]
pub enum AutocollimatorConfig {
    /// A Moeller-Wedel ELCOMAT on a serial port (8N1).
    Elcomat {
        port: String,
        #[serde(default = "baud_9600")]
        baud: u32,
    },
}

/// `[arm]`: what the SMR arm is, to check the located axis against.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmSection {
    /// Distance of the SMR from the axis, mm.
    pub radius_mm: f64,
    /// How far the fitted radius may differ before the survey refuses to start, mm.
    #[serde(default = "radius_tolerance")]
    pub radius_tolerance_mm: f64,
}

/// `[polygon]`: the N-face polygon and its certificate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PolygonSection {
    pub faces: u32,
    /// Face angle deviations from nominal, arcseconds, one per face (default all 0).
    #[serde(default)]
    pub certificate_arcsec: Vec<f64>,
    /// The certificate's expanded uncertainty (k = 2) of each face angle,
    /// arcseconds; `None`: 0.2 arcsec, a calibrated polygon's typical.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub certificate_u_arcsec: Option<f64>,
    /// The polygon turned by hand between runs: by `turns[r - 1]` faces
    /// relative to the table in run `r` (repeated), the operator asked for
    /// each turn (the survey stops for it; `survey resume` confirms it).
    /// Empty: never turned.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub turns: Vec<u32>,
}

/// `[timing]`: deadlines, waits, retries and the axis dynamics, in seconds and
/// degrees. Every key is optional; the defaults are those of [`Timing`].
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimingSection {
    pub call_timeout_s: Option<f64>,
    pub measure_timeout_s: Option<f64>,
    pub move_margin_s: Option<f64>,
    pub poll_interval_s: Option<f64>,
    pub dwell_s: Option<f64>,
    pub max_retries: Option<u32>,
    pub retry_backoff_s: Option<f64>,
    pub locate_points: Option<u32>,
    pub velocity_deg_s: Option<f64>,
    pub accel_deg_s2: Option<f64>,
    /// `"adaptive"` (default) or `"in-position"` (the default when `dwell_s` is given).
    pub settle: Option<SettleMode>,
    /// Adaptive settling: the readout stays this close to the target, degrees ...
    pub settle_window_deg: Option<f64>,
    /// ... for this long, seconds,
    pub settle_stable_s: Option<f64>,
    /// ... read this often, seconds.
    pub settle_poll_s: Option<f64>,
    /// The settling the axis needs after a move (the drive's data), seconds:
    /// what the lower bound counts. Without it the bound counts none.
    pub settle_time_s: Option<f64>,
    /// Continuous scan: velocity of the survey's passes, deg/s (default half `velocity_deg_s`).
    pub scan_velocity_deg_s: Option<f64>,
    /// Continuous scan: velocity of the first run, which calibrates the
    /// latency, deg/s (default `velocity_deg_s`).
    pub calibration_velocity_deg_s: Option<f64>,
    /// Continuous scan: the readout's capture (or polling) period, seconds.
    pub capture_period_s: Option<f64>,
    /// Continuous scan: the tracker's point period, seconds.
    pub stream_period_s: Option<f64>,
    /// Continuous scan: how often both streams are read, seconds.
    pub fetch_interval_s: Option<f64>,
    /// How long a survey suspended on a lost beam waits for it, s.
    pub beam_wait_s: Option<f64>,
    /// Wait between attempts to re-acquire a lost beam, s.
    pub beam_retry_s: Option<f64>,
    /// The instruments run this many times faster than the hardware they
    /// stand for (a rehearsal on `survey sim --time-scale X`; 1, the default,
    /// for real instruments): instrument time is reported on their clock,
    /// the time this process measured times this.
    pub time_scale: Option<f64>,
}

fn one() -> u32 {
    1
}
fn one_u8() -> u8 {
    1
}
fn baud_9600() -> u32 {
    9600
}
fn in_position_window() -> f64 {
    0.01
}
fn radius_tolerance() -> f64 {
    5.0
}

/// A defect of a configuration file, naming the file and where: the line
/// and the dotted key (`c.toml:12: timing.dwell_s: ...`), or the file alone
/// when it cannot be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}:{}{message}", self.place())]
pub struct ConfigError {
    pub file: String,
    /// The line (1-based) and the dotted key the message is about.
    pub at: Option<(usize, String)>,
    pub message: String,
}

impl ConfigError {
    fn place(&self) -> String {
        match &self.at {
            Some((line, key)) => format!("{line}: {key}: "),
            None => " ".into(),
        }
    }
}

impl SurveyConfig {
    /// Read and check a configuration file.
    pub fn from_file(path: &Path) -> Result<Self, ConfigError> {
        Self::read(path).map(|(cfg, _)| cfg)
    }

    /// [`Self::from_file`] for a command that opens the instruments (`run`,
    /// `check`, `resume`; not `sim`, which makes its serial ports): every
    /// serial port it names that is there must be a serial line, checked
    /// without opening it ([`readdress::serial_line`]; `/dev/null` or a disk
    /// is refused at its line and key before anything is stored or opened).
    pub fn from_file_to_open(path: &Path) -> Result<Self, ConfigError> {
        let (cfg, text) = Self::read(path)?;
        for (key, port) in readdress::device_paths(&cfg) {
            // Nothing there: nothing to open by mistake (the driver says it cannot connect).
            let Err(why) = readdress::serial_line(Path::new(&port)).or_else(|e| match Path::new(&port).exists() {
                true => Err(e),
                false => Ok(String::new()),
            }) else {
                continue;
            };
            let doc = toml::de::DeTable::parse(&text).expect("parsed above");
            let d = Places::of(&text, doc.get_ref()).defect(key, format!("{why}; nothing was opened"));
            return Err(ConfigError { file: path.display().to_string(), at: Some((d.line, d.key)), message: d.text });
        }
        Ok(cfg)
    }

    /// The configuration of the file at `path`, checked, and its text.
    fn read(path: &Path) -> Result<(Self, String), ConfigError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| ConfigError {
            file: file.clone(),
            at: None,
            message: format!("cannot read the configuration: {e}"),
        })?;
        Self::parse(&text, &file).map(|cfg| (cfg, text))
    }

    /// Parse and check configuration text; `file` names it in errors. The
    /// keys are checked against what each takes ([`schema`]) before serde
    /// reads them, then the sections' ranges and consistency ([`Self::check`]);
    /// every defect is named with its line and dotted key ([`place`]).
    pub fn parse(text: &str, file: &str) -> Result<Self, ConfigError> {
        let err = |d: Defect| ConfigError { file: file.to_string(), at: Some((d.line, d.key)), message: d.text };
        let doc = toml::de::DeTable::parse(text).map_err(|e| err(place::syntax(text, &e)))?;
        let places = Places::of(text, doc.get_ref());
        if let Some(d) = schema::Walk::first(text, doc.get_ref()) {
            return Err(err(d));
        }
        let cfg: SurveyConfig = toml::from_str(text).map_err(|e| err(place::unexpected(text, &places, &e)))?;
        cfg.check(&places).map_err(err)?;
        Ok(cfg)
    }

    /// The reference instrument this configuration uses.
    pub fn reference(&self) -> ReferenceKind {
        self.survey.reference.unwrap_or(ReferenceKind::Tracker)
    }

    /// How many times faster than the hardware the instruments run (`[timing] time_scale`, default 1).
    pub fn time_scale(&self) -> f64 {
        self.timing.time_scale.unwrap_or(1.0)
    }

    /// The engine timing: the defaults with this file's settings on top.
    pub fn timing(&self) -> Timing {
        let t = &self.timing;
        let d = Timing::default();
        let secs = |v: Option<f64>, default: Duration| v.map(Duration::from_secs_f64).unwrap_or(default);
        let ds = d.settle;
        // An instrument that needs a fixed dwell gets the in-position wait
        // it was configured for, unless adaptive settling is asked as well.
        let mode = t.settle.unwrap_or(if t.dwell_s.is_some() { SettleMode::InPosition } else { SettleMode::Adaptive });
        let settle = SettleSpec {
            mode,
            window_deg: t.settle_window_deg.unwrap_or(default_window_deg(self.reference())),
            stable_for: secs(t.settle_stable_s, ds.stable_for),
            poll: secs(t.settle_poll_s, ds.poll),
            ..ds
        };
        let dsc = d.scan;
        let scan = survey_plan::ScanTiming {
            velocity_deg_s: t.scan_velocity_deg_s,
            calibration_velocity_deg_s: t.calibration_velocity_deg_s,
            capture_period: secs(t.capture_period_s, dsc.capture_period),
            stream_period: secs(t.stream_period_s, dsc.stream_period),
            fetch_interval: secs(t.fetch_interval_s, dsc.fetch_interval),
            ..dsc
        };
        // The engine waits on the wall clock; the instruments of a rehearsal
        // (`survey sim --time-scale X`) run X times faster, so the waits that
        // pace them (polls, settling, dwell, back-off) shrink with them and
        // the rehearsal's instrument time is the hardware's. The bounds
        // (timeouts, the move's margin, the beam's wait) stay on the wall
        // clock: a loaded machine must not turn them into faults.
        let scale = self.time_scale();
        let paced = |d: Duration| if scale == 1.0 { d } else { d.div_f64(scale) };
        let settle = SettleSpec { stable_for: paced(settle.stable_for), poll: paced(settle.poll), ..settle };
        Timing {
            call_timeout: secs(t.call_timeout_s, d.call_timeout),
            measure_timeout: secs(t.measure_timeout_s, d.measure_timeout),
            move_margin: secs(t.move_margin_s, d.move_margin),
            poll_interval: paced(secs(t.poll_interval_s, d.poll_interval)),
            dwell: paced(secs(t.dwell_s, d.dwell)),
            max_retries: t.max_retries.unwrap_or(d.max_retries),
            retry_backoff: paced(secs(t.retry_backoff_s, d.retry_backoff)),
            locate_points: t.locate_points.unwrap_or(d.locate_points),
            velocity_deg_s: t.velocity_deg_s.unwrap_or(d.velocity_deg_s),
            accel_deg_s2: t.accel_deg_s2.unwrap_or(d.accel_deg_s2),
            beam_wait: secs(t.beam_wait_s, d.beam_wait),
            beam_retry: paced(secs(t.beam_retry_s, d.beam_retry)),
            settle,
            scan,
        }
    }

    /// The settling the configured axis needs, for the bound (`settle_time_s`).
    pub fn settle_model(&self) -> SettleModel {
        match self.timing.settle_time_s {
            Some(s) => SettleModel::Fixed(Duration::from_secs_f64(s)),
            None => SettleModel::Unknown,
        }
    }
}

/// The most characters a text field of the certificate holds (`laboratory`,
/// `traceability`, `signatory`, ...): about six lines of the header's value
/// column on A4 at 10 pt (some 67 characters a line), or two of a DCC
/// reader's screen; a longer text is not a field but a document.
pub const FIELD_MAX_CHARS: usize = 400;

/// The most characters a certificate number holds: one line of the running
/// head printed at the top of every page.
pub const NUMBER_MAX_CHARS: usize = 64;

/// The first control character of `text` (NUL, tab, a line break, escape,
/// the C1 controls), with its place, counted in characters from 1.
pub fn control_character(text: &str) -> Option<(usize, char)> {
    text.chars().enumerate().find(|(_, c)| c.is_control()).map(|(i, c)| (i + 1, c))
}

/// Text a certificate can print on its line: not empty (nor only spaces), no
/// control character (a field is one line: an address's parts are separated
/// by commas), at most `max` characters. The reason, as a predicate of the
/// text (`is empty`).
pub fn check_printable(text: &str, max: usize) -> Result<(), String> {
    let count = text.chars().count();
    if text.trim().is_empty() {
        Err("is empty: a key that is given must state something (leave it out to have \"not stated\")".into())
    } else if let Some((at, c)) = control_character(text) {
        Err(format!(
            "holds the control character U+{:04X} at character {at}, which a certificate cannot print (one line, \
             no tab, no line break)",
            c as u32
        ))
    } else if count > max {
        Err(format!("is {count} characters long: a certificate's field holds at most {max}"))
    } else {
        Ok(())
    }
}

/// A text field of the certificate: [`check_printable`] with [`FIELD_MAX_CHARS`].
pub fn check_field(text: &str) -> Result<(), String> {
    check_printable(text, FIELD_MAX_CHARS)
}

/// A certificate number: [`check_printable`] with [`NUMBER_MAX_CHARS`].
pub fn check_number(text: &str) -> Result<(), String> {
    check_printable(text, NUMBER_MAX_CHARS)
}

/// A calendar date `YYYY-MM-DD` that exists (`2026-02-30` does not).
pub fn check_date(text: &str) -> Result<(), String> {
    let shaped = text.len() == 10
        && text.char_indices().all(|(i, c)| if i == 4 || i == 7 { c == '-' } else { c.is_ascii_digit() });
    if !shaped {
        Err("not a date of the form YYYY-MM-DD".into())
    } else if humantime::parse_rfc3339(&format!("{text}T00:00:00Z")).is_ok() {
        Ok(())
    } else {
        // The form is right: the day is not one of the calendar's.
        Err("not a date (no such day in the calendar)".into())
    }
}

/// The officially assigned ISO 3166-1 alpha-2 country codes (249).
const ISO3166_ALPHA2: &str = "AD AE AF AG AI AL AM AO AQ AR AS AT AU AW AX AZ BA BB BD BE BF BG BH BI BJ BL BM BN BO \
    BQ BR BS BT BV BW BY BZ CA CC CD CF CG CH CI CK CL CM CN CO CR CU CV CW CX CY CZ DE DJ DK DM DO DZ EC EE EG EH ER \
    ES ET FI FJ FK FM FO FR GA GB GD GE GF GG GH GI GL GM GN GP GQ GR GS GT GU GW GY HK HM HN HR HT HU ID IE IL IM IN \
    IO IQ IR IS IT JE JM JO JP KE KG KH KI KM KN KP KR KW KY KZ LA LB LC LI LK LR LS LT LU LV LY MA MC MD ME MF MG MH \
    MK ML MM MN MO MP MQ MR MS MT MU MV MW MX MY MZ NA NC NE NF NG NI NL NO NP NR NU NZ OM PA PE PF PG PH PK PL PM PN \
    PR PS PT PW PY QA RE RO RS RU RW SA SB SC SD SE SG SH SI SJ SK SL SM SN SO SR SS ST SV SX SY SZ TC TD TF TG TH TJ \
    TK TL TM TN TO TR TT TV TW TZ UA UG UM US UY UZ VA VC VE VG VI VN VU WF WS YE YT ZA ZM ZW";

/// An officially assigned ISO 3166-1 alpha-2 code, two upper-case letters (`DE`, `GB`).
pub fn check_country(code: &str) -> Result<(), String> {
    if code.len() == 2 && ISO3166_ALPHA2.split_whitespace().any(|c| c == code) {
        Ok(())
    } else {
        Err("not an ISO 3166-1 alpha-2 country code (two upper-case letters, such as DE or GB)".into())
    }
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod driver_tests;

#[cfg(test)]
mod message_tests;
