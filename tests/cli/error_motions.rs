//! The axis's error motions (issue 52) from outside: `process --json`'s
//! `error_motions` with the contract's keys, its figures against the model
//! file's motions within their stated U, a wobble below the detection limit
//! said so, and a bad motion refused naming its line and key.

use super::Bench;
use serde_json::Value;

/// The Figure 8 positioner with motions a tracker can see, and two SMRs
/// at opposite phases (the axial motion on the axis and the tilt). The
/// truth, at the first SMR (50 mm above the tilt's pivot): radial 2 cpr 60
/// um (the tilt adds 0.05 m x 200 urad at 2 cpr), axial 3 cpr 40 um on the
/// axis, tilt 2 cpr 200 urad.
const MOVING: &str = r#"[design]
gear_ratios = [20]

[[effect]]
kind = "gear_pass"
cycles_per_rev = 20
amplitude_deg = 0.0078
phase_deg = 0.0

[[effect]]
kind = "radial_motion"
cycles_per_rev = 2
amplitude_um = 60.0
phase_deg = 0.0

[[effect]]
kind = "axial_motion"
cycles_per_rev = 3
amplitude_um = 40.0
phase_deg = 30.0

[[effect]]
kind = "tilt_motion"
cycles_per_rev = 2
amplitude_urad = 200.0
phase_deg = 0.0

[[effect]]
kind = "bearing_noise"
sigma_um = 1.0

[smrs]
phases_deg = [0, 180]
"#;

/// The sim's axis (sims' `ArmGeometry`: through [2500, 800, -300] mm,
/// tilted 0.3 deg toward 30 deg) as the z axis of a machine whose origin is
/// 10 mm, -20 mm off it (and 35 mm below the axis's point): `[machine_frame]`
/// with `R = Ry(ry) Rx(rx)` (fixed x then y) taking z to the axis.
fn machine_frame() -> String {
    let (o, r) = frame_values();
    format!(
        "[machine_frame]\norigin_mm = [{}, {}, {}]\nrotation_deg = [{}, {}, {}]\n",
        o[0], o[1], o[2], r[0], r[1], r[2]
    )
}

/// The true frame's `origin_mm` and `rotation_deg` (see [`machine_frame`]).
fn frame_values() -> ([f64; 3], [f64; 3]) {
    let (t, w) = (0.3f64.to_radians(), 30f64.to_radians());
    let n = [t.sin() * w.cos(), t.sin() * w.sin(), t.cos()];
    let (rx, ry) = (-n[1].asin(), n[0].atan2(n[2]));
    let rotate = |v: [f64; 3]| {
        let (s, c) = rx.sin_cos();
        let v = [v[0], c * v[1] - s * v[2], s * v[1] + c * v[2]];
        let (s, c) = ry.sin_cos();
        [c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2]]
    };
    let off = rotate([10.0, -20.0, 35.0]);
    let z = rotate([0.0, 0.0, 1.0]);
    assert!((0..3).all(|i| (z[i] - n[i]).abs() < 1e-12), "the machine's z is the axis");
    let o = [2500.0 - off[0], 800.0 - off[1], -300.0 - off[2]];
    (o, [rx.to_degrees(), ry.to_degrees(), 0.0])
}

fn num(v: &Value, what: &str) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("{what} should be a number: {v}"))
}

/// The peak-to-valley of `f` at `points` targets over the turn.
fn pv(points: usize, f: impl Fn(f64) -> f64) -> f64 {
    let v: Vec<f64> = (0..points).map(|j| f(360.0 * j as f64 / points as f64)).collect();
    v.iter().copied().fold(f64::NEG_INFINITY, f64::max) - v.iter().copied().fold(f64::INFINITY, f64::min)
}

#[test]
fn error_motions_against_the_models_truth_and_below_the_limit() {
    let bench = Bench::new();
    bench.write("moving.toml", format!("{MOVING}\n{}", machine_frame()));
    let doc = bench
        .survey(&["run", "--points", "72", "--runs", "2", "--bidirectional", "--model", "moving.toml", "--json"])
        .success()
        .json();
    assert!(doc["process"]["error_motions"].is_object(), "{}", doc["process"]);
    let doc = bench.survey(&["process", "--json"]).success().json();
    let m = &doc["error_motions"];
    for key in ["x0_mm", "y0_mm", "a0_urad", "b0_urad"] {
        num(&m["location"][key], key);
    }
    for block in ["radial_um", "axial_um", "tilt_urad"] {
        for key in ["total", "synchronous", "asynchronous", "u"] {
            assert!(m[block].get(key).is_some(), "{block}.{key}: {m}");
        }
    }
    let limit = num(&m["detection_limit_um"], "detection_limit_um");
    assert!((25.0..40.0).contains(&limit), "an AT-class tracker a few metres away: {limit}");
    // The bench's arm: SMR 1 at 2.5 m, tilted 0.3 deg toward 30 deg (sims' ArmGeometry).
    assert!((num(&m["location"]["b0_urad"], "b0") - 4534.0).abs() < 30.0, "{m}");
    let within = |block: &str, truth: f64| {
        let got = num(&m[block]["synchronous"], block);
        let u = num(&m[block]["u"], "u");
        assert!((got - truth).abs() <= u, "{block}: {got} against the model's {truth}, U = {u}");
    };
    let tilt = |t: f64| 200.0 * (2.0 * t).to_radians().sin();
    within("radial_um", pv(72, |t| 60.0 * (2.0 * t).to_radians().sin() - 0.05 * tilt(t)));
    within("axial_um", pv(72, |t| 40.0 * (3.0 * t + 30.0).to_radians().sin() + tilt(t)));
    within("tilt_urad", pv(72, tilt));
    within("axial_on_axis_um", pv(72, |t| 40.0 * (3.0 * t + 30.0).to_radians().sin()));
    assert_eq!(m["tilt_urad"]["method"], "phases", "{m}");
    // The location in the machine's frame: the frame puts the sim's axis on its z axis, 10 mm along its x and
    // -20 mm along its y from its origin.
    let machine = &m["location"]["machine"];
    for (key, truth, u) in [
        ("x0_mm", 10.0, "u_xy_mm"),
        ("y0_mm", -20.0, "u_xy_mm"),
        ("a0_urad", 0.0, "u_ab_urad"),
        ("b0_urad", 0.0, "u_ab_urad"),
    ] {
        let (got, u) = (num(&machine[key], key), num(&machine[u], u));
        assert!((got - truth).abs() <= u, "machine {key}: {got} against {truth}, U = {u}");
    }
    let text = bench.survey(&["process"]).success().stdout;
    for line in [
        "axis average line (ISO 230-1, machine frame): X0 ",
        "error motion (ISO 230-7) axial on the axis: total",
        "error motion (ISO 230-7) tilt (2 SMRs at several phases)",
    ] {
        assert!(text.contains(line), "{text}");
    }

    // The report shows them (a table and polar plots); the DCC carries them as a result of their own.
    bench.survey(&["report", "--out", "r"]).success();
    let html = bench.read("r/index.html");
    for id in ["tbl-axis-location", "tbl-error-motions", "fig-error-motions"] {
        assert!(html.contains(&format!("id=\"{id}\"")), "the report shows {id}");
    }
    assert!(html.contains("machine frame (X0C, Y0C at its z = 0)") && html.contains("axial on the axis, µm"));
    let dcc = bench.read("r/dcc.xml");
    for ref_type in ["survey_errorMotions", "survey_motionRadialSynchronous", "survey_motionTiltTotal", "survey_axisB0"]
    {
        assert!(dcc.contains(ref_type), "the DCC carries {ref_type}");
    }
    assert!(dcc.contains("<dcc:noQuantity>"), "the asynchronous motions are below the limit: said, not a number");
    for ref_type in ["survey_motionAxialOnAxisSynchronous", "survey_axisMachineX0", "survey_axisMachineB0"] {
        assert!(dcc.contains(ref_type), "the DCC carries {ref_type}");
    }
    if super::dcc::validator_missing().is_none() {
        super::dcc::validate(&bench, &["r/dcc.xml"]);
    }

    // The Figure 8 positioner with a small wobble (a few um) is below what the tracker can tell.
    bench.write("wobble.toml", include_str!("../fixtures/fig8-wobble.toml"));
    let fig8 = bench
        .survey(&["--db", "fig8.db", "run", "--points", "72", "--runs", "2", "--model", "wobble.toml", "--json"])
        .success()
        .json();
    let m = &fig8["process"]["error_motions"];
    assert!(m["radial_um"]["total"].is_null() && m["radial_um"]["below_detection_limit"] == true, "{m}");
    assert!(m["tilt_urad"].is_null() && m["axial_on_axis_um"].is_null(), "one SMR: no tilt, only the face motion");
    assert!(m["axial_um"]["u"].is_f64() && m["location"]["machine"].is_null(), "no frame stated: {m}");

    // A once-per-revolution radial motion is the axis's location: refused.
    bench.write(
        "bad.toml",
        MOVING.replace("cycles_per_rev = 2\namplitude_um = 60.0", "cycles_per_rev = 1\namplitude_um = 60.0"),
    );
    bench.survey(&["--db", "bad.db", "run", "--points", "24", "--model", "bad.toml"]).bad_input(&[
        "bad.toml:12",
        "cycles_per_rev",
        "location",
    ]);
}

/// A growing wobble (a worn bearing) across an asset's surveys: `history`
/// shows each survey's radial and axial totals, `compare` the change.
#[test]
fn history_and_compare_show_a_growing_wobble() {
    let bench = Bench::new();
    let model = |um: f64| {
        format!("[[effect]]\nkind = \"radial_motion\"\ncycles_per_rev = 2\namplitude_um = {um:.1}\nphase_deg = 0.0\n")
    };
    // The worn one measured with two SMRs at opposite phases: its axial motion on the axis separated too.
    let axial = "[[effect]]\nkind = \"axial_motion\"\ncycles_per_rev = 3\namplitude_um = 60.0\nphase_deg = 0.0\n\
                 [smrs]\nphases_deg = [0.0, 180.0]\n";
    for (file, um) in [("new.toml", 40.0), ("worn.toml", 120.0)] {
        let text = if file == "worn.toml" { model(um) + axial } else { model(um) };
        bench.write(file, text);
        bench.survey(&["run", "--points", "72", "--runs", "2", "--model", file, "--asset", "az-1", "--json"]).success();
    }
    let h = bench.survey(&["history", "--asset", "az-1", "--json"]).success().json();
    let totals: Vec<f64> = h["surveys"]
        .as_array()
        .expect("surveys")
        .iter()
        .map(|s| num(&s["error_motions"]["radial_um"]["total"], "radial total"))
        .collect();
    assert_eq!(totals.len(), 2, "{h}");
    for (got, truth) in totals.iter().zip([80.0, 240.0]) {
        assert!((got - truth).abs() < 40.0, "radial totals {totals:?} against 2 x the amplitudes");
    }
    // The axial motion on the axis where the SMRs separate it (60 um at 3 cycles/rev: 120 um
    // peak to valley; within its U, about 46 um on this bench), null where one SMR cannot.
    let on_axis = |k: usize| h["surveys"][k]["error_motions"]["axial_on_axis_um"].clone();
    assert!(on_axis(0).is_null(), "{h}");
    let worn = &on_axis(1);
    assert!((num(&worn["total"], "on the axis") - 120.0).abs() < num(&worn["u"], "its U"), "{worn}");
    // Two SMRs on one line (0 and 180 deg) cannot see the tilt across: null, and no change of it.
    assert!(h["surveys"][1]["error_motions"]["tilt_across_urad"].is_null(), "{h}");
    // And in the history's text, a line a survey.
    let text = bench.survey(&["history", "--asset", "az-1"]).success().stdout;
    assert_eq!(text.matches("error motions (ISO 230-7, totals): radial ").count(), 2, "{text}");
    assert_eq!(text.matches(", axial on the axis ").count(), 1, "{text}");
    let c = bench.survey(&["compare", "1", "2", "--json"]).success().json();
    let change = &c["error_motions"]["radial_total_change_um"];
    assert!(num(&change["change"], "change") > 100.0 && change["significant"] == true, "{c}");
    assert!(c["error_motions"]["tilt_across_total_change_urad"].is_null(), "{c}");
}

/// A growing tilt (a worn bearing that rocks the table) seen across, at 90
/// deg to the first SMR's radial direction, by three SMRs at 0, 120 and 240
/// deg: `history` keeps each survey's `tilt_across_urad` (text and JSON), and
/// `compare` finds its change significant. The model's tilt turns with the
/// table, so across it is the model's at 90 deg on: its peak-to-valley at the
/// 72 targets is twice the amplitude (`2 theta + 90` reaches 90 and 270 deg).
#[test]
fn history_and_compare_show_a_growing_tilt_across() {
    let bench = Bench::new();
    let model = |urad: f64| {
        format!(
            "[[effect]]\nkind = \"tilt_motion\"\ncycles_per_rev = 2\namplitude_urad = {urad:.1}\nphase_deg = 0.0\n\n\
             [smrs]\nphases_deg = [0.0, 120.0, 240.0]\n"
        )
    };
    let amplitudes = [100.0, 300.0];
    for (file, urad) in ["new.toml", "worn.toml"].into_iter().zip(amplitudes) {
        bench.write(file, model(urad));
        bench.survey(&["run", "--points", "72", "--runs", "2", "--model", file, "--asset", "az-1", "--json"]).success();
    }
    let truth = |urad: f64| pv(72, |t| urad * (2.0 * t + 90.0).to_radians().sin());
    let h = bench.survey(&["history", "--asset", "az-1", "--json"]).success().json();
    let surveys = h["surveys"].as_array().expect("surveys");
    assert_eq!(surveys.len(), 2, "{h}");
    // Each survey's total within its U (k = 2: the tracker's systematic bound and what its noise
    // makes of a peak-to-valley, which bound the total's error; no bearing noise here).
    for (s, urad) in surveys.iter().zip(amplitudes) {
        let across = &s["error_motions"]["tilt_across_urad"];
        for key in ["total", "u", "below_detection_limit", "detection_limit"] {
            assert!(across.get(key).is_some(), "tilt_across_urad.{key}: {s}");
        }
        let (got, u) = (num(&across["total"], "tilt across total"), num(&across["u"], "its U"));
        eprintln!("tilt across: {got:.1} urad against {:.1}, U {u:.1}", truth(urad));
        assert!((got - truth(urad)).abs() <= u, "tilt across {got} against the model's {}, U = {u}", truth(urad));
    }
    let text = bench.survey(&["history", "--asset", "az-1"]).success().stdout;
    assert_eq!(text.matches(", tilt across ").count(), 2, "{text}");
    let c = bench.survey(&["compare", "1", "2", "--json"]).success().json();
    let change = &c["error_motions"]["tilt_across_total_change_urad"];
    let (got, u) = (num(&change["change"], "change"), num(&change["u"], "its U"));
    let true_change = truth(amplitudes[1]) - truth(amplitudes[0]);
    eprintln!("tilt across change: {got:.1} urad against {true_change:.1}, U {u:.1}");
    // The two surveys' U in quadrature bound the change's error; the truth, 400 urad, is far beyond it.
    assert!((got - true_change).abs() <= u && change["significant"] == true, "{c}");
    assert!(c["error_motions"]["tilt_total_change_urad"]["significant"] == true, "the tilt too: {c}");
    assert!(c["error_motions"]["a"]["tilt_across_urad"].is_object(), "each survey's totals beside: {c}");
}

/// Three SMRs at 0, 120 and 240 deg measure the tilt across the first SMR's
/// radial direction too (`tilt_across_urad`); and a machine frame stated as
/// an alignment states it, off the true one by less than its stated U, gives
/// the location within the combined U (the fit's and the alignment's).
#[test]
fn three_smrs_give_the_tilt_across_and_the_alignments_u_is_in_the_machine_frames() {
    let bench = Bench::new();
    // The true frame, then 0.08 mm off along the tracker's x and 0.006 deg off about its x; U 0.1 mm, 0.01 deg.
    let (mut o, mut r) = frame_values();
    o[0] += 0.08;
    r[0] += 0.006;
    let frame = format!(
        "[machine_frame]\norigin_mm = [{}, {}, {}]\nrotation_deg = [{}, {}, {}]\norigin_u_mm = 0.1\nrotation_u_deg = 0.01\n",
        o[0], o[1], o[2], r[0], r[1], r[2]
    );
    let model = MOVING.replace("phases_deg = [0, 180]", "phases_deg = [0, 120, 240]");
    bench.write("three.toml", format!("{model}\n{frame}"));
    bench.survey(&["run", "--points", "72", "--runs", "2", "--bidirectional", "--model", "three.toml"]).success();
    let doc = bench.survey(&["process", "--json"]).success().json();
    let m = &doc["error_motions"];
    // The model's tilt (2 cpr, 200 urad) at an SMR mounted 90 deg on from the first: t2's truth.
    let truth = pv(72, |t| 200.0 * (2.0 * t + 90.0).to_radians().sin());
    let across = &m["tilt_across_urad"];
    for key in ["total", "synchronous", "asynchronous", "u"] {
        assert!(across.get(key).is_some(), "tilt_across_urad.{key}: {m}");
    }
    let (got, u) = (num(&across["synchronous"], "t2"), num(&across["u"], "its U"));
    assert!((got - truth).abs() <= u, "tilt across: {got} against the model's {truth}, U = {u}");
    assert_eq!((across["method"].as_str(), across["smrs"].as_u64()), (Some("phases"), Some(3)), "{m}");
    let t1 = num(&m["tilt_urad"]["synchronous"], "t1");
    assert!((t1 - pv(72, |t| 200.0 * (2.0 * t).to_radians().sin())).abs() <= num(&m["tilt_urad"]["u"], "U"), "{m}");
    // The machine frame: off the truth by more than the fit's U, within the combined one.
    let l = &m["location"]["machine"];
    let x0 = num(&l["x0_mm"], "x0");
    assert!((x0 - 10.0).abs() > num(&l["u_xy_fit_mm"], "the fit's U"), "{l}");
    for (key, truth, u) in [("x0_mm", 10.0, "u_xy_mm"), ("y0_mm", -20.0, "u_xy_mm"), ("a0_urad", 0.0, "u_ab_urad")] {
        let (got, u) = (num(&l[key], key), num(&l[u], u));
        assert!((got - truth).abs() <= u, "machine {key}: {got} against {truth}, U = {u}");
    }
    let (xy, ab) = (num(&l["u_xy_alignment_mm"], "alignment xy"), num(&l["u_ab_alignment_urad"], "alignment ab"));
    assert!((0.1..0.1002).contains(&xy) && (ab - 174.53).abs() < 0.5, "the stated U's share: {l}");
    assert_eq!((l["origin_u_mm"].as_f64(), l["rotation_u_deg"].as_f64()), (Some(0.1), Some(0.01)));
    let text = bench.survey(&["process"]).success().stdout;
    for line in [
        "error motion (ISO 230-7) tilt across, at 90 deg to the first SMR's radial direction (3 SMRs): total",
        "the alignment's 0.100 mm, 174.5 urad",
    ] {
        assert!(text.contains(line), "{line}\n{text}");
    }
    bench.survey(&["report", "--out", "r"]).success();
    assert!(bench.read("r/index.html").contains("tilt across, at 90° to the first SMR"), "the report's table");
    let dcc = bench.read("r/dcc.xml");
    assert!(dcc.contains("survey_motionTiltAcrossSynchronous"), "the DCC carries the tilt across");
    if super::dcc::validator_missing().is_none() {
        super::dcc::validate(&bench, &["r/dcc.xml"]);
    }
    // A bad alignment uncertainty: exit 2 naming the file, the line and the key; nothing stored.
    let before = bench.survey(&["list", "--json"]).success().stdout;
    bench.write("bad.toml", format!("{MOVING}\n[machine_frame]\norigin_mm = [0, 0, 0]\norigin_u_mm = -1\n"));
    let line = format!("bad.toml:{}", MOVING.lines().count() + 4);
    bench.survey(&["run", "--points", "24", "--model", "bad.toml"]).bad_input(&[&line, "origin_u_mm"]);
    assert_eq!(bench.survey(&["list", "--json"]).success().stdout, before, "nothing stored");
}

/// `survey sim --model` with a `[machine_frame]`: the configuration to run
/// against states the simulated bench's frame (as `survey run --model`
/// stores it), so a survey against the served instruments gives the
/// location in it.
#[test]
fn survey_sim_passes_the_models_machine_frame() {
    let bench = Bench::new();
    bench.write("frame.toml", format!("{}origin_u_mm = 0.05\n", machine_frame()));
    bench.write(
        "sim.toml",
        "[survey]\npoints = 12\nruns = 2\nbidirectional = true\nreference = \"tracker\"\n\
         [positioner]\ndriver = \"modbus-tcp\"\naddress = \"127.0.0.1:0\"\n\
         [tracker]\ndriver = \"emscon\"\naddress = \"127.0.0.1:0\"\n[timing]\ndwell_s = 0.01\nlocate_points = 4\n",
    );
    let (sim, ready) =
        super::drift::Sim::serve(&bench, &["--config", "sim.toml", "--model", "frame.toml", "--time-scale", "500"]);
    let config = ready["config"].as_str().expect("the configuration to run against").to_string();
    let written: toml::Table = std::fs::read_to_string(&config).unwrap().parse().unwrap();
    let f = &written["machine_frame"];
    let (o, r) = frame_values();
    let three = |k: &str| -> Vec<f64> { f[k].as_array().unwrap().iter().map(|v| v.as_float().unwrap()).collect() };
    assert_eq!((three("origin_mm"), three("rotation_deg")), (o.to_vec(), r.to_vec()), "{written}");
    assert_eq!(f["origin_u_mm"].as_float(), Some(0.05));
    bench.survey(&["run", "--config", &config]).success();
    drop(sim);
    let doc = bench.survey(&["process", "--json"]).success().json();
    let l = &doc["error_motions"]["location"]["machine"];
    assert_eq!(l["origin_mm"].as_array().map(|a| a.len()), Some(3), "the frame reached the survey: {doc}");
    for (key, truth, u) in [("x0_mm", 10.0, "u_xy_mm"), ("y0_mm", -20.0, "u_xy_mm"), ("a0_urad", 0.0, "u_ab_urad")] {
        let (got, u) = (num(&l[key], key), num(&l[u], u));
        assert!((got - truth).abs() <= u, "machine {key}: {got} against {truth}, U = {u}");
    }
    assert!(num(&l["u_xy_alignment_mm"], "the alignment's") >= 0.05, "{l}");
}
