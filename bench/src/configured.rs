//! The bench of a configuration file: real instruments (or anything that
//! speaks their protocols, such as `survey sim`), on the system clock.

use super::{Bench, DEFAULT_RUNS};
use crate::instruments::Instruments;
use anyhow::Context as _;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;
use survey_acquire::{Engine, ReferenceKind};
use survey_drivers::{Clock, SystemClock};
use survey_plan::SurveyPlan;
use survey_store::config::SurveyConfig;
use survey_store::error::bad_input;
use survey_store::survey::{ConfiguredSetup, Setup, SurveySource};

/// Plan settings from the command line, over the configuration's `[survey]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PlanOverrides {
    /// `--points`.
    pub points: Option<u32>,
    /// `--runs`.
    pub runs: Option<u32>,
    /// `--bidirectional` (it can only turn the reverse pass on).
    pub bidirectional: bool,
    /// `--scan` (over `[survey] scan`).
    pub scan: Option<survey_plan::ScanMode>,
    /// `--smrs N`: N SMRs at equal spacing (over `[smrs]`; 1: one).
    pub smrs: Option<u32>,
}

impl Bench {
    /// The bench of the configuration file at `path`, checked before anything is stored.
    pub fn configured(path: &Path, overrides: PlanOverrides) -> anyhow::Result<Bench> {
        let mut cfg = SurveyConfig::from_file_to_open(path)?;
        if let Some(n) = overrides.smrs {
            let max = survey_processing::smrs::MAX_SMRS;
            if n as usize > max {
                return Err(bad_input(format!("--smrs {n}: a survey measures at most {max} SMRs at a target")));
            }
            // Stored with the survey as its configuration says it.
            cfg.smrs = (n > 1).then(|| survey_store::config::SmrsSection {
                phases_deg: survey_processing::smrs::SmrMount::equal(n as usize).iter().map(|m| m.phase_deg).collect(),
                heights_mm: None,
            });
            if n > 1 && cfg.reference() != ReferenceKind::Tracker {
                return Err(bad_input(format!("--smrs {n}: several SMRs need the tracker as the reference")));
            }
        }
        let plan = configured_plan(&cfg, overrides, path)?;
        if cfg.smrs.is_some() && plan.continuous() {
            return Err(bad_input(
                "several SMRs are measured one after the other at rest: use --scan step (a continuous scan follows one SMR)",
            ));
        }
        if let Some(p) = cfg.polygon.as_ref().filter(|p| !p.turns.is_empty()) {
            let (tracker, directions) = (cfg.reference() == ReferenceKind::Tracker, plan.directions().len() as u32);
            let name = format!("{}: [polygon] turns", path.display());
            crate::simulated::check_polygon_turns(&name, &p.turns, tracker, p.faces, plan.runs, directions)?;
        }
        let setup = ConfiguredSetup { config: cfg, plan };
        let mut bench = on_clock(&setup, Arc::new(SystemClock::new()));
        if let Some(obj) = bench.instruments.as_object_mut() {
            obj.insert("config_file".into(), path.display().to_string().into());
        }
        Ok(bench)
    }
}

/// The plan of a configuration (its `[survey]` under the command line's
/// overrides), checked against its travel; errors name `path`.
pub fn configured_plan(cfg: &SurveyConfig, overrides: PlanOverrides, path: &Path) -> anyhow::Result<SurveyPlan> {
    // The count from where it is known before asking for it: an autocollimator's polygon has its faces.
    let faces = cfg.polygon.as_ref().filter(|_| cfg.reference() == ReferenceKind::Autocollimator).map(|p| p.faces);
    let points = overrides.points.or(cfg.survey.points).or(faces).ok_or_else(|| {
        bad_input(format!("--points N is required (or `points` in the [survey] section of {})", path.display()))
    })?;
    let runs = overrides.runs.or(cfg.survey.runs).unwrap_or(DEFAULT_RUNS);
    let bidirectional = overrides.bidirectional || cfg.survey.bidirectional.unwrap_or(false);
    let travel = cfg.survey.travel_deg.map(|[lo, hi]| (lo, hi));
    let plan = match (cfg.reference(), &cfg.polygon, travel) {
        (ReferenceKind::Autocollimator, Some(polygon), travel) => {
            SurveyPlan::polygon(polygon.faces, points, travel, runs, bidirectional)
        }
        (_, _, Some((lo, hi))) => SurveyPlan::within_travel(lo, hi, points, runs, bidirectional),
        (_, _, None) => SurveyPlan::full_circle(points, runs, bidirectional),
    };
    let mut plan = plan.with_context(|| path.display().to_string())?;
    if let Some(overrun) = cfg.survey.overrun_deg {
        plan.overrun_deg = overrun;
    }
    if let Some([lo, hi]) = cfg.survey.travel_deg {
        plan.check_travel(lo, hi)?;
    }
    plan.scan = overrides.scan.or(cfg.survey.scan).unwrap_or_default();
    if let (true, Some([lo, hi])) = (plan.continuous(), cfg.survey.travel_deg) {
        let t = cfg.timing();
        plan = survey_plan::within_travel_for_scan(&plan, (lo, hi), t.velocity_deg_s, t.accel_deg_s2, &t.scan)
            .with_context(|| path.display().to_string())?;
    }
    if plan.continuous()
        && let Err(why) = crate::instruments::continuous_support(cfg)
    {
        return Err(bad_input(format!("{}: --scan continuous is not possible: {why}", path.display())));
    }
    Ok(plan)
}

fn on_clock(setup: &ConfiguredSetup, clock: Arc<dyn Clock>) -> Bench {
    let cfg = &setup.config;
    let engine = configured_engine(cfg, clock.clone());
    let instruments = serde_json::json!({
        "positioner": engine.positioner_name(),
        "reference": engine.reference_name(),
    });
    Bench {
        engine,
        clock,
        estimate: configured_estimate(cfg, &setup.plan),
        plan: setup.plan.clone(),
        setup: Setup::Configured(setup.clone()),
        model: None,
        source: SurveySource::Instruments,
        instruments,
        plan_progress: None,
    }
}

/// How long `plan` should take on the instruments of `cfg` (what `run` says
/// before it starts). Every move and pass is within a day (the
/// configuration's check), so the sum is a duration.
pub fn configured_estimate(cfg: &SurveyConfig, plan: &SurveyPlan) -> Duration {
    let t = cfg.timing();
    let measure = integration(cfg).unwrap_or(Duration::from_millis(200));
    let others = cfg.smrs.as_ref().map_or(0, |s| s.phases_deg.len().saturating_sub(1) as u32);
    // Each other SMR pointed at, found and measured; then the first again.
    let pointing =
        if others > 0 { (CONFIGURED_POINT_BOUND + measure) * others + CONFIGURED_POINT_BOUND } else { Duration::ZERO };
    let per_target = t.dwell + measure + t.poll_interval + pointing;
    if plan.continuous() {
        let d = survey_plan::budget::Dynamics {
            velocity_deg_s: t.velocity_deg_s,
            accel_deg_s2: t.accel_deg_s2,
            integration_s: measure.as_secs_f64(),
            locate_points: t.locate_points,
            other_smrs: cfg.smrs.as_ref().map_or(0, |s| s.phases_deg.len().saturating_sub(1) as u32),
            point_s: CONFIGURED_POINT_BOUND.as_secs_f64(),
        };
        Duration::from_secs_f64(survey_plan::budget::scan_bound(plan, &d, &cfg.settle_model(), &t.scan).total())
    } else {
        plan.estimate_duration(t.velocity_deg_s, t.accel_deg_s2, per_target)
    }
}

/// The reference's integration time per sample, when the configuration
/// says it (a tracker's measurement time).
fn integration(cfg: &SurveyConfig) -> Option<Duration> {
    match (&cfg.tracker, cfg.reference()) {
        (Some(survey_store::config::TrackerConfig::Emscon { settings, .. }), ReferenceKind::Tracker) => {
            Some(Duration::from_millis(u64::from(settings.measurement_time_ms)))
        }
        _ => None,
    }
}

/// The engine on the configured instruments.
pub fn configured_engine(cfg: &SurveyConfig, clock: Arc<dyn Clock>) -> Engine {
    let mut engine = Instruments::from_config(cfg)
        .into_engine(clock, cfg)
        .with_travel(cfg.survey.travel_deg.map(|[lo, hi]| (lo, hi)))
        .with_physics(cfg.settle_model(), integration(cfg));
    if let Some(arm) = &cfg.arm {
        engine = engine.with_arm_check(arm.radius_mm, arm.radius_tolerance_mm);
    }
    engine.set_drift_control(cfg.drift_control.clone());
    let turns = cfg.polygon.as_ref().map(|p| p.turns.clone()).unwrap_or_default();
    if !turns.is_empty() && cfg.reference() == ReferenceKind::Autocollimator {
        engine = engine.with_polygon_stage(survey_acquire::PolygonStage::by_operator(turns));
    }
    match &cfg.smrs {
        // A real tracker's search time is its own: the simulated tracker's
        // (ours, half a second) stands as the bound's.
        Some(s) => engine.with_smrs(s.mounts(), CONFIGURED_POINT_BOUND),
        None => engine,
    }
}

/// The least time a configured tracker is taken to need to point at another
/// SMR and find it, for the plan's bound: the simulated tracker's search
/// (our own figure; a tracker's is not in its public specification).
pub const CONFIGURED_POINT_BOUND: Duration = Duration::from_millis(500);

/// The configured bench of a stored survey, its clock going on from `resume_at`.
pub(super) fn resume(setup: &ConfiguredSetup, resume_at: Duration) -> Bench {
    on_clock(setup, Arc::new(SystemClock::starting_at(resume_at)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every shipped example sets up a bench: its plan fits its reference
    /// and its travel, checked before anything is stored (the elevation
    /// example once planned 36 points over 100 deg against a 36-face polygon,
    /// which no face matched: every run stored an empty interrupted survey).
    #[test]
    fn every_example_configuration_sets_up_a_bench() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/config");
        let mut seen = 0;
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "toml") {
                let bench = Bench::configured(&path, PlanOverrides::default())
                    .unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
                assert!(bench.plan.targets_deg.len() >= 2, "{}", path.display());
                seen += 1;
            }
        }
        assert!(seen >= 5);
        let elevation = Path::new(dir).join("scpi-serial-elevation.toml");
        let bench = Bench::configured(&elevation, PlanOverrides::default()).unwrap();
        assert_eq!(bench.plan.targets_deg, (0..=8).map(|k| f64::from(k) * 10.0).collect::<Vec<_>>());
        let wrong = PlanOverrides { points: Some(24), ..PlanOverrides::default() };
        let e = Bench::configured(&elevation, wrong).unwrap_err();
        assert!(e.chain().any(|c| c.is::<survey_plan::PlanError>()), "a plan error (bad input, exit status 2): {e:#}");
        // The plan's error under the file's name, as the command line prints it.
        let shown = format!("{e:#}");
        assert!(shown.contains("scpi-serial-elevation.toml: ") && shown.contains("--points must be 36"), "{shown}");
    }
}
