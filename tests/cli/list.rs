//! `survey list` and `survey show`: what a database holds.

use super::{Bench, VALID_CSV};

#[test]
fn list_names_every_survey_with_its_status_source_plan_and_samples() {
    let bench = Bench::new();
    let first = bench.small_survey(true);
    bench.write("data.csv", VALID_CSV);
    let imported = bench.import("data.csv");
    let out = bench.survey(&["list", "--json"]).success();
    let doc = out.json();
    let surveys = doc["surveys"].as_array().expect("surveys is an array");
    assert_eq!(surveys.len(), 2, "{out}");
    for (s, id) in surveys.iter().zip([first, imported]) {
        assert_eq!(s["id"].as_i64(), Some(id));
        for key in ["status", "source", "points", "runs", "samples", "planned_samples", "created_at", "updated_at"] {
            assert!(s.get(key).is_some(), "list --json names {key}: {s}");
        }
    }
    assert_eq!(surveys[0]["status"], "complete");
    assert_eq!(surveys[0]["source"], "simulated");
    assert_eq!((surveys[0]["samples"].as_u64(), surveys[0]["planned_samples"].as_u64()), (Some(144), Some(144)));
    assert_eq!(surveys[1]["status"], "imported");
    assert_eq!(surveys[1]["source"], "import:data.csv");
    assert_eq!(surveys[1]["samples"].as_u64(), Some(8));

    let text = bench.survey(&["list"]).success().stdout;
    assert!(
        text.contains("complete") && text.contains("144 of 144") && text.contains("36 x 2 runs, both ways"),
        "{text}"
    );

    let show = bench.survey(&["show", &first.to_string(), "--json"]).success().json();
    assert_eq!(show["id"].as_i64(), Some(first));
    assert_eq!(show["plan"]["targets"].as_u64(), Some(36));
    assert!(show["axis"]["radius_mm"].as_f64().is_some_and(|r| r > 0.0), "{show}");
    assert!(show["events"].is_array());
    // The axis fitted again from every SMR position is recorded with the survey.
    let events = show["events"].as_array().unwrap();
    assert!(events.iter().any(|e| e.to_string().contains("axis fitted again from")), "{show}");
    let text = bench.survey(&["show"]).success().stdout;
    assert!(text.starts_with(&format!("survey {imported} (imported)")), "{text}");

    // No database: bad input, and none is created.
    let empty = Bench::new();
    empty.survey(&["list"]).bad_input(&["no survey database"]);
    assert!(!empty.exists("survey.db"));
    bench.survey(&["show", "99"]).bad_input(&["no survey with id 99"]);
}
