//! Naming spectral lines from the design, and the alias report.
//!
//! See the documentation of [`crate::analysis`] for the rules.

use super::AnalysisOptions;
use crate::model::{Design, PeriodicKind};
use crate::types::wrap_360;
use serde::{Serialize, Serializer};

pub(crate) fn ser_kind<S: Serializer>(kind: &PeriodicKind, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(kind.as_str())
}

/// A frequency the design predicts.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Candidate {
    /// The contract's kind word.
    #[serde(serialize_with = "ser_kind")]
    pub kind: PeriodicKind,
    /// The true frequency, cycles per revolution.
    pub cycles_per_rev: f64,
    /// Harmonic number of the part (1 for eccentricity and ellipticity).
    pub harmonic: u32,
    /// For a sideband, the signed multiple of the gear pass (`-1` for `t - g`).
    pub sideband: Option<i32>,
    /// What it is: "12:1 pinion, harmonic 3".
    pub description: String,
    /// Naming priority within one aliasing status (lower first).
    #[serde(skip)]
    rank: (u8, u32, u32),
}

/// Formats a frequency or ratio: whole numbers without decimals.
pub(crate) fn num(v: f64) -> String {
    if (v - v.round()).abs() < 1e-9 {
        format!("{}", v.round() as i64)
    } else {
        format!("{}", (v * 1000.0).round() / 1000.0)
    }
}

/// Every frequency the design predicts up to the configured orders, plus 1
/// (eccentricity) and 2 (ellipticity) cycles per revolution.
pub fn design_candidates(design: &Design, o: &AnalysisOptions) -> Vec<Candidate> {
    let mut v = vec![
        Candidate {
            kind: PeriodicKind::Eccentricity,
            cycles_per_rev: 1.0,
            harmonic: 1,
            sideband: None,
            description: "once per revolution: eccentric mounting of the encoder scale, the ring gear or the bearing"
                .into(),
            rank: (0, 1, 0),
        },
        Candidate {
            kind: PeriodicKind::Ellipticity,
            cycles_per_rev: 2.0,
            harmonic: 1,
            sideband: None,
            description: "twice per revolution: elliptical distortion of the encoder scale or the ring gear".into(),
            rank: (1, 1, 0),
        },
    ];
    for &g in &design.gear_ratios {
        for h in 1..=o.gear_harmonics {
            let fundamental = if h == 1 { " (fundamental)" } else { "" };
            v.push(Candidate {
                kind: PeriodicKind::GearPass,
                cycles_per_rev: g * h as f64,
                harmonic: h,
                sideband: None,
                description: format!("{}:1 pinion, harmonic {h}{fundamental}", num(g)),
                rank: (2, h, 0),
            });
        }
    }
    for &t in &design.tooth_counts {
        for h in 1..=o.tooth_harmonics {
            v.push(Candidate {
                kind: PeriodicKind::ToothMesh,
                cycles_per_rev: t as f64 * h as f64,
                harmonic: h,
                sideband: None,
                description: format!("{t}-tooth gear, harmonic {h}"),
                rank: (3, h, 0),
            });
        }
        for h in 1..=o.sideband_tooth_harmonics {
            for &g in &design.gear_ratios {
                for m in 1..=o.sideband_orders as i32 {
                    for m in [-m, m] {
                        let f = t as f64 * h as f64 + g * m as f64;
                        if f <= 0.0 {
                            continue;
                        }
                        let mesh =
                            if h == 1 { format!("{t}-tooth mesh") } else { format!("{t}-tooth mesh harmonic {h}") };
                        v.push(Candidate {
                            kind: PeriodicKind::ToothMesh,
                            cycles_per_rev: f,
                            harmonic: h,
                            sideband: Some(m),
                            description: format!("sideband of the {mesh} at {m:+} x the {}:1 gear pass", num(g)),
                            rank: (4, h, m.unsigned_abs()),
                        });
                    }
                }
            }
        }
    }
    v
}

/// Where a frequency lands when sampled at `points_per_rev` points per revolution.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Alias {
    /// The observed frequency `|f - N round(f / N)|`, in `[0, N/2]`.
    pub observed: f64,
    /// `round(f / N)`.
    pub m: f64,
    /// Whether `f - N m` is negative: the observed phase is then mirrored.
    pub folded: bool,
}

/// The alias of `f` cycles/rev at `points_per_rev` points per revolution.
pub fn alias(f: f64, points_per_rev: f64) -> Alias {
    let m = (f / points_per_rev).round();
    let s = f - points_per_rev * m;
    Alias { observed: s.abs(), m, folded: s < 0.0 }
}

/// The phase at the true frequency of a component seen at its alias with phase
/// `observed_phase_deg`, samples at `start_deg + j * 360 / N`.
///
/// With `f = N m + s`, `sin(f theta_j + phi) = sin(s theta_j + phi + N m start)`;
/// for `s < 0` that is `sin(|s| theta_j + 180 - phi - N m start)`.
pub fn unalias_phase_deg(observed_phase_deg: f64, a: Alias, points_per_rev: f64, start_deg: f64) -> f64 {
    let shift = points_per_rev * a.m * start_deg;
    wrap_360(if a.folded { 180.0 - observed_phase_deg - shift } else { observed_phase_deg - shift })
}

/// The frame the lines are seen in.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Frame {
    /// Points per revolution (`360 / step` for a partial range).
    pub points_per_rev: f64,
    pub full_circle: bool,
    pub start_deg: f64,
    pub encoder_heads: u32,
}

impl Frame {
    fn is_aliased(&self, f: f64) -> bool {
        f > self.points_per_rev / 2.0 + 1e-9
    }

    /// Whether candidate frequency `f` is seen at `observed`.
    fn lands_at(&self, f: f64, observed: f64) -> bool {
        if self.full_circle {
            (alias(f, self.points_per_rev).observed - observed).abs() <= 0.5
        } else {
            (f - observed).abs() <= 1e-9 * f.max(1.0)
        }
    }

    fn describe(&self, c: &Candidate) -> String {
        if self.full_circle && self.is_aliased(c.cycles_per_rev) {
            let a = alias(c.cycles_per_rev, self.points_per_rev);
            format!(
                "{} at {} cycles/rev, aliased to {} by {} points/rev",
                c.description,
                num(c.cycles_per_rev),
                num(a.observed),
                num(self.points_per_rev)
            )
        } else {
            c.description.clone()
        }
    }
}

/// The name of a line.
#[derive(Debug, Clone)]
pub(crate) struct Naming {
    pub kind: PeriodicKind,
    pub explanation: String,
    /// The primary candidate's true frequency (the observed one when unexplained).
    pub true_cycles: f64,
    pub aliased: bool,
    pub candidates: Vec<Candidate>,
    pub notes: Vec<String>,
}

/// Name the line observed at `observed` cycles/rev.
pub(crate) fn name_line(observed: f64, candidates: &[Candidate], frame: &Frame) -> Naming {
    let mut matched: Vec<&Candidate> =
        candidates.iter().filter(|c| frame.lands_at(c.cycles_per_rev, observed)).collect();
    matched.sort_by(|a, b| {
        (frame.is_aliased(a.cycles_per_rev), a.rank)
            .cmp(&(frame.is_aliased(b.cycles_per_rev), b.rank))
            .then(a.cycles_per_rev.total_cmp(&b.cycles_per_rev))
    });
    let n = frame.points_per_rev;
    let mut notes = Vec::new();
    let (kind, explanation, true_cycles, aliased) = match matched.first() {
        None => {
            let k = num(observed);
            let mut e =
                format!("{k} cycles/rev matches no part of the design: look for a {k}:1 gear pass or a bearing");
            if frame.full_circle && observed > 0.0 {
                e += &format!(
                    " (or a component at {} cycles/rev aliased by the {}-point sampling)",
                    num(n - observed),
                    num(n)
                );
            }
            (PeriodicKind::Harmonic, e, observed, false)
        }
        Some(primary) => {
            let mut e = frame.describe(primary);
            let others: Vec<String> = matched[1..].iter().map(|c| frame.describe(c)).collect();
            if !others.is_empty() {
                e += &format!("; also {}", others.join("; "));
            }
            (primary.kind, e, primary.cycles_per_rev, frame.full_circle && frame.is_aliased(primary.cycles_per_rev))
        }
    };
    if frame.full_circle {
        for c in &matched {
            if (c.cycles_per_rev - c.cycles_per_rev.round()).abs() > 1e-9 {
                notes.push(format!(
                    "{} cycles/rev is not a whole number of cycles per revolution: that error does not repeat every \
                     revolution and spreads over neighbouring bins",
                    num(c.cycles_per_rev)
                ));
            }
        }
        if 2.0 * observed == n {
            notes.push(format!(
                "at the Nyquist frequency of {} points/rev: only the part of the error in phase with the samples is seen",
                num(n)
            ));
        }
    }
    let h = frame.encoder_heads;
    let whole = (observed - observed.round()).abs() < 1e-9;
    if h >= 2
        && whole
        && !(observed.round() as u64).is_multiple_of(u64::from(h))
        && matches!(kind, PeriodicKind::Eccentricity | PeriodicKind::Harmonic)
    {
        let which =
            if h == 2 { "odd harmonics".to_string() } else { format!("harmonics that are not multiples of {h}") };
        notes.push(format!(
            "{h} encoder heads cancel the scale's {which}: an error at {} cycles/rev comes from outside the scale \
             (gear train, bearing, axis wobble) or from a faulty head",
            num(observed)
        ));
    }
    Naming { kind, explanation, true_cycles, aliased, candidates: matched.into_iter().cloned().collect(), notes }
}

/// What to do with an aliased design harmonic.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AliasAction {
    /// Move the observed line to its true frequency: the observed bin holds no
    /// other design harmonic.
    Relocate,
    /// Remove the observed line from the correction: it cannot be attributed
    /// to one source (or cannot be moved as one line).
    Null,
}

/// One aliased design harmonic.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AliasEntry {
    /// Where it appears, cycles/rev.
    pub observed_cycles: f64,
    /// Its true frequency, cycles/rev.
    pub true_cycles: f64,
    /// The recommended action (a recipe may override it).
    pub action: AliasAction,
    /// The design part(s) it comes from.
    pub source: String,
    /// Why this action.
    pub reason: String,
    /// Whether the observed bin holds a significant line.
    pub significant: bool,
    /// Amplitude of the mean spectrum at the observed bin, degrees (full circle).
    pub observed_amplitude_deg: Option<f64>,
    /// The phase at the true frequency if the observed bin were all this
    /// component (full circle, not at bin 0 or N/2).
    pub true_phase_deg: Option<f64>,
}

/// The alias report: one entry per distinct design frequency at or above half
/// the sampling rate. `observed(bin)` gives, for a full circle, whether the
/// bin holds a significant line and the mean spectrum's amplitude and phase there.
pub(crate) fn alias_report(
    candidates: &[Candidate],
    frame: &Frame,
    observed: impl Fn(usize) -> Option<(bool, f64, f64)>,
) -> Vec<AliasEntry> {
    let n = frame.points_per_rev;
    let mut freqs: Vec<f64> = candidates.iter().map(|c| c.cycles_per_rev).filter(|&f| f >= n / 2.0 - 1e-9).collect();
    freqs.sort_by(f64::total_cmp);
    freqs.dedup_by(|a, b| (*a - *b).abs() <= 1e-9);
    let mut out = Vec::new();
    for f in freqs {
        let same: Vec<&Candidate> = candidates.iter().filter(|c| (c.cycles_per_rev - f).abs() <= 1e-9).collect();
        let source = same.iter().map(|c| c.description.as_str()).collect::<Vec<_>>().join(" / ");
        let a = alias(f, n);
        if !frame.full_circle {
            out.push(AliasEntry {
                observed_cycles: a.observed,
                true_cycles: f,
                action: AliasAction::Null,
                source,
                reason: format!(
                    "at or above the sampling limit of {} cycles/rev: not fitted, and it leaks into the fit near {} cycles/rev; \
                     sample at steps below {} deg to resolve it",
                    num(n / 2.0),
                    num(a.observed),
                    num(180.0 / f)
                ),
                significant: false,
                observed_amplitude_deg: None,
                true_phase_deg: None,
            });
            continue;
        }
        let bin = a.observed.round();
        let seen = observed(bin as usize);
        let others: Vec<&Candidate> = candidates
            .iter()
            .filter(|c| (c.cycles_per_rev - f).abs() > 1e-9 && alias(c.cycles_per_rev, n).observed.round() == bin)
            .collect();
        let whole = (f - f.round()).abs() < 1e-9;
        let (action, reason) = if !whole {
            (AliasAction::Null, "not a whole number of cycles per revolution: it spreads over neighbouring bins and cannot be moved as one line".to_string())
        } else if bin == 0.0 {
            (AliasAction::Null, "lands on the mean (bin 0), which holds no line".to_string())
        } else if 2.0 * bin == n {
            (AliasAction::Null, format!("lands on the Nyquist bin {}, where only part of it is seen", num(bin)))
        } else if !others.is_empty() {
            let names: Vec<String> = others.iter().map(|c| frame.describe(c)).collect();
            (
                AliasAction::Null,
                format!("bin {} also holds {}: the contributions cannot be separated", num(bin), names.join("; ")),
            )
        } else {
            (
                AliasAction::Relocate,
                format!("bin {} holds no other design harmonic: move it to {} cycles/rev", num(bin), num(f)),
            )
        };
        let phase_ok = whole && bin > 0.0 && 2.0 * bin != n;
        out.push(AliasEntry {
            observed_cycles: bin,
            true_cycles: f,
            action,
            source,
            reason,
            significant: seen.is_some_and(|s| s.0),
            observed_amplitude_deg: seen.map(|s| s.1),
            true_phase_deg: seen.filter(|_| phase_ok).map(|s| unalias_phase_deg(s.2, a, n, frame.start_deg)),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fig4() -> Design {
        Design { gear_ratios: vec![12.0], tooth_counts: vec![216], encoder_heads: Some(2) }
    }

    fn frame(n: f64) -> Frame {
        Frame { points_per_rev: n, full_circle: true, start_deg: 0.0, encoder_heads: 2 }
    }

    #[test]
    fn candidates_of_the_figure_4_design() {
        let c = design_candidates(&fig4(), &AnalysisOptions::default());
        let freqs: Vec<f64> = c.iter().map(|c| c.cycles_per_rev).collect();
        let want = [1.0, 2.0, 12.0, 24.0, 36.0, 48.0, 60.0, 72.0, 216.0, 432.0, 648.0, 204.0, 228.0, 192.0, 240.0];
        assert_eq!(freqs, want);
        assert_eq!(c[4].description, "12:1 pinion, harmonic 3");
        assert_eq!(c[2].description, "12:1 pinion, harmonic 1 (fundamental)");
        assert_eq!(c[9].description, "216-tooth gear, harmonic 2");
        assert_eq!(c[11].description, "sideband of the 216-tooth mesh at -1 x the 12:1 gear pass");
        assert_eq!(c[11].kind, PeriodicKind::ToothMesh);
        assert_eq!(c[11].sideband, Some(-1));
        let o =
            AnalysisOptions { gear_harmonics: 2, tooth_harmonics: 1, sideband_orders: 0, ..AnalysisOptions::default() };
        let few: Vec<f64> = design_candidates(&Design { gear_ratios: vec![2.5], ..fig4() }, &o)
            .iter()
            .map(|c| c.cycles_per_rev)
            .collect();
        assert_eq!(few, vec![1.0, 2.0, 2.5, 5.0, 216.0]);
    }

    #[test]
    fn aliases_and_their_phases() {
        assert_eq!(alias(432.0, 720.0), Alias { observed: 288.0, m: 1.0, folded: true });
        assert_eq!(alias(648.0, 720.0), Alias { observed: 72.0, m: 1.0, folded: true });
        assert_eq!(alias(100.0, 720.0), Alias { observed: 100.0, m: 0.0, folded: false });
        assert_eq!(alias(1000.0, 720.0), Alias { observed: 280.0, m: 1.0, folded: false });
        // 432 cycles at phase 45 is seen at 288 with phase 135 (samples from 0).
        assert!((unalias_phase_deg(135.0, alias(432.0, 720.0), 720.0, 0.0) - 45.0).abs() < 1e-12);
        assert!((unalias_phase_deg(30.0, alias(1000.0, 720.0), 720.0, 0.0) - 30.0).abs() < 1e-12);
    }

    #[test]
    fn lines_of_figure_4_at_720_points_are_named() {
        let c = design_candidates(&fig4(), &AnalysisOptions::default());
        let f = frame(720.0);
        let n72 = name_line(72.0, &c, &f);
        assert_eq!(n72.kind, PeriodicKind::GearPass);
        assert!(!n72.aliased && n72.true_cycles == 72.0);
        assert_eq!(
            n72.explanation,
            "12:1 pinion, harmonic 6; also 216-tooth gear, harmonic 3 at 648 cycles/rev, aliased to 72 by 720 points/rev"
        );
        let n288 = name_line(288.0, &c, &f);
        assert_eq!((n288.kind, n288.aliased, n288.true_cycles), (PeriodicKind::ToothMesh, true, 432.0));
        assert_eq!(n288.explanation, "216-tooth gear, harmonic 2 at 432 cycles/rev, aliased to 288 by 720 points/rev");
        let n204 = name_line(204.0, &c, &f);
        assert_eq!(n204.explanation, "sideband of the 216-tooth mesh at -1 x the 12:1 gear pass");
        let n2 = name_line(2.0, &c, &f);
        assert_eq!(n2.kind, PeriodicKind::Ellipticity);
        assert!(n2.notes.is_empty());
        let n7 = name_line(7.0, &c, &f);
        assert_eq!(n7.kind, PeriodicKind::Harmonic);
        assert_eq!(
            n7.explanation,
            "7 cycles/rev matches no part of the design: look for a 7:1 gear pass or a bearing \
             (or a component at 713 cycles/rev aliased by the 720-point sampling)"
        );
        assert!(n7.notes[0].starts_with("2 encoder heads cancel the scale's odd harmonics"), "{:?}", n7.notes);
        let n1 = name_line(1.0, &c, &f);
        assert_eq!(n1.kind, PeriodicKind::Eccentricity);
        assert_eq!(n1.notes.len(), 1);
        // A single-head encoder gets no such note.
        assert!(name_line(7.0, &c, &Frame { encoder_heads: 1, ..f }).notes.is_empty());
    }

    #[test]
    fn alias_report_of_figure_4() {
        let c = design_candidates(&fig4(), &AnalysisOptions::default());
        let r = alias_report(&c, &frame(720.0), |bin| Some((bin == 288 || bin == 72, 1e-3, 135.0)));
        assert_eq!(r.len(), 2, "{r:#?}");
        assert_eq!((r[0].observed_cycles, r[0].true_cycles, r[0].action), (288.0, 432.0, AliasAction::Relocate));
        assert_eq!(r[0].source, "216-tooth gear, harmonic 2");
        assert!(r[0].significant);
        assert!((r[0].true_phase_deg.unwrap() - 45.0).abs() < 1e-12);
        assert_eq!((r[1].observed_cycles, r[1].true_cycles, r[1].action), (72.0, 648.0, AliasAction::Null));
        assert_eq!(r[1].reason, "bin 72 also holds 12:1 pinion, harmonic 6: the contributions cannot be separated");
        // At 360 points both 432 and 648 land on 72 (with the 6th gear harmonic): null;
        // 216 -> 144 and the sidebands have bins of their own: relocate.
        let r = alias_report(&c, &frame(360.0), |_| None);
        let get = |f: f64| r.iter().find(|e| e.true_cycles == f).unwrap();
        assert_eq!((get(216.0).observed_cycles, get(216.0).action), (144.0, AliasAction::Relocate));
        assert_eq!((get(432.0).observed_cycles, get(432.0).action), (72.0, AliasAction::Null));
        assert_eq!((get(648.0).observed_cycles, get(648.0).action), (72.0, AliasAction::Null));
        assert_eq!((get(204.0).observed_cycles, get(204.0).action), (156.0, AliasAction::Relocate));
        // At 432 points the tooth mesh sits on the Nyquist bin; 864 = 2 x 432 on the mean.
        let r = alias_report(&c, &frame(432.0), |_| None);
        assert!(r.iter().find(|e| e.true_cycles == 216.0).unwrap().reason.contains("Nyquist"));
        assert!(r.iter().find(|e| e.true_cycles == 432.0).unwrap().reason.contains("mean"));
        // A partial range reports what it could not fit.
        let r = alias_report(&c, &Frame { full_circle: false, ..frame(720.0) }, |_| None);
        assert!(r.iter().all(|e| e.action == AliasAction::Null && !e.significant));
        assert_eq!(r.len(), 2);
    }
}
