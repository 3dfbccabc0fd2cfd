//! The units a report shows its errors in (`--units deg|arcsec|urad`).
//! Angles along an axis (targets, readouts) stay in degrees; every error,
//! deviation and figure is converted here, once, from the degrees the rest
//! of the program computes in.

/// The unit of every error in the report.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Units {
    /// Degrees (the contract's unit).
    #[default]
    Deg,
    /// Arcseconds (1 deg = 3600 arcsec).
    Arcsec,
    /// Microradians (1 deg = pi/180 x 1e6 urad).
    Urad,
}

impl Units {
    /// How many of this unit make one degree.
    pub fn per_deg(self) -> f64 {
        match self {
            Units::Deg => 1.0,
            Units::Arcsec => 3600.0,
            Units::Urad => std::f64::consts::PI / 180.0 * 1e6,
        }
    }

    /// `deg` in this unit.
    pub fn of(self, deg: f64) -> f64 {
        deg * self.per_deg()
    }

    /// The unit's symbol as printed (`deg`, `arcsec`, `µrad`).
    pub fn symbol(self) -> &'static str {
        match self {
            Units::Deg => "deg",
            Units::Arcsec => "arcsec",
            Units::Urad => "µrad",
        }
    }

    /// Decimals that show a tenth of the tracker's noise (about 1e-4 deg).
    fn decimals(self) -> usize {
        match self {
            Units::Deg => 5,
            Units::Arcsec => 2,
            Units::Urad => 2,
        }
    }

    /// `deg` converted and printed with the unit's decimals (no symbol).
    pub fn num(self, deg: f64) -> String {
        format!("{:.*}", self.decimals(), self.of(deg))
    }

    /// `deg` converted and printed with its symbol.
    pub fn show(self, deg: f64) -> String {
        format!("{} {}", self.num(deg), self.symbol())
    }

    /// An optional figure, `-` when absent.
    pub fn opt(self, deg: Option<f64>) -> String {
        deg.map(|d| self.num(d)).unwrap_or_else(|| "-".into())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions_are_exact_to_rounding() {
        assert_eq!(Units::Deg.of(0.01), 0.01);
        assert!((Units::Arcsec.of(0.01) - 36.0).abs() < 1e-12);
        // 1 deg = 17453.29 urad.
        assert!((Units::Urad.of(1.0) - 17_453.292_519_943_3).abs() < 1e-6);
        assert_eq!(Units::Arcsec.show(0.001), "3.60 arcsec");
        assert_eq!(Units::Deg.opt(None), "-");
    }
}
