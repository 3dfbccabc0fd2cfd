//! A survey killed in the middle (SIGKILL: no chance to clean up) resumes from
//! its last stored sample: no sample lost, none duplicated.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use survey_orchestrator::store::{Store, SurveyStatus};

#[tokio::test]
async fn a_killed_survey_resumes_without_losing_or_duplicating_a_sample() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("k.db");
    let bin = env!("CARGO_BIN_EXE_survey");
    let mut child = Command::new(bin)
        .args(["--db", db.to_str().unwrap(), "run", "--points", "1800", "--bidirectional", "--runs", "3"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Wait until some batches are on disk, then kill the process outright.
    // Whatever the moment of the kill, the assertions below must hold.
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        if let Ok(store) = Store::open_existing(&db).await
            && let Ok(Some(id)) = store.latest_survey_id().await
            && store.survey(id).await.map(|r| r.sample_count).unwrap_or(0) >= 1000
        {
            store.close().await;
            break;
        }
        assert!(Instant::now() < deadline, "the survey never stored 1000 samples");
        assert!(child.try_wait().unwrap().is_none(), "the survey finished before it could be killed");
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();

    let store = Store::open_existing(&db).await.unwrap();
    let before = store.survey(1).await.unwrap();
    assert_eq!(before.status, SurveyStatus::Running, "a killed survey is left running");
    let kept = store.samples(1).await.unwrap();
    assert!(kept.len() as u64 >= 1000 && (kept.len() as u64) < 10800);
    store.close().await;

    let out = Command::new(bin).args(["--db", db.to_str().unwrap(), "resume"]).output().unwrap();
    assert!(out.status.success(), "resume failed: {}", String::from_utf8_lossy(&out.stderr));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains(&format!("resumed at step {}", kept.len())), "{stderr}");

    let store = Store::open_existing(&db).await.unwrap();
    let after = store.survey(1).await.unwrap();
    assert_eq!(after.status, SurveyStatus::Complete);
    let all = store.samples(1).await.unwrap();
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
    let again = Command::new(bin).args(["--db", db.to_str().unwrap(), "resume"]).output().unwrap();
    assert_eq!(again.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&again.stderr).contains("nothing to resume"));
    store.close().await;
}
