//! The SMRs' angles combined against a known tracker error and a known
//! positioner: what stays of the tracker's error, and the stated `u_deg`.

use super::*;

/// A tracker error function of the place on the circle, degrees: orders 1 to
/// 8, a few tenths of a millidegree each (the size a typical tracker puts
/// into a 1 m arm's angles).
fn tracker_error(psi_deg: f64) -> f64 {
    let p = psi_deg.to_radians();
    (1..=8).map(|m| 2.0e-4 / m as f64 * (m as f64 * p + 0.7 * m as f64).sin()).sum()
}

/// The same, its orders that are multiples of `n` only.
fn multiples_of(n: usize, psi_deg: f64) -> f64 {
    let p = psi_deg.to_radians();
    (1..=8).filter(|m| m % n == 0).map(|m| 2.0e-4 / m as f64 * (m as f64 * p + 0.7 * m as f64).sin()).sum()
}

/// A positioner error: a 20-cycle gear and eccentricity.
fn positioner(theta_deg: f64) -> f64 {
    let t = theta_deg.to_radians();
    0.008 * (20.0 * t).sin() + 0.0015 * (t + 1.9).sin()
}

/// A deterministic noise of standard deviation about `sd` (a sum of three
/// uniforms from a small linear congruential generator).
struct Noise(u64);

impl Noise {
    fn next(&mut self, sd: f64) -> f64 {
        let mut u = || {
            self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        (u() + u() + u()) * 2.0 * sd
    }
}

/// Samples of `points` targets x `runs`, the SMRs at `phases`: (targets,
/// each SMR's angles, each sample's true angle).
fn survey(points: usize, runs: usize, phases: &[f64], noise_sd: f64) -> (Vec<f64>, Vec<Vec<f64>>, Vec<f64>) {
    let mut noise = Noise(7);
    let (mut targets, mut truth) = (Vec::new(), Vec::new());
    let mut angles = vec![Vec::new(); phases.len()];
    for _ in 0..runs {
        for j in 0..points {
            let target = 360.0 * j as f64 / points as f64;
            let true_angle = target - positioner(target);
            targets.push(target);
            truth.push(true_angle);
            for (k, phi) in phases.iter().enumerate() {
                // Each SMR's own zero differs by a constant.
                angles[k].push(true_angle + tracker_error(true_angle + phi) + 1e-3 * k as f64 + noise.next(noise_sd));
            }
        }
    }
    (targets, angles, truth)
}

fn residual_rms(c: &Combined, truth: &[f64], left: impl Fn(f64) -> f64) -> f64 {
    let r: Vec<f64> = c.angles_deg.iter().zip(truth).map(|(a, t)| a - t - left(*t)).collect();
    let mean = r.iter().sum::<f64>() / r.len() as f64;
    (r.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / r.len() as f64).sqrt()
}

#[test]
fn one_smr_keeps_the_whole_bound() {
    let (targets, angles, _) = survey(90, 2, &[0.0], 1e-5);
    let c = combine(&targets, &angles, &[0.0], 7.7e-4);
    assert_eq!((c.method, c.separated, c.u_deg), (Method::None, false, 7.7e-4));
    assert_eq!(c.angles_deg, angles[0]);
}

#[test]
fn equal_spacing_cancels_every_order_but_the_multiples_of_the_count() {
    let phases = [0.0, 120.0, 240.0];
    let (targets, angles, truth) = survey(360, 3, &phases, 0.0);
    let c = combine(&targets, &angles, &phases, 7.7e-4);
    assert_eq!((c.method, c.separated), (Method::EqualDivision, true));
    // What stays is exactly the tracker's orders 3 and 6 (to rounding).
    let rms = residual_rms(&c, &truth, |t| multiples_of(3, t));
    assert!(rms < 1e-12, "{rms}");
    // One SMR alone left all of it.
    let one = Combined { angles_deg: angles[0].clone(), ..c.clone() };
    assert!(residual_rms(&one, &truth, |_| 0.0) > 1e-4);
    // U: the unseen orders' share of the bound (orders 3, 6, ... of the 179 resolved: 59 of them).
    let share = 7.7e-4 * (59.0f64 / 179.0).sqrt();
    assert!((c.u_deg / share - 1.0).abs() < 1e-9, "{} against {share}", c.u_deg);
}

#[test]
fn unequal_spacing_separates_the_trackers_error_to_its_noise() {
    let phases = [0.0, 37.0, 131.0];
    let noise = 2e-5;
    let (targets, angles, truth) = survey(360, 3, &phases, noise);
    let c = combine(&targets, &angles, &phases, 7.7e-4);
    assert_eq!((c.method, c.separated), (Method::Separation, true));
    // The tracker's error is gone to the noise of the mean of three SMRs
    // (2e-5 / sqrt 3 a reading) and of the separated orders.
    let rms = residual_rms(&c, &truth, |_| 0.0);
    let one = residual_rms(&Combined { angles_deg: angles[0].clone(), ..c.clone() }, &truth, |_| 0.0);
    assert!(rms < 1.6e-5 && one > 10.0 * rms, "combined {rms:.2e}, one SMR {one:.2e}");
    // The separated lines are the tracker's: orders 1..4 at their amplitudes, phases.
    for m in 1..=4 {
        let line = c.lines.iter().find(|l| l.cycles_per_rev == m as f64).unwrap_or_else(|| panic!("order {m}: {c:?}"));
        let want = 2.0e-4 / m as f64;
        assert!((line.amplitude_deg - want).abs() < 5e-6, "order {m}: {line:?}");
        let phase = wrap_180(line.phase_deg - (0.7 * m as f64).to_degrees());
        assert!(phase.abs() < 3.0, "order {m}: {line:?}");
    }
    // U covers what is left and is far below one SMR's bound: the orders
    // these phases cannot see (88, 107 and 165 of the 179 resolved, where
    // every SMR's phase is nearly a whole turn) keep their share of it.
    assert!(c.notes[0].contains("3 order(s) no difference between them sees (88, 107, 165)"), "{:?}", c.notes);
    let unseen = 7.7e-4 * (3.0f64 / 179.0).sqrt();
    assert!(c.u_deg > 0.9 * unseen && c.u_deg < 1.1 * unseen && rms < c.u_deg, "{} {:?}", c.u_deg, c.notes);
}

#[test]
fn a_partial_arc_is_averaged_and_keeps_the_bound() {
    let phases = [0.0, 120.0, 240.0];
    let (targets, angles, _) = survey(360, 2, &phases, 0.0);
    let keep: Vec<usize> = (0..targets.len()).filter(|s| targets[*s] < 90.0).collect();
    let t: Vec<f64> = keep.iter().map(|s| targets[*s]).collect();
    let a: Vec<Vec<f64>> = angles.iter().map(|v| keep.iter().map(|s| v[*s]).collect()).collect();
    let c = combine(&t, &a, &phases, 7.7e-4);
    assert!(!c.separated && c.u_deg == 7.7e-4, "{c:?}");
    assert!(c.notes[0].contains("full circle"), "{:?}", c.notes);
}

#[test]
fn the_expected_position_of_an_smr_is_on_the_located_circle() {
    let axis = crate::geometry::AxisFit {
        center_mm: [100.0, 0.0, 0.0],
        normal: [0.0, 0.0, 1.0],
        u: [1.0, 0.0, 0.0],
        v: [0.0, 1.0, 0.0],
        radius_mm: 500.0,
        zero_offset_deg: 10.0,
        plane_rms_mm: 0.0,
        circle_rms_mm: 0.0,
        points: 12,
    };
    let p = SmrMount { phase_deg: 80.0, height_mm: 30.0 }.expected_position_mm(&axis, 0.0);
    // Raw angle 0 + 10 + 80 = 90 deg: along v, 30 mm up.
    assert!((p[0] - 100.0).abs() < 1e-9 && (p[1] - 500.0).abs() < 1e-9 && (p[2] - 30.0).abs() < 1e-9, "{p:?}");
    assert_eq!(SmrMount::equal(4).iter().map(|m| m.phase_deg).collect::<Vec<_>>(), [0.0, 90.0, 180.0, 270.0]);
}
