//! `survey report --out DIR`, from outside.

use super::Bench;

#[test]
fn report_writes_a_self_contained_page_with_plots_and_figures() {
    let bench = Bench::new();
    bench.survey(&["report", "--out", "r"]).bad_input(&["survey.db"]);
    assert!(!bench.exists("r/index.html"));
    bench.small_survey(true);
    let out = bench.survey(&["report", "--out", "r"]).success();
    assert!(out.stdout.trim().ends_with("index.html"), "{out}");
    let html = bench.read("r/index.html");
    assert!(html.starts_with("<!doctype html>"));
    assert_eq!(html.matches("<svg").count(), 2, "the error map and the spectrum");
    for words in ["Error map", "ISO 230-2", "A accuracy", "gear_pass", "forward", "reverse"] {
        assert!(html.contains(words), "the page should show {words:?}");
    }
    assert!(
        !html.contains("<script") && !html.contains("src=") && !html.contains("href="),
        "self-contained: no scripts, no links"
    );
    bench.survey(&["report", "--out", "r", "--survey", "9"]).bad_input(&["9"]);
    bench.survey(&["report"]).bad_input(&["--out"]);
}
