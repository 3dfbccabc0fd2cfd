//! Several SMRs against the simulators' truth (issue 48): a tracker whose own
//! error sits where one SMR cannot tell it from the axis's (its azimuth
//! encoder's orders 4 to 8 at 2 urad each: within its MPE, about 1.5e-3 deg
//! in the default arm's angles), the paper's Figure 8 positioner, 360
//! points, 3 runs, both ways. The table's true error (its value against the
//! positioner's true error) for one SMR, three at equal spacing, three at
//! unequal spacing (0, 37, 131 deg: the tracker's error separated), and an
//! ideal tracker; each survey acquired and processed by the built binary,
//! its figures from [`super::coverage::run_case`].
//!
//! Required: with three SMRs at unequal spacing the table's true error (its
//! 95th percentile) within 1.5 times the ideal tracker's and at least 3
//! times below one SMR's; at equal spacing below one SMR's (the orders that
//! are multiples of 3 stay); `U` covering at least 95 % of the table's rows
//! in every case (one SMR's `U` is its MPE's bound).

use super::coverage::{Case, Figures, run_case};
use survey_processing::model::Model;

const FIG8: &str = include_str!("../../sims/presets/fig8.toml");

/// The tracker: its azimuth encoder's orders 4 to 8 at 2 urad.
macro_rules! tracker {
    () => {
        "\n[tracker_errors]\nazimuth = [{order = 4, amplitude_urad = 2.0, phase_deg = 0.0}, \
         {order = 5, amplitude_urad = 2.0, phase_deg = 50.0}, {order = 6, amplitude_urad = 2.0, phase_deg = 100.0}, \
         {order = 7, amplitude_urad = 2.0, phase_deg = 150.0}, {order = 8, amplitude_urad = 2.0, phase_deg = 200.0}]\n"
    };
}

const ONE: &str = concat!(include_str!("../../sims/presets/fig8.toml"), tracker!());
const UNEQUAL: &str =
    concat!(include_str!("../../sims/presets/fig8.toml"), tracker!(), "\n[smrs]\nphases_deg = [0, 37, 131]\n");
const IDEAL: &str = concat!(include_str!("../../sims/presets/fig8.toml"), "\n[tracker_errors]\nnone = true\n");

fn case(name: &'static str, args: &str, file: &'static str) -> Case {
    Case {
        name,
        args: args.split_whitespace().map(String::from).collect(),
        model: Model::parse(FIG8, "fig8.toml").unwrap(),
        model_file: Some(file),
    }
}

fn figures(c: &Case) -> Figures {
    let f = run_case(c, 1..=1);
    eprintln!(
        "{}: true error p95 {:.2e} deg, U {:.2e} deg, coverage {:.1} %",
        c.name,
        f.p95,
        f.widest_u,
        100.0 * f.coverage
    );
    assert!(f.coverage >= 0.95, "{}: only {:.1} % of the table's rows within U", c.name, 100.0 * f.coverage);
    f
}

#[test]
fn several_smrs_take_the_trackers_own_error_out_of_the_table() {
    let one = figures(&case("one SMR", "--points 360 --runs 3 --bidirectional", ONE));
    let equal = figures(&case("three SMRs, equal spacing", "--points 360 --runs 3 --bidirectional --smrs 3", ONE));
    let unequal = figures(&case("three SMRs, 0/37/131 deg", "--points 360 --runs 3 --bidirectional", UNEQUAL));
    let ideal = figures(&case("an ideal tracker", "--points 360 --runs 3 --bidirectional", IDEAL));
    assert!(unequal.p95 <= 1.5 * ideal.p95, "unequal {:.2e} against ideal {:.2e}", unequal.p95, ideal.p95);
    assert!(3.0 * unequal.p95 <= one.p95, "unequal {:.2e} against one {:.2e}", unequal.p95, one.p95);
    assert!(equal.p95 < one.p95, "equal {:.2e} against one {:.2e}", equal.p95, one.p95);
    // The bound of one SMR is the MPE's; measured, U comes down with it.
    assert!(unequal.widest_u < 0.5 * one.widest_u, "{:.2e} against {:.2e}", unequal.widest_u, one.widest_u);
}

/// A tracker error set drawn from `seed`, independently of the simulator's
/// own typical draw: the azimuth encoder's orders 1 to 8 and the elevation
/// encoder's 1 to 3, each at an amplitude uniform up to 3 and 2 urad at a
/// uniform phase, the offsets uniform within +/-10 um, the tilts within
/// +/-5 urad; kept only when its transverse error on the default arm's
/// circle is within the AT-class MPE everywhere (a tracker in its
/// specification). The model file's `[tracker_errors]` text.
fn tracker_set(seed: u64) -> String {
    use survey_processing::tracker_errors::{EncoderHarmonic, TrackerErrors, transverse_mpe_um};
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let arm = survey_sims::tracker::ArmGeometry::default();
    loop {
        let mut harmonics = |orders: u32, max: f64| -> Vec<EncoderHarmonic> {
            (1..=orders)
                .map(|order| EncoderHarmonic { order, amplitude_urad: max * uniform(), phase_deg: 360.0 * uniform() })
                .collect()
        };
        let (azimuth, elevation) = (harmonics(8, 3.0), harmonics(3, 2.0));
        let mut within = |w: f64| w * (2.0 * uniform() - 1.0);
        let e = TrackerErrors {
            azimuth,
            elevation,
            transit_offset_um: within(10.0),
            beam_offset_um: within(10.0),
            beam_offset_normal_um: within(10.0),
            range_offset_um: within(10.0),
            vertical_index_urad: within(5.0),
            beam_tilt_urad: within(5.0),
            transit_tilt_urad: within(5.0),
            ..TrackerErrors::ideal()
        };
        let in_spec = (0..72).all(|i| {
            let p = arm.smr_position_mm(5.0 * i as f64);
            let m = e.measured(p, [0.0; 3]);
            let d: [f64; 3] = std::array::from_fn(|k| m[k] - p[k]);
            let r = p.iter().map(|x| x * x).sum::<f64>().sqrt();
            let along = d.iter().zip(p).map(|(a, b)| a * b).sum::<f64>() / r;
            let across = (d.iter().map(|x| x * x).sum::<f64>() - along * along).max(0.0).sqrt();
            across * 1000.0 <= transverse_mpe_um(r)
        });
        if in_spec {
            return format!("\n{}", e.to_toml());
        }
    }
}

/// One SMR's `U` over tracker error sets the simulator was not built on:
/// each survey's `U` covers at least 90 % of its table's rows.
fn one_smr_over_sets(sets: std::ops::Range<u64>) -> Vec<f64> {
    over_sets(sets, "one SMR", "").into_iter().map(|f| f.coverage).collect()
}

/// The surveys of the tracker error sets `sets` with `smrs` (the model
/// file's `[smrs]` text, or none for one SMR), each its figures.
fn over_sets(sets: std::ops::Range<u64>, label: &str, smrs: &str) -> Vec<Figures> {
    sets.map(|s| {
        let text: &'static str = Box::leak(format!("{FIG8}{}{smrs}", tracker_set(s)).into_boxed_str());
        let name: &'static str = Box::leak(format!("{label}, tracker set {s}").into_boxed_str());
        let f = run_case(&case(name, "--points 360 --runs 3 --bidirectional", text), 1..=1);
        eprintln!(
            "{name}: coverage {:.1} %, true error p95 {:.2e} deg, U {:.2e} deg",
            100.0 * f.coverage,
            f.p95,
            f.widest_u
        );
        f
    })
    .collect()
}

#[test]
fn one_smrs_u_covers_the_tables_error_over_tracker_error_sets() {
    let coverage = one_smr_over_sets(1..4);
    assert!(coverage.iter().all(|c| *c >= 0.9), "{coverage:?}");
}

#[test]
#[ignore = "Monte Carlo over tracker error sets: SURVEY_TRACKER_SETS=N, figures for docs/validation/uncertainty.md"]
fn one_smrs_u_over_many_tracker_error_sets() {
    let n: u64 = std::env::var("SURVEY_TRACKER_SETS").ok().and_then(|s| s.parse().ok()).unwrap_or(20);
    let coverage = one_smr_over_sets(1..n + 1);
    let worst = coverage.iter().copied().fold(1.0, f64::min);
    eprintln!("{n} tracker error sets: the worst survey's coverage {:.1} %", 100.0 * worst);
    assert!(worst >= 0.9, "{coverage:?}");
}

/// Three SMRs at unequal spacing (0, 37, 131 deg) over the tracker error
/// sets: each survey's coverage, and its table's true error against one
/// SMR's and an ideal tracker's (docs/validation/uncertainty.md).
#[test]
#[ignore = "Monte Carlo over tracker error sets: SURVEY_TRACKER_SETS=N, figures for docs/validation/uncertainty.md"]
fn three_smrs_over_many_tracker_error_sets() {
    let n: u64 = std::env::var("SURVEY_TRACKER_SETS").ok().and_then(|s| s.parse().ok()).unwrap_or(10);
    let three = over_sets(1..n + 1, "three SMRs, 0/37/131 deg", "\n[smrs]\nphases_deg = [0, 37, 131]\n");
    let one = over_sets(1..n + 1, "one SMR", "");
    let ideal = figures(&case("an ideal tracker", "--points 360 --runs 3 --bidirectional", IDEAL));
    let worst = three.iter().map(|f| f.coverage).fold(1.0, f64::min);
    let (mut to_one, mut to_ideal): (Vec<f64>, Vec<f64>) =
        three.iter().zip(&one).map(|(t, o)| (o.p95 / t.p95, t.p95 / ideal.p95)).unzip();
    to_one.sort_by(f64::total_cmp);
    to_ideal.sort_by(f64::total_cmp);
    eprintln!(
        "{n} tracker error sets, three SMRs: the worst survey's coverage {:.1} %; one SMR's p95 over three's {:.2} to \
         {:.2} (median {:.2}); three's over an ideal tracker's {:.2} to {:.2} (median {:.2}); U {:.2e} to {:.2e}",
        100.0 * worst,
        to_one[0],
        to_one[to_one.len() - 1],
        to_one[to_one.len() / 2],
        to_ideal[0],
        to_ideal[to_ideal.len() - 1],
        to_ideal[to_ideal.len() / 2],
        three.iter().map(|f| f.widest_u).fold(f64::INFINITY, f64::min),
        three.iter().map(|f| f.widest_u).fold(0.0, f64::max),
    );
    assert!(worst >= 0.95, "{:?}", three.iter().map(|f| f.coverage).collect::<Vec<_>>());
}

/// The axis whirling (a radial error motion of 40 um at 3 cycles/rev): one
/// SMR reads its part along the circle as angle, and the table corrects it
/// as the positioner's, so against the positioner's own angular error (the
/// model's angle, E_C) the table is off by up to 2.5e-3 deg. `U` counts it
/// from the radial motion the survey measured (before: `U` 1.54e-3 deg
/// covered 47.8 % of the rows); two SMRs at opposite phases cancel it in
/// their mean angle and count nothing for it.
#[test]
fn the_axis_whirl_read_as_angle_is_in_u_and_two_smrs_cancel_it() {
    const WHIRL: &str = concat!(
        include_str!("../../sims/presets/fig8.toml"),
        "\n[[effect]]\nkind = \"radial_motion\"\ncycles_per_rev = 3\namplitude_um = 40\nphase_deg = 30\n"
    );
    let one = figures(&case("one SMR, the axis whirling", "--points 360 --runs 3 --bidirectional", WHIRL));
    let two = figures(&case("two SMRs, the axis whirling", "--points 360 --runs 3 --bidirectional --smrs 2", WHIRL));
    assert!(one.p95 > 1.5e-3, "the whirl is in one SMR's table: p95 {:.2e}", one.p95);
    assert!(two.p95 < 4e-4, "two SMRs cancel it: p95 {:.2e}", two.p95);
    assert!(two.widest_u < 0.5 * one.widest_u, "{:.2e} against {:.2e}", two.widest_u, one.widest_u);
}
