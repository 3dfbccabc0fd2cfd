//! Issue 12, instrument time, measured on the simulators against their truth.
//!
//! - The default plan (the paper's Figure 8 positioner, a tracker, 1800
//!   points, 5 runs, both directions) in step mode takes at most 5 % more
//!   instrument time than its physical lower bound; scanned continuously it
//!   takes at least 50 times less than in step mode (issue 21; 20 in issue
//!   12), and its correction table's true residual is within 20 % of the
//!   step scan's.
//! - Adaptive settling against a long fixed dwell, on noise-free instruments
//!   so that what is left is the settling: its error is stated and bounded,
//!   and a wait that is too short (a wide window) shows up as error.

use super::axis_refit::{against_truth, survey};
use std::sync::Arc;
use std::time::Duration;
use survey_acquire::MemorySink;
use survey_acquire::{Engine, Reference, Timing};
use survey_acquire::{SettleMode, SettleModel};
use survey_drivers::{Clock, VirtualClock};
use survey_plan::SurveyPlan;
use survey_processing::model::Model;
use survey_sims::servo::Servo;
use survey_sims::{Preset, SimBench};

fn num(doc: &serde_json::Value, key: &str) -> f64 {
    doc[key].as_f64().unwrap_or_else(|| panic!("{key} in {doc}"))
}

#[test]
fn the_default_plan_scanned_continuously_takes_50_times_less_instrument_time_for_the_same_table() {
    let model = Model::parse(include_str!("../../sims/presets/fig8.toml"), "fig8.toml").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let plan = ["--points", "1800", "--runs", "5", "--bidirectional", "--json"];
    let mut figures = Vec::new();
    for seed in ["1", "2"] {
        let mut measured = Vec::new();
        for scan in ["step", "continuous"] {
            let db = dir.path().join(format!("{scan}{seed}.db"));
            let mut args = vec!["run", "--scan", scan, "--seed", seed];
            args.extend(plan);
            let run = survey(&db, &args);
            assert_eq!(run["status"], "complete", "{run}");
            assert_eq!(run["samples"], 18000, "{scan}: the plan's points per pass");
            let (time, bound) = (num(&run, "instrument_time_s"), num(&run, "bound_s"));
            // Step mode's goal is 5 % over its bound (measured 1.7 %); the
            // continuous scan's passes are the bound's plus the run-up margins.
            assert!(time <= 1.05 * bound, "{scan} seed {seed}: {time} s against a bound of {bound} s");
            assert!(time >= bound, "{scan} seed {seed}: nothing beats the bound ({time} < {bound} s)");
            let table = dir.path().join(format!("{scan}{seed}.csv"));
            let processed = survey(&db, &["process", "--table-out", table.to_str().unwrap(), "--json"]);
            let (_, residual) = against_truth(&processed, &table, &model);
            // The reversal: fig8's backlash is 0.008 deg. A latency left in
            // the continuous scan would add twice velocity x latency to it
            // (0.05 deg at 5 deg/s and 5 ms), which a non-directional table
            // averages away: so it is checked here, within 2e-4 deg.
            let b_mean = run["iso230_2"]["B_mean"].as_f64().unwrap();
            assert!((b_mean + 0.008).abs() < 2e-4, "{scan} seed {seed}: mean reversal {b_mean} deg");
            if scan == "continuous" {
                // The same plan at the positioner's pace without the
                // latency's calibration passes: what the scan spends on
                // them (and its margins) is the gap.
                let at_pace = num(&run["scan"], "bound_at_max_velocity_s");
                assert!(at_pace < bound, "{at_pace} s at pace against {bound} s");
                eprintln!(
                    "seed {seed}: continuous {time:.0} s, bound {bound:.0} s, at the positioner's maximum velocity \
                     without the calibration passes {at_pace:.0} s; latency {:.4} +/- {:.4} ms",
                    num(&run["scan"], "latency_s") * 1e3,
                    num(&run["scan"], "latency_se_s") * 1e3
                );
            }
            measured.push((time, bound, residual));
        }
        let ((step_t, step_b, step_r), (cont_t, cont_b, cont_r)) = (measured[0], measured[1]);
        eprintln!(
            "seed {seed}: step {step_t:.0} s (bound {step_b:.0} s, x{:.3}), continuous {cont_t:.0} s (bound {cont_b:.0} \
             s): {:.1} times less; true residual rms step {step_r:.2e} deg, continuous {cont_r:.2e} deg",
            step_t / step_b,
            step_t / cont_t
        );
        figures.push((step_t / cont_t, cont_r / step_r));
    }
    for (seed, (less, residual)) in figures.iter().enumerate() {
        // The goals, as stated: at least 50 times less instrument time,
        // a true residual within 20 % of step mode's.
        assert!(*less >= 50.0, "seed {}: only {less:.1} times less instrument time", seed + 1);
        assert!(*residual <= 1.2, "seed {}: the continuous table's residual is {residual:.2} of step mode's", seed + 1);
    }
}

/// One noise-free survey of 180 targets, twice each way, on the simulated
/// servo with `timing`: each sample's error less the simulator's truth at
/// its actual angle (by seq, degrees, the mean removed: a constant is the
/// zero reference, and the axis located from forward approaches carries half
/// the backlash in its zero), and the instrument time, seconds.
async fn deviations(timing: Timing) -> (Vec<f64>, f64) {
    let clock: Arc<dyn Clock> = Arc::new(VirtualClock::new());
    let preset = Preset::by_name("fig8").unwrap();
    let bench =
        SimBench::builder(&preset, 7, clock.clone()).servo(Servo::default()).without_noise().without_motions().build();
    let model = bench.positioner.config().model.clone();
    let timing = Timing { velocity_deg_s: preset.velocity_deg_s, accel_deg_s2: preset.accel_deg_s2, ..timing };
    let window = timing.settle.window_deg;
    let mut engine =
        Engine::new(clock.clone(), Box::new(bench.positioner), Reference::Tracker(Box::new(bench.tracker)), timing)
            .with_physics(SettleModel::Servo { servo: Servo::default(), window_deg: window }, None);
    let plan = SurveyPlan::full_circle(180, 2, true).unwrap();
    let mut sink = MemorySink::default();
    let outcome = engine.run(&plan, 0, &mut sink, &mut |_| {}).await.unwrap();
    assert_eq!(sink.samples.len(), 720);
    let dev: Vec<f64> = sink
        .samples
        .iter()
        .map(|r| r.sample.error_deg() - model.repeatable_error_deg(r.sample.actual_deg, r.sample.direction))
        .collect();
    let mean = dev.iter().sum::<f64>() / dev.len() as f64;
    (dev.iter().map(|d| d - mean).collect(), outcome.instrument_time.as_secs_f64())
}

/// rms and largest magnitude of `a - b`, degrees.
fn rms_max(a: &[f64], b: &[f64]) -> (f64, f64) {
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
    let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt();
    (rms, d.iter().fold(0.0f64, |m, x| m.max(x.abs())))
}

#[tokio::test]
async fn adaptive_settling_costs_no_accuracy_against_a_long_dwell_and_a_short_wait_shows() {
    let adaptive = Timing::default();
    let mut dwell = Timing { dwell: Duration::from_secs(1), ..Timing::default() };
    dwell.settle.mode = SettleMode::InPosition;
    let mut short = Timing::default();
    short.settle.window_deg = 0.01;
    let (a, a_time) = deviations(adaptive).await;
    let (d, d_time) = deviations(dwell).await;
    let (s, s_time) = deviations(short).await;
    let zero = vec![0.0; d.len()];
    let (d_rms, d_max) = rms_max(&d, &zero);
    let (a_rms, a_max) = rms_max(&a, &d);
    let (s_rms, s_max) = rms_max(&s, &d);
    eprintln!(
        "noise-free, 720 samples: in-position + 1 s dwell {d_time:.0} s, off the truth by {d_rms:.2e} rms / {d_max:.2e} \
         max deg; against it, sample by sample: adaptive ({a_time:.0} s) {a_rms:.2e} / {a_max:.2e} deg, a 0.01 deg \
         window ({s_time:.0} s) {s_rms:.2e} / {s_max:.2e} deg"
    );
    // The long dwell (the servo held within 1e-5 deg, and a second more) is
    // the reference: what it leaves is the same in every mode (the axis
    // located from 12 positions), within 2e-5 deg.
    assert!(d_max < 2e-5, "the long dwell is off the truth by {d_max:.2e} deg");
    // Adaptive settling against it: within the window (1e-4 deg) on every
    // sample, and within a tenth of the positioner's own noise (4e-4 deg per
    // sample on fig8) in rms: no cost beyond the noise.
    assert!(a_max <= 1e-4, "adaptive settling left {a_max:.2e} deg on a sample");
    assert!(a_rms <= 4e-5, "adaptive settling's rms cost {a_rms:.2e} deg");
    assert!(a_time < 0.8 * d_time, "adaptive settling saves time ({a_time:.0} against {d_time:.0} s)");
    // A window wider than the ringing ends the wait while the axis still
    // swings: the error shows, at least five times the adaptive one.
    assert!(s_rms > 5.0 * a_rms.max(1e-6), "a too short wait shows ({s_rms:.2e} against {a_rms:.2e} deg)");
}

#[tokio::test]
async fn a_continuous_survey_stopped_after_a_pass_resumes_with_its_latency_and_every_sample_once() {
    use super::integrity::{dense_prefix, survey as run_binary, text};
    use survey_store::survey::SurveyStatus;
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("s.db");
    // 360 targets x 3 runs x 2 directions: 6 passes of 360 samples, each
    // stored as it ends (the latency is measured before the first); the
    // signal is raised after the fifth pass (1800 samples).
    let plan = ["run", "--points", "360", "--runs", "3", "--bidirectional", "--scan", "continuous", "--json"];
    let mut args = plan.to_vec();
    args.extend(["--sim-signal-after", "1800"]);
    let out = run_binary(&db, &args);
    assert_eq!(out.status.code(), Some(1), "a stop is a run-time end: {}", text(&out));
    let (status, kept, _) = dense_prefix(&db).await;
    assert_eq!(status, SurveyStatus::Interrupted);
    // Whole passes only: the stop is seen before the sixth pass or during it
    // (then that pass is dropped, never half-stored).
    assert_eq!(kept, 1800, "{}", text(&out));
    let out = run_binary(&db, &["resume", "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let (status, n, _) = dense_prefix(&db).await;
    assert_eq!((status, n), (SurveyStatus::Complete, 2160));
    // The resume goes on with the latency the calibration passes measured
    // (read back from the stored passes), so the last pass is paired as the others.
    let latency = doc["scan"]["latency_s"].as_f64().expect("the latency after a resume");
    assert!((latency - 0.005).abs() < 1e-4, "latency {latency} s (5.000 ms measured on the whole survey)");
    let b_mean = doc["iso230_2"]["B_mean"].as_f64().unwrap();
    assert!((b_mean + 0.008).abs() < 5e-4, "mean reversal {b_mean} deg (fig8's backlash 0.008)");
}
