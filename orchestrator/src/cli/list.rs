//! `survey list [--json]` and `survey show ID [--json]`: what a database
//! holds, read-only.
//!
//! `list --json` prints `{"db": ..., "surveys": [{"id", "uid", "asset", "status", "source",
//! "points", "runs", "bidirectional", "samples", "planned_samples",
//! "created_at", "updated_at"}, ...]}`, oldest first; `show --json` one
//! survey with its plan, instruments, located axis, model and event log.

use super::support::{emit, open_read_only};
use crate::survey::{Setup, SurveyRecord};
use clap::Args;

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
    #[arg(value_name = "ID")]
    pub survey: Option<crate::survey::SurveyRef>,
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
        let doc = crate::documents::list_json(&crate::store::lab::display(db), &surveys);
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

pub async fn show(db: &Path, args: ShowArgs) -> anyhow::Result<()> {
    let store = open_read_only(db).await?;
    let shown = crate::documents::shown(&store, args.survey).await;
    store.close().await;
    let shown = shown?;
    let (r, events, drift) = (&shown.survey, &shown.events, &shown.drift);
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
            let _ = writeln!(s, "  bench        simulated {} (seed {})", sim.preset, sim.seed);
        }
        Setup::Configured(_) => {
            let _ = writeln!(s, "  bench        configured instruments: {}", r.instruments);
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
    for line in survey_processing::drift::text(drift).lines() {
        let _ = writeln!(s, "  {line}");
    }
    if !events.is_empty() {
        let _ = writeln!(s, "  events");
        for e in events {
            let _ = writeln!(s, "    {:>10.1} s  {:<5}  {}", e.at_s, e.level, e.message);
        }
    }
    emit(&s);
    Ok(())
}
