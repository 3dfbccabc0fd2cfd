//! A simulated emScon server (Leica laser tracker, TPI binary protocol) on a
//! TCP port.
//!
//! [`serve_tcp`] speaks the protocol of [`survey_drivers::emscon`] (see its
//! module documentation for the packet layouts and what was looked up versus
//! chosen) and answers from a [`SimTracker`]: positions, noise, measurement
//! time, beam breaks and re-acquisition are the simulated tracker's, on its
//! clock (use a [`VirtualClock`](survey_drivers::VirtualClock): a measurement
//! then costs no real time). Only the tracker's public API is used.
//!
//! # Behaviour
//!
//! - One client at a time, like the hardware. A second client that connects
//!   while one is served gets its first command answered with
//!   `ES_RS_MultiConnectionsNotAllowed` (10011) and is then disconnected; the
//!   next client is served once the current one has gone. The server state
//!   (initialised, units, modes, lock) survives reconnections.
//! - A fresh server is not initialised (`StartMeasurement`,
//!   `GoLastMeasuredPoint` and `FindReflector` answer
//!   `ES_RS_TrackerNotInitialized` until `Initialize`) and reports lengths in
//!   metres (`ES_LU_Meter`, the enum's first value) until `SetUnits`.
//!   All length, temperature and pressure units of `Enum.h` are honoured;
//!   an out-of-range unit is `ES_RS_WrongParameter1..5` for the offending field.
//! - Only `ES_CS_RHR`, `ES_MM_Stationary` and `ES_MM_ContinuousTime` (see
//!   [`continuous`]) are implemented (other defined values:
//!   `ES_RS_NotImplemented`; undefined ones: `ES_RS_WrongParameter1`).
//!   `lMeasTime` must be at least 1 ms (`ES_RS_Parameter1OutOfRangeNOK`); it is
//!   kept, but a simulated measurement always takes the [`SimTracker`]'s own
//!   configured measurement time (its API has no setter).
//! - `StartMeasurement` answers with a `SingleMeasResultT`: the tracker's
//!   position and standard deviations (also as the a-priori ones; the totals
//!   are the root sum of squares; no pointing error), at 20 °C, 1013.25 mbar,
//!   50 %RH. When the beam breaks during the measurement the server first
//!   sends the status change `ES_SSC_MeasStatus_NotReady`, then answers
//!   `ES_RS_NoStationaryResult` (10009); while it stays broken, measurements
//!   answer `ES_RS_MeasurementStatusNotReady` (10004).
//! - `GoLastMeasuredPoint` re-acquires the SMR ([`SimTracker::reacquire`])
//!   when a measurement succeeded before, else answers
//!   `ES_RS_NoLastMeasuredPoint` (28). `FindReflector` re-acquires it (a
//!   distance that is not a positive number: `ES_RS_Parameter1OutOfRangeNOK`).
//!   Both send `ES_SSC_MeasStatus_Ready` first when the lock comes back.
//!   When the beam is still blocked and no reflector is found, both answer
//!   `ES_RS_MeasurementStatusNotReady` (10004). Our choice: the public V3.6
//!   header defines no "reflector not found" status and no public document
//!   says what a failed search answers; 10004 is the header's status for a
//!   tracker whose measurement status is not ready (no reflector locked, the
//!   state `ES_SSC_MeasStatus_NotReady` announced), the one this server
//!   already answers to a measurement while the beam stays broken, so a
//!   client reads both the same way.
//! - `GetSystemStatus`: `ES_TPS_Initialized` once initialised (else
//!   `ES_TPS_CompensationSet`), laser ready, ADM ready, version 3.6.0, serial
//!   [`SIM_SERIAL_NUMBER`], and the status of the previous command.
//!   `GetMeasurementStatusInfo`: tracker, compensation, ADM, face 1 and nivel
//!   bits, `ES_MSI_Initialized` once initialised, `ES_MSI_ReflectorFound`
//!   while the tracker is locked.
//! - A command this server does not model: a bare answer with
//!   `ES_RS_NotImplemented`; a command packet of the wrong size:
//!   `ES_RS_WrongParameter`; a packet that is not a command: an
//!   `ErrorResponseT` for `ES_C_Unknown` with `ES_RS_WrongParameter`; an
//!   absurd size field: the connection is closed.
//!
//! # Faults ([`Faults`])
//!
//! The server is a [`Service`] served by [`crate::serve`]'s loops; link
//! faults are the [`relay`](crate::relay)'s in front of it ([`garbled`]: the
//! emScon ways to garble an answer, [`Garble`]). Device faults armed in its
//! [`Faults`] apply to the next commands as they come:
//!
//! - [`Fault::Refuse`]: the next command is not executed and is answered
//!   with the given result status as a bare `BasicCommandRT` (`None`:
//!   `ES_RS_SensorNotStable`); [`Fault::RefuseWithError`]: as an
//!   `ErrorResponseT`;
//! - [`Fault::Event`]: an unsolicited `SystemStatusChangeT` (e.g.
//!   `ES_SSC_MeasStatus_NotReady`) right before the next answer (the
//!   tracker's state does not change).
//!
//! [`Server::requests`] lists the commands received, for tests.

use crate::serve::{self, Codec, Service};
use async_trait::async_trait;
use std::sync::{Arc, Mutex};
use survey_drivers::emscon::codes::{
    adm_status, command as cmd, coordinate_system, data_type, laser_status, length_unit, meas_mode,
    measurement_status_info as msi, pressure_unit, statistic_mode, status, status_change, temperature_unit,
    tracker_processor_status, weather_monitor_status,
};
use survey_drivers::emscon::packets::{
    Answer, AnswerBody, MeasurementStatusInfo, Reply, Request, RequestDecoder, SingleMeasResult, SingleMeasResult2,
    StationaryModeData, SystemStatus, SystemUnits,
};
use survey_drivers::traits::{SmrMeasurement, Tracker, TrackerState};
use survey_sims::faults::{Fault, Faults};
use survey_sims::tracker::{CODE_BEAM_BROKEN, SimTracker};
use tokio::net::TcpListener;

mod continuous;

/// `dTemperature` of a result whose measurement carries no room, and of the continuous stream's packets, °C.
pub const SIM_TEMPERATURE_C: f64 = 20.0;
/// `dPressure` of every result, mbar.
pub const SIM_PRESSURE_MBAR: f64 = 1013.25;
/// `dHumidity` of every result, %RH.
pub const SIM_HUMIDITY_RH: f64 = 50.0;
/// `lTrackerSerialNumber` of `GetSystemStatus`.
pub const SIM_SERIAL_NUMBER: i32 = 390_001;

/// The emScon ways to garble an answer ([`garbled`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Garble {
    /// The `type` field becomes a value no `ES_DataType` has.
    UnknownType,
    /// The last 4 bytes are cut and `lPacketSize` says so: a size that does
    /// not fit the packet's type.
    WrongLength,
    /// `lPacketSize` becomes absurd (1 GiB): the framing is lost.
    AbsurdSize,
    /// The second byte of the `enum ES_ResultStatus` field is changed (XOR
    /// 0x5a, as the relay of `survey sim` garbles a byte): `ES_RS_AllOK`
    /// reads 23040, a status the header does not define.
    Status,
}

/// A link fault for the relay in front of the server: the next answer
/// garbled as `how` says.
pub fn garbled(how: Garble) -> Fault {
    Fault::Garble(survey_sims::faults::Garble::edit("emScon answer garbled", move |packet: &[u8]| {
        (packet.len() >= 16).then(|| garble(packet.to_vec(), how))
    }))
}

/// The commands a server received, in order (also the refused ones); a
/// cheap handle shared by clones.
#[derive(Debug, Clone, Default)]
pub struct Requests(Arc<Mutex<Vec<Request>>>);

impl Requests {
    /// The commands received so far.
    pub fn get(&self) -> Vec<Request> {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }

    fn push(&self, request: Request) {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).push(request);
    }
}

/// Serve the tracker on `listener`, one client at a time, until the task
/// running this future is dropped or aborted.
pub async fn serve_tcp(listener: TcpListener, tracker: SimTracker, faults: Faults) {
    serve_server(listener, Server::new(tracker, faults)).await;
}

/// Serve `server` on `listener` (see [`serve_tcp`]).
pub async fn serve_server(listener: TcpListener, server: Server) {
    crate::serve::serve_tcp(listener, RequestDecoder::new, server).await;
}

impl Codec for RequestDecoder {
    type Item = Result<Request, (survey_drivers::emscon::DecodeError, Option<i32>)>;
    fn push(&mut self, bytes: &[u8]) {
        RequestDecoder::push(self, bytes);
    }
    fn next_item(&mut self) -> Option<Self::Item> {
        self.next_request()
    }
}

/// Packets for one command: status changes, then the answer.
struct Response {
    events: Vec<i32>,
    answer: Reply,
}

/// A simulated emScon server: the [`Service`] [`serve_tcp`] serves.
#[derive(Debug)]
pub struct Server {
    sim: SimTracker,
    faults: Faults,
    requests: Requests,
    initialized: bool,
    units: SystemUnits,
    stationary: StationaryModeData,
    /// Mirror of the tracker's lock (only measure and reacquire change it).
    locked: bool,
    last_point: bool,
    last_status: i32,
    /// `ES_StatisticMode` of stationary measurements: standard answers
    /// `SingleMeasResultT`, extended `SingleMeasResult2T` (per
    /// `ES_C_API_Def.h`). Survives reconnections, like the tracker's.
    statistic_mode: i32,
    /// The measurement mode set, and the continuous mode's state ([`continuous`]).
    mode: i32,
    continuous: continuous::Continuous,
}

fn ok(command: i32) -> Reply {
    Reply::answer(command, status::ALL_OK)
}

impl Server {
    /// A server of `sim`, its device faults armed in `faults`.
    pub fn new(sim: SimTracker, faults: Faults) -> Self {
        let meas_time_ms = i32::try_from(sim.config().measurement_time.as_millis()).unwrap_or(i32::MAX);
        Self {
            sim,
            faults,
            requests: Requests::default(),
            initialized: false,
            units: SystemUnits { length: length_unit::METER, angle: 0, temperature: 0, pressure: 0, humidity: 0 },
            stationary: StationaryModeData { meas_time_ms, use_adm: false },
            locked: true,
            last_point: false,
            last_status: status::ALL_OK,
            statistic_mode: statistic_mode::STANDARD,
            mode: meas_mode::STATIONARY,
            continuous: continuous::Continuous::default(),
        }
    }

    /// The tracker was left in extended statistic mode by other software:
    /// it answers measurements with `SingleMeasResult2T` until a client sets
    /// the mode.
    pub fn left_in_extended_statistic_mode(mut self) -> Self {
        self.statistic_mode = statistic_mode::EXTENDED;
        self
    }

    /// The commands received, shared (read it while the server serves).
    pub fn requests(&self) -> Requests {
        self.requests.clone()
    }

    /// The packets for one request: the points streamed since the last
    /// packets, the status changes (the command's own, then one armed), then
    /// the answer.
    async fn respond(&mut self, response: Response) -> Vec<u8> {
        let armed = match self.faults.take_device(|f| matches!(f, Fault::Event(_))) {
            Some(Fault::Event(e)) => i32::try_from(e).ok(),
            _ => None,
        };
        let mut bytes = self.stream_packets().await;
        for event in response.events.iter().chain(&armed) {
            bytes.extend(Reply::StatusChange(*event).encode());
        }
        bytes.extend(response.answer.encode());
        bytes
    }

    async fn handle(&mut self, request: Request) -> Response {
        let c = request.command();
        self.requests.push(request);
        let refused = self.faults.take_device(|f| matches!(f, Fault::Refuse(_) | Fault::RefuseWithError(_)));
        if let Some(fault) = refused {
            let code = |d: &survey_drivers::traits::DeviceFault| i32::try_from(d.code).unwrap_or(status::UNKNOWN);
            let answer = match &fault {
                Fault::RefuseWithError(d) => Reply::Error { command: c, status: code(d) },
                Fault::Refuse(Some(d)) => Reply::answer(c, code(d)),
                _ => Reply::answer(c, status::SENSOR_NOT_STABLE),
            };
            tracing::debug!(?request, ?fault, "emscon simulator: command refused (injected)");
            self.last_status = match &answer {
                Reply::Answer(a) => a.status,
                Reply::Error { status, .. } => *status,
                _ => status::UNKNOWN,
            };
            return Response { events: Vec::new(), answer };
        }
        let mut events = Vec::new();
        let fail = |code| Reply::answer(c, code);
        let answer = match request {
            Request::Initialize => {
                self.initialized = true;
                ok(c)
            }
            Request::SetUnits(u) => match bad_unit(u) {
                Some(field) => fail(status::WRONG_PARAMETER1 + field),
                None => {
                    self.units = u;
                    ok(c)
                }
            },
            Request::SetCoordinateSystemType(t) => match t {
                coordinate_system::RHR => ok(c),
                1..=coordinate_system::SCC => fail(status::NOT_IMPLEMENTED),
                _ => fail(status::WRONG_PARAMETER1),
            },
            Request::SetMeasurementMode(m) => match m {
                meas_mode::STATIONARY | meas_mode::CONTINUOUS_TIME if self.continuous.running() => {
                    fail(status::SERVER_BUSY)
                }
                meas_mode::STATIONARY | meas_mode::CONTINUOUS_TIME => {
                    self.mode = m;
                    ok(c)
                }
                1..=meas_mode::LAST => fail(status::NOT_IMPLEMENTED),
                _ => fail(status::WRONG_PARAMETER1),
            },
            Request::SetStationaryModeParams(p) if p.meas_time_ms < 1 => fail(status::PARAMETER1_OUT_OF_RANGE_NOK),
            Request::SetStationaryModeParams(p) => {
                let sim_ms = self.sim.config().measurement_time.as_millis();
                if u128::try_from(p.meas_time_ms).ok() != Some(sim_ms) {
                    tracing::debug!(
                        p.meas_time_ms,
                        sim_ms,
                        "emscon simulator: lMeasTime kept, the sim's own time applies"
                    );
                }
                self.stationary = p;
                ok(c)
            }
            Request::GetSystemStatus => Reply::Answer(Answer {
                command: c,
                status: status::ALL_OK,
                body: AnswerBody::SystemStatus(self.system_status()),
            }),
            Request::GetMeasurementStatusInfo => {
                let locked = matches!(self.sim.status().await, Ok(TrackerState::TargetLocked));
                let mut info = msi::TRACKER_FOUND
                    | msi::TRACKER_COMPENSATION_FOUND
                    | msi::ADM_FOUND
                    | msi::ADM_COMPENSATION_FOUND
                    | msi::IN_FACE1
                    | msi::NIVEL_IN_WORKING_RANGE;
                if self.initialized {
                    info |= msi::INITIALIZED;
                }
                if locked {
                    info |= msi::REFLECTOR_FOUND;
                }
                let m = MeasurementStatusInfo { last_result_status: self.last_status, info };
                Reply::Answer(Answer { command: c, status: status::ALL_OK, body: AnswerBody::MeasurementStatusInfo(m) })
            }
            Request::SetContinuousTimeModeParams(p) => self.continuous_params(p),
            Request::StopMeasurement => self.stop_stream().await,
            _ if !self.initialized => fail(status::TRACKER_NOT_INITIALIZED),
            Request::StartMeasurement if self.mode == meas_mode::CONTINUOUS_TIME => self.start_stream().await,
            Request::StartMeasurement => self.measure(&mut events).await,
            Request::GoLastMeasuredPoint if !self.last_point => fail(status::NO_LAST_MEASURED_POINT),
            Request::GoLastMeasuredPoint => self.relock(c, &mut events).await,
            Request::FindReflector { approx_distance } if !(approx_distance.is_finite() && approx_distance > 0.0) => {
                fail(status::PARAMETER1_OUT_OF_RANGE_NOK)
            }
            Request::FindReflector { .. } => self.relock(c, &mut events).await,
            Request::GoPosition { position, .. } => match self.sim.go_position(position).await {
                Ok(()) => {
                    if self.locked {
                        // The beam left the reflector it was on.
                        events.push(status_change::MEAS_STATUS_NOT_READY);
                        self.locked = false;
                    }
                    ok(c)
                }
                Err(e) => {
                    tracing::info!(error = %e, "emscon simulator: GoPosition refused");
                    fail(status::PARAMETER1_OUT_OF_RANGE_NOK)
                }
            },
            Request::SetStatisticMode { stationary, continuous } => {
                let valid = |m: i32| m == statistic_mode::STANDARD || m == statistic_mode::EXTENDED;
                if !valid(stationary) {
                    fail(status::WRONG_PARAMETER1)
                } else if !valid(continuous) {
                    fail(status::WRONG_PARAMETER)
                } else {
                    self.statistic_mode = stationary;
                    ok(c)
                }
            }
        };
        self.last_status = match &answer {
            Reply::Answer(a) => a.status,
            Reply::SingleMeas(m) => m.status,
            Reply::SingleMeas2(m) => m.status,
            Reply::Error { status, .. } => *status,
            Reply::StatusChange(_) | Reply::Other { .. } | Reply::MultiMeas(_) => status::ALL_OK,
        };
        Response { events, answer }
    }

    async fn measure(&mut self, events: &mut Vec<i32>) -> Reply {
        let c = cmd::START_MEASUREMENT;
        let before = self.sim.measurements();
        match self.sim.measure().await {
            Ok(m) => {
                self.last_point = true;
                self.locked = true;
                let standard = self.result(&m);
                if self.statistic_mode == statistic_mode::EXTENDED {
                    Reply::SingleMeas2(extended(standard))
                } else {
                    Reply::SingleMeas(standard)
                }
            }
            Err(e) if e.code == Some(CODE_BEAM_BROKEN) => {
                let broke_now = self.sim.measurements() > before;
                if broke_now && self.locked {
                    events.push(status_change::MEAS_STATUS_NOT_READY);
                }
                self.locked = false;
                let code = if broke_now { status::NO_STATIONARY_RESULT } else { status::MEASUREMENT_STATUS_NOT_READY };
                Reply::answer(c, code)
            }
            Err(e) => {
                tracing::warn!(error = %e, "emscon simulator: the simulated tracker failed");
                Reply::answer(c, status::UNKNOWN)
            }
        }
    }

    async fn relock(&mut self, c: i32, events: &mut Vec<i32>) -> Reply {
        // After a GoPosition the search is where the beam points, else the
        // reflector it was on is found again.
        let found = if c == cmd::FIND_REFLECTOR { self.sim.find_reflector().await } else { self.sim.reacquire().await };
        match found {
            Ok(()) => {
                if !self.locked {
                    events.push(status_change::MEAS_STATUS_READY);
                    self.locked = true;
                }
                ok(c)
            }
            Err(e) if e.code == Some(CODE_BEAM_BROKEN) => {
                // No reflector found: the tracker stays not ready to measure.
                tracing::info!(error = %e, "emscon simulator: no reflector found, the beam is still broken");
                self.locked = false;
                Reply::answer(c, status::MEASUREMENT_STATUS_NOT_READY)
            }
            Err(e) => {
                tracing::warn!(error = %e, "emscon simulator: re-acquisition failed");
                Reply::answer(c, status::UNKNOWN)
            }
        }
    }

    fn system_status(&self) -> SystemStatus {
        SystemStatus {
            last_result_status: self.last_status,
            tracker_processor_status: if self.initialized {
                tracker_processor_status::INITIALIZED
            } else {
                tracker_processor_status::COMPENSATION_SET
            },
            laser_status: laser_status::LASER_READY,
            adm_status: adm_status::ADM_READY,
            version: [3, 6, 0],
            weather_monitor_status: weather_monitor_status::READ_ONLY,
            flags: 0,
            tracker_serial_number: SIM_SERIAL_NUMBER,
        }
    }

    /// The tracker's measurement in the units set.
    fn result(&self, m: &SmrMeasurement) -> SingleMeasResult {
        let k = per_mm(self.units.length);
        let std = m.std_dev_mm.map(|s| s * k);
        let total = std.iter().map(|s| s * s).sum::<f64>().sqrt();
        // The simulated room ([`survey_sims::room`]) the measurement reports.
        let air = m.environment.unwrap_or(survey_drivers::AirEnvironment {
            temperature_c: SIM_TEMPERATURE_C,
            pressure_hpa: SIM_PRESSURE_MBAR,
            humidity_pct: SIM_HUMIDITY_RH,
        });
        let temperature = match self.units.temperature {
            temperature_unit::FAHRENHEIT => air.temperature_c * 9.0 / 5.0 + 32.0,
            _ => air.temperature_c,
        };
        SingleMeasResult {
            status: status::ALL_OK,
            meas_mode: meas_mode::STATIONARY,
            is_try_mode: false,
            val: m.xyz().map(|v| v * k),
            std,
            std_total: total,
            pointing_error: [0.0; 3],
            apriori_std: std,
            apriori_std_total: total,
            temperature,
            pressure: air.pressure_hpa * per_mbar(self.units.pressure),
            humidity: air.humidity_pct,
        }
    }
}

/// The extended result of a stationary measurement: the standard one with
/// its covariances (the simulated tracker's coordinate errors are
/// independent: zero covariance).
fn extended(m: SingleMeasResult) -> SingleMeasResult2 {
    SingleMeasResult2 {
        status: m.status,
        meas_mode: m.meas_mode,
        is_try_mode: m.is_try_mode,
        val: m.val,
        std: m.std,
        std_total: m.std_total,
        covar: [0.0; 3],
        pointing_error: m.pointing_error,
        apriori_std: m.apriori_std,
        apriori_std_total: m.apriori_std_total,
        apriori_covar: [0.0; 3],
        temperature: m.temperature,
        pressure: m.pressure,
        humidity: m.humidity,
    }
}

/// The field (0-based) of `SystemUnitsDataT` holding an undefined value.
fn bad_unit(u: SystemUnits) -> Option<i32> {
    let ok = [(0..=5).contains(&u.length), (0..=2).contains(&u.angle), (0..=1).contains(&u.temperature)];
    let ok = [ok[0], ok[1], ok[2], (0..=6).contains(&u.pressure), u.humidity == 0];
    ok.iter().position(|good| !good).map(|i| i as i32)
}

/// Length units per millimetre.
fn per_mm(unit: i32) -> f64 {
    match unit {
        length_unit::METER => 1e-3,
        length_unit::MICRON => 1e3,
        length_unit::FOOT => 1.0 / 304.8,
        length_unit::YARD => 1.0 / 914.4,
        length_unit::INCH => 1.0 / 25.4,
        _ => 1.0,
    }
}

/// Pressure units per millibar.
fn per_mbar(unit: i32) -> f64 {
    match unit {
        pressure_unit::KPASCAL => 0.1,
        pressure_unit::MMHG => 0.750_061_683,
        pressure_unit::PSI => 0.014_503_773_8,
        pressure_unit::INH2O => 0.401_463_078,
        pressure_unit::INHG => 0.029_529_983_1,
        _ => 1.0,
    }
}

#[async_trait]
impl Service for Server {
    type Request = Result<Request, (survey_drivers::emscon::DecodeError, Option<i32>)>;
    type Reply = Vec<u8>;

    /// One client at a time, like the hardware.
    const REFUSES_SECOND_CLIENT: bool = true;

    async fn call(&mut self, request: Self::Request) -> serve::Answer<Vec<u8>> {
        let response = match request {
            Ok(request) => self.handle(request).await,
            Err((e, _)) if e.loses_framing() => {
                tracing::warn!(error = %e, "emscon simulator: unframed request, closing");
                return serve::Answer::Close;
            }
            Err((e, command)) => {
                tracing::debug!(error = %e, "emscon simulator: request refused");
                let code = match e {
                    survey_drivers::emscon::DecodeError::UnsupportedCommand { .. } => status::NOT_IMPLEMENTED,
                    _ => status::WRONG_PARAMETER,
                };
                let answer = match command {
                    Some(c) => Reply::answer(c, code),
                    None => Reply::Error { command: cmd::UNKNOWN, status: code },
                };
                Response { events: Vec::new(), answer }
            }
        };
        serve::Answer::Send(self.respond(response).await)
    }

    /// The points measured so far, pushed on a timer while a continuous
    /// measurement runs on a clock that is not virtual.
    async fn unsolicited(&mut self) -> serve::Answer<Vec<u8>> {
        if !self.continuous.pushes() {
            return std::future::pending().await;
        }
        self.continuous.tick().await;
        let bytes = self.stream_packets().await;
        if bytes.is_empty() { serve::Answer::Nothing } else { serve::Answer::Send(bytes) }
    }

    /// `ES_RS_MultiConnectionsNotAllowed` to the command of a second client.
    fn busy(request: Self::Request) -> Option<Vec<u8>> {
        let command = match request {
            Ok(r) => r.command(),
            Err((_, c)) => c.unwrap_or(cmd::UNKNOWN),
        };
        Some(Reply::answer(command, status::MULTI_CONNECTIONS_NOT_ALLOWED).encode())
    }
}

/// A packet garbled as `how` asks.
fn garble(mut packet: Vec<u8>, how: Garble) -> Vec<u8> {
    match how {
        Garble::UnknownType => packet[4..8].copy_from_slice(&0x0BAD_F00Di32.to_le_bytes()),
        Garble::WrongLength => {
            packet.truncate(packet.len() - 4);
            let n = packet.len() as i32;
            packet[..4].copy_from_slice(&n.to_le_bytes());
        }
        Garble::AbsurdSize => packet[..4].copy_from_slice(&(1i32 << 30).to_le_bytes()),
        Garble::Status => {
            // After the header: `command` then `status` in `BasicCommandRT`
            // and `ErrorResponseT`; `status` first in `ReturnDataT`.
            let data_type = i32::from_le_bytes([packet[4], packet[5], packet[6], packet[7]]);
            let at = if matches!(data_type, data_type::COMMAND | data_type::ERROR) { 12 } else { 8 };
            packet[at + 1] ^= 0x5a;
        }
    }
    tracing::debug!(?how, "emscon simulator: answer garbled (injected)");
    packet
}

#[cfg(test)]
mod tests;
