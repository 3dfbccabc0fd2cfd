//! The binary layouts of the emScon TPI packets this driver uses, sans-IO:
//! [`Request`]s and [`Reply`]s encode to bytes and decode from complete
//! frames; [`Framer`] cuts a byte stream into frames by `lPacketSize`.
//!
//! Layout rules (from `ES_C_API_Def.h`): little-endian; `long`, `int`,
//! `ES_BOOL` and every `enum` are 4 bytes; `double` is 8 bytes; the header
//! declares `#pragma pack (push, 4)`, so a `double` after an odd number of
//! 4-byte fields is NOT padded (e.g. `SingleMeasResultT.dVal1` sits at offset
//! 20, and the struct is 156 bytes, not the 160 natural alignment would give). `lPacketSize` counts the whole
//! packet, header included.

use super::codes::{command as cmd, data_type as dt, status};
use super::frame::{DecodeError, MAX_PACKET_LEN, MIN_PACKET_LEN, PACKET_HEADER_LEN, RETURN_DATA_LEN};
use super::stream::{self, ContinuousTimeModeData, MultiMeasResult};
use std::collections::VecDeque;

/// `sizeof(struct BasicCommandCT)`: header + `enum ES_Command command`.
pub const BASIC_COMMAND_CT_LEN: usize = 12;
/// `sizeof(struct BasicCommandRT)`: header + `command` + `enum ES_ResultStatus status`.
pub const BASIC_COMMAND_RT_LEN: usize = 16;
/// `sizeof(struct ErrorResponseT)`: header + `command` + `status`.
pub const ERROR_RESPONSE_LEN: usize = 16;
/// `sizeof(struct SystemStatusChangeT)`: header + `enum ES_SystemStatusChange`.
pub const SYSTEM_STATUS_CHANGE_LEN: usize = 12;
/// `sizeof(struct SingleMeasResultT)`: `ReturnDataT`, `measMode`,
/// `bIsTryMode`, 17 doubles.
pub const SINGLE_MEAS_RESULT_LEN: usize = RETURN_DATA_LEN + 8 + 17 * 8;
/// `sizeof(struct SingleMeasResult2T)`: `ReturnDataT`, `measMode`,
/// `bIsTryMode`, 23 doubles (204 bytes).
pub const SINGLE_MEAS_RESULT2_LEN: usize = RETURN_DATA_LEN + 8 + 23 * 8;
/// `sizeof(struct SetStatisticModeCT)`: `BasicCommandCT` + two enums.
pub const SET_STATISTIC_MODE_CT_LEN: usize = BASIC_COMMAND_CT_LEN + 8;
/// `sizeof(struct SetUnitsCT)`: `BasicCommandCT` + `SystemUnitsDataT` (5 enums).
pub const SET_UNITS_CT_LEN: usize = BASIC_COMMAND_CT_LEN + 20;
/// `sizeof(struct SetCoordinateSystemTypeCT)` and `SetMeasurementModeCT`:
/// `BasicCommandCT` + one enum.
pub const ONE_ENUM_CT_LEN: usize = BASIC_COMMAND_CT_LEN + 4;
/// `sizeof(struct SetStationaryModeParamsCT)`: `BasicCommandCT` +
/// `StationaryModeDataT { long lMeasTime; ES_BOOL bUseADM; }`.
pub const SET_STATIONARY_MODE_PARAMS_CT_LEN: usize = BASIC_COMMAND_CT_LEN + 8;
/// `sizeof(struct FindReflectorCT)`: `BasicCommandCT` + `double dAproxDistance`.
pub const FIND_REFLECTOR_CT_LEN: usize = BASIC_COMMAND_CT_LEN + 8;
/// `sizeof(struct GoPositionCT)`: `BasicCommandCT` + three doubles + `ES_BOOL bUseADM`
/// (packed to 4: no padding before the doubles).
pub const GO_POSITION_CT_LEN: usize = BASIC_COMMAND_CT_LEN + 3 * 8 + 4;
/// `sizeof(struct GetSystemStatusRT)`: `BasicCommandRT` + four enums +
/// `ESVersionNumberT` (3 ints) + an enum + two longs.
pub const GET_SYSTEM_STATUS_RT_LEN: usize = BASIC_COMMAND_RT_LEN + 40;
/// `sizeof(struct GetMeasurementStatusInfoRT)`: `BasicCommandRT` +
/// `lastResultStatus` + `long lMeasurementStatusInfo`.
pub const GET_MEASUREMENT_STATUS_INFO_RT_LEN: usize = BASIC_COMMAND_RT_LEN + 8;

/// `struct SystemUnitsDataT`: five unit enums (see [`super::codes`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SystemUnits {
    /// `enum ES_LengthUnit lenUnitType`.
    pub length: i32,
    /// `enum ES_AngleUnit angUnitType`.
    pub angle: i32,
    /// `enum ES_TemperatureUnit tempUnitType`.
    pub temperature: i32,
    /// `enum ES_PressureUnit pressUnitType`.
    pub pressure: i32,
    /// `enum ES_HumidityUnit humUnitType`.
    pub humidity: i32,
}

impl SystemUnits {
    /// What this driver sets: mm, degrees, Celsius, mbar, %RH.
    pub const SURVEY: SystemUnits = SystemUnits { length: 1, angle: 1, temperature: 0, pressure: 0, humidity: 0 };
}

/// `struct StationaryModeDataT`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StationaryModeData {
    /// `long lMeasTime`: measurement time, milliseconds.
    pub meas_time_ms: i32,
    /// `ES_BOOL bUseADM`.
    pub use_adm: bool,
}

/// A command from the client (the `...CT` structs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Request {
    /// `InitializeCT`.
    Initialize,
    /// `SetUnitsCT`.
    SetUnits(SystemUnits),
    /// `SetCoordinateSystemTypeCT`: `enum ES_CoordinateSystemType`.
    SetCoordinateSystemType(i32),
    /// `SetMeasurementModeCT`: `enum ES_MeasMode`.
    SetMeasurementMode(i32),
    /// `SetStationaryModeParamsCT`.
    SetStationaryModeParams(StationaryModeData),
    /// `StartMeasurementCT`.
    StartMeasurement,
    /// `GetSystemStatusCT`.
    GetSystemStatus,
    /// `GetMeasurementStatusInfoCT`.
    GetMeasurementStatusInfo,
    /// `GoLastMeasuredPointCT`.
    GoLastMeasuredPoint,
    /// `FindReflectorCT`: `double dAproxDistance` (current length unit).
    FindReflector {
        /// Approximate distance to the reflector.
        approx_distance: f64,
    },
    /// `GoPositionCT`: `double dVal1, dVal2, dVal3` (the current coordinate
    /// system's values: x, y, z in the length unit for the right-handed
    /// rectangular one), `ES_BOOL bUseADM`.
    GoPosition {
        /// `dVal1..3`.
        position: [f64; 3],
        /// `bUseADM`.
        use_adm: bool,
    },
    /// `SetStatisticModeCT`: `enum ES_StatisticMode` for stationary and for
    /// continuous measurements.
    SetStatisticMode {
        /// `stationaryMeasurements`.
        stationary: i32,
        /// `continuousMeasurements`.
        continuous: i32,
    },
    /// `SetContinuousTimeModeParamsCT` ([`stream`]).
    SetContinuousTimeModeParams(ContinuousTimeModeData),
    /// `StopMeasurementCT`: ends a continuous measurement.
    StopMeasurement,
}

/// `GetSystemStatusRT` after its `BasicCommandRT`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SystemStatus {
    /// `enum ES_ResultStatus lastResultStatus`.
    pub last_result_status: i32,
    /// `enum ES_TrackerProcessorStatus trackerProcessorStatus`.
    pub tracker_processor_status: i32,
    /// `enum ES_LaserProcessorStatus laserStatus`.
    pub laser_status: i32,
    /// `enum ES_ADMStatus admStatus`.
    pub adm_status: i32,
    /// `struct ESVersionNumberT esVersionNumber`: major, minor, build.
    pub version: [i32; 3],
    /// `enum ES_WeatherMonitorStatus weatherMonitorStatus`.
    pub weather_monitor_status: i32,
    /// `long lFlagsValue`.
    pub flags: i32,
    /// `long lTrackerSerialNumber`.
    pub tracker_serial_number: i32,
}

/// `GetMeasurementStatusInfoRT` after its `BasicCommandRT`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MeasurementStatusInfo {
    /// `enum ES_ResultStatus lastResultStatus`.
    pub last_result_status: i32,
    /// `long lMeasurementStatusInfo`: `ES_MeasurementStatusInfo` bits.
    pub info: i32,
}

/// What follows the `BasicCommandRT` of a command answer.
#[derive(Debug, Clone, PartialEq)]
pub enum AnswerBody {
    /// Nothing: the answer is a bare `BasicCommandRT` (every modelled command
    /// on success but the two below, and any failed command).
    Empty,
    /// `GetSystemStatusRT`.
    SystemStatus(SystemStatus),
    /// `GetMeasurementStatusInfoRT`.
    MeasurementStatusInfo(MeasurementStatusInfo),
    /// The answer to an `ES_Command` this codec does not model: raw bytes.
    Other(Vec<u8>),
}

/// A command answer (`ES_DT_Command`, the `...RT` structs).
#[derive(Debug, Clone, PartialEq)]
pub struct Answer {
    /// `enum ES_Command command`.
    pub command: i32,
    /// `enum ES_ResultStatus status`.
    pub status: i32,
    /// The rest of the `...RT` struct.
    pub body: AnswerBody,
}

/// `struct SingleMeasResultT`, in the units set with `SetUnits`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SingleMeasResult {
    /// `packetInfo.status` (`ReturnDataT`).
    pub status: i32,
    /// `enum ES_MeasMode measMode`.
    pub meas_mode: i32,
    /// `ES_BOOL bIsTryMode`.
    pub is_try_mode: bool,
    /// `dVal1..3`: the position (x, y, z in a Cartesian system).
    pub val: [f64; 3],
    /// `dStd1..3`: standard deviations of the coordinates.
    pub std: [f64; 3],
    /// `dStdTotal`.
    pub std_total: f64,
    /// `dPointingError1..3`.
    pub pointing_error: [f64; 3],
    /// `dAprioriStd1..3`.
    pub apriori_std: [f64; 3],
    /// `dAprioriStdTotal`.
    pub apriori_std_total: f64,
    /// `dTemperature`.
    pub temperature: f64,
    /// `dPressure`.
    pub pressure: f64,
    /// `dHumidity`.
    pub humidity: f64,
}

/// `struct SingleMeasResult2T`: the extended stationary result a tracker
/// in `ES_SM_Extended` statistic mode sends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SingleMeasResult2 {
    /// `packetInfo.status`.
    pub status: i32,
    /// `enum ES_MeasMode measMode`.
    pub meas_mode: i32,
    /// `ES_BOOL bIsTryMode`.
    pub is_try_mode: bool,
    /// `dVal1..3`.
    pub val: [f64; 3],
    /// `dStd1..3`.
    pub std: [f64; 3],
    /// `dStdTotal`.
    pub std_total: f64,
    /// `dCovar12`, `dCovar13`, `dCovar23`.
    pub covar: [f64; 3],
    /// `dPointingErrorH`, `dPointingErrorV`, `dPointingErrorD`.
    pub pointing_error: [f64; 3],
    /// `dAprioriStd1..3`.
    pub apriori_std: [f64; 3],
    /// `dAprioriStdTotal`.
    pub apriori_std_total: f64,
    /// `dAprioriCovar12`, `dAprioriCovar13`, `dAprioriCovar23`.
    pub apriori_covar: [f64; 3],
    /// `dTemperature`.
    pub temperature: f64,
    /// `dPressure`.
    pub pressure: f64,
    /// `dHumidity`.
    pub humidity: f64,
}

impl From<SingleMeasResult2> for SingleMeasResult {
    /// The standard result inside an extended one (the covariances dropped).
    fn from(m: SingleMeasResult2) -> Self {
        SingleMeasResult {
            status: m.status,
            meas_mode: m.meas_mode,
            is_try_mode: m.is_try_mode,
            val: m.val,
            std: m.std,
            std_total: m.std_total,
            pointing_error: m.pointing_error,
            apriori_std: m.apriori_std,
            apriori_std_total: m.apriori_std_total,
            temperature: m.temperature,
            pressure: m.pressure,
            humidity: m.humidity,
        }
    }
}

/// A packet from the server.
#[derive(Debug, Clone, PartialEq)]
pub enum Reply {
    /// `ES_DT_Command`: a command answer.
    Answer(Answer),
    /// `ES_DT_Error`: `ErrorResponseT { command; status; }`.
    Error {
        /// `enum ES_Command command`.
        command: i32,
        /// `enum ES_ResultStatus status`.
        status: i32,
    },
    /// `ES_DT_SingleMeasResult`.
    SingleMeas(SingleMeasResult),
    /// `ES_DT_SingleMeasResult2` (extended statistic mode).
    SingleMeas2(SingleMeasResult2),
    /// `ES_DT_SystemStatusChange`: `enum ES_SystemStatusChange`.
    StatusChange(i32),
    /// `ES_DT_MultiMeasResult`: points of a continuous measurement ([`stream`]).
    MultiMeas(MultiMeasResult),
    /// Any other `ES_DataType` (reflector position, nivel, multi-measurement,
    /// probe results): not used here; kept raw so it can be skipped.
    Other {
        /// The `ES_DataType`.
        data_type: i32,
        /// The bytes after the packet header.
        body: Vec<u8>,
    },
}

// ---------------------------------------------------------------------------
// Byte helpers
// ---------------------------------------------------------------------------

/// A packet under construction: the size field is patched at the end.
struct Writer(Vec<u8>);

impl Writer {
    fn new(data_type: i32) -> Self {
        let mut w = Writer(Vec::with_capacity(64));
        w.i32(0);
        w.i32(data_type);
        w
    }
    fn i32(&mut self, v: i32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn finish(mut self) -> Vec<u8> {
        let n = i32::try_from(self.0.len()).unwrap_or(i32::MAX);
        self.0[..4].copy_from_slice(&n.to_le_bytes());
        self.0
    }
}

/// Reads fields of a frame whose length was checked beforehand.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn new(bytes: &'a [u8], at: usize) -> Self {
        Self { bytes, at }
    }
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        if let Some(s) = self.bytes.get(self.at..self.at + N) {
            out.copy_from_slice(s);
        }
        self.at += N;
        out
    }
    fn i32(&mut self) -> i32 {
        i32::from_le_bytes(self.take())
    }
    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take())
    }
    fn f64x3(&mut self) -> [f64; 3] {
        [self.f64(), self.f64(), self.f64()]
    }
}

fn expect_len(what: &'static str, frame: &[u8], expected: usize) -> Result<(), DecodeError> {
    if frame.len() == expected { Ok(()) } else { Err(DecodeError::WrongLength { what, len: frame.len(), expected }) }
}

/// Check `lPacketSize` against the frame and return the `type`.
fn header(frame: &[u8]) -> Result<i32, DecodeError> {
    if frame.len() < MIN_PACKET_LEN {
        return Err(DecodeError::WrongLength { what: "packet", len: frame.len(), expected: MIN_PACKET_LEN });
    }
    let mut r = Reader::new(frame, 0);
    let size = r.i32();
    if size < 0 || size as usize != frame.len() {
        return Err(DecodeError::SizeMismatch { size: i64::from(size), len: frame.len() });
    }
    Ok(r.i32())
}

// ---------------------------------------------------------------------------
// Requests
// ---------------------------------------------------------------------------

impl Request {
    /// The `ES_Command` of the request.
    pub fn command(&self) -> i32 {
        match self {
            Request::Initialize => cmd::INITIALIZE,
            Request::SetUnits(_) => cmd::SET_UNITS,
            Request::SetCoordinateSystemType(_) => cmd::SET_COORDINATE_SYSTEM_TYPE,
            Request::SetMeasurementMode(_) => cmd::SET_MEASUREMENT_MODE,
            Request::SetStationaryModeParams(_) => cmd::SET_STATIONARY_MODE_PARAMS,
            Request::StartMeasurement => cmd::START_MEASUREMENT,
            Request::GetSystemStatus => cmd::GET_SYSTEM_STATUS,
            Request::GetMeasurementStatusInfo => cmd::GET_MEASUREMENT_STATUS_INFO,
            Request::GoLastMeasuredPoint => cmd::GO_LAST_MEASURED_POINT,
            Request::FindReflector { .. } => cmd::FIND_REFLECTOR,
            Request::GoPosition { .. } => cmd::GO_POSITION,
            Request::SetStatisticMode { .. } => cmd::SET_STATISTIC_MODE,
            Request::SetContinuousTimeModeParams(_) => cmd::SET_CONTINUOUS_TIME_MODE_PARAMS,
            Request::StopMeasurement => cmd::STOP_MEASUREMENT,
        }
    }

    /// The packet: `BasicCommandCT` then the command's parameters.
    pub fn encode(&self) -> Vec<u8> {
        let mut w = Writer::new(dt::COMMAND);
        w.i32(self.command());
        match *self {
            Request::SetUnits(u) => {
                for v in [u.length, u.angle, u.temperature, u.pressure, u.humidity] {
                    w.i32(v);
                }
            }
            Request::SetCoordinateSystemType(v) | Request::SetMeasurementMode(v) => w.i32(v),
            Request::SetStationaryModeParams(p) => {
                w.i32(p.meas_time_ms);
                w.i32(i32::from(p.use_adm));
            }
            Request::FindReflector { approx_distance } => w.f64(approx_distance),
            Request::GoPosition { position, use_adm } => {
                for v in position {
                    w.f64(v);
                }
                w.i32(i32::from(use_adm));
            }
            Request::SetStatisticMode { stationary, continuous } => {
                w.i32(stationary);
                w.i32(continuous);
            }
            Request::SetContinuousTimeModeParams(p) => stream::encode_params(&p, &mut w.0),
            Request::StopMeasurement
            | Request::Initialize
            | Request::StartMeasurement
            | Request::GetSystemStatus
            | Request::GetMeasurementStatusInfo
            | Request::GoLastMeasuredPoint => {}
        }
        w.finish()
    }

    /// The `ES_Command` of a command frame, if it has one (for answering a
    /// request that did not decode).
    pub fn command_of(frame: &[u8]) -> Option<i32> {
        (header(frame).ok()? == dt::COMMAND).then(|| Reader::new(frame, PACKET_HEADER_LEN).i32())
    }

    /// Decode one complete command frame.
    pub fn decode(frame: &[u8]) -> Result<Request, DecodeError> {
        let data_type = header(frame)?;
        if data_type != dt::COMMAND {
            return Err(if (0..=11).contains(&data_type) {
                DecodeError::UnexpectedType { data_type }
            } else {
                DecodeError::UnknownType { data_type }
            });
        }
        let mut r = Reader::new(frame, PACKET_HEADER_LEN);
        let command = r.i32();
        let bare = |req: Request, what| expect_len(what, frame, BASIC_COMMAND_CT_LEN).map(|()| req);
        match command {
            cmd::INITIALIZE => bare(Request::Initialize, "InitializeCT"),
            cmd::START_MEASUREMENT => bare(Request::StartMeasurement, "StartMeasurementCT"),
            cmd::GET_SYSTEM_STATUS => bare(Request::GetSystemStatus, "GetSystemStatusCT"),
            cmd::GET_MEASUREMENT_STATUS_INFO => bare(Request::GetMeasurementStatusInfo, "GetMeasurementStatusInfoCT"),
            cmd::GO_LAST_MEASURED_POINT => bare(Request::GoLastMeasuredPoint, "GoLastMeasuredPointCT"),
            cmd::STOP_MEASUREMENT => bare(Request::StopMeasurement, "StopMeasurementCT"),
            cmd::SET_CONTINUOUS_TIME_MODE_PARAMS => {
                stream::decode_params(frame).map(Request::SetContinuousTimeModeParams)
            }
            cmd::SET_UNITS => {
                expect_len("SetUnitsCT", frame, SET_UNITS_CT_LEN)?;
                let u = SystemUnits {
                    length: r.i32(),
                    angle: r.i32(),
                    temperature: r.i32(),
                    pressure: r.i32(),
                    humidity: r.i32(),
                };
                Ok(Request::SetUnits(u))
            }
            cmd::SET_COORDINATE_SYSTEM_TYPE => {
                expect_len("SetCoordinateSystemTypeCT", frame, ONE_ENUM_CT_LEN)?;
                Ok(Request::SetCoordinateSystemType(r.i32()))
            }
            cmd::SET_MEASUREMENT_MODE => {
                expect_len("SetMeasurementModeCT", frame, ONE_ENUM_CT_LEN)?;
                Ok(Request::SetMeasurementMode(r.i32()))
            }
            cmd::SET_STATIONARY_MODE_PARAMS => {
                expect_len("SetStationaryModeParamsCT", frame, SET_STATIONARY_MODE_PARAMS_CT_LEN)?;
                let meas_time_ms = r.i32();
                let use_adm = r.i32() != 0;
                Ok(Request::SetStationaryModeParams(StationaryModeData { meas_time_ms, use_adm }))
            }
            cmd::FIND_REFLECTOR => {
                expect_len("FindReflectorCT", frame, FIND_REFLECTOR_CT_LEN)?;
                Ok(Request::FindReflector { approx_distance: r.f64() })
            }
            cmd::GO_POSITION => {
                expect_len("GoPositionCT", frame, GO_POSITION_CT_LEN)?;
                let position = [r.f64(), r.f64(), r.f64()];
                Ok(Request::GoPosition { position, use_adm: r.i32() != 0 })
            }
            cmd::SET_STATISTIC_MODE => {
                expect_len("SetStatisticModeCT", frame, SET_STATISTIC_MODE_CT_LEN)?;
                Ok(Request::SetStatisticMode { stationary: r.i32(), continuous: r.i32() })
            }
            _ => Err(DecodeError::UnsupportedCommand { command }),
        }
    }
}

// ---------------------------------------------------------------------------
// Replies
// ---------------------------------------------------------------------------

impl Reply {
    /// A bare `BasicCommandRT`.
    pub fn answer(command: i32, status: i32) -> Reply {
        Reply::Answer(Answer { command, status, body: AnswerBody::Empty })
    }

    /// The packet.
    pub fn encode(&self) -> Vec<u8> {
        match self {
            Reply::Answer(a) => {
                let mut w = Writer::new(dt::COMMAND);
                w.i32(a.command);
                w.i32(a.status);
                match &a.body {
                    AnswerBody::Empty => {}
                    AnswerBody::SystemStatus(s) => {
                        for v in [s.last_result_status, s.tracker_processor_status, s.laser_status, s.adm_status] {
                            w.i32(v);
                        }
                        for v in s.version {
                            w.i32(v);
                        }
                        for v in [s.weather_monitor_status, s.flags, s.tracker_serial_number] {
                            w.i32(v);
                        }
                    }
                    AnswerBody::MeasurementStatusInfo(m) => {
                        w.i32(m.last_result_status);
                        w.i32(m.info);
                    }
                    AnswerBody::Other(bytes) => w.0.extend_from_slice(bytes),
                }
                w.finish()
            }
            Reply::Error { command, status } => {
                let mut w = Writer::new(dt::ERROR);
                w.i32(*command);
                w.i32(*status);
                w.finish()
            }
            Reply::SingleMeas(m) => {
                let mut w = Writer::new(dt::SINGLE_MEAS_RESULT);
                w.i32(m.status);
                w.i32(m.meas_mode);
                w.i32(i32::from(m.is_try_mode));
                let doubles = m.val.iter().chain(&m.std).chain([&m.std_total]).chain(&m.pointing_error);
                for v in doubles.chain(&m.apriori_std).chain([&m.apriori_std_total]) {
                    w.f64(*v);
                }
                for v in [m.temperature, m.pressure, m.humidity] {
                    w.f64(v);
                }
                w.finish()
            }
            Reply::SingleMeas2(m) => {
                let mut w = Writer::new(dt::SINGLE_MEAS_RESULT2);
                w.i32(m.status);
                w.i32(m.meas_mode);
                w.i32(i32::from(m.is_try_mode));
                let doubles = m.val.iter().chain(&m.std).chain([&m.std_total]).chain(&m.covar).chain(&m.pointing_error);
                let doubles = doubles.chain(&m.apriori_std).chain([&m.apriori_std_total]).chain(&m.apriori_covar);
                for v in doubles.chain([&m.temperature, &m.pressure, &m.humidity]) {
                    w.f64(*v);
                }
                w.finish()
            }
            Reply::StatusChange(e) => {
                let mut w = Writer::new(dt::SYSTEM_STATUS_CHANGE);
                w.i32(*e);
                w.finish()
            }
            Reply::MultiMeas(m) => {
                let mut w = Writer::new(dt::MULTI_MEAS_RESULT);
                stream::encode_multi(m, &mut w.0);
                w.finish()
            }
            Reply::Other { data_type, body } => {
                let mut w = Writer::new(*data_type);
                w.0.extend_from_slice(body);
                w.finish()
            }
        }
    }

    /// Decode one complete frame from the server.
    pub fn decode(frame: &[u8]) -> Result<Reply, DecodeError> {
        let data_type = header(frame)?;
        let mut r = Reader::new(frame, PACKET_HEADER_LEN);
        match data_type {
            dt::COMMAND => decode_answer(frame),
            dt::ERROR => {
                expect_len("ErrorResponseT", frame, ERROR_RESPONSE_LEN)?;
                Ok(Reply::Error { command: r.i32(), status: r.i32() })
            }
            dt::SYSTEM_STATUS_CHANGE => {
                expect_len("SystemStatusChangeT", frame, SYSTEM_STATUS_CHANGE_LEN)?;
                Ok(Reply::StatusChange(r.i32()))
            }
            dt::SINGLE_MEAS_RESULT => {
                expect_len("SingleMeasResultT", frame, SINGLE_MEAS_RESULT_LEN)?;
                let status = r.i32();
                let meas_mode = r.i32();
                let is_try_mode = r.i32() != 0;
                Ok(Reply::SingleMeas(SingleMeasResult {
                    status,
                    meas_mode,
                    is_try_mode,
                    val: r.f64x3(),
                    std: r.f64x3(),
                    std_total: r.f64(),
                    pointing_error: r.f64x3(),
                    apriori_std: r.f64x3(),
                    apriori_std_total: r.f64(),
                    temperature: r.f64(),
                    pressure: r.f64(),
                    humidity: r.f64(),
                }))
            }
            dt::SINGLE_MEAS_RESULT2 => {
                expect_len("SingleMeasResult2T", frame, SINGLE_MEAS_RESULT2_LEN)?;
                let status = r.i32();
                let meas_mode = r.i32();
                let is_try_mode = r.i32() != 0;
                Ok(Reply::SingleMeas2(SingleMeasResult2 {
                    status,
                    meas_mode,
                    is_try_mode,
                    val: r.f64x3(),
                    std: r.f64x3(),
                    std_total: r.f64(),
                    covar: r.f64x3(),
                    pointing_error: r.f64x3(),
                    apriori_std: r.f64x3(),
                    apriori_std_total: r.f64(),
                    apriori_covar: r.f64x3(),
                    temperature: r.f64(),
                    pressure: r.f64(),
                    humidity: r.f64(),
                }))
            }
            dt::MULTI_MEAS_RESULT => stream::decode_multi(frame).map(Reply::MultiMeas),
            4..=7 | 10..=11 => Ok(Reply::Other { data_type, body: frame[PACKET_HEADER_LEN..].to_vec() }),
            _ => Err(DecodeError::UnknownType { data_type }),
        }
    }
}

/// `BasicCommandRT` and, for the commands modelled here, the rest of the
/// `...RT`. A failed command may come as a bare `BasicCommandRT` or as the
/// full `...RT` with its status set; a successful one must be the full `...RT`.
fn decode_answer(frame: &[u8]) -> Result<Reply, DecodeError> {
    let len = frame.len();
    if len < BASIC_COMMAND_RT_LEN {
        return Err(DecodeError::WrongLength { what: "BasicCommandRT", len, expected: BASIC_COMMAND_RT_LEN });
    }
    let mut r = Reader::new(frame, PACKET_HEADER_LEN);
    let command = r.i32();
    let status = r.i32();
    let failed_bare = status != status::ALL_OK && len == BASIC_COMMAND_RT_LEN;
    let body = match command {
        cmd::GET_SYSTEM_STATUS if !failed_bare => {
            expect_len("GetSystemStatusRT", frame, GET_SYSTEM_STATUS_RT_LEN)?;
            AnswerBody::SystemStatus(SystemStatus {
                last_result_status: r.i32(),
                tracker_processor_status: r.i32(),
                laser_status: r.i32(),
                adm_status: r.i32(),
                version: [r.i32(), r.i32(), r.i32()],
                weather_monitor_status: r.i32(),
                flags: r.i32(),
                tracker_serial_number: r.i32(),
            })
        }
        cmd::GET_MEASUREMENT_STATUS_INFO if !failed_bare => {
            expect_len("GetMeasurementStatusInfoRT", frame, GET_MEASUREMENT_STATUS_INFO_RT_LEN)?;
            AnswerBody::MeasurementStatusInfo(MeasurementStatusInfo { last_result_status: r.i32(), info: r.i32() })
        }
        cmd::GET_SYSTEM_STATUS | cmd::GET_MEASUREMENT_STATUS_INFO => AnswerBody::Empty,
        cmd::INITIALIZE
        | cmd::SET_UNITS
        | cmd::SET_COORDINATE_SYSTEM_TYPE
        | cmd::SET_MEASUREMENT_MODE
        | cmd::SET_STATIONARY_MODE_PARAMS
        | cmd::START_MEASUREMENT
        | cmd::GO_LAST_MEASURED_POINT
        | cmd::SET_CONTINUOUS_TIME_MODE_PARAMS
        | cmd::STOP_MEASUREMENT
        | cmd::GO_POSITION
        | cmd::FIND_REFLECTOR => {
            expect_len("BasicCommandRT", frame, BASIC_COMMAND_RT_LEN)?;
            AnswerBody::Empty
        }
        c if cmd::is_known(c) => AnswerBody::Other(frame[BASIC_COMMAND_RT_LEN..].to_vec()),
        _ => return Err(DecodeError::UnsupportedCommand { command }),
    };
    Ok(Reply::Answer(Answer { command, status, body }))
}

// ---------------------------------------------------------------------------
// Framing
// ---------------------------------------------------------------------------

/// Cuts a byte stream into packets by their `lPacketSize`.
///
/// An absurd size field (below [`MIN_PACKET_LEN`] or above
/// [`MAX_PACKET_LEN`]) is reported once, as soon as its 4 bytes are in; the
/// framer then holds nothing and drops every byte pushed until
/// [`clear`](Self::clear) is called (the caller resynchronises), so what
/// comes out never depends on how the bytes were chunked.
#[derive(Debug, Clone, Default)]
pub struct Framer {
    buf: Vec<u8>,
    lost: bool,
}

impl Framer {
    /// An empty framer.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feed received bytes (dropped while the framing is lost).
    pub fn push(&mut self, bytes: &[u8]) {
        if !self.lost {
            self.buf.extend_from_slice(bytes);
        }
    }

    /// The next complete packet, or the absurd size that lost the framing.
    pub fn next_frame(&mut self) -> Option<Result<Vec<u8>, DecodeError>> {
        if self.lost {
            return None;
        }
        let size_bytes: [u8; 4] = self.buf.get(..4)?.try_into().ok()?;
        let size = i32::from_le_bytes(size_bytes);
        let n = usize::try_from(size).ok().filter(|n| (MIN_PACKET_LEN..=MAX_PACKET_LEN).contains(n));
        let Some(n) = n else {
            self.buf.clear();
            self.lost = true;
            return Some(Err(DecodeError::AbsurdSize { size: i64::from(size) }));
        };
        if self.buf.len() < n {
            return None;
        }
        let rest = self.buf.split_off(n);
        Some(Ok(std::mem::replace(&mut self.buf, rest)))
    }

    /// Bytes held of a packet not yet complete.
    pub fn buffered_len(&self) -> usize {
        self.buf.len()
    }

    /// Whether an absurd size lost the framing (until [`clear`](Self::clear)).
    pub fn is_lost(&self) -> bool {
        self.lost
    }

    /// Drop everything held and start framing afresh at the next byte
    /// pushed; returns how many bytes were dropped.
    pub fn clear(&mut self) -> usize {
        let n = self.buf.len();
        self.buf.clear();
        self.lost = false;
        n
    }
}

/// The client's side: bytes in, [`Reply`]s (or one [`DecodeError`] per bad
/// packet) out, in order.
#[derive(Debug, Clone, Default)]
pub struct ReplyDecoder {
    framer: Framer,
    ready: VecDeque<Result<Reply, DecodeError>>,
}

impl ReplyDecoder {
    /// An empty decoder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feed received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.framer.push(bytes);
        while let Some(frame) = self.framer.next_frame() {
            self.ready.push_back(frame.and_then(|f| Reply::decode(&f)));
        }
    }

    /// The next reply or decode error, if any.
    pub fn next_reply(&mut self) -> Option<Result<Reply, DecodeError>> {
        self.ready.pop_front()
    }

    /// Bytes held of a packet not yet complete.
    pub fn buffered_len(&self) -> usize {
        self.framer.buffered_len()
    }

    /// Whether an absurd size lost the framing (until [`clear`](Self::clear)).
    pub fn is_lost(&self) -> bool {
        self.framer.is_lost()
    }

    /// Drop the partial packet and the replies not yet taken and start
    /// framing afresh; returns how many partial bytes and replies were dropped.
    pub fn clear(&mut self) -> (usize, usize) {
        let replies = self.ready.len();
        self.ready.clear();
        (self.framer.clear(), replies)
    }
}

/// The server's side: bytes in, [`Request`]s out. A request that does not
/// decode comes with its `ES_Command` when its frame has one, so it can be
/// answered.
#[derive(Debug, Clone, Default)]
pub struct RequestDecoder {
    framer: Framer,
}

impl RequestDecoder {
    /// An empty decoder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feed received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.framer.push(bytes);
    }

    /// The next request, or the decode error and the command of the frame.
    pub fn next_request(&mut self) -> Option<Result<Request, (DecodeError, Option<i32>)>> {
        let frame = self.framer.next_frame()?;
        Some(match frame {
            Ok(f) => Request::decode(&f).map_err(|e| (e, Request::command_of(&f))),
            Err(e) => Err((e, None)),
        })
    }
}
