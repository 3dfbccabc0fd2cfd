//! The four interpolation methods of the paper's Figure 6 and their comparison.
//!
//! Between the measured points some interpolation must estimate the error.
//! The paper compares (1) a fixed value between points, (2) linear, (3)
//! quadratic interpolation and (4) spectral resampling, by decimating a survey
//! by 2 and predicting the points left out. [`compare_interpolation`] does
//! exactly that; [`upsample`] gives the curves of Figure 6 (any factor).
//!
//! - **Fixed**: the nearest lower sample (a table read without interpolation).
//! - **Linear**: the straight line between the two neighbours.
//! - **Quadratic**: the 3-point Lagrange parabola through the three nearest
//!   samples (the node below, the node above, and whichever of the next two out
//!   is nearer; at exactly half way, the one below): at the midpoint the weights
//!   are `-1/8, 3/4, 3/8`.
//! - **Spectral**: band-limited resampling ([`Resampler::resample`]), exact for
//!   a signal whose lines are below half the sampling rate.
//!
//! All four treat the samples as one period over a full revolution.

use super::Resampler;
use serde::{Deserialize, Serialize};

/// An interpolation method of the paper's Figure 6.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// The nearest lower sample.
    Fixed,
    /// Linear between neighbours.
    Linear,
    /// 3-point Lagrange (quadratic).
    Quadratic,
    /// Spectral (band-limited) resampling.
    Spectral,
}

impl Method {
    /// The four methods, from the crudest to the best.
    pub const ALL: [Method; 4] = [Method::Fixed, Method::Linear, Method::Quadratic, Method::Spectral];

    /// The name used in files and reports (`fixed`, `linear`, `quadratic`, `spectral`).
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Fixed => "fixed",
            Method::Linear => "linear",
            Method::Quadratic => "quadratic",
            Method::Spectral => "spectral",
        }
    }
}

/// How well a method predicts the samples a decimation left out.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MethodScore {
    /// The method.
    pub method: Method,
    /// RMS of prediction minus measurement over the left-out samples, degrees.
    pub rms_deg: f64,
    /// Largest `|prediction - measurement|`, degrees.
    pub peak_deg: f64,
}

/// Why a comparison cannot be made.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CompareError {
    /// Decimating by 2 needs an even number of points around the revolution.
    #[error("the survey has {0} points; decimating by 2 needs an even count")]
    OddLength(usize),
    /// The quadratic method needs at least 3 points after decimation.
    #[error("the survey has {0} points; the comparison needs at least 6")]
    TooShort(usize),
}

/// `samples` (uniform over one revolution) interpolated to `factor` times as
/// many uniform points with `method`. Every `factor`-th output is the input
/// sample itself (for the spectral method, up to rounding).
pub fn upsample(method: Method, samples: &[f64], factor: usize, resampler: &mut Resampler) -> Vec<f64> {
    let n = samples.len();
    if n == 0 || factor == 0 {
        return vec![0.0; n * factor];
    }
    if method == Method::Spectral {
        return resampler.resample(samples, n * factor);
    }
    let at = |i: isize| samples[i.rem_euclid(n as isize) as usize];
    let mut out = Vec::with_capacity(n * factor);
    for j in 0..n as isize {
        for i in 0..factor {
            let t = i as f64 / factor as f64;
            let v = match method {
                Method::Fixed => at(j),
                Method::Linear => at(j) + (at(j + 1) - at(j)) * t,
                Method::Quadratic => {
                    let (c, u) = if t <= 0.5 { (j, t) } else { (j + 1, t - 1.0) };
                    let (wm, w0, wp) = (u * (u - 1.0) / 2.0, 1.0 - u * u, u * (u + 1.0) / 2.0);
                    wm * at(c - 1) + w0 * at(c) + wp * at(c + 1)
                }
                Method::Spectral => unreachable!("handled above"),
            };
            out.push(v);
        }
    }
    out
}

/// The paper's Figure 6 test: keep every other sample of `y_full` (uniform
/// over one revolution), predict the others with each method, and score the
/// predictions against the samples left out. Returned in [`Method::ALL`] order.
pub fn compare_interpolation(y_full: &[f64]) -> Result<Vec<MethodScore>, CompareError> {
    let n = y_full.len();
    if !n.is_multiple_of(2) {
        return Err(CompareError::OddLength(n));
    }
    if n < 6 {
        return Err(CompareError::TooShort(n));
    }
    let kept: Vec<f64> = y_full.iter().step_by(2).copied().collect();
    let mut rs = Resampler::new();
    Ok(Method::ALL
        .iter()
        .map(|&method| {
            let pred = upsample(method, &kept, 2, &mut rs);
            let (mut sum2, mut peak) = (0.0f64, 0.0f64);
            for j in (1..n).step_by(2) {
                let e = pred[j] - y_full[j];
                sum2 += e * e;
                peak = peak.max(e.abs());
            }
            MethodScore { method, rms_deg: (sum2 / (n / 2) as f64).sqrt(), peak_deg: peak }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The gear-pass part of the paper's Figure 4 positioner (12:1 pinion to
    /// its 5th harmonic, and the 2-cycle ellipticity), sampled at 720 points:
    /// every line is below 720/4, so the half survey still resolves it.
    fn fig4_like(n: usize) -> Vec<f64> {
        let lines = [
            (2.0, 0.002, 40.0),
            (12.0, 0.006, 15.0),
            (24.0, 0.003, 70.0),
            (36.0, 0.0018, 130.0),
            (48.0, 0.0012, 200.0),
            (60.0, 0.0008, 260.0),
            (150.0, 0.0002, 10.0),
        ];
        (0..n)
            .map(|j| {
                let t = 360.0 * j as f64 / n as f64;
                lines.iter().map(|(k, a, p): &(f64, f64, f64)| a * (k * t + p).to_radians().sin()).sum()
            })
            .collect()
    }

    #[test]
    fn spectral_beats_quadratic_beats_linear_beats_fixed() {
        let scores = compare_interpolation(&fig4_like(720)).unwrap();
        let names: Vec<Method> = scores.iter().map(|s| s.method).collect();
        assert_eq!(names, Method::ALL);
        let [fixed, linear, quadratic, spectral] = [scores[0], scores[1], scores[2], scores[3]];
        eprintln!("{scores:#?}");
        assert!(spectral.peak_deg < 1e-12, "{spectral:?}");
        assert!(spectral.rms_deg < quadratic.rms_deg && spectral.peak_deg < quadratic.peak_deg);
        assert!(quadratic.rms_deg < linear.rms_deg && quadratic.peak_deg < linear.peak_deg);
        assert!(linear.rms_deg < fixed.rms_deg && linear.peak_deg < fixed.peak_deg);
    }

    #[test]
    fn local_methods_pass_through_the_samples() {
        let y = fig4_like(64);
        let mut rs = Resampler::new();
        for method in Method::ALL {
            let up = upsample(method, &y, 4, &mut rs);
            assert_eq!(up.len(), 256);
            for (j, v) in y.iter().enumerate() {
                assert!((up[4 * j] - v).abs() < 1e-15, "{method:?} at {j}");
            }
        }
        // Quadratic is exact for a parabola (away from the wrap).
        let p: Vec<f64> = (0..16).map(|j| 0.5 * (j as f64).powi(2) - j as f64).collect();
        let up = upsample(Method::Quadratic, &p, 2, &mut rs);
        for j in 2..13 {
            let x = j as f64 + 0.5;
            assert!((up[2 * j + 1] - (0.5 * x * x - x)).abs() < 1e-12);
        }
        assert!(upsample(Method::Linear, &[], 3, &mut rs).is_empty());
    }

    #[test]
    fn bad_inputs_are_refused() {
        assert_eq!(compare_interpolation(&[0.0; 7]), Err(CompareError::OddLength(7)));
        assert_eq!(compare_interpolation(&[0.0; 4]), Err(CompareError::TooShort(4)));
    }
}
