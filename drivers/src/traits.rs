//! One async trait per instrument, with what an unattended survey needs of it.
//!
//! Every method is one bounded request to the instrument: the engine wraps each
//! call in [`crate::clock::with_timeout`], and a driver that talks over a wire
//! also bounds its own reads.

use crate::error::{DriverError, Result};
use async_trait::async_trait;
use serde::{Deserialize, Serialize};
use std::fmt::Debug;
use std::time::Duration;
use survey_processing::table::CorrectionTable;

/// A fault the instrument itself reports, with its own code and text.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct DeviceFault {
    pub code: i64,
    pub text: String,
}

/// Which travel limit is active.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Limit {
    Lower,
    Upper,
}

/// The positioner controller's status word, decoded.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PositionerStatus {
    /// The axis is moving.
    pub moving: bool,
    /// The axis has reached its commanded position and settled in the window.
    pub in_position: bool,
    /// The controller reports a fault.
    pub fault: Option<DeviceFault>,
    /// A travel limit switch is active.
    pub limit: Option<Limit>,
    /// The correction table is loaded and applied in the feedback path.
    pub correction_enabled: bool,
}

/// One readout a controller captured while the axis turned, stamped by the
/// controller's own clock.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CapturedReadout {
    /// The controller's time of the readout, seconds (its own epoch).
    pub device_time_s: f64,
    /// The readout, degrees.
    pub readout_deg: f64,
}

/// One point of a tracker's continuous measurement, stamped by the
/// tracker's own clock.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StreamedPoint {
    /// The tracker's time of the point, seconds (its own epoch).
    pub device_time_s: f64,
    /// The SMR position, mm, tracker frame.
    pub xyz_mm: [f64; 3],
    /// The point's status (emScon's `ES_MeasurementStatus`: 0 all OK).
    pub status: i32,
}

/// A positioner controller: one axis.
#[async_trait]
pub trait Positioner: Send + Debug {
    /// A short name for logs (`"sim-positioner"`, `"modbus-tcp 10.0.0.5:502"`).
    fn name(&self) -> &str;
    /// Start a move to the absolute readout angle `target_deg`; returns when
    /// the controller has accepted the command (not when the move ends).
    async fn move_to(&mut self, target_deg: f64) -> Result<()>;
    /// The readout angle: what the controller displays, degrees.
    async fn readout(&mut self) -> Result<f64>;
    /// Moving, in position, fault, limits.
    async fn status(&mut self) -> Result<PositionerStatus>;
    /// Stop any motion now.
    async fn stop(&mut self) -> Result<()>;
    /// Set the velocity for the following moves, degrees per second.
    async fn set_velocity(&mut self, deg_per_s: f64) -> Result<()>;
    /// Clear a latched fault (after the cause is gone).
    async fn clear_fault(&mut self) -> Result<()>;
    /// Load a correction table into the controller (not yet applied).
    async fn load_correction_table(&mut self, table: &CorrectionTable) -> Result<()>;
    /// Apply (or stop applying) the loaded table in the feedback path.
    async fn enable_correction(&mut self, enabled: bool) -> Result<()>;
    /// Whether the controller applies a correction table now, as the
    /// controller itself reports it; `Ok(None)` when this driver cannot
    /// read it (the state is then unknown: never assumed off). A calibration
    /// reads it before it measures: a corrected axis is not the native one.
    async fn correction_state(&mut self) -> Result<Option<bool>>;
    /// What the instrument says it is, when its protocol lets it say (a
    /// SCPI `*IDN?`, a CiA 301 device name, a Modbus device identification,
    /// an emScon tracker's serial number and version); `Ok(None)` when its
    /// protocol has no such request. Stored with a survey and stated on its
    /// certificate beside what the configuration states.
    async fn identification(&mut self) -> Result<Option<String>> {
        Ok(None)
    }
    /// Whether the controller records its readout at a fixed rate with its
    /// own time stamps (a position capture). Without one, a continuous scan
    /// polls [`Positioner::readout`] at a fixed rate and stamps each reading
    /// with the host's clock.
    fn can_capture(&self) -> bool {
        false
    }
    /// Start recording the readout every `period`.
    async fn start_capture(&mut self, _period: Duration) -> Result<()> {
        Err(DriverError::usage(self.name(), "this controller has no position capture"))
    }
    /// The readouts recorded since the previous read, in time order.
    async fn read_capture(&mut self) -> Result<Vec<CapturedReadout>> {
        Err(DriverError::usage(self.name(), "this controller has no position capture"))
    }
    /// Stop recording.
    async fn stop_capture(&mut self) -> Result<()> {
        Ok(())
    }
}

/// One stationary measurement of the SMR, in the tracker's frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SmrMeasurement {
    pub x_mm: f64,
    pub y_mm: f64,
    pub z_mm: f64,
    /// The instrument's standard deviations of the coordinates, mm.
    pub std_dev_mm: [f64; 3],
    /// How long the stationary measurement took, seconds.
    pub measurement_time_s: f64,
    /// The air the tracker's weather station measured with it (emScon's
    /// `dTemperature`, `dPressure`, `dHumidity`), where it reports them.
    #[serde(default)]
    pub environment: Option<AirEnvironment>,
}

/// The air around a measurement, as a tracker's weather station reports it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AirEnvironment {
    /// Air temperature, degrees Celsius.
    pub temperature_c: f64,
    /// Air pressure, hPa (= mbar).
    pub pressure_hpa: f64,
    /// Relative humidity, percent.
    pub humidity_pct: f64,
}

#[cfg(test)]
mod air_tests {
    use super::AirEnvironment;

    #[test]
    fn a_station_that_reports_nothing_is_no_environment() {
        assert!(AirEnvironment::of_emscon(20.5, 1013.25, 45.0).is_some());
        assert_eq!(AirEnvironment::of_emscon(0.0, 0.0, 0.0), None, "zeros: no weather station");
        assert_eq!(AirEnvironment::of_emscon(f64::NAN, 1013.0, 45.0), None);
        assert_eq!(AirEnvironment::of_emscon(20.0, 1013.0, 130.0), None);
    }
}

impl AirEnvironment {
    /// The environment of an emScon result in the units `survey` sets
    /// (`ES_TU_Celsius`, `ES_PU_Mbar`, `ES_HU_RH`), when each is finite and
    /// plausible for a room (a tracker without a station sends zeros).
    pub fn of_emscon(temperature: f64, pressure: f64, humidity: f64) -> Option<AirEnvironment> {
        let plausible = (-40.0..=80.0).contains(&temperature)
            && (500.0..=1200.0).contains(&pressure)
            && (0.0..=100.0).contains(&humidity)
            && pressure != 0.0;
        plausible.then_some(AirEnvironment {
            temperature_c: temperature,
            pressure_hpa: pressure,
            humidity_pct: humidity,
        })
    }
}

impl SmrMeasurement {
    pub fn xyz(&self) -> [f64; 3] {
        [self.x_mm, self.y_mm, self.z_mm]
    }
}

/// The tracking laser's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum TrackerState {
    /// The beam is on the SMR: measurements can be taken.
    TargetLocked,
    /// The beam lost the SMR: re-acquire before measuring.
    BeamBroken,
    /// Initialising, warming up or otherwise not able to measure.
    NotReady,
}

/// A tracking laser measuring an SMR on an arm fixed to the turntable.
#[async_trait]
pub trait Tracker: Send + Debug {
    fn name(&self) -> &str;
    /// What the instrument says it is, when its protocol lets it say (a
    /// SCPI `*IDN?`, a CiA 301 device name, a Modbus device identification,
    /// an emScon tracker's serial number and version); `Ok(None)` when its
    /// protocol has no such request. Stored with a survey and stated on its
    /// certificate beside what the configuration states.
    async fn identification(&mut self) -> Result<Option<String>> {
        Ok(None)
    }
    /// A stationary measurement (takes the instrument's measurement time).
    async fn measure(&mut self) -> Result<SmrMeasurement>;
    async fn status(&mut self) -> Result<TrackerState>;
    /// Find the reflector again after a beam break.
    async fn reacquire(&mut self) -> Result<()>;
    /// Whether the tracker can be pointed at a position to lock onto another
    /// reflector there ([`Tracker::point_at`]), as a survey of several SMRs needs.
    fn can_point(&self) -> bool {
        false
    }
    /// Turn the beam to `xyz_mm` (the tracker's frame, mm) and lock onto the
    /// reflector there: the next measurements are of it.
    async fn point_at(&mut self, _xyz_mm: [f64; 3]) -> Result<()> {
        Err(DriverError::usage(self.name(), "this tracker cannot be pointed at another reflector"))
    }
    /// Whether the tracker measures continuously (a time-triggered stream
    /// of stamped points), as a continuous scan needs.
    fn can_stream(&self) -> bool {
        false
    }
    /// Start measuring one point every `period` until [`Tracker::stop_stream`].
    async fn start_stream(&mut self, _period: Duration) -> Result<()> {
        Err(DriverError::usage(self.name(), "this tracker does not measure continuously"))
    }
    /// The points measured since the previous read, in time order (may be empty).
    async fn read_stream(&mut self) -> Result<Vec<StreamedPoint>> {
        Err(DriverError::usage(self.name(), "this tracker does not measure continuously"))
    }
    /// Stop measuring continuously (stationary measurements work again).
    async fn stop_stream(&mut self) -> Result<()> {
        Ok(())
    }
}

/// One autocollimator reading, arcseconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AcReading {
    pub x_arcsec: f64,
    pub y_arcsec: f64,
}

/// Whether the autocollimator sees a mirror.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum AcState {
    InRange,
    NoReflection,
}

/// An autocollimator looking at a polygon face (or mirror) on the turntable.
#[async_trait]
pub trait Autocollimator: Send + Debug {
    fn name(&self) -> &str;
    /// What the instrument says it is, when its protocol lets it say (a
    /// SCPI `*IDN?`, a CiA 301 device name, a Modbus device identification,
    /// an emScon tracker's serial number and version); `Ok(None)` when its
    /// protocol has no such request. Stored with a survey and stated on its
    /// certificate beside what the configuration states.
    async fn identification(&mut self) -> Result<Option<String>> {
        Ok(None)
    }
    /// An absolute X/Y reading. Fails with a device error when no mirror is in
    /// range.
    async fn read(&mut self) -> Result<AcReading>;
    async fn status(&mut self) -> Result<AcState>;
}
