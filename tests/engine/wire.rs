//! A survey whose instruments sit behind their wire protocols, configured by a
//! configuration file like a user's, gives the same statistics as the same
//! simulated bench driven in-process.

use std::sync::Arc;
use survey_acquire::MemorySink;
use survey_acquire::{Engine, Reference, Timing};
use survey_bench::instruments::{Instruments, ReferenceInstrument};
use survey_drivers::{Clock, VirtualClock};
use survey_plan::SurveyPlan;
use survey_processing::iso230::{Iso230, iso230_2};
use survey_processing::{Direction, Sample};
use survey_sim_servers::elcomat_server::{pty_pair, serve};
use survey_sim_servers::scpi_server::serve_tcp;
use survey_sims::autocollimator::AutocollimatorConfig;
use survey_sims::faults::Faults;
use survey_sims::{Preset, SimBench};
use survey_store::config::SurveyConfig;
use tokio_serial::SerialPort as _;

const FACES: u32 = 24;
const RUNS: u32 = 4;

fn bench(seed: u64, clock: Arc<dyn Clock>) -> SimBench {
    let preset = Preset::by_name("fig8").unwrap();
    SimBench::builder(&preset, seed, clock).autocollimator(AutocollimatorConfig::seeded(FACES, 4)).build()
}

async fn survey(engine: &mut Engine) -> (Vec<Sample>, Iso230) {
    let plan = SurveyPlan::full_circle(FACES, RUNS, true).unwrap();
    let mut sink = MemorySink::default();
    engine.run(&plan, 0, &mut sink, &mut |_| {}).await.unwrap();
    let samples: Vec<Sample> = sink.samples.iter().map(|r| r.sample).collect();
    let iso = iso230_2(&samples).unwrap();
    (samples, iso)
}

fn mean_error(samples: &[Sample], target: f64, dir: Direction) -> f64 {
    let e: Vec<f64> =
        samples.iter().filter(|s| s.target_deg == target && s.direction == dir).map(|s| s.error_deg()).collect();
    e.iter().sum::<f64>() / e.len() as f64
}

#[tokio::test]
async fn a_survey_over_scpi_and_elcomat_matches_the_in_process_survey() {
    // Over the wire: the positioner behind the SCPI server on loopback TCP, the
    // autocollimator behind the ELCOMAT server on a pty, both on one virtual clock.
    let clock: Arc<dyn Clock> = Arc::new(VirtualClock::new());
    let wired = bench(21, clock.clone());
    let certificate = wired.autocollimator.certificate_arcsec().to_vec();
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let address = listener.local_addr().unwrap();
    let server = tokio::spawn(serve_tcp(listener, wired.positioner, Faults::new()));
    let (master, slave) = pty_pair().unwrap();
    let port = slave.name().expect("the pty has a path");
    drop(slave);
    let cert: Vec<String> = certificate.iter().map(|c| format!("{c:?}")).collect();
    let text = format!(
        "[survey]\nreference = \"autocollimator\"\n\
         [positioner]\ndriver = \"scpi-tcp\"\naddress = \"{address}\"\n\
         [autocollimator]\ndriver = \"elcomat\"\nport = \"{port}\"\nbaud = 115200\n\
         [polygon]\nfaces = {FACES}\ncertificate_arcsec = [{}]\n",
        cert.join(", ")
    );
    let cfg = SurveyConfig::parse(&text, "wire.toml").unwrap();
    let mut instruments = Instruments::from_config(&cfg);
    // The pty's master reads EIO until a slave is open: open it, then serve.
    let ReferenceInstrument::Autocollimator { instrument, .. } = &mut instruments.reference else { unreachable!() };
    instrument.connect().await.unwrap();
    let elcomat = tokio::spawn(serve(master, wired.autocollimator));
    let mut engine = instruments.into_engine(clock.clone(), &cfg);
    let (wire_samples, wire) = survey(&mut engine).await;
    drop(engine);
    server.abort();
    let _ = elcomat.await;

    // In process: the same bench (another seed: independent noise), no wire.
    let local_clock: Arc<dyn Clock> = Arc::new(VirtualClock::new());
    let local = bench(22, local_clock.clone());
    let reference = Reference::Autocollimator {
        faces: local.autocollimator.faces(),
        certificate_arcsec: local.autocollimator.certificate_arcsec().to_vec(),
        instrument: Box::new(local.autocollimator),
    };
    let mut engine = Engine::new(local_clock, Box::new(local.positioner), reference, Timing::default());
    let (local_samples, local) = survey(&mut engine).await;

    // Both estimate the same error map; each target mean has sd
    // sigma/sqrt(RUNS) with sigma the positioner's noise (0.0004 deg in fig8)
    // plus 0.1" of autocollimator noise and the 0.01" print rounding of the
    // ELCOMAT replies. The difference of two means: sqrt(2) of that. 5 sd.
    let sigma = (0.0004f64.powi(2) + (0.1f64 / 3600.0).powi(2)).sqrt();
    let tol = 5.0 * sigma * (2.0 / RUNS as f64).sqrt();
    for t in SurveyPlan::full_circle(FACES, RUNS, true).unwrap().targets_deg {
        for dir in [Direction::Forward, Direction::Reverse] {
            let (a, b) = (mean_error(&wire_samples, t, dir), mean_error(&local_samples, t, dir));
            assert!((a - b).abs() < tol, "target {t} {dir}: wire {a} vs in-process {b} (tolerance {tol})");
        }
    }
    // The ISO figures agree: B_mean averages 24 such differences, E and M are
    // extremes of the means (within the same per-target tolerance).
    assert!((wire.b_mean.unwrap() - local.b_mean.unwrap()).abs() < tol / (FACES as f64).sqrt() * 2.0);
    assert!((wire.e - local.e).abs() < 2.0 * tol, "E {} vs {}", wire.e, local.e);
    assert!((wire.m.unwrap() - local.m.unwrap()).abs() < 2.0 * tol);
    assert_eq!(wire_samples.len(), local_samples.len());
}

/// The configuration: a Modbus TCP positioner and an emScon tracker,
/// both behind their protocols, against the same bench in process.
#[tokio::test]
async fn a_survey_over_modbus_and_emscon_matches_the_in_process_survey() {
    use survey_positioner_drivers::modbus::RegisterMap;

    use survey_sim_servers::modbus_server::ModbusDevice;
    const POINTS: u32 = 36;
    const RUNS: u32 = 3;

    let clock: Arc<dyn Clock> = Arc::new(VirtualClock::new());
    let preset = Preset::by_name("fig8").unwrap();
    let wired = SimBench::new(&preset, 31, clock.clone());
    let device = ModbusDevice::new(wired.positioner, RegisterMap::default()).unwrap();
    let modbus = device.spawn_tcp(Faults::new()).await.unwrap();
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let emscon_addr = listener.local_addr().unwrap();
    let emscon = tokio::spawn(survey_sim_servers::emscon_server::serve_tcp(listener, wired.tracker, Faults::new()));
    let text = format!(
        "[survey]\nreference = \"tracker\"\n\
         [positioner]\ndriver = \"modbus-tcp\"\naddress = \"{}\"\n\
         [tracker]\ndriver = \"emscon\"\naddress = \"{emscon_addr}\"\n\
         [arm]\nradius_mm = 1000.0\n",
        modbus.addr
    );
    let cfg = SurveyConfig::parse(&text, "wire.toml").unwrap();
    let mut engine = Instruments::from_config(&cfg).into_engine(clock.clone(), &cfg).with_arm_check(1000.0, 5.0);
    let plan = SurveyPlan::full_circle(POINTS, RUNS, true).unwrap();
    let mut sink = MemorySink::default();
    engine.run(&plan, 0, &mut sink, &mut |_| {}).await.unwrap();
    let wire_samples: Vec<Sample> = sink.samples.iter().map(|r| r.sample).collect();
    let wire = iso230_2(&wire_samples).unwrap();
    drop(engine);
    emscon.abort();
    drop(modbus);

    let local_clock: Arc<dyn Clock> = Arc::new(VirtualClock::new());
    let local = SimBench::new(&preset, 32, local_clock.clone());
    let mut engine = Engine::new(
        local_clock,
        Box::new(local.positioner),
        Reference::Tracker(Box::new(local.tracker)),
        Timing::default(),
    );
    let mut sink = MemorySink::default();
    engine.run(&plan, 0, &mut sink, &mut |_| {}).await.unwrap();
    let local_samples: Vec<Sample> = sink.samples.iter().map(|r| r.sample).collect();
    let local = iso230_2(&local_samples).unwrap();

    // Per-sample noise: the positioner's 0.0004 deg and the tracker's angular
    // noise (its coordinate sigma over the 1 m arm, at the worst target: about
    // 0.0009 deg); the Modbus counts resolve 1e-5 deg. Each target mean has sd
    // sigma/sqrt(RUNS); the difference of two independent means sqrt(2) of
    // that, and each survey's axis fit adds a smooth error of about
    // sigma_trk * sqrt(2/12) to every target. 5 sd.
    let arm = survey_sims::tracker::ArmGeometry::default();
    let sigma_trk = plan.targets_deg.iter().map(|&t| super::tracker_sigma_deg(&arm, t)).fold(0.0f64, f64::max);
    let sigma = (0.0004f64.powi(2) + sigma_trk.powi(2)).sqrt();
    let fit = sigma_trk * (2.0f64 / 12.0).sqrt();
    let tol = 5.0 * ((2.0 * sigma * sigma / RUNS as f64) + 2.0 * fit * fit).sqrt();
    for t in &plan.targets_deg {
        for dir in [Direction::Forward, Direction::Reverse] {
            let (a, b) = (mean_error(&wire_samples, *t, dir), mean_error(&local_samples, *t, dir));
            assert!((a - b).abs() < tol, "target {t} {dir}: wire {a} vs in-process {b} (tolerance {tol})");
        }
    }
    // The reversal averages the per-target differences, in which the fit error
    // cancels (it is the same for both directions): sd sigma * sqrt(4 / (RUNS N)).
    let b_tol = 5.0 * sigma * (4.0 / (RUNS * POINTS) as f64).sqrt();
    assert!(
        (wire.b_mean.unwrap() - local.b_mean.unwrap()).abs() < b_tol,
        "B_mean {:?} vs {:?}",
        wire.b_mean,
        local.b_mean
    );
    assert!((wire.e - local.e).abs() < 2.0 * tol, "E {} vs {}", wire.e, local.e);
}

/// emScon's continuous time mode over TCP (issue 12): the driver sets the
/// mode and the time separation, starts, and collects the `MultiMeasResultT`
/// points the simulated server sends with its answers; the points come every
/// period on the tracker's own clock, at the SMR's position; stopping goes
/// back to stationary measurements.
#[tokio::test]
async fn the_emscon_driver_streams_in_continuous_time_mode_and_goes_back_to_stationary() {
    use survey_drivers::Tracker as _;
    use survey_drivers::emscon::{EmsconConfig, EmsconTracker};
    use survey_sim_servers::emscon_server::serve_tcp;
    use survey_sims::tracker::{SimTracker, TrackerConfig};
    let clock = VirtualClock::new();
    let turntable = survey_sims::Turntable::new(0.0);
    turntable.place(30.0);
    let cfg = TrackerConfig { measurement_time: std::time::Duration::from_millis(50), ..TrackerConfig::default() };
    let arm = cfg.arm.clone();
    let sim = SimTracker::new(cfg, Arc::new(clock.clone()), turntable);
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let server = tokio::spawn(serve_tcp(listener, sim, Faults::new()));
    let mut t = EmsconTracker::connect(addr, EmsconConfig { measurement_time_ms: 50, ..EmsconConfig::default() })
        .await
        .unwrap();
    assert!(t.can_stream());
    t.start_stream(std::time::Duration::from_millis(5)).await.unwrap();
    clock.sleep(std::time::Duration::from_millis(200)).await;
    let points = t.read_stream().await.unwrap();
    t.stop_stream().await.unwrap();
    // 200 ms at 5 ms: 40 points (one either way for where the read lands).
    assert!((39..=42).contains(&points.len()), "{} points", points.len());
    let truth = arm.smr_position_mm(30.0);
    for w in points.windows(2) {
        // The tracker's clock runs 20 ppm slow against the clock.
        let dt = w[1].device_time_s - w[0].device_time_s;
        assert!((dt - 0.005).abs() < 2e-6, "points {dt} s apart");
    }
    for p in &points {
        assert_eq!(p.status, 0, "{p:?}");
        // The tracker's clock is 5000 s ahead of the clock (the simulator's
        // default), stamped in microseconds.
        assert!(p.device_time_s > 5000.0 && p.device_time_s < 5000.5, "{p:?}");
        let d = (0..3).map(|i| (p.xyz_mm[i] - truth[i]).powi(2)).sum::<f64>().sqrt();
        assert!(d < 0.1, "a point {d} mm off the SMR (noise: about 0.01 mm)");
    }
    // Stationary again.
    let m = t.measure().await.unwrap();
    let d = ((m.x_mm - truth[0]).powi(2) + (m.y_mm - truth[1]).powi(2) + (m.z_mm - truth[2]).powi(2)).sqrt();
    assert!(d < 0.1, "the stationary measurement after the stream is {d} mm off");
    server.abort();
}
