//! The one way a command loads a stored survey: its record, its samples as
//! the compact `Vec<Sample>` (read once), its drift points, and as the
//! command asks, the actual angles of a tracker survey recomputed around the
//! axis fitted again from every SMR position ([`crate::refit`]) or how well
//! the axis located before the runs is known. The drift correction is
//! applied when the samples are read for analysis ([`Loaded::analysed`]),
//! borrowing them when the survey asked for none, and never written back.

use crate::polygon::{PolygonClosure, close_polygon};
use crate::refit::{AxisRefit, AxisUsed, ReferenceError, located_axis_knowledge, refit_survey};
use std::borrow::Cow;
use std::path::Path;
use survey_modelgap::ReferenceInfo;
use survey_plan::drift::DriftPoint;
use survey_processing::Sample;
use survey_processing::geometry::{AxisFit, Refit};
use survey_store::Store;
use survey_store::survey::{SurveyRecord, SurveyRef};
use survey_tables::gross::{self, GrossTest};
use survey_tables::timedrift::{self, TimeDrift};
use survey_tables::uncertainty::UncertaintyInputs;

/// Around which axis a tracker survey's actual angles are taken, and what a
/// command learns of it. Every command that states a survey's figures uses
/// [`Axis::Refitted`] (one set of numbers); `--located-axis` asks for
/// [`Axis::Located`] to compare.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    /// As stored, around the axis located before the runs, with how well it
    /// is known ([`Loaded::located`]).
    Located,
    /// Around the axis fitted again from every SMR position, when the survey
    /// has a located axis ([`Loaded::refit`]); otherwise as [`Axis::Located`].
    Refitted,
}

/// A stored survey, loaded for a command.
#[derive(Debug)]
pub struct Loaded {
    /// The survey.
    pub survey: SurveyRecord,
    /// Its samples in acquisition order: as stored, or around the refitted
    /// axis when `refit` is some. As measured: see [`Loaded::analysed`].
    pub samples: Vec<Sample>,
    /// The axis fitted again, when the samples are around it.
    pub refit: Option<AxisRefit>,
    /// How well the axis located before the runs is known (with
    /// [`Axis::Located`], or [`Axis::Refitted`] when there was no refit); a
    /// verification's, its calibration's (the axis it measured around).
    pub located: Option<Refit>,
    /// The drift-control reference measurements.
    pub drift: Vec<DriftPoint>,
    /// The check points measured between the targets, when the survey has
    /// them ([`crate::resolving`]).
    pub checks: Vec<Sample>,
    /// The polygon calibrated in place, when the survey turned it
    /// ([`crate::polygon`]): the samples are then corrected to its measured
    /// faces.
    pub polygon: Option<PolygonClosure>,
    /// Gross readings found in the drift-corrected samples
    /// ([`survey_tables::gross`]): those replaced are left out of
    /// [`Loaded::analysed`].
    pub gross: GrossTest,
    /// A drift in time measured from the same targets read at different
    /// times ([`survey_tables::timedrift`]), when the survey tells one
    /// and drift control did not correct it: corrected in
    /// [`Loaded::analysed`] when significant.
    pub time_drift: Option<TimeDrift>,
    /// The axis a verification's angles were measured around when it
    /// located none of its own: its calibration's. The tracker's
    /// systematic part of its `U` is reckoned through that geometry.
    pub reference_axis: Option<AxisFit>,
}

impl Loaded {
    /// The samples the statistics and the processing use: [`Loaded::samples`]
    /// corrected for the drift when the survey asked for it.
    pub fn analysed(&self) -> Cow<'_, [Sample]> {
        self.corrected(&self.samples)
    }

    /// `samples` of this survey (the refitted ones a command made itself)
    /// corrected for the drift when the survey asked for it.
    pub fn corrected<'a>(&self, samples: &'a [Sample]) -> Cow<'a, [Sample]> {
        let mut drifted = crate::drift::for_analysis(&self.survey, samples, &self.drift);
        if let Some(d) = self.time_drift.as_ref().filter(|d| d.corrected) {
            drifted = Cow::Owned(timedrift::corrected(&drifted, d));
        }
        if self.gross.readings.iter().any(|g| g.replaced) && samples.len() == self.samples.len() {
            Cow::Owned(gross::without(&drifted, &self.gross))
        } else {
            drifted
        }
    }

    /// Check points `checks` of this survey (on its clock) corrected for the
    /// drift in time the survey measured, as its samples are.
    pub fn checks_corrected(&self, checks: &[Sample]) -> Vec<Sample> {
        match self.time_drift.as_ref().filter(|d| d.corrected) {
            Some(d) => timedrift::corrected(checks, d),
            None => checks.to_vec(),
        }
    }

    /// What a drift in time that no straight line takes left in the
    /// readings (the largest a pass keeps, degrees), when the survey
    /// measured one beyond doubt ([`TimeDrift::left_beyond_doubt`]): no
    /// correction took it.
    pub fn uncorrected_drift_deg(&self) -> Option<f64> {
        self.time_drift.as_ref().filter(|d| d.left_beyond_doubt).map(|d| d.left_deg)
    }

    /// Which axis the samples are around, as the output says it.
    pub fn axis_used(&self) -> AxisUsed {
        AxisUsed::of(&self.survey, self.refit.as_ref())
    }

    /// What model-gap is told of the survey's reference.
    pub fn reference_info(&self) -> ReferenceInfo {
        crate::refit::reference_info(&self.survey, self.refit.as_ref(), self.located.as_ref())
    }

    /// What the table's uncertainty budget needs beyond the samples.
    pub fn uncertainty_inputs(&self) -> UncertaintyInputs {
        let mut inputs = crate::refit::uncertainty_inputs(&self.survey, self.refit.as_ref(), self.located.as_ref());
        self.complete_reference(&mut inputs);
        inputs
    }

    /// `inputs` given what the survey's reference leaves that the record
    /// alone does not say: the faces of a polygon calibrated in place, or
    /// the tracker's systematic part through the axis a verification
    /// measured around; and what the drift in time's measured slope leaves
    /// in the table.
    pub fn complete_reference(&self, inputs: &mut UncertaintyInputs) {
        if let Some(p) = &self.polygon {
            inputs.reference_systematic_u_deg = Some(p.u_deg);
        } else if let (None, Some(axis)) = (inputs.reference_systematic_u_deg, &self.reference_axis) {
            inputs.reference_systematic_u_deg = Some(crate::refit::tracker_systematic_u_deg(&self.survey, axis));
        }
        inputs.drift_in_time_u_deg = self.time_drift.as_ref().map(|d| d.table_u_deg(&self.samples));
    }

    /// What the survey says of its reference's own error (the contract's
    /// `reference_error`): its SMRs' when its axis was fitted again; for a
    /// verification measured around its calibration's axis, what the
    /// tracker's specification bounds, not separated.
    pub fn reference_error(&self) -> Option<ReferenceError> {
        if let Some(r) = &self.refit {
            return Some(r.reference_error.clone());
        }
        let axis = self.reference_axis.as_ref()?;
        Some(ReferenceError {
            separated: false,
            method: survey_processing::smrs::Method::None.as_str(),
            smrs: self.survey.smrs().len().max(1),
            lines: Vec::new(),
            u_deg: crate::refit::tracker_systematic_u_deg(&self.survey, axis),
            notes: vec![format!(
                "a verification, measured around the axis of survey {} with the same tracker: its error is not \
                 separated, what its specification bounds stays in U",
                self.survey.verification.as_ref().map_or(0, |v| v.verifies_survey)
            )],
        })
    }
}

/// Load survey `id` (an id or a uid; the latest when `None`) from `store`,
/// its actual angles taken around `axis`.
pub async fn load(store: &Store, id: Option<SurveyRef>, axis: Axis) -> anyhow::Result<Loaded> {
    // Counted here, as its samples are read (not walked twice).
    let mut survey = store.resolve_uncounted(id).await?;
    let refitted = match axis {
        Axis::Refitted => refit_survey(store, &survey).await?,
        Axis::Located => None,
    };
    let (samples, refit) = match refitted {
        Some((samples, refit)) => (samples, Some(refit)),
        None => (store.samples(survey.id).await?, None),
    };
    let mut samples = samples;
    let polygon = close_polygon(store, &survey, &mut samples).await?;
    survey.sample_count = samples.len() as u64;
    // A verification locates no axis: it measures around its calibration's,
    // located before the calibration's runs, and carries what is known of it.
    let calibration = match (&survey.axis, &survey.verification, survey.reference()) {
        (None, Some(v), Some(survey_acquire::ReferenceKind::Tracker)) => store.survey(v.verifies_survey).await.ok(),
        _ => None,
    };
    let located = match (&refit, &calibration) {
        (Some(_), _) => None,
        (None, Some(c)) => located_axis_knowledge(store, c).await?,
        (None, None) => located_axis_knowledge(store, &survey).await?,
    };
    let reference_axis = calibration.and_then(|c| c.axis);
    let drift = store.drift_points(survey.id).await?;
    let checks = store.check_points(survey.id).await?;
    let controlled = crate::drift::for_analysis(&survey, &samples, &drift);
    // Drift control's own correction, when it made one, is the survey's.
    // A polygon turned between runs: each turn reads its own faces and
    // the stage's own error at every target, and the stage lands each run
    // a little differently; none of it is a drift, which is told between
    // runs at the same turn only, against that landing.
    let time_drift = match (&controlled, &polygon) {
        (Cow::Borrowed(_), None) => timedrift::estimate(&samples),
        (Cow::Borrowed(_), Some(p)) => timedrift::estimate_between_placements(&samples, &p.turns_of(&samples)),
        (Cow::Owned(_), _) => None,
    };
    let in_time = match time_drift.as_ref().filter(|d| d.corrected) {
        Some(d) => Cow::Owned(timedrift::corrected(&controlled, d)),
        None => controlled,
    };
    let gross = gross::find(&in_time, gross::ALPHA);
    for note in gross.notes() {
        tracing::info!(survey = survey.id, "{note}");
    }
    Ok(Loaded { survey, samples, refit, located, drift, checks, polygon, gross, time_drift, reference_axis })
}

/// [`load`] from the database at `db`, opened read-only and closed again:
/// what a command that only reads does.
pub async fn load_read_only(db: &Path, id: Option<SurveyRef>, axis: Axis) -> anyhow::Result<Loaded> {
    let store = Store::open_read_only(db).await?;
    let loaded = load(&store, id, axis).await;
    store.close().await;
    loaded
}

#[cfg(test)]
mod tests {
    use super::*;
    use survey_plan::drift::DriftMeasurement;
    use survey_processing::Direction;
    use survey_store::survey::{NewSurvey, Setup, SurveySource, SurveyStatus};

    fn samples() -> Vec<Sample> {
        (0..8)
            .map(|k| Sample {
                run: 1 + k / 4,
                direction: if k % 4 < 2 { Direction::Forward } else { Direction::Reverse },
                target_deg: f64::from(k % 2) * 180.0,
                readout_deg: f64::from(k % 2) * 180.0,
                actual_deg: f64::from(k % 2) * 180.0 - 1e-3,
                timestamp_s: Some(f64::from(k) * 10.0),
            })
            .collect()
    }

    #[tokio::test]
    async fn a_survey_loads_once_with_its_drift_and_is_analysed_without_a_copy_when_no_correction_is_asked() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("s.db");
        let store = Store::open(&db).await.unwrap();
        let new = NewSurvey {
            status: SurveyStatus::Imported,
            source: SurveySource::Import { file: "s.csv".into() },
            setup: Setup::Imported { file: "s.csv".into() },
            ..NewSurvey::default()
        };
        let id = store.import(&new, &samples()).await.unwrap();
        let m = |before_seq, at_s, actual_deg| DriftMeasurement {
            before_seq,
            at_s,
            reference_deg: 0.0,
            readout_deg: 0.0,
            actual_deg,
        };
        store.add_drift_measurement(id, &m(0, 0.0, 0.0)).await.unwrap();
        store.add_drift_measurement(id, &m(8, 80.0, -0.002)).await.unwrap();
        store.close().await;

        for axis in [Axis::Located, Axis::Refitted] {
            let loaded = load_read_only(&db, None, axis).await.unwrap();
            assert_eq!((loaded.survey.id, loaded.samples.as_slice()), (id, samples().as_slice()), "{axis:?}");
            assert_eq!(loaded.drift.len(), 2, "{axis:?}");
            assert_eq!(loaded.survey.sample_count, 8, "counted as read: {axis:?}");
            // An import has no axis, and asks for no drift correction.
            assert!(loaded.refit.is_none() && loaded.located.is_none(), "{axis:?}");
            assert_eq!(loaded.axis_used(), AxisUsed::None, "{axis:?}");
            assert!(loaded.checks.is_empty(), "{axis:?}");
            assert!(matches!(loaded.analysed(), Cow::Borrowed(s) if s == loaded.samples.as_slice()), "{axis:?}");
        }
        let e = load_read_only(&db, Some((id + 1).into()), Axis::Located).await.unwrap_err();
        assert!(survey_store::is_not_found(&e), "{e:#}");
    }
}
