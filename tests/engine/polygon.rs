//! A polygon calibrated in place against the simulators' truth (issue 48):
//! a 24-face polygon whose certificate is stale at one face (face 5 off by
//! 1.5 arcsec, the others exact) on a quiet positioner whose error 24
//! faces resolve (orders 1 to 3 and backlash, its noise 0.04 arcsec, so that
//! a face can be measured to better than the stale certificate is off), 4
//! runs both ways. Read where
//! it stands, the certificate's error goes into every angle at face 5 and
//! so into the table; turned by one face between runs on the simulated
//! index stage (`--polygon-turns 0,1`), the closure measures every face,
//! names face 5 stale and the table comes out without its error.
//!
//! Required, each tolerance from the closure's own statistics: every
//! measured face (its mean taken out, as the certificate's convention
//! leaves one constant free) within 4 of its stated standard uncertainty
//! of the truth, their rms (four surveys) within 2x the autocollimator's
//! noise limit; face 5, and no other, stale; the table's true error (95th
//! percentile) 3 times below the one read where the polygon stands, and
//! within what the faces' own uncertainty adds (`2 u`, in quadrature) to
//! that of the same survey given an exact certificate.

use super::coverage::{Case, run_case, survey};
use survey_processing::model::Model;

/// Orders 1 to 3 (within what 24 faces resolve), backlash, 0.04 arcsec of noise.
const QUIET: &str = "[design]\ngear_ratios = []\ntooth_counts = []\n\n\
    [[effect]]\nkind = \"eccentricity\"\ncycles_per_rev = 1\namplitude_deg = 0.003\nphase_deg = 20.0\n\n\
    [[effect]]\nkind = \"ellipticity\"\ncycles_per_rev = 2\namplitude_deg = 0.001\nphase_deg = 70.0\n\n\
    [[effect]]\nkind = \"harmonic\"\ncycles_per_rev = 3\namplitude_deg = 0.0005\nphase_deg = 140.0\n\n\
    [[effect]]\nkind = \"backlash\"\namplitude_deg = 0.0004\n\n\
    [[effect]]\nkind = \"noise\"\nsigma_deg = 0.00001\n";

/// The truth: up to about 0.5 arcsec, no mean.
fn truth() -> Vec<f64> {
    (0..24).map(|k| 0.4 * (k as f64 * 0.7).sin() + 0.15 * (k as f64 * 2.3).cos()).collect()
}

fn list(v: &[f64]) -> String {
    v.iter().map(|x| format!("{x:.6}")).collect::<Vec<_>>().join(", ")
}

/// The quiet positioner and the polygon, its certificate stale or exact.
fn model_text(stale: bool) -> &'static str {
    let truth = truth();
    let certificate: Vec<f64> =
        truth.iter().enumerate().map(|(k, t)| if stale && k == 5 { t + 1.5 } else { *t }).collect();
    let text = QUIET.to_string()
        + &format!(
            "\n[polygon]\nface_errors_arcsec = [{}]\ncertificate_arcsec = [{}]\n",
            list(&truth),
            list(&certificate)
        );
    Box::leak(text.into_boxed_str())
}

fn case(name: &'static str, args: &str, stale: bool) -> Case {
    let file = model_text(stale);
    Case {
        name,
        args: args.split_whitespace().map(String::from).collect(),
        model: Model::parse(file, "model.toml").unwrap(),
        model_file: Some(file),
    }
}

const ARGS: &str = "--reference autocollimator --points 24 --runs 4 --bidirectional";

#[test]
fn a_polygon_turned_between_runs_is_calibrated_in_place_and_its_stale_face_found() {
    let turned_args = format!("{ARGS} --polygon-turns 0,1");
    // The closure's own figures, from four surveys (seeds 1 to 4): one
    // realisation's rms over 24 faces varies by about 30 % (the faces'
    // errors are correlated along the chain), four pool it to about 15 %.
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model.toml");
    std::fs::write(&model, model_text(true)).unwrap();
    let (mut sum2, mut limit2, mut u_used) = (0.0, 0.0, 0.0f64);
    for seed in 1..=4u64 {
        let db = dir.path().join(format!("s{seed}.db"));
        let seed_s = seed.to_string();
        let mut run: Vec<&str> = vec!["run", "--json", "--seed", &seed_s, "--model", model.to_str().unwrap()];
        run.extend(turned_args.split_whitespace());
        let done = survey(&db, &run);
        let p = &done["process"]["polygon"];
        let list = |key: &str| -> Vec<f64> { p[key].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect() };
        let (measured, u) = (list("face_errors_arcsec"), list("face_u_arcsec"));
        let mean = measured.iter().sum::<f64>() / 24.0;
        for (k, t) in truth().iter().enumerate() {
            let off = (measured[k] - mean - t).abs();
            assert!(off < 4.0 * u[k], "seed {seed} face {k}: {off:.3} arcsec off the truth, u {:.3}", u[k]);
            sum2 += off * off;
        }
        // The autocollimator's noise limit: the closure's standard
        // uncertainty were its noise (0.1 arcsec a reading) the only
        // scatter, the stated u scaled by 0.1 over the scatter of one reading.
        let sd = p["reading_sd_arcsec"].as_f64().unwrap();
        limit2 += (u[0] * 0.1 / sd).powi(2) * 24.0;
        eprintln!(
            "seed {seed}: faces measured to {:.3} arcsec (u), one reading {sd:.3} arcsec, stale {}",
            u[0], p["stale_faces"]
        );
        assert_eq!(p["stale_faces"], serde_json::json!([5]), "seed {seed}: {p}");
        u_used = u_used.max(p["u_deg"].as_f64().unwrap());
    }
    let (rms, limit) = ((sum2 / 96.0).sqrt(), (limit2 / 96.0).sqrt());
    eprintln!("faces {rms:.3} arcsec rms off the truth; the autocollimator's noise limit {limit:.3} arcsec");
    assert!(rms <= 2.0 * limit, "faces {rms:.3} arcsec rms off the truth, the noise limit {limit:.3}");
    // The table against the truth.
    let where_it_stands = run_case(&case("stale certificate, polygon where it stands", ARGS, true), 1..=1);
    let turned = run_case(&case("stale certificate, polygon turned 0,1", &turned_args, true), 1..=1);
    let exact = run_case(&case("exact certificate, polygon where it stands", ARGS, false), 1..=1);
    eprintln!(
        "table's true error p95: where it stands {:.2e} deg, turned {:.2e} deg, exact certificate {:.2e} deg",
        where_it_stands.p95, turned.p95, exact.p95
    );
    assert!(3.0 * turned.p95 < where_it_stands.p95, "{:.2e} against {:.2e}", turned.p95, where_it_stands.p95);
    let allowed = exact.p95.hypot(2.0 * u_used);
    assert!(turned.p95 <= allowed, "{:.2e} against {:.2e} (u of the faces used {u_used:.2e})", turned.p95, allowed);
    assert!(turned.coverage >= 0.95, "U covers {:.1} %", 100.0 * turned.coverage);
}

/// The quiet positioner with an exact certificate, drifting by `rate` deg a
/// run (a ramp in time) when `rate` is not zero.
fn drifting(rate: f64) -> String {
    let drift = if rate == 0.0 {
        String::new()
    } else {
        format!("\n[[effect]]\nkind = \"drift\"\nrate_deg_per_run = {rate}\n")
    };
    QUIET.to_string() + &drift
}

/// `survey run --json` of `model` with `args`, seed `seed`: the processing's
/// drift in time and whether the table is a result.
fn drift_of(dir: &std::path::Path, model: &str, args: &str, seed: u64) -> (serde_json::Value, serde_json::Value) {
    let path = dir.join(format!("m{seed}-{}.toml", args.len()));
    std::fs::write(&path, model).unwrap();
    let db = dir.join(format!("d{seed}-{}-{}.db", args.len(), model.len()));
    let seed_s = seed.to_string();
    let mut run: Vec<&str> = vec!["run", "--json", "--seed", &seed_s, "--model", path.to_str().unwrap()];
    run.extend(args.split_whitespace());
    let done = survey(&db, &run);
    (done["process"]["drift_in_time"].clone(), done["process"]["predicted"]["not_a_result"].clone())
}

/// Turning the polygon is not a drift (issue 48: each turn reads its own
/// faces and the stage's own error at every target, and the stage lands
/// each run a little differently; compared across turns, 5 of 6 seeds read
/// that as a drift no straight line takes, NOT A RESULT, and 4 of 6
/// "corrected" a false drift of 4.6e-4 to 1.07e-3 deg/h). Six seeds of the
/// quiet positioner turned 0,1 over 4 runs: none made no result by its
/// drift, none
/// corrected (the slope is tested at 1 %: 6 seeds make a false correction
/// a 6 % event at worst, and it would show as a drift, which the assertion
/// names). And a real drift is still found with turns: 0.002 deg a run (a
/// ramp) over 6 runs in 2 turns (3 degrees of freedom against the stage's
/// landing) is corrected in each of three seeds, what it makes over the
/// survey within 4.5 combined standard errors of the same survey's without
/// turns (Student's 3 degrees of freedom put 2 % of draws past 4.5).
#[test]
fn turning_the_polygon_is_not_a_drift_and_a_real_drift_is_still_found() {
    let dir = tempfile::tempdir().unwrap();
    let quiet = drifting(0.0);
    let turned = format!("{ARGS} --polygon-turns 0,1");
    for seed in 1..=6u64 {
        let (d, not_a_result) = drift_of(dir.path(), &quiet, &turned, seed);
        eprintln!("seed {seed}, no drift, turned: {d}");
        // (24 faces leave this quiet table "no better than native" whatever
        // the drift: that is the prediction's, said beside; the drift's is
        // `drift-not-corrected`.)
        assert_ne!(not_a_result, "drift-not-corrected", "seed {seed}: {d}");
        assert_eq!(d["corrected"], false, "seed {seed}: a false drift corrected: {d}");
        assert_eq!(d["left_beyond_doubt"], false, "seed {seed}: {d}");
    }
    let ramp = drifting(0.002);
    let six = ARGS.replace("--runs 4", "--runs 6");
    assert_ne!(six, ARGS);
    for seed in 1..=3u64 {
        let (t, not_a_result) = drift_of(dir.path(), &ramp, &format!("{six} --polygon-turns 0,1"), seed);
        let (u, _) = drift_of(dir.path(), &ramp, &six, seed);
        eprintln!("seed {seed}, 0.002 deg a run: turned {t}; where it stands {u}");
        assert_eq!(t["corrected"], true, "seed {seed}: the drift not found with turns: {t}");
        assert_eq!(u["corrected"], true, "seed {seed}: the drift not found without turns: {u}");
        assert_ne!(not_a_result, "drift-not-corrected", "seed {seed}: {t}");
        // Over the survey: the simulated drift grows with the plan's steps,
        // and the stage's turns add time between the runs without steps (the
        // turned survey's slope in time is 1.2 % lower for it: its runs take
        // 1.2 % longer); over the survey the two are the same drift.
        let over = |d: &serde_json::Value| {
            let duration = d["duration_h"].as_f64().unwrap();
            (d["over_survey_deg"].as_f64().unwrap(), d["slope_se_deg_per_h"].as_f64().unwrap() * duration)
        };
        let ((bt, st), (bu, su)) = (over(&t), over(&u));
        assert!(
            (bt - bu).abs() < 4.5 * st.hypot(su),
            "seed {seed}: over the survey turned {bt:.3e} +/- {st:.1e} deg, without {bu:.3e} +/- {su:.1e}"
        );
    }
}
