//! Tests of the ISO 230-2 statistics ([`super`]).

use super::*;
use proptest::prelude::*;
use std::path::Path;

fn sample(run: u32, direction: Direction, target_deg: f64, deviation: f64) -> Sample {
    Sample {
        run,
        direction,
        target_deg,
        readout_deg: target_deg,
        actual_deg: target_deg + deviation,
        timestamp_s: None,
    }
}

/// Samples at `target` in `direction`, one per run (runs from 1).
fn runs(direction: Direction, target: f64, deviations: &[f64]) -> Vec<Sample> {
    deviations.iter().enumerate().map(|(j, &x)| sample(j as u32 + 1, direction, target, x)).collect()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
}

#[track_caller]
fn assert_close(name: &str, got: f64, want: f64) {
    assert!(close(got, want), "{name}: got {got}, want {want}");
}

#[track_caller]
fn assert_some_close(name: &str, got: Option<f64>, want: f64) {
    match got {
        Some(g) => assert_close(name, g, want),
        None => panic!("{name}: got None, want {want}"),
    }
}

use Direction::{Forward as Up, Reverse as Down};

/// Two targets x 3 runs, bidirectional, round numbers.
///
/// ```text
/// target 0:  up   x = 1, 2, 3       mean  2    s 1    4s 4
///            down x = -1, -0.5, 0   mean -0.5  s 0.5  4s 2
///            B = 2 - (-0.5) = 2.5;  R = max(2*1 + 2*0.5 + 2.5, 4, 2) = max(5.5, 4, 2) = 5.5
///            x̄ = (2 - 0.5)/2 = 0.75
/// target 90: up   x = -2, 0, 2      mean  0    s 2    4s 8
///            down x = -4, -3, -2    mean -3    s 1    4s 4
///            B = 0 - (-3) = 3;      R = max(2*2 + 2*1 + 3, 8, 4) = max(9, 8, 4) = 9
///            x̄ = (0 - 3)/2 = -1.5
/// R_up = max(4, 8) = 8;  R_down = max(2, 4) = 4;  R = max(5.5, 9) = 9 (bidirectional term wins, not 8)
/// B = max(2.5, 3) = 3;   B_mean = (2.5 + 3)/2 = 2.75
/// E_up = 2 - 0 = 2;  E_down = -0.5 - (-3) = 2.5;
/// E = max(2, 0, -0.5, -3) - min(2, 0, -0.5, -3) = 2 - (-3) = 5 (not max(E_up, E_down) = 2.5)
/// M = 0.75 - (-1.5) = 2.25
/// A_up:   x̄+2s = 4, 4;      x̄-2s = 0, -4    -> 4 - (-4) = 8
/// A_down: x̄+2s = 0.5, -1;   x̄-2s = -1.5, -5 -> 0.5 - (-5) = 5.5
/// A = max(4, 0.5) - min(-4, -5) = 4 + 5 = 9
/// ```
fn case_one() -> Vec<Sample> {
    let mut s = Vec::new();
    // Interleave the groups so that grouping, not input order, does the work.
    s.extend(runs(Down, 90.0, &[-4.0, -3.0, -2.0]));
    s.extend(runs(Up, 0.0, &[1.0, 2.0, 3.0]));
    s.extend(runs(Up, 90.0, &[-2.0, 0.0, 2.0]));
    s.extend(runs(Down, 0.0, &[-1.0, -0.5, 0.0]));
    s.reverse();
    s
}

#[test]
fn hand_computed_bidirectional_r_and_e_over_both_directions() {
    let st = iso230_2(&case_one()).unwrap();
    assert_eq!(st.runs, 3);
    assert_eq!(st.targets.len(), 2);
    let (t0, t1) = (&st.targets[0], &st.targets[1]);
    assert_eq!(t0.target_deg, 0.0);
    assert_eq!(t1.target_deg, 90.0);

    let u0 = t0.up.as_ref().unwrap();
    let d0 = t0.down.as_ref().unwrap();
    assert_eq!(u0.n, 3);
    assert_close("t0 up mean", u0.mean, 2.0);
    assert_close("t0 up s", u0.s, 1.0);
    assert_close("t0 up R", u0.r, 4.0);
    assert_close("t0 down mean", d0.mean, -0.5);
    assert_close("t0 down s", d0.s, 0.5);
    assert_close("t0 down R", d0.r, 2.0);
    assert_some_close("t0 B", t0.b, 2.5);
    assert_close("t0 R", t0.r, 5.5);
    assert_some_close("t0 mean", t0.mean_bi, 0.75);

    let u1 = t1.up.as_ref().unwrap();
    let d1 = t1.down.as_ref().unwrap();
    assert_close("t1 up mean", u1.mean, 0.0);
    assert_close("t1 up s", u1.s, 2.0);
    assert_close("t1 down mean", d1.mean, -3.0);
    assert_close("t1 down s", d1.s, 1.0);
    assert_some_close("t1 B", t1.b, 3.0);
    assert_close("t1 R", t1.r, 9.0);
    assert_some_close("t1 mean", t1.mean_bi, -1.5);

    assert_some_close("R_up", st.r_up, 8.0);
    assert_some_close("R_down", st.r_down, 4.0);
    assert_close("R", st.r, 9.0);
    assert_some_close("B", st.b, 3.0);
    assert_some_close("B_mean", st.b_mean, 2.75);
    assert_some_close("E_up", st.e_up, 2.0);
    assert_some_close("E_down", st.e_down, 2.5);
    assert_close("E", st.e, 5.0);
    assert_some_close("M", st.m, 2.25);
    assert_some_close("A_up", st.a_up, 8.0);
    assert_some_close("A_down", st.a_down, 5.5);
    assert_close("A", st.a, 9.0);
}

/// Two targets x 4 runs, where 4 s wins R and the targets jitter within the tolerance.
///
/// ```text
/// target -10: up   x = 0, 0, 0, 4            mean 1   dev -1,-1,-1,3: ss 12, s = sqrt(12/3) = 2, 4s 8
///             down x = 1, 1, 1, 1            mean 1   s 0
///             B = 0;  R = max(2*2 + 0 + 0, 8, 0) = 8 (4 s_up wins);  x̄ = 1
/// target 20:  up   x = 2, 2, 2, 2            mean 2   s 0
///             down x = -2.5, -0.5, -0.5, -0.5 mean -1 dev -1.5,.5,.5,.5: ss 3, s 1, 4s 4
///             B = 3;  R = max(0 + 2 + 3, 0, 4) = 5;  x̄ = 0.5
/// R_up = 8, R_down = 4, R = max(8, 5) = 8
/// B = 3, B_mean = (0 + 3)/2 = 1.5
/// E_up = 2 - 1 = 1;  E_down = 1 - (-1) = 2;  E = max(1, 2, 1, -1) - min(...) = 2 - (-1) = 3
/// M = 1 - 0.5 = 0.5
/// A_up:   x̄+2s = 5, 2;  x̄-2s = -3, 2   -> 5 - (-3) = 8
/// A_down: x̄+2s = 1, 1;  x̄-2s = 1, -3   -> 1 - (-3) = 4
/// A = max(5, 1) - min(-3, -3) = 8
/// ```
#[test]
fn hand_computed_four_s_wins_and_targets_group_within_tolerance() {
    let mut s = Vec::new();
    s.extend(runs(Up, 20.0, &[2.0, 2.0, 2.0, 2.0]));
    s.extend(runs(Down, 20.0 + 5e-10, &[-2.5, -0.5, -0.5, -0.5]));
    s.extend(runs(Up, -10.0, &[0.0, 0.0, 0.0, 4.0]));
    s.extend(runs(Down, -10.0 - 4e-10, &[1.0, 1.0, 1.0, 1.0]));
    let st = iso230_2(&s).unwrap();
    assert_eq!(st.runs, 4);
    assert_eq!(st.targets.len(), 2, "targets within 1e-9 deg are one target");
    assert_eq!(st.targets[0].target_deg, -10.0 - 4e-10, "the smallest target of the group");
    assert_eq!(st.targets[1].target_deg, 20.0);
    let (t0, t1) = (&st.targets[0], &st.targets[1]);
    assert_close("t0 up s", t0.up.as_ref().unwrap().s, 2.0);
    assert_close("t0 down s", t0.down.as_ref().unwrap().s, 0.0);
    assert_some_close("t0 B", t0.b, 0.0);
    assert_close("t0 R", t0.r, 8.0);
    assert_close("t1 down s", t1.down.as_ref().unwrap().s, 1.0);
    assert_some_close("t1 B", t1.b, 3.0);
    assert_close("t1 R", t1.r, 5.0);

    assert_some_close("R_up", st.r_up, 8.0);
    assert_some_close("R_down", st.r_down, 4.0);
    assert_close("R", st.r, 8.0);
    assert_some_close("B", st.b, 3.0);
    assert_some_close("B_mean", st.b_mean, 1.5);
    assert_some_close("E_up", st.e_up, 1.0);
    assert_some_close("E_down", st.e_down, 2.0);
    assert_close("E", st.e, 3.0);
    assert_some_close("M", st.m, 0.5);
    assert_some_close("A_up", st.a_up, 8.0);
    assert_some_close("A_down", st.a_down, 4.0);
    assert_close("A", st.a, 8.0);
}

/// The forward half of `case_one`: A_up = 8, R_up = 8, E_up = 2 (see there).
/// The reverse half: A_down = 5.5, R_down = 4, E_down = 2.5.
#[test]
fn unidirectional_surveys_report_one_direction() {
    let forward: Vec<Sample> = case_one().into_iter().filter(|s| s.direction == Up).collect();
    let st = iso230_2(&forward).unwrap();
    assert_close("A", st.a, 8.0);
    assert_close("R", st.r, 8.0);
    assert_close("E", st.e, 2.0);
    assert_eq!((st.a_up, st.r_up, st.e_up), (Some(st.a), Some(st.r), Some(st.e)));
    assert_eq!((st.a_down, st.r_down, st.e_down), (None, None, None));
    assert_eq!((st.b, st.b_mean, st.m), (None, None, None));
    assert_eq!(st.runs, 3);
    for t in &st.targets {
        assert!(t.up.is_some() && t.down.is_none() && t.b.is_none() && t.mean_bi.is_none());
        assert_eq!(t.r, t.up.as_ref().unwrap().r);
    }

    let reverse: Vec<Sample> = case_one().into_iter().filter(|s| s.direction == Down).collect();
    let st = iso230_2(&reverse).unwrap();
    assert_close("A", st.a, 5.5);
    assert_close("R", st.r, 4.0);
    assert_close("E", st.e, 2.5);
    assert_eq!((st.a_down, st.r_down, st.e_down), (Some(st.a), Some(st.r), Some(st.e)));
    assert_eq!((st.a_up, st.r_up, st.e_up), (None, None, None));
    assert_eq!((st.b, st.b_mean, st.m), (None, None, None));
}

#[test]
fn serialises_with_the_contract_keys() {
    let st = iso230_2(&case_one()).unwrap();
    let v = serde_json::to_value(&st).unwrap();
    for key in ["A", "A_up", "A_down", "R", "R_up", "R_down", "B", "B_mean", "E", "E_up", "E_down", "M"] {
        assert!(v[key].is_f64(), "key {key} missing or not a number in {v}");
    }
    assert_eq!(v["R"], 9.0);
    assert_eq!(v["E"], 5.0);
    assert_eq!(v["runs"], 3);
    assert_eq!(v["targets"][1]["R"], 9.0);
    assert_eq!(v["targets"][1]["B"], 3.0);
    assert_eq!(v["targets"][1]["up"]["s"], 2.0);

    let forward: Vec<Sample> = case_one().into_iter().filter(|s| s.direction == Up).collect();
    let v = serde_json::to_value(iso230_2(&forward).unwrap()).unwrap();
    for key in ["A_down", "R_down", "B", "B_mean", "E_down", "M"] {
        assert!(v.get(key).is_some_and(|x| x.is_null()), "key {key} should be present and null in {v}");
    }
}

#[test]
fn no_samples_is_an_error() {
    assert_eq!(iso230_2(&[]), Err(StatsError::NoSamples));
}

#[test]
fn one_run_names_the_target_and_direction() {
    let mut s = case_one();
    s.retain(|x| !(x.direction == Down && x.target_deg == 0.0 && x.run > 1));
    let mut s2 = runs(Up, 12.5, &[0.1, 0.2]);
    s2.extend(runs(Down, 12.5, &[0.1]));
    let err = iso230_2(&s2).unwrap_err();
    assert_eq!(err, StatsError::TooFewRuns { target_deg: 12.5, direction: Down, runs: 1 });
    assert_eq!(err.to_string(), "target 12.5 deg, reverse: 1 run; ISO 230-2 needs at least 2");
    assert_eq!(iso230_2(&s).unwrap_err(), StatsError::TooFewRuns { target_deg: 0.0, direction: Down, runs: 1 });
}

#[test]
fn a_bidirectional_survey_needs_both_directions_at_every_target() {
    let mut s = case_one();
    s.retain(|x| !(x.direction == Up && x.target_deg == 90.0));
    let err = iso230_2(&s).unwrap_err();
    assert_eq!(err, StatsError::MissingDirection { target_deg: 90.0, missing: Up });
    let msg = err.to_string();
    assert!(msg.contains("target 90 deg") && msg.contains("no forward samples"), "{msg}");
}

#[test]
fn duplicate_runs_are_an_error() {
    let mut s = case_one();
    s.push(sample(2, Up, 90.0, 0.5));
    let err = iso230_2(&s).unwrap_err();
    assert_eq!(err, StatsError::DuplicateRun { target_deg: 90.0, direction: Up, run: 2, count: 2 });
    assert!(err.to_string().contains("run 2 appears 2 times"), "{err}");
}

#[test]
fn non_finite_values_are_an_error() {
    let mut s = case_one();
    s[4].actual_deg = f64::NAN;
    let err = iso230_2(&s).unwrap_err();
    assert!(matches!(err, StatsError::NonFinite { index: 4, field: "actual_deg", .. }), "{err:?}");
    assert!(err.to_string().starts_with("sample 4 (run "), "{err}");
    let mut s = case_one();
    s[0].target_deg = f64::INFINITY;
    let err = iso230_2(&s).unwrap_err();
    assert!(matches!(err, StatsError::NonFinite { index: 0, field: "target_deg", .. }), "{err:?}");
    assert!(err.to_string().contains("target_deg is inf"), "{err}");
}

// ---- Real data: the PSI ecmc ISO 230-2 files (see shared/data/iso230-ecmc/README.md).

fn ecmc_dir() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data/iso230-ecmc"))
}

/// Parses an ecmc `*_ISO230.dat` file into samples: target = readout = `TGT_DATA[i]`,
/// actual = `REF_DATA_FWD[i,j]` / `REF_DATA_BWD[i,j]`, run = `j`.
fn parse_ecmc_dat(text: &str) -> Vec<Sample> {
    let mut targets = std::collections::BTreeMap::new();
    let mut refs = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let Some((key, value)) = line.trim().split_once('=') else { continue };
        let Some((name, index)) = key.strip_suffix(']').and_then(|k| k.split_once('[')) else { continue };
        let parse = |v: &str| -> f64 {
            v.trim().parse().unwrap_or_else(|e| panic!("line {}: '{v}' is not a number: {e}", n + 1))
        };
        let parse_index =
            |v: &str| -> u32 { v.trim().parse().unwrap_or_else(|e| panic!("line {}: index '{v}': {e}", n + 1)) };
        match name {
            "TGT_DATA" => {
                targets.insert(parse_index(index), parse(value));
            }
            "REF_DATA_FWD" | "REF_DATA_BWD" => {
                let (i, j) = index.split_once(',').unwrap_or_else(|| panic!("line {}: bad index", n + 1));
                let direction = if name == "REF_DATA_FWD" { Up } else { Down };
                refs.push((parse_index(i), parse_index(j), direction, parse(value)));
            }
            _ => {}
        }
    }
    refs.into_iter()
        .map(|(i, j, direction, actual)| {
            let target = *targets.get(&i).unwrap_or_else(|| panic!("no TGT_DATA[{i}]"));
            Sample { run: j, direction, target_deg: target, readout_deg: target, actual_deg: actual, timestamp_s: None }
        })
        .collect()
}

/// Compares every figure to the README's table, to 6 significant digits
/// (relative 5e-6: half a unit in the sixth digit; no absolute floor, so the
/// small figures such as B_mean = -5.4e-6 are checked as strictly as the large ones).
fn check_ecmc(file: &str, want: [f64; 12]) {
    let path = ecmc_dir().join(file);
    if !path.exists() {
        eprintln!("skipped: {} is absent (the shared data sits beside the repository)", path.display());
        return;
    }
    let text = std::fs::read_to_string(&path).unwrap();
    let samples = parse_ecmc_dat(&text);
    assert_eq!(samples.len(), 50, "{file}: 5 targets x 5 runs x 2 directions");
    let st = iso230_2(&samples).unwrap();
    assert_eq!(st.runs, 5);
    assert_eq!(st.targets.len(), 5);
    let got = [
        Some(st.a),
        st.a_up,
        st.a_down,
        Some(st.r),
        st.r_up,
        st.r_down,
        st.b,
        st.b_mean,
        Some(st.e),
        st.e_up,
        st.e_down,
        st.m,
    ];
    let names = ["A", "A_up", "A_down", "R", "R_up", "R_down", "B", "B_mean", "E", "E_up", "E_down", "M"];
    for ((name, got), want) in names.iter().zip(got).zip(want) {
        let got = got.unwrap_or_else(|| panic!("{file}: {name} is None"));
        assert!((got - want).abs() <= 5e-6 * want.abs(), "{file}: {name} = {got:.6e}, README says {want:.6e}");
    }
}

#[test]
fn ecmc_fat_sat_matches_the_readme() {
    check_ecmc(
        "fat_sat_ISO230.dat",
        [
            8.88072e-05,
            8.88072e-05,
            6.42824e-05,
            6.8815e-05,
            6.29031e-05,
            5.03269e-05,
            1.22e-05,
            -5.4e-06,
            3.68e-05,
            3.3e-05,
            2.46e-05,
            2.77e-05,
        ],
    );
}

#[test]
fn ecmc_mcu1025_matches_the_readme() {
    check_ecmc(
        "mcu1025_ISO230.dat",
        [
            0.204759,
            0.204759,
            0.0892653,
            0.204759,
            0.204759,
            0.018297,
            0.0434594,
            -0.00718486,
            0.074772,
            0.0461161,
            0.074772,
            0.0480935,
        ],
    );
}

#[test]
fn ecmc_parser_reads_leading_dot_numbers() {
    let s = parse_ecmc_dat("# comment\nUNIT=mm\nTGT_DATA[1]=0.24\nREF_DATA_FWD[1,2]=.2399139810\n");
    assert_eq!(s.len(), 1);
    assert_eq!((s[0].run, s[0].direction, s[0].target_deg), (2, Up, 0.24));
    assert_eq!(s[0].actual_deg, 0.2399139810);
}

// ---- Invariances.

/// A random survey: 2-6 targets on a 30-degree grid, 2-5 runs, deviations within
/// +-0.1 deg, bidirectional or one direction.
fn survey() -> impl Strategy<Value = Vec<Sample>> {
    (2usize..=6, 2usize..=5, 0u8..3).prop_flat_map(|(targets, runs, dirs)| {
        let directions: Vec<Direction> = match dirs {
            0 => vec![Up, Down],
            1 => vec![Up],
            _ => vec![Down],
        };
        let n = targets * runs * directions.len();
        prop::collection::vec(-0.1f64..0.1, n).prop_map(move |x| {
            let mut s = Vec::with_capacity(n);
            let mut k = 0;
            for i in 0..targets {
                for &d in &directions {
                    for j in 0..runs {
                        s.push(sample(j as u32 + 1, d, 30.0 * i as f64, x[k]));
                        k += 1;
                    }
                }
            }
            s
        })
    })
}

/// Equal within 1e-12 relative; the 1e-12 deg floor covers the rounding of
/// `actual = target + x + c` (targets up to 150 deg: about 3e-14 deg).
fn near(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
}

fn near_opt(a: Option<f64>, b: Option<f64>) -> bool {
    match (a, b) {
        (Some(a), Some(b)) => near(a, b),
        (None, None) => true,
        _ => false,
    }
}

proptest! {
    #[test]
    fn the_a_alone_is_the_a_of_the_whole_statistics_bit_for_bit(s in survey(), c in -1e-3f64..1e-3) {
        let groups = TargetGroups::of(&s);
        let actual = |i: usize| s[i].actual_deg + c * (i as f64).sin();
        let whole = iso230_2_with_actual(&s, &groups, actual).map(|st| st.a.to_bits());
        prop_assert_eq!(iso230_2_a_with_actual(&s, &groups, actual).map(f64::to_bits), whole);
    }

    /// The figures and the `A` of other actual angles from one walk are
    /// each what its own function gives, to the bit, errors included: a
    /// value that is not finite in either set, or a sample whose run is
    /// repeated (both sets' error).
    #[test]
    fn the_figures_and_the_a_together_are_each_alone(
        s in survey(),
        c in -1e-3f64..1e-3,
        broken in proptest::option::of((proptest::num::usize::ANY, proptest::bool::ANY)),
        repeat in proptest::bool::ANY,
    ) {
        let mut s = s;
        if repeat {
            let x = s[0];
            s.push(x);
        }
        let mut bad = None;
        if let Some((at, native)) = broken {
            let i = at % s.len();
            if native { s[i].actual_deg = f64::NAN } else { bad = Some(i) }
        }
        let groups = TargetGroups::of(&s);
        let actual = |i: usize| if bad == Some(i) { f64::INFINITY } else { s[i].actual_deg + c * (i as f64).cos() };
        let (figures, a) = iso230_2_figures_and_a_with_actual(&s, &groups, actual);
        // Compared as printed: an error's NaN is not equal to itself.
        prop_assert_eq!(format!("{figures:?}"), format!("{:?}", iso230_2_figures_grouped(&s, &groups)));
        let bits = |r: Result<f64, StatsError>| format!("{:?}", r.map(f64::to_bits));
        prop_assert_eq!(bits(a), bits(iso230_2_a_with_actual(&s, &groups, actual)));
    }

    /// The figures folded target by target (what the processing keeps) are
    /// the figures of the per-target statistics taken whole, to the bit.
    #[test]
    fn the_figures_folded_are_those_of_the_targets_taken_whole(s in survey()) {
        let groups = TargetGroups::of(&s);
        let whole = iso230_2(&s).unwrap();
        let folded = iso230_2_figures_grouped(&s, &groups).unwrap();
        prop_assert!(folded.targets.is_empty());
        prop_assert_eq!(folded.target_count, whole.targets.len());
        prop_assert_eq!(&Iso230 { targets: Vec::new(), ..whole.clone() }, &folded);
        // And from the per-target statistics directly, as a reader would take them.
        let t = &whole.targets;
        let bits = |v: Option<f64>| v.map(f64::to_bits);
        let bs: Vec<f64> = t.iter().filter_map(|t| t.b).collect();
        let means: Vec<f64> = t.iter().filter_map(|t| t.mean_bi).collect();
        if !bs.is_empty() {
            prop_assert_eq!(bits(folded.b_mean), bits(Some(bs.iter().sum::<f64>() / bs.len() as f64)));
            prop_assert_eq!(bits(folded.b), bits(Some(bs.iter().map(|b| b.abs()).fold(0.0, f64::max))));
            let (hi, lo) = means.iter().fold((f64::NEG_INFINITY, f64::INFINITY), |(h, l), &m| (h.max(m), l.min(m)));
            prop_assert_eq!(bits(folded.m), bits(Some(hi - lo)));
        }
        prop_assert_eq!(folded.r.to_bits(), t.iter().map(|t| t.r).fold(f64::NEG_INFINITY, f64::max).to_bits());
        let ups: Vec<&DirStats> = t.iter().filter_map(|t| t.up.as_ref()).collect();
        if !ups.is_empty() {
            let hi = ups.iter().map(|d| d.mean + 2.0 * d.s).fold(f64::NEG_INFINITY, f64::max);
            let lo = ups.iter().map(|d| d.mean - 2.0 * d.s).fold(f64::INFINITY, f64::min);
            prop_assert_eq!(bits(folded.a_up), bits(Some(hi - lo)));
        }
    }

    #[test]
    fn invariant_under_sample_order(
        (s, shuffled) in survey().prop_flat_map(|s| (Just(s.clone()), Just(s).prop_shuffle()))
    ) {
        // Groups are sorted by run before summing, so the result is bit-identical.
        prop_assert_eq!(iso230_2(&s).unwrap(), iso230_2(&shuffled).unwrap());
    }

    #[test]
    fn a_constant_shift_moves_only_the_means(s in survey(), c in -1.0f64..1.0) {
        let base = iso230_2(&s).unwrap();
        let moved: Vec<Sample> = s.iter().map(|x| Sample { actual_deg: x.actual_deg + c, ..*x }).collect();
        let st = iso230_2(&moved).unwrap();
        for (name, a, b) in [("A", base.a, st.a), ("R", base.r, st.r), ("E", base.e, st.e)] {
            prop_assert!(near(a, b), "{} {} vs {}", name, a, b);
        }
        for (name, a, b) in [
            ("A_up", base.a_up, st.a_up), ("A_down", base.a_down, st.a_down),
            ("R_up", base.r_up, st.r_up), ("R_down", base.r_down, st.r_down),
            ("B", base.b, st.b), ("B_mean", base.b_mean, st.b_mean),
            ("E_up", base.e_up, st.e_up), ("E_down", base.e_down, st.e_down), ("M", base.m, st.m),
        ] {
            prop_assert!(near_opt(a, b), "{} {:?} vs {:?}", name, a, b);
        }
        prop_assert_eq!(base.runs, st.runs);
        for (t0, t1) in base.targets.iter().zip(&st.targets) {
            prop_assert!(near(t0.r, t1.r));
            prop_assert!(near_opt(t0.b, t1.b));
            prop_assert!(near_opt(t0.mean_bi.map(|m| m + c), t1.mean_bi));
            for (d0, d1) in [(&t0.up, &t1.up), (&t0.down, &t1.down)] {
                prop_assert_eq!(d0.is_some(), d1.is_some());
                if let (Some(d0), Some(d1)) = (d0, d1) {
                    prop_assert!(near(d0.mean + c, d1.mean), "mean {} + {} vs {}", d0.mean, c, d1.mean);
                    prop_assert!(near(d0.s, d1.s), "s {} vs {}", d0.s, d1.s);
                }
            }
        }
    }
}

/// Whole sweeps over `targets` (each sweep ascending when its flag is set),
/// then `edit` applied: a target moved, a sample dropped or repeated.
fn sweeps(targets: &[f64], up: &[bool]) -> Vec<Sample> {
    let mut out = Vec::new();
    for (s, &forward) in up.iter().enumerate() {
        let direction = if forward { Direction::Forward } else { Direction::Reverse };
        let order: Vec<f64> = if forward { targets.to_vec() } else { targets.iter().rev().copied().collect() };
        out.extend(order.into_iter().map(|t| sample(s as u32 / 2 + 1, direction, t, 0.0)));
    }
    out
}

fn same_groups(a: &TargetGroups, b: &TargetGroups) -> bool {
    a.ranges == b.ranges && a.sorted == b.sorted
}

proptest! {
    /// A survey's whole sweeps are grouped without a sort, to the indices
    /// the stable sort gives; any other layout is sorted (the same groups,
    /// whichever path takes it).
    #[test]
    fn sweeps_are_grouped_as_the_sort_groups_them(
        steps in proptest::collection::vec(prop_oneof![Just(1e-12), Just(0.5), 0.001f64..3.0], 1..40),
        start in prop_oneof![Just(-0.0), Just(0.0), -20.0f64..20.0],
        up in proptest::collection::vec(proptest::bool::ANY, 1..7),
        edit in 0usize..5,
        at in proptest::num::usize::ANY,
    ) {
        let targets: Vec<f64> = steps.iter().scan(start, |t, d| { *t += d; Some(*t) }).collect();
        let mut s = sweeps(&targets, &up);
        let i = at % s.len();
        match edit {
            1 => s[i].target_deg += 1e-3,
            2 => { s.remove(i); }
            3 => { let x = s[i]; s.insert(i, x); }
            4 => s[i].target_deg = f64::NAN,
            _ => {}
        }
        if s.is_empty() {
            return Ok(());
        }
        let fast = TargetGroups::of_sweeps(&s);
        if edit == 0 {
            prop_assert!(fast.is_some() || targets.len() < 2, "whole sweeps take the sort");
        }
        if let Some(fast) = fast {
            prop_assert!(same_groups(&fast, &TargetGroups::by_sort(&s)));
        }
        prop_assert!(same_groups(&TargetGroups::of(&s), &TargetGroups::by_sort(&s)));
    }
}
