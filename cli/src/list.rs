//! `survey list [--json]` and `survey show ID [--json]`: what a database
//! holds, read-only.
//!
//! `list --json` prints `{"db": ..., "surveys": [{"id", "uid", "asset", "status", "source",
//! "points", "runs", "bidirectional", "samples", "planned_samples",
//! "created_at", "updated_at"}, ...]}`, oldest first; `show --json` one
//! survey with its plan, instruments, located axis, model and event log.

use super::args::UnitsArg;
use super::support::{emit, open_read_only};
use clap::Args;
use serde_json::Value;
use survey_store::survey::{Setup, SurveyRecord};

use std::fmt::Write as _;
use std::path::Path;

#[derive(Debug, Args)]
pub struct ListArgs {
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, Args)]
pub struct ShowArgs {
    /// Survey id or uid (default: the latest).
    #[arg(value_name = "ID", allow_negative_numbers = true)]
    pub survey: Option<survey_store::survey::SurveyRef>,
    #[command(flatten)]
    pub units: UnitsArg,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

/// "1800 x 5 runs, both ways" or "-" for a survey without a plan.
fn plan_text(r: &SurveyRecord) -> String {
    match (r.points, r.runs) {
        (Some(p), Some(n)) => format!("{p} x {n} runs{}", if r.bidirectional { ", both ways" } else { "" }),
        _ => "-".into(),
    }
}

pub async fn list(db: &Path, args: ListArgs) -> anyhow::Result<()> {
    let store = open_read_only(db).await?;
    let surveys = store.list().await;
    store.close().await;
    let surveys = surveys?;
    if args.json {
        let doc = survey_lab::documents::list_json(&survey_store::lab::display(db), &surveys);
        emit(&format!("{doc}\n"));
        return Ok(());
    }
    if surveys.is_empty() {
        emit(&format!("{} holds no survey yet\n", survey_store::lab::display(db)));
        return Ok(());
    }
    let mut s = format!(
        "{:>4}  {:<12} {:<14} {:<24} {:>17}  {}\n",
        "id", "status", "source", "plan", "samples", "created (UTC)"
    );
    for r in &surveys {
        let samples = match r.planned_samples {
            Some(p) => format!("{} of {p}", r.sample_count),
            None => r.sample_count.to_string(),
        };
        let source = r.source.to_column();
        let source: String = if source.chars().count() > 14 {
            source.chars().take(13).chain(std::iter::once('…')).collect()
        } else {
            source
        };
        let _ = writeln!(
            s,
            "{:>4}  {:<12} {:<14} {:<24} {:>17}  {}",
            r.id,
            r.status.as_str(),
            source,
            plan_text(r),
            samples,
            r.created_at
        );
    }
    emit(&s);
    Ok(())
}

/// The instruments of a configured survey, one a line (`positioner   scpi-tcp
/// 192.168.1.20:4000`), as stored: a name's text, what each identified
/// itself as on a line of its own, any other value as JSON.
fn instruments_text(s: &mut String, instruments: &Value) {
    let shown = instruments.as_object().into_iter().flatten();
    for (role, name) in shown.filter(|(k, _)| !matches!(k.as_str(), "config_file" | "identified")) {
        let name = name.as_str().map_or_else(|| name.to_string(), str::to_string);
        let _ = writeln!(s, "  {role:<12} {name}");
    }
    let identified = instruments.get("identified").and_then(Value::as_object).into_iter().flatten();
    for (role, said) in identified {
        let said = said.as_str().unwrap_or("(did not say)");
        let _ = writeln!(s, "  {:<12} {said}", format!("{role} is"));
    }
}

pub async fn show(db: &Path, args: ShowArgs) -> anyhow::Result<()> {
    let store = open_read_only(db).await?;
    let shown = survey_lab::documents::shown(&store, args.survey).await;
    store.close().await;
    let shown = shown?;
    let (r, events, drift, checks) = (&shown.survey, &shown.events, &shown.drift, &shown.checks);
    let at = shown.check_angles();
    let plan = r.setup.plan();
    if args.json {
        emit(&format!("{}\n", shown.json()));
        return Ok(());
    }
    let mut s = format!("survey {} ({})\n", r.id, r.status.as_str());
    let _ = writeln!(s, "  uid          {}", r.uid);
    let _ = writeln!(s, "  asset        {}", r.asset);
    let _ = writeln!(s, "  source       {}", r.source.to_column());
    let _ = writeln!(s, "  created      {}, last change {}", r.created_at, r.updated_at);
    let samples = match r.planned_samples {
        Some(p) => format!("{} of {p} stored", r.sample_count),
        None => format!("{} stored", r.sample_count),
    };
    let _ = writeln!(s, "  samples      {samples}");
    if let Some(p) = plan {
        let _ = writeln!(
            s,
            "  plan         {} targets from {} to {} deg, {} runs{}, overrun {} deg",
            p.targets_deg.len(),
            p.targets_deg.first().copied().unwrap_or(f64::NAN),
            p.targets_deg.last().copied().unwrap_or(f64::NAN),
            p.runs,
            if p.bidirectional { ", both ways" } else { "" },
            p.overrun_deg
        );
    }
    match &r.setup {
        Setup::Simulated(sim) => {
            let model = sim.model_file.as_ref().map(|m| format!(" running {m}")).unwrap_or_default();
            let _ = writeln!(
                s,
                "  bench        simulated {}{model} with a {}, seed {}",
                sim.preset,
                sim.reference.as_str(),
                sim.seed
            );
            if let Some(faults) = &sim.faults {
                let _ = writeln!(s, "  faults       {}", survey_bench::output::fault_rates(faults));
            }
        }
        Setup::Configured(_) => {
            let from = r.instruments.get("config_file").and_then(Value::as_str);
            let _ = writeln!(s, "  bench        configured{}", from.map(|f| format!(" from {f}")).unwrap_or_default());
            instruments_text(&mut s, &r.instruments);
        }
        Setup::Imported { file } => {
            let _ = writeln!(s, "  imported     from {file}");
        }
        Setup::Unrecorded => {}
    }
    if let Some(a) = &r.axis {
        let _ = writeln!(s, "  axis         located: radius {:.3} mm, plane rms {:.4} mm", a.radius_mm, a.plane_rms_mm);
    }
    if let Some(v) = &r.verification {
        let _ = writeln!(s, "  verifies     survey {} (table {})", v.verifies_survey, v.table);
    }
    if let Some(uid) = &r.check_of {
        let _ = writeln!(s, "  checks       the calibration {uid}");
    }
    if !checks.is_empty() {
        let shown: Vec<String> = at.iter().map(|t| format!("{t:.3}")).collect();
        let _ = writeln!(s, "  check points {} samples between the targets, at {} deg", checks.len(), shown.join(", "));
    }
    if let Some(of) = r.resolves {
        let _ = writeln!(
            s,
            "  resolves     the check points of survey {of}, being acquired (`survey resume` finishes them)"
        );
    }
    let units = args.units.units();
    for line in survey_plan::drift::text(drift, units).lines() {
        let _ = writeln!(s, "  {line}");
    }
    if !events.is_empty() {
        let _ = writeln!(s, "  events");
        for e in events {
            let _ = writeln!(s, "    {:>10.1} s  {:<5}  {}", e.at_s, e.level, units.text(&e.message));
        }
    }
    emit(&s);
    Ok(())
}
