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

/// `v` to the decimal place `10^last`.
fn at(v: f64, last: i32) -> String {
    let r = (v / 10f64.powi(last)).round() * 10f64.powi(last);
    let r = if r == 0.0 { 0.0 } else { r };
    format!("{r:.*}", (-last).max(0) as usize)
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

/// U alone (degrees) in `units`, to at most two significant digits, rounded up.
pub fn show_u(units: Units, u_deg: f64) -> String {
    match round_u(units.of(u_deg)) {
        Some((u, last)) => format!("{} {}", at(u, last), units.symbol()),
        None => units.show(u_deg),
    }
}

/// The statement of every U on the certificate.
pub const COVERAGE: &str = "The expanded uncertainty U is the standard uncertainty multiplied by the coverage \
    factor k = 2, which for a normal distribution corresponds to a coverage probability of about 95 %. U is \
    stated with at most two significant digits (rounded up) and each result rounded to the same decimal place \
    (ILAC-P14).";

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
    }
}
