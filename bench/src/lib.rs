//! The bench a survey runs on: the engine with its instruments, its clock and
//! its plan, set up from the command line (the simulated bench), from a
//! configuration file (real instruments), or from a stored survey (resume).
//!
//! Everything here is checked before anything is stored: a [`Bench`] that
//! was built is one the survey can start on. Below the commands, above the
//! engine: nothing here prints or reads the command line.

pub mod inputs;
pub mod output;
pub mod session;
pub mod sim;

mod configured;
pub mod instruments;
mod simulated;

pub use configured::{PlanOverrides, configured_engine, configured_estimate, configured_plan};
pub use simulated::{DEFAULT_RUNS, SimulatedRequest, default_polygon_faces, simulated_engine};

use std::sync::Arc;
use std::time::Duration;
use survey_acquire::Engine;
use survey_drivers::Clock;
use survey_plan::SurveyPlan;
use survey_processing::model::Model;
use survey_sims::PlanProgress;
use survey_store::survey::{NewSurvey, Setup, SurveyRecord, SurveySource, SurveyStatus};

/// An engine ready to acquire a plan, and what the survey stores about it.
#[derive(Debug)]
pub struct Bench {
    /// The engine on the bench's instruments.
    pub engine: Engine,
    /// The clock the engine and the instruments share (virtual for the simulated bench).
    pub clock: Arc<dyn Clock>,
    /// What to measure.
    pub plan: SurveyPlan,
    /// How it was set up (stored with the survey).
    pub setup: Setup,
    /// The positioner model simulated (stored with the survey).
    pub model: Option<Model>,
    /// Simulated or instruments.
    pub source: SurveySource,
    /// The instruments described for people (`positioner`, `reference`, ...).
    pub instruments: serde_json::Value,
    /// The expected instrument time of the whole plan.
    pub estimate: Duration,
    /// The simulated positioner's drift clock (the simulated bench): the
    /// acquisition sets it to the next step of the plan before each step.
    pub plan_progress: Option<PlanProgress>,
}

impl Bench {
    /// What a new survey on this bench stores.
    pub fn new_survey(&self) -> NewSurvey {
        NewSurvey {
            status: SurveyStatus::Running,
            source: self.source.clone(),
            points: Some(self.plan.targets_deg.len() as u32),
            runs: Some(self.plan.runs),
            bidirectional: self.plan.bidirectional,
            setup: self.setup.clone(),
            model: self.model.clone(),
            instruments: self.instruments.clone(),
            verification: None,
            planned_samples: Some(self.plan.total_steps()),
            asset: self.setup.default_asset(),
            check_of: None,
        }
    }

    /// One line for people: `simulated fig8 positioner, simulated tracker`.
    pub fn describe(&self) -> String {
        let field = |k: &str| self.instruments.get(k).and_then(|v| v.as_str()).unwrap_or("?").to_string();
        format!("{} positioner, {} reference", field("positioner"), field("reference"))
    }

    /// The bench of a stored survey, to continue it at step `next_seq` from
    /// instrument time `resume_at` (drift goes on from where it stopped). The
    /// simulated instruments draw new noise rather than replaying the first
    /// steps'; the located axis is reused.
    pub fn resume(record: &SurveyRecord, resume_at: Duration, next_seq: u64) -> anyhow::Result<Bench> {
        let id = record.id;
        let mut bench = match &record.setup {
            Setup::Simulated(setup) => simulated::resume(setup, record.model.clone(), resume_at, next_seq)
                .map_err(|e| e.context(format!("survey {id}")))?,
            Setup::Configured(setup) => configured::resume(setup, resume_at),
            Setup::Imported { .. } => {
                return Err(survey_store::error::bad_input(format!(
                    "survey {id} was imported, not acquired: it cannot be resumed"
                )));
            }
            Setup::Unrecorded => {
                return Err(survey_store::error::bad_input(format!(
                    "survey {id} has no stored setup (plan and instruments): it cannot be resumed"
                )));
            }
        };
        bench.source = record.source.clone();
        if let Some(axis) = &record.axis {
            bench.engine = bench.engine.with_axis(axis.clone());
        }
        Ok(bench)
    }
}
