//! The packets of emScon's continuous time mode (sans-IO), from
//! `ES_C_API_Def.h` (V3.6, `beckjac/emscon_ros` and `MuffinSpawn/Leica`),
//! with the header's `#pragma pack (push, 4)`:
//!
//! | struct | layout | bytes |
//! |---|---|---|
//! | `SetContinuousTimeModeParamsCT` | `BasicCommandCT` + `ContinuousTimeModeDataT { long lTimeSeparation; long lNumberOfPoints; ES_BOOL bUseRegion; enum ES_RegionType regionType; }` | 28 |
//! | `StopMeasurementCT` | `BasicCommandCT` | 12 |
//! | `MultiMeasResultT` (type `ES_DT_MultiMeasResult`, 3) | `ReturnDataT` (12), `long lNumberOfResults`, `enum ES_MeasMode measMode`, `ES_BOOL bIsTryMode`, `double dTemperature, dPressure, dHumidity` (at 24), then `lNumberOfResults` x `MeasValueT { enum ES_MeasurementStatus status; long lTime1; long lTime2; double dVal1, dVal2, dVal3; }` (36 bytes each, from 48) | 48 + 36 n |
//!
//! The header declares `data[1]` ("first element (exact number of elements
//! is in lNumberOfResults)"), so the packet's size is `48 + 36 n`.
//! `lNumberOfPoints` 0 means "continuously". What the header does not say
//! and is our reading: `lTimeSeparation` in milliseconds, and `lTime1` /
//! `lTime2` as seconds and microseconds of the tracker's clock, as the public
//! ROS client `beckjac/emscon_ros` reads them (`ros::Duration(lTime1,
//! 1000 * lTime2)`).

use super::frame::{DecodeError, MAX_PACKET_LEN, PACKET_HEADER_LEN, RETURN_DATA_LEN};

/// `sizeof(SetContinuousTimeModeParamsCT)`.
pub const SET_CONTINUOUS_TIME_MODE_PARAMS_CT_LEN: usize = 12 + 16;
/// `offsetof(MultiMeasResultT, data)`.
pub const MULTI_MEAS_HEADER_LEN: usize = RETURN_DATA_LEN + 12 + 24;
/// `sizeof(MeasValueT)`.
pub const MEAS_VALUE_LEN: usize = 4 + 4 + 4 + 24;
/// The most points a `MultiMeasResultT` of at most
/// [`MAX_PACKET_LEN`] bytes holds.
pub const MAX_POINTS_PER_PACKET: usize = (MAX_PACKET_LEN - MULTI_MEAS_HEADER_LEN) / MEAS_VALUE_LEN;

/// `struct ContinuousTimeModeDataT`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ContinuousTimeModeData {
    /// `long lTimeSeparation`: between two points, ms (our reading).
    pub time_separation_ms: i32,
    /// `long lNumberOfPoints`: 0 = continuously.
    pub number_of_points: i32,
    /// `ES_BOOL bUseRegion`.
    pub use_region: bool,
    /// `enum ES_RegionType regionType`.
    pub region_type: i32,
}

/// `struct MeasValueT`: one point of the stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasValue {
    /// `enum ES_MeasurementStatus status`.
    pub status: i32,
    /// `long lTime1`: seconds of the tracker's clock.
    pub time1: i32,
    /// `long lTime2`: microseconds within that second.
    pub time2: i32,
    /// `dVal1..3`: the position.
    pub val: [f64; 3],
}

impl MeasValue {
    /// The point's time, seconds of the tracker's clock.
    pub fn time_s(&self) -> f64 {
        f64::from(self.time1) + f64::from(self.time2) * 1e-6
    }

    /// `lTime1` and `lTime2` of a time in seconds (non-negative, below 2^31 s).
    pub fn split_time(t: f64) -> (i32, i32) {
        let mut secs = t.floor();
        let mut micros = ((t - secs) * 1e6).round();
        if micros >= 1e6 {
            secs += 1.0;
            micros -= 1e6;
        }
        (secs as i32, micros as i32)
    }
}

/// `struct MultiMeasResultT` with its points.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiMeasResult {
    /// `packetInfo.status`.
    pub status: i32,
    /// `enum ES_MeasMode measMode`.
    pub meas_mode: i32,
    /// `ES_BOOL bIsTryMode`.
    pub is_try_mode: bool,
    pub temperature: f64,
    pub pressure: f64,
    pub humidity: f64,
    /// The `lNumberOfResults` points.
    pub points: Vec<MeasValue>,
}

/// The body of `SetContinuousTimeModeParamsCT` after its `BasicCommandCT`.
pub(super) fn encode_params(p: &ContinuousTimeModeData, out: &mut Vec<u8>) {
    for v in [p.time_separation_ms, p.number_of_points, i32::from(p.use_region), p.region_type] {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

fn i32_at(b: &[u8], at: usize) -> i32 {
    i32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"))
}

fn f64_at(b: &[u8], at: usize) -> f64 {
    f64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"))
}

/// Decode the parameters from a whole `SetContinuousTimeModeParamsCT` frame.
pub(super) fn decode_params(frame: &[u8]) -> Result<ContinuousTimeModeData, DecodeError> {
    if frame.len() != SET_CONTINUOUS_TIME_MODE_PARAMS_CT_LEN {
        return Err(DecodeError::WrongLength {
            what: "SetContinuousTimeModeParamsCT",
            len: frame.len(),
            expected: SET_CONTINUOUS_TIME_MODE_PARAMS_CT_LEN,
        });
    }
    Ok(ContinuousTimeModeData {
        time_separation_ms: i32_at(frame, 12),
        number_of_points: i32_at(frame, 16),
        use_region: i32_at(frame, 20) != 0,
        region_type: i32_at(frame, 24),
    })
}

/// The bytes of a `MultiMeasResultT` after its packet header.
pub(super) fn encode_multi(m: &MultiMeasResult, out: &mut Vec<u8>) {
    let n = i32::try_from(m.points.len()).expect("a packet holds at most MAX_POINTS_PER_PACKET points");
    for v in [m.status, n, m.meas_mode, i32::from(m.is_try_mode)] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in [m.temperature, m.pressure, m.humidity] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for p in &m.points {
        for v in [p.status, p.time1, p.time2] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for v in p.val {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
}

/// Decode a whole `MultiMeasResultT` frame: its size must be `48 + 36 n`
/// for its `lNumberOfResults` n (at least 0).
pub(super) fn decode_multi(frame: &[u8]) -> Result<MultiMeasResult, DecodeError> {
    let len = frame.len();
    if len < MULTI_MEAS_HEADER_LEN {
        return Err(DecodeError::WrongLength { what: "MultiMeasResultT", len, expected: MULTI_MEAS_HEADER_LEN });
    }
    let n = i32_at(frame, RETURN_DATA_LEN);
    let expected = usize::try_from(n).ok().map(|n| MULTI_MEAS_HEADER_LEN + n * MEAS_VALUE_LEN);
    if expected != Some(len) {
        return Err(DecodeError::WrongLength {
            what: "MultiMeasResultT",
            len,
            expected: expected.unwrap_or(MULTI_MEAS_HEADER_LEN),
        });
    }
    let points = (0..n as usize)
        .map(|k| {
            let at = MULTI_MEAS_HEADER_LEN + k * MEAS_VALUE_LEN;
            MeasValue {
                status: i32_at(frame, at),
                time1: i32_at(frame, at + 4),
                time2: i32_at(frame, at + 8),
                val: [f64_at(frame, at + 12), f64_at(frame, at + 20), f64_at(frame, at + 28)],
            }
        })
        .collect();
    Ok(MultiMeasResult {
        status: i32_at(frame, PACKET_HEADER_LEN),
        meas_mode: i32_at(frame, RETURN_DATA_LEN + 4),
        is_try_mode: i32_at(frame, RETURN_DATA_LEN + 8) != 0,
        temperature: f64_at(frame, 24),
        pressure: f64_at(frame, 32),
        humidity: f64_at(frame, 40),
        points,
    })
}
