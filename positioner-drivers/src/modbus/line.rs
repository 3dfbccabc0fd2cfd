//! The RTU line the tokio-modbus client talks through. RTU has no
//! transaction id, so a reply that comes after its request timed out would
//! be taken for the next request's: the line lets through only the response
//! frames that answer the request just written ([`Expected`]: slave,
//! function, byte count or echo), discarding (and logging) any other; and
//! after a timeout the driver drains it ([`LateReplies::drain_until`]) for as
//! long as the device may still answer.

use super::rtu::{Expected, rtu_response_len};
use std::future::{Future, poll_fn};
use std::io;
use std::pin::Pin;
use std::sync::{Arc, Mutex, MutexGuard};
use std::task::{Context, Poll};
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::time::Instant;

/// The most bytes held while no frame can be cut from them (a garbled
/// length): then they go to the client as they are, which reports them.
const MAX_HELD: usize = 512;

struct Shared<T> {
    io: T,
    /// What the reply to the request last written must carry.
    expected: Option<Expected>,
    /// Bytes read, not yet cut into a frame.
    held: Vec<u8>,
    /// Bytes of matched frames, for the client.
    ready: Vec<u8>,
}

impl<T> Shared<T> {
    /// Cut whole frames from what is held: the one that answers goes to the
    /// client, the others are discarded.
    fn frames(&mut self) {
        while let Some(len) = rtu_response_len(&self.held).filter(|&n| n > 0 && self.held.len() >= n) {
            let frame: Vec<u8> = self.held.drain(..len).collect();
            match self.expected.map(|e| e.mismatch(&frame)) {
                Some(None) => {
                    self.expected = None;
                    self.ready.extend_from_slice(&frame);
                }
                Some(Some(why)) => {
                    tracing::warn!(%why, frame = ?frame, "modbus-rtu: discarded a reply that does not answer the request");
                }
                None => tracing::warn!(frame = ?frame, "modbus-rtu: discarded a reply no request awaits"),
            }
        }
        if self.held.len() > MAX_HELD {
            self.ready.append(&mut self.held);
        }
    }
}

/// The line given to the tokio-modbus client.
pub(super) struct Line<T> {
    shared: Arc<Mutex<Shared<T>>>,
}

fn lock<T>(shared: &Mutex<Shared<T>>) -> MutexGuard<'_, Shared<T>> {
    shared.lock().unwrap_or_else(|p| p.into_inner())
}

/// Reads the line's late replies (a handle the driver keeps).
pub(super) trait LateReplies: Send + Sync {
    /// Read and discard what arrives until `deadline` (or the line closes);
    /// returns the bytes discarded.
    fn drain_until(&self, deadline: Instant) -> Pin<Box<dyn Future<Output = usize> + Send + '_>>;
}

/// `transport` as a matched line, and its drain.
pub(super) fn line<T>(transport: T) -> (Line<T>, Arc<dyn LateReplies>)
where
    T: AsyncRead + AsyncWrite + Send + Unpin + 'static,
{
    let shared = Arc::new(Mutex::new(Shared { io: transport, expected: None, held: Vec::new(), ready: Vec::new() }));
    (Line { shared: Arc::clone(&shared) }, Arc::new(Line { shared }))
}

impl<T: AsyncRead + Send + Unpin> LateReplies for Line<T> {
    fn drain_until(&self, deadline: Instant) -> Pin<Box<dyn Future<Output = usize> + Send + '_>> {
        Box::pin(async move {
            let mut dropped = 0;
            loop {
                let read = poll_fn(|cx| {
                    let mut s = lock(&self.shared);
                    let mut buf = [0u8; 256];
                    let mut rb = ReadBuf::new(&mut buf);
                    Pin::new(&mut s.io).poll_read(cx, &mut rb).map_ok(|()| rb.filled().len())
                });
                match tokio::time::timeout_at(deadline, read).await {
                    Ok(Ok(n)) if n > 0 => dropped += n,
                    _ => break,
                }
            }
            let mut s = lock(&self.shared);
            dropped += s.held.len() + s.ready.len();
            (s.expected, s.held, s.ready) = (None, Vec::new(), Vec::new());
            dropped
        })
    }
}

impl<T: AsyncRead + Unpin> AsyncRead for Line<T> {
    fn poll_read(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        let mut s = lock(&self.shared);
        loop {
            if !s.ready.is_empty() {
                let n = s.ready.len().min(buf.remaining());
                buf.put_slice(&s.ready[..n]);
                s.ready.drain(..n);
                return Poll::Ready(Ok(()));
            }
            let mut tmp = [0u8; 256];
            let mut rb = ReadBuf::new(&mut tmp);
            match Pin::new(&mut s.io).poll_read(cx, &mut rb) {
                Poll::Pending => return Poll::Pending,
                Poll::Ready(Err(e)) => return Poll::Ready(Err(e)),
                // End of stream: the client sees it.
                Poll::Ready(Ok(())) if rb.filled().is_empty() => return Poll::Ready(Ok(())),
                Poll::Ready(Ok(())) => {
                    let filled = rb.filled().to_vec();
                    s.held.extend_from_slice(&filled);
                    s.frames();
                }
            }
        }
    }
}

impl<T: AsyncWrite + Unpin> AsyncWrite for Line<T> {
    fn poll_write(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        let mut s = lock(&self.shared);
        if let Some(expected) = Expected::of_request(buf) {
            // A new request: what was matched for an earlier one is stale.
            s.expected = Some(expected);
            s.ready.clear();
        }
        Pin::new(&mut s.io).poll_write(cx, buf)
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut lock(&self.shared).io).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut lock(&self.shared).io).poll_shutdown(cx)
    }
}
