//! The model-gap findings as text: the gap before, the steps as a table, what
//! was added and adjusted, and the gap after.

use super::explain::num;
use super::{ModelGap, Views};
use std::fmt::Write as _;

impl ModelGap {
    /// The report as text (what `survey model-gap` prints without `--json`).
    pub fn to_text(&self) -> String {
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
            "noise floor {:.3e} deg (standard deviation of one sample, {}{})",
            self.noise_floor_deg,
            if self.noise.method == "run_cell_interaction" {
                "scatter from run to run"
            } else {
                "from the spectrum of the one run"
            },
            self.noise.dof.map(|d| format!(", {d} degrees of freedom")).unwrap_or_default()
        );
        let _ = writeln!(s, "significance: {}", self.significance.statement);
        let d = &self.detection_limits;
        let _ = writeln!(
            s,
            "found with probability 99.9 % from: periodic {:.2e} deg{}{}",
            d.periodic_deg,
            d.backlash_deg.map(|b| format!(", backlash {b:.2e} deg")).unwrap_or_default(),
            d.drift_deg_per_run.map(|b| format!(", drift {b:.2e} deg per run")).unwrap_or_default()
        );
        let _ = writeln!(s, "\nthe gap with the model given:");
        views_text(&mut s, &self.before, self.noise_floor_deg);

        let _ = writeln!(s, "\nsteps (each effect fitted by least squares, the model simulated again):");
        let _ = writeln!(
            s,
            "  {:>4}  {:<52} {:>14} {:>12} {:>12}",
            "step", "change", "amplitude_deg", "rms_deg", "peak_deg"
        );
        let _ = writeln!(
            s,
            "  {:>4}  {:<52} {:>14} {:>12.3e} {:>12.3e}",
            0,
            "the model as given",
            "",
            self.rms_before_deg,
            self.before.angle.mean_peak_deg.abs()
        );
        for st in &self.steps {
            let _ = writeln!(
                s,
                "  {:>4}  {:<52} {:>14.3e} {:>12.3e} {:>12.3e}",
                st.step, st.added, st.amplitude_deg, st.rms_deg, st.mean_peak_deg
            );
        }
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
                    "  {}{at}: {:.3e} +/- {:.1e} deg{unit}{phase}: {}",
                    f.kind, f.amplitude_deg, f.standard_error_deg, f.explanation
                );
            }
        }
        if !self.effects_adjusted.is_empty() {
            let _ = writeln!(s, "\neffects adjusted:");
            for f in &self.effects_adjusted {
                let _ = writeln!(s, "  {}", f.explanation);
            }
        }
        let _ = writeln!(s, "\nthe gap with the improved model:");
        views_text(&mut s, &self.after, self.noise_floor_deg);
        let _ = writeln!(
            s,
            "residual rms {:.3e} -> {:.3e} deg (noise floor {:.3e} deg); zero-reference offset {:+.3e} deg",
            self.rms_before_deg, self.rms_after_deg, self.noise_floor_deg, self.offset_deg
        );
        let _ = writeln!(s, "verdict: {}", self.verdict.statement);
        for n in &self.notes {
            let _ = writeln!(s, "note: {n}");
        }
        s
    }
}

fn views_text(s: &mut String, v: &Views, floor: f64) {
    let _ = writeln!(
        s,
        "  residual rms {:.3e} deg over all samples ({:.2} x the noise floor)",
        v.rms_deg,
        v.rms_deg / floor.max(f64::MIN_POSITIVE)
    );
    let a = &v.angle;
    if a.ranges_total == 0 {
        let _ = writeln!(
            s,
            "  in angle:     every target's mean residual inside +/-{:.2e} deg (largest {:+.2e} deg at {} deg)",
            a.band_deg,
            a.mean_peak_deg,
            num(a.peak_at_deg)
        );
    } else {
        let shown: Vec<String> = a
            .ranges
            .iter()
            .take(6)
            .map(|r| {
                format!(
                    "{}..{} deg (peak {:+.2e} deg at {} deg)",
                    num(r.start_deg),
                    num(r.end_deg),
                    r.peak_deg,
                    num(r.at_deg)
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "  in angle:     {} targets in {} ranges leave +/-{:.2e} deg: {}{}",
            a.targets_outside,
            a.ranges_total,
            a.band_deg,
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
            format!("{at} cycles/rev {:.2e} deg {}", l.amplitude_deg, l.kind)
        })
        .collect();
    if significant.is_empty() {
        let _ = writeln!(s, "  in frequency: no line above {:.2e} deg", f.threshold_deg);
    } else {
        let more = f.lines.iter().filter(|l| l.coherent).count() - significant.len();
        let _ = writeln!(
            s,
            "  in frequency: above {:.2e} deg: {}{}",
            f.threshold_deg,
            significant.join("; "),
            if more > 0 { format!("; and {more} more") } else { String::new() }
        );
    }
    match &v.direction {
        Some(d) => {
            let _ = writeln!(
                s,
                "  by direction: forward - reverse {:+.2e} deg; backlash change {:+.2e} +/- {:.1e} deg: {}",
                d.forward_minus_reverse_deg,
                d.backlash_change_deg,
                d.standard_error_deg,
                if d.significant {
                    format!("significant (above {:.2e} deg)", d.threshold_deg)
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
                "  in time:      trend {:+.2e} +/- {:.1e} deg per run over {} runs: {}",
                t.drift_change_deg_per_run,
                t.standard_error_deg_per_run,
                t.run_means.len(),
                if t.significant {
                    format!("significant (above {:.2e} deg per run)", t.threshold_deg_per_run)
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
