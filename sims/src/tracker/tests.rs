use super::*;
use survey_drivers::VirtualClock;
use survey_drivers::error::ErrorKind;

fn setup(cfg: TrackerConfig) -> (VirtualClock, Turntable, SimTracker) {
    let clock = VirtualClock::new();
    let table = Turntable::new(0.0);
    let t = SimTracker::new(cfg, Arc::new(clock.clone()), table.clone());
    (clock, table, t)
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| a[i] - b[i])
}

#[test]
fn basis_is_orthonormal_right_handed_and_tilted() {
    let arm = ArmGeometry::default();
    let (u, v, n) = arm.basis();
    for (a, b, want) in [(u, u, 1.0), (v, v, 1.0), (n, n, 1.0), (u, v, 0.0), (u, n, 0.0), (v, n, 0.0)] {
        assert!((dot(a, b) - want).abs() < 1e-12);
    }
    let w = cross(u, v);
    assert!((0..3).all(|i| (w[i] - n[i]).abs() < 1e-12));
    assert!((n[2].acos().to_degrees() - 0.3).abs() < 1e-9);
}

#[test]
fn angle_increases_counterclockwise_about_the_normal() {
    let arm = ArmGeometry::default();
    let (u, v, _) = arm.basis();
    let c = arm.circle_center_mm();
    for theta in [0.0, 10.0, 123.4, 359.0] {
        let d = sub(arm.smr_position_mm(theta), c);
        let phi = dot(d, v).atan2(dot(d, u)).to_degrees();
        assert!((wrap_deg(phi - arm.arm_phase_deg - theta)).abs() < 1e-9, "{theta}");
    }
}

fn wrap_deg(x: f64) -> f64 {
    survey_processing::types::wrap_180(x)
}

#[tokio::test]
async fn smr_positions_lie_on_the_designed_circle() {
    let (_clock, table, mut t) = setup(TrackerConfig { noise_scale: 0.0, ..TrackerConfig::default() });
    let arm = t.config().arm.clone();
    let (_, _, n) = arm.basis();
    let c = arm.circle_center_mm();
    for k in 0..36 {
        table.place(k as f64 * 10.0 + 0.3);
        let m = t.measure().await.unwrap();
        let d = sub(m.xyz(), c);
        assert!((dot(d, d).sqrt() - arm.radius_mm).abs() < 1e-9);
        assert!(dot(d, n).abs() < 1e-9);
        // The circle's plane sits smr_height above the axis point.
        assert!((dot(sub(m.xyz(), arm.axis_center_mm), n) - arm.smr_height_mm).abs() < 1e-9);
    }
}

#[tokio::test]
async fn noise_sd_matches_the_mpe_formula() {
    let (_clock, table, mut t) = setup(TrackerConfig { seed: 77, ..TrackerConfig::default() });
    table.place(200.0);
    let exact = t.config().arm.smr_position_mm(200.0);
    let sigma = sigma_mm(dot(exact, exact).sqrt());
    // About 2 m away: (15 + 6*2)/2 um.
    assert!((0.0125..0.0145).contains(&sigma), "{sigma}");
    let n = 1500;
    let mut sums = [0.0; 3];
    for _ in 0..n {
        let m = t.measure().await.unwrap();
        assert_eq!(m.std_dev_mm, [sigma; 3]);
        assert_eq!(m.measurement_time_s, 1.0);
        for i in 0..3 {
            sums[i] += (m.xyz()[i] - exact[i]).powi(2);
        }
    }
    // sd about the known truth (n degrees of freedom): relative standard error
    // 1/sqrt(2n); a 4-sigma bound.
    let tol = 4.0 / (2.0 * n as f64).sqrt();
    for s in sums {
        let sd = (s / n as f64).sqrt();
        assert!((sd / sigma - 1.0).abs() < tol, "sd {sd} vs sigma {sigma}");
    }
}

#[tokio::test]
async fn measurement_takes_its_time_and_samples_the_start() {
    let (clock, table, mut t) = setup(TrackerConfig { noise_scale: 0.0, ..TrackerConfig::default() });
    table.place(33.0);
    let t0 = clock.now();
    let m = t.measure().await.unwrap();
    assert_eq!(clock.now() - t0, Duration::from_secs(1));
    assert_eq!(m.xyz(), t.config().arm.smr_position_mm(33.0));
    let t1 = clock.now();
    assert_eq!(t.status().await.unwrap(), TrackerState::TargetLocked);
    assert_eq!(clock.now() - t1, LINK_LATENCY);
}

#[tokio::test]
async fn beam_break_fails_until_reacquired() {
    let cfg = TrackerConfig { break_on_measurement: Some(2), ..TrackerConfig::default() };
    let (clock, table, mut t) = setup(cfg);
    table.place(10.0);
    t.measure().await.unwrap();
    let e = t.measure().await.unwrap_err();
    assert_eq!((e.kind, e.code), (ErrorKind::Device, Some(CODE_BEAM_BROKEN)));
    assert!(e.message.contains("beam broken"), "{e}");
    assert_eq!(t.status().await.unwrap(), TrackerState::BeamBroken);
    let t0 = clock.now();
    let e = t.measure().await.unwrap_err();
    assert_eq!(e.code, Some(CODE_BEAM_BROKEN));
    assert_eq!(clock.now() - t0, LINK_LATENCY, "a broken beam fails at once");
    let t1 = clock.now();
    t.reacquire().await.unwrap();
    assert_eq!(clock.now() - t1, Duration::from_secs(5));
    assert_eq!(t.status().await.unwrap(), TrackerState::TargetLocked);
    assert!(t.measure().await.is_ok());
    assert_eq!(t.measurements(), 3);
}

#[tokio::test]
async fn beam_breaks_do_not_change_the_noise_of_good_measurements() {
    async fn good(p: f64) -> (Vec<[f64; 3]>, usize) {
        let cfg = TrackerConfig { seed: 5, beam_break_probability: p, ..TrackerConfig::default() };
        let (_clock, table, mut t) = setup(cfg);
        table.place(77.0);
        let (mut out, mut breaks) = (Vec::new(), 0);
        while out.len() < 50 {
            match t.measure().await {
                Ok(m) => out.push(m.xyz()),
                Err(_) => {
                    breaks += 1;
                    t.reacquire().await.unwrap();
                }
            }
        }
        (out, breaks)
    }
    let (clean, none) = good(0.0).await;
    let (faulty, some) = good(0.3).await;
    assert_eq!(none, 0);
    assert!(some > 5, "{some} breaks");
    assert_eq!(clean, faulty);
}

#[tokio::test]
async fn a_beam_held_broken_cannot_be_reacquired_until_it_clears() {
    let cfg =
        TrackerConfig { break_on_measurement: Some(1), beam_hold: Duration::from_secs(60), ..TrackerConfig::default() };
    let (clock, table, mut t) = setup(cfg);
    let injected = crate::faults::Injected::new();
    t.count_injected(injected.clone());
    table.place(10.0);
    let broke_at = clock.now() + Duration::from_secs(1);
    assert_eq!(t.measure().await.unwrap_err().code, Some(CODE_BEAM_BROKEN));
    assert_eq!(injected.get(crate::faults::FaultKind::Beam), 1);
    // Each search takes the re-acquisition time and fails while the beam is blocked.
    let mut searches = 0;
    while t.reacquire().await.is_err() {
        searches += 1;
        assert_eq!(t.status().await.unwrap(), TrackerState::BeamBroken);
    }
    // Searches of 5 s from the break: the first that ends at or after 60 s succeeds.
    assert_eq!(searches, 11);
    assert!(clock.now() >= broke_at + Duration::from_secs(60));
    assert_eq!(t.status().await.unwrap(), TrackerState::TargetLocked);
    assert!(t.measure().await.is_ok());
}
