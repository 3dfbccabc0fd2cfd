//! The driver's continuous measurement (emScon's continuous time mode).
//!
//! - `start_stream(period)`: `SetMeasurementMode` (`ES_MM_ContinuousTime`),
//!   `SetContinuousTimeModeParams` (`lTimeSeparation` = the period in ms,
//!   `lNumberOfPoints` 0: until stopped, no region), `StartMeasurement`,
//!   answered by its acknowledgement; the tracker then sends
//!   `MultiMeasResultT` packets whenever it has points, and the driver keeps
//!   every point that arrives, also while it waits for another answer.
//! - `read_stream()`: `GetMeasurementStatusInfo`; the points that came
//!   before its answer are returned (a simulator that sends its points
//!   when asked sends them first; a tracker that pushes them as measured has
//!   sent them anyway). A reflector no longer found is a device fault
//!   (`ES_RS_MeasurementStatusNotReady`): the beam broke during the scan. A
//!   point whose `ES_MeasurementStatus` is not `ES_MS_AllOK` is returned
//!   with its status (the engine leaves it out).
//! - `stop_stream()`: `StopMeasurement`, then `SetMeasurementMode`
//!   (`ES_MM_Stationary`) so stationary measurements work again; points that
//!   come after are dropped.
//!
//! Not in the public record, our own choice: querying the status during a
//! continuous measurement.

use super::EmsconTracker;
use crate::emscon::codes::{meas_mode, measurement_status_info as msi, region_type, status};
use crate::emscon::packets::Request;
use crate::emscon::stream::{ContinuousTimeModeData, MultiMeasResult};
use crate::error::{DriverError, Result};
use crate::traits::StreamedPoint;
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncWrite};

/// The most points kept between two reads (about 100 s at 1 kHz).
const MAX_BUFFERED: usize = 100_000;

impl<T> EmsconTracker<T>
where
    T: AsyncRead + AsyncWrite + Unpin + Send,
{
    /// Keep the points of a `MultiMeasResultT` while streaming.
    pub(super) fn take_points(&mut self, m: MultiMeasResult) {
        match &mut self.streamed {
            Some(buf) if buf.len() + m.points.len() <= MAX_BUFFERED => buf.extend(m.points),
            Some(_) => tracing::warn!(instrument = %self.name, "stream buffer full: points dropped"),
            None => tracing::debug!(instrument = %self.name, n = m.points.len(), "points after the stream stopped"),
        }
    }

    /// Start the continuous time mode, one point every `period`.
    pub async fn start_continuous(&mut self, period: Duration) -> Result<()> {
        let ms = i32::try_from(period.as_millis()).ok().filter(|m| *m >= 1).ok_or_else(|| {
            DriverError::usage(&self.name, format!("a time separation of {period:?} is not 1 ms to 2^31 ms"))
        })?;
        self.command(Request::SetMeasurementMode(meas_mode::CONTINUOUS_TIME)).await?;
        let params = ContinuousTimeModeData {
            time_separation_ms: ms,
            number_of_points: 0,
            use_region: false,
            region_type: region_type::SPHERE,
        };
        self.command(Request::SetContinuousTimeModeParams(params)).await?;
        self.streamed = Some(Vec::new());
        if let Err(e) = self.command(Request::StartMeasurement).await {
            self.streamed = None;
            if let Err(back) = self.command(Request::SetMeasurementMode(meas_mode::STATIONARY)).await {
                tracing::warn!(instrument = %self.name, error = %back, "could not set stationary mode again");
            }
            return Err(e);
        }
        tracing::debug!(instrument = %self.name, separation_ms = ms, "continuous time mode started");
        Ok(())
    }

    /// The points received since the last read (see the module documentation).
    pub async fn read_continuous(&mut self) -> Result<Vec<StreamedPoint>> {
        if self.streamed.is_none() {
            return Err(DriverError::usage(&self.name, "not measuring continuously (start the stream first)"));
        }
        let info = self.measurement_status_info().await?;
        let points = self.streamed.as_mut().map(std::mem::take).unwrap_or_default();
        if info.info & msi::REFLECTOR_FOUND == 0 {
            let code = status::MEASUREMENT_STATUS_NOT_READY;
            return Err(DriverError::device(
                &self.name,
                i64::from(code),
                format!(
                    "{} ({code}): the reflector was lost during the continuous measurement",
                    status::describe(code)
                ),
            ));
        }
        Ok(points
            .into_iter()
            .map(|p| StreamedPoint { device_time_s: p.time_s(), xyz_mm: p.val, status: p.status })
            .collect())
    }

    /// Stop the continuous measurement and go back to stationary mode.
    pub async fn stop_continuous(&mut self) -> Result<()> {
        if self.streamed.is_none() {
            return Ok(());
        }
        let stopped = self.command(Request::StopMeasurement).await;
        self.streamed = None;
        stopped?;
        self.command(Request::SetMeasurementMode(meas_mode::STATIONARY)).await?;
        Ok(())
    }
}
