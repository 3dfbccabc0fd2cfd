//! Instrument driver traits for a positioner survey.
//!
//! One async trait per instrument ([`Positioner`], [`Tracker`],
//! [`Autocollimator`]), one error type ([`DriverError`]) whose [`ErrorKind`]
//! tells link faults from device faults and bad usage, and the [`Clock`] every
//! instrument and the survey engine share, so simulated instruments can run on
//! virtual time.
//!
//! The tracker's and the autocollimator's drivers ([`emscon`], [`elcomat`])
//! live here; the positioner controllers' (CANopen, Modbus, SCPI) are in
//! `survey-positioner-drivers`.

pub mod clock;
pub mod elcomat;
pub mod emscon;
pub mod error;
pub mod fuzz_targets;
pub mod reconnect;
pub mod stream;
pub mod traits;

pub use clock::{Clock, ScaledClock, SystemClock, VirtualClock};
pub use error::{DriverError, ErrorKind, Result};
pub use traits::*;
