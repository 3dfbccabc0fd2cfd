//! The simulated instruments of `survey-sims` as devices on a wire: each
//! server speaks the real protocol a driver of `survey-drivers` or
//! `survey-positioner-drivers` expects, over a real socket, a pty or an
//! in-memory CAN bus, in front of a simulated instrument.
//!
//! - [`modbus_server`]: a positioner controller's Modbus TCP/RTU register map;
//! - [`canopen_node`]: a CiA 402 drive on a CAN bus, and [`slcan_adapter`], a
//!   USB-CAN adapter speaking SLCAN on a pty;
//! - [`scpi_server`]: a SCPI positioner controller over TCP or a pty;
//! - [`emscon_server`]: a tracker's emScon TPI over TCP;
//! - [`elcomat_server`]: an ELCOMAT autocollimator on a pty;
//! - [`relay`]: a byte relay between driver and device that injects wire
//!   faults (drops, delays, garbling, disconnects), seeded;
//! - [`serve`]: `survey sim`, a whole bench served on its addresses.
//!
//! What the instruments measure, and their errors, are `survey-sims`'; these
//! modules only carry it on the wire as the instruments' documentation says.

#![warn(missing_docs)]

pub mod canopen_node;
pub mod elcomat_server;
pub mod emscon_server;
pub mod modbus_server;
pub mod relay;
pub mod scpi_server;
pub mod serve;
pub mod slcan_adapter;
