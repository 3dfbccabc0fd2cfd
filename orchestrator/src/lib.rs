//! The survey orchestrator: the engine that acquires a survey from the
//! instrument drivers, the SQLite store it writes to, and the `survey` CLI.
//!
//! Layers, from the roof down (a module only uses those below it):
//! `cli` (the command line) -> `conclude`, `verify`, `session`, `process`,
//! `report` (what the commands do) -> `bench` (the simulated or configured
//! instruments, set up) -> `engine` (acquisition) -> `store` (SQLite) and
//! `survey` (typed survey records) -> `config`, `plan`, `record`, `csvio`,
//! `output`, `error` -> the `survey-processing`, `survey-drivers` and
//! `survey-sims` crates.

pub mod bench;
pub mod cli;
pub mod conclude;
pub mod config;
pub mod csvio;
pub mod engine;
pub mod error;
pub mod output;
pub mod plan;
pub mod process;
pub mod record;
pub mod report;
pub mod session;
pub mod store;
pub mod survey;
pub mod verify;
