//! The acquisition core: the engine that locates the axis and measures a
//! plan on the instruments (step by step or in continuous passes),
//! surviving their faults, into a [`SampleSink`].
//!
//! This module is the core's one door: the commands, the bench, the
//! session, the verification and the tests use what it names here, never
//! its files. Inside, the settings (plain values: [`Timing`],
//! [`ReferenceKind`], settling) and the records ([`RecordedSample`], the
//! sink) are leaves the behaviour imports; the engine (`engine/`, with its
//! suspend, drift-control, reading and continuous-scan parts) and the
//! settling wait (`settle`) act on them. The pure arithmetic (plans, bounds,
//! pairing, drift) is `survey_processing`'s.

pub mod stop;

mod engine;
mod record;
mod settings;
mod settle;

pub use engine::{Engine, EngineError, FaultCounts, Outcome, PolygonStage, Progress, Reference, ScanReport};
pub use record::{MemorySink, RawReading, RecordedSample, SampleSink, ScanPassRecord};
pub use settings::{ReferenceKind, SettleMode, SettleModel, SettleSpec, Timing, default_window_deg};
pub use settle::SettleStats;
