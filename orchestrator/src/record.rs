//! What the engine records at each target, and the sink it records into.

use async_trait::async_trait;
use serde::{Deserialize, Serialize};
use survey_drivers::{AcReading, SmrMeasurement};
use survey_processing::Sample;
use survey_processing::geometry::AxisFit;

/// The reference instrument's raw values behind one sample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum RawReading {
    /// Imported data carries no raw values.
    None,
    /// A tracking-laser stationary measurement of the SMR.
    Smr(SmrMeasurement),
    /// An autocollimator reading of polygon face `face` (0-based).
    Autocollimator { face: u32, reading: AcReading },
}

/// One acquired sample: its place in the survey plan (`seq`, 0-based and
/// dense), the paired readout/actual values and the raw reference reading.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RecordedSample {
    pub seq: u64,
    pub sample: Sample,
    pub raw: RawReading,
}

/// Where the engine puts samples. `record` may buffer; a sample counts as
/// acknowledged (durable) once `flush` has returned after it.
#[async_trait]
pub trait SampleSink: Send {
    async fn record(&mut self, sample: RecordedSample) -> anyhow::Result<()>;
    async fn flush(&mut self) -> anyhow::Result<()>;
    /// The axis was located from these SMR positions (readout, measurement).
    async fn axis_located(&mut self, _points: &[(f64, SmrMeasurement)], _fit: &AxisFit) -> anyhow::Result<()> {
        Ok(())
    }
    /// Something worth keeping in the survey's log (a fault survived, a resume).
    async fn event(&mut self, _at_s: f64, _level: &str, _message: &str) -> anyhow::Result<()> {
        Ok(())
    }
    /// The drift-control reference target was measured ([`crate::drift`]).
    async fn drift_measured(&mut self, _m: &crate::drift::DriftMeasurement) -> anyhow::Result<()> {
        Ok(())
    }
}

/// A sink that keeps samples in memory (tests, dry runs).
#[derive(Debug, Default)]
pub struct MemorySink {
    pub samples: Vec<RecordedSample>,
    pub axis: Option<AxisFit>,
    pub locate_points: Vec<(f64, SmrMeasurement)>,
    /// (instrument time, level, message)
    pub events: Vec<(f64, String, String)>,
    /// The drift-control reference measurements.
    pub drift: Vec<crate::drift::DriftMeasurement>,
}

#[async_trait]
impl SampleSink for MemorySink {
    async fn record(&mut self, sample: RecordedSample) -> anyhow::Result<()> {
        self.samples.push(sample);
        Ok(())
    }
    async fn flush(&mut self) -> anyhow::Result<()> {
        Ok(())
    }
    async fn axis_located(&mut self, points: &[(f64, SmrMeasurement)], fit: &AxisFit) -> anyhow::Result<()> {
        self.locate_points = points.to_vec();
        self.axis = Some(fit.clone());
        Ok(())
    }
    async fn event(&mut self, at_s: f64, level: &str, message: &str) -> anyhow::Result<()> {
        self.events.push((at_s, level.to_string(), message.to_string()));
        Ok(())
    }
    async fn drift_measured(&mut self, m: &crate::drift::DriftMeasurement) -> anyhow::Result<()> {
        self.drift.push(*m);
        Ok(())
    }
}
