//! Draining stale input before a request, shared by the drivers that talk to
//! an instrument over a byte stream (the SCPI controller's in `survey-positioner-drivers`,
//! [`elcomat`](crate::elcomat), [`emscon`](crate::emscon)).
//!
//! None of these protocols ties a reply to its request, so a reply that comes
//! after its request timed out would be taken for the answer to the next one.
//! Before it writes a request, each driver reads and throws away the input
//! already waiting on the stream and, after a timeout, whatever arrives within
//! a short grace period (a reply that was merely slow). [`Drain`] does the
//! reading; what happens to the bytes (decoded and dropped, status packets
//! kept, or not even decoded) and what a closed stream means stay the
//! driver's.

use std::future::poll_fn;
use std::io;
use std::pin::Pin;
use std::task::Poll;
use tokio::io::{AsyncRead, AsyncReadExt, ReadBuf};
use tokio::time::Instant;

/// Why a drain stopped early: the stream ended or failed.
#[derive(Debug)]
pub enum Lost {
    /// End of stream: the peer closed the connection.
    Closed,
    /// The read failed.
    Failed(io::Error),
}

impl Lost {
    /// The reason as the drivers report it: `connection closed by <peer>`, or
    /// the I/O error's text.
    pub fn why(&self, peer: &str) -> String {
        match self {
            Lost::Closed => format!("connection closed by {peer}"),
            Lost::Failed(e) => e.to_string(),
        }
    }
}

/// Reads stale input chunk by chunk ([`next`](Self::next)): first, when a
/// grace deadline is set, everything that arrives until it passes; then, when
/// asked for, what is already waiting, without blocking.
#[derive(Debug, Clone)]
pub struct Drain {
    /// Wait for late input until then.
    late_until: Option<Instant>,
    /// Then take what is already waiting.
    waiting: bool,
    /// Stop taking waiting input after this many bytes in all.
    limit: usize,
    /// Bytes read so far.
    read: usize,
}

impl Drain {
    /// What arrives until `late_until` (when given), then what is already
    /// waiting.
    pub fn new(late_until: Option<Instant>) -> Self {
        Self { late_until, waiting: true, limit: usize::MAX, read: 0 }
    }

    /// Only what is already waiting.
    pub fn waiting() -> Self {
        Self::new(None)
    }

    /// Only what arrives until `deadline`.
    pub fn late(deadline: Instant) -> Self {
        Self { waiting: false, ..Self::new(Some(deadline)) }
    }

    /// Stop taking waiting input once `limit` bytes were read (a peer that
    /// never stops sending would otherwise keep the drain busy forever).
    pub fn at_most(self, limit: usize) -> Self {
        Self { limit, ..self }
    }

    /// The next chunk of stale input, read into `buf`: `Ok(Some(n))` for
    /// `buf[..n]`, `Ok(None)` when the drain is over (the grace has passed and
    /// nothing more is waiting, or the limit is reached).
    pub async fn next<T>(&mut self, io: &mut T, buf: &mut [u8]) -> Result<Option<usize>, Lost>
    where
        T: AsyncRead + Unpin,
    {
        let read = if let Some(deadline) = self.late_until
            && let Ok(read) = tokio::time::timeout_at(deadline, io.read(buf)).await
        {
            read
        } else {
            self.late_until = None;
            if !self.waiting || self.read >= self.limit {
                return Ok(None);
            }
            match read_ready(io, buf).await {
                Some(read) => read,
                None => return Ok(None),
            }
        };
        match read {
            Ok(0) => Err(Lost::Closed),
            Ok(n) => {
                self.read += n;
                Ok(Some(n))
            }
            Err(e) => Err(Lost::Failed(e)),
        }
    }
}

/// One read that does not wait: `None` when it would block.
async fn read_ready<T>(io: &mut T, buf: &mut [u8]) -> Option<io::Result<usize>>
where
    T: AsyncRead + Unpin,
{
    poll_fn(|cx| {
        let mut rb = ReadBuf::new(&mut *buf);
        match Pin::new(&mut *io).poll_read(cx, &mut rb) {
            Poll::Ready(Ok(())) => Poll::Ready(Some(Ok(rb.filled().len()))),
            Poll::Ready(Err(e)) => Poll::Ready(Some(Err(e))),
            Poll::Pending => Poll::Ready(None),
        }
    })
    .await
}
