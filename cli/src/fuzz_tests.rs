//! Every parser of user input, fed random bytes and random mutations of
//! valid files: an error names the file (and the line or key where there is
//! one), never a panic; what parses is within the stated ranges and can be
//! used (a configuration's timing, a CSV's processing) without a panic.
//!
//! The inputs: the survey CSV (`import`), the positioner model (`--model`,
//! `--design`, `model-gap`), the configuration (`--config`) and the recipe
//! (`--recipe`). Mutations: bytes flipped, inserted and deleted; lines
//! duplicated and dropped; numbers replaced by extreme ones (nan, inf, 1e308,
//! -0, 4294967296, ...).

use proptest::prelude::*;
use survey_bench::{PlanOverrides, configured_estimate, configured_plan};
use survey_lab::csvio::{MAX_ABS_ANGLE_DEG, parse_survey_csv};
use survey_plan::ScanMode;
use survey_processing::model::Model;
use survey_store::config::SurveyConfig;
use survey_tables::recipe::Recipe;

const CONFIGS: [&str; 5] = [
    include_str!("../../examples/config/canopen-emscon.toml"),
    include_str!("../../examples/config/modbus-emscon.toml"),
    include_str!("../../examples/config/modbus-rtu-emscon.toml"),
    include_str!("../../examples/config/scpi-elcomat.toml"),
    include_str!("../../examples/config/scpi-serial-elevation.toml"),
];

const MODEL: &str = "[design]\ngear_ratios = [12]\ntooth_counts = [216]\nencoder_heads = 2\n\n\
[[effect]]\nkind = \"gear_pass\"\ncycles_per_rev = 12\namplitude_deg = 0.006\nphase_deg = 30.0\n\n\
[[effect]]\nkind = \"backlash\"\namplitude_deg = 0.004\n\n[[effect]]\nkind = \"drift\"\nrate_deg_per_run = 0.001\n\n\
[[effect]]\nkind = \"noise\"\nsigma_deg = 0.0005\n";

/// A small valid survey: 8 targets x 2 runs x both directions, with times.
fn csv() -> String {
    let mut s = String::from("run,direction,target_deg,readout_deg,actual_deg,timestamp_s\n");
    let mut t = 0.0;
    for run in 1..=2 {
        for (dir, order) in [("forward", [0, 1, 2, 3, 4, 5, 6, 7]), ("reverse", [7, 6, 5, 4, 3, 2, 1, 0])] {
            for k in order {
                let target = f64::from(k) * 45.0;
                let e = 0.01 * (f64::from(k) * 0.7).sin() + if dir == "forward" { 0.001 } else { -0.001 };
                t += 2.5;
                s += &format!("{run},{dir},{target},{target},{},{t}\n", target - e);
            }
        }
    }
    s
}

#[derive(Debug, Clone)]
enum Mutation {
    Flip(usize, u8),
    Insert(usize, u8),
    Delete(usize),
    DuplicateLine(usize),
    DropLine(usize),
    Number(usize, &'static str),
}

const EXTREMES: [&str; 14] = [
    "nan",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e19",
    "-0",
    "0",
    "4294967296",
    "-1",
    "1e-320",
    "18446744073709551616",
    "\"x\"",
    "[]",
];

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Mutation::Flip(i, b)),
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Mutation::Insert(i, b)),
        any::<usize>().prop_map(Mutation::Delete),
        any::<usize>().prop_map(Mutation::DuplicateLine),
        any::<usize>().prop_map(Mutation::DropLine),
        (any::<usize>(), 0..EXTREMES.len()).prop_map(|(i, k)| Mutation::Number(i, EXTREMES[k])),
    ]
}

fn apply(text: &str, mutations: &[Mutation]) -> String {
    let mut bytes = text.as_bytes().to_vec();
    for m in mutations {
        let n = bytes.len().max(1);
        match *m {
            Mutation::Flip(i, b) if !bytes.is_empty() => bytes[i % n] ^= b | 1,
            Mutation::Insert(i, b) => bytes.insert(i % (bytes.len() + 1), b),
            Mutation::Delete(i) if !bytes.is_empty() => {
                bytes.remove(i % n);
            }
            Mutation::DuplicateLine(i) | Mutation::DropLine(i) => {
                let text = String::from_utf8_lossy(&bytes).into_owned();
                let mut lines: Vec<&str> = text.lines().collect();
                if !lines.is_empty() {
                    let k = i % lines.len();
                    if matches!(m, Mutation::DuplicateLine(_)) {
                        lines.insert(k, lines[k]);
                    } else {
                        lines.remove(k);
                    }
                }
                bytes = (lines.join("\n") + "\n").into_bytes();
            }
            Mutation::Number(i, with) => {
                // Replace the i-th number (a run of digits, '.', 'e', '-') by `with`.
                let text = String::from_utf8_lossy(&bytes).into_owned();
                let starts: Vec<usize> = text
                    .char_indices()
                    .filter(|&(k, c)| c.is_ascii_digit() && (k == 0 || !text.as_bytes()[k - 1].is_ascii_alphanumeric()))
                    .map(|(k, _)| k)
                    .collect();
                if !starts.is_empty() {
                    let a = starts[i % starts.len()];
                    let len = text[a..]
                        .find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | 'e' | 'E' | '-' | '+')))
                        .unwrap_or(text.len() - a);
                    bytes = format!("{}{with}{}", &text[..a], &text[a + len..]).into_bytes();
                }
            }
            _ => {}
        }
    }
    String::from_utf8_lossy(&bytes).into_owned()
}

fn inputs(seed: String) -> impl Strategy<Value = String> {
    prop_oneof![
        proptest::collection::vec(mutation(), 1..6).prop_map(move |ms| apply(&seed, &ms)),
        proptest::collection::vec(any::<u8>(), 0..200).prop_map(|b| String::from_utf8_lossy(&b).into_owned()),
    ]
}

/// Every numeric key of `[timing]`.
const TIMING_KEYS: [&str; 21] = [
    "call_timeout_s",
    "measure_timeout_s",
    "move_margin_s",
    "poll_interval_s",
    "dwell_s",
    "max_retries",
    "retry_backoff_s",
    "locate_points",
    "velocity_deg_s",
    "accel_deg_s2",
    "settle_window_deg",
    "settle_stable_s",
    "settle_poll_s",
    "settle_time_s",
    "scan_velocity_deg_s",
    "calibration_velocity_deg_s",
    "capture_period_s",
    "stream_period_s",
    "fetch_interval_s",
    "beam_wait_s",
    "beam_retry_s",
];

/// A value for a timing key: any magnitude from 1e-320 to 1e308, either
/// sign, any float, a small integer.
fn timing_value() -> impl Strategy<Value = String> {
    prop_oneof![
        (-320i32..=308, 1u8..10, any::<bool>())
            .prop_map(|(k, m, neg)| format!("{}{m}e{k}", if neg { "-" } else { "" })),
        any::<f64>().prop_filter("a TOML float", |f| f.is_finite()).prop_map(|f| format!("{f:e}")),
        (0u32..100_000).prop_map(|n| n.to_string()),
    ]
}

/// An example configuration with up to 6 of its `[timing]` keys set to
/// [`timing_value`]s (after its own `[timing]` header, or a new one), and
/// the keys set.
fn timing_inputs() -> impl Strategy<Value = (String, Vec<&'static str>)> {
    (0..CONFIGS.len(), proptest::collection::btree_map(0..TIMING_KEYS.len(), timing_value(), 1..6)).prop_map(
        |(k, values)| {
            let lines: String = values.iter().map(|(key, v)| format!("{} = {v}\n", TIMING_KEYS[*key])).collect();
            let seed = CONFIGS[k];
            let text = match seed.find("[timing]\n") {
                Some(at) => format!("{}{lines}{}", &seed[..at + 9], &seed[at + 9..]),
                None => format!("{seed}\n[timing]\n{lines}"),
            };
            (text, values.keys().map(|key| TIMING_KEYS[*key]).collect())
        },
    )
}

fn config_inputs() -> impl Strategy<Value = String> {
    (0..CONFIGS.len(), proptest::collection::vec(mutation(), 1..6)).prop_map(|(k, ms)| apply(CONFIGS[k], &ms))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn survey_csv(text in inputs(csv())) {
        match parse_survey_csv(&text, "in.csv") {
            Ok(samples) => {
                for s in &samples {
                    for v in [s.target_deg, s.readout_deg, s.actual_deg] {
                        prop_assert!(v.is_finite() && v.abs() <= MAX_ABS_ANGLE_DEG);
                    }
                    prop_assert!(s.timestamp_s.is_none_or(f64::is_finite));
                }
                // What imports can be processed, or refused, without a panic.
                let _ = survey_processing::iso230::iso230_2(&samples);
                let _ = survey_tables::pipeline::process(&samples, &Default::default(), None);
            }
            Err(e) => prop_assert!(e.to_string().starts_with("in.csv"), "{e}"),
        }
    }

    #[test]
    fn model_file(text in inputs(MODEL.to_string())) {
        match Model::parse(&text, "m.toml") {
            Ok(model) => {
                // What parses evaluates to finite errors, and writes back to a file that parses.
                for k in 0..8 {
                    let e = model.repeatable_error_deg(f64::from(k) * 45.0, survey_processing::Direction::Forward);
                    prop_assert!(e.is_finite());
                }
                let again = Model::parse(&model.to_toml(), "again.toml");
                prop_assert!(again.is_ok(), "{:?}", again.err());
            }
            Err(e) => prop_assert!(e.to_string().starts_with("m.toml"), "{e}"),
        }
    }

    #[test]
    fn configuration(text in config_inputs()) {
        match SurveyConfig::parse(&text, "c.toml") {
            Ok(cfg) => {
                // The timing turns into durations (this panicked on 1e19 s).
                let _ = cfg.timing();
            }
            // The file, the line and the dotted key (issue 42).
            Err(e) => prop_assert!(e.to_string().starts_with("c.toml:"), "{e}"),
        }
    }

    #[test]
    fn timing_section((text, keys) in timing_inputs()) {
        match SurveyConfig::parse(&text, "c.toml") {
            Ok(cfg) => {
                // Every duration the timing makes converts, for a plan in
                // either scan mode: the estimate `run` prints (every move
                // and pass summed), and the deadline of the longest move.
                let t = cfg.timing();
                let longest = survey_plan::move_time(362.0, t.velocity_deg_s, t.accel_deg_s2);
                prop_assert!(std::time::Duration::try_from_secs_f64(longest).is_ok(), "{longest}");
                for scan in [ScanMode::Step, ScanMode::Continuous] {
                    let overrides =
                        PlanOverrides { points: Some(360), runs: Some(5), bidirectional: true, scan: Some(scan), smrs: None };
                    if let Ok(plan) = configured_plan(&cfg, overrides, std::path::Path::new("c.toml")) {
                        let _ = configured_estimate(&cfg, &plan);
                    }
                }
            }
            Err(e) => {
                let e = e.to_string();
                prop_assert!(e.starts_with("c.toml:"), "{e}");
                // A bad value is named by its key, whatever is wrong with it.
                prop_assert!(keys.iter().any(|k| e.contains(k)), "{keys:?}: {e}");
            }
        }
    }

    #[test]
    fn recipe_file(text in inputs(Recipe::default().to_toml())) {
        match Recipe::parse(&text, "r.toml") {
            Ok(recipe) => {
                let again = Recipe::parse(&recipe.to_toml(), "again.toml");
                prop_assert!(again.is_ok(), "{:?}", again.err());
            }
            Err(e) => prop_assert!(e.to_string().starts_with("r.toml"), "{e}"),
        }
    }
}

#[test]
fn the_seeds_are_valid_and_the_mutations_reach_their_numbers() {
    assert_eq!(parse_survey_csv(&csv(), "in.csv").map(|s| s.len()).ok(), Some(32));
    assert!(Model::parse(MODEL, "m.toml").is_ok());
    assert!(Recipe::parse(&Recipe::default().to_toml(), "r.toml").is_ok());
    for c in CONFIGS {
        assert!(SurveyConfig::parse(c, "c.toml").is_ok());
    }
    // A number replaced in place: the first number of the model is its gear ratio.
    let m = apply(MODEL, &[Mutation::Number(0, "1e19")]);
    assert!(m.starts_with("[design]\ngear_ratios = [1e19]"), "{m}");
    let e = Model::parse(&m, "m.toml").unwrap_err().to_string();
    assert!(e.starts_with("m.toml:2: design.gear_ratios"), "{e}");
}

#[test]
fn physically_absurd_model_values_are_refused_with_the_reason() {
    let amplitude = MODEL.replace("amplitude_deg = 0.006", "amplitude_deg = 5.0");
    let e = Model::parse(&amplitude, "m.toml").unwrap_err().to_string();
    assert!(e.starts_with("m.toml:9:") && e.contains("arcseconds or radians"), "{e}");
    let nan = MODEL.replace("phase_deg = 30.0", "phase_deg = nan");
    let e = Model::parse(&nan, "m.toml").unwrap_err().to_string();
    assert!(e.starts_with("m.toml:10:") && e.contains("finite"), "{e}");
    let teeth = MODEL.replace("[216]", "[4294967295]");
    assert!(Model::parse(&teeth, "m.toml").unwrap_err().to_string().contains("tooth count"));
}
