//! A request to stop (SIGINT or SIGTERM), seen by whoever holds a [`Stop`].
//!
//! An acquisition is never cancelled in the middle of a write: the engine
//! checks its [`Stop`] between steps and races it only against the moves and
//! reads of a step (never against a commit), then stops the axis and returns
//! [`Stopped`]; the session commits what was measured and marks the survey
//! `interrupted` with the reason. The processing after an acquisition checks
//! it between its phases. So a signal at any moment ends the command with exit
//! status 1 and a survey that `survey resume` continues.

use futures_util::StreamExt;
use futures_util::stream::FuturesUnordered;
use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};
use tokio::sync::watch;

/// The stop request: which signal, once one arrived.
#[derive(Debug, Clone)]
pub struct Stop {
    rx: watch::Receiver<Option<&'static str>>,
}

/// Sends the stop request (the signal listener; tests).
#[derive(Debug)]
pub struct StopSender(watch::Sender<Option<&'static str>>);

impl StopSender {
    /// Ask every [`Stop`] of this channel to stop, naming why.
    pub fn stop(&self, why: &'static str) {
        self.0.send_if_modified(|v| {
            let first = v.is_none();
            if first {
                *v = Some(why);
            }
            first
        });
    }
}

/// The command was stopped by a signal.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("stopped by signal ({0})")]
pub struct Stopped(pub &'static str);

impl Default for Stop {
    /// [`Stop::never`].
    fn default() -> Self {
        Stop::never()
    }
}

impl Stop {
    /// A stop and its sender.
    pub fn channel() -> (StopSender, Stop) {
        let (tx, rx) = watch::channel(None);
        (StopSender(tx), Stop { rx })
    }

    /// A stop that never fires.
    pub fn never() -> Stop {
        Stop::channel().1
    }

    /// A stop fired by SIGINT (Ctrl-C) or SIGTERM, from now on. Once this is
    /// called the signals no longer end the process by themselves: the holder
    /// must check [`Stop::requested`] or wait on [`Stop::wait`].
    pub fn on_signals() -> Stop {
        let (tx, stop) = Stop::channel();
        tokio::spawn(async move {
            tokio::select! {
                _ = tokio::signal::ctrl_c() => tx.stop("SIGINT"),
                _ = terminated() => tx.stop("SIGTERM"),
            }
            tracing::warn!("stop requested by signal: finishing the current step and committing what was measured");
            // Keep the sender alive, so the request stays visible.
            std::future::pending::<()>().await;
        });
        stop
    }

    /// The stop requested so far, if any.
    pub fn requested(&self) -> Option<Stopped> {
        self.rx.borrow().map(Stopped)
    }

    /// `Err(Stopped)` when a stop was requested.
    pub fn check(&self) -> Result<(), Stopped> {
        self.requested().map_or(Ok(()), Err)
    }

    /// Resolves when a stop is requested, like [`Stop::wait`], for racing
    /// work that yields often: it is polled again only when its own waker
    /// fired (a stop may have come), not every time the work it races is
    /// (a simulated step re-polls its `select!` some sixty times).
    pub fn waiter(&self) -> StopWaiter {
        let mut stop = self.clone();
        StopWaiter(std::iter::once(Box::pin(async move { stop.wait().await }) as _).collect())
    }

    /// Resolves when a stop is requested (never, if no sender remains).
    pub async fn wait(&mut self) -> Stopped {
        let requested = self.rx.wait_for(Option::is_some).await.map(|v| Stopped(v.expect("waited for Some")));
        match requested {
            Ok(why) => why,
            Err(_) => std::future::pending().await,
        }
    }
}

/// See [`Stop::waiter`]: the wait, in a [`FuturesUnordered`]'s ready queue.
pub struct StopWaiter(FuturesUnordered<Pin<Box<dyn Future<Output = Stopped> + Send>>>);

impl std::fmt::Debug for StopWaiter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("StopWaiter")
    }
}

impl Future for StopWaiter {
    type Output = Stopped;
    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Stopped> {
        match self.0.poll_next_unpin(cx) {
            Poll::Ready(Some(why)) => Poll::Ready(why),
            // Already resolved once: nothing more to wait for.
            Poll::Ready(None) | Poll::Pending => Poll::Pending,
        }
    }
}

/// Resolves when the process is asked to terminate (SIGTERM on Unix).
async fn terminated() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        match signal(SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    }
    #[cfg(not(unix))]
    std::future::pending::<()>().await
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn the_first_reason_is_kept_and_every_holder_sees_it() {
        let (tx, mut a) = Stop::channel();
        let b = a.clone();
        assert_eq!(a.check(), Ok(()));
        tx.stop("SIGTERM");
        tx.stop("SIGINT");
        assert_eq!(a.wait().await, Stopped("SIGTERM"));
        assert_eq!(b.check(), Err(Stopped("SIGTERM")));
        assert_eq!(Stopped("SIGTERM").to_string(), "stopped by signal (SIGTERM)");
    }

    #[tokio::test]
    async fn a_waiter_wins_the_race_against_work_that_keeps_yielding() {
        // The work yields (and is polled again) a thousand times; the stop
        // comes from another task after the work's tenth poll.
        let (tx, stop) = Stop::channel();
        let polls = std::sync::Arc::new(std::sync::atomic::AtomicU32::new(0));
        let counted = polls.clone();
        let mut tx = Some(tx);
        let work = std::future::poll_fn(move |cx| {
            let n = counted.fetch_add(1, std::sync::atomic::Ordering::SeqCst) + 1;
            if n == 10 {
                let tx = tx.take().expect("once");
                tokio::spawn(async move { tx.stop("SIGINT") });
            }
            if n == 1000 {
                return Poll::Ready(());
            }
            cx.waker().wake_by_ref();
            Poll::Pending
        });
        let raced = tokio::select! {
            biased;
            why = stop.waiter() => Err(why),
            () = work => Ok(()),
        };
        assert_eq!(raced, Err(Stopped("SIGINT")));
        assert!(polls.load(std::sync::atomic::Ordering::SeqCst) < 1000);
        // Without a stop the work ends first, and the waiter never fires.
        let raced = tokio::select! {
            biased;
            why = Stop::never().waiter() => Err(why),
            () = tokio::task::yield_now() => Ok(()),
        };
        assert_eq!(raced, Ok(()));
    }

    #[tokio::test]
    async fn a_stop_without_a_sender_never_fires() {
        let mut never = Stop::never();
        assert_eq!(never.check(), Ok(()));
        let waited = tokio::time::timeout(std::time::Duration::from_millis(10), never.wait()).await;
        assert!(waited.is_err(), "never fired");
    }
}
