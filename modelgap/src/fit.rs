//! The joint least-squares fit of the effects model-gap has touched (added or
//! adjusted), with every other effect of the model held as it is.

use super::stats::least_squares;
use super::survey::Survey;
use survey_processing::model::{Effect, Model};
use survey_processing::spectrum::Phasor;

/// The outcome of a refit.
#[derive(Debug, Clone)]
pub(crate) struct Refit {
    /// The fitted constant (zero reference), degrees.
    pub offset_deg: f64,
    /// Per touched effect: the standard error of its amplitude (periodic: of
    /// each quadrature component), backlash or drift rate, at noise `sigma`.
    pub standard_error: Vec<f64>,
}

fn zeroed(e: &Effect) -> Effect {
    match e {
        Effect::Periodic { kind, cycles_per_rev, .. } => {
            Effect::Periodic { kind: *kind, cycles_per_rev: *cycles_per_rev, amplitude_deg: 0.0, phase_deg: 0.0 }
        }
        Effect::Backlash { .. } => Effect::Backlash { amplitude_deg: 0.0 },
        Effect::Drift { shape, .. } => Effect::Drift { rate_deg_per_run: 0.0, shape: *shape },
        Effect::Noise { sigma_deg } => Effect::Noise { sigma_deg: *sigma_deg },
    }
}

/// Fit `offset + sum over touched effects` to the data minus the untouched
/// effects, by least squares over every sample, and write the fitted values
/// into `model`. On an unresolvable column, returns the position (in
/// `touched`) of the effect that cannot be fitted and leaves `model` as it was.
pub(crate) fn refit(survey: &Survey, model: &mut Model, touched: &[usize], sigma: f64) -> Result<Refit, usize> {
    let mut base = model.clone();
    for &i in touched {
        base.effects[i] = zeroed(&base.effects[i]);
    }
    let rest = survey.predict(&base);
    let target: Vec<f64> = survey.ys().zip(&rest).map(|(y, p)| y - p).collect();
    let n = survey.len();
    let mut columns = vec![vec![1.0; n]];
    let mut owner = vec![usize::MAX];
    for (k, &i) in touched.iter().enumerate() {
        match &model.effects[i] {
            Effect::Periodic { cycles_per_rev, .. } => {
                let (s, c): (Vec<f64>, Vec<f64>) =
                    survey.angles().map(|a| (cycles_per_rev * a).to_radians().sin_cos()).unzip();
                columns.push(s);
                columns.push(c);
                owner.extend([k, k]);
            }
            Effect::Backlash { .. } => {
                columns.push((0..n).map(|j| survey.direction(j).sign() / 2.0).collect());
                owner.push(k);
            }
            Effect::Drift { shape, .. } => {
                columns.push((0..n).map(|j| shape.runs_at(survey.drift_time(j))).collect());
                owner.push(k);
            }
            Effect::Noise { .. } => unreachable!("noise is never fitted"),
        }
    }
    let columns: Vec<&[f64]> = columns.iter().map(Vec::as_slice).collect();
    let fit = least_squares(&columns, &target).map_err(|col| owner[col].min(touched.len().saturating_sub(1)))?;
    let mut standard_error = Vec::with_capacity(touched.len());
    let mut col = 1;
    for &i in touched {
        match &mut model.effects[i] {
            Effect::Periodic { amplitude_deg, phase_deg, .. } => {
                let z = Phasor { sin_deg: fit.coef[col], cos_deg: fit.coef[col + 1] };
                *amplitude_deg = z.amplitude_deg();
                *phase_deg = z.phase_deg();
                standard_error.push(sigma * (0.5 * (fit.unit_var[col] + fit.unit_var[col + 1])).sqrt());
                col += 2;
            }
            Effect::Backlash { amplitude_deg } => {
                *amplitude_deg = fit.coef[col];
                standard_error.push(sigma * fit.unit_var[col].sqrt());
                col += 1;
            }
            Effect::Drift { rate_deg_per_run, .. } => {
                *rate_deg_per_run = fit.coef[col];
                standard_error.push(sigma * fit.unit_var[col].sqrt());
                col += 1;
            }
            Effect::Noise { .. } => unreachable!("noise is never fitted"),
        }
    }
    Ok(Refit { offset_deg: fit.coef[0], standard_error })
}
