//! A drift in time, measured from the survey's own readings: each target is
//! read in every run and direction at different times, so the change of a
//! target's error with the time it was read is the drift, whatever the
//! positioner's error there (it cancels within the target). The slope is
//! the within-group least-squares estimate (groups: target and direction):
//! `b = sum (t - t_g)(e - e_g) / sum (t - t_g)^2`, its standard error from
//! the residual scatter over `N - G - 1` degrees of freedom.
//!
//! A ramp that grows within the runs as well as between them (thermal
//! growth) reads forward and reverse passes at opposite ends of their
//! times: left in, it becomes a false backlash and direction-dependent lines
//! (issue 49). It is corrected when its slope is significant at 1 %
//! (two-sided): each reading less `b (t - t_mid)`. What a straight line in
//! time does not take is then tested: the corrected readings' deviations,
//! in each pass, from their target's mean over the runs, fitted by a mean
//! and a slope per pass; when those differ beyond their noise (a chi-square
//! per degree of freedom at 1 %)
//! the drift is not a straight line, the survey says so with its size, and
//! the table is not a result (a drift it cannot correct is in every value).
//! Our design (ISO 230-2 asks for drift to be checked, not how).

use serde::Serialize;
use std::collections::HashMap;
use survey_processing::special::{normal_two_sided_isf, student_two_sided_isf};
use survey_processing::types::{Direction, Sample};

/// The drift found in a survey's readings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TimeDrift {
    /// The slope, degrees per hour (`readout - actual` growing in time).
    pub slope_deg_per_h: f64,
    /// Its standard error, degrees per hour.
    pub slope_se_deg_per_h: f64,
    /// The slope over the survey's duration, degrees.
    pub over_survey_deg: f64,
    /// The survey's duration, hours.
    pub duration_h: f64,
    /// The time the correction is zero at: the survey's middle, seconds
    /// (readings taken later, check points, are corrected on from it).
    pub mid_s: f64,
    /// Significant at the rate: the readings are corrected for it.
    pub corrected: bool,
    /// What a straight line leaves: the largest of a pass's mean and its
    /// own slope's difference times its duration, degrees; and whether they
    /// are beyond their noise (the drift is then not corrected fully).
    pub left_deg: f64,
    pub left_significant: bool,
    /// The chi-square of the passes' means and slopes per degree of freedom.
    pub left_f: f64,
    /// `P(a chi-square this large | a straight line)` (Wilson-Hilferty).
    pub left_p: f64,
    /// Beyond doubt: `left_p` below [`NOT_A_RESULT_ALPHA`]; the table
    /// carries what no correction took, and is not a result. (At 1 % it is
    /// named: noise alone would make one drift-free survey in a hundred
    /// not a result.)
    pub left_beyond_doubt: bool,
}

/// The rate at which a drift no straight line takes makes a survey's table
/// not a result: one drift-free survey in a thousand. Our design.
pub const NOT_A_RESULT_ALPHA: f64 = 1e-3;

/// The two-sided rate the slope is tested at.
pub const ALPHA: f64 = 0.01;

/// A group of readings that differ only by when they were read: a target,
/// a direction and the class of the run (one class unless the runs are
/// classed, [`estimate_between_placements`]).
type Key = (i64, Direction, usize);

fn key(s: &Sample, class: usize) -> Key {
    ((s.target_deg * 1e9).round() as i64, s.direction, class)
}

/// Within-group sums: for each group its mean time and error; then
/// `(sxx, sxy, syy, n, groups)` about them, and each sample's deviations
/// `(dt, de)` from its group's means (`None` in a group of one).
type Within = (f64, f64, f64, usize, usize, Vec<Option<(f64, f64)>>);

fn within(samples: &[Sample], t: impl Fn(usize) -> f64, class: impl Fn(usize) -> usize) -> Within {
    let mut g: HashMap<Key, (f64, f64, usize)> = HashMap::new();
    for (i, s) in samples.iter().enumerate() {
        let e = g.entry(key(s, class(i))).or_default();
        e.0 += t(i);
        e.1 += s.error_deg();
        e.2 += 1;
    }
    let (mut sxx, mut sxy, mut syy, mut n) = (0.0, 0.0, 0.0, 0);
    let mut deviations = Vec::with_capacity(samples.len());
    for (i, s) in samples.iter().enumerate() {
        let (st, se, m) = g[&key(s, class(i))];
        if m < 2 {
            deviations.push(None);
            continue;
        }
        let (dt, de) = (t(i) - st / m as f64, s.error_deg() - se / m as f64);
        deviations.push(Some((dt, de)));
        sxx += dt * dt;
        sxy += dt * de;
        syy += de * de;
        n += 1;
    }
    let groups = g.values().filter(|v| v.2 >= 2).count();
    (sxx, sxy, syy, n, groups, deviations)
}

/// The drift in `samples` (a survey's, every one with a timestamp), `None`
/// when they do not tell it (a reading without a time, one run, nothing
/// read twice).
pub fn estimate(samples: &[Sample]) -> Option<TimeDrift> {
    let times: Vec<f64> = samples.iter().map(|s| s.timestamp_s).collect::<Option<_>>()?;
    let (sxx, sxy, syy, n, groups, _) = within(samples, |i| times[i], |_| 0);
    let dof = n.checked_sub(groups + 1).filter(|d| *d >= 3)?;
    if sxx <= 0.0 {
        return None;
    }
    let b = sxy / sxx;
    let rss = (syy - b * sxy).max(0.0);
    let se = (rss / dof as f64 / sxx).sqrt();
    let z = normal_two_sided_isf(ALPHA);
    let corrected = se > 0.0 && (b / se).abs() > z;
    let left = straightness(samples, &times, |_| 0, if corrected { b } else { 0.0 }, rss / dof as f64, false);
    Some(TimeDrift::of(b, se, corrected, &times, left))
}

/// The drift in `samples` (a survey's, every one with a timestamp) whose
/// runs each sat on a placement of the reference of their own: a polygon
/// turned on a stage between runs (issue 48), `class[i]` the turn of sample
/// `i`'s run. A turn carries its own offset and its own faces at every
/// target (the stage's error there, the faces read), which no reading
/// tells from a drift: the readings are compared only with those of the
/// same target, direction and turn (runs that came back to a turn). And
/// the stage lands a little differently each time it turns: an offset of
/// each run that is neither known nor a drift. The slope is tested against
/// the scatter of the runs' own means about the line, `R - K - 1` degrees
/// of freedom for `R` runs in `K` turns (Student's `t`): a drift is found
/// where it passes what the stage's landing may make of it. What a
/// straight line does not take is tested within the runs (their passes'
/// means against their run's, and the passes' slopes): between the runs
/// the landing is not told from it. `None` when no turn came back in a
/// second run past what the slope takes (`R - K - 1 < 1`), or as
/// [`estimate`].
pub fn estimate_between_placements(samples: &[Sample], class: &[usize]) -> Option<TimeDrift> {
    if class.len() != samples.len() {
        return None;
    }
    let times: Vec<f64> = samples.iter().map(|s| s.timestamp_s).collect::<Option<_>>()?;
    let (sxx, sxy, _, n, groups, deviations) = within(samples, |i| times[i], |i| class[i]);
    if sxx <= 0.0 {
        return None;
    }
    let b = sxy / sxx;
    // Each run's count, deviations' sums of time and error, and turn.
    let mut runs: std::collections::BTreeMap<u32, (f64, f64, f64, usize)> = Default::default();
    for ((s, d), c) in samples.iter().zip(&deviations).zip(class) {
        if let Some((dt, de)) = d {
            let r = runs.entry(s.run).or_insert((0.0, 0.0, 0.0, *c));
            r.0 += 1.0;
            r.1 += dt;
            r.2 += de;
        }
    }
    let turns = runs.values().map(|r| r.3).collect::<std::collections::BTreeSet<_>>().len();
    let dof = runs.len().checked_sub(turns + 1).filter(|d| *d >= 1)?;
    // A run's mean off the line (the landing and the noise): its scatter
    // over the runs is the slope's.
    let v = runs.values().map(|r| (r.2 / r.0 - b * r.1 / r.0).powi(2)).sum::<f64>() / dof as f64;
    let se = (v * runs.values().map(|r| r.1 * r.1).sum::<f64>()).sqrt() / sxx;
    let corrected = se > 0.0 && (b / se).abs() > student_two_sided_isf(ALPHA, dof as u32);
    // The noise of one reading within its run: about the group's and the
    // run's means, `N - G - R + K` degrees of freedom.
    let mean_of_run = |r: u32| runs.get(&r).map_or(0.0, |r| (r.2 - b * r.1) / r.0);
    let rss: f64 = samples
        .iter()
        .zip(&deviations)
        .filter_map(|(s, d)| d.map(|(dt, de)| (de - b * dt - mean_of_run(s.run)).powi(2)))
        .sum();
    let within_dof = (n + turns).checked_sub(groups + runs.len()).filter(|d| *d >= 3)?;
    let b_used = if corrected { b } else { 0.0 };
    let left = straightness(samples, &times, |i| class[i], b_used, rss / within_dof as f64, true);
    Some(TimeDrift::of(b, se, corrected, &times, left))
}

impl TimeDrift {
    /// The drift of slope `b` (degrees a second, standard error `se`) over
    /// readings at `times`, and what a straight line leaves of it.
    fn of(b: f64, se: f64, corrected: bool, times: &[f64], left: (f64, f64, f64, bool)) -> Self {
        let (t0, t1) = times.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, z), t| (a.min(*t), z.max(*t)));
        let (left_deg, left_f, left_p, left_significant) = left;
        TimeDrift {
            slope_deg_per_h: b * 3600.0,
            slope_se_deg_per_h: se * 3600.0,
            over_survey_deg: b * (t1 - t0),
            duration_h: (t1 - t0) / 3600.0,
            mid_s: 0.5 * (t0 + t1),
            corrected,
            left_deg,
            left_significant,
            left_f,
            left_p,
            left_beyond_doubt: left_significant && left_p < NOT_A_RESULT_ALPHA,
        }
    }
}

/// One pass's figures for [`straightness`]: its run, count, mean deviation,
/// slope and its variance, duration.
struct Pass {
    run: u32,
    n: f64,
    mean: f64,
    slope: f64,
    slope_var: f64,
    span: f64,
}

/// Each pass's mean and slope of the readings corrected by `b`, against
/// their group's mean over the runs (a straight line leaves both at
/// zero, within their noise; with `run_offsets`, each run's own mean is
/// free and a pass's mean is taken against its run's): the largest of
/// `|mean|` and the slope's difference times a pass's duration, degrees; the
/// chi-square of means and slopes per degree of freedom; and whether it is
/// beyond the 1 % point (its normal limit for many degrees of freedom:
/// `F > 1 + z sqrt(2 / k)`).
fn straightness(
    samples: &[Sample],
    times: &[f64],
    class: impl Fn(usize) -> usize,
    b: f64,
    var: f64,
    run_offsets: bool,
) -> (f64, f64, f64, bool) {
    let mut by_pass: HashMap<(u32, Direction), Vec<usize>> = HashMap::new();
    for (i, s) in samples.iter().enumerate() {
        by_pass.entry((s.run, s.direction)).or_default().push(i);
    }
    let corrected: Vec<f64> = samples.iter().zip(times).map(|(s, t)| s.error_deg() - b * t).collect();
    let mut mean: HashMap<Key, (f64, usize)> = HashMap::new();
    for (i, s) in samples.iter().enumerate() {
        let m = mean.entry(key(s, class(i))).or_default();
        m.0 += corrected[i];
        m.1 += 1;
    }
    let passes: Vec<Pass> = by_pass
        .iter()
        .filter(|(_, p)| p.len() >= 3)
        .filter_map(|(&(run, _), p)| {
            let n = p.len() as f64;
            let tm = p.iter().map(|&i| times[i]).sum::<f64>() / n;
            let dev = |i: usize| {
                let (sum, m) = mean[&key(&samples[i], class(i))];
                corrected[i] - sum / m as f64
            };
            let dm = p.iter().map(|&i| dev(i)).sum::<f64>() / n;
            let sxx: f64 = p.iter().map(|&i| (times[i] - tm).powi(2)).sum();
            let sxy: f64 = p.iter().map(|&i| (times[i] - tm) * (dev(i) - dm)).sum();
            let span = p.iter().map(|&i| times[i]).fold(f64::NEG_INFINITY, f64::max)
                - p.iter().map(|&i| times[i]).fold(f64::INFINITY, f64::min);
            (sxx > 0.0).then(|| Pass { run, n, mean: dm, slope: sxy / sxx, slope_var: var / sxx, span })
        })
        .collect();
    if passes.len() < 2 || var <= 0.0 {
        return (0.0, 0.0, 1.0, false);
    }
    // Each pass's mean as tested, its variance; the degrees of freedom the
    // means give. Against its run's mean, `sum n_p (m_p - m_run)^2 / var`
    // is a chi-square of `passes - 1` degrees of freedom a run.
    let (means, mean_dof): (Vec<(f64, f64)>, usize) = if run_offsets {
        let mut runs: HashMap<u32, (f64, f64, usize)> = HashMap::new();
        for p in &passes {
            let r = runs.entry(p.run).or_default();
            r.0 += p.n * p.mean;
            r.1 += p.n;
            r.2 += 1;
        }
        let means = passes
            .iter()
            .map(|p| {
                let (sum, n, count) = runs[&p.run];
                if count < 2 { (0.0, 0.0) } else { (p.mean - sum / n, var / p.n) }
            })
            .collect();
        (means, runs.values().map(|r| r.2 - 1).sum())
    } else {
        (passes.iter().map(|p| (p.mean, var / p.n)).collect(), passes.len() - 1)
    };
    let w: f64 = passes.iter().map(|p| 1.0 / p.slope_var).sum();
    let m = passes.iter().map(|p| p.slope / p.slope_var).sum::<f64>() / w;
    let chi2: f64 = passes
        .iter()
        .zip(&means)
        .map(|(p, (d, v))| if *v > 0.0 { d * d / v } else { 0.0 } + (p.slope - m).powi(2) / p.slope_var)
        .sum();
    let k = (mean_dof + passes.len() - 1) as f64;
    let f = chi2 / k;
    let z = normal_two_sided_isf(2.0 * ALPHA);
    let significant = f > 1.0 + z * (2.0 / k).sqrt();
    let left =
        passes.iter().zip(&means).map(|(p, (d, _))| d.abs().max((p.slope - m).abs() * p.span)).fold(0.0, f64::max);
    // Wilson-Hilferty: (chi2 / k)^(1/3) is about normal, mean 1 - 2/(9k).
    let h = 2.0 / (9.0 * k);
    let p = 0.5 * survey_processing::special::erfc((f.cbrt() - (1.0 - h)) / h.sqrt() / std::f64::consts::SQRT_2);
    (left, f, p, significant)
}

/// Each table cell's mean time (a target in one direction), sorted.
fn cell_times(samples: &[Sample]) -> Vec<f64> {
    let mut cells: HashMap<Key, (f64, usize)> = HashMap::new();
    for (s, t) in samples.iter().filter_map(|s| s.timestamp_s.map(|t| (s, t))) {
        let c = cells.entry(key(s, 0)).or_default();
        (c.0, c.1) = (c.0 + t, c.1 + 1);
    }
    let mut out: Vec<f64> = cells.values().map(|(t, n)| t / *n as f64).collect();
    out.sort_by(f64::total_cmp);
    out
}

/// `samples` (the survey's, or readings it took after, on its clock) less
/// the drift `d`, about the survey's middle time.
pub fn corrected(samples: &[Sample], d: &TimeDrift) -> Vec<Sample> {
    let (b, mid) = (d.slope_deg_per_h / 3600.0, d.mid_s);
    samples
        .iter()
        .map(|s| match s.timestamp_s {
            // readout - actual grows by b t: the actual angle moves by it.
            Some(t) => Sample { actual_deg: s.actual_deg + b * (t - mid), ..*s },
            None => *s,
        })
        .collect()
}

impl TimeDrift {
    /// What the slope's own uncertainty leaves in a table of `samples`,
    /// standard, degrees: a cell (a target's readings in one direction over
    /// the runs) corrected by `b (t - mid)` keeps `db (t_cell - mid)`; its rms
    /// over the cells, `db` the slope's standard error (corrected or not:
    /// issue 49, "what it leaves is in U").
    pub fn table_u_deg(&self, samples: &[Sample]) -> f64 {
        let t = cell_times(samples);
        let ms = t.iter().map(|t| (t - self.mid_s).powi(2)).sum::<f64>() / t.len().max(1) as f64;
        self.slope_se_deg_per_h / 3600.0 * ms.sqrt()
    }

    /// One line for people (a survey's: what no straight line takes makes
    /// its table not a result).
    pub fn text(&self) -> String {
        if self.left_beyond_doubt {
            self.text_saying("the table carries it and is not a result")
        } else {
            self.text_saying(
                "named (at p = {p} one drift-free survey in a hundred shows as much; the table is not a result below \
                 1 in 1000)",
            )
            .replace("{p}", &format!("{:.1e}", self.left_p))
        }
    }

    /// [`TimeDrift::text`], with `consequence` said of what no straight
    /// line takes (a verification's: it is named, not corrected).
    pub fn text_saying(&self, consequence: &str) -> String {
        let what = if self.corrected {
            format!("corrected ({:.2e} deg over the survey's {:.2} h)", self.over_survey_deg, self.duration_h)
        } else {
            "within its noise, not corrected".to_string()
        };
        let left = if self.left_significant {
            format!(
                "; NOT A STRAIGHT LINE: the passes differ beyond their noise (chi-square {:.1} a degree of freedom, \
                 p = {:.1e}), up to {:.2e} deg a pass that no correction takes: {consequence}",
                self.left_f, self.left_p, self.left_deg
            )
        } else {
            String::new()
        };
        format!(
            "drift in time (the same targets read at different times): {:+.2e} +/- {:.1e} deg/h, {what}{left}\n",
            self.slope_deg_per_h, self.slope_se_deg_per_h
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 120 targets, `runs` runs both ways, one reading a second; `ramp`
    /// deg per run growing in time; `step` deg added from run 2 on; noise
    /// `sigma`.
    fn survey(runs: u32, ramp: f64, step: f64, sigma: f64, seed: u64) -> Vec<Sample> {
        survey_processing::analysis::testutil::timed_survey(120, runs, sigma, seed, |t, run| {
            ramp * t / 240.0 + if run >= 2 { step } else { 0.0 }
        })
    }

    /// The ramp: 0.004 deg a run, growing within the runs, 3 runs.
    /// Measured and corrected to within 3 standard errors; the corrected
    /// survey's mean reversal is the true backlash (0.008) again.
    #[test]
    fn a_ramp_within_the_runs_is_measured_and_corrected() {
        for seed in 0..5 {
            let s = survey(3, 0.004, 0.0, 0.0005, seed);
            let d = estimate(&s).unwrap();
            let truth = 0.004 / 240.0 * 3600.0;
            assert!(d.corrected && (d.slope_deg_per_h - truth).abs() < 3.0 * d.slope_se_deg_per_h, "{d:?}");
            assert!(!d.left_significant, "a straight line leaves nothing: {d:?}");
            let c = corrected(&s, &d);
            let reversal = |s: &[Sample]| {
                let f: f64 = s.iter().filter(|x| x.direction == Direction::Forward).map(Sample::error_deg).sum();
                let r: f64 = s.iter().filter(|x| x.direction == Direction::Reverse).map(Sample::error_deg).sum();
                (f - r) / (s.len() / 2) as f64
            };
            assert!((reversal(&s) - 0.008).abs() > 0.0015, "the ramp moved the reversal: {}", reversal(&s));
            assert!((reversal(&c) - 0.008).abs() < 1e-4, "corrected: {}", reversal(&c));
        }
    }

    /// No drift: corrected, or called no straight line, in at most a few of
    /// 200 surveys each (1 % stated: 2 expected, 4.5 Poisson sigma allow 8).
    #[test]
    fn no_drift_is_corrected_at_the_rate() {
        let found: Vec<TimeDrift> =
            (0..200).map(|seed| estimate(&survey(3, 0.0, 0.0, 0.0005, seed)).unwrap()).collect();
        let corrected = found.iter().filter(|d| d.corrected).count();
        let crooked = found.iter().filter(|d| d.left_significant).count();
        eprintln!("of 200 drift-free surveys {corrected} corrected, {crooked} not a straight line");
        assert!(corrected <= 8 && crooked <= 8, "{corrected}, {crooked} of 200");
        // Not a result at 1 in 1000: 0.2 expected, at most 2 allowed.
        let beyond = found.iter().filter(|d| d.left_beyond_doubt).count();
        assert!(beyond <= 2, "{beyond} of 200 beyond doubt");
    }

    /// Over 300 drift-free surveys the cells' correction error `(b - 0)
    /// (t_cell - mid)` has the rms `table_u_deg` states, within 15 % (300
    /// draws: the rms of their squares is known to about 8 % at 1 sigma).
    #[test]
    fn the_slopes_uncertainty_in_the_table_is_what_the_draws_show() {
        let (mut sq, mut stated) = (0.0, 0.0);
        for seed in 0..300 {
            let s = survey(3, 0.0, 0.0, 0.0005, seed);
            let d = estimate(&s).unwrap();
            let (b, t) = (d.slope_deg_per_h / 3600.0, cell_times(&s));
            sq += t.iter().map(|t| (b * (t - d.mid_s)).powi(2)).sum::<f64>() / t.len() as f64;
            stated += d.table_u_deg(&s).powi(2);
        }
        let ratio = (sq / stated).sqrt();
        assert!((ratio - 1.0).abs() < 0.15, "the correction's error in the table is {ratio:.3} of its stated u");
    }

    /// A survey of `runs` runs, a polygon turned between them on a stage
    /// (two turns, alternating): each turn puts 0.003 deg into its runs, and
    /// the stage lands each run within 0.0003 deg (standard deviation) of
    /// its turn's; 0.0005 deg of noise a reading; `ramp` deg a run.
    fn turned(runs: u32, ramp: f64, seed: u64) -> (Vec<Sample>, Vec<usize>) {
        let landing: Vec<f64> = (0..=runs)
            .map(|r| {
                // A deterministic normal-ish draw (the sum of three uniforms).
                let mut x = seed
                    .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                    .wrapping_add(u64::from(r).wrapping_mul(0xBF58_476D_1CE4_E5B9));
                let mut u = || {
                    x ^= x >> 31;
                    x = x.wrapping_mul(0x94D0_49BB_1331_11EB);
                    x ^= x >> 29;
                    (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5
                };
                (u() + u() + u()) * 2.0 * 0.0003
            })
            .collect();
        let turn = |run: u32| (run as usize - 1) % 2;
        let s = survey_processing::analysis::testutil::timed_survey(120, runs, 0.0005, seed, |t, run| {
            ramp * t / 240.0 + 0.003 * turn(run) as f64 + landing[run as usize]
        });
        let class = s.iter().map(|x| turn(x.run)).collect();
        (s, class)
    }

    /// Turned, no drift (issue 48: the turns read as a drift and the
    /// survey as no result): corrected, or called no straight line, in at
    /// most a few of 200 surveys (1 % stated: 2 expected, 4.5 Poisson sigma
    /// allow 8); the estimate that ignores the turns calls most of them a
    /// drift (the test can fail).
    #[test]
    fn turns_and_a_stage_that_lands_differently_are_not_a_drift() {
        let (mut corrected, mut crooked, mut beyond, mut fooled) = (0, 0, 0, 0);
        for seed in 0..200 {
            let (s, class) = turned(6, 0.0, seed);
            let d = estimate_between_placements(&s, &class).unwrap();
            corrected += usize::from(d.corrected);
            crooked += usize::from(d.left_significant);
            beyond += usize::from(d.left_beyond_doubt);
            let naive = estimate(&s).unwrap();
            fooled += usize::from(naive.corrected || naive.left_beyond_doubt);
        }
        eprintln!(
            "of 200 turned drift-free surveys {corrected} corrected, {crooked} not a straight line, {beyond} beyond doubt; ignoring the turns {fooled}"
        );
        assert!(corrected <= 8 && crooked <= 8 && beyond <= 2, "{corrected}, {crooked}, {beyond} of 200");
        assert!(fooled >= 150, "ignoring the turns, {fooled} of 200 fooled");
    }

    /// Turned, with the ramp (0.004 deg a run, 6 runs in 2 turns:
    /// 3 degrees of freedom against the landing): found in every one of 20
    /// surveys, each within Student's 1-in-1000 point (3 degrees of freedom:
    /// 12.9) of its standard error from the truth, so that 20 surveys fail
    /// by chance 2 % of the time at most; corrected, a straight line is left.
    #[test]
    fn a_drift_with_turns_is_still_found() {
        for seed in 0..20 {
            let (s, class) = turned(6, 0.004, seed);
            let d = estimate_between_placements(&s, &class).unwrap();
            let truth = 0.004 / 240.0 * 3600.0;
            assert!(d.corrected, "seed {seed}: {d:?}");
            let t = survey_processing::special::student_two_sided_isf(1e-3, 3);
            assert!((d.slope_deg_per_h - truth).abs() < t * d.slope_se_deg_per_h, "seed {seed}: {d:?}");
            assert!(!d.left_beyond_doubt, "seed {seed}: {d:?}");
        }
        // Two turns in four runs leave one degree of freedom; two runs, none.
        assert!(estimate_between_placements(&turned(4, 0.0, 1).0, &turned(4, 0.0, 1).1).is_some());
        assert!(estimate_between_placements(&turned(2, 0.0, 1).0, &turned(2, 0.0, 1).1).is_none());
    }

    /// A step between runs is no straight line: said, with its size.
    #[test]
    fn a_step_is_not_a_straight_line_and_says_so() {
        let d = estimate(&survey(3, 0.0, 0.004, 0.0005, 1)).unwrap();
        assert!(d.left_significant && d.text().contains("NOT A STRAIGHT LINE"), "{d:?}");
        // 0.004 deg against 0.0005 of noise: beyond doubt, the table not a result.
        assert!(d.left_beyond_doubt && d.left_p < 1e-6 && d.text().contains("is not a result"), "{d:?}");
    }
}
