//! The simulated tracker's continuous measurement (emScon's continuous time
//! mode): one point every `period` while it runs.
//!
//! Point `k` integrates the SMR over `[start + k P, start + (k + 1) P]` and is
//! taken at the true angle of the middle of that interval (the mean for an
//! axis turning steadily); it carries the tracker's own error, the same
//! systematic part and random part as a stationary measurement (our own model
//! choice: on a real tracker a 1 s stationary point is quieter than one
//! streamed point). It is stamped by
//! the tracker's clock ([`StreamSim::clock`]) at the end of its interval plus
//! [`StreamSim::stamp_latency`], and it is delivered once that stamp is
//! due: the engine sees the point's time lag the motion by half the
//! integration and the latency, on a clock that is not its own. With
//! [`StreamSim::drop_probability`] a point is lost (decided per point from
//! the seed). Points are produced when they are read, on the turntable's
//! path at that moment.

use super::SimTracker;
use crate::derive_seed;
use crate::servo::DeviceClock;
use rand_distr::{Distribution, StandardNormal};
use std::time::Duration;
use survey_drivers::error::{DriverError, Result};
use survey_drivers::traits::StreamedPoint;

/// Salt of the seed that decides which points are lost.
const DROP_SALT: u64 = 0x6472_6f70;

/// The most points buffered between two reads.
pub const STREAM_BUFFER: usize = 100_000;

/// The clock, latency and losses of the continuous measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StreamSim {
    /// The tracker's clock (default: 5000 s ahead, 20 ppm slow).
    pub clock: DeviceClock,
    /// Between the end of a point's integration and its time stamp (default 3 ms).
    pub stamp_latency: Duration,
    /// Probability that a point is lost (default 0).
    pub drop_probability: f64,
}

impl Default for StreamSim {
    fn default() -> Self {
        Self {
            clock: DeviceClock { offset_s: 5000.0, rate_ppm: -20.0 },
            stamp_latency: Duration::from_millis(3),
            drop_probability: 0.0,
        }
    }
}

/// A running continuous measurement.
#[derive(Debug)]
pub struct Streaming {
    period: Duration,
    start: Duration,
    next: u64,
}

impl SimTracker {
    /// Start measuring every `period` from now.
    pub(super) fn begin_stream(&mut self, period: Duration) -> Result<()> {
        if period.is_zero() {
            return Err(DriverError::usage(super::INSTRUMENT, "a stream period must be positive"));
        }
        self.streaming = Some(Streaming { period, start: self.clock.now(), next: 0 });
        Ok(())
    }

    /// The points whose stamps are due, since the previous read.
    pub(super) fn take_stream(&mut self) -> Result<Vec<StreamedPoint>> {
        let now = self.clock.now();
        let Some(s) = self.streaming.as_mut() else {
            return Err(DriverError::usage(super::INSTRUMENT, "not measuring continuously (start the stream first)"));
        };
        let (period, start) = (s.period, s.start);
        let cfg = self.cfg.stream;
        let drop_seed = derive_seed(self.cfg.seed ^ DROP_SALT, start.as_nanos() as u64);
        let mut out = Vec::new();
        loop {
            let k = self.streaming.as_ref().map_or(0, |s| s.next);
            let begin = start + Duration::from_nanos((period.as_nanos() as u64).saturating_mul(k));
            let end = begin + period;
            let stamped = end + cfg.stamp_latency;
            if stamped > now || out.len() >= STREAM_BUFFER {
                break;
            }
            if let Some(s) = self.streaming.as_mut() {
                s.next += 1;
            }
            let p = cfg.drop_probability;
            if p > 0.0 && (derive_seed(drop_seed, k) >> 11) as f64 / (1u64 << 53) as f64 <= p {
                continue;
            }
            let theta = self.turntable.actual_deg(begin + period / 2);
            let z: [f64; 3] = std::array::from_fn(|_| StandardNormal.sample(&mut self.noise_rng));
            let xyz = self.read_at(theta, z);
            out.push(StreamedPoint { device_time_s: cfg.clock.at(stamped), xyz_mm: xyz, status: 0 });
        }
        Ok(out)
    }
}
