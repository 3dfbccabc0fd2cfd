//! [`StoreSink`]: the [`SampleSink`] that writes to the store in batches.

use std::future::Future;
use std::sync::Arc;
use std::time::{Duration, Instant};

use async_trait::async_trait;
use survey_drivers::SmrMeasurement;
use survey_processing::geometry::AxisFit;
use tokio::task::JoinHandle;

use super::{Store, is_busy};
use survey_acquire::{RecordedSample, SampleSink, ScanPassRecord};

/// A write of a batch running as a task of its own.
type Write = JoinHandle<anyhow::Result<()>>;

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
/// about the real disk. A sample is acknowledged (durable) when a write that
/// holds it has committed: `flush()` returns once everything recorded is
/// (or returns the error), and [`StoreSink::last_acknowledged`] says how far
/// the writes have come. With real instruments a sample takes seconds, so each
/// one (from the second on) is written, and waited for, as soon as it is
/// recorded; a fast simulation writes in batches. The sink has no timer of its
/// own: the engine calls `flush()` before anything that may wait (a fault
/// recovery, a pause) and at the end.
///
/// A full batch (or one aged by `max_age` while samples come quickly) is
/// written beside the acquisition: the write runs as a task of its own while
/// the engine goes on measuring, and the next write (or `flush()`) first waits
/// for it. At most one such write is under way, so at most two batches are in
/// memory; a process killed meanwhile loses what was not acknowledged, as it
/// would the buffer (the transaction is whole or absent). On 2 cores this puts
/// the SQLite work of a simulated survey (about a quarter of its CPU) beside
/// the simulation instead of after it.
///
/// When a write fails, its samples go back to the front of the buffer (the
/// transaction rolled back, nothing of them is stored), the error is returned
/// by the call that waited for it, and the next write tries again.
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
    /// The batch being written beside the acquisition, and its write.
    in_flight: Option<(Arc<Vec<RecordedSample>>, Write)>,
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
            in_flight: None,
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

    /// Samples recorded but not yet acknowledged (buffered, or in a write
    /// still under way).
    pub fn pending(&self) -> usize {
        self.buffer.len() + self.in_flight.as_ref().map_or(0, |(batch, _)| batch.len())
    }

    /// The highest seq this sink has acknowledged (written durably), if any,
    /// as far as the writes it has waited for tell.
    pub fn last_acknowledged(&self) -> Option<u64> {
        self.acknowledged
    }

    /// Count `batch` as written.
    fn acknowledge(&mut self, batch: &[RecordedSample]) {
        let top = batch.iter().map(|r| r.seq).max();
        self.acknowledged = self.acknowledged.max(top);
    }

    /// Wait for the write under way, if any. On failure its samples go back to
    /// the front of the buffer.
    async fn settle(&mut self) -> anyhow::Result<()> {
        let Some((batch, write)) = self.in_flight.take() else { return Ok(()) };
        let outcome = write.await.unwrap_or_else(|e| {
            Err(anyhow::anyhow!(
                "the write of {} samples of survey {} ended unfinished: {e}",
                batch.len(),
                self.survey_id
            ))
        });
        match outcome {
            Ok(()) => {
                self.acknowledge(&batch);
                Ok(())
            }
            Err(e) => {
                let mut back = Arc::unwrap_or_clone(batch);
                back.append(&mut self.buffer);
                self.buffer = back;
                self.oldest.get_or_insert_with(Instant::now);
                Err(e)
            }
        }
    }

    /// Write the buffer beside the acquisition, once the previous write is done.
    async fn dispatch(&mut self) -> anyhow::Result<()> {
        self.settle().await?;
        if self.buffer.is_empty() {
            return Ok(());
        }
        let batch = Arc::new(std::mem::take(&mut self.buffer));
        self.oldest = None;
        let (store, survey_id, busy_wait, samples) =
            (self.store.clone(), self.survey_id, self.busy_wait, batch.clone());
        let write = tokio::spawn(async move { append_retrying(&store, survey_id, &samples, busy_wait).await });
        self.in_flight = Some((batch, write));
        Ok(())
    }

    /// Write everything recorded and wait for it.
    async fn write(&mut self) -> anyhow::Result<()> {
        self.settle().await?;
        if self.buffer.is_empty() {
            return Ok(());
        }
        append_retrying(&self.store, self.survey_id, &self.buffer, self.busy_wait).await?;
        let written = std::mem::take(&mut self.buffer);
        self.acknowledge(&written);
        self.oldest = None;
        Ok(())
    }
}

/// [`Store::append`], retried while another writer holds the database, for up
/// to `busy_wait`.
async fn append_retrying(
    store: &Store,
    survey_id: i64,
    samples: &[RecordedSample],
    busy_wait: Duration,
) -> anyhow::Result<()> {
    let what = format!("{} samples", samples.len());
    while_busy(survey_id, &what, busy_wait, || store.append(survey_id, samples)).await
}

/// `write`, tried again every 200 ms while the database is locked by another
/// writer, each wait logged, for up to `busy_wait`; then its error.
async fn while_busy<F: Future<Output = anyhow::Result<()>>>(
    survey_id: i64,
    what: &str,
    busy_wait: Duration,
    mut write: impl FnMut() -> F,
) -> anyhow::Result<()> {
    let started = Instant::now();
    let mut attempt = 0u32;
    loop {
        match write().await {
            Ok(()) => return Ok(()),
            Err(e) if is_busy(&e) && started.elapsed() < busy_wait => {
                attempt += 1;
                tracing::warn!(
                    survey = survey_id,
                    attempt,
                    waited_s = started.elapsed().as_secs_f64(),
                    pending = what,
                    "the database is locked by another writer: what is pending waits in memory, retrying"
                );
                tokio::time::sleep(Duration::from_millis(200)).await;
            }
            Err(e) => return Err(e),
        }
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
        if slow {
            self.write().await
        } else if self.buffer.len() >= self.batch || now.duration_since(oldest) >= self.max_age {
            self.dispatch().await
        } else {
            Ok(())
        }
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
        let what = format!("pass {}", pass.pass);
        while_busy(self.survey_id, &what, self.busy_wait, || self.store.append_pass(self.survey_id, &pass)).await?;
        self.acknowledge(&pass.samples);
        Ok(())
    }

    /// Logged at once (not buffered).
    async fn event(&mut self, at_s: f64, level: &str, message: &str) -> anyhow::Result<()> {
        self.store.log_event(self.survey_id, at_s, level, message).await
    }
    async fn drift_measured(&mut self, m: &survey_plan::drift::DriftMeasurement) -> anyhow::Result<()> {
        self.store.add_drift_measurement(self.survey_id, m).await
    }
}
