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
    // The failure said once on its line, and the log lines without time or module.
    let error = out.stderr.lines().find(|l| l.starts_with("error: ")).expect("an error line");
    assert_eq!(error.matches("cannot connect").count(), 1, "{out}");
    let module = |w: &&str| w.starts_with("survey_") && w.contains("::");
    assert!(!out.stderr.split(|c: char| !(c.is_alphanumeric() || "_:".contains(c))).any(|w| module(&w)), "{out}");
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

#[test]
fn sim_and_show_print_what_a_person_reads_and_json_stays_json() {
    use std::io::{BufRead as _, BufReader};
    use std::process::Stdio;
    let b = Bench::new();
    b.write(
        "sim.toml",
        "[positioner]\ndriver = \"modbus-tcp\"\naddress = \"127.0.0.1:0\"\n\
         [tracker]\ndriver = \"emscon\"\naddress = \"127.0.0.1:0\"\n",
    );
    for (faults, shown) in [
        ("0", "faults injected: none"),
        ("0.01", "faults injected: timeout=0.0025, garbled=0.0025, disconnect=0.0025, stall=0.0025, device=0.01"),
    ] {
        let mut child = b
            .command(&["sim", "--config", "sim.toml", "--faults", faults, "--time-scale", "100"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start survey sim");
        let (mut ready, mut serving) = (String::new(), String::new());
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut ready).unwrap();
        // The lines before say where each instrument is served.
        let mut stderr = BufReader::new(child.stderr.take().unwrap());
        while !serving.contains("serving") {
            serving.clear();
            assert!(stderr.read_line(&mut serving).unwrap() > 0, "survey sim said nothing of serving");
        }
        drop(super::drift::Sim(child));
        assert!(ready.contains("\"ready\":true"), "{ready}");
        assert!(serving.contains("100x real time") && serving.contains(shown), "{serving}");
        assert!(!serving.contains("FaultRates") && !serving.contains('{'), "{serving}");
    }

    // A configured survey's bench, one instrument a line.
    b.write("polygon.toml", unreachable_polygon_config(""));
    b.survey(&["--db", "c.db", "run", "--config", "polygon.toml"]);
    let show = b.survey(&["--db", "c.db", "show"]).success();
    assert!(show.stdout.contains("bench        configured from polygon.toml"), "{show}");
    assert!(show.stdout.contains("positioner   scpi-tcp 127.0.0.1:1"), "{show}");
    assert!(show.stdout.contains("reference    elcomat /nonexistent/tty"), "{show}");
    assert!(!show.stdout.contains("{\""), "no raw JSON in the text\n{show}");
    let doc = b.survey(&["--db", "c.db", "show", "--json"]).success().json();
    assert_eq!(doc["instruments"]["positioner"], "scpi-tcp 127.0.0.1:1", "{doc}");

    // A simulated one: preset, reference, seed and the faults it injected.
    b.survey(&["run", "--points", "12", "--runs", "2", "--fault-rates", "timeout=0.01,device=0.02"]).success();
    let show = b.survey(&["show"]).success();
    assert!(show.stdout.contains("bench        simulated fig8 with a tracker, seed 1"), "{show}");
    assert!(show.stdout.contains("faults       timeout=0.01, device=0.02"), "{show}");
}

#[test]
fn how_the_table_was_made_is_said_under_verbose_only() {
    let b = Bench::new();
    let run = b.survey(&["run", "--points", "36", "--runs", "2", "--bidirectional"]).success();
    assert!(!run.stderr.contains("direction model"), "{run}");
    for args in [&["process"][..], &["report", "--out", "r"]] {
        let out = b.survey(args).success();
        assert!(!out.stderr.contains("direction model"), "{out}");
    }
    let verbose = b.survey(&["-v", "process"]).success();
    assert!(verbose.stderr.contains("direction model: forward - reverse modelled on its own"), "{verbose}");
    let logged = b.survey_with_env(&["process"], "RUST_LOG", "info").success();
    assert!(logged.stderr.contains("direction model"), "{logged}");
    // The document carries it, and the report's page keeps it among its notes.
    let doc = b.survey(&["process", "--json"]).success().json();
    assert!(doc["table"]["direction_model"]["mean_deg"].as_f64().is_some_and(|m| m > 0.0), "{doc}");
    assert!(b.read("r/index.html").contains("direction model: forward - reverse"));
}

/// The first number after `label` on the line of `text` that starts with it.
fn figure_after(text: &str, label: &str) -> f64 {
    let line = text.lines().find(|l| l.trim_start().starts_with(label)).unwrap_or_else(|| panic!("{label}\n{text}"));
    line.trim_start()[label.len()..]
        .split_whitespace()
        .next()
        .and_then(|w| w.parse().ok())
        .unwrap_or_else(|| panic!("{line}"))
}

#[test]
fn one_units_option_on_every_command_that_prints_errors_and_json_stays_in_degrees() {
    let b = Bench::new();
    b.write("gear.toml", "[design]\ngear_ratios = [20]\n\n[[effect]]\nkind = \"gear_pass\"\ncycles_per_rev = 20\namplitude_deg = 0.006\nphase_deg = 30.0\n");
    let run = b.survey(&["run", "--points", "36", "--runs", "2", "--bidirectional", "--units", "arcsec"]).success();
    let a_deg = super::number(&b.stats_json(None), "A");
    // The figure to a thousandth of an arcsecond in the text, in degrees in the document.
    assert!((figure_after(&run.stdout, "A  accuracy") - a_deg * 3600.0).abs() < 1e-3, "{run}");
    assert!(run.stdout.contains("bidirectional (arcseconds)") && run.stdout.contains("predicted: native +/-"), "{run}");
    for args in
        [&["stats"][..], &["process"], &["model-gap", "--model", "gear.toml"], &["show"], &["report", "--out", "r"]]
    {
        let help = b.survey(&[args[0], "--help"]).success();
        assert!(help.stdout.contains("--units <UNIT>") && help.stdout.contains("SURVEY_UNITS"), "{help}");
        let mut with = args.to_vec();
        with.extend(["--units", "urad"]);
        let out = b.survey(&with).success();
        if args[0] != "report" {
            assert!(out.stdout.contains("µrad"), "{out}");
            let deg = b.survey(args).success();
            // Every error moved to µrad; what stays in degrees is along the axis.
            let shown = |t: &str, unit: &str| t.matches(unit).count();
            assert!(shown(&deg.stdout, " µrad") == 0, "{deg}");
            assert_eq!(shown(&deg.stdout, " deg") - shown(&out.stdout, " deg"), shown(&out.stdout, " µrad"), "{out}");
        }
    }
    let stats = b.survey_with_env(&["stats"], "SURVEY_UNITS", "urad").success();
    let a_urad = figure_after(&stats.stdout, "A  accuracy");
    assert!((a_urad - a_deg.to_radians() * 1e6).abs() < 0.01, "{stats}");
    // --json stays in degrees whatever the unit.
    let json = b.survey(&["stats", "--json", "--units", "arcsec"]).success().json();
    assert_eq!(super::number(&json, "A"), a_deg);
    let process = b.survey(&["process", "--json", "--units", "urad"]).success().json();
    let native = process["predicted"]["native_peak_deg"].as_f64().unwrap();
    assert!(native > 0.001 && native < 0.1, "degrees: {process}");
    assert!(b.read("r/index.html").contains("µrad"), "the report's errors in µrad");
    b.survey(&["stats", "--units", "furlong"]).bad_input(&["furlong", "deg, arcsec, urad"]);
    b.survey_with_env(&["stats"], "SURVEY_UNITS", "furlong").bad_input(&["furlong"]);
}

/// The lines of `script` from the first that contains `start`, `n` of them.
fn after(script: &str, start: &str, n: usize) -> String {
    script.lines().skip_while(|l| !l.contains(start)).take(n).collect::<Vec<_>>().join("\n")
}

#[test]
fn completions_offer_values_for_choices_folders_for_folders_and_no_file_names_for_numbers() {
    let b = Bench::new();
    let bash = b.survey(&["completions", "bash"]).success().stdout;
    for (flag, values) in [
        ("--controller)", "linuxcnc 840d fanuc generic"),
        ("--preset)", "fig1 fig4 fig8"),
        ("--reference)", "tracker autocollimator"),
        ("--scan)", "step continuous"),
        ("--units)", "deg arcsec urad"),
    ] {
        let case = after(&bash, flag, 2);
        assert!(case.contains(&format!("compgen -W \"{values}\"")), "{flag}: {case}");
    }
    for flag in ["--points)", "--survey)", "--seed)", "--table-start)"] {
        assert!(!after(&bash, flag, 2).contains("compgen -f"), "{flag} completes to file names");
    }
    let zsh = b.survey(&["completions", "zsh"]).success().stdout;
    let line = |flag: &str| zsh.lines().find(|l| l.contains(flag)).unwrap_or_else(|| panic!("{flag}")).to_string();
    assert!(line("--controller=").ends_with(":LIST:(linuxcnc 840d fanuc generic)' \\"), "{}", line("--controller="));
    assert!(line("'--out=[The folder").contains(":DIR:_files -/"), "a folder completes to folders");
    assert!(line("'--config=").contains(":FILE:_files"), "a file to files");
    assert!(
        line("'--points=").ends_with(":N:' \\") && line("'--survey=").ends_with(":ID:' \\"),
        "no files for numbers"
    );
    let fish = b.survey(&["completions", "fish"]).success().stdout;
    let controller = fish.lines().find(|l| l.contains("-l controller")).expect("fish completes --controller");
    assert!(controller.contains("-f -a \"linuxcnc") || controller.contains("linuxcnc\t"), "{controller}");
}

/// Issue 50: `report --help` names every file it writes, and no example
/// of any command's help writes into the source tree (a clone's `report/`
/// is the report crate): every `--out` of every example names a folder the
/// repository does not hold.
#[test]
fn report_help_names_its_files_and_no_example_writes_into_the_repository() {
    let b = Bench::new();
    let help = b.survey(&["report", "--help"]).success().stdout;
    for file in ["index.html", "dcc.xml", "index.pdf"] {
        assert!(help.contains(file), "report's help names {file}\n{help}");
    }
    b.survey(&["man", "--out", "man"]).success();
    let repository = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut outs = Vec::new();
    for entry in std::fs::read_dir(b.path("man")).unwrap() {
        let page = std::fs::read_to_string(entry.unwrap().path()).unwrap().replace("\\-", "-");
        let examples = page.split(".SH EXAMPLES\n.nf\n").nth(1).unwrap_or("").split(".fi\n").next().unwrap();
        for line in examples.lines() {
            let words: Vec<&str> = line.split_whitespace().collect();
            for pair in words.windows(2).filter(|w| w[0] == "--out") {
                outs.push((line.to_string(), pair[1].to_string()));
            }
        }
    }
    assert!(outs.iter().any(|(_, out)| out == "certificate/"), "report's example: {outs:?}");
    for (line, out) in &outs {
        let first = std::path::Path::new(out).components().next().unwrap();
        let first = repository.join(first.as_os_str());
        assert!(out.starts_with('/') || !first.exists(), "{line}: --out {out} writes into the repository ({first:?})");
    }
}

#[test]
fn man_pages_have_examples_and_see_also_only_pages_that_exist() {
    let b = Bench::new();
    b.survey(&["man", "--out", "man"]).success();
    let pages: Vec<String> = std::fs::read_dir(b.path("man"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(pages.len() > 10 && !pages.iter().any(|p| p.contains("help")), "{pages:?}");
    for name in &pages {
        let page = b.read(&format!("man/{name}"));
        assert!(!page.contains(".SH EXTRA"), "{name}");
        let examples = page.split(".SH EXAMPLES\n.nf\n").nth(1).unwrap_or_else(|| panic!("{name} has no EXAMPLES"));
        let examples = examples.split(".fi\n").next().unwrap();
        assert!(examples.lines().all(|l| l.starts_with("survey ")), "{name}: one example a line, as typed\n{examples}");
        assert!(page.contains(".SH \"SEE ALSO\"\n"), "{name}");
        // Every page named (in SEE ALSO and the command list) is written.
        for (i, _) in page.match_indices("(1)") {
            let named = page[..i].rsplit([' ', '\n']).next().unwrap();
            let named = named.trim_start_matches("\\fB").trim_end_matches("\\fR").replace("\\-", "-");
            assert!(pages.contains(&format!("{named}.1")), "{name} names {named}(1), which is not written");
        }
    }
    let root = b.survey(&["man"]).success().stdout;
    assert!(root.contains("\\fBsurvey\\-run\\fR(1)") && !root.contains("survey\\-help"), "{root}");
}

#[test]
fn model_gap_names_its_columns_for_what_they_measure() {
    let b = Bench::new();
    b.small_survey(true);
    b.write("gear.toml", "[design]\ngear_ratios = [20]\n\n[[effect]]\nkind = \"gear_pass\"\ncycles_per_rev = 20\namplitude_deg = 0.006\nphase_deg = 30.0\n");
    let text = b.survey(&["model-gap", "--model", "gear.toml"]).success().stdout;
    let head = after(&text, "steps (each effect", 3);
    for name in ["amplitude", "of the effect", "residual RMS", "of all samples", "largest residual", "of a target mean"]
    {
        assert!(head.contains(name), "{name:?} in\n{head}");
    }
    assert!(!text.contains("peak_deg") && !text.contains("rms_deg"), "{text}");
    assert!(text.contains("the noise averages out, so it can be below the RMS"), "{text}");
    // The JSON keeps the contract's keys, and the columns are those figures.
    let doc = b.survey(&["model-gap", "--model", "gear.toml", "--json"]).success().json();
    let step = &doc["steps"][0];
    let row = text.lines().find(|l| l.trim_start().starts_with("1  ")).expect("step 1's row");
    let cells: Vec<f64> = row.split_whitespace().rev().take(2).map(|c| c.parse().unwrap()).collect();
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-3 * b.abs();
    assert!(close(cells[1], step["rms_deg"].as_f64().unwrap()), "{row}\n{step}");
    assert!(close(cells[0], step["mean_peak_deg"].as_f64().unwrap()), "{row}\n{step}");
}

#[test]
fn a_rehearsal_on_a_scaled_sim_reports_instrument_time_on_the_instruments_clock() {
    use std::io::{BufRead as _, BufReader};
    use std::process::Stdio;
    const SCALE: f64 = 500.0;
    let b = Bench::new();
    let config = |positioner: &str, tracker: &str, timing: &str| {
        format!(
            "[survey]\npoints = 4\nruns = 2\nreference = \"tracker\"\n\
             [positioner]\ndriver = \"modbus-tcp\"\naddress = \"{positioner}\"\n\
             [tracker]\ndriver = \"emscon\"\naddress = \"{tracker}\"\n[timing]\ndwell_s = 0.01\nlocate_points = 4\n{timing}"
        )
    };
    b.write("sim.toml", config("127.0.0.1:0", "127.0.0.1:0", ""));
    let mut child = b
        .command(&["sim", "--config", "sim.toml", "--time-scale", &SCALE.to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("start survey sim");
    let mut ready = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut ready).unwrap();
    let sim = super::drift::Sim(child);
    let ready: serde_json::Value = serde_json::from_str(&ready).expect("the ready line");
    let at = |k: &str| ready["instruments"][k].as_str().unwrap().to_string();

    // Declared: the time on the instruments' clock, which no survey beats the bound on.
    b.write("scaled.toml", config(&at("positioner"), &at("tracker"), &format!("time_scale = {SCALE}\n")));
    let text = b.survey(&["--db", "a.db", "run", "--config", "scaled.toml"]).success();
    assert!(text.stdout.contains(&format!("on the instruments' clock at {SCALE}x real time")), "{text}");
    assert!(text.stderr.contains(&format!("at {SCALE}x real time)")), "the estimate in real time too\n{text}");
    assert!(!text.stdout.contains("below the bound"), "{text}");
    // run has no --design: its note names the commands that have one.
    assert!(text.stderr.contains("no design was given") && text.stderr.contains("`survey process --design"), "{text}");
    let out = b.survey(&["--db", "b.db", "run", "--config", "scaled.toml", "--json"]).success();
    // A size is never a signed zero (its `left` wrote `"second_order_deg":-0.0`).
    assert!(!out.stdout.contains(":-0.0,") && !out.stdout.contains(":-0.0}"), "{out}");
    let doc = out.json();
    let num = |k: &str| doc[k].as_f64().unwrap_or_else(|| panic!("{k} in {doc}"));
    assert_eq!(num("time_scale"), SCALE);
    assert!(num("instrument_time_s") >= num("bound_s"), "{doc}");
    let real = num("real_time_s");
    // The instruments' clock runs at SCALE x real time: within a tenth of the
    // run's real time (under a second), and 0.3 s of scheduling on a loaded
    // machine (eight test threads on two cores put it 0.087 s apart, 11 %;
    // four builds beside them 0.19 s). A clock not scaled would be hundreds
    // of seconds apart.
    assert!((num("instrument_time_s") / SCALE - real).abs() < 0.1 * real + 0.3, "{doc}");
    let components: f64 =
        doc["time_budget"]["components"].as_array().unwrap().iter().map(|c| c["time_s"].as_f64().unwrap()).sum();
    assert!((components - num("instrument_time_s")).abs() < 1e-6 * components, "{doc}");

    // Not declared: below the physical bound, and the summary says why and what to do.
    b.write("plain.toml", config(&at("positioner"), &at("tracker"), ""));
    let text = b.survey(&["--db", "c.db", "run", "--config", "plain.toml"]).success();
    drop(sim);
    assert!(text.stdout.contains("below the bound") && text.stdout.contains("time_scale = X"), "{text}");
    // A configuration written by hand ([rehearsal] and time_scale left out) is still a rehearsal: the
    // simulators said so when asked what they are, and the survey kept what they said.
    let shown = b.survey(&["--db", "c.db", "show", "1", "--json"]).success().json();
    let positioner = shown["instruments"]["identified"]["positioner"].as_str().unwrap_or_default();
    assert!(positioner.contains("Modbus positioner controller (simulated)"), "{shown}");
    assert!(shown["instruments"]["identified"]["reference"].as_str().unwrap_or_default().contains("tracker serial"));
    b.survey(&["--db", "c.db", "report", "--out", "plain"]).success();
    let page = b.read("plain/index.html");
    assert!(page.contains("id=\"rehearsal\"><b>Rehearsal on simulated instruments, not a calibration</b>"));
    assert!(page.contains("instruments that said they are simulated (the positioner identified itself as"));
    let dcc = b.read("plain/dcc.xml");
    assert!(dcc.contains("refType=\"survey_rehearsal\"") && dcc.contains("(simulated)</dcc:value>"), "{dcc}");
}

/// Issue 41: `--db` is offered where it means something (and works before or
/// after the command, as the contract says), never by `sim`, `check`,
/// `completions` or `man`; an unset variable is not shown as set to nothing;
/// the manual page has its ENVIRONMENT and EXIT STATUS.
#[test]
fn each_command_offers_the_options_it_uses_and_the_manual_says_its_environment_and_exit_statuses() {
    let b = Bench::new();
    for command in ["run", "stats", "list", "show", "history", "report", "serve", "push", "import", "export"] {
        let help = b.survey(&[command, "--help"]).success();
        assert!(help.stdout.contains("--db <PATH|URL>"), "{help}");
        assert!(!help.stdout.contains("SURVEY_UNITS=") && !help.stdout.contains("SURVEY_DB="), "{help}");
    }
    for command in ["sim", "check", "completions", "man"] {
        let help = b.survey(&[command, "--help"]).success();
        assert!(!help.stdout.contains("--db"), "{help}");
    }
    b.survey(&["sim", "--db", "x.db", "--config", "none.toml"]).bad_input(&["--db"]);
    b.survey(&["--db", "a.db", "run", "--points", "12", "--runs", "2"]).success();
    b.survey(&["stats", "--db", "a.db"]).success();
    b.survey(&["--db", "a.db", "stats"]).success();
    b.survey_with_env(&["stats"], "SURVEY_DB", "a.db").success();
    // The command's own --db before survey's, before the environment's.
    b.survey_with_env(&["--db", "none.db", "stats", "--db", "a.db"], "SURVEY_DB", "none.db").success();
    b.survey_with_env(&["stats"], "SURVEY_DB", "none.db").stderr_mentions(&["none.db"]);
    let history = b.survey(&["--db", "a.db", "history"]).success();
    assert!(history.stdout.contains(": 1 survey\n"), "{history}");
    let man = b.survey(&["man"]).success();
    for section in [".SH ENVIRONMENT", ".SH \"EXIT STATUS\"", "SURVEY_DB", "SURVEY_UNITS", "SURVEY_LAB"] {
        assert!(man.stdout.contains(section), "{section}\n{man}");
    }
}

/// Output that cannot be written (stdout on a full device) is never a silent
/// success: exit status 1 and the reason on stderr; a closed pipe (a reader
/// that had enough) is not an error. What the command stored stays.
#[test]
fn output_that_cannot_be_written_is_exit_1_with_the_reason() {
    if !std::path::Path::new("/dev/full").exists() {
        eprintln!("skipped: this machine has no /dev/full");
        return;
    }
    let bench = Bench::new();
    let full = || std::process::Stdio::from(std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap());
    for args in [vec!["run", "--points", "24", "--runs", "2", "--json"], vec!["list"], vec!["stats", "--help"]] {
        let mut cmd = bench.command(&args);
        cmd.stdout(full());
        let out = Bench::output_of(&args, cmd);
        assert_eq!(out.code, 1, "{out}");
        assert!(out.stderr.contains("could not be written to stdout: No space left on device"), "{out}");
    }
    // The survey the first one ran is stored and whole.
    let doc = bench.survey(&["show", "1", "--json"]).success().json();
    assert_eq!(doc["status"], "complete", "{doc}");
    // A reader that closes the pipe early: no error.
    let mut child = bench.command(&["list"]).stdout(std::process::Stdio::piped()).spawn().unwrap();
    drop(child.stdout.take());
    assert!(child.wait().unwrap().success());
}
