//! The `survey process` JSON document and the summary for people.
//!
//! The JSON holds the contract's keys (`survey_id`; `peaks` with
//! `cycles_per_rev`, `amplitude_deg`, `source`, `repeatable`; `aliases` with
//! `observed_cycles`, `true_cycles`, `action` = `relocated` or `nulled`;
//! `table` with `path`, `points`, `directional`; `predicted` with
//! `native_peak_deg` and `corrected_peak_deg`) and more: each peak's true
//! frequency, phase, share and fate in the table; each alias' source and
//! reason; the table's method, kept lines, hysteresis test and direction
//! model (a directional full-circle table's forward - reverse); the predicted
//! RMS and ISO 230-2 `A`, the repeatability floor and the LinuxCNC file's
//! predicted peak; the Figure 6 interpolation comparison; the noise floor;
//! the points needed; the design and recipe used; every file written
//! (`files`), and `controllers`: per controller file written, its format,
//! paths, points, range, spacing, directions, modulo, reference, predicted
//! corrected peak, parameters (Fanuc) and notes.
//! `peaks` lists the significant lines of the survey; `cycles_per_rev` is
//! where the spectrum shows the line (the alias bin of an aliased line,
//! whose true frequency is `true_cycles_per_rev`).

use super::ProcessOutcome;
use serde_json::{Value, json};
use std::fmt::Write as _;
use survey_bench::output::Units;
use survey_controllers::export::{Controller, ControllerExport};
use survey_tables::correction::NotAResult;
use survey_tables::recipe::LineAction;

/// The controller files written (none when the table went to a device or a pipe).
fn written(o: &ProcessOutcome) -> impl Iterator<Item = (&ControllerExport, Vec<String>)> {
    o.processed.controllers.iter().filter_map(|c| {
        let files: Vec<String> =
            c.files.iter().filter_map(|f| o.files.of_kind(f.kind)).map(|p| p.display().to_string()).collect();
        (!files.is_empty()).then_some((c, files))
    })
}

fn controllers_json(o: &ProcessOutcome) -> Value {
    written(o)
        .map(|(c, files)| {
            json!({
                "controller": c.controller,
                "files": files,
                "points": c.grid.points,
                "start_deg": c.grid.start_deg,
                "end_deg": c.grid.end_deg(),
                "interval_deg": c.grid.interval_deg,
                "directional": c.directional,
                "modulo": c.modulo,
                "reference_deg": c.reference_deg,
                "zero_at_reference": c.zero_at_reference,
                "corrected_peak_deg": c.corrected_peak_deg,
                "parameters": c.parameters.iter().map(|(n, v, m)| json!({"number": n, "value": v, "meaning": m})).collect::<Vec<_>>(),
                "notes": c.notes,
            })
        })
        .collect()
}

fn path(p: &Option<std::path::PathBuf>) -> Value {
    p.as_ref().map_or(Value::Null, |p| Value::String(p.display().to_string()))
}

/// The JSON document (see the module documentation).
pub fn json(o: &ProcessOutcome) -> Value {
    let p = &o.processed;
    let a = &p.analysis;
    let peaks: Vec<Value> = a
        .lines
        .iter()
        .map(|l| {
            let d = p.decisions.lines.iter().find(|d| d.significant && d.cycles_per_rev == l.cycles_per_rev);
            json!({
                "cycles_per_rev": l.cycles_per_rev,
                "amplitude_deg": l.amplitude_deg,
                "source": l.source,
                "repeatable": l.repeatable,
                "true_cycles_per_rev": d.map_or(l.true_cycles_per_rev, |d| d.true_cycles_per_rev),
                "phase_deg": l.phase_deg,
                "share": l.share,
                "coherence": l.coherence,
                "kept": d.is_some_and(|d| matches!(d.action, LineAction::Kept | LineAction::Relocated)),
                "action": d.map(|d| d.action),
                "reason": d.map(|d| d.reason.clone()),
            })
        })
        .collect();
    let aliases: Vec<Value> = p
        .decisions
        .aliases
        .iter()
        .map(|x| {
            json!({
                "observed_cycles": x.observed_cycles,
                "true_cycles": x.true_cycles,
                "action": x.action,
                "applied": x.applied,
                "from_recipe": x.from_recipe,
                "recommended": x.recommended,
                "source": x.source,
                "reason": x.reason,
            })
        })
        .collect();
    let t = &p.built.table;
    let pr = &p.prediction;
    json!({
        "survey_id": o.survey_id,
        "peaks": peaks,
        "aliases": aliases,
        "table": {
            "path": o.files.table_csv.display().to_string(),
            "points": t.len(),
            "directional": t.is_directional(),
            "spacing_deg": t.spacing_deg(),
            "directional_reason": p.built.directional_reason,
            "hysteresis": p.built.hysteresis,
            "direction_model": p.built.direction_model,
            "method": p.built.method,
            "method_text": p.built.method.to_string(),
            "kept_cycles": p.decisions.kept_cycles,
            "null_bins": p.decisions.edit.null,
        },
        "predicted": {
            "native_peak_deg": pr.native_peak_deg,
            "corrected_peak_deg": pr.corrected_peak_deg,
            "native_rms_deg": pr.native.rms_deg,
            "corrected_rms_deg": pr.corrected.rms_deg,
            "native_iso230_a_deg": pr.native.iso230_a_deg,
            "corrected_iso230_a_deg": pr.corrected.iso230_a_deg,
            "floor_deg": p.floor.deg,
            "floor": p.floor.what,
            "linuxcnc_corrected_peak_deg": p.controllers.iter().find(|c| c.controller == Controller::LinuxCnc).and_then(|c| c.corrected_peak_deg),
            "samples": pr.samples,
            "in_sample_corrected_peak_deg": pr.in_sample_corrected_peak_deg,
            "unseen_between_targets_deg": pr.unseen_between_targets_deg,
            "peak_spread_deg": pr.peak_spread_deg,
            "no_better_than_native": pr.no_better_than_native(),
            "not_a_result": pr.not_a_result(),
            "uncorrected_drift_deg": pr.uncorrected_drift_deg,
        },
        "left": p.left,
        "interpolation": p.interpolation.as_ref().ok(),
        "noise": a.noise,
        "points_needed": a.points_needed,
        "runs": a.runs,
        "points_per_rev": a.points_per_rev,
        "design": o.design,
        "recipe": {
            "path": o.files.recipe.as_ref().map(|p| p.display().to_string()),
            "replayed": p.replayed,
            "from": path(&o.recipe_from),
            "lines_keep": p.recipe.lines.keep,
            "lines_remove": p.recipe.lines.remove,
        },
        "files": o.files,
        "controllers": controllers_json(o),
        "notes": a.notes.iter().chain(&p.notes).collect::<Vec<_>>(),
        "uncertainty": o.uncertainty,
    })
}

/// The human summary (see the module documentation): errors in `units`,
/// angles along the axis (ranges, spacings) in degrees. Its sections in
/// order: the heading, the peaks, the aliases, the interpolation
/// comparison, the table and its predicted accuracy, the controller files,
/// the points needed, the files written and the uncertainty budget.
pub fn text(o: &ProcessOutcome, units: Units) -> String {
    let e = Errors { units, u: units.symbol() };
    let mut s = String::new();
    heading(&mut s, o, e);
    peaks(&mut s, o, e);
    aliases(&mut s, o, e);
    interpolation(&mut s, o, e);
    table(&mut s, o, e);
    prediction(&mut s, o, e);
    controllers(&mut s, o, e);
    if let Some(n) = &o.processed.analysis.points_needed {
        let _ = writeln!(s, "points: {}", n.note);
    }
    files(&mut s, o);
    s += &units.text(&o.uncertainty.text());
    s
}

/// How the summary writes an error: in its units (`u` their symbol), to
/// 1e-5 deg, or to 1e-6 deg in a table's column; a small one in exponent
/// form.
#[derive(Debug, Clone, Copy)]
struct Errors {
    units: Units,
    u: &'static str,
}

impl Errors {
    /// To 1e-5 deg.
    fn e5(self, deg: f64) -> String {
        self.units.fixed(deg, 5)
    }

    /// To 1e-6 deg (a table's column).
    fn e6(self, deg: f64) -> String {
        self.units.fixed(deg, 6)
    }

    /// A small error (in degrees, in exponent form).
    fn small(self, deg: f64) -> String {
        self.units.small(deg, 2, false)
    }

    /// To 1e-5 deg, `-` when there is none.
    fn opt(self, deg: Option<f64>) -> String {
        deg.map_or_else(|| "-".to_string(), |d| self.e5(d))
    }
}

/// The survey processed (points, runs, design, recipe) and its noise: a
/// sample's, and the amplitude a line needs in the mean spectrum.
fn heading(s: &mut String, o: &ProcessOutcome, e: Errors) {
    let a = &o.processed.analysis;
    let u = e.u;
    let _ = writeln!(
        s,
        "survey {}: processing of {} points/rev x {} runs; design: {}; recipe: {}",
        o.survey_id,
        a.points_per_rev,
        a.runs,
        o.design.from,
        match &o.recipe_from {
            Some(r) => format!("replayed from {}", r.display()),
            None => "derived from this survey".to_string(),
        }
    );
    let _ = writeln!(
        s,
        "noise: {} {u} per sample; a line needs {} {u} in the mean spectrum",
        e.small(a.noise.sample_sd_deg),
        e.small(a.noise.coherent_threshold_deg)
    );
}

/// The significant lines, each with its amplitude, share, kind, fate in the
/// table and source; then the lines the recipe keeps that are not
/// significant, with the reason.
fn peaks(s: &mut String, o: &ProcessOutcome, e: Errors) {
    let p = &o.processed;
    let a = &p.analysis;
    let _ = writeln!(s, "\npeaks ({} significant):", a.lines.len());
    let amp = format!("amp {}", e.u);
    let _ = writeln!(s, "  {:>8} {:>10} {:>7}  {:<10} {:<10} source", "cyc/rev", amp, "share", "", "table");
    for l in &a.lines {
        let d = p.decisions.lines.iter().find(|d| d.significant && d.cycles_per_rev == l.cycles_per_rev);
        let fate = match d.map(|d| (d.action, d.true_cycles_per_rev)) {
            Some((LineAction::Relocated, f)) => format!("-> {f}"),
            Some((action, _)) => format!("{action:?}").to_lowercase(),
            None => "-".into(),
        };
        let _ = writeln!(
            s,
            "  {:>8} {:>10} {:>6.1}%  {:<10} {:<10} {}",
            l.cycles_per_rev,
            e.e6(l.amplitude_deg),
            100.0 * l.share,
            if l.repeatable { "repeatable" } else { "random" },
            fate,
            l.source
        );
    }
    for d in p.decisions.lines.iter().filter(|d| !d.significant) {
        let _ = writeln!(
            s,
            "  {:>8} {:>10} {:>7}  {:<10} {:<10} {}",
            d.cycles_per_rev,
            e.e6(d.amplitude_deg),
            "",
            "",
            "kept",
            e.units.text(&d.reason)
        );
    }
}

/// The aliases applied or given by the recipe (observed <- true frequency,
/// the action, the source and the reason), and how many aliased design
/// frequencies had no line at their bin.
fn aliases(s: &mut String, o: &ProcessOutcome, e: Errors) {
    let aliases = &o.processed.decisions.aliases;
    let applied: Vec<_> = aliases.iter().filter(|x| x.applied || x.from_recipe).collect();
    if !applied.is_empty() {
        let _ = writeln!(s, "\naliases (observed <- true cycles/rev):");
        for x in applied {
            let _ = writeln!(
                s,
                "  {:>6} <- {:<6} {:<9} {} ({})",
                x.observed_cycles,
                x.true_cycles,
                format!("{:?}", x.action).to_lowercase(),
                x.source,
                e.units.text(&x.reason)
            );
        }
    }
    let quiet = aliases.iter().filter(|x| !x.applied && !x.from_recipe).count();
    if quiet > 0 {
        let _ = writeln!(s, "  ({quiet} more aliased design frequencies with no line at their bin)");
    }
}

/// The paper's Figure 6 comparison: each interpolation's RMS and peak on
/// the survey decimated by 2, the recipe's marked; or why it was not made.
fn interpolation(s: &mut String, o: &ProcessOutcome, e: Errors) {
    let p = &o.processed;
    let u = e.u;
    match &p.interpolation {
        Ok(scores) => {
            let _ = writeln!(s, "\ninterpolation of the survey decimated by 2 (paper Figure 6), {u}:");
            for m in scores {
                let mark = if m.method == p.recipe.table.interpolation { " *" } else { "" };
                let _ = writeln!(
                    s,
                    "  {:<10} rms {} {u}  peak {} {u}{mark}",
                    m.method.as_str(),
                    e.small(m.rms_deg),
                    e.small(m.peak_deg)
                );
            }
        }
        Err(why) => {
            let _ = writeln!(s, "\ninterpolation comparison: not made ({})", e.units.text(why));
        }
    }
}

/// The table: its rows and spacing, one column or directional (and why),
/// the method.
fn table(s: &mut String, o: &ProcessOutcome, e: Errors) {
    let built = &o.processed.built;
    let t = &built.table;
    let _ = writeln!(
        s,
        "\ntable: {} rows every {:.5} deg, {}, {}; {}",
        t.len(),
        t.spacing_deg(),
        if t.is_directional() { "directional" } else { "one column" },
        built.method,
        e.units.text(&built.directional_reason)
    );
}

/// The predicted accuracy, native and corrected (peak, ISO 230-2 `A`,
/// RMS), what the corrected peak is made of, the lines left, a warning when
/// the table is not expected to improve the axis, and the repeatability
/// floor.
fn prediction(s: &mut String, o: &ProcessOutcome, e: Errors) {
    let p = &o.processed;
    let pr = &p.prediction;
    let u = e.u;
    let _ = writeln!(
        s,
        "predicted: native +/-{} {u} (ISO A {} {u}) -> corrected +/-{} {u} (ISO A {} {u}); RMS {} {u} -> {} {u}",
        e.e5(pr.native_peak_deg),
        e.opt(pr.native.iso230_a_deg),
        e.e5(pr.corrected_peak_deg),
        e.opt(pr.corrected.iso230_a_deg),
        e.e5(pr.native.rms_deg),
        e.e5(pr.corrected.rms_deg)
    );
    let _ = writeln!(
        s,
        "  corrected peak: +/-{} {u} at the survey's own samples, +{} {u} for what the table leaves between the \
         targets, +{} {u} for the spread of a new survey's peak of noise (95 %)",
        e.e5(pr.in_sample_corrected_peak_deg),
        e.e5(pr.unseen_between_targets_deg),
        e.e5(pr.peak_spread_deg)
    );
    for l in &p.left.lines {
        let _ = writeln!(s, "  left: {}", e.units.text(&l.why));
    }
    match pr.not_a_result() {
        Some(NotAResult::NoBetterThanNative) => {
            let _ = writeln!(
                s,
                "NOT A RESULT: this table is not expected to improve the axis (corrected +/-{} {u} against native \
                 +/-{} {u}): do not load it",
                e.e5(pr.corrected_peak_deg),
                e.e5(pr.native_peak_deg)
            );
        }
        Some(NotAResult::DriftNotCorrected) => {
            let _ = writeln!(
                s,
                "NOT A RESULT: the survey drifted in time in a way no straight line takes (a pass keeps up to {} \
                 {u}): the table carries that drift: do not load it",
                e.e5(pr.uncorrected_drift_deg.unwrap_or(0.0))
            );
        }
        None => {}
    }
    let _ = writeln!(s, "repeatability floor: {} {u} ({})", e.opt(p.floor.deg), p.floor.what);
}

/// Each controller file written: its points, range, spacing, directions,
/// modulo and predicted corrected peak, its notes, and a Fanuc file's
/// parameters.
fn controllers(s: &mut String, o: &ProcessOutcome, e: Errors) {
    let u = e.u;
    for (c, _) in written(o) {
        let _ = writeln!(
            s,
            "{} table: {} points, {:.4}..{:.4} deg every {:.6} deg{}{}: corrected {}",
            match c.controller {
                Controller::LinuxCnc => "LinuxCNC",
                Controller::Sinumerik840d => "Siemens 840D",
                Controller::Fanuc => "Fanuc",
                Controller::Generic => "generic",
            },
            c.grid.points,
            c.grid.start_deg,
            c.grid.end_deg(),
            c.grid.interval_deg,
            if c.directional { ", forward and reverse" } else { "" },
            if c.modulo { ", modulo 360" } else { "" },
            c.corrected_peak_deg.map_or_else(|| "-".to_string(), |v| format!("+/-{} {u}", e.e5(v))),
        );
        for n in &c.notes {
            let _ = writeln!(s, "  note: {}", e.units.text(n));
        }
        if c.controller == Controller::Fanuc {
            let params: Vec<String> = c.parameters.iter().map(|(n, v, _)| format!("{n}={v}")).collect();
            let _ = writeln!(s, "  parameters: {}", params.join(" "));
        }
    }
}

/// Every file written: the table, each controller's and the binary file,
/// the recipe.
fn files(s: &mut String, o: &ProcessOutcome) {
    let _ = writeln!(s, "\nfiles:");
    let f = &o.files;
    let _ = writeln!(s, "  table           {}", f.table_csv.display());
    for (what, p) in [
        ("LinuxCNC type 0", &f.linuxcnc_type0),
        ("LinuxCNC type 1", &f.linuxcnc_type1),
        ("Siemens 840D", &f.sinumerik_840d),
        ("Fanuc", &f.fanuc),
        ("generic", &f.generic),
        ("binary", &f.binary),
    ] {
        if let Some(p) = p {
            let _ = writeln!(s, "  {what:<15} {}", p.display());
        }
    }
    if let Some(recipe) = &f.recipe {
        let _ = writeln!(s, "  recipe          {} (replay with --recipe)", recipe.display());
    }
}
