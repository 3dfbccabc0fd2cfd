//! What a recipe does with one survey's analysis (see the parent module).

use super::{AliasChoice, AliasChoiceAction, ChoiceError, LineChoices, Recipe, Unlisted};
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet};
use survey_processing::analysis::{AliasAction, AliasEntry, Analysis, Line};
use survey_processing::errormap::Coverage;
use survey_processing::resample::{EditError, Keep, Relocation, SpectralEdit, alias_of};

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

    /// [`Recipe::decide`] on a full circle of `n` points: the recipe's own
    /// choices first (its resolved lines, its `[[alias]]` entries, then its
    /// lines this survey sees only through their alias), then the analysis'
    /// aliased harmonics, then the fate of every line; the spectral edit is
    /// what they settled.
    fn decide_full(&self, analysis: &Analysis, n: usize) -> Result<Decisions, ChoiceError> {
        let mut d = FullCircle::new(n);
        let unresolved = d.recipe_lines(&self.lines)?;
        for (i, a) in self.aliases.iter().enumerate() {
            d.recipe_alias(i, a, analysis)?;
        }
        d.unresolved_lines(unresolved)?;
        d.no_bin_relocated_and_nulled()?;
        for e in &analysis.aliases {
            if self.names(e.true_cycles) {
                d.named_alias(e);
            } else {
                d.unnamed_alias(e, analysis, self.lines.unlisted);
            }
        }
        let lines = d.line_decisions(&self.lines, analysis);
        d.finish(lines, self.table.dense_points)
    }

    /// Whether the recipe names the true frequency `f`: in an `[[alias]]`
    /// entry, in `lines.keep` or in `lines.remove`.
    fn names(&self, f: f64) -> bool {
        self.aliases.iter().any(|a| a.true_cycles as f64 == f)
            || self.lines.keep.contains(&f)
            || self.lines.remove.contains(&f)
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

/// The bin a frequency seen at `c` cycles/rev falls in.
fn bin_of(c: f64) -> usize {
    c.round() as usize
}

/// The mean spectrum's amplitude at bin `k` of `analysis`, degrees (0
/// without one).
fn amplitude_at(analysis: &Analysis, k: usize) -> f64 {
    analysis.spectra.as_ref().and_then(|s| s.mean.bins.get(k)).map_or(0.0, |b| b.amplitude_deg)
}

/// What the decision of a full circle of `n` points has settled so far: the
/// bins the spectral edit keeps, nulls and relocates, and the fates of the
/// aliased harmonics and the remarks written down on the way.
struct FullCircle {
    /// Points per revolution.
    n: usize,
    /// The resolved lines the table carries (each below `n / 2`).
    keep: BTreeSet<usize>,
    /// The resolved lines the recipe removes.
    removed: BTreeSet<usize>,
    /// The bins the edit empties.
    null: BTreeSet<usize>,
    /// The bins the edit moves: bin -> (true frequency, key of the choice that claimed it).
    relocated: BTreeMap<usize, (usize, String)>,
    /// Per aliased design harmonic, in the order decided.
    aliases: Vec<AliasDecision>,
    /// Remarks (recipe entries that meant something else on this survey).
    notes: Vec<String>,
}

/// The recipe's kept and removed lines at or above `n / 2`: this survey sees
/// them only through their alias.
struct Unresolved {
    /// From `lines.keep`, cycles/rev.
    keep: Vec<usize>,
    /// From `lines.remove`, cycles/rev.
    remove: Vec<usize>,
}

impl FullCircle {
    fn new(n: usize) -> Self {
        FullCircle {
            n,
            keep: BTreeSet::new(),
            removed: BTreeSet::new(),
            null: BTreeSet::new(),
            relocated: BTreeMap::new(),
            aliases: Vec::new(),
            notes: Vec::new(),
        }
    }

    /// Relocate bin `b` to `f` cycles/rev for the choice `key`. One bin moves
    /// to one frequency only: a bin already relocated is an error naming both.
    fn claim(&mut self, b: usize, f: usize, key: String) -> Result<(), ChoiceError> {
        let n = self.n;
        if let Some((other, by)) = self.relocated.get(&b) {
            return Err(ChoiceError::new(
                key,
                format!(
                    "{f} and {other} cycles/rev ({by}) both appear at bin {b} with {n} points; one bin can be relocated to one frequency only: null one of them"
                ),
            ));
        }
        self.relocated.insert(b, (f, key));
        Ok(())
    }

    /// The recipe's `lines.keep` and `lines.remove`, each a whole number of
    /// cycles/rev: those this survey resolves (below `n / 2`) are kept or
    /// removed as lines; the others are returned, to be decided through their
    /// alias once the `[[alias]]` entries have claimed their bins.
    fn recipe_lines(&mut self, choices: &LineChoices) -> Result<Unresolved, ChoiceError> {
        let n = self.n;
        let mut unresolved = Unresolved { keep: Vec::new(), remove: Vec::new() };
        for &f in &choices.keep {
            let f = whole("lines.keep", f, n)?;
            if 2 * f < n {
                self.keep.insert(f);
            } else {
                unresolved.keep.push(f);
            }
        }
        for &f in &choices.remove {
            let f = whole("lines.remove", f, n)?;
            if 2 * f < n {
                self.removed.insert(f);
            } else {
                unresolved.remove.push(f);
            }
        }
        Ok(unresolved)
    }

    /// The recipe's `[[alias]]` entry `a` (the `i`-th, from 0). A frequency
    /// this survey resolves is kept (`relocate`) or removed as a line, with a
    /// note. Otherwise its alias bin is relocated, nulled or left to the other
    /// frequency that lands on it, as the entry says; an alias on bin 0 is left
    /// alone, one on the Nyquist bin is nulled whatever the entry says.
    fn recipe_alias(&mut self, i: usize, a: &AliasChoice, analysis: &Analysis) -> Result<(), ChoiceError> {
        let n = self.n;
        let key = format!("alias[{}].true_cycles", i + 1);
        let f = a.true_cycles;
        if 2 * f < n {
            let (set, what) = match a.action {
                AliasChoiceAction::Relocate => (&mut self.keep, "kept as a line"),
                AliasChoiceAction::Null | AliasChoiceAction::Absent => (&mut self.removed, "removed as a line"),
            };
            set.insert(f);
            self.notes
                .push(format!("alias[{}]: {f} cycles/rev is resolved by this survey's {n} points: {what}", i + 1));
            return Ok(());
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
            self.null.insert(b);
            (
                AliasOutcome::Nulled,
                true,
                format!("lands on the Nyquist bin {b}, where its phase is lost: nulled (recipe: {:?})", a.action),
            )
        } else {
            match a.action {
                AliasChoiceAction::Relocate => {
                    self.claim(b, f, format!("alias[{}]", i + 1)).map_err(|e| ChoiceError { key, ..e })?;
                    (AliasOutcome::Relocated, true, by_recipe("relocated"))
                }
                AliasChoiceAction::Null => {
                    self.null.insert(b);
                    (AliasOutcome::Nulled, true, by_recipe("nulled"))
                }
                AliasChoiceAction::Absent => (
                    AliasOutcome::Nulled,
                    false,
                    by_recipe("absent (not there: check points showed it), its bin left to the other frequency"),
                ),
            }
        };
        self.aliases.push(AliasDecision {
            observed_cycles: b as f64,
            true_cycles: f as f64,
            action,
            applied,
            from_recipe: true,
            recommended: report.map(|e| e.action),
            source: report.map(|e| e.source.clone()).or_else(|| a.source.clone()).unwrap_or_default(),
            reason,
        });
        Ok(())
    }

    /// The recipe's kept and removed lines this survey cannot resolve, through
    /// their alias: a kept line relocates its bin (none on bin 0 or the
    /// Nyquist bin, where its phase is lost: a note says so); a removed line
    /// nulls its bin, unless that bin is 0 or relocated already.
    fn unresolved_lines(&mut self, unresolved: Unresolved) -> Result<(), ChoiceError> {
        let n = self.n;
        for f in unresolved.keep {
            let b = alias_of(f, n).observed_cycles;
            if b == 0 || 2 * b == n {
                self.notes.push(format!("lines.keep: {f} cycles/rev lands on bin {b} with {n} points, where its phase is lost: it cannot be in the table"));
                continue;
            }
            self.claim(b, f, "lines.keep".into())?;
            self.notes.push(format!(
                "lines.keep: {f} cycles/rev is above this survey's Nyquist ({n} points): relocated from bin {b}"
            ));
        }
        for f in unresolved.remove {
            let b = alias_of(f, n).observed_cycles;
            if b != 0 && !self.relocated.contains_key(&b) {
                self.null.insert(b);
            }
        }
        Ok(())
    }

    /// The recipe's choices do not both relocate and null one bin.
    fn no_bin_relocated_and_nulled(&self) -> Result<(), ChoiceError> {
        let n = self.n;
        for (b, (_, key)) in &self.relocated {
            if self.null.contains(b) {
                return Err(ChoiceError::new(
                    key.clone(),
                    format!("bin {b} is both relocated and nulled with {n} points"),
                ));
            }
        }
        Ok(())
    }

    /// An aliased harmonic of the analysis that the recipe names. An
    /// `[[alias]]` entry has decided it already; otherwise its fate is what
    /// `[lines]` did to its bin: relocated when the bin moved to it, else
    /// nulled (applied when the bin is emptied).
    fn named_alias(&mut self, e: &AliasEntry) {
        if self.aliases.iter().any(|d: &AliasDecision| d.true_cycles == e.true_cycles) {
            return;
        }
        let b = bin_of(e.observed_cycles);
        let moved = self.relocated.get(&b).is_some_and(|(f, _)| *f as f64 == e.true_cycles);
        self.aliases.push(AliasDecision {
            observed_cycles: e.observed_cycles,
            true_cycles: e.true_cycles,
            action: if moved { AliasOutcome::Relocated } else { AliasOutcome::Nulled },
            applied: moved || self.null.contains(&b),
            from_recipe: true,
            recommended: Some(e.action),
            source: e.source.clone(),
            reason: "decided by the recipe's [lines]".into(),
        });
    }

    /// An aliased harmonic of the analysis that the recipe does not name.
    /// Nothing is done when its bin holds no significant line or is relocated
    /// already; its bin is nulled when the line there is not repeatable or
    /// `unlisted` removes lines; else it takes the analysis' recommendation
    /// (a relocation only to a whole frequency and a bin not nulled).
    fn unnamed_alias(&mut self, e: &AliasEntry, analysis: &Analysis, unlisted: Unlisted) {
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
        } else if let Some((other, by)) = self.relocated.get(&b) {
            decision(AliasOutcome::Nulled, false, format!("bin {b} is relocated to {other} cycles/rev ({by})"))
        } else if !line.is_some_and(|l| l.repeatable) {
            self.null.insert(b);
            decision(AliasOutcome::Nulled, true, format!("the line at bin {b} is not repeatable"))
        } else if unlisted == Unlisted::Remove {
            self.null.insert(b);
            decision(AliasOutcome::Nulled, true, "not in the recipe, whose lines.unlisted is \"remove\"".into())
        } else if e.action == AliasAction::Relocate && e.true_cycles.fract() == 0.0 && !self.null.contains(&b) {
            self.relocated.insert(b, (e.true_cycles as usize, "the analysis".into()));
            decision(AliasOutcome::Relocated, true, e.reason.clone())
        } else {
            self.null.insert(b);
            decision(AliasOutcome::Nulled, true, e.reason.clone())
        };
        self.aliases.push(d);
    }

    /// The fate of every significant line of the survey, then of each kept
    /// line the survey did not flag, ascending.
    fn line_decisions(&mut self, choices: &LineChoices, analysis: &Analysis) -> Vec<LineDecision> {
        let mut lines: Vec<LineDecision> = analysis.lines.iter().map(|l| self.significant_line(choices, l)).collect();
        for &k in &self.keep {
            if lines.iter().any(|d| bin_of(d.cycles_per_rev) == k) {
                continue;
            }
            let nulled = self.null.contains(&k);
            lines.push(LineDecision {
                cycles_per_rev: k as f64,
                true_cycles_per_rev: k as f64,
                significant: false,
                repeatable: false,
                amplitude_deg: amplitude_at(analysis, k),
                action: if nulled { LineAction::Nulled } else { LineAction::Kept },
                from_recipe: true,
                reason: "kept by the recipe; not significant in this survey".into(),
            });
        }
        lines.sort_by(|a, b| a.cycles_per_rev.total_cmp(&b.cycles_per_rev));
        lines
    }

    /// The fate of the significant line `l`, by its bin: what the edit does to
    /// the bin (relocated, nulled), else removed when aliased, else what the
    /// recipe lists, else what `lines.unlisted` and `lines.min_amplitude_deg`
    /// make of it. A repeatable unlisted line that passes is kept.
    fn significant_line(&mut self, choices: &LineChoices, l: &Line) -> LineDecision {
        let k = bin_of(l.cycles_per_rev);
        let listed = self.keep.contains(&k) && choices.keep.contains(&(k as f64));
        let (action, true_cycles, from_recipe, reason) = if let Some((f, by)) = self.relocated.get(&k) {
            (LineAction::Relocated, *f as f64, by != "the analysis", format!("relocated to {f} cycles/rev"))
        } else if self.null.contains(&k) {
            (
                LineAction::Nulled,
                l.true_cycles_per_rev,
                false,
                format!("bin {k} is nulled (an aliased line the table cannot place shares it)"),
            )
        } else if l.aliased {
            (LineAction::Removed, l.true_cycles_per_rev, false, "aliased and not relocated".into())
        } else if self.keep.contains(&k) {
            (
                LineAction::Kept,
                k as f64,
                true,
                if listed { "in lines.keep".into() } else { "relocate in [[alias]]: resolved here".into() },
            )
        } else if self.removed.contains(&k) {
            (LineAction::Removed, k as f64, true, "removed by the recipe".into())
        } else if choices.unlisted == Unlisted::Remove {
            (LineAction::Removed, k as f64, false, "not in the recipe, whose lines.unlisted is \"remove\"".into())
        } else if !l.repeatable {
            (LineAction::Removed, k as f64, false, "not repeatable".into())
        } else if l.amplitude_deg < choices.min_amplitude_deg {
            (LineAction::Removed, k as f64, false, "below lines.min_amplitude_deg".into())
        } else {
            self.keep.insert(k);
            (LineAction::Kept, k as f64, false, "repeatable".into())
        };
        LineDecision {
            cycles_per_rev: l.cycles_per_rev,
            true_cycles_per_rev: true_cycles,
            significant: true,
            repeatable: l.repeatable,
            amplitude_deg: l.amplitude_deg,
            action,
            from_recipe,
            reason,
        }
    }

    /// The spectral edit of what was settled, checked against a dense grid of
    /// `dense_points`, and the true frequencies the table carries.
    fn finish(mut self, lines: Vec<LineDecision>, dense_points: usize) -> Result<Decisions, ChoiceError> {
        let n = self.n;
        self.aliases.sort_by(|a, b| a.true_cycles.total_cmp(&b.true_cycles));
        let edit = SpectralEdit {
            keep: Keep::Lines { cycles: self.keep.iter().copied().collect() },
            null: self.null.iter().copied().collect(),
            relocate: self
                .relocated
                .iter()
                .map(|(&b, &(f, _))| Relocation { observed_cycles: b, true_cycles: f })
                .collect(),
            remove_mean: false,
        };
        edit.validate(n, dense_points).map_err(edit_error)?;
        let mut kept_cycles: Vec<f64> = self
            .keep
            .iter()
            .filter(|k| !self.null.contains(k))
            .chain(self.relocated.values().map(|(f, _)| f))
            .map(|&f| f as f64)
            .collect();
        kept_cycles.sort_by(f64::total_cmp);
        kept_cycles.dedup();
        Ok(Decisions { edit, points: Some(n), kept_cycles, lines, aliases: self.aliases, notes: self.notes })
    }
}
