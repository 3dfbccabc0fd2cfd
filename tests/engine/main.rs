//! End-to-end tests of the survey engine on the simulated instruments, into
//! SQLite, checked against the truth the simulators know.

mod axis_refit;
mod coverage;
mod examples;
mod instrument_time;
mod integrity;
mod interop_canopen;
mod interop_emscon;
mod modelgap;
mod polygon;
mod resume;
mod scan_latency;
mod smrs;
mod soak;
mod uncertainty;
mod wire;
mod wire_faults;

use std::sync::Arc;
use survey_acquire::{Engine, Reference, Timing};
use survey_acquire::{MemorySink, RawReading};
use survey_drivers::{Clock, VirtualClock};
use survey_plan::SurveyPlan;
use survey_processing::geometry::AxisFit;
use survey_processing::iso230::iso230_2;
use survey_processing::model::Model;
use survey_processing::{Direction, Sample};
use survey_sims::tracker::{ArmGeometry, sigma_mm};
use survey_sims::{Preset, SimBench, SimBenchBuilder};
use survey_store::survey::{NewSurvey, SurveyStatus};
use survey_store::{Store, StoreSink};

fn fig8() -> Preset {
    Preset::by_name("fig8").expect("fig8 preset")
}

fn engine_from(builder: SimBenchBuilder) -> Engine {
    let bench = builder.build();
    let timing = Timing { velocity_deg_s: bench.positioner.config().velocity_deg_s, ..Timing::default() };
    Engine::new(bench.clock.clone(), Box::new(bench.positioner), Reference::Tracker(Box::new(bench.tracker)), timing)
}

fn virtual_clock() -> Arc<dyn Clock> {
    Arc::new(VirtualClock::new())
}

/// The angular standard deviation (deg) that the tracker's coordinate noise
/// gives on the arm at axis angle `theta`: the tangential component of the
/// per-coordinate sigma over the radius.
fn tracker_sigma_deg(arm: &ArmGeometry, theta: f64) -> f64 {
    let p = arm.smr_position_mm(theta);
    let d = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    (sigma_mm(d) / arm.radius_mm).to_degrees()
}

#[tokio::test]
async fn a_bidirectional_multi_run_survey_lands_in_sqlite() {
    let dir = tempfile::tempdir().unwrap();
    let store = Store::open(&dir.path().join("s.db")).await.unwrap();
    let plan = SurveyPlan::full_circle(90, 3, true).unwrap();
    let id = store
        .create_survey(&NewSurvey {
            status: SurveyStatus::Running,
            source: survey_store::survey::SurveySource::Simulated,
            points: Some(90),
            runs: Some(3),
            bidirectional: true,
            planned_samples: Some(plan.total_steps()),
            ..NewSurvey::default()
        })
        .await
        .unwrap();
    let mut engine = engine_from(SimBench::builder(&fig8(), 7, virtual_clock()));
    let mut sink = StoreSink::new(store.clone(), id);
    let outcome = engine.run(&plan, 0, &mut sink, &mut |_| {}).await.unwrap();
    assert_eq!(outcome.samples_recorded, 540);

    // Read back from the database (a second connection would see the same: WAL, committed).
    let stored = store.recorded_samples(id).await.unwrap();
    assert_eq!(stored.len(), 540);
    assert!(stored.iter().enumerate().all(|(i, r)| r.seq == i as u64), "seq dense from 0");
    assert!(stored.iter().all(|r| matches!(r.raw, RawReading::Smr(_))), "raw SMR readings kept");
    let steps = plan.steps();
    for (r, step) in stored.iter().zip(&steps) {
        assert_eq!(
            (r.sample.run, r.sample.direction, r.sample.target_deg),
            (step.run, step.direction, step.target_deg)
        );
    }
    let times: Vec<f64> = stored.iter().map(|r| r.sample.timestamp_s.unwrap()).collect();
    assert!(times.windows(2).all(|w| w[1] > w[0]), "instrument time increases");
    assert!(times[539] > 3600.0 * 0.3, "a 540-target survey stands for a good part of an hour: {}", times[539]);
    assert_eq!(store.locate_points(id).await.unwrap().len(), Timing::default().locate_points as usize);
    let row = store.survey(id).await.unwrap();
    let axis: AxisFit = row.axis.expect("axis stored");
    assert!((axis.radius_mm - 1000.0).abs() < 0.1);
    assert_eq!(row.sample_count, 540);

    let samples: Vec<Sample> = stored.iter().map(|r| r.sample).collect();
    let iso = iso230_2(&samples).unwrap();
    assert_eq!(iso.runs, 3);
    assert_eq!(iso.targets.len(), 90);
    store.close().await;
}

/// The ISO 230-2 figures of a survey of a known model agree with what the
/// model predicts: the reversal equals the backlash, the repeatability its noise.
#[tokio::test]
async fn iso_figures_agree_with_the_model() {
    let backlash: f64 = 0.006;
    let sigma_pos: f64 = 0.0005;
    let model = Model::parse(
        &format!(
            "[design]\ngear_ratios = [20]\n\
             [[effect]]\nkind = \"gear_pass\"\ncycles_per_rev = 20\namplitude_deg = 0.005\nphase_deg = 10\n\
             [[effect]]\nkind = \"backlash\"\namplitude_deg = {backlash}\n\
             [[effect]]\nkind = \"noise\"\nsigma_deg = {sigma_pos}\n"
        ),
        "test model",
    )
    .unwrap();
    let points = 180u32;
    let runs = 5u32;
    let plan = SurveyPlan::full_circle(points, runs, true).unwrap();
    let builder = SimBench::builder(&fig8(), 11, virtual_clock()).model(model);
    let arm = builder.tracker.arm.clone();
    let mut engine = engine_from(builder);
    let mut sink = MemorySink::default();
    engine.run(&plan, 0, &mut sink, &mut |_| {}).await.unwrap();
    let samples: Vec<Sample> = sink.samples.iter().map(|r| r.sample).collect();
    let iso = iso230_2(&samples).unwrap();

    // Expected variance of one sample: the positioner's rest noise plus the
    // tracker's angular noise at that target (the axis-fit error is the same
    // in every run and so does not enter s).
    let var: Vec<f64> =
        plan.targets_deg.iter().map(|&t| sigma_pos.powi(2) + tracker_sigma_deg(&arm, t).powi(2)).collect();
    let mean_var = var.iter().sum::<f64>() / var.len() as f64;
    let n = runs as f64;
    let big_n = points as f64;

    // Reversal: x = actual - target = -(error), forward error +b/2, reverse -b/2,
    // so B_i = x_up - x_down = -b. B_mean averages N targets of a difference of
    // two means of n runs: sd = sqrt(2 var / n / N). Allow 5 sd.
    let b_mean = iso.b_mean.unwrap();
    let sd_b_mean = (2.0 * mean_var / n / big_n).sqrt();
    assert!((b_mean + backlash).abs() < 5.0 * sd_b_mean, "B_mean {b_mean} vs -{backlash} (5 sd = {})", 5.0 * sd_b_mean);

    // Repeatability: the pooled s^2 over targets and directions estimates the
    // mean variance; with dof = 2 N (n - 1) its sd relative to sigma is about
    // 1 / sqrt(2 dof). Allow 5 of those.
    let s2: Vec<f64> = iso
        .targets
        .iter()
        .flat_map(|t| [t.up.as_ref().unwrap().s, t.down.as_ref().unwrap().s])
        .map(|s| s * s)
        .collect();
    let pooled = (s2.iter().sum::<f64>() / s2.len() as f64).sqrt();
    let expected = mean_var.sqrt();
    let dof = 2.0 * big_n * (n - 1.0);
    let rel_tol = 5.0 / (2.0 * dof).sqrt();
    assert!(
        (pooled / expected - 1.0).abs() < rel_tol,
        "pooled s {pooled} vs expected {expected} (relative tolerance {rel_tol})"
    );
    // And R_up = 4 s at the worst of N targets. s / sigma with 4 dof exceeds k
    // with probability P(chi2_4 > 4 k^2); for k = 2.6 that is 2e-5, so over 180
    // targets the maximum stays below 2.6 sigma with probability > 99.6 %, and
    // it is surely above 1 sigma (all 180 below would have probability ~0).
    let r_up = iso.r_up.unwrap();
    let sigma_max = var.iter().cloned().fold(0.0f64, f64::max).sqrt();
    assert!(r_up > 4.0 * expected && r_up < 4.0 * sigma_max * 2.6, "R_up {r_up} vs 4 sigma {}", 4.0 * expected);
}

/// The circle fit recovers a tilted, off-centre arm's axis, and the angles it
/// gives agree with the truth to within the tracker's noise.
#[tokio::test]
async fn the_circle_fit_recovers_a_tilted_off_centre_arm() {
    let tilt = 2.0f64.to_radians();
    let arm = ArmGeometry {
        radius_mm: 750.0,
        axis_center_mm: [3100.0, -1200.0, 450.0],
        axis_normal: [tilt.sin() * 0.6, tilt.sin() * 0.8, tilt.cos()],
        arm_phase_deg: -71.0,
        smr_height_mm: 120.0,
        ..ArmGeometry::default()
    };
    // A perfect positioner: the true angle is the readout, so every deviation
    // of the measured angle is the tracker's noise plus the fit's error.
    // An ideal tracker (its random part only): this is a test of the fit
    // against the noise it averages; a real tracker's own error moves the
    // circle by up to its MPE (`survey_processing::tracker_errors`).
    let mut builder = SimBench::builder(&fig8(), 3, virtual_clock()).model(Model::default()).arm(arm.clone());
    builder.tracker.errors = survey_processing::tracker_errors::TrackerErrorSpec::None;
    let mut engine = engine_from(builder);
    let plan = SurveyPlan::full_circle(360, 2, true).unwrap();
    let mut sink = MemorySink::default();
    engine.run(&plan, 0, &mut sink, &mut |_| {}).await.unwrap();
    let fit = sink.axis.clone().expect("axis located");

    let sigma_c = sigma_mm(3500.0); // per-coordinate sd at about the arm's distance
    let m = Timing::default().locate_points as f64;
    // The plane normal is known to about sigma / (R sqrt(m / 2)) rad; the centre
    // to about sigma sqrt(2 / m) in the plane. Allow 5 of each.
    let (_, _, n_true) = arm.basis();
    let cos = fit.normal.iter().zip(n_true).map(|(a, b)| a * b).sum::<f64>();
    let normal_err = cos.abs().min(1.0).acos();
    assert!(normal_err < 5.0 * sigma_c / (arm.radius_mm * (m / 2.0).sqrt()), "normal off by {normal_err} rad");
    let c_true = arm.circle_center_mm();
    let c_err = (0..3).map(|i| (fit.center_mm[i] - c_true[i]).powi(2)).sum::<f64>().sqrt();
    assert!(c_err < 5.0 * sigma_c * (2.0 / m).sqrt() * 1.5, "centre off by {c_err} mm");
    assert!((fit.radius_mm - arm.radius_mm).abs() < 5.0 * sigma_c / m.sqrt(), "radius {}", fit.radius_mm);
    assert!(cos > 0.0, "the normal points so that angles increase with the readout");

    // Angles: each is off by the tracker's noise (sd sigma_ang) plus the fit's
    // error (a once-per-revolution term of about sigma_ang * sqrt(2 / m) and a
    // zero offset of about sigma_ang / sqrt(m)). Max within 5 sigma_ang * 1.5;
    // rms within 25 % of the noise-plus-fit prediction.
    let sigma_ang = (sigma_c / arm.radius_mm).to_degrees();
    let errs: Vec<f64> = sink.samples.iter().map(|r| r.sample.actual_deg - r.sample.target_deg).collect();
    let max = errs.iter().fold(0.0f64, |a, e| a.max(e.abs()));
    let rms = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt();
    let predicted_rms = sigma_ang * (1.0 + 3.0 / m).sqrt();
    assert!(max < 5.0 * sigma_ang * 1.5, "max angle error {max} deg, sigma {sigma_ang}");
    assert!((rms / predicted_rms - 1.0).abs() < 0.25, "rms {rms} vs {predicted_rms}");
}

/// With the autocollimator on a polygon, the survey's error map is the
/// model's error at the faces, through the polygon certificate.
#[tokio::test]
async fn the_autocollimator_survey_reads_the_model_at_the_faces() {
    let preset = fig8();
    let faces = 36;
    let builder = SimBench::builder(&preset, 5, virtual_clock())
        .autocollimator(survey_sims::autocollimator::AutocollimatorConfig::seeded(faces, 9));
    let model = builder.positioner.model.clone();
    let bench = builder.build();
    let reference = Reference::Autocollimator {
        faces: bench.autocollimator.faces(),
        certificate_arcsec: bench.autocollimator.certificate_arcsec().to_vec(),
        instrument: Box::new(bench.autocollimator),
    };
    let mut engine = Engine::new(bench.clock.clone(), Box::new(bench.positioner), reference, Timing::default());
    let plan = SurveyPlan::full_circle(faces, 3, true).unwrap();
    let mut sink = MemorySink::default();
    engine.run(&plan, 0, &mut sink, &mut |_| {}).await.unwrap();
    assert_eq!(sink.samples.len(), (faces * 3 * 2) as usize);
    // Error = readout - actual = the model's error at the true angle, plus the
    // positioner's noise and 0.1 arcsec of autocollimator noise. Averaged over
    // 3 runs: allow 5 sd of the mean.
    let sd = (model.noise_sigma_deg().powi(2) + (0.1f64 / 3600.0).powi(2)).sqrt() / 3f64.sqrt();
    for (k, &t) in plan.targets_deg.iter().enumerate() {
        for dir in [Direction::Forward, Direction::Reverse] {
            let errs: Vec<f64> = sink
                .samples
                .iter()
                .filter(|r| r.sample.direction == dir && r.sample.target_deg == t)
                .map(|r| r.sample.error_deg())
                .collect();
            let mean = errs.iter().sum::<f64>() / errs.len() as f64;
            let truth = model.repeatable_error_deg(t, dir);
            assert!((mean - truth).abs() < 5.0 * sd, "face {k} {dir}: {mean} vs {truth}");
        }
    }
}
