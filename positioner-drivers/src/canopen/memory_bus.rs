//! An in-memory CAN bus: every endpoint sees the frames every other endpoint
//! sends (never its own), in the order they were sent, like a real bus with
//! SocketCAN's default of not receiving one's own frames.
//!
//! Built on a `tokio::sync::broadcast` channel of [`BUS_CAPACITY`] frames. An
//! endpoint that falls further behind loses the oldest frames (logged), as a
//! CAN controller whose receive buffer overflows does. [`MemoryBus::shut_down`]
//! takes the bus away: sends fail at once and receives fail once the frames
//! already on the bus are read, both with [`ErrorKind::Disconnected`] (the
//! interface went down).

use super::frame::{CanBus, CanFrame};
use async_trait::async_trait;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use survey_drivers::error::{DriverError, ErrorKind, Result};
use tokio::sync::broadcast;
use tokio::sync::broadcast::error::{RecvError, TryRecvError};

/// Frames the bus holds for an endpoint that has not read them yet.
pub const BUS_CAPACITY: usize = 4096;

#[derive(Debug)]
struct Shared {
    tx: Mutex<Option<broadcast::Sender<(u64, CanFrame)>>>,
    next_endpoint: AtomicU64,
}

/// The bus; hand out endpoints with [`MemoryBus::endpoint`]. Clones share the bus.
#[derive(Debug, Clone)]
pub struct MemoryBus {
    shared: Arc<Shared>,
}

impl Default for MemoryBus {
    fn default() -> Self {
        Self::new()
    }
}

impl MemoryBus {
    /// A new, empty bus.
    pub fn new() -> Self {
        let (tx, _) = broadcast::channel(BUS_CAPACITY);
        Self { shared: Arc::new(Shared { tx: Mutex::new(Some(tx)), next_endpoint: AtomicU64::new(0) }) }
    }

    /// A new endpoint: it receives the frames sent from now on by the others.
    /// On a bus that was shut down, the endpoint fails every call.
    pub fn endpoint(&self) -> MemoryEndpoint {
        let id = self.shared.next_endpoint.fetch_add(1, Ordering::Relaxed);
        let rx = self.lock().as_ref().map(broadcast::Sender::subscribe);
        MemoryEndpoint { id, shared: Arc::clone(&self.shared), rx }
    }

    /// Take the bus away (the interface goes down): see the module documentation.
    pub fn shut_down(&self) {
        self.lock().take();
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Option<broadcast::Sender<(u64, CanFrame)>>> {
        self.shared.tx.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// One node's connection to a [`MemoryBus`].
#[derive(Debug)]
pub struct MemoryEndpoint {
    id: u64,
    shared: Arc<Shared>,
    rx: Option<broadcast::Receiver<(u64, CanFrame)>>,
}

impl MemoryEndpoint {
    fn down(&self, what: &str) -> DriverError {
        DriverError::new(ErrorKind::Disconnected, self.describe(), format!("{what}: the in-memory bus was shut down"))
    }
}

#[async_trait]
impl CanBus for MemoryEndpoint {
    async fn send(&mut self, frame: CanFrame) -> Result<()> {
        let guard = self.shared.tx.lock().unwrap_or_else(|p| p.into_inner());
        match guard.as_ref() {
            // An error means no endpoint listens: a frame on an empty bus is lost, as on a real one.
            Some(tx) => {
                let _ = tx.send((self.id, frame));
                Ok(())
            }
            None => {
                drop(guard);
                Err(self.down("send"))
            }
        }
    }

    async fn recv(&mut self) -> Result<CanFrame> {
        loop {
            let Some(rx) = self.rx.as_mut() else {
                return Err(self.down("recv"));
            };
            match rx.recv().await {
                Ok((from, frame)) if from != self.id => return Ok(frame),
                Ok(_) => {}
                Err(RecvError::Lagged(n)) => {
                    tracing::warn!(endpoint = self.id, lost = n, "in-memory CAN bus: receive buffer overflow");
                }
                Err(RecvError::Closed) => {
                    self.rx = None;
                    return Err(self.down("recv"));
                }
            }
        }
    }

    fn try_recv(&mut self) -> Result<Option<CanFrame>> {
        loop {
            let Some(rx) = self.rx.as_mut() else {
                return Err(self.down("try_recv"));
            };
            match rx.try_recv() {
                Ok((from, frame)) if from != self.id => return Ok(Some(frame)),
                Ok(_) => {}
                Err(TryRecvError::Empty) => return Ok(None),
                Err(TryRecvError::Lagged(n)) => {
                    tracing::warn!(endpoint = self.id, lost = n, "in-memory CAN bus: receive buffer overflow");
                }
                Err(TryRecvError::Closed) => {
                    self.rx = None;
                    return Err(self.down("try_recv"));
                }
            }
        }
    }

    fn describe(&self) -> String {
        format!("memory bus endpoint {}", self.id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn f(id: u16, b: u8) -> CanFrame {
        CanFrame::new(id, &[b]).unwrap()
    }

    #[tokio::test]
    async fn every_endpoint_sees_the_others_frames_in_order_but_not_its_own() {
        let bus = MemoryBus::new();
        let (mut a, mut b, mut c) = (bus.endpoint(), bus.endpoint(), bus.endpoint());
        a.send(f(1, 1)).await.unwrap();
        b.send(f(2, 2)).await.unwrap();
        a.send(f(3, 3)).await.unwrap();
        assert_eq!(b.recv().await.unwrap(), f(1, 1));
        assert_eq!(b.recv().await.unwrap(), f(3, 3));
        assert_eq!(b.try_recv().unwrap(), None);
        assert_eq!(a.recv().await.unwrap(), f(2, 2));
        assert_eq!(a.try_recv().unwrap(), None);
        let seen: Vec<_> = std::iter::from_fn(|| c.try_recv().unwrap()).collect();
        assert_eq!(seen, vec![f(1, 1), f(2, 2), f(3, 3)]);
        // A late endpoint sees only what comes after it joined.
        let mut d = bus.endpoint();
        assert_eq!(d.try_recv().unwrap(), None);
        c.send(f(4, 4)).await.unwrap();
        assert_eq!(d.recv().await.unwrap(), f(4, 4));
    }

    #[tokio::test(start_paused = true)]
    async fn recv_is_cancel_safe() {
        let bus = MemoryBus::new();
        let (mut a, mut b) = (bus.endpoint(), bus.endpoint());
        assert!(tokio::time::timeout(Duration::from_millis(10), b.recv()).await.is_err());
        a.send(f(7, 7)).await.unwrap();
        assert_eq!(b.recv().await.unwrap(), f(7, 7));
    }

    #[tokio::test]
    async fn shut_down_is_a_disconnection_after_the_frames_on_the_bus() {
        let bus = MemoryBus::new();
        let (mut a, mut b) = (bus.endpoint(), bus.endpoint());
        a.send(f(1, 1)).await.unwrap();
        bus.shut_down();
        assert_eq!(a.send(f(2, 2)).await.unwrap_err().kind, ErrorKind::Disconnected);
        assert_eq!(b.recv().await.unwrap(), f(1, 1));
        assert_eq!(b.recv().await.unwrap_err().kind, ErrorKind::Disconnected);
        assert_eq!(b.try_recv().unwrap_err().kind, ErrorKind::Disconnected);
        let mut late = bus.endpoint();
        assert_eq!(late.recv().await.unwrap_err().kind, ErrorKind::Disconnected);
    }

    #[tokio::test]
    async fn an_overflowing_endpoint_loses_the_oldest_frames() {
        let bus = MemoryBus::new();
        let (mut a, mut b) = (bus.endpoint(), bus.endpoint());
        for i in 0..BUS_CAPACITY + 10 {
            a.send(f(1, i as u8)).await.unwrap();
        }
        let mut n = 0;
        while b.try_recv().unwrap().is_some() {
            n += 1;
        }
        assert_eq!(n, BUS_CAPACITY);
    }
}
