//! The everyday commands from outside: an example in every command's
//! `--help`, shell completions and manual pages generated from the command
//! line, and units beside the numbers of the human summaries.

use super::Bench;

/// The commands `survey --help` lists (besides `help`).
fn commands(bench: &Bench) -> Vec<String> {
    let help = bench.survey(&["--help"]).success().stdout;
    let list = help.split("Commands:").nth(1).expect("a Commands: section");
    let list = list.split("\n\n").next().unwrap();
    list.lines().filter_map(|l| l.split_whitespace().next()).filter(|c| *c != "help").map(str::to_string).collect()
}

#[test]
fn every_command_shows_an_example_in_its_help() {
    let bench = Bench::new();
    let all = commands(&bench);
    for c in ["run", "process", "stats", "list", "show", "completions", "man", "model-gap", "sim"] {
        assert!(all.iter().any(|x| x == c), "{c} missing from {all:?}");
    }
    assert!(bench.survey(&["--help"]).success().stdout.contains("Examples:\n  survey run"));
    for c in &all {
        let out = bench.survey(&[c, "--help"]).success().stdout;
        let examples =
            out.split("Examples:").nth(1).unwrap_or_else(|| panic!("`survey {c} --help` has no example\n{out}"));
        assert!(
            examples.contains(&format!("survey {c}")) || examples.contains(&format!("survey --db lab.db {c}")),
            "{c}: {examples}"
        );
    }
}

#[test]
fn completions_and_manual_pages_come_from_the_command_line() {
    let bench = Bench::new();
    let bash = bench.survey(&["completions", "bash"]).success().stdout;
    assert!(bash.contains("_survey()") && bash.contains("complete -F _survey"), "{}", &bash[..200.min(bash.len())]);
    assert!(bash.contains("--table-start") && bash.contains("--controller"), "the process flags are completed");
    assert!(bench.survey(&["completions", "zsh"]).success().stdout.starts_with("#compdef survey"));
    assert!(bench.survey(&["completions", "fish"]).success().stdout.contains("complete -c survey"));
    bench.survey(&["completions", "ksh"]).bad_input(&["ksh", "bash"]);

    let man = bench.survey(&["man"]).success().stdout;
    assert!(
        man.contains(".TH survey 1") && man.contains("Calibrate rotary positioners"),
        "{}",
        &man[..300.min(man.len())]
    );
    bench.survey(&["man", "--out", "man"]).success();
    for c in commands(&bench) {
        let page = bench.read(&format!("man/survey-{c}.1"));
        assert!(page.contains(&format!(".TH survey-{c} 1")) && page.contains(".SH EXAMPLES\n"), "survey-{c}.1");
    }
    let process = bench.read("man/survey-process.1");
    assert!(process.contains("table\\-start") && process.contains("sinumerik\\-axis"));
    bench.write("afile", "x");
    bench.survey(&["man", "--out", "afile/sub"]).bad_input(&["afile/sub"]);
}

#[test]
fn summaries_print_units_beside_their_numbers() {
    let bench = Bench::new();
    bench.survey(&["run", "--points", "36", "--runs", "2", "--bidirectional"]).success();
    let stats = bench.survey(&["stats"]).success().stdout;
    for l in stats.lines().filter(|l| l.trim_start().starts_with(['A', 'R', 'E', 'B', 'M'])) {
        assert!(l.ends_with(" deg"), "{l:?}\n{stats}");
    }
    let process = bench.survey(&["process"]).success().stdout;
    let predicted = process.lines().find(|l| l.starts_with("predicted:")).expect("a predicted line");
    // Every number on the line is followed by its unit.
    let words: Vec<&str> = predicted.split_whitespace().collect();
    for (i, w) in words.iter().enumerate() {
        let w = w.trim_start_matches("+/-").trim_start_matches('(');
        if w.parse::<f64>().is_ok() {
            assert!(words.get(i + 1).is_some_and(|u| u.starts_with("deg")), "{w} has no unit in {predicted:?}");
        }
    }
    for l in process.lines().filter(|l| l.contains(" table: ")) {
        assert!(l.contains("deg every") && l.contains(" deg"), "{l}");
    }
}
