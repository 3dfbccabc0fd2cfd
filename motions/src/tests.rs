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
    error_motions(&Input { samples, tracks, mpe: TransverseMpe::AT_CLASS, frame: None }).expect("figures")
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

/// The peak-to-valley of the model's tilt and axial motion on the axis at
/// the survey's targets, and the synchronous figures reported.
fn on_axis_and_tilt(e: &ErrorMotions, m: &AxisMotions, points: usize) -> ((f64, f64), (f64, f64)) {
    let on_axis = e.axial_on_axis_um.as_ref().expect("the phases separate it");
    let tilt = e.tilt_urad.as_ref().expect("a tilt");
    assert!((on_axis.u_synchronous - on_axis.u).abs() >= 0.0 && tilt.smrs >= 2);
    let truth = (pv(points, |t| m.axial_um(t)), pv(points, |t| m.tilt_urad(t, 0.0)));
    let got = (on_axis.synchronous.expect("above the limit"), tilt.synchronous.expect("above the limit"));
    assert!(
        (got.0 - truth.0).abs() <= on_axis.u_synchronous,
        "on the axis {} against {} +/- {}",
        got.0,
        truth.0,
        on_axis.u_synchronous
    );
    assert!(
        (got.1 - truth.1).abs() <= tilt.u_synchronous,
        "tilt {} against {} +/- {}",
        got.1,
        truth.1,
        tilt.u_synchronous
    );
    (got, truth)
}

#[test]
fn two_smrs_at_opposite_phases_give_the_axial_motion_on_the_axis_and_the_tilt() {
    // A fundamental axial motion (1 cpr) too: on the axis it is a motion, kept; at one SMR the plane takes it.
    let m = motions(&[(2, 30.0, 0.0)], &[(1, 25.0, 20.0), (3, 40.0, 10.0)], &[(2, 150.0, 60.0)]);
    let mounts = [SmrMount { phase_deg: 0.0, height_mm: 50.0 }, SmrMount { phase_deg: 180.0, height_mm: 50.0 }];
    let (samples, tracks) = survey(72, 2, &mounts, &m, 3.5);
    let e = run(&samples, &tracks, &mounts);
    let (got, truth) = on_axis_and_tilt(&e, &m, 72);
    // An exact tracker: the noise's share only (3.5 um a coordinate, halved by the pair's mean and the 2 runs'
    // mean, read as a peak-to-valley of 144 readings: about 2 x 3 x 1.75 um at most).
    assert!((got.0 - truth.0).abs() < 12.0 && (got.1 - truth.1).abs() < 12.0, "{got:?} {truth:?}");
    let t = e.tilt_urad.as_ref().unwrap();
    assert_eq!((t.method, t.smrs), ("phases", 2));
    // U of the pair: the MPE once (the weights 1/2 and 1/2 add to 1), the random bound by 1/sqrt(2); the tilt's
    // the same over the 1 m radius (weights +-1/2 over 1 m).
    let on_axis = e.axial_on_axis_um.as_ref().unwrap();
    let systematic = |b: &Block| (b.u_total.powi(2) - b.u_asynchronous.powi(2)).sqrt();
    assert!((systematic(on_axis) - systematic(&e.axial_um)).abs() < 0.01, "{on_axis:?} {:?}", e.axial_um);
    assert!((on_axis.u_asynchronous - e.axial_um.u_asynchronous / 2f64.sqrt()).abs() < 0.01, "{on_axis:?}");
    assert!((t.u_total - on_axis.u_total).abs() < 0.5, "{t:?} {on_axis:?}");
    // One SMR's face motion is still reported: at 1 m the tilt's share, less the 1 cpr the plane takes.
    let face = pv(72, |x| 40.0 * (3.0 * x + 10.0).to_radians().sin() + m.tilt_urad(x, 0.0));
    assert!((e.axial_um.synchronous.unwrap() - face).abs() < 12.0, "{:?} {face}", e.axial_um);
    assert!(e.notes.iter().any(|n| n.contains("2 SMRs at 0.0, 180.0 deg")), "{:?}", e.notes);
    let json = serde_json::to_value(&e).unwrap();
    assert_eq!(json["tilt_urad"]["method"], "phases");
    assert!(json["tilt_urad"]["synchronous"].is_f64() && json["axial_on_axis_um"]["u"].is_f64());
    assert!(json["polar"][0]["axial_on_axis_um"].is_f64());
}

#[test]
fn three_smrs_spread_and_a_pair_at_one_phase_choose_the_better_tilt() {
    let m = motions(&[(3, 20.0, 0.0)], &[(2, 35.0, 0.0)], &[(2, 120.0, 10.0), (4, 40.0, 0.0)]);
    let spread: Vec<SmrMount> = [0.0, 120.0, 240.0].map(|p| SmrMount { phase_deg: p, height_mm: 50.0 }).to_vec();
    let (samples, tracks) = survey(72, 2, &spread, &m, 3.5);
    let e = run(&samples, &tracks, &spread);
    let (got, truth) = on_axis_and_tilt(&e, &m, 72);
    // As above; three SMRs' least squares weigh the axial 1/3 each, the tilt 2/3, -1/3, -1/3 over 1 m.
    assert!((got.0 - truth.0).abs() < 12.0 && (got.1 - truth.1).abs() < 12.0, "{got:?} {truth:?}");
    tilt_across_against_the_truth(&e, &m, 72);
    // Two opposite SMRs cannot see the tilt across their line: none, said.
    let pair = [SmrMount { phase_deg: 0.0, height_mm: 50.0 }, SmrMount { phase_deg: 180.0, height_mm: 50.0 }];
    let (samples, tracks) = survey(36, 2, &pair, &m, 3.5);
    let e = run(&samples, &tracks, &pair);
    assert!(e.tilt_urad.is_some() && e.tilt_across_urad.is_none(), "{:?}", e.tilt_across_urad);
    assert!(e.notes.iter().any(|n| n.contains("no tilt at 90 deg")), "{:?}", e.notes);
    assert!(serde_json::to_value(&e).unwrap()["tilt_across_urad"].is_null());
    // Two at one phase 300 mm apart and one opposite: both ways to the tilt; the phases' (2 m apart) is the better.
    let mixed = [
        SmrMount { phase_deg: 0.0, height_mm: 50.0 },
        SmrMount { phase_deg: 0.0, height_mm: 350.0 },
        SmrMount { phase_deg: 180.0, height_mm: 50.0 },
    ];
    let (samples, tracks) = survey(72, 2, &mixed, &m, 3.5);
    let e = run(&samples, &tracks, &mixed);
    on_axis_and_tilt(&e, &m, 72);
    assert_eq!(e.tilt_urad.as_ref().unwrap().method, "phases");
    // Two SMRs 90 deg apart cannot tell the axial motion from the tilt: said, and no figure.
    let square = [SmrMount { phase_deg: 0.0, height_mm: 50.0 }, SmrMount { phase_deg: 90.0, height_mm: 50.0 }];
    let (samples, tracks) = survey(36, 2, &square, &m, 3.5);
    let e = run(&samples, &tracks, &square);
    assert!(e.axial_on_axis_um.is_none() && e.tilt_urad.is_none());
    assert!(e.notes.iter().any(|n| n.contains("do not separate")), "{:?}", e.notes);
}

#[test]
fn the_location_in_a_stated_machine_frame_against_the_truth() {
    use survey_processing::frame::MachineFrame;
    let m = motions(&[(2, 30.0, 0.0)], &[(3, 20.0, 0.0)], &[]);
    let mounts = [SmrMount { phase_deg: 0.0, height_mm: 50.0 }];
    let (samples, tracks) = survey(72, 2, &mounts, &m, 3.5);
    // The machine's z axis is the true axis, its x turned 30 deg about it; the axis passes (10, -20) mm from the
    // machine's origin: rotation_deg makes R ez = n (R = Rz Ry Rx: Ry Rx ez = Rz(-30) n).
    let (_, _, n) = basis();
    let (s, c) = (-30f64).to_radians().sin_cos();
    let turned = [c * n[0] - s * n[1], s * n[0] + c * n[1], n[2]];
    let rotation_deg = [(-turned[1]).asin().to_degrees(), turned[0].atan2(turned[2]).to_degrees(), 30.0];
    let r = MachineFrame { origin_mm: [0.0; 3], rotation_deg, ..Default::default() }.rotation();
    assert!((0..3).all(|i| (r[i][2] - n[i]).abs() < 1e-12), "the machine's z is the axis");
    let at = [10.0, -20.0, 35.0];
    let origin_mm: [f64; 3] = std::array::from_fn(|i| CENTRE[i] - (0..3).map(|j| r[i][j] * at[j]).sum::<f64>());
    let frame = MachineFrame { origin_mm, rotation_deg, ..Default::default() };
    let tracks_of = || tracks.iter().zip(&mounts).map(|(p, m)| Track { mount: *m, points_mm: p }).collect();
    let input = Input { samples: &samples, tracks: tracks_of(), mpe: TransverseMpe::AT_CLASS, frame: Some(frame) };
    let e = error_motions(&input).expect("figures");
    let l = e.location.machine.expect("a C axis's frame");
    for (got, truth, u) in [
        (l.x0_mm, 10.0, l.u_xy_mm),
        (l.y0_mm, -20.0, l.u_xy_mm),
        (l.a0_urad, 0.0, l.u_ab_urad),
        (l.b0_urad, 0.0, l.u_ab_urad),
    ] {
        assert!((got - truth).abs() <= u, "{got} against {truth} +/- {u}: {l:?}");
    }
    // An exact tracker: the noise's share only (3.5 um over 144 points: the centre to some 0.5 um, the normal to
    // some 0.5 urad; the axial motion's 3 cpr does not tilt the plane).
    assert!((l.x0_mm - 10.0).abs() < 0.002 && (l.y0_mm + 20.0).abs() < 0.002, "{l:?}");
    assert!(l.a0_urad.abs() < 3.0 && l.b0_urad.abs() < 3.0, "{l:?}");
    // U: the MPE's once-per-revolution share, 4 e_T / pi (e_T about 37 um at 3.6 m), the normal's over 1 m.
    assert!((0.045..0.05).contains(&l.u_xy_mm) && (45.0..50.0).contains(&l.u_ab_urad), "{l:?}");
    assert!((e.location.u_xy_mm - l.u_xy_mm).abs() < 0.001 && e.location.frame == "tracker");
    let json = serde_json::to_value(&e).unwrap();
    assert!(json["location"]["machine"]["x0_mm"].is_f64() && json["location"]["x0_mm"].is_f64());
    assert!(run(&samples, &tracks, &mounts).location.machine.is_none(), "no frame stated: none");
    assert!((l.u_xy_fit_mm, l.u_ab_fit_urad) == (l.u_xy_mm, l.u_ab_urad) && l.u_xy_alignment_mm.is_none());
    assert!(e.notes.iter().any(|n| n.contains("taken as stated")), "{:?}", e.notes);
    // The frame as an alignment states it: off the true one by 0.08 mm along the tracker's x and 0.006 deg about
    // its x, within its stated U of 0.1 mm and 0.01 deg. The location against the true frame's truth is off by
    // more than the fit's U, and within the combined one.
    let mut off = frame;
    off.origin_mm[0] += 0.08;
    off.rotation_deg[0] += 0.006;
    off.origin_u_mm = Some(0.1);
    off.rotation_u_deg = Some(0.01);
    let input = Input { samples: &samples, tracks: tracks_of(), mpe: TransverseMpe::AT_CLASS, frame: Some(off) };
    let e = error_motions(&input).expect("figures");
    let l = e.location.machine.expect("a C axis's frame");
    assert!((l.x0_mm - 10.0).abs() > l.u_xy_fit_mm && (l.a0_urad.abs() > l.u_ab_fit_urad), "{l:?}");
    for (got, truth, u) in [
        (l.x0_mm, 10.0, l.u_xy_mm),
        (l.y0_mm, -20.0, l.u_xy_mm),
        (l.a0_urad, 0.0, l.u_ab_urad),
        (l.b0_urad, 0.0, l.u_ab_urad),
    ] {
        assert!((got - truth).abs() <= u, "{got} against {truth} +/- {u}: {l:?}");
    }
    // The terms: the origin's U moves X0C, Y0C by itself (a shift of the frame), the rotation's about z by the
    // line's 22 mm from the machine's origin times 175 urad (4 um); the rotations about x and y move A0C, B0C by
    // 0.01 deg (174.5 urad) each.
    let (a_xy, a_ab) = (l.u_xy_alignment_mm.unwrap(), l.u_ab_alignment_urad.unwrap());
    assert!((0.1..0.1002).contains(&a_xy), "{l:?}");
    assert!((a_ab - 0.01f64.to_radians() * 1e6).abs() < 0.5, "{l:?}");
    assert!(
        (l.u_xy_mm - l.u_xy_fit_mm.hypot(a_xy)).abs() < 1e-12
            && (l.u_ab_urad - l.u_ab_fit_urad.hypot(a_ab)).abs() < 1e-9
    );
    assert_eq!((l.origin_u_mm, l.rotation_u_deg), (Some(0.1), Some(0.01)));
    assert!(!e.notes.iter().any(|n| n.contains("taken as stated")), "{:?}", e.notes);
    // A frame on its side (the axis along the machine's x): not a C axis's frame, said.
    let side = MachineFrame { origin_mm, rotation_deg: [0.0, 90.0, 0.0], ..Default::default() };
    let input = Input { samples: &samples, tracks: tracks_of(), mpe: TransverseMpe::AT_CLASS, frame: Some(side) };
    let e = error_motions(&input).expect("figures");
    assert!(e.location.machine.is_none() && e.notes.iter().any(|n| n.contains("60 deg")), "{:?}", e.notes);
}

/// The tilt at 90 deg to the first SMR's radial direction (`t2`) against the
/// model's: a tilt of the table has a direction, the model's `T sin(k theta +
/// phi + delta)` at an SMR `delta` from the first is `t1 cos delta + t2 sin
/// delta` with `t2` the tilt "in the radial direction" of an SMR mounted 90 deg
/// on (`tilt_urad(theta, 90)`). Its synchronous figure within its `U`, and its
/// mean curve within half of it at every target (the random part of `U_sync`
/// bounds a peak-to-valley of two points, each by half; this tracker is
/// exact): the curve is `t2`'s, not `t1`'s (which is off by more).
fn tilt_across_against_the_truth(e: &ErrorMotions, m: &AxisMotions, points: usize) -> (f64, f64) {
    let across = e.tilt_across_urad.as_ref().expect("three SMRs at spread phases measure it");
    assert_eq!((across.method, across.smrs), ("phases", 3));
    let truth = pv(points, |t| m.tilt_urad(t, 90.0));
    let got = across.synchronous.expect("above the limit");
    assert!(
        (got - truth).abs() <= across.u_synchronous,
        "tilt across {got} against {truth} +/- {}",
        across.u_synchronous
    );
    let (mut worst, mut as_t1) = (0.0f64, 0.0f64);
    for p in &e.polar {
        let v = p.tilt_across_urad.expect("in the polar points");
        worst = worst.max((v - m.tilt_urad(p.target_deg, 90.0)).abs());
        as_t1 = as_t1.max((v - m.tilt_urad(p.target_deg, 0.0)).abs());
    }
    assert!(worst <= across.u_synchronous / 2.0, "t2's curve off by {worst} urad (U {})", across.u_synchronous);
    assert!(as_t1 > across.u_synchronous, "the curve is t2's, not t1's: {as_t1}");
    // U as the tilt's: three SMRs at 0, 120, 240 deg weigh t2 0, +-1/sqrt(3) over 1 m: the MPE by 2/sqrt(3), the
    // random bound by sqrt(2/3).
    let t1 = e.tilt_urad.as_ref().unwrap();
    assert!(across.u_asynchronous < t1.u_asynchronous + 0.5, "{across:?} {t1:?}");
    let json = serde_json::to_value(e).unwrap();
    for key in ["total", "synchronous", "asynchronous", "u", "below_detection_limit", "method", "smrs"] {
        assert!(json["tilt_across_urad"].get(key).is_some(), "tilt_across_urad.{key}");
    }
    assert!(json["polar"][0]["tilt_across_urad"].is_f64());
    (got, truth)
}
