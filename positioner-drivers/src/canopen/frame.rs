//! The classic CAN frame this driver speaks (11-bit identifier, up to 8 data
//! bytes) and the bus trait every transport implements.

use async_trait::async_trait;
use std::fmt;
use survey_drivers::error::Result;

/// Highest 11-bit (CAN 2.0A) identifier.
pub const MAX_STANDARD_ID: u16 = 0x7FF;

/// A classic CAN data frame with an 11-bit identifier (CAN 2.0A). CANopen
/// (CiA 301) uses only these.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: u16,
    data: [u8; 8],
    len: u8,
}

/// Why a frame cannot be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// The identifier does not fit in 11 bits.
    #[error("CAN identifier 0x{0:X} does not fit in 11 bits")]
    IdTooLarge(u32),
    /// More than 8 data bytes.
    #[error("{0} data bytes (a classic CAN frame carries at most 8)")]
    TooLong(usize),
}

impl CanFrame {
    /// A frame with identifier `id` (at most [`MAX_STANDARD_ID`]) and up to 8
    /// data bytes.
    pub fn new(id: u16, payload: &[u8]) -> Result<Self, FrameError> {
        if id > MAX_STANDARD_ID {
            return Err(FrameError::IdTooLarge(u32::from(id)));
        }
        if payload.len() > 8 {
            return Err(FrameError::TooLong(payload.len()));
        }
        let mut data = [0u8; 8];
        data[..payload.len()].copy_from_slice(payload);
        Ok(Self { id, data, len: payload.len() as u8 })
    }

    /// A frame with all 8 data bytes (the form of every SDO frame).
    pub fn full(id: u16, data: [u8; 8]) -> Result<Self, FrameError> {
        Self::new(id, &data)
    }

    /// The 11-bit identifier (the CANopen COB-ID).
    pub fn id(&self) -> u16 {
        self.id
    }

    /// The data bytes (0 to 8 of them).
    pub fn data(&self) -> &[u8] {
        &self.data[..usize::from(self.len)]
    }

    /// The data length code: how many data bytes.
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// Whether the frame carries no data bytes.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl fmt::Debug for CanFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{self}")
    }
}

impl fmt::Display for CanFrame {
    /// `candump` style: `605#4041600000000000`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:03X}#", self.id)?;
        for b in self.data() {
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}

/// A CAN bus endpoint: sends frames and receives the frames other endpoints
/// send (never its own).
///
/// `recv` must be cancel-safe: the SDO client wraps it in a timeout, and a
/// frame must not be lost when the timeout wins. Link failures are
/// [`ErrorKind::Disconnected`](survey_drivers::error::ErrorKind::Disconnected) (the
/// interface is gone or down); a CAN bus has no connection, so a node that
/// stops answering is silence, which the caller sees as a timeout.
#[async_trait]
pub trait CanBus: Send + fmt::Debug {
    /// Put one frame on the bus.
    async fn send(&mut self, frame: CanFrame) -> Result<()>;
    /// The next frame from another endpoint (cancel-safe).
    async fn recv(&mut self) -> Result<CanFrame>;
    /// A frame that has already arrived, if any, without waiting (to drop
    /// stale input before a request).
    fn try_recv(&mut self) -> Result<Option<CanFrame>>;
    /// A short description for logs (`"memory bus"`, `"socketcan vcan0"`).
    fn describe(&self) -> String;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_checked_and_shown_candump_style() {
        let f = CanFrame::new(0x605, &[0x40, 0x41, 0x60, 0]).unwrap();
        assert_eq!(f.id(), 0x605);
        assert_eq!(f.data(), &[0x40, 0x41, 0x60, 0]);
        assert_eq!((f.len(), f.is_empty()), (4, false));
        assert_eq!(f.to_string(), "605#40416000");
        assert_eq!(format!("{f:?}"), "605#40416000");
        assert!(CanFrame::new(0, &[]).unwrap().is_empty());
        assert_eq!(CanFrame::new(0x800, &[]), Err(FrameError::IdTooLarge(0x800)));
        assert_eq!(CanFrame::new(1, &[0; 9]), Err(FrameError::TooLong(9)));
        assert_eq!(CanFrame::full(0x7FF, [1; 8]).unwrap().len(), 8);
    }
}
