//! Instrument driver traits for a positioner survey.
//!
//! One async trait per instrument ([`Positioner`], [`Tracker`],
//! [`Autocollimator`]), one error type ([`DriverError`]) whose [`ErrorKind`]
//! tells link faults from device faults and bad usage, and the [`Clock`] every
//! instrument and the survey engine share, so simulated instruments can run on
//! virtual time.

pub mod canopen;
pub mod clock;
pub mod elcomat;
pub mod emscon;
pub mod error;
pub mod fuzz_targets;
pub mod modbus;
pub mod reconnect;
pub mod scpi;
mod stream;
pub mod traits;

pub use clock::{Clock, ScaledClock, SystemClock, VirtualClock};
pub use error::{DriverError, ErrorKind, Result};
pub use traits::*;
