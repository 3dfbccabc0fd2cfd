//! What the engine records at each target, and the sink it records into.

use async_trait::async_trait;
use serde::{Deserialize, Serialize};
use survey_drivers::{AcReading, SmrMeasurement};
use survey_processing::geometry::AxisFit;
use survey_processing::{Direction, Sample};

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
/// dense), the paired readout/actual values and the raw reference reading
/// (the first SMR's, with a tracker), and the other SMRs' readings at the
/// same target (a survey of several SMRs; empty otherwise), in the arm's order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordedSample {
    pub seq: u64,
    pub sample: Sample,
    pub raw: RawReading,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub others: Vec<SmrMeasurement>,
}

/// One pass of a continuous scan as it is stored: its samples (a dense run
/// of steps) with the raw streams they were paired from and how.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanPassRecord {
    /// The pass's place in the plan (0-based: run and direction order).
    pub pass: u32,
    pub run: u32,
    pub direction: Direction,
    /// Unsigned velocity of the pass, deg/s.
    pub velocity_deg_s: f64,
    /// The latency removed and its standard error, seconds.
    pub latency_s: f64,
    pub latency_se_s: f64,
    /// The clock maps (`host = offset + rate * stamp`) of the readout
    /// stream (identity when polled) and of the tracker stream.
    pub readout_clock: (f64, f64),
    pub tracker_clock: (f64, f64),
    /// Whether the readouts are the controller's capture (stamped by its
    /// clock) or polled by the engine (stamped by the host).
    pub readout_captured: bool,
    /// Instrument time the pass's move started and ended, seconds.
    pub started_at_s: f64,
    pub ended_at_s: f64,
    /// The samples, seq ascending.
    pub samples: Vec<RecordedSample>,
    /// `[stamp, readout]`.
    pub readouts: Vec<[f64; 2]>,
    /// `[stamp of the newest item, host time of the answer]` per read.
    pub readout_fetches: Vec<[f64; 2]>,
    /// `[stamp, x, y, z, status]`.
    pub points: Vec<[f64; 5]>,
    pub point_fetches: Vec<[f64; 2]>,
}

/// Where the engine puts samples. `record` may buffer; a sample counts as
/// acknowledged (durable) once `flush` has returned after it.
#[async_trait]
pub trait SampleSink: Send {
    async fn record(&mut self, sample: RecordedSample) -> anyhow::Result<()>;
    async fn flush(&mut self) -> anyhow::Result<()>;
    /// A whole pass of a continuous scan, durable when this returns Ok
    /// (all of it or none: a store keeps it in one transaction). By default
    /// its samples are recorded and flushed; the streams are not kept.
    async fn record_pass(&mut self, pass: ScanPassRecord) -> anyhow::Result<()> {
        for sample in pass.samples {
            self.record(sample).await?;
        }
        self.flush().await
    }
    /// The axis was located from these SMR positions (readout, measurement).
    async fn axis_located(&mut self, _points: &[(f64, SmrMeasurement)], _fit: &AxisFit) -> anyhow::Result<()> {
        Ok(())
    }
    /// Something worth keeping in the survey's log (a fault survived, a resume).
    async fn event(&mut self, _at_s: f64, _level: &str, _message: &str) -> anyhow::Result<()> {
        Ok(())
    }
    /// The drift-control reference target was measured ([`survey_plan::drift`]).
    async fn drift_measured(&mut self, _m: &survey_plan::drift::DriftMeasurement) -> anyhow::Result<()> {
        Ok(())
    }
}

/// A sink that keeps samples in memory (tests, dry runs).
#[derive(Debug, Default)]
pub struct MemorySink {
    pub samples: Vec<RecordedSample>,
    /// Continuous scans' passes, without their samples (they are in `samples`).
    pub passes: Vec<ScanPassRecord>,
    pub axis: Option<AxisFit>,
    pub locate_points: Vec<(f64, SmrMeasurement)>,
    /// (instrument time, level, message)
    pub events: Vec<(f64, String, String)>,
    /// The drift-control reference measurements.
    pub drift: Vec<survey_plan::drift::DriftMeasurement>,
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
    async fn record_pass(&mut self, mut pass: ScanPassRecord) -> anyhow::Result<()> {
        self.samples.append(&mut pass.samples);
        self.passes.push(pass);
        Ok(())
    }
    async fn drift_measured(&mut self, m: &survey_plan::drift::DriftMeasurement) -> anyhow::Result<()> {
        self.drift.push(*m);
        Ok(())
    }
}
