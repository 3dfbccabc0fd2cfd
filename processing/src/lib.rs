//! Pure processing for rotary-positioner surveys.
//!
//! Functions from data to data: no I/O, no clock, no async runtime, no database.
//! The simulators (`survey-sims`) and the orchestrator both build on it, so the
//! error model that generates simulated data is the same code that explains
//! measured data.

pub mod analysis;
pub mod budget;
pub mod correction;
pub mod corrector;
pub mod coverage;
pub mod drift;
pub mod errormap;
pub mod export;
pub mod geometry;
pub mod iso230;
pub mod lstsq;
pub mod model;
pub mod modelgap;
pub mod pairing;
pub mod pipeline;
pub mod plan;
pub mod recipe;
pub mod resample;
mod special;
pub mod spectrum;
pub mod table;
pub mod types;
pub mod uncertainty;
pub mod vdi3441;
pub mod verification;

pub use types::{Direction, Sample};
