//! The axis from the whole survey (issue 14): on the default bench (the
//! paper's Figure 8 positioner, a tracker, 1800 points, 5 runs, both
//! directions) over three seeds, the table made around the axis fitted again
//! from every SMR position carries the positioner's true once-per-revolution
//! error, where the axis located from 12 positions before the runs left up to
//! 6.5e-4 deg of false eccentricity in it. The tracker is an ideal one here
//! (`[tracker_errors] none = true`): a real tracker's own error is in the
//! table whatever the axis (the uncertainty's systematic part of the
//! reference), and this is a test of the axis.

use std::path::Path;
use std::process::Command;
use survey_processing::Direction;
use survey_processing::model::Model;

const BIN: &str = env!("CARGO_BIN_EXE_survey");

pub(crate) fn survey(db: &Path, args: &[&str]) -> serde_json::Value {
    let out = Command::new(BIN).arg("--db").arg(db).args(args).env_remove("RUST_LOG").output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("one JSON document")
}

/// The table's once-per-revolution line against the truth (|difference of
/// the phasors|, deg), and the table's residual rms against the model's
/// error (deg, mean removed: a constant is the zero reference).
pub(crate) fn against_truth(doc: &serde_json::Value, table: &Path, model: &Model) -> (f64, f64) {
    let line = doc["peaks"].as_array().unwrap().iter().find(|p| p["cycles_per_rev"] == 1.0).cloned();
    let (a, ph) = line.map_or((0.0, 0.0), |p| (p["amplitude_deg"].as_f64().unwrap(), p["phase_deg"].as_f64().unwrap()));
    let (ta, tph) = (0.0015f64, 110f64); // fig8's eccentricity
    let d = (a * ph.to_radians().cos() - ta * tph.to_radians().cos())
        .hypot(a * ph.to_radians().sin() - ta * tph.to_radians().sin());
    let text = std::fs::read_to_string(table).unwrap();
    let mut res = Vec::new();
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        let cols: Vec<(Direction, f64)> = if v.len() == 3 {
            vec![(Direction::Forward, v[1]), (Direction::Reverse, v[2])]
        } else {
            vec![(Direction::Forward, v[1])]
        };
        for (dir, e) in cols {
            let actual = v[0] - e;
            let truth = if v.len() == 3 {
                model.repeatable_error_deg(actual, dir)
            } else {
                (model.repeatable_error_deg(actual, Direction::Forward)
                    + model.repeatable_error_deg(actual, Direction::Reverse))
                    / 2.0
            };
            res.push(e - truth);
        }
    }
    let mean = res.iter().sum::<f64>() / res.len() as f64;
    let rms = (res.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / res.len() as f64).sqrt();
    (d, rms)
}

#[test]
fn the_refitted_axis_keeps_the_located_axis_error_out_of_the_table() {
    let text = format!("{}\n[tracker_errors]\nnone = true\n", include_str!("../../sims/presets/fig8.toml"));
    let model = Model::parse(&text, "fig8.toml").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("fig8-ideal-tracker.toml");
    std::fs::write(&file, &text).unwrap();
    let mut worst = (0.0f64, 0.0f64, 0.0f64);
    for seed in ["1", "2", "3"] {
        let db = dir.path().join(format!("s{seed}.db"));
        let args = ["run", "--points", "1800", "--bidirectional", "--seed", seed, "--json", "--model"];
        survey(&db, &[&args[..], &[file.to_str().unwrap()]].concat());
        let t = dir.path().join(format!("t{seed}.csv"));
        let refit = survey(&db, &["process", "--table-out", t.to_str().unwrap(), "--json"]);
        let (line, rms) = against_truth(&refit, &t, &model);
        let located = survey(&db, &["process", "--located-axis", "--table-out", t.to_str().unwrap(), "--json"]);
        let (located_line, located_rms) = against_truth(&located, &t, &model);
        eprintln!(
            "seed {seed}: once-per-rev error {line:.2e} deg (located {located_line:.2e}), true residual rms {rms:.2e} \
             (located {located_rms:.2e}); {}",
            refit["axis_refit"]
        );
        let r = &refit["axis_refit"];
        assert!(r["points"].as_u64().unwrap() >= 18_000, "{r}");
        // The refit's own estimate of what it removed is the line's change.
        assert!(r["located_once_per_rev_deg"].as_f64().unwrap() > 0.0, "{r}");
        worst = (worst.0.max(line), worst.1.max(rms), worst.2.max(located_line));
    }
    // Goal 4e-5 deg on the once-per-revolution line (measured 0.4 to 3.4e-5;
    // the located axis gave up to 6.5e-4), and the goal of a true residual
    // rms of at most 3e-5 deg (measured 1.97 to 2.97e-5 on these seeds, 1.34
    // to 2.97e-5 on seeds 1-6: the tracker's noise through the three kept
    // lines; the located axis gave up to 4.6e-4, and each direction's lines
    // fitted on their own, before the direction model, up to 3.2e-5).
    assert!(worst.0 < 4e-5, "once-per-revolution line off the truth by {:.2e} deg", worst.0);
    assert!(worst.1 <= 3e-5, "true residual rms {:.2e} deg", worst.1);
    assert!(worst.2 > 1e-4, "the located axis's error shows without the refit ({:.2e})", worst.2);
}

/// A survey some of whose samples have no SMR position (their raw readings
/// gone: read from the rows, the positions through their indices) is
/// refitted from the positions it has: the same axis to well within its
/// uncertainty, two positions fewer.
#[test]
fn samples_without_a_position_are_refitted_from_the_others() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("s.db");
    survey(&db, &["run", "--points", "360", "--bidirectional", "--json"]);
    let (t, u) = (dir.path().join("t.csv"), dir.path().join("u.csv"));
    let whole = survey(&db, &["process", "--table-out", t.to_str().unwrap(), "--json"]);
    let c = rusqlite::Connection::open(&db).unwrap();
    assert_eq!(c.execute("DELETE FROM raw_readings WHERE seq IN (10, 2000)", []).unwrap(), 2);
    drop(c);
    let sparse = survey(&db, &["process", "--table-out", u.to_str().unwrap(), "--json"]);
    // The table as it was, to the noise two positions carry (the zero
    // reference aside: a table's constant is its zero's).
    let rows = |p: &Path| -> Vec<Vec<f64>> {
        let text = std::fs::read_to_string(p).unwrap();
        text.lines().skip(1).map(|l| l.split(',').map(|x| x.parse().unwrap()).collect()).collect()
    };
    let worst = rows(&t)
        .iter()
        .zip(rows(&u))
        .flat_map(|(a, b)| a[1..].iter().zip(&b[1..]).map(|(x, y)| (x - y).abs()).collect::<Vec<_>>())
        .fold(0.0f64, f64::max);
    assert!(worst < 2e-5, "the table moved by {worst} deg");
    // The two samples without a position are in the refit's frame, not
    // named gross readings (they stood 3-4e-3 deg off, the zeros apart).
    assert_eq!(sparse["gross_readings"]["readings"], serde_json::json!([]), "{}", sparse["gross_readings"]);
    let (w, s) = (&whole["axis_refit"], &sparse["axis_refit"]);
    assert_eq!(s["points"].as_u64().unwrap() + 2, w["points"].as_u64().unwrap(), "{s} {w}");
    // Two positions of 3612 move the centre by about 2/3612 of a position's
    // scatter: far below the centre's standard error.
    let se = w["center_se_mm"].as_f64().unwrap();
    let moved = (s["center_shift_mm"].as_f64().unwrap() - w["center_shift_mm"].as_f64().unwrap()).abs();
    assert!(moved < se, "the centre moved {moved} mm, its standard error {se} mm");
    assert!((s["radius_mm"].as_f64().unwrap() - w["radius_mm"].as_f64().unwrap()).abs() < se, "{s} {w}");
}
