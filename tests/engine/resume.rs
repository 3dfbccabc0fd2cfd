//! A survey that dies in the middle (the process aborts: no chance to clean up) resumes from
//! its last stored sample: no sample lost, none duplicated.

use std::process::{Command, Stdio};
use survey_store::Store;
use survey_store::survey::SurveyStatus;

#[tokio::test]
async fn a_killed_survey_resumes_without_losing_or_duplicating_a_sample() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("k.db");
    let bin = env!("CARGO_BIN_EXE_survey");
    // The simulated bench loses power (the process aborts: no flush, no
    // cleanup) once 3000 of the 10800 samples have been measured.
    let crashed = Command::new(bin)
        .current_dir(dir.path())
        .args(["--db", db.to_str().unwrap(), "run", "--points", "1800", "--bidirectional", "--runs", "3"])
        .args(["--sim-crash-after", "3000"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .unwrap();
    assert!(!crashed.success(), "the survey was to be cut short");

    let store = Store::open_existing(&db).await.unwrap();
    let before = store.survey(1).await.unwrap();
    // Stored `running`, and no process holds it: read as interrupted.
    assert_eq!(before.status, SurveyStatus::Interrupted, "a killed survey reads as interrupted");
    let kept = store.recorded_samples(1).await.unwrap();
    // Batches of 256 and the end of the first pass (1800) were committed
    // before the crash; the samples in the last unfinished batch are lost, as
    // in a power loss, and are measured again by the resume.
    assert!((2048..=3000).contains(&kept.len()), "{} samples kept", kept.len());
    store.close().await;

    let out =
        Command::new(bin).current_dir(dir.path()).args(["--db", db.to_str().unwrap(), "resume"]).output().unwrap();
    assert!(out.status.success(), "resume failed: {}", String::from_utf8_lossy(&out.stderr));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains(&format!("resumed at step {}", kept.len())), "{stderr}");

    let store = Store::open_existing(&db).await.unwrap();
    let after = store.survey(1).await.unwrap();
    assert_eq!(after.status, SurveyStatus::Complete);
    let all = store.recorded_samples(1).await.unwrap();
    assert_eq!(all.len(), 10800, "1800 targets x 3 runs x 2 directions");
    assert!(all.iter().enumerate().all(|(i, r)| r.seq == i as u64), "every step exactly once");
    // What was stored before the kill is unchanged.
    assert_eq!(&all[..kept.len()], &kept[..]);
    // The plan is followed across the resume.
    let n = 1800;
    for (i, r) in all.iter().enumerate() {
        let run = (i / (2 * n)) as u32 + 1;
        assert_eq!(r.sample.run, run, "step {i}");
    }
    let events = store.events(1).await.unwrap();
    assert!(events.iter().any(|e| e.message.contains("resumed at step")));

    // A complete survey has nothing to resume: bad usage, exit 2.
    let again =
        Command::new(bin).current_dir(dir.path()).args(["--db", db.to_str().unwrap(), "resume"]).output().unwrap();
    assert_eq!(again.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&again.stderr).contains("nothing to resume"));
    store.close().await;
}
