//! The one way a process (or a test) runs async work to its end: a
//! multi-thread tokio runtime whose shutdown is bounded.
//!
//! Dropping a runtime waits for every worker thread, and a task that never
//! yields keeps its worker forever: sqlx-core 0.9.0's pool reaper can spin so
//! (sqlx issue 3645; the fix, pull request 4289, is not in 0.9.0). The store
//! builds its pools without the reaper (`store::single_connection_pool`);
//! this is the second guard: once the work is done, whatever still runs is
//! given [`SHUTDOWN_WAIT`] and then abandoned, so the process can end.

use std::future::Future;
use std::time::Duration;

/// How long the runtime waits, after the work, for its background tasks.
pub const SHUTDOWN_WAIT: Duration = Duration::from_secs(2);

/// Run `work` to its end on a new multi-thread runtime of `workers` threads,
/// then shut the runtime down, waiting at most [`SHUTDOWN_WAIT`] for what is
/// still running. Everything `work` awaited (every write) has finished when it
/// returns; tasks it only spawned are not waited for beyond the bound.
pub fn block_on_bounded<F: Future>(workers: usize, work: F) -> std::io::Result<F::Output> {
    let runtime = tokio::runtime::Builder::new_multi_thread().worker_threads(workers).enable_all().build()?;
    let output = runtime.block_on(work);
    runtime.shutdown_timeout(SHUTDOWN_WAIT);
    Ok(output)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A task that spins without yielding holds a worker thread for good;
    /// the bounded shutdown still returns (a plain drop would wait forever).
    #[test]
    fn a_spinning_task_does_not_keep_the_runtime() {
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let spinning = stop.clone();
        let out = block_on_bounded(2, async move {
            tokio::spawn(async move {
                while !spinning.load(std::sync::atomic::Ordering::Relaxed) {
                    std::hint::spin_loop();
                }
            });
            tokio::task::yield_now().await;
            42
        })
        .unwrap();
        assert_eq!(out, 42);
        // Let the abandoned worker go, so it does not load the rest of the suite.
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
    }
}
