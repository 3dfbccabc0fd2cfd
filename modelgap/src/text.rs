//! The model-gap findings as text: the gap before, the steps as a table, what
//! was added and adjusted, and the gap after.

use super::explain::num;
use super::{ModelGap, Views};
use std::fmt::Write as _;
use survey_processing::units::Units;

impl ModelGap {
    /// The report as text, in degrees.
    pub fn to_text(&self) -> String {
        self.to_text_in(Units::Deg)
    }

    /// The report as text with its errors in `units` (what `survey
    /// model-gap` prints without `--json`); angles along the axis and
    /// phases stay in degrees.
    pub fn to_text_in(&self, units: Units) -> String {
        let (u, e) = (units.symbol(), |deg: f64, digits: usize| units.small(deg, digits, false));
        let mut s = String::new();
        let sh = &self.survey;
        let _ = writeln!(
            s,
            "model-gap: {} targets x {} runs, {}, {} ({} points/rev); drift time from {}",
            sh.targets,
            sh.runs,
            if sh.bidirectional { "bidirectional" } else { "one direction" },
            if sh.full_circle { "full circle" } else { "partial range" },
            num(sh.points_per_rev),
            match (sh.timebase, sh.run_duration_s) {
                (super::Timebase::Timestamps, Some(d)) => format!("the timestamps (one run = {d:.1} s)"),
                _ => "the acquisition order".to_string(),
            }
        );
        let _ = writeln!(
            s,
            "noise floor {} {u} (standard deviation of one sample, {}{})",
            e(self.noise_floor_deg, 3),
            if self.noise.method == "run_cell_interaction" {
                "scatter from run to run"
            } else {
                "from the spectrum of the one run"
            },
            self.noise.dof.map(|d| format!(", {d} degrees of freedom")).unwrap_or_default()
        );
        let _ = writeln!(s, "significance: {}", units.text(&self.significance.statement));
        let d = &self.detection_limits;
        let _ = writeln!(
            s,
            "found with probability 99.9 % from: periodic {} {u}{}{}",
            e(d.periodic_deg, 2),
            d.backlash_deg.map(|b| format!(", backlash {} {u}", e(b, 2))).unwrap_or_default(),
            d.drift_deg_per_run.map(|b| format!(", drift {} {u} per run", e(b, 2))).unwrap_or_default()
        );
        let _ = writeln!(s, "\nthe gap with the model given:");
        views_text(&mut s, &self.before, self.noise_floor_deg, units);

        let _ = writeln!(s, "\nsteps (each effect fitted by least squares, the model simulated again), {u}:");
        // Two residual figures of different things: every sample's scatter
        // is in the RMS, a target's mean over its runs averages it out.
        let _ = writeln!(
            s,
            "  {:>4}  {:<52} {:>14}  {:>14}  {:>16}",
            "", "", "amplitude", "residual RMS", "largest residual"
        );
        let _ = writeln!(
            s,
            "  {:>4}  {:<52} {:>14}  {:>14}  {:>16}",
            "step", "change", "of the effect", "of all samples", "of a target mean"
        );
        let _ = writeln!(
            s,
            "  {:>4}  {:<52} {:>14}  {:>14}  {:>16}",
            0,
            "the model as given",
            "",
            e(self.rms_before_deg, 3),
            e(self.before.angle.mean_peak_deg.abs(), 3)
        );
        for st in &self.steps {
            let _ = writeln!(
                s,
                "  {:>4}  {:<52} {:>14}  {:>14}  {:>16}",
                st.step,
                st.added,
                e(st.amplitude_deg, 3),
                e(st.rms_deg, 3),
                e(st.mean_peak_deg, 3)
            );
        }
        let _ = writeln!(
            s,
            "  (residual RMS: over every sample, its noise included; largest residual of a target mean: the \
             residual averaged over a target's runs and directions, largest in magnitude over the targets: the \
             noise averages out, so it can be below the RMS)"
        );
        if self.effects_added.is_empty() && self.verdict.explained && self.verdict.reference.is_empty() {
            let _ = writeln!(s, "\neffects added: none (the model explains the data down to the noise floor)");
        } else if self.effects_added.is_empty() {
            let _ = writeln!(s, "\neffects added: none (see the verdict)");
        } else {
            let _ = writeln!(s, "\neffects added:");
            for f in &self.effects_added {
                let phase = f.phase_deg.map(|p| format!(" at phase {p:.1} deg")).unwrap_or_default();
                let unit = if f.kind == "drift" { " per run" } else { "" };
                let at = if f.cycles_per_rev > 0.0 {
                    format!(" {} cycles/rev", num(f.cycles_per_rev))
                } else {
                    String::new()
                };
                let _ = writeln!(
                    s,
                    "  {}{at}: {} +/- {} {u}{unit}{phase}: {}",
                    f.kind,
                    e(f.amplitude_deg, 3),
                    e(f.standard_error_deg, 1),
                    units.text(&f.explanation)
                );
            }
        }
        if !self.effects_adjusted.is_empty() {
            let _ = writeln!(s, "\neffects adjusted:");
            for f in &self.effects_adjusted {
                let _ = writeln!(s, "  {}", units.text(&f.explanation));
            }
        }
        let _ = writeln!(s, "\nthe gap with the improved model:");
        views_text(&mut s, &self.after, self.noise_floor_deg, units);
        let _ = writeln!(
            s,
            "residual rms {} -> {} {u} (noise floor {} {u}); zero-reference offset {} {u}",
            e(self.rms_before_deg, 3),
            e(self.rms_after_deg, 3),
            e(self.noise_floor_deg, 3),
            units.small(self.offset_deg, 3, true)
        );
        let _ = writeln!(s, "verdict: {}", units.text(&self.verdict.statement));
        for n in &self.notes {
            let _ = writeln!(s, "note: {}", units.text(n));
        }
        s
    }
}

fn views_text(s: &mut String, v: &Views, floor: f64, units: Units) {
    let u = units.symbol();
    let e = |deg: f64, digits: usize| units.small(deg, digits, false);
    let signed = |deg: f64| units.small(deg, 2, true);
    let _ = writeln!(
        s,
        "  residual rms {} {u} over all samples ({:.2} x the noise floor)",
        e(v.rms_deg, 3),
        v.rms_deg / floor.max(f64::MIN_POSITIVE)
    );
    let a = &v.angle;
    if a.ranges_total == 0 {
        let _ = writeln!(
            s,
            "  in angle:     every target's mean residual inside +/-{} {u} (largest {} {u} at {} deg)",
            e(a.band_deg, 2),
            signed(a.mean_peak_deg),
            num(a.peak_at_deg)
        );
    } else {
        let shown: Vec<String> = a
            .ranges
            .iter()
            .take(6)
            .map(|r| {
                format!(
                    "{}..{} deg (peak {} {u} at {} deg)",
                    num(r.start_deg),
                    num(r.end_deg),
                    signed(r.peak_deg),
                    num(r.at_deg)
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "  in angle:     {} targets in {} ranges leave +/-{} {u}: {}{}",
            a.targets_outside,
            a.ranges_total,
            e(a.band_deg, 2),
            shown.join(", "),
            if a.ranges_total > shown.len() { ", ..." } else { "" }
        );
    }
    let f = &v.frequency;
    let significant: Vec<String> = f
        .lines
        .iter()
        .filter(|l| l.coherent)
        .take(8)
        .map(|l| {
            let at = if l.aliased {
                format!("{} (seen at {})", num(l.cycles_per_rev), num(l.observed_cycles_per_rev))
            } else {
                num(l.cycles_per_rev)
            };
            format!("{at} cycles/rev {} {u} {}", e(l.amplitude_deg, 2), l.kind)
        })
        .collect();
    if significant.is_empty() {
        let _ = writeln!(s, "  in frequency: no line above {} {u}", e(f.threshold_deg, 2));
    } else {
        let more = f.lines.iter().filter(|l| l.coherent).count() - significant.len();
        let _ = writeln!(
            s,
            "  in frequency: above {} {u}: {}{}",
            e(f.threshold_deg, 2),
            significant.join("; "),
            if more > 0 { format!("; and {more} more") } else { String::new() }
        );
    }
    match &v.direction {
        Some(d) => {
            let _ = writeln!(
                s,
                "  by direction: forward - reverse {} {u}; backlash change {} +/- {} {u}: {}",
                signed(d.forward_minus_reverse_deg),
                signed(d.backlash_change_deg),
                e(d.standard_error_deg, 1),
                if d.significant {
                    format!("significant (above {} {u})", e(d.threshold_deg, 2))
                } else {
                    "not significant".into()
                }
            );
        }
        None => {
            let _ = writeln!(s, "  by direction: one direction measured");
        }
    }
    match &v.time {
        Some(t) => {
            let _ = writeln!(
                s,
                "  in time:      trend {} +/- {} {u} per run over {} runs: {}",
                signed(t.drift_change_deg_per_run),
                e(t.standard_error_deg_per_run, 1),
                t.run_means.len(),
                if t.significant {
                    format!("significant (above {} {u} per run)", e(t.threshold_deg_per_run, 2))
                } else {
                    "not significant".into()
                }
            );
        }
        None => {
            let _ = writeln!(s, "  in time:      one run");
        }
    }
}
