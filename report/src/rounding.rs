//! ILAC-P14 (09/2020, 5.4): the expanded uncertainty U stated with at most
//! two significant digits, and the result rounded to the same decimal place
//! as U. U is rounded up (GUM 7.2.6: never state less uncertainty than was
//! estimated); the result to the nearest.

use crate::units::Units;

/// The decimal exponent of the last digit U keeps, and U rounded up to at
/// most two significant digits there; `None` for a U that is not positive.
pub fn round_u(u: f64) -> Option<(f64, i32)> {
    if !(u.is_finite() && u > 0.0) {
        return None;
    }
    let mut last = u.log10().floor() as i32 - 1;
    // 1e-9 of a digit: a U that is already of two digits stays as it is.
    let mut digits = (u / 10f64.powi(last) - 1e-9).ceil();
    if digits >= 100.0 {
        last += 1;
        digits = (digits / 10.0).ceil();
    }
    Some((digits * 10f64.powi(last), last))
}

/// `v` to the decimal place `10^last` (a value that rounds to nothing there is `0`).
fn at(v: f64, last: i32) -> String {
    let r = (v / 10f64.powi(last)).round() * 10f64.powi(last);
    if r == 0.0 { "0".into() } else { format!("{r:.*}", (-last).max(0) as usize) }
}

/// A figure (degrees) in `units` without its symbol, rounded as [`show`]
/// rounds it beside `u_deg` (a column whose unit is in its head): every
/// figure of the certificate that belongs to a U goes through here or
/// [`show`], on the page and in the DCC (one rounding).
pub fn num(units: Units, value_deg: f64, u_deg: Option<f64>) -> String {
    match u_deg.and_then(|u| round_u(units.of(u))) {
        Some((_, last)) => at(units.of(value_deg), last),
        None => units.num(value_deg),
    }
}

/// [`num`] of a figure that may be absent (`-`).
pub fn opt(units: Units, value_deg: Option<f64>, u_deg: Option<f64>) -> String {
    value_deg.map_or_else(|| "-".into(), |v| num(units, v, u_deg))
}

/// A result and its U (both degrees) in `units`, each with its symbol: U
/// to at most two significant digits (rounded up), the result to U's
/// last decimal place. Without a usable U the result by significance and `None`.
pub fn show(units: Units, value_deg: f64, u_deg: Option<f64>) -> (String, Option<String>) {
    match u_deg.and_then(|u| round_u(units.of(u))) {
        Some((u, last)) => (
            format!("{} {}", at(units.of(value_deg), last), units.symbol()),
            Some(format!("{} {}", at(u, last), units.symbol())),
        ),
        None => (units.show(value_deg), None),
    }
}

/// U alone (degrees) in `units` without its symbol, as [`show_u`] rounds it.
pub fn num_u(units: Units, u_deg: f64) -> String {
    match round_u(units.of(u_deg)) {
        Some((u, last)) => at(u, last),
        None => units.num(u_deg),
    }
}

/// U alone (degrees) in `units`, to at most two significant digits, rounded up.
pub fn show_u(units: Units, u_deg: f64) -> String {
    match round_u(units.of(u_deg)) {
        Some((u, last)) => format!("{} {}", at(u, last), units.symbol()),
        None => units.show(u_deg),
    }
}

/// The statement of every U on the certificate.
pub const COVERAGE: &str = "The expanded uncertainty U is the standard uncertainty multiplied by the coverage \
    factor k = 2, which for a normal distribution corresponds to a coverage probability of about 95 % (95.45 %); \
    the table's U is the 95.45 % coverage interval of its own distribution, not normal (what the table may leave \
    is a sum of sinusoids, propagated as GUM Supplement 1 does). U is stated with at most two significant digits \
    (rounded up) and each result, those of its table or figure without a U of their own too, rounded to the same \
    decimal place (ILAC-P14), on the certificate and in its DCC alike.";

/// The coverage probability of every U (k = 2): 95.45 %, the normal
/// distribution's, which the table's non-normal interval is computed for too.
pub const PROBABILITY: &str = "0.9545";
/// The distribution of the measured figures' U (a quadrature sum of standard uncertainties).
pub const NORMAL: &str = "normal";
/// The distribution of the table's U.
pub const TABLE_DISTRIBUTION: &str = "other: a normal part plus the sinusoids the table may leave (arcsine-like), \
    propagated as GUM Supplement 1 (JCGM 101) does; U is its 95.45 % coverage interval";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn u_keeps_two_significant_digits_rounded_up_and_the_result_follows_it() {
        assert_eq!(show_u(Units::Deg, 0.00177), "0.0018 deg");
        assert_eq!(show_u(Units::Deg, 0.0012), "0.0012 deg", "two digits already: unchanged");
        assert_eq!(show_u(Units::Deg, 0.000996), "0.0010 deg", "99.6 rounds up to 100: two digits, one place up");
        assert_eq!(show_u(Units::Deg, 23.01), "24 deg");
        assert_eq!(show_u(Units::Deg, 230.1), "240 deg");
        assert_eq!(round_u(0.0), None);
        assert_eq!(show(Units::Deg, 0.034962, Some(0.00177)), ("0.0350 deg".to_string(), Some("0.0018 deg".into())));
        assert_eq!(show(Units::Deg, 0.0173, None), ("0.0173 deg".to_string(), None));
        // In arcseconds: 0.00177 deg = 6.372 arcsec -> 6.4; 0.034962 deg = 125.86 arcsec -> 125.9.
        assert_eq!(show(Units::Arcsec, 0.034962, Some(0.00177)).0, "125.9 arcsec");
        assert_eq!(show_u(Units::Deg, 6.15e-5), "0.000062 deg");
        // One rounding for every figure beside a U, in a column or in the DCC.
        assert_eq!(num(Units::Deg, 0.00998, Some(0.0018)), "0.0100");
        assert_eq!(num(Units::Deg, 0.00916, Some(0.0018)), "0.0092");
        assert_eq!(num(Units::Deg, 0.00003, Some(0.0018)), "0", "nothing at U's place");
        assert_eq!(num(Units::Deg, 0.0123456, Some(0.000079)), "0.012346");
        assert_eq!(opt(Units::Deg, None, Some(0.0018)), "-");
    }
}
