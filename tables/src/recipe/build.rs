//! Building the table a recipe decided: the direction question, the spectral
//! path of a full circle and the fitted path of a partial range.

use super::direction::{DirectionModel, direction_model};
use super::{ApplyError, ChoiceError, Decisions, Directional, Recipe};
use crate::correction::{CorrectionError, TableBuilder};
use crate::true_angle;
use serde::Serialize;
use std::fmt;
use survey_processing::analysis::Analysis;
use survey_processing::errormap::{Coverage, Series};
use survey_processing::resample::{
    Complex64, PartialError, PartialMethod, Resampler, Series as Spectrum, Span, fit_partial,
};
use survey_processing::table::CorrectionTable;

/// The survey's hysteresis against its noise.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Hysteresis {
    /// `max |forward mean - reverse mean|` over the targets, degrees.
    pub max_deg: f64,
    /// Mean of `forward mean - reverse mean`, degrees (backlash shows here).
    pub mean_deg: f64,
    /// Standard deviation of one target's `forward mean - reverse mean` from
    /// noise alone: `sigma sqrt(2 / runs)`, `sigma` the noise of one sample of
    /// one direction (from the analysis' noise floor), degrees.
    pub noise_deg: f64,
    /// The recipe's `table.hysteresis_factor`.
    pub factor: f64,
    /// `max_deg > factor * noise_deg`.
    pub significant: bool,
}

impl Hysteresis {
    /// Why `table.directional = "auto"` chose its columns, the largest
    /// hysteresis written as `max` (here to five decimals of a degree; a
    /// certificate states it as it rounds its B: `survey_report`).
    pub fn auto_reason(&self, max: &str) -> String {
        let cmp = if self.significant { ">" } else { "<=" };
        format!(
            "hysteresis max {max} {cmp} {} x {:.2e} deg (its noise): {}",
            self.factor,
            self.noise_deg,
            if self.significant { "forward and reverse columns" } else { "one column" }
        )
    }

    /// The largest hysteresis as [`Hysteresis::auto_reason`] writes it by default.
    pub fn max_text(&self) -> String {
        format!("{:.5} deg", self.max_deg)
    }
}

/// The hysteresis of a bidirectional survey (`None` with one direction).
pub fn hysteresis(analysis: &Analysis, factor: f64) -> Option<Hysteresis> {
    let h = analysis.error_map.hysteresis_deg.as_ref()?;
    if h.is_empty() {
        return None;
    }
    let max_deg = h.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mean_deg = h.iter().sum::<f64>() / h.len() as f64;
    // The analysed series of a bidirectional survey averages the two
    // directions, halving the variance of the noise of one sample.
    let sigma = match analysis.series {
        Series::Bidirectional => analysis.noise.sample_sd_deg * std::f64::consts::SQRT_2,
        Series::Forward | Series::Reverse => analysis.noise.sample_sd_deg,
    };
    let noise_deg = sigma * (2.0 / analysis.runs.max(1) as f64).sqrt();
    Some(Hysteresis { max_deg, mean_deg, noise_deg, factor, significant: max_deg > factor * noise_deg })
}

/// How the table's rows were made.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum TableMethod {
    /// Spectral resampling of a full circle through `dense_points`.
    Spectral {
        /// The dense grid.
        dense_points: usize,
    },
    /// A fit over a partial range.
    Partial {
        /// The fit.
        fit: PartialMethod,
    },
}

impl fmt::Display for TableMethod {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TableMethod::Spectral { dense_points } => write!(f, "spectral resampling through {dense_points} points"),
            TableMethod::Partial { fit: PartialMethod::Cubic } => {
                f.write_str("cubic interpolation over the measured span")
            }
            TableMethod::Partial { fit: PartialMethod::LeastSquares { cycles, poly_degree } } => {
                let c: Vec<String> = cycles.iter().map(|c| format!("{c}")).collect();
                write!(
                    f,
                    "least squares over the measured span: degree-{poly_degree} polynomial + [{}] cycles/rev",
                    c.join(", ")
                )
            }
        }
    }
}

/// A correction table and how it was made.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BuiltTable {
    /// The table.
    #[serde(skip)]
    pub table: CorrectionTable,
    /// Whether it has forward and reverse columns.
    pub directional: bool,
    /// Why (or why not), in words.
    pub directional_reason: String,
    /// The survey's hysteresis (bidirectional surveys).
    pub hysteresis: Option<Hysteresis>,
    /// How the rows were made.
    pub method: TableMethod,
    /// The forward - reverse model of a full-circle directional table.
    pub direction_model: Option<DirectionModel>,
    /// Remarks.
    pub notes: Vec<String>,
}

/// `C_k exp(-i k t0)`: the series of samples taken from `t0` instead of 0.
fn rotate(series: Spectrum, start_deg: f64) -> Spectrum {
    if start_deg == 0.0 {
        return series;
    }
    let t = start_deg.to_radians();
    let coeffs =
        series.coeffs().iter().enumerate().map(|(k, c)| c * Complex64::from_polar(1.0, -(k as f64) * t)).collect();
    Spectrum::from_coeffs(coeffs)
}

fn subtract(col: &mut [f64], v: f64) {
    col.iter_mut().for_each(|x| *x -= v);
}

impl Recipe {
    /// Whether this survey's table is directional, why, and its hysteresis.
    pub fn directional_for(&self, analysis: &Analysis) -> (bool, String, Option<Hysteresis>) {
        let h = hysteresis(analysis, self.table.hysteresis_factor);
        let map = &analysis.error_map;
        let both = map.forward.is_some() && map.reverse.is_some();
        let (on, why) = match (self.table.directional, &h) {
            (Directional::Off, _) => (false, "table.directional = \"off\": one column for both directions".to_string()),
            (Directional::On, _) if both => (true, "table.directional = \"on\"".to_string()),
            (_, None) | (Directional::On, _) => {
                (false, "the survey measured one direction only: one column".to_string())
            }
            (Directional::Auto, Some(h)) => (h.significant, h.auto_reason(&h.max_text())),
        };
        (on, why, h)
    }

    /// Build the table `decisions` describe from `analysis`' error map.
    pub fn build_table(&self, analysis: &Analysis, decisions: &Decisions) -> Result<BuiltTable, ApplyError> {
        let (directional, directional_reason, hysteresis) = self.directional_for(analysis);
        let map = &analysis.error_map;
        let single = match analysis.series {
            Series::Forward => map.forward.as_ref().map(|d| &d.mean_deg),
            Series::Reverse => map.reverse.as_ref().map(|d| &d.mean_deg),
            Series::Bidirectional => map.bidirectional_mean_deg.as_ref(),
        }
        .or(map.forward.as_ref().map(|d| &d.mean_deg))
        .or(map.reverse.as_ref().map(|d| &d.mean_deg))
        .ok_or_else(|| ApplyError::Targets("the error map holds no direction".into()))?;
        let columns: Vec<&[f64]> = match (directional, &map.forward, &map.reverse) {
            (true, Some(f), Some(r)) => vec![&f.mean_deg, &r.mean_deg],
            _ => vec![single],
        };
        let rows = self.table.rows;
        let mut notes = Vec::new();
        let mut rs = Resampler::new();
        let model = match (map.coverage, columns.as_slice(), &hysteresis) {
            (Coverage::FullCircle { .. }, [f, r], Some(h)) => {
                // Not a note: it changes nothing the user should do (`direction_model` carries it).
                let (dm, half) = direction_model(f, r, h.noise_deg, analysis.noise.false_alarm_rate, &mut rs);
                let mean: Vec<f64> = f.iter().zip(r.iter()).map(|(a, b)| (a + b) / 2.0).collect();
                Some((dm, half, mean))
            }
            _ => None,
        };
        let (mut cols, method) = match map.coverage {
            Coverage::FullCircle { n } => {
                let dense = self.table.dense_points;
                if dense < n {
                    return Err(ChoiceError::new(
                        "table.dense_points",
                        format!("{dense} points is fewer than the survey's {n}"),
                    )
                    .into());
                }
                let mut builder = TableBuilder::new(dense, rows);
                let start = map.targets_deg[0];
                let targets: Vec<f64> = (0..n).map(|j| start + 360.0 * j as f64 / n as f64).collect();
                let edit = |m: &[f64]| Ok(rotate(builder.edited_series(m, &decisions.edit)?, start));
                let cols = match &model {
                    Some((dm, half, mean)) => {
                        let lines = true_angle::TrueLines::fit(mean, &targets, edit, rows, &mut rs)?;
                        let minus = Spectrum::from_coeffs(half.coeffs().iter().map(|c| -c).collect());
                        vec![
                            lines.column(Some(half), dm.mean_deg / 2.0, rows, &mut rs),
                            lines.column(Some(&minus), -dm.mean_deg / 2.0, rows, &mut rs),
                        ]
                    }
                    None => columns
                        .iter()
                        .map(|c| {
                            let edit = |m: &[f64]| Ok(rotate(builder.edited_series(m, &decisions.edit)?, start));
                            true_angle::full_circle_column(c, &targets, edit, rows, &mut rs)
                        })
                        .collect::<Result<Vec<_>, CorrectionError>>()?,
                };
                (cols, TableMethod::Spectral { dense_points: dense })
            }
            Coverage::Partial { start, end, .. } => {
                if !map.uniform_spacing {
                    return Err(ApplyError::Targets(
                        "the targets are not evenly spaced: a partial-range table needs uniform targets".into(),
                    ));
                }
                let span = Span { start_deg: start, end_deg: end };
                let fit = match &self.table.partial_method {
                    Some(m) => m.clone(),
                    None => {
                        let width = end - start;
                        let cycles: Vec<f64> =
                            decisions.kept_cycles.iter().copied().filter(|f| f * width / 360.0 >= 0.5).collect();
                        let ls = PartialMethod::LeastSquares { cycles, poly_degree: 3 };
                        match fit_partial(span, single, &ls) {
                            Ok(_) => ls,
                            Err(e @ (PartialError::Degenerate { .. } | PartialError::TooFewSamples { .. })) => {
                                notes.push(format!(
                                    "least squares at the kept lines is not possible ({e}): cubic interpolation instead"
                                ));
                                PartialMethod::Cubic
                            }
                            Err(e) => return Err(CorrectionError::from(e).into()),
                        }
                    }
                };
                let cols = columns
                    .iter()
                    .map(|c| true_angle::partial_column(span, c, &fit, rows).map_err(CorrectionError::from))
                    .collect::<Result<Vec<_>, CorrectionError>>()?;
                (cols, TableMethod::Partial { fit })
            }
        };
        if self.table.remove_mean {
            // The common mean: a directional table keeps its forward/reverse offset.
            let mean = cols.iter().map(|c| c.iter().sum::<f64>() / c.len() as f64).sum::<f64>() / cols.len() as f64;
            cols.iter_mut().for_each(|c| subtract(c, mean));
        }
        let table = if cols.len() == 2 {
            let r = cols.pop().expect("two columns");
            let f = cols.pop().expect("two columns");
            CorrectionTable::directional(f, r)
        } else {
            CorrectionTable::new(cols.pop().expect("one column"))
        }
        .map_err(CorrectionError::from)?;
        Ok(BuiltTable {
            directional: table.is_directional(),
            table,
            directional_reason,
            hysteresis,
            method,
            direction_model: model.map(|(dm, _, _)| dm),
            notes,
        })
    }
}
