//! A positioner's life (issue 22): assets and uids, `history`, `compare`
//! and the recalibration loop `run --check`, through the built binary.

use super::{Bench, VALID_CSV};
use serde_json::Value;

/// Whether `s` is a UUID: 8-4-4-4-12 lower-case hexadecimal digits.
fn is_uuid(s: &str) -> bool {
    let groups: Vec<&str> = s.split('-').collect();
    groups.len() == 5
        && groups
            .iter()
            .zip([8, 4, 4, 4, 12])
            .all(|(g, n)| g.len() == n && g.chars().all(|c| c.is_ascii_digit() || ('a'..='f').contains(&c)))
}

/// `list --json`'s surveys.
fn listed(bench: &Bench) -> Vec<Value> {
    bench.survey(&["list", "--json"]).success().json()["surveys"].as_array().expect("surveys").clone()
}

#[test]
fn every_survey_belongs_to_an_asset_and_has_a_uid_that_names_it() {
    let bench = Bench::new();
    bench.survey(&["run", "--points", "36", "--runs", "2", "--json"]).success();
    bench.survey(&["run", "--points", "36", "--runs", "2", "--preset", "fig4", "--json"]).success();
    bench.survey(&["run", "--points", "36", "--runs", "2", "--asset", "bay-3/az.1", "--json"]).success();
    bench.write("data.csv", VALID_CSV);
    bench.import("data.csv");
    let out = bench.survey(&["import", "data.csv", "--asset", "rig_7"]).success();
    assert_eq!(out.stdout, "5\n", "{out}");

    let surveys = listed(&bench);
    let assets: Vec<&str> = surveys.iter().map(|s| s["asset"].as_str().unwrap()).collect();
    assert_eq!(assets, ["sim-fig8", "sim-fig4", "bay-3/az.1", "unassigned", "rig_7"]);
    let uids: Vec<&str> = surveys.iter().map(|s| s["uid"].as_str().unwrap()).collect();
    assert!(uids.iter().all(|u| is_uuid(u)), "{uids:?}");
    let mut distinct = uids.clone();
    distinct.sort_unstable();
    distinct.dedup();
    assert_eq!(distinct.len(), 5);

    // A uid names its survey wherever an id does.
    let show = bench.survey(&["show", uids[2], "--json"]).success().json();
    assert_eq!(
        (show["id"].as_i64(), show["uid"].as_str(), show["asset"].as_str()),
        (Some(3), Some(uids[2]), Some("bay-3/az.1"))
    );
    let by_id = bench.survey(&["stats", "--survey", "2", "--json"]).success().json();
    let by_uid = bench.survey(&["stats", "--survey", &uids[1].to_uppercase(), "--json"]).success().json();
    assert_eq!(by_id, by_uid);
    bench.survey(&["export", "--csv", "by-uid.csv", "--survey", uids[3]]).success();
    assert_eq!(bench.read("by-uid.csv"), VALID_CSV);

    // A uid that names no survey, or a value that is neither: bad input.
    bench
        .survey(&["stats", "--survey", "00000000-0000-4000-8000-000000000000"])
        .bad_input(&["no survey with uid 00000000-0000-4000-8000-000000000000"]);
    bench.survey(&["stats", "--survey", "12ab"]).bad_input(&["12ab", "neither a survey id"]);

    // A bad asset id: bad input, nothing stored.
    let before = bench.stored();
    let out = bench.survey(&["run", "--points", "36", "--runs", "2", "--asset", "bay 3"]);
    let out = out.bad_input(&["--asset", "bay 3"]);
    bench.survey(&["import", "data.csv", "--asset", &"x".repeat(65)]).bad_input(&["65 characters"]);
    bench.assert_unchanged(&before, &out);
}
