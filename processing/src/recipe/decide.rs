//! What a recipe does with one survey's analysis (see the parent module).

use super::{AliasChoiceAction, ChoiceError, Recipe, Unlisted};
use crate::analysis::{AliasAction, Analysis};
use crate::errormap::Coverage;
use crate::resample::{EditError, Keep, Relocation, SpectralEdit, alias_of};
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet};

/// What happened to a line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LineAction {
    /// In the table at its frequency.
    Kept,
    /// Not in the table.
    Removed,
    /// Moved from its alias bin to its true frequency, and in the table.
    Relocated,
    /// Its bin was emptied (an aliased spur shares it).
    Nulled,
}

/// The fate of one line: each significant line of the survey, and each line
/// the recipe keeps that the survey did not flag.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LineDecision {
    /// Where the survey sees it, cycles/rev (the bin, or the fitted frequency).
    pub cycles_per_rev: f64,
    /// Its true frequency, cycles/rev.
    pub true_cycles_per_rev: f64,
    /// A significant line of this survey's analysis.
    pub significant: bool,
    /// Repeatable in this survey.
    pub repeatable: bool,
    /// Amplitude, degrees (the line's, or the mean spectrum's at that bin).
    pub amplitude_deg: f64,
    /// What happened to it.
    pub action: LineAction,
    /// Whether the recipe named it (else a rule decided).
    pub from_recipe: bool,
    /// Why, in words.
    pub reason: String,
}

/// What happened to an aliased design harmonic: `relocated` or `nulled`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AliasOutcome {
    /// Moved to its true frequency.
    Relocated,
    /// Not carried by the table.
    Nulled,
}

/// The fate of one aliased design harmonic.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AliasDecision {
    /// The bin it appears in, cycles/rev.
    pub observed_cycles: f64,
    /// Its true frequency, cycles/rev.
    pub true_cycles: f64,
    /// `relocated` or `nulled`.
    pub action: AliasOutcome,
    /// Whether the spectral edit acts on its bin (a bin with no line is simply
    /// left out of the table by the keep filter).
    pub applied: bool,
    /// Whether the recipe decided it (else the analysis' recommendation).
    pub from_recipe: bool,
    /// The analysis' recommendation, when the analysis reported it.
    pub recommended: Option<AliasAction>,
    /// The design part(s) it comes from.
    pub source: String,
    /// Why, in words.
    pub reason: String,
}

/// Everything [`Recipe::decide`] settles for one survey.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Decisions {
    /// The spectral edit of a full circle (no edit for a partial range).
    pub edit: SpectralEdit,
    /// Points per revolution of a full circle.
    pub points: Option<usize>,
    /// The true frequencies the table carries, ascending.
    pub kept_cycles: Vec<f64>,
    /// Per line.
    pub lines: Vec<LineDecision>,
    /// Per aliased design harmonic.
    pub aliases: Vec<AliasDecision>,
    /// Remarks (recipe entries that meant something else on this survey).
    pub notes: Vec<String>,
}

fn whole(key: &str, f: f64, n: usize) -> Result<usize, ChoiceError> {
    if f.fract() == 0.0 && (1.0..1e12).contains(&f) {
        Ok(f as usize)
    } else {
        Err(ChoiceError::new(key, format!("{f} cycles/rev: a full circle of {n} points has whole-number lines only")))
    }
}

fn edit_error(e: EditError) -> ChoiceError {
    match e {
        EditError::DenseTooSmall { .. } => ChoiceError::new("table.dense_points", e.to_string()),
        other => ChoiceError::new("alias", other.to_string()),
    }
}

impl Recipe {
    /// Decide, for this survey's `analysis`, which lines the table carries and
    /// what happens to every aliased line (see the module documentation).
    pub fn decide(&self, analysis: &Analysis) -> Result<Decisions, ChoiceError> {
        match analysis.error_map.coverage {
            Coverage::FullCircle { n } => self.decide_full(analysis, n),
            Coverage::Partial { .. } => Ok(self.decide_partial(analysis)),
        }
    }

    fn decide_full(&self, analysis: &Analysis, n: usize) -> Result<Decisions, ChoiceError> {
        let mut notes = Vec::new();
        let mut keep = BTreeSet::new();
        let mut removed = BTreeSet::new();
        let mut null = BTreeSet::new();
        // bin -> (true frequency, key of the choice that claimed it)
        let mut relocated: BTreeMap<usize, (usize, String)> = BTreeMap::new();
        let mut aliases = Vec::new();
        let bin_of = |c: f64| c.round() as usize;
        let amplitude_at =
            |k: usize| analysis.spectra.as_ref().and_then(|s| s.mean.bins.get(k)).map_or(0.0, |b| b.amplitude_deg);
        let claim = |b: usize, f: usize, key: String, relocated: &mut BTreeMap<usize, (usize, String)>| {
            if let Some((other, by)) = relocated.get(&b) {
                return Err(ChoiceError::new(
                    key,
                    format!(
                        "{f} and {other} cycles/rev ({by}) both appear at bin {b} with {n} points; one bin can be relocated to one frequency only: null one of them"
                    ),
                ));
            }
            relocated.insert(b, (f, key));
            Ok(())
        };

        // The recipe's lines.
        let mut keep_high = Vec::new();
        for &f in &self.lines.keep {
            let f = whole("lines.keep", f, n)?;
            if 2 * f < n {
                keep.insert(f);
            } else {
                keep_high.push(f);
            }
        }
        let mut remove_high = Vec::new();
        for &f in &self.lines.remove {
            let f = whole("lines.remove", f, n)?;
            if 2 * f < n {
                removed.insert(f);
            } else {
                remove_high.push(f);
            }
        }

        // The recipe's [[alias]] entries.
        for (i, a) in self.aliases.iter().enumerate() {
            let key = format!("alias[{}].true_cycles", i + 1);
            let f = a.true_cycles;
            if 2 * f < n {
                let (set, what) = match a.action {
                    AliasChoiceAction::Relocate => (&mut keep, "kept as a line"),
                    AliasChoiceAction::Null | AliasChoiceAction::Absent => (&mut removed, "removed as a line"),
                };
                set.insert(f);
                notes.push(format!("alias[{}]: {f} cycles/rev is resolved by this survey's {n} points: {what}", i + 1));
                continue;
            }
            let b = alias_of(f, n).observed_cycles;
            let report = analysis.aliases.iter().find(|e| e.true_cycles == f as f64);
            let by_recipe = |what: &str| match report {
                Some(e) => {
                    let rec = if e.action == AliasAction::Relocate { "relocate" } else { "null" };
                    format!("{what} by the recipe (the analysis recommends {rec}: {})", e.reason)
                }
                None => format!("{what} by the recipe"),
            };
            let (action, applied, reason) = if b == 0 {
                (
                    AliasOutcome::Nulled,
                    false,
                    format!("lands on bin 0 with {n} points: it cannot be told from the zero offset and is left alone"),
                )
            } else if 2 * b == n {
                null.insert(b);
                (
                    AliasOutcome::Nulled,
                    true,
                    format!("lands on the Nyquist bin {b}, where its phase is lost: nulled (recipe: {:?})", a.action),
                )
            } else {
                match a.action {
                    AliasChoiceAction::Relocate => {
                        claim(b, f, format!("alias[{}]", i + 1), &mut relocated)
                            .map_err(|e| ChoiceError { key: key.clone(), ..e })?;
                        (AliasOutcome::Relocated, true, by_recipe("relocated"))
                    }
                    AliasChoiceAction::Null => {
                        null.insert(b);
                        (AliasOutcome::Nulled, true, by_recipe("nulled"))
                    }
                    AliasChoiceAction::Absent => (
                        AliasOutcome::Nulled,
                        false,
                        by_recipe("absent (not there: check points showed it), its bin left to the other frequency"),
                    ),
                }
            };
            aliases.push(AliasDecision {
                observed_cycles: b as f64,
                true_cycles: f as f64,
                action,
                applied,
                from_recipe: true,
                recommended: report.map(|e| e.action),
                source: report.map(|e| e.source.clone()).or_else(|| a.source.clone()).unwrap_or_default(),
                reason,
            });
        }
        // Kept or removed lines this survey cannot resolve: through their alias.
        for f in keep_high {
            let b = alias_of(f, n).observed_cycles;
            if b == 0 || 2 * b == n {
                notes.push(format!("lines.keep: {f} cycles/rev lands on bin {b} with {n} points, where its phase is lost: it cannot be in the table"));
                continue;
            }
            claim(b, f, "lines.keep".into(), &mut relocated)?;
            notes.push(format!(
                "lines.keep: {f} cycles/rev is above this survey's Nyquist ({n} points): relocated from bin {b}"
            ));
        }
        for f in remove_high {
            let b = alias_of(f, n).observed_cycles;
            if b != 0 && !relocated.contains_key(&b) {
                null.insert(b);
            }
        }
        for (b, (_, key)) in &relocated {
            if null.contains(b) {
                return Err(ChoiceError::new(
                    key.clone(),
                    format!("bin {b} is both relocated and nulled with {n} points"),
                ));
            }
        }

        // The analysis' aliased harmonics the recipe does not name.
        let named = |f: f64| {
            self.aliases.iter().any(|a| a.true_cycles as f64 == f)
                || self.lines.keep.contains(&f)
                || self.lines.remove.contains(&f)
        };
        for e in &analysis.aliases {
            if named(e.true_cycles) {
                if !aliases.iter().any(|d: &AliasDecision| d.true_cycles == e.true_cycles) {
                    let b = bin_of(e.observed_cycles);
                    let moved = relocated.get(&b).is_some_and(|(f, _)| *f as f64 == e.true_cycles);
                    aliases.push(AliasDecision {
                        observed_cycles: e.observed_cycles,
                        true_cycles: e.true_cycles,
                        action: if moved { AliasOutcome::Relocated } else { AliasOutcome::Nulled },
                        applied: moved || null.contains(&b),
                        from_recipe: true,
                        recommended: Some(e.action),
                        source: e.source.clone(),
                        reason: "decided by the recipe's [lines]".into(),
                    });
                }
                continue;
            }
            let b = bin_of(e.observed_cycles);
            let line = analysis.lines.iter().find(|l| bin_of(l.cycles_per_rev) == b);
            let decision = |action: AliasOutcome, applied: bool, reason: String| AliasDecision {
                observed_cycles: e.observed_cycles,
                true_cycles: e.true_cycles,
                action,
                applied,
                from_recipe: false,
                recommended: Some(e.action),
                source: e.source.clone(),
                reason,
            };
            let d = if !e.significant || line.is_none() {
                decision(AliasOutcome::Nulled, false, format!("no significant line at bin {b}: nothing to carry"))
            } else if let Some((other, by)) = relocated.get(&b) {
                decision(AliasOutcome::Nulled, false, format!("bin {b} is relocated to {other} cycles/rev ({by})"))
            } else if !line.is_some_and(|l| l.repeatable) {
                null.insert(b);
                decision(AliasOutcome::Nulled, true, format!("the line at bin {b} is not repeatable"))
            } else if self.lines.unlisted == Unlisted::Remove {
                null.insert(b);
                decision(AliasOutcome::Nulled, true, "not in the recipe, whose lines.unlisted is \"remove\"".into())
            } else if e.action == AliasAction::Relocate && e.true_cycles.fract() == 0.0 && !null.contains(&b) {
                relocated.insert(b, (e.true_cycles as usize, "the analysis".into()));
                decision(AliasOutcome::Relocated, true, e.reason.clone())
            } else {
                null.insert(b);
                decision(AliasOutcome::Nulled, true, e.reason.clone())
            };
            aliases.push(d);
        }

        // Every significant line, then the recipe's lines the survey did not flag.
        let mut lines = Vec::new();
        for l in &analysis.lines {
            let k = bin_of(l.cycles_per_rev);
            let listed = keep.contains(&k) && self.lines.keep.contains(&(k as f64));
            let (action, true_cycles, from_recipe, reason) = if let Some((f, by)) = relocated.get(&k) {
                (LineAction::Relocated, *f as f64, by != "the analysis", format!("relocated to {f} cycles/rev"))
            } else if null.contains(&k) {
                (
                    LineAction::Nulled,
                    l.true_cycles_per_rev,
                    false,
                    format!("bin {k} is nulled (an aliased line the table cannot place shares it)"),
                )
            } else if l.aliased {
                (LineAction::Removed, l.true_cycles_per_rev, false, "aliased and not relocated".into())
            } else if keep.contains(&k) {
                (
                    LineAction::Kept,
                    k as f64,
                    true,
                    if listed { "in lines.keep".into() } else { "relocate in [[alias]]: resolved here".into() },
                )
            } else if removed.contains(&k) {
                (LineAction::Removed, k as f64, true, "removed by the recipe".into())
            } else if self.lines.unlisted == Unlisted::Remove {
                (LineAction::Removed, k as f64, false, "not in the recipe, whose lines.unlisted is \"remove\"".into())
            } else if !l.repeatable {
                (LineAction::Removed, k as f64, false, "not repeatable".into())
            } else if l.amplitude_deg < self.lines.min_amplitude_deg {
                (LineAction::Removed, k as f64, false, "below lines.min_amplitude_deg".into())
            } else {
                keep.insert(k);
                (LineAction::Kept, k as f64, false, "repeatable".into())
            };
            lines.push(LineDecision {
                cycles_per_rev: l.cycles_per_rev,
                true_cycles_per_rev: true_cycles,
                significant: true,
                repeatable: l.repeatable,
                amplitude_deg: l.amplitude_deg,
                action,
                from_recipe,
                reason,
            });
        }
        for &k in &keep {
            if lines.iter().any(|d| bin_of(d.cycles_per_rev) == k) {
                continue;
            }
            let nulled = null.contains(&k);
            lines.push(LineDecision {
                cycles_per_rev: k as f64,
                true_cycles_per_rev: k as f64,
                significant: false,
                repeatable: false,
                amplitude_deg: amplitude_at(k),
                action: if nulled { LineAction::Nulled } else { LineAction::Kept },
                from_recipe: true,
                reason: "kept by the recipe; not significant in this survey".into(),
            });
        }
        lines.sort_by(|a, b| a.cycles_per_rev.total_cmp(&b.cycles_per_rev));
        aliases.sort_by(|a, b| a.true_cycles.total_cmp(&b.true_cycles));

        let edit = SpectralEdit {
            keep: Keep::Lines { cycles: keep.iter().copied().collect() },
            null: null.iter().copied().collect(),
            relocate: relocated.iter().map(|(&b, &(f, _))| Relocation { observed_cycles: b, true_cycles: f }).collect(),
            remove_mean: false,
        };
        edit.validate(n, self.table.dense_points).map_err(edit_error)?;
        let mut kept_cycles: Vec<f64> = keep
            .iter()
            .filter(|k| !null.contains(k))
            .chain(relocated.values().map(|(f, _)| f))
            .map(|&f| f as f64)
            .collect();
        kept_cycles.sort_by(f64::total_cmp);
        kept_cycles.dedup();
        Ok(Decisions { edit, points: Some(n), kept_cycles, lines, aliases, notes })
    }

    fn decide_partial(&self, analysis: &Analysis) -> Decisions {
        let mut notes = Vec::new();
        if !self.aliases.is_empty() {
            notes.push("[[alias]] entries do not apply to a partial range (no spectrum to edit): ignored".to_string());
        }
        let mut keep: Vec<f64> = self.lines.keep.clone();
        let mut lines = Vec::new();
        for l in &analysis.lines {
            let f = l.true_cycles_per_rev;
            let (action, from_recipe, reason) = if self.lines.keep.contains(&f) {
                (LineAction::Kept, true, "in lines.keep")
            } else if self.lines.remove.contains(&f) {
                (LineAction::Removed, true, "removed by the recipe")
            } else if self.lines.unlisted == Unlisted::Remove {
                (LineAction::Removed, false, "not in the recipe, whose lines.unlisted is \"remove\"")
            } else if !l.repeatable {
                (LineAction::Removed, false, "not repeatable")
            } else if l.amplitude_deg < self.lines.min_amplitude_deg {
                (LineAction::Removed, false, "below lines.min_amplitude_deg")
            } else {
                keep.push(f);
                (LineAction::Kept, false, "repeatable")
            };
            lines.push(LineDecision {
                cycles_per_rev: l.cycles_per_rev,
                true_cycles_per_rev: f,
                significant: true,
                repeatable: l.repeatable,
                amplitude_deg: l.amplitude_deg,
                action,
                from_recipe,
                reason: reason.to_string(),
            });
        }
        for &f in &self.lines.keep {
            if !lines.iter().any(|d| d.true_cycles_per_rev == f) {
                lines.push(LineDecision {
                    cycles_per_rev: f,
                    true_cycles_per_rev: f,
                    significant: false,
                    repeatable: false,
                    amplitude_deg: 0.0,
                    action: LineAction::Kept,
                    from_recipe: true,
                    reason: "kept by the recipe; not significant in this survey".into(),
                });
            }
        }
        lines.sort_by(|a, b| a.cycles_per_rev.total_cmp(&b.cycles_per_rev));
        keep.sort_by(f64::total_cmp);
        keep.dedup();
        let aliases = analysis
            .aliases
            .iter()
            .map(|e| AliasDecision {
                observed_cycles: e.observed_cycles,
                true_cycles: e.true_cycles,
                action: AliasOutcome::Nulled,
                applied: false,
                from_recipe: false,
                recommended: Some(e.action),
                source: e.source.clone(),
                reason: "above the sampling limit of the partial range: not fitted, left out".into(),
            })
            .collect();
        Decisions { edit: SpectralEdit::none(), points: None, kept_cycles: keep, lines, aliases, notes }
    }
}
