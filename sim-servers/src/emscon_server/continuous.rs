//! The simulated server's continuous time mode (`ES_MM_ContinuousTime`).
//!
//! - `SetMeasurementMode(ES_MM_ContinuousTime)` selects it (refused with
//!   `ES_RS_ServerBusy` while a continuous measurement runs);
//!   `SetContinuousTimeModeParams` keeps `lTimeSeparation` (ms, at least 1:
//!   else `ES_RS_Parameter1OutOfRangeNOK`), `lNumberOfPoints` must be 0
//!   (until stopped; else `ES_RS_NotImplemented`) and regions are not
//!   modelled (`bUseRegion` true: `ES_RS_NotImplemented`).
//! - `StartMeasurement` in that mode starts the simulated tracker's stream
//!   ([`Tracker::start_stream`]) and is answered by a bare acknowledgement
//!   (`ES_RS_AllOK`); `StopMeasurement` stops it.
//! - While it runs, the points measured so far are sent as
//!   `MultiMeasResultT` packets (at most [`MAX_POINTS_PER_PACKET`] each,
//!   `lTime1`/`lTime2` from the tracker's clock, coordinates in the length
//!   unit set) before every answer, and, when the server's clock is not
//!   virtual (`survey sim`), also every 10 ms of real time as a tracker
//!   pushes them. On a virtual clock time only moves when the client's
//!   side sleeps, so points go out with answers only.

use super::{Server, ok, per_mm};
use std::time::Duration;
use survey_drivers::emscon::codes::{command as cmd, meas_mode, status};
use survey_drivers::emscon::packets::Reply;
use survey_drivers::emscon::stream::{ContinuousTimeModeData, MAX_POINTS_PER_PACKET, MeasValue, MultiMeasResult};
use survey_drivers::traits::Tracker;

/// How often points are pushed on a real or scaled clock.
const PUSH_EVERY: Duration = Duration::from_millis(10);

/// The continuous mode's state.
#[derive(Debug, Default)]
pub(super) struct Continuous {
    separation_ms: Option<i32>,
    running: bool,
    /// Push points on a timer (the clock is not virtual).
    timer: bool,
}

impl Continuous {
    pub(super) fn running(&self) -> bool {
        self.running
    }

    /// Whether points are pushed on a timer now.
    pub(super) fn pushes(&self) -> bool {
        self.running && self.timer
    }

    /// The push timer.
    pub(super) async fn tick(&self) {
        tokio::time::sleep(PUSH_EVERY).await;
    }
}

impl Server {
    pub(super) fn continuous_params(&mut self, p: ContinuousTimeModeData) -> Reply {
        let c = cmd::SET_CONTINUOUS_TIME_MODE_PARAMS;
        if p.time_separation_ms < 1 {
            return Reply::answer(c, status::PARAMETER1_OUT_OF_RANGE_NOK);
        }
        if p.number_of_points != 0 || p.use_region {
            return Reply::answer(c, status::NOT_IMPLEMENTED);
        }
        self.continuous.separation_ms = Some(p.time_separation_ms);
        ok(c)
    }

    pub(super) async fn start_stream(&mut self) -> Reply {
        let c = cmd::START_MEASUREMENT;
        if self.continuous.running {
            return Reply::answer(c, status::SERVER_BUSY);
        }
        let ms = self.continuous.separation_ms.unwrap_or(1);
        match self.sim.start_stream(Duration::from_millis(u64::try_from(ms).unwrap_or(1))).await {
            Ok(()) => {
                self.continuous.running = true;
                self.continuous.timer = !self.sim.clock_is_virtual();
                ok(c)
            }
            Err(e) => {
                tracing::warn!(error = %e, "emscon simulator: the stream did not start");
                self.locked = false;
                Reply::answer(c, status::MEASUREMENT_STATUS_NOT_READY)
            }
        }
    }

    pub(super) async fn stop_stream(&mut self) -> Reply {
        if self.continuous.running {
            if let Err(e) = self.sim.stop_stream().await {
                tracing::warn!(error = %e, "emscon simulator: stopping the stream failed");
            }
            self.continuous.running = false;
        }
        ok(cmd::STOP_MEASUREMENT)
    }

    /// The points measured since the last packets, as `MultiMeasResultT`
    /// packets (none when not streaming).
    pub(super) async fn stream_packets(&mut self) -> Vec<u8> {
        if !self.continuous.running {
            return Vec::new();
        }
        let points = match self.sim.read_stream().await {
            Ok(p) => p,
            Err(e) => {
                tracing::warn!(error = %e, "emscon simulator: reading the stream failed");
                return Vec::new();
            }
        };
        let k = per_mm(self.units.length);
        let mut bytes = Vec::new();
        for chunk in points.chunks(MAX_POINTS_PER_PACKET) {
            let values = chunk
                .iter()
                .map(|p| {
                    let (time1, time2) = MeasValue::split_time(p.device_time_s);
                    MeasValue { status: p.status, time1, time2, val: p.xyz_mm.map(|v| v * k) }
                })
                .collect();
            let m = MultiMeasResult {
                status: status::ALL_OK,
                meas_mode: meas_mode::CONTINUOUS_TIME,
                is_try_mode: false,
                temperature: super::SIM_TEMPERATURE_C,
                pressure: super::SIM_PRESSURE_MBAR,
                humidity: super::SIM_HUMIDITY_RH,
                points: values,
            };
            bytes.extend(Reply::MultiMeas(m).encode());
        }
        bytes
    }
}
