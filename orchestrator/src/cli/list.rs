//! `survey list [--json]` and `survey show ID [--json]`: what a database
//! holds, read-only.
//!
//! `list --json` prints `{"db": ..., "surveys": [{"id", "uid", "asset", "status", "source",
//! "points", "runs", "bidirectional", "samples", "planned_samples",
//! "created_at", "updated_at"}, ...]}`, oldest first; `show --json` one
//! survey with its plan, instruments, located axis, model and event log.

use super::args::UnitsArg;
use super::support::{emit, open_read_only};
use crate::survey::{Setup, SurveyRecord};
use clap::Args;
use serde_json::{Value, json};
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
    pub survey: Option<crate::survey::SurveyRef>,
    #[command(flatten)]
    pub units: UnitsArg,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

/// One survey as a line of `list`.
fn summary(r: &SurveyRecord) -> Value {
    json!({
        "id": r.id,
        "uid": r.uid,
        "asset": r.asset,
        "status": r.status.as_str(),
        "source": r.source.to_column(),
        "points": r.points,
        "runs": r.runs,
        "bidirectional": r.bidirectional,
        "samples": r.sample_count,
        "planned_samples": r.planned_samples,
        "created_at": r.created_at,
        "updated_at": r.updated_at,
    })
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
        let doc =
            json!({"db": crate::store::lab::display(db), "surveys": surveys.iter().map(summary).collect::<Vec<_>>()});
        emit(&format!("{doc}\n"));
        return Ok(());
    }
    if surveys.is_empty() {
        emit(&format!("{} holds no survey yet\n", crate::store::lab::display(db)));
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
/// 192.168.1.20:4000`), as stored: a name's text, any other value as JSON.
fn instruments_text(s: &mut String, instruments: &Value) {
    for (role, name) in instruments.as_object().into_iter().flatten().filter(|(k, _)| *k != "config_file") {
        let name = name.as_str().map_or_else(|| name.to_string(), str::to_string);
        let _ = writeln!(s, "  {role:<12} {name}");
    }
}

pub async fn show(db: &Path, args: ShowArgs) -> anyhow::Result<()> {
    let store = open_read_only(db).await?;
    let shown = async {
        let r = store.resolve(args.survey).await?;
        let events = store.events(r.id).await?;
        let drift = store.drift_points(r.id).await?;
        let checks = store.check_points(r.id).await?;
        anyhow::Ok((r, events, drift, checks))
    }
    .await;
    store.close().await;
    let (r, events, drift, checks) = shown?;
    let plan = r.setup.plan();
    let mut doc = summary(&r);
    doc["plan"] = json!(plan.map(|p| json!({
        "targets_deg": [p.targets_deg.first(), p.targets_deg.last()],
        "targets": p.targets_deg.len(),
        "runs": p.runs,
        "bidirectional": p.bidirectional,
        "overrun_deg": p.overrun_deg,
    })));
    doc["instruments"] = r.instruments.clone();
    doc["started_at_s"] = json!(r.started_at_s);
    doc["ended_at_s"] = json!(r.ended_at_s);
    doc["axis"] = json!(r.axis.as_ref().map(|a| json!({
        "center_mm": a.center_mm,
        "normal": a.normal,
        "radius_mm": a.radius_mm,
        "plane_rms_mm": a.plane_rms_mm,
    })));
    doc["model"] = json!(r.model.as_ref().map(|m| m.to_toml()));
    doc["verifies_survey"] = json!(r.verification.as_ref().map(|v| v.verifies_survey));
    doc["check_of"] = json!(r.check_of);
    doc["events"] = json!(
        events.iter().map(|e| json!({"at_s": e.at_s, "level": e.level, "message": e.message})).collect::<Vec<_>>()
    );
    doc["drift"] = crate::drift::json(&r, &drift);
    // Check points measured between the targets (issue 20): their angles, as many times as measured.
    let mut at: Vec<f64> = checks.iter().map(|c| c.target_deg).collect();
    at.sort_by(f64::total_cmp);
    at.dedup();
    doc["check_points"] = json!({"samples": checks.len(), "targets_deg": at});
    doc["resolves_survey"] = json!(r.resolves);
    if args.json {
        emit(&format!("{doc}\n"));
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
                let _ = writeln!(s, "  faults       {}", crate::output::fault_rates(faults));
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
    for line in survey_processing::drift::text(&drift, units).lines() {
        let _ = writeln!(s, "  {line}");
    }
    if !events.is_empty() {
        let _ = writeln!(s, "  events");
        for e in &events {
            let _ = writeln!(s, "    {:>10.1} s  {:<5}  {}", e.at_s, e.level, units.text(&e.message));
        }
    }
    emit(&s);
    Ok(())
}
