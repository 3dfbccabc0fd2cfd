//! Tables tested against the truth: the error model knows the true error, so
//! the residual of a table is measured against it at dense angles *between*
//! the measured points, not only at them.
//!
//! The simulators' convention (sims/src/positioner.rs): the encoder reads
//! `readout = actual + e(actual) + noise` and the servo stops the axis where the
//! readout equals the target. So the true error *as a function of the readout*
//! is `E(r) = r - theta(r)` with `theta + e(theta) = r` (solved by Newton here),
//! and a survey at `N` targets measures `E(360 j / N) + noise`. `E` is not a
//! plain sum of the model's lines: it also holds their products (the `e e'`
//! terms, some above `N/2`), which is why the bounds below use the spectrum of
//! `E` itself, computed with `rustfft` directly (not with the code under test).
//!
//! Every bound is the sum of three terms, each derived:
//! - **noise**: the table interpolates the noise of the mean map, whose
//!   standard deviation is `sigma_m = sigma / sqrt(runs)` at every angle (the
//!   band-limited interpolant of white noise has the variance of its samples).
//!   Its peak over the dense angles stays below `6 sigma_m` (a Gaussian process
//!   of `N` degrees of freedom exceeds `6 sigma` with probability about
//!   `N * 2e-9`); its RMS is `sigma_m`, bounded at `1.25 sigma_m` (the RMS of
//!   `N >= 720` values is known to a few per cent);
//! - **interpolation**: linear interpolation between table rows loses at most
//!   `A (2 pi k / rows)^2 / 8` on a line of amplitude `A` at `k` cycles, summed
//!   over the spectrum of `E`;
//! - **out of band**: a line of `E` at or above `N/2` is both missing from the
//!   table and aliased into it, so it costs at most twice its amplitude (unless
//!   relocated; a relocation also moves whatever else was in the observed bin,
//!   which costs twice that bin's in-band amplitude).

use super::*;
use proptest::prelude::*;
use proptest::test_runner::{Config as ProptestConfig, RngSeed};
use rustfft::FftPlanner;
use rustfft::num_complex::Complex;
use std::f64::consts::PI;
use survey_processing::model::{Effect, Model};
use survey_processing::resample::{Keep, Relocation};
use survey_processing::types::Direction;

/// The fig4 preset (sims/presets/fig4.toml), copied so that these numbers do
/// not move when the preset is tuned.
const FIG4: &str = r#"
[design]
gear_ratios = [12]
tooth_counts = [216]
encoder_heads = 2
[[effect]]
kind = "gear_pass"
cycles_per_rev = 12
amplitude_deg = 0.006
phase_deg = 15.0
[[effect]]
kind = "gear_pass"
cycles_per_rev = 24
amplitude_deg = 0.003
phase_deg = 70.0
[[effect]]
kind = "gear_pass"
cycles_per_rev = 36
amplitude_deg = 0.0018
phase_deg = 130.0
[[effect]]
kind = "gear_pass"
cycles_per_rev = 48
amplitude_deg = 0.0012
phase_deg = 200.0
[[effect]]
kind = "gear_pass"
cycles_per_rev = 60
amplitude_deg = 0.0008
phase_deg = 260.0
[[effect]]
kind = "ellipticity"
cycles_per_rev = 2
amplitude_deg = 0.002
phase_deg = 40.0
[[effect]]
kind = "tooth_mesh"
cycles_per_rev = 216
amplitude_deg = 0.0015
phase_deg = 0.0
[[effect]]
kind = "tooth_mesh"
cycles_per_rev = 432
amplitude_deg = 0.0004
phase_deg = 45.0
[[effect]]
kind = "tooth_mesh"
cycles_per_rev = 648
amplitude_deg = 0.00025
phase_deg = 90.0
[[effect]]
kind = "tooth_mesh"
cycles_per_rev = 204
amplitude_deg = 0.0002
phase_deg = 10.0
[[effect]]
kind = "tooth_mesh"
cycles_per_rev = 228
amplitude_deg = 0.0002
phase_deg = 190.0
[[effect]]
kind = "backlash"
amplitude_deg = 0.001
[[effect]]
kind = "noise"
sigma_deg = 0.0002
"#;

/// The fig1 preset (sims/presets/fig1.toml): an elevation axis, -10..90 deg.
const FIG1: &str = r#"
[design]
gear_ratios = [6, 72]
[[effect]]
kind = "gear_pass"
cycles_per_rev = 6
amplitude_deg = 0.028
phase_deg = 20.0
[[effect]]
kind = "gear_pass"
cycles_per_rev = 12
amplitude_deg = 0.003
phase_deg = 75.0
[[effect]]
kind = "gear_pass"
cycles_per_rev = 72
amplitude_deg = 0.006
phase_deg = 0.0
[[effect]]
kind = "eccentricity"
cycles_per_rev = 1
amplitude_deg = 0.002
phase_deg = 150.0
[[effect]]
kind = "backlash"
amplitude_deg = 0.0048
[[effect]]
kind = "noise"
sigma_deg = 0.0005
"#;

/// Deterministic normal deviates: splitmix64 and Box-Muller.
struct Gauss(u64);

impl Gauss {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in (0, 1).
    fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * PI * v).cos()
    }
}

/// The repeatable error of one direction: lines `(k, A, phase in rad)` and a
/// constant (backlash/2 with its sign).
#[derive(Debug, Clone)]
struct Truth {
    lines: Vec<(f64, f64, f64)>,
    offset: f64,
}

impl Truth {
    fn from_model(m: &Model, dir: Direction) -> Self {
        let lines = m
            .periodic_effects()
            .filter_map(|e| match e {
                Effect::Periodic { cycles_per_rev, amplitude_deg, phase_deg, .. } => {
                    Some((*cycles_per_rev, *amplitude_deg, phase_deg.to_radians()))
                }
                _ => None,
            })
            .collect();
        Truth { lines, offset: dir.sign() * m.backlash_deg() / 2.0 }
    }

    /// `e(theta)` and `de/dtheta` at the axis angle (degrees).
    fn axis(&self, theta: f64) -> (f64, f64) {
        let t = theta.to_radians();
        let (mut e, mut d) = (self.offset, 0.0);
        for &(k, a, p) in &self.lines {
            let (s, c) = (k * t + p).sin_cos();
            e += a * s;
            d += a * k * c * PI / 180.0;
        }
        (e, d)
    }

    /// `E(r) = r - theta` with `theta + e(theta) = r`.
    fn at_readout(&self, r: f64) -> f64 {
        let mut theta = r - self.axis(r).0;
        for _ in 0..30 {
            let (e, d) = self.axis(theta);
            let step = (theta + e - r) / (1.0 + d);
            theta -= step;
            if step.abs() < 1e-15 {
                break;
            }
        }
        r - theta
    }
}

/// Mean over `runs` of `E(360 j / n) + sigma * normal`.
fn mean_map(truth: &Truth, n: usize, runs: usize, sigma: f64, rng: &mut Gauss) -> Vec<f64> {
    (0..n)
        .map(|j| {
            let e = truth.at_readout(360.0 * j as f64 / n as f64);
            (0..runs).map(|_| e + sigma * rng.normal()).sum::<f64>() / runs as f64
        })
        .collect()
}

/// Line amplitudes `|C_k|` of `E`, from `l` uniform samples (rustfft directly).
fn spectrum(truth: &Truth, l: usize) -> Vec<f64> {
    let mut buf: Vec<Complex<f64>> =
        (0..l).map(|j| Complex::new(truth.at_readout(360.0 * j as f64 / l as f64), 0.0)).collect();
    FftPlanner::new().plan_fft_forward(l).process(&mut buf);
    (0..l / 2).map(|k| buf[k].norm() * if k == 0 { 1.0 } else { 2.0 } / l as f64).collect()
}

/// Interpolation and out-of-band terms of the bound (module documentation).
fn systematic_bound(amps: &[f64], n: usize, rows: usize, relocated: &[Relocation]) -> (f64, f64) {
    let interp: f64 =
        amps.iter().enumerate().skip(1).map(|(k, a)| a * (2.0 * PI * k as f64 / rows as f64).powi(2) / 8.0).sum();
    let moved = |k: usize| relocated.iter().any(|r| r.true_cycles == k);
    let oob: f64 = amps.iter().enumerate().filter(|&(k, _)| 2 * k >= n && !moved(k)).map(|(_, a)| 2.0 * a).sum();
    let emptied: f64 = relocated.iter().map(|r| 2.0 * amps[r.observed_cycles]).sum();
    (interp, oob + emptied)
}

#[derive(Debug, Clone, Copy)]
struct Residual {
    rms: f64,
    peak: f64,
    mean: f64,
}

/// `E(a) - table.error_at(a)` at `count` angles between the table rows and
/// the survey points.
fn residual(table: &CorrectionTable, truth: &Truth, dir: Direction, count: usize) -> Residual {
    let (mut s1, mut s2, mut peak) = (0.0, 0.0, 0.0f64);
    for i in 0..count {
        let a = 360.0 * (i as f64 + 0.37) / count as f64;
        let r = truth.at_readout(a) - table.error_at(a, dir);
        s1 += r;
        s2 += r * r;
        peak = peak.max(r.abs());
    }
    Residual { rms: (s2 / count as f64).sqrt(), peak, mean: s1 / count as f64 }
}

#[test]
fn truth_matches_the_model() {
    let m = Model::parse(FIG4, "fig4").unwrap();
    for dir in [Direction::Forward, Direction::Reverse] {
        let t = Truth::from_model(&m, dir);
        for theta in [0.0, 17.3, 200.0] {
            assert!((t.axis(theta).0 - m.repeatable_error_deg(theta, dir)).abs() < 1e-15);
            // E(r) at r = theta + e(theta) is e(theta).
            let r = theta + t.axis(theta).0;
            assert!((t.at_readout(r) - t.axis(theta).0).abs() < 1e-12);
        }
    }
}

/// Figure 5: at 720 points the ring gear's 432 and 648 alias to 288 and 72.
/// Relocated, the table follows the truth down to the noise of the mean map;
/// left where they are, the aliased lines are wrong between the measured
/// points by about their amplitudes.
#[test]
fn fig4_at_720_points_relocation_removes_the_alias_error() {
    let m = Model::parse(FIG4, "fig4").unwrap();
    let truth = Truth::from_model(&m, Direction::Forward);
    let (n, runs, sigma) = (720, 8, m.noise_sigma_deg());
    let sigma_m = sigma / (runs as f64).sqrt();
    let map = mean_map(&truth, n, runs, sigma, &mut Gauss(4));
    let relocate = vec![
        Relocation { observed_cycles: 288, true_cycles: 432 },
        Relocation { observed_cycles: 72, true_cycles: 648 },
    ];
    let mut b = TableBuilder::default();
    let fixed = b.build(&map, &SpectralEdit { relocate: relocate.clone(), ..SpectralEdit::none() }).unwrap();
    let plain = b.build(&map, &SpectralEdit::none()).unwrap();
    let with = residual(&fixed, &truth, Direction::Forward, 20_000);
    let without = residual(&plain, &truth, Direction::Forward, 20_000);

    let amps = spectrum(&truth, 8192);
    let (interp, oob) = systematic_bound(&amps, n, DEFAULT_TABLE_ROWS, &relocate);
    let alias_rms = (amps[432].powi(2) + amps[648].powi(2)).sqrt();
    eprintln!(
        "fig4 @720: sigma_m {sigma_m:.2e}; relocated rms {:.2e} peak {:.2e}; not relocated rms {:.2e} peak {:.2e}; \
         interp {interp:.1e} out-of-band {oob:.1e}; alias rms {alias_rms:.2e}",
        with.rms, with.peak, without.rms, without.peak
    );
    assert!(with.peak <= 6.0 * sigma_m + interp + oob, "{with:?}");
    assert!(with.rms <= 1.25 * sigma_m + interp + oob, "{with:?}");
    // Not relocated: the aliased lines add their RMS to the noise.
    assert!(without.rms >= 0.9 * alias_rms, "{without:?}");
    assert!(without.rms >= 4.0 * with.rms && without.peak >= 2.0 * with.peak);
}

/// 1800 points (> 2 x 648: nothing aliases) resampled to the 16384-row table
/// correct as well as a 16000-point survey.
#[test]
fn fig4_1800_points_resampled_correct_as_well_as_16000() {
    let m = Model::parse(FIG4, "fig4").unwrap();
    let truth = Truth::from_model(&m, Direction::Forward);
    let amps = spectrum(&truth, 8192);
    let mut b = TableBuilder::default();
    let none = SpectralEdit::none();
    // Without noise, the systematic residual is interpolation and out-of-band
    // content only, for both.
    let (i1800, o1800) = systematic_bound(&amps, 1800, DEFAULT_TABLE_ROWS, &[]);
    let (i16k, o16k) = systematic_bound(&amps, 16_000, DEFAULT_TABLE_ROWS, &[]);
    let clean1800 = residual(
        &b.build(&mean_map(&truth, 1800, 1, 0.0, &mut Gauss(0)), &none).unwrap(),
        &truth,
        Direction::Forward,
        20_000,
    );
    let clean16k = residual(
        &b.build(&mean_map(&truth, 16_000, 1, 0.0, &mut Gauss(0)), &none).unwrap(),
        &truth,
        Direction::Forward,
        20_000,
    );
    eprintln!(
        "noise-free: 1800 peak {:.2e} (bound {:.2e}), 16000 peak {:.2e} (bound {:.2e})",
        clean1800.peak,
        i1800 + o1800,
        clean16k.peak,
        i16k + o16k
    );
    assert!(clean1800.peak <= i1800 + o1800 && clean16k.peak <= i16k + o16k);
    assert!(clean1800.peak <= 1e-5, "the systematic residual is negligible beside any noise");

    // With the preset's noise: the same noise per point in both, so the same
    // residual, except that linear interpolation between 16384 rows averages
    // the 16000-point map's noise above ~4000 cycles (the mean square of a
    // line of phase step w between rows is (2 + cos w) / 3 of its own: 0.82 of
    // the RMS over 0..8000 cycles). Margin: 1800 within 1.25 x the 16000 RMS.
    let (runs, sigma) = (8, m.noise_sigma_deg());
    let sigma_m = sigma / (runs as f64).sqrt();
    let map1800 = mean_map(&truth, 1800, runs, sigma, &mut Gauss(18));
    let r1800 = residual(&b.build(&map1800, &none).unwrap(), &truth, Direction::Forward, 20_000);
    let r16k = residual(
        &b.build(&mean_map(&truth, 16_000, runs, sigma, &mut Gauss(16)), &none).unwrap(),
        &truth,
        Direction::Forward,
        20_000,
    );
    eprintln!(
        "sigma_m {sigma_m:.2e}: 1800 rms {:.2e} peak {:.2e}; 16000 rms {:.2e} peak {:.2e}",
        r1800.rms, r1800.peak, r16k.rms, r16k.peak
    );
    assert!(r1800.rms <= 1.25 * r16k.rms + i1800 + o1800, "{r1800:?} vs {r16k:?}");
    assert!(r1800.peak <= 6.0 * sigma_m + i1800 + o1800);
    assert!(r16k.peak <= 6.0 * sigma_m + i16k + o16k);

    // The paper's filter: keep the lines that stand out of the noise. A noise
    // line of the mean map has RMS amplitude 2 sigma_m / sqrt(N) (Rayleigh);
    // at 5 times that, a noise bin survives with probability exp(-25). What is
    // left: the noise riding on the K kept lines (RMS sigma_m sqrt(2K / N)) and
    // the true lines too small to pass (those below twice the threshold, at
    // worst all dropped: RMS sqrt(sum A^2 / 2)).
    let threshold = 5.0 * 2.0 * sigma_m / (1800f64).sqrt();
    let filter = SpectralEdit { keep: Keep::AboveThreshold { amplitude_deg: threshold }, ..SpectralEdit::none() };
    let kept = b.edited_series(&map1800, &filter).unwrap().coeffs().iter().skip(1).filter(|c| c.norm() > 0.0).count();
    let filtered = residual(&b.build(&map1800, &filter).unwrap(), &truth, Direction::Forward, 20_000);
    let small: f64 = amps.iter().skip(1).filter(|&&a| a < 2.0 * threshold).map(|a| a * a / 2.0).sum::<f64>().sqrt();
    let bound = sigma_m * (2.0 * kept as f64 / 1800.0).sqrt() + small + i1800 + o1800;
    eprintln!(
        "filtered at {threshold:.1e}: {kept} lines kept, rms {:.2e} (bound {bound:.2e}), peak {:.2e}",
        filtered.rms, filtered.peak
    );
    assert!(filtered.rms <= bound, "{filtered:?}");
    assert!(filtered.rms <= 0.5 * r1800.rms, "filtering removes most of the noise");
}

/// Backlash: one table per direction leaves only the noise; a single table
/// (the mean of both directions) leaves +b/2 forward and -b/2 in reverse.
#[test]
fn backlash_needs_a_directional_table() {
    let mut m = Model::parse(FIG4, "fig4").unwrap();
    let b_deg = 0.004;
    for e in &mut m.effects {
        if let Effect::Backlash { amplitude_deg } = e {
            *amplitude_deg = b_deg;
        }
    }
    let (n, runs, sigma) = (1800, 8, m.noise_sigma_deg());
    let sigma_m = sigma / (runs as f64).sqrt();
    let tf = Truth::from_model(&m, Direction::Forward);
    let tr = Truth::from_model(&m, Direction::Reverse);
    let mut rng = Gauss(77);
    let fwd = mean_map(&tf, n, runs, sigma, &mut rng);
    let rev = mean_map(&tr, n, runs, sigma, &mut rng);
    let mut b = TableBuilder::default();
    let none = SpectralEdit::none();
    let directional = b.build_directional(&fwd, &rev, &none).unwrap();
    let both: Vec<f64> = fwd.iter().zip(&rev).map(|(f, r)| (f + r) / 2.0).collect();
    let single = b.build(&both, &none).unwrap();
    let (interp, oob) = systematic_bound(&spectrum(&tf, 8192), n, DEFAULT_TABLE_ROWS, &[]);
    for (dir, truth, sign) in [(Direction::Forward, &tf, 1.0), (Direction::Reverse, &tr, -1.0)] {
        let d = residual(&directional, truth, dir, 20_000);
        let s = residual(&single, truth, dir, 20_000);
        eprintln!(
            "{dir}: directional rms {:.2e} peak {:.2e}; single mean {:.2e} rms {:.2e}",
            d.rms, d.peak, s.mean, s.rms
        );
        assert!(d.peak <= 6.0 * sigma_m + interp + oob, "{d:?}");
        assert!(d.rms <= 1.25 * sigma_m + interp + oob, "{d:?}");
        // The single table is off by b/2 on average; the difference of the two
        // directions' E (shifted by b in readout) averages out over a turn.
        assert!((s.mean - sign * b_deg / 2.0).abs() <= 6.0 * sigma_m / (n as f64).sqrt() + interp + oob, "{s:?}");
        assert!(s.rms >= 0.9 * b_deg / 2.0);
    }
}

/// An elevation axis measured from -10 to 90 deg (the paper's Figure 1), built
/// into a table by both partial-span methods.
#[test]
fn partial_span_elevation_table() {
    let m = Model::parse(FIG1, "fig1").unwrap();
    let truth = Truth::from_model(&m, Direction::Forward);
    let span = Span { start_deg: -10.0, end_deg: 90.0 };
    let (points, runs, sigma) = (401, 5, m.noise_sigma_deg());
    let sigma_m = sigma / (runs as f64).sqrt();
    let at = |j: usize| span.start_deg + j as f64 * span.width_deg() / (points - 1) as f64;
    let mut rng = Gauss(90);
    let clean: Vec<f64> = (0..points).map(|j| truth.at_readout(at(j))).collect();
    let noisy: Vec<f64> =
        clean.iter().map(|e| (0..runs).map(|_| e + sigma * rng.normal()).sum::<f64>() / runs as f64).collect();
    let amps = spectrum(&truth, 4096);
    let rows = DEFAULT_TABLE_ROWS;
    let (interp, _) = systematic_bound(&amps, 4096, rows, &[]);
    let dense: Vec<f64> =
        (0..20_000).map(|i| span.start_deg + span.width_deg() * (i as f64 + 0.37) / 20_000.0).collect();
    let worst = |table: &CorrectionTable| {
        dense.iter().map(|&a| (truth.at_readout(a) - table.error_at(a, Direction::Forward)).abs()).fold(0.0, f64::max)
    };

    // Least squares on the design's lines and the products the readout
    // convention adds (6 +- 72, 6 + 12, 2 x 72), a cubic for the rest. What the
    // basis lacks is bounded by 3 x the amplitude of the truth's other lines
    // (the least-squares projection of a missing line costs at most a few of
    // its amplitudes), plus the cubic's miss on the 1- and 2-cycle part.
    let cycles = vec![6.0, 12.0, 18.0, 66.0, 72.0, 78.0, 144.0];
    let method = PartialMethod::LeastSquares { cycles: cycles.clone(), poly_degree: 3 };
    let unmodeled: f64 =
        amps.iter().enumerate().filter(|&(k, _)| k >= 3 && !cycles.contains(&(k as f64))).map(|(_, a)| a).sum();
    // Chebyshev bound for a degree-3 fit of A sin(k x) over a half-width w (rad):
    // A (k w)^4 / (2^3 4!), doubled for least squares.
    let w = (span.width_deg() / 2.0).to_radians();
    let low: f64 = (1..=2).map(|k| 2.0 * amps[k] * (k as f64 * w).powi(4) / 192.0).sum();
    let det_bound = 3.0 * unmodeled + low + interp;
    let det = worst(&build_partial_table(span, &clean, &method, rows).unwrap());
    let fit = fit_partial(span, &noisy, &method).unwrap();
    let lev = dense.iter().map(|&a| fit.leverage(a)).fold(0.0, f64::max);
    let ls = build_partial_table(span, &noisy, &method, rows).unwrap();
    let ls_err = worst(&ls);
    eprintln!(
        "elevation least squares: noise-free {det:.2e} (bound {det_bound:.2e}), noisy {ls_err:.2e}, \
         sigma_m {sigma_m:.2e} x max leverage {lev:.3}, fit residual rms {:.2e}",
        fit.residual_rms_deg()
    );
    assert!(det <= det_bound, "{det:e} > {det_bound:e}");
    assert!(ls_err <= det + 6.0 * sigma_m * lev + interp + 1e-6, "{ls_err:e}");
    assert!(fit.residual_rms_deg() <= 1.2 * sigma_m, "the basis explains the map down to the noise");

    // Cubic interpolation of the map: no frequency list, all the noise.
    // Lagrange remainder: |f''''| h^4 / 24 x max |prod (u - u_i)| (1 at the
    // one-sided ends), |f''''| <= sum A (k pi / 180)^4.
    let h = span.width_deg() / (points - 1) as f64;
    let f4: f64 = amps.iter().enumerate().map(|(k, a)| a * (k as f64 * PI / 180.0).powi(4)).sum();
    let cubic_bound = f4 * h.powi(4) / 24.0;
    // Between table rows the cubic also carries the noise's curvature: at most
    // 6 sigma_m x |w''| / h^2 (|w''| <= sqrt 6 for the cubic weights), which
    // linear interpolation between rows misses by row^2 / 8 of it.
    let row = 360.0 / rows as f64;
    let noise_curvature = 6.0 * sigma_m * 6f64.sqrt() / (h * h) * row * row / 8.0;
    let cubic = build_partial_table(span, &noisy, &PartialMethod::Cubic, rows).unwrap();
    let cubic_err = worst(&cubic);
    eprintln!(
        "elevation cubic: {cubic_err:.2e} (interpolation {cubic_bound:.1e} + 6 sigma_m {:.2e} + noise curvature {noise_curvature:.1e})",
        6.0 * sigma_m
    );
    assert!(cubic_err <= cubic_bound + 6.0 * sigma_m + interp + noise_curvature);

    // Outside the span the rows are held at the nearer end, not wrapped: from
    // 90 up to half way round (220) the 90 deg value, beyond it the -10 value.
    let cubic_fit = fit_partial(span, &noisy, &PartialMethod::Cubic).unwrap();
    for (table, fit) in [(&ls, &fit), (&cubic, &cubic_fit)] {
        let step = table.spacing_deg();
        let (top, bottom) = (fit.eval(90.0), fit.eval(-10.0));
        assert_eq!(table.error_at(90.0, Direction::Forward), top, "row 4096 is at 90 deg");
        for a in [90.0 + 2.0 * step, 120.0, 200.0, 219.0] {
            assert!((table.error_at(a, Direction::Forward) - top).abs() < 1e-12, "{a}");
        }
        for a in [221.0, 300.0, 350.0 - 2.0 * step] {
            assert!((table.error_at(a, Direction::Forward) - bottom).abs() < 1e-12, "{a}");
        }
        assert!((top - bottom).abs() > 1e-3, "the two ends differ, so wrapping would show");
    }
}

/// A random positioner: gear passes (1 to 3 ratios from 2 to 30, each with 1
/// to 3 harmonics), a ring gear (50 to 300 teeth, 1 or 2 harmonics), amplitudes
/// log-uniform in 1e-4..1e-2 deg, random phases, noise log-uniform in
/// 1e-5..5e-4 deg, surveyed at N > 2 x the highest line (odd and even N).
fn design() -> impl Strategy<Value = (Vec<(usize, f64, f64)>, f64, usize, u64)> {
    (
        prop::collection::vec((2usize..=30, 1usize..=3), 1..=3),
        (50usize..=300, 1usize..=2),
        prop::collection::vec(((1e-4f64).ln()..(1e-2f64).ln(), 0.0f64..360.0), 11),
        (1e-5f64).ln()..(5e-4f64).ln(),
        1usize..200,
        any::<u64>(),
    )
        .prop_map(|(gears, (teeth, th), amp_phase, ln_sigma, extra, seed)| {
            let mut ks: Vec<usize> = gears.iter().flat_map(|&(g, h)| (1..=h).map(move |i| g * i)).collect();
            ks.extend((1..=th).map(|i| teeth * i));
            let lines: Vec<(usize, f64, f64)> =
                ks.iter().zip(&amp_phase).map(|(&k, &(la, p))| (k, la.exp(), p)).collect();
            let top = ks.iter().copied().max().unwrap_or(1);
            (lines, ln_sigma.exp(), 2 * top + extra, seed)
        })
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 16,
        rng_seed: RngSeed::Fixed(0x7ab1e),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Every random design is corrected, between the measured points, to
    /// within 6 sigma_m plus its interpolation and out-of-band terms.
    #[test]
    fn random_designs_are_corrected_down_to_their_noise((lines, sigma, n, seed) in design()) {
        let truth = Truth { lines: lines.iter().map(|&(k, a, p)| (k as f64, a, p.to_radians())).collect(), offset: 0.0 };
        let runs = 4;
        let sigma_m = sigma / (runs as f64).sqrt();
        let map = mean_map(&truth, n, runs, sigma, &mut Gauss(seed));
        let table = TableBuilder::default().build(&map, &SpectralEdit { keep: Keep::All, ..SpectralEdit::none() }).unwrap();
        let (interp, oob) = systematic_bound(&spectrum(&truth, 4 * n), n, DEFAULT_TABLE_ROWS, &[]);
        let r = residual(&table, &truth, Direction::Forward, 4000);
        let bound = 6.0 * sigma_m + interp + oob;
        prop_assert!(r.peak <= bound, "n={} sigma={:.1e}: peak {:.2e} > {:.2e} (interp {:.1e}, oob {:.1e})", n, sigma, r.peak, bound, interp, oob);
    }
}
