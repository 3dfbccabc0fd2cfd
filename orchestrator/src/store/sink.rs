//! [`StoreSink`]: the [`SampleSink`] that writes to the store in batches.

use std::time::{Duration, Instant};

use async_trait::async_trait;
use survey_drivers::SmrMeasurement;
use survey_processing::geometry::AxisFit;

use super::{Store, is_busy};
use crate::acquire::{RecordedSample, SampleSink, ScanPassRecord};

/// A [`SampleSink`] that writes to the store in batches.
///
/// `record` buffers the sample and writes the buffer (one [`Store::append`]
/// transaction) when
/// - it holds `batch` samples (default 256), or
/// - its oldest sample has waited `max_age` (default 1 s), or
/// - the previous sample was recorded `max_age` or more ago: samples come
///   slowly, so waiting for the next one would hold this one too long.
///
/// `max_age` is measured in real time ([`Instant`]), because durability is
/// about the real disk. A sample is acknowledged (durable) when a flush that
/// holds it returns `Ok`: on `flush()` or on the automatic flushes above. With
/// real instruments a sample takes seconds, so each one (from the second on)
/// is on disk as soon as it is recorded; a fast simulation writes in batches.
/// The sink has no timer of its own: the engine calls `flush()` before anything
/// that may wait (a fault recovery, a pause) and at the end.
///
/// When a write fails, the samples stay in the buffer (the transaction rolled
/// back, nothing of them is stored) and the next flush tries again.
///
/// Another writer holding the database (an import, another survey's
/// acquisition) never stops this one: a write that finds the database locked
/// beyond the busy timeout is retried, each wait logged, for up to
/// `busy_wait` (default 10 minutes) before it is an error. Readers never
/// block a write (WAL).
#[derive(Debug)]
pub struct StoreSink {
    store: Store,
    survey_id: i64,
    batch: usize,
    max_age: Duration,
    buffer: Vec<RecordedSample>,
    oldest: Option<Instant>,
    last_record: Option<Instant>,
    acknowledged: Option<u64>,
    busy_wait: Duration,
}

impl StoreSink {
    /// Default number of samples per write.
    pub const DEFAULT_BATCH: usize = 256;
    /// Default longest wait for another writer's lock.
    pub const DEFAULT_BUSY_WAIT: Duration = Duration::from_secs(600);
    /// Default longest time a sample waits in the buffer.
    pub const DEFAULT_MAX_AGE: Duration = Duration::from_secs(1);

    /// A sink writing the samples of survey `survey_id` into `store`.
    pub fn new(store: Store, survey_id: i64) -> Self {
        StoreSink {
            store,
            survey_id,
            batch: Self::DEFAULT_BATCH,
            max_age: Self::DEFAULT_MAX_AGE,
            buffer: Vec::new(),
            oldest: None,
            last_record: None,
            acknowledged: None,
            busy_wait: Self::DEFAULT_BUSY_WAIT,
        }
    }

    /// Write every `batch` samples (at least 1).
    pub fn with_batch(mut self, batch: usize) -> Self {
        self.batch = batch.max(1);
        self
    }

    /// Write when the oldest buffered sample has waited `max_age`.
    pub fn with_max_age(mut self, max_age: Duration) -> Self {
        self.max_age = max_age;
        self
    }

    /// Wait up to `busy_wait` for another writer's lock before a write fails.
    pub fn with_busy_wait(mut self, busy_wait: Duration) -> Self {
        self.busy_wait = busy_wait;
        self
    }

    /// The survey the samples go to.
    pub fn survey_id(&self) -> i64 {
        self.survey_id
    }

    /// The store.
    pub fn store(&self) -> &Store {
        &self.store
    }

    /// Samples recorded but not yet acknowledged.
    pub fn pending(&self) -> usize {
        self.buffer.len()
    }

    /// The highest seq this sink has acknowledged (written durably), if any.
    pub fn last_acknowledged(&self) -> Option<u64> {
        self.acknowledged
    }

    async fn write(&mut self) -> anyhow::Result<()> {
        if self.buffer.is_empty() {
            return Ok(());
        }
        let started = Instant::now();
        let mut attempt = 0u32;
        loop {
            match self.store.append(self.survey_id, &self.buffer).await {
                Ok(()) => break,
                Err(e) if is_busy(&e) && started.elapsed() < self.busy_wait => {
                    attempt += 1;
                    tracing::warn!(
                        survey = self.survey_id,
                        attempt,
                        waited_s = started.elapsed().as_secs_f64(),
                        pending = self.buffer.len(),
                        "the database is locked by another writer: the samples wait in memory, retrying"
                    );
                    tokio::time::sleep(Duration::from_millis(200)).await;
                }
                Err(e) => return Err(e),
            }
        }
        let top = self.buffer.iter().map(|r| r.seq).max();
        self.acknowledged = self.acknowledged.max(top);
        self.buffer.clear();
        self.oldest = None;
        Ok(())
    }
}

#[async_trait]
impl SampleSink for StoreSink {
    async fn record(&mut self, sample: RecordedSample) -> anyhow::Result<()> {
        let now = Instant::now();
        let slow = self.last_record.is_some_and(|t| now.duration_since(t) >= self.max_age);
        self.last_record = Some(now);
        self.buffer.push(sample);
        let oldest = *self.oldest.get_or_insert(now);
        if slow || self.buffer.len() >= self.batch || now.duration_since(oldest) >= self.max_age {
            self.write().await?;
        }
        Ok(())
    }

    async fn flush(&mut self) -> anyhow::Result<()> {
        self.write().await
    }

    /// Stores the positions after those already stored (a resume that locates
    /// the axis again adds its own) and replaces the survey's axis (JSON of
    /// the [`AxisFit`]).
    async fn axis_located(&mut self, points: &[(f64, SmrMeasurement)], fit: &AxisFit) -> anyhow::Result<()> {
        self.store.add_locate_points(self.survey_id, points).await?;
        self.store.set_axis(self.survey_id, fit).await
    }

    /// The buffer is written first; then the pass, its samples and its
    /// streams in one transaction (retried while another writer holds the
    /// database, like every write).
    async fn record_pass(&mut self, pass: ScanPassRecord) -> anyhow::Result<()> {
        self.write().await?;
        let started = Instant::now();
        loop {
            match self.store.append_pass(self.survey_id, &pass).await {
                Ok(()) => break,
                Err(e) if is_busy(&e) && started.elapsed() < self.busy_wait => {
                    tracing::warn!(
                        survey = self.survey_id,
                        pass = pass.pass,
                        "the database is locked: retrying the pass"
                    );
                    tokio::time::sleep(Duration::from_millis(200)).await;
                }
                Err(e) => return Err(e),
            }
        }
        let top = pass.samples.iter().map(|r| r.seq).max();
        self.acknowledged = self.acknowledged.max(top);
        Ok(())
    }

    /// Logged at once (not buffered).
    async fn event(&mut self, at_s: f64, level: &str, message: &str) -> anyhow::Result<()> {
        self.store.log_event(self.survey_id, at_s, level, message).await
    }
    async fn drift_measured(&mut self, m: &survey_processing::drift::DriftMeasurement) -> anyhow::Result<()> {
        self.store.add_drift_measurement(self.survey_id, m).await
    }
}
