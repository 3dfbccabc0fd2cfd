use super::*;
use crate::presets::{Preset, without_noise};
use survey_drivers::VirtualClock;
use survey_drivers::clock::with_timeout;
use survey_processing::model::{DriftShape, Effect};

fn sim(cfg: PositionerConfig) -> (VirtualClock, SimPositioner) {
    let clock = VirtualClock::new();
    let p = SimPositioner::new(cfg, Arc::new(clock.clone()));
    (clock, p)
}

fn fig8() -> Model {
    Preset::by_name("fig8").unwrap().model
}

/// Poll until in position (or faulted), 50 ms of clock time between polls.
async fn settle(p: &mut SimPositioner) -> PositionerStatus {
    for _ in 0..100_000 {
        let s = p.status().await.unwrap();
        if s.in_position || s.fault.is_some() {
            return s;
        }
        p.clock.sleep(Duration::from_millis(50)).await;
    }
    panic!("never settled");
}

async fn go(p: &mut SimPositioner, target: f64) -> (f64, f64) {
    p.move_to(target).await.unwrap();
    let s = settle(p).await;
    assert!(s.in_position, "{s:?}");
    let r = p.readout().await.unwrap();
    (r, p.truth().actual_deg(p.clock.now()))
}

#[tokio::test]
async fn rest_readout_is_the_target_and_the_error_is_the_models() {
    let model = without_noise(&fig8());
    let (_c, mut p) = sim(PositionerConfig::new(model.clone()));
    let b = model.backlash_deg();
    let targets: Vec<f64> =
        (0..=12).map(|i| i as f64 * 27.5).chain((0..12).rev().map(|i| i as f64 * 27.5 + 3.3)).collect();
    let mut last = 0.0;
    for t in targets {
        let (r, a) = go(&mut p, t).await;
        let dir = if t > last {
            Direction::Forward
        } else if t < last {
            Direction::Reverse
        } else {
            p.direction()
        };
        last = t;
        assert_eq!(p.direction(), dir);
        assert_eq!(r, t, "readout at rest equals the target");
        let e = model.systematic_error_deg(a, dir, 0.0);
        assert!((r - a - e).abs() < 1e-9, "readout - actual {} vs model {e} at {t}", r - a);
        // Backlash sign (contract): forward reads +b/2, reverse -b/2.
        assert!((r - a - model.periodic_error_deg(a) - dir.sign() * b / 2.0).abs() < 1e-9);
        assert!(p.truth().actual_deg(p.clock.now()) == a, "stationary axis stays put");
    }
}

#[tokio::test]
async fn noise_scatter_matches_sigma() {
    let model = fig8();
    let sigma = model.noise_sigma_deg();
    let (_c, mut p) = sim(PositionerConfig { seed: 99, ..PositionerConfig::new(model.clone()) });
    let n = 400;
    let mut resid = Vec::with_capacity(n);
    for i in 0..n {
        let t = (i % 40) as f64 * 9.0 + if (i / 40) % 2 == 0 { 0.0 } else { 0.45 };
        let (r, a) = go(&mut p, t).await;
        // Re-reading a stationary axis gives the same value.
        assert_eq!(p.readout().await.unwrap(), r);
        let res = r - a - model.systematic_error_deg(a, p.direction(), 0.0);
        assert!((res - p.rest_noise_deg()).abs() < 1e-9);
        resid.push(res);
    }
    let mean = resid.iter().sum::<f64>() / n as f64;
    let sd = (resid.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
    // The sample sd of n normal draws has relative standard error ~1/sqrt(2(n-1))
    // (3.5 % for n = 400): a 4-sigma bound is ±14 %. The mean: 4 sigma/sqrt(n).
    let tol = 4.0 / (2.0 * (n - 1) as f64).sqrt();
    assert!((sd / sigma - 1.0).abs() < tol, "sd {sd} vs sigma {sigma}");
    assert!(mean.abs() < 4.0 * sigma / (n as f64).sqrt(), "mean {mean}");
}

#[tokio::test]
async fn a_90_degree_move_takes_9_5_s_plus_settle() {
    let (clock, mut p) = sim(PositionerConfig::new(fig8()));
    p.move_to(90.0).await.unwrap();
    let t0 = clock.now(); // the move starts when move_to returns
    // Half time is half way (symmetric profile): the readout interpolates.
    clock.advance_to(t0 + Duration::from_millis(4750) - LINK_LATENCY);
    let mid = p.readout().await.unwrap();
    assert!((mid - 45.0).abs() < 1e-9, "{mid}");
    let (mut stopped, mut ready) = (None, None);
    let mut phases = Vec::new();
    while ready.is_none() {
        let s = p.status().await.unwrap();
        let now = clock.now() - t0;
        let phase = match (s.moving, s.in_position) {
            (true, false) => "moving",
            (false, false) => "settling",
            (false, true) => "in_position",
            _ => panic!("moving and in position"),
        };
        if phases.last() != Some(&phase) {
            phases.push(phase);
        }
        if !s.moving && stopped.is_none() {
            stopped = Some(now);
        }
        if s.in_position {
            ready = Some(now);
        }
        clock.sleep(Duration::from_millis(8)).await;
    }
    assert_eq!(phases, ["moving", "settling", "in_position"]);
    let (stopped, ready) = (stopped.unwrap().as_secs_f64(), ready.unwrap().as_secs_f64());
    // Polled every 10 ms.
    assert!((9.5..9.511).contains(&stopped), "stopped at {stopped}");
    assert!((9.8..9.811).contains(&ready), "in position at {ready}");
    assert_eq!(p.readout().await.unwrap(), 90.0);
}

#[tokio::test]
async fn velocity_changes_the_timing_and_bad_values_are_refused() {
    let (clock, mut p) = sim(PositionerConfig::new(fig8()));
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let e = p.set_velocity(bad).await.unwrap_err();
        assert_eq!(e.kind, ErrorKind::Usage, "{bad}");
    }
    p.set_velocity(20.0).await.unwrap();
    p.move_to(90.0).await.unwrap();
    let t0 = clock.now();
    // 90/20 + 20/20 = 5.5 s.
    clock.advance_to(t0 + Duration::from_millis(5499) - LINK_LATENCY);
    assert!(p.status().await.unwrap().moving);
    clock.advance_to(t0 + Duration::from_millis(5500) - LINK_LATENCY);
    assert!(!p.status().await.unwrap().moving);
}

#[tokio::test]
async fn drift_grows_by_the_rate_per_run_period() {
    let rate = 0.002;
    let mut model = without_noise(&fig8());
    model.effects.push(Effect::Drift { rate_deg_per_run: rate, shape: DriftShape::Ramp });
    let period = Duration::from_secs(600);
    let cfg = PositionerConfig { drift_run_period: Some(period), ..PositionerConfig::new(model.clone()) };
    let (clock, mut p) = sim(cfg);
    let drift_part = |p: &SimPositioner, r: f64, a: f64| r - a - model.repeatable_error_deg(a, p.direction());
    let ta = clock.now();
    let (r1, a1) = go(&mut p, 10.0).await;
    let q1 = drift_part(&p, r1, a1);
    // It came to rest 2 ms (link) + 1.5 s (profile) after the command.
    assert!((q1 - rate * 1.502 / 600.0).abs() < 1e-9, "{q1}");
    go(&mut p, 0.0).await;
    // The same move, exactly one run period later.
    clock.advance_to(ta + period);
    let (r2, a2) = go(&mut p, 10.0).await;
    let q2 = drift_part(&p, r2, a2);
    assert!((q2 - q1 - rate).abs() < 1e-9, "drift grew by {}", q2 - q1);
    assert!((p.runs_elapsed_at(ta + period) - 1.0).abs() < 1e-12);
    // Without a period, no drift at all.
    let (_c, mut still) = sim(PositionerConfig::new(model.clone()));
    let (r, a) = go(&mut still, 10.0).await;
    assert!(drift_part(&still, r, a).abs() < 1e-9);
}

/// With a plan progress, the drift is the model's rate per run exactly:
/// step `j` of run `k` (of `n` steps a run) is at `k + j / n` runs for a
/// ramp and `k` for a step, whatever the clock says (a long wait changes
/// nothing), and it takes precedence over a drift period.
#[tokio::test]
async fn drift_by_plan_progress_is_the_rate_per_run_exactly() {
    let rate = 0.002;
    for shape in [DriftShape::Ramp, DriftShape::Step] {
        let mut model = without_noise(&fig8());
        model.effects.push(Effect::Drift { rate_deg_per_run: rate, shape });
        let progress = PlanProgress::new(8);
        let cfg = PositionerConfig {
            drift_run_period: Some(Duration::from_secs(1)),
            drift_progress: Some(progress.clone()),
            ..PositionerConfig::new(model.clone())
        };
        let (clock, mut p) = sim(cfg);
        let drift_part = |p: &SimPositioner, r: f64, a: f64| r - a - model.repeatable_error_deg(a, p.direction());
        for (seq, target) in [(0u64, 10.0), (3, 20.0), (8, 10.0), (13, 30.0), (37, 5.0)] {
            progress.set_next_step(seq);
            clock.advance(Duration::from_secs(5000));
            let (r, a) = go(&mut p, target).await;
            let (k, j) = ((seq / 8) as f64, (seq % 8) as f64);
            let want = match shape {
                DriftShape::Ramp => rate * (k + j / 8.0),
                DriftShape::Step => rate * k,
            };
            assert!((drift_part(&p, r, a) - want).abs() < 1e-12, "{shape:?} step {seq}: {}", drift_part(&p, r, a));
        }
        // A verification after the plan: 6 steps a run, its time counted on
        // from the calibration's next step (37 of 8 a run: 4.625 runs).
        progress.continue_with(6);
        for (seq, target) in [(0u64, 12.0), (3, 40.0), (9, 15.0)] {
            progress.set_next_step(seq);
            let (r, a) = go(&mut p, target).await;
            let runs = 4.625 + (seq / 6) as f64 + (seq % 6) as f64 / 6.0;
            let want = match shape {
                DriftShape::Ramp => rate * runs,
                DriftShape::Step => rate * runs.floor(),
            };
            assert!((drift_part(&p, r, a) - want).abs() < 1e-12, "{shape:?} verification step {seq}");
        }
    }
}

#[tokio::test]
async fn correction_in_the_feedback_path_puts_the_axis_on_target() {
    let model = without_noise(&fig8());
    let n = 3600;
    let rows = |d| (0..n).map(|i| model.repeatable_error_deg(i as f64 * 360.0 / n as f64, d)).collect::<Vec<_>>();
    let table = CorrectionTable::directional(rows(Direction::Forward), rows(Direction::Reverse)).unwrap();
    // Bound: actual - target = T(raw) - e(actual) with raw - actual = e(actual), so
    // |actual - target| <= h^2/8 max|e''| (linear interpolation of the table)
    //                     + max|e'| max|e| (the table is read at raw, not at actual).
    let (mut e1, mut e2, mut e0) = (0.0, 0.0, model.backlash_deg() / 2.0);
    for e in model.periodic_effects() {
        if let Effect::Periodic { cycles_per_rev, amplitude_deg, .. } = e {
            let w = cycles_per_rev.to_radians();
            e0 += amplitude_deg;
            e1 += amplitude_deg * w;
            e2 += amplitude_deg * w * w;
        }
    }
    let h = 360.0 / n as f64;
    let bound = h * h / 8.0 * e2 + e1 * e0 + 1e-9;
    assert!(bound < 1e-4, "bound {bound}");

    let (clock, mut p) = sim(PositionerConfig::new(model.clone()));
    let e = p.enable_correction(true).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Usage, "no table loaded yet");
    // Loading while moving is refused.
    p.move_to(30.0).await.unwrap();
    clock.advance(Duration::from_millis(100));
    let e = p.load_correction_table(&table).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Usage);
    settle(&mut p).await;
    p.load_correction_table(&table).await.unwrap();
    assert!(!p.status().await.unwrap().correction_enabled);
    p.enable_correction(true).await.unwrap();
    assert!(p.status().await.unwrap().correction_enabled);
    let mut worst: f64 = 0.0;
    for t in [5.0, 47.3, 90.0, 181.1, 270.25, 359.0, 200.0, 100.05, 3.3] {
        let (r, a) = go(&mut p, t).await;
        assert_eq!(r, t);
        worst = worst.max((a - t).abs());
    }
    assert!(worst <= bound, "corrected |actual - target| {worst} > bound {bound}");
    // Native, the same axis is off by up to the native error.
    p.enable_correction(false).await.unwrap();
    let mut native: f64 = 0.0;
    for t in [5.0, 47.3, 90.0, 181.1, 270.25, 359.0] {
        let (_, a) = go(&mut p, t).await;
        native = native.max((a - t).abs());
    }
    assert!(native > 0.005, "native {native}");
}

#[tokio::test]
async fn toggling_correction_changes_the_display_not_the_axis() {
    let model = without_noise(&fig8());
    let (clock, mut p) = sim(PositionerConfig::new(model.clone()));
    let (r, a) = go(&mut p, 40.0).await;
    let table = CorrectionTable::new(vec![0.01; 8]).unwrap();
    p.load_correction_table(&table).await.unwrap();
    p.enable_correction(true).await.unwrap();
    assert!((p.readout().await.unwrap() - (r - 0.01)).abs() < 1e-12);
    assert_eq!(p.truth().actual_deg(clock.now()), a);
    p.enable_correction(false).await.unwrap();
    assert_eq!(p.readout().await.unwrap(), r);
}

#[tokio::test]
async fn travel_limits() {
    let cfg = PositionerConfig { travel: Some((-10.0, 90.0)), ..PositionerConfig::new(without_noise(&fig8())) };
    let (_c, mut p) = sim(cfg);
    let e = p.move_to(95.0).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Usage);
    assert!(e.message.contains("target 95 deg is outside the travel -10..90 deg"), "{e}");
    assert_eq!(p.move_to(f64::NAN).await.unwrap_err().kind, ErrorKind::Usage);
    assert_eq!(p.status().await.unwrap().limit, None);
    go(&mut p, 90.0).await;
    assert_eq!(p.status().await.unwrap().limit, Some(Limit::Upper));
    go(&mut p, -10.0).await;
    assert_eq!(p.status().await.unwrap().limit, Some(Limit::Lower));
    go(&mut p, 45.0).await;
    assert_eq!(p.status().await.unwrap().limit, None);
}

#[tokio::test]
async fn stop_halts_where_the_axis_is() {
    let model = fig8();
    let (clock, mut p) = sim(PositionerConfig { seed: 3, ..PositionerConfig::new(model.clone()) });
    p.move_to(90.0).await.unwrap();
    clock.advance(Duration::from_secs(3));
    p.stop().await.unwrap();
    let s = p.status().await.unwrap();
    assert!(!s.moving && !s.in_position, "{s:?}");
    let r = p.readout().await.unwrap();
    let a = p.truth().actual_deg(clock.now());
    assert!(r > 10.0 && r < 40.0, "{r}");
    let res = r - a - model.systematic_error_deg(a, Direction::Forward, 0.0);
    assert!((res - p.rest_noise_deg()).abs() < 1e-9);
    assert!(settle(&mut p).await.in_position);
    assert_eq!(p.readout().await.unwrap(), r);
    // A zero-length move keeps the direction.
    go(&mut p, 5.0).await;
    assert_eq!(p.direction(), Direction::Reverse);
    go(&mut p, 5.0).await;
    assert_eq!(p.direction(), Direction::Reverse);
}

#[tokio::test]
async fn scheduled_device_fault_latches_until_cleared() {
    let faults = PositionerFaults { fault_on_move: Some(2), ..Default::default() };
    let (_c, mut p) = sim(PositionerConfig { faults, ..PositionerConfig::new(without_noise(&fig8())) });
    go(&mut p, 10.0).await;
    p.move_to(50.0).await.unwrap(); // accepted; the drive trips halfway
    let s = settle(&mut p).await;
    let f = s.fault.clone().expect("latched fault");
    assert_eq!(f.code, FAULT_FOLLOWING_ERROR);
    assert!(!s.moving && !s.in_position);
    let r = p.readout().await.unwrap();
    assert!((r - 30.0).abs() < 0.05, "halted half way: {r}");
    let e = p.move_to(50.0).await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(FAULT_FOLLOWING_ERROR)));
    p.clear_fault().await.unwrap();
    let s = p.status().await.unwrap();
    assert!(s.fault.is_none() && !s.in_position, "not on target until commanded again: {s:?}");
    let (r, _) = go(&mut p, 50.0).await;
    assert_eq!(r, 50.0);
}

#[tokio::test]
async fn a_new_command_makes_a_pending_trip_happen_now() {
    let faults = PositionerFaults { fault_on_move: Some(1), ..Default::default() };
    let (clock, mut p) = sim(PositionerConfig { faults, ..PositionerConfig::new(fig8()) });
    p.move_to(90.0).await.unwrap();
    clock.advance(Duration::from_secs(1));
    assert!(p.status().await.unwrap().fault.is_none(), "not tripped yet");
    let e = p.move_to(20.0).await.unwrap_err();
    assert_eq!(e.code, Some(FAULT_FOLLOWING_ERROR));
    let s = p.status().await.unwrap();
    assert!(s.fault.is_some() && !s.moving);
}

#[tokio::test]
async fn injected_timeout_trips_with_timeout_and_the_next_call_works() {
    let faults = PositionerFaults { timeout_on_call: Some(2), ..Default::default() };
    let (clock, mut p) = sim(PositionerConfig { faults, ..PositionerConfig::new(fig8()) });
    p.status().await.unwrap();
    let t0 = clock.now();
    let e = with_timeout(&clock, Duration::from_secs(5), "positioner", "status", p.status()).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Timeout);
    assert!(clock.now() - t0 >= INJECTED_TIMEOUT);
    assert!(p.status().await.is_ok());
}

#[tokio::test]
async fn injected_disconnect_fails_once_and_loses_the_request() {
    let faults = PositionerFaults { disconnect_on_call: Some(1), ..Default::default() };
    let (_c, mut p) = sim(PositionerConfig { faults, ..PositionerConfig::new(fig8()) });
    let e = p.move_to(10.0).await.unwrap_err();
    assert_eq!(e.kind, ErrorKind::Disconnected);
    assert!(e.is_link());
    assert_eq!(p.moves(), 0, "the lost request did not move the axis");
    assert!(p.status().await.unwrap().in_position);
    go(&mut p, 10.0).await;
}

/// The noise of each successful move, retrying link faults.
async fn noises(faults: PositionerFaults) -> Vec<u64> {
    let cfg = PositionerConfig { seed: 21, faults, ..PositionerConfig::new(fig8()) };
    let (_c, mut p) = sim(cfg);
    let mut out = Vec::new();
    for k in 0..30 {
        while let Err(e) = p.move_to(k as f64 * 7.0).await {
            assert!(e.is_link(), "{e}");
        }
        out.push(p.rest_noise_deg().to_bits());
    }
    out
}

#[tokio::test]
async fn faults_do_not_change_the_noise() {
    let clean = noises(PositionerFaults::default()).await;
    let faulty = noises(PositionerFaults {
        timeout_probability_per_call: 0.2,
        disconnect_probability_per_call: 0.2,
        garbled_probability_per_call: 0.1,
        ..Default::default()
    })
    .await;
    assert_eq!(clean, faulty);
    assert_ne!(clean, {
        let cfg = PositionerConfig { seed: 22, ..PositionerConfig::new(fig8()) };
        let (_c, mut p) = sim(cfg);
        p.move_to(0.0).await.unwrap();
        vec![p.rest_noise_deg().to_bits()]
    });
}

#[tokio::test]
async fn random_device_faults_happen_at_their_rate() {
    let faults = PositionerFaults { fault_probability_per_move: 0.25, ..Default::default() };
    let (_c, mut p) = sim(PositionerConfig { seed: 4, faults, ..PositionerConfig::new(fig8()) });
    let mut trips = 0;
    let n = 200;
    for k in 0..n {
        p.move_to((k % 36) as f64 * 10.0).await.unwrap();
        if settle(&mut p).await.fault.is_some() {
            trips += 1;
            p.clear_fault().await.unwrap();
        }
    }
    // Binomial(200, 0.25): mean 50, sd 6.1; 4 sigma.
    assert!((trips as f64 - 50.0).abs() < 4.0 * 6.13, "{trips} trips");
}

#[tokio::test]
async fn same_seed_is_bit_identical() {
    async fn run(seed: u64) -> Vec<u64> {
        let (c, mut p) = sim(PositionerConfig { seed, ..PositionerConfig::new(fig8()) });
        let mut out = Vec::new();
        for t in [10.0, 20.0, 5.0, 300.0, 0.5] {
            let (r, a) = go(&mut p, t).await;
            out.extend([r.to_bits(), a.to_bits(), c.now().as_nanos() as u64]);
        }
        out
    }
    assert_eq!(run(8).await, run(8).await);
    assert_ne!(run(8).await, run(9).await);
}
