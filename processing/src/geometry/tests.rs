use super::*;
use crate::types::wrap_360;

/// A seeded xorshift64* generator with Box-Muller normals (rand is not a
/// dependency of this crate).
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in (0, 1].
    fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) + 1) as f64 / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// Rotation matrix about unit `axis` by `deg` (Rodrigues).
fn rotation(axis: V3, deg: f64) -> [[f64; 3]; 3] {
    let k = normalize(axis);
    let (s, c) = deg.to_radians().sin_cos();
    let mut r = [[0.0; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            let kx = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]][i][j];
            *x = if i == j { c } else { 0.0 } + s * kx + (1.0 - c) * k[i] * k[j];
        }
    }
    r
}

fn column(m: [[f64; 3]; 3], j: usize) -> V3 {
    [m[0][j], m[1][j], m[2][j]]
}

fn angle_between_deg(a: V3, b: V3) -> f64 {
    (dot(a, b) / (dot(a, a) * dot(b, b)).sqrt()).clamp(-1.0, 1.0).acos().to_degrees()
}

/// The true geometry: an SMR on a 1000 mm arm about an axis through
/// `center`, with the plane tilted by 0.5 deg and the arm mounted 37 deg
/// from the frame's `u`.
struct Truth {
    center: V3,
    u: V3,
    v: V3,
    n: V3,
    radius: f64,
    phase_deg: f64,
}

impl Truth {
    fn standard() -> Self {
        let r = rotation([0.6, 0.8, 0.0], 0.5);
        let (u, v) = (column(r, 0), column(r, 1));
        Truth { center: [2500.0, 800.0, -300.0], u, v, n: cross(u, v), radius: 1000.0, phase_deg: 37.0 }
    }

    /// The SMR position at axis angle `theta_deg`.
    fn point(&self, theta_deg: f64) -> V3 {
        let (s, c) = (theta_deg + self.phase_deg).to_radians().sin_cos();
        add(self.center, add(scale(self.u, self.radius * c), scale(self.v, self.radius * s)))
    }

    fn noisy(&self, theta_deg: f64, rng: &mut Rng, sigma: f64) -> V3 {
        add(self.point(theta_deg), [sigma * rng.normal(), sigma * rng.normal(), sigma * rng.normal()])
    }

    /// Standard errors predicted by linearised least squares for noise
    /// `sigma` per coordinate at axis angles `thetas`: (centre along u, along
    /// v, along n, radius, normal tilt in radians).
    fn predicted(&self, thetas: &[f64], sigma: f64) -> [f64; 5] {
        let inverse = |m: [[f64; 3]; 3]| -> [[f64; 3]; 3] {
            let cols = [0, 1, 2].map(|k| {
                let mut e = [0.0; 3];
                e[k] = 1.0;
                solve3(m, e).unwrap()
            });
            [0, 1, 2].map(|i| [0, 1, 2].map(|j| cols[j][i]))
        };
        // Circle: residual derivatives [cos phi, sin phi, 1] for (centre u, centre v, radius).
        let mut jtj = [[0.0; 3]; 3];
        // Plane: height = h0 + t1 x + t2 y, rows [1, x, y] in the plane's frame about the centroid.
        let phis: Vec<f64> = thetas.iter().map(|t| (t + self.phase_deg).to_radians()).collect();
        let nf = phis.len() as f64;
        let xm = phis.iter().map(|p| self.radius * p.cos()).sum::<f64>() / nf;
        let ym = phis.iter().map(|p| self.radius * p.sin()).sum::<f64>() / nf;
        let mut xtx = [[0.0; 3]; 3];
        for p in &phis {
            let jr = [p.cos(), p.sin(), 1.0];
            let xr = [1.0, self.radius * p.cos() - xm, self.radius * p.sin() - ym];
            for i in 0..3 {
                for j in 0..3 {
                    jtj[i][j] += jr[i] * jr[j];
                    xtx[i][j] += xr[i] * xr[j];
                }
            }
        }
        let cc = inverse(jtj);
        let cp = inverse(xtx);
        // The centre's height error: the plane's height at the centre, (-xm, -ym) from the centroid.
        let g = [1.0, -xm, -ym];
        let h2: f64 = (0..3).flat_map(|i| (0..3).map(move |j| (i, j))).map(|(i, j)| g[i] * cp[i][j] * g[j]).sum();
        [
            sigma * cc[0][0].sqrt(),
            sigma * cc[1][1].sqrt(),
            sigma * h2.sqrt(),
            sigma * cc[2][2].sqrt(),
            sigma * (cp[1][1] + cp[2][2]).sqrt(),
        ]
    }
}

const SIGMA_MM: f64 = 0.016;

/// Fits noisy points at `thetas` (readouts = true angles) and checks the
/// centre, normal, radius, residuals and the angles of 360 further noisy
/// points spread over `test_range`.
fn check_geometry(thetas: &[f64], test_range: (f64, f64), seed: u64) {
    let truth = Truth::standard();
    let mut rng = Rng(seed);
    let points: Vec<V3> = thetas.iter().map(|&t| truth.noisy(t, &mut rng, SIGMA_MM)).collect();
    let fit = fit_axis(&points, thetas).unwrap();
    let [s_u, s_v, s_n, s_r, s_tilt] = truth.predicted(thetas, SIGMA_MM);
    let n = thetas.len() as f64;

    // Centre, per component of the true frame, within 5 predicted standard
    // errors (P(|z| > 5) = 6e-7). For n points evenly spread over a revolution
    // the prediction is sigma*sqrt(2/n) in the plane and sigma/sqrt(n) along
    // the axis; on a partial arc it is larger and comes from the same algebra.
    let dc = sub(fit.center_mm, truth.center);
    for (name, got, sd) in [("u", dot(dc, truth.u), s_u), ("v", dot(dc, truth.v), s_v), ("n", dot(dc, truth.n), s_n)] {
        assert!(got.abs() <= 5.0 * sd, "centre error along {name}: {got} mm > 5 x {sd} mm");
    }
    // Normal (sign included: readouts are the true angles, so the fit must
    // point along the true n), within 5 x the predicted tilt error.
    let tilt = angle_between_deg(fit.normal, truth.n);
    assert!(tilt <= 5.0 * s_tilt.to_degrees(), "normal off by {tilt} deg > 5 x {} deg", s_tilt.to_degrees());
    assert!((fit.radius_mm - truth.radius).abs() <= 5.0 * s_r, "radius {} mm, sd {s_r}", fit.radius_mm);
    // The frame is orthonormal and right-handed.
    assert!((dot(fit.u, fit.u) - 1.0).abs() < 1e-12 && dot(fit.u, fit.v).abs() < 1e-12);
    assert!(angle_between_deg(cross(fit.u, fit.v), fit.normal) < 1e-9);
    // Residual RMS estimate sigma with n - 3 degrees of freedom: E[rms^2] =
    // sigma^2 (n - 3) / n; 0.15 to 2 sigma holds for any plausible draw and
    // fails for residuals in wrong units or of a wrong fit.
    for (name, rms) in [("plane", fit.plane_rms_mm), ("circle", fit.circle_rms_mm)] {
        assert!((0.15 * SIGMA_MM..2.0 * SIGMA_MM).contains(&rms), "{name} rms {rms} mm");
    }
    assert_eq!(fit.points, thetas.len());

    // Angles. The readouts are the true angles, so the mean readout error at
    // the fit points is zero and the recovered angle should be the true one.
    // One point's transverse noise is sigma_deg = sigma / R in degrees; 4 of
    // those (360 draws: P(max > 4 sd) ~ 2 %) plus 5 x the fit's own angular
    // uncertainty: the centre's in-plane error over R, plus the zero
    // offset's error sigma_deg / sqrt(n).
    let sigma_deg = (SIGMA_MM / truth.radius).to_degrees();
    let fit_deg = (s_u.hypot(s_v) / truth.radius).to_degrees() + sigma_deg / n.sqrt();
    let tol = 4.0 * sigma_deg + 5.0 * fit_deg;
    let mut worst = 0.0f64;
    for k in 0..360 {
        let theta = test_range.0 + (test_range.1 - test_range.0) * k as f64 / 359.0;
        let p = truth.noisy(theta, &mut rng, SIGMA_MM);
        let got = fit.angle_deg(p, theta);
        worst = worst.max((got - theta).abs());
    }
    assert!(worst <= tol, "worst angle error {worst} deg > {tol} deg");
}

#[test]
fn full_revolution_of_twelve_points() {
    let thetas: Vec<f64> = (0..12).map(|k| 30.0 * k as f64).collect();
    check_geometry(&thetas, (0.0, 360.0), 0x5eed_0001);
}

#[test]
fn elevation_arc_of_nine_points_from_minus_10_to_90() {
    let thetas: Vec<f64> = (0..9).map(|k| -10.0 + 12.5 * k as f64).collect();
    check_geometry(&thetas, (-10.0, 90.0), 0x5eed_0002);
}

#[test]
fn several_seeds_full_and_partial() {
    let full: Vec<f64> = (0..12).map(|k| 30.0 * k as f64).collect();
    let arc: Vec<f64> = (0..9).map(|k| -10.0 + 12.5 * k as f64).collect();
    for seed in 1..=20u64 {
        check_geometry(&full, (0.0, 360.0), seed * 7919);
        check_geometry(&arc, (-10.0, 90.0), seed * 104_729);
    }
}

/// The zero offset makes the mean readout error over the fit points zero.
/// With contract sign `error = readout - actual`, the recovered angle is
/// therefore `actual + mean(error at the fit points)`. With 12 points evenly
/// spread, harmonics 1 and 3 average to zero and only the constant remains;
/// harmonic 12 aliases onto the constant and does not cancel.
#[test]
fn zero_offset_cancels_harmonics_that_are_not_multiples_of_the_point_count() {
    let truth = Truth::standard();
    let thetas: Vec<f64> = (0..12).map(|k| 30.0 * k as f64 + 5.0).collect();
    let points: Vec<V3> = thetas.iter().map(|&t| truth.point(t)).collect();
    let cases: [(&dyn Fn(f64) -> f64, f64); 2] = [
        (&|t: f64| 0.05 + 0.02 * (t + 10.0).to_radians().sin() + 0.01 * (3.0 * t + 40.0).to_radians().sin(), 0.05),
        // 0.01 sin(12 (30 k + 5) + 30) = 0.01 sin(90 deg) at every point.
        (&|t: f64| 0.01 * (12.0 * t + 30.0).to_radians().sin(), 0.01),
    ];
    for (error, mean_error) in cases {
        let readouts: Vec<f64> = thetas.iter().map(|&t| t + error(t)).collect();
        let fit = fit_axis(&points, &readouts).unwrap();
        for k in 0..360 {
            let theta = k as f64;
            let got = fit.angle_deg(truth.point(theta), theta);
            // Noise-free points: only rounding remains (1e-9 deg is 2e-8 mm on the arm).
            assert!((got - (theta + mean_error)).abs() < 1e-9, "at {theta}: {got}, want {}", theta + mean_error);
        }
    }
}

#[test]
fn readouts_in_decreasing_order_give_the_same_axis() {
    let truth = Truth::standard();
    let mut rng = Rng(77);
    let thetas: Vec<f64> = (0..12).map(|k| 30.0 * k as f64).collect();
    let points: Vec<V3> = thetas.iter().map(|&t| truth.noisy(t, &mut rng, SIGMA_MM)).collect();
    let fit = fit_axis(&points, &thetas).unwrap();
    let rev_points: Vec<V3> = points.iter().rev().copied().collect();
    let rev_thetas: Vec<f64> = thetas.iter().rev().copied().collect();
    let rev = fit_axis(&rev_points, &rev_thetas).unwrap();
    assert!(angle_between_deg(rev.normal, truth.n) < 0.01, "normal flipped: {:?}", rev.normal);
    // Same data in another order: equal up to rounding.
    assert!(sub(rev.center_mm, fit.center_mm).iter().all(|d| d.abs() < 1e-9));
    for k in 0..360 {
        let p = truth.point(k as f64);
        assert!((rev.angle_deg(p, k as f64) - fit.angle_deg(p, k as f64)).abs() < 1e-9);
    }
    // And a scrambled order, an arc swept downwards.
    let order = [5, 0, 11, 3, 8, 1, 10, 6, 2, 9, 4, 7];
    let sp: Vec<V3> = order.iter().map(|&i| points[i]).collect();
    let st: Vec<f64> = order.iter().map(|&i| thetas[i]).collect();
    let scrambled = fit_axis(&sp, &st).unwrap();
    assert!(angle_between_deg(scrambled.normal, truth.n) < 0.01);
    let arc: Vec<f64> = (0..9).rev().map(|k| -10.0 + 12.5 * k as f64).collect();
    let arc_points: Vec<V3> = arc.iter().map(|&t| truth.point(t)).collect();
    let down = fit_axis(&arc_points, &arc).unwrap();
    assert!(angle_between_deg(down.normal, truth.n) < 1e-6);
    assert!((down.angle_deg(truth.point(45.0), 0.0) - 45.0).abs() < 1e-9);
}

/// A mirrored tracker frame (x -> -x) turns the rotation clockwise about the
/// mirrored normal: the fit must flip the normal so that angles still
/// increase with the readouts. The normal for which they increase is
/// `M u x M v = -M n`.
#[test]
fn a_mirrored_frame_still_gives_increasing_angles() {
    let truth = Truth::standard();
    let mirror = |p: V3| [-p[0], p[1], p[2]];
    let thetas: Vec<f64> = (0..12).map(|k| 30.0 * k as f64).collect();
    let mut rng = Rng(99);
    let points: Vec<V3> = thetas.iter().map(|&t| mirror(truth.noisy(t, &mut rng, SIGMA_MM))).collect();
    let fit = fit_axis(&points, &thetas).unwrap();
    let want_normal = scale(mirror(truth.n), -1.0);
    assert!(angle_between_deg(fit.normal, want_normal) < 0.01, "{:?} vs {:?}", fit.normal, want_normal);
    // Noise-free test points: only the fit's error remains, well under 0.01 deg.
    for k in 0..360 {
        let theta = k as f64;
        let got = fit.angle_deg(mirror(truth.point(theta)), theta);
        assert!((got - theta).abs() < 0.01, "at {theta}: {got}");
    }
}

#[test]
fn angle_deg_unwraps_to_the_representative_near_the_hint() {
    let truth = Truth::standard();
    let thetas: Vec<f64> = (0..12).map(|k| 30.0 * k as f64).collect();
    let points: Vec<V3> = thetas.iter().map(|&t| truth.point(t)).collect();
    let fit = fit_axis(&points, &thetas).unwrap();
    let at = |theta: f64, near: f64| fit.angle_deg(truth.point(theta), near);
    for (theta, near, want) in [
        (359.9, 0.0, -0.1),
        (359.9, 360.0, 359.9),
        (359.9, 720.0, 719.9),
        (359.9, -300.0, -360.1),
        (0.1, 359.0, 360.1),
        (0.1, 0.0, 0.1),
        (-5.0, -10.0, -5.0),
        (-5.0, 90.0, -5.0),
        (-5.0, 45.0, -5.0),
        (-5.0, 270.0, 355.0),
        (185.0, 0.0, -175.0),
        (185.0, 100.0, 185.0),
    ] {
        let got = at(theta, near);
        assert!((got - want).abs() < 1e-9, "angle of {theta} near {near}: {got}, want {want}");
    }
    assert!((wrap_360(at(123.0, 0.0)) - 123.0).abs() < 1e-9);
}

#[test]
fn three_points_give_the_exact_circle() {
    let truth = Truth::standard();
    let thetas = [0.0, 100.0, 250.0];
    let points: Vec<V3> = thetas.iter().map(|&t| truth.point(t)).collect();
    let fit = fit_axis(&points, &thetas).unwrap();
    assert!(sub(fit.center_mm, truth.center).iter().all(|d| d.abs() < 1e-8), "{:?}", fit.center_mm);
    assert!((fit.radius_mm - 1000.0).abs() < 1e-8);
    assert!(angle_between_deg(fit.normal, truth.n) < 1e-9);
    assert!(fit.plane_rms_mm < 1e-9 && fit.circle_rms_mm < 1e-9);
}

#[test]
fn errors() {
    let truth = Truth::standard();
    let p: Vec<V3> = [0.0, 120.0, 240.0].iter().map(|&t| truth.point(t)).collect();
    assert_eq!(fit_axis(&p[..2], &[0.0, 120.0]), Err(GeometryError::TooFewPoints(2)));
    assert_eq!(fit_axis(&[], &[]), Err(GeometryError::TooFewPoints(0)));
    assert_eq!(fit_axis(&p, &[0.0, 120.0]), Err(GeometryError::LengthMismatch { points: 3, readouts: 2 }));
    let mut bad = p.clone();
    bad[1][2] = f64::NAN;
    let err = fit_axis(&bad, &[0.0, 120.0, 240.0]).unwrap_err();
    assert!(matches!(err, GeometryError::NonFinite { index: 1, what: "z", .. }), "{err:?}");
    assert_eq!(err.to_string(), "point 1: z is NaN, not a finite number");
    let err = fit_axis(&p, &[0.0, f64::INFINITY, 240.0]).unwrap_err();
    assert!(matches!(err, GeometryError::NonFinite { index: 1, what: "readout", .. }), "{err:?}");
    // The first value that is not finite is named, a point's or a readout's.
    let mut both = p.clone();
    both[2][0] = f64::NEG_INFINITY;
    let err = fit_axis(&both, &[0.0, f64::NAN, 240.0]).unwrap_err();
    assert!(matches!(err, GeometryError::NonFinite { index: 1, what: "readout", .. }), "{err:?}");
    let err = fit_axis(&both, &[0.0, 120.0, 240.0]).unwrap_err();
    assert_eq!(err.to_string(), "point 2: x is -inf, not a finite number");
    // Finite values whose sum overflows are not taken for values that are not.
    let huge = vec![[f64::MAX, 0.0, 0.0], [f64::MAX, 1.0, 0.0], [0.0, 0.0, 1.0]];
    if let Err(err) = fit_axis(&huge, &[0.0, 120.0, 240.0]) {
        assert!(!matches!(err, GeometryError::NonFinite { .. }), "{err:?}");
    }

    let line: Vec<V3> = (0..5).map(|k| [k as f64 * 10.0, 2.0 * k as f64, -3.0]).collect();
    let err = fit_axis(&line, &[0.0, 1.0, 2.0, 3.0, 4.0]).unwrap_err();
    assert!(matches!(err, GeometryError::Degenerate(ref m) if m.contains("straight line")), "{err}");
    let same = vec![[1.0, 2.0, 3.0]; 4];
    let err = fit_axis(&same, &[0.0, 1.0, 2.0, 3.0]).unwrap_err();
    assert!(matches!(err, GeometryError::Degenerate(ref m) if m.contains("coincide")), "{err}");
    let err = fit_axis(&p, &[10.0, 10.0, 10.0]).unwrap_err();
    assert!(matches!(err, GeometryError::Degenerate(ref m) if m.contains("direction of rotation")), "{err}");
}

#[test]
fn jacobi_eigen_decomposes_symmetric_matrices() {
    let mut rng = Rng(2024);
    let mut cases = vec![
        [[3.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.0]],
        [[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 3.0]], // eigenvalues 1, 3, 3 (repeated)
        [[1e6, 1e3, 1.0], [1e3, 5e5, 2.0], [1.0, 2.0, 1e-4]], // widely spread, like a covariance
    ];
    for _ in 0..50 {
        let [a, b, c, d, e, f]: [f64; 6] = std::array::from_fn(|_| rng.normal());
        cases.push([[a, b, c], [b, d, e], [c, e, f]]);
    }
    for m in cases {
        let (values, vectors) = sym_eigen3(m);
        let norm = m.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
        assert!(values[0] <= values[1] && values[1] <= values[2], "{values:?}");
        for k in 0..3 {
            let mv = [0, 1, 2].map(|i| dot(m[i], vectors[k]));
            let residual = sub(mv, scale(vectors[k], values[k]));
            assert!(dot(residual, residual).sqrt() <= 1e-12 * norm, "{m:?}: pair {k} residual {residual:?}");
            for j in 0..3 {
                let want = if j == k { 1.0 } else { 0.0 };
                assert!((dot(vectors[k], vectors[j]) - want).abs() < 1e-12);
            }
        }
    }
    let (values, _) = sym_eigen3([[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 3.0]]);
    assert!((values[0] - 1.0).abs() < 1e-14 && (values[1] - 3.0).abs() < 1e-14 && (values[2] - 3.0).abs() < 1e-14);
}

#[test]
fn axis_fit_round_trips_through_serde() {
    let truth = Truth::standard();
    let thetas = [0.0, 100.0, 250.0];
    let points: Vec<V3> = thetas.iter().map(|&t| truth.point(t)).collect();
    let fit = fit_axis(&points, &thetas).unwrap();
    let json = serde_json::to_string(&fit).unwrap();
    let back: AxisFit = serde_json::from_str(&json).unwrap();
    // serde_json without its `float_roundtrip` feature may miss the last bit
    // when reading a float back: equal to 1e-15 relative.
    let flat = |f: &AxisFit| {
        let mut v = [f.center_mm, f.normal, f.u, f.v].concat();
        v.extend([f.radius_mm, f.zero_offset_deg, f.plane_rms_mm, f.circle_rms_mm]);
        v
    };
    for (a, b) in flat(&fit).into_iter().zip(flat(&back)) {
        assert!((a - b).abs() <= 1e-15 * a.abs().max(b.abs()), "{a} vs {b}");
    }
    assert_eq!(back.points, fit.points);
    assert!(json.contains("\"center_mm\"") && json.contains("\"zero_offset_deg\""), "{json}");
}

/// Thousands of noisy positions with a few glitches: the glitches are
/// left out, the centre is found within a few of its stated standard
/// errors, and far better than from 12 positions.
#[test]
fn the_refit_from_a_whole_survey_is_robust_and_knows_its_uncertainty() {
    let center = [2500.0, 800.0, -300.0];
    let r_mm = 1000.0;
    let sigma = 0.01; // mm per coordinate
    let mut rng = Rng(0x5eed_1234);
    let point = |deg: f64, rng: &mut Rng| {
        let t = deg.to_radians();
        [
            center[0] + r_mm * t.cos() + sigma * rng.normal(),
            center[1] + r_mm * t.sin() + sigma * rng.normal(),
            center[2] + sigma * rng.normal(),
        ]
    };
    let readouts: Vec<f64> = (0..4000).map(|k| k as f64 * 0.09).collect();
    let mut points: Vec<[f64; 3]> = readouts.iter().map(|&d| point(d, &mut rng)).collect();
    for k in [7, 1500, 2222, 3900] {
        points[k][0] += 5.0; // glitches: 5 mm off
    }
    let refit = refit_axis(&points, &readouts).unwrap();
    assert_eq!(refit.dropped, 4);
    let off = (refit.fit.center_mm[0] - center[0]).hypot(refit.fit.center_mm[1] - center[1]);
    // sigma * sqrt(2 / n) = 2.2e-4 mm; within 4 standard errors.
    assert!((refit.center_se_mm - sigma * (2.0f64 / 3996.0).sqrt()).abs() < 0.2 * refit.center_se_mm, "{refit:?}");
    assert!(off < 4.0 * refit.center_se_mm, "centre off by {off} mm, se {}", refit.center_se_mm);
    let twelve: Vec<usize> = (0..12).map(|k| k * 333 + 1).collect();
    let few = fit_axis(
        &twelve.iter().map(|&k| points[k]).collect::<Vec<_>>(),
        &twelve.iter().map(|&k| readouts[k]).collect::<Vec<_>>(),
    )
    .unwrap();
    let few_off = (few.center_mm[0] - center[0]).hypot(few.center_mm[1] - center[1]);
    assert!(off < few_off, "{off} from 4000 positions against {few_off} from 12");
}

/// On a partial arc (100 deg, as an elevation axis) the centre is known
/// far worse along the arc's bisector than across it; the refit says so,
/// and its stated uncertainty is what repeated fits show: over 300
/// surveys of 600 noisy positions, the spread of the centre along the
/// worst direction and of the angle error it makes over the arc are within
/// 15 % of the stated standard errors (the spread of 300 draws scatters by
/// 1 / sqrt(600) = 4 %).
#[test]
fn on_a_partial_arc_the_refit_states_what_the_arc_allows() {
    let center = [2500.0, 800.0, -300.0];
    let (r_mm, sigma) = (1000.0, 0.01);
    let mut rng = Rng(0xa4c_0001);
    let readouts: Vec<f64> = (0..600).map(|k| -10.0 + 100.0 * k as f64 / 599.0).collect();
    let mut shifts = Vec::new();
    let mut stated = None;
    for _ in 0..300 {
        let points: Vec<[f64; 3]> = readouts
            .iter()
            .map(|d| {
                let t = d.to_radians();
                [
                    center[0] + r_mm * t.cos() + sigma * rng.normal(),
                    center[1] + r_mm * t.sin() + sigma * rng.normal(),
                    center[2] + sigma * rng.normal(),
                ]
            })
            .collect();
        let refit = refit_axis(&points, &readouts).unwrap();
        shifts.push([refit.fit.center_mm[0] - center[0], refit.fit.center_mm[1] - center[1]]);
        stated.get_or_insert(refit);
    }
    let stated = stated.unwrap();
    assert!((stated.arc_deg - 100.0).abs() < 0.5, "{}", stated.arc_deg);
    // Full circle: sigma sqrt(2 / n) = 5.8e-4 mm; along the bisector of a
    // 100-degree arc the centre trades with the radius (6.4 times worse here).
    assert!(stated.center_se_mm > 4.0 * sigma * (2.0f64 / 600.0).sqrt(), "{stated:?}");
    // The worst direction is the bisector (40 deg): the spread along it.
    let b = 40f64.to_radians();
    let along: Vec<f64> = shifts.iter().map(|d| d[0] * b.cos() + d[1] * b.sin()).collect();
    let sd = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
    };
    let ratio = sd(&along) / stated.center_se_mm;
    assert!((ratio - 1.0).abs() < 0.15, "spread {} against stated {}", sd(&along), stated.center_se_mm);
    // The angle error over the arc, its mean removed, at the arc's ends
    // (where it is largest): spread against the stated figure.
    let ends: Vec<f64> = shifts
        .iter()
        .map(|d| {
            let err = |deg: f64| {
                let p = deg.to_radians();
                (d[0] * p.sin() - d[1] * p.cos()) / r_mm
            };
            let mean = readouts.iter().map(|&x| err(x)).sum::<f64>() / readouts.len() as f64;
            (err(90.0) - mean).to_degrees()
        })
        .collect();
    let ratio = sd(&ends) / stated.over_arc_se_deg;
    assert!((ratio - 1.0).abs() < 0.15, "spread {} against stated {}", sd(&ends), stated.over_arc_se_deg);
    assert!(stated.over_arc_se_deg < stated.once_per_rev_se_deg, "{stated:?}");
}

/// The points the refit keeps are those `hypot` everywhere keeps: the
/// cheaper estimates only spare `hypot` where they decide, at the limit too.
#[test]
fn the_refit_keeps_the_points_hypot_everywhere_keeps() {
    let reference = |fit: &AxisFit, points: &[[f64; 3]]| -> Vec<usize> {
        let r: Vec<f64> = points
            .iter()
            .map(|&p| {
                let d = sub(p, fit.center_mm);
                let h = dot(d, fit.normal);
                let in_plane = sub(d, scale(fit.normal, h));
                (dot(in_plane, in_plane).sqrt() - fit.radius_mm).hypot(h)
            })
            .collect();
        let mut sorted = r.clone();
        let mad = *sorted.select_nth_unstable_by(r.len() / 2, f64::total_cmp).1;
        let limit = 5.0 * 1.4826 * mad;
        (0..r.len()).filter(|&i| !(limit <= 0.0 || r[i] <= limit)).collect()
    };
    // A noisy survey with glitches, around its own fit.
    let mut rng = Rng(0x00dd_ba11);
    let readouts: Vec<f64> = (0..3001).map(|k| k as f64 * 0.12).collect();
    let mut points: Vec<[f64; 3]> = readouts
        .iter()
        .map(|d| {
            let t = d.to_radians();
            [700.0 + 500.0 * t.cos() + 0.01 * rng.normal(), -40.0 + 0.01 * rng.normal(), 500.0 * t.sin()]
        })
        .collect();
    for k in [3, 999, 2000] {
        points[k][1] += 2.0;
    }
    let fit = fit_axis(&points, &readouts).unwrap();
    let beyond = beyond_limit(&fit, &points);
    assert_eq!(beyond, reference(&fit, &points));
    assert_eq!(beyond, [3, 999, 2000]);
    // A unit circle where a position's distance is exactly its offset from
    // the plane: distances 0 and 1e-200 (hypot's own), the median, one
    // exactly at the limit (kept) and the next one above it (left out).
    let fit = AxisFit {
        center_mm: [0.0; 3],
        normal: [0.0, 0.0, 1.0],
        u: [1.0, 0.0, 0.0],
        v: [0.0, 1.0, 0.0],
        radius_mm: 1.0,
        zero_offset_deg: 0.0,
        plane_rms_mm: 0.0,
        circle_rms_mm: 0.0,
        points: 0,
    };
    let mut h: Vec<f64> = vec![0.0, -1e-200];
    h.extend((1..=100).map(|k| k as f64 * 1e-3 * if k % 2 == 0 { 1.0 } else { -1.0 }));
    let limit: f64 = 5.0 * 1.4826 * (51.0 * 1e-3);
    h.extend([limit, limit.next_up()]);
    let points: Vec<[f64; 3]> = h.iter().map(|&h| [1.0, 0.0, h]).collect();
    let beyond = beyond_limit(&fit, &points);
    assert_eq!(beyond, reference(&fit, &points));
    assert_eq!(beyond, [103]);
    // Every distance 0: every point kept.
    let zero = vec![[0.0, 1.0, 0.0]; 5];
    assert_eq!(beyond_limit(&fit, &zero), Vec::<usize>::new());
}

/// The largest gap found through buckets is the sorted angles' own, to the
/// bit: on clustered angles (a survey's: each target's runs side by side),
/// on a partial arc, on angles spread evenly (where it falls back to the
/// sort), with repeats and signed zeros.
mod largest_gap_by_buckets {
    use super::super::{largest_gap, sorted_largest_gap};
    use proptest::prelude::*;
    use std::f64::consts::PI;

    fn check(angles: &[f64]) -> Result<(), TestCaseError> {
        let mut sorted = angles.to_vec();
        sorted.sort_unstable_by(f64::total_cmp);
        let by_buckets = largest_gap(|| angles.iter().copied(), angles.len());
        prop_assert_eq!(by_buckets.to_bits(), sorted_largest_gap(&sorted).to_bits(), "{:?}", angles);
        Ok(())
    }

    proptest! {
        #[test]
        fn clustered_targets(
            targets in 1usize..400,
            runs in 1usize..6,
            start in -PI..PI,
            arc in 0.1f64..(2.0 * PI),
            jitter in 0.0f64..1e-3,
            // Each sample's place within its target's jitter, cycled.
            places in proptest::collection::vec(-0.5f64..0.5, 1..64),
        ) {
            let step = arc / targets as f64;
            let angles: Vec<f64> = (0..runs)
                .flat_map(|_| 0..targets)
                .enumerate()
                .map(|(k, t)| {
                    let a = start + t as f64 * step + jitter * step * places[k % places.len()];
                    if a >= PI { a - 2.0 * PI } else { a }
                })
                .collect();
            check(&angles)?;
        }

        #[test]
        fn spread_evenly_or_repeated(angles in proptest::collection::vec(prop_oneof![
            -PI..PI,
            Just(0.0),
            Just(-0.0),
            Just(1.0),
        ], 0..300)) {
            check(&angles)?;
        }
    }

    #[test]
    fn none_one_and_all_equal() {
        assert_eq!(largest_gap(std::iter::empty, 0), 0.0);
        assert_eq!(largest_gap(|| [0.5].into_iter(), 1), 2.0 * PI);
        assert_eq!(largest_gap(|| [0.5; 9].into_iter(), 9), 2.0 * PI);
        // A half circle: the gap is the other half.
        let half: Vec<f64> = (0..1000).map(|k| k as f64 * PI / 999.0).collect();
        let gap = largest_gap(|| half.iter().copied(), half.len());
        assert!((gap - PI).abs() < 1e-12, "{gap}");
    }
}
