//! A request to stop (SIGINT or SIGTERM), seen by whoever holds a [`Stop`].
//!
//! An acquisition is never cancelled in the middle of a write: the engine
//! checks its [`Stop`] between steps and races it only against the moves and
//! reads of a step (never against a commit), then stops the axis and returns
//! [`Stopped`]; the session commits what was measured and marks the survey
//! `interrupted` with the reason. The processing after an acquisition checks
//! it between its phases. So a signal at any moment ends the command with exit
//! status 1 and a survey that `survey resume` continues.

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

    /// Resolves when a stop is requested (never, if no sender remains).
    pub async fn wait(&mut self) -> Stopped {
        match self.rx.wait_for(Option::is_some).await {
            Ok(v) => Stopped(v.expect("waited for Some")),
            Err(_) => std::future::pending().await,
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
    async fn a_stop_without_a_sender_never_fires() {
        let mut never = Stop::never();
        assert_eq!(never.check(), Ok(()));
        let waited = tokio::time::timeout(std::time::Duration::from_millis(10), never.wait()).await;
        assert!(waited.is_err(), "never fired");
    }
}
