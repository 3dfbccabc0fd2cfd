//! Spectra of error curves in cycles per revolution, and least-squares fits of
//! sinusoids at chosen frequencies.
//!
//! # Convention
//!
//! Amplitudes and phases are degrees in the contract's convention: a component
//! `a * sin(k * theta + phi)` (theta the axis angle) is the [`Phasor`]
//! `z = a * e^(i phi) = s + i c`, with `s = a cos(phi)` the coefficient of
//! `sin(k theta)` and `c = a sin(phi)` that of `cos(k theta)`. Phases are
//! absolute, referred to theta = 0, whatever angle the samples start at; they
//! are reported in `[0, 360)`.
//!
//! # Full circle ([`Spectrum::full_circle`])
//!
//! `N` samples `y_j` at `theta_j = start + j * 360 / N` (any `N >= 3`; `realfft`
//! plans mixed-radix and Bluestein transforms, so 720 or 1801 points cost no more
//! than a power of two). With `X_k = sum_j y_j e^(-2 pi i j k / N)` (the forward
//! transform of `realfft`/`rustfft`), bin `k` in `1 ..< N/2` is
//! `z_k = (2 i X_k / N) * e^(-i k start)`: a component at exactly `k` cycles
//! appears at bin `k` with its amplitude and phase, exactly (to rounding), and
//! contributes nothing to any other bin.
//!
//! Two bins cannot carry a phase, and are reported in a canonical form:
//! - `k = 0` (the mean `m`): `a sin(0 theta + phi)` is the constant `a sin(phi)`,
//!   so only the product is known. Bin 0 is amplitude `|m|` with phase 90 deg
//!   (`m >= 0`) or 270 deg (`m < 0`), i.e. `s = 0, c = m`.
//! - `k = N/2` (Nyquist, `N` even): `sin(N/2 theta_j + phi)` alternates in sign,
//!   so the samples only see `a sin(N/2 start + phi)`; the part of the component
//!   in quadrature with the sample grid is invisible (`sin(N/2 theta)` with
//!   `start = 0` is zero at every sample). The bin holds the smallest sinusoid
//!   that reproduces the samples: with `start = 0`, amplitude `|a sin(phi)|` and
//!   phase 90 or 270 deg.
//!
//! # Partial range ([`Spectrum::span`], [`fit_sinusoids`])
//!
//! An axis that does not turn a full revolution (an elevation axis from -10 to
//! 90 deg) has no periodic error curve to transform. [`Spectrum::span`] treats the
//! `N` samples at spacing `step` as one period of length `span = N * step` (for
//! -10..90 at 0.5 deg: 201 samples, span 100.5 deg) and reports bin `k` at
//! `k * 360 / span` cycles per revolution. This is for display only: a 6:1 gear
//! pass makes 6 * 100.5 / 360 = 1.675 cycles per span, which falls between bins
//! (bins are 3.58 cycles/rev apart here), so its energy leaks into neighbouring
//! bins and its bin amplitude is low by the scalloping loss (up to about 36 %
//! with no window, 15 % with Hann, and less predictable within a few bins of 0,
//! where the line's mirror image at negative frequency overlaps it) and its
//! phase is not meaningful. The window choice:
//! [`Window::Rectangular`] (no window) is exact for components with a whole
//! number of cycles per span and leaks most otherwise, with sidelobes falling as
//! `1/distance`; [`Window::Hann`] (periodic, `0.5 - 0.5 cos(2 pi j / N)`,
//! amplitudes divided by its coherent gain 0.5) widens each line to 3 bins but
//! its sidelobes fall as `1/distance^3`, so the jump between the two ends of the
//! span does not spread over the whole spectrum. The mean is removed before
//! windowing and reported in bin 0.
//!
//! Named lines of a partial range are therefore not read from this spectrum:
//! [`fit_sinusoids`] fits `offset + sum_f (s_f sin(f theta) + c_f cos(f theta))`
//! at the design frequencies `f` (any real number of cycles per revolution, any
//! sample angles) by linear least squares, solved by Householder QR (no normal
//! equations: columns such as 1 and 2 cycles/rev over a 100 deg span are nearly
//! collinear with the constant, and forming `A^T A` would square that condition
//! number). It also gives `(A^T A)^-1` for the uncertainty of each amplitude. On a
//! uniform full circle with integer frequencies the fit and the DFT agree.
//!
//! Looked up: the `realfft` 3.5 API on docs.rs (`RealFftPlanner::plan_fft_forward`,
//! `RealToComplex::process` overwrites its input, output of `N/2 + 1` bins for
//! odd and even `N`); the transform sign is `rustfft`'s forward `e^(-2 pi i jk/N)`,
//! which the tests below check through the phase convention.

use crate::lstsq::Qr;
use crate::types::wrap_360;
use realfft::RealFftPlanner;
use serde::{Deserialize, Serialize};
use std::fmt;

/// A sinusoid `sin_deg * sin(k theta) + cos_deg * cos(k theta)`, that is
/// `amplitude * sin(k theta + phase)`. See the module documentation.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Phasor {
    /// Coefficient of `sin(k theta)`, degrees (`amplitude * cos(phase)`).
    pub sin_deg: f64,
    /// Coefficient of `cos(k theta)`, degrees (`amplitude * sin(phase)`).
    pub cos_deg: f64,
}

impl Phasor {
    /// The phasor of `amplitude_deg * sin(k theta + phase_deg)`.
    pub fn from_polar(amplitude_deg: f64, phase_deg: f64) -> Self {
        let (sin, cos) = phase_deg.to_radians().sin_cos();
        Phasor { sin_deg: amplitude_deg * cos, cos_deg: amplitude_deg * sin }
    }

    /// Amplitude, degrees.
    pub fn amplitude_deg(self) -> f64 {
        self.sin_deg.hypot(self.cos_deg)
    }

    /// Phase in `[0, 360)` degrees (0 for a zero phasor).
    pub fn phase_deg(self) -> f64 {
        wrap_360(self.cos_deg.atan2(self.sin_deg).to_degrees())
    }

    /// Squared amplitude.
    pub fn norm_sqr(self) -> f64 {
        self.sin_deg * self.sin_deg + self.cos_deg * self.cos_deg
    }

    /// The phasor with its phase advanced by `deg`.
    pub fn rotate_deg(self, deg: f64) -> Self {
        let (sn, cs) = deg.to_radians().sin_cos();
        Phasor { sin_deg: self.sin_deg * cs - self.cos_deg * sn, cos_deg: self.sin_deg * sn + self.cos_deg * cs }
    }

    /// The value of the sinusoid at `cycles_per_rev` and axis angle `theta_deg`.
    pub fn value_at(self, cycles_per_rev: f64, theta_deg: f64) -> f64 {
        let (sn, cs) = (cycles_per_rev * theta_deg).to_radians().sin_cos();
        self.sin_deg * sn + self.cos_deg * cs
    }

    /// The mean of phasors (zero for none).
    pub fn mean(items: impl IntoIterator<Item = Phasor>) -> Phasor {
        let (mut sum, mut n) = (Phasor::default(), 0usize);
        for p in items {
            sum = sum + p;
            n += 1;
        }
        if n == 0 { sum } else { sum * (1.0 / n as f64) }
    }
}

impl std::ops::Add for Phasor {
    type Output = Phasor;
    fn add(self, o: Phasor) -> Phasor {
        Phasor { sin_deg: self.sin_deg + o.sin_deg, cos_deg: self.cos_deg + o.cos_deg }
    }
}

impl std::ops::Sub for Phasor {
    type Output = Phasor;
    fn sub(self, o: Phasor) -> Phasor {
        Phasor { sin_deg: self.sin_deg - o.sin_deg, cos_deg: self.cos_deg - o.cos_deg }
    }
}

impl std::ops::Mul<f64> for Phasor {
    type Output = Phasor;
    fn mul(self, f: f64) -> Phasor {
        Phasor { sin_deg: self.sin_deg * f, cos_deg: self.cos_deg * f }
    }
}

/// The window applied before a transform.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Window {
    /// No window: exact on a full circle and for whole cycles per span.
    #[default]
    Rectangular,
    /// Periodic Hann window, amplitudes corrected by its coherent gain.
    Hann,
}

/// One bin of a spectrum.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Bin {
    /// Frequency, cycles per revolution (`k * 360 / span`).
    pub cycles_per_rev: f64,
    /// Amplitude, degrees.
    pub amplitude_deg: f64,
    /// Phase, degrees in `[0, 360)`.
    pub phase_deg: f64,
    /// The component as sine and cosine coefficients.
    pub phasor: Phasor,
}

impl Bin {
    fn new(cycles_per_rev: f64, phasor: Phasor) -> Self {
        Bin { cycles_per_rev, amplitude_deg: phasor.amplitude_deg(), phase_deg: phasor.phase_deg(), phasor }
    }
}

/// A one-sided spectrum: bins `k = 0 ..= N/2`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Spectrum {
    /// Number of samples transformed.
    pub points: usize,
    /// Angle of the first sample, degrees.
    pub start_deg: f64,
    /// The period the samples are taken to cover, degrees (360 for a full circle).
    pub span_deg: f64,
    /// Window applied.
    pub window: Window,
    /// `N/2 + 1` bins (`N/2` rounded down), bin `k` at `k * 360 / span_deg` cycles/rev.
    pub bins: Vec<Bin>,
}

/// Why a spectrum or a fit cannot be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SpectrumError {
    /// Too few samples.
    #[error("{points} samples: at least {min} are needed")]
    TooFewPoints {
        /// Samples given.
        points: usize,
        /// Samples needed.
        min: usize,
    },
    /// A sample, angle or frequency is NaN or infinite.
    #[error("{what} {index} is {value}, not a finite number")]
    NonFinite {
        /// `sample`, `angle` or `frequency`.
        what: &'static str,
        /// Its position (from 0).
        index: usize,
        /// The value.
        value: f64,
    },
    /// Angles and values differ in length.
    #[error("{angles} angles but {values} values")]
    LengthMismatch {
        /// Number of angles.
        angles: usize,
        /// Number of values.
        values: usize,
    },
    /// A fit frequency is zero or negative (the offset is always fitted).
    #[error("frequency {cycles_per_rev} cycles/rev: fit frequencies must be positive (the offset is always fitted)")]
    BadFrequency {
        /// The frequency.
        cycles_per_rev: f64,
    },
    /// The same frequency is asked for twice.
    #[error("frequency {cycles_per_rev} cycles/rev is given twice")]
    DuplicateFrequency {
        /// The frequency.
        cycles_per_rev: f64,
    },
    /// A frequency cannot be told apart from the others (and the offset) at
    /// these sample angles: for example exactly the sampling Nyquist frequency,
    /// or two frequencies too close for the span.
    #[error("{cycles_per_rev} cycles/rev cannot be separated from the other frequencies at these sample angles")]
    Unresolvable {
        /// The frequency.
        cycles_per_rev: f64,
    },
    /// The span step is not positive.
    #[error("step {step_deg} deg: the spacing of the samples must be positive")]
    BadStep {
        /// The step.
        step_deg: f64,
    },
    /// The FFT library reported an error.
    #[error("FFT failed: {0}")]
    Fft(String),
}

/// Plans FFTs once and reuses them (planning costs more than a transform).
#[derive(Default)]
pub struct Planner {
    inner: RealFftPlanner<f64>,
}

impl fmt::Debug for Planner {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Planner").finish_non_exhaustive()
    }
}

fn check_finite(what: &'static str, v: &[f64]) -> Result<(), SpectrumError> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(index) => Err(SpectrumError::NonFinite { what, index, value: v[index] }),
        None => Ok(()),
    }
}

impl Planner {
    /// A planner with an empty cache.
    pub fn new() -> Self {
        Self::default()
    }

    /// Spectrum of `y` taken as one period of `span_deg` starting at `start_deg`.
    pub fn spectrum(
        &mut self,
        y: &[f64],
        start_deg: f64,
        span_deg: f64,
        window: Window,
    ) -> Result<Spectrum, SpectrumError> {
        let phasors = self.phasors(y, start_deg, span_deg, window)?;
        Ok(Spectrum::of_phasors(y.len(), start_deg, span_deg, window, phasors))
    }

    /// The phasors of [`Planner::spectrum`]'s bins alone (each bin's
    /// amplitude and phase, an `atan2` and a `hypot`, not taken): what the
    /// runs' spectra are needed for when only their mean is kept.
    pub fn phasors(
        &mut self,
        y: &[f64],
        start_deg: f64,
        span_deg: f64,
        window: Window,
    ) -> Result<Vec<Phasor>, SpectrumError> {
        let n = y.len();
        if n < 3 {
            return Err(SpectrumError::TooFewPoints { points: n, min: 3 });
        }
        check_finite("sample", y)?;
        let mean = y.iter().sum::<f64>() / n as f64;
        let (mut input, gain): (Vec<f64>, f64) = match window {
            Window::Rectangular => (y.to_vec(), n as f64),
            Window::Hann => {
                let w = |j: usize| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * j as f64 / n as f64).cos();
                let gain: f64 = (0..n).map(w).sum();
                ((0..n).map(|j| (y[j] - mean) * w(j)).collect(), gain)
            }
        };
        let fft = self.inner.plan_fft_forward(n);
        let mut out = fft.make_output_vec();
        fft.process(&mut input, &mut out).map_err(|e| SpectrumError::Fft(e.to_string()))?;
        let half = n / 2;
        Ok(out
            .iter()
            .enumerate()
            .map(|(k, x)| {
                let local = if k == 0 {
                    Phasor { sin_deg: 0.0, cos_deg: if window == Window::Hann { mean } else { x.re / gain } }
                } else if 2 * k == n {
                    Phasor { sin_deg: 0.0, cos_deg: x.re / gain }
                } else {
                    Phasor { sin_deg: -2.0 * x.im / gain, cos_deg: 2.0 * x.re / gain }
                };
                debug_assert!(k <= half);
                local.rotate_deg(-bin_cycles(k, span_deg) * start_deg)
            })
            .collect())
    }
}

/// The frequency of bin `k` over a span, cycles/rev.
fn bin_cycles(k: usize, span_deg: f64) -> f64 {
    k as f64 * 360.0 / span_deg
}

impl Spectrum {
    /// Spectrum of a uniform full circle: `y[j]` at `start_deg + j * 360 / N`.
    pub fn full_circle(y: &[f64], start_deg: f64) -> Result<Spectrum, SpectrumError> {
        Planner::new().spectrum(y, start_deg, 360.0, Window::Rectangular)
    }

    /// Display spectrum of a partial range: `y[j]` at `start_deg + j * step_deg`,
    /// taken as one period of `N * step_deg`. See the module documentation.
    pub fn span(y: &[f64], start_deg: f64, step_deg: f64, window: Window) -> Result<Spectrum, SpectrumError> {
        if !(step_deg > 0.0 && step_deg.is_finite()) {
            return Err(SpectrumError::BadStep { step_deg });
        }
        Planner::new().spectrum(y, start_deg, y.len() as f64 * step_deg, window)
    }

    /// The bin nearest `cycles_per_rev`, if it is within the spectrum.
    pub fn bin_near(&self, cycles_per_rev: f64) -> Option<&Bin> {
        let k = (cycles_per_rev * self.span_deg / 360.0).round();
        (k >= 0.0).then(|| self.bins.get(k as usize)).flatten()
    }

    /// The spectrum whose bins have `phasors` ([`Planner::phasors`] of `points`
    /// samples over `span_deg` from `start_deg`).
    pub fn of_phasors(
        points: usize,
        start_deg: f64,
        span_deg: f64,
        window: Window,
        phasors: impl IntoIterator<Item = Phasor>,
    ) -> Spectrum {
        let bins = phasors.into_iter().enumerate().map(|(k, p)| Bin::new(bin_cycles(k, span_deg), p)).collect();
        Spectrum { points, start_deg, span_deg, window, bins }
    }

    /// The spectrum of the mean series: the mean of the phasors of spectra with
    /// the same points, start, span and window (the transform is linear).
    /// `None` when `spectra` is empty or they differ in shape.
    pub fn mean_of(spectra: &[Spectrum]) -> Option<Spectrum> {
        let first = spectra.first()?;
        if spectra.iter().any(|s| {
            s.points != first.points
                || s.start_deg != first.start_deg
                || s.span_deg != first.span_deg
                || s.window != first.window
        }) {
            return None;
        }
        let mean = (0..first.bins.len()).map(|k| Phasor::mean(spectra.iter().map(|s| s.bins[k].phasor)));
        Some(Spectrum::of_phasors(first.points, first.start_deg, first.span_deg, first.window, mean))
    }

    /// [`Spectrum::mean_of`] of the runs' spectra from their phasors alone
    /// ([`Planner::phasors`] of `points` samples each, over `span_deg` from
    /// `start_deg`): the same spectrum, to the bit.
    pub fn mean_of_phasors(
        points: usize,
        start_deg: f64,
        span_deg: f64,
        window: Window,
        runs: &[Vec<Phasor>],
    ) -> Spectrum {
        let mean = (0..runs.first().map_or(0, Vec::len)).map(|k| Phasor::mean(runs.iter().map(|r| r[k])));
        Spectrum::of_phasors(points, start_deg, span_deg, window, mean)
    }
}

/// One fitted sinusoid of a [`SinusoidFit`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FitTerm {
    /// Frequency, cycles per revolution.
    pub cycles_per_rev: f64,
    /// Amplitude, degrees.
    pub amplitude_deg: f64,
    /// Phase, degrees in `[0, 360)`.
    pub phase_deg: f64,
    /// The sinusoid as sine and cosine coefficients.
    pub phasor: Phasor,
    /// Variance of the sine coefficient per unit noise variance (`(A^T A)^-1`
    /// diagonal): multiply by the sample noise variance.
    pub sin_unit_var: f64,
    /// Variance of the cosine coefficient per unit noise variance.
    pub cos_unit_var: f64,
}

/// Result of [`fit_sinusoids`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SinusoidFit {
    /// The fitted constant, degrees.
    pub offset_deg: f64,
    /// One term per frequency, in the order asked.
    pub terms: Vec<FitTerm>,
    /// Root mean square of the residual over the samples, degrees.
    pub residual_rms_deg: f64,
    /// Degrees of freedom of the residual: samples minus unknowns.
    pub dof: usize,
}

/// Least-squares fit of `offset + sum_f a_f sin(f theta + phi_f)` to `y` at
/// angles `theta_deg`. See the module documentation.
pub fn fit_sinusoids(theta_deg: &[f64], y: &[f64], freqs: &[f64]) -> Result<SinusoidFit, SpectrumError> {
    SinusoidBasis::new(theta_deg, freqs)?.fit(y)
}

/// The QR factorisation of the design matrix of a sinusoid fit, to fit many
/// series at the same angles and frequencies.
#[derive(Debug, Clone)]
pub struct SinusoidBasis {
    freqs: Vec<f64>,
    qr: Qr,
    /// `(A^T A)^-1` diagonal.
    unit_var: Vec<f64>,
}

impl SinusoidBasis {
    /// Factorise the columns `1, sin(f theta), cos(f theta), ...` at `theta_deg`.
    pub fn new(theta_deg: &[f64], freqs: &[f64]) -> Result<Self, SpectrumError> {
        check_finite("angle", theta_deg)?;
        check_finite("frequency", freqs)?;
        for (i, &f) in freqs.iter().enumerate() {
            if f <= 0.0 {
                return Err(SpectrumError::BadFrequency { cycles_per_rev: f });
            }
            if freqs[..i].iter().any(|&g| (g - f).abs() <= 1e-9 * f.max(1.0)) {
                return Err(SpectrumError::DuplicateFrequency { cycles_per_rev: f });
            }
        }
        let (n, p) = (theta_deg.len(), 1 + 2 * freqs.len());
        if n < p {
            return Err(SpectrumError::TooFewPoints { points: n, min: p });
        }
        let mut columns = vec![vec![0.0; n]; p];
        for (i, &t) in theta_deg.iter().enumerate() {
            columns[0][i] = 1.0;
            for (j, &f) in freqs.iter().enumerate() {
                let (sn, cs) = (f * t).to_radians().sin_cos();
                columns[1 + 2 * j][i] = sn;
                columns[2 + 2 * j][i] = cs;
            }
        }
        // Every entry is at most 1 and the constant column has norm sqrt(n): a
        // column whose part independent of the earlier ones is below 1e-9 of
        // that scale cannot be resolved.
        let floor = 1e-9 * (n as f64).sqrt();
        let qr = Qr::new(columns, |_| floor).map_err(|col| SpectrumError::Unresolvable {
            cycles_per_rev: if col == 0 { 0.0 } else { freqs[(col - 1) / 2] },
        })?;
        let unit_var = qr.unit_var();
        Ok(SinusoidBasis { freqs: freqs.to_vec(), qr, unit_var })
    }

    /// The frequencies, in the order given.
    pub fn freqs(&self) -> &[f64] {
        &self.freqs
    }

    /// Fit the values `y` (one per angle given to [`SinusoidBasis::new`]).
    pub fn fit(&self, y: &[f64]) -> Result<SinusoidFit, SpectrumError> {
        if y.len() != self.qr.rows() {
            return Err(SpectrumError::LengthMismatch { angles: self.qr.rows(), values: y.len() });
        }
        check_finite("sample", y)?;
        let (n, p) = (self.qr.rows(), self.qr.cols());
        let (x, residual_ss) = self.qr.solve(y);
        let terms = self
            .freqs
            .iter()
            .enumerate()
            .map(|(j, &f)| {
                let phasor = Phasor { sin_deg: x[1 + 2 * j], cos_deg: x[2 + 2 * j] };
                FitTerm {
                    cycles_per_rev: f,
                    amplitude_deg: phasor.amplitude_deg(),
                    phase_deg: phasor.phase_deg(),
                    phasor,
                    sin_unit_var: self.unit_var[1 + 2 * j],
                    cos_unit_var: self.unit_var[2 + 2 * j],
                }
            })
            .collect();
        Ok(SinusoidFit { offset_deg: x[0], terms, residual_rms_deg: (residual_ss / n as f64).sqrt(), dof: n - p })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Samples of `sum a sin(k theta + phi)` at `start + j * span / n`.
    fn synth(n: usize, start: f64, span: f64, comps: &[(f64, f64, f64)]) -> Vec<f64> {
        (0..n)
            .map(|j| {
                let t = start + j as f64 * span / n as f64;
                comps.iter().map(|&(k, a, p)| a * (k * t + p).to_radians().sin()).sum()
            })
            .collect()
    }

    #[track_caller]
    fn assert_phasor(got: Phasor, want: Phasor, tol: f64) {
        assert!((got - want).amplitude_deg() <= tol, "got {got:?}, want {want:?}");
    }

    #[test]
    fn phasor_convention() {
        let z = Phasor::from_polar(2.0, 30.0);
        assert!((z.sin_deg - 2.0 * 30f64.to_radians().cos()).abs() < 1e-15);
        assert!((z.value_at(3.0, 10.0) - 2.0 * 60f64.to_radians().sin()).abs() < 1e-15);
        assert!((z.rotate_deg(45.0).phase_deg() - 75.0).abs() < 1e-12);
        assert!((Phasor::from_polar(1.0, -90.0).phase_deg() - 270.0).abs() < 1e-12);
    }

    /// Every component at exactly `k` cycles appears at bin `k` with its
    /// amplitude and phase to 1e-12, other bins stay empty, for even and odd N,
    /// a power of two and not, and samples that do not start at 0.
    #[test]
    fn full_circle_recovers_amplitude_and_phase_exactly() {
        for &n in &[8usize, 9, 15, 720, 1000, 1801] {
            for &start in &[0.0, 0.25, -180.0, 17.3] {
                let ks = [1.0, 2.0, 5.0, ((n - 1) / 2) as f64];
                let comps: Vec<(f64, f64, f64)> =
                    ks.iter().enumerate().map(|(i, &k)| (k, 0.5 + i as f64 * 0.25, 20.0 + 77.0 * i as f64)).collect();
                let kmax = ((n - 1) / 2) as f64;
                let comps: Vec<_> = comps.into_iter().filter(|c| c.0 <= kmax).fold(Vec::new(), |mut v, c| {
                    if !v.iter().any(|d: &(f64, f64, f64)| d.0 == c.0) {
                        v.push(c);
                    }
                    v
                });
                let s = Spectrum::full_circle(&synth(n, start, 360.0, &comps), start).unwrap();
                assert_eq!(s.bins.len(), n / 2 + 1);
                for (k, bin) in s.bins.iter().enumerate() {
                    assert_eq!(bin.cycles_per_rev, k as f64);
                    match comps.iter().find(|c| c.0 == k as f64) {
                        Some(&(_, a, p)) => {
                            assert!((bin.amplitude_deg - a).abs() < 1e-12, "n {n} start {start} k {k}: {bin:?}");
                            let dphase = crate::types::wrap_180(bin.phase_deg - p).to_radians();
                            assert!(dphase.abs() < 1e-12, "n {n} start {start} k {k}: {bin:?} want {p}");
                        }
                        None => assert!(bin.amplitude_deg < 1e-12, "n {n} start {start} k {k}: {bin:?}"),
                    }
                }
            }
        }
    }

    #[test]
    fn mean_and_nyquist_are_canonical() {
        // k = 0: a sin(phi) is a constant; bin 0 has amplitude |a sin phi| and phase 90 or 270.
        for &(a, p) in &[(0.3, 90.0), (0.3, 30.0), (0.3, 200.0)] {
            let y = synth(16, 5.0, 360.0, &[(0.0, a, p)]);
            let b = Spectrum::full_circle(&y, 5.0).unwrap().bins[0];
            let m = a * f64::to_radians(p).sin();
            assert!((b.amplitude_deg - m.abs()).abs() < 1e-12);
            assert_eq!(b.phase_deg, if m >= 0.0 { 90.0 } else { 270.0 });
        }
        // k = N/2: only a sin(phi) is seen (start 0); the sine part is invisible.
        let n = 12;
        let b = Spectrum::full_circle(&synth(n, 0.0, 360.0, &[(6.0, 0.4, 210.0)]), 0.0).unwrap().bins[6];
        assert!((b.amplitude_deg - 0.2).abs() < 1e-12, "{b:?}");
        assert!((b.phase_deg - 270.0).abs() < 1e-9, "{b:?}");
        let invisible = Spectrum::full_circle(&synth(n, 0.0, 360.0, &[(6.0, 1.0, 0.0)]), 0.0).unwrap();
        assert!(invisible.bins[6].amplitude_deg < 1e-12);
        // With a start offset, the Nyquist bin still reproduces the samples.
        let y = synth(n, 7.0, 360.0, &[(6.0, 0.4, 10.0)]);
        let b = Spectrum::full_circle(&y, 7.0).unwrap().bins[6];
        for (j, v) in y.iter().enumerate() {
            assert!((b.phasor.value_at(6.0, 7.0 + j as f64 * 30.0) - v).abs() < 1e-12);
        }
    }

    #[test]
    fn aliased_component_appears_conjugated() {
        // 432 cycles at 720 points lands at 288 with phase 180 - phi.
        let y = synth(720, 0.0, 360.0, &[(432.0, 0.0004, 45.0)]);
        let b = Spectrum::full_circle(&y, 0.0).unwrap().bins[288];
        assert!((b.amplitude_deg - 0.0004).abs() < 1e-15);
        assert!((b.phase_deg - 135.0).abs() < 1e-9, "{b:?}");
    }

    #[test]
    fn mean_of_spectra_is_spectrum_of_mean() {
        let a = synth(30, 0.0, 360.0, &[(3.0, 1.0, 10.0), (0.0, 1.0, 90.0)]);
        let b = synth(30, 0.0, 360.0, &[(3.0, 0.5, 100.0), (7.0, 0.2, 0.0)]);
        let mean: Vec<f64> = a.iter().zip(&b).map(|(x, y)| (x + y) / 2.0).collect();
        let sa = Spectrum::full_circle(&a, 0.0).unwrap();
        let sb = Spectrum::full_circle(&b, 0.0).unwrap();
        let m = Spectrum::mean_of(&[sa.clone(), sb]).unwrap();
        let direct = Spectrum::full_circle(&mean, 0.0).unwrap();
        for (x, y) in m.bins.iter().zip(&direct.bins) {
            assert_phasor(x.phasor, y.phasor, 1e-13);
        }
        let other = Spectrum::full_circle(&a[..29], 0.0).unwrap();
        assert!(Spectrum::mean_of(&[sa, other]).is_none());
        assert!(Spectrum::mean_of(&[]).is_none());
    }

    /// A 6:1 gear pass over an elevation range -10..90 at 0.5 deg (201 points,
    /// span 100.5 deg): 1.675 cycles per span, between bins 1 (3.58) and 2 (7.16).
    /// The display spectrum puts it at the nearest bin with a scalloping loss;
    /// the least-squares fit at 6 cycles/rev recovers it exactly.
    #[test]
    fn partial_range_display_spectrum_and_fit() {
        let theta: Vec<f64> = (0..=200).map(|j| -10.0 + 0.5 * j as f64).collect();
        let y: Vec<f64> = theta.iter().map(|t| 0.028 * (6.0 * t + 20.0f64).to_radians().sin()).collect();
        for window in [Window::Hann, Window::Rectangular] {
            let s = Spectrum::span(&y, -10.0, 0.5, window).unwrap();
            assert!((s.span_deg - 100.5).abs() < 1e-12);
            let peak = s.bins[1..].iter().max_by(|a, b| a.amplitude_deg.total_cmp(&b.amplitude_deg)).unwrap();
            assert!((peak.cycles_per_rev - 2.0 * 360.0 / 100.5).abs() < 1e-9, "{window:?}: {peak:?}");
            let ratio = peak.amplitude_deg / 0.028;
            let (lo, hi) = if window == Window::Hann { (0.80, 1.0) } else { (0.6, 1.0) };
            assert!(ratio > lo && ratio < hi, "{window:?}: {ratio}");
        }
        // Whole cycles per span are exact with either window.
        let f = 5.0 * 360.0 / 100.5;
        let y2: Vec<f64> = theta.iter().map(|t| 0.01 * (f * t + 33.0f64).to_radians().sin()).collect();
        for window in [Window::Hann, Window::Rectangular] {
            let b = Spectrum::span(&y2, -10.0, 0.5, window).unwrap().bins[5];
            assert!((b.amplitude_deg - 0.01).abs() < 1e-12 && (b.phase_deg - 33.0).abs() < 1e-8, "{window:?} {b:?}");
        }
        let fit = fit_sinusoids(&theta, &y, &[6.0]).unwrap();
        assert!((fit.terms[0].amplitude_deg - 0.028).abs() < 1e-12);
        assert!((fit.terms[0].phase_deg - 20.0).abs() < 1e-9);
        assert!(fit.offset_deg.abs() < 1e-12 && fit.residual_rms_deg < 1e-12);
        assert_eq!(fit.dof, 201 - 3);
        assert_eq!(Spectrum::span(&y, 0.0, 0.0, Window::Hann), Err(SpectrumError::BadStep { step_deg: 0.0 }));
    }

    /// The Figure 1 elevation axis: 1, 2, 6, 12, 72 cycles and an offset over
    /// -10..90, fitted together (the slow terms are nearly collinear over 100 deg).
    #[test]
    fn fit_recovers_nearly_collinear_terms() {
        let theta: Vec<f64> = (0..=200).map(|j| -10.0 + 0.5 * j as f64).collect();
        let comps =
            [(1.0, 0.002, 150.0), (2.0, 0.001, 10.0), (6.0, 0.028, 20.0), (12.0, 0.003, 75.0), (72.0, 0.006, 0.0)];
        let y: Vec<f64> = theta
            .iter()
            .map(|t| 0.01 + comps.iter().map(|&(k, a, p)| a * (k * t + p).to_radians().sin()).sum::<f64>())
            .collect();
        let freqs: Vec<f64> = comps.iter().map(|c| c.0).collect();
        let fit = fit_sinusoids(&theta, &y, &freqs).unwrap();
        for (term, &(k, a, p)) in fit.terms.iter().zip(&comps) {
            assert_eq!(term.cycles_per_rev, k);
            assert_phasor(term.phasor, Phasor::from_polar(a, p), 1e-10);
        }
        assert!((fit.offset_deg - 0.01).abs() < 1e-10);
        // The slow terms are far less certain than the 72-cycle term.
        assert!(fit.terms[0].sin_unit_var > 100.0 * fit.terms[4].sin_unit_var);
    }

    #[test]
    fn fit_on_a_full_circle_matches_the_dft_and_its_variances() {
        let n = 64;
        let theta: Vec<f64> = (0..n).map(|j| j as f64 * 360.0 / n as f64).collect();
        let y = synth(n, 0.0, 360.0, &[(3.0, 1.0, 40.0), (10.0, 0.5, 300.0), (0.0, 0.2, 90.0)]);
        let fit = fit_sinusoids(&theta, &y, &[3.0, 10.0, 11.0]).unwrap();
        let s = Spectrum::full_circle(&y, 0.0).unwrap();
        for t in &fit.terms {
            assert_phasor(t.phasor, s.bins[t.cycles_per_rev as usize].phasor, 1e-12);
            // Orthogonal columns: (A^T A)^-1 = 2/N for sine and cosine.
            assert!((t.sin_unit_var - 2.0 / n as f64).abs() < 1e-12 && (t.cos_unit_var - 2.0 / n as f64).abs() < 1e-12);
        }
        assert!((fit.offset_deg - 0.2).abs() < 1e-12);
    }

    #[test]
    fn fit_defects_are_named() {
        let theta: Vec<f64> = (0..=200).map(|j| -10.0 + 0.5 * j as f64).collect();
        let y = vec![0.0; theta.len()];
        assert_eq!(
            fit_sinusoids(&theta, &y, &[6.0, 6.0]).unwrap_err(),
            SpectrumError::DuplicateFrequency { cycles_per_rev: 6.0 }
        );
        assert_eq!(fit_sinusoids(&theta, &y, &[0.0]).unwrap_err(), SpectrumError::BadFrequency { cycles_per_rev: 0.0 });
        // 360 cycles/rev at 0.5 deg spacing starting at -10: sin column is zero.
        assert_eq!(
            fit_sinusoids(&theta, &y, &[6.0, 360.0]).unwrap_err(),
            SpectrumError::Unresolvable { cycles_per_rev: 360.0 }
        );
        // 720 cycles/rev at 0.5 deg: indistinguishable from the offset.
        assert_eq!(
            fit_sinusoids(&theta, &y, &[720.0]).unwrap_err(),
            SpectrumError::Unresolvable { cycles_per_rev: 720.0 }
        );
        assert_eq!(
            fit_sinusoids(&theta[..4], &y[..4], &[1.0, 2.0]).unwrap_err(),
            SpectrumError::TooFewPoints { points: 4, min: 5 }
        );
        assert_eq!(
            fit_sinusoids(&theta, &y[..3], &[1.0]).unwrap_err(),
            SpectrumError::LengthMismatch { angles: 201, values: 3 }
        );
        let mut bad = y.clone();
        bad[7] = f64::INFINITY;
        assert!(matches!(
            fit_sinusoids(&theta, &bad, &[1.0]).unwrap_err(),
            SpectrumError::NonFinite { what: "sample", index: 7, .. }
        ));
        assert_eq!(
            Spectrum::full_circle(&[1.0, 2.0], 0.0).unwrap_err(),
            SpectrumError::TooFewPoints { points: 2, min: 3 }
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
        /// Any N, any bin strictly between 0 and N/2, any start: exact recovery.
        #[test]
        fn prop_single_component_round_trip(n in 3usize..400, kf in 0.0f64..1.0, a in 1e-4f64..1.0, p in 0.0f64..360.0, start in -360.0f64..360.0) {
            let kmax = (n - 1) / 2;
            let k = 1 + ((kmax as f64 - 1.0) * kf).round() as usize;
            let y = synth(n, start, 360.0, &[(k as f64, a, p)]);
            let s = Spectrum::full_circle(&y, start).unwrap();
            assert_phasor(s.bins[k].phasor, Phasor::from_polar(a, p), 1e-12);
            for (j, b) in s.bins.iter().enumerate() {
                if j != k { prop_assert!(b.amplitude_deg < 1e-12); }
            }
        }
    }
}
