//! Drift control end to end: `survey sim` serves a Modbus TCP positioner
//! whose model drifts (a ramp) and an emScon tracker, in another process;
//! `survey run --config` with `[drift_control]` measures the reference target
//! every 6 steps; `survey show` and `survey stats` (text and `--json`) report
//! the drift, which must be the simulator's: `rate x (time scale) x (t - t0)
//! / drift_run_s` (the ready line says the simulator's run length).

use super::BIN;
use serde_json::Value;
use std::io::{BufRead as _, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};

/// The drift the simulated positioner gains per run (ramp).
const RATE: f64 = 0.05;
/// `survey sim --time-scale`.
const SCALE: f64 = 100.0;

pub(super) struct Sim(pub(super) Child);

impl Drop for Sim {
    fn drop(&mut self) {
        let _ =
            nix::sys::signal::kill(nix::unistd::Pid::from_raw(self.0.id() as i32), nix::sys::signal::Signal::SIGTERM);
        let _ = self.0.wait();
    }
}

impl Sim {
    /// `survey sim ARGS` in `b`, running until dropped, and its ready line.
    pub(super) fn serve(b: &super::Bench, args: &[&str]) -> (Sim, serde_json::Value) {
        use std::io::{BufRead as _, BufReader};
        use std::process::Stdio;
        let mut all = vec!["sim"];
        all.extend_from_slice(args);
        let mut child = b.command(&all).stdout(Stdio::piped()).stderr(Stdio::null()).spawn().expect("start survey sim");
        let mut ready = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut ready).unwrap();
        let sim = Sim(child);
        (sim, serde_json::from_str(&ready).expect("the ready line"))
    }
}

fn config(positioner: &str, tracker: &str) -> String {
    format!(
        "[survey]\nreference = \"tracker\"\npoints = 12\nruns = 2\nbidirectional = true\n\
         [positioner]\ndriver = \"modbus-tcp\"\naddress = \"{positioner}\"\n\
         [tracker]\ndriver = \"emscon\"\naddress = \"{tracker}\"\n\
         [timing]\ndwell_s = 0.01\npoll_interval_s = 0.02\n\
         [drift_control]\nevery_steps = 6\nreference_deg = 0.0\ncorrect = true\n"
    )
}

fn survey(db: &Path, args: &[&str]) -> (i32, String, String) {
    let out = Command::new(BIN).arg("--db").arg(db).args(args).env_remove("RUST_LOG").output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The rows `(time_s, before_step, drift_deg)` of a drift table in text output.
fn drift_rows(text: &str) -> Vec<(f64, u64, f64)> {
    let mut lines = text.lines().skip_while(|l| !l.contains("drift of the reference target"));
    assert!(lines.next().is_some(), "no drift table in:\n{text}");
    assert!(lines.next().is_some_and(|h| h.contains("time_s") && h.contains("drift_deg")), "{text}");
    lines
        .map_while(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            match f.as_slice() {
                [t, s, d] => Some((t.parse().ok()?, s.parse().ok()?, d.parse().ok()?)),
                _ => None,
            }
        })
        .collect()
}

#[test]
fn drift_control_against_survey_sim_is_the_simulators_drift_in_show_and_stats() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("drift.toml");
    std::fs::write(&model, format!("[[effect]]\nkind = \"drift\"\nrate_deg_per_run = {RATE}\nshape = \"ramp\"\n"))
        .unwrap();
    let sim_cfg = dir.path().join("sim.toml");
    std::fs::write(&sim_cfg, config("127.0.0.1:0", "127.0.0.1:0")).unwrap();
    let mut child = Command::new(BIN)
        .args(["sim", "--config", sim_cfg.to_str().unwrap(), "--model", model.to_str().unwrap()])
        .args(["--time-scale", &SCALE.to_string(), "--seed", "5"])
        .env_remove("RUST_LOG")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.as_mut().unwrap()).read_line(&mut line).unwrap();
    let sim = Sim(child);
    let ready: Value = serde_json::from_str(&line).expect("the ready line");
    let run_s = ready["drift_run_s"].as_f64().expect("a drifting model: the ready line gives the run length");
    // 12 targets both ways: 24 moves of 30 deg at the preset's pace, each
    // with settle, dwell, a 1 s measurement and a poll; tens of seconds.
    assert!((10.0..300.0).contains(&run_s), "{run_s}");
    let at = |k: &str| ready["instruments"][k].as_str().unwrap().to_string();
    let run_cfg = dir.path().join("run.toml");
    std::fs::write(&run_cfg, config(&at("positioner"), &at("tracker"))).unwrap();

    let db = dir.path().join("s.db");
    let (code, out, err) = survey(&db, &["run", "--config", run_cfg.to_str().unwrap(), "--json"]);
    drop(sim);
    assert_eq!(code, 0, "{err}");
    let run: Value = serde_json::from_str(&out).unwrap();
    assert_eq!((run["status"].as_str(), run["samples"].as_u64()), (Some("complete"), Some(48)), "{run}");

    // show and stats, --json: the same points; stats says they corrected.
    let (code, out, err) = survey(&db, &["show", "--json"]);
    assert_eq!(code, 0, "{err}");
    let show: Value = serde_json::from_str(&out).unwrap();
    let (code, out, err) = survey(&db, &["stats", "--json"]);
    assert_eq!(code, 0, "{err}");
    let stats: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(show["drift"], stats["drift"]);
    assert_eq!(stats["drift"]["corrected"], true);
    let points = stats["drift"]["points"].as_array().unwrap().clone();
    let seqs: Vec<u64> = points.iter().map(|p| p["before_seq"].as_u64().unwrap()).collect();
    assert_eq!(seqs, [0, 6, 12, 18, 24, 30, 36, 42, 48], "before step 0, every 6 steps, after the last");
    let t: Vec<f64> = points.iter().map(|p| p["at_s"].as_f64().unwrap()).collect();
    let d: Vec<f64> = points.iter().map(|p| p["drift_deg"].as_f64().unwrap()).collect();
    assert_eq!(d[0], 0.0, "the drift is counted from the first reference measurement");

    // Against the simulator's drift: the model has no other error (P' = 0:
    // the reference sees the whole drift), so drift(t) = RATE x SCALE x
    // (t - t0) / run_s, t the run's wall-clock time stamps. Tolerance: the
    // tracker's noise at the reference (0.0009 deg for each reading; a
    // difference of two, 5 sd: 0.0064 deg), and the lag from the moment the
    // simulated axis came to rest (its drift freezes there) to the time stamp,
    // which varies by up to a 0.1 s poll plus the scheduling of two processes
    // on a shared machine: allowed 0.5 s of wall-clock time. Measured: 0.31
    // deg of drift over 6.8 s, the worst point 3.2e-3 deg off (tolerance
    // 0.029 deg).
    let per_s = RATE * SCALE / run_s;
    let tol = 0.0064 + 0.5 * per_s;
    let total = per_s * (t[8] - t[0]);
    assert!(total > 5.0 * tol, "the drift ({total} deg) stands well above the tolerance ({tol} deg)");
    for k in 0..points.len() {
        let want = per_s * (t[k] - t[0]);
        assert!(
            (d[k] - want).abs() < tol,
            "point {k} at {} s: drift {} deg, simulated {want} deg (+/- {tol})",
            t[k],
            d[k]
        );
    }

    // The text of show and stats: the same table.
    for cmd in ["show", "stats"] {
        let (code, out, err) = survey(&db, &[cmd]);
        assert_eq!(code, 0, "{cmd}: {err}");
        let rows = drift_rows(&out);
        assert_eq!(rows.len(), points.len(), "{cmd}:\n{out}");
        for (r, k) in rows.iter().zip(0..) {
            assert!((r.0 - t[k]).abs() <= 0.051 && r.1 == seqs[k], "{cmd} row {k}: {r:?}");
            // Three significant digits (`{:.3e}`).
            assert!((r.2 - d[k]).abs() <= 0.0005 * d[k].abs() + 1e-15, "{cmd} row {k}: {} vs {}", r.2, d[k]);
        }
        if cmd == "stats" {
            assert!(out.contains("corrected for this drift"), "{out}");
        }
    }

    // Corrected, the statistics see the positioner without its drift: the
    // model has no other error, so what is left is the tracker's noise (0.0009
    // deg a sample) and the correction's own error, each sample's time stamp
    // lagging its rest by a varying part of a poll and of the scheduling (at
    // 0.045 deg of drift per wall-clock second here); uncorrected, the
    // accuracy would carry the drift of a whole survey. Measured: A = 0.015
    // deg against 0.31 deg of drift; asserted below a fifth of the drift.
    let a = stats["iso230_2"]["A"].as_f64().unwrap();
    let worst = (0..points.len()).map(|k| (d[k] - per_s * (t[k] - t[0])).abs()).fold(0.0, f64::max);
    eprintln!(
        "drift: run_s {run_s:.1}, {:.1} s of wall clock, total {total:.4} deg, worst deviation {worst:.2e} deg (tolerance {tol:.2e}), A {a:.4} deg",
        t[8] - t[0]
    );
    assert!(a < total / 5.0, "A {a} deg with the drift {total} deg corrected");

    // The report draws the drift over time and states its range: the last
    // point's drift, printed with the report's digits.
    let out_dir = dir.path().join("report");
    let (code, _, err) = survey(&db, &["report", "--out", out_dir.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let html = std::fs::read_to_string(out_dir.join("index.html")).unwrap();
    for id in ["<section id=\"drift\"", "<figure id=\"fig-drift\">", "<table id=\"tbl-drift\">"] {
        assert!(html.contains(id), "{id} missing from the report");
    }
    assert!(html.contains("9 re-measurements of the reference position"), "the caption counts the 9 points");
}

#[test]
fn survey_sim_refuses_a_drifting_model_when_the_run_length_is_unknown() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("drift.toml");
    std::fs::write(&model, "[[effect]]\nkind = \"drift\"\nrate_deg_per_run = 0.01\n").unwrap();
    let cfg = dir.path().join("c.toml");
    let text = config("127.0.0.1:0", "127.0.0.1:0").replace("points = 12\n", "");
    std::fs::write(&cfg, text).unwrap();
    let out = Command::new(BIN)
        .args(["sim", "--config", cfg.to_str().unwrap(), "--model", model.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("drifts 0.01 deg per run") && err.contains("`points`"), "{err}");
    assert!(out.stdout.is_empty(), "no ready line");
}

/// A survey of 3 runs both ways (120 targets, a 20 cycles/rev line, backlash
/// 0.008 deg, noise 2e-4 deg, a target every 10 s) whose error jumps by
/// `knock` deg half-way through the second run (a knock, a reference that
/// slipped), as the import CSV with its times.
fn knocked_csv(knock: f64) -> String {
    let mut csv = String::from("run,direction,target_deg,readout_deg,actual_deg,timestamp_s\n");
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut noise = || {
        // Sum of 12 uniforms less 6: about normal, unit variance.
        (0..12)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 11) as f64 / (1u64 << 53) as f64
            })
            .sum::<f64>()
            - 6.0
    };
    let mut t = 0.0;
    for run in 1..=3 {
        for (dir, sign, order) in
            [("forward", 0.5, (0..120).collect::<Vec<_>>()), ("reverse", -0.5, (0..120).rev().collect::<Vec<_>>())]
        {
            for i in order {
                let target = 3.0 * f64::from(i);
                let knocked = if t > 3.0 * 2400.0 / 2.0 { knock } else { 0.0 };
                let error = 0.004 * (20.0 * target.to_radians()).sin() + sign * 0.008 + knocked + 2e-4 * noise();
                csv += &format!("{run},{dir},{target},{},{target},{t}\n", target + error);
                t += 10.0;
            }
        }
    }
    csv
}

/// Issue 49, item 1: a drift the survey detected and could not correct (no
/// straight line in time takes a jump half-way through) is named with its
/// size, and the table is NOT A RESULT (`predicted.not_a_result`,
/// `"drift-not-corrected"`; the text and the notes say so); the same survey
/// without the jump is a result.
#[test]
fn a_drift_no_straight_line_takes_makes_the_table_not_a_result() {
    let dir = tempfile::tempdir().unwrap();
    for (knock, crooked) in [(0.003, true), (0.0, false)] {
        let db = dir.path().join(format!("k{knock}.db"));
        let csv = dir.path().join(format!("k{knock}.csv"));
        std::fs::write(&csv, knocked_csv(knock)).unwrap();
        let (code, _, err) = survey(&db, &["import", csv.to_str().unwrap()]);
        assert_eq!(code, 0, "{err}");
        let table = dir.path().join(format!("t{knock}.csv"));
        // The design names the line, as the positioner's drawing would.
        let design = dir.path().join("design.toml");
        std::fs::write(&design, "[design]\ngear_ratios = [20]\ntooth_counts = []\n").unwrap();
        let design = design.to_str().unwrap();
        let (code, out, err) =
            survey(&db, &["process", "--design", design, "--table-out", table.to_str().unwrap(), "--json"]);
        assert_eq!(code, 0, "{err}");
        let doc: Value = serde_json::from_str(&out).unwrap();
        let d = &doc["drift_in_time"];
        let p = &doc["predicted"];
        if crooked {
            assert_eq!(d["left_beyond_doubt"], true, "{d}");
            assert_eq!(p["not_a_result"], "drift-not-corrected", "{p}");
            // The jump, less what the straight line took of it, is what a pass
            // keeps (measured 9.8e-4 deg of the 3e-3 jump).
            let left = p["uncorrected_drift_deg"].as_f64().unwrap();
            assert!(left > 5e-4 && left < 0.003, "{p}");
            assert!(err.contains("the table carries that drift and is not a result"), "{err}");
            let (code, text, _) = survey(&db, &["process", "--design", design, "--table-out", table.to_str().unwrap()]);
            assert_eq!(code, 0);
            assert!(text.contains("NOT A RESULT: the survey drifted in time"), "{text}");
        } else {
            assert_eq!(d["left_beyond_doubt"], false, "{d}");
            assert_eq!(p["not_a_result"], Value::Null, "{p}");
            assert_eq!(p["uncorrected_drift_deg"], Value::Null, "{p}");
        }
    }
}
