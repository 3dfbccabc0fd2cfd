//! The soak (issue 10): `survey sim` serves a Modbus TCP positioner and an
//! emScon tracker with faults on 12 in 100 moves, 8 in 100 measurements, 1 in
//! 100 requests (refused in the instrument's own code) and 4 in 100 replies (a
//! dropped, garbled, cut or stalled reply, 1 in 100 each), time-scaled; `survey run
//! --config` against it, in another process, is SIGKILLed at seeded random
//! moments five times and resumed each time. The survey ends with every
//! planned sample exactly once, and its ISO 230-2 accuracy within the
//! seed-to-seed spread of fault-free runs. `survey sim` prints what it
//! injected when it stops: every link kind was injected and survived.

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use std::io::{BufRead as _, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use survey_store::Store;
use survey_store::survey::SurveyStatus;

const BIN: &str = env!("CARGO_BIN_EXE_survey");

/// A `survey sim` process and the configuration a client uses to reach it.
struct Sim {
    child: Child,
    config: PathBuf,
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = kill(Pid::from_raw(self.child.id() as i32), Signal::SIGTERM);
        let _ = self.child.wait();
    }
}

/// The soak's fault rates over `--faults 0.01`: each link kind at 0.01,
/// moves tripped at 0.12 and beams broken at 0.08 (so a survey of 96 samples
/// meets several of each: about 900 replies, 60 moves, 110 measurements).
const LINK_RATES: &str = "timeout=0.01,garbled=0.01,disconnect=0.01,stall=0.01,move=0.12,beam=0.08";

impl Sim {
    /// Stop `survey sim` with SIGTERM and read what it prints when it stops.
    fn stop(&mut self) -> serde_json::Value {
        kill(Pid::from_raw(self.child.id() as i32), Signal::SIGTERM).unwrap();
        let mut out = String::new();
        std::io::Read::read_to_string(self.child.stdout.as_mut().unwrap(), &mut out).unwrap();
        self.child.wait().unwrap();
        let line = out.lines().find(|l| l.contains("\"stopped\"")).expect("the stopped line");
        serde_json::from_str(line).unwrap()
    }
}

fn start_sim(dir: &Path, name: &str, faults: &str, seed: &str) -> Sim {
    let base = "[survey]\nreference = \"tracker\"\n[positioner]\ndriver = \"modbus-tcp\"\naddress = \"ADDR_P\"\n\
                timeouts = { request_ms = 200 }\n\
                [tracker]\ndriver = \"emscon\"\naddress = \"ADDR_T\"\nmeasurement_time_ms = 500\n\
                [timing]\ndwell_s = 0.01\ncall_timeout_s = 0.3\nmeasure_timeout_s = 2.0\nmax_retries = 8\n\
                retry_backoff_s = 0.02\n";
    let sim_cfg = dir.join(format!("{name}.sim.toml"));
    std::fs::write(&sim_cfg, base.replace("ADDR_P", "127.0.0.1:0").replace("ADDR_T", "127.0.0.1:0")).unwrap();
    let mut child = Command::new(BIN)
        .args(["sim", "--config", sim_cfg.to_str().unwrap(), "--time-scale", "200", "--faults", faults])
        .args(if faults == "0" { vec![] } else { vec!["--fault-rates", LINK_RATES] })
        .args(["--seed", seed])
        .env_remove("RUST_LOG")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.as_mut().unwrap()).read_line(&mut line).unwrap();
    let ready: serde_json::Value = serde_json::from_str(&line).expect("the ready line");
    let at = |k: &str| ready["instruments"][k].as_str().unwrap().to_string();
    let config = dir.join(format!("{name}.run.toml"));
    std::fs::write(&config, base.replace("ADDR_P", &at("positioner")).replace("ADDR_T", &at("tracker"))).unwrap();
    Sim { child, config }
}

fn survey(db: &Path, args: &[&str]) -> Child {
    Command::new(BIN)
        .arg("--db")
        .arg(db)
        .args(args)
        .env_remove("RUST_LOG")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

/// 24 targets x 2 runs x 2 directions: 96 samples, long enough that five kills
/// (each after 3 to 10 more samples, plus up to a batch) land before the end.
const PLAN: [&str; 5] = ["--points", "24", "--runs", "2", "--bidirectional"];
const PLANNED: usize = 96;

async fn stored(db: &Path) -> u64 {
    if !db.exists() {
        return 0;
    }
    match Store::open_read_only(db).await {
        Ok(store) => {
            let n = store.sample_count(1).await.unwrap_or(0);
            store.close().await;
            n
        }
        Err(_) => 0,
    }
}

async fn complete(db: &Path) -> bool {
    let store = Store::open_read_only(db).await.unwrap();
    let done = store.survey(1).await.unwrap().status == SurveyStatus::Complete;
    store.close().await;
    done
}

async fn accuracy(db: &Path) -> f64 {
    let out = Command::new(BIN).arg("--db").arg(db).args(["stats", "--json"]).output().unwrap();
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    doc["iso230_2"]["A"].as_f64().unwrap()
}

/// A fault-free survey of the same plan on a fresh simulator with `seed`,
/// started now (it runs beside the soak) and finished by [`FaultFree::accuracy`].
struct FaultFree {
    _sim: Sim,
    db: PathBuf,
    child: Child,
}

impl FaultFree {
    fn start(dir: &Path, seed: &str) -> FaultFree {
        let sim = start_sim(dir, &format!("clean{seed}"), "0", seed);
        let db = dir.join(format!("clean{seed}.db"));
        let mut args = vec!["run", "--config", sim.config.to_str().unwrap()];
        args.extend(PLAN);
        let child = survey(&db, &args);
        FaultFree { _sim: sim, db, child }
    }

    async fn accuracy(mut self) -> f64 {
        assert!(self.child.wait().unwrap().success(), "a fault-free survey failed");
        accuracy(&self.db).await
    }
}

#[test]
fn a_faulty_bench_killed_five_times_loses_and_repeats_nothing() {
    survey_store::runtime::block_on_bounded(2, async {
        let dir = tempfile::tempdir().unwrap();
        // The fault-free surveys the soak is compared with run beside it.
        let clean = [FaultFree::start(dir.path(), "11"), FaultFree::start(dir.path(), "12")];
        let mut sim = start_sim(dir.path(), "soak", "0.01", "11");
        let db = dir.path().join("soak.db");
        let mut run_args = vec!["run", "--config", sim.config.to_str().unwrap()];
        run_args.extend(PLAN);
        // Seeded kill points: after 3 to 10 more samples each time.
        let mut lcg: u64 = 20_261_124;
        let mut next_gap = || {
            lcg = lcg.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            3 + (lcg >> 33) % 8
        };
        let (mut kills, mut attempts) = (0, 0);
        let deadline = Instant::now() + Duration::from_secs(240);
        loop {
            attempts += 1;
            assert!(attempts < 30, "too many attempts");
            let mut child = if attempts == 1 { survey(&db, &run_args) } else { survey(&db, &["resume"]) };
            let kill_at = stored(&db).await + next_gap();
            let status = loop {
                if let Some(status) = child.try_wait().unwrap() {
                    break Some(status);
                }
                // A kill counts when it leaves the survey unfinished: one that
                // lands after the acquisition completed needs no resume.
                if kills < 5 && stored(&db).await >= kill_at {
                    kill(Pid::from_raw(child.id() as i32), Signal::SIGKILL).unwrap();
                    child.wait().unwrap();
                    if !complete(&db).await {
                        kills += 1;
                    }
                    break None;
                }
                assert!(Instant::now() < deadline, "the soak took more than 240 s");
                tokio::time::sleep(Duration::from_millis(20)).await;
            };
            if let Some(status) = status {
                // Exit 1 is a survey that gave up on a fault burst (resumable);
                // exit 2 a resume of a survey whose acquisition had completed
                // before the last kill (it was killed while processing).
                if status.success() || (status.code() == Some(2) && complete(&db).await) {
                    break;
                }
                assert_eq!(status.code(), Some(1), "a run or resume ended with {status}");
            }
        }
        assert!(kills >= 5, "{kills} kills");
        let store = Store::open_read_only(&db).await.unwrap();
        let record = store.survey(1).await.unwrap();
        let samples = store.recorded_samples(1).await.unwrap();
        let events = store.events(1).await.unwrap();
        store.close().await;
        assert_eq!(record.status, SurveyStatus::Complete);
        assert_eq!(samples.len(), PLANNED, "24 targets x 2 runs x 2 directions");
        assert!(samples.iter().enumerate().all(|(i, r)| r.seq == i as u64), "every step exactly once, none lost");
        // A resume continues the acquisition, or finishes a survey killed while it
        // was processing (every sample already stored).
        let resumes = events
            .iter()
            .filter(|e| e.message.contains("resumed at step") || e.message.contains("are stored: finishing"))
            .count();
        let faults = events.iter().filter(|e| e.level == "warn" && e.message.contains("retrying")).count();
        eprintln!("soak: {kills} kills, {resumes} resumes, {faults} faults survived, {} samples", samples.len());
        // What the simulators injected, as `survey sim` prints it when it stops.
        let stopped = sim.stop();
        let f = &stopped["faults"];
        let by_kind = &f["by_kind"];
        eprintln!(
            "soak: {} requests relayed, {} faults injected {by_kind}; {faults} recoveries logged, {kills} kills, \
             {} of {PLANNED} samples, 0 lost, 0 duplicated",
            f["replies"],
            f["injected"],
            samples.len()
        );
        for kind in ["timeout", "garbled", "disconnect", "stall", "device", "move", "beam"] {
            assert!(by_kind[kind].as_u64().unwrap() >= 1, "no {kind} fault was injected: {stopped}");
        }
        // Every kind was injected, and the survey completed with every sample
        // once (above): each fault was survived, or ended a process that a resume
        // continued.
        assert!(faults >= 1, "{faults} recoveries logged: {stopped}");
        // Every kill is followed by a resume, and a process is killed only after it
        // stored a sample (so after a resume had logged itself).
        assert!(resumes >= kills, "{resumes} resumes after {kills} kills");

        // Its accuracy is the bench's, within the spread of fault-free seeds.
        let a = accuracy(&db).await;
        let [c1, c2] = clean;
        let (a1, a2) = (c1.accuracy().await, c2.accuracy().await);
        // Two fault-free seeds give a poor idea of A's own scatter: with 2
        // runs a target's s comes from 2 readings, so A (max of mean + 2 s,
        // min of mean - 2 s) moves from seed to seed. Over 30 seeds of this
        // plan on the in-process simulated bench (`survey run --points 24
        // --runs 2 --bidirectional --seed 1..30`) A's relative standard
        // deviation was 3.9 % (pairs of seeds differed by up to 8 %; the
        // tolerance before, 3 x max(pair difference, 2 % of A), failed
        // twice under load). So A's standard deviation is taken as 4 % of
        // the fault-free mean, and the soak's A must lie within 4 standard
        // deviations of the difference from it (sqrt(1 + 1/2): the soak
        // against the mean of two): 20 % of A, a false alarm about once in
        // 16000. A sample stored at the wrong target or twice shifts A by
        // the error's whole range (fig8's 0.03 deg), far beyond it.
        let clean_mean = (a1 + a2) / 2.0;
        let tolerance = 4.0 * 0.04 * clean_mean * 1.5f64.sqrt();
        eprintln!("soak: A = {a:.6} deg; fault-free A = {a1:.6} and {a2:.6} deg (tolerance {tolerance:.6} deg)");
        assert!((a - clean_mean).abs() <= tolerance, "A {a} against fault-free {a1} / {a2}");
    })
    .expect("a runtime");
}
