//! The survey orchestrator: the engine that acquires a survey from the
//! instrument drivers, the SQLite store it writes to, and the `survey` CLI.

pub mod record;
