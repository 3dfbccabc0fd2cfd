//! Special functions shared by the statistical tests of the analysis and of
//! model-gap, and the median they and the crates above take.

/// The median of `v` (reordered; the mean of the two middle values of an
/// even count), in linear time.
pub fn median(v: &mut [f64]) -> f64 {
    let n = v.len();
    let (left, mid, _) = v.select_nth_unstable_by(n / 2, f64::total_cmp);
    let mid = *mid;
    if n % 2 == 1 { mid } else { 0.5 * (mid + left.iter().copied().fold(f64::NEG_INFINITY, f64::max)) }
}

/// Complementary error function (Numerical Recipes `erfcc`, fractional error
/// below 1.2e-7 everywhere).
pub fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98 + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 { r } else { 2.0 - r }
}

/// `P(|T| > t)` for Student's `T` with `dof` degrees of freedom (at least
/// one), from the closed forms for whole degrees of freedom (Abramowitz and
/// Stegun 26.7.3 and 26.7.4): `theta = atan(t / sqrt(dof))`.
pub fn student_two_sided_sf(t: f64, dof: u32) -> f64 {
    let dof = dof.max(1);
    let theta = (t.abs() / f64::from(dof).sqrt()).atan();
    let (s, c) = theta.sin_cos();
    let n = dof as usize;
    let inside = if n % 2 == 1 {
        // 2 / pi (theta + sin (cos + 2/3 cos^3 + 2 4 / (3 5) cos^5 + ...)), to cos^(dof - 2).
        let (mut term, mut sum) = (c, 0.0);
        for j in 0..n.saturating_sub(1) / 2 {
            if j > 0 {
                term *= c * c * (2 * j) as f64 / (2 * j + 1) as f64;
            }
            sum += term;
        }
        2.0 / std::f64::consts::PI * (theta + s * sum)
    } else {
        // sin (1 + 1/2 cos^2 + 1 3 / (2 4) cos^4 + ...), to cos^(dof - 2).
        let (mut term, mut sum) = (1.0, 1.0);
        for j in 1..n / 2 {
            term *= c * c * (2 * j - 1) as f64 / (2 * j) as f64;
            sum += term;
        }
        s * sum
    };
    (1.0 - inside).clamp(0.0, 1.0)
}

/// The `t` with `P(|T| > t) = p` for Student's `T` with `dof` degrees of
/// freedom (at least one).
pub fn student_two_sided_isf(p: f64, dof: u32) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 1e7f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if student_two_sided_sf(mid, dof) > p { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

/// The `c` with `P(|Z| > c) = p` for a standard normal `Z`.
pub fn normal_two_sided_isf(p: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 40.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if erfc(mid / std::f64::consts::SQRT_2) > p { lo = mid } else { hi = mid }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_selected_median_is_the_sorted_one() {
        let mut rng = crate::analysis::testutil::Normal::new(5);
        for n in 1..40 {
            let mut v: Vec<f64> = (0..n).map(|_| rng.sample()).collect();
            let m = median(&mut v.clone());
            v.sort_by(f64::total_cmp);
            let sorted = if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) };
            assert_eq!(m, sorted, "{n}");
        }
    }

    /// Student's two-sided 1 % points against the tables (Abramowitz and
    /// Stegun, table 26.10, to the digits printed), and the normal's beyond.
    #[test]
    fn student_quantiles_match_the_tables() {
        for (dof, t) in [(1, 63.657), (2, 9.925), (3, 5.841), (4, 4.604), (5, 4.032), (9, 3.250), (30, 2.750)] {
            let found = student_two_sided_isf(0.01, dof);
            assert!((found - t).abs() < 1e-3 * t, "dof {dof}: {found} against {t}");
        }
        let far = student_two_sided_isf(0.01, 2000);
        assert!(far > normal_two_sided_isf(0.01) && far < normal_two_sided_isf(0.01) + 5e-3, "{far}");
    }
}
