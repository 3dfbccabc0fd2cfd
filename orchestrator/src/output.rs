//! What a command prints: one JSON document (`--json`) or text, and the
//! pieces several commands share (the ISO 230-2 figures, durations).

use std::fmt::Write as _;
use std::time::Duration;
use survey_processing::iso230::Iso230;

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
    let mut figures = serde_json::to_value(iso).expect("statistics serialise");
    let targets = figures.as_object_mut().and_then(|o| o.remove("targets")).unwrap_or_default();
    serde_json::json!({ "survey_id": survey_id, "iso230_2": figures, "targets": targets })
}

fn fmt_opt(v: Option<f64>) -> String {
    v.map(|x| format!("{x:>10.6}")).unwrap_or_else(|| format!("{:>10}", "-"))
}

/// The ISO 230-2 figures as a small table, degrees.
pub fn iso_text(survey_id: i64, iso: &Iso230) -> String {
    let bidirectional = iso.b.is_some();
    let mut s = format!(
        "survey {survey_id}: ISO 230-2, {} targets x {} runs, {} (degrees)\n",
        iso.targets.len(),
        iso.runs,
        if bidirectional { "bidirectional" } else { "unidirectional" }
    );
    let _ = writeln!(s, "  {:<28}{:>10} {:>10} {:>10}", "", "axis", "forward", "reverse");
    let rows = [
        ("A  accuracy", Some(iso.a), iso.a_up, iso.a_down),
        ("R  repeatability", Some(iso.r), iso.r_up, iso.r_down),
        ("E  systematic deviation", Some(iso.e), iso.e_up, iso.e_down),
    ];
    for (name, all, up, down) in rows {
        let _ = writeln!(s, "  {name:<28}{} {} {} deg", fmt_opt(all), fmt_opt(up), fmt_opt(down));
    }
    if bidirectional {
        let _ = writeln!(s, "  {:<28}{} deg", "B  reversal value", fmt_opt(iso.b));
        let _ = writeln!(s, "  {:<28}{} deg", "B  mean reversal", fmt_opt(iso.b_mean));
        let _ = writeln!(s, "  {:<28}{} deg", "M  mean bidirectional dev.", fmt_opt(iso.m));
    }
    s
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_read_as_people_say_them() {
        assert_eq!(human(Duration::from_secs(36352)), "10h 05m");
        assert_eq!(human(Duration::from_secs(245)), "4m 05s");
        assert_eq!(human(Duration::from_millis(12_340)), "12.3 s");
    }
}
