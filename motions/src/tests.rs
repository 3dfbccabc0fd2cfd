//! The figures against known motions: SMR positions made with the model
//! file's motions (`survey_processing::model::AxisMotions`, the code the
//! simulated tracker moves its SMRs with), seeded normal noise.

use super::*;
use survey_processing::model::{AxisMotions, MotionHarmonic, SmrPlace};

/// SplitMix64 then Box-Muller: seeded standard normals.
struct Normals(u64);

impl Normals {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    fn next(&mut self) -> f64 {
        let (a, b) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }
}

const CENTRE: [f64; 3] = [2500.0, 800.0, -300.0];
const RADIUS: f64 = 1000.0;

/// The axis tilted 0.3 deg toward 30 deg: its (u, v, n).
fn basis() -> ([f64; 3], [f64; 3], [f64; 3]) {
    let (t, w) = (0.3f64.to_radians(), 30f64.to_radians());
    let n = [t.sin() * w.cos(), t.sin() * w.sin(), t.cos()];
    let d = n[0];
    let u0 = [1.0 - d * n[0], -d * n[1], -d * n[2]];
    let l = (u0[0] * u0[0] + u0[1] * u0[1] + u0[2] * u0[2]).sqrt();
    let u = u0.map(|x| x / l);
    let v = [n[1] * u[2] - n[2] * u[1], n[2] * u[0] - n[0] * u[2], n[0] * u[1] - n[1] * u[0]];
    (u, v, n)
}

/// A survey of `points` targets, `runs` runs both ways, with SMRs at
/// `mounts` (height above the tilt's pivot), moved by `motions` and read with
/// noise `sigma_um` per coordinate.
fn survey(
    points: usize,
    runs: u32,
    mounts: &[SmrMount],
    motions: &AxisMotions,
    sigma_um: f64,
) -> (Vec<Sample>, Vec<Vec<[f64; 3]>>) {
    let (u, v, n) = basis();
    let mut rng = Normals(52);
    let mut samples = Vec::new();
    let mut tracks = vec![Vec::new(); mounts.len()];
    for run in 1..=runs {
        for direction in [Direction::Forward, Direction::Reverse] {
            for j in 0..points {
                let j = if direction == Direction::Forward { j } else { points - 1 - j };
                let theta = 360.0 * j as f64 / points as f64;
                samples.push(Sample {
                    run,
                    direction,
                    target_deg: theta,
                    readout_deg: theta,
                    actual_deg: theta,
                    timestamp_s: None,
                });
                let jitter: [f64; 3] = std::array::from_fn(|_| motions.bearing_sigma_um * rng.next());
                for (k, m) in mounts.iter().enumerate() {
                    let place = SmrPlace { phase_deg: m.phase_deg, radius_mm: RADIUS, height_mm: m.height_mm };
                    let [dr, dt, dz] = motions.displacement_um(theta, place);
                    let (s, c) = (theta + 37.0 + m.phase_deg).to_radians().sin_cos();
                    let p: [f64; 3] = std::array::from_fn(|i| {
                        let out = c * u[i] + s * v[i];
                        let along = -s * u[i] + c * v[i];
                        CENTRE[i]
                            + m.height_mm * n[i]
                            + RADIUS * out
                            + 1e-3
                                * (dr * out
                                    + dt * along
                                    + dz * n[i]
                                    + jitter[0] * u[i]
                                    + jitter[1] * v[i]
                                    + jitter[2] * n[i])
                    });
                    let noisy = p.map(|x| x + 1e-3 * sigma_um * rng.next());
                    tracks[k].push(noisy);
                }
            }
        }
    }
    (samples, tracks)
}

fn motions(radial: &[(u32, f64, f64)], axial: &[(u32, f64, f64)], tilt: &[(u32, f64, f64)]) -> AxisMotions {
    let h = |l: &[(u32, f64, f64)]| {
        l.iter()
            .map(|&(cycles_per_rev, amplitude, phase_deg)| MotionHarmonic { cycles_per_rev, amplitude, phase_deg })
            .collect()
    };
    AxisMotions { radial: h(radial), axial: h(axial), tilt: h(tilt), bearing_sigma_um: 0.0 }
}

fn run(samples: &[Sample], tracks: &[Vec<[f64; 3]>], mounts: &[SmrMount]) -> ErrorMotions {
    let tracks = tracks.iter().zip(mounts).map(|(p, m)| Track { mount: *m, points_mm: p }).collect();
    error_motions(&Input { samples, tracks, mpe: TransverseMpe::AT_CLASS }).expect("figures")
}

/// The peak-to-valley of `f` over the survey's targets.
fn pv(points: usize, f: impl Fn(f64) -> f64) -> f64 {
    let v: Vec<f64> = (0..points).map(|j| f(360.0 * j as f64 / points as f64)).collect();
    v.iter().copied().fold(f64::NEG_INFINITY, f64::max) - v.iter().copied().fold(f64::INFINITY, f64::min)
}

#[test]
fn one_smr_radial_and_axial_against_the_truth() {
    let m = motions(&[(2, 60.0, 40.0), (3, 20.0, 200.0)], &[(3, 40.0, 10.0)], &[]);
    let mounts = [SmrMount { phase_deg: 0.0, height_mm: 50.0 }];
    let (samples, tracks) = survey(72, 3, &mounts, &m, 3.5);
    let e = run(&samples, &tracks, &mounts);
    let radial = pv(72, |t| m.radial_um(t, 0.0));
    let axial = pv(72, |t| m.axial_um(t));
    let r = e.radial_um.synchronous.expect("above the limit");
    let a = e.axial_um.synchronous.expect("above the limit");
    assert!(
        (r - radial).abs() <= e.radial_um.u_synchronous,
        "radial {r} against {radial} +/- {}",
        e.radial_um.u_synchronous
    );
    assert!((a - axial).abs() <= e.axial_um.u_synchronous, "axial {a} against {axial}");
    // With an exact tracker the figures are the truth to the noise's share.
    assert!((r - radial).abs() < 12.0 && (a - axial).abs() < 12.0, "{r} {radial} {a} {axial}");
    let total = e.radial_um.total.unwrap();
    assert!(total >= r && total - radial <= e.radial_um.u_total, "{total}");
    assert!(e.tilt_urad.is_none() && e.notes[0].contains("no tilt"));
    // The detection limit: 15 um + 6 um/m at the farthest reading (about 3.6 m), or the noise's own peak-to-valley.
    assert!((36.8..45.0).contains(&e.detection_limit_um), "{}", e.detection_limit_um);
    // Noise only across runs: the asynchronous figure is below the limit.
    assert!(e.radial_um.asynchronous.is_none() && e.radial_um.below_limit == ["asynchronous"]);
    // The location: the circle centre 50 mm up the axis, the tilt 0.3 deg toward 30 deg.
    let (_, _, n) = basis();
    assert!((e.location.x0_mm - (CENTRE[0] + 50.0 * n[0])).abs() < 0.01, "{:?}", e.location);
    assert!((e.location.y0_mm - (CENTRE[1] + 50.0 * n[1])).abs() < 0.01, "{:?}", e.location);
    let tilt = 0.3f64.to_radians();
    assert!((e.location.b0_urad - 1e6 * (tilt.sin() * 30f64.to_radians().cos()).atan2(tilt.cos())).abs() < 20.0);
    assert!((e.location.a0_urad + 1e6 * (tilt.sin() * 30f64.to_radians().sin()).atan2(tilt.cos())).abs() < 20.0);
    assert_eq!(e.polar.len(), 144);
}

#[test]
fn two_smrs_at_two_heights_give_the_tilt() {
    let m = motions(&[(2, 50.0, 0.0)], &[], &[(2, 300.0, 90.0)]);
    let mounts = [SmrMount { phase_deg: 0.0, height_mm: 50.0 }, SmrMount { phase_deg: 0.0, height_mm: 350.0 }];
    let (samples, tracks) = survey(72, 2, &mounts, &m, 3.5);
    let e = run(&samples, &tracks, &mounts);
    let t = e.tilt_urad.as_ref().expect("a tilt");
    let truth = pv(72, |x| m.tilt_urad(x, 0.0));
    let got = t.synchronous.expect("above the limit");
    assert!((got - truth).abs() <= t.u_synchronous, "tilt {got} against {truth} +/- {}", t.u_synchronous);
    assert!((got - truth).abs() < 40.0, "{got} {truth}");
    // The first SMR's radial motion carries its height's share of the tilt.
    let radial = pv(72, |x| m.radial_um(x, 0.0) - 0.05 * m.tilt_urad(x, 0.0));
    assert!((e.radial_um.synchronous.unwrap() - radial).abs() < 12.0, "{:?} {radial}", e.radial_um);
}

#[test]
fn a_small_wobble_is_below_the_detection_limit() {
    let m = motions(&[(2, 4.0, 0.0)], &[(2, 3.0, 0.0)], &[]);
    let mounts = [SmrMount::FIRST];
    let (samples, tracks) = survey(72, 2, &mounts, &m, 3.5);
    let e = run(&samples, &tracks, &mounts);
    for b in [&e.radial_um, &e.axial_um] {
        assert_eq!((b.total, b.synchronous, b.asynchronous), (None, None, None), "{b:?}");
        assert!(b.below_detection_limit && b.u > 0.0);
    }
    let json = serde_json::to_value(&e).unwrap();
    assert!(json["radial_um"]["total"].is_null() && json["radial_um"]["below_detection_limit"] == true);
    for key in ["x0_mm", "y0_mm", "a0_urad", "b0_urad"] {
        assert!(json["location"][key].is_f64(), "{key}");
    }
    assert!(json["tilt_urad"].is_null() && json["detection_limit_um"].is_f64());
}
