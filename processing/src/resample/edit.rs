//! Editing a survey's spectrum: keep the repeatable lines, null or relocate
//! aliased ones (the paper's section 4, Figures 4 and 5).
//!
//! The edit acts on the [`Series`] of the survey's mean error map, in this
//! order:
//!
//! 1. **Relocate.** For each [`Relocation`], the complex amplitude in the
//!    observed bin `b` moves to the true bin `f` (conjugated when the alias is
//!    a mirror image, see [`alias_of`](super::alias_of)) and bin `b` is emptied.
//!    The series is then evaluated on a dense grid of `M > 2 f` points, which
//!    has room for `f`: the paper's "resample to a higher rate and move the
//!    line". Everything in bin `b` moves: if another source also contributes
//!    there, the operator should null the bin instead (the paper's caution).
//! 2. **Keep.** [`Keep`] filters the lines from 1 cycle up, after relocation, so
//!    it names true frequencies (432, not 288). Relocated lines are always kept:
//!    relocating is already the choice to keep them.
//! 3. **Null.** Listed bins are set to zero (an aliased spur that cannot be
//!    relocated with confidence, or any line the operator excludes).
//! 4. **Mean.** With `remove_mean`, the mean (bin 0: the zero reference of the
//!    reference instrument) is removed; by default it stays in the table.
//!
//! The edit is plain data (serde) so the recipe file can store it and a
//! recalibration replays it on new data. In TOML:
//!
//! ```toml
//! keep = { mode = "lines", cycles = [2, 12, 24, 36, 48, 60, 204, 216, 228] }
//! null = []
//! relocate = [{ observed_cycles = 288, true_cycles = 432 }, { observed_cycles = 72, true_cycles = 648 }]
//! ```

use super::{Complex64, Series, alias_of};
use serde::{Deserialize, Serialize};

/// Which lines (1 cycle and up) survive the edit.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "mode", rename_all = "snake_case", deny_unknown_fields)]
pub enum Keep {
    /// Every line (no filtering): `{ mode = "all" }`.
    #[default]
    All,
    /// Only these lines, cycles per revolution: `{ mode = "lines", cycles = [...] }`.
    Lines {
        /// The lines to keep (true frequencies, after relocation).
        cycles: Vec<usize>,
    },
    /// Lines whose amplitude is at least this many degrees:
    /// `{ mode = "above_threshold", amplitude_deg = ... }`.
    ///
    /// Choosing it: white noise of standard deviation `sigma_m` on a mean map
    /// of `N` points gives every bin a Rayleigh-distributed amplitude of RMS
    /// `2 sigma_m / sqrt(N)`; a bin passes a threshold `t` with probability
    /// `exp(-(t / rms)^2)`, so 4 to 5 times that RMS keeps no noise line.
    AboveThreshold {
        /// The smallest amplitude kept, degrees.
        amplitude_deg: f64,
    },
}

/// Move the line seen in bin `observed_cycles` to `true_cycles`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Relocation {
    /// The bin the aliased line appears in, cycles per revolution.
    pub observed_cycles: usize,
    /// Its true frequency (above the survey's Nyquist, `N/2`).
    pub true_cycles: usize,
}

/// An edit of the spectrum of an error map (see the module documentation).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpectralEdit {
    /// Which lines survive (default: all).
    #[serde(default)]
    pub keep: Keep,
    /// Bins set to zero, cycles per revolution (default: none).
    #[serde(default)]
    pub null: Vec<usize>,
    /// Aliased lines moved to their true frequency (default: none).
    #[serde(default)]
    pub relocate: Vec<Relocation>,
    /// Remove the mean error from the table (default: false, the mean stays).
    #[serde(default)]
    pub remove_mean: bool,
}

/// Why an edit cannot be applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EditError {
    /// The true frequency is not above the survey's Nyquist, so it cannot alias.
    #[error(
        "relocation {observed} -> {true_cycles}: {true_cycles} cycles is below the Nyquist \
         frequency of {points} points ({nyquist}), it is not aliased"
    )]
    NotAliased {
        /// The observed bin given.
        observed: usize,
        /// The true frequency given.
        true_cycles: usize,
        /// Survey points per revolution.
        points: usize,
        /// `points / 2`.
        nyquist: usize,
    },
    /// The true frequency aliases to another bin than the one given.
    #[error(
        "relocation {observed} -> {true_cycles}: with {points} points, {true_cycles} cycles \
         appear at {expected}, not at {observed}"
    )]
    NotAnAlias {
        /// The observed bin given.
        observed: usize,
        /// The true frequency given.
        true_cycles: usize,
        /// Survey points per revolution.
        points: usize,
        /// Where the true frequency does appear.
        expected: usize,
    },
    /// The true frequency aliases onto the mean or the Nyquist bin, where its
    /// phase is lost.
    #[error(
        "relocation {observed} -> {true_cycles}: with {points} points the line falls on bin \
         {observed} (mean or Nyquist), where its phase is lost; null it instead"
    )]
    PhaseLost {
        /// The bin the line falls on (0 or `points / 2`).
        observed: usize,
        /// The true frequency given.
        true_cycles: usize,
        /// Survey points per revolution.
        points: usize,
    },
    /// The dense grid has no room for the true frequency.
    #[error("relocation to {true_cycles} cycles needs more than {need} dense points, got {dense}")]
    DenseTooSmall {
        /// The true frequency given.
        true_cycles: usize,
        /// The dense grid size.
        dense: usize,
        /// `2 * true_cycles`: the dense grid must be larger.
        need: usize,
    },
    /// Two relocations share a bin.
    #[error("bin {cycles} appears in more than one relocation")]
    DuplicateRelocation {
        /// The shared bin.
        cycles: usize,
    },
    /// A bin is both nulled and relocated.
    #[error("bin {cycles} is both nulled and relocated")]
    NulledAndRelocated {
        /// The bin.
        cycles: usize,
    },
    /// The threshold of [`Keep::AboveThreshold`] is negative or not finite.
    #[error("keep threshold {} deg must be a finite, non-negative number", crate::num::Num(*.0))]
    BadThreshold(f64),
}

impl SpectralEdit {
    /// No edit: keep everything.
    pub fn none() -> Self {
        Self::default()
    }

    /// Check the edit against a survey of `points` points resampled to
    /// `dense` points, without applying it.
    pub fn validate(&self, points: usize, dense: usize) -> Result<(), EditError> {
        if let Keep::AboveThreshold { amplitude_deg } = self.keep
            && !(amplitude_deg.is_finite() && amplitude_deg >= 0.0)
        {
            return Err(EditError::BadThreshold(amplitude_deg));
        }
        let mut seen: Vec<usize> = Vec::with_capacity(2 * self.relocate.len());
        for r in &self.relocate {
            let (observed, true_cycles) = (r.observed_cycles, r.true_cycles);
            if 2 * true_cycles <= points {
                return Err(EditError::NotAliased { observed, true_cycles, points, nyquist: points / 2 });
            }
            let a = alias_of(true_cycles, points);
            if a.observed_cycles == 0 || 2 * a.observed_cycles == points {
                return Err(EditError::PhaseLost { observed: a.observed_cycles, true_cycles, points });
            }
            if a.observed_cycles != observed {
                return Err(EditError::NotAnAlias { observed, true_cycles, points, expected: a.observed_cycles });
            }
            if 2 * true_cycles >= dense {
                return Err(EditError::DenseTooSmall { true_cycles, dense, need: 2 * true_cycles });
            }
            for c in [observed, true_cycles] {
                if seen.contains(&c) {
                    return Err(EditError::DuplicateRelocation { cycles: c });
                }
                if self.null.contains(&c) {
                    return Err(EditError::NulledAndRelocated { cycles: c });
                }
                seen.push(c);
            }
        }
        Ok(())
    }

    /// Apply the edit to the series of a `points`-point survey that will be
    /// resampled to `dense` points (see the module documentation for the order).
    pub fn apply(&self, series: &mut Series, points: usize, dense: usize) -> Result<(), EditError> {
        self.validate(points, dense)?;
        for r in &self.relocate {
            let c = series.coeff(r.observed_cycles);
            series.set_coeff(r.observed_cycles, Complex64::default());
            let moved = if alias_of(r.true_cycles, points).conjugated { c.conj() } else { c };
            series.set_coeff(r.true_cycles, moved);
        }
        let relocated = |k: usize| self.relocate.iter().any(|r| r.true_cycles == k);
        match &self.keep {
            Keep::All => {}
            Keep::Lines { cycles } => {
                for k in 1..series.bins() {
                    if !cycles.contains(&k) && !relocated(k) {
                        series.set_coeff(k, Complex64::default());
                    }
                }
            }
            Keep::AboveThreshold { amplitude_deg } => {
                for k in 1..series.bins() {
                    if series.amplitude(k) < *amplitude_deg && !relocated(k) {
                        series.set_coeff(k, Complex64::default());
                    }
                }
            }
        }
        for &k in &self.null {
            series.set_coeff(k, Complex64::default());
        }
        if self.remove_mean {
            series.set_coeff(0, Complex64::default());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::Resampler;
    use super::*;

    fn sampled(s: &Series, n: usize) -> Vec<f64> {
        (0..n).map(|j| s.eval(360.0 * j as f64 / n as f64)).collect()
    }

    /// A single sinusoid of known phase above the Nyquist of 720 points,
    /// relocated from its alias, is exact on the dense grid.
    #[test]
    fn relocation_restores_a_single_sinusoid_exactly() {
        let mut rs = Resampler::new();
        for (f, b, phase) in [(432usize, 288usize, 45.0), (648, 72, 90.0), (648, 72, -123.0), (1000, 280, 17.0)] {
            let truth = Series::from_sines(0.0, &[(f, 0.0004, phase)]);
            let y = sampled(&truth, 720);
            let mut s = rs.analyze(&y);
            // The alias: amplitude at b, phase 180 - phase when conjugated.
            assert!((s.amplitude(b) - 0.0004).abs() < 1e-15, "f={f}");
            let conj = alias_of(f, 720).conjugated;
            let seen_phase = if conj { 180.0 - phase } else { phase };
            let d = (s.phase_deg(b) - seen_phase).rem_euclid(360.0);
            assert!(d.min(360.0 - d) < 1e-9, "f={f}: phase {} vs {seen_phase}", s.phase_deg(b));
            let edit = SpectralEdit {
                relocate: vec![Relocation { observed_cycles: b, true_cycles: f }],
                ..SpectralEdit::none()
            };
            edit.apply(&mut s, 720, 4096).unwrap();
            let dense = rs.synthesize(&s, 4096);
            let err = dense
                .iter()
                .enumerate()
                .map(|(j, v)| (v - 0.0004 * (f as f64 * 360.0 * j as f64 / 4096.0 + phase).to_radians().sin()).abs())
                .fold(0.0, f64::max);
            assert!(err < 1e-12, "f={f}: {err:e}");
            assert!(s.amplitude(b) == 0.0);
        }
    }

    #[test]
    fn keep_null_and_mean() {
        let base = Series::from_sines(0.1, &[(2, 0.002, 0.0), (12, 0.006, 10.0), (13, 1e-6, 0.0), (50, 0.001, 0.0)]);
        let mut s = base.clone();
        SpectralEdit { keep: Keep::Lines { cycles: vec![2, 12] }, ..SpectralEdit::none() }
            .apply(&mut s, 128, 1024)
            .unwrap();
        assert_eq!((s.amplitude(13), s.amplitude(50)), (0.0, 0.0));
        assert_eq!(s.coeff(12), base.coeff(12));
        assert_eq!(s.amplitude(0), 0.1);

        let mut s = base.clone();
        let edit = SpectralEdit {
            keep: Keep::AboveThreshold { amplitude_deg: 1e-5 },
            null: vec![50],
            remove_mean: true,
            ..SpectralEdit::none()
        };
        edit.apply(&mut s, 128, 1024).unwrap();
        assert_eq!(s.amplitude(13), 0.0);
        assert_eq!(s.amplitude(50), 0.0);
        assert_eq!(s.amplitude(0), 0.0);
        assert_eq!(s.coeff(2), base.coeff(2));
        assert_eq!(s.coeff(12), base.coeff(12));
    }

    #[test]
    fn relocated_lines_survive_the_keep_filter() {
        let truth = Series::from_sines(0.0, &[(12, 0.006, 0.0), (432, 0.0004, 45.0)]);
        let mut s = Resampler::new().analyze(&sampled(&truth, 720));
        let edit = SpectralEdit {
            keep: Keep::Lines { cycles: vec![12] },
            relocate: vec![Relocation { observed_cycles: 288, true_cycles: 432 }],
            ..SpectralEdit::none()
        };
        edit.apply(&mut s, 720, 2048).unwrap();
        assert!((s.coeff(432) - truth.coeff(432)).norm() < 1e-15);
        assert!((s.coeff(12) - truth.coeff(12)).norm() < 1e-15);
    }

    #[test]
    fn invalid_edits_are_named() {
        let r = |o, t| SpectralEdit {
            relocate: vec![Relocation { observed_cycles: o, true_cycles: t }],
            ..SpectralEdit::none()
        };
        assert!(matches!(r(288, 432).validate(720, 864), Err(EditError::DenseTooSmall { need: 864, .. })));
        assert!(r(288, 432).validate(720, 865).is_ok());
        assert!(matches!(r(216, 216).validate(720, 4096), Err(EditError::NotAliased { .. })));
        assert!(matches!(r(280, 432).validate(720, 4096), Err(EditError::NotAnAlias { expected: 288, .. })));
        assert!(matches!(r(0, 720).validate(720, 4096), Err(EditError::PhaseLost { .. })));
        assert!(matches!(r(360, 1080).validate(720, 4096), Err(EditError::PhaseLost { .. })));
        let mut dup = r(288, 432);
        dup.relocate.push(Relocation { observed_cycles: 288, true_cycles: 1008 });
        assert_eq!(dup.validate(720, 4096), Err(EditError::DuplicateRelocation { cycles: 288 }));
        let mut both = r(72, 648);
        both.null.push(72);
        assert_eq!(both.validate(720, 4096), Err(EditError::NulledAndRelocated { cycles: 72 }));
        let bad = SpectralEdit { keep: Keep::AboveThreshold { amplitude_deg: f64::NAN }, ..SpectralEdit::none() };
        assert!(matches!(bad.validate(720, 4096), Err(EditError::BadThreshold(_))));
        assert!(r(280, 432).validate(720, 4096).unwrap_err().to_string().contains("appear at 288"));
    }

    #[test]
    fn edits_round_trip_through_toml_and_json() {
        let edit = SpectralEdit {
            keep: Keep::Lines { cycles: vec![2, 12, 216] },
            null: vec![72],
            relocate: vec![Relocation { observed_cycles: 288, true_cycles: 432 }],
            remove_mean: false,
        };
        let text = toml::to_string(&edit).unwrap();
        assert_eq!(toml::from_str::<SpectralEdit>(&text).unwrap(), edit, "{text}");
        let json = serde_json::to_string(&edit).unwrap();
        assert_eq!(serde_json::from_str::<SpectralEdit>(&json).unwrap(), edit);
        // The documented recipe form parses; missing keys take their defaults.
        let doc: SpectralEdit = toml::from_str(
            "keep = { mode = \"above_threshold\", amplitude_deg = 1e-5 }\n\
             relocate = [{ observed_cycles = 72, true_cycles = 648 }]\n",
        )
        .unwrap();
        assert_eq!(doc.keep, Keep::AboveThreshold { amplitude_deg: 1e-5 });
        assert!(doc.null.is_empty() && !doc.remove_mean);
        assert_eq!(toml::from_str::<SpectralEdit>("").unwrap(), SpectralEdit::none());
        assert!(toml::from_str::<SpectralEdit>("nul = [1]").is_err());
        assert!(toml::from_str::<SpectralEdit>("keep = { mode = \"some\" }").is_err());
    }
}
