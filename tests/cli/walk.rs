//! The README's walk, run as written (issue 41): every command of its shell
//! blocks, in order, with the `--db` each uses, so the walk cannot drift from
//! the program again; and its example figures, compared with what this build
//! prints for the commands they name.
//!
//! The walk is written for a real bench (`bench.toml` naming instruments at
//! lab addresses). Here the bench is `survey sim` serving the copied example:
//! after step 1, `bench.toml` becomes the configuration that simulator writes
//! (its instruments on loopback), with a shorter plan than the example's 360
//! points x 5 runs both ways (72 x 2, one way: the walk's commands and their outcomes are what is
//! tested, not the plan's length, and the suite stays fast). Nothing else is
//! changed: the commands run exactly as the README prints them, but for the
//! rehearsal's configuration path, the README's placeholder
//! (`/tmp/survey-sim-Ab12Cd/bench.toml`), which is the path the step-3
//! simulator prints.

use super::*;
use std::io::{BufRead as _, BufReader};
use std::path::Path;
use std::process::{Child, Stdio};

const README: &str = include_str!("../../README.md");

/// The README's placeholder for the configuration `survey sim` writes.
const PLACEHOLDER: &str = "/tmp/survey-sim-Ab12Cd/bench.toml";

/// The shell commands of the walk ("From a bench to a loaded table" up to
/// "Other commands"), block by block, in order.
fn walk_commands() -> Vec<String> {
    let start = README.find("## From a bench to a loaded table").expect("the README's walk");
    let end = start + README[start..].find("\n## Other commands").expect("the section after the walk");
    let mut commands = Vec::new();
    let mut in_sh = false;
    for line in README[start..end].lines() {
        let line = line.trim();
        if line.starts_with("```") {
            in_sh = line == "```sh";
            continue;
        }
        if in_sh && !line.is_empty() {
            commands.push(line.to_string());
        }
    }
    commands
}

/// A `survey sim` started in the bench folder; its ready line's
/// configuration path. Killed when dropped.
pub(super) struct Sim {
    child: Child,
    pub(super) config: String,
}

impl Sim {
    pub(super) fn start(bench: &Bench, args: &[&str]) -> Sim {
        let mut child = bench.command(args).stdout(Stdio::piped()).stderr(Stdio::null()).spawn().unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.as_mut().unwrap()).read_line(&mut line).unwrap();
        let ready: Value =
            serde_json::from_str(&line).unwrap_or_else(|e| panic!("the simulator's ready line {line:?}: {e}"));
        let config = ready["config"].as_str().expect("the configuration to run against").to_string();
        Sim { child, config }
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The README's words split as a shell would (the walk quotes nothing).
fn words(command: &str) -> Vec<&str> {
    assert!(!command.contains(['"', '\'', '|', '>', '<', '$']), "the walk's commands are plain: {command}");
    command.split_whitespace().collect()
}

#[test]
fn the_readme_walk_runs_as_written_against_survey_sim() {
    let commands = walk_commands();
    let expected = [
        "cp ~/survey/examples/config/modbus-emscon.toml bench.toml",
        "survey check --config bench.toml",
        "survey sim --config bench.toml --time-scale 100",
        "survey check --config /tmp/survey-sim-Ab12Cd/bench.toml",
        "survey --db rehearsal.db run --config /tmp/survey-sim-Ab12Cd/bench.toml --points 24 --runs 2",
        "survey --db rehearsal.db report --out rehearsal/",
        "survey run --config bench.toml",
        "survey resume",
        "survey report --out certificate/",
        "survey run --config bench.toml --verify",
        "survey run --config bench.toml --recipe survey-1/table-1.recipe.toml --correction off --verify",
    ];
    assert_eq!(commands, expected, "the README's walk changed: run it here as written, then update this list");

    let bench = Bench::new();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut sims = Vec::new();
    for command in &commands {
        let command = command.replace(PLACEHOLDER, sims.first().map_or(PLACEHOLDER, |s: &Sim| s.config.as_str()));
        let argv = words(&command);
        match argv[..] {
            ["cp", from, to] => {
                // From the clone, which the README calls ~/survey: this repository.
                let from = from.strip_prefix("~/survey/").expect("the README copies from the clone");
                std::fs::copy(root.join(from), bench.path(to)).unwrap();
                // The bench: step 3's own simulator, started now (step 2
                // checks the bench), serving the copied example; bench.toml
                // becomes the configuration it writes, its plan shortened.
                // Its clock ten times faster than the README's 100 (the
                // engine's waits are paced by it: 69 s of this test's 73 s
                // at 100), the commands the same.
                let step3 = expected.iter().find(|c| c.starts_with("survey sim")).unwrap();
                let step3 = step3.replace("--time-scale 100", "--time-scale 1000");
                let hardware = Sim::start(&bench, &words(&step3)[1..]);
                let text = std::fs::read_to_string(&hardware.config).unwrap();
                let plan = [
                    ("points = 360", "points = 72"),
                    ("runs = 5", "runs = 2"),
                    ("bidirectional = true", "bidirectional = false"),
                ];
                let text = plan.iter().fold(text, |text, (from, to)| {
                    assert!(text.contains(from), "the example's plan has {from}: {text}");
                    text.replacen(from, to, 1)
                });
                bench.write(to, text);
                sims.push(hardware);
            }
            // Started with step 1, as the bench.
            ["survey", "sim", ..] => assert_eq!(sims.len(), 1),
            ["survey", ..] => {
                let began = std::time::Instant::now();
                let out = bench.survey(&argv[1..]);
                eprintln!("{command}: exit {} in {:.1} s", out.code, began.elapsed().as_secs_f64());
                match argv[1..] {
                    // Nothing was interrupted: the README's "continue where it stopped" says so.
                    ["resume"] => {
                        out.bad_input(&["complete", "nothing to resume"]);
                    }
                    _ => {
                        out.success();
                    }
                }
            }
            _ => panic!("a command the walk test cannot run: {command}"),
        }
    }
    // What the walk says it leaves.
    for file in [
        "rehearsal.db",
        "rehearsal/index.html",
        "rehearsal.db.survey-1/table-1.csv",
        "survey.db",
        "certificate/index.html",
        "certificate/dcc.xml",
        "survey-1/table-1.recipe.toml",
        "survey-1/table-1.comp1",
        "survey-1/table-1.840d.ini",
        "survey-1/table-1.fanuc.txt",
    ] {
        assert!(bench.exists(file), "the walk leaves {file}");
    }
    // Every survey of the walk is of survey sim's instruments: a rehearsal, never a calibration, on
    // every page and in the DCC; the example's traceability is not claimed; the time the survey measured.
    for page in ["rehearsal/index.html", "certificate/index.html"] {
        let html = bench.read(page);
        let banner = "id=\"rehearsal\"><b>Rehearsal on simulated instruments, not a calibration</b>: instruments \
                      simulated by survey sim";
        assert!(html.contains(banner) && html.contains("@bottom-left{content:\"REHEARSAL ON SIMULATED"), "{page}");
        assert!(!html.contains("national metrology institute"), "{page} claims no traceability");
        assert!(html.contains("simulated, standing in for: Leica AT960"), "{page}");
        let time = html.split(" of instrument time)").next().and_then(|s| s.rsplit('(').next()).expect("its time");
        assert!(time.ends_with(" min") || time.ends_with(" h"), "{page}: {time}");
    }
    let dcc = bench.read("certificate/dcc.xml");
    assert!(dcc.contains("refType=\"survey_rehearsal\"") && !dcc.contains("national metrology institute"));
    // The example's address structured, its instruments identified; a stand-in's calibration not claimed.
    for words in [
        "<dcc:street>Bay Road</dcc:street>",
        "<dcc:streetNo>1</dcc:streetNo>",
        "<dcc:postCode>38116</dcc:postCode>",
        "<dcc:city>Braunschweig</dcc:city>",
        "<dcc:countryCode>DE</dcc:countryCode>",
        "<dcc:model>AZ-200</dcc:model>",
        "<dcc:model>AT960</dcc:model>",
        "<dcc:value>7788</dcc:value>",
    ] {
        assert!(dcc.contains(words), "the DCC holds {words}");
    }
    assert!(!dcc.contains(">5678<") && !dcc.contains("5678,"), "a stand-in's calibration is claimed");
    match crate::dcc::validator_missing() {
        Some(why) => println!("skipped the validation: {why}"),
        None => crate::dcc::validate(&bench, &["certificate/dcc.xml"]),
    }
}

/// The lines of the README's first output block after `marker`.
fn block_after(marker: &str) -> Vec<&'static str> {
    let at = README.find(marker).unwrap_or_else(|| panic!("the README says {marker:?}"));
    let rest = &README[at..];
    let open = rest.find("\n```\n").expect("an output block") + 5;
    let close = open + rest[open..].find("\n```").expect("its end");
    rest[open..close].lines().filter(|l| *l != "...").collect()
}

#[test]
fn the_readme_s_example_figures_are_what_this_build_prints() {
    let bench = Bench::new();
    let iso = block_after("On the\ndefault bench (`survey run --points 1800 --bidirectional`):");
    assert!(iso.len() >= 8, "{iso:?}");
    let out = bench.survey(&["--db", "default.db", "run", "--points", "1800", "--bidirectional"]).success();
    for line in iso {
        assert!(out.stdout.lines().any(|l| l == line), "the README prints {line:?}; this build does not\n{out}");
    }
    let verification = block_after("(here `survey run --points 120 --verify`, on the simulated bench):");
    let out = bench.survey(&["--db", "verify.db", "run", "--points", "120", "--verify"]).success();
    // No signed zero printed as a size (its budget said "-0.00e0 deg").
    assert!(!out.stdout.contains("-0.00e0"), "{out}");
    for line in verification.iter().filter(|l| !l.starts_with("verdict:")) {
        assert!(out.stdout.lines().any(|l| l == *line), "the README prints {line:?}; this build does not\n{out}");
    }
    let verdict = verification.iter().find(|l| l.starts_with("verdict:")).expect("the README shows the verdict");
    let shown = verdict.trim_end_matches("(...)").trim_end();
    assert!(out.stdout.lines().any(|l| l.starts_with(shown)), "the README's verdict {verdict:?}\n{out}");
}
