//! A polygon calibrated in place (issue 48): the table's errors and the
//! polygon's face errors from one survey, the polygon turned relative to the
//! table between runs, without trusting its certificate (closure).
//!
//! At target `i` (the table at face pitch `i`) with the polygon turned by `s`
//! faces, the autocollimator sees face `k = i - s` (mod `N`), and the sample's
//! error as the survey computed it with the certificate `c` is
//!
//! ```text
//! y = e_i + (t_k - c_k) / 3600 + o_s      (degrees)
//! ```
//!
//! with `e_i` the table's error at the target (per direction), `t_k` the
//! face's true deviation from nominal (arcsec) and `o_r` how far the polygon
//! sat from its nominal turn in run `r` (the stage that turned it errs, and
//! lands a little differently each time it turns: one offset per run, the
//! first run's the zero). At one orientation only
//! the sums `e_i + t_k` are seen; two orientations `a` turn apart link face
//! `k` to face `k + a`, and every face is linked to every other when the
//! turns between the orientations have no common divisor with `N` (a turn of
//! one face always does; half the polygon never does). The face deviations
//! are known up to one constant, a turn of the whole polygon that the
//! table's zero takes up: they are given in the certificate's convention
//! (their mean is the certificate's mean), so the correction
//! `(t_k - c_k) / 3600` has no mean and leaves the table's zero alone.
//! Least squares over every sample gives `e`, `t` and `o`, `t` with its
//! standard uncertainty from the residual scatter (the noise of one
//! reading); each sample's actual angle is then corrected by adding
//! `(t_k - c_k) / 3600`.

use survey_processing::lstsq::Qr;
use survey_processing::types::Direction;

/// One sample as the closure reads it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaceSample {
    /// The target's place on the table, in faces (`0..N`).
    pub target: usize,
    /// The face the autocollimator saw (`0..N`).
    pub face: usize,
    pub direction: Direction,
    /// The run (one placement of the polygon).
    pub run: u32,
    /// `readout - actual` as computed with the certificate, degrees.
    pub error_deg: f64,
}

impl FaceSample {
    /// The polygon's turn relative to the table, faces (`0..N`).
    pub fn orientation(&self, faces: usize) -> usize {
        (self.target + faces - self.face) % faces
    }
}

/// What the closure found.
#[derive(Debug, Clone, PartialEq)]
pub struct Closure {
    /// The polygon's face deviations from nominal, measured, arcsec (their
    /// mean the certificate's).
    pub face_errors_arcsec: Vec<f64>,
    /// Their standard uncertainties, arcsec.
    pub face_u_arcsec: Vec<f64>,
    /// The orientations seen (faces turned, `0..N`), ascending.
    pub orientations: Vec<usize>,
    /// The runs seen, ascending.
    pub runs: Vec<u32>,
    /// How far the polygon sat from its nominal turn in each run, relative
    /// to the first run, arcsec (in the order of `runs`).
    pub run_offsets_arcsec: Vec<f64>,
    /// The standard deviation of one reading about the fit, arcsec.
    pub reading_sd_arcsec: f64,
}

impl Closure {
    /// What to add to an actual angle measured on face `k` with the
    /// certificate, degrees.
    pub fn correction_deg(&self, face: usize, certificate_arcsec: &[f64]) -> f64 {
        (self.face_errors_arcsec[face] - certificate_arcsec[face]) / 3600.0
    }
}

/// Why the closure cannot be solved.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ClosureError {
    #[error("the polygon was seen in {0} orientation(s) relative to the table: the closure needs two or more")]
    OneOrientation(usize),
    #[error(
        "the orientations {orientations:?} leave faces unlinked (the turns between them share a divisor with the {faces} faces): turn the polygon by one face"
    )]
    Unlinked { orientations: Vec<usize>, faces: usize },
    #[error("{0}")]
    Input(String),
}

/// The greatest common divisor.
fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// Solve the closure of `samples` on a polygon of `faces` faces whose
/// certificate is `certificate_arcsec`.
pub fn solve(faces: usize, samples: &[FaceSample], certificate_arcsec: &[f64]) -> Result<Closure, ClosureError> {
    let n = faces;
    if n < 2 || certificate_arcsec.len() != n {
        return Err(ClosureError::Input(format!(
            "a polygon of {n} faces with {} certificate entries",
            certificate_arcsec.len()
        )));
    }
    if let Some(s) = samples.iter().find(|s| s.target >= n || s.face >= n) {
        return Err(ClosureError::Input(format!("target {} or face {} past the {n} faces", s.target, s.face)));
    }
    let mut orientations: Vec<usize> = samples.iter().map(|s| s.orientation(n)).collect();
    orientations.sort_unstable();
    orientations.dedup();
    if orientations.len() < 2 {
        return Err(ClosureError::OneOrientation(orientations.len()));
    }
    let linked = orientations.iter().skip(1).fold(n, |g, o| gcd(g, o - orientations[0]));
    if linked != 1 {
        return Err(ClosureError::Unlinked { orientations, faces: n });
    }
    let directions: Vec<Direction> = {
        let mut d: Vec<Direction> = samples.iter().map(|s| s.direction).collect();
        d.sort_by_key(|d| *d == Direction::Reverse);
        d.dedup();
        d
    };
    // Unknowns (arcsec): e per direction and target; d_0..d_{n-2} with
    // d_{n-1} = -(the others' sum) (d = t - c has no mean); o for every
    // run past the first.
    let mut runs: Vec<u32> = samples.iter().map(|s| s.run).collect();
    runs.sort_unstable();
    runs.dedup();
    let e_cols = directions.len() * n;
    let o_cols = e_cols + n - 1;
    let p = o_cols + runs.len() - 1;
    let rows = samples.len();
    if rows <= p {
        return Err(ClosureError::Input(format!("{rows} samples for {p} unknowns")));
    }
    let mut columns = vec![vec![0.0; rows]; p];
    let mut y = vec![0.0; rows];
    for (r, s) in samples.iter().enumerate() {
        let di = directions.iter().position(|d| *d == s.direction).expect("listed");
        columns[di * n + s.target][r] = 1.0;
        y[r] = s.error_deg * 3600.0;
        if s.face < n - 1 {
            columns[e_cols + s.face][r] = 1.0;
        } else {
            for col in &mut columns[e_cols..o_cols] {
                col[r] = -1.0;
            }
        }
        let o = runs.binary_search(&s.run).expect("listed");
        if o > 0 {
            columns[o_cols + o - 1][r] = 1.0;
        }
    }
    // Every column is a count of ones: an unresolvable one is a rank defect
    // the checks above did not foresee (a target never seen).
    let qr = Qr::new(columns, |_| 1e-6)
        .map_err(|j| ClosureError::Input(format!("unknown {j} of {p} is not seen by the samples")))?;
    let (x, rss) = qr.solve(&y);
    let sd = (rss / (rows - p) as f64).sqrt();
    let unit = qr.unit_var();
    let mut d: Vec<f64> = x[e_cols..o_cols].to_vec();
    d.push(-d.iter().sum::<f64>());
    let mut face_u_arcsec: Vec<f64> = unit[e_cols..o_cols].iter().map(|v| sd * v.sqrt()).collect();
    let last: Vec<f64> = (0..p).map(|j| if (e_cols..o_cols).contains(&j) { -1.0 } else { 0.0 }).collect();
    face_u_arcsec.push(sd * qr.leverage(&last));
    let face_errors_arcsec = d.iter().zip(certificate_arcsec).map(|(d, c)| d + c).collect();
    let mut run_offsets_arcsec = vec![0.0];
    run_offsets_arcsec.extend_from_slice(&x[o_cols..]);
    Ok(Closure { face_errors_arcsec, face_u_arcsec, orientations, runs, run_offsets_arcsec, reading_sd_arcsec: sd })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic noise of standard deviation about `sd`.
    fn noise(seed: &mut u64, sd: f64) -> f64 {
        let mut u = || {
            *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (*seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        (u() + u() + u()) * 2.0 * sd
    }

    struct Polygon {
        samples: Vec<FaceSample>,
        truth: Vec<f64>,
        certificate: Vec<f64>,
    }

    /// A survey of a 24-face polygon turned by `shifts` between runs (the
    /// stage that turns it off by `stage_arcsec[i]` in turn `i`, and by
    /// 0.3 arcsec more in the second run of each), two runs each, both ways: the table's error (with 0.002 deg of backlash), the
    /// faces' truth and a stale certificate (face 5 off by 1.5 arcsec, the
    /// others by 0.1).
    fn survey(shifts: &[usize], stage_arcsec: &[f64], sd_arcsec: f64) -> Polygon {
        survey_seeded(shifts, stage_arcsec, sd_arcsec, 11)
    }

    fn survey_seeded(shifts: &[usize], stage_arcsec: &[f64], sd_arcsec: f64, seed: u64) -> Polygon {
        let n = 24;
        let truth: Vec<f64> = (0..n).map(|k| 0.8 * ((k as f64) * 0.7).sin() + 0.3 * ((k as f64) * 2.1).cos()).collect();
        let certificate: Vec<f64> = truth.iter().enumerate().map(|(k, t)| t + if k == 5 { 1.5 } else { 0.1 }).collect();
        let mut seed = seed;
        let mut samples = Vec::new();
        let mut run = 0;
        for (&s, &stage) in shifts.iter().zip(stage_arcsec) {
            for again in [0.0, 0.3] {
                run += 1;
                for direction in [Direction::Forward, Direction::Reverse] {
                    for i in 0..n {
                        let theta = (i as f64 * 15.0).to_radians();
                        let e = 0.004 * (20.0 * theta).sin() + 0.0015 * (theta + 1.0).sin() + 0.001 * direction.sign();
                        let k = (i + n - s) % n;
                        let off = truth[k] - certificate[k] + stage + again + noise(&mut seed, sd_arcsec);
                        samples.push(FaceSample { target: i, face: k, direction, run, error_deg: e + off / 3600.0 });
                    }
                }
            }
        }
        Polygon { samples, truth, certificate }
    }

    fn centred(v: &[f64]) -> Vec<f64> {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        v.iter().map(|x| x - m).collect()
    }

    #[test]
    fn two_orientations_find_the_faces_without_the_certificate() {
        let sd = 0.1;
        // The stage errs by 2 arcsec in the second orientation.
        let p = survey(&[0, 1], &[0.0, 2.0], sd);
        let c = solve(24, &p.samples, &p.certificate).expect("separable");
        assert_eq!(c.orientations, [0, 1]);
        assert_eq!(c.runs, [1, 2, 3, 4]);
        let o = &c.run_offsets_arcsec;
        assert!((o[1] - 0.3).abs() < 0.1 && (o[2] - 2.0).abs() < 0.1 && (o[3] - 2.3).abs() < 0.1, "{o:?}");
        assert!((c.reading_sd_arcsec / sd - 1.0).abs() < 0.25, "{}", c.reading_sd_arcsec);
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        assert!((mean(&c.face_errors_arcsec) - mean(&p.certificate)).abs() < 1e-9, "the certificate's convention");
        let (found, truth) = (centred(&c.face_errors_arcsec), centred(&p.truth));
        for k in 0..24 {
            let off = (found[k] - truth[k]).abs();
            // Within 3.5 of its stated standard uncertainty (24 faces: one
            // past 3 sigma is not rare), which is itself within a few times
            // the noise of one reading (two orientations, four readings a
            // face each, chained round the polygon).
            assert!(off < 3.5 * c.face_u_arcsec[k], "face {k}: off {off} u {}", c.face_u_arcsec[k]);
            assert!(c.face_u_arcsec[k] < 3.0 * sd, "face {k}: u {}", c.face_u_arcsec[k]);
        }
        // The stale face is found off its certificate by 1.4 arcsec more
        // than the others.
        let stale = (p.certificate[5] - c.face_errors_arcsec[5]) - (p.certificate[0] - c.face_errors_arcsec[0]);
        assert!((stale - 1.4).abs() < 0.2, "{stale}");
        // The correction takes the certificate's error out of a sample.
        let k = 5;
        assert!((c.correction_deg(k, &p.certificate) * 3600.0 - (found[k] - centred(&p.certificate)[k])).abs() < 1e-9);
    }

    /// The stated uncertainty is the scatter: over 200 noise draws, each
    /// face's rms error (mean taken out) within 15 % of its stated standard
    /// uncertainty (200 draws know an rms to 5 %).
    #[test]
    fn the_stated_uncertainty_is_the_scatter_over_many_surveys() {
        let (draws, sd) = (200, 0.1);
        let mut sum2 = [0.0; 24];
        let mut stated = [0.0; 24];
        for seed in 0..draws {
            let p = survey_seeded(&[0, 1], &[0.0, 2.0], sd, 1000 + seed);
            let c = solve(24, &p.samples, &p.certificate).unwrap();
            let (found, truth) = (centred(&c.face_errors_arcsec), centred(&p.truth));
            for k in 0..24 {
                sum2[k] += (found[k] - truth[k]).powi(2);
                stated[k] += c.face_u_arcsec[k] / draws as f64;
            }
        }
        for k in 0..24 {
            let rms = (sum2[k] / draws as f64).sqrt();
            assert!((rms / stated[k] - 1.0).abs() < 0.15, "face {k}: scatter {rms:.4} stated {:.4}", stated[k]);
        }
    }

    #[test]
    fn noiseless_the_faces_come_back_exactly() {
        let p = survey(&[0, 7, 19], &[0.0, -1.0, 0.5], 0.0);
        let c = solve(24, &p.samples, &p.certificate).unwrap();
        let (found, truth) = (centred(&c.face_errors_arcsec), centred(&p.truth));
        for k in 0..24 {
            assert!((found[k] - truth[k]).abs() < 1e-9, "face {k}");
        }
        assert!((c.run_offsets_arcsec[4] - 0.5).abs() < 1e-9);
        assert!((c.run_offsets_arcsec[5] - 0.8).abs() < 1e-9);
    }

    #[test]
    fn orientations_that_cannot_separate_say_so() {
        let p = survey(&[3], &[0.0], 0.1);
        assert_eq!(solve(24, &p.samples, &p.certificate).unwrap_err(), ClosureError::OneOrientation(1));
        // Half the polygon apart: face k is only ever compared with k + 12.
        let p = survey(&[0, 12], &[0.0, 0.0], 0.1);
        let e = solve(24, &p.samples, &p.certificate).unwrap_err();
        assert!(matches!(e, ClosureError::Unlinked { .. }), "{e}");
        assert!(e.to_string().contains("turn the polygon by one face"), "{e}");
        // Two turns that share 24's divisor 2 with each other, but a third
        // links the rest.
        let p = survey(&[0, 2, 5], &[0.0, 0.0, 0.0], 0.0);
        assert!(solve(24, &p.samples, &p.certificate).is_ok());
        let e = solve(25, &p.samples, &p.certificate).unwrap_err();
        assert!(matches!(e, ClosureError::Input(_)), "{e}");
    }
}
