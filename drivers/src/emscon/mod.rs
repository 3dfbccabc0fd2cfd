//! Leica laser trackers through the emScon TPI (Tracker Programming
//! Interface) binary protocol over TCP (port [`DEFAULT_PORT`], 700, one
//! client): a sans-IO codec ([`packets`]) and the [`EmsconTracker`] driver,
//! generic over its byte stream (TCP, or an in-memory duplex in tests).
//!
//! # The protocol as implemented
//!
//! Every packet starts with `struct PacketHeaderT { long lPacketSize; enum
//! ES_DataType type; }`; `lPacketSize` counts the whole packet. Integers and
//! enums are 32-bit, doubles 64-bit, all little-endian, laid out with the
//! header's `#pragma pack (push, 4)` (no padding before a double). Commands
//! go out as `...CT` structs (`BasicCommandCT { PacketHeaderT; enum ES_Command
//! command; }` + parameters) with type `ES_DT_Command`; answers come back as
//! `...RT` structs (`BasicCommandRT { PacketHeaderT; command; enum
//! ES_ResultStatus status; }` + results), also typed `ES_DT_Command`.
//!
//! | request | struct sent | answer | sizes (bytes) |
//! |---|---|---|---|
//! | `ES_C_Initialize` (7) | `InitializeCT` | `InitializeRT` | 12 / 16 |
//! | `ES_C_SetUnits` (5) | `SetUnitsCT` (`SystemUnitsDataT`: 5 enums) | `SetUnitsRT` | 32 / 16 |
//! | `ES_C_SetCoordinateSystemType` (26) | `SetCoordinateSystemTypeCT` | `...RT` | 16 / 16 |
//! | `ES_C_SetMeasurementMode` (24) | `SetMeasurementModeCT` (`ES_MM_Stationary`) | `...RT` | 16 / 16 |
//! | `ES_C_SetStationaryModeParams` (28) | `...CT` (`StationaryModeDataT { long lMeasTime; ES_BOOL bUseADM; }`) | `...RT` | 20 / 16 |
//! | `ES_C_SetStatisticMode` (80) | `...CT` (`enum ES_StatisticMode stationaryMeasurements, continuousMeasurements`) | `...RT` | 20 / 16 |
//! | `ES_C_StartMeasurement` (49) | `StartMeasurementCT` | `SingleMeasResultT` (type `ES_DT_SingleMeasResult`), or `SingleMeasResult2T` (type `ES_DT_SingleMeasResult2`) in extended statistic mode | 12 / 156 or 204 |
//! | `ES_C_GetSystemStatus` (1) | `GetSystemStatusCT` | `GetSystemStatusRT` | 12 / 56 |
//! | `ES_C_GetMeasurementStatusInfo` (122) | `...CT` | `...RT` (`lastResultStatus`, `lMeasurementStatusInfo`) | 12 / 24 |
//! | `ES_C_GoLastMeasuredPoint` (62) | `GoLastMeasuredPointCT` | `...RT` | 12 / 16 |
//! | `ES_C_FindReflector` (63) | `FindReflectorCT` (`double dAproxDistance`) | `...RT` | 20 / 16 |
//! | `ES_C_GoPosition` (55) | `GoPositionCT` (`double dVal1, dVal2, dVal3; ES_BOOL bUseADM`) | `...RT` | 40 / 16 |
//!
//! Also from the server, at any time: `SystemStatusChangeT { PacketHeaderT;
//! enum ES_SystemStatusChange systemStatusChange; }` (type
//! `ES_DT_SystemStatusChange`, 12 bytes) and `ErrorResponseT { PacketHeaderT;
//! command; status; }` (type `ES_DT_Error`, 16 bytes).
//!
//! `SingleMeasResultT` is `ReturnDataT { PacketHeaderT; status; }`, `measMode`,
//! `bIsTryMode`, then `dVal1..3, dStd1..3, dStdTotal, dPointingError1..3,
//! dAprioriStd1..3, dAprioriStdTotal, dTemperature, dPressure, dHumidity`
//! (17 doubles from offset 20: 156 bytes; natural 8-byte alignment would
//! wrongly give 160).
//!
//! ## The driver
//!
//! - On connect ([`EmsconTracker::connect`] / [`EmsconTracker::open`] /
//!   [`EmsconTracker::setup`]): `Initialize` (unless
//!   [`EmsconConfig::initialize`] is false), `SetUnits` (mm, degree, Celsius,
//!   mbar, %RH), `SetCoordinateSystemType` (`ES_CS_RHR`, so `dVal1..3` are
//!   x, y, z), `SetMeasurementMode` (`ES_MM_Stationary`), `SetStatisticMode`
//!   (`ES_SM_Standard` for both modes, so the answer is the standard result),
//!   `SetStationaryModeParams` (`lMeasTime` = [`EmsconConfig::measurement_time_ms`]).
//! - `measure`: `StartMeasurement`; the answer is the `SingleMeasResultT`, or
//!   the `SingleMeasResult2T` a tracker left in extended mode by other
//!   software sends (its covariances are dropped). An
//!   `ES_DT_Command` answer to `StartMeasurement` with `ES_RS_AllOK` (what a
//!   server sends in continuous mode) is taken as an acknowledgement and the
//!   result still awaited.
//! - `status`: `GetSystemStatus` (`trackerProcessorStatus` other than
//!   `ES_TPS_Initialized` or `laserStatus` other than `ES_LPS_LaserReady` ->
//!   `NotReady`), then `GetMeasurementStatusInfo` (bit `ES_MSI_ReflectorFound`
//!   -> `TargetLocked`, else `BeamBroken`).
//! - `reacquire`: `GoLastMeasuredPoint`; if it is refused or no reflector is
//!   locked afterwards, `FindReflector` with the distance of the last measured
//!   point (or [`EmsconConfig::approx_distance_mm`]).
//! - Answers are matched by their `command`: an answer or `ErrorResponseT` to
//!   another command, or a measurement result while none is awaited, is stale
//!   and dropped. Status-change packets are applied whenever they come (while
//!   waiting, or found before the next request): `ES_SSC_MeasStatus_NotReady`
//!   sets [`EmsconTracker::state`] to `BeamBroken`, `ES_SSC_MeasStatus_Ready`
//!   to `TargetLocked`, `ES_SSC_ServerClosing`/`TPConnectionClosing` to
//!   `NotReady`; the last one is kept ([`EmsconTracker::last_status_change`]).
//!   Packets of the data types not used here (reflector position, nivel...)
//!   are skipped.
//!
//! ## Errors
//!
//! - A status other than `ES_RS_AllOK` (in a `...RT`, an `ErrorResponseT` or
//!   a `SingleMeasResultT`) -> [`ErrorKind::Device`](crate::ErrorKind::Device)
//!   with the `ES_ResultStatus` value as the code and its header name in the
//!   text (`ES_RS_SensorNotWarmedUp (10012) in answer to ES_C_StartMeasurement`).
//!   A status the V3.6 header does not define (`ES_ResultStatus 23040`) is no
//!   answer of the tracker but a changed byte of the field (the packets carry
//!   no checksum) -> `Garbled` ([`codes::status::is_defined`]). A newer
//!   server's own statuses beyond the V3.6 header would read the same way: a
//!   link fault, retried under the same bound, its value named in the text.
//! - No answer within the request's deadline ([`EmsconTimeouts`]; a
//!   measurement gets `lMeasTime` + a margin) -> `Timeout`; the next request
//!   first reads for [`EmsconTimeouts::resync_grace_ms`] and drops a late answer.
//! - A size field below 12 or above [`frame::MAX_PACKET_LEN`] -> `Garbled`;
//!   the framing is lost, so the next request first throws away whatever
//!   arrives within the resync grace. An unknown `ES_DataType` or
//!   `ES_Command`, or a packet whose size does not fit its type -> `Garbled`
//!   (the packet is consumed whole; the framing holds).
//! - End of stream or an I/O error (also in the middle of a packet) ->
//!   `Disconnected`; every later call fails at once: build a new driver.
//!
//! # What was looked up and what was chosen
//!
//! Looked up (the public emScon SDK headers, copyright Leica Geosystems,
//! "EmScon TPI/SDK Version V3.6", found by code search):
//!
//! - `ES_C_API_Def.h` and `Enum.h` in `github.com/beckjac/emscon_ros`
//!   (`include/emscon_ros/`, the all-trackers edition; its author notes that
//!   the header assumes a 4-byte `long` and pins it to `int32_t`) and the
//!   AT4xx edition in `github.com/MuffinSpawn/Leica` (`Include/`): every struct
//!   named above, `#pragma pack (push, 4)`, `ES_BOOL` = `int`, and the values
//!   of `ES_DataType`, `ES_Command`, `ES_ResultStatus` (including the V3.x
//!   ones at `ES_API_ERROR_OFFSET` = 10000 + n), `ES_SystemStatusChange`,
//!   `ES_MeasurementStatusInfo`, `ES_TrackerProcessorStatus`,
//!   `ES_LaserProcessorStatus` and the unit enums (see [`codes`]). The managed
//!   C++ edition (`ES_MCPP_API_Def.h`) declares the same structs with
//!   `StructLayout(Pack=4)`.
//! - `MuffinSpawn/Leica`, `Include/ES_CPP_API_Def.h`, `ProcessData()`:
//!   `lPacketSize` is the size of the whole packet; an `ES_DT_Command` answer
//!   with a status other than `ES_RS_AllOK` is handled as a bare
//!   `BasicCommandRT`; the `StartMeasurement` answer is "called only in
//!   continuous mode" (in stationary mode the `SingleMeasResultT` is the
//!   answer). That sample client ignores packets of unknown type; this driver
//!   reports them as garbled instead (a type outside `ES_DataType` on a
//!   length-framed stream means the bytes are not what they claim).
//! - `MuffinSpawn/Leica`, `CESAPI/connection.py` and the generated
//!   `CommandSync`: port 700, one connection at a time, the reader loop
//!   framing by `lPacketSize`, and a client that skips status changes and
//!   reflector positions while it waits for the answer to its command.
//!
//! Chosen (not documented by what was found): which result status means a
//! broken beam (the header has no "beam broken" value: the simulator uses
//! `ES_RS_NoStationaryResult` when the beam breaks during the measurement and
//! `ES_RS_MeasurementStatusNotReady` when no reflector is locked at the start),
//! reading `ES_MSI_ReflectorFound` as "a reflector is locked on", the packet
//! size limit, the deadlines and the resynchronisation after a timeout or an
//! absurd size.

pub mod codes;
mod driver;
pub mod frame;
pub mod packets;
pub mod stream;

#[cfg(test)]
mod tests;

pub use driver::{DEFAULT_PORT, EmsconConfig, EmsconConnector, EmsconTimeouts, EmsconTracker};
pub use frame::DecodeError;
pub use packets::{
    Answer, AnswerBody, Framer, MeasurementStatusInfo, Reply, ReplyDecoder, Request, RequestDecoder, SingleMeasResult,
    SingleMeasResult2, StationaryModeData, SystemStatus, SystemUnits,
};
