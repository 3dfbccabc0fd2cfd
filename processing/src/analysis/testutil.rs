//! Test support: a deterministic normal generator and synthetic surveys.

use crate::model::Model;
use crate::types::{Direction, Sample};

/// SplitMix64 with Box-Muller: deterministic, seeded, no dependency.
#[derive(Debug, Clone)]
pub struct Normal {
    state: u64,
    spare: Option<f64>,
}

impl Normal {
    pub fn new(seed: u64) -> Self {
        Normal { state: seed ^ 0x5DEE_CE66_D1CE_4E5B, spare: None }
    }

    fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in (0, 1).
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// Standard normal.
    pub fn sample(&mut self) -> f64 {
        if let Some(s) = self.spare.take() {
            return s;
        }
        let (u, v) = (self.uniform(), self.uniform());
        let r = (-2.0 * u.ln()).sqrt();
        let (s, c) = (2.0 * std::f64::consts::PI * v).sin_cos();
        self.spare = Some(r * s);
        r * c
    }
}

/// The Figure 4 azimuth positioner (the simulators' preset).
pub fn fig4() -> Model {
    Model::parse(include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/../sims/presets/fig4.toml")), "fig4.toml").unwrap()
}

/// The Figure 1 elevation axis (the simulators' preset).
pub fn fig1() -> Model {
    Model::parse(include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/../sims/presets/fig1.toml")), "fig1.toml").unwrap()
}

/// `n` targets uniformly over a revolution from `start`.
pub fn circle(n: usize, start: f64) -> Vec<f64> {
    (0..n).map(|k| start + k as f64 * 360.0 / n as f64).collect()
}

/// A synthetic survey: at every target, run and direction, the readout error is
/// `error(run, direction, theta)` plus normal noise of `sigma`. The actual angle
/// is the target plus a per-run offset (so only `readout - actual` carries the error).
pub fn survey(
    targets: &[f64],
    runs: u32,
    directions: &[Direction],
    sigma: f64,
    seed: u64,
    error: impl Fn(u32, Direction, f64) -> f64,
) -> Vec<Sample> {
    let mut rng = Normal::new(seed);
    let mut out = Vec::with_capacity(targets.len() * runs as usize * directions.len());
    for run in 1..=runs {
        for &direction in directions {
            let ordered: Vec<f64> = match direction {
                Direction::Forward => targets.to_vec(),
                Direction::Reverse => targets.iter().rev().copied().collect(),
            };
            for t in ordered {
                let actual = t + 1e-3 * run as f64;
                let e = error(run, direction, t) + sigma * rng.sample();
                out.push(Sample {
                    run,
                    direction,
                    target_deg: t,
                    readout_deg: actual + e,
                    actual_deg: actual,
                    timestamp_s: None,
                });
            }
        }
    }
    out
}

/// A survey of `points` targets, `runs` runs both ways, one reading a
/// second (each sample stamped with its place in acquisition order): the
/// error two lines (20 and 1 cycles/rev) and 0.008 deg of backlash, plus
/// `drift(t, run)` and normal noise of `sigma`.
pub fn timed_survey(points: usize, runs: u32, sigma: f64, seed: u64, drift: impl Fn(f64, u32) -> f64) -> Vec<Sample> {
    let targets = circle(points, 0.0);
    let time = |run: u32, d: Direction, t: f64| {
        let k = (t * points as f64 / 360.0).round() as usize;
        let (pass, at) = match d {
            Direction::Forward => (0, k),
            Direction::Reverse => (1, points - 1 - k),
        };
        (((run as usize - 1) * 2 + pass) * points + at) as f64
    };
    let mut out = survey(&targets, runs, &[Direction::Forward, Direction::Reverse], sigma, seed, |run, d, t| {
        let x = t.to_radians();
        let back = if d == Direction::Forward { 0.004 } else { -0.004 };
        0.0078 * (20.0 * x).sin() + 0.0015 * (x + 1.9).sin() + back + drift(time(run, d, t), run)
    });
    for (i, s) in out.iter_mut().enumerate() {
        s.timestamp_s = Some(i as f64);
    }
    out
}

/// The true angle `theta` at which a positioner whose error at the true angle
/// is `error(theta)` reads `readout` (`theta + error(theta) = readout`, the
/// contract's convention), by fixed-point iteration.
pub fn true_angle(readout: f64, error: impl Fn(f64) -> f64) -> f64 {
    let mut theta = readout;
    for _ in 0..60 {
        theta = readout - error(theta);
    }
    theta
}

/// [`survey`] with the contract's convention: `error(run, direction, theta)`
/// is a function of the TRUE angle, and the sample at target `t` carries it at
/// the `theta` where the positioner reads `t` ([`true_angle`]): the error as
/// a function of the readout then holds the products of the lines, as a
/// simulated or a real positioner's does.
pub fn survey_at_true_angle(
    targets: &[f64],
    runs: u32,
    directions: &[Direction],
    sigma: f64,
    seed: u64,
    error: impl Fn(u32, Direction, f64) -> f64,
) -> Vec<Sample> {
    survey(targets, runs, directions, sigma, seed, |run, d, t| error(run, d, true_angle(t, |th| error(run, d, th))))
}

#[test]
fn normal_generator_has_unit_moments() {
    let mut g = Normal::new(42);
    let x: Vec<f64> = (0..200_000).map(|_| g.sample()).collect();
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / x.len() as f64;
    assert!(mean.abs() < 0.01 && (var - 1.0).abs() < 0.01, "{mean} {var}");
    let tail = x.iter().filter(|v| v.abs() > 3.0).count() as f64 / x.len() as f64;
    assert!((tail - 0.0027).abs() < 0.0006, "{tail}");
}
