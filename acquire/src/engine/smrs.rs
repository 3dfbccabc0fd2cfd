//! Several SMRs on the table (issue 48): at every target, once the first
//! SMR's pair is read, the tracker is pointed at each other SMR where the
//! located axis puts it ([`SmrMount::expected_position_mm`]: the first
//! SMR's circle, the other's phase and height), the reflector found there
//! and measured; then it is pointed back at the first, which the next
//! target's move carries along. The axis stands still meanwhile: every
//! SMR's reading is of the same target. Pointing is asked again in place
//! (a refusal too); a measurement lost or refused (the beam not broken) is
//! measured again in place, as a reading's is ([`super::read`]); beyond
//! that a pointing or a reading that fails is a reference fault like any
//! other (retried with recovery, or the survey stops `interrupted`).

use super::read::ReadFault;
use super::{Engine, EngineError, Failed, read_reference};
use crate::record::{RawReading, SampleSink};
use crate::settings::Timing;
use std::time::Duration;
use survey_drivers::SmrMeasurement;
use survey_plan::budget::Component;
use survey_processing::smrs::SmrMount;

impl Engine {
    /// The SMRs on the table, the first one first (it locates the axis and
    /// gives each sample's angle at acquisition), and the least time to
    /// point the tracker at one and find it (the plan's bound counts it at
    /// every target for each other SMR and the way back).
    pub fn with_smrs(mut self, smrs: Vec<SmrMount>, point_bound: Duration) -> Self {
        self.smrs = if smrs.is_empty() { vec![SmrMount::FIRST] } else { smrs };
        self.point_bound = point_bound;
        self
    }

    /// The SMRs on the table.
    pub fn smrs(&self) -> &[SmrMount] {
        &self.smrs
    }

    /// The least time to point at one SMR, for the bound.
    pub fn point_bound(&self) -> Duration {
        self.point_bound
    }

    /// The other SMRs' readings at `target` (none with one SMR), the tracker
    /// back on the first at the end.
    pub(super) async fn read_other_smrs(
        &mut self,
        target: f64,
        sink: &mut dyn SampleSink,
    ) -> Result<Vec<SmrMeasurement>, EngineError> {
        if self.smrs.len() <= 1 {
            return Ok(Vec::new());
        }
        let mut out = Vec::with_capacity(self.smrs.len() - 1);
        for k in 1..self.smrs.len() {
            let m = self.point_and_read(k, target, true, sink).await?;
            out.push(m.expect("a reading was asked for"));
        }
        self.point_and_read(0, target, false, sink).await?;
        Ok(out)
    }

    /// Point at SMR `k` at `target` and, when `read`, measure it; faults
    /// retried as a reference's are.
    async fn point_and_read(
        &mut self,
        k: usize,
        target: f64,
        read: bool,
        sink: &mut dyn SampleSink,
    ) -> Result<Option<SmrMeasurement>, EngineError> {
        let axis = self.axis.clone().ok_or_else(|| EngineError::Plan("the axis has not been located".into()))?;
        let at = self.smrs[k].expected_position_mm(&axis, target);
        let what = format!("SMR {} at {target} deg", k + 1);
        let mut attempt = 0;
        loop {
            let clock = self.clock.clone();
            let t = self.timing.clone();
            self.ledger.switch(clock.now(), Component::Point);
            let super::Reference::Tracker(tracker) = &mut self.reference else {
                return Err(EngineError::Plan("several SMRs need a tracker as the reference".into()));
            };
            let name = tracker.name().to_string();
            // Pointing is a command (pointing again is safe): each fault,
            // the tracker's refusal too, asked again in place as a
            // positioner's request is, under the measurement's deadline.
            let pointing = Timing { call_timeout: t.measure_timeout, ..t.clone() };
            let mut survived = Vec::new();
            let pointed =
                crate::settle::retried!(&*clock, &pointing, &name, "pointing", survived, tracker.point_at(at));
            self.retried_in_place(&survived, &what, sink).await?;
            let result = match pointed {
                Ok(()) if !read => return Ok(None),
                Ok(()) => {
                    self.ledger.switch(clock.now(), Component::Measure);
                    // The measurement asked again in place as a reading's is
                    // (a link fault, a refusal with the beam not broken): the
                    // tracker stays on this SMR, nothing else is read with it.
                    let mut failed = 0u32;
                    loop {
                        match read_reference(&*clock, &t, &mut self.reference, target, 0).await {
                            Ok(RawReading::Smr(m)) => return Ok(Some(m)),
                            Ok(_) => unreachable!("a tracker gives SMR readings"),
                            Err(e)
                                if crate::settle::again(&e, failed, survived.len(), &t)
                                    && self.read_fault(&e, Failed::Reference).await == ReadFault::InPlace =>
                            {
                                failed += 1;
                                tracing::debug!(error = %e, failed, "measuring {what} again in place");
                                self.retried_in_place(std::slice::from_ref(&e), &what, sink).await?;
                                survived.push(e);
                                clock.sleep(t.retry_backoff).await;
                            }
                            Err(e) => break e,
                        }
                    }
                }
                Err(e) => e,
            };
            attempt += 1;
            self.survive(result, Failed::Reference, attempt, &what, sink).await?;
        }
    }
}
