//! Band-limited resampling of uniform periodic series over a full revolution,
//! and the spectral editing of the paper's section 4.
//!
//! A survey of `N` points at readout angles `360 k / N` (k = 0..N) over a full
//! revolution is one period of a periodic function. Its discrete Fourier
//! transform gives the trigonometric polynomial of lowest degree through the
//! points ([`Series`]); evaluating that polynomial at `M` uniform angles is
//! spectral resampling (zero-padding the spectrum for `M > N`, truncating it
//! for `M < N`, which is a low-pass decimation). The paper expands 1800 points
//! to 128k this way, edits the spectrum (keeps the repeatable lines, nulls or
//! relocates aliased ones: [`SpectralEdit`]) and decimates to the table the
//! hardware holds.
//!
//! # Conventions
//!
//! A [`Series`] holds complex amplitudes `C_k` indexed by `k` cycles per
//! revolution, so that `y(theta) = sum_k Re(C_k exp(i k theta))`. `|C_k|` is
//! the amplitude of the line at `k`; the contract's
//! `A sin(k theta + phase)` has `C_k = -i A exp(i phase)` ([`Series::from_sines`],
//! [`Series::phase_deg`]). From `N` samples with the unnormalised forward DFT
//! `X_k`: `C_0 = X_0 / N`, `C_k = 2 X_k / N` for `0 < k < N/2`, and for even
//! `N` the Nyquist line `C_{N/2} = X_{N/2} / N` (real: only its cosine part is
//! visible at `N` points). Synthesising `M` points puts `C_k / 2` in bin `k`
//! of the half spectrum for `0 < k < M/2`, `Re(C_{M/2})` in the Nyquist bin of
//! an even `M`, and drops lines above `M/2`. For even `N` and `M > N` the
//! Nyquist line is therefore split evenly between `+N/2` and `-N/2` (the only
//! real, symmetric choice); for even `M < N` the pair `+-M/2` is joined, which
//! is what sampling the low-passed signal at `M` points gives. These are the
//! conventions of `scipy.signal.resample` (its source, "Split/join Nyquist
//! component(s) if present", read for this module).
//!
//! # FFT
//!
//! `realfft` 3.5 (real-to-complex transforms on top of `rustfft` 6.4). Looked
//! up in its source and docs (docs.rs/realfft, `RealFftPlanner`,
//! `RealToComplex::process_with_scratch`): both directions are unnormalised,
//! the complex-to-real inverse requires the imaginary parts of bin 0 and, for
//! even lengths, of the last bin to be zero (it zeroes them and reports
//! `FftError::InputValues` otherwise: this module always writes them real),
//! and plans are cached by the planner. [`Resampler`] keeps one planner and
//! its buffers, so repeated calls at the same lengths neither plan (5 to 8 ms
//! at 131072 points) nor allocate beyond their output.

mod edit;
mod interp;
mod partial;

pub use edit::{EditError, Keep, Relocation, SpectralEdit};
pub use interp::{CompareError, Method, MethodScore, compare_interpolation, upsample};
pub use partial::{PartialError, PartialFit, PartialMethod, Span, fit_partial};
pub use realfft::num_complex::Complex64;

use realfft::RealFftPlanner;
use serde::Serialize;
use std::fmt;

/// A trigonometric polynomial over one revolution: complex amplitudes `C_k`
/// at `k` cycles per revolution, `y(theta) = sum_k Re(C_k exp(i k theta))`.
///
/// `C_0` is the mean (real). Bins past the end are zero.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    coeffs: Vec<Complex64>,
}

impl Series {
    /// A series from its complex amplitudes (index = cycles per revolution).
    /// The imaginary part of `C_0` is ignored (a constant has no phase).
    pub fn from_coeffs(mut coeffs: Vec<Complex64>) -> Self {
        if let Some(c0) = coeffs.first_mut() {
            c0.im = 0.0;
        }
        Self { coeffs }
    }

    /// `mean + sum A sin(k theta + phase)` from `(cycles_per_rev, amplitude_deg,
    /// phase_deg)` triples (the contract's periodic effects). Lines at the same
    /// `k` add; `k = 0` adds `A sin(phase)` to the mean.
    pub fn from_sines(mean: f64, lines: &[(usize, f64, f64)]) -> Self {
        let mut s = Self::from_coeffs(vec![Complex64::new(mean, 0.0)]);
        for &(k, a, phase_deg) in lines {
            let (sin, cos) = phase_deg.to_radians().sin_cos();
            let c = if k == 0 { Complex64::new(a * sin, 0.0) } else { Complex64::new(a * sin, -a * cos) };
            s.set_coeff(k, s.coeff(k) + c);
        }
        s
    }

    /// The complex amplitudes, index = cycles per revolution.
    pub fn coeffs(&self) -> &[Complex64] {
        &self.coeffs
    }

    /// Number of bins held (one more than the highest line that may be non-zero).
    pub fn bins(&self) -> usize {
        self.coeffs.len()
    }

    /// The complex amplitude at `k` cycles (zero past the end).
    pub fn coeff(&self, k: usize) -> Complex64 {
        self.coeffs.get(k).copied().unwrap_or_default()
    }

    /// Set the complex amplitude at `k` cycles, growing the series as needed.
    /// The imaginary part at `k = 0` is dropped.
    pub fn set_coeff(&mut self, k: usize, mut c: Complex64) {
        if k == 0 {
            c.im = 0.0;
        }
        if k >= self.coeffs.len() {
            if c == Complex64::default() {
                return;
            }
            self.coeffs.resize(k + 1, Complex64::default());
        }
        self.coeffs[k] = c;
    }

    /// Amplitude of the line at `k` cycles, degrees (`|C_k|`; the mean for `k = 0`,
    /// with its sign).
    pub fn amplitude(&self, k: usize) -> f64 {
        if k == 0 { self.coeff(0).re } else { self.coeff(k).norm() }
    }

    /// Phase of the line at `k` in the contract's convention
    /// `A sin(k theta + phase)`, degrees in `(-180, 180]`.
    pub fn phase_deg(&self, k: usize) -> f64 {
        let c = self.coeff(k);
        // i C = A exp(i phase).
        c.re.atan2(-c.im).to_degrees()
    }

    /// Value at axis angle `theta_deg` (any angle; the series is periodic).
    /// Costs one `sin_cos` per non-zero bin: for many angles,
    /// [`Resampler::synthesize`].
    pub fn eval(&self, theta_deg: f64) -> f64 {
        let t = theta_deg.to_radians();
        self.coeffs
            .iter()
            .enumerate()
            .filter(|(_, c)| **c != Complex64::default())
            .map(|(k, c)| {
                let (s, co) = (k as f64 * t).sin_cos();
                c.re * co - c.im * s
            })
            .sum()
    }

    /// Drop every line above `max_cycles` (an ideal low-pass).
    pub fn truncate(&mut self, max_cycles: usize) {
        self.coeffs.truncate(max_cycles + 1);
    }
}

/// Where a sinusoid of `true_cycles` per revolution appears when the
/// revolution is sampled at `n` uniform points.
///
/// With `r = f - n round(f / n)` in `(-n/2, n/2]`, the line appears at
/// `observed_cycles = |r|`. When `r < 0` the alias is the mirror image:
/// `A sin(f theta + phase)` reads at the sample points as
/// `A sin(|r| theta + 180 - phase)`, so its complex amplitude is the conjugate
/// of the true one (`conjugated = true`). For example, with 720 points, 432
/// appears at 288 and 648 at 72, both conjugated; 1000 appears at 280, not
/// conjugated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Alias {
    /// The bin the line lands in, cycles per revolution (`0..=n/2`).
    pub observed_cycles: usize,
    /// Whether the observed complex amplitude is the conjugate of the true one.
    pub conjugated: bool,
}

/// The alias of a line at `true_cycles` sampled at `n` points (see [`Alias`]).
/// `n = 0` returns the line unchanged.
pub fn alias_of(true_cycles: usize, n: usize) -> Alias {
    if n == 0 {
        return Alias { observed_cycles: true_cycles, conjugated: false };
    }
    let rem = true_cycles % n;
    if 2 * rem <= n {
        Alias { observed_cycles: rem, conjugated: false }
    } else {
        Alias { observed_cycles: n - rem, conjugated: true }
    }
}

/// Spectral analysis and synthesis with cached FFT plans and buffers.
///
/// Build one and reuse it: the first call at a length plans the FFT, later
/// calls at that length reuse the plan, the scratch space and the spectrum
/// buffers (only the returned vectors are allocated; the `_into` variants
/// allocate nothing once warm).
pub struct Resampler {
    planner: RealFftPlanner<f64>,
    real: Vec<f64>,
    spectrum: Vec<Complex64>,
    scratch: Vec<Complex64>,
    series: Series,
}

impl fmt::Debug for Resampler {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Resampler")
            .field("buffer_len", &self.real.len())
            .field("spectrum_len", &self.spectrum.len())
            .field("scratch_len", &self.scratch.len())
            .finish_non_exhaustive()
    }
}

impl Default for Resampler {
    fn default() -> Self {
        Self::new()
    }
}

impl Resampler {
    /// A resampler with no plans yet.
    pub fn new() -> Self {
        Self {
            planner: RealFftPlanner::new(),
            real: Vec::new(),
            spectrum: Vec::new(),
            scratch: Vec::new(),
            series: Series::default(),
        }
    }

    /// The series through `y`, uniform samples over one revolution
    /// (`y[j]` at `360 j / N` degrees). Empty input gives the zero series.
    pub fn analyze(&mut self, y: &[f64]) -> Series {
        let mut s = Series::default();
        self.analyze_into(y, &mut s);
        s
    }

    /// [`Resampler::analyze`] into an existing series (its buffer is reused).
    pub fn analyze_into(&mut self, y: &[f64], out: &mut Series) {
        let n = y.len();
        out.coeffs.clear();
        if n == 0 {
            return;
        }
        let fft = self.planner.plan_fft_forward(n);
        self.real.clear();
        self.real.extend_from_slice(y);
        self.spectrum.clear();
        self.spectrum.resize(n / 2 + 1, Complex64::default());
        let need = fft.get_scratch_len();
        if self.scratch.len() < need {
            self.scratch.resize(need, Complex64::default());
        }
        fft.process_with_scratch(&mut self.real, &mut self.spectrum, &mut self.scratch[..need])
            .expect("buffer lengths follow the plan");
        let inv = 1.0 / n as f64;
        out.coeffs.extend(
            self.spectrum.iter().enumerate().map(
                |(k, x)| {
                    if k == 0 || 2 * k == n { *x * inv } else { *x * (2.0 * inv) }
                },
            ),
        );
        // Bin 0 and the Nyquist bin of a real signal are real; drop rounding.
        out.coeffs[0].im = 0.0;
        if n.is_multiple_of(2) {
            out.coeffs[n / 2].im = 0.0;
        }
    }

    /// The series sampled at `m` uniform angles `360 j / m`: lines below `m/2`
    /// exactly, the cosine part of a line at `m/2` (even `m`), nothing above.
    pub fn synthesize(&mut self, series: &Series, m: usize) -> Vec<f64> {
        let mut out = vec![0.0; m];
        self.synthesize_into(series, &mut out);
        out
    }

    /// [`Resampler::synthesize`] into `out` (`m = out.len()`).
    pub fn synthesize_into(&mut self, series: &Series, out: &mut [f64]) {
        let m = out.len();
        if m == 0 {
            return;
        }
        let half = m / 2;
        self.spectrum.clear();
        self.spectrum.extend((0..=half).map(|k| {
            let c = series.coeff(k);
            if k == 0 || 2 * k == m { Complex64::new(c.re, 0.0) } else { c * 0.5 }
        }));
        let fft = self.planner.plan_fft_inverse(m);
        let need = fft.get_scratch_len();
        if self.scratch.len() < need {
            self.scratch.resize(need, Complex64::default());
        }
        fft.process_with_scratch(&mut self.spectrum, out, &mut self.scratch[..need])
            .expect("buffer lengths follow the plan and bins 0 and m/2 are real");
    }

    /// Band-limited resampling of `y` (uniform over one revolution) to `m`
    /// uniform points: zero-padding for `m > N` (exact for a signal whose lines
    /// are below `N/2`, with the Nyquist line of an even `N` split), spectral
    /// truncation for `m < N` (a low-pass decimation).
    pub fn resample(&mut self, y: &[f64], m: usize) -> Vec<f64> {
        let mut out = vec![0.0; m];
        self.resample_into(y, &mut out);
        out
    }

    /// [`Resampler::resample`] into `out` (`m = out.len()`).
    pub fn resample_into(&mut self, y: &[f64], out: &mut [f64]) {
        let mut s = std::mem::take(&mut self.series);
        self.analyze_into(y, &mut s);
        self.synthesize_into(&s, out);
        self.series = s;
    }
}

/// One-shot [`Resampler::resample`] (plans afresh: reuse a [`Resampler`] for
/// repeated calls).
pub fn spectral_resample(y: &[f64], m: usize) -> Vec<f64> {
    Resampler::new().resample(y, m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use proptest::test_runner::{Config as ProptestConfig, RngSeed};

    fn angles(m: usize) -> impl Iterator<Item = f64> {
        (0..m).map(move |j| 360.0 * j as f64 / m as f64)
    }

    fn max_diff(a: &[f64], b: impl Iterator<Item = f64>) -> f64 {
        a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
    }

    /// A band-limited test signal for `n` points: lines strictly below `n/2`,
    /// plus the cosine of the Nyquist line for even `n`.
    fn signal(n: usize) -> impl Fn(f64) -> f64 {
        move |t: f64| {
            let r = t.to_radians();
            let mut v = 0.3;
            if n >= 3 {
                v += 0.01 * (r + 0.4).sin();
            }
            let top = (n - 1) / 2;
            v += 0.002 * (top as f64 * r + 1.1).sin();
            if top > 3 {
                v += 0.004 * (3.0 * r - 0.7).sin();
            }
            if n.is_multiple_of(2) {
                v += 0.003 * ((n / 2) as f64 * r).cos();
            }
            v
        }
    }

    #[test]
    fn upsampling_is_exact_for_band_limited_signals_odd_and_even() {
        let mut rs = Resampler::new();
        for (n, m) in [(9, 64), (10, 64), (10, 65), (720, 4096), (1800, 131_072), (17, 17), (16, 16), (1, 5), (2, 8)] {
            let f = signal(n);
            let y: Vec<f64> = angles(n).map(&f).collect();
            let z = rs.resample(&y, m);
            let err = max_diff(&z, angles(m).map(&f));
            assert!(err < 1e-12, "n={n} m={m}: max error {err:e}");
        }
    }

    #[test]
    fn decimation_keeps_the_low_band_and_joins_the_nyquist_pair() {
        let mut rs = Resampler::new();
        // Lines at 3 and 40 sampled at 128 points, decimated to 64: 3 survives,
        // 40 (above 32) is removed rather than aliased to 24.
        let y: Vec<f64> = angles(128)
            .map(|t| {
                let r = t.to_radians();
                0.01 * (3.0 * r + 0.2).sin() + 0.005 * (40.0 * r + 1.0).sin()
            })
            .collect();
        let z = rs.resample(&y, 64);
        let err = max_diff(&z, angles(64).map(|t| 0.01 * (3.0 * t.to_radians() + 0.2).sin()));
        assert!(err < 1e-13, "{err:e}");
        // A line exactly at the new Nyquist (32 of 64): the decimated samples
        // are the samples of the line itself (its cosine part survives).
        let g = |t: f64| 0.004 * (32.0 * t.to_radians() + 0.5).sin();
        let y: Vec<f64> = angles(128).map(g).collect();
        let z = rs.resample(&y, 64);
        let err = max_diff(&z, angles(64).map(g));
        assert!(err < 1e-13, "{err:e}");
    }

    #[test]
    fn series_amplitudes_and_phases_follow_the_contract() {
        let mut rs = Resampler::new();
        let y: Vec<f64> =
            angles(360).map(|t| 0.5 + 0.006 * (12.0 * t.to_radians() + 30f64.to_radians()).sin()).collect();
        let s = rs.analyze(&y);
        assert!((s.amplitude(0) - 0.5).abs() < 1e-14);
        assert!((s.amplitude(12) - 0.006).abs() < 1e-15);
        assert!((s.phase_deg(12) - 30.0).abs() < 1e-9);
        assert!(s.amplitude(11) < 1e-16);
        let built = Series::from_sines(0.5, &[(12, 0.006, 30.0)]);
        for t in [0.0, 1.3, 77.0, 359.9] {
            assert!((built.eval(t) - s.eval(t)).abs() < 1e-15);
        }
        assert_eq!(rs.synthesize(&built, 0), Vec::<f64>::new());
        assert_eq!(spectral_resample(&[], 4), vec![0.0; 4]);
    }

    #[test]
    fn alias_positions_and_conjugation() {
        assert_eq!(alias_of(432, 720), Alias { observed_cycles: 288, conjugated: true });
        assert_eq!(alias_of(648, 720), Alias { observed_cycles: 72, conjugated: true });
        assert_eq!(alias_of(1000, 720), Alias { observed_cycles: 280, conjugated: false });
        assert_eq!(alias_of(216, 720), Alias { observed_cycles: 216, conjugated: false });
        assert_eq!(alias_of(1440, 720), Alias { observed_cycles: 0, conjugated: false });
        // Check the rule against sampling itself: the sampled line equals the
        // observed line with the (conjugated) amplitude.
        let mut rs = Resampler::new();
        for (f, n) in [(432usize, 720usize), (648, 720), (1000, 720), (701, 256)] {
            let s = Series::from_sines(0.0, &[(f, 0.001, 37.0)]);
            let sampled: Vec<f64> = angles(n).map(|t| s.eval(t)).collect();
            let seen = rs.analyze(&sampled);
            let a = alias_of(f, n);
            let expect = if a.conjugated { s.coeff(f).conj() } else { s.coeff(f) };
            assert!((seen.coeff(a.observed_cycles) - expect).norm() < 1e-14, "f={f} n={n}");
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 64,
            rng_seed: RngSeed::Fixed(0x5eed_0001),
            failure_persistence: None,
            ..ProptestConfig::default()
        })]

        /// Random band-limited series, random lengths: resampling reproduces
        /// the series at the new points, and going back gives the input.
        #[test]
        fn resampling_random_band_limited_series(
            n in 1usize..300,
            extra in 0usize..700,
            raw in prop::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 150),
        ) {
            let m = n + extra;
            let top = n.div_ceil(2); // bins 0..top are strictly below n/2
            let mut coeffs: Vec<Complex64> = raw[..top].iter().map(|&(a, b)| Complex64::new(a, b)).collect();
            coeffs[0].im = 0.0;
            if n.is_multiple_of(2) {
                coeffs.push(Complex64::new(raw[top].0, 0.0));
            }
            let s = Series::from_coeffs(coeffs);
            let y: Vec<f64> = angles(n).map(|t| s.eval(t)).collect();
            let mut rs = Resampler::new();
            let z = rs.resample(&y, m);
            let scale = 1e-12 * (1.0 + n as f64).sqrt() * 8.0;
            prop_assert!(max_diff(&z, angles(m).map(|t| s.eval(t))) < scale);
            let back = rs.resample(&z, n);
            prop_assert!(max_diff(&back, y.iter().copied()) < scale);
        }
    }
}
