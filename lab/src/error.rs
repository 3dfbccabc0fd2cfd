//! What an error means for the user, decided in one place.
//!
//! Every layer returns [`anyhow::Error`]s that carry a typed cause. An error
//! is *bad input* (exit status 2: a flag, a file, a database or a survey id
//! the user gave is wrong, and nothing stored was changed) when a cause in its
//! chain is one of the input error types listed in [`is_bad_input`];
//! everything else is a *run-time failure* (exit status 1: an instrument, the
//! disk). The command line turns the error into the exit status with
//! [`exit_status`] and nowhere else.

use crate::csvio::CsvError;
use crate::overrides::FlagError;
use survey_modelgap::ModelGapError;
use survey_plan::PlanError;
use survey_processing::iso230::StatsError;
use survey_processing::model::ModelError;
use survey_store::NotFound;
use survey_store::config::ConfigError;
pub use survey_store::error::{BadInput, PathError, bad_input, path_error};
use survey_store::survey::Damaged;
use survey_tables::pipeline::PipelineError;
use survey_tables::recipe::{ChoiceError, RecipeError};

/// Whether the user's input caused `err`: some cause in its chain is an input
/// error ([`BadInput`], a usage error the command line found after parsing
/// ([`clap::Error`]), the store's [`NotFound`], a [`Damaged`] survey record,
/// a defect of a configuration, model, recipe or CSV file, a plan that cannot
/// be made, a path that cannot be used, an export choice that cannot be
/// honoured, data that cannot be processed, compared with a model or give
/// ISO 230-2 statistics).
pub fn is_bad_input(err: &anyhow::Error) -> bool {
    err.chain().any(|c| {
        c.is::<BadInput>()
            || c.is::<NotFound>()
            || c.is::<Damaged>()
            || c.is::<ConfigError>()
            || c.is::<CsvError>()
            || c.is::<ModelError>()
            || c.is::<RecipeError>()
            || c.is::<PlanError>()
            || c.downcast_ref::<PathError>().is_some_and(PathError::is_the_users)
            || c.is::<ChoiceError>()
            || c.is::<FlagError>()
            || c.is::<PipelineError>()
            || c.is::<ModelGapError>()
            || c.is::<StatsError>()
            || c.is::<clap::Error>()
    })
}

/// Not a failure: `survey run --check` made a full survey (the check found
/// a change, or the table in force no longer held, or the asset had no
/// calibration yet), so a new table is in force. Exit status [`RECALIBRATED`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("recalibrated: {0}")]
pub struct Recalibrated(pub String);

/// The exit status of `survey run --check` when it recalibrated.
pub const RECALIBRATED: u8 = 3;

/// The exit status of a failed command: 2 for bad input, 1 for a run-time
/// failure; [`RECALIBRATED`] (3) when a check recalibrated.
pub fn exit_status(err: &anyhow::Error) -> u8 {
    if err.chain().any(|c| c.is::<Recalibrated>()) {
        RECALIBRATED
    } else if is_bad_input(err) {
        2
    } else {
        1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use anyhow::Context as _;

    #[test]
    fn the_chain_decides() {
        let e = Err::<(), _>(NotFound("no survey with id 7".into())).context("reading").unwrap_err();
        assert_eq!(exit_status(&e), 2);
        assert_eq!(exit_status(&anyhow::anyhow!("the disk is full")), 1);
        assert_eq!(exit_status(&bad_input("--points N is required").context("survey run")), 2);
        let io = std::io::Error::from(std::io::ErrorKind::NotFound);
        assert_eq!(exit_status(&path_error(io, "cannot create out/t.csv".into())), 2);
        let io = std::io::Error::from(std::io::ErrorKind::StorageFull);
        assert_eq!(exit_status(&path_error(io, "cannot write out/t.csv".into())), 1);
        // A typed cause decides, under any context.
        let e = Err::<(), _>(StatsError::NoSamples).context("ISO 230-2 statistics").unwrap_err();
        assert_eq!((exit_status(&e), format!("{e:#}").matches("no samples").count()), (2, 1));
    }

    #[test]
    fn a_recalibration_is_status_3_whatever_its_context() {
        let e = anyhow::Error::from(Recalibrated("the 20 cycles/rev line grew".into())).context("survey run --check");
        assert_eq!(exit_status(&e), RECALIBRATED);
        assert_eq!(format!("{e:#}"), "survey run --check: recalibrated: the 20 cycles/rev line grew");
    }

    #[test]
    fn a_path_error_reads_as_before() {
        let io = std::io::Error::from(std::io::ErrorKind::NotFound);
        let e = path_error(io, "cannot create out/t.csv".into()).context("survey export");
        assert_eq!(format!("{e:#}"), "survey export: cannot create out/t.csv: entity not found");
    }
}
