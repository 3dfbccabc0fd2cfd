//! The table's stated uncertainty `U` (`table_u_deg`) and its predicted
//! corrected peak against the simulators' truth, where the project's
//! assumptions fail (issue 20 item 1): a table that nulls lines it cannot
//! place, a sparse survey of a positioner whose design is unknown, a partial
//! arc. Each case is acquired and processed by the built binary; the
//! table's true error at every row in its range (the table's value against
//! the positioner's true error at the readout, `E(r) = r - theta` with
//! `theta + e(theta) = r`, both columns, the mean over the range removed:
//! the zero reference) is set beside `U`.
//!
//! Required in each case, over its seeds pooled: at least 95 % of the rows'
//! `|true error - table|` within `U` (the contract's definition), and `U` at
//! most 3 times the 95th percentile of those sizes (not inflated: the
//! brief's "about 3 times"; a sinusoid left whole has `U / p95` near 1, a
//! possible alias counted as one near 1.5 when it is one), less the
//! reference's systematic part: that is its specification's bound (the
//! tracker's MPE through the survey's geometry), which one SMR cannot
//! separate from the positioner's error, not the simulated tracker's own
//! error (the bench's typical tracker is well inside its MPE). The predicted
//! corrected peak must not be better than the table's true peak error in
//! its range less the noise the prediction carries (it is made at the
//! targets, with the noise of one sample; the true error is of the mean).
//!
//! The tests run two seeds per case (each case 2 to 8 s in a debug build);
//! `SURVEY_COVERAGE_SEEDS=N cargo test --test engine coverage -- --ignored
//! --nocapture` runs `N` seeds of every case and prints the figures
//! `docs/validation/uncertainty.md` reports.

use std::path::Path;
use std::process::Command;
use survey_processing::Direction;
use survey_processing::model::Model;

const BIN: &str = env!("CARGO_BIN_EXE_survey");

/// The fig8 positioner with no `[design]`: the processing does not know its parts.
const FIG8_NO_DESIGN: &str = include_str!("../fixtures/fig8-no-design.toml");

pub fn survey(db: &Path, args: &[&str]) -> serde_json::Value {
    let out = Command::new(BIN).arg("--db").arg(db).args(args).env_remove("RUST_LOG").output().unwrap();
    assert!(out.status.success(), "survey {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("one JSON document")
}

/// One case: the `survey run` arguments (beside `--seed` and `--json`) and the model simulated.
pub struct Case {
    pub name: &'static str,
    pub args: Vec<String>,
    pub model: Model,
    /// A model file the run needs (`--model`), written into the temporary folder.
    pub model_file: Option<&'static str>,
}

/// Every case of issue 20 item 1.
pub fn cases() -> Vec<Case> {
    let preset = |name: &str| survey_sims::Preset::by_name(name).unwrap().model;
    let args = |a: &str| a.split_whitespace().map(String::from).collect::<Vec<_>>();
    vec![
        Case {
            name: "default bench, 360 points",
            args: args("--points 360 --bidirectional"),
            model: preset("fig8"),
            model_file: None,
        },
        Case {
            name: "autocollimator, 24 faces",
            args: args("--points 24 --reference autocollimator --bidirectional"),
            model: preset("fig8"),
            model_file: None,
        },
        Case {
            name: "unknown design, 36 points, 2 runs",
            args: args("--points 36 --runs 2 --bidirectional"),
            model: Model::parse(FIG8_NO_DESIGN, "fig8-no-design.toml").unwrap(),
            model_file: Some(FIG8_NO_DESIGN),
        },
        Case {
            name: "partial arc (fig1), 101 points",
            args: args("--preset fig1 --points 101 --bidirectional"),
            model: preset("fig1"),
            model_file: None,
        },
        Case {
            name: "two design harmonics at one bin (fig4, 288 points)",
            args: args("--preset fig4 --points 288 --runs 3 --bidirectional"),
            model: preset("fig4"),
            model_file: None,
        },
    ]
}

/// Further cases for the Monte Carlo only (other samplings of the same physics).
pub fn variants() -> Vec<Case> {
    let preset = |name: &str| survey_sims::Preset::by_name(name).unwrap().model;
    let args = |a: &str| a.split_whitespace().map(String::from).collect::<Vec<_>>();
    let case = |name, a: &str, model: &str| Case { name, args: args(a), model: preset(model), model_file: None };
    vec![
        case("default bench, 1800 points", "--points 1800 --bidirectional", "fig8"),
        case("autocollimator, 36 faces", "--points 36 --reference autocollimator --bidirectional", "fig8"),
        case("autocollimator, 12 faces", "--points 12 --reference autocollimator --bidirectional", "fig8"),
        case("fig8 tracker, 30 points (20 and 40 at bin 10)", "--points 30 --bidirectional", "fig8"),
        case("fig4, 720 points (648 at 72)", "--points 720 --runs 3 --bidirectional --preset fig4", "fig4"),
        case("partial arc (fig1), 41 points", "--preset fig1 --points 41 --bidirectional", "fig1"),
        Case {
            name: "unknown design, 48 points, 2 runs",
            args: args("--points 48 --runs 2 --bidirectional"),
            model: Model::parse(FIG8_NO_DESIGN, "fig8-no-design.toml").unwrap(),
            model_file: Some(FIG8_NO_DESIGN),
        },
        Case {
            name: "unknown design, 360 points",
            args: args("--points 360 --bidirectional"),
            model: Model::parse(FIG8_NO_DESIGN, "fig8-no-design.toml").unwrap(),
            model_file: Some(FIG8_NO_DESIGN),
        },
    ]
}

/// `E(r)`: the true error at readout `r` (`theta + e(theta) = r`, fixed point).
fn true_error(model: &Model, r: f64, dir: Direction) -> f64 {
    let mut theta = r;
    for _ in 0..50 {
        theta = r - model.repeatable_error_deg(theta, dir);
    }
    model.repeatable_error_deg(theta, dir)
}

/// The table's true errors at its rows within `[lo, hi]` (every column), mean removed.
fn true_errors(table: &Path, model: &Model, lo: f64, hi: f64) -> Vec<f64> {
    let text = std::fs::read_to_string(table).unwrap();
    let mut res = Vec::new();
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        let r = v[0];
        let inside = (lo..=hi).contains(&r) || (lo..=hi).contains(&(r - 360.0));
        if !inside {
            continue;
        }
        let dirs: &[Direction] =
            if v.len() == 3 { &[Direction::Forward, Direction::Reverse] } else { &[Direction::Forward] };
        for (i, &dir) in dirs.iter().enumerate() {
            let table_value = v[1 + i];
            // A one-column table serves both directions: both are its error.
            if v.len() == 2 {
                for d in [Direction::Forward, Direction::Reverse] {
                    res.push(true_error(model, r, d) - table_value);
                }
            } else {
                res.push(true_error(model, r, dir) - table_value);
            }
        }
    }
    let mean = res.iter().sum::<f64>() / res.len() as f64;
    res.iter().map(|r| r - mean).collect()
}

/// The figures of one case over its seeds.
#[derive(Debug)]
pub struct Figures {
    pub coverage: f64,
    pub p95: f64,
    pub widest_u: f64,
    /// The widest `U` without the reference's systematic part (`sqrt(U^2 - (k u_sys)^2)`).
    pub widest_u_beside_reference: f64,
    pub narrowest_u: f64,
    /// The smallest predicted corrected peak over the largest true peak of the table (per seed).
    pub prediction_ratio: f64,
}

pub fn run_case(case: &Case, seeds: std::ops::RangeInclusive<u64>) -> Figures {
    let dir = tempfile::tempdir().unwrap();
    let mut args = case.args.clone();
    if let Some(text) = case.model_file {
        let path = dir.path().join("model.toml");
        std::fs::write(&path, text).unwrap();
        args.extend(["--model".to_string(), path.display().to_string()]);
    }
    let (mut within, mut total) = (0usize, 0usize);
    let mut sizes = Vec::new();
    let mut us = Vec::new();
    let mut beside = 0.0f64;
    let mut prediction_ratio = f64::INFINITY;
    for seed in seeds {
        let db = dir.path().join(format!("s{seed}.db"));
        let seed_s = seed.to_string();
        let mut run: Vec<&str> = vec!["run", "--seed", &seed_s, "--json"];
        run.extend(args.iter().map(String::as_str));
        survey(&db, &run);
        {
            let t = dir.path().join(format!("t{seed}.csv"));
            let p = survey(&db, &["process", "--table-out", t.to_str().unwrap(), "--json"]);
            let u = p["uncertainty"]["table_u_deg"].as_f64().unwrap();
            let k = p["uncertainty"]["k"].as_f64().unwrap();
            let combined = p["uncertainty"]["combined_u_deg"].as_f64().unwrap();
            assert!((u / (k * combined) - 1.0).abs() < 1e-9, "U = k u: {}", p["uncertainty"]);
            let systematic = p["uncertainty"]["budget"]
                .as_array()
                .unwrap()
                .iter()
                .find(|c| c["source"] == "reference instrument, systematic")
                .map_or(0.0, |c| c["u_deg"].as_f64().unwrap());
            beside = beside.max((u * u - (k * systematic).powi(2)).max(0.0).sqrt());
            let predicted = p["predicted"]["corrected_peak_deg"].as_f64().unwrap();
            // The table's range: the measured span (a full circle: all of it).
            let (lo, hi) = span(&db);
            let r = true_errors(&t, &case.model, lo, hi);
            let inside = r.iter().filter(|x| x.abs() <= u).count();
            let peak = r.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            eprintln!(
                "{} seed {seed}: U = {u:.2e} deg (k = {k:.2}), true error rms {:.2e} peak {peak:.2e}, {inside} of {} \
                 within; predicted corrected peak {predicted:.2e}",
                case.name,
                (r.iter().map(|x| x * x).sum::<f64>() / r.len() as f64).sqrt(),
                r.len()
            );
            within += inside;
            total += r.len();
            sizes.extend(r.iter().map(|x| x.abs()));
            us.push(u);
            prediction_ratio = prediction_ratio.min(predicted / peak);
        }
    }
    sizes.sort_by(f64::total_cmp);
    let p95 = sizes[(0.95 * sizes.len() as f64) as usize];
    Figures {
        coverage: within as f64 / total as f64,
        p95,
        widest_u: us.iter().fold(0.0f64, |m, u| m.max(*u)),
        widest_u_beside_reference: beside,
        narrowest_u: us.iter().fold(f64::INFINITY, |m, u| m.min(*u)),
        prediction_ratio,
    }
}

/// The measured span of the latest survey in `db` (its first and last target).
fn span(db: &Path) -> (f64, f64) {
    let csv = db.with_extension("survey.csv");
    let out = Command::new(BIN).arg("--db").arg(db).args(["export", "--csv"]).arg(&csv).output().unwrap();
    assert!(out.status.success());
    let text = std::fs::read_to_string(&csv).unwrap();
    let targets: Vec<f64> = text.lines().skip(1).map(|l| l.split(',').nth(2).unwrap().parse().unwrap()).collect();
    let lo = targets.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = targets.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if hi - lo > 359.0 { (0.0, 360.0) } else { (lo, hi) }
}

fn check(case: &Case, f: &Figures) {
    eprintln!(
        "{}: coverage {:.2} %, p95 {:.2e} deg, U {:.2e}..{:.2e} deg ({:.2} x p95; {:.2} x beside the reference's \
         systematic part), predicted / true peak >= {:.2}",
        case.name,
        100.0 * f.coverage,
        f.p95,
        f.narrowest_u,
        f.widest_u,
        f.widest_u / f.p95,
        f.widest_u_beside_reference / f.p95,
        f.prediction_ratio
    );
    assert!(f.coverage >= 0.95, "{}: only {:.2} % of the true errors within U", case.name, 100.0 * f.coverage);
    assert!(
        f.widest_u_beside_reference <= 3.0 * f.p95,
        "{}: U beside the reference's systematic part {:.2e} is more than 3 x the p95 {:.2e}",
        case.name,
        f.widest_u_beside_reference,
        f.p95
    );
}

#[test]
fn u_covers_what_the_table_leaves_in_every_case() {
    for case in cases() {
        let f = run_case(&case, 1..=2);
        check(&case, &f);
    }
}

#[test]
#[ignore = "Monte Carlo over many seeds: SURVEY_COVERAGE_SEEDS=N, figures for docs/validation/uncertainty.md"]
fn monte_carlo_figures() {
    let n: u64 = std::env::var("SURVEY_COVERAGE_SEEDS").ok().and_then(|s| s.parse().ok()).unwrap_or(10);
    // The cases of issue 20 are held to the requirements; the variants are
    // measured and printed (two are limits docs/validation/uncertainty.md
    // states: two real lines in one bin at 12 faces, and the precision of
    // the check points beside a decided line at 360 points of an unknown
    // design).
    let mut failed = Vec::new();
    for case in cases() {
        let f = run_case(&case, 1..=n);
        if std::panic::catch_unwind(|| check(&case, &f)).is_err() {
            failed.push(case.name);
        }
    }
    for case in variants() {
        let f = run_case(&case, 1..=n);
        if std::panic::catch_unwind(|| check(&case, &f)).is_err() {
            eprintln!("{}: outside the requirements (a limit when the docs name it)", case.name);
        }
    }
    assert!(failed.is_empty(), "{failed:?}");
}

/// Issue 49: the Figure 8 positioner with a ramp that grows within the runs
/// as between them (0.004 deg a run, thermal growth; 120 points, 3 runs
/// both ways). The drift term once looked only for a trend between runs:
/// the ramp entered the table as wrong backlash and direction-dependent
/// lines (coverage 62-67 %). Measured in time and corrected, `U` covers the
/// table's true error (the repeatable error, the drift's zero being the
/// table's) at the suite's requirement, and the survey says so.
#[test]
fn a_ramp_within_the_runs_is_measured_corrected_and_covered() {
    const RAMP: &str = concat!(
        include_str!("../../sims/presets/fig8.toml"),
        "\n[[effect]]\nkind = \"drift\"\nrate_deg_per_run = 0.004\nshape = \"ramp\"\n"
    );
    let case = Case {
        name: "a ramp within the runs (fig8, 0.004 deg a run), 120 points, 3 runs",
        args: ["--points", "120", "--runs", "3", "--bidirectional"].map(String::from).to_vec(),
        model: Model::parse(RAMP, "ramp.toml").unwrap(),
        model_file: Some(RAMP),
    };
    let f = run_case(&case, 1..=2);
    // Covered (measured 100 %; 62-67 % before). Not held to 3x: the check
    // points, measured after the runs while the ramp goes on, scatter by
    // what the straight line leaves of the simulated drift between their
    // runs (it grows with the plan's steps, not with time), and `U` counts
    // what they cannot exclude by that scatter (measured 5.7x beside the
    // reference's systematic part).
    assert!(f.coverage >= 0.95, "{}: only {:.2} % within U", case.name, 100.0 * f.coverage);
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("ramp.toml");
    std::fs::write(&model, RAMP).unwrap();
    let db = dir.path().join("r.db");
    let run = survey(
        &db,
        &["run", "--points", "120", "--runs", "3", "--bidirectional", "--seed", "3", "--json", "--verify", "--model"]
            .into_iter()
            .chain([model.to_str().unwrap()])
            .collect::<Vec<_>>(),
    );
    let d = &run["process"]["drift_in_time"];
    assert_eq!(d["corrected"], true, "{d}");
    // 3 runs of 0.004 deg: 0.012 over the survey, within 3 standard errors.
    let over = d["over_survey_deg"].as_f64().unwrap();
    assert!((over - 0.012).abs() < 5e-4, "{d}");
    assert!((run["iso230_2"]["B_mean"].as_f64().unwrap() + 0.008).abs() < 3e-4, "{}", run["iso230_2"]);
    // The verification carries its own drift: the ramp goes on through it,
    // measured from its own readings and corrected before it is judged.
    let v = &run["verify"]["drift_in_time"];
    assert_eq!(v["corrected"], true, "{v}");
    let (slope, survey_slope) = (v["slope_deg_per_h"].as_f64().unwrap(), d["slope_deg_per_h"].as_f64().unwrap());
    assert!(slope > 0.0 && (slope / survey_slope - 1.0).abs() < 0.5, "the same ramp: {v} against {d}");
}

/// Issue 49: a drift that steps between the runs (0.004 deg a run, the
/// axis constant within each run: a re-homing, a warm-up that settles
/// during the pause). Read in time, it is the ramp's slope between the
/// runs but nothing within them, and a straight line in time would put a
/// sawtooth of half a run's step into the passes.
#[test]
fn a_drift_that_steps_between_runs_is_covered_or_not_a_result() {
    const STEP: &str = concat!(
        include_str!("../../sims/presets/fig8.toml"),
        "\n[[effect]]\nkind = \"drift\"\nrate_deg_per_run = 0.004\nshape = \"step\"\n"
    );
    let case = Case {
        name: "a drift stepping between the runs (fig8, 0.004 deg a run), 120 points, 3 runs",
        args: ["--points", "120", "--runs", "3", "--bidirectional"].map(String::from).to_vec(),
        model: Model::parse(STEP, "step.toml").unwrap(),
        model_file: Some(STEP),
    };
    let f = run_case(&case, 1..=2);
    check(&case, &f);
}
