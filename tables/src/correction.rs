//! Correction tables from a survey's error map, and the predicted accuracy
//! (the paper's section 4, "Final processing of the data").
//!
//! # The table
//!
//! The input is the repeatable part of the error (the mean over runs),
//! `error = readout - actual`, at `N` uniform angles `360 j / N` over a full
//! revolution. A survey stops the axis where the readout equals the target, so
//! the map is already indexed by the readout angle: exactly what the contract's
//! table stores (`corrected = readout - error(readout)`), and at the targets
//! its values need no change of variable. Between them, the processing's
//! tables (the recipe's, [`crate::recipe`]) take the kept lines as lines of
//! the TRUE angle, where a positioner's errors are sparse, and make the table
//! through the change of variable, so the products of the lines (`e e'`,
//! below any test's threshold, and dropped by a table that keeps only the
//! significant lines of the readout map) are in it (`true_angle`). The
//! [`TableBuilder`] here resamples a map as it is (the paper's method).
//!
//! [`TableBuilder`] (and the one-shot [`build_table`]) follow the paper: the map
//! is taken to the spectral domain ([`Resampler`]), the [`SpectralEdit`] is
//! applied on the dense grid of `dense` points (default 131072, the paper's
//! "128k": relocated lines must lie below `dense / 2`), and the result is
//! decimated to the table's `rows` (default 16384, the paper's dense hardware
//! table) by spectral truncation. Decimating the dense map by truncation is the
//! same as evaluating the edited series at the table rows, so the dense map is
//! only materialised when asked for ([`TableBuilder::dense_map`]); a test
//! checks the two agree to 1e-12. The decimation is a low-pass: a line at or
//! above `rows / 2` cannot be held by the table and is dropped rather than
//! aliased.
//!
//! Linear interpolation between rows (the contract's reading) loses at most
//! `A (2 pi k / rows)^2 / 8` on a line of amplitude `A` at `k` cycles: for the
//! paper's 648-cycle ring-gear harmonic (0.25 mdeg) at 16384 rows, 2 udeg.
//!
//! Partial-span axes (an elevation from -10 to 90 deg) are not periodic over
//! what was measured: [`build_partial_table`] fits them without that
//! assumption (see [`survey_processing::resample::PartialMethod`]).
//!
//! # The predicted accuracy
//!
//! [`predict_accuracy`] applies a table to measured samples: the corrected
//! error of a sample is `(readout - table.error_at(readout, direction)) - actual`.
//! Its figures, native and corrected:
//!
//! - `peak_deg` = `max |e - mean(e)|` over every sample (every run, both
//!   directions): the "+/-" figure of the paper's Figures 8 and 9 (+/-0.015 to
//!   +/-0.005 deg). The mean is a matter of zero reference and is removed.
//!   These are the contract's `native_peak_deg` and `corrected_peak_deg`.
//! - `rms_deg`: RMS of `e - mean(e)`.
//! - `iso230_a_deg`: ISO 230-2 accuracy `A` ([`survey_processing::iso230::iso230_2`]), when
//!   the samples allow it (at least two runs per target and direction). The
//!   corrected `A` uses the positioning deviation the corrected axis would show:
//!   driven until the *corrected* readout `c = readout - E(readout)` equals the
//!   target, its deviation is `actual - c`, so each sample's actual angle is
//!   replaced by `target + actual - c` (with `readout = target` at rest this is
//!   `actual + E(readout)`).
//!
//! The prediction is made on the survey's samples, at its targets: the table
//! was built from the same runs, so it has absorbed their mean noise and the
//! corrected figures are slightly optimistic (by a factor of about
//! `sqrt(1 - 1/runs)` on the noise). Between the targets the table may do
//! worse than at them: a line it does not carry, or one it carries at a bin
//! that may be the alias of its true frequency ([`left`]), peaks higher
//! there than the survey saw. [`Prediction::with_left`] makes the
//! contract's `corrected_peak_deg` a prediction of what a new survey of the
//! same plan with the table applied measures (what `survey run --verify`
//! checks), never better than the table can do: the in-sample peak, plus how
//! much higher what the table leaves peaks between the targets than at them
//! (under the least favourable hypothesis of its lines' true frequencies),
//! plus how much higher a new survey's peak of noise may be than this one's
//! (95 %). The in-sample figure stays beside it. The
//! repeatability floor (`floor_deg`, passed in: for example half the ISO 230-2
//! `R`, or the bidirectional repeatability when a single table is used) is
//! reported beside them: no correction can go below it, and the paper's
//! answer is to measure again with the correction applied.

use serde::Serialize;
use survey_processing::iso230::{TargetGroups, iso230_2_a_with_actual};
use survey_processing::resample::EditError;
use survey_processing::resample::{PartialError, PartialMethod, Resampler, Series, Span, SpectralEdit, fit_partial};
use survey_processing::table::{CorrectionTable, TableError};
use survey_processing::types::Sample;

#[cfg(test)]
mod truth_tests;

/// The paper's dense grid, "128k" points.
pub const DEFAULT_DENSE_POINTS: usize = 131_072;
/// The paper's dense hardware table, 16k rows.
pub const DEFAULT_TABLE_ROWS: usize = 16_384;

/// Why a table or a prediction cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CorrectionError {
    /// The error map has no points.
    #[error("the error map is empty")]
    EmptyMap,
    /// A point of the error map is NaN or infinite.
    #[error("error map point {index} is {value}, not a finite number")]
    NotFinite {
        /// Position in the map (from 0).
        index: usize,
        /// The value.
        value: f64,
    },
    /// The dense grid is coarser than the survey.
    #[error("the dense grid ({dense} points) is smaller than the error map ({points} points)")]
    DenseTooSmall {
        /// The dense grid size.
        dense: usize,
        /// The map's points.
        points: usize,
    },
    /// Forward and reverse maps differ in length.
    #[error("forward and reverse maps differ in length ({forward} vs {reverse})")]
    LengthMismatch {
        /// Forward map points.
        forward: usize,
        /// Reverse map points.
        reverse: usize,
    },
    /// The spectral edit does not fit the survey.
    #[error(transparent)]
    Edit(#[from] EditError),
    /// The table itself is invalid (too few rows).
    #[error(transparent)]
    Table(#[from] TableError),
    /// A partial-span map cannot be fitted.
    #[error(transparent)]
    Partial(#[from] PartialError),
    /// No samples to predict from.
    #[error("no samples to predict the accuracy from")]
    NoSamples,
    /// A sample's readout or actual angle is not finite.
    #[error("sample {index}: readout or actual angle is not a finite number")]
    BadSample {
        /// Position of the sample (from 0).
        index: usize,
    },
}

/// Builds correction tables, reusing its FFT plans and buffers across calls.
#[derive(Debug)]
pub struct TableBuilder {
    resampler: Resampler,
    series: Series,
    dense: usize,
    rows: usize,
}

impl Default for TableBuilder {
    /// [`DEFAULT_DENSE_POINTS`] and [`DEFAULT_TABLE_ROWS`].
    fn default() -> Self {
        Self::new(DEFAULT_DENSE_POINTS, DEFAULT_TABLE_ROWS)
    }
}

impl TableBuilder {
    /// A builder for tables of `rows` rows through a dense grid of `dense` points.
    pub fn new(dense: usize, rows: usize) -> Self {
        Self { resampler: Resampler::new(), series: Series::default(), dense, rows }
    }

    /// The dense grid size.
    pub fn dense(&self) -> usize {
        self.dense
    }

    /// The table size.
    pub fn rows(&self) -> usize {
        self.rows
    }

    fn prepare(&mut self, map: &[f64], edit: &SpectralEdit) -> Result<(), CorrectionError> {
        if map.is_empty() {
            return Err(CorrectionError::EmptyMap);
        }
        if let Some((index, &value)) = map.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(CorrectionError::NotFinite { index, value });
        }
        if self.dense < map.len() {
            return Err(CorrectionError::DenseTooSmall { dense: self.dense, points: map.len() });
        }
        self.resampler.analyze_into(map, &mut self.series);
        edit.apply(&mut self.series, map.len(), self.dense)?;
        Ok(())
    }

    /// The edited series of `map` (for reports: the lines the table carries).
    pub fn edited_series(&mut self, map: &[f64], edit: &SpectralEdit) -> Result<Series, CorrectionError> {
        self.prepare(map, edit)?;
        Ok(self.series.clone())
    }

    /// The edited map on the dense grid (`dense` points at `360 j / dense`).
    pub fn dense_map(&mut self, map: &[f64], edit: &SpectralEdit) -> Result<Vec<f64>, CorrectionError> {
        self.prepare(map, edit)?;
        let mut out = vec![0.0; self.dense];
        self.resampler.synthesize_into(&self.series, &mut out);
        Ok(out)
    }

    /// One table column: the edited map decimated to `rows` rows.
    pub fn column(&mut self, map: &[f64], edit: &SpectralEdit) -> Result<Vec<f64>, CorrectionError> {
        if self.rows < 2 {
            return Err(TableError::TooShort(self.rows).into());
        }
        self.prepare(map, edit)?;
        let mut out = vec![0.0; self.rows];
        self.resampler.synthesize_into(&self.series, &mut out);
        Ok(out)
    }

    /// A table with one column for both directions.
    pub fn build(&mut self, map: &[f64], edit: &SpectralEdit) -> Result<CorrectionTable, CorrectionError> {
        Ok(CorrectionTable::new(self.column(map, edit)?)?)
    }

    /// A direction-aware table from the forward and reverse maps (same length),
    /// the same edit applied to both.
    pub fn build_directional(
        &mut self,
        forward: &[f64],
        reverse: &[f64],
        edit: &SpectralEdit,
    ) -> Result<CorrectionTable, CorrectionError> {
        if forward.len() != reverse.len() {
            return Err(CorrectionError::LengthMismatch { forward: forward.len(), reverse: reverse.len() });
        }
        let f = self.column(forward, edit)?;
        let r = self.column(reverse, edit)?;
        Ok(CorrectionTable::directional(f, r)?)
    }
}

/// One-shot table from the mean error map (uniform over a full revolution,
/// indexed by readout): resample to `dense`, edit, decimate to `rows`.
/// Reuse a [`TableBuilder`] for repeated calls.
pub fn build_table(
    mean_error: &[f64],
    edit: &SpectralEdit,
    dense: usize,
    rows: usize,
) -> Result<CorrectionTable, CorrectionError> {
    TableBuilder::new(dense, rows).build(mean_error, edit)
}

/// One-shot direction-aware table from forward and reverse mean error maps.
pub fn build_directional_table(
    forward: &[f64],
    reverse: &[f64],
    edit: &SpectralEdit,
    dense: usize,
    rows: usize,
) -> Result<CorrectionTable, CorrectionError> {
    TableBuilder::new(dense, rows).build_directional(forward, reverse, edit)
}

/// A table for an axis measured over `span` only: `samples` uniform over the
/// span (both ends included) fitted with `method`, rows inside the span from
/// the fit, rows outside held at the nearer end ([`survey_processing::resample::PartialFit::column`]).
pub fn build_partial_table(
    span: Span,
    samples: &[f64],
    method: &PartialMethod,
    rows: usize,
) -> Result<CorrectionTable, CorrectionError> {
    let col = fit_partial(span, samples, method)?.column(rows)?;
    Ok(CorrectionTable::new(col)?)
}

/// The direction-aware variant of [`build_partial_table`].
pub fn build_partial_directional_table(
    span: Span,
    forward: &[f64],
    reverse: &[f64],
    method: &PartialMethod,
    rows: usize,
) -> Result<CorrectionTable, CorrectionError> {
    let f = fit_partial(span, forward, method)?.column(rows)?;
    let r = fit_partial(span, reverse, method)?.column(rows)?;
    Ok(CorrectionTable::directional(f, r)?)
}

/// Error figures of a set of samples (see the module documentation).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ErrorFigures {
    /// Mean error, degrees (the zero reference; removed from the others).
    pub mean_deg: f64,
    /// `max |e - mean|`, degrees: the "+/-" figure.
    pub peak_deg: f64,
    /// RMS of `e - mean`, degrees.
    pub rms_deg: f64,
    /// ISO 230-2 `A`, degrees, when the samples allow it.
    pub iso230_a_deg: Option<f64>,
}

/// The accuracy a table is predicted to give on measured samples.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Prediction {
    /// The contract's `native_peak_deg`: `max |e - mean|` without correction.
    pub native_peak_deg: f64,
    /// The contract's `corrected_peak_deg`: the same after correction, with
    /// what the table leaves between the targets ([`Prediction::with_left`]).
    pub corrected_peak_deg: f64,
    /// The corrected peak at the survey's own samples (the targets), degrees.
    pub in_sample_corrected_peak_deg: f64,
    /// How much higher what the table leaves peaks between the targets than
    /// at them, degrees (0 when it leaves nothing the survey saw).
    pub unseen_between_targets_deg: f64,
    /// How much higher the noise of a new survey of the same plan may peak
    /// than this one's did (95 %), degrees ([`Prediction::with_left`]).
    pub peak_spread_deg: f64,
    /// All native figures.
    pub native: ErrorFigures,
    /// All corrected figures.
    pub corrected: ErrorFigures,
    /// The repeatability floor passed in, degrees.
    pub floor_deg: f64,
    /// Number of samples used.
    pub samples: usize,
    /// What a drift in time that no straight line takes leaves in the
    /// survey's readings (the largest a pass keeps, degrees), when the
    /// survey measured one: the table carries it ([`Prediction::not_a_result`]).
    pub uncorrected_drift_deg: Option<f64>,
}

/// Why a table is not a result to load.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum NotAResult {
    /// The corrected axis is predicted no better than the native one.
    NoBetterThanNative,
    /// The survey drifted in time in a way it could not correct: the table
    /// carries the drift, whatever the prediction says.
    DriftNotCorrected,
}

/// The corrected error of each sample: `(readout - table.error_at(readout)) - actual`.
pub fn corrected_errors(samples: &[Sample], table: &CorrectionTable) -> Vec<f64> {
    samples.iter().map(|s| (s.readout_deg - table.error_at(s.readout_deg, s.direction)) - s.actual_deg).collect()
}

/// Report the native and corrected figures of `samples` beside the
/// repeatability floor `floor_deg` (see the module documentation),
/// `corrected` their corrected errors under the table
/// ([`corrected_errors`]) and `groups` their grouping by target
/// ([`TargetGroups::of`]), both made once for every figure of the table.
/// `native_iso230_a_deg` is the samples' own ISO 230-2 `A`
/// (`iso230_2(samples).ok().map(|s| s.a)`), which the caller has already.
pub fn predict_accuracy(
    samples: &[Sample],
    corrected: &[f64],
    groups: &TargetGroups,
    floor_deg: f64,
    native_iso230_a_deg: Option<f64>,
) -> Result<Prediction, CorrectionError> {
    let corrected_a = iso230_2_a_with_actual(samples, groups, |i| samples[i].target_deg - corrected[i]).ok();
    predict_accuracy_with_a(samples, corrected, floor_deg, native_iso230_a_deg, corrected_a)
}

/// [`predict_accuracy`] with the corrected samples' ISO 230-2 `A` made
/// already (by the caller, with the native figures: one walk of the groups
/// for both).
pub(crate) fn predict_accuracy_with_a(
    samples: &[Sample],
    corrected: &[f64],
    floor_deg: f64,
    native_iso230_a_deg: Option<f64>,
    corrected_a: Option<f64>,
) -> Result<Prediction, CorrectionError> {
    if samples.is_empty() {
        return Err(CorrectionError::NoSamples);
    }
    if let Some(index) = samples.iter().position(|s| !(s.readout_deg.is_finite() && s.actual_deg.is_finite())) {
        return Err(CorrectionError::BadSample { index });
    }
    let native = figures(samples.iter().map(Sample::error_deg), native_iso230_a_deg);
    let corrected = figures(corrected.iter().copied(), corrected_a);
    Ok(Prediction {
        native_peak_deg: native.peak_deg,
        corrected_peak_deg: corrected.peak_deg,
        in_sample_corrected_peak_deg: corrected.peak_deg,
        unseen_between_targets_deg: 0.0,
        peak_spread_deg: 0.0,
        native,
        corrected,
        floor_deg,
        samples: samples.len(),
        uncorrected_drift_deg: None,
    })
}

impl Prediction {
    /// Whether the corrected axis is predicted no better than the native one.
    pub fn no_better_than_native(&self) -> bool {
        self.corrected_peak_deg >= self.native_peak_deg
    }

    /// Why the table is not a result to load, if it is not: a drift the
    /// survey could not correct first (it is in every value), then a
    /// prediction no better than native.
    pub fn not_a_result(&self) -> Option<NotAResult> {
        if self.uncorrected_drift_deg.is_some() {
            Some(NotAResult::DriftNotCorrected)
        } else if self.no_better_than_native() {
            Some(NotAResult::NoBetterThanNative)
        } else {
            None
        }
    }
}

impl ErrorFigures {
    /// The figures of the errors `e` (readout - actual), with an ISO 230-2 `A` when known.
    pub fn of(e: &[f64], iso230_a_deg: Option<f64>) -> Self {
        figures(e.iter().copied(), iso230_a_deg)
    }
}

/// The noise of the corrected errors: their pooled standard deviation about
/// the mean of each target and direction (`None` with one run).
pub(crate) fn noise_sd(samples: &[Sample], corrected: &[f64], by_target: &TargetGroups) -> Option<f64> {
    // Each group (one target exactly, one direction) summed in the samples'
    // order, the groups then taken in the order of their keys (the target's
    // bits as a `u64`, then the direction: reverse first). The grouping by
    // target lists equal targets side by side in the samples' order (its
    // sort is stable): a group's samples are found by walking it, with no
    // map from a sample to its group. It lists the targets ascending, which
    // is the keys' order for the targets from +0.0 up, and the reverse of it
    // for the negative ones (their bits grow with their magnitude; they all
    // follow the positive ones): the groups from +0.0 up are folded as they
    // close, and the negative ones' terms, kept a target each, are added
    // after them in the reverse order. No list of every group is made (40
    // bytes a group at the processing's peak), and the sum has the same bits.
    let mut ss_positive = 0.0;
    let mut dof = 0usize;
    // Each negative target's terms, reverse then forward.
    let mut negative: Vec<[Option<f64>; 2]> = Vec::new();
    let mut open: [(f64, f64, usize); 2] = [(0.0, 0.0, 0); 2];
    let mut bits = None;
    let mut close = |bits: u64, open: &mut [(f64, f64, usize); 2]| {
        let terms = std::mem::take(open).map(|(s1, s2, n)| {
            (n > 0).then(|| {
                dof += n - 1;
                (s2 - s1 * s1 / n as f64).max(0.0)
            })
        });
        if bits >> 63 == 1 {
            negative.push(terms);
        } else {
            ss_positive = terms.into_iter().flatten().fold(ss_positive, |ss, t| ss + t);
        }
    };
    for i in by_target.iter().flatten().map(|&i| i as usize) {
        let (s, e) = (&samples[i], corrected[i]);
        let b = s.target_deg.to_bits();
        if let Some(previous) = bits.filter(|&p| p != b) {
            close(previous, &mut open);
        }
        bits = Some(b);
        let g = &mut open[usize::from(s.direction == survey_processing::types::Direction::Forward)];
        g.0 += e;
        g.1 += e * e;
        g.2 += 1;
    }
    if let Some(last) = bits {
        close(last, &mut open);
    }
    let ss = negative.iter().rev().flatten().flatten().fold(ss_positive, |ss, t| ss + t);
    (dof > 0).then(|| (ss / dof as f64).sqrt())
}

/// The figures of the errors `e` yields (walked three times: the mean, then
/// the peak and the RMS about it, with no vector of them kept).
fn figures(e: impl Iterator<Item = f64> + Clone, iso230_a_deg: Option<f64>) -> ErrorFigures {
    let n = e.clone().count() as f64;
    let mean = e.clone().sum::<f64>() / n;
    let peak = e.clone().map(|v| (v - mean).abs()).fold(0.0, f64::max);
    let rms = (e.map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    ErrorFigures { mean_deg: mean, peak_deg: peak, rms_deg: rms, iso230_a_deg }
}

#[cfg(test)]
mod tests {
    use super::*;
    use survey_processing::iso230::iso230_2;
    use survey_processing::resample::{Keep, Relocation, spectral_resample};
    use survey_processing::types::Direction;

    /// The pooled noise as it was first written: every group listed with its
    /// key, the list sorted by key, then summed.
    fn noise_sd_listed(samples: &[Sample], corrected: &[f64]) -> Option<f64> {
        type Group = ((u64, bool), (f64, f64, usize));
        let mut groups: Vec<Group> = Vec::new();
        let mut order: Vec<usize> = (0..samples.len()).collect();
        order.sort_by(|&a, &b| samples[a].target_deg.total_cmp(&samples[b].target_deg));
        for i in order {
            let key = (samples[i].target_deg.to_bits(), samples[i].direction == Direction::Forward);
            let e = corrected[i];
            match groups.iter_mut().find(|(k, _)| *k == key) {
                Some((_, g)) => *g = (g.0 + e, g.1 + e * e, g.2 + 1),
                None => groups.push((key, (e, e * e, 1))),
            }
        }
        groups.sort_unstable_by_key(|(key, _)| *key);
        let (ss, dof) = groups
            .iter()
            .fold((0.0, 0usize), |(ss, dof), (_, (s1, s2, n))| (ss + (s2 - s1 * s1 / *n as f64).max(0.0), dof + n - 1));
        (dof > 0).then(|| (ss / dof as f64).sqrt())
    }

    proptest::proptest! {
        /// Folding the groups as they close (the positive targets) and the
        /// negative ones after, in reverse, gives the bits of the sorted list.
        #[test]
        fn the_pooled_noise_folded_is_the_sorted_lists(
            picks in proptest::collection::vec((0usize..7, proptest::bool::ANY, -1e-3f64..1e-3), 1..80),
        ) {
            // Negative, signed-zero and positive targets, two of them within
            // the grouping's tolerance of each other but not equal.
            let targets = [-20.0, -5.0, -0.0, 0.0, 5.0, 5.0 + 1e-12, 40.0];
            let samples: Vec<Sample> = picks
                .iter()
                .enumerate()
                .map(|(k, &(t, forward, _))| Sample {
                    run: k as u32,
                    direction: if forward { Direction::Forward } else { Direction::Reverse },
                    target_deg: targets[t],
                    readout_deg: targets[t],
                    actual_deg: targets[t],
                    timestamp_s: None,
                })
                .collect();
            let corrected: Vec<f64> = picks.iter().map(|p| p.2).collect();
            let folded = noise_sd(&samples, &corrected, &TargetGroups::of(&samples));
            proptest::prop_assert_eq!(folded.map(f64::to_bits), noise_sd_listed(&samples, &corrected).map(f64::to_bits));
        }
    }

    fn map(n: usize, f: impl Fn(f64) -> f64) -> Vec<f64> {
        (0..n).map(|j| f(360.0 * j as f64 / n as f64)).collect()
    }

    fn band_limited(t: f64) -> f64 {
        let r = t.to_radians();
        0.001 + 0.006 * (12.0 * r + 0.3).sin() + 0.0015 * (216.0 * r).sin() + 0.0003 * (300.0 * r + 2.0).sin()
    }

    #[test]
    fn table_rows_are_the_map_resampled_and_the_dense_map_decimates_to_them() {
        let m = map(720, band_limited);
        let mut b = TableBuilder::new(8192, 2048);
        let t = b.build(&m, &SpectralEdit::none()).unwrap();
        assert_eq!(t.len(), 2048);
        for (j, v) in t.forward.iter().enumerate() {
            assert!((v - band_limited(t.readout_at(j))).abs() < 1e-12);
        }
        let dense = b.dense_map(&m, &SpectralEdit::none()).unwrap();
        let decimated = spectral_resample(&dense, 2048);
        let d = decimated.iter().zip(&t.forward).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(d < 1e-12, "{d:e}");
        // The sign: correcting a readout removes the error it carries.
        let r = t.readout_at(777);
        assert!((t.correct(r, Direction::Forward) - (r - band_limited(r))).abs() < 1e-12);
    }

    #[test]
    fn a_line_the_table_cannot_hold_is_dropped_not_aliased() {
        // 300 cycles into a 256-row table: removed; 12 cycles kept.
        let m = map(720, |t| 0.006 * (12.0 * t.to_radians()).sin() + 0.001 * (300.0 * t.to_radians()).sin());
        let t = build_table(&m, &SpectralEdit::none(), 4096, 256).unwrap();
        for (j, v) in t.forward.iter().enumerate() {
            assert!((v - 0.006 * (12.0 * t.readout_at(j).to_radians()).sin()).abs() < 1e-12);
        }
    }

    #[test]
    fn directional_tables_and_edits() {
        let f = map(360, |t| band_limited(t) + 0.002);
        let r = map(360, |t| band_limited(t) - 0.002);
        let edit = SpectralEdit { keep: Keep::Lines { cycles: vec![12] }, ..SpectralEdit::none() };
        let t = build_directional_table(&f, &r, &edit, 4096, 1024).unwrap();
        assert!(t.is_directional());
        let x: f64 = 10.0;
        let g = 0.006 * (12.0 * x.to_radians() + 0.3).sin();
        assert!((t.error_at(x, Direction::Forward) - (g + 0.003)).abs() < 1e-5);
        assert!((t.error_at(x, Direction::Reverse) - (g - 0.001)).abs() < 1e-5);
    }

    #[test]
    fn bad_inputs_are_named() {
        let m = map(720, band_limited);
        let none = SpectralEdit::none();
        assert_eq!(build_table(&[], &none, 1024, 64), Err(CorrectionError::EmptyMap));
        let mut nan = m.clone();
        nan[3] = f64::INFINITY;
        assert!(matches!(build_table(&nan, &none, 1024, 64), Err(CorrectionError::NotFinite { index: 3, .. })));
        assert_eq!(build_table(&m, &none, 512, 64), Err(CorrectionError::DenseTooSmall { dense: 512, points: 720 }));
        assert_eq!(build_table(&m, &none, 1024, 1), Err(CorrectionError::Table(TableError::TooShort(1))));
        assert!(matches!(
            build_directional_table(&m, &m[1..], &none, 1024, 64),
            Err(CorrectionError::LengthMismatch { .. })
        ));
        let reloc = SpectralEdit { relocate: vec![Relocation { observed_cycles: 72, true_cycles: 648 }], ..none };
        let e = build_table(&m, &reloc, 1024, 64).unwrap_err();
        assert!(matches!(e, CorrectionError::Edit(EditError::DenseTooSmall { .. })), "{e}");
        assert!(e.to_string().contains("1296"), "{e}");
    }

    #[test]
    fn partial_directional_tables_keep_both_columns() {
        let span = Span { start_deg: -10.0, end_deg: 90.0 };
        let f = |j: usize| 0.01 * (6.0 * (-10.0 + j as f64)).to_radians().sin();
        let fwd: Vec<f64> = (0..=100).map(|j| f(j) + 0.002).collect();
        let rev: Vec<f64> = (0..=100).map(|j| f(j) - 0.002).collect();
        let t = build_partial_directional_table(span, &fwd, &rev, &PartialMethod::Cubic, 3600).unwrap();
        for a in [-10.0, 0.0, 45.5, 90.0] {
            let d = t.error_at(a, Direction::Forward) - t.error_at(a, Direction::Reverse);
            assert!((d - 0.004).abs() < 1e-12, "{a}: {d}");
        }
        assert!(matches!(
            build_partial_directional_table(span, &fwd, &rev[..3], &PartialMethod::Cubic, 3600),
            Err(CorrectionError::Partial(PartialError::TooFewSamples { .. }))
        ));
    }

    fn samples_with(error: impl Fn(f64) -> f64, runs: u32) -> Vec<Sample> {
        let mut out = Vec::new();
        for run in 1..=runs {
            for direction in [Direction::Forward, Direction::Reverse] {
                for j in 0..36 {
                    let target = 10.0 * j as f64;
                    out.push(Sample {
                        run,
                        direction,
                        target_deg: target,
                        readout_deg: target,
                        actual_deg: target - error(target) + 1e-5 * (run as f64 - 1.5),
                        timestamp_s: None,
                    });
                }
            }
        }
        out
    }

    /// The samples' ISO 230-2 `A`, as the pipeline passes it.
    fn a_of(samples: &[Sample]) -> Option<f64> {
        iso230_2(samples).ok().map(|s| s.a)
    }

    /// [`predict_accuracy`] of `table` on `samples`, its inputs made as the pipeline makes them.
    fn predict(
        samples: &[Sample],
        table: &CorrectionTable,
        floor_deg: f64,
        a: Option<f64>,
    ) -> Result<Prediction, CorrectionError> {
        predict_accuracy(samples, &corrected_errors(samples, table), &TargetGroups::of(samples), floor_deg, a)
    }

    #[test]
    fn prediction_applies_the_table_with_the_contract_sign() {
        let e = |t: f64| 0.004 * (3.0 * t.to_radians()).sin() + 0.01;
        let samples = samples_with(e, 2);
        let table = CorrectionTable::new(map(36, e)).unwrap();
        let p = predict(&samples, &table, 1e-5, a_of(&samples)).unwrap();
        assert_eq!(p.samples, 144);
        assert!((p.native_peak_deg - 0.004).abs() < 1e-5, "{p:?}");
        assert!((p.native.mean_deg - 0.01).abs() < 1e-9);
        // The table holds the error exactly at the targets: only the +-5e-6
        // run scatter is left.
        assert!((p.corrected_peak_deg - 5e-6).abs() < 1e-12, "{p:?}");
        assert!(p.corrected.mean_deg.abs() < 1e-12);
        // ISO 230-2 A: native spans the sinusoid (2 * 0.004) plus the 2s bands;
        // corrected only the bands (s = 1e-5 / sqrt 2 per target).
        let s = 1e-5 / 2f64.sqrt();
        assert!((p.native.iso230_a_deg.unwrap() - (0.008 + 4.0 * s)).abs() < 1e-4);
        assert!((p.corrected.iso230_a_deg.unwrap() - 4.0 * s).abs() < 1e-9, "{p:?}");
        // A wrong sign would double the error instead.
        let wrong = CorrectionTable::new(map(36, |t| -e(t))).unwrap();
        assert!(predict(&samples, &wrong, 0.0, a_of(&samples)).unwrap().corrected_peak_deg > 0.007);
        // One run: no ISO figures, the rest stands.
        let one = predict(&samples_with(e, 1), &table, 0.0, a_of(&samples_with(e, 1))).unwrap();
        assert_eq!(one.native.iso230_a_deg, None);
        let json = serde_json::to_value(&p).unwrap();
        assert!(json["native_peak_deg"].is_f64() && json["corrected_peak_deg"].is_f64());
        assert_eq!(predict(&[], &table, 0.0, None), Err(CorrectionError::NoSamples));
    }
}
