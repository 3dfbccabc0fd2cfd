//! Simulated instruments for positioner surveys: a positioner with the error
//! model of the paper, a tracking laser and an autocollimator, all looking at
//! one simulated turntable and all running on one [`Clock`].
//!
//! # How the simulation is built
//!
//! - [`Turntable`] is the shared truth: the true axis angle as a function of
//!   time. The [`SimPositioner`] drives it; the [`SimTracker`] and the
//!   [`SimAutocollimator`] read it.
//! - There are no background tasks. Every state is computed from the clock when
//!   it is asked for, so a run on a [`VirtualClock`](survey_drivers::VirtualClock)
//!   is deterministic and hours of instrument time pass in milliseconds.
//! - Every operation that takes time on hardware sleeps on the clock for that
//!   time: 2 ms of link latency for a query or a command, the measurement time
//!   of the tracker, the read time of the autocollimator, a move's profile.
//! - Every random draw is seeded. Each instrument has two independent streams,
//!   one for measurement noise and one for fault injection, so turning faults on
//!   does not change the noise of the moves or measurements that do succeed.
//!   [`SimBench`] derives the seeds of the three instruments from one seed.
//! - The instruments as devices on a wire (the protocol servers of Modbus,
//!   CANopen, SCPI, emScon and ELCOMAT, the fault relay, `survey sim`'s
//!   serving) are in `survey-sim-servers`, built on these.
//!
//! # Sign conventions (the contract's)
//!
//! - `error = readout - actual`. The positioner's readout at rest is
//!   `actual + model.systematic_error_deg(actual, direction, runs_elapsed) + noise`
//!   (see [`positioner`]).
//! - Backlash: forward approaches read `+backlash/2`, reverse `-backlash/2`.
//! - Autocollimator: `X = 3600*(theta - phi_k) - c_k + noise`, so
//!   `theta = phi_k + (X + c_k)/3600` (see [`autocollimator`]).
//!
//! # Device fault codes
//!
//! | instrument | code | meaning |
//! |---|---|---|
//! | positioner | [`positioner::FAULT_FOLLOWING_ERROR`] (0x8611) | CiA 402 following error: the drive tripped mid-move |
//! | tracker | [`tracker::CODE_BEAM_BROKEN`] (9001) | the beam lost the SMR; `reacquire()` first |
//! | autocollimator | [`autocollimator::CODE_NO_REFLECTION`] (2) | no face within the measuring range |

#![warn(missing_docs)]

pub mod autocollimator;
pub mod bench;
pub mod faults;
pub mod positioner;
pub mod presets;
pub mod room;
pub mod servo;
pub mod tracker;
pub mod turntable;

pub use autocollimator::{AutocollimatorConfig, SimAutocollimator};
pub use bench::{SimBench, SimBenchBuilder};
pub use positioner::{PlanProgress, PositionerConfig, PositionerFaults, SimPositioner};
pub use presets::Preset;
pub use tracker::{ArmGeometry, SimTracker, TrackerConfig};
pub use turntable::Turntable;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::time::Duration;

/// Link latency of one query or command to a simulated instrument.
pub const LINK_LATENCY: Duration = Duration::from_millis(2);

/// The stream of an instrument's RNG that draws measurement noise.
pub(crate) const NOISE_STREAM: u64 = 0;
/// The stream of an instrument's RNG that draws injected faults.
pub(crate) const FAULT_STREAM: u64 = 1;

/// A seeded ChaCha8 RNG on one of its independent streams.
pub(crate) fn seeded_rng(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    rng
}

/// Derive an independent seed from `seed` and a `salt` (SplitMix64 finaliser),
/// so one survey seed gives every instrument its own seed.
pub fn derive_seed(seed: u64, salt: u64) -> u64 {
    let mut z = seed ^ salt.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Solve `x = f(x)` by fixed-point iteration from `x0` (the simulators' error
/// functions are contractions: their slope is far below 1). Stops when a step
/// is below 1e-12 degrees, or after 100 iterations.
pub(crate) fn fixed_point(f: impl Fn(f64) -> f64, x0: f64) -> f64 {
    let mut x = x0;
    for _ in 0..100 {
        let next = f(x);
        if (next - x).abs() <= 1e-12 {
            return next;
        }
        x = next;
    }
    tracing::warn!(x, "fixed-point iteration did not converge in 100 steps (error slope near 1?)");
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    #[test]
    fn streams_and_derived_seeds_are_independent_and_stable() {
        let mut a = seeded_rng(7, NOISE_STREAM);
        let mut b = seeded_rng(7, FAULT_STREAM);
        let mut a2 = seeded_rng(7, NOISE_STREAM);
        let x: u64 = a.random();
        assert_ne!(x, b.random::<u64>());
        assert_eq!(x, a2.random::<u64>());
        assert_ne!(derive_seed(1, 1), derive_seed(1, 2));
        assert_eq!(derive_seed(42, 3), derive_seed(42, 3));
    }

    #[test]
    fn fixed_point_converges() {
        let x = fixed_point(|x| 10.0 - 0.01 * x.sin(), 10.0);
        assert!((x + 0.01 * x.sin() - 10.0).abs() < 1e-12);
    }
}
