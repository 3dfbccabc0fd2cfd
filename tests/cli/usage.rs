//! Issue 24 from outside: the command line as a new user meets it (the usage
//! line, where a count comes from, negative numbers, what `sim` and `show`
//! print, notes only where they matter, one `--units`, completions, the man
//! pages, model-gap's columns, the time scale).

use super::Bench;

/// A configuration of instruments nothing answers for (port 1 refuses at
/// once, the serial port does not exist): the plan is made and printed, then
/// the first call fails.
fn unreachable_polygon_config(survey: &str) -> String {
    format!(
        "[survey]\nruns = 2\nreference = \"autocollimator\"\n{survey}\n\
         [positioner]\ndriver = \"scpi-tcp\"\naddress = \"127.0.0.1:1\"\n\n\
         [autocollimator]\ndriver = \"elcomat\"\nport = \"/nonexistent/tty\"\n\n\
         [polygon]\nfaces = 12\n\n[timing]\ncall_timeout_s = 0.2\nmax_retries = 0\n"
    )
}

#[test]
fn run_shows_its_required_arguments_and_asks_for_points_only_where_nothing_gives_them() {
    let b = Bench::new();
    let help = b.survey(&["run", "--help"]).success();
    assert!(help.stdout.contains("Usage: survey run --points <N> [OPTIONS]"), "{help}");
    assert!(help.stdout.contains("survey run --config <FILE> [OPTIONS]"), "{help}");
    let out = b.survey(&["run"]).bad_input(&["--points N is required", "Usage: survey run --points <N>"]);
    assert!(out.stderr.contains("--reference autocollimator"), "says where else the count comes from\n{out}");
    assert!(!b.exists("survey.db"), "{out}");

    // The simulated autocollimator's polygon: its 24 faces.
    let doc = b.survey(&["run", "--reference", "autocollimator", "--runs", "2", "--json"]).success().json();
    assert_eq!(doc["samples"], 24 * 2, "{doc}");

    // A configured polygon gives its faces (12 here): the plan is made before
    // the instruments are called (and fail: nothing listens).
    b.write("polygon.toml", unreachable_polygon_config(""));
    let out = b.survey(&["--db", "c.db", "run", "--config", "polygon.toml"]);
    assert_eq!(out.code, 1, "the instruments fail, not the plan\n{out}");
    assert!(out.stderr.contains("12 targets x 2 runs"), "{out}");
    // The configuration's [survey] points comes first (it must be the faces).
    b.write("points.toml", unreachable_polygon_config("points = 10"));
    b.survey(&["--db", "c.db", "run", "--config", "points.toml"]).bad_input(&["points.toml", "10", "12"]);
}

#[test]
fn a_negative_count_gets_the_range_not_unexpected_argument() {
    let b = Bench::new();
    for (flag, value, range) in [
        ("--points", "-5", "at least 2"),
        ("--runs", "-1", "at least 2"),
        ("--seed", "-1", "at least 0"),
        ("--points", "0", "at least 2"),
    ] {
        let mut args = vec!["run", "--points", "36", "--runs", "2"];
        match args.iter().position(|a| *a == flag) {
            Some(i) => args[i + 1] = value,
            None => args.extend([flag, value]),
        }
        let out = b.survey(&args).bad_input(&[flag, value, range]);
        assert!(!out.stderr.contains("unexpected argument"), "{out}");
    }
    let out = b.survey(&["run", "--points", "36", "--verify", "--verify-points", "0"]);
    out.bad_input(&["--verify-points", "at least 2"]);
    b.survey(&["process", "--table-points", "-3"]).bad_input(&["--table-points", "at least 2"]);
    assert!(!b.exists("survey.db"));
    // A negative survey id is an id that does not exist.
    b.small_survey(false);
    b.survey(&["stats", "--survey", "-1"]).bad_input(&["-1"]);
}
