//! The driver error type: every fault is classified so retry logic can branch.

use std::fmt;
use std::time::Duration;

/// The class of a driver failure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    /// Link: no reply within the deadline.
    Timeout,
    /// Link: the connection is gone (refused, reset, closed, port vanished).
    Disconnected,
    /// Link: a reply arrived but could not be decoded (bad checksum, truncated,
    /// wrong protocol).
    Garbled,
    /// Device: the instrument answered and reported a fault of its own.
    Device,
    /// Usage: the request itself is wrong (out of travel, bad argument, wrong
    /// state); retrying the same request will fail the same way.
    Usage,
}

impl ErrorKind {
    /// A link fault: the request may succeed after the link is rebuilt.
    pub fn is_link(self) -> bool {
        matches!(self, ErrorKind::Timeout | ErrorKind::Disconnected | ErrorKind::Garbled)
    }

    pub fn as_str(self) -> &'static str {
        match self {
            ErrorKind::Timeout => "timeout",
            ErrorKind::Disconnected => "disconnected",
            ErrorKind::Garbled => "garbled frame",
            ErrorKind::Device => "device fault",
            ErrorKind::Usage => "bad usage",
        }
    }
}

impl fmt::Display for ErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A driver failure: its class, the instrument, the device's own code when it
/// reported one, and a message.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct DriverError {
    pub kind: ErrorKind,
    /// Which instrument (`"positioner"`, `"tracker"`, `"autocollimator"`, or a driver name).
    pub instrument: String,
    /// The device's own fault code, for device faults.
    pub code: Option<i64>,
    pub message: String,
}

impl fmt::Display for DriverError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.instrument, self.kind)?;
        if let Some(code) = self.code {
            write!(f, " (code {code})")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl DriverError {
    pub fn new(kind: ErrorKind, instrument: impl Into<String>, message: impl Into<String>) -> Self {
        Self { kind, instrument: instrument.into(), code: None, message: message.into() }
    }

    /// A device-reported fault with the device's code.
    pub fn device(instrument: impl Into<String>, code: i64, message: impl Into<String>) -> Self {
        Self { kind: ErrorKind::Device, instrument: instrument.into(), code: Some(code), message: message.into() }
    }

    pub fn timeout(instrument: impl Into<String>, what: &str, after: Duration) -> Self {
        Self::new(ErrorKind::Timeout, instrument, format!("no reply to {what} within {after:?}"))
    }

    pub fn usage(instrument: impl Into<String>, message: impl Into<String>) -> Self {
        Self::new(ErrorKind::Usage, instrument, message)
    }

    pub fn is_link(&self) -> bool {
        self.kind.is_link()
    }
}

/// Result of a driver call.
pub type Result<T, E = DriverError> = std::result::Result<T, E>;
