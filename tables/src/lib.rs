//! A survey's correction table, from its analysis to its verdict: pure
//! functions from data to data (no I/O, no clock, no runtime), built on the
//! analysis of `survey-processing` and writing the controller formats of
//! `survey-controllers`.
//!
//! - [`recipe`]: every processing choice, replayable (its `[export]` section
//!   is the controllers crate's).
//! - [`correction`]: tables plain, directional and partial-range from an
//!   error map; the predicted accuracy.
//! - [`true_angle`]: the kept lines as lines of the true angle.
//! - [`left`]: what the table leaves that the survey saw; [`resolve`]: check
//!   points between the targets, and which hypothesis of a line they decide;
//!   [`left::folds`]: lines the design does not name folded onto a bin the
//!   table holds, in doubt until check points measure them.
//! - [`pipeline`]: the whole processing of one survey (what `survey process`
//!   and the end of `survey run` compute).
//! - [`uncertainty`]: the table's uncertainty budget.
//! - [`verification`]: a verification's figures and its verdict.
//! - [`gross`]: gross readings, found and left out before anything is
//!   computed; [`timedrift`]: the drift in time of the same targets read at
//!   different times; [`closure`]: a polygon turned between runs, calibrated
//!   in place. Leaves: they use only `survey-processing`.
//!
//! The modules form one way (no circle): `correction` at the bottom;
//! `true_angle` and `verification` on it; `recipe` on `correction` and
//! `true_angle`; `left` on `recipe` and `verification`; `resolve` on `left`;
//! `pipeline` on all of these; `uncertainty` on `pipeline` (ARCHITECTURE.md's
//! module graphs).

pub mod closure;
pub mod correction;
pub mod gross;
pub mod left;
pub mod pipeline;
pub mod recipe;
pub mod resolve;
pub mod timedrift;
pub mod true_angle;
pub mod uncertainty;
pub mod verification;

#[cfg(test)]
mod mechanisms_tests;
