//! Numbers in messages: a value as the user wrote it, never as 309 digits.
//!
//! Rust prints an `f64` in full positional notation (`1e308` as a 309-digit
//! number, `1e-300` as 300 zeros and a 1). Error messages name the value that
//! was wrong; [`Num`] prints large and tiny magnitudes in exponent form
//! (`1e308`, `1e-300`, `-2.5e-7`) and the rest as usual (`0.006`, `360`),
//! always the shortest text that reads back as the same number.

use std::fmt;

/// An `f64` for a message (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Num(pub f64);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = self.0.abs();
        if a == 0.0 || !a.is_finite() || (1e-4..1e6).contains(&a) {
            write!(f, "{}", self.0)
        } else {
            write!(f, "{:e}", self.0)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Num;

    #[test]
    fn large_and_tiny_values_print_in_exponent_form_and_read_back() {
        let shown = |x: f64| Num(x).to_string();
        assert_eq!(shown(1e308), "1e308");
        assert_eq!(shown(-1e308), "-1e308");
        assert_eq!(shown(1e-300), "1e-300");
        assert_eq!(shown(1e-320), "1e-320");
        assert_eq!(shown(4294967296.0), "4.294967296e9");
        assert_eq!(shown(-2.5e-7), "-2.5e-7");
        assert_eq!(shown(0.006), "0.006");
        assert_eq!(shown(360.0), "360");
        assert_eq!(shown(999999.5), "999999.5");
        assert_eq!(shown(-0.0), "-0");
        assert_eq!((shown(f64::NAN), shown(f64::INFINITY)), ("NaN".into(), "inf".into()));
        for x in [1e308, 1e-300, 1e-320, 0.1 + 0.2, 123456789.123, 1.0 / 3.0, -7e-5] {
            assert_eq!(shown(x).parse::<f64>().unwrap().to_bits(), x.to_bits(), "{x}");
            assert!(shown(x).len() <= 24, "{}", shown(x));
        }
    }
}
