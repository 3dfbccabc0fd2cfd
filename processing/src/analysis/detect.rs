//! Significance and repeatability of spectral lines: the statistics.
//!
//! See the documentation of [`crate::analysis`] for the tests these functions
//! implement.

use crate::spectrum::Phasor;
use serde::Serialize;

/// How the noise floor was estimated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NoiseMethod {
    /// Full circle, 2 runs or more: the run-to-run scatter of the complex
    /// spectrum, pooled over every bin strictly between 0 and N/2.
    SpectrumScatter,
    /// Full circle, one run: from the median power of the bins (lines are few,
    /// so the median bin is noise).
    SpectrumMedian,
    /// Partial range, 2 runs or more: the run-to-run scatter of the residuals of
    /// the per-run least-squares fits.
    ResidualScatter,
    /// Partial range, one run: the residual of the fit (it also holds any
    /// repeatable error the fit does not model, so the floor is conservative).
    Residual,
}

/// The noise floor of the spectral analysis, degrees.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NoiseFloor {
    /// How it was estimated.
    pub method: NoiseMethod,
    /// Standard deviation of each quadrature component (sine and cosine
    /// coefficient) of a line in ONE run's spectrum, from noise alone. For a
    /// partial range this is the median over the fitted frequencies (each line
    /// carries its own, for the mean, in [`super::Line::noise_sd_deg`]).
    pub line_sd_run_deg: f64,
    /// The same for the spectrum of the mean over runs: `line_sd_run_deg / sqrt(runs)`.
    pub line_sd_mean_deg: f64,
    /// Standard deviation of the non-repeatable part of one sample of the
    /// analysed series (for a full circle `line_sd_run_deg * sqrt(N / 2)`).
    /// Run-to-run offsets are not in it (they only move bin 0 / the fitted offset).
    pub sample_sd_deg: f64,
    /// Degrees of freedom of the estimate (`None` for the median estimate).
    pub dof: Option<usize>,
    /// The number of frequencies tested for a line.
    pub tests: usize,
    /// The expected number of false lines per spectrum the thresholds allow.
    pub false_alarm_rate: f64,
    /// A line is coherently significant when its amplitude in the mean spectrum
    /// exceeds this (for a partial range: at the typical frequency).
    pub coherent_threshold_deg: f64,
    /// A line is incoherently significant when the RMS over runs of its
    /// single-run amplitude exceeds this (`None` with one run).
    pub incoherent_threshold_deg: Option<f64>,
    /// The coherence a repeatable line needs.
    pub min_coherence: f64,
}

/// One frequency under test: its phasor in every run.
#[derive(Debug, Clone)]
pub(crate) struct Tested {
    pub runs: Vec<Phasor>,
    pub mean: Phasor,
    /// Standard deviation of each quadrature component of a single-run phasor.
    pub sd_run: f64,
    /// Whether the bin has one component only (Nyquist).
    pub one_dim: bool,
}

/// The verdict on one tested frequency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Verdict {
    pub coherent: bool,
    pub incoherent: bool,
    pub repeatable: bool,
    pub coherence: f64,
    pub run_rms_amplitude: f64,
    pub scatter: Option<f64>,
    pub sd_mean: f64,
}

/// Thresholds in units of a standard deviation, for a per-test false rate.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Thresholds {
    pub runs: usize,
    /// `|mean| > coh_2d * sd_mean` (two components).
    pub coh_2d: f64,
    /// `|mean| > coh_1d * sd_mean` (one component).
    pub coh_1d: f64,
    /// `sum_r |z_r|^2 / sd_run^2 > inc` (`2 runs` components).
    pub inc: Option<f64>,
    pub min_coherence: f64,
}

impl Thresholds {
    /// Thresholds for `tests` frequencies, `runs` runs, and `alpha` expected false
    /// lines per spectrum (split evenly between the coherent and the incoherent
    /// test when both are made). `dof` is the number of degrees of freedom of
    /// the noise estimate (`None`: taken as exact): the statistics are then
    /// F-distributed rather than chi-square, which matters at the far tail.
    pub fn new(tests: usize, runs: usize, alpha: f64, min_coherence: f64, dof: Option<usize>) -> Self {
        let per_test = if runs >= 2 { alpha / (2 * tests.max(1)) as f64 } else { alpha / tests.max(1) as f64 };
        let p = per_test.min(0.5);
        let d = dof.map(|d| d as f64);
        Thresholds {
            runs,
            coh_2d: (2.0 * f_even_isf(1, d, p)).sqrt(),
            coh_1d: normal_two_sided_isf(p),
            inc: (runs >= 2).then(|| 2.0 * runs as f64 * f_even_isf(runs, d, p)),
            min_coherence,
        }
    }

    pub fn judge(&self, t: &Tested) -> Verdict {
        let r = self.runs as f64;
        let sd_mean = t.sd_run / r.sqrt();
        let coherent = t.mean.amplitude_deg() > if t.one_dim { self.coh_1d } else { self.coh_2d } * sd_mean;
        let power: f64 = t.runs.iter().map(|z| z.norm_sqr()).sum();
        let incoherent = match self.inc {
            Some(x) if !t.one_dim => power / (t.sd_run * t.sd_run) > x,
            _ => false,
        };
        let coherence = if power > 0.0 { (r * t.mean.norm_sqr() / power).min(1.0) } else { 0.0 };
        let scatter = (self.runs >= 2).then(|| {
            let dims = if t.one_dim { 1.0 } else { 2.0 };
            let ss: f64 = t.runs.iter().map(|z| (*z - t.mean).norm_sqr()).sum();
            (ss / (dims * (r - 1.0))).sqrt()
        });
        Verdict {
            coherent,
            incoherent,
            repeatable: self.runs >= 2 && coherent && coherence >= self.min_coherence,
            coherence,
            run_rms_amplitude: (power / r).sqrt(),
            scatter,
            sd_mean,
        }
    }
}

/// The default coherence a repeatable line needs with `runs` runs: halfway
/// between the expected coherence of a line whose phase is random from run to
/// run (`1 / runs`) and that of a perfectly repeatable line (1).
pub fn default_min_coherence(runs: usize) -> f64 {
    (1.0 + 1.0 / runs.max(1) as f64) / 2.0
}

/// Survival function of `F = (chi2_{2m} / 2m) / (chi2_d / d)`, the ratio of a
/// chi-square with an even number `2m` of degrees of freedom to an independent
/// variance estimate with `d` degrees of freedom (`None`: the chi-square limit,
/// `P(chi2_{2m} > 2 m f)`). Closed form for even numerator degrees of freedom:
/// with `x = d / (d + 2 m f)`,
/// `P(F > f) = x^(d/2) sum_{j < m} [Gamma(d/2 + j) / (Gamma(d/2) j!)] (1 - x)^j`
/// (for `m = 1`: `(1 + 2f/d)^(-d/2)`), and
/// `P(chi2_{2m} > y) = e^(-y/2) sum_{j < m} (y/2)^j / j!`.
pub(crate) fn f_even_sf(m: usize, d: Option<f64>, f: f64) -> f64 {
    if f <= 0.0 {
        return 1.0;
    }
    let m = m.max(1);
    // Log of each term, summed by log-sum-exp to stay finite for large m and f.
    let (lead, logs): (f64, Vec<f64>) = match d {
        None => {
            let h = m as f64 * f;
            let logs = (0..m)
                .scan(0.0f64, |acc, j| {
                    if j > 0 {
                        *acc += h.ln() - (j as f64).ln();
                    }
                    Some(*acc)
                })
                .collect();
            (-h, logs)
        }
        Some(d) => {
            let x = d / (d + 2.0 * m as f64 * f);
            let logs = (0..m)
                .scan(0.0f64, |acc, j| {
                    if j > 0 {
                        *acc += (d / 2.0 + j as f64 - 1.0).ln() - (j as f64).ln() + (1.0 - x).ln();
                    }
                    Some(*acc)
                })
                .collect();
            (d / 2.0 * x.ln(), logs)
        }
    };
    let top = logs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let sum: f64 = logs.iter().map(|l| (l - top).exp()).sum();
    (lead + top + sum.ln()).exp().min(1.0)
}

/// The `f` with `f_even_sf(m, d, f) = p`.
pub(crate) fn f_even_isf(m: usize, d: Option<f64>, p: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 4.0f64);
    while f_even_sf(m, d, hi) > p && hi < 1e300 {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if f_even_sf(m, d, mid) > p { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

pub(crate) use crate::special::normal_two_sided_isf;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f_chi_square_and_normal_tails() {
        // Chi-square limit, 2 dof: exponential with mean 2 (F = chi2 / 2).
        assert!((f_even_sf(1, None, 1.5) - (-1.5f64).exp()).abs() < 1e-15);
        // Chi-square 4 dof at 4 (F = 1): e^-2 (1 + 2).
        assert!((f_even_sf(2, None, 1.0) - 3.0 * (-2.0f64).exp()).abs() < 1e-15);
        // Tabulated chi-square 10 dof, upper 1 % point 23.209 (F = 2.3209).
        assert!((10.0 * f_even_isf(5, None, 0.01) - 23.2093).abs() < 1e-3);
        // F(2, d): (1 + 2f/d)^(-d/2).
        assert!((f_even_sf(1, Some(10.0), 3.0) - 1.6f64.powf(-5.0)).abs() < 1e-15);
        // Tabulated F quantiles: F(2, 10) 5 % = 4.1028; F(4, 20) 1 % = 4.4307; F(10, 30) 5 % = 2.1646.
        assert!((f_even_isf(1, Some(10.0), 0.05) - 4.1028).abs() < 1e-3);
        assert!((f_even_isf(2, Some(20.0), 0.01) - 4.4307).abs() < 1e-3);
        assert!((f_even_isf(5, Some(30.0), 0.05) - 2.1646).abs() < 1e-3);
        // Large d tends to the chi-square limit.
        assert!((f_even_isf(3, Some(1e9), 1e-4) - f_even_isf(3, None, 1e-4)).abs() < 1e-5);
        // Far tails stay finite.
        assert!(f_even_sf(50, Some(1e6), 1e8) < 1e-300);
        // Two-sided normal: 5 % at 1.95996, 1 % at 2.57583.
        assert!((normal_two_sided_isf(0.05) - 1.959_964).abs() < 1e-5);
        assert!((normal_two_sided_isf(0.01) - 2.575_829).abs() < 1e-5);
        assert!(
            (crate::special::erfc(0.0) - 1.0).abs() < 1e-7 && (crate::special::erfc(-1.0) - 1.842_700_79).abs() < 1e-6
        );
    }

    #[test]
    fn thresholds_for_720_points() {
        // 360 tests, 5 runs, 0.01 false lines per spectrum: each test at 0.01/720.
        let t = Thresholds::new(360, 5, 0.01, default_min_coherence(5), None);
        assert!((t.coh_2d - (2.0 * (72_000.0f64).ln()).sqrt()).abs() < 1e-9);
        // An estimated floor (2872 dof, 720 points x 5 runs) raises it a little.
        let est = Thresholds::new(360, 5, 0.01, default_min_coherence(5), Some(2872));
        assert!(est.coh_2d > t.coh_2d && est.coh_2d < t.coh_2d * 1.01, "{} {}", est.coh_2d, t.coh_2d);
        assert!((default_min_coherence(5) - 0.6).abs() < 1e-15);
        let z = |a: f64, p: f64| Phasor::from_polar(a, p);
        // A steady line well above the noise: repeatable.
        let steady = Tested {
            runs: vec![z(1.0, 10.0), z(1.01, 11.0), z(0.99, 9.0)],
            mean: z(1.0, 10.0),
            sd_run: 0.01,
            one_dim: false,
        };
        let v = Thresholds::new(360, 3, 0.01, default_min_coherence(3), Some(1000)).judge(&steady);
        assert!(v.coherent && v.incoherent && v.repeatable && v.coherence > 0.99, "{v:?}");
        // Same amplitude, phases spread evenly: incoherent, not repeatable.
        let runs: Vec<Phasor> = (0..3).map(|r| z(1.0, 120.0 * r as f64)).collect();
        let random = Tested { mean: Phasor::mean(runs.iter().copied()), runs, sd_run: 0.01, one_dim: false };
        let v = Thresholds::new(360, 3, 0.01, default_min_coherence(3), Some(1000)).judge(&random);
        assert!(!v.coherent && v.incoherent && !v.repeatable && v.coherence < 1e-12, "{v:?}");
    }
}
