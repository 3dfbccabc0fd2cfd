//! What a grid of targets can see, and a check survey designed to see what
//! it decides about.
//!
//! Evenly spaced targets `360 / N` apart (a full circle of `N`, or an arc at
//! that spacing) see a line of `k` cycles per revolution at its alias, the
//! distance from `k` to the nearest multiple of `N` (`0..=N/2`). A line whose
//! alias is the mean (0) cannot be told from an offset; one on the Nyquist
//! bin (`N/2`) shows only its cosine at the targets, so neither its
//! amplitude nor its phase is estimable; two lines at one alias cannot be
//! told apart. "Near" is within one bin (one cycle per revolution): on a
//! full circle distinct integer bins are orthogonal, and a line that is not
//! an integer needs a bin of room to stay well conditioned.
//!
//! [`design_check`] chooses the fewest targets, at least [`MIN_CHECK_POINTS`],
//! that see every line asked for (the lines in force, the mounting's once
//! per revolution, the design's) and that test the table between the
//! calibration's own targets: spaced an odd number of half calibration steps
//! apart (`2 N_cal / N` odd), every other check target is a calibration
//! target (the mean error maps compare there, cell by cell) and the ones
//! between fall half way between two (where the table interpolates).

use survey_processing::analysis::alias;

/// The fewest targets of a check survey: 16 targets, both ways, two runs,
/// give 64 samples and 32 cells (16 shared with a calibration on the
/// half-step grid), enough for the map's F test and the table's binomial
/// count at the stated false-alarm rate to see a change of a few
/// repeatabilities.
pub const MIN_CHECK_POINTS: u32 = 16;

/// A line the targets cannot see, and why.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Unseen {
    /// The line, cycles per revolution.
    pub cycles_per_rev: f64,
    /// Why, in words.
    pub why: String,
}

/// The targets' points per revolution when they are evenly spaced (`360 /
/// step`: a full circle's count, or an arc's at its spacing); `None` for
/// fewer than two targets or an uneven grid.
pub fn points_per_rev(targets_deg: &[f64]) -> Option<f64> {
    let mut t: Vec<f64> = targets_deg.to_vec();
    t.sort_by(f64::total_cmp);
    t.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    if t.len() < 2 {
        return None;
    }
    let step = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    let even = step > 0.0 && t.windows(2).all(|w| ((w[1] - w[0]) - step).abs() < 1e-6 * step.max(1e-9));
    even.then(|| 360.0 / step)
}

/// `20` or `20.5`.
fn cycles(k: f64) -> String {
    if k.fract() == 0.0 { format!("{k:.0}") } else { format!("{k}") }
}

/// `N` as a count when it is one.
fn count(n: f64) -> String {
    if (n - n.round()).abs() < 1e-9 { format!("{:.0}", n.round()) } else { format!("{n:.2}") }
}

/// The lines of `lines` (positive, duplicates once, in order) that targets
/// at `n` points per revolution cannot see, each with why; a line that
/// shares its alias with an earlier one is unseen unless `jointly` (a
/// polygon's faces, the calibration's own grid: the two are tested together,
/// as the calibration saw them).
pub fn unseen(lines: &[f64], n: f64, jointly: bool) -> Vec<Unseen> {
    let mut kept: Vec<(f64, f64)> = Vec::new();
    let mut out = Vec::new();
    for &k in lines {
        if k <= 0.0
            || kept.iter().any(|(l, _)| (l - k).abs() < 1e-9)
            || out.iter().any(|u: &Unseen| u.cycles_per_rev == k)
        {
            continue;
        }
        let a = alias(k, n).observed;
        let why = if a < 1.0 {
            Some(format!(
                "at {} points per revolution the {} cycles/rev line aliases onto the mean (bin {}): it cannot be told \
                 from an offset",
                count(n),
                cycles(k),
                count(a)
            ))
        } else if n / 2.0 - a < 1.0 {
            Some(format!(
                "at {} points per revolution the {} cycles/rev line sits {} the Nyquist bin ({}): only its cosine is \
                 seen, so neither its amplitude nor its phase can be estimated",
                count(n),
                cycles(k),
                if (n / 2.0 - a).abs() < 1e-9 { "on" } else { "next to" },
                count(n / 2.0)
            ))
        } else if let Some((l, _)) = kept.iter().find(|(_, b)| (b - a).abs() < 1.0) {
            (!jointly).then(|| {
                format!(
                    "at {} points per revolution the {} cycles/rev line aliases onto the {} cycles/rev line (bin {}): \
                     the two cannot be told apart",
                    count(n),
                    cycles(k),
                    cycles(*l),
                    count(a)
                )
            })
        } else {
            None
        };
        match why {
            Some(why) => out.push(Unseen { cycles_per_rev: k, why }),
            None => kept.push((k, a)),
        }
    }
    out
}

/// Why a line that is not in force hides from a grid of targets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Blind {
    /// It aliases onto the mean: it cannot be told from an offset.
    Mean,
    /// It sits on or next to the Nyquist bin: only its cosine is seen (none
    /// at all at phase 0 on the bin).
    Nyquist,
    /// It aliases onto a line in force: seen only as a change of that line.
    LineInForce,
}

/// Whether a line at `k` cycles per revolution hides from targets at `n`
/// points per revolution by its alias alone (the rule of [`unseen`]: within
/// a bin of the mean or of the Nyquist bin).
fn hides(k: f64, n: f64) -> Option<Blind> {
    let a = alias(k, n).observed;
    if a < 1.0 {
        Some(Blind::Mean)
    } else if n / 2.0 - a < 1.0 {
        Some(Blind::Nyquist)
    } else {
        None
    }
}

/// The whole cycles per revolution from 1 to `up_to` at which a line hides
/// from targets at `n` points per revolution, and why ([`Blind::Mean`] or
/// [`Blind::Nyquist`]).
pub fn blind_bins(n: f64, up_to: u32) -> Vec<(u32, Blind)> {
    (1..=up_to).filter_map(|k| hides(f64::from(k), n).map(|b| (k, b))).collect()
}

/// Every whole line from 1 to `up_to` cycles per revolution that is not in
/// `lines` (those in force and seen before) and that targets at `n` points
/// per revolution cannot see by itself: on the mean, on the Nyquist bin, or
/// on the bin of a line in force (then seen only as a change of that line),
/// each with why. A new line there would leave a check "in tolerance" while
/// the table in force no longer holds: the check lists them.
pub fn blind(n: f64, lines: &[f64], up_to: u32) -> Vec<(Blind, Unseen)> {
    let in_force: Vec<(f64, f64)> = lines.iter().filter(|k| **k > 0.0).map(|&k| (k, alias(k, n).observed)).collect();
    let mut out = Vec::new();
    for k in 1..=up_to {
        let kf = f64::from(k);
        if in_force.iter().any(|(l, _)| (l - kf).abs() < 1e-9) {
            continue;
        }
        let (kind, why) = match hides(kf, n) {
            Some(Blind::Mean) => (
                Blind::Mean,
                format!(
                    "a new line at {k} cycles/rev aliases onto the mean at {} points per revolution: the check cannot see it",
                    count(n)
                ),
            ),
            Some(_) => (
                Blind::Nyquist,
                format!(
                    "a new line at {k} cycles/rev sits on or next to the Nyquist bin ({}) at {} points per revolution: only its cosine is seen, none of it at phase 0",
                    count(n / 2.0),
                    count(n)
                ),
            ),
            None => {
                let a = alias(kf, n).observed;
                let Some((l, _)) = in_force.iter().find(|(_, b)| (b - a).abs() < 1.0) else { continue };
                (
                    Blind::LineInForce,
                    format!(
                        "a new line at {k} cycles/rev aliases onto the {} cycles/rev line in force at {} points per revolution: seen only as a change of that line",
                        cycles(*l),
                        count(n)
                    ),
                )
            }
        };
        out.push((kind, Unseen { cycles_per_rev: kf, why }));
    }
    out
}

/// Whether targets at `n` points per revolution share none of `other`'s
/// blind bins from 1 to `up_to` (the mean's, the Nyquist bin's).
fn apart(n: f64, other: &[u32], up_to: u32) -> bool {
    blind_bins(n, up_to).iter().all(|(k, _)| !other.contains(k))
}

/// Whether targets at `n` and at `m` points per revolution share no blind
/// bin from 1 to `up_to` (the mean's, the Nyquist bin's): a line one check
/// cannot see, the other can.
pub fn blind_bins_differ(n: f64, m: f64, up_to: u32) -> bool {
    let other: Vec<u32> = blind_bins(m, up_to).iter().map(|(k, _)| *k).collect();
    apart(n, &other, up_to)
}

/// The calibration a check is designed from: its targets' grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationGrid {
    /// Its targets.
    pub points: u32,
    /// The arc they span, degrees; `None` for a full circle (`360 / points` apart).
    pub arc_deg: Option<f64>,
    /// The reference is a polygon: its faces are the targets, of the check too.
    pub polygon: bool,
}

/// A check survey's design: how many targets, why, and what it cannot see.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckDesign {
    /// Targets (evenly spaced over the calibration's circle or arc, from its first target).
    pub points: u32,
    /// Why this many, in words.
    pub why: String,
    /// The lines asked for that these targets cannot see.
    pub unseen: Vec<Unseen>,
    /// The lines not in force, up to [`CheckDesign::up_to`], that these
    /// targets cannot see by themselves, and why ([`blind`]).
    pub blind: Vec<(Blind, Unseen)>,
    /// The highest line the check answers for: the calibration's own
    /// Nyquist bin (a line above it the calibration could not have placed).
    pub up_to: u32,
    /// The targets of the asset's check before this one, when there was one.
    pub previous: Option<u32>,
}

impl CalibrationGrid {
    /// Points per revolution of `n` targets on this grid's circle or arc.
    fn per_rev(&self, n: u32) -> f64 {
        match self.arc_deg {
            None => f64::from(n),
            Some(arc) => 360.0 * f64::from(n.max(2) - 1) / arc,
        }
    }

    /// The calibration's own intervals: `points` on a full circle, `points - 1` on an arc.
    fn intervals(&self, n: u32) -> u32 {
        if self.arc_deg.is_some() { n.saturating_sub(1) } else { n }
    }
}

/// The check survey for a calibration on `grid` whose table corrects (or
/// whose history has seen) `lines` (see the module documentation).
/// `requested`: the targets the command line asked for, used as they are.
/// `previous`: the targets of the asset's last check: successive checks
/// choose grids whose blind bins ([`blind_bins`], up to the calibration's
/// Nyquist bin) differ, so that a new line one check cannot see, the next
/// one can (where no grid that sees the lines in force does, the design
/// says so).
pub fn design_check(
    grid: CalibrationGrid,
    lines: &[f64],
    requested: Option<u32>,
    previous: Option<u32>,
) -> CheckDesign {
    design_check_avoiding(grid, lines, &[], requested, previous)
}

/// [`design_check`], with the design's other frequencies `avoid` (its gear
/// and tooth harmonics that are not lines in force): the grid a check takes
/// to be blind elsewhere than the last check is not one on which one of them
/// aliases onto a line in force's bin, since the check's own processing may
/// then hold that line in doubt (it cannot tell the two apart) and decide
/// nothing (measured: the Figure 8 positioner's second check at 17 targets,
/// 100 of 100 not decided). The first check's grid is chosen as before:
/// there the processing places such lines by the calibration's (measured:
/// 0 of 100 not decided on the grids it takes).
pub fn design_check_avoiding(
    grid: CalibrationGrid,
    lines: &[f64],
    avoid: &[f64],
    requested: Option<u32>,
    previous: Option<u32>,
) -> CheckDesign {
    let up_to = (grid.per_rev(grid.points) / 2.0).floor().max(1.0) as u32;
    // The last check's blind bins, once: every candidate is held apart from them.
    let before: Option<Vec<u32>> =
        previous.map(|p| blind_bins(grid.per_rev(p), up_to).iter().map(|(k, _)| *k).collect());
    let differs = |n: u32| before.as_deref().is_none_or(|b| apart(grid.per_rev(n), b, up_to));
    let clear = |n: u32| !collides(avoid, lines, grid.per_rev(n));
    let plain = design_with(grid, lines, requested, (&|_| true, false));
    let mut d = match previous {
        Some(p) if requested.is_none() && !grid.polygon => {
            let fresh = design_with(grid, lines, requested, (&|n| differs(n) && clear(n), true));
            if fresh.unseen.is_empty() && differs(fresh.points) {
                CheckDesign {
                    why: format!(
                        "{}; its blind bins differ from the last check's ({p} targets) up to {up_to} cycles/rev",
                        fresh.why
                    ),
                    ..fresh
                }
            } else {
                CheckDesign {
                    why: format!(
                        "{}; no grid that sees the lines in force has blind bins apart from the last check's ({p} targets): the two share some",
                        plain.why
                    ),
                    ..plain
                }
            }
        }
        _ => plain,
    };
    d.blind = blind(grid.per_rev(d.points), lines, up_to);
    d.up_to = up_to;
    d.previous = previous;
    d
}

/// Whether at `n` points per revolution a frequency of `avoid` (not itself
/// a line) aliases onto the bin of one of `lines` (a line's own aliases, the
/// mean and the Nyquist bin are [`unseen`]'s).
fn collides(avoid: &[f64], lines: &[f64], n: f64) -> bool {
    avoid.iter().filter(|f| **f > 0.0 && !lines.iter().any(|l| (l - *f).abs() < 1e-9)).any(|&f| {
        let a = alias(f, n).observed;
        lines.iter().filter(|l| **l > 0.0).any(|&l| (alias(l, n).observed - a).abs() < 1.0)
    })
}

/// [`design_check`]'s choice among the grids `fresh` admits (the last
/// resort, every calibration target and every point half way, admitted
/// always); `previous_apart`: the choice is of a grid apart from the last
/// check's.
fn design_with(
    grid: CalibrationGrid,
    lines: &[f64],
    requested: Option<u32>,
    (fresh, previous_apart): (&dyn Fn(u32) -> bool, bool),
) -> CheckDesign {
    let done = |points: u32, why: String, unseen: Vec<Unseen>| CheckDesign {
        points,
        why,
        unseen,
        blind: Vec::new(),
        up_to: 0,
        previous: None,
    };
    let names = |ls: &[f64]| {
        let mut seen: Vec<f64> = Vec::new();
        for &k in ls.iter().filter(|k| **k > 0.0) {
            if !seen.contains(&k) {
                seen.push(k);
            }
        }
        seen.iter().map(|k| cycles(*k)).collect::<Vec<_>>().join(", ")
    };
    if grid.polygon {
        let n = grid.points;
        return done(
            n,
            format!("every face of the polygon ({n}): the faces are the targets"),
            unseen(lines, grid.per_rev(n), true),
        );
    }
    if let Some(n) = requested {
        return done(n, format!("{n} targets, as asked (--points)"), unseen(lines, grid.per_rev(n), false));
    }
    let cal = grid.intervals(grid.points);
    let first = |n: u32| if grid.arc_deg.is_some() { n + 1 } else { n };
    // Spacings of an odd number of half steps: 2 cal / (2m + 1) intervals.
    let mut half_steps: Vec<u32> = (0..)
        .map(|m| 2 * m + 1)
        .take_while(|d| *d <= 2 * cal)
        .filter(|d| (2 * cal).is_multiple_of(*d))
        .map(|d| first(2 * cal / d))
        .filter(|&n| n >= MIN_CHECK_POINTS)
        .collect();
    half_steps.sort_unstable();
    let limit = first(2 * cal).max(MIN_CHECK_POINTS);
    let sees = |n: u32| fresh(n) && unseen(lines, grid.per_rev(n), false).is_empty();
    // A grid apart from the last check's: the half steps' only when it costs
    // at most twice the fewest targets of any grid apart.
    let most = match previous_apart {
        true => (MIN_CHECK_POINTS..=limit).find(|&n| sees(n)).map_or(u32::MAX, |n| 2 * n),
        false => u32::MAX,
    };
    if let Some(&n) = half_steps.iter().find(|&&n| n <= most && sees(n)) {
        let spacing = (2 * cal) / grid.intervals(n);
        return done(
            n,
            format!(
                "{n} targets: the fewest (at least {MIN_CHECK_POINTS}) that see every line in force and seen before \
                 ({} cycles/rev) away from the mean, the Nyquist bin and each other, spaced {spacing} half steps of the \
                 calibration apart: every other target is a calibration target, the rest fall half way between two, \
                 where the table interpolates",
                names(lines)
            ),
            Vec::new(),
        );
    }
    // No half-step grid sees them all: the fewest evenly spaced targets that do.
    if let Some(n) = (MIN_CHECK_POINTS..=limit).find(|&n| sees(n)) {
        let (m, c) = (grid.intervals(n), cal);
        let shared = (0..n).filter(|j| (u64::from(*j) * u64::from(c)).is_multiple_of(u64::from(m.max(1)))).count();
        return done(
            n,
            format!(
                "{n} targets: the fewest (at least {MIN_CHECK_POINTS}) that see every line in force and seen before \
                 ({} cycles/rev) away from the mean, the Nyquist bin and each other (no spacing of whole half steps of \
                 the calibration does); {shared} of them are calibration targets, the rest fall between",
                names(lines)
            ),
            Vec::new(),
        );
    }
    done(
        limit,
        format!(
            "{limit} targets, every calibration target and every point half way between: no smaller grid sees every \
             line in force and seen before ({} cycles/rev)",
            names(lines)
        ),
        unseen(lines, grid.per_rev(limit), false),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn full(points: u32) -> CalibrationGrid {
        CalibrationGrid { points, arc_deg: None, polygon: false }
    }

    #[test]
    fn the_mean_the_nyquist_bin_and_a_shared_alias_are_unseen() {
        let u = unseen(&[1.0, 20.0, 40.0], 40.0, false);
        assert_eq!(u.iter().map(|u| u.cycles_per_rev).collect::<Vec<_>>(), [20.0, 40.0]);
        assert!(u[0].why.contains("on the Nyquist bin (20)") && u[1].why.contains("onto the mean"), "{u:?}");
        // At 36, 16 is 20's alias; on a polygon's faces the two are tested together.
        let u = unseen(&[20.0, 16.0], 36.0, false);
        assert!(u.len() == 1 && u[0].why.contains("onto the 20 cycles/rev line (bin 16)"), "{u:?}");
        assert!(unseen(&[20.0, 16.0], 36.0, true).is_empty());
        // Near is within a bin; duplicates and the zero frequency are skipped.
        assert!(unseen(&[19.5, 0.0, 1.0, 1.0], 40.0, false)[0].why.contains("next to the Nyquist"));
        assert!(unseen(&[1.0, 2.0, 3.0, 17.0], 36.0, false).is_empty());
    }

    #[test]
    fn evenly_spaced_targets_give_their_points_per_revolution() {
        let circle: Vec<f64> = (0..40).map(|j| 9.0 * f64::from(j)).collect();
        assert_eq!(points_per_rev(&circle), Some(40.0));
        // Repeated targets (runs, directions) count once; an arc at 2.5 deg is 144 a turn.
        let arc: Vec<f64> = (0..10).flat_map(|j| [2.5 * f64::from(j) - 5.0; 3]).collect();
        assert_eq!(points_per_rev(&arc), Some(144.0));
        assert_eq!(points_per_rev(&[0.0, 1.0, 3.0]), None);
        assert_eq!(points_per_rev(&[5.0]), None);
    }

    /// The 120-point calibration with its lines in force (1, 20 and
    /// 40 cycles/rev): 16 targets put 40 on the Nyquist bin, so the check
    /// takes 48 (five half steps apart): every other one a calibration
    /// target, every other half way between.
    #[test]
    fn a_check_of_a_120_point_calibration_sees_its_lines_with_48_targets() {
        let d = design_check(full(120), &[1.0, 20.0, 40.0], None, None);
        assert_eq!(d.points, 48, "{d:?}");
        assert!(d.unseen.is_empty() && d.why.contains("5 half steps"), "{d:?}");
        let step = 3.0;
        let shared = (0..48).filter(|j| (7.5 * f64::from(*j) / step).fract() == 0.0).count();
        assert_eq!(shared, 24);
        // Every line seen, with a bin of room, at the design.
        assert!(unseen(&[1.0, 20.0, 40.0], 48.0, false).is_empty());
    }

    #[test]
    fn checks_of_other_calibrations_see_every_line_in_force() {
        for (points, lines) in [
            (60, vec![1.0, 20.0, 40.0]),
            (360, vec![1.0, 20.0, 40.0]),
            (1800, vec![1.0, 20.0, 40.0, 100.0]),
            (36, vec![1.0, 16.0, 4.0]),
            (720, vec![1.0, 2.0, 3.0, 24.0, 48.0, 72.0]),
        ] {
            let d = design_check(full(points), &lines, None, None);
            assert!(d.unseen.is_empty() && d.points >= MIN_CHECK_POINTS, "{points}: {d:?}");
            assert!(unseen(&lines, f64::from(d.points), false).is_empty(), "{points}: {d:?}");
            // Fewest: no smaller count of at least 16 on the half-step grid sees them.
            let half_step = (2 * points).is_multiple_of(d.points) && ((2 * points) / d.points) % 2 == 1;
            if half_step {
                let smaller = (MIN_CHECK_POINTS..d.points).filter(|n| {
                    (2 * points).is_multiple_of(*n)
                        && ((2 * points) / n) % 2 == 1
                        && unseen(&lines, f64::from(*n), false).is_empty()
                });
                assert_eq!(smaller.count(), 0, "{points}: {d:?}");
            }
        }
    }

    #[test]
    fn a_polygon_is_checked_at_its_faces_and_an_asked_count_as_asked() {
        let faces = CalibrationGrid { points: 24, arc_deg: None, polygon: true };
        let d = design_check(faces, &[1.0, 20.0, 100.0, 12.0], None, None);
        assert_eq!(d.points, 24);
        // 100 shares 20's bin (4): tested together; 12 is the Nyquist bin of 24 faces.
        assert_eq!(d.unseen.iter().map(|u| u.cycles_per_rev).collect::<Vec<_>>(), [12.0]);
        let asked = design_check(full(120), &[1.0, 20.0, 40.0], Some(40), None);
        assert_eq!((asked.points, asked.unseen.len()), (40, 2));
    }

    /// Issue 49's check of a 120-point calibration with 16 targets: a new
    /// line at 16 or 48 cycles/rev (the mean) or at 8 (the Nyquist bin) is
    /// listed as blind; the next check of the asset takes 18 targets, blind
    /// elsewhere, and sees all three.
    #[test]
    fn a_check_lists_its_blind_bins_and_the_next_one_is_blind_elsewhere() {
        let first = design_check(full(120), &[1.0, 20.0], None, None);
        assert_eq!((first.points, first.up_to, first.previous), (16, 60, None), "{first:?}");
        let listed: Vec<f64> = first.blind.iter().map(|(_, u)| u.cycles_per_rev).collect();
        for k in [8.0, 16.0, 24.0, 32.0, 40.0, 48.0, 56.0] {
            assert!(listed.contains(&k), "{k} not listed: {listed:?}");
        }
        // 4 = 20 - 16 and 36 = 16 + 20 share the 20 cycles/rev line's bin; 15 and 17 the mounting's.
        for k in [4.0, 36.0, 15.0, 17.0] {
            assert!(listed.contains(&k), "{k} not listed: {listed:?}");
        }
        assert!(!listed.contains(&20.0) && !listed.contains(&1.0) && !listed.contains(&5.0), "{listed:?}");
        assert!(
            first
                .blind
                .iter()
                .find(|(_, u)| u.cycles_per_rev == 36.0)
                .is_some_and(|(_, u)| u.why.contains("20 cycles/rev"))
        );
        let next = design_check(full(120), &[1.0, 20.0], None, Some(first.points));
        assert_eq!(next.points, 18, "{next:?}");
        assert!(next.unseen.is_empty() && next.why.contains("differ from the last check's (16 targets)"), "{next:?}");
        assert!(blind_bins_differ(18.0, 16.0, 60));
        // Neither on the mean nor on the Nyquist bin now (16 shares the 20
        // cycles/rev line's bin at 18: seen as a change of that line).
        for k in [8.0, 16.0, 48.0] {
            let again = next.blind.iter().find(|(_, u)| u.cycles_per_rev == k);
            assert!(again.is_none_or(|(_, u)| u.why.contains("line in force")), "{k} blind again: {again:?}");
        }
        // And the one after goes back to 16, apart from 18's.
        let third = design_check(full(120), &[1.0, 20.0], None, Some(next.points));
        assert!(third.points == 16 && blind_bins_differ(16.0, 18.0, 60), "{third:?}");
    }

    /// The Figure 8 positioner's second check (issue 49, measured): 17
    /// targets put its design's 120 and 100 cycles/rev onto the lines in
    /// force at 1 and 2, so the check's processing held them in doubt and
    /// decided nothing, every other night. A grid where a design frequency
    /// lands on a line's bin is not chosen.
    #[test]
    fn a_check_keeps_the_design_s_other_frequencies_off_its_lines_bins() {
        let lines = [1.0, 20.0, 40.0, 2.0];
        let design = [1.0, 2.0, 20.0, 40.0, 60.0, 80.0, 100.0, 120.0];
        let blind = design_check(full(120), &lines, None, Some(48));
        assert_eq!(blind.points, 17, "without the design: {blind:?}");
        assert!(collides(&design, &lines, 17.0));
        let next = design_check_avoiding(full(120), &lines, &design, None, Some(48));
        assert!(!collides(&design, &lines, f64::from(next.points)), "{next:?}");
        assert!(next.points != 17 && next.unseen.is_empty(), "{next:?}");
        // A frequency that is itself a line is the line, not a collision.
        assert!(!collides(&[20.0], &[20.0, 1.0], 19.0));
    }

    #[test]
    fn blind_bins_are_the_mean_s_and_the_nyquist_bin_s() {
        let b = blind_bins(16.0, 40);
        assert_eq!(
            b,
            [(8, Blind::Nyquist), (16, Blind::Mean), (24, Blind::Nyquist), (32, Blind::Mean), (40, Blind::Nyquist)]
        );
        // An odd count has no whole Nyquist line but two next to it.
        let odd: Vec<u32> = blind_bins(17.0, 20).iter().map(|(k, _)| *k).collect();
        assert_eq!(odd, [8, 9, 17]);
        assert!(!blind_bins_differ(16.0, 48.0, 60) && blind_bins_differ(16.0, 18.0, 60));
    }

    #[test]
    fn a_check_of_an_arc_keeps_the_arc_s_half_steps() {
        // 101 targets over 100 deg (1 deg apart): 67 targets 1.5 deg apart (3 half steps).
        let arc = CalibrationGrid { points: 101, arc_deg: Some(100.0), polygon: false };
        let d = design_check(arc, &[1.0, 20.0], None, None);
        assert!(d.unseen.is_empty(), "{d:?}");
        let spacing = 100.0 / f64::from(d.points - 1);
        assert!(
            ((spacing / 0.5) - (spacing / 0.5).round()).abs() < 1e-9 && (spacing / 0.5).round() % 2.0 == 1.0,
            "{d:?}"
        );
    }
}
