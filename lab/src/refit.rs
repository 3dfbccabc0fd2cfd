//! The axis from the whole survey: after a tracker survey (and on `survey
//! process`), the axis is fitted again from every stored SMR position (the
//! points that located it before the runs and every sample's), and the actual
//! angles are recomputed from the raw readings around it
//! ([`survey_processing::geometry::refit_axis`]). The stored samples are not
//! changed (the originals are kept); what is processed is the recomputed
//! survey, and the refit is reported with it.
//!
//! Why: the dozen positions that locate the axis before the runs leave an
//! error in its centre, and every actual angle computed around a wrong centre
//! carries a once-per-revolution error that the table would then "correct"
//! into the positioner. The survey's thousands of positions know the centre
//! far better.
//!
//! One set of numbers: every command that states a survey's figures
//! (`stats`, `process`, `report`, the end of `run`) computes them from the
//! same samples, loaded by [`crate::load`] with [`crate::load::Axis::Refitted`]:
//! around the refitted axis when the survey has one (a tracker survey with SMR
//! positions), as stored otherwise, corrected for the drift when the survey
//! asked for it; and says which axis ([`AxisUsed`]: `"axis": "refitted" |
//! "located" | "none"` in their JSON). `survey process --located-axis` processes around the located axis
//! for comparison and says so.

use survey_acquire::ReferenceKind;
use survey_modelgap::ReferenceInfo;
use survey_processing::Sample;
use survey_processing::geometry::{AxisFit, Refit, refit_axis, refit_axis_with_angles};
use survey_processing::special::median;
use survey_processing::tracker_errors::TransverseMpe;
use survey_store::Store;
use survey_store::survey::{Setup, SurveyRecord};
use survey_tables::uncertainty::UncertaintyInputs;

/// The refit and what it changed, for the output.
#[derive(Debug, Clone, serde::Serialize)]
pub struct AxisRefit {
    /// SMR positions fitted (locate points and samples).
    pub points: usize,
    /// Positions left out as outliers.
    pub dropped: usize,
    /// The refitted circle's radius, mm.
    pub radius_mm: f64,
    /// How far the centre moved from the located one, in the plane, mm.
    pub center_shift_mm: f64,
    /// The once-per-revolution angle error the located centre carried, deg
    /// (`center_shift_mm / radius`): what the refit removed from the table.
    pub located_once_per_rev_deg: f64,
    /// Standard error of the refitted centre in its worst-known direction, mm.
    pub center_se_mm: f64,
    /// The once-per-revolution angle uncertainty left, deg (standard error;
    /// what the centre's uncertainty costs on a full circle).
    pub once_per_rev_se_deg: f64,
    /// The arc the SMR positions cover, deg (360 on a full circle).
    pub arc_deg: f64,
    /// What the centre's uncertainty costs over the measured arc, deg
    /// (standard error, its mean over the arc removed): how far the arc
    /// allows the axis to be known.
    pub over_arc_se_deg: f64,
    /// What the survey's SMRs say of the tracker's own error (the
    /// contract's `reference_error`).
    pub reference_error: ReferenceError,
    /// The axis's location and error motions (ISO 230-1, ISO 230-7:
    /// `survey_motions`), the contract's `error_motions`; `None` where the
    /// SMR positions do not give them. Put in the documents by their own key.
    #[serde(skip)]
    pub error_motions: Option<survey_motions::ErrorMotions>,
}

/// The tracker's own error as the survey's SMRs separated it from the
/// axis's (`survey_processing::smrs`): the contract's `reference_error`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ReferenceError {
    /// Whether it was measured (several SMRs over a full circle).
    pub separated: bool,
    /// `none`, `equal-division` or `separation`.
    pub method: &'static str,
    /// The SMRs measured at every target.
    pub smrs: usize,
    /// The orders of the tracker's error the SMRs separated, as they land on
    /// the first SMR's angles (taken out of the survey's angles).
    pub lines: Vec<ReferenceLine>,
    /// The standard uncertainty of what stays of the tracker's systematic
    /// error in the angles (rms over the circle), degrees: the budget's
    /// "reference instrument, systematic".
    pub u_deg: f64,
    /// In words.
    pub notes: Vec<String>,
}

/// One order of the tracker's separated error.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ReferenceLine {
    pub cycles_per_rev: f64,
    pub amplitude_deg: f64,
    pub phase_deg: f64,
}

/// Which axis a survey's actual angles were computed around.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AxisUsed {
    /// Fitted again from every SMR position of the survey.
    Refitted,
    /// Located before the runs (as stored).
    Located,
    /// No axis: an autocollimator, an import.
    None,
}

impl AxisUsed {
    /// The JSON word.
    pub fn as_str(self) -> &'static str {
        match self {
            AxisUsed::Refitted => "refitted",
            AxisUsed::Located => "located",
            AxisUsed::None => "none",
        }
    }

    /// The axis of `survey` analysed with `refit` (or without one).
    pub fn of(survey: &SurveyRecord, refit: Option<&AxisRefit>) -> Self {
        match (refit, &survey.axis) {
            (Some(_), _) => AxisUsed::Refitted,
            (None, Some(_)) => AxisUsed::Located,
            (None, None) => AxisUsed::None,
        }
    }

    /// One line for people: which angles the figures are of.
    pub fn text(self) -> &'static str {
        match self {
            AxisUsed::Refitted => "axis: refitted (actual angles around the axis fitted again from every SMR position)",
            AxisUsed::Located => "axis: located (actual angles as stored, around the axis located before the runs)",
            AxisUsed::None => "axis: none (the reference measures angles directly)",
        }
    }
}

/// The shift between two centres, in the plane of `fit`.
fn in_plane_shift(fit: &AxisFit, other: &AxisFit) -> f64 {
    let d: Vec<f64> = (0..3).map(|i| fit.center_mm[i] - other.center_mm[i]).collect();
    let h: f64 = (0..3).map(|i| d[i] * fit.normal[i]).sum();
    (0..3).map(|i| (d[i] - h * fit.normal[i]).powi(2)).sum::<f64>().sqrt()
}

/// The survey's samples with their actual angles recomputed around the axis
/// fitted from all its SMR positions, and the refit; `None` for a survey
/// without a located axis (an autocollimator survey, an import).
pub async fn refit_survey(store: &Store, survey: &SurveyRecord) -> anyhow::Result<Option<(Vec<Sample>, AxisRefit)>> {
    let Some(located) = &survey.axis else { return Ok(None) };
    let locate = store.locate_points(survey.id).await?;
    // The locate points first, then every sample's position.
    let (mut samples, smr) = store.samples_with_smr(survey.id, locate.iter().map(|(_, m)| m.xyz()).collect()).await?;
    let points = &smr.xyz_mm;
    if points.len() < 3 {
        return Ok(None);
    }
    // The readouts in the order of `points`, made anew for each pass: the
    // first samples' in order when each has a position (a tracker survey:
    // no index looked up a position), through the indices otherwise.
    let at_locate = || locate.iter().map(|(readout, _)| *readout);
    let fitted = match smr.dense() {
        Some(n) => refit_axis_with_angles(points, || at_locate().chain(samples[..n].iter().map(|s| s.readout_deg))),
        None => {
            refit_axis_with_angles(points, || at_locate().chain(smr.sample_indices().map(|i| samples[i].readout_deg)))
        }
    };
    let (Refit { fit, dropped, center_se_mm, once_per_rev_se_deg, arc_deg, over_arc_se_deg, .. }, raw) = fitted
        .map_err(|e| {
            anyhow::anyhow!("survey {}: the axis cannot be fitted again from its SMR positions: {e}", survey.id)
        })?;
    // The samples' positions follow the locate points in `raw`.
    let mut moved: Vec<(usize, f64)> = Vec::new();
    for (i, &raw) in smr.sample_indices().zip(&raw[locate.len()..]) {
        let s = &mut samples[i];
        let was = s.actual_deg;
        s.actual_deg = fit.angle_of_raw(raw, s.target_deg);
        moved.push((i, s.actual_deg - was));
    }
    // The first SMR's positions, one a sample in order (a tracker survey's case): no copy made.
    let indices: Option<Vec<usize>> = match smr.dense() {
        Some(n) if n == samples.len() => None,
        _ => Some(smr.sample_indices().collect()),
    };
    if indices.is_some() {
        into_the_refits_frame(&mut samples, &moved);
    }
    let (reference_error, others) = combine_smrs(store, survey, &mut samples).await?;
    let error_motions = motions_of(survey, &samples, indices.as_deref(), &points[locate.len()..], others.as_deref());
    let center_shift_mm = in_plane_shift(&fit, located);
    let refit = AxisRefit {
        points: smr.xyz_mm.len(),
        dropped,
        radius_mm: fit.radius_mm,
        center_shift_mm,
        located_once_per_rev_deg: (center_shift_mm / fit.radius_mm).to_degrees(),
        center_se_mm,
        once_per_rev_se_deg,
        arc_deg,
        over_arc_se_deg,
        reference_error,
        error_motions,
    };
    tracing::info!(survey = survey.id, ?refit, "axis fitted again from the survey's SMR positions");
    Ok(Some((samples, refit)))
}

/// A sample whose SMR position is gone keeps the angle it was stored with,
/// measured around the located axis from another zero: it is moved into the
/// refit's frame by what the refit moved the samples at its target (`moved`:
/// each refitted sample's index and change; the change is the two axes'
/// difference at that angle, the same in every run), their median, or over
/// the survey where no other sample has its target. Left as stored, it
/// stood 3-4e-3 deg off the others (the two zeros apart) and was either
/// named a gross reading or moved the table.
fn into_the_refits_frame(samples: &mut [Sample], moved: &[(usize, f64)]) {
    let key = |s: &Sample| (s.target_deg * 1e9).round() as i64;
    let mut at: std::collections::HashMap<i64, Vec<f64>> = std::collections::HashMap::new();
    let mut refitted = vec![false; samples.len()];
    for &(i, d) in moved {
        at.entry(key(&samples[i])).or_default().push(d);
        refitted[i] = true;
    }
    let mut all: Vec<f64> = moved.iter().map(|m| m.1).collect();
    if all.is_empty() {
        return;
    }
    let overall = median(&mut all);
    for (i, s) in samples.iter_mut().enumerate() {
        if !refitted[i] {
            s.actual_deg += at.get_mut(&key(s)).map_or(overall, |v| median(v));
        }
    }
}

/// The axis's location and error motions ([`survey_motions`]) from the
/// first SMR's positions `first` (those of the samples `indices`, or of
/// every sample in order when `None`) and, where every sample has them, the
/// other SMRs' (`others[k - 1][sample]`).
fn motions_of(
    survey: &SurveyRecord,
    samples: &[Sample],
    indices: Option<&[usize]>,
    first: &[[f64; 3]],
    others: Option<&[Vec<[f64; 3]>]>,
) -> Option<survey_motions::ErrorMotions> {
    let kept: std::borrow::Cow<'_, [Sample]> = match indices {
        None => std::borrow::Cow::Borrowed(samples),
        Some(ix) => std::borrow::Cow::Owned(ix.iter().map(|&i| samples[i]).collect()),
    };
    let mounts = survey.smrs();
    let mut tracks = vec![survey_motions::Track { mount: survey_processing::smrs::SmrMount::FIRST, points_mm: first }];
    let theirs: Vec<std::borrow::Cow<'_, [[f64; 3]]>> = match (others, indices) {
        (Some(o), None) => o.iter().map(|pts| std::borrow::Cow::Borrowed(pts.as_slice())).collect(),
        (Some(o), Some(ix)) => {
            o.iter().map(|pts| std::borrow::Cow::Owned(ix.iter().map(|&i| pts[i]).collect())).collect()
        }
        (None, _) => Vec::new(),
    };
    for (k, pts) in theirs.iter().enumerate() {
        if let Some(mount) = mounts.get(k + 1) {
            tracks.push(survey_motions::Track { mount: *mount, points_mm: pts });
        }
    }
    survey_motions::error_motions(&survey_motions::Input {
        samples: &kept,
        tracks,
        mpe: tracker_mpe(survey),
        frame: survey.machine_frame(),
    })
}

/// The other SMRs' positions (`[k - 1][sample]`), when every sample has them.
type OtherSmrs = Option<Vec<Vec<[f64; 3]>>>;

/// The samples' angles from every SMR of the survey (each located by its own
/// circle, the first's already in `samples`), combined and the tracker's
/// error separated ([`survey_processing::smrs::combine`]); with one SMR,
/// what the specification bounds. Also the other SMRs' positions, for the
/// error motions.
async fn combine_smrs(
    store: &Store,
    survey: &SurveyRecord,
    samples: &mut [Sample],
) -> anyhow::Result<(ReferenceError, OtherSmrs)> {
    let mounts = survey.smrs();
    let u_spec = reference_systematic_u_deg(survey).unwrap_or(0.0);
    let alone = |notes: Vec<String>| ReferenceError {
        separated: false,
        method: survey_processing::smrs::Method::None.as_str(),
        smrs: mounts.len(),
        lines: Vec::new(),
        u_deg: u_spec,
        notes,
    };
    if mounts.len() <= 1 {
        return Ok((alone(Vec::new()), None));
    }
    let n = samples.len();
    let others = store.other_smr_positions(survey.id).await?;
    let mut points: Vec<Vec<Option<[f64; 3]>>> = vec![vec![None; n]; mounts.len()];
    for (seq, k, xyz) in others {
        if let Some(slot) = points.get_mut(k).and_then(|p| p.get_mut(seq as usize)) {
            *slot = Some(xyz);
        }
    }
    let missing = (1..mounts.len()).map(|k| points[k].iter().filter(|p| p.is_none()).count()).sum::<usize>();
    if missing > 0 {
        return Ok((
            alone(vec![format!(
                "{missing} readings of the other SMRs are missing: the first SMR's angles alone are used, and the \
                 tracker's error is not separated"
            )]),
            None,
        ));
    }
    let readouts: Vec<f64> = samples.iter().map(|s| s.readout_deg).collect();
    let mut angles = vec![samples.iter().map(|s| s.actual_deg).collect::<Vec<f64>>()];
    let mut others = Vec::new();
    for (k, pts) in points.iter().enumerate().skip(1) {
        let xyz: Vec<[f64; 3]> = pts.iter().map(|p| p.expect("checked above")).collect();
        others.push(xyz.clone());
        let fit = survey_processing::geometry::fit_axis(&xyz, &readouts)
            .map_err(|e| anyhow::anyhow!("survey {}: SMR {} cannot be located: {e}", survey.id, k + 1))?;
        angles.push(xyz.iter().zip(samples.iter()).map(|(p, s)| fit.angle_deg(*p, s.target_deg)).collect());
    }
    let targets: Vec<f64> = samples.iter().map(|s| s.target_deg).collect();
    let phases: Vec<f64> = mounts.iter().map(|m| m.phase_deg).collect();
    let c = survey_processing::smrs::combine(&targets, &angles, &phases, u_spec);
    for (s, a) in samples.iter_mut().zip(&c.angles_deg) {
        s.actual_deg = *a;
    }
    let error = ReferenceError {
        separated: c.separated,
        method: c.method.as_str(),
        smrs: mounts.len(),
        lines: c
            .lines
            .iter()
            .map(|l| ReferenceLine {
                cycles_per_rev: l.cycles_per_rev,
                amplitude_deg: l.amplitude_deg,
                phase_deg: l.phase_deg,
            })
            .collect(),
        u_deg: c.u_deg,
        notes: c.notes,
    };
    Ok((error, Some(others)))
}

impl AxisRefit {
    /// The contract's `error_motions` (null where the positions give none).
    pub fn motions_json(&self) -> serde_json::Value {
        self.error_motions.as_ref().and_then(|m| serde_json::to_value(m).ok()).unwrap_or_default()
    }

    /// The error motions for people: the location, then one line a motion.
    pub fn motions_text(&self) -> String {
        let Some(m) = &self.error_motions else { return String::new() };
        let l = &m.location;
        let mut s = format!(
            "axis average line (ISO 230-1, tracker frame): X0 {:.3} mm, Y0 {:.3} mm, A0 {:.1} urad, B0 {:.1} urad (U = \
             {:.3} mm, {:.1} urad, k = 2)\n",
            l.x0_mm, l.y0_mm, l.a0_urad, l.b0_urad, l.u_xy_mm, l.u_ab_urad
        );
        if let Some(m) = &l.machine {
            let terms = match (m.u_xy_alignment_mm, m.u_ab_alignment_urad) {
                (Some(xy), Some(ab)) => format!(
                    ": the fit's {:.3} mm, {:.1} urad; the alignment's {xy:.3} mm, {ab:.1} urad",
                    m.u_xy_fit_mm, m.u_ab_fit_urad
                ),
                _ => ", the frame taken as stated".into(),
            };
            s += &format!(
                "axis average line (ISO 230-1, machine frame): X0 {:.3} mm, Y0 {:.3} mm (at the machine's z = 0), A0 \
                 {:.1} urad, B0 {:.1} urad (U = {:.3} mm, {:.1} urad, k = 2{terms})\n",
                m.x0_mm, m.y0_mm, m.a0_urad, m.b0_urad, m.u_xy_mm, m.u_ab_urad
            );
        }
        // Each figure with its unit, or "below the limit" (no number).
        let shown = |v: Option<f64>, unit: &str| {
            v.map(|v| format!("{v:.1} {unit}")).unwrap_or_else(|| "below the limit".into())
        };
        let mut line = |name: &str, unit: &str, b: &survey_motions::Block| {
            s += &format!(
                "error motion (ISO 230-7) {name}: total {}, synchronous {}, asynchronous {} (U = {:.1} {unit}, k = 2; \
                 detection limit {:.1} {unit})\n",
                shown(b.total, unit),
                shown(b.synchronous, unit),
                shown(b.asynchronous, unit),
                b.u,
                b.detection_limit
            );
        };
        line("radial", "um", &m.radial_um);
        line(&format!("axial at {:.0} mm", m.radius_mm), "um", &m.axial_um);
        if let Some(a) = &m.axial_on_axis_um {
            line("axial on the axis", "um", a);
        }
        if let Some(t) = &m.tilt_urad {
            let how = if t.method == "phases" { "at several phases" } else { "at two heights" };
            line(&format!("tilt ({} SMRs {how})", t.smrs), "urad", t);
        }
        if let Some(t) = &m.tilt_across_urad {
            line(&format!("tilt across, at 90 deg to the first SMR's radial direction ({} SMRs)", t.smrs), "urad", t);
        }
        s
    }

    /// Two lines for people.
    pub fn text(&self) -> String {
        let mut s = format!(
            "axis fitted again from {} SMR positions ({} left out): the centre moved {:.4} mm, a once-per-revolution \
             error of {:.6} deg removed; the centre is now known to {:.5} mm ({:.2e} deg once per revolution, 1 sigma)\n",
            self.points,
            self.dropped,
            self.center_shift_mm,
            self.located_once_per_rev_deg,
            self.center_se_mm,
            self.once_per_rev_se_deg
        );
        let e = &self.reference_error;
        if e.smrs > 1 {
            s += &format!(
                "{} SMRs ({}): the tracker's own error {}; what stays of it: {:.2e} deg (1 sigma)\n",
                e.smrs,
                e.method,
                if e.separated {
                    let orders: Vec<String> = e
                        .lines
                        .iter()
                        .take(6)
                        .map(|l| format!("{} cycles/rev {:.2e} deg", l.cycles_per_rev, l.amplitude_deg))
                        .collect();
                    format!(
                        "separated ({}{})",
                        if orders.is_empty() { "nothing significant".into() } else { orders.join(", ") },
                        if e.lines.len() > 6 { ", ..." } else { "" }
                    )
                } else {
                    "not separated".to_string()
                },
                e.u_deg
            );
            for note in &e.notes {
                s += note;
                s += "\n";
            }
        }
        if self.arc_deg < 359.0 {
            s += &format!(
                "the positions cover {:.1} deg of arc: over it the axis location costs {:.2e} deg (1 sigma), all this \
                 arc allows\n",
                self.arc_deg, self.over_arc_se_deg
            );
        }
        s
    }
}

/// How well the axis located before the runs is known: the same fit from
/// its dozen locate points alone, with their stated uncertainty (`None`
/// without a located axis or its points).
pub async fn located_axis_knowledge(store: &Store, survey: &SurveyRecord) -> anyhow::Result<Option<Refit>> {
    if survey.axis.is_none() {
        return Ok(None);
    }
    let locate = store.locate_points(survey.id).await?;
    if locate.len() < 4 {
        return Ok(None);
    }
    let points: Vec<[f64; 3]> = locate.iter().map(|(_, m)| m.xyz()).collect();
    let readouts: Vec<f64> = locate.iter().map(|(r, _)| *r).collect();
    Ok(refit_axis(&points, &readouts).ok())
}

/// What model-gap is told of the survey's reference: a tracker with the axis
/// fitted again (`refit`) or located before the runs (`located`), an
/// autocollimator, or unknown (an import).
pub fn reference_info(survey: &SurveyRecord, refit: Option<&AxisRefit>, located: Option<&Refit>) -> ReferenceInfo {
    if let Some(r) = refit {
        return ReferenceInfo::Tracker {
            radius_mm: r.radius_mm,
            points: r.points,
            axis_se_deg: r.over_arc_se_deg,
            refitted: true,
        };
    }
    if let Some(axis) = &survey.axis {
        return ReferenceInfo::Tracker {
            radius_mm: axis.radius_mm,
            points: axis.points,
            axis_se_deg: located.map_or(0.0, |l| l.over_arc_se_deg),
            refitted: false,
        };
    }
    match survey.reference() {
        Some(ReferenceKind::Autocollimator) => ReferenceInfo::Autocollimator,
        _ => ReferenceInfo::Unknown,
    }
}

/// What the uncertainty budget of a survey's table needs beyond its samples:
/// the reference instrument's stated standard uncertainty of one angle (as
/// the report's header states it: the configuration's `[certificate]`, or
/// the simulated bench's), and the once-per-revolution standard error of the
/// axis the angles were computed around over the measured arc (fitted again,
/// `refit`, or located before the runs, `located`).
pub fn uncertainty_inputs(
    survey: &SurveyRecord,
    refit: Option<&AxisRefit>,
    located: Option<&Refit>,
) -> UncertaintyInputs {
    let axis_u_deg = match (refit, located) {
        (Some(r), _) => Some(r.over_arc_se_deg),
        (None, Some(l)) => Some(l.over_arc_se_deg),
        (None, None) => None,
    };
    // With several SMRs, what stays of the tracker's error once they
    // separated it; with one, what its specification bounds.
    let systematic = match refit {
        Some(r) => Some(r.reference_error.u_deg),
        None => reference_systematic_u_deg(survey),
    };
    // Each angle is the mean of the SMRs' readings: its random part too.
    let smrs = survey.smrs().len() as f64;
    UncertaintyInputs {
        reference_u_deg: stated_reference_u_deg(survey).map(|u| u / smrs.sqrt()),
        reference_systematic_u_deg: systematic,
        axis_u_deg,
        drift_in_time_u_deg: None,
        wobble_u_deg: refit.and_then(wobble_u_deg),
    }
}

/// What the axis's radial error motion puts into the table's angles, as a
/// standard uncertainty, degrees: a translation of the axis moves an SMR
/// along its circle as much as across its radius (a whirl: the same
/// amplitude), the along part is read as angle, repeats in every run and is
/// corrected into the table as the positioner's (ISO 230-1 keeps E_C, the
/// angle, apart from E_XC and E_YC). Sized from the synchronous radial
/// motion measured (a sinusoid of half its peak-to-valley at the SMR's
/// radius: `A / sqrt 2`); `None` below the tracker's detection limit (the
/// reference's own systematic part bounds as much) and where SMRs at equal
/// spacing average the angles (a translation moves them in senses that
/// cancel: measured, docs/error-motions.md).
fn wobble_u_deg(refit: &AxisRefit) -> Option<f64> {
    if refit.reference_error.method == survey_processing::smrs::Method::EqualDivision.as_str() {
        return None;
    }
    let m = refit.error_motions.as_ref()?;
    let pv_um = m.radial_um.synchronous?;
    Some((0.5 * pv_um * 1e-3 / m.radius_mm).to_degrees() / std::f64::consts::SQRT_2)
}

/// The tracker reference's transverse MPE: the configuration's
/// `[certificate] reference_mpe_um` and `reference_mpe_um_per_m`, each
/// defaulting to the AT-class specification (the simulated tracker's).
pub fn tracker_mpe(survey: &SurveyRecord) -> TransverseMpe {
    let stated = match &survey.setup {
        Setup::Configured(c) => c.config.certificate.as_ref(),
        _ => None,
    };
    let at = TransverseMpe::AT_CLASS;
    TransverseMpe {
        constant_um: stated.and_then(|c| c.reference_mpe_um).unwrap_or(at.constant_um),
        per_m_um: stated.and_then(|c| c.reference_mpe_um_per_m).unwrap_or(at.per_m_um),
    }
}

/// The reference's systematic standard uncertainty at an angle of the
/// table, degrees: a tracker's from its MPE through the survey's geometry
/// (the located axis in the tracker's frame, over the plan's targets:
/// [`tracker_systematic_u_deg`]); an autocollimator's, what its polygon's
/// certificate states of each face ([`polygon_certificate_u_arcsec`]: each
/// target is read at one face, whose error repeats at every reading);
/// `None` for a tracker survey without a located axis (an import; a
/// verification, which measured around its calibration's axis, is given it
/// by [`crate::load`]).
pub fn reference_systematic_u_deg(survey: &SurveyRecord) -> Option<f64> {
    match survey.reference() {
        Some(ReferenceKind::Autocollimator) => Some(polygon_certificate_u_arcsec(survey) / 3600.0),
        _ => survey.axis.as_ref().map(|axis| tracker_systematic_u_deg(survey, axis)),
    }
}

/// A tracker's systematic standard uncertainty at an angle of `survey`'s
/// table measured around `axis` (its own located axis, or the one a
/// verification measured around: its calibration's), degrees: its MPE
/// through the geometry, over the plan's targets.
pub fn tracker_systematic_u_deg(survey: &SurveyRecord, axis: &AxisFit) -> f64 {
    let arc = match survey.setup.plan().map(|p| &p.targets_deg) {
        Some(t) if !t.is_empty() => {
            let lo = t.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let step = if t.len() > 1 { (hi - lo) / (t.len() - 1) as f64 } else { 0.0 };
            // A full circle's targets stop one step short of 360.
            if hi - lo + step >= 360.0 - 1e-6 { (0.0, 360.0) } else { (lo, hi) }
        }
        _ => (0.0, 360.0),
    };
    tracker_mpe(survey).systematic_angle_u_deg(axis, arc)
}

/// What an autocollimator survey's polygon certificate states of each
/// face, arcseconds (standard uncertainty): half the configuration's
/// `[polygon] certificate_u_arcsec` (the certificate's `U`, `k = 2`), else
/// the simulated polygon's ([`survey_sims::autocollimator::CERTIFICATE_U_ARCSEC`],
/// 0.1 arcsec, a calibrated polygon's typical `U = 0.2` arcsec). Systematic:
/// a face's error is the same at every reading of its target, so it is
/// never divided by their number. A polygon calibrated in place replaces it
/// with what the closure measured ([`crate::polygon`]).
pub fn polygon_certificate_u_arcsec(survey: &SurveyRecord) -> f64 {
    let stated = match &survey.setup {
        Setup::Configured(c) => c.config.polygon.as_ref().and_then(|p| p.certificate_u_arcsec),
        _ => None,
    };
    stated.map_or(survey_sims::autocollimator::CERTIFICATE_U_ARCSEC, |u| u / 2.0)
}

/// The reference instrument's stated standard uncertainty of one angle, as
/// the certificate states it when no flag overrides it: the configuration's
/// `[certificate] reference_uncertainty_deg`, else the simulated bench's own
/// ([`simulated_reference_u_deg`]); `None` for an imported survey.
pub fn stated_reference_u_deg(survey: &SurveyRecord) -> Option<f64> {
    match &survey.setup {
        Setup::Configured(c) => c.config.certificate.as_ref().and_then(|c| c.reference_uncertainty_deg),
        Setup::Simulated(s) => Some(simulated_reference_u_deg(s.reference)),
        _ => None,
    }
}

/// The standard uncertainty of one angle from a simulated reference (its
/// random part): the typical tracker's random error per coordinate at the
/// arm's centre distance, across the arm's radius; the autocollimator's
/// noise per reading (0.1 arcsec).
pub fn simulated_reference_u_deg(kind: ReferenceKind) -> f64 {
    match kind {
        ReferenceKind::Tracker => {
            let arm = survey_sims::tracker::ArmGeometry::default();
            let distance = arm.axis_center_mm.iter().map(|c| c * c).sum::<f64>().sqrt();
            (survey_sims::tracker::sigma_mm(distance) / arm.radius_mm).to_degrees()
        }
        ReferenceKind::Autocollimator => {
            survey_sims::autocollimator::AutocollimatorConfig::seeded(1, 0).noise_arcsec / 3600.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_simulated_tracker_states_its_random_part() {
        // 1.5 urad of each angle at 2.64 m = 3.96 um across 1000 mm: 2.3e-4 deg.
        let u = simulated_reference_u_deg(ReferenceKind::Tracker);
        assert!((u - 2.27e-4).abs() < 1e-6, "{u}");
        assert!((simulated_reference_u_deg(ReferenceKind::Autocollimator) - 0.1 / 3600.0).abs() < 1e-15);
    }

    /// A configured survey of the example polygon configuration, its
    /// `[polygon]` section given `extra` keys.
    fn polygon_survey(extra: &str) -> SurveyRecord {
        let text =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/config/scpi-elcomat.toml"))
                .unwrap()
                .replace("certificate_u_arcsec = 0.2", extra);
        let config = survey_store::config::SurveyConfig::parse(&text, "scpi-elcomat.toml").unwrap();
        let setup = survey_store::survey::ConfiguredSetup {
            config,
            plan: survey_plan::SurveyPlan::full_circle(24, 5, true).unwrap(),
        };
        let instruments = r#"{"positioner": "scpi-tcp 192.168.1.20:4000", "reference": "elcomat"}"#;
        let columns = survey_store::survey::StoredColumns::configured(1, &setup, instruments);
        SurveyRecord::parse(columns, "x.db").unwrap()
    }

    /// A real polygon's certificate states its own `U` (`[polygon]
    /// certificate_u_arcsec`, `k = 2`): half of it is the reference's
    /// systematic standard uncertainty; unstated, the typical 0.2 arcsec.
    #[test]
    fn a_configured_polygon_s_certificate_states_its_u() {
        let stated = polygon_survey("certificate_u_arcsec = 0.6");
        assert_eq!(stated.reference(), Some(ReferenceKind::Autocollimator));
        let u = reference_systematic_u_deg(&stated).unwrap();
        assert!((u * 3600.0 - 0.3).abs() < 1e-12, "{u}");
        let unstated = polygon_survey("");
        assert!((reference_systematic_u_deg(&unstated).unwrap() * 3600.0 - 0.1).abs() < 1e-12);
        let text =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/config/scpi-elcomat.toml"))
                .unwrap()
                .replace("certificate_u_arcsec = 0.2", "certificate_u_arcsec = 0");
        let e = survey_store::config::SurveyConfig::parse(&text, "c.toml").unwrap_err().to_string();
        assert!(e.contains("polygon.certificate_u_arcsec"), "{e}");
    }
}
