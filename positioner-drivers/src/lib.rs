//! The positioner controllers' drivers: each speaks one controller's protocol
//! behind [`survey_drivers::Positioner`], with the error kinds, clock and
//! reconnection of `survey-drivers`.
//!
//! - [`canopen`]: a CiA 402 drive over CAN (SocketCAN, or an SLCAN adapter on
//!   a serial line; an in-memory bus for tests), SDO, NMT, the correction table;
//! - [`modbus`]: a controller's register map over Modbus TCP or RTU;
//! - [`scpi`]: a SCPI controller over TCP or RS-232.
//!
//! The tracker's and the autocollimator's drivers (emScon, ELCOMAT) stay in
//! `survey-drivers` beside the traits.

pub mod canopen;
pub mod fuzz_targets;
pub mod modbus;
pub mod scpi;
