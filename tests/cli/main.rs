//! End-to-end tests of the `survey` binary against the outside surface in
//! `/work/shared/contract.md`: every command that exists today (`run`, `import`,
//! `export`, `stats`) and every exit status (0 success, 1 run-time failure,
//! 2 bad usage or bad input).
//!
//! Each test gets its own temporary folder, runs the built binary in it and keeps
//! its simulated surveys small (36 points x 2 runs runs in a few milliseconds of
//! real time). The simulator is seeded (`--seed` defaults to 1), so every test is
//! deterministic.
//!
//! "Nothing already stored is changed by a failed command" is checked black-box:
//! [`Bench::stored`] exports every survey of the database (ids 1, 2, ... until
//! the first that does not exist); a failed command must leave that list equal,
//! and the next valid import must get the next id.

mod auth;
mod browser;
mod budget;
mod correction;
mod damage;
mod dcc;
mod docs;
mod doors;
mod drift;
mod error_motions;
mod everyday;
mod files;
mod history;
mod instruments;
mod lab;
mod lab_tls;
mod life;
mod list;
mod modelgap;
mod process;
mod report;
mod runs;
mod serve;
mod stale;
mod tables;
mod usage;
mod verify;
mod walk;

use serde_json::Value;
use std::fmt;
use std::path::PathBuf;
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_survey");

const HEADER: &str = "run,direction,target_deg,readout_deg,actual_deg";

/// The keys of `survey stats --json`'s `iso230_2` object that the contract names.
const ISO_KEYS: [&str; 12] = ["A", "A_up", "A_down", "R", "R_up", "R_down", "B", "B_mean", "E", "E_up", "E_down", "M"];

/// A small, valid, bidirectional survey (2 targets x 2 runs) written the way
/// `survey export` writes numbers (shortest round-trip form), so that importing
/// and exporting it gives back the same bytes.
const VALID_CSV: &str = "run,direction,target_deg,readout_deg,actual_deg\n\
1,forward,0,0,0.001\n\
1,forward,180,180,180.002\n\
1,reverse,180,180,179.999\n\
1,reverse,0,0,-0.001\n\
2,forward,0,0,0.0012\n\
2,forward,180,180,180.0025\n\
2,reverse,180,180,179.9985\n\
2,reverse,0,0,-0.0008\n";

/// The same survey with the optional `timestamp_s` column.
const VALID_CSV_WITH_TIMESTAMPS: &str = "run,direction,target_deg,readout_deg,actual_deg,timestamp_s\n\
1,forward,0,0,0.001,0\n\
1,forward,180,180,180.002,12.5\n\
1,reverse,180,180,179.999,14.25\n\
1,reverse,0,0,-0.001,26.75\n\
2,forward,0,0,0.0012,29\n\
2,forward,180,180,180.0025,41.5\n\
2,reverse,180,180,179.9985,43.25\n\
2,reverse,0,0,-0.0008,55.75\n";

/// The contract's example model file, without the drift effect: a 12-pass gear,
/// backlash and noise, with a `[design]` table.
const CONTRACT_MODEL: &str = r#"[design]
gear_ratios = [12]      # gear passes per axis revolution (a 12:1 pinion gives 12)
tooth_counts = [216]    # tooth counts of gears that turn once per revolution
encoder_heads = 2       # optional: 2 diametric heads cancel odd harmonics

[[effect]]
kind = "gear_pass"
cycles_per_rev = 12
amplitude_deg = 0.006
phase_deg = 30.0

[[effect]]
kind = "backlash"
amplitude_deg = 0.004

[[effect]]
kind = "noise"
sigma_deg = 0.0005
"#;

// ---------------------------------------------------------------------------
// Running the binary
// ---------------------------------------------------------------------------

/// What one run of the binary gave.
#[derive(Debug)]
struct Output {
    args: Vec<String>,
    code: i32,
    stdout: String,
    stderr: String,
}

impl fmt::Display for Output {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "`survey {}` exited {}\n--- stdout ---\n{}\n--- stderr ---\n{}",
            self.args.join(" "),
            self.code,
            self.stdout,
            self.stderr
        )
    }
}

impl Output {
    /// Asserts exit status 0 and returns self.
    #[track_caller]
    fn success(self) -> Self {
        assert_eq!(self.code, 0, "expected success\n{self}");
        self
    }

    /// Asserts exit status 2 (bad usage or bad input), a message on stderr that
    /// contains every one of `words`, and returns self.
    #[track_caller]
    fn bad_input(self, words: &[&str]) -> Self {
        assert_eq!(self.code, 2, "expected exit status 2 (bad usage or input)\n{self}");
        self.stderr_mentions(words)
    }

    /// Asserts stderr contains every one of `words`.
    #[track_caller]
    fn stderr_mentions(self, words: &[&str]) -> Self {
        for w in words {
            assert!(self.stderr.contains(w), "stderr should mention {w:?}\n{self}");
        }
        self
    }

    /// Parses stdout as exactly one JSON document (nothing else on stdout).
    #[track_caller]
    fn json(&self) -> Value {
        match serde_json::from_str::<Value>(&self.stdout) {
            Ok(v) => {
                assert!(v.is_object(), "the JSON document should be an object\n{self}");
                v
            }
            Err(e) => panic!("stdout should be exactly one JSON document: {e}\n{self}"),
        }
    }
}

/// A temporary folder to run the binary in (the default database `survey.db`
/// lives there).
struct Bench {
    dir: tempfile::TempDir,
}

impl Bench {
    fn new() -> Self {
        Bench { dir: tempfile::tempdir().expect("temporary folder") }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    fn exists(&self, name: &str) -> bool {
        self.path(name).exists()
    }

    fn write(&self, name: &str, content: impl AsRef<[u8]>) {
        std::fs::write(self.path(name), content).expect("write a test file");
    }

    fn read(&self, name: &str) -> String {
        std::fs::read_to_string(self.path(name)).unwrap_or_else(|e| panic!("read {name}: {e}"))
    }

    /// A command for the binary in the bench folder, with no `SURVEY_DB`,
    /// `SURVEY_LAB` or `RUST_LOG` from the environment of the test run.
    fn command(&self, args: &[&str]) -> Command {
        let mut cmd = Command::new(BIN);
        cmd.args(args)
            .current_dir(self.dir.path())
            .env_remove("SURVEY_DB")
            .env_remove("SURVEY_LAB")
            .env_remove("RUST_LOG");
        cmd
    }

    fn output_of(args: &[&str], mut cmd: Command) -> Output {
        let out = cmd.output().expect("start the survey binary");
        Output {
            args: args.iter().map(|s| s.to_string()).collect(),
            code: out.status.code().expect("the binary exited (not killed by a signal)"),
            stdout: String::from_utf8(out.stdout).expect("stdout is UTF-8"),
            stderr: String::from_utf8(out.stderr).expect("stderr is UTF-8"),
        }
    }

    fn survey(&self, args: &[&str]) -> Output {
        Self::output_of(args, self.command(args))
    }

    fn survey_with_env(&self, args: &[&str], key: &str, value: &str) -> Output {
        let mut cmd = self.command(args);
        cmd.env(key, value);
        Self::output_of(args, cmd)
    }

    /// A small simulated survey (36 points x 2 runs) in the default database;
    /// returns its id.
    fn small_survey(&self, bidirectional: bool) -> i64 {
        let mut args = vec!["run", "--points", "36", "--runs", "2", "--json"];
        if bidirectional {
            args.push("--bidirectional");
        }
        let out = self.survey(&args).success();
        out.json()["survey_id"].as_i64().unwrap_or_else(|| panic!("survey_id is an integer\n{out}"))
    }

    /// `survey stats --json [--survey ID]` on the default database.
    fn stats_json(&self, id: Option<i64>) -> Value {
        let id = id.map(|i| i.to_string());
        let mut args = vec!["stats", "--json"];
        if let Some(id) = &id {
            args.extend(["--survey", id.as_str()]);
        }
        self.survey(&args).success().json()
    }

    /// `survey export --csv FILE [--survey ID]` on the default database; returns the CSV.
    fn export(&self, id: Option<i64>, file: &str) -> String {
        let id = id.map(|i| i.to_string());
        let mut args = vec!["export", "--csv", file];
        if let Some(id) = &id {
            args.extend(["--survey", id.as_str()]);
        }
        self.survey(&args).success();
        self.read(file)
    }

    /// `survey import FILE` on the default database; checks stdout is just the
    /// new id and returns it.
    fn import(&self, file: &str) -> i64 {
        let out = self.survey(&["import", file]).success();
        let id: i64 = out
            .stdout
            .trim_end()
            .parse()
            .unwrap_or_else(|e| panic!("import should print only the new id ({e})\n{out}"));
        assert_eq!(out.stdout, format!("{id}\n"), "import prints the id and nothing else\n{out}");
        id
    }

    /// Every survey stored in the default database, as its CSV export, in id
    /// order (ids 1, 2, ... up to the first that does not exist). Empty when
    /// there is no database.
    fn stored(&self) -> Vec<String> {
        if !self.exists("survey.db") {
            return Vec::new();
        }
        let mut surveys = Vec::new();
        for id in 1.. {
            let probe = format!("probe-{id}.csv");
            let id_text = id.to_string();
            let out = self.survey(&["export", "--csv", &probe, "--survey", &id_text]);
            if out.code != 0 {
                out.bad_input(&[&id_text]);
                break;
            }
            surveys.push(self.read(&probe));
            std::fs::remove_file(self.path(&probe)).expect("remove the probe export");
        }
        surveys
    }

    /// Asserts that the database holds exactly `before`, and that a following
    /// valid import gets the next id (so the failed command stored nothing, not
    /// even an empty survey that was removed again).
    #[track_caller]
    fn assert_unchanged(&self, before: &[String], failed: &Output) {
        let after = self.stored();
        assert_eq!(after.len(), before.len(), "a failed command added or removed a survey\n{failed}");
        for (i, (a, b)) in before.iter().zip(&after).enumerate() {
            assert!(a == b, "survey {} changed after a failed command\n{failed}", i + 1);
        }
        self.write("next-valid.csv", VALID_CSV);
        let next = self.import("next-valid.csv");
        assert_eq!(next, before.len() as i64 + 1, "the next import should get the next id\n{failed}");
    }
}

/// The `iso230_2` figures of a stats document, by contract key.
fn iso_figure(doc: &Value, key: &str) -> Option<f64> {
    let iso = doc.get("iso230_2").unwrap_or_else(|| panic!("no iso230_2 in {doc}"));
    let v = iso.get(key).unwrap_or_else(|| panic!("iso230_2 has no key {key:?}: {iso}"));
    if v.is_null() {
        None
    } else {
        Some(v.as_f64().unwrap_or_else(|| panic!("iso230_2.{key} should be a number or null, got {v}")))
    }
}

/// The figure `key`, which must be a number.
#[track_caller]
fn number(doc: &Value, key: &str) -> f64 {
    iso_figure(doc, key).unwrap_or_else(|| panic!("iso230_2.{key} should be a number: {doc}"))
}

/// The data rows of a survey CSV (without the header), split into cells.
fn rows(csv: &str) -> Vec<Vec<String>> {
    csv.lines().skip(1).map(|l| l.split(',').map(str::to_string).collect()).collect()
}

// ---------------------------------------------------------------------------
// An independent ISO 230-2 computation from a survey CSV
// ---------------------------------------------------------------------------

/// Mean and sample standard deviation (n - 1) of one direction at one target.
fn mean_s(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let s = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    (mean, s)
}

/// The contract's ISO 230-2 figures, computed here from the CSV rows with the
/// positioning deviation `x = actual - target` and the standard's formulas.
fn iso_from_csv(csv: &str) -> std::collections::BTreeMap<&'static str, Option<f64>> {
    // (target, forward deviations, reverse deviations), in order of appearance.
    let mut targets: Vec<(f64, Vec<f64>, Vec<f64>)> = Vec::new();
    for row in rows(csv) {
        let target: f64 = row[2].parse().expect("target_deg");
        let actual: f64 = row[4].parse().expect("actual_deg");
        let i = match targets.iter().position(|t| t.0 == target) {
            Some(i) => i,
            None => {
                targets.push((target, Vec::new(), Vec::new()));
                targets.len() - 1
            }
        };
        match row[1].as_str() {
            "forward" => targets[i].1.push(actual - target),
            "reverse" => targets[i].2.push(actual - target),
            other => panic!("direction {other}"),
        }
    }
    let max = |it: &mut dyn Iterator<Item = f64>| it.fold(f64::NEG_INFINITY, f64::max);
    let min = |it: &mut dyn Iterator<Item = f64>| it.fold(f64::INFINITY, f64::min);
    let up: Vec<(f64, f64)> = targets.iter().filter(|t| !t.1.is_empty()).map(|t| mean_s(&t.1)).collect();
    let down: Vec<(f64, f64)> = targets.iter().filter(|t| !t.2.is_empty()).map(|t| mean_s(&t.2)).collect();
    let dir_figures = |d: &[(f64, f64)]| -> (Option<f64>, Option<f64>, Option<f64>) {
        if d.is_empty() {
            return (None, None, None);
        }
        let a = max(&mut d.iter().map(|(m, s)| m + 2.0 * s)) - min(&mut d.iter().map(|(m, s)| m - 2.0 * s));
        let r = max(&mut d.iter().map(|(_, s)| 4.0 * s));
        let e = max(&mut d.iter().map(|(m, _)| *m)) - min(&mut d.iter().map(|(m, _)| *m));
        (Some(a), Some(r), Some(e))
    };
    let (a_up, r_up, e_up) = dir_figures(&up);
    let (a_down, r_down, e_down) = dir_figures(&down);
    let mut f = std::collections::BTreeMap::new();
    f.insert("A_up", a_up);
    f.insert("R_up", r_up);
    f.insert("E_up", e_up);
    f.insert("A_down", a_down);
    f.insert("R_down", r_down);
    f.insert("E_down", e_down);
    if up.is_empty() || down.is_empty() {
        let one = if up.is_empty() { (a_down, r_down, e_down) } else { (a_up, r_up, e_up) };
        f.insert("A", one.0);
        f.insert("R", one.1);
        f.insert("E", one.2);
        f.insert("B", None);
        f.insert("B_mean", None);
        f.insert("M", None);
        return f;
    }
    assert_eq!(up.len(), down.len(), "every target has both directions");
    let both: Vec<(f64, f64)> = up.iter().chain(&down).copied().collect();
    let b_i: Vec<f64> = up.iter().zip(&down).map(|(u, d)| u.0 - d.0).collect();
    let r_i = up
        .iter()
        .zip(&down)
        .zip(&b_i)
        .map(|((u, d), b)| (2.0 * u.1 + 2.0 * d.1 + b.abs()).max(4.0 * u.1).max(4.0 * d.1));
    let mean_bi: Vec<f64> = up.iter().zip(&down).map(|(u, d)| (u.0 + d.0) / 2.0).collect();
    f.insert(
        "A",
        Some(max(&mut both.iter().map(|(m, s)| m + 2.0 * s)) - min(&mut both.iter().map(|(m, s)| m - 2.0 * s))),
    );
    f.insert("R", Some(max(&mut r_i.into_iter())));
    f.insert("E", Some(max(&mut both.iter().map(|(m, _)| *m)) - min(&mut both.iter().map(|(m, _)| *m))));
    f.insert("B", Some(max(&mut b_i.iter().map(|b| b.abs()))));
    f.insert("B_mean", Some(b_i.iter().sum::<f64>() / b_i.len() as f64));
    f.insert("M", Some(max(&mut mean_bi.iter().copied()) - min(&mut mean_bi.iter().copied())));
    f
}

/// Asserts the stats document agrees with [`iso_from_csv`] on every contract key.
#[track_caller]
fn assert_iso_matches_csv(doc: &Value, csv: &str) {
    let expected = iso_from_csv(csv);
    for key in ISO_KEYS {
        let got = iso_figure(doc, key);
        let want = expected[key];
        match (got, want) {
            (Some(g), Some(w)) => {
                assert!((g - w).abs() <= 1e-12, "iso230_2.{key} = {g}, ISO 230-2 from the CSV gives {w}")
            }
            (None, None) => {}
            _ => panic!("iso230_2.{key} = {got:?}, ISO 230-2 from the CSV gives {want:?}"),
        }
    }
}

/// The contract's relations between the figures of a bidirectional survey.
#[track_caller]
fn assert_bidirectional_relations(doc: &Value) {
    for key in ISO_KEYS {
        let v = number(doc, key);
        assert!(v.is_finite(), "iso230_2.{key} = {v}");
        if key != "B_mean" {
            assert!(v >= 0.0, "iso230_2.{key} = {v} should not be negative");
        }
    }
    let f = |k| number(doc, k);
    assert!(f("R") >= f("R_up") && f("R") >= f("R_down"), "R >= R_up, R_down: {doc}");
    assert!(f("A") >= f("A_up") && f("A") >= f("A_down"), "A >= A_up, A_down: {doc}");
    assert!(f("E") >= f("E_up") && f("E") >= f("E_down"), "E >= E_up, E_down: {doc}");
    assert!(f("B") >= f("B_mean").abs(), "B >= |B_mean|: {doc}");
    // A covers the 2s bands around the deviations that E spans.
    assert!(f("A") >= f("E"), "A >= E: {doc}");
    assert!(f("R") > 0.0 && f("A") > 0.0, "a simulated survey has some error: {doc}");
}

// ---------------------------------------------------------------------------
// Usage: help, version, bad arguments
// ---------------------------------------------------------------------------

#[test]
fn help_lists_the_commands_and_exits_0() {
    let b = Bench::new();
    let out = b.survey(&["--help"]).success();
    for cmd in ["run", "import", "export", "stats", "list", "show", "--db"] {
        assert!(out.stdout.contains(cmd), "--help should mention {cmd}\n{out}");
    }
    let out = b.survey(&["run", "--help"]).success();
    for flag in ["--points", "--bidirectional", "--runs", "--model", "--json", "--db"] {
        assert!(out.stdout.contains(flag), "run --help should mention {flag}\n{out}");
    }
    for cmd in ["import", "export", "stats"] {
        b.survey(&[cmd, "--help"]).success();
    }
    assert!(!b.exists("survey.db"), "--help creates no database");
}

#[test]
fn version_exits_0() {
    let b = Bench::new();
    let out = b.survey(&["--version"]).success();
    let version = out.stdout.trim().strip_prefix("survey ").unwrap_or_else(|| panic!("`survey <version>`\n{out}"));
    let parts: Vec<&str> = version.split('.').collect();
    assert!(
        parts.len() == 3 && parts.iter().all(|p| p.parse::<u64>().is_ok()),
        "version should be MAJOR.MINOR.PATCH\n{out}"
    );
}

#[test]
fn mistyped_flag_exits_2_naming_it() {
    let b = Bench::new();
    let out = b.survey(&["run", "--pointz", "5"]).bad_input(&["--pointz"]);
    assert!(out.stdout.is_empty(), "{out}");
    assert!(!b.exists("survey.db"));
}

#[test]
fn unknown_command_exits_2_naming_it() {
    let b = Bench::new();
    let out = b.survey(&["frobnicate"]).bad_input(&["frobnicate"]);
    assert!(out.stdout.is_empty(), "{out}");
}

#[test]
fn no_command_exits_2() {
    let b = Bench::new();
    b.survey(&[]).bad_input(&["Usage"]);
}

#[test]
fn run_without_points_exits_2() {
    let b = Bench::new();
    b.survey(&["run", "--runs", "2"]).bad_input(&["--points"]);
    assert!(!b.exists("survey.db"));
}

#[test]
fn run_with_a_non_number_for_points_exits_2() {
    let b = Bench::new();
    b.survey(&["run", "--points", "abc"]).bad_input(&["--points", "abc"]);
    b.survey(&["run", "--points", "36", "--runs", "two"]).bad_input(&["--runs", "two"]);
    assert!(!b.exists("survey.db"));
}

#[test]
fn run_with_too_few_points_or_runs_exits_2() {
    let b = Bench::new();
    for (flag, value) in [("--points", "1"), ("--points", "0"), ("--runs", "1"), ("--runs", "0")] {
        let mut args = vec!["run", "--points", "36", "--runs", "2", "--bidirectional"];
        let i = args.iter().position(|a| *a == flag).expect("flag in args");
        args[i + 1] = value;
        let out = b.survey(&args).bad_input(&[flag, "at least"]);
        assert!(out.stdout.is_empty(), "{out}");
        assert!(!b.exists("survey.db"), "a rejected run creates no database\n{out}");
    }
}
