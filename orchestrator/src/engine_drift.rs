//! The engine's side of drift control ([`crate::drift`]): before step 0 of
//! a pass (or the step a resume starts at) and every K-th step, the axis goes
//! to the reference target (approached forward) and the pair is read there;
//! the run loop writes the measurement to the sink outside the race with a
//! stop request (a stop never cancels a write). Moves and reads race a stop
//! like a step's, and their faults are survived the same way.

use super::{Engine, EngineError};
use crate::drift::DriftMeasurement;
use crate::record::SampleSink;
use survey_processing::Direction;

impl Engine {
    /// Measure the reference target before step `seq` when it is due.
    pub(super) async fn drift_reference(
        &mut self,
        seq: u64,
        from_seq: u64,
        overrun: f64,
        sink: &mut dyn SampleSink,
    ) -> Result<Option<DriftMeasurement>, EngineError> {
        let Some(control) = self.drift.clone() else { return Ok(None) };
        if !control.due(seq, from_seq) {
            return Ok(None);
        }
        let target = control.reference_deg;
        let (readout, raw) = self.measure(target, Direction::Forward, overrun, sink).await?;
        let actual = self.actual_deg(target, &raw)?;
        let m = DriftMeasurement {
            before_seq: seq,
            at_s: self.clock.now().as_secs_f64(),
            reference_deg: target,
            readout_deg: readout,
            actual_deg: actual,
        };
        tracing::debug!(seq, error_deg = m.error_deg(), "drift control: reference measured");
        Ok(Some(m))
    }

    /// The reference target, approached forward from below by the overrun,
    /// within the travel `lo..=hi`, or why not.
    pub(super) fn check_drift_travel(&self, lo: f64, hi: f64, overrun: f64) -> Result<(), EngineError> {
        let Some(control) = &self.drift else { return Ok(()) };
        let (from, to) = (control.reference_deg - overrun, control.reference_deg);
        if from < lo || to > hi {
            return Err(EngineError::Plan(format!(
                "the drift reference at {to} deg is approached from {from} deg, outside the travel {lo}..{hi} deg"
            )));
        }
        Ok(())
    }
}
