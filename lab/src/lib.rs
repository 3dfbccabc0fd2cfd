//! What the lab does with a stored survey: load it (`load`, around the axis
//! fitted again: `refit`, drift-corrected: `drift`), process it into its
//! files (`process`), resolve its doubts with check points (`resolving`),
//! conclude an acquisition (`conclude`), verify a table in closed loop
//! (`verify`), follow a positioner's life and its recalibration loop
//! (`life`), and the commands' documents (`documents`) and CSV (`csvio`).
//! What an error means for the exit status is decided here, once
//! ([`error::exit_status`]): this crate sits above every error type it names.
//!
//! Below: the bench and the session (`survey-bench`), the store
//! (`survey-store`), the pure processing. Above: the report, the lab's
//! pages and the command line.

pub mod conclude;
pub mod correction;
pub mod csvio;
pub mod documents;
pub mod drift;
pub mod environment;
pub mod error;
pub mod identify;
pub mod life;
pub mod load;
pub mod overrides;
pub mod polygon;
pub mod process;
pub mod refit;
pub mod resolving;
pub mod verify;
