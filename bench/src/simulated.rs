//! The simulated bench (the embedded default): one of the paper's
//! positioners, or a model file, with a tracker or an autocollimator, on a
//! virtual clock.

use super::Bench;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use survey_acquire::PolygonStage;
use survey_acquire::{Engine, Reference, ReferenceKind, Timing};
use survey_acquire::{SettleMode, SettleModel};
use survey_drivers::{Clock, VirtualClock};
use survey_plan::budget::{Dynamics, plan_bound};
use survey_plan::{ScanMode, SurveyPlan, within_travel_for_scan};
use survey_processing::model::Model;
use survey_sims::autocollimator::AutocollimatorConfig;
use survey_sims::servo::Servo;
use survey_sims::{PlanProgress, Preset, SimBench};
use survey_store::error::bad_input;
use survey_store::survey::{Setup, SimulatedSetup, SurveySource};

/// Runs when neither the command line nor the configuration says: ISO 230-2's five.
pub const DEFAULT_RUNS: u32 = 5;

/// What the user asked of the simulated bench.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulatedRequest {
    /// Targets per revolution (or over the travel); with the autocollimator,
    /// the polygon's faces.
    pub points: u32,
    /// Runs (default [`DEFAULT_RUNS`]).
    pub runs: Option<u32>,
    /// Measure the reverse pass too.
    pub bidirectional: bool,
    /// The preset (`fig1`, `fig4`, `fig8`).
    pub preset: String,
    /// A model file to simulate instead of the preset's model.
    pub model_file: Option<PathBuf>,
    /// The reference instrument.
    pub reference: ReferenceKind,
    /// The seed of every random draw.
    pub seed: u64,
    /// Step or continuous scan.
    pub scan: ScanMode,
    /// Faults the simulated instruments inject.
    pub faults: Option<survey_sims::faults::FaultRates>,
    /// SMRs at equal spacing on the table (`--smrs N`; 0: the model file's
    /// `[smrs]`, else one).
    pub smrs: u32,
    /// The polygon on a stage, turned by these faces in run 1, 2, …
    /// (`--polygon-turns`; empty: on the table).
    pub polygon_turns: Vec<u32>,
}

/// The least time the simulated tracker takes to point at another SMR and
/// find it: its search (the turn adds to it).
pub fn simulated_point_bound() -> Duration {
    survey_sims::tracker::TrackerConfig::default().find_time
}

/// The simulated bench's losses: the fraction of streamed tracker points
/// and of captured readouts that never arrive.
pub const TRACKER_STREAM_LOSS: f64 = 0.002;
/// See [`TRACKER_STREAM_LOSS`].
pub const CAPTURE_LOSS: f64 = 0.001;

/// The settling the simulated axis needs, for the bound.
pub fn settle_model(timing: &Timing) -> SettleModel {
    SettleModel::Servo { servo: Servo::default(), window_deg: timing.settle.window_deg }
}

/// The instrument time a plan is expected to take on the simulated bench:
/// its bound, plus what polling and commands add (3 % measured on the
/// default bench), plus any fixed dwell.
pub fn expected_time(
    plan: &SurveyPlan,
    timing: &Timing,
    integration: Duration,
    tracker: bool,
    smrs: usize,
) -> Duration {
    let d = Dynamics {
        velocity_deg_s: timing.velocity_deg_s,
        accel_deg_s2: timing.accel_deg_s2,
        integration_s: integration.as_secs_f64(),
        locate_points: if tracker { timing.locate_points } else { 0 },
        other_smrs: smrs.saturating_sub(1) as u32,
        point_s: simulated_point_bound().as_secs_f64(),
    };
    let bound = plan_bound(plan, &d, &settle_model(timing), &timing.scan).total();
    let steps = plan.total_steps() as f64;
    let waits = match timing.settle.mode {
        SettleMode::Adaptive => timing.dwell.as_secs_f64() * steps,
        SettleMode::InPosition => (timing.dwell + timing.poll_interval).as_secs_f64() * steps,
    };
    Duration::from_secs_f64(bound * 1.03 + if plan.continuous() { 0.0 } else { waits })
}

/// The faces of the simulated polygon when the command line does not say
/// (with the autocollimator, `--points` is the faces): the simulator's own.
pub fn default_polygon_faces() -> u32 {
    AutocollimatorConfig::default().faces
}

/// The stationary measurement time of each simulated reference.
fn measurement_time(reference: ReferenceKind) -> Duration {
    match reference {
        ReferenceKind::Tracker => Duration::from_secs(1),
        ReferenceKind::Autocollimator => Duration::from_millis(200),
    }
}

impl Bench {
    /// The simulated bench of a request, checked before anything is stored.
    pub fn simulated(req: &SimulatedRequest) -> anyhow::Result<Bench> {
        let points = req.points;
        let runs = req.runs.unwrap_or(DEFAULT_RUNS);
        let preset =
            Preset::by_name(&req.preset).ok_or_else(|| bad_input(format!("unknown preset '{}'", req.preset)))?;
        let model = match &req.model_file {
            Some(path) => crate::inputs::read_model(path)?,
            None => preset.model.clone(),
        };
        let plan = match (req.reference, preset.travel) {
            (ReferenceKind::Autocollimator, Some((lo, hi))) => {
                return Err(bad_input(format!(
                    "the autocollimator reference needs a full revolution, but preset {} travels {lo}..{hi} deg",
                    preset.name
                )));
            }
            (_, None) => SurveyPlan::full_circle(points, runs, req.bidirectional)?,
            (_, Some((lo, hi))) => SurveyPlan::within_travel(lo, hi, points, runs, req.bidirectional)?,
        };
        let mut plan = plan;
        plan.scan = req.scan;
        if plan.continuous() && req.reference == ReferenceKind::Autocollimator {
            return Err(bad_input(
                "--scan continuous needs a tracker that measures continuously: the autocollimator reads the polygon's faces only at rest (use --reference tracker, or --scan step)",
            ));
        }
        let mut timing =
            Timing { velocity_deg_s: preset.velocity_deg_s, accel_deg_s2: preset.accel_deg_s2, ..Timing::default() };
        timing.settle.window_deg = survey_acquire::default_window_deg(req.reference);
        if let (true, Some(travel)) = (plan.continuous(), preset.travel) {
            plan = within_travel_for_scan(&plan, travel, timing.velocity_deg_s, timing.accel_deg_s2, &timing.scan)?;
        }
        let tracker = req.reference == ReferenceKind::Tracker;
        if let (false, Some(p)) = (tracker, &model.polygon)
            && p.face_errors_arcsec.len() != points as usize
        {
            return Err(bad_input(format!(
                "the model file's [polygon] has {} faces, but the survey measures {points} (--points is the \
                 polygon's faces with the autocollimator)",
                p.face_errors_arcsec.len()
            )));
        }
        if req.smrs as usize > survey_processing::smrs::MAX_SMRS {
            return Err(bad_input(format!(
                "--smrs {}: a survey measures at most {} SMRs at a target",
                req.smrs,
                survey_processing::smrs::MAX_SMRS
            )));
        }
        let smrs = match (req.smrs, &model.smrs) {
            (0, Some(m)) => m.clone(),
            (0, None) => Vec::new(),
            (n, _) => survey_processing::smrs::SmrMount::equal(n as usize),
        };
        let smrs = if smrs.len() > 1 { smrs } else { Vec::new() };
        if !smrs.is_empty() && !tracker {
            return Err(bad_input("several SMRs (--smrs, [smrs]) need the tracker as the reference"));
        }
        if !smrs.is_empty() && plan.continuous() {
            return Err(bad_input(
                "several SMRs are measured one after the other at rest: use --scan step (a continuous scan follows one SMR)",
            ));
        }
        check_polygon_turns(
            "--polygon-turns",
            &req.polygon_turns,
            tracker,
            points,
            runs,
            plan.directions().len() as u32,
        )?;
        let run_period = expected_time(&plan, &timing, measurement_time(req.reference), tracker, smrs.len()) / runs;
        let setup = SimulatedSetup {
            preset: preset.name.to_string(),
            model_file: req.model_file.as_ref().map(|p| p.display().to_string()),
            reference: req.reference,
            seed: req.seed,
            plan,
            timing,
            run_period_s: run_period.as_secs_f64(),
            faults: req.faults,
            smrs,
            polygon_turns: req.polygon_turns.clone(),
            machine_frame: model.machine_frame,
            asset: None,
        };
        Ok(on_clock(&setup, &preset, model, Arc::new(VirtualClock::new())))
    }
}

/// `--polygon-turns`: the faces the polygon turns in each run, checked
/// before anything is measured: an autocollimator's polygon, each turn
/// within its faces, a run for each, and turns that link every face to
/// every other (the closure's condition, `survey_tables::closure`).
pub fn check_polygon_turns(
    name: &str,
    turns: &[u32],
    tracker: bool,
    faces: u32,
    runs: u32,
    directions: u32,
) -> anyhow::Result<()> {
    if turns.is_empty() {
        return Ok(());
    }
    if tracker {
        return Err(bad_input(format!(
            "{name} turns the polygon an autocollimator reads, and the reference is a tracker (on the simulated \
             bench: --reference autocollimator)"
        )));
    }
    if let Some(t) = turns.iter().find(|t| **t >= faces) {
        return Err(bad_input(format!("{name}: {t} faces is past the polygon's {faces} (0 to {})", faces - 1)));
    }
    if (runs as usize) < turns.len() {
        return Err(bad_input(format!(
            "{name} names {} turns but the survey has {runs} runs: one run at least for each",
            turns.len()
        )));
    }
    // The closure's unknowns: the table's error at each face each way, the
    // faces but one, an offset per run but the first; the readings must
    // outnumber them to tell the noise.
    let (readings, unknowns) = (runs * directions * faces, directions * faces + faces - 1 + runs - 1);
    if readings <= unknowns {
        return Err(bad_input(format!(
            "{name} with {runs} runs {}: {readings} readings for the {unknowns} unknowns of the closure \
             leave nothing to tell the noise by: add a run, or measure both ways (--bidirectional)",
            if directions == 2 { "both ways" } else { "one way" }
        )));
    }
    let mut distinct = turns.to_vec();
    distinct.sort_unstable();
    distinct.dedup();
    if distinct.len() < 2 {
        return Err(bad_input(format!(
            "{name} needs two turns or more (e.g. 0,1): at one the table's and the polygon's errors are seen only together"
        )));
    }
    let gcd = |mut a: u32, mut b: u32| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    if distinct.iter().skip(1).fold(faces, |g, t| gcd(g, t - distinct[0])) != 1 {
        return Err(bad_input(format!(
            "{name} {}: the turns between them share a divisor with the {faces} faces, so some faces are never \
             compared with others: turn the polygon by one face (e.g. 0,1)",
            turns.iter().map(u32::to_string).collect::<Vec<_>>().join(",")
        )));
    }
    Ok(())
}

/// The bench of `setup` on `clock`.
fn on_clock(setup: &SimulatedSetup, preset: &Preset, model: Model, clock: Arc<VirtualClock>) -> Bench {
    let progress = plan_progress(&setup.plan);
    let engine = simulated_engine(setup, preset, model.clone(), clock.clone(), Some(progress.clone()));
    let instruments = serde_json::json!({
        // A model file is the positioner: named by it, never by the preset
        // whose instruments it borrows.
        "positioner": match &setup.model_file {
            Some(file) => format!("simulated {}", file.rsplit('/').next().unwrap_or(file)),
            None => format!("simulated {}", preset.name),
        },
        "reference": format!("simulated {}", setup.reference.as_str()),
    });
    Bench {
        engine,
        clock,
        plan: setup.plan.clone(),
        estimate: Duration::from_secs_f64(setup.run_period_s * setup.plan.runs as f64),
        setup: Setup::Simulated(setup.clone()),
        model: Some(model),
        source: SurveySource::Simulated,
        instruments,
        plan_progress: Some(progress),
    }
}

/// The drift clock of a plan: its steps a run.
fn plan_progress(plan: &SurveyPlan) -> PlanProgress {
    PlanProgress::new(plan.targets_deg.len() as u64 * plan.directions().len() as u64)
}

/// Build the simulated instruments of a setup on `clock`. The model's drift
/// goes by the plan's `progress` when given (the acquisition sets it to the
/// next step: [`crate::session::AcquireOptions::plan_progress`]), else by
/// clock time over the setup's run period.
pub fn simulated_engine(
    setup: &SimulatedSetup,
    preset: &Preset,
    model: Model,
    clock: Arc<VirtualClock>,
    progress: Option<PlanProgress>,
) -> Engine {
    let dyn_clock: Arc<dyn Clock> = clock;
    // The polygon the model file states (its true faces, its certificate)
    // and the autocollimator's scale error.
    let (polygon, scale_ppm) = (model.polygon.clone(), model.autocollimator_scale_ppm);
    let mut builder = SimBench::builder(preset, setup.seed, dyn_clock.clone())
        .model(model)
        .drift_run_period(Duration::from_secs_f64(setup.run_period_s))
        .servo(Servo::default())
        .stream_losses(TRACKER_STREAM_LOSS, CAPTURE_LOSS);
    if let Some(p) = progress {
        builder = builder.drift_progress(p);
    }
    if setup.reference == ReferenceKind::Autocollimator {
        let faces = setup.plan.targets_deg.len() as u32;
        let mut ac = AutocollimatorConfig::seeded(faces, survey_sims::derive_seed(setup.seed, 3));
        ac.scale_ppm = scale_ppm;
        if let Some(p) = polygon.filter(|p| p.face_errors_arcsec.len() == faces as usize) {
            ac.certificate_arcsec = p.certificate().to_vec();
            ac.face_errors_arcsec = Some(p.face_errors_arcsec);
        }
        builder = builder.autocollimator(ac);
    }
    if let Some(rates) = &setup.faults {
        builder = builder.fault_rates(rates);
    }
    if setup.smrs.len() > 1 {
        builder.tracker.arm.smrs = setup.smrs.clone();
    }
    if !setup.polygon_turns.is_empty() {
        builder = builder.polygon_stage(survey_sims::bench::index_stage(survey_sims::derive_seed(setup.seed, 5)));
    }
    let mut bench = builder.build();
    let injected = bench.injected.clone();
    let polygon_stage = bench.polygon_stage.take();
    let reference = match setup.reference {
        ReferenceKind::Tracker => Reference::Tracker(Box::new(bench.tracker)),
        ReferenceKind::Autocollimator => Reference::Autocollimator {
            faces: bench.autocollimator.faces(),
            certificate_arcsec: bench.autocollimator.certificate_arcsec().to_vec(),
            instrument: Box::new(bench.autocollimator),
        },
    };
    let travel = bench.positioner.config().travel;
    let engine = Engine::new(dyn_clock, Box::new(bench.positioner), reference, setup.timing.clone())
        .with_travel(travel)
        .with_physics(settle_model(&setup.timing), Some(measurement_time(setup.reference)))
        .with_smrs(setup.smrs.clone(), simulated_point_bound());
    let mut engine = match polygon_stage {
        Some(stage) => engine.with_polygon_stage(PolygonStage::new(Box::new(stage), setup.polygon_turns.clone())),
        None => engine,
    };
    engine.set_injected(Some(injected));
    engine
}

/// The simulated bench of a stored survey, continued at step `next_seq`.
pub(super) fn resume(
    setup: &SimulatedSetup,
    model: Option<Model>,
    resume_at: Duration,
    next_seq: u64,
) -> anyhow::Result<Bench> {
    let preset =
        Preset::by_name(&setup.preset).ok_or_else(|| bad_input(format!("unknown preset '{}'", setup.preset)))?;
    let model = model.unwrap_or_else(|| preset.model.clone());
    let mut resumed = setup.clone();
    resumed.seed = survey_sims::derive_seed(setup.seed, 0x5e5u64 + next_seq);
    let mut bench = on_clock(&resumed, &preset, model, Arc::new(VirtualClock::starting_at(resume_at)));
    // What is stored stays the original setup (its seed included).
    bench.setup = Setup::Simulated(setup.clone());
    Ok(bench)
}
