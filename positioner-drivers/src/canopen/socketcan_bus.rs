//! [`CanBus`] over Linux SocketCAN (`socketcan` 4.0, `socketcan::tokio::CanSocket`).
//!
//! Only classic data frames with 11-bit identifiers are CANopen's: received
//! remote, error and extended-identifier frames are skipped (logged at trace
//! level). SocketCAN does not deliver a socket its own frames by default, so
//! this endpoint, like the in-memory one, sees only the other nodes' frames.
//! A socket error (interface down, gone) is [`ErrorKind::Disconnected`].
//!
//! Opening needs a kernel with `AF_CAN` and the interface: where the kernel
//! has no CAN support, opening fails with os error 97 (`EAFNOSUPPORT`); where
//! the interface does not exist, with os error 19 (`ENODEV`). Use
//! [`SocketCanBus::open_io`] to see the raw error, [`is_can_unavailable`] to
//! tell those two apart from other failures.

use super::frame::{CanBus, CanFrame};
use async_trait::async_trait;
use socketcan::{EmbeddedFrame, Frame, StandardId};
use std::fmt;
use survey_drivers::error::{DriverError, ErrorKind, Result};

/// `ENODEV`: no such interface.
pub const ENODEV: i32 = 19;
/// `EAFNOSUPPORT`: the kernel has no `AF_CAN`.
pub const EAFNOSUPPORT: i32 = 97;

/// Whether an open error means "no CAN here" (no `AF_CAN` in the kernel, or
/// no such interface) rather than a fault of a CAN setup that exists.
pub fn is_can_unavailable(e: &std::io::Error) -> bool {
    matches!(e.raw_os_error(), Some(ENODEV | EAFNOSUPPORT))
}

/// A SocketCAN raw socket bound to one interface.
pub struct SocketCanBus {
    socket: socketcan::tokio::CanSocket,
    interface: String,
}

impl fmt::Debug for SocketCanBus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SocketCanBus").field("interface", &self.interface).finish()
    }
}

impl SocketCanBus {
    /// Open `interface` (`"can0"`, `"vcan0"`), returning the raw I/O error.
    /// Must be called within a tokio runtime.
    pub fn open_io(interface: &str) -> std::io::Result<Self> {
        let socket = socketcan::tokio::CanSocket::open(interface)?;
        Ok(Self { socket, interface: interface.to_string() })
    }

    /// Open `interface`; a failure is [`ErrorKind::Disconnected`] with the OS
    /// error in the message.
    pub fn open(interface: &str) -> Result<Self> {
        Self::open_io(interface).map_err(|e| {
            let e = DriverError::new(
                ErrorKind::Disconnected,
                format!("socketcan {interface}"),
                format!("cannot open CAN interface {interface}: {e} (os error {:?})", e.raw_os_error()),
            );
            tracing::warn!(error = %e, "socketcan open failed");
            e
        })
    }

    /// The interface name.
    pub fn interface(&self) -> &str {
        &self.interface
    }

    fn failed(&self, what: &str, e: &std::io::Error) -> DriverError {
        let e = DriverError::new(ErrorKind::Disconnected, self.describe(), format!("{what}: {e}"));
        tracing::warn!(error = %e, "socketcan I/O failed");
        e
    }

    /// Our frame from a socketcan frame, or `None` for what CANopen does not use.
    fn convert(&self, frame: &socketcan::CanFrame) -> Option<CanFrame> {
        let socketcan::CanFrame::Data(data) = frame else {
            tracing::trace!(interface = %self.interface, ?frame, "skipped a remote or error frame");
            return None;
        };
        match data.id() {
            socketcan::Id::Standard(id) => CanFrame::new(id.as_raw(), data.data()).ok(),
            socketcan::Id::Extended(_) => {
                tracing::trace!(interface = %self.interface, raw = data.raw_id(), "skipped an extended-id frame");
                None
            }
        }
    }
}

#[async_trait]
impl CanBus for SocketCanBus {
    async fn send(&mut self, frame: CanFrame) -> Result<()> {
        let id = StandardId::new(frame.id()).ok_or_else(|| {
            DriverError::usage(self.describe(), format!("identifier 0x{:X} is not 11-bit", frame.id()))
        })?;
        let out = socketcan::CanFrame::new(id, frame.data())
            .ok_or_else(|| DriverError::usage(self.describe(), format!("frame {frame} does not fit a CAN frame")))?;
        self.socket.write_frame(out).await.map_err(|e| self.failed("write", &e))
    }

    async fn recv(&mut self) -> Result<CanFrame> {
        loop {
            let frame = self.socket.read_frame().await.map_err(|e| self.failed("read", &e))?;
            if let Some(f) = self.convert(&frame) {
                return Ok(f);
            }
        }
    }

    fn try_recv(&mut self) -> Result<Option<CanFrame>> {
        loop {
            match self.socket.try_read_frame() {
                Ok(frame) => {
                    if let Some(f) = self.convert(&frame) {
                        return Ok(Some(f));
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return Ok(None),
                Err(e) => return Err(self.failed("read", &e)),
            }
        }
    }

    fn describe(&self) -> String {
        format!("socketcan {}", self.interface)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn opening_a_missing_interface_is_unavailable_or_disconnected() {
        // No interface has this name, with or without AF_CAN in the kernel.
        let e = SocketCanBus::open_io("nosuchcan9").unwrap_err();
        assert!(is_can_unavailable(&e), "{e} ({:?})", e.raw_os_error());
        let e = SocketCanBus::open("nosuchcan9").unwrap_err();
        assert_eq!(e.kind, ErrorKind::Disconnected);
        assert!(e.message.contains("nosuchcan9"), "{e}");
        assert!(!is_can_unavailable(&std::io::Error::from_raw_os_error(13)));
    }
}
