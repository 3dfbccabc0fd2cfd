//! The simulated controller's position capture: while it runs, the
//! controller records its displayed readout every `period` of clock time,
//! stamped by its own clock ([`CaptureSim::clock`](super::CaptureSim)), like
//! a drive's trace recorder or position-capture buffer; a read returns what
//! was recorded since the previous read. With `drop_probability` a recorded
//! readout is lost (decided per readout from the seed, so a run is
//! reproducible). Readouts are recorded up to the moment of each read and
//! before every new move, so each is taken on the path the axis followed.

use super::SimPositioner;
use crate::derive_seed;
use std::time::Duration;
use survey_drivers::error::{DriverError, Result};
use survey_drivers::traits::CapturedReadout;

/// Salt of the seed that decides which captured readouts are lost.
const DROP_SALT: u64 = 0x6361_7074;

/// The most readouts the controller buffers between two reads.
pub const CAPTURE_BUFFER: usize = 1_000_000;

/// A running capture.
#[derive(Debug)]
pub(super) struct Capture {
    period: Duration,
    start: Duration,
    /// Index of the next readout to record.
    next: u64,
    recorded: Vec<CapturedReadout>,
}

impl SimPositioner {
    /// Start recording every `period` from now.
    pub(super) fn begin_capture(&mut self, period: Duration) -> Result<()> {
        if period.is_zero() {
            return Err(DriverError::usage("positioner", "a capture period must be positive"));
        }
        let start = self.clock.now();
        self.capture = Some(Capture { period, start, next: 0, recorded: Vec::new() });
        Ok(())
    }

    /// Record the readouts due up to `now` (on the current path).
    pub(super) fn capture_until(&mut self, now: Duration) {
        let Some(mut c) = self.capture.take() else { return };
        let drop_seed = derive_seed(self.cfg.seed ^ DROP_SALT, c.start.as_nanos() as u64);
        loop {
            let t = c.start + Duration::from_nanos((c.period.as_nanos() as u64).saturating_mul(c.next));
            if t > now || c.recorded.len() >= CAPTURE_BUFFER {
                break;
            }
            let k = c.next;
            c.next += 1;
            let p = self.cfg.capture.drop_probability;
            if p > 0.0 && (derive_seed(drop_seed, k) >> 11) as f64 / (1u64 << 53) as f64 <= p {
                continue;
            }
            c.recorded
                .push(CapturedReadout { device_time_s: self.cfg.capture.clock.at(t), readout_deg: self.display_at(t) });
        }
        self.capture = Some(c);
    }

    /// What was recorded since the last read.
    pub(super) fn take_capture(&mut self) -> Result<Vec<CapturedReadout>> {
        let now = self.clock.now();
        self.capture_until(now);
        match &mut self.capture {
            Some(c) => Ok(std::mem::take(&mut c.recorded)),
            None => Err(DriverError::usage("positioner", "no capture is running (start_capture first)")),
        }
    }
}
