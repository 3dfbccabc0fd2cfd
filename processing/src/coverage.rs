//! Coverage of an expanded uncertainty: the coverage factor `k = 2`, the
//! probability it gives a normal distribution, and the coverage interval of
//! a distribution that is not normal (a function of the readout plus a
//! normal part). A leaf: the uncertainty budget and the check points
//! ([`crate::correction::resolve`]) both use it.

/// The coverage factor stated (about 95 % for a normal distribution).
pub const K: f64 = 2.0;

/// The coverage probability of `K` for a normal distribution (95.45 %), the
/// probability the interval of a non-normal distribution is computed for.
pub fn coverage_probability() -> f64 {
    1.0 - crate::special::erfc(K / std::f64::consts::SQRT_2)
}

/// The `U` with `mean_i P(|s_i + u_n Z| <= U) = p`, `Z` standard normal:
/// the coverage interval of the readouts' left error `s` plus the normal
/// part `u_n` (bisection to 1e-12 of the range).
pub fn coverage_interval(s: &[f64], u_n: f64, p: f64) -> f64 {
    let peak = s.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let covered = |u: f64| {
        let inside: f64 = if u_n > 0.0 {
            let phi = |x: f64| 0.5 * crate::special::erfc(-x / (u_n * std::f64::consts::SQRT_2));
            s.iter().map(|&v| phi(u - v) - phi(-u - v)).sum()
        } else {
            s.iter().filter(|v| v.abs() <= u).count() as f64
        };
        inside / s.len().max(1) as f64
    };
    let (mut lo, mut hi) = (0.0, peak + 10.0 * u_n);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if covered(mid) >= p {
            hi = mid
        } else {
            lo = mid
        }
        if hi - lo <= 1e-12 * (peak + u_n) {
            break;
        }
    }
    hi
}
