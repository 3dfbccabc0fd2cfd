//! The survey orchestrator: the engine that acquires a survey from the
//! instrument drivers, the SQLite store it writes to, and the `survey` CLI.

pub mod cli;
pub mod commands;
pub mod config;
pub mod csvio;
pub mod engine;
pub mod instruments;
pub mod modelgap;
pub mod plan;
pub mod process;
pub mod record;
pub mod report;
pub mod run;
pub mod store;
