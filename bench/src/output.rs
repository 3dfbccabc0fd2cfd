//! What a command prints: one JSON document (`--json`) or text, and the
//! pieces several commands share (the ISO 230-2 figures, durations, the
//! time budget of an acquisition, fault rates). Errors in text are printed
//! in the unit the user chose ([`Units`], the command line's `--units`:
//! `units.fixed(deg, 6)` in a table's column, `units.show(deg)` in a
//! sentence, `units.text(sentence)` for the processing's sentences); JSON
//! documents stay in degrees.

/// A line for people on stderr, as `eprintln!` writes it, but a stderr
/// that went away (a log pipe closed, `2>&1 | head -c1`) loses the line and
/// nothing else: `eprintln!` panics there, and a panic would leave a survey
/// `running` with nothing measured. Every note, warning and error line of
/// the commands goes through it.
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

use std::fmt::Write as _;
use std::time::Duration;
use survey_plan::budget::{Bound, Component, Spent};
use survey_processing::iso230::Iso230;
use survey_processing::num::Num;
pub use survey_processing::units::Units;
use survey_sims::faults::{FaultKind, FaultRates};

/// A command's result for the user: the JSON document and the text, built
/// together so they never disagree; the command prints one of them.
#[derive(Debug, Clone, PartialEq)]
pub struct Output {
    /// The `--json` document.
    pub doc: serde_json::Value,
    /// The text.
    pub text: String,
}

impl Output {
    /// The document or the text, with a final newline.
    pub fn render(&self, json: bool) -> String {
        if json { format!("{}\n", self.doc) } else { self.text.clone() }
    }
}

/// The `stats --json` document: the contract's keys, plus per-target figures.
pub fn iso_json(survey_id: i64, iso: &Iso230) -> serde_json::Value {
    let targets = serde_json::to_value(&iso.targets).expect("statistics serialise");
    serde_json::json!({ "survey_id": survey_id, "iso230_2": iso_figures_json(iso), "targets": targets })
}

/// The axis figures of `iso` as [`iso_json`] gives them under `"iso230_2"`,
/// without serialising the per-target figures (a map per target: most of the
/// time of `survey process` on a large survey when they were made and
/// thrown away).
pub fn iso_figures_json(iso: &Iso230) -> serde_json::Value {
    let figures = Iso230 { targets: Vec::new(), ..*iso };
    let mut doc = serde_json::to_value(figures).expect("statistics serialise");
    doc.as_object_mut().map(|o| o.remove("targets"));
    doc
}

/// A figure in a column of a text table: `units`, to a millionth of a degree's resolution.
fn fmt_opt(v: Option<f64>, units: Units) -> String {
    v.map(|x| format!("{:>10}", units.fixed(x, 6))).unwrap_or_else(|| format!("{:>10}", "-"))
}

/// The ISO 230-2 figures as a small table, in `units`.
pub fn iso_text(survey_id: i64, iso: &Iso230, units: Units) -> String {
    let bidirectional = iso.b.is_some();
    let mut s = format!(
        "survey {survey_id}: ISO 230-2, {} targets x {} runs, {} ({})\n",
        iso.target_count,
        iso.runs,
        if bidirectional { "bidirectional" } else { "unidirectional" },
        units.name()
    );
    let (fmt_opt, unit) = (|v| fmt_opt(v, units), units.symbol());
    let _ = writeln!(s, "  {:<28}{:>10} {:>10} {:>10}", "", "axis", "forward", "reverse");
    let rows = [
        ("A  accuracy", Some(iso.a), iso.a_up, iso.a_down),
        ("R  repeatability", Some(iso.r), iso.r_up, iso.r_down),
        ("E  systematic deviation", Some(iso.e), iso.e_up, iso.e_down),
    ];
    for (name, all, up, down) in rows {
        let _ = writeln!(s, "  {name:<28}{} {} {} {unit}", fmt_opt(all), fmt_opt(up), fmt_opt(down));
    }
    if bidirectional {
        let _ = writeln!(s, "  {:<28}{} {unit}", "B  reversal value", fmt_opt(iso.b));
        let _ = writeln!(s, "  {:<28}{} {unit}", "B  mean reversal", fmt_opt(iso.b_mean));
        let _ = writeln!(s, "  {:<28}{} {unit}", "M  mean bidirectional dev.", fmt_opt(iso.m));
    }
    s
}

/// Fault rates as a person reads them (and as `--fault-rates` takes them):
/// `timeout=0.0025, device=0.01, beam_hold_s=5`, the kinds injected only,
/// or `none`.
pub fn fault_rates(rates: &FaultRates) -> String {
    let mut items: Vec<String> = FaultKind::ALL
        .into_iter()
        .filter(|k| rates.rate(*k) > 0.0)
        .map(|k| format!("{}={}", k.name(), rates.rate(k)))
        .collect();
    if rates.beam_hold_s > 0.0 {
        items.push(format!("beam_hold_s={}", rates.beam_hold_s));
    }
    if items.is_empty() { "none".into() } else { items.join(", ") }
}

/// `3h 12m`, `4m 05s`, `12.3 s`.
pub fn human(d: Duration) -> String {
    let s = d.as_secs();
    if s >= 3600 {
        format!("{}h {:02}m", s / 3600, (s % 3600) / 60)
    } else if s >= 60 {
        format!("{}m {:02}s", s / 60, s % 60)
    } else {
        format!("{:.1} s", d.as_secs_f64())
    }
}

/// The survey's time beside its bound, per component: what `survey run` reports.
#[derive(Debug, Clone, PartialEq)]
pub struct Budget {
    /// The survey's duration on the instruments' clock, seconds.
    pub instrument_time_s: f64,
    /// Its plan's lower bound.
    pub bound: Bound,
    /// Where the time went (the acquisitions of this survey that were
    /// accounted), on the instruments' clock.
    pub spent: Spent,
    /// The settling observed after measured moves: how many, mean and
    /// largest time from the profile's end until within the window, seconds
    /// on the instruments' clock.
    pub settle_observed: Option<(u64, f64, f64)>,
    /// How far apart the settling reads are on the instruments' clock,
    /// seconds: a shorter settling is not seen.
    pub settle_poll_s: f64,
    /// The scan mode (`step` or `continuous`).
    pub scan: &'static str,
    /// A continuous scan: the positioner's maximum velocity (the configured
    /// one), deg/s, and the plan's bound at it without the latency's
    /// calibration passes, seconds.
    pub at_max_velocity: Option<(f64, f64)>,
    /// How many times faster than real time the instruments' clock ran (a
    /// rehearsal on `survey sim --time-scale X`; 1 on real instruments).
    pub time_scale: f64,
}

impl Budget {
    /// The `time_budget` document of `run --json`.
    pub fn json(&self) -> serde_json::Value {
        let unaccounted = self.instrument_time_s - self.spent.total();
        let mut components: Vec<serde_json::Value> = Component::ALL
            .into_iter()
            .filter(|c| self.spent.get(*c) != 0.0 || self.bound.of(*c) != 0.0)
            .map(|c| serde_json::json!({"component": c.as_str(), "time_s": self.spent.get(c), "bound_s": self.bound.of(c)}))
            .collect();
        if unaccounted.abs() > 1e-6 {
            components.push(serde_json::json!({"component": "unaccounted", "time_s": unaccounted, "bound_s": 0.0}));
        }
        let total = self.bound.total();
        serde_json::json!({
            "scan": self.scan,
            "time_scale": self.time_scale,
            "instrument_time_s": self.instrument_time_s,
            "bound_s": total,
            "ratio": if total > 0.0 { self.instrument_time_s / total } else { f64::NAN },
            "components": components,
            "settle_observed": self.settle_observed.map(|(n, mean, max)| serde_json::json!({
                "moves": n, "mean_s": mean, "max_s": max,
            })),
        })
    }

    /// The lines of the text summary.
    pub fn text(&self) -> String {
        let total = self.bound.total();
        let mut s = format!(
            "instrument time {} ({:.0} s{}) against a bound of {} ({:.0} s) for this plan ({}): {:.3} x\n",
            human(Duration::from_secs_f64(self.instrument_time_s.max(0.0))),
            self.instrument_time_s,
            if self.time_scale == 1.0 {
                String::new()
            } else {
                format!(" on the instruments' clock at {}x real time", self.time_scale)
            },
            human(Duration::from_secs_f64(total.max(0.0))),
            total,
            self.scan,
            if total > 0.0 { self.instrument_time_s / total } else { f64::NAN },
        );
        if let Some((v, bound)) = self.at_max_velocity {
            let _ = writeln!(
                s,
                "  at the positioner's maximum velocity ({} deg/s) without the latency's calibration passes, the bound \
                 is {} ({bound:.0} s): {:.3} x",
                Num(v),
                human(Duration::from_secs_f64(bound.max(0.0))),
                if bound > 0.0 { self.instrument_time_s / bound } else { f64::NAN },
            );
        }
        let _ = writeln!(s, "  {:<18}{:>12} {:>12}", "component", "time s", "bound s");
        for c in Component::ALL {
            let (t, b) = (self.spent.get(c), self.bound.of(c));
            if t != 0.0 || b != 0.0 {
                let _ = writeln!(s, "  {:<18}{t:>12.1} {b:>12.1}", c.as_str());
            }
        }
        let unaccounted = self.instrument_time_s - self.spent.total();
        if unaccounted.abs() > 0.05 {
            let _ = writeln!(s, "  {:<18}{unaccounted:>12.1} {:>12}", "unaccounted", "");
        }
        if total > 0.0 && self.instrument_time_s < 0.9 * total && self.time_scale == 1.0 {
            let _ = writeln!(
                s,
                "  below the bound: these instruments run faster than the hardware the bound assumes (a rehearsal on \
                 `survey sim --time-scale X`? `time_scale = X` in the configuration's [timing] reports on their clock)"
            );
        }
        if let Some((n, mean, max)) = self.settle_observed {
            let _ =
                writeln!(s, "  settling seen after {n} moves: mean {:.0} ms, largest {:.0} ms", mean * 1e3, max * 1e3);
            if self.time_scale != 1.0 {
                let _ = writeln!(
                    s,
                    "  (read every {:.0} ms on the instruments' clock: a shorter settling is not seen)",
                    self.settle_poll_s * 1e3
                );
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fault_rates_read_as_the_flag_takes_them() {
        assert_eq!(fault_rates(&FaultRates::default()), "none");
        let rates = FaultRates::uniform(0.01).parse_over("beam=0,beam_hold_s=5").unwrap();
        assert_eq!(
            fault_rates(&rates),
            "timeout=0.0025, garbled=0.0025, disconnect=0.0025, stall=0.0025, device=0.01, move=0.01, beam_hold_s=5"
        );
    }

    #[test]
    fn durations_read_as_people_say_them() {
        assert_eq!(human(Duration::from_secs(36352)), "10h 05m");
        assert_eq!(human(Duration::from_secs(245)), "4m 05s");
        assert_eq!(human(Duration::from_millis(12_340)), "12.3 s");
    }
}
