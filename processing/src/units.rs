//! The units errors are shown in (`--units deg|arcsec|urad`, the report and
//! every command's text). Angles along an axis (targets, readouts) stay in
//! degrees; every error, deviation and figure is converted here, once, from
//! the degrees the rest of the program computes in (and every file and JSON
//! document keeps).

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

    /// The unit's name in words (`degrees`, `arcseconds`, `microradians`).
    pub fn name(self) -> &'static str {
        match self {
            Units::Deg => "degrees",
            Units::Arcsec => "arcseconds",
            Units::Urad => "microradians",
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

    /// `deg` converted and printed by significance ([`significant`]), no symbol.
    pub fn num(self, deg: f64) -> String {
        significant(self.of(deg))
    }

    /// `deg` converted and printed with its symbol.
    pub fn show(self, deg: f64) -> String {
        format!("{} {}", self.num(deg), self.symbol())
    }

    /// `text` (a sentence of the processing, whose errors are in degrees)
    /// with each error in this unit: a number below 1 followed by ` deg`
    /// (an error: angles along the axis, phases and ranges are left as they
    /// are: a number of 1 or more, one after `at`, `from` or `to`, or one in
    /// a clause about a phase).
    pub fn text(self, text: &str) -> String {
        if self == Units::Deg {
            return text.to_string();
        }
        let mut out = String::with_capacity(text.len());
        let mut rest = text;
        while let Some(at) = rest.find(" deg") {
            let (before, after) = rest.split_at(at);
            let start = before
                .char_indices()
                .rev()
                .take_while(|(_, c)| c.is_ascii_digit() || matches!(c, '.' | 'e' | '-' | '+'))
                .last()
                .map_or(before.len(), |(i, _)| i);
            let (head, number) = before.split_at(start);
            let word_ends = after[4..].chars().next().is_none_or(|c| !c.is_alphanumeric());
            let clause = head.rsplit([',', ';', '(']).next().unwrap_or(head);
            // "at 0 deg", "from 0.5 deg": a position along the axis.
            let position = head.ends_with(" at ") || head.ends_with(" from ") || head.ends_with(" to ");
            match number.parse::<f64>() {
                Ok(v) if word_ends && v.abs() < 1.0 && !clause.contains("phase") && !position => {
                    out += head;
                    if number.starts_with('+') {
                        out += "+";
                    }
                    out += &self.show(v);
                }
                _ => out += &rest[..at + 4],
            }
            rest = &after[4..];
        }
        out + rest
    }

    /// An optional figure, `-` when absent.
    pub fn opt(self, deg: Option<f64>) -> String {
        deg.map(|d| self.num(d)).unwrap_or_else(|| "-".into())
    }

    /// `deg` in this unit, fixed-point, to the resolution `deg_decimals`
    /// decimals give in degrees (a text table's column: 6 decimals of a
    /// degree are 3 of an arcsecond, 2 of a microradian), no symbol.
    pub fn fixed(self, deg: f64, deg_decimals: usize) -> String {
        let shift = self.per_deg().log10().floor() as usize;
        format!("{:.*}", deg_decimals.saturating_sub(shift), self.of(deg))
    }

    /// A small error as the text summaries print it, no symbol: in degrees
    /// in exponent form with `digits` decimals (`7.80e-4`), in another unit
    /// by significance (`2.81`); `signed` puts a `+` before a positive value.
    pub fn small(self, deg: f64, digits: usize, signed: bool) -> String {
        let shown = match self {
            Units::Deg => format!("{deg:.digits$e}"),
            _ => significant(self.of(deg)),
        };
        if signed && !shown.starts_with('-') { format!("+{shown}") } else { shown }
    }
}

/// `v` with three significant digits: fixed-point from 1e-4 up to 1e6 (so
/// 0.000884, 0.0344, 121), exponent form outside (2.36e-6), `0` for zero.
/// Never a row of zeros for a small value, never false precision.
pub fn significant(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return "-".into();
    }
    let e = format!("{v:.2e}");
    let exponent: i32 = e.rsplit('e').next().and_then(|x| x.parse().ok()).unwrap_or(0);
    if (-4..6).contains(&exponent) { format!("{v:.*}", (2 - exponent).max(0) as usize) } else { e }
}

/// An angle along the axis, degrees, to 0.0001 deg and no trailing zero
/// (`0`, `12.5`, `359.0001`): a position, not a measured error.
pub fn angle(deg: f64) -> String {
    let r = (deg * 1e4).round() / 1e4;
    format!("{}", if r == 0.0 { 0.0 } else { r })
}

/// A fraction as a percentage by significance: `37.5 %`, `0.25 %`, `< 0.1 %` below a thousandth, `0 %`.
pub fn percent(fraction: f64) -> String {
    let p = fraction * 100.0;
    match p {
        0.0 => "0 %".into(),
        p if p.abs() < 0.1 => "< 0.1 %".into(),
        p => format!("{} %", significant(p)),
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

    #[test]
    fn numbers_are_shown_by_significance_never_as_zeros() {
        for (v, shown) in [
            (0.0344, "0.0344"),
            (0.000884, "0.000884"),
            (121.31, "121"),
            (9.996, "10.0"),
            (-30.004, "-30.0"),
            (2.357e-6, "2.36e-6"),
            (1.0e-4, "0.000100"),
            (0.0, "0"),
            (123_456_789.0, "1.23e8"),
        ] {
            assert_eq!(significant(v), shown, "{v}");
        }
        assert_eq!(Units::Deg.num(2.2e-7), "2.20e-7", "the interpolation's share is not 0.00000");
        assert_eq!(Units::Arcsec.num(2.2e-7), "0.000792");
        assert_eq!(
            (angle(0.0), angle(-0.00001), angle(12.5), angle(359.00012)),
            ("0".into(), "0".into(), "12.5".into(), "359.0001".into())
        );
        assert_eq!(
            (percent(0.375), percent(0.0025), percent(1e-6), percent(0.0)),
            ("37.5 %".into(), "0.250 %".into(), "< 0.1 %".into(), "0 %".into())
        );
    }

    #[test]
    fn text_columns_keep_their_resolution_in_every_unit() {
        assert_eq!(Units::Deg.fixed(0.001498, 6), "0.001498");
        assert_eq!(Units::Arcsec.fixed(0.001498, 6), "5.393");
        assert_eq!(Units::Urad.fixed(0.001498, 6), "26.15");
        assert_eq!(Units::Arcsec.fixed(0.01522, 5), "54.79");
        assert_eq!(Units::Deg.small(7.8e-4, 2, false), "7.80e-4");
        assert_eq!(Units::Deg.small(7.8e-4, 2, true), "+7.80e-4");
        assert_eq!(Units::Arcsec.small(7.8e-4, 2, false), "2.81");
        assert_eq!(Units::Arcsec.small(-7.8e-4, 2, true), "-2.81");
    }

    #[test]
    fn errors_in_sentences_take_the_unit_and_angles_stay_in_degrees() {
        let s = "hysteresis max 0.00116 deg > 5 x 7.48e-5 deg (its noise); partial range -10 to 90 deg, phase 0.5 deg";
        assert_eq!(
            Units::Arcsec.text(s),
            "hysteresis max 4.18 arcsec > 5 x 0.269 arcsec (its noise); partial range -10 to 90 deg, phase 0.5 deg"
        );
        assert_eq!(Units::Deg.text(s), s);
        assert_eq!(Units::Arcsec.text("drift 1.0e-3 deg per run, 12 degrees"), "drift 3.60 arcsec per run, 12 degrees");
        assert_eq!(
            Units::Arcsec.text("largest +1.00e-3 deg at 0 deg, from 0.5 deg to 0.75 deg"),
            "largest +3.60 arcsec at 0 deg, from 0.5 deg to 0.75 deg"
        );
    }
}
