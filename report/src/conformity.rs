//! The verdict against a tolerance (`survey report --tolerance DEG`), by the
//! decision rule of ISO 14253-1 and ILAC-G8 (a guard band of the expanded
//! uncertainty): the figure passes when it is within the tolerance by more
//! than its uncertainty (`A + U <= T`), fails when it exceeds the tolerance
//! by more than its uncertainty (`A - U > T`), and is otherwise not decidable
//! within the uncertainty. Without a known uncertainty nothing is decidable.
//!
//! The figure judged is ISO 230-2's accuracy A: the corrected A, measured by
//! a verification survey with the table applied, when there is one; else
//! the native A of the survey. Its expanded uncertainty ([`accuracy_u_deg`])
//! is the measurement's: the reference instrument and, with a tracker, the
//! axis the angles are computed around, combined and expanded with k = 2
//! (ISO 230-2 Annex A's measuring-instrument and set-up contributions). The
//! scatter over the runs is already inside A (its ±2 s bands) and is not
//! counted twice.

/// The rule in words, as every verdict states it.
pub const RULE: &str = "Decision rule: ILAC-G8:09/2019 guarded acceptance and guarded rejection with a guard band \
    w = U (ISO 14253-1): pass when A + U ≤ the tolerance (the probability of a false pass is at most about 2.5 %); \
    fail when A − U > the tolerance; otherwise not decidable within the uncertainty, and no pass or fail is stated. \
    Without a stated U nothing is decidable.";

/// The coverage factor of the stated uncertainty.
pub const K: f64 = 2.0;

/// What the rule decided.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    /// `A + U <= T`.
    Pass,
    /// `A - U > T`.
    Fail,
    /// Neither: the tolerance lies within the uncertainty of the figure, or the uncertainty is unknown.
    NotDecidable,
}

impl Decision {
    /// The word a certificate prints.
    pub fn word(self) -> &'static str {
        match self {
            Decision::Pass => "pass",
            Decision::Fail => "fail",
            Decision::NotDecidable => "not decidable (within the uncertainty)",
        }
    }
}

/// The rule: `figure` with expanded uncertainty `u` (`None`: unknown) against `tolerance`.
pub fn decide(figure: f64, u: Option<f64>, tolerance: f64) -> Decision {
    match u {
        Some(u) if figure + u <= tolerance => Decision::Pass,
        Some(u) if figure - u > tolerance => Decision::Fail,
        _ => Decision::NotDecidable,
    }
}

/// The expanded uncertainty (k = 2) of a measured ISO 230-2 accuracy A, from
/// the reference's standard uncertainty of one angle (random), its
/// systematic part at an angle (a tracker's own error, the same at a
/// target in every run) and the axis location's (a tracker), degrees;
/// `None` when the reference's is not stated.
pub fn accuracy_u_deg(
    reference_u_deg: Option<f64>,
    systematic_u_deg: Option<f64>,
    axis_u_deg: Option<f64>,
) -> Option<f64> {
    let square = |u: Option<f64>| u.unwrap_or(0.0).powi(2);
    reference_u_deg.map(|r| K * (r * r + square(systematic_u_deg) + square(axis_u_deg)).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_guard_band_is_the_uncertainty() {
        // A = 0.010 deg, U = 0.002 deg.
        assert_eq!(decide(0.010, Some(0.002), 0.012), Decision::Pass, "A + U on the tolerance passes");
        assert_eq!(decide(0.010, Some(0.002), 0.011), Decision::NotDecidable, "within U below");
        assert_eq!(decide(0.010, Some(0.002), 0.008), Decision::NotDecidable, "A - U on the tolerance");
        assert_eq!(decide(0.010, Some(0.002), 0.0079), Decision::Fail, "beyond U above");
        assert_eq!(decide(0.001, None, 1.0), Decision::NotDecidable, "no uncertainty, no decision");
        assert_eq!(Decision::NotDecidable.word(), "not decidable (within the uncertainty)");
    }

    #[test]
    fn the_accuracy_uncertainty_combines_reference_and_axis() {
        assert_eq!(accuracy_u_deg(None, None, Some(1e-4)), None);
        assert!((accuracy_u_deg(Some(3e-4), None, Some(4e-4)).unwrap() - 1e-3).abs() < 1e-15);
        assert!((accuracy_u_deg(Some(5e-4), None, None).unwrap() - 1e-3).abs() < 1e-15);
        assert!((accuracy_u_deg(Some(2e-4), Some(4e-4), Some(4e-4)).unwrap() - 1.2e-3).abs() < 1e-15);
    }
}
