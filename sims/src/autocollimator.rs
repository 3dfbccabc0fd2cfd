//! A simulated autocollimator looking at an N-face polygon on the turntable.
//!
//! # Reading convention (the engine relies on it)
//!
//! Face `k` (0-based) has the nominal angle `phi_k = k * 360 / faces` degrees;
//! its certificate gives its deviation `c_k` from nominal, arcseconds. With the
//! turntable at true angle `theta`, the face in view is the nearest one (angles
//! compared modulo 360), and
//!
//! - `X = 3600 * (theta - phi_k) - c_k + noise` (with `theta - phi_k` wrapped
//!   into [-180, 180)), so the engine recovers `theta = phi_k + (X + c_k) / 3600`;
//!   where the face's true deviation `t_k` is not its certificate's (a stale
//!   certificate, [`AutocollimatorConfig::face_errors_arcsec`]), `X` reads
//!   `t_k`, and the engine, given `c_k`, errs by `c_k - t_k` at that face;
//!   with a scale error `s` ([`AutocollimatorConfig::scale_ppm`]) `X` is
//!   `(1 + s)` times the above (the noise aside);
//! - `Y = pyramidal_k + noise` (the face's pyramidal error; no axis dependence).
//!
//! When the polygon stands on a stage ([`SimAutocollimator::on_stage`], a
//! second turntable on the table, driven by its own simulated positioner),
//! the polygon's angle is the table's less the stage's, `theta - sigma`:
//! turned by `s` faces (`sigma = s * 360 / faces`, whatever the stage's own
//! error makes of it), face `k` meets the optical axis with the table at
//! `(k + s)` faces.
//!
//! The noise of each coordinate is Gaussian with sigma `noise_arcsec`. When
//! `|3600 * (theta - phi_k)| > range_arcsec` no reflection comes back:
//! `status()` is `NoReflection` and `read()` fails with the device code
//! [`CODE_NO_REFLECTION`].
//!
//! `read()` takes `read_time` of clock time and samples the angle at its start;
//! `status()` takes the link latency.
//!
//! With `blocked_probability`, that fraction of reads finds no reflection
//! although the face is in range (the view blocked for that read: an injected
//! device fault, counted by the [`Injected`] handle given with
//! [`SimAutocollimator::count_injected`]); the next read sees the face again.

use crate::faults::{FaultKind, Injected};
use crate::turntable::Turntable;
use crate::{FAULT_STREAM, LINK_LATENCY, NOISE_STREAM, seeded_rng};
use async_trait::async_trait;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::sync::Arc;
use std::time::Duration;
use survey_drivers::clock::Clock;
use survey_drivers::error::{DriverError, Result};
use survey_drivers::traits::{AcReading, AcState, Autocollimator};
use survey_processing::types::wrap_180;

const INSTRUMENT: &str = "autocollimator";

/// Device code of a read with no face in range (the simulator's own code).
pub const CODE_NO_REFLECTION: i64 = 2;

/// The standard uncertainty the simulated polygon's certificate states for
/// each face, arcsec: a calibrated polygon's certificate typically states
/// `U = 0.2` arcsec (`k = 2`). Our own choice, for the closure's weighing of
/// the certificate against the faces measured in place.
pub const CERTIFICATE_U_ARCSEC: f64 = 0.1;

/// The RNG stream that draws a default certificate and pyramidal errors.
const CERTIFICATE_STREAM: u64 = 2;

/// Configuration of a [`SimAutocollimator`].
#[derive(Debug, Clone, PartialEq)]
pub struct AutocollimatorConfig {
    /// Number of polygon faces (default 24).
    pub faces: u32,
    /// Face angle deviations from nominal, arcsec, one per face (the polygon's
    /// certificate, which the engine is given).
    pub certificate_arcsec: Vec<f64>,
    /// Pyramidal error of each face, arcsec (what Y reads).
    pub pyramidal_arcsec: Vec<f64>,
    /// Noise sigma of each coordinate, arcsec (default 0.1).
    pub noise_arcsec: f64,
    /// Half-width of the measuring range, arcsec (default 1000).
    pub range_arcsec: f64,
    /// Duration of one reading (default 200 ms).
    pub read_time: Duration,
    /// Seed of the noise stream (and of the seeded certificate).
    pub seed: u64,
    /// Probability that a read finds no reflection although the face is in
    /// range (default 0).
    pub blocked_probability: f64,
    /// The faces' true deviations from nominal, arcsec, one per face, when
    /// they are not what the certificate says (a stale certificate; `None`:
    /// the certificate is the truth).
    pub face_errors_arcsec: Option<Vec<f64>>,
    /// The autocollimator's scale error, parts per million: it reads
    /// `(1 + scale)` times the true angle from the optical axis (default 0).
    pub scale_ppm: f64,
}

impl AutocollimatorConfig {
    /// A polygon of `faces` faces whose certificate is drawn from `seed`
    /// (uniform within ±0.5 arcsec) and whose pyramidal errors are drawn from it
    /// too (uniform within ±3 arcsec); other settings at their defaults.
    pub fn seeded(faces: u32, seed: u64) -> Self {
        let faces = faces.max(1);
        let mut rng = seeded_rng(seed, CERTIFICATE_STREAM);
        let certificate_arcsec = (0..faces).map(|_| rng.random_range(-0.5..=0.5)).collect();
        let pyramidal_arcsec = (0..faces).map(|_| rng.random_range(-3.0..=3.0)).collect();
        Self {
            faces,
            certificate_arcsec,
            pyramidal_arcsec,
            noise_arcsec: 0.1,
            range_arcsec: 1000.0,
            read_time: Duration::from_millis(200),
            seed,
            blocked_probability: 0.0,
            face_errors_arcsec: None,
            scale_ppm: 0.0,
        }
    }

    /// Nominal angle of face `k`, degrees.
    pub fn nominal_deg(&self, k: usize) -> f64 {
        k as f64 * 360.0 / self.faces as f64
    }

    /// The face in view at true angle `theta_deg` and the angle of the axis from
    /// that face's nominal angle, degrees (in [-180, 180)).
    pub fn face_in_view(&self, theta_deg: f64) -> (usize, f64) {
        let pitch = 360.0 / self.faces as f64;
        let k = ((theta_deg / pitch).round().rem_euclid(self.faces as f64)) as usize % self.faces as usize;
        (k, wrap_180(theta_deg - self.nominal_deg(k)))
    }
}

impl Default for AutocollimatorConfig {
    fn default() -> Self {
        Self::seeded(24, 0)
    }
}

/// The simulated autocollimator. See the module documentation.
#[derive(Debug)]
pub struct SimAutocollimator {
    clock: Arc<dyn Clock>,
    cfg: AutocollimatorConfig,
    turntable: Turntable,
    /// The stage the polygon stands on, when it does.
    stage: Option<Turntable>,
    noise_rng: ChaCha8Rng,
    fault_rng: ChaCha8Rng,
    injected: Option<Injected>,
}

impl SimAutocollimator {
    /// An autocollimator on the polygon of `turntable`.
    ///
    /// # Panics
    /// If `faces` is 0 or the certificate or pyramidal lists do not have one
    /// entry per face.
    pub fn new(cfg: AutocollimatorConfig, clock: Arc<dyn Clock>, turntable: Turntable) -> Self {
        assert!(cfg.faces > 0, "an autocollimator polygon needs at least one face");
        let n = cfg.faces as usize;
        assert_eq!(cfg.certificate_arcsec.len(), n, "one certificate entry per face");
        assert_eq!(cfg.pyramidal_arcsec.len(), n, "one pyramidal entry per face");
        assert!(cfg.face_errors_arcsec.as_ref().is_none_or(|t| t.len() == n), "one true deviation per face");
        Self {
            noise_rng: seeded_rng(cfg.seed, NOISE_STREAM),
            fault_rng: seeded_rng(cfg.seed, FAULT_STREAM),
            clock,
            cfg,
            turntable,
            stage: None,
            injected: None,
        }
    }

    /// The polygon stands on a stage whose true angle `stage` gives (a
    /// turntable driven by its own positioner): see the module documentation.
    pub fn on_stage(&mut self, stage: Turntable) {
        self.stage = Some(stage);
    }

    /// The polygon's angle now: the table's less the stage's.
    fn polygon_deg(&self) -> f64 {
        let now = self.clock.now();
        self.turntable.actual_deg(now) - self.stage.as_ref().map_or(0.0, |s| s.actual_deg(now))
    }

    /// Count every fault this instrument injects in `injected`.
    pub fn count_injected(&mut self, injected: Injected) {
        self.injected = Some(injected);
    }

    /// The polygon certificate: face deviations from nominal, arcsec.
    pub fn certificate_arcsec(&self) -> &[f64] {
        &self.cfg.certificate_arcsec
    }

    /// Number of faces.
    pub fn faces(&self) -> u32 {
        self.cfg.faces
    }

    /// The configuration.
    pub fn config(&self) -> &AutocollimatorConfig {
        &self.cfg
    }

    fn in_range(&self, offset_deg: f64) -> bool {
        (offset_deg * 3600.0).abs() <= self.cfg.range_arcsec
    }
}

#[async_trait]
impl Autocollimator for SimAutocollimator {
    fn name(&self) -> &str {
        "sim-autocollimator"
    }

    async fn read(&mut self) -> Result<AcReading> {
        let theta = self.polygon_deg();
        self.clock.sleep(self.cfg.read_time).await;
        let (k, offset) = self.cfg.face_in_view(theta);
        let blocked =
            self.cfg.blocked_probability > 0.0 && self.fault_rng.random::<f64>() < self.cfg.blocked_probability;
        if blocked {
            if let Some(i) = &self.injected {
                i.add(FaultKind::Device);
            }
            return Err(DriverError::device(
                INSTRUMENT,
                CODE_NO_REFLECTION,
                format!("no reflection from face {k}: the view is blocked (simulated)"),
            ));
        }
        if !self.in_range(offset) {
            return Err(DriverError::device(
                INSTRUMENT,
                CODE_NO_REFLECTION,
                format!(
                    "no reflection: face {k} is {:.0} arcsec off the optical axis (range ±{} arcsec)",
                    offset * 3600.0,
                    self.cfg.range_arcsec
                ),
            ));
        }
        let zx: f64 = StandardNormal.sample(&mut self.noise_rng);
        let zy: f64 = StandardNormal.sample(&mut self.noise_rng);
        let sigma = self.cfg.noise_arcsec;
        // The face's true deviation: its certificate's, unless stale.
        let deviation = self.cfg.face_errors_arcsec.as_ref().map_or(self.cfg.certificate_arcsec[k], |t| t[k]);
        let scale = 1.0 + self.cfg.scale_ppm * 1e-6;
        Ok(AcReading {
            x_arcsec: (3600.0 * offset - deviation) * scale + sigma * zx,
            y_arcsec: self.cfg.pyramidal_arcsec[k] + sigma * zy,
        })
    }

    async fn status(&mut self) -> Result<AcState> {
        self.clock.sleep(LINK_LATENCY).await;
        let (_, offset) = self.cfg.face_in_view(self.polygon_deg());
        Ok(if self.in_range(offset) { AcState::InRange } else { AcState::NoReflection })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use survey_drivers::VirtualClock;
    use survey_drivers::error::ErrorKind;

    fn setup(seed: u64) -> (VirtualClock, Turntable, SimAutocollimator) {
        let clock = VirtualClock::new();
        let table = Turntable::new(0.0);
        let ac = SimAutocollimator::new(AutocollimatorConfig::seeded(24, seed), Arc::new(clock.clone()), table.clone());
        (clock, table, ac)
    }

    #[test]
    fn default_certificate_is_seeded_and_small() {
        let a = AutocollimatorConfig::seeded(24, 5);
        assert_eq!(a, AutocollimatorConfig::seeded(24, 5));
        assert_ne!(a.certificate_arcsec, AutocollimatorConfig::seeded(24, 6).certificate_arcsec);
        assert_eq!(a.certificate_arcsec.len(), 24);
        assert!(a.certificate_arcsec.iter().all(|c| c.abs() <= 0.5));
        assert!(a.certificate_arcsec.iter().any(|c| c.abs() > 0.05));
        assert_eq!(AutocollimatorConfig::default().faces, 24);
    }

    #[test]
    fn face_in_view_wraps() {
        let c = AutocollimatorConfig::default();
        assert_eq!(c.face_in_view(15.1).0, 1);
        let (k, off) = c.face_in_view(359.9);
        assert_eq!(k, 0);
        assert!((off + 0.1).abs() < 1e-9);
        let (k, off) = c.face_in_view(-30.05);
        assert_eq!(k, 22);
        assert!((off + 0.05).abs() < 1e-9);
    }

    #[tokio::test]
    async fn reading_round_trips_the_angle_within_noise() {
        let (clock, table, mut ac) = setup(3);
        let cert = ac.certificate_arcsec().to_vec();
        let faces = ac.faces();
        let pitch = 360.0 / faces as f64;
        let mut worst: f64 = 0.0;
        for (i, k) in (0..faces as usize).chain([0, 23]).enumerate() {
            // A little off the face, on either side, and across the wrap at 360.
            let off_arcsec = [-700.0, 123.4, 950.0, -5.0][i % 4];
            let theta = k as f64 * pitch + off_arcsec / 3600.0 + if i % 5 == 0 { 360.0 } else { 0.0 };
            table.place(theta);
            let t0 = clock.now();
            let r = ac.read().await.unwrap();
            assert_eq!(clock.now() - t0, Duration::from_millis(200));
            let recovered = k as f64 * pitch + (r.x_arcsec + cert[k]) / 3600.0;
            worst = worst.max((3600.0 * wrap_180(recovered - theta)).abs());
            assert!((r.y_arcsec - ac.config().pyramidal_arcsec[k]).abs() < 0.5);
            assert_eq!(ac.status().await.unwrap(), AcState::InRange);
        }
        // Noise 0.1 arcsec: 5 sigma.
        assert!(worst < 0.5, "worst round-trip error {worst} arcsec");
    }

    #[tokio::test]
    async fn out_of_range_is_no_reflection() {
        let (_clock, table, mut ac) = setup(1);
        table.place(15.0 + 1001.0 / 3600.0);
        assert_eq!(ac.status().await.unwrap(), AcState::NoReflection);
        let e = ac.read().await.unwrap_err();
        assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(CODE_NO_REFLECTION)));
        assert!(e.message.contains("no reflection"), "{e}");
        table.place(15.0 + 999.0 / 3600.0);
        assert_eq!(ac.status().await.unwrap(), AcState::InRange);
        assert!(ac.read().await.is_ok());
    }

    #[tokio::test]
    async fn blocked_reads_find_no_reflection_at_their_rate_and_are_counted() {
        let clock = VirtualClock::new();
        let table = Turntable::new(0.0);
        let cfg = AutocollimatorConfig { blocked_probability: 0.1, ..AutocollimatorConfig::seeded(24, 4) };
        let mut ac = SimAutocollimator::new(cfg, Arc::new(clock), table.clone());
        let injected = Injected::new();
        ac.count_injected(injected.clone());
        table.place(30.0);
        let n = 2000;
        let mut blocked = 0;
        for _ in 0..n {
            if let Err(e) = ac.read().await {
                assert_eq!(e.code, Some(CODE_NO_REFLECTION));
                assert!(e.message.contains("face 2"), "{e}");
                blocked += 1;
            }
        }
        assert_eq!(injected.get(FaultKind::Device), blocked);
        // Binomial(2000, 0.1): mean 200, sd 13.4; 4 sd.
        assert!((blocked as f64 - 200.0).abs() < 54.0, "{blocked} blocked");
    }

    #[tokio::test]
    async fn noise_has_its_sigma() {
        let (_clock, table, mut ac) = setup(11);
        table.place(30.0);
        let n = 2000;
        let mut xs = Vec::with_capacity(n);
        for _ in 0..n {
            xs.push(ac.read().await.unwrap().x_arcsec);
        }
        let mean = xs.iter().sum::<f64>() / n as f64;
        let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
        // Relative standard error of a sample sd: 1/sqrt(2(n-1)); 4 of them.
        let tol = 4.0 / (2.0 * (n - 1) as f64).sqrt();
        assert!((sd / 0.1 - 1.0).abs() < tol, "sd {sd}");
        assert!((mean + ac.certificate_arcsec()[2]).abs() < 4.0 * 0.1 / (n as f64).sqrt());
    }

    #[tokio::test]
    async fn a_stale_certificate_and_a_scale_error_read_as_their_causes_do() {
        let clock = VirtualClock::new();
        let table = Turntable::new(0.0);
        let mut cfg = AutocollimatorConfig { noise_arcsec: 0.0, ..AutocollimatorConfig::seeded(24, 3) };
        let stated = cfg.certificate_arcsec.clone();
        // Face 5 truly 1.5 arcsec off what its certificate states.
        let mut truth = stated.clone();
        truth[5] += 1.5;
        cfg.face_errors_arcsec = Some(truth.clone());
        let mut ac = SimAutocollimator::new(cfg.clone(), Arc::new(clock.clone()), table.clone());
        assert_eq!(ac.certificate_arcsec(), &stated[..], "the engine is given the certificate");
        // At face 5's nominal angle plus 100 arcsec: the reading is of the true face.
        table.place(5.0 * 15.0 + 100.0 / 3600.0);
        let x = ac.read().await.unwrap().x_arcsec;
        assert!((x - (100.0 - truth[5])).abs() < 1e-6, "{x}");
        // The engine's angle, from the certificate, errs by certificate - truth.
        let angle = 75.0 + (x + stated[5]) / 3600.0;
        assert!(((angle - (75.0 + 100.0 / 3600.0)) * 3600.0 + 1.5).abs() < 1e-6, "{angle}");
        // A scale error of 1000 ppm: 1000 ppm of what the face shows.
        cfg.scale_ppm = 1000.0;
        let mut scaled = SimAutocollimator::new(cfg, Arc::new(clock.clone()), table.clone());
        let y = scaled.read().await.unwrap().x_arcsec;
        assert!((y - x * 1.001).abs() < 1e-6, "{y} against {x}");
    }
}
